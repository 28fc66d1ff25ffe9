"""Dead variables under Koord's round semantics (issue 47; docs/koord.md,
"Reductions under the round semantics"): on where something can be dead,
by name alone or with symmetry; the verdicts, the shortest counterexamples'
lengths and the violations are the unreduced search's; merging and
partial-order reduction stay refused."""

from __future__ import annotations

from pathlib import Path

import pytest

from pccl.api import explore, make_model
from pccl.lang.errors import PcclError
from pccl.lang.koord import parse_koord

from cases import KOORD_LATE_READ

ROOT = Path(__file__).resolve().parents[2]
K = ROOT / "programs" / "koord"

#: a local written by one event and read by the next event one round later:
#: live at the top of the block only through the event body (the guards
#: read `c` alone); only v = 2 fails the assertion
LATE_READ = KOORD_LATE_READ


def _verdict(r):
    return r.status, sorted((v.kind, v.name, v.depth) for v in r.violations)


@pytest.mark.parametrize("name, kw", [
    ("add_numbers.koord", {"agents": 3}),
    ("fischer.koord", {"overrides": {"k": "3"}}),
    ("task_alloc.koord", {"world": K / "task_alloc.toml", "blackbox": "straight"}),
])
def test_dead_keeps_the_verdicts_of_the_shipped_programs(name, kw):
    truth = explore(K / name, reduce="none", exact=True, engine="python", **kw)
    dead = explore(K / name, reduce="dead", **kw)
    auto = explore(K / name, **kw)
    assert "dead" in dead.model.reduction.on and "dead" in auto.model.reduction.on
    assert _verdict(dead) == _verdict(truth) == _verdict(auto)
    assert auto.stats.states <= dead.stats.states <= truth.stats.states


def test_a_local_read_one_round_later_stays_live():
    prog = parse_koord(LATE_READ, "late.koord")
    truth = explore(prog, reduce="none", exact=True, engine="python", find_all=True)
    for red in ("dead", "symmetry,dead", "auto"):
        r = explore(prog, reduce=red, find_all=True)
        assert r.status == truth.status == "violation"
        assert {v.kind for v in r.violations} == {v.kind for v in truth.violations} \
            == {"assert", "deadlock"}
        # the counterexample is a real run: detour, then setB, then use's assertion
        steps = [s.event for s in r.violations[0].trace if s.event]
        assert steps[-1] == "use" and "setB" in steps and "detour" in steps, steps


def test_only_symmetry_and_dead_are_argued():
    m = make_model(K / "add_numbers_lost.koord")
    assert "merge" in m.reduction.off and "por" in m.reduction.off
    assert "not argued for Koord's round semantics" in m.reduction.off["merge"]
    assert "dead" not in m.reduction.off
    for red in ("merge", "por", "counters", "symmetry,por"):
        with pytest.raises(PcclError, match="cannot be used here: not argued"):
            make_model(K / "add_numbers_lost.koord", reduce=red)
    make_model(K / "fischer.koord", reduce="symmetry,dead")


def test_coverage_turns_dead_off_under_koord_too():
    r = explore(K / "add_numbers.koord", coverage=True)
    assert "dead" not in r.model.reduction.on and "symmetry" not in r.model.reduction.on
    with pytest.raises(PcclError, match="dead reduction cannot be used here: .*coverage"):
        explore(K / "add_numbers.koord", coverage=True, reduce="dead")
