"""Old code against new in one run: the package of this working tree or of a
git revision, copied into a temporary directory and run from there
(``benchmarks/startup.py``, ``benchmarks/lsp_large.py``); and one search
per process, its figures as JSON (:func:`run_explore`:
``benchmarks/counters.py``, ``benchmarks/liveness.py``)."""

from __future__ import annotations

import os
import resource
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
#: ``python -c CHILD TREE ARGS...``: the ``pccl`` command with the package of TREE
CHILD = ("import sys; sys.path.insert(0, sys.argv.pop(1)); sys.argv[0] = 'pccl'; "
         "from pccl.cli import main; main()")


def tree_of_worktree(into: str) -> str:
    """This working tree's package, importable from ``into``."""
    ignore = shutil.ignore_patterns("__pycache__")
    shutil.copytree(ROOT / "pccl", os.path.join(into, "pccl"), ignore=ignore)
    for sub in ("semantics", "blackboxes"):
        shutil.copytree(ROOT / sub, os.path.join(into, "pccl", sub), ignore=ignore)
    return into


def tree_of_revision(rev: str, into: str, paths: tuple = ("pccl", "semantics", "blackboxes")) -> str:
    """The package of git revision ``rev``, importable from ``into``
    (``paths``: what to extract; empty: the whole revision), with
    ``pccl.semantics`` and ``pccl.blackboxes`` linked in as the install does."""
    archive = subprocess.run(["git", "archive", rev, *paths], cwd=ROOT,
                             capture_output=True, check=True)
    subprocess.run(["tar", "-x", "-C", into], input=archive.stdout, check=True)
    for sub in ("semantics", "blackboxes"):
        link = os.path.join(into, "pccl", sub)
        if not os.path.exists(link):
            os.symlink(os.path.join(into, sub), link)
    return into


def versions(tmp: str, baseline: str | None) -> list[tuple[str, str]]:
    """``[(name, tree)]``: the baseline's (``old REV``) first when given, then this tree's (``new``)."""
    out = [("new", tree_of_worktree(os.path.join(tmp, "new")))]
    if baseline:
        old = os.path.join(tmp, "old")
        os.mkdir(old)
        out.insert(0, (f"old {baseline}"[:12], tree_of_revision(baseline, old)))
    return out


def run_pccl(tree: str, args: list[str], env: dict, cwd: str | None = None,
             ok: tuple = (0, 1)) -> tuple[float, float]:
    """``pccl ARGS`` with the package of ``tree``: (wall s, the child's user + system CPU s)."""
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-c", CHILD, tree, *args], env=env, cwd=cwd,
                       stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if p.returncode not in ok:
        raise SystemExit(f"pccl {' '.join(args)} in {tree}: exit {p.returncode}\n{p.stderr[-2000:]}")
    return wall, (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)


#: ``python -c EXPLORE_CHILD SPEC [TREE]``: one ``api.explore`` of SPEC (JSON: the
#: program, then explore's options) in a process of its own, so that its
#: peak memory is its own; prints its figures as one JSON line
EXPLORE_CHILD = r"""
import json, resource, sys, time
if len(sys.argv) > 2:
    sys.path.insert(0, sys.argv[2])     # the package of a baseline revision
from pccl import api
spec = json.loads(sys.argv[1])
prog = spec.pop("program")
t0, c0 = time.perf_counter(), time.process_time()
r = api.explore(prog, **spec)
wall, cpu = time.perf_counter() - t0, time.process_time() - c0
print(json.dumps(dict(status=r.status, verdict=r.verdict.splitlines()[0][:90],
                      states=r.stats.states, transitions=r.stats.transitions, wall=wall, cpu=cpu,
                      engine=r.model.engine_used, reductions="+".join(r.model.reduction.on) or "none",
                      peak_mib=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)))
"""


def run_explore(spec: dict, timeout: float, tree: str | None = None) -> dict:
    """:data:`EXPLORE_CHILD` of ``spec`` from the repository's root (with
    the package of ``tree``, :func:`tree_of_revision`, when given): its
    figures, or ``{"status": why}`` when it timed out or failed."""
    import json
    try:
        p = subprocess.run([sys.executable, "-c", EXPLORE_CHILD, json.dumps(spec),
                            *([tree] if tree else [])], cwd=ROOT,
                           capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return dict(status=f"not finished in {timeout:.0f} s")
    if p.returncode != 0:
        return dict(status="error: " + p.stderr.strip().splitlines()[-1][:200])
    return json.loads(p.stdout.strip().splitlines()[-1])


def uptime() -> str:
    """``uptime``'s line (the load a measurement ran under)."""
    try:
        return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    except OSError:
        return "(uptime not available)"
