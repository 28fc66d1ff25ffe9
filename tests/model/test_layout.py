"""The configuration's layout (pccl.model.layout): one module owns it.

* No module outside pccl/model/layout.py and the rule kernel (semantics/rules.py)
  reads a configuration cell by number — not even inside generated code.
* The views, the constants and the let-style helpers agree with each other on
  real states of shipped programs.
"""

from __future__ import annotations

import itertools
import re
from pathlib import Path

import pytest

from conftest import FISCHER, RACE, RACE_WORLD, model_of
from pccl.model import layout as L
from pccl.api import load_program, make_model
from pccl.lang.world import load_world

ROOT = Path(__file__).resolve().parents[2]

#: Where numeric subscripts of configurations are allowed: the layout module
#: itself, and the rule kernel (named constants cost 1.5-3 % there).
ALLOWED = {"pccl/model/layout.py", "semantics/rules.py"}

#: Names that hold a configuration, an agent cell or a reach cell somewhere in
#: the code (``st``, ``ag``, ``s2``, ``before``, ``res.final``, ...).
_CONFIG_NAMES = (r"st|state|s|ag|agent|ga|gb|ra|rb|reach|before|after|last|final|"
                 r"prev|cur")
_PATTERNS = [
    # st[4], ag[7], s2[0], st0[1], before[0], res.final[4] (not self.last[1])
    re.compile(rf"(?<![\w])(?<!self\.)(?:{_CONFIG_NAMES})\d?\[\d+\]"),
    # the same inside generated code: "ag[5][" or 'st[3]'
    re.compile(r"[\"'{ (](?:st|ag|ags\[\w+\])\[\d+\]"),
    # a numeric cell after a named one: st[AGS][i][3], ag[REACH][4]
    re.compile(r"\[(?:AGS\]\[\w+|REACH)\]\[\d+\]"),
    # numeric cell chains: x[4][i][3], x[7][3]
    re.compile(r"(?<![\w])(?:st|s|ag|a)\w*\[[4-7]\]\[\w+\]"),
]


def numeric_subscripts(text: str) -> list:
    """``[(line number, line)]`` of the lines that read a configuration cell by number."""
    hits = []
    for n, line in enumerate(text.splitlines(), 1):
        code = line.split("#", 1)[0]
        if any(p.search(code) for p in _PATTERNS):
            hits.append((n, line.strip()))
    return hits


def test_no_numeric_subscripts_of_configurations_outside_the_layout():
    found = []
    for d in ("pccl", "semantics", "blackboxes"):
        for f in sorted((ROOT / d).rglob("*.py")):
            rel = f.relative_to(ROOT).as_posix()
            if rel in ALLOWED:
                continue
            found += [f"{rel}:{n}: {line}" for n, line in numeric_subscripts(f.read_text())]
    assert not found, ("configuration cells read by number; use the constants of "
                       "pccl/model/layout.py (st[AGS], ag[STATUS], ...):\n" + "\n".join(found))


def test_no_numeric_subscripts_of_configurations_in_the_tests():
    found = []
    for f in sorted((ROOT / "tests").glob("**/test_*.py")):
        found += [f"{f.name}:{n}: {line}" for n, line in numeric_subscripts(f.read_text())
                  if f.name != "test_layout.py"]
    assert not found, "tests read configuration cells by number:\n" + "\n".join(found)


@pytest.mark.parametrize("text", [
    "x = st[4][i]", "a = ag[3]", "t = res.final[0]", 'src = f"    sh = st[3]; ags = st[4]"',
    "ref = f\"ag[5][{vs.slot}]\"", "f = ag[REACH][4]", "s = st[AGS][i][3]", "s2[1] == 0",
    "return st0[0]", "cell = ags[j][7][3]", "o.times.append(res.final[0])",
])
def test_the_grep_catches_numeric_subscripts(text):
    assert numeric_subscripts(text), text


@pytest.mark.parametrize("text", [
    "x = st[AGS][i]", "a = ag[STATUS]", "t = res.final[TIME]", "p = (pos[0], pos[1])",
    "rate = (states - self.last[0])", "h = args[0]", "x = st[AGS][i][LOC][0]",
    "q = t[0] + p[1]", "lab = trace[0][1]   # (label, state) pairs",
])
def test_the_grep_lets_other_subscripts_pass(text):
    assert not numeric_subscripts(text), text


# -- the layout itself, on real states ---------------------------------------------------

def _states(model, limit=300) -> list:
    """Up to ``limit`` reachable states, breadth first."""
    seen, order = set(), []
    frontier = list(model.init_states())
    while frontier and len(order) < limit:
        nxt = []
        for st in frontier:
            if st in seen:
                continue
            seen.add(st)
            order.append(st)
            nxt.extend(s for _, s in model.successors(st))
        frontier = nxt
    return order[:limit]


@pytest.fixture(scope="module")
def states():
    race = make_model(load_program(RACE), world=load_world(RACE_WORLD), blackbox="straight",
                      agents=3)
    fischer = make_model(load_program(FISCHER), agents=2)
    four = model_of("""
        loc:
          int x = 0;

        Step():
          pre(x < 2);
          eff:
            x = x + 1;
        """, agents=4)
    return _states(race) + _states(fischer) + _states(four)


def test_views_are_the_configurations_they_show(states):
    for st in states:
        v = L.view(st)
        assert v == st and hash(v) == hash(st)
        assert isinstance(v.agents[0], L.Agent) and isinstance(v.agents[0].reach, L.Reach)
        assert (v.time, v.phase, v.lock_queue, v.shared, v.env) == \
            (st[L.TIME], st[L.PHASE], st[L.LQ], st[L.SH], st[L.ENV])
        for a, ag in zip(v.agents, st[L.AGS]):
            assert (a.pc, a.counter, a.lock_state, a.status, a.locals, a.allread, a.position) \
                == (ag[L.PC], ag[L.CNT], ag[L.LCK], ag[L.STATUS], ag[L.LOC], ag[L.AR], ag[L.POS])
            r = ag[L.REACH]
            assert (a.reach.target, a.reach.obstacles, a.reach.t0, a.reach.done, a.reach.fail) \
                == (r[L.TARGET], r[L.OBSTACLES], r[L.T0], r[L.DONE], r[L.FAIL])


def test_views_cover_every_cell():
    assert len(L.State._fields) == L.N_STATE_CELLS
    assert len(L.Agent._fields) == L.N_AGENT_CELLS
    assert len(L.Reach._fields) == L.N_REACH_CELLS


def test_let_helpers_agree_with_the_views_replace(states):
    """Each helper (plain tuples, the hot path) against NamedTuple._replace on the view."""
    agent_helpers = [(L.with_pc, "pc"), (L.with_counter, "counter"), (L.with_lock, "lock_state"),
                     (L.with_status, "status"), (L.with_locals, "locals"),
                     (L.with_allread, "allread")]
    marker = ("new",)
    for st in states:
        for ag in st[L.AGS]:
            for fn, field in agent_helpers:
                new = fn(ag, marker)
                assert type(new) is tuple
                assert new == L.agent_view(ag)._replace(**{field: marker})
            for k in range(L.N_AGENT_CELLS):
                assert L.with_cell(ag, k, marker) == \
                    L.agent_view(ag)._replace(**{L.Agent._fields[k]: marker})
        v = L.view(st)
        assert L.with_lock_queue(st, marker) == v._replace(lock_queue=marker)
        assert L.with_shared(st, marker) == v._replace(shared=marker)
        assert L.with_agents(st, marker) == v._replace(agents=marker)
        assert L.without_time(st) == tuple(v)[1:]
        assert L.make_state(*v) == st
        for ag in st[L.AGS]:
            assert L.make_agent(*L.agent_view(ag)) == ag


def test_put_agent_for_every_team_size(states):
    """put_agent's unrolled small-team paths and its general path against _replace."""
    sizes = set()
    for st in states:
        n = len(st[L.AGS])
        sizes.add(n)
        v = L.view(st)
        for i, sh in itertools.product(range(n), (None, ("sh",))):
            new = L.put_agent(st, i, ("agent",), sh)
            want_agents = v.agents[:i] + (("agent",),) + v.agents[i + 1:]
            want = v._replace(agents=want_agents, shared=v.shared if sh is None else sh)
            assert type(new) is tuple and new == want
    assert {2, 3, 4} <= sizes


def test_status_codes():
    assert not L.is_stuck(L.RUNNING) and not L.is_stuck(L.EXITED) and L.is_stuck(L.STUCK)
    m = model_of("""
        loc:
          int x = 0;

        Go():
          pre(true);
          eff:
            x = 1 / x;
        """)
    (st,) = m.init_states()
    for rule in ("EVENT SELECT", "STATEMENT"):        # the division by zero
        st = next(s for lab, s in m.successors(st) if lab[:2] == (rule, 0))
    code = st[L.AGS][0][L.STATUS]
    assert L.is_stuck(code) and m.compiled.stuck_reasons[code][1] == "division by zero"
