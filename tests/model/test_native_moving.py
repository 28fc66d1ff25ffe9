"""The native engine on programs that move (issue 23): positions, reach
cells, env and list/position variables are interned ids in the native
vector; the statements C does not compute and DOREACH INVOKE are memoised
in C and run by the Python rule on a miss.  Equal results are the contract:
states, transitions, depth, verdicts and counterexamples (decoded, positions
included) equal the Python engine's, under nondet, instant and straight,
each reduction on and off; and a deliberately wrong memo is caught."""

import os

import pytest

from pccl.api import explore, make_model
from pccl.model import native as NV
from pccl.model.layout import AGS, POS
from pccl.lang.errors import PcclError

from test_native import MISSING, UNREDUCED, both, summary

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
pytestmark = pytest.mark.skipif(MISSING is not None, reason=f"native engine unavailable: {MISSING}")


def P(path: str) -> str:
    return os.path.join(ROOT, path)


#: (program, world, agents) that move and that the native engine serves
MOVING = [
    ("programs/race.pccl", "programs/race.toml", 2),
    ("programs/race_nonatomic.pccl", "programs/race.toml", 2),
    ("programs/race_safe.pccl", "programs/race.toml", 2),
    ("programs/race_robust.pccl", "programs/race.toml", 2),
    ("programs/race_robust.pccl", "programs/race_obstacles.toml", 2),
    ("programs/collide.pccl", "programs/collide.toml", 2),
    ("programs/collide_fixed.pccl", "programs/collide.toml", 2),
    ("tests/programs/rdv_meet.pccl", "tests/programs/rdv_open.toml", 2),
    ("tests/programs/rdv_meet.pccl", "tests/programs/rdv_wall.toml", 2),
    ("tests/programs/ref_doreach.pccl", None, 2),
    ("tests/programs/eng_move1.pccl", None, 2),
]


def kw_of(world, agents, blackbox, reduce) -> dict:
    kw = dict(agents=agents, blackbox=blackbox, reduce=reduce)
    if world is not None:
        kw["world"] = P(world)
    return kw


@pytest.mark.parametrize("program, world, agents", MOVING)
def test_moving_programs_are_served(program, world, agents):
    for bb in ("nondet", "instant", "straight", "nondet-fail"):
        m = make_model(P(program), **kw_of(world, agents, bb, "auto"))
        assert NV.unsupported(m) is None, (program, bb)


@pytest.mark.parametrize("blackbox", ["nondet", "instant", "straight"])
@pytest.mark.parametrize("program, world, agents", MOVING)
def test_equal_results_unreduced(program, world, agents, blackbox):
    py, nat = both(P(program), find_all=True, max_states=2_000,
                   **kw_of(world, agents, blackbox, "none"), timelock=False, stall=False)
    assert nat == py


@pytest.mark.parametrize("reduce", ["merge", "por", "symmetry", "merge,por", "auto"])
@pytest.mark.parametrize("program, world, agents", MOVING)
def test_equal_results_each_reduction(program, world, agents, reduce):
    """Under nondet (the default for programs that move), with the
    time-lock and stall checks on: the graph recorder's hooks too."""
    kw = kw_of(world, agents, "nondet", reduce)
    try:
        make_model(P(program), **kw)
    except PcclError as e:          # symmetry asked for where it is unsound
        assert reduce == "symmetry" and "unsound" in str(e)
        return
    py, nat = both(P(program), find_all=True, max_states=2_000,
                   **kw_of(world, agents, "nondet", reduce))
    assert nat == py


def test_race_nonatomic_counterexample_with_positions_equal():
    """race_nonatomic gets a robot stuck on remove() under nondet: the
    decoded counterexample (positions and targets included) is the Python one."""
    py, nat = both(P("programs/race_nonatomic.pccl"), **kw_of("programs/race.toml", 2, "nondet", "none"))
    assert py["status"] == "violation" and nat == py
    last = py["traces"][0][1][-1]
    assert any(a[POS] != (0.0, 0.0, 0.0) for a in last[AGS])     # someone moved


@pytest.mark.parametrize("world, agents", [("programs/race.toml", 3), ("programs/race_obstacles.toml", 3)])
def test_three_robots_default_equal(world, agents):
    py, nat = both(P("programs/race_robust.pccl"), **kw_of(world, agents, "nondet", "auto"),
                   max_states=5_000)
    assert nat == py
    assert py["states"] == 5_000 and py["status"] == "bounded"


#: (Init, guard, body) of generated programs that move
SHAPES = [
    ("doReach(ItemPosition(2, 0), obs);", "pre(doReach_done && !stop);",
         "if (contains(l, getPosition())):\n      remove(l, getPosition());\n    else:\n      stop = size(l) < 2;"),
        ("doReach(head(l), obs);", "pre(doReach_fail || doReach_done);",
         "if (!isEmpty(l)):\n      p = head(l);\n      remove(l, p);\n      doReach(p, obs);"),
        ("p = getPosition();", "pre(!stop);",
         "add(l, p);\n    doReach(ItemPosition(1, 1), obs);\n    stop = p == getPosition();\n"
         "    if (size(l) > 3):\n      exit();"),
]


@pytest.mark.parametrize("blackbox", ["nondet", "instant", "straight"])
@pytest.mark.parametrize("shape", range(3))
def test_generated_moving_programs_equal(shape, blackbox):
    """Programs that move with lists, positions, obstacles and flags in
    statements, conditions and guards, in several shapes."""
    for init, guard, body in SHAPES[shape:shape + 1]:
        text = ("allwrite:\n  List<ItemPosition> l = [ItemPosition(2, 0), ItemPosition(1, 1)];\n"
                "loc:\n  ObstacleList obs = getObs();\n  ItemPosition p = ItemPosition(0, 0);\n"
                "  boolean stop = false;\n"
                f"Init:\n  {init}\nE():\n  {guard}\n  eff:\n    {body}\n")
        for reduce in ("none", "auto"):
            kw = dict(source=True, agents=2, blackbox=blackbox, reduce=reduce)
            assert NV.unsupported(make_model(text, **kw)) is None, text
            py, nat = both(text, find_all=True, max_states=2_000, **kw)
            assert nat == py, (text, blackbox, reduce)


def test_a_dropped_outcome_is_caught(monkeypatch):
    """Teeth: a memo that drops the blackbox's last outcome gives a different
    search, which the comparison sees (the outcomes made by Python: the
    shipped blackboxes' C, tests/model/test_native_robots.py, off)."""
    monkeypatch.setenv("PCCL_C_BLACKBOX", "0")
    orig = NV.NativeModel._miss

    def wrong(self, k, b):
        val, grown = orig(self, k, b)
        from array import array
        v = array("q")
        v.frombytes(val)
        if self.gen.sites[k][0] == "env" and v[0] > 1:
            w = (len(v) - 1) // v[0]
            v = v[:1 + w * (v[0] - 1)]
            v[0] -= 1
        return v.tobytes(), grown

    kw = kw_of("programs/race.toml", 2, "nondet", "none")
    good = summary(explore(P("programs/race_robust.pccl"), engine="native", **kw))
    monkeypatch.setattr(NV.NativeModel, "_miss", wrong)
    bad = summary(explore(P("programs/race_robust.pccl"), engine="native", **kw))
    assert bad["states"] < good["states"]


def test_memo_misses_are_few_and_the_python_rule_runs_once_per_key(monkeypatch):
    """Every miss asks Python once (the blackbox's C off: with it, C makes
    DOREACH INVOKE's entries and Python the statements')."""
    monkeypatch.setenv("PCCL_C_BLACKBOX", "0")
    m = make_model(P("programs/race_robust.pccl"), **kw_of("programs/race.toml", 2, "nondet", "none"))
    nm = NV.NativeModel(m)
    calls = []
    orig = nm._miss
    nm.lib.setup(nm.gen.labels, NV.NativeOverflow, nm._violations, 0,
                 lambda k, b: (calls.append(k), orig(k, b))[1])
    seen, frontier = set(), list(nm.init_states())
    while frontier and len(seen) < 5_000:
        nxt = []
        for s in frontier:
            py_succ = m.successors(nm.decode(s))
            nat = [(lab, nm.decode(b)) for lab, b in nm.successors(s)]
            assert nat == py_succ
            for _, b in nm.successors(s):
                if nm.key(b) not in seen:
                    seen.add(nm.key(b))
                    nxt.append(b)
        frontier = nxt
    entries, misses, hits = nm.lib.memo_stats()
    assert misses == entries == len(calls) and hits > 10 * misses


def test_a_rule_writing_a_slot_its_site_does_not_write_stops_the_native_search():
    """The check of every memo miss: a site whose rule changes a slot the
    site does not list as written raises NativeOverflow (the native search
    stops and Python runs), naming the slot; the same miss with the slot
    listed passes."""
    m = make_model(P("programs/race_robust.pccl"), **kw_of("programs/race.toml", 2, "nondet", "none"))
    nm = NV.NativeModel(m)
    env = [k for k, site in enumerate(nm.gen.sites) if site[0] == "env"]
    assert env
    k = env[0]
    kind, i, pc, rs, ws = nm.gen.sites[k]
    # a state right after TIME ADVANCE with both robots moving: DOREACH INVOKE
    # writes their positions
    frontier, found = list(nm.init_states()), None
    while frontier and found is None:
        nxt = []
        for b in frontier:
            for lab, b2 in nm.successors(b):
                if lab[0] == "DOREACH INVOKE" and nm.decode(b2)[AGS][0][POS] != nm.decode(b)[AGS][0][POS]:
                    found = b
                nxt.append(b2)
        frontier = nxt[:2000]
    assert found is not None
    assert nm._miss(k, found)[0]                # as generated: passes
    for q in ws:
        nm.gen.sites[k] = (kind, i, pc, rs, [w for w in ws if w != q])
        nm._unwritten.pop(k, None)
        try:
            nm._miss(k, found)
        except NV.NativeOverflow as e:
            assert f"changed slot {q}," in str(e)
            break
        finally:
            nm.gen.sites[k] = (kind, i, pc, rs, ws)
            nm._unwritten.pop(k, None)
    else:
        raise AssertionError("no written slot of DOREACH INVOKE changed")


def test_batch_stall_signatures_equal_one_by_one():
    # the graph recorder's one C call per batch (stall_signatures) against
    # the per-state signature the parallel search and the tests use
    m = make_model(P("programs/race_robust.pccl"), **kw_of("programs/race.toml", 3, "nondet", "auto"))
    nm = NV.NativeModel(m)
    states, frontier = [], list(nm.init_states())
    while frontier and len(states) < 3_000:
        states += frontier
        frontier = [b for s in frontier for _, b in nm.successors(s)][:2_000]
    one = nm.stall_signature()
    got = nm.stall_signatures(states)
    assert got.tolist() == [one(s) for s in states]
    assert len(set(got.tolist())) > 10       # the states differ in what the check compares


def test_encode_memo_keeps_equal_values_of_other_types_apart():
    """encode's memo of agent and shared cells is keyed by the marshal
    encoding, as the fingerprints are: 1, 1.0 and True are three cells
    (a dict keyed by the values would hand the first one's ints to all)."""
    cache: dict = {}
    made = []
    def fn(x):
        made.append(x)
        return [len(made)]
    got = [NV.NativeModel._cached(cache, x, fn) for x in ((1,), (1.0,), (True,), (1,), (1.0,))]
    assert got == [[1], [2], [3], [1], [2]]
    assert [type(x[0]) for x in made] == [int, float, bool]


def test_parallel_search_and_checkpoint_of_a_moving_program_run_native():
    m = make_model(P("programs/race_robust.pccl"), **kw_of("programs/race.toml", 2, "nondet", "auto"))
    assert NV.unsupported(m, parallel=True) is None
    assert NV.unsupported(m, checkpoint=True) is None
    assert NV.unsupported(m) is None


def _figures(r) -> tuple:
    s = r.stats
    return (r.status, s.states, s.transitions, s.max_depth)


def test_workers_and_checkpoints_of_a_moving_program_run_native_and_agree(tmp_path, monkeypatch):
    """Forked workers intern values by a hash of the value (stable ids), and
    a checkpoint saves the id table: both run the native engine and find
    what the one-process native search and the Python engine find; two
    threads of one process too."""
    kw = dict(world=P("programs/race.toml"), agents=2, blackbox="nondet")
    one = explore(P("programs/race_robust.pccl"), **kw)
    assert one.model.engine_used == "native"
    threads = explore(P("programs/race_robust.pccl"), workers=2, **kw)
    assert threads.model.engine_threads == 2 and _figures(threads) == _figures(one)
    monkeypatch.setenv("PCCL_THREADS", "0")
    two = explore(P("programs/race_robust.pccl"), workers=2, **kw)
    assert two.model.engine_used == "native", two.model.engine_reason
    ck = explore(P("programs/race_robust.pccl"), checkpoint=str(tmp_path / "ck"), **kw)
    assert ck.model.engine_used == "native", ck.model.engine_reason
    py = explore(P("programs/race_robust.pccl"), engine="python", **kw)
    assert _figures(one) == _figures(two) == _figures(ck) == _figures(py)
    two = explore(P("programs/race_robust.pccl"), workers=2, engine="native", **kw)
    assert _figures(two) == _figures(one)


@pytest.mark.slow
def test_race_robust_three_robots_exhaustive_equal():
    py, nat = both(P("programs/race_robust.pccl"), **kw_of("programs/race.toml", 3, "nondet", "auto"))
    # complete for nondet; robots start second legs, so "not exhaustive for pymunk"
    assert nat == py and py["status"] == "bounded" and py["states"] > 80_000


_ = UNREDUCED
