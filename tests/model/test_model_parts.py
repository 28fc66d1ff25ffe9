"""The model split of issue 22: properties (pccl/model/properties.py), the
Init-block search (pccl/model/initstates.py), the world, blackbox and clock
(pccl/model/environment.py) and the reductions as a wrapper around the model
(pccl/model/reduce.py's Reduced), each checked against the engine it came from."""

from __future__ import annotations

from collections import deque

import pytest

from pccl.api import explore_model, make_model
from pccl.model.engine import Model
from pccl.cli import cli_spelling
from pccl.lang.errors import PcclError, location_spelling, spell
from pccl.model.initstates import InitSearch
from pccl.model.options import ModelOptions
from pccl.lang.parser import parse_file
from pccl.model.properties import sources
from pccl.model.reduce import Reduced, unreduced

from conftest import FISCHER, RACE, RACE_WORLD

MUTEX = "count(inCs) <= 1"


def _reachable(m, limit=3000) -> list:
    """Up to ``limit`` states reachable in ``m`` (its own successors)."""
    seen: dict = {}
    todo = deque(m.init_states())
    while todo and len(seen) < limit:
        st = todo.popleft()
        if st in seen:
            continue
        seen[st] = None
        todo.extend(s for _, s in m.successors(st))
    return list(seen)


def test_reductions_wrap_the_model_and_replace_none_of_its_methods():
    m = make_model(FISCHER, invariants=[MUTEX], reduce="auto")
    base = m.model
    assert isinstance(m, Reduced) and isinstance(m, Model) and type(base) is Model
    assert m.reduction.on                      # merge, symmetry, por: all sound here
    for name in ("successors", "key", "violations"):
        assert name not in vars(base), name    # the model's methods are its own
    assert m.successors is not base.plain_successors
    assert unreduced(m) is base and unreduced(base) is base
    # attributes not the wrapper's are the model's, read and written
    assert m.compiled is base.compiled and m.N == base.N
    m.lock_deadlocks = False
    assert base.lock_deadlocks is False and "lock_deadlocks" not in vars(m)


def test_without_reductions_the_wrapper_is_the_model_s_fast_path():
    m = make_model(FISCHER, reduce="none")
    assert not m.reduced
    assert m.successors is m.model.plain_successors
    assert m.key is m.model.plain_key and m.violations is m.model.fast_violations


def test_coverage_rewraps_without_touching_the_model():
    m = make_model(FISCHER, reduce="auto")
    c = m.with_uses(("coverage",))
    assert c.model is m.model and c.reduction.on == () and m.reduction.on
    assert set(c.reduction.off) >= {"merge", "symmetry", "por"}


def test_a_bare_model_is_explored_with_the_reductions_its_options_ask_for():
    prog = parse_file(RACE)
    plain = Model(prog, ModelOptions(world=RACE_WORLD, blackbox="instant", reduce="none"))
    r1 = explore_model(plain, timelock=False, stall=False)
    r2 = explore_model(make_model(prog, world=RACE_WORLD, blackbox="instant", reduce="none"),
                       timelock=False, stall=False)
    assert (r1.status, r1.stats.states) == (r2.status, r2.stats.states)
    assert isinstance(r1.model, Reduced) and r1.model.model is plain


@pytest.mark.parametrize("prog, kw", [
    (FISCHER, {"invariants": [MUTEX, "reqid == -1"], "overrides": {"k": "0"}}),
    (RACE, {"world": RACE_WORLD, "invariants": ["size(dests) >= 2"]}),
    (FISCHER, {"invariants": [MUTEX, "reqid == -1"], "overrides": {"k": "0"}, "collisions": True})])
def test_fast_violations_agree_with_the_readable_ones(prog, kw):
    """The compiled fast path and pccl.model.properties' violations give the same
    violations on every reachable state (two ways of one result)."""
    m = make_model(prog, reduce="none", **kw)
    base = m.model
    states = _reachable(base, 20000)
    assert len(states) > 50
    bad = 0
    for st in states:
        assert base.fast_violations(st) == base.violations(st)
        bad += bool(base.violations(st))
    assert bad                                  # some state violates a property


def test_generic_and_generated_successors_and_keys_agree():
    m = make_model(FISCHER, reduce="none").model
    for st in _reachable(m, 1000):
        assert m.plain_successors(st) == Model.successors(m, st)
        assert m.plain_key(st) == m.key(st)


def test_the_init_search_is_the_model_s_initial_states():
    m = make_model(FISCHER, agents=3, reduce="none", overrides={"k": "1"}).model
    inits = list(InitSearch(m).states())
    assert inits == list(m.init_states())
    assert len(inits) == len(set(inits)) == (2 * 6) ** 3      # rand(k), rand(5) per agent
    search = InitSearch(m)
    search.INIT_DEDUP = 0                                     # no early deduplication
    assert list(search.states()) == inits


def test_property_sources_keep_their_order_and_names():
    prog = parse_file(FISCHER)
    got = list(sources(prog, ["k  >= 0"], [" eventually inCs[0]", "d >= 0"]))
    # where each was given: the option as a placeholder, spelt by the front end
    assert [(s.name, s.temporal, s.filename) for s in got[-3:]] == [
        ("k  >= 0", False, "{invariants} #1"), ("eventually inCs[0]", True, "{properties} #1"),
        ("d >= 0", False, "{properties} #2")]
    assert [spell(s.filename, location_spelling(cli_spelling)) for s in got[-3:]] == [
        "--invariant #1", "--property #1", "--property #2"]


def test_a_temporal_invariant_text_is_refused_by_the_properties_module():
    prog = parse_file(FISCHER)
    with pytest.raises(PcclError) as e:
        list(sources(prog, ["eventually inCs[0]"]))
    # the API's spelling, then the command line's
    assert e.value.filename == "invariants #1" and "goes with properties" in e.value.message
    e.value.respell(cli_spelling)
    assert e.value.filename == "--invariant #1" and "goes with --property" in e.value.message
