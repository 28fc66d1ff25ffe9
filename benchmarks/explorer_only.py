"""The explorer's own cost, old against new: successors are served from a
dict filled by one search beforehand, so only the explorer's work (keys,
fingerprints, visited table, property checks) is timed.

    python benchmarks/explorer_only.py [--baseline REV] [--k 1] [--d 1] [--repeat 3]
                                       [--reduce none]

Prints CPU seconds per run for the explorer of REV (default e58fcde) and
for this checkout's, alternating, on the same model and the same cached
successors.
"""

from __future__ import annotations

import argparse
import gc
import importlib.util
import os
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def old_explorer(rev: str, tmp: str):
    src = subprocess.run(["git", "show", f"{rev}:pccl/search/explorer.py"], cwd=ROOT,
                         capture_output=True, text=True, check=True).stdout
    path = os.path.join(tmp, "old_explorer.py")
    with open(path, "w") as f:
        f.write(src)
    spec = importlib.util.spec_from_file_location("pccl._old_explorer", path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod.Explorer


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", default="e58fcde")
    ap.add_argument("--k", default="1")
    ap.add_argument("--d", default="1")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--reduce", default="auto", help="the model's reductions (none: unreduced)")
    args = ap.parse_args()
    from pccl.api import make_model
    from pccl.search.explorer import Explorer
    m = make_model(os.path.join(ROOT, "programs/fischer.pccl"),
                   overrides={"k": args.k, "d": args.d}, reduce=args.reduce)
    cache: dict = {}

    class Recording:
        def __getattr__(self, name):
            return getattr(m, name)

        def successors(self, s):
            out = cache[s] = m.successors(s)
            return out

    gc.disable()
    Explorer(Recording(), find_all=True).run()

    class Cached:
        pass

    model = Cached()
    for name in ("init_states", "key", "violations", "terminal_kind", "deadlock_violation"):
        setattr(model, name, getattr(m, name))
    model.successors = cache.__getitem__
    with tempfile.TemporaryDirectory() as tmp:
        versions = [(f"old {args.baseline}", old_explorer(args.baseline, tmp)), ("new", Explorer)]
        for _ in range(args.repeat):
            for label, E in versions:
                c = time.process_time()
                r = E(model).run()
                print(f"{label:<12} {r.stats.states:>10,} states {r.stats.transitions:>11,} "
                      f"transitions  {time.process_time() - c:6.2f} s CPU", flush=True)


if __name__ == "__main__":
    main()
