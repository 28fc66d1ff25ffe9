"""Per-agent temporal properties by the orbit argument (issue 46;
docs/reductions.md, "Per-agent temporal properties").

``forall i: P(i) ~> Q(i)`` is one property per agent.  Where the program is
symmetric, the formula names no agent but ``i`` and the initial states are
closed under renaming agents, instance ``i = 0`` is checked alone, on the
quotient by the renamings that keep agent 0 in place (``Plan.fixed``), and
the other instances share its verdict (under ``--all`` each with the
counterexample renamed).  Every verdict here is held equal to ``--reduce
none --engine python`` (status, violations, properties that hold), on both
engines, and every counterexample shown is a real run of the unreduced
rules.  Teeth: instance 0 alone on the quotient by *all* renamings (agent 0
not kept in place), and the orbit argument without its condition on the
initial states (robots that start at different places), are both caught.
"""

from __future__ import annotations

import pytest

from pccl.api import explore, make_model
from pccl.model import reduce as RD
from pccl.model.layout import DISCRETE, PHASE
from pccl.model.reduce import unreduced

from conftest import verdict as agreed

#: one agent grabs the token and exits; the others spin for ever: every
#: instance of `forall i: eventually exited[i]` fails (some run makes agent
#: i a loser), but on the quotient by every renaming a representative may
#: always show the winner as agent 0
WINNER = """allwrite:
  int owner = -1;
loc:
  bool lost = false;
Grab():
  pre(owner == -1);
  eff:
    owner = getAgentIndex();
    exit();
Spin():
  pre(owner != -1 && owner != getAgentIndex());
  eff:
    lost = !lost;
"""

#: a token passed on: each agent enters twice, then exits (every instance
#: of the properties below holds)
TOKEN = """allwrite:
  int owner = -1;
loc:
  bool want = true;
  bool inCs = false;
  int c = 0;
Try():
  pre(want && owner == -1);
  eff:
    owner = getAgentIndex();
    want = false;
    inCs = true;
Leave():
  pre(inCs);
  eff:
    inCs = false;
    owner = -1;
    c = c + 1;
    if (c >= 2):
      exit();
    else:
      want = true;
"""

#: robots drive to (2, 0); with WALLED_WORLD robot 1 has a wall in its way
#: (under straight it fails and never exits), robot 0 arrives
DRIVE = """loc:
  bool started = false;
Go():
  pre(!started);
  eff:
    started = true;
    doReach(ItemPosition(2, 0), getObs());
Arrive():
  pre(started && doReach_done);
  eff:
    exit();
"""
WALLED_WORLD = """agents = 2
resolution = 0.01
speed = 1.0
start = [[0, 0], [3, 0]]

[[obstacles]]
polygon = [[2.4, -1], [2.6, -1], [2.6, 1], [2.4, 1]]
"""

FISCHER_SMALL = dict(overrides={"k": 1, "d": 1})


def verdict(res) -> tuple:
    return agreed(res, lines=False, holds=True)


def real_runs(res) -> bool:
    """Every counterexample of ``res`` is a run of the unreduced rules (each
    step a rule's), and a lasso's cycle returns to its first state and lets
    time advance."""
    m = unreduced(res.model)
    for cx in res.counterexamples:
        tr = cx.trace
        if tr is None:
            continue
        if tr.initial not in set(m.init_states()):
            return False
        for st in tr.steps:
            if not any(lab == st.label and s == st.after for lab, s in m.successors(st.before)):
                return False
        if cx.cycle_start is not None:
            loop = cx.cycle_start
            if m.plain_key(tr.states[loop]) != m.plain_key(tr.last):
                return False
            if not any(s[PHASE] != DISCRETE for s in tr.states[loop + 1:]):
                return False
    return True


def both(src, props, **kw) -> tuple:
    """(truth, reduced results by engine): ``--reduce none --engine
    python`` and the default reductions on each engine, every violation."""
    kw = dict(kw, properties=props, find_all=True)
    truth = explore(src, reduce="none", engine="python", **kw)
    return truth, {e: explore(src, engine=e, **kw) for e in ("python", "auto")}


CASES = [
    ("winner-2", WINNER, 2, ["forall i: eventually exited[i]"]),
    ("winner-3", WINNER, 3, ["forall i: eventually exited[i]"]),
    ("token-3", TOKEN, 3, ["forall i: want[i] ~> inCs[i]", "forall i: eventually exited[i]"]),
    ("token-within", TOKEN, 2, ["forall i: inCs[i] ~> !inCs[i] within 1",
                                "forall i: want[i] ~> inCs[i] within 1"]),
    ("token-reachable", TOKEN, 3, ["forall i: reachable c[i] == 2", "forall i: reachable c[i] == 3"]),
]


@pytest.mark.parametrize("name,src,agents,props", CASES, ids=[c[0] for c in CASES])
def test_instance_zero_decides_every_instance(name, src, agents, props):
    truth, red = both(src, props, source=True, agents=agents)
    for engine, r in red.items():
        assert r.model.reduction.fixed == 1, (engine, r.model.reduction.describe())
        assert verdict(r) == verdict(truth), (engine, verdict(r), verdict(truth))
        assert real_runs(r), engine
    # the quotient that keeps agent 0 in place is smaller than the unreduced graph
    assert red["python"].stats.states < truth.stats.states


def test_fischer_forall_leads_to(tmp_path):
    """The benchmark's property on the paper's Fischer, small constants:
    every instance violated, each with a real lasso."""
    props = ["forall i: wait[i] ~> inCs[i]"]
    r = explore("programs/fischer.pccl", agents=2, properties=props, find_all=True, **FISCHER_SMALL)
    assert r.model.reduction.fixed == 1 and r.model.engine_used == "native"
    assert sorted(v["name"] for v in r.violations if v["kind"] == "liveness") == \
        [f"{props[0]} [i=0]", f"{props[0]} [i=1]"]
    assert real_runs(r)
    py = explore("programs/fischer.pccl", agents=2, properties=props, find_all=True, engine="python",
                 **FISCHER_SMALL)
    assert verdict(py) == verdict(r) and py.stats.states == r.stats.states


def test_the_other_instances_get_the_renamed_counterexample():
    r = explore(WINNER, source=True, agents=3, properties=["forall i: eventually exited[i]"],
                find_all=True, engine="python")
    live = {cx.violation.name: cx for cx in r.counterexamples if cx.violation.kind == "liveness"}
    assert len(live) == 3
    m = r.model
    c0 = live["forall i: eventually exited[i] [i=0]"]
    for j in (1, 2):
        cj = live[f"forall i: eventually exited[i] [i={j}]"]
        assert f"[i={j}]" in cj.violation.message
        assert cj.cycle_start == c0.cycle_start
        # shortening may have replaced either path: compare the renamed one
        # where both are the ones made (not shortened)
        if "shortened" not in (getattr(c0.shortening, "status", None), getattr(cj.shortening, "status", None)):
            assert cj.trace.states == m.mirror_trace(c0.trace, j).states
    assert real_runs(r)


def test_robots_that_start_apart_keep_every_instance(tmp_path):
    """Start positions break the symmetry of the initial states: the orbit
    argument is not used (the header says why), the instances are checked
    one by one (robot 0 arrives, robot 1 never does)."""
    walled = tmp_path / "walled.toml"
    walled.write_text(WALLED_WORLD)
    props = ["forall i: eventually exited[i]"]
    truth, red = both(DRIVE, props, source=True, world=str(walled), blackbox="straight")
    assert f"{props[0]} [i=0]" in truth.holds
    for engine, r in red.items():
        assert r.model.reduction.fixed == 0 and "symmetry" not in r.model.reduction.on
        assert "the initial states are not symmetric" in r.model.reduction.describe()
        assert verdict(r) == verdict(truth), engine


def test_the_plan():
    one = "forall i: eventually exited[i]"
    m = make_model(WINNER, source=True, agents=3, properties=[one])
    assert m.reduction.fixed == 1 and "symmetry" in m.reduction.on
    assert "keeps agent 0 in place" in m.reduction.describe()
    assert m.reduction.as_dict()["fixed_agents"] == [0]
    # asked for by name too
    assert make_model(WINNER, source=True, agents=3, properties=[one],
                      reduce="symmetry").reduction.fixed == 1
    # a formula that names an agent besides i, two quantifiers, an invariant
    # naming an agent: the instances are checked one by one, symmetry off
    for props, invs in ((["forall i: eventually exited[i] && exited[0]"], []),
                        (["forall i: forall j: eventually exited[i] || exited[j]"], []),
                        ([one], ["owner != 1"])):
        m = make_model(WINNER, source=True, agents=3, properties=props, invariants=invs)
        assert m.reduction.fixed == 0 and "symmetry" not in m.reduction.on, props
    # symmetric properties alone: the whole symmetry, no agent kept in place
    m = make_model(WINNER, source=True, agents=3, properties=["eventually count(exited) == 3"])
    assert m.reduction.fixed == 0 and "symmetry" in m.reduction.on
    assert "fixed_agents" not in m.reduction.as_dict()


def test_rename_state_is_a_symmetry_of_the_rules():
    """The renaming the orbit argument and the renamed counterexamples use:
    s -> t iff rename(s) -> rename(t), on every reachable state of a
    program whose ids are held in shared and local variables."""
    m = unreduced(make_model(WINNER, source=True, agents=3, reduce="none"))
    _, slots = RD.symmetry_problem(m)
    seen, todo = set(), list(m.init_states())
    while todo:
        s = todo.pop()
        if m.plain_key(s) in seen:          # (the key drops the clock)
            continue
        seen.add(m.plain_key(s))
        succ = [t for _, t in m.successors(s)]
        for j in (1, 2):
            r = RD.swap(3, 0, j)
            assert {RD.rename_state(t, r, slots) for t in succ} == \
                {t for _, t in m.successors(RD.rename_state(s, r, slots))}
        todo.extend(succ)
    assert len(seen) > 20


# ---------------------------------------------------------------------------
# teeth
# ---------------------------------------------------------------------------

def test_teeth_instance_zero_on_the_quotient_by_every_renaming(monkeypatch):
    """Agent 0 not kept in place: the representative may always show the
    winner as agent 0, `eventually exited[0]` then holds on the quotient,
    and the verdict differs from the unreduced one."""
    props = ["forall i: eventually exited[i]"]
    truth = explore(WINNER, source=True, agents=2, properties=props, find_all=True, reduce="none",
                    engine="python")
    orig = RD.make_symmetric_key
    monkeypatch.setattr(RD, "make_symmetric_key", lambda m, slots, fixed=0: orig(m, slots, 0))
    r = explore(WINNER, source=True, agents=2, properties=props, find_all=True, engine="python")
    assert r.model.reduction.fixed == 1
    assert verdict(r) != verdict(truth)


def test_teeth_the_orbit_argument_without_symmetric_initial_states(monkeypatch, tmp_path):
    """The condition on the initial states dropped: robot 0 arrives, so
    instance 0 holds, and robot 1's failure is not reported."""
    walled = tmp_path / "walled.toml"
    walled.write_text(WALLED_WORLD)
    kw = dict(source=True, world=str(walled), blackbox="straight",
              properties=["forall i: eventually exited[i]"], find_all=True, engine="python")
    truth = explore(DRIVE, reduce="none", **kw)
    monkeypatch.setattr(RD, "orbit_problem", lambda m, slots: None)
    r = explore(DRIVE, **kw)
    assert r.model.reduction.fixed == 1
    assert verdict(r) != verdict(truth)


# Init blocks run one agent after the other: an Init that writes a shared
# variable leaves the last agent's value (owner == 2 with 3 agents), so the
# initial states are not symmetric although every initialiser and statement
# is (the oracle's finding, seed 1300417, family orbit).
LAST_INIT = """allwrite:
  int owner = -1;

loc:
  int y = 1;

Init:
  owner = getAgentIndex();
"""


def test_an_init_that_writes_shared_variables_keeps_every_instance():
    props = ["forall i: owner == i ~> owner != i"]
    truth, red = both(LAST_INIT, props, source=True, agents=3)
    assert any("[i=2]" in v.violation.identity[1] for v in truth.counterexamples)
    for engine, r in red.items():
        assert r.model.reduction.fixed == 0, (engine, r.model.reduction.describe())
        assert "the initial states are not symmetric" in r.model.reduction.describe()
        assert verdict(r) == verdict(truth), engine


@pytest.mark.parametrize("init, private", [
    ("  y = getAgentIndex();\n", True),
    ("  owner = getAgentIndex();\n", False),
    ("  if (y == 1):\n    owner = 1;\n", False),
    ("  atomic:\n    y = 2;\n", False),
])
def test_init_is_private(init, private):
    src = LAST_INIT.replace("  owner = getAgentIndex();\n", init)
    assert RD.init_is_private(make_model(src, source=True, agents=2)) is private
