"""Options travel whole (issue 22): ``Model(program, options)``, the options'
versioned JSON form as a trace file's ``config["options"]`` (replay rebuilds
the model from it; older files from their flat keys), and the cross-option
checks written once in pccl/model/options.py, spelt by the API and the CLI."""

from __future__ import annotations

import json

import pytest

from pccl import api
from pccl.lang.parser import parse_file
from pccl.model.engine import Model
from pccl.model.options import (OPTIONS_VERSION, ExploreOptions, ModelOptions, RunOptions,
                                api_spelling, conflict)
from pccl.tools.replay import model_from_config

from conftest import FISCHER, RACE, RACE_WORLD, cli

MUTEX = "count(inCs) <= 1"


@pytest.mark.parametrize("opts", [
    ExploreOptions(agents=3, world=RACE_WORLD, blackbox="nondet", delta=0.5, n0=2, rates={1: 2},
                   events="first", collisions=True, overrides={"k": "2"}, invariants=(MUTEX,),
                   properties=("eventually inCs[0]",), max_time=7, abstract_time=False,
                   reduce=["merge"], depth=9, max_states=100, max_memory=None, deadlock=False,
                   find_all=True, workers="auto", timelock=False, engine="python",
                   checkpoint="ck", checkpoint_interval=60),
    ExploreOptions(),
    RunOptions(seed=4, max_steps=50, stall_steps=3, max_time=12.5, invariants=("x > 0",)),
    ModelOptions(reduce="none", rates={0: 1}),
])
def test_options_round_trip_through_json(opts):
    data = json.loads(json.dumps(opts.to_dict()))
    assert data["version"] == OPTIONS_VERSION
    assert type(opts).from_dict(data) == opts


def test_from_dict_reads_a_model_s_part_and_refuses_what_it_does_not_know():
    full = ExploreOptions(depth=3, n0=2, invariants=(MUTEX,)).to_dict()
    assert ModelOptions.from_dict(full) == ModelOptions(n0=2, invariants=(MUTEX,))
    with pytest.raises(ValueError, match="unknown option nosuch"):
        ModelOptions.from_dict({**full, "nosuch": 1})
    with pytest.raises(ValueError, match="version"):
        ModelOptions.from_dict({**full, "version": OPTIONS_VERSION + 1})


def test_api_only_fields_are_not_serialised():
    d = ExploreOptions(functions={"getInput": ()}, progress=print, blackbox=None).to_dict()
    assert not {"functions", "rand_policy", "progress", "progress_interval", "source"} & set(d)


def test_the_model_keeps_its_options():
    opts = ModelOptions(agents=3, n0=2, invariants=(MUTEX,), reduce="none")
    m = Model(parse_file(FISCHER), opts)
    assert m.options is opts and m.N == 3 and m.n0 == 2 and [p.name for p in m.properties] == [MUTEX]


def _trace(tmp_path, *args) -> tuple:
    out = tmp_path / "t.json"
    res = cli("explore", FISCHER, "--set", "k=0", "--invariant", MUTEX, "--n0", "2",
              "--trace-out", str(out), *args)
    assert res.exit_code == 1, res.output
    return out, json.loads(out.read_text())


def test_a_trace_config_is_the_options_and_replay_reads_them(tmp_path):
    out, doc = _trace(tmp_path, "--max-states", "100000")
    cfg = doc["config"]
    opts = ExploreOptions.from_dict(cfg["options"])
    assert (opts.overrides, opts.invariants, opts.n0, opts.max_states) == ({"k": "0"}, (MUTEX,), 2,
                                                                          100000)
    new = model_from_config(cfg, out, [])
    old_cfg = {k: v for k, v in cfg.items() if k != "options"}     # a file from before
    old = model_from_config(old_cfg, out, [])
    assert new.options.overrides == {"k": "0"} and new.options.invariants == (MUTEX,)
    # both ways give the same model: team, properties, initial states
    assert (new.N, new.n0, [p.name for p in new.properties]) == \
        (old.N, old.n0, [p.name for p in old.properties])
    assert list(new.init_states()) == list(old.init_states())
    # replay goes by the options: an options part that says otherwise wins
    cfg2 = {**cfg, "options": {**cfg["options"], "n0": 1}}
    assert model_from_config(cfg2, out, []).n0 == 1


def test_old_trace_files_still_replay(tmp_path):
    out, doc = _trace(tmp_path)
    del doc["config"]["options"]
    out.write_text(json.dumps(doc))
    res = cli("replay", str(out))
    assert res.exit_code == 1 and "reproduced" in res.stdout, res.output


def test_a_bad_options_part_is_one_clear_error(tmp_path):
    out, doc = _trace(tmp_path)
    doc["config"]["options"]["version"] = 99
    out.write_text(json.dumps(doc))
    res = cli("replay", str(out))
    assert res.exit_code == 2 and "config.options" in res.stderr and "Traceback" not in res.output


@pytest.mark.parametrize("opts, api_text, cli_text", [
    (ExploreOptions(exact=True, ray="local"), "exact=True runs in one process: use workers=1 "
     "without ray", "--exact runs in one process: use --workers 1 without --ray"),
    (ExploreOptions(resume="d", functions={"getInput": ()}), "resume does not run with "
     "functions= (a Python object", "--resume does not run with functions= (a Python object"),
])
def test_a_cross_option_check_is_written_once_and_spelt_twice(opts, api_text, cli_text):
    from pccl.cli import cli_spelling
    c = conflict(opts)
    assert c is not None
    assert c.message(api_spelling).startswith(api_text)
    assert c.message(cli_spelling).startswith(cli_text)


def test_the_cli_spells_a_conflict_with_flags():
    res = cli("explore", RACE, "--exact", "--workers", "2")
    assert res.exit_code == 2 and "--exact runs in one process" in res.stderr
    assert "exact=True" not in res.stderr
    with pytest.raises(api.ArgumentError, match="exact=True runs in one process"):
        api.explore(RACE, exact=True, workers=2)


def test_the_explorer_takes_its_options_whole():
    from pccl.search.explorer import Explorer, SearchOptions
    o = ExploreOptions(depth=4, max_states=500, deadlock=False, find_all=True, reduce="none")
    s = o.search_options(max_memory=1 << 30)
    assert s == SearchOptions(max_depth=4, max_states=500, deadlock=False, find_all=True,
                              max_memory=1 << 30)
    m = api.make_model(FISCHER, reduce="none")
    ex = Explorer(m, s)
    assert ex.options is s and (ex.max_depth, ex.max_states, ex.deadlock) == (4, 500, False)
    # keywords still work, and agree with the options whole
    a = Explorer(m, s).run().stats.states
    b = Explorer(m, max_depth=4, max_states=500, deadlock=False, find_all=True,
                 max_memory=1 << 30).run().stats.states
    assert a == b and a <= 500


def test_options_and_the_keys_that_repeat_them_must_agree(tmp_path):
    out, doc = _trace(tmp_path)
    doc["config"]["invariants"] = ["k >= 0"]          # edited by hand, the options not
    out.write_text(json.dumps(doc))
    res = cli("replay", str(out))
    assert res.exit_code == 2 and "config.options: options.invariants" in res.stderr, res.output
