"""Koord's lists of records, nested records, ``for x in xs:`` and
``any``/``all`` under both semantics (docs/koord.md, "Records" and
"Constructs"): the program explores exactly as its hand-written PCCL twin,
and under Koord's round semantics a whole loop runs inside the robot's one
event transition."""

from __future__ import annotations

from pathlib import Path

from pccl.api import explore, run
from pccl.lang.koord import parse_koord
from pccl.lang.parser import parse_program

PROGRAMS = Path(__file__).resolve().parents[1] / "programs"
LISTS = (PROGRAMS / "koord_lists.koord").read_text()
TWIN = (PROGRAMS / "koord_lists_twin.pccl").read_text()


def test_lists_explore_as_the_twin_under_pccl_semantics():
    a = explore(parse_koord(LISTS, "lists.koord"), semantics="pccl", reduce="none", agents=2)
    b = explore(parse_program(TWIN, "twin.pccl"), reduce="none", agents=2)
    assert a.status == b.status == "exhaustive", a.verdict
    assert (a.stats.states, a.stats.transitions) == (b.stats.states, b.stats.transitions)


def test_lists_under_koord_semantics_reduced_and_not_agree():
    a = explore(parse_koord(LISTS, "lists.koord"), reduce="none", agents=3)
    b = explore(parse_koord(LISTS, "lists.koord"), agents=3, exact=True)
    assert a.status == b.status == "exhaustive", (a.verdict, b.verdict)
    assert b.stats.states <= a.stats.states


def test_a_loop_is_inside_the_one_event_transition():
    """Under Koord's semantics each robot's event, loops included, is one
    step of the trace; under PCCL's every statement is one."""
    k = run(parse_koord(LISTS, "lists.koord"), agents=2, seed=1, record_trace=True)
    p = run(parse_koord(LISTS, "lists.koord"), agents=2, seed=1, record_trace=True,
            semantics="pccl")
    assert [s.label[:2] for s in k.trace.steps] == [("EVENT TRANS", 0), ("EVENT TRANS", 1)]
    assert k.status == p.status
    # under PCCL's semantics every statement of the loops is a step of its own
    assert sum(1 for s in p.trace.steps if s.label[0] == "STATEMENT") > 2 * 20


def test_a_wrong_loop_sum_is_caught():
    bad = LISTS.replace("      total = total + v\n", "      total = total + v + v\n")
    r = explore(parse_koord(bad, "lists.koord"), agents=2)
    assert r.status == "violation" and r.violations[0].name == "sum"
