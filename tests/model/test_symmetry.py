"""The symmetry reduction cannot lie (issue 20): agent ids as a type.

1. the issue's examples, each a false "exhaustive" (or a false refusal) on
   the analysis before pccl/lang/scalarset.py;
2. the type rules one by one (pccl.lang.scalarset.IdTypes);
3. the attack: 2,000 generated programs that try to tell agents apart
   (tests/symattack.py); wherever the analysis keeps symmetry on, the
   symmetry key is a bisimulation that respects the properties, and the
   verdict equals ``reduce="none"``; merge and por keep the verdict too;
4. the attack has teeth: two weakened analyses (the two holes the issue
   found) are caught by it.
"""

from __future__ import annotations

import textwrap

import pytest

import symattack
from pccl.lang import scalarset as SS
from pccl.api import explore, make_model
from pccl.lang.errors import PcclError
from pccl.lang.parser import parse_program

from conftest import cli, verdict


def src(text: str) -> str:
    return "Agent::T\n\n" + textwrap.dedent(text).lstrip("\n")


def plan(text, agents=2, **kw):
    return make_model(src(text), source=True, agents=agents, blackbox="instant",
                      reduce="auto", **kw).reduction


def same_verdict(text, agents=2, **kw):
    """The default (reduced) verdict and the unreduced one; asserts equal."""
    kw = dict(source=True, agents=agents, blackbox="instant", find_all=True, **kw)
    base = explore(src(text), reduce="none", **kw)
    res = explore(src(text), reduce="auto", **kw)
    assert verdict(res) == verdict(base), (res.verdict, base.verdict)
    return res


ME_DONE = """
    allread:
      int me = getAgentIndex();
      bool done = false;

    Init:

    Go():
      pre(!done);
      eff:
        done = true;
    """


# ---------------------------------------------------------------------------
# 1. the issue's examples
# ---------------------------------------------------------------------------

def test_an_id_read_through_an_agent_indexed_variable_in_a_property():
    """The issue's first example: the default explore said exhaustive."""
    inv = "forall i: (me[i] == 1 && done[i]) -> (exists j: me[j] == 0 && done[j])"
    p = plan(ME_DONE, invariants=(inv,))
    assert "symmetry" not in p.on
    assert "me[i] == 1" in p.off["symmetry"]
    res = same_verdict(ME_DONE, invariants=[inv])
    assert res.status == "violation"


def test_the_issue_example_through_the_command_line(tmp_path):
    f = tmp_path / "me.pccl"
    f.write_text(src(ME_DONE) + "\ninvariant:\n  forall i: (me[i] == 1 && done[i]) -> "
                 "(exists j: me[j] == 0 && done[j])\n")
    r = cli("explore", str(f))
    assert r.exit_code == 1, r.output
    assert "symmetry off: an agent id is compared with a value that is not an id (me[i] == 1)" \
        in r.output


@pytest.mark.parametrize("stmt,why", [
    ("x = me[getAgentIndex()];", "stored in `x`"),
    ("if (me[getAgentIndex()] == 1):\n              x = 1;", "me[getAgentIndex()] == 1"),
    ("x = me[owner];", "stored in `x`"),
    ("if (me[owner] == 0):\n              x = 1;", "me[owner] == 0"),
])
def test_ids_read_back_through_agent_indexed_variables_are_ids(stmt, why):
    text = f"""
        allwrite:
          int owner = -1;

        allread:
          int me = getAgentIndex();
          bool done = false;

        loc:
          int x = 0;

        Init:

        Take():
          pre(owner == -1);
          eff:
            owner = getAgentIndex();

        Go():
          pre(!done);
          eff:
            done = true;
            {stmt}
        """
    p = plan(text, invariants=("forall i: x[i] == 0 || done[i]",))
    assert "symmetry" not in p.on and why in p.off["symmetry"], p.off
    same_verdict(text, invariants=["forall i: x[i] != 1"])


FLAGS = """
    allread:
      bool flags[2] = false;
      bool done = false;

    Init:

    Mark():
      pre(!done);
      eff:
        flags[getAgentIndex()] = true;
        done = true;

    Copy():
      pre(done && !flags[0]);
      eff:
        flags[0] = flags[1];
    """


def test_an_allread_arrays_own_element_is_not_an_agent_index():
    """``flags[getAgentIndex()]`` is this agent's element getAgentIndex():
    an id used as an array index tells agents apart."""
    p = plan(FLAGS, invariants=("forall i: !(flags[i][0] && flags[i][1])",))
    assert "symmetry" not in p.on
    assert "flags[getAgentIndex()]" in p.off["symmetry"]
    assert "not indexed by agent" in p.off["symmetry"]
    same_verdict(FLAGS, invariants=["forall i: !flags[i][1]"])


def test_a_constant_own_element_keeps_symmetry():
    """``a[0]`` on an allread array is this agent's element 0, which every
    agent has: the analysis used to refuse it as "names agent 0"."""
    text = """
        allread:
          int a[2] = 0;

        Init:

        Step():
          pre(a[0] < 2);
          eff:
            a[0] = a[0] + 1;
            a[1] = a[0];
        """
    p = plan(text, invariants=("forall i: a[i][1] <= a[i][0]",))
    assert p.on == ("merge", "symmetry", "por"), p.off
    res = same_verdict(text, invariants=["forall i: a[i][1] <= a[i][0]"], agents=3)
    base = explore(src(text), source=True, agents=3, blackbox="instant", reduce="none",
                   invariants=["forall i: a[i][1] <= a[i][0]"])
    assert res.stats.states < base.stats.states


def test_another_agents_element_is_named_by_an_id():
    text = """
        allwrite:
          int owner = -1;

        allread:
          int a[2] = 0;

        Init:

        Take():
          pre(owner == -1);
          eff:
            owner = getAgentIndex();
            a[1] = 1;

        Look():
          pre(owner != -1 && a[owner][1] == 1);
          eff:
            a[0] = 1;
        """
    assert "symmetry" in plan(text).on
    same_verdict(text, invariants=["forall i: a[i][0] == 0 || owner != i"], agents=3)
    p = plan(text.replace("a[owner][1]", "a[0][1]"))
    assert "a[0][1] names agent 0" in p.off["symmetry"]


def test_the_message_keeps_parentheses():
    text = """
        allread:
          int v = 0;

        loc:
          int id = getAgentIndex();

        Init:

        E():
          pre(v[(id + 1) % getNumAgents()] == 0);
          eff:
            v = 1;
        """
    why = plan(text).off["symmetry"]
    assert "v[(id + 1) % getNumAgents()]" in why, why


@pytest.mark.parametrize("asked", ["symmetry", "por", "merge,symmetry"])
def test_a_reduction_asked_for_with_one_agent_is_an_error(tmp_path, asked):
    """It used to run unreduced, the request dropped with a note."""
    f = tmp_path / "one.pccl"
    f.write_text(src(ME_DONE))
    r = cli("explore", str(f), "-n", "1", "--reduce", asked)
    assert r.exit_code == 2, r.output
    name = "por" if asked == "por" else "symmetry"
    assert f"{name} reduction needs two or more agents" in r.output
    assert "Traceback" not in r.output
    ok = cli("explore", str(f), "-n", "1", "--no-stall")     # auto: nothing to say
    head = ok.output.splitlines()[0]
    # nothing said of the reductions (the engine may follow)
    assert ok.exit_code == 0 and head.split("reductions ")[1].split(", engine ")[0] == "merge"


# ---------------------------------------------------------------------------
# 2. the type rules
# ---------------------------------------------------------------------------

def id_types(text, props=()):
    m = make_model(src(text), source=True, agents=2, blackbox="instant", reduce="none",
                   invariants=tuple(props))
    return SS.IdTypes(m.compiled.layout, m.program, m.compiled.stmts.values(),
                      [(p.expr, p.text) for p in m.properties])


DECLS = """
    allwrite:
      int owner = -1;
      int never = -1;
      int plain = 0;

    allread:
      int me = getAgentIndex();
      int arr[2] = 0;

    loc:
      int peer = -1;
      int copy = 0;

    Init:

    E():
      pre(true);
      eff:
        owner = me[getAgentIndex()];
        peer = me[owner];
        plain = plain + 1;
    """


def test_gamma_is_the_id_valued_variables():
    t = id_types(DECLS)
    assert t.ids == {"owner", "me", "peer"}
    assert t.neutral == {"never"}
    assert t.reason is None


@pytest.mark.parametrize("use,ok", [
    ("owner == peer", True),
    ("owner != -1", True),
    ("peer == never", True),            # a variable that only holds -1
    ("me[owner] == peer", True),
    ("me[peer] == getAgentIndex()", True),
    ("owner == 0", False),
    ("owner < peer", False),
    ("owner + 1 == peer", False),
    ("arr[owner] == 0", False),         # own element owner: an array index
    ("arr[0] == 0", True),              # own element 0
    ("arr[owner][0] == 0", True),       # agent owner's element 0
    ("arr[0][0] == 0", False),          # agent 0's element 0
    ("me[0] == owner", False),
    ("plain == owner", False),
    ("contains([1], owner)", False),
])
def test_the_use_rules(use, ok):
    t = id_types(DECLS.replace("pre(true)", f"pre({use})"))
    assert (t.reason is None) == ok, t.reason


@pytest.mark.parametrize("prop,ok", [
    ("forall i: me[i] == i", True),
    ("forall i: exists j: me[i] == me[j]", True),
    ("forall i: owner == i -> arr[i][0] == 0", True),
    ("forall i: me[i] == 1", False),
    ("forall i: i < 1", False),
    ("arr[0][0] == 0", False),
    ("forall i: arr[i][i] == 0", False),
    ("owner != 0", False),
])
def test_the_use_rules_in_properties(prop, ok):
    t = id_types(DECLS, props=[prop])
    assert (t.reason is None) == ok, t.reason


def test_a_variable_with_a_plain_definition_is_not_an_id():
    t = id_types(DECLS.replace("plain = plain + 1;", "peer = 0;"))
    assert "peer" not in t.ids
    assert t.reason is not None and "stored in `peer`" in t.reason


def test_show_parenthesises():
    m = make_model(src("allwrite:\n  int v = 0;\n\nInit:\n\nE():\n  pre(v == (v + 1) % 2 * -(v - 1));\n"
                       "  eff:\n    v = 1;\n"), source=True, agents=1, reduce="none")
    g = m.program.events[0].guard
    assert SS.show(g) == "v == (((v + 1) % 2) * -(v - 1))"


# ---------------------------------------------------------------------------
# 3. the attack
# ---------------------------------------------------------------------------

N_ATTACK = 2000


@pytest.mark.slow
def test_the_attack_finds_no_disagreement():
    counts = {"on": 0, "off": 0, "invalid": 0, "bounded": 0}
    bad = []
    for seed in range(N_ATTACK):
        r = symattack.check(seed, reductions=("symmetry", "merge", "por") if seed % 10 == 0
                            else ("symmetry",))
        if "invalid" in r or "bounded" in r:
            counts["invalid" if "invalid" in r else "bounded"] += 1
            continue
        counts["on" if r["symmetry"] is not None else "off"] += 1
        if r.get("orbits") is False:
            bad.append((seed, "the symmetry key is not a bisimulation"))
        for name, v in r.items():
            if name != "orbits" and v is not None and not v[1]:
                bad.append((seed, f"{name} changes the verdict"))
    assert bad == [], f"python tests/symattack.py SEED shows the program: {bad[:5]}"
    # the attack attacks: most programs are valid, and both answers occur
    assert counts["invalid"] == 0
    assert counts["on"] > N_ATTACK // 5 and counts["off"] > N_ATTACK // 5, counts


# ---------------------------------------------------------------------------
# 5. robots that move (issue 23): positions and reach cells in the key
# ---------------------------------------------------------------------------

N_MOVING = 150


@pytest.mark.slow
def test_moving_robots_keep_symmetry_soundly(tmp_path):
    """Generated programs that move (doReach, getPosition, pos[i], walls,
    three blackboxes): wherever symmetry is on, the key is a bisimulation
    and the verdict equals reduce="none"."""
    on, bad = 0, []
    for seed in range(N_MOVING):
        r = symattack.check_moving(seed, tmp_path)
        assert "invalid" not in r, r
        if r.get("symmetry") is None or "bounded" in r:
            continue
        on += 1
        if not r["orbits"] or not r["symmetry"][1]:
            bad.append(seed)
    assert bad == [], f"symattack.moving_program(SEED): {bad}"
    assert on > N_MOVING // 2


@pytest.mark.slow
def test_the_moving_attack_catches_a_key_without_positions(tmp_path, monkeypatch):
    """Positions left out of the key while robots move: caught."""
    from pccl.model import reduce as RD
    orig = RD.symmetry_problem

    def weak(m):
        why, slots = orig(m)
        return (why, slots) if slots is None else (why, slots[:4] + (False,))
    monkeypatch.setattr(RD, "symmetry_problem", weak)
    for seed in range(300):
        r = symattack.check_moving(seed, tmp_path)
        if r.get("symmetry") and (not r["orbits"] or not r["symmetry"][1]):
            return
    pytest.fail("the moving attack did not catch a key without positions")


def test_race_safe_is_symmetric_with_positions_in_the_key():
    m = make_model("programs/race_safe.pccl", world="programs/race.toml", agents=3,
                   blackbox="nondet", reduce="auto")
    assert "symmetry" in m.reduction.on
    st = next(iter(m.init_states()))
    # the start positions differ, so the initial state is its own orbit's
    # only member up to the permutation that moves the positions with it
    from pccl.model.layout import AGS, POS
    assert len({a[POS] for a in st[AGS]}) == 3
    assert symattack.orbits_agree(open("programs/race_safe.pccl").read(), None, [], limit=3000,
                                  world="programs/race.toml", blackbox="nondet")


def test_pymunk_keeps_symmetry_off_for_movers():
    pytest.importorskip("pymunk")
    p = make_model("programs/race_safe.pccl", world="programs/race.toml", agents=2,
                   blackbox="pymunk", reduce="auto").reduction
    assert "symmetry" not in p.on and "pymunk may treat agents differently" in p.off["symmetry"]


@pytest.mark.slow
@pytest.mark.parametrize("attr,weak", [("typeof", symattack.weak_reads), ("agent_index", symattack.weak_arrays)])
def test_the_attack_catches_the_old_holes(monkeypatch, attr, weak):
    monkeypatch.setattr(SS.IdTypes, attr, weak)
    for seed in range(N_ATTACK):
        text, invariants, agents = symattack.program(seed)
        try:
            text = parse_program(text, "<input>")      # once for both models
            p = make_model(text, source=True, agents=agents, blackbox="instant",
                           invariants=invariants, reduce="auto").reduction
        except PcclError:
            continue
        if "symmetry" in p.on and not symattack.orbits_agree(text, agents, invariants):
            return
    pytest.fail(f"the attack did not catch the weakened analysis ({weak.__doc__})")
