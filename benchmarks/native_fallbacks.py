"""Which programs the native engine serves, and why not the others: every
shipped program (programs/*.pccl with its world), the docs' examples
(docs/examples/, the tutorial's dock programs with dock.toml), the test
programs (tests/programs/*.pccl) and the program table of tests/cases.py,
each explored as its case says (``--max-states 50``: only the engine chosen
matters), then the reasons counted, most frequent first.

    python benchmarks/native_fallbacks.py
"""

from __future__ import annotations

import collections
import glob
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tests"))


def cases() -> list:
    import cases as C
    out = [(n, p, {k: v for k, v in kw.items() if k != "max_states"})
           for n, p, kw in C.SHIPPED + C.TESTPROGS]
    seen = {os.path.realpath(p) for _, p, _ in out}
    for p in sorted(glob.glob(os.path.join(ROOT, "docs/examples/*.pccl"))):
        w = os.path.join(ROOT, "docs/examples/dock.toml")
        out.append((os.path.relpath(p, ROOT), p, dict(world=w) if "dock" in p else {}))
    for p in sorted(glob.glob(os.path.join(ROOT, "programs/*.pccl"))):
        w = p[:-5] + ".toml"
        out.append((os.path.relpath(p, ROOT) + " (defaults)", p, dict(world=w) if os.path.exists(w) else {}))
    for p in sorted(glob.glob(os.path.join(ROOT, "tests/programs/*.pccl"))):
        if os.path.realpath(p) not in seen:
            out.append((os.path.relpath(p, ROOT), p, {}))
    return out


def main() -> int:
    from pccl.api import explore
    from pccl.lang.errors import PcclError
    reasons: collections.Counter = collections.Counter()
    for name, prog, kw in cases():
        try:
            r = explore(prog, max_states=50, **kw)
        except PcclError as e:
            print(f"{name:45s} -       ({str(e).splitlines()[0]})")
            continue
        why = r.model.engine_reason if r.model.engine_used == "python" else None
        print(f"{name:45s} {r.model.engine_used:7s} {why or ''}", flush=True)
        if why:
            reasons[why.split(" (line")[0]] += 1
    print()
    for why, n in reasons.most_common():
        print(f"{n:3d}  {why}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
