"""Acceptance counts of Fischer's protocol (2 agents), equal to an independent
model's, with the explorer's default 128-bit fingerprints and, where it fits,
with exact state storage.  The counts are those of the unreduced semantics
(``reduce="none"``; the default ``auto`` explores fewer states, and
tests/model/test_reduce.py checks that its verdicts are the same).

These are long runs (``slow``): the paper's k = 10 alone explores
26,362,800 states.  Deselect them in the inner loop with ``-m 'not slow'``.
"""

import pytest

from pccl.api import explore, make_model, explore_model

FISCHER = "programs/fischer.pccl"
MUTEX = "count(inCs) <= 1"

pytestmark = pytest.mark.slow


@pytest.mark.parametrize("k, d, states, transitions", [
    (2, 2, 1_066_248, 1_805_328),
    (2, 1, 1_408_680, 2_389_464),
])
def test_fischer_exhaustive_counts(k, d, states, transitions):
    r = explore(FISCHER, overrides={"k": str(k), "d": str(d)}, reduce="none")
    assert r.status == "exhaustive" and r.exit_status == 0
    assert (r.stats.states, r.stats.transitions) == (states, transitions)
    assert r.collision_probability < 1e-25


def test_fischer_timed_count_and_exact_agree():
    opts = dict(overrides={"k": "2", "d": "2"}, max_time=4, find_all=True, reduce="none")
    fp = explore(FISCHER, **opts)
    ex = explore(FISCHER, exact=True, **opts)
    assert fp.status == ex.status == "bounded" and fp.bound_labels == ["max_time=4"]
    assert fp.stats.states == ex.stats.states == 85_932
    assert fp.stats.transitions == ex.stats.transitions


def test_fischer_2_2_fingerprints_equal_exact():
    opts = dict(overrides={"k": "2", "d": "2"}, find_all=True, reduce="none")
    fp = explore(FISCHER, **opts)
    ex = explore(FISCHER, exact=True, **opts)
    assert (fp.status, fp.stats.states, fp.stats.transitions, fp.stats.max_depth) == \
        (ex.status, ex.stats.states, ex.stats.transitions, ex.stats.max_depth)


def test_fischer_paper_k10_exhaustive():
    """The paper's Fischer (k = 10), whole space (no property: the program's
    mutual-exclusion bug would stop the search): 26,362,800 states.  The
    time-lock and stall checks are off: they record the 44 million
    transitions' graph (198 s of the suite at load 5), and the counts are
    the rules' whichever checks run (test_fischer_timed_count_and_exact_agree
    and the reductions' tests run them)."""
    m = make_model(FISCHER, invariants=(), reduce="none")
    r = explore_model(m, timelock=False, stall=False)
    assert r.status == "exhaustive"
    assert (r.stats.states, r.stats.transitions) == (26_362_800, 44_152_200)
