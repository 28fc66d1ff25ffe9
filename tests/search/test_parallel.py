"""``--workers N``: the parallel search gives exactly the one-process results
(states, transitions, depth, bounds, verdict and the very counterexample)."""

import subprocess
import sys

import pytest

from conftest import cli, started
from pccl.api import explore, make_model
from pccl.model.layout import TIME
from pccl.search.explorer import Explorer
from pccl.search.parallel import ParallelExplorer, available_workers

FISCHER = "programs/fischer.pccl"
RACE_WORLD = "programs/race.toml"
MUTEX = "count(inCs) <= 1"


def signature(r):
    # max_time: the largest model time (gathered from the workers; it was None)
    return (r.status, r.exit_status, r.stats.states, r.stats.transitions, r.stats.max_depth,
            r.stats.initial_states, r.stats.max_time, r.bounds,
            [(v["kind"], v["name"], v["line"], v["depth"]) for v in r.violations],
            [cx.index for cx in r.counterexamples],
            [cx.trace and tuple(cx.trace.labels) for cx in r.counterexamples],
            [v["trace"] for v in r.violations])


def result_signature(r):
    """The same for a :class:`SearchResult` (Explorer.run)."""
    s = r.stats
    return (r.status, s.states, s.transitions, s.max_depth, s.initial_states, s.frontier,
            sorted(map(str, r.bounds_hit)),
            [(f.violation.kind, f.index, f.depth, f.trace and tuple(f.trace.labels))
             for f in r.found])


CASES = {
    "fischer-exhaustive": (FISCHER, dict(overrides={"k": "0", "d": "1"})),
    "fischer-violation": (FISCHER, dict(overrides={"k": "1"}, invariants=[MUTEX])),
    "fischer-all": (FISCHER, dict(overrides={"k": "0"}, invariants=[MUTEX], find_all=True)),
    "fischer-max-states": (FISCHER, dict(overrides={"k": "1", "d": "1"}, max_states=3000)),
    "fischer-depth": (FISCHER, dict(overrides={"k": "1", "d": "1"}, depth=15)),
    "fischer-max-time": (FISCHER, dict(overrides={"k": "0", "d": "1"}, max_time=2)),
    "fischer-reduce-auto": (FISCHER, dict(overrides={"k": "1"}, invariants=[MUTEX],
                                          reduce="auto")),
    "race-nonatomic-stuck": ("programs/race_nonatomic.pccl",
                             dict(world=RACE_WORLD, blackbox="nondet", agents=3)),
    "race-nonatomic-all": ("programs/race_nonatomic.pccl",
                           dict(world=RACE_WORLD, blackbox="nondet", agents=2, find_all=True)),
    "race-safe": ("programs/race_safe.pccl", dict(world=RACE_WORLD, blackbox="nondet")),
    "leader": ("programs/leader.pccl", dict(agents=3, max_states=20_000)),
    "rendezvous": ("programs/rendezvous.pccl", dict(world="programs/rendezvous.toml",
                                                     max_states=20_000)),
    "collide": ("programs/collide.pccl", dict(world="programs/collide.toml", collisions=True)),
    "formation": ("programs/formation.pccl", dict(world="programs/formation.toml",
                                                   max_states=5_000)),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_workers_give_the_one_process_results(name):
    program, opts = CASES[name]
    one = signature(explore(program, **opts))
    for w in (2, 3):
        assert signature(explore(program, workers=w, **opts)) == one, f"workers={w}"


def test_deadlock_and_stuck_stop_events_in_serial_order():
    """race_nonatomic with --all has a stuck agent and a deadlock; with
    several workers they are found at the same state numbers."""
    m = make_model("programs/race_nonatomic.pccl", world=RACE_WORLD, blackbox="nondet", agents=3)
    a = Explorer(m, find_all=True).run()
    b = ParallelExplorer(m, workers=2, find_all=True).run()
    assert [(f.violation.kind, f.index, f.depth) for f in a.found] == \
        [(f.violation.kind, f.index, f.depth) for f in b.found]
    assert {f.violation.kind for f in a.found} >= {"stuck", "deadlock"}


#: an agent stuck in its initialiser for one ``rand`` outcome (the
#: coordinator meets that reason while it makes the initial states); with
#: ``--all`` the search goes on and another worker expands successors that
#: carry the stuck status (oracle finding W1: ``KeyError`` in the worker)
STUCK_IN_INIT = """\
allwrite:
  int s = rand(2) - 1;
  List<int> q0 = [7, 8];
loc:
  int x = q0[rand(2)];
"""


@pytest.mark.parametrize("engine,fastest", [("python", False), ("python", True),
                                           ("native", False)])
def test_a_stuck_reason_met_by_one_process_is_named_by_every_worker(tmp_path, monkeypatch,
                                                                   engine, fastest):
    monkeypatch.setenv("PCCL_THREADS", "0")      # the native engine's workers: processes
    prog = tmp_path / "stuck_in_init.pccl"
    prog.write_text(STUCK_IN_INIT)
    opts = dict(agents=2, find_all=True, engine=engine, fastest=fastest)
    if engine == "python":
        opts["properties"] = ["eventually s > 0"]
    serial = explore(str(prog), **opts)
    assert any("index 2 out of range" in v["message"] for v in serial.violations)
    one = signature(serial)
    for w in (2, 3):
        assert signature(explore(str(prog), workers=w, **opts)) == one, f"workers={w}"


def _fps(*pairs):
    import numpy as np
    return np.array(pairs, dtype=np.uint64).reshape(-1, 2)


def test_owner_keeps_the_smallest_key_of_equal_fingerprints():
    """An owner merging candidates from several generators: equal
    fingerprints keep the smallest key, whichever generator sent it, and
    distinct fingerprints that share their low word (which the merge sorts
    by first) both stay."""
    import numpy as np
    from pccl.search import parallel as P
    m = make_model(FISCHER, overrides={"k": "0"})
    w = P._Worker(m, 0, 2, True, False)
    # mine (kept by the step, never sent): fingerprints A and B
    w.own = (_fps(1, 10, 2, 20), np.array([5, 9], dtype=np.uint64))
    # from generator 1: A again with a smaller key, C sharing B's low word, D
    other = (_fps(1, 10, 3, 20, 4, 40), np.array([3, 7, 8], dtype=np.uint64))
    keys = w.decide(None, other)
    got = {tuple(f): int(k) for f, k in zip(w.pending[0].tolist(), w.pending[1].tolist())}
    assert got == {(1, 10): 3, (2, 20): 9, (3, 20): 7, (4, 40): 8}
    assert sorted(keys.tolist()) == [3, 7, 8, 9]
    # once B and D are committed (numbers 0 and 1), a later level's B is old
    ranks = np.array([got[tuple(f)] for f in w.pending[0].tolist()])
    w.commit((0, 4, np.argsort(np.argsort(ranks)), np.zeros(0, np.uint64),
              np.zeros(0, np.int64)))
    w.own = None
    assert w.decide(None, (_fps(2, 20, 5, 50), np.array([1, 2], dtype=np.uint64))).tolist() == [2]


def test_discarded_states_are_freed():
    """States the pipes transport frees while waiting do not outlive the search."""
    from pccl.search import parallel_worker as P
    m = make_model(FISCHER, overrides={"k": "0", "d": "1"}, reduce="merge,symmetry,por")
    r = ParallelExplorer(m, workers=2).run()
    assert r.stats.states > 1000 and P._LITTER == []


class _SlowIn:
    """A model whose successors take ``delay`` seconds longer in the
    coordinator's process (``coordinator=True``) or in the forked workers':
    one worker slowed down, as by another job on its core."""

    def __init__(self, model, coordinator: bool, delay: float):
        import os
        self.model, self.pid, self.coordinator, self.delay = model, os.getpid(), coordinator, delay

    def __getattr__(self, name):
        return getattr(self.model, name)

    def successors(self, s):
        import os
        import time
        if (os.getpid() == self.pid) == self.coordinator:
            time.sleep(self.delay)
        return self.model.successors(s)


@pytest.mark.parametrize("slow, workers, fastest", [("coordinator", 2, False),
                                                     ("forked", 2, False), ("forked", 3, False),
                                                     ("forked", 2, True)])
def test_a_slowed_worker_hands_work_over_with_the_same_results(slow, workers, fastest,
                                                               monkeypatch):
    """Balanced levels: when one worker is slow, the others expand part of
    its share (and hold the successors).  Every figure, the violations and
    the counterexamples stay those of one process, and the states did move
    (both ways: the coordinator's worker hands work to a hungry forked
    worker, and steals from a slow one).  Small chunks, for these small
    levels (forked workers inherit them)."""
    from pccl.search import parallel_pipes as P
    monkeypatch.setattr(P, "_CHUNK", 4)
    monkeypatch.setattr(P, "_MIN_GIVE", 2)
    monkeypatch.setattr(P, "_BALANCE_LEVEL", 0)
    for opts in (dict(overrides={"k": "0", "d": "1"}, max_states=3000),
                 dict(overrides={"k": "1"}, invariants=[MUTEX], find_all=True, max_states=4000)):
        m = make_model(FISCHER, overrides=opts["overrides"], invariants=opts.get("invariants", ()),
                       reduce="merge,symmetry,por")
        run = {k: v for k, v in opts.items() if k in ("max_states", "find_all")}
        if fastest:
            from pccl.search.fastest import FastestExplorer
            one = FastestExplorer(m, **run).run()
        else:
            one = Explorer(m, **run).run()
        e = ParallelExplorer(_SlowIn(m, slow == "coordinator", 0.0005), workers=workers,
                             fastest=fastest, **run)
        many = e.run()
        assert e.moved > 10, e.moved
        assert result_signature(many) == result_signature(one)
        assert one.found or one.status == "bounded"


def test_small_levels_are_not_balanced():
    """Levels under _BALANCE_LEVEL states keep the static split (a request
    for work costs a wait for the other worker): nothing moves, even with
    one worker slowed down."""
    from pccl.search import parallel_pipes as P
    m = make_model(FISCHER, overrides={"k": "0", "d": "1"}, reduce="merge,symmetry,por")
    e = ParallelExplorer(_SlowIn(m, False, 0.0002), workers=2, max_states=2000)
    assert e.run().stats.states == 2000
    assert e.moved == 0 and P._BALANCE_LEVEL > 1000


def test_waiting_blocks_when_the_cores_are_taken(monkeypatch):
    """A waiting process polls only while no more processes are runnable
    than the machine has cores (the kernel's count, read each time: a
    pinned worker's own single core does not count); without that count,
    while the load average is at most four times the cores (read at most
    once a second)."""
    import os
    from pccl.search import parallel_pipes as P
    cores = os.cpu_count()
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0})    # as if pinned
    assert P._runnable() is None or P._runnable() >= 1      # this process runs
    for now, want in ((cores + 1, True), (cores, False), (1, False)):
        monkeypatch.setattr(P, "_runnable", lambda now=now: now)
        assert P._overloaded() is want
    monkeypatch.setattr(P, "_runnable", lambda: None)
    for load, want in ((4 * cores + 0.5, True), (4 * cores - 0.5, False)):
        monkeypatch.setattr(os, "getloadavg", lambda load=load: (load, load, load))
        monkeypatch.setattr(P, "_LOAD", [0.0, not want])
        assert P._overloaded() is want
        monkeypatch.setattr(os, "getloadavg", lambda: (0.0, 0.0, 0.0))
        assert P._overloaded() is want          # cached within the second


PIN = r"""
import os, sys
from pccl.search import parallel_pipes as P
cpus = sorted(os.sched_getaffinity(0))
n = len(cpus)
print(P._pin(n - 1, n + 1), sorted(os.sched_getaffinity(0)) == cpus)   # more workers than cores
had = P._pin(n - 1, n)
print(had == set(cpus) if n > 1 else had is None, sorted(os.sched_getaffinity(0)))
P._PIN = False
os.sched_setaffinity(0, cpus)
print(P._pin(0, n))
"""


@pytest.mark.skipif(not hasattr(__import__("os"), "sched_setaffinity"), reason="Linux only")
def test_workers_are_pinned_only_when_as_many_as_the_cores():
    """_pin: a worker gets one core of its own when the workers are exactly
    as many as the cores this process may use, and says which cores it had
    (to restore); not with more workers than cores, nor with PCCL_PIN=0."""
    import os
    cpus = sorted(os.sched_getaffinity(0))
    r = subprocess.run([sys.executable, "-c", PIN], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert lines[0] == "None True"
    assert lines[1] == (f"True [{cpus[-1]}]" if len(cpus) > 1 else f"True {cpus}")
    assert lines[2] == "None"


@pytest.mark.skipif(not hasattr(__import__("os"), "sched_setaffinity"), reason="Linux only")
def test_a_pinned_search_gives_its_cores_back():
    """With as many workers as cores (pinned), the coordinator's process has
    all its cores again after the search, and the results are the one
    process's."""
    import os
    cpus = os.sched_getaffinity(0)
    kw = dict(overrides={"k": "1", "d": "1"}, reduce="none", timelock=False, stall=False)
    one = explore("programs/fischer.pccl", **kw)
    many = explore("programs/fischer.pccl", workers=max(2, len(cpus)), **kw)
    assert os.sched_getaffinity(0) == cpus
    assert (many.stats.states, many.stats.transitions, many.stats.max_depth) == \
        (one.stats.states, one.stats.transitions, one.stats.max_depth)


LARGE_LEVEL = r"""
import numpy as np
from pccl.search import parallel as P
from pccl.api import make_model
m = make_model("programs/fischer.pccl", overrides={"k": "0"})
m.prepare()
big = 300_000                   # 7 MB of candidates each way, beyond any socket buffer

def finish_step(self):
    f = np.arange(2 * big, dtype=np.uint64).reshape(-1, 2) * np.uint64(2) + np.uint64(self.wid)
    k = np.arange(big, dtype=np.uint64)
    self.own = (f[:0], k[:0])
    return (*[None if o == self.wid else (f, k) for o in range(self.n)],
            (big, [], None, None, [], 0, np.zeros(0, np.int64)))

def step(self, decision, at_bound):
    return finish_step(self)

P._Worker.step = step               # PCCL_BALANCE=0
P._Worker.finish_step = finish_step     # balanced levels
t = P._Pipes(2)
t.start(m, True, False)
try:
    rest, new = t.level([(None, False), (None, False)], 1 << 20)
    print(len(new[0]), len(new[1]), rest[1][0])
finally:
    t.stop()
"""


@pytest.mark.parametrize("balance", ["1", "0"])
def test_pipes_exchange_large_levels_without_deadlock(balance):
    """Two workers whose candidates for each other exceed the socket
    buffers: the pipelined level must not leave both writing at once
    (balanced levels, and with ``PCCL_BALANCE=0``)."""
    import os
    r = subprocess.run([sys.executable, "-c", LARGE_LEVEL], capture_output=True, text=True,
                       timeout=120, env=dict(os.environ, PCCL_BALANCE=balance))
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["300000", "300000", "300000"]


def test_exact_needs_one_process():
    from pccl.lang.errors import PcclError
    with pytest.raises(PcclError, match="one process"):
        explore(FISCHER, overrides={"k": "0"}, exact=True, workers=2)


def test_cli_workers_option():
    # in this process (conftest.cli): the option is tested, not a process's start
    base = ["explore", FISCHER, "--set", "k=1",
            "--invariant", MUTEX, "--no-progress", "--format", "json"]
    one = cli(*base)
    two = cli(*base, "--workers", "2")
    assert one.exit_code == two.exit_code == 1
    import json
    a, b = json.loads(one.stdout), json.loads(two.stdout)
    for k in ("states", "transitions", "max_depth"):
        assert a["statistics"][k] == b["statistics"][k]
    assert a["violations"] == b["violations"]
    bad = cli(*base, "--workers", "zero")
    assert bad.exit_code == 2 and "Traceback" not in bad.stderr
    assert available_workers() >= 1


# ---------------------------------------------------------------------------
# The Ray backend (``--ray``): the same partitioned search, actors as workers
# ---------------------------------------------------------------------------

def _ray():
    try:
        import ray
    except ImportError:
        pytest.skip("ray is not installed (pip install 'pccl[ray]')")
    return ray


@pytest.fixture(scope="module")
def local_ray():
    """One local Ray instance for the module (start-up costs seconds); the
    explorer uses an existing connection and leaves it open."""
    ray = _ray()
    import logging
    ray.init(num_cpus=2, include_dashboard=False, logging_level=logging.WARNING,
             log_to_driver=False)
    yield ray
    ray.shutdown()


# Few cases (each run creates its actors): the partitioning code is the one
# the pipe tests above cover for every program; these check the transport.
RAY_CASES = [("fischer-violation", 2), ("race-nonatomic-stuck", 3), ("fischer-max-states", 2)]


@pytest.mark.slow
def test_ray_actors_give_the_one_process_results(local_ray):
    for name, w in RAY_CASES:
        program, opts = CASES[name]
        one = signature(explore(program, **opts))
        assert signature(explore(program, ray="auto", workers=w, **opts)) == one, \
            f"{name}: ray with {w} actors"
    program, opts = FASTEST_CASES["fischer-violation"]      # --fastest through the actors
    assert fastest_signature(explore(program, ray="auto", workers=2, fastest=True, **opts)) == \
        fastest_signature(explore(program, fastest=True, **opts))
    assert local_ray.is_initialized()        # a connection it did not open stays open


@pytest.mark.slow
def test_ray_actors_give_the_one_process_time_lock_and_temporal_verdicts(local_ray):
    """The graph travels back from Ray actors too: the time-lock programs
    and a lasso counterexample, as in one process."""
    for name in ("tl_spin.pccl-agents2", "tl_spin_leave.pccl-agents2", "rdv-wall-lasso"):
        program, opts = TEMPORAL_CASES[name]
        one = full_signature(explore(program, **opts))
        assert full_signature(explore(program, ray="auto", workers=2, **opts)) == one, name


@pytest.mark.slow
def test_ray_actors_load_a_blackbox_from_a_file(local_ray, tmp_path):
    """``--blackbox FILE.py:ATTR`` with Ray: the file's module is no module
    the actors can import, so its classes travel by value (oracle finding
    R1: every actor died in its creation task, "worker 0 of 2 was lost")."""
    bb = tmp_path / "ray_user_bb.py"
    bb.write_text("from pccl.blackboxes.nondet import Nondet\n\n\n"
                  "class Mine(Nondet):\n    pass\n\n\nBB = Mine\n")
    opts = dict(world=RACE_WORLD, blackbox=f"{bb}:BB", agents=2, find_all=True)
    one = signature(explore("programs/race_nonatomic.pccl", **opts))
    assert one[0] == "violation"
    assert signature(explore("programs/race_nonatomic.pccl", ray="auto", workers=2,
                             **opts)) == one


@pytest.mark.slow
def test_cli_ray_local_starts_and_stops_ray():
    _ray()
    base = [sys.executable, "-m", "pccl.cli", "explore", FISCHER, "--set", "k=1",
            "--invariant", MUTEX, "--no-progress", "--format", "json"]
    one = subprocess.run(base, capture_output=True, text=True)
    ray = subprocess.run(base + ["--ray", "local", "--workers", "2"], capture_output=True,
                         text=True, timeout=300)
    assert one.returncode == ray.returncode == 1, ray.stderr
    import json
    a, b = json.loads(one.stdout), json.loads(ray.stdout)
    for k in ("states", "transitions", "max_depth"):
        assert a["statistics"][k] == b["statistics"][k]
    assert a["violations"] == b["violations"]


def test_ray_missing_says_how_to_install():
    """Without the extra, --ray exits 2 with the install command (ray made
    unimportable in the child)."""
    code = ("import sys; sys.modules['ray'] = None; sys.argv = ['pccl'] + sys.argv[1:]; "
            "from pccl.cli import main; main()")
    r = subprocess.run([sys.executable, "-c", code, "explore", FISCHER, "--ray", "local"],
                       capture_output=True, text=True)
    assert r.returncode == 2
    assert "pip install -e '" in r.stderr and "[ray]'" in r.stderr and "Traceback" not in r.stderr
    code_api = ("import sys; sys.modules['ray'] = None\n"
                "from pccl.api import explore\n"
                "from pccl.lang.errors import PcclError\n"
                "try:\n    explore('programs/fischer.pccl', ray='local')\n"
                "except PcclError as e:\n    print(e)\n")
    r = subprocess.run([sys.executable, "-c", code_api], capture_output=True, text=True)
    assert "pip install -e '" in r.stdout and "[ray]'" in r.stdout, r.stderr


def test_bad_ray_argument_is_named():
    from pccl.lang.errors import ArgumentError
    with pytest.raises(ArgumentError, match="ray must be"):
        explore(FISCHER, overrides={"k": "0"}, ray=3)
    with pytest.raises(ArgumentError, match="one process"):
        explore(FISCHER, overrides={"k": "0"}, exact=True, ray="local")


# ---------------------------------------------------------------------------
# One verdict on every backend: the time-lock check and temporal properties
# run on the graph the workers record, as on the one-process graph
# ---------------------------------------------------------------------------

def full_signature(r):
    """Everything a verdict shows: the search's figures, the violations with
    their traces (lassos included), what holds, the notes, the witnesses."""
    notes = [n for n in r.notes if not n.startswith("Ray: ")]   # --ray: where its actors ran
    return (signature(r), r.verdict, notes, r.holds,
            [(w["name"], w["depth"], w["trace"]) for w in r.witnesses],
            [cx.cycle_start for cx in r.counterexamples])


def _tl_programs():
    from conftest import TEST_PROGRAMS
    return sorted(str(p) for p in TEST_PROGRAMS.glob("tl_*.pccl"))


def _temporal_cases():
    from conftest import TEST_PROGRAMS as T
    rdv, alls = str(T / "rdv_meet.pccl"), ["eventually forall i: exited[i]"]
    ring = str(T / "token_ring.pccl")
    cases = {f"{p.rsplit('/', 1)[1]}-agents{a}": (p, dict(agents=a))
             for p in _tl_programs() for a in (2, 3)}
    cases.update({
        "tl_spin_leave-depth": (str(T / "tl_spin_leave.pccl"), dict(depth=3)),
        "rdv-wall-lasso": (rdv, dict(world=str(T / "rdv_wall.toml"), blackbox="straight",
                                     properties=alls)),
        "rdv-open-nondet-fair": (rdv, dict(world=str(T / "rdv_open.toml"), blackbox="nondet",
                                           properties=alls)),
        "token-keep-leadsto": (str(T / "token_keep.pccl"),
                               dict(agents=3, properties=["forall i: want[i] ~> has[i]"])),
        "token-ring-within": (ring, dict(agents=3, properties=["want[1] ~> has[1] within 2.5"])),
        "fischer-reachable": (FISCHER, dict(overrides={"k": "0", "d": "1"},
                                            properties=["reachable count(inCs) == 1",
                                                        "reachable count(inCs) == 3"])),
        "fischer-max-states-temporal": (FISCHER, dict(overrides={"k": "0", "d": "1"},
                                                      max_states=2000,
                                                      properties=["eventually inCs[0]"])),
    })
    return cases


TEMPORAL_CASES = _temporal_cases()


def test_the_time_lock_programs_are_there():
    """The time-lock cases below cover a time-locked program and one that
    only looks like one (a spin that can be left)."""
    names = [p.rsplit("/", 1)[1] for p in _tl_programs()]
    assert {"tl_spin.pccl", "tl_spin_leave.pccl"} <= set(names)
    assert explore(str(_tl_programs()[0]), workers=1).violation.kind == "timelock"


@pytest.mark.parametrize("name", sorted(TEMPORAL_CASES))
def test_time_lock_and_temporal_verdicts_equal_on_every_backend(name):
    """The time-lock check and the temporal properties give, with 2 and 3
    workers, the one-process verdict: status, message, figures, the very
    counterexample (lasso and cycle), what holds, the notes.  (Before, with
    workers, a time-locked program was 'no violation', exit 0, with a note
    that the check did not run; temporal properties were refused.)"""
    program, opts = TEMPORAL_CASES[name]
    one = full_signature(explore(program, **opts))
    for w in (2, 3):
        assert full_signature(explore(program, workers=w, **opts)) == one, f"workers={w}"


def test_time_lock_with_workers_is_a_violation():
    from conftest import TEST_PROGRAMS
    r = explore(str(TEST_PROGRAMS / "tl_spin.pccl"), workers=2)
    assert r.status == "violation" and r.exit_status == 1
    assert r.violation.kind == "timelock" and r.notes == []
    assert r.counterexamples[0].cycle_start is not None


@pytest.mark.parametrize("chunk", [None, 100])
def test_workers_hand_over_the_graph_the_one_process_search_records(chunk, monkeypatch):
    """The recorder after a parallel search holds the one-process graph:
    the same edges (as a multiset per source, in successor order) and the
    same per-state columns; also when the workers hand their transitions
    over in chunks of 100 (levels cut in pieces)."""
    import numpy as np
    from pccl.search import liveness as L
    from pccl.search import parallel as P
    if chunk is not None:
        monkeypatch.setattr(P, "_GRAPH_CHUNK", chunk)
    m = make_model(FISCHER, overrides={"k": "0", "d": "1"}, reduce="merge,symmetry",
                   properties=["reachable count(inCs) == 1"])
    graphs = []
    for w in (1, 2, 3):
        rec = L.make_recorder(m, True)
        ex = Explorer(m, recorder=rec) if w == 1 else \
            ParallelExplorer(m, workers=w, recorder=rec)
        sr = ex.run()
        g = rec.freeze(sr.stats.states)
        graphs.append((sr.stats.states, g.esrc.tolist(), g.fdst.tolist(), g.dyn.tolist(),
                       g.bits.tolist(), rec.complete))
        if w > 1:       # the coordinator's table numbers states as the search did
            assert ex.table.n == sr.stats.states
            links = _parent_links(m)
            assert [ex.table.parent(i) for i in range(0, sr.stats.states, 97)] == \
                [links[i] for i in range(0, sr.stats.states, 97)]
    assert graphs[0][0] > 1000 and np.asarray(graphs[0][3]).any()
    assert graphs[1] == graphs[0] and graphs[2] == graphs[0]


@pytest.mark.parametrize("workers", [2, 3])
def test_kept_workers_number_states_for_the_replay_until_closed(workers):
    """With ``keep_workers`` the workers outlive the search, and the
    counterexamples of the graph analysis replay through their tables (the
    coordinator builds no table of every state); :meth:`close` stops them.
    Without it the coordinator's table answers the same numbers."""
    import multiprocessing
    import numpy as np
    from pccl.search import liveness as L
    from pccl.search.explorer import FingerprintTable
    m = make_model(FISCHER, overrides={"k": "0", "d": "1"}, reduce="merge,symmetry,por")
    one = Explorer(m, recorder=L.make_recorder(m, True))
    one.run()
    kept = ParallelExplorer(m, workers=workers, recorder=L.make_recorder(m, True))
    kept.keep_workers = True
    plain = ParallelExplorer(m, workers=workers, recorder=L.make_recorder(m, True))
    try:
        sr = kept.run()
        assert len(multiprocessing.active_children()) == workers - 1
        assert not isinstance(kept.table, FingerprintTable)
        plain.run()
        assert isinstance(plain.table, FingerprintTable)
        n = sr.stats.states
        fps = one.table.fps[:n]
        for i in list(range(0, n, max(1, n // 40))) + [n - 1]:
            fp = fps[i].tobytes()
            assert kept.table.index_of(fp) == plain.table.index_of(fp) == i
        assert kept.table.index_of(np.zeros(2, np.uint64).tobytes()) == -1
        assert kept.replay(n - 1).states == one.replay(n - 1).states
    finally:
        kept.close()
    assert not multiprocessing.active_children()
    kept.close()        # twice: nothing more to stop


def test_graph_edges_come_in_chunks_in_the_order_generated():
    """A worker hands its transitions over about ``most`` at a time (a long
    part cut, short ones joined), in the order generated, and keeps none."""
    import numpy as np
    from pccl.search import parallel as P
    w = P._Worker(make_model(FISCHER, overrides={"k": "0"}), 0, 1, True, False)
    sizes = [3, 1, 12, 0, 2, 5]
    w.g_src = [np.arange(sum(sizes[:i]), sum(sizes[:i + 1]), dtype=np.uint32)
               for i in range(len(sizes))]
    w.g_fps = [np.stack([s.astype(np.uint64), s.astype(np.uint64) * 7], axis=1) for s in w.g_src]
    got = []
    while (part := w.graph_edges(4)) is not None:
        src, fps = part
        assert 1 <= len(src) <= 4 and len(fps) == len(src)
        assert (fps[:, 0] == src).all() and (fps[:, 1] == src.astype(np.uint64) * 7).all()
        got.append(src.tolist())
    assert sum(got, []) == list(range(sum(sizes)))
    assert [len(g) for g in got] == [4, 4, 4, 4, 4, 3]
    assert w.g_src == [] and w.g_fps == []


_LINKS: dict = {}


def _parent_links(m):
    """The one-process search's parent links (computed once)."""
    if "p" not in _LINKS:
        ex = Explorer(m)
        sr = ex.run()
        _LINKS["p"] = [ex.table.parent(i) for i in range(sr.stats.states)]
    return _LINKS["p"]


FAST_SLOW = "tests/programs/fast_slow.pccl"

#: --fastest: the search ordered on (time steps, transitions), its buckets
#: expanded as levels by the workers
FASTEST_CASES = {
    "fast-slow": (FAST_SLOW, dict(agents=1, reduce="none")),
    "fischer-violation": (FISCHER, dict(overrides={"k": "0"}, invariants=[MUTEX])),
    "fischer-exhaustive": CASES["fischer-exhaustive"],
    "fischer-all": CASES["fischer-all"],
    "fischer-max-states": CASES["fischer-max-states"],
    "fischer-depth": CASES["fischer-depth"],
    "race-nonatomic-stuck": CASES["race-nonatomic-stuck"],
    "race-nonatomic-all": CASES["race-nonatomic-all"],
    "leader": CASES["leader"],
}


def fastest_signature(r):
    cxs = r.counterexamples
    return (signature(r), r.stats.frontier, [cx.trace and cx.trace.last[TIME] for cx in cxs])


@pytest.mark.parametrize("name", ["fischer-exhaustive"])
def test_fastest_reports_the_largest_time_as_the_breadth_first_search(name):
    """An exhaustive search visits the same states in either order: the
    fastest search's largest model time (one process and 2 workers) is the
    breadth-first search's (it was None)."""
    program, opts = FASTEST_CASES[name]
    bfs = explore(program, **opts)
    assert bfs.status == "exhaustive" and bfs.stats.max_time is not None
    for w in (1, 2):
        fast = explore(program, fastest=True, workers=w, **opts)
        assert (fast.status, fast.stats.states, fast.stats.max_time) == \
            ("exhaustive", bfs.stats.states, bfs.stats.max_time), f"workers={w}"


@pytest.mark.parametrize("name", sorted(FASTEST_CASES))
def test_fastest_with_workers_gives_the_one_process_results(name):
    """--fastest with 2 and 3 workers: the one-process fastest search's
    figures (states, transitions, depth, the frontier left), verdict and
    very counterexample (the same states, the same time).  Before, refused."""
    program, opts = FASTEST_CASES[name]
    one = explore(program, fastest=True, **opts)
    for w in (2, 3):
        assert fastest_signature(explore(program, fastest=True, workers=w, **opts)) == \
            fastest_signature(one), f"workers={w}"


def test_fastest_with_workers_is_the_fastest_not_the_shortest():
    """fast_slow: breadth-first finds the violation at time 2, the fastest
    search at time 0 (a longer path); so do the workers, and the command
    line says so."""
    from pccl.cli import main
    from click.testing import CliRunner
    bfs = explore(FAST_SLOW, agents=1, reduce="none", workers=2)
    fast = explore(FAST_SLOW, agents=1, reduce="none", fastest=True, workers=2)
    assert bfs.counterexamples[0].trace.last[TIME] == 2
    assert fast.counterexamples[0].trace.last[TIME] == 0
    assert len(fast.counterexamples[0].trace) > len(bfs.counterexamples[0].trace)
    res = CliRunner().invoke(main, ["explore", FAST_SLOW, "-n", "1", "--fastest", "--workers",
                                    "2", "--no-progress"])
    assert res.exit_code == 1, res.output
    assert "fastest: violation at t=0" in res.output


@pytest.mark.parametrize("name", ["tl_spin.pccl-agents2", "tl_spin_leave.pccl-agents3",
                                  "rdv-wall-lasso", "token-keep-leadsto", "token-ring-within",
                                  "fischer-max-states-temporal"])
def test_fastest_time_lock_and_temporal_verdicts_with_workers(name):
    """The time-lock check and temporal properties on the graph the fastest
    search records: the same verdicts with workers."""
    program, opts = TEMPORAL_CASES[name]
    one = full_signature(explore(program, fastest=True, **opts))
    for w in (2, 3):
        assert full_signature(explore(program, fastest=True, workers=w, **opts)) == one, \
            f"workers={w}"


def test_ray_address_where_nothing_listens_fails_at_once():
    """--ray HOST:PORT with no Ray head there: exit 2 with the address and
    what to do, instead of ray.init retrying for ever (probed before Ray is
    imported into the search)."""
    import socket
    from pccl.search.parallel import RayUnavailable, probe_ray_address
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()                       # a free port: nothing listens
    with pytest.raises(RayUnavailable, match=f"nothing answers at 127.0.0.1:{port}"):
        probe_ray_address(f"127.0.0.1:{port}", timeout=2)
    with pytest.raises(RayUnavailable, match="ray start --head"):
        probe_ray_address(f"ray://127.0.0.1:{port}", timeout=2)
    probe_ray_address("auto")       # left to Ray
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(1)
    try:
        probe_ray_address(f"127.0.0.1:{srv.getsockname()[1]}", timeout=2)   # answers: no error
    finally:
        srv.close()
    _ray()
    # a process of its own: in this one Ray may be up already (a fixture's),
    # and the search would use it instead of the address given
    r = subprocess.run([sys.executable, "-m", "pccl.cli", "explore", FISCHER, "--set", "k=0",
                        "--ray", f"127.0.0.1:{port}", "--no-progress"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2, r.stderr
    assert f"nothing answers at 127.0.0.1:{port}" in r.stderr and "Traceback" not in r.stderr


# ---------------------------------------------------------------------------
# Signals and the death of the coordinator
# ---------------------------------------------------------------------------

LONG_SEARCH = ["explore", FISCHER, "--workers", "2", "--progress", "--progress-interval", "0.1"]


def _start_long_search(env=None):
    """``pccl explore`` on fischer (k=10: minutes) with two workers, in a
    session of its own (its own process group, as a terminal's job), once
    its first progress line is out: the search is under way.  Worker
    processes (``PCCL_THREADS=0``): two threads would be one process."""
    return started(LONG_SEARCH, "states ", env={"PCCL_THREADS": "0", **(env or {})},
                   new_session=True)


def _gone(pids, timeout):
    import time
    import psutil
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        alive = []
        for pid in pids:
            try:
                if psutil.Process(pid).status() != psutil.STATUS_ZOMBIE:
                    alive.append(pid)
            except psutil.NoSuchProcess:
                pass
        if not alive:
            return True
        time.sleep(0.05)
    return False


@pytest.mark.slow
@pytest.mark.parametrize("signame", ["SIGINT", "SIGTERM"])
def test_signal_during_a_parallel_search_reports_once(signame):
    """SIGINT or SIGTERM to the process group (a terminal's Ctrl-C, a job
    control's stop) or to the coordinator alone: the header, the
    statistics so far and the interrupted verdict, each exactly once, no
    traceback from any process, exit 130 (SIGINT) or 143 (SIGTERM), and
    no worker left behind.  (Before: with the group signalled, a worker's
    KeyboardInterrupt traceback, often no report at all, once a hang.)
    Repeated: the old failures were intermittent."""
    import os
    import signal
    import psutil
    sig = getattr(signal, signame)
    for attempt in range(4):
        p, _ = _start_long_search()
        workers = [c.pid for c in psutil.Process(p.pid).children()]
        try:
            if attempt % 2 == 0:
                os.killpg(p.pid, sig)
            else:
                os.kill(p.pid, sig)
            out, err = p.communicate(timeout=120)
        finally:
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait()
        where = f"{signame} to the {'group' if attempt % 2 == 0 else 'parent'}"
        assert p.returncode == (130 if sig == signal.SIGINT else 143), (where, out, err)
        assert "Traceback" not in out + err and "KeyboardInterrupt" not in out + err, where
        assert out.count("pccl explore programs/fischer.pccl: 2 agents") == 1, (where, out)
        assert out.count("statistics:") == 1 and out.count("\ninterrupted — ") == 1, (where, out)
        assert "states  " in out and "transitions  " in out
        assert workers and _gone(workers, 10), where


@pytest.mark.parametrize("pdeathsig", ["1", "0"])
def test_workers_die_with_a_killed_coordinator(pdeathsig):
    """SIGKILL to the coordinator: its workers exit within seconds, by the
    parent-death signal (Linux) and, without it (PCCL_PDEATHSIG=0), because
    their pipe to the coordinator closes (before: each worker held the
    coordinator's end of its own pipe open, and one ran on for 80 minutes)."""
    import os
    import signal
    import psutil
    p, _ = _start_long_search(env={"PCCL_PDEATHSIG": pdeathsig})
    try:
        workers = [c.pid for c in psutil.Process(p.pid).children()]
        assert len(workers) == 1, workers          # --workers 2: worker 0 is the coordinator
        os.kill(p.pid, signal.SIGKILL)
        p.wait(timeout=10)
        assert _gone(workers, 10), "a worker outlived its coordinator"
    finally:
        for pid in [p.pid] + workers:
            try:
                os.kill(pid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):
                pass
        p.communicate()
