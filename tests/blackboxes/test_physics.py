"""Issue 5 acceptance: swapping blackboxes, pymunk determinism and exploration."""

from __future__ import annotations

from pathlib import Path

import pytest
from shapely.geometry import Point, Polygon

from pccl import api
from pccl.blackboxes import load_blackbox
from pccl.model.layout import AGS, FAIL, POS, REACH, SH

ROOT = Path(__file__).resolve().parents[2]
PROG = ROOT / "programs"
RACE = PROG / "race.pccl"
NONATOMIC = PROG / "race_nonatomic.pccl"
WORLD = PROG / "race.toml"
OBST = PROG / "race_obstacles.toml"


def _stuck_reasons(res):
    return [v["message"] for v in res.violations if v["kind"] == "stuck"]


def test_swapping_blackboxes_gives_the_papers_two_race_outcomes():
    """Section 5.2: the same program, two blackboxes, two outcomes."""
    stuck = api.explore(NONATOMIC, world=WORLD, blackbox=load_blackbox("instant"))
    assert stuck.status == "violation"
    assert "remove of an element not in the list" in _stuck_reasons(stuck)[0]
    assert stuck.violation["line"] == 35  # remove(dests, currentDest);
    clean = api.explore(NONATOMIC, world=WORLD, blackbox=load_blackbox("straight"))
    assert clean.status == "exhaustive" and clean.exit_status == 0
    # and one concrete run of each
    run_clean = api.run(NONATOMIC, world=WORLD, blackbox="straight", seed=0)
    assert run_clean.status == "final"
    assert run_clean.final[SH] == ((),)   # dests empty


def test_blackbox_object_from_python_api_is_used():
    class Frozen:
        """Nobody ever arrives: the race never progresses past the first pick."""
        name = "frozen"
        uses_time = False

        def init_env(self, world, n):
            return None

        def step(self, world, motions, env, time, delta):
            from pccl.blackboxes.base import Outcome
            return [Outcome(tuple(m.position for m in motions), (False,) * len(motions),
                            (False,) * len(motions), None)]

    # robots that never arrive: a stall, by the stall check
    res = api.explore(RACE, world=WORLD, blackbox=Frozen())
    assert res.blackbox == "frozen" and "[blackbox frozen]" in res.verdict
    assert res.violation.kind == "stall"
    res = api.explore(RACE, world=WORLD, blackbox=Frozen(), stall=False)
    assert res.status == "exhaustive"
    assert res.stats.states < 200


def _positions(res):
    return [tuple(ag[POS] for ag in s[AGS]) for _, s in res.summary]


def test_pymunk_run_is_deterministic():
    a = api.run(RACE, world=OBST, blackbox="pymunk", seed=4, record_trace=True)
    b = api.run(RACE, world=OBST, blackbox="pymunk", seed=4, record_trace=True)
    assert a.status == b.status == "final"
    assert a.trace.states == b.trace.states   # identical states
    assert a.final == b.final


@pytest.mark.parametrize("world", [WORLD, OBST])
@pytest.mark.parametrize("program", [RACE, NONATOMIC])
def test_pymunk_explore_terminates_with_a_verdict(program, world):
    res = api.explore(program, world=world, blackbox="pymunk", agents=2)
    assert res.status in ("exhaustive", "violation")
    assert "[blackbox pymunk]" in res.verdict
    assert res.stats.states > 50        # a real search (85-88 states under the default reductions)


def test_pymunk_sends_robots_around_the_obstacles():
    res = api.run(RACE, world=OBST, blackbox="pymunk", seed=0)
    assert res.status == "final"
    world = res.model.world
    polys = [Polygon(p) for p in world.obstacles]
    assert polys, "the obstacle world has obstacles"
    for snapshot in _positions(res):
        for p in snapshot:
            disc = Point(p[0], p[1]).buffer(world.radius * 0.9)
            assert not any(disc.intersects(poly) for poly in polys), p
    # robot 0's straight line to (4, 0) crosses the first obstacle: under
    # `straight` that doReach fails, under pymunk it gets there
    straight = api.run(RACE, world=OBST, blackbox="straight", seed=0, max_time=10)
    assert straight.final[AGS][0][REACH][FAIL] is True        # doReach_fail
