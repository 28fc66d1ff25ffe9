"""End-to-end tests of the example programs programs/leader.pccl,
programs/formation.pccl and programs/rendezvous.pccl: they check clean,
every seeded run ends in a final state (every agent exited) under the
instant, straight and nondet blackboxes, exploration is exhaustive with no
violation, and deliberately buggy variants (written inline below) are
caught by explore."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from pccl import api
from pccl.output import codec as C
from pccl.lang.checker import check_program
from pccl.cli import main as cli
from pccl.lang.parser import parse_file, parse_program

ROOT = Path(__file__).resolve().parents[2]
PROGRAMS = ROOT / "programs"
LEADER = PROGRAMS / "leader.pccl"
FORMATION = PROGRAMS / "formation.pccl"
FORMATION_WORLD = PROGRAMS / "formation.toml"
RENDEZVOUS = PROGRAMS / "rendezvous.pccl"
RENDEZVOUS_WORLD = PROGRAMS / "rendezvous.toml"

BLACKBOXES = ("instant", "straight", "nondet")
SEEDS = (0, 1, 2)
AGENTS = (2, 3)


def variant(path: Path, old: str, new: str, name: str):
    """``path``'s program with the single occurrence of ``old`` replaced."""
    text = path.read_text()
    assert text.count(old) == 1, f"{old!r} must occur exactly once in {path.name}"
    return parse_program(text.replace(old, new), name)


def variant_text(prog, old: str, new: str):
    """A parsed variant's text edited once more."""
    assert prog.source.count(old) == 1
    return parse_program(prog.source.replace(old, new), prog.filename)


def assert_final(res, n_agents: int):
    assert res.status == "final", res.message
    assert res.exit_status == 0
    state = C.encode_state(res.model, res.final)
    assert [a["status"]["status"] for a in state["agents"]] == ["exited"] * n_agents
    return state


def violation_names(res) -> set:
    return {v["name"] for v in res.violations}


# --------------------------------------------------------------------------
# checking
# --------------------------------------------------------------------------

@pytest.mark.parametrize("path,world", [(LEADER, None), (FORMATION, FORMATION_WORLD),
                                        (RENDEZVOUS, RENDEZVOUS_WORLD)])
def test_checks_clean(path, world):
    info = check_program(parse_file(str(path)))
    assert info is not None
    args = ["check", str(path)] + (["--world", str(world)] if world else [])
    out = CliRunner().invoke(cli, args)
    assert out.exit_code == 0, out.output
    assert ": ok (" in out.output


# --------------------------------------------------------------------------
# leader election
# --------------------------------------------------------------------------

@pytest.mark.parametrize("blackbox", BLACKBOXES)
@pytest.mark.parametrize("agents", AGENTS)
@pytest.mark.parametrize("seed", SEEDS)
def test_leader_runs_to_agreement(blackbox, agents, seed):
    res = api.run(LEADER, blackbox=blackbox, agents=agents, seed=seed)
    state = assert_final(res, agents)
    vs = [a["variables"] for a in state["agents"]]
    top = max(v["mine"] for v in vs)
    assert all(v["stage"] == "DONE" for v in vs)
    assert {v["best"] for v in vs} == {top}
    assert {v["leader"] for v in vs} == {top % agents}


@pytest.mark.parametrize("agents,overrides", [(1, None), (2, None), (3, None), (3, {"maxPrio": "0"})])
def test_leader_explores_clean(agents, overrides):
    # (the extra --invariant doubles the time for 3 agents: only for fewer)
    extra = ["forall i: stage[i] == DONE -> leader[i] == best[i] % N"] if agents < 3 else []
    res = api.explore(LEADER, blackbox="nondet", agents=agents, overrides=overrides,
                      invariants=extra)
    assert res.status == "exhaustive", res.verdict
    assert res.exit_status == 0
    assert res.violations == []
    assert res.stats.initial_states == (2 ** agents if overrides is None else 1)


def test_leader_missing_last_agent_is_caught():
    # The scan stops one short, so nobody but the last agent ever sees the
    # last agent's key: when it holds the largest key, the others elect
    # someone else.
    bug = variant(LEADER, "m = best;\n    j = 0;\n    while (j < getNumAgents()):",
                  "m = best;\n    j = 0;\n    while (j < getNumAgents() - 1):", "leader_bug.pccl")
    res = api.explore(bug, blackbox="nondet", agents=2, find_all=True)
    assert res.status == "violation"
    assert res.exit_status == 1
    assert {"agree", "maximal"} <= violation_names(res)
    assert res.trace, "a counterexample trace"
    # and a run that starts from the bad priorities shows it too
    res = api.run(bug, blackbox="instant", agents=2, seed=0, overrides={"maxPrio": "0"})
    assert res.status == "violation" and res.exit_status == 1


def test_leader_bug_cli_exit_status(tmp_path):
    text = LEADER.read_text().replace("while (j < getNumAgents()):",
                                      "while (j < getNumAgents() - 1):", 1)
    bug = tmp_path / "bug.pccl"
    bug.write_text(text)
    out = CliRunner().invoke(cli, ["explore", str(bug), "-b", "nondet",
                                   "--invariant", "forall i: forall j: (stage[i] == DONE && "
                                   "stage[j] == DONE) -> best[i] == best[j]"])
    assert out.exit_code == 1, out.output
    assert "violation" in out.output


# --------------------------------------------------------------------------
# formation
# --------------------------------------------------------------------------

@pytest.mark.parametrize("blackbox", BLACKBOXES)
@pytest.mark.parametrize("agents", AGENTS)
@pytest.mark.parametrize("seed", SEEDS)
def test_formation_runs_into_line(blackbox, agents, seed):
    res = api.run(FORMATION, world=FORMATION_WORLD, blackbox=blackbox, agents=agents, seed=seed)
    state = assert_final(res, agents)
    for i, a in enumerate(state["agents"]):
        assert a["variables"]["stage"] == "ARRIVED"
        assert a["variables"]["arrived"] is True
        assert a["position"][:2] == pytest.approx([10.0, 1.0 + 1.5 * i])


@pytest.mark.parametrize("blackbox,agents", [("nondet", 2), ("nondet", 3), ("instant", 3),
                                             ("straight", 2), ("straight", 3)])
def test_formation_explores_clean(blackbox, agents):
    res = api.explore(FORMATION, world=FORMATION_WORLD, blackbox=blackbox, agents=agents,
                      collisions=True,
                      invariants=["count(leaving) == 0 || count(arrived) == N"])
    # under nondet positions (--collisions) are not enumerated in mid-motion:
    # the search is complete for nondet, not exhaustive for straight/pymunk
    assert res.status == ("bounded" if blackbox == "nondet" else "exhaustive"), res.verdict
    assert res.exit_status == 0
    assert res.violations == []


def test_formation_direct_route_fails_under_straight():
    # Without the gateway, robot 0's straight path to its slot crosses the
    # block: `straight` reports doReach_fail, the robot retries, gives up.
    direct = variant(FORMATION, "Init:\n  doReach(gate, obs);", "Init:\n  doReach(slot, obs);",
                     "formation_direct.pccl")
    direct = variant_text(direct, "Stage stage = TO_GATE;", "Stage stage = TO_SLOT;")
    res = api.explore(direct, world=FORMATION_WORLD, blackbox="straight", agents=2)
    assert res.status == "violation" and res.exit_status == 1
    assert violation_names(res) == {"noFailure"}
    # the instant blackbox does not look at the path, so it lets it through
    res = api.explore(direct, world=FORMATION_WORLD, blackbox="instant", agents=2)
    assert res.status == "exhaustive", res.verdict


def test_formation_blocked_gateway_gives_up(tmp_path):
    # A pillar on robot 1's gateway: doReach fails under every blackbox; the
    # robot gives up after maxTries retries and the others still leave.
    world = tmp_path / "blocked.toml"
    world.write_text(FORMATION_WORLD.read_text() + (
        "\n[[obstacles]]\npolygon = [[4.8, 3.3], [5.2, 3.3], [5.2, 3.7], [4.8, 3.7]]\n"))
    res = api.explore(FORMATION, world=world, blackbox="nondet", agents=3)
    assert res.status == "violation" and res.exit_status == 1
    assert violation_names(res) == {"noFailure"}
    res = api.run(FORMATION, world=world, blackbox="straight", agents=3, seed=0)
    assert res.status == "violation" and "noFailure" in res.message


def test_formation_leaving_early_is_caught():
    # Off by one in the exit test: a robot leaves while another is on its way.
    early = variant(FORMATION, "if (finished == getNumAgents()):",
                    "if (finished >= getNumAgents() - 1):", "formation_early.pccl")
    res = api.explore(early, world=FORMATION_WORLD, blackbox="nondet", agents=2)
    assert res.status == "violation" and res.exit_status == 1
    assert violation_names(res) == {"leaveTogether"}


# --------------------------------------------------------------------------
# rendezvous
# --------------------------------------------------------------------------

# Not nondet with 3 agents: there robots' paths cross, nondet may fail a
# robot after its detour (pymunk's discs can block one another) and the
# program asserts; see test_rendezvous_detour_blocked_under_nondet.
@pytest.mark.parametrize("blackbox,agents", [(b, n) for b in BLACKBOXES for n in (1,) + AGENTS
                                             if (b, n) != ("nondet", 3)])
@pytest.mark.parametrize("seed", SEEDS)
def test_rendezvous_runs_into_column(blackbox, agents, seed):
    res = api.run(RENDEZVOUS, world=RENDEZVOUS_WORLD, blackbox=blackbox, agents=agents, seed=seed)
    state = assert_final(res, agents)
    vs = [a["variables"] for a in state["agents"]]
    top = state["shared"]["top"]
    assert top == max(v["key"] for v in vs)
    leader = top % agents
    assert {v["leader"] for v in vs} == {leader}
    home = state["agents"][leader]["position"][:2]
    for i, a in enumerate(state["agents"]):
        assert a["variables"]["stage"] == "THERE"
        rank = (i - leader) % agents
        assert a["position"][:2] == pytest.approx([home[0], home[1] + 1.0 * rank])


def test_rendezvous_detours_under_straight():
    # Robot 0 cannot drive straight to (3, 1) or (6, 1): the wall is in the
    # way, so under `straight` it must take the detour at least once.
    res = api.run(RENDEZVOUS, world=RENDEZVOUS_WORLD, blackbox="straight", agents=3, seed=0,
                  record_trace=True, overrides={"maxPrio": "0"})
    assert_final(res, 3)
    rules = [(label[0], label[1]) for label in res.trace.labels]
    assert ("DOREACH INVOKE", None) in rules
    stages = {C.encode_state(res.model, after)["agents"][0]["variables"]["stage"]
              for after in res.trace.states[1:]}
    assert {"DETOUR", "FINAL", "THERE"} <= stages


@pytest.mark.parametrize("blackbox,agents,overrides", [
    ("nondet", 2, None), ("instant", 2, None), ("straight", 2, None),
    ("straight", 3, {"maxPrio": "0"})])
def test_rendezvous_explores_clean(blackbox, agents, overrides):
    res = api.explore(RENDEZVOUS, world=RENDEZVOUS_WORLD, blackbox=blackbox, agents=agents,
                      overrides=overrides, collisions=(agents == 2),
                      invariants=["forall i: stage[i] == THERE -> leader[i] >= 0"])
    # under nondet getPosition() is not enumerated in mid-motion: the search is
    # complete for nondet, not exhaustive for straight/pymunk
    assert res.status == ("bounded" if blackbox == "nondet" else "exhaustive"), res.verdict
    assert res.exit_status == 0
    assert res.violations == []


def test_rendezvous_detour_blocked_under_nondet():
    # With 3 robots, a robot's detour path crosses another robot's path:
    # under pymunk the discs may block each other, so the covering nondet
    # lets the detour fail, and the program's assert(false) in Lost fires.
    # Under straight (robots never block one another) it stays clean.
    res = api.explore(RENDEZVOUS, world=RENDEZVOUS_WORLD, blackbox="nondet", agents=3,
                      overrides={"maxPrio": "0"})
    assert res.status == "violation", res.verdict
    assert res.violation.kind == "assert"
    stuck = res.violation.agent
    # the failing doReach is the detour's (or the final leg's)
    last = res.final_state.agents[stuck]
    assert last.variables["stage"] in ("DETOUR", "FINAL")
    assert last.doReach_fail is True
    res = api.explore(RENDEZVOUS, world=RENDEZVOUS_WORLD, blackbox="straight", agents=3,
                      overrides={"maxPrio": "0"})
    assert res.status == "exhaustive", res.verdict


def test_rendezvous_check_outside_lock_is_caught():
    # The Race bug again: `key > top` tested outside `atomic`, so a smaller
    # key can overwrite a larger one that was written in between.
    bug = variant(RENDEZVOUS,
                  "    atomic:\n      if (key > top):\n        top = key;\n",
                  "    if (key > top):\n      atomic:\n        top = key;\n",
                  "rendezvous_bug.pccl")
    res = api.explore(bug, world=RENDEZVOUS_WORLD, blackbox="nondet", agents=2)
    assert res.status == "violation" and res.exit_status == 1
    assert violation_names(res) == {"maximal"}
    # the shortest counterexample shows the lost update: top goes down
    writes = [(c.old, c.new) for step in res.trace for c in step.changes if c.cell == "top"]
    assert any(new < old for old, new in writes), writes
