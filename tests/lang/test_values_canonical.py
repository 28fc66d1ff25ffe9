"""Canonical values: one representation per PCCL value in every stored
configuration (docs/decisions.md, "Canonical values").

State identity hashes a byte encoding of the state tuple (``marshal``), so
``1``, ``1.0`` and ``True`` would be three different states: every write path
must convert to the declared type, at every depth, and a computed float must
be finite (else the agent is stuck) and never ``-0.0``.
"""

from __future__ import annotations

import marshal
import math
import textwrap

import pytest

from pccl.output import display as D
from pccl.api import explore
from pccl.lang.errors import PcclError

from conftest import AGS, STATUS, model_of, shared


def init_state(src, **kw):
    m = model_of(src, agents=1, **kw)
    (st,) = m.init_states()
    return m, st


def assert_floats(v):
    """Every number inside ``v`` (nested tuples) is a finite, non-negative-zero float."""
    if isinstance(v, tuple):
        for x in v:
            assert_floats(x)
        return
    assert type(v) is float, f"{v!r} is {type(v).__name__}, not float"
    assert math.isfinite(v), v
    assert v != 0.0 or math.copysign(1.0, v) == 1.0, v


def stuck(m, st, i=0):
    """(reason, line) of stuck agent i, or None."""
    code = st[AGS][i][STATUS]
    if code < 2:
        return None
    kind, reason, where = m.compiled.stuck_reasons[code]
    return reason, m.compiled.span_of(where).line


# ---------------------------------------------------------------------------
# int widens to float on every write path, at every depth
# ---------------------------------------------------------------------------

def test_list_of_float_literal_widens_so_division_is_float():
    m, st = init_state("""
        allwrite:
          List<float> xs = [1];
          float r;
        init:
          r = head(xs) / 2;
        """)
    assert shared(m, st, "xs") == (1.0,)
    assert_floats(shared(m, st, "xs"))
    assert shared(m, st, "r") == 0.5


def test_list_of_float_literal_is_one_state_with_float_literal():
    m, st = init_state("""
        allwrite:
          List<float> a = [1, 2];
          List<float> b = [1.0, 2.0];
          float c = 1;
          float d = 1.0;
        """)
    assert marshal.dumps(shared(m, st, "a"), 2) == marshal.dumps(shared(m, st, "b"), 2)
    assert marshal.dumps(shared(m, st, "c"), 2) == marshal.dumps(shared(m, st, "d"), 2)


def test_division_property_sees_float():
    res = explore(textwrap.dedent("""
        allwrite:
          List<float> xs = [1];
        E():
          pre(true);
          eff:
            exit();
        """).lstrip("\n"), source=True, agents=1, blackbox="instant", invariants=["head(xs) / 2 == 0.5"])
    assert res.status == "exhaustive", res.verdict


def test_nested_lists_and_arrays_widen():
    m, st = init_state("""
        allwrite:
          List<List<float>> ll = [[1], [2.5]];
          List<List<int>> li = [[1, 2, 3]];
          List<List<float>> l2;
          List<float> a[2] = [1];
          float f[3] = 2;
          List<ItemPosition> ps = [ItemPosition(1, 2)];
          int n = 4;
        init:
          l2 = li;
          add(ll, head(li));
          a[1] = [n, 5];
          f[0] = n;
        """)
    assert shared(m, st, "ll") == ((1.0,), (2.5,), (1.0, 2.0, 3.0))
    assert shared(m, st, "l2") == ((1.0, 2.0, 3.0),)
    assert shared(m, st, "a") == ((1.0,), (4.0, 5.0))
    assert shared(m, st, "f") == (4.0, 2.0, 2.0)
    assert shared(m, st, "ps") == ((1.0, 2.0, 0.0),)
    for name in ("ll", "l2", "a", "f", "ps"):
        assert_floats(shared(m, st, name))
    # the int list itself stays ints
    assert all(type(x) is int for x in shared(m, st, "li")[0])
    # a List<float> of three elements displays as a list, not as a position
    assert "l2 = [[1.0, 2.0, 3.0]]" in D.format_state(m, st)


def test_add_int_into_list_of_float():
    m, st = init_state("""
        allwrite:
          List<float> xs = [];
          int n = 7;
        init:
          add(xs, 3);
          add(xs, n);
          add(xs, n / 2);
        """)
    assert shared(m, st, "xs") == (3.0, 7.0, 3.0)
    assert_floats(shared(m, st, "xs"))


# ---------------------------------------------------------------------------
# world (uninterpreted) values and --set overrides
# ---------------------------------------------------------------------------

def test_world_int_for_float_uses():
    m, st = init_state("""
        allwrite:
          List<float> xs = [];
          List<float> ys = [getInput(), 1];
          float f;
          ItemPosition g = getCorner()[0];
          List<ItemPosition> gs = getCorner();
        init:
          add(xs, getInput());
          f = getInput();
        """, functions={"getInput": 2, "getCorner": ((4, 0), (1, 2, 3))})
    assert shared(m, st, "xs") == (2.0,)
    assert shared(m, st, "ys") == (2.0, 1.0)
    assert shared(m, st, "f") == 2.0
    assert shared(m, st, "g") == (4.0, 0.0, 0.0)
    assert shared(m, st, "gs") == ((4.0, 0.0, 0.0), (1.0, 2.0, 3.0))
    for name in ("xs", "ys", "f", "g", "gs"):
        assert_floats(shared(m, st, name))


def test_world_bool_never_stored_as_int():
    with pytest.raises(PcclError, match="getInput"):
        init_state("""
            allwrite:
              List<int> ns = [getInput()];
            """, functions={"getInput": True})
    with pytest.raises(PcclError, match="getInput"):
        model_of("""
            allwrite:
              List<int> ns = [];
            init:
              add(ns, getInput());
            """, functions={"getInput": True})


def test_world_value_that_does_not_fit_at_run_time_gets_agent_stuck():
    m, st = init_state("""
        allwrite:
          int n;
        init:
          n = getInput()[1];
        """, functions={"getInput": (1, True)})
    reason, line = stuck(m, st)
    assert "expected an int" in reason and line == 4


def test_set_override_widens_float_variables():
    m, st = init_state("""
        allwrite:
          float f = 0.5;
          List<float> xs = [0.5];
        """, overrides={"f": "3", "xs": "[1, 2]"})
    assert shared(m, st, "f") == 3.0
    assert shared(m, st, "xs") == (1.0, 2.0)
    assert_floats(shared(m, st, "f"))
    assert_floats(shared(m, st, "xs"))


# ---------------------------------------------------------------------------
# NaN and infinities are runtime errors; -0.0 is stored as 0.0
# ---------------------------------------------------------------------------

def test_float_overflow_gets_agent_stuck_with_its_line():
    m, st = init_state("""
        allwrite:
          float x = 1e308;
        init:
          x = x * 10;
        """)
    assert stuck(m, st) == ("float overflow: the result is inf", 4)
    assert shared(m, st, "x") == 1e308


def test_float_overflow_in_explore_reports_line():
    res = explore(textwrap.dedent("""
        allwrite:
          float x = 1e308;
        Grow():
          pre(true);
          eff:
            x = x * 10;
            exit();
        """).lstrip("\n"), source=True, agents=1, blackbox="instant")
    assert res.status == "violation"
    assert "float overflow" in res.violation["message"]
    assert res.violation["line"] == 6


def test_inf_minus_inf_gets_agent_stuck():
    m, st = init_state("""
        allwrite:
          float big = 1e308;
          float r = 0.0;
        init:
          r = (big * 10) - (big * 10);
        """)
    assert stuck(m, st) == ("float result is not a number (NaN)", 5)
    assert shared(m, st, "r") == 0.0


def test_non_finite_in_list_and_position_gets_agent_stuck():
    m, st = init_state("""
        allwrite:
          float big = 1e308;
          List<float> xs = [];
        init:
          add(xs, big * 10);
        """)
    assert stuck(m, st)[1] == 5 and shared(m, st, "xs") == ()
    m, st = init_state("""
        allwrite:
          float big = 1e308;
          ItemPosition p;
        init:
          p = ItemPosition(big * 10, 0);
        """)
    reason, line = stuck(m, st)
    assert "not finite" in reason and line == 5


def test_float_literal_out_of_range_is_a_load_error():
    with pytest.raises(PcclError, match="out of range"):
        init_state("""
            allwrite:
              float x = 1e999;
            """)


def test_negative_zero_is_stored_as_zero():
    m, st = init_state("""
        allwrite:
          float z = -0.0;
          float y = 0.0;
          ItemPosition p = ItemPosition(-0.0, 0 - 0.0);
          List<float> xs = [-0.0];
        init:
          y = -y;
        """)
    for name in ("z", "y", "p", "xs"):
        v = shared(m, st, name)
        assert marshal.dumps(v, 2) == marshal.dumps((0.0,) * len(v) if isinstance(v, tuple) else 0.0, 2)
