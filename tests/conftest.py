"""Shared helpers for the engine test-suite (test_rules, test_engine,
test_properties, test_acceptance, test_cli, test_fuzz).

Configurations are the engine's plain tuples (see ``semantics/rules.py``)::

    state = (time, phase, lockQueue, shared, agents, env)
    agent = (pc, counter, lockState, status, locals, allread, position, reach)
    reach = (target, obstacles, t0, doReach_done, doReach_fail)

The helpers below build a model from a small program text, then edit such
tuples by name, so that tests can hand-build the configuration a rule needs.
Nothing here reads /work/shared: the programs used live in the repository.
"""

from __future__ import annotations

import os
import textwrap
from pathlib import Path

import pytest

from pccl.api import make_model
from pccl.lang.parser import parse_program

ROOT = Path(__file__).resolve().parent.parent
PROGRAMS = ROOT / "programs"
TEST_PROGRAMS = Path(__file__).resolve().parent / "programs"

FISCHER = str(PROGRAMS / "fischer.pccl")
RACE = str(PROGRAMS / "race.pccl")
RACE_NONATOMIC = str(PROGRAMS / "race_nonatomic.pccl")
RACE_WORLD = str(PROGRAMS / "race.toml")

# The suite's own cache ($PCCL_CACHE: the native engine's compiled modules and
# the parser's tables), set here before any test runs so that the xdist
# workers and every pccl process a test starts share it, and kept between runs
# (.pytest_cache/ is git-ignored; `pytest --cache-clear` empties it: a cold
# run).  A module is compiled once per generated source
# for the whole suite instead of once per worker, per file and per run (about
# 1.4 CPU-s each).  Its key hashes the source, the fixed C and the Python ABI,
# so a module of older code is never loaded.  A PCCL_CACHE set by the caller
# wins; the tests of the cache itself set their own directory.
os.environ.setdefault("PCCL_CACHE", str(ROOT / ".pytest_cache" / "pccl"))
# The suite compiles about a thousand native modules, most for searches of a
# few hundred states: at -O0 (pccl/model/native_build.py opt_level) each takes
# a third of -O2's CPU time, which was most of the suite's.  -O2, the default
# outside the suite, is held equal to it by tests/model/test_native_opt.py and
# the shipped programs are compiled at both there.
os.environ.setdefault("PCCL_NATIVE_OPT", "0")
# -O0 modules are about twice as large (126 KB for Fischer's): a bound that
# holds the whole suite's, so that none is pruned and compiled again mid-run
os.environ.setdefault("PCCL_CACHE_SIZE", "1G")

def started(args, ready=None, *, cwd=None, env=None, new_session=False, timeout=300):
    """Start ``python -m pccl.cli ARGS`` (standard output and error piped)
    and, with ``ready``, wait until its standard error says that text (a
    progress line: the search is under way); ``(process, standard error so
    far)``.  ``env``: variables set besides this one's; ``new_session``: in
    a session of its own (its own process group, as a terminal's job).  The
    process is the caller's to end (``communicate`` reads the rest of its
    output)."""
    import select
    import subprocess
    import sys
    import time
    import signal
    # SIGINT as a terminal's job has it, even when this suite was started from a
    # background job of a non-interactive shell (which starts it ignored, and an
    # ignored SIGINT is inherited: the signal tests would wait for ever)
    p = subprocess.Popen([sys.executable, "-m", "pccl.cli", *map(str, args)], cwd=cwd,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         env=None if env is None else {**os.environ, **env},
                         start_new_session=new_session,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    # read the descriptor itself: lines read ahead into the text buffer of
    # p.stderr would never make it readable again for select
    fd, seen = p.stderr.fileno(), b""
    deadline = time.monotonic() + timeout
    while ready is not None and ready.encode() not in seen:
        if time.monotonic() > deadline:
            p.kill()
            raise AssertionError(("never ready", seen.decode(errors="replace")))
        if select.select([fd], [], [], 1.0)[0]:
            chunk = os.read(fd, 65536)
            if not chunk:
                p.wait()
                raise AssertionError(("exited before it was ready", p.returncode,
                                      seen.decode(errors="replace")))
            seen += chunk
    return p, seen.decode(errors="replace")


def interrupted(args, sig, *, delay=3.0, cwd=None, attempts=3, ready=None, after=0.0):
    """Run ``python -m pccl.cli ARGS`` and send it ``sig`` (a name, such as
    ``"SIGTERM"``); ``(status, stdout, stderr)``.

    With ``ready``, the signal goes as soon as standard error says that
    text (:func:`started`), or ``after`` seconds later (a random point of
    the search).  Without, it goes after ``delay`` seconds; a
    process that dies of the signal itself (status ``-signum``) had not
    installed its handlers yet — a loaded machine spent the delay importing
    — which says nothing of pccl, so the run is tried again with twice the
    delay, up to ``attempts`` times."""
    import signal
    import subprocess
    import time
    signum = getattr(signal, sig)
    for attempt in range(attempts):
        p, seen = started(args, ready, cwd=cwd)
        if ready is None:
            time.sleep(delay * 2 ** attempt)
        else:
            time.sleep(after)
        p.send_signal(signum)
        try:
            out, err = p.communicate(timeout=120)
        except subprocess.TimeoutExpired:
            p.kill()            # never left running after the test
            p.communicate()
            raise
        err = seen + err
        if p.returncode != -signum or ready is not None:
            break
    return p.returncode, out, err


def cli(*args, cwd=None, **kw):
    """Run ``pccl ARGS`` in-process with click's CliRunner (``kw`` to
    ``invoke``: ``env``, ``input``...; ``cwd`` to run from a directory).
    No command may crash: an exception other than ``SystemExit`` is
    re-raised here with its traceback, and no output holds one."""
    from click.testing import CliRunner
    from pccl.cli import main
    old = os.getcwd()
    if cwd is not None:
        os.chdir(cwd)
    try:
        res = CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=True, **kw)
    finally:
        os.chdir(old)
    if res.exception is not None and not isinstance(res.exception, SystemExit):
        raise res.exception
    assert "Traceback" not in res.output, res.output
    return res


def reachable(m, limit=5000) -> list:
    """The reachable states of model m (at most ``limit``), depth first,
    one per key."""
    seen, out, todo = set(), [], list(m.init_states())
    while todo and len(out) < limit:
        st = todo.pop()
        k = m.key(st)
        if k in seen:
            continue
        seen.add(k)
        out.append(st)
        todo.extend(s for _, s in m.successors(st))
    return out


# the configuration's cells and values (pccl.model.layout), for the tests to read states by name
from pccl.model.layout import (AGS, AR, CNT, DISCRETE, DONE, DYNAMIC, ENV, EXITED, FAIL,  # noqa: F401,E402
                               IDLE, LCK, LOC, LOCK, LQ, OBSTACLES, PC, PHASE, POS, REACH, REQUEST,
                               RUNNING, SH, STATUS, T0, TARGET, TIME)


def model_of(src: str, *, blackbox="instant", agents=2, filename="t.pccl", **kw):
    """A Model of the program text ``src`` (dedented), instant blackbox by default."""
    prog = parse_program(textwrap.dedent(src).lstrip("\n"), filename)
    kw.setdefault("reduce", "none")     # the rules themselves
    return make_model(prog, blackbox=blackbox, agents=agents, **kw)


def sid(m, text: str, nth: int = 0) -> int:
    """The sid of the ``nth`` statement whose source line (stripped) starts with ``text``."""
    lines = m.program.source.splitlines()
    hits = sorted((s.span.line, s.span.column, k) for k, s in m.compiled.stmts.items()
                  if lines[s.span.line - 1].strip().startswith(text))
    assert len(hits) > nth, f"no statement starting with {text!r}"
    return hits[nth][2]


def sids(m, *texts) -> tuple:
    return tuple(sid(m, t) for t in texts)


def k_pc(m, *items) -> int:
    """Intern a k cell (statement sids and END / AEND / acq(sid) markers)."""
    return m.ctl.intern(tuple(items))


def k_of(m, ag) -> tuple:
    """The k cell (tuple) of an agent tuple."""
    return m.ctl.ks[ag[PC]]


def _slot(m, name):
    vs = m.compiled.layout.vars[name]
    return vs


def set_agent(m, st, i, *, pc=None, counter=None, lock=None, status=None, pos=None,
              reach=None, **values):
    """A copy of ``st`` with agent i's cells (and named variables) replaced."""
    ag = list(st[AGS][i])
    if pc is not None:
        ag[PC] = pc
    if counter is not None:
        ag[CNT] = counter
    if lock is not None:
        ag[LCK] = lock
    if status is not None:
        ag[STATUS] = status
    if pos is not None:
        ag[POS] = pos
    if reach is not None:
        ag[REACH] = reach
    loc, ar = list(ag[LOC]), list(ag[AR])
    for name, v in values.items():
        vs = _slot(m, name)
        if vs.section == "loc":
            loc[vs.slot] = v
        elif vs.section == "allread":
            ar[vs.slot] = v
        else:  # pragma: no cover - test misuse
            raise KeyError(f"{name} is shared: use set_state")
    ag[LOC], ag[AR] = tuple(loc), tuple(ar)
    ags = st[AGS]
    return st[:AGS] + (ags[:i] + (tuple(ag),) + ags[i + 1:],) + st[AGS + 1:]


def set_state(m, st, *, time=None, phase=None, lq=None, env=None, **values):
    """A copy of ``st`` with global cells (and named shared variables) replaced."""
    s = list(st)
    if time is not None:
        s[TIME] = time
    if phase is not None:
        s[PHASE] = phase
    if lq is not None:
        s[LQ] = tuple(lq)
    if env is not None:
        s[ENV] = env
    sh = list(s[SH])
    for name, v in values.items():
        vs = _slot(m, name)
        assert vs.section == "allwrite", name
        sh[vs.slot] = v
    s[SH] = tuple(sh)
    return tuple(s)


def var(m, st, i, name):
    """Agent i's value of a local or allread variable."""
    vs = m.compiled.layout.vars[name]
    if vs.section == "loc":
        return st[AGS][i][LOC][vs.slot]
    if vs.section == "allread":
        return st[AGS][i][AR][vs.slot]
    return st[SH][vs.slot]


def shared(m, st, name):
    vs = m.compiled.layout.vars[name]
    assert vs.section == "allwrite"
    return st[SH][vs.slot]


def succ(m, st, rule=None, agent="any"):
    """Successors of ``st``, optionally only those of ``rule`` (and ``agent``)."""
    return [(l, s) for l, s in m.successors(st)
            if (rule is None or l[0] == rule) and (agent == "any" or l[1] == agent)]


def labels(m, st, agent="any"):
    return [l for l, _ in m.successors(st) if agent == "any" or l[1] == agent]


def agent_rules(m, st, i):
    """The rule names enabled for agent i."""
    return sorted({l[0] for l, _ in m.successors(st) if l[1] == i})


def only(m, st, rule, agent="any"):
    """The one successor of ``rule`` (fails unless exactly one)."""
    out = succ(m, st, rule, agent)
    assert len(out) == 1, f"expected exactly one {rule} for agent {agent}, got {[l for l, _ in out]}"
    return out[0]


@pytest.fixture
def chdir_root(monkeypatch):
    """Run with the repository root as the working directory (for relative paths)."""
    monkeypatch.chdir(ROOT)
    return ROOT


# ---------------------------------------------------------------------------
# the quick subset: python -m pytest -m "not slow" (README, "Tests")
# ---------------------------------------------------------------------------

def portable_id(nodeid: str) -> str:
    """A test id as tests/slow_tests.txt writes it: a parameter that is the
    absolute path of a file of this checkout (``[/work/x/programs/a.pccl]``)
    relative to its root (``[programs/a.pccl]``), so that the id is the same
    in every clone."""
    return nodeid.replace(str(ROOT) + os.sep, "")


def _slow_ids() -> frozenset:
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "slow_tests.txt")
    with open(path, encoding="utf-8") as f:
        return frozenset(ln.strip() for ln in f if ln.strip() and not ln.startswith("#"))


SLOW_TESTS = _slow_ids()


def pytest_collection_modifyitems(config, items):
    """Mark the tests listed in tests/slow_tests.txt (measured: 0.25 s or
    more each) as ``slow``, so that ``-m "not slow"`` is a quick subset."""
    import pytest
    for item in items:
        if portable_id(item.nodeid) in SLOW_TESTS:
            item.add_marker(pytest.mark.slow)


def closure(m, st, limit: int = 20_000, key=None) -> list:
    """Brute force over the unreduced rules of model ``m``: ``(label, before,
    after)`` of every transition reachable from ``st`` (``after`` None: a
    terminal state), one expansion per key (``key``: ``m.key`` unless given).
    The stall and frozen-team tests' independent check."""
    from pccl.model.engine import Model
    key = key or m.key
    seen, todo, out = set(), [st], []
    while todo:
        s = todo.pop()
        k = key(s)
        if k in seen:
            continue
        seen.add(k)
        assert len(seen) < limit, "closure too large for a test"
        succ = Model.successors(m, s)
        if not succ:
            out.append((None, s, None))
        for lab, s2 in succ:
            out.append((lab, s, s2))
            todo.append(s2)
    return out


def verdict(res, *, lines: bool = True, holds: bool = False) -> tuple:
    """What two ways of computing an ``explore`` result must agree on (reduced
    and unreduced, native and Python...): the status and the violations as a
    set of (kind, name, line) (``lines=False``: (kind, name)); with ``holds``,
    also the set of properties that hold."""
    found = frozenset((v["kind"], v["name"], v["line"]) if lines else (v["kind"], v["name"])
                      for v in res.violations)
    return (res.status, found, frozenset(res.holds)) if holds else (res.status, found)


def cli_robust(*args):
    """:func:`cli` for inputs made to break it (mutants, truncations): the
    command exits 0, 1 or 2, and a 2 is one rendered error (``file:line:col:
    error:``) on standard error and nothing on standard output."""
    res = cli(*args)
    cmd = "pccl " + " ".join(map(str, args))
    assert res.exit_code in (0, 1, 2), f"{cmd}: exit {res.exit_code}\n{res.output}"
    if res.exit_code == 2:
        assert res.stderr.count(": error: ") == 1, f"{cmd}: not one rendered error:\n{res.stderr}"
        assert res.stdout == ""
    return res
