"""The Koord example programs of issue 47 written here after the published
applications' descriptions: task allocation, shape formation and follow
path (programs/koord/), each explored with a real verdict, its faulty
variant caught, and the round semantics' verdicts compared with and
without symmetry reduction where it is on."""

from __future__ import annotations

from pathlib import Path

import pytest

from pccl.api import explore, load_program, run

KOORD = Path(__file__).resolve().parents[2] / "programs" / "koord"
ALL_EXIT = "eventually (forall i: exited[i])"


def k(name: str) -> str:
    return str(KOORD / name)


def _ex(name, world, **kw):
    return explore(load_program(k(name)), world=k(world), **kw)


# ---- task allocation -------------------------------------------------------

@pytest.mark.parametrize("agents", [2, 3])
def test_task_allocation_does_every_task_once(agents):
    r = _ex("task_alloc.koord", "task_alloc.toml", agents=agents, blackbox="straight",
            properties=["eventually size(done) == size(sites)", ALL_EXIT])
    assert r.status == "exhaustive", r.verdict
    assert not r.violations
    assert r.stats.states > 20


def test_task_allocation_racy_claims_one_task_twice():
    r = _ex("task_alloc_racy.koord", "task_alloc.toml", blackbox="straight")
    assert r.status == "violation"
    v = r.violations[0]
    assert v.kind == "invariant" and v.name == "unique"
    # the shortest: both robots claim in the first round, reading the same claims
    assert len(r.trace) == 2
    assert {s.agent for s in r.trace} == {0, 1}
    assert {s.rule for s in r.trace} == {"EVENT TRANS"} and {s.event for s in r.trace} == {"claim"}


def test_task_allocation_under_nondet_a_crossing_leg_may_fail():
    """Koord has no port for a failed leg: under the covering nondet two
    robots whose legs cross may both fail, and the team stalls (the claim
    is still never doubled)."""
    r = _ex("task_alloc.koord", "task_alloc.toml", find_all=True)
    kinds = {v.kind for v in r.violations}
    assert "stall" in kinds and "invariant" not in kinds, r.verdict


def test_task_allocation_semantics_pccl_agrees_on_the_claims():
    r = _ex("task_alloc.koord", "task_alloc.toml", blackbox="straight", semantics="pccl",
            properties=["eventually size(done) == size(sites)"])
    assert r.status == "exhaustive" and not r.violations, r.verdict
    r = _ex("task_alloc_racy.koord", "task_alloc.toml", blackbox="straight", semantics="pccl")
    assert r.status == "violation" and r.violations[0].name == "unique"


# ---- shape formation -------------------------------------------------------

def test_shape_formation_forms_the_shape():
    r = _ex("shape.koord", "shape.toml", blackbox="straight", properties=[ALL_EXIT])
    assert r.status == "exhaustive" and not r.violations, r.verdict
    res = run(load_program(k("shape.koord")), world=k("shape.toml"), blackbox="straight",
              max_time=60)
    assert res.status == "final", res.message
    from pccl.model.layout import AGS, POS
    assert [ag[POS][:2] for ag in res.final[AGS]] == [(0.0, 4.0), (3.0, 8.0), (6.0, 4.0)]


def test_shape_formation_under_nondet_holds_but_is_not_claimed_exhaustive():
    r = _ex("shape.koord", "shape.toml", properties=[ALL_EXIT])
    assert r.status != "violation" and not r.violations, r.verdict
    assert "exhaustive" not in r.verdict.split("—")[0] and "not exhaustive" in r.verdict


def test_shape_formation_stopping_early_is_caught():
    r = _ex("shape_early.koord", "shape.toml", blackbox="straight")
    assert r.status == "violation" and r.violations[0].name == "formed", r.verdict


# ---- follow path -----------------------------------------------------------

@pytest.mark.parametrize("agents", [2, 3])
def test_follow_path_every_robot_ends_its_path(agents):
    r = _ex("follow_path.koord", "allstop.toml", agents=agents, blackbox="straight",
            properties=[ALL_EXIT])
    assert r.status == "exhaustive" and not r.violations, r.verdict


def test_follow_path_and_follow_points_end_alike():
    """The same tour, given at once (Motion.path) or point by point
    (Motion.target): the robots end at the same places."""
    ends = []
    for name in ("follow_path.koord", "follow_points.koord"):
        res = run(load_program(k(name)), world=k("allstop.toml"), agents=2, blackbox="straight",
                  max_time=60)
        assert res.status == "final", res.message
        from pccl.model.layout import AGS, POS
        ends.append([ag[POS][:2] for ag in res.final[AGS]])
    assert ends[0] == ends[1] == [(3.0, 0.0), (3.0, 2.0)]


# ---- agreement: symmetry on and off ----------------------------------------

@pytest.mark.parametrize("name,world", [("task_alloc.koord", "task_alloc.toml"),
                                        ("task_alloc_racy.koord", "task_alloc.toml"),
                                        ("follow_path.koord", "allstop.toml")])
def test_examples_same_verdict_with_and_without_reduction(name, world):
    a = _ex(name, world, blackbox="straight", reduce="none", exact=True, find_all=True)
    b = _ex(name, world, blackbox="straight", find_all=True)
    assert a.status == b.status
    assert {(v.kind, v.name, v.line) for v in a.violations} == \
        {(v.kind, v.name, v.line) for v in b.violations}
