"""What a verdict covers (pccl/output/checked.py): the ``checked`` section of
``pccl explore`` (text and JSON) and ``pccl run`` (JSON), the vacuity notes,
and the events that never fired in an exhaustive search -- the same under
every reduction as without any (the soundness test)."""

from __future__ import annotations

import json
import textwrap
from pathlib import Path

import jsonschema
import pytest

from conftest import RACE, RACE_WORLD, ROOT, cli
from pccl.api import explore, run
from pccl.output.checked import NO_PROPERTY_NOTE

SCHEMA = json.loads((ROOT / "docs" / "trace-format.schema.json").read_text())


def valid_checked(doc: dict) -> None:
    """Validate ``doc`` against ``$defs/checked`` of the trace schema."""
    sub = dict(SCHEMA["$defs"]["checked"])
    sub["$defs"] = SCHEMA["$defs"]
    jsonschema.validate(doc, sub, cls=jsonschema.Draft202012Validator)


#: Two agents; Reset's guard never holds (x only reaches 1).  Bump runs
#: twice per agent through local statements (merge and por apply), and Late
#: fires only for the agent that did not take the token (symmetry applies:
#: ids are used only as the agent's own).
NEVER = textwrap.dedent("""\
    allwrite:
      boolean taken = false;
      int x = 0;

    loc:
      int n = 0;
      int k = 0;
      boolean mine = false;
      boolean done = false;

    Bump():
      pre(n < 2);
      eff:
        k = k + 1;
        k = k + 2;
        n = n + 1;

    Take():
      pre(n == 2 && !taken && !done);
      eff:
        atomic:
          if (!taken):
            taken = true;
            mine = true;
        done = true;

    Late():
      pre(n == 2 && taken && !mine && !done);
      eff:
        x = 1;
        done = true;

    Reset():
      pre(x > 5);
      eff:
        x = 0;

    Stop():
      pre(done);
      eff:
        exit();
    """)


@pytest.fixture
def never(tmp_path) -> str:
    p = tmp_path / "never.pccl"
    p.write_text(NEVER)
    return str(p)


RESET_LINE = NEVER.splitlines().index("Reset():") + 1


# ---------------------------------------------------------------------------
# never-fired events on a small program, under every reduction
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("reduce", ["none", "merge", "symmetry", "por", "auto"])
def test_never_fired_under_every_reduction(never, reduce):
    r = explore(never, reduce=reduce)
    assert r.status == "exhaustive"
    if reduce not in ("none", "auto"):
        assert r.model.reduction.on == (reduce,)
    else:
        assert r.model.reduction.on == (() if reduce == "none" else ("merge", "symmetry", "por", "dead"))
    assert r.checked.never_fired == (("Reset", RESET_LINE),)
    # Late is fired only by the agent that lost the race for the token: the
    # symmetric representative must still count it
    assert r.checked.events == 5


def test_never_fired_text_line(never):
    res = cli("explore", never, "--no-progress")
    assert res.exit_code == 0, res.output
    lines = res.output.splitlines()
    assert f"  never fired: event Reset (line {RESET_LINE})" in lines
    # the section sits after the verdict and before the statistics
    assert lines.index("checked:") < lines.index("statistics:")
    assert lines.index("checked:") > 1


def test_every_event_fired(tmp_path):
    p = tmp_path / "all.pccl"
    p.write_text(NEVER.replace("pre(x > 5)", "pre(x > 0)"))
    r = explore(str(p))
    assert r.status == "exhaustive"
    assert r.checked.never_fired == ()
    assert "  events: every event fired (5)" in r.checked.lines()


def test_never_fired_not_computed_when_bounded(never):
    r = explore(never, depth=3)
    assert r.status == "bounded"
    assert r.checked.never_fired is None
    assert r.checked.events_reason == "a bound stopped the search"
    j = r.checked.to_json()
    assert j["events"]["never_fired"] is None
    assert {"bound": "depth=3", "stopped": True} in j["bounds"]


def test_never_fired_after_a_violation_only_with_all(never):
    # the first violation stops the search: not exhaustive
    r = explore(never, invariants=["!taken"])
    assert r.status == "violation" and r.checked.never_fired is None
    assert r.checked.events_reason == "the search stopped at the first violation"
    # --all visits every reachable state: the events are known again
    r = explore(never, invariants=["!taken"], find_all=True)
    assert r.status == "violation"
    assert r.checked.never_fired == (("Reset", RESET_LINE),)


def test_never_fired_with_fastest(never):
    r = explore(never, fastest=True)
    assert r.status == "exhaustive"
    assert r.checked.never_fired == (("Reset", RESET_LINE),)


def test_never_fired_not_computed_with_worker_processes(never, monkeypatch):
    """Two threads of one process see every transition (the events are
    known); worker processes each see their part only (not computed)."""
    r = explore(never, workers=2)
    assert r.status == "exhaustive" and r.model.engine_threads == 2
    assert r.checked.never_fired == (("Reset", RESET_LINE),)
    monkeypatch.setenv("PCCL_THREADS", "0")
    r = explore(never, workers=2)
    assert r.status == "exhaustive" and r.model.engine_threads == 1
    assert r.checked.never_fired is None
    assert "workers=1" in r.checked.events_reason


# ---------------------------------------------------------------------------
# soundness: the reductions hide no firing, on every shipped and test program
# ---------------------------------------------------------------------------

#: program -> options that keep the unreduced search small enough to finish
CONFIGS = {
    "programs/fischer.pccl": dict(overrides={"k": "0"}),
    "programs/rendezvous.pccl": dict(world="programs/rendezvous.toml", agents=2),
    "programs/race_nonatomic.pccl": dict(world="programs/race.toml"),
    "programs/race_safe.pccl": dict(world="programs/race.toml"),
    "programs/collide_fixed.pccl": dict(world="programs/collide.toml"),
}
#: programs whose state space is infinite (the search never finishes)
INFINITE = {"tests/programs/eng_loop.pccl": "n grows for ever inside one event",
            "tests/programs/runaway.pccl": "x grows for ever inside one event"}
SLOW = {"programs/formation.pccl"}


def _programs():
    out = []
    for d in ("programs", "tests/programs", "docs/examples"):
        for p in sorted((ROOT / d).glob("*.pccl")):
            rel = f"{d}/{p.name}"
            if rel in INFINITE:
                continue
            marks = [pytest.mark.slow] if rel in SLOW else []
            out.append(pytest.param(rel, id=rel, marks=marks))
    return out


def _options(rel: str) -> dict:
    if rel in CONFIGS:
        return dict(CONFIGS[rel])
    world = ROOT / rel.replace(".pccl", ".toml")
    return {"world": str(world)} if world.exists() else {}


#: the unreduced state count up to which a reduction's search costs the
#: Python engine less than a native module's compilation (measured with
#: PCCL_NATIVE_OPT=0: programs/race.pccl, 5,280 states, 0.1-0.3 CPU-s a
#: reduction against 0.8; programs/fischer.pccl, 85,428, 0.6-1.7 against 0.9)
PY_STATES = 20_000


@pytest.mark.parametrize("rel", _programs())
def test_reductions_hide_no_firing(rel, chdir_root):
    """The soundness test: the set of never-fired events of the default
    (reduced) search equals that of --reduce none, and of each reduction
    alone where it applies.

    The default search runs on the native engine (the default path); each
    reduction alone, where the unreduced search has at most
    :data:`PY_STATES` states, on the Python engine, whose searches of those
    cost a fraction of a native module's compilation (a module per program
    and reduction: 4 to 5 per program, most of this test's cost).  The
    native engine under each reduction alone is held to the Python one's
    never-fired events by test_never_fired_under_every_reduction (and here
    on the larger programs) and to its states and verdicts by
    tests/model/test_native.py."""
    kw = _options(rel)
    base = explore(rel, reduce="none", find_all=True, max_states=150_000, coverage=True, **kw)
    assert base.checked.never_fired is not None, (rel, base.status, base.checked.events_reason)
    # computed two ways: --coverage counts the firings of the unreduced search
    assert [e for e, _ in base.checked.never_fired] == base.coverage.never_fired, rel
    red = explore(rel, find_all=True, **kw)
    assert red.checked.never_fired == base.checked.never_fired, rel
    engine = "python" if base.stats.states <= PY_STATES else "auto"
    for name in red.model.reduction.on:
        one = explore(rel, reduce=[name], find_all=True, engine=engine, **kw)
        assert one.checked.never_fired == base.checked.never_fired, (rel, name)


def test_the_soundness_test_sees_never_fired_events():
    """Some shipped programs do have events that never fire (the
    comparison above is not only of empty sets)."""
    r = explore("docs/examples/never.pccl")
    assert r.checked.never_fired and r.checked.never_fired[0][0] == "Alarm"


# ---------------------------------------------------------------------------
# properties, built-in checks, bounds
# ---------------------------------------------------------------------------

def _outcomes(r) -> dict:
    return {p.name: (p.outcome, p.reason) for p in r.checked.properties}


def test_property_outcomes(never):
    r = explore(never, invariants=["x <= 1"], properties=["reachable x == 1"])
    assert r.status == "exhaustive"
    assert _outcomes(r) == {"x <= 1": ("held", None),
                            "reachable x == 1": ("held", "a witness reaches it")}
    assert NO_PROPERTY_NOTE not in r.checked.notes
    r = explore(never, invariants=["x <= 1"], properties=["eventually x == 1"], depth=3)
    assert r.status == "bounded"
    assert _outcomes(r) == {
        "x <= 1": ("held within bounds", "stopped by depth=3"),
        "eventually x == 1": ("not checked", "the search did not finish (stopped by depth=3)")}
    r = explore(never, invariants=["x == 0", "n[0] < 5"])
    assert r.status == "violation"
    assert _outcomes(r) == {
        "x == 0": ("violated", None),
        "n[0] < 5": ("held in the states explored", "the search stopped at the first violation")}


def test_property_lines_in_text(never):
    res = cli("explore", never, "--invariant", "x <= 1", "--property", "eventually done[0]",
              "--no-progress")
    assert res.exit_code == 0, res.output
    assert "  invariant 'x <= 1': held" in res.output
    assert "  property 'eventually done[0]': held" in res.output


def test_builtin_checks_follow_the_options(never):
    def on(r):
        return {c: o for c, o, _ in r.checked.builtin}
    r = explore(never)
    assert on(r) == {"assertions": True, "stuck agents": True, "deadlock": True,
                     "stall": True, "time-lock": True, "collisions": False}
    r = explore(never, deadlock=False, timelock=False, stall=False, collisions=True)
    assert on(r) == {"assertions": True, "stuck agents": True, "deadlock": False,
                     "stall": False, "time-lock": False, "collisions": True}
    res = cli("explore", never, "--no-deadlock", "--no-progress")
    assert ("  built-in: assertions +, stuck agents +, deadlock -, stall +, time-lock +, "
            "collisions -") in res.output
    res = cli("explore", never, "--no-stall", "--no-progress")
    assert "stall -" in res.output


def test_blackbox_and_reductions(chdir_root):
    r = explore(RACE, world=RACE_WORLD, blackbox="straight")
    assert r.checked.blackbox == "straight"
    assert r.checked.covers.startswith("one timing")
    r = explore(RACE, world=RACE_WORLD, reduce="none")
    assert r.checked.blackbox == "nondet" and r.checked.covers.startswith("every travel time")
    assert r.checked.reductions_on == ()
    r = explore("programs/fischer.pccl", overrides={"k": "0"})
    assert "does not call doReach" in r.checked.covers
    assert r.checked.reductions_on == ("merge", "symmetry", "por", "dead")


# ---------------------------------------------------------------------------
# vacuity notes
# ---------------------------------------------------------------------------

def test_no_property_note_only_on_clean_verdicts(never):
    assert NO_PROPERTY_NOTE in explore(never).checked.notes
    assert NO_PROPERTY_NOTE in explore(never, depth=2).checked.notes
    assert NO_PROPERTY_NOTE not in explore(never, invariants=["x <= 1"]).checked.notes
    # a program's own invariant: section counts
    prog = NEVER + "\ninvariant:\n  x <= 1;\n"
    assert NO_PROPERTY_NOTE not in explore(prog, source=True).checked.notes
    # a violation is not weak: it has a counterexample
    bad = NEVER.replace("x = 1;", "x = 1;\n    assert(false);")
    r = explore(bad, source=True)
    assert r.status == "violation" and NO_PROPERTY_NOTE not in r.checked.notes


def test_world_note_in_explore(chdir_root):
    r = explore(RACE)          # the API names the option as its keyword (the CLI: --world)
    notes = [n for n in r.checked.notes if n.startswith("no world given")]
    assert notes == ["no world given, so the defaults are used: getInput() = [] (read at "
                     "line 7); getObs() = [], no obstacles (read at line 12); the robots start "
                     "on a line at (0.0, 0.0, 0.0), (0.75, 0.0, 0.0) (doReach at line 25)"]
    assert not any(n.startswith("no world") for n in explore(RACE, world=RACE_WORLD)
                   .checked.notes)
    # a program that reads nothing of the world needs no world
    assert not any(n.startswith("no world") for n in
                   explore("programs/fischer.pccl", overrides={"k": "0"}).checked.notes)


def test_run_without_its_world_says_why_it_ended_at_t0(chdir_root):
    res = cli("run", RACE)
    assert res.exit_code == 0, res.output
    assert "result: final — every agent exited (t=0, 6 transitions)" in res.output
    note = [ln for ln in res.output.splitlines() if ln.startswith("note: ")]
    assert len(note) == 1
    assert note[0].endswith("the run ended at t=0 because getInput() is the empty list "
                            "(give the world with --world FILE)")
    assert "getInput() = [] (read at line 7)" in note[0]
    res = cli("run", RACE, "--world", RACE_WORLD)
    assert "note:" not in res.output


def test_run_checked_json(chdir_root):
    res = cli("run", RACE, "--format", "json", "--invariant", "size(dests) <= 3")
    out = json.loads(res.output)
    c = out["checked"]
    valid_checked(c)
    assert c["properties"] == [{"kind": "invariant", "name": "size(dests) <= 3",
                                "text": "size(dests) <= 3", "source": "option",
                                "outcome": "held on this run", "reason": None}]
    assert {"check": "stall", "on": True, "detail": "--stall-steps 20"} in c["builtin"]
    assert c["bounds"] == [{"bound": "--max-time 100", "stopped": False},
                           {"bound": "--max-steps 100000", "stopped": False}]
    assert c["events"]["never_fired"] is None
    assert any("ended at t=0" in n for n in c["notes"])
    r = run(RACE, invariants=["size(dests) <= 3"])
    assert r.status == "final"


# ---------------------------------------------------------------------------
# JSON
# ---------------------------------------------------------------------------

def test_explore_json_checked_is_the_api_s(never):
    res = cli("explore", never, "--format", "json", "--invariant", "x <= 1", "--depth", "4")
    out = json.loads(res.output)
    valid_checked(out["checked"])
    # the API's, spelt with the CLI's flags as pccl explore does
    from pccl.api import build_model, explore_model
    from pccl.cli import cli_spelling
    from pccl.model.options import ExploreOptions
    opts = ExploreOptions(invariants=("x <= 1",), depth=4)
    api = explore_model(build_model(never, opts, explore=True), options=opts,
                        spelling=cli_spelling).checked.to_json()
    assert out["checked"] == api
    assert out["checked"]["properties"][0]["outcome"] == "held within bounds"
    assert out["checked"]["bounds"][0] == {"bound": "--depth 4", "stopped": True}
    assert out["checked"]["bounds"][-1] == {"bound": "--max-memory 80% of RAM",
                                            "stopped": False}
    # pccl.api.explore: the same, the options spelt as its keywords
    kw = explore(never, invariants=["x <= 1"], depth=4).checked.to_json()
    assert kw["bounds"] == [{"bound": "depth=4", "stopped": True},
                            {"bound": "max_memory=80% of RAM", "stopped": False}]
    assert kw["builtin"][-1] == {"check": "collisions", "on": False, "detail": "collisions not given"}
    spelt = ("bounds", "properties", "builtin")      # the texts that name options
    assert {k: v for k, v in kw.items() if k not in spelt} == \
        {k: v for k, v in api.items() if k not in spelt}


def test_schema_rejects_a_bad_checked(never):
    c = explore(never).checked.to_json()
    valid_checked(c)
    c["properties"] = [{"kind": "invariant", "name": "x", "text": "x", "source": "program",
                        "outcome": "fine", "reason": None}]
    with pytest.raises(jsonschema.ValidationError):
        valid_checked(c)


def test_text_and_json_say_the_same(never):
    c = explore(never, invariants=["x <= 1"]).checked
    j = c.to_json()
    text = "\n".join(c.lines())
    for p in j["properties"]:
        assert f"'{p['name']}': {p['outcome']}" in text
    for b in j["builtin"]:
        assert f"{b['check']} {'+' if b['on'] else '-'}" in text
    for e in j["events"]["never_fired"]:
        assert f"event {e['event']} (line {e['line']})" in text


def test_checked_exists_for_every_status(never, tmp_path):
    Path(tmp_path / "x").mkdir()
    for kw in (dict(), dict(depth=1), dict(invariants=["x == 0"]), dict(max_states=5)):
        c = explore(never, **kw).checked
        valid_checked(c.to_json())
        assert c.lines()[0] == "checked:"
