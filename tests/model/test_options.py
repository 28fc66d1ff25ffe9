"""One options object for the CLI and the API, and typed API results.

Every option of ``pccl run``/``pccl explore`` is a field of
:class:`~pccl.model.options.RunOptions`/:class:`~pccl.model.options.ExploreOptions` and
the other way round; the CLI and the API build equal option objects for the
same request; results are typed views whose text and JSON are what the CLI
prints."""

from __future__ import annotations

import dataclasses
import json

import click
import pytest

import pccl.api as api
from pccl.model import options as O
from pccl.cli import flag as cli_flag, main
from pccl.lang.errors import ArgumentError
from pccl.search.explorer import Bound
from pccl.model.layout import TIME
from pccl.output.results import AgentView, Finding, StateView, StepView

from conftest import FISCHER, RACE, RACE_NONATOMIC, RACE_WORLD
from conftest import cli

COMMANDS = {"run": O.RunOptions, "explore": O.ExploreOptions}




@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_every_cli_option_is_an_api_option_and_back(command):
    cmd = main.commands[command]
    params = {p.name for p in cmd.params if not isinstance(p, click.Argument)}
    params -= O.PRESENTATION[command]
    assert params == O.cli_fields(COMMANDS[command])


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_every_field_is_spelt_as_its_flag(command):
    cmd = main.commands[command]
    by_name = {p.name: p for p in cmd.params}
    for name in O.cli_fields(COMMANDS[command]):
        assert cli_flag(name) in by_name[name].opts, (name, by_name[name].opts)


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_cli_defaults_are_the_api_defaults(command):
    cls = COMMANDS[command]
    ctx = main.commands[command].make_context(command, [FISCHER])
    opts = cls.from_cli(ctx.params)
    assert opts == cls()


def _captured_explore_options(monkeypatch, *args):
    seen = {}

    def fake(model, *, options=None, **kw):
        seen["options"] = options
        raise SystemExit(0)
    monkeypatch.setattr(api, "explore_model", fake)
    cli("explore", FISCHER, *args)
    return seen["options"]


def test_cli_and_api_build_the_same_explore_options(monkeypatch):
    from_cli = _captured_explore_options(
        monkeypatch, "--set", "k=1", "--invariant", "count(inCs) <= 1", "--max-states", "500",
        "--depth", "40", "--no-deadlock", "--all", "--n0", "2", "--rate", "1=2", "--delta", "2",
        "--reduce", "merge", "--max-memory", "1G", "--events", "first", "--no-abstract-time")
    from_api = O.ExploreOptions.from_api("explore", dict(
        overrides={"k": "1"}, invariants=["count(inCs) <= 1"], max_states=500, depth=40,
        deadlock=False, find_all=True, n0=2, rates={1: 2}, delta=2, reduce="merge",
        max_memory=2**30, events="first", abstract_time=False))
    ignore = {"progress", "progress_interval", "invariants"}
    for f in dataclasses.fields(O.ExploreOptions):
        if f.name not in ignore:
            assert getattr(from_cli, f.name) == getattr(from_api, f.name), f.name
    assert tuple(from_cli.invariants) == tuple(from_api.invariants)


def test_unknown_api_option_lists_the_options():
    with pytest.raises(ArgumentError, match=r"unknown option max_sates; options are .*max_states"):
        api.explore(FISCHER, max_sates=3)
    with pytest.raises(ArgumentError, match=r"unknown option depth; options are .*seed"):
        api.run(FISCHER, depth=3)


def test_api_messages_name_the_option_not_the_flag():
    with pytest.raises(ArgumentError, match=r"pccl\.api\.explore: error: max_states must be"):
        api.explore(FISCHER, max_states=0)
    with pytest.raises(ArgumentError, match=r"reduce is not an option of run \(a run executes the unreduced"):
        api.run(FISCHER, reduce="merge")


# ---------------------------------------------------------------------------
# run --invariant, in both spellings
# ---------------------------------------------------------------------------

def test_run_invariant_in_cli_and_api_agree():
    inv = "count(inCs) <= 1"
    res = api.run(FISCHER, overrides={"k": "1"}, invariants=[inv])
    assert res.status == "violation" and res.exit_status == 1
    assert res.violations[0].kind == "invariant"
    assert sum(a.variables["inCs"] for a in res.final_state.agents) == 2
    out = cli("run", FISCHER, "--set", "k=1", "--invariant", inv)
    assert out.exit_code == 1
    assert f"result: violation — invariant '{inv}' violated" in out.output
    assert f" {res.steps} transitions)" in out.output
    clean = api.run(FISCHER, overrides={"k": "1"}, invariants=["count(inCs) <= 2"])
    assert clean.status != "violation"


def test_run_invariant_typo_is_a_user_error():
    out = cli("run", FISCHER, "--invariant", "count(inCz) <= 1")
    assert out.exit_code == 2 and "inCz" in out.stderr and "^" in out.stderr


# ---------------------------------------------------------------------------
# typed results
# ---------------------------------------------------------------------------

def test_explore_result_is_typed_and_matches_the_cli_json():
    r = api.explore(RACE_NONATOMIC, world=RACE_WORLD, blackbox="instant")
    assert isinstance(r.violation, Finding) and r.violation is r.violations[0]
    assert all(isinstance(s, StepView) for s in r.trace)
    assert isinstance(r.final_state, StateView)
    assert all(isinstance(a, AgentView) for a in r.final_state.agents)
    stuck = [a for a in r.final_state.agents if a.status == "stuck"]
    assert stuck and stuck[0].stuck.line == r.violation.line
    out = cli("explore", RACE_NONATOMIC, "--world", RACE_WORLD, "-b", "instant",
              "--format", "json")
    data = json.loads(out.output)
    assert data["violations"][0] == r.violation.to_json()
    # the finding's path as the trace format writes one: {initial, steps, final}
    assert data["violations"][0]["trace"]["final"]["agents"][0]["variables"] == \
        dict(r.final_state.agents[0].variables)


def test_state_view_text_is_what_the_cli_prints():
    r = api.explore(RACE_NONATOMIC, world=RACE_WORLD, blackbox="instant")
    out = cli("explore", RACE_NONATOMIC, "--world", RACE_WORLD, "-b", "instant").output
    block = out.split("violating state:\n", 1)[1].split("\nchecked:", 1)[0]
    assert str(r.final_state) == block
    res = api.run(RACE, world=RACE_WORLD, blackbox="instant", seed=3)
    out = cli("run", RACE, "--world", RACE_WORLD, "-b", "instant", "--seed", "3").output
    assert out.rstrip("\n").endswith(str(res.final_state))
    assert res.final_state.time == res.final[TIME]
    assert [a.status for a in res.final_state.agents] == ["exited"] * len(res.final_state.agents)
    assert res.final_state.shared["dests"] == []


def test_views_read_by_json_key_like_the_json():
    r = api.explore(RACE_NONATOMIC, world=RACE_WORLD, blackbox="instant")
    last = r.trace[-1]
    assert last["source"] == last.source and last["changes"][0] == last.changes[0].to_json()
    assert r.violation["message"] == r.violation.message


def test_bounds_are_the_enum_and_labels_the_keywords_or_the_flags():
    """The API labels a bound with its keyword, the CLI with its flag."""
    r = api.explore(FISCHER, max_states=50, depth=1000)
    assert r.status == "bounded"
    assert r.bounds == [Bound.MAX_STATES] and r.bound_labels == ["max_states=50"]
    assert r.verdict.startswith("no violation within bounds — stopped by max_states=50 [")
    assert [b["bound"] for b in r.checked["bounds"]] == ["depth=1000", "max_states=50",
                                                         "max_memory=80% of RAM"]
    out = cli("explore", FISCHER, "--max-states", "50", "--depth", "1000", "--format", "json")
    data = json.loads(out.output)
    assert data["bounds"] == ["--max-states 50"]
    assert data["message"].startswith("no violation within bounds — stopped by --max-states 50 [")
    assert [b["bound"] for b in data["checked"]["bounds"]] == ["--depth 1000", "--max-states 50",
                                                               "--max-memory 80% of RAM"]
    # the same bounds stopped the search
    assert [b["stopped"] for b in data["checked"]["bounds"]] == \
        [b["stopped"] for b in r.checked["bounds"]] == [False, True, False]


@pytest.mark.parametrize("kw, flag, keyword", [
    (dict(rates={1: 5}), ["--rate", "1=5"], "rates"),
    (dict(overrides={"zz": "1"}), ["--set", "zz=1"], "overrides"),
    (dict(agents=20_000), ["--agents", "20000"], "agents"),
])
def test_model_option_errors_name_the_keyword_in_the_api_and_the_flag_in_the_cli(kw, flag,
                                                                                   keyword):
    with pytest.raises(ArgumentError) as e:
        api.explore(FISCHER, **kw)
    api_text = str(e.value)
    assert api_text.startswith(f"pccl.api.explore: error: {keyword}: ")
    out = cli("explore", FISCHER, *flag)
    assert out.exit_code == 2
    assert out.stderr.startswith(f"{flag[0]}: error: ")
    # the same message after the prefix, the options it names spelt each way
    api_msg, cli_msg = api_text.split(f"{keyword}: ", 1)[1], out.stderr.strip().split(": error: ", 1)[1]
    assert "--" not in api_msg
    assert cli_msg == api_msg.replace("(n0=5 rates={1: 5})", "(--n0 5 --rate 1=5)")


# ---------------------------------------------------------------------------
# run --property: what one run says about a temporal property
# ---------------------------------------------------------------------------

def _outcomes(res):
    return {o.name: o.outcome for o in res.properties}


def test_run_property_within_is_violated_on_the_run_and_explore_agrees():
    prop = "inCs[0] ~> !inCs[0] within 3"
    res = api.run(FISCHER, overrides={"k": "1"}, properties=[prop], max_time=30)
    assert res.status == "violation" and res.exit_status == 1
    assert _outcomes(res)[prop] == "violated"
    assert res.violations[0].kind == "within"
    # every run is one of explore's runs: explore must find a violation too
    ex = api.explore(FISCHER, overrides={"k": "1"}, properties=[prop])
    assert ex.status == "violation" and ex.violation.name == prop
    out = cli("run", FISCHER, "--set", "k=1", "--property", prop, "--max-time", "30")
    assert out.exit_code == 1 and f"  {prop}: violated — " in out.output


def test_run_property_eventually_decided_when_the_run_ends():
    done = "eventually forall i: exited[i]"
    never = "eventually count(exited) == 3"       # two agents
    res = api.run(RACE, world=RACE_WORLD, blackbox="instant", seed=3, properties=[done])
    assert res.status == "final" and res.exit_status == 0 and _outcomes(res)[done] == "holds"
    res = api.run(RACE, world=RACE_WORLD, blackbox="instant", seed=3, properties=[never])
    assert res.status == "violation" and res.exit_status == 1
    assert _outcomes(res)[never] == "violated"
    ex = api.explore(RACE, world=RACE_WORLD, blackbox="instant", properties=[never])
    assert ex.status == "violation"


def test_run_property_cut_run_is_undecided_and_reachable_is_reported():
    res = api.run(RACE, world=RACE_WORLD, blackbox="instant", seed=3, max_time=1,
                  properties=["eventually forall i: exited[i]", "reachable count(exited) == 2",
                              "reachable time == 0"])
    assert res.status == "bounded" and res.exit_status == 0
    assert _outcomes(res) == {"eventually forall i: exited[i]": "undecided",
                              "reachable count(exited) == 2": "not reached",
                              "reachable time == 0": "witnessed"}


def test_run_property_typo_is_a_user_error():
    out = cli("run", FISCHER, "--property", "eventualy count(inCs) == 1")
    assert out.exit_code == 2 and "^" in out.stderr


# ---------------------------------------------------------------------------
# the lists of option names are derived from the dataclasses
# ---------------------------------------------------------------------------

#: a bad value for every model option validate.model_options checks, and the
#: message's start: a new model option needs its line here (the test below
#: fails until it has one), so its check cannot be forgotten
BAD_MODEL_VALUES = {
    "delta": (0, "delta must be positive"), "n0": (0, "n0 must be an integer >= 1"),
    "rates": ([1], "rates must map agent indexes"), "events": ("all", "events must be 'any' or 'first'"),
    "collisions": ("yes", "collisions must be True or False"),
    "invariants": ("x > 0", "invariants must be a list of strings"),
    "properties": ("x > 0", "properties must be a list of strings"),
    "max_time": (-1, "max_time must be >= 0"), "functions": ([1], "functions must map names"),
    "rand_policy": (3, "rand_policy must be callable"),
    "abstract_time": ("on", "abstract_time must be True or False"),
    "reduce": (3, "reduce must be 'auto', 'none' or a list"),
    "semantics": ("rounds", "semantics must be None, 'pccl' or 'koord'"),
    "skip_events": ("yes", "skip_events must be True or False"),
}


def test_the_model_options_checked_are_the_dataclass_fields():
    """``MODEL_OPTIONS`` is ModelOptions' fields but those checked on their
    own, and each is checked: a bad value is an error naming it."""
    fields = [f.name for f in dataclasses.fields(O.ModelOptions)]
    assert O.CHECKED_ALONE <= set(fields)
    assert O.MODEL_OPTIONS == tuple(n for n in fields if n not in O.CHECKED_ALONE)
    assert set(BAD_MODEL_VALUES) == set(O.MODEL_OPTIONS)
    for name, (value, message) in BAD_MODEL_VALUES.items():
        with pytest.raises(ArgumentError, match=r"pccl\.api\.make_model: error: " + message):
            api.make_model(FISCHER, **{name: value})


def test_a_new_field_is_seen_by_the_derived_lists():
    """A field added to the options dataclasses joins the model options
    checked and the identity of a checkpointed search (unless excluded)."""
    M2 = dataclasses.make_dataclass("M2", [("brand_new", int, 0)], bases=(O.ModelOptions,), frozen=True)
    E2 = dataclasses.make_dataclass("E2", [("brand_new", int, 0)], bases=(O.ExploreOptions,), frozen=True)
    assert O.model_option_names(M2) == O.MODEL_OPTIONS + ("brand_new",)
    assert O.identity_option_names(E2) == O.IDENTITY_OPTIONS + ("brand_new",)


def test_the_checkpoint_identity_is_every_search_option_but_the_resources():
    fields = {f.name for f in dataclasses.fields(O.ExploreOptions)}
    assert (O.NOT_IDENTITY - O.API_ONLY) <= fields
    assert set(O.IDENTITY_OPTIONS) == fields - O.NOT_IDENTITY
    # the list this replaced (kept by hand in pccl/search/checkpoint.py): the same options
    assert set(O.IDENTITY_OPTIONS) == {
        "agents", "blackbox", "delta", "n0", "rates", "events", "collisions", "overrides",
        "lang", "semantics", "skip_events", "invariants", "properties", "max_time", "abstract_time",
        "reduce", "depth", "max_states",
        "deadlock", "find_all", "exact", "timelock", "stall", "coverage", "fastest"}


def test_the_conversions_are_derived_from_the_field_defaults():
    assert O.MAPPING_OPTIONS == ("rates", "overrides")
    assert O.LIST_OPTIONS == ("invariants", "properties")
    assert O.TIME_OPTIONS == ("delta", "max_time")
    # and they convert: the CLI's pairs and tuples, a JSON form's string agent keys
    o = O.ExploreOptions.from_cli({"rates": ((1, 2),), "invariants": ["x"], "delta": 2.0})
    assert o.rates == {1: 2} and o.invariants == ("x",) and o.delta == 2 and isinstance(o.delta, int)
    assert O.ExploreOptions.from_dict(o.to_dict()) == o
