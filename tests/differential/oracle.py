"""The oracle's comparisons (issue 41, "The oracle").

A *mode* is one configuration of ``pccl explore`` (or of ``pccl run``
against ``explore``: ``covering``).  Every mode of a program is compared
with the truth, ``--reduce none --exact --engine python`` with one worker:

* **verdicts**, always: the status (``violation``/``exhaustive``/an error
  at load time) and the set of distinct violations, each as (kind,
  property name, line), found with ``--all``.  A reduction may show
  another counterexample, never another set (docs/reductions.md,
  "Evidence"); an error is compared by its message.
* **figures** (initial states, states, transitions, depth) where the docs
  promise equality: within a *figure group*, the modes that search the
  same graph: the same reductions on either engine (docs/reductions.md:
  the native engine's "states, transitions, depth, verdicts and
  counterexamples equal this module's"), one worker or several, threads
  or processes, Ray (docs/scale-out.md: "identical to one process"), a
  search interrupted, checkpointed and resumed (docs/scale-out.md: "the
  same states, transitions, depth, ... verdict"), fingerprints or
  ``--exact`` (equal unless two states collide: probability below 1e-30
  at these sizes).
* **covering** (docs/blackboxes.md, "What each blackbox covers"): every
  configuration of a seeded ``pccl run`` under ``straight`` (and
  ``pymunk`` where installed) is reachable under the default exploring
  blackbox, as far as the program observes it (statuses, variables,
  doReach flags; positions when the program or a property reads them), and
  a run's violation is found by ``explore``.

Bounded searches: every search runs with the same ``max_states``.  A
verdict is compared exactly only when the truth is exhaustive (complete);
when the truth is bounded, only what it found must be found by a complete
mode (a real violation cannot be missed), and the program is counted
*inconclusive*.  Figures are compared only between complete searches.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import traceback
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Optional

from pccl import api
from pccl.lang.errors import PcclError

from .gen import Case, parse

MAX_STATES = 5_000
REDUCTIONS = ("merge", "symmetry", "por", "dead", "counters")


@dataclass(frozen=True)
class Mode:
    name: str
    kw: tuple = ()              # explore keywords (sorted items)
    env: tuple = ()             # environment variables set during the search
    group: str = ""             # figure group: modes that search the same graph
    kind: str = "explore"       # explore | ckpt | covering
    cost: int = 1               # rough relative cost (native compiles, processes)
    koord_only: bool = False    # run on Koord programs under Koord's round semantics only

    @property
    def options(self) -> dict:
        return dict(self.kw)

    def cli(self) -> str:
        """The ``pccl explore`` flags of this mode."""
        out = []
        for k, v in self.kw:
            if v is True:
                out.append(f"--{k.replace('_', '-')}")
            elif k == "ray":
                out.append("--ray local")
            else:
                out.append(f"--{k.replace('_', '-')} {v}")
        if self.kind == "ckpt":
            out.append("--checkpoint ck/  (interrupt it, then: --resume ck/)")
        return " ".join(out)

    def env_prefix(self) -> str:
        return "".join(f"{k}={v} " for k, v in self.env)


def _m(name, group, kind="explore", env=(), cost=1, koord_only=False, **kw) -> Mode:
    return Mode(name, tuple(sorted(kw.items())), tuple(env), group, kind, cost, koord_only)


TRUTH = _m("truth", "none", reduce="none", exact=True, engine="python")
MODES = [
    TRUTH,
    _m("default", "auto", cost=3),
    _m("auto-python", "auto", engine="python"),
    _m("none-fingerprints", "none", reduce="none", engine="python"),
    _m("none-native", "none", reduce="none", cost=3),
    *[_m(f"{r}-python", r, reduce=r, engine="python") for r in REDUCTIONS],
    *[_m(f"{r}-native", r, reduce=r, cost=3) for r in REDUCTIONS],
    _m("merge+por-python", "merge,por", reduce="merge,por", engine="python"),
    _m("merge+por-native", "merge,por", reduce="merge,por", cost=3),
    _m("all-python", "all", reduce="merge,symmetry,por,dead", engine="python"),
    _m("all-native", "all", reduce="merge,symmetry,por,dead", cost=3),
    _m("all-exact", "all", reduce="merge,symmetry,por,dead", engine="python", exact=True),
    _m("workers2-threads", "auto", workers=2, cost=3),
    _m("workers2-processes", "auto", env=(("PCCL_THREADS", "0"),), workers=2, cost=6),
    _m("workers2-python", "auto", engine="python", workers=2, cost=6),
    _m("ray-local", "auto", ray="local", workers=2, cost=20),
    _m("checkpoint-native", "auto", kind="ckpt", cost=4),
    _m("checkpoint-python", "auto", kind="ckpt", engine="python", cost=2),
    _m("covering", "", kind="covering", cost=2),
    _m("symmetry-orbits", "", kind="orbits", cost=1),
    # Koord's round semantics (docs/koord.md): --events first (the deployed
    # runtime's choice) reaches a subset of the states --events any reaches,
    # SkipEvent a superset, so their safety violations are included in, and
    # include, the truth's
    _m("koord-events-first", "", kind="subset", reduce="none", exact=True, engine="python",
       events="first"),
    _m("koord-skip-events", "", kind="superset", reduce="none", exact=True, engine="python",
       skip_events=True),
    # dead variables under Koord's round semantics (docs/koord.md, "Reductions
    # under the round semantics"), alone (run on every Koord program) and with
    # symmetry (drawn), against the truth
    _m("koord-dead", "dead", reduce="dead", engine="python", koord_only=True),
    _m("koord-dead-symmetry", "symmetry,dead", reduce="symmetry,dead", engine="python",
       koord_only=True),
]
BY_NAME = {m.name: m for m in MODES}
#: the violations that are properties of one state (a state reached under
#: both semantics compared shows the same ones): what the subset and
#: superset modes compare
SAFETY_KINDS = frozenset({"invariant", "stuck", "assertion", "collision"})


@dataclass
class Outcome:
    """What a mode says about a program."""
    status: str                          # violation | exhaustive | bounded | error | crash | n/a
    violations: frozenset = frozenset()  # {(kind, name, line)}
    figures: Optional[tuple] = None      # (initial, states, transitions, depth) of a complete search
    complete: bool = False               # no bound cut the search
    detail: str = ""                     # an error's message, a crash's traceback, why n/a
    engine: str = ""


@dataclass
class Disagreement:
    seed: int
    family: str
    check: str                           # verdict | figures | covering | crash
    mode: str
    against: str
    detail: str
    known: Optional[str] = None          # a known open hole it matches (KNOWN)
    missed: frozenset = frozenset()      # (verdict) violations of the truth this mode misses

    def signature(self) -> tuple:
        return (self.check, self.mode, self.against)


@dataclass
class Report:
    seed: int
    family: str
    outcomes: dict = field(default_factory=dict)
    disagreements: list = field(default_factory=list)
    inconclusive: bool = False
    agreements: int = 0


class Files:
    """The case's world and blackbox written to a temporary directory."""

    def __init__(self, case: Case):
        self.dir = tempfile.mkdtemp(prefix="pccl-oracle-")
        self.world = self.bb = None
        if case.world:
            self.world = os.path.join(self.dir, "world.toml")
            with open(self.world, "w") as f:
                f.write(case.world)
        if case.blackbox:
            self.bb = os.path.join(self.dir, f"userbb_{abs(hash(case.blackbox)) % 10**8}.py")
            with open(self.bb, "w") as f:
                f.write(case.blackbox)

    def close(self):
        shutil.rmtree(self.dir, ignore_errors=True)


def base_kw(case: Case, files: Files) -> dict:
    kw = dict(source=True, find_all=True, max_states=MAX_STATES,
              invariants=list(case.invariants), properties=list(case.properties), **case.options)
    if case.agents is not None:
        kw["agents"] = case.agents
    if files.world:
        kw["world"] = files.world
    if files.bb:
        kw["blackbox"] = f"{files.bb}:BLACKBOX"
    return kw


@contextmanager
def _env(pairs):
    old = {k: os.environ.get(k) for k, _ in pairs}
    os.environ.update(dict(pairs))
    try:
        yield
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _outcome(r) -> Outcome:
    complete = not r.bounds and r.status in ("violation", "exhaustive")
    s = r.stats
    figs = (s.initial_states, s.states, s.transitions, s.max_depth) if complete else None
    viol = frozenset((v.kind, v.name, v.line) for v in r.violations)
    return Outcome(r.status, viol, figs, complete, r.verdict,
                   getattr(r.model, "engine_used", "") or "")


class _Interrupt:
    """A progress callback that interrupts the search at its ``k``-th call."""

    def __init__(self, k: int):
        self.k, self.calls = k, 0

    def __call__(self, p) -> None:
        self.calls += 1
        if self.calls == self.k:
            raise KeyboardInterrupt


def _checkpointed(prog, kw: dict, files: Files) -> Outcome:
    """Interrupted at its second progress call, checkpointed, resumed (as
    often as it takes) until it ends."""
    d = os.path.join(files.dir, "ck")
    shutil.rmtree(d, ignore_errors=True)
    resumed = 0
    for _ in range(20):
        # interrupted one progress call later at each resume: a level that
        # reports progress twice (the native kernel's) is resumed from its
        # start, so a fixed cut could interrupt it there for ever
        extra = dict(checkpoint=d, progress_interval=1e-9, progress=_Interrupt(2 + resumed))
        if os.path.exists(d) and os.listdir(d):
            extra["resume"] = d
            resumed += 1
        r = api.explore(prog, **kw, **extra)
        if r.status != "interrupted":
            out = _outcome(r)
            out.detail += f" (resumed {resumed} times)"
            return out
    return Outcome("n/a", detail="never finished")


@contextmanager
def _no_turn_cache(on: bool):
    """Under Koord's round semantics the truth computes every robot's turn
    afresh (no turn table: pccl.model.koord.KoordModel.TURN_CACHE 0), so
    that the table's key is checked by every other mode."""
    from pccl.model.koord import KoordModel
    old = KoordModel.TURN_CACHE
    if on:
        KoordModel.TURN_CACHE = 0
    try:
        yield
    finally:
        KoordModel.TURN_CACHE = old


def koord_rounds(case: Case) -> bool:
    """Whether ``case`` runs under Koord's round semantics."""
    return case.lang == "koord" and case.options.get("semantics", "koord") == "koord"


def explore_mode(case: Case, mode: Mode, prog, files: Files) -> Outcome:
    kw = base_kw(case, files)
    kw.update(mode.options)
    if "ray" in kw:
        try:
            import ray  # noqa: F401
        except ImportError:
            return Outcome("n/a", detail="ray is not installed")
    try:
        with _env(mode.env), _no_turn_cache(mode.name == "truth"):
            if mode.kind == "ckpt":
                return _checkpointed(prog, kw, files)
            return _outcome(api.explore(prog, **kw))
    except PcclError as e:
        msg = str(e).splitlines()[0] if str(e) else type(e).__name__
        if "unsound here" in msg or "needs two or more agents" in msg or "cannot be used here" in msg \
                or "engine" in msg and "native" in msg:
            return Outcome("n/a", detail=msg)
        if "cannot start or reach Ray" in msg:
            # the machine, not the checker: Ray's own start-up timed out
            # (seen at load 14-23 on 2 cores); no verdict to compare
            return Outcome("n/a", detail=msg)
        return Outcome("error", detail=msg)
    except KeyboardInterrupt:
        raise
    except BaseException:
        return Outcome("crash", detail=traceback.format_exc()[-2500:])


# ---------------------------------------------------------------------------
# covering: run under straight/pymunk against explore under the default
# ---------------------------------------------------------------------------

RUN_SEEDS = (0, 1, 2)


def _observer(model, with_pos: bool):
    from pccl.model.layout import AGS, AR, DONE, FAIL, LOC, POS, REACH, SH, STATUS

    def obs(st):
        return (st[SH], tuple((ag[STATUS], ag[LOC], ag[AR], ag[REACH][DONE], ag[REACH][FAIL],
                               ag[POS] if with_pos else None) for ag in st[AGS]))
    return obs


def _reads_positions(case: Case) -> bool:
    texts = [case.text] + list(case.invariants) + list(case.properties)
    return any("getPosition" in t or "pos[" in t for t in texts)


def covering(case: Case, prog, files: Files) -> tuple:
    """(Outcome, [problems]): runs under ``straight`` (and ``pymunk``)
    against every state ``explore`` reaches under the default blackbox."""
    if any(t in case.text for t in ("getPosition", "Motion.position", "Motion.psn")):
        # positions in mid-motion: nondet does not claim to cover them
        # (docs/blackboxes.md; explore says "not exhaustive for straight/pymunk")
        return Outcome("n/a", detail="the program reads positions in mid-motion"), []
    kw = base_kw(case, files)
    for k in ("find_all", "max_states", "properties", "blackbox"):
        kw.pop(k, None)
    bb, _ = api.explore_blackbox(api.load_program(prog, source=True))
    try:
        m = api.make_model(prog, blackbox=bb, reduce="none", **kw)
    except PcclError as e:
        return Outcome("error", detail=str(e).splitlines()[0]), []
    obs = _observer(m, _reads_positions(case))
    seen, reach, todo = set(), set(), list(m.init_states())
    while todo:
        if len(seen) > MAX_STATES * 4:
            return Outcome("bounded", detail="explore too large for covering"), []
        st = todo.pop()
        k = m.key(st)
        if k in seen:
            continue
        seen.add(k)
        reach.add(obs(st))
        todo.extend(s for _, s in m.successors(st))
    runners = ["straight"]
    try:
        import pymunk  # noqa: F401
        runners.append("pymunk")
    except ImportError:
        pass
    problems = []
    for runner in runners:
        for seed in RUN_SEEDS:
            try:
                res = api.run(prog, blackbox=runner, seed=seed, max_time=30, record_trace=True,
                              **kw)
            except PcclError as e:
                problems.append(f"run -b {runner} --seed {seed}: error {str(e).splitlines()[0]}")
                continue
            states = res.trace.states if res.trace is not None else (res.final,)
            for n, st in enumerate(states):
                if obs(st) not in reach:
                    problems.append(
                        f"pccl run -b {runner} --seed {seed} ({res.status}: {res.message}) passes "
                        f"through a configuration (step {n}) that explore under {bb} never reaches")
                    break
    return Outcome("exhaustive", detail=f"{len(reach)} observable configurations under {bb}"), problems


# ---------------------------------------------------------------------------
# symmetry, state by state (tests/symattack.py's orbits_agree)
# ---------------------------------------------------------------------------

def orbits(case: Case, prog, files: Files) -> tuple:
    """Where ``auto`` keeps symmetry on: over the unreduced reachable states,
    states with one canonical key have the same successor keys and the same
    violations (the soundness argument itself, finer than a verdict)."""
    if koord_rounds(case):
        # under Koord's round semantics a state in the middle of a round is
        # keyed exactly (pccl.model.reduce.koord_symmetric_key): symmetric
        # states then have successors with different keys by design, so this
        # state-by-state check does not apply; the verdicts are compared
        return Outcome("n/a", detail="mid-round states are keyed exactly"), None
    kw = base_kw(case, files)
    for k in ("find_all", "max_states", "source", "invariants", "agents"):
        kw.pop(k, None)
    if not kw.get("properties"):
        kw.pop("properties", None)
    kw.setdefault("blackbox", api.explore_blackbox(api.load_program(prog, source=True))[0])
    try:
        plan = api.make_model(prog, source=True, agents=case.agents, reduce="auto",
                              invariants=list(case.invariants), **kw).reduction
    except PcclError as e:
        return Outcome("n/a", detail=str(e).splitlines()[0]), None
    if "symmetry" not in plan.on:
        return Outcome("n/a", detail="symmetry off"), None
    from .gen import _attack_module
    try:
        ok = _attack_module("symattack").orbits_agree(prog, case.agents, list(case.invariants),
                                                      limit=MAX_STATES, **kw)
    except PcclError as e:     # an initialiser's error (every mode reports it): nothing to check
        return Outcome("n/a", detail=str(e).splitlines()[0]), None
    if ok:
        return Outcome("exhaustive", detail="orbits agree"), None
    return (Outcome("violation", detail="orbits differ"),
            "two states with one symmetry key have different successor keys or violations")


# ---------------------------------------------------------------------------
# one program
# ---------------------------------------------------------------------------

def choose_modes(names, seed: int, sample: int = 0) -> list:
    """The modes to run for program ``seed``: ``names`` ("all" or a list),
    or with ``sample`` > 0 the truth, the default, the Koord modes and
    ``sample`` others drawn by the seed (a fixed budget sees every mode over many programs)."""
    import random
    pool = [m for m in MODES if names == "all" or m.name in names]
    if sample <= 0:
        return pool
    rng = random.Random(seed)
    # the Koord modes are always run (only on Koord programs: cheap, and
    # the only check of --events first and SkipEvent)
    # (and koord-dead: dead variables under the round semantics; the other
    # Koord-only mode, koord-dead-symmetry, is drawn like the rest)
    fixed = ("truth", "default", "koord-dead") + tuple(m.name for m in MODES
                                                       if m.kind in ("subset", "superset"))
    rest = [m for m in pool if m.name not in fixed]
    picked = rng.sample(rest, min(sample, len(rest)))
    return [m for m in pool if m.name in fixed or m in picked]


def compare(case: Case, modes: list) -> Report:
    rep = Report(case.seed, case.family)
    files = Files(case)
    try:
        try:
            prog = parse(case)
        except PcclError as e:
            rep.outcomes["truth"] = Outcome("invalid", detail=str(e))
            return rep
        truth = explore_mode(case, TRUTH, prog, files)
        rep.outcomes["truth"] = truth
        if truth.status == "crash":
            rep.disagreements.append(Disagreement(case.seed, case.family, "crash", "truth", "",
                                                  truth.detail))
        if truth.status in ("crash", "n/a"):
            return rep
        rep.inconclusive = not truth.complete and truth.status != "error"
        first_in_group: dict = {"none": "truth"}
        for mode in modes:
            if mode.name == "truth" or mode.koord_only and not koord_rounds(case):
                continue
            if mode.kind == "covering":
                if not case.moves or case.blackbox or truth.status == "error":
                    continue
                out, problems = covering(case, prog, files)
                rep.outcomes[mode.name] = out
                for p in problems:
                    rep.disagreements.append(Disagreement(case.seed, case.family, "covering",
                                                          "covering", "truth", p))
                if out.status == "exhaustive" and not problems:
                    rep.agreements += 1
                continue
            if mode.kind == "orbits":
                out, problem = orbits(case, prog, files)
                rep.outcomes[mode.name] = out
                if problem:
                    rep.disagreements.append(Disagreement(case.seed, case.family, "orbits",
                                                          mode.name, "", problem))
                elif out.status == "exhaustive":
                    rep.agreements += 1
                continue
            if mode.kind in ("subset", "superset"):
                if not koord_rounds(case):
                    continue
                out = explore_mode(case, mode, prog, files)
                rep.outcomes[mode.name] = out
                d = inclusion_difference(truth, out, mode.kind, guard_lines(prog))
                if d:
                    rep.disagreements.append(Disagreement(
                        case.seed, case.family, "crash" if out.status == "crash" else "inclusion",
                        mode.name, "truth", d))
                elif out.status != "n/a":
                    rep.agreements += 1
                continue
            out = explore_mode(case, mode, prog, files)
            rep.outcomes[mode.name] = out
            if out.status == "n/a":
                continue
            d = verdict_difference(truth, out)
            if d:
                rep.disagreements.append(Disagreement(case.seed, case.family,
                                                      "crash" if out.status == "crash" else "verdict",
                                                      mode.name, "truth", d,
                                                      missed=truth.violations - out.violations))
                continue
            ok = True
            ref_name = first_in_group.setdefault(mode.group, mode.name)
            ref = rep.outcomes.get(ref_name)
            if ref_name != mode.name and ref is not None and ref.figures and out.figures \
                    and ref.figures != out.figures:
                ok = False
                rep.disagreements.append(Disagreement(
                    case.seed, case.family, "figures", mode.name, ref_name,
                    f"(initial, states, transitions, depth) {out.figures} [{out.engine}] "
                    f"vs {ref.figures} [{ref.engine}]"))
            rep.agreements += ok
    finally:
        files.close()
    for d in rep.disagreements:
        d.known = known_hole(case, d)
    return rep


def verdict_difference(truth: Outcome, out: Outcome) -> Optional[str]:
    if out.status == "crash":
        return out.detail
    if truth.status == "error" or out.status == "error":
        if truth.status == out.status and truth.detail == out.detail:
            return None
        return f"{out.status}: {out.detail} vs truth {truth.status}: {truth.detail}"
    if truth.complete and out.complete:
        if truth.status != out.status or truth.violations != out.violations:
            return (f"{out.status} {sorted(out.violations, key=str)} vs truth {truth.status} "
                    f"{sorted(truth.violations, key=str)}")
        return None
    if out.complete and not truth.violations <= out.violations:
        # the truth's violations are real; a complete search must find them
        return (f"complete search misses {sorted(truth.violations - out.violations, key=str)} "
                f"found by the (bounded) truth")
    return None


def guard_lines(prog) -> frozenset:
    """The lines of the program's event guards."""
    return frozenset(ev.guard.span.line for ev in prog.events
                     if getattr(ev.guard, "span", None) is not None)


def inclusion_difference(truth: Outcome, out: Outcome, kind: str,
                         guards: frozenset = frozenset()) -> Optional[str]:
    """A ``subset`` mode (``--events first``) finds no safety violation the
    complete truth misses; a complete ``superset`` mode (SkipEvent) finds
    every one the truth found.  A load-time error is the same message.

    The subset claim needs every guard to evaluate: ``--events first``
    evaluates the guards in source order and stops at the first that holds
    (the paper's EVENT SELECT: "if C evaluates to false, this block rewrites
    to Es"), ``--events any`` evaluates them all and an error in any of them
    gets the agent stuck (docs/language.md §9), so where a later guard fails
    the first event runs under ``first`` and not under ``any`` (seed 1800212,
    2026-12-07).  When the truth has an agent stuck at a guard's line
    (``guards``), the subset claim is not made."""
    if out.status == "crash":
        return out.detail
    if truth.status == "error" or out.status == "error":
        if truth.status == out.status and truth.detail == out.detail:
            return None
        return f"{out.status}: {out.detail} vs truth {truth.status}: {truth.detail}"
    mine = {v for v in out.violations if v[0] in SAFETY_KINDS}
    theirs = {v for v in truth.violations if v[0] in SAFETY_KINDS}
    guard_error = any(v[0] == "stuck" and len(v) > 2 and v[2] in guards for v in truth.violations)
    if kind == "subset" and truth.complete and not guard_error and not mine <= theirs:
        return (f"finds {sorted(mine - theirs, key=str)}, which the complete truth "
                f"(a superset of its states) does not")
    if kind == "superset" and out.complete and not theirs <= mine:
        return f"complete search misses {sorted(theirs - mine, key=str)} found by the truth (a subset of its states)"
    return None


# ---------------------------------------------------------------------------
# known open holes (issue 41): reported, not failed, until the fixes land
# ---------------------------------------------------------------------------

def known_hole(case: Case, d: Disagreement) -> Optional[str]:
    """The hole of issue 41 that ``d`` matches, if any (an entry goes when its
    fix is merged: the CI test then fails on it)."""
    # issue 41's holes 1-6 are fixed: a disagreement of their shape is a
    # finding again (the teeth re-open each by a monkeypatch); so are the
    # crashes this oracle found (W1, C1, R1: tests in test_parallel.py and
    # test_checkpoint.py)
    return None
