"""pccl replay: reproduces violations and clean runs; names the first divergence."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import cli
from pccl.output import traces as T
from pccl.lang.errors import PcclError
from pccl.tools.replay import replay as api_replay

ROOT = Path(__file__).resolve().parents[2]
PROGRAMS = ROOT / "programs"
LOST = ROOT / "docs" / "examples" / "lost_update.pccl"


def record(tmp_path, *args, name="t.json"):
    out = tmp_path / name
    cli(*args, "--trace-out", out)
    return out


def test_replay_reproduces_a_counterexample(tmp_path):
    t = record(tmp_path, "explore", PROGRAMS / "fischer.pccl", "--invariant", "count(inCs) <= 1",
               "--set", "k=1")
    n = len(json.loads(t.read_text())["steps"])
    assert n >= 130             # the globally shortest (--reduce none) has 130
    res = cli("replay", t)
    assert res.exit_code == 1, res.output
    assert f"replayed {n} of {n} steps" in res.output
    assert "reproduced: invariant 'count(inCs) <= 1' violated" in res.output
    assert "warning" not in res.output


def test_a_property_option_violation_is_recorded_and_reproduced(tmp_path):
    # --property texts travel in the trace (property_options) so that replay
    # checks them again; the reductions the search ran with are recorded too
    t = record(tmp_path, "explore", PROGRAMS / "fischer.pccl", "--property", "count(inCs) <= 1",
               "--set", "k=1")
    doc = json.loads(t.read_text())
    assert doc["config"]["property_options"] == ["count(inCs) <= 1"]
    assert doc["config"]["invariants"] == []
    assert doc["config"]["reductions"] == ["merge", "symmetry", "por", "dead"]
    n = len(doc["steps"])
    res = cli("replay", t)
    assert res.exit_code == 1, res.output
    assert f"replayed {n} of {n} steps" in res.output
    assert "reproduced: invariant 'count(inCs) <= 1' violated" in res.output
    t = record(tmp_path, "explore", PROGRAMS / "fischer.pccl", "--property", "count(inCs) <= 1",
               "--set", "k=1", "--reduce", "none", name="none.json")
    assert json.loads(t.read_text())["config"]["reductions"] == []
    # a file written before these fields existed still replays (they are optional)
    old = json.loads(t.read_text())
    del old["config"]["property_options"], old["config"]["reductions"]
    del old["config"]["options"]            # written later still (issue 22)
    old["config"]["invariants"] = ["count(inCs) <= 1"]
    (tmp_path / "old.json").write_text(json.dumps(old))
    res = cli("replay", tmp_path / "old.json")
    assert res.exit_code == 1 and "reproduced:" in res.output, res.output


def test_a_reduced_counterexample_replays_step_by_step(tmp_path):
    # under the default reductions the trace file holds the expanded,
    # unreduced steps: replay re-executes each of them
    t = record(tmp_path, "explore", LOST, "--reduce", "auto", name="auto.json")
    n = len(json.loads(t.read_text())["steps"])
    full = record(tmp_path, "explore", LOST, "--reduce", "none", name="none.json")
    assert n >= len(json.loads(full.read_text())["steps"])
    res = cli("replay", t)
    assert res.exit_code == 1, res.output
    assert f"replayed {n} of {n} steps" in res.output
    assert "reproduced: invariant 'noLostUpdate' violated" in res.output


def test_replay_reproduces_a_clean_run(tmp_path):
    t = record(tmp_path, "run", PROGRAMS / "race.pccl", "--world", PROGRAMS / "race.toml",
               "-b", "instant", "--seed", "3")
    res = cli("replay", t)
    assert res.exit_code == 0, res.output
    assert "reproduced: final" in res.output


def test_replay_reproduces_a_stuck_run_with_rand_and_nondet(tmp_path):
    t = record(tmp_path, "run", PROGRAMS / "race_nonatomic.pccl", "--world", PROGRAMS / "race.toml",
               "-b", "nondet", "--agents", "3", "--seed", "5")
    res = cli("replay", t)
    assert res.exit_code == 1, res.output
    assert "stuck" in res.output


def test_edited_program_warns_and_names_the_diverging_step(tmp_path):
    prog = tmp_path / "lost.pccl"
    shutil.copy(LOST, prog)
    t = record(tmp_path, "explore", prog, "--reduce", "none")
    prog.write_text(prog.read_text().replace("total = mine + 1;", "total = mine + 2;"))
    res = cli("replay", t)
    assert res.exit_code == 2, res.output
    assert "has changed since the trace was recorded" in res.output
    assert "diverged at step 3 of 20 (agent 0 STATEMENT [Add] line 16" in res.output
    assert "the program differs here: line 16 now reads 'total = mine + 2;'" in res.output


def test_tampered_changes_are_named(tmp_path):
    t = record(tmp_path, "explore", LOST, "--reduce", "none")
    d = json.loads(t.read_text())
    d["steps"][2]["changes"][0]["new"] = 5
    t.write_text(json.dumps(d))
    res = cli("replay", t)
    assert res.exit_code == 2 and "diverged at step 3 of 20" in res.output
    assert "recorded total 0 -> 5; replayed total 0 -> 1" in res.output


def test_shifted_program_reports_a_transition_not_enabled(tmp_path):
    prog = tmp_path / "lost.pccl"
    shutil.copy(LOST, prog)
    t = record(tmp_path, "explore", prog, "--reduce", "none")
    prog.write_text(prog.read_text().replace("    mine = total;", "    skip;\n    mine = total;"))
    res = cli("replay", t)
    assert res.exit_code == 2
    assert "diverged at step 2 of 20" in res.output
    assert "line 15 now reads 'skip;'" in res.output


def test_tampered_initial_state_diverges_at_the_start(tmp_path):
    t = record(tmp_path, "explore", LOST, "--reduce", "none")
    d = json.loads(t.read_text())
    d["initial"]["shared"]["total"] = 7
    t.write_text(json.dumps(d))
    res = cli("replay", t)
    assert res.exit_code == 2
    assert "diverged at the initial state" in res.output and "shared.total" in res.output


def test_replay_accepts_json_output_and_refuses_other_files(tmp_path):
    out = cli("explore", LOST, "--format", "json").output
    (tmp_path / "o.json").write_text(out)
    assert cli("replay", tmp_path / "o.json").exit_code == 1
    (tmp_path / "bad.json").write_text("{}")
    res = cli("replay", tmp_path / "bad.json")
    assert res.exit_code == 2 and "not a pccl trace file" in res.output
    res = cli("replay", tmp_path / "missing.json")
    assert res.exit_code == 2


def test_replay_plot(tmp_path):
    t = record(tmp_path, "explore", LOST, "--reduce", "none")
    res = cli("replay", t, "--plot", tmp_path / "p.png")
    assert res.exit_code == 1 and (tmp_path / "p.png").stat().st_size > 0


def test_a_step_that_is_not_enabled_lists_the_enabled_ones(tmp_path):
    t = record(tmp_path, "explore", LOST, "--reduce", "none")
    d = json.loads(t.read_text())
    d["steps"][0]["rule"] = "IDLE"
    t.write_text(json.dumps(d))
    res = cli("replay", t)
    assert res.exit_code == 2
    assert "diverged at step 1 of 20 (agent 0 IDLE [Add] line 13" in res.output
    assert "that transition is not enabled; enabled here: agent 0 EVENT SELECT [Add]" in res.output


# ---------------------------------------------------------------------------
# trace files are data (issue 20): nothing named in a file is imported, every
# malformed file is one message naming the field (exit 2), the end of a trace
# is re-derived, not trusted
# ---------------------------------------------------------------------------

TESTS = ROOT / "tests"
RDV = TESTS / "programs" / "rdv_meet.pccl"
RDV_OPEN = TESTS / "programs" / "rdv_open.toml"
RDV_WALL = TESTS / "programs" / "rdv_wall.toml"
RACE_NA = PROGRAMS / "race_nonatomic.pccl"


def pccl_exe() -> str:
    return str(Path(sys.executable).with_name("pccl"))


def rewrite(path, edit, name=None):
    """A copy of the trace ``path`` with ``edit(doc)`` applied."""
    d = json.loads(Path(path).read_text())
    edit(d)
    out = Path(path).with_name(name or "edited.json")
    out.write_text(json.dumps(d))
    return out


def typed_state(path, k):
    """The typed state after step k of the trace ``path`` (as replay rebuilds it)."""
    r = api_replay(path)
    return T.normal(T.state_typed(r.model, r.states[k]))


@pytest.fixture(scope="module")
def run_trace(tmp_path_factory):
    d = tmp_path_factory.mktemp("run")
    out = d / "run.json"
    res = cli("run", PROGRAMS / "race.pccl", "--world", PROGRAMS / "race.toml", "-b", "instant",
              "--seed", "3", "--trace-out", out)
    assert res.exit_code == 0, res.output
    return out


def test_a_trace_naming_os_abort_is_refused_and_nothing_runs(tmp_path):
    # the issue: replay imported and called config.blackbox, os:abort killed it (exit 134)
    t = record(tmp_path, "explore", LOST, "--reduce", "none")
    bad = rewrite(t, lambda d: d["config"].__setitem__("blackbox", "os:abort"))
    p = subprocess.run([pccl_exe(), "replay", str(bad)], capture_output=True, text=True,
                       timeout=120)
    assert p.returncode == 2, (p.returncode, p.stdout, p.stderr)
    assert "Traceback" not in p.stderr
    assert (f"{bad}: error: config.blackbox: the trace names the user blackbox 'os:abort'; "
            "replay does not import code a trace file names: if you trust it, pass "
            "--blackbox os:abort") in p.stderr
    # given on the command line it must be the file's own name
    res = cli("replay", bad, "--blackbox", "os:getcwd")
    assert res.exit_code == 2
    assert ("config.blackbox: the trace was recorded with blackbox 'os:abort', but --blackbox "
            "gives 'os:getcwd'") in res.output


def test_a_user_blackbox_replays_only_when_the_user_names_it(tmp_path):
    bb = tmp_path / "hop_bb.py"
    shutil.copy(TESTS / "replay_user_bb.py", bb)
    marker = bb.with_suffix(".imported")
    spec = f"{bb}:BLACKBOX"
    t = record(tmp_path, "run", RDV, "--world", RDV_OPEN, "-b", spec, "--seed", "1")
    assert json.loads(t.read_text())["config"]["blackbox"] == spec
    marker.unlink()
    res = cli("replay", t)
    assert res.exit_code == 2 and f"pass --blackbox {spec}" in res.output
    assert not marker.exists()              # not imported
    res = cli("replay", t, "--blackbox", spec)
    assert res.exit_code == 0, res.output
    assert "blackbox hop" in res.output and "reproduced: final" in res.output
    assert marker.exists()
    # another blackbox than the file's: refused, naming both
    res = cli("replay", t, "--blackbox", "instant")
    assert res.exit_code == 2
    assert f"recorded with blackbox '{spec}', but --blackbox gives 'instant'" in res.output


def test_the_api_takes_a_blackbox_object_checked_against_the_file(tmp_path):
    import importlib.util
    bb = tmp_path / "hop_api.py"
    shutil.copy(TESTS / "replay_user_bb.py", bb)
    t = record(tmp_path, "run", RDV, "--world", RDV_OPEN, "-b", f"{bb}:BLACKBOX", "--seed", "1")
    spec = importlib.util.spec_from_file_location("hop_api_for_test", bb)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    # an object of the same name: the file named it as module:attr (the
    # module loaded under another name here), its name is "hop"
    with pytest.raises(PcclError, match="config.blackbox: the trace names the user blackbox"):
        api_replay(t)
    doc = json.loads(t.read_text())
    doc["config"]["blackbox"] = "hop"             # how the API records an object
    t2 = tmp_path / "api.json"
    t2.write_text(json.dumps(doc))
    r = api_replay(t2, blackbox=mod.BLACKBOX)
    assert (r.status, r.exit_status) == ("clean", 0), r.message
    from pccl.blackboxes import INSTANT
    with pytest.raises(PcclError, match="recorded with blackbox 'hop', but the blackbox given "
                                        "is 'instant'"):
        api_replay(t2, blackbox=INSTANT)


MALFORMED = {
    # name: (how the file is made from a good one's text, or its parsed
    # document; the message expected)
    "invalid UTF-8": (lambda text: text.encode().replace(b'"pccl-trace"', b'"pccl-\xfftrace"'),
                      "not a trace file: not UTF-8 (byte 0xff at offset"),
    "an integer of 5,000 digits": (lambda text: text.replace('"index": 1,', '"index": ' + "9" * 5000 + ",", 1),
                                   "not a trace file: an integer of 5000 digits (at most 4300)"),
    "deeply nested JSON": (lambda text: text.replace('"steps": [', '"steps": ' + "[" * 100_000, 1),
                           "not a trace file: nested too deeply"),
    "a violation of the wrong type": (lambda d: d["result"].__setitem__("violation", "bad"),
                                      "result.violation: expected an object, got a string"),
    "a missing config": (lambda d: d.pop("config"), "config: missing"),
    "steps not a list": (lambda d: d.__setitem__("steps", {"0": d["steps"][0]}),
                         "steps: expected a list, got an object"),
    "a step of the wrong type": (lambda d: d["steps"].__setitem__(3, "STATEMENT"),
                                 "steps[3]: expected an object, got a string"),
    "changes of the wrong type": (lambda d: d["steps"][2].__setitem__("changes", 5),
                                  "steps[2].changes: expected a list, got an integer 5"),
    "a cell of the wrong type": (lambda d: d["steps"][2]["changes"][0].__setitem__("cell", "total"),
                                 "steps[2].changes[0].cell: expected an object, got a string"),
    "an agent index of the wrong type": (lambda d: d["initial"].__setitem__("agents", "two"),
                                         "initial.agents: expected a list, got a string"),
    # every kind of JSON value named in the message (pccl/lang/data.py)
    "a null config": (lambda d: d.__setitem__("config", None), "config: expected an object, got null"),
    "a result that is a list": (lambda d: d.__setitem__("result", []),
                                "result: expected an object, got a list"),
    "steps that are a boolean": (lambda d: d.__setitem__("steps", True),
                                 "steps: expected a list, got a boolean true"),
    "steps that are a number": (lambda d: d.__setitem__("steps", 1.5),
                                "steps: expected a list, got a number 1.5"),
    "agents that are a boolean": (lambda d: d["config"].__setitem__("agents", True),
                                  "config.agents: expected an integer, got a boolean true"),
    "an infinite delta": (lambda text: text.replace('"delta": 1,', '"delta": 1e999,', 1),
                          "config.delta: expected a finite number, got a number Infinity"),
}


@pytest.fixture(scope="module")
def lost_trace(tmp_path_factory):
    out = tmp_path_factory.mktemp("lost") / "lost.json"
    res = cli("explore", LOST, "--reduce", "none", "--trace-out", out)
    assert res.exit_code == 1
    return out


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_a_malformed_trace_is_one_message_naming_the_field(lost_trace, tmp_path, case):
    make, message = MALFORMED[case]
    text = lost_trace.read_text()
    bad = tmp_path / "bad.json"
    if make.__code__.co_varnames[0] == "text":
        out = make(text)
    else:                                       # an edit of the parsed document
        d = json.loads(text)
        make(d)
        out = json.dumps(d, indent=1)
    if isinstance(out, bytes):
        bad.write_bytes(out)
    else:
        bad.write_text(out)
    res = cli("replay", bad)
    assert res.exit_code == 2, res.output
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"{bad}"), res.output
    assert message in lines[0], res.output


def test_a_json_syntax_error_names_line_and_column(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text('{"format": "pccl-trace",\n  "version": 1,\n  "config": }\n')
    res = cli("replay", bad)
    assert res.exit_code == 2
    assert res.output.startswith(f"{bad}:3:13: error: not a JSON trace file: Expecting value")


def test_a_run_trace_with_its_steps_removed_does_not_reproduce(run_trace, tmp_path):
    # the issue: it replayed as "reproduced: final — every agent exited"
    t = rewrite(run_trace, lambda d: d.__setitem__("steps", []))
    res = cli("replay", t)
    assert res.exit_code == 2, res.output
    assert "the recorded final state is not the last state" in res.output
    # final made consistent as well: the run does not end at the initial state
    init = json.loads(run_trace.read_text())["initial"]
    t = rewrite(t, lambda d: d.__setitem__("final", init), "edited2.json")
    res = cli("replay", t)
    assert res.exit_code == 2, res.output
    assert ("the recorded run ends here (final: every agent exited) and the replayed one goes "
            "on") in res.output
    assert "reproduced:" not in res.output


def test_a_run_result_rewritten_to_deadlock_does_not_reproduce(run_trace):
    # the issue: it replayed as "reproduced: deadlock"
    t = rewrite(run_trace, lambda d: d["result"].__setitem__("status", "deadlock"))
    res = cli("replay", t)
    assert res.exit_code == 2, res.output
    assert ("the recorded result (deadlock: every agent exited) does not match the replayed "
            "run's (final: every agent exited)") in res.output


def test_a_run_cut_short_does_not_reproduce(run_trace):
    d = json.loads(run_trace.read_text())
    k = len(d["steps"]) - 5
    final = typed_state(run_trace, k)

    def cut(d):
        d["steps"] = d["steps"][:k]
        d["final"] = final
    res = cli("replay", rewrite(run_trace, cut))
    assert res.exit_code == 2, res.output
    assert "the replayed one goes on" in res.output


def test_the_end_of_a_run_agrees_with_the_runner(tmp_path):
    # two ways to the same verdict: the run's own result and the replay's
    # re-derivation of it, over runs that end differently
    cases = [("run", PROGRAMS / "race.pccl", "--world", PROGRAMS / "race.toml", "-b", "instant"),
             ("run", RACE_NA, "--world", PROGRAMS / "race.toml", "-b", "nondet", "--agents", "3"),
             ("run", PROGRAMS / "fischer.pccl", "--set", "k=1", "--max-time", "8",
              "--invariant", "count(inCs) <= 1")]
    seen = set()
    for n, case in enumerate(cases):
        for seed in (1, 5):
            t = record(tmp_path, *case, "--seed", seed, name=f"r{n}_{seed}.json")
            rec = json.loads(t.read_text())["result"]
            res = cli("replay", t)
            failed = rec["violation"] or rec["status"] in ("stalled", "max-steps")
            assert res.exit_code == (1 if failed else 0), res.output
            assert "reproduced:" in res.output and rec["message"] in res.output
            seen.add(rec["status"])
    assert len(seen) >= 2, seen


@pytest.fixture(scope="module")
def lasso_trace(tmp_path_factory):
    out = tmp_path_factory.mktemp("lasso") / "lasso.json"
    res = cli("explore", RDV, "--world", RDV_WALL, "-b", "straight", "--property",
              "eventually forall i: exited[i]", "--trace-out", out)
    assert res.exit_code == 1
    return out


def test_a_lasso_replays_and_closes(lasso_trace):
    d = json.loads(lasso_trace.read_text())
    cs = d["result"]["cycle_start"]
    res = cli("replay", lasso_trace)
    assert res.exit_code == 1, res.output
    assert f"a lasso: the cycle from step {cs} closes" in res.output


def test_a_lasso_whose_cycle_was_cut_off_is_refused(lasso_trace):
    # the issue: a lasso whose cycle was cut off was accepted
    d = json.loads(lasso_trace.read_text())
    k = len(d["steps"]) - 2
    final = typed_state(lasso_trace, k)

    def cut(d):
        d["steps"] = d["steps"][:k]
        d["final"] = final
    res = cli("replay", rewrite(lasso_trace, cut))
    assert res.exit_code == 2, res.output
    assert (f"the cycle does not close: the last state is not the state after step "
            f"{d['result']['cycle_start']}") in res.output


def test_a_lasso_must_be_a_counterexample_of_its_property(lasso_trace):
    # the same lasso claimed for a property it does not violate
    def other(d):
        d["config"]["property_options"] = ["eventually met || !met"]
        d["config"]["options"]["properties"] = ["eventually met || !met"]   # the options whole
        d["result"]["violation"]["name"] = "eventually met || !met"
    res = cli("replay", rewrite(lasso_trace, other))
    assert res.exit_code == 2, res.output
    assert "`eventually met || !met` holds after step 0" in res.output
    res = cli("replay", rewrite(lasso_trace, lambda d: d["result"].pop("cycle_start")))
    assert res.exit_code == 2
    assert "the path does not end in a terminal state" in res.output


TL_SPIN = TESTS / "programs" / "tl_spin.pccl"
TL_SPIN_LEAVE = TESTS / "programs" / "tl_spin_leave.pccl"


def _zero_time_lasso(m):
    """A path of ``m`` (breadth-first from an initial state) to a state
    that two steps, neither a time advance, lead back to (up to the key):
    (states, labels, cycle_start)."""
    from collections import deque
    init = next(iter(m.init_states()))
    parent: dict = {m.key(init): None}
    todo = deque([init])
    while todo:
        s = todo.popleft()
        for l1, n1 in m.successors(s):
            for l2, n2 in m.successors(n1):
                if m.key(n2) == m.key(s) and "TIME ADVANCE" not in (l1[0], l2[0]):
                    states, labels, k = [s], [], m.key(s)
                    while parent[k] is not None:
                        prev, lab = parent[k]
                        states.insert(0, prev)
                        labels.insert(0, lab)
                        k = m.key(prev)
                    return states + [n1, n2], labels + [l1, l2], len(labels)
        for lab, nxt in m.successors(s):
            if m.key(nxt) not in parent:
                parent[m.key(nxt)] = (s, lab)
                todo.append(nxt)
    raise AssertionError("no zero-time cycle")


def test_a_time_lock_replays_and_a_false_one_does_not(tmp_path):
    # the time-lock end of a trace: a real one is reproduced (the cycle
    # closes, time never advances in it nor from anything reachable) ...
    t = record(tmp_path, "explore", TL_SPIN, "--reduce", "none", name="tl.json")
    d = json.loads(t.read_text())
    assert d["result"]["violation"]["kind"] == "timelock"
    cs = d["result"]["cycle_start"]
    res = cli("replay", t)
    assert res.exit_code == 1, res.output
    assert "reproduced: time-lock: time can never advance again" in res.output
    assert f"a lasso: the cycle from step {cs} closes" in res.output
    # ... a time-lock is a lasso ...
    res = cli("replay", rewrite(t, lambda d: d["result"].pop("cycle_start")))
    assert res.exit_code == 2, res.output
    assert "a time-lock counterexample is a lasso" in res.output


#: agent 0 spins in zero time until agent 1 sets go, then both run their
#: event again and again: no run ends, but time advances
SPIN_THEN_TIME = """allwrite:
  bool go = false;
loc:
  int id = getAgentIndex();
Run():
  pre(true);
  eff:
    if (id == 0):
      while (!go):
        skip;
    else:
      go = true;
"""


@pytest.mark.parametrize("how", ["the run can end", "time can advance"])
def test_a_zero_time_cycle_that_can_be_left_is_no_time_lock(tmp_path, how):
    # a real path of the model, whose zero-time cycle closes, claimed as a
    # time-lock: in tl_spin_leave every run can end; in SPIN_THEN_TIME none
    # can, but time advances once agent 1 has set go
    if how == "the run can end":
        program = TL_SPIN_LEAVE
    else:
        program = tmp_path / "spin_then_time.pccl"
        program.write_text(SPIN_THEN_TIME)
    tl = json.loads(record(tmp_path, "explore", TL_SPIN, name="tl.json").read_text())
    v = record(tmp_path, "explore", program, "--reduce", "none", "--invariant", "!go",
               name="v.json")
    m = api_replay(v).model
    states, labels, start = _zero_time_lasso(m)
    from pccl.search.explorer import Trace
    forged = T.document(m, json.loads(v.read_text())["config"],
                        Trace(tuple(states), tuple(labels)), status="violation",
                        message=tl["result"]["message"])
    forged["result"]["violation"] = tl["result"]["violation"]
    forged["result"]["cycle_start"] = start
    (tmp_path / "forged.json").write_text(json.dumps(forged))
    res = cli("replay", tmp_path / "forged.json")
    assert res.exit_code == 2, res.output
    assert f"replayed {len(labels)} of {len(labels)} steps" in res.output
    assert ("every step reproduced, but time can advance again (or the run end) from the "
            "recorded time-lock cycle") in res.output


def test_an_unreachable_verdict_is_not_replayed_as_a_clean_run(tmp_path):
    # the issue: it replayed with exit 0
    t = record(tmp_path, "explore", PROGRAMS / "fischer.pccl", "--set", "k=0", "--property",
               "reachable count(inCs) == 3")
    res = cli("replay", t)
    assert res.exit_code == 2, res.output
    assert ("nothing to replay: the recorded verdict (unreachable: no reachable state "
            "satisfies `reachable count(inCs) == 3`) is about every run of the model, and no "
            "trace can reproduce it") in res.output


def test_a_reachable_witness_is_written_and_replayed(tmp_path):
    t = record(tmp_path, "explore", PROGRAMS / "fischer.pccl", "--set", "k=0", "--property",
               "reachable count(inCs) == 1")
    d = json.loads(t.read_text())
    assert d["result"]["witness"] == {"name": "reachable count(inCs) == 1",
                                      "text": "reachable count(inCs) == 1"}
    assert d["result"]["violation"] is None and len(d["steps"]) >= 1
    res = cli("replay", t)
    assert res.exit_code == 0, res.output
    assert (f"reproduced: witness — `reachable count(inCs) == 1` holds after "
            f"{len(d['steps'])} steps") in res.output
    # cut before the step that sets inCs (final made consistent): no witness
    k = min(n for n, st in enumerate(d["steps"])
            if any(c["cell"].get("var") == "inCs" and c["new"] is True for c in st["changes"]))
    final = typed_state(t, k)

    def cut(d):
        d["steps"] = d["steps"][:k]
        d["final"] = final
    res = cli("replay", rewrite(t, cut))
    assert res.exit_code == 2
    assert "does not hold in the last state, so the path is no witness" in res.output


def test_step_time_branch_and_final_are_checked(lost_trace):
    res = cli("replay", rewrite(lost_trace, lambda d: d["steps"][3].__setitem__("time", 1)))
    assert res.exit_code == 2
    assert "diverged at step 4 of 20" in res.output and "its time differs" in res.output

    def flip(d):
        d["final"]["shared"]["total"] = 7
    res = cli("replay", rewrite(lost_trace, flip))
    assert res.exit_code == 2
    assert "the recorded final state is not the last state (final.shared.total" in res.output
    # 1 is not true: values are compared as JSON, with their types
    res = cli("replay", rewrite(lost_trace, lambda d: d["initial"]["shared"].__setitem__(
        "total", float(d["initial"]["shared"]["total"]))))
    assert res.exit_code == 2 and "diverged at the initial state" in res.output


def test_a_violation_record_must_match(lost_trace):
    res = cli("replay", rewrite(lost_trace, lambda d: d["result"]["violation"].__setitem__(
        "line", 99)))
    assert res.exit_code == 2 and "is not: invariant 'noLostUpdate' violated" in res.output


def test_a_run_violating_a_temporal_property_replays(tmp_path):
    # the run monitor's violation carries the property's kind ("within"); the
    # schema and replay used to refuse such a file
    t = record(tmp_path, "run", PROGRAMS / "fischer.pccl", "--set", "k=1", "--max-time", "30",
               "--property", "start[0] ~> inCs[1] within 1", "--seed", "2")
    d = json.loads(t.read_text())
    assert d["result"]["violation"]["kind"] == "within"
    import jsonschema
    jsonschema.validate(d, json.loads((ROOT / "docs" / "trace-format.schema.json").read_text()),
                        cls=jsonschema.Draft202012Validator)
    res = cli("replay", t)
    assert res.exit_code == 1, res.output
    assert "reproduced: start[0] ~> inCs[1] within 1: the premise held at t = 0" in res.output


def test_a_stalled_run_replays_with_its_recorded_stall_steps(tmp_path):
    t = record(tmp_path, "run", RDV, "--world", RDV_WALL, "-b", "straight", "--stall-steps", "3")
    res = cli("replay", t)
    assert res.exit_code == 1, res.output
    assert "reproduced: agent 0 waits for Go" in res.output
    assert "nothing changed since t = 1" in res.output
    # a file without stall_steps (older) means the default, 20: this run
    # would not have stopped yet
    res = cli("replay", rewrite(t, lambda d: d["config"].pop("stall_steps")))
    assert res.exit_code == 2 and "the replayed one goes on" in res.output


# ---------------------------------------------------------------------------
# issue 27, item 2: replay from anywhere, --program/--world, hashes, --view
# ---------------------------------------------------------------------------

def _make_trace_elsewhere(tmp_path):
    """A run recorded from tmp_path/made with a relative program path; the
    trace goes to tmp_path/made/traces/t.json."""
    made = tmp_path / "made"
    (made / "traces").mkdir(parents=True)
    shutil.copy(PROGRAMS / "fischer.pccl", made / "fischer.pccl")
    res = cli("run", "fischer.pccl", "--set", "k=1", "--invariant", "count(inCs) <= 1",
              "--trace-out", "traces/t.json", cwd=made)
    assert res.exit_code == 1
    return made, made / "traces" / "t.json"


def test_replay_from_another_directory(tmp_path):
    made, t = _make_trace_elsewhere(tmp_path)
    rec = json.loads(t.read_text())["config"]["program"]
    assert rec["path"] == "fischer.pccl"
    assert rec["absolute"] == str(made / "fischer.pccl")
    assert rec["relative"] == str(Path("..") / "fischer.pccl")
    res = cli("replay", t, cwd=ROOT)                 # not where it was made
    assert res.exit_code == 1, res.output
    assert "reproduced: invariant 'count(inCs) <= 1' violated" in res.output
    assert "warning" not in res.output


def test_replay_after_moving_trace_and_program_together(tmp_path):
    made, t = _make_trace_elsewhere(tmp_path)
    moved = tmp_path / "moved"
    shutil.move(str(made), str(moved))               # the absolute path is gone
    res = cli("replay", moved / "traces" / "t.json", cwd=ROOT)
    assert res.exit_code == 1, res.output
    assert "reproduced" in res.output


def test_replay_missing_program_says_how_to_give_it(tmp_path):
    made, t = _make_trace_elsewhere(tmp_path)
    (made / "fischer.pccl").unlink()
    res = cli("replay", t, cwd=ROOT)
    assert res.exit_code == 2 and "Traceback" not in res.output
    assert "does not exist" in res.output and "--program FILE" in res.output
    ok = cli("replay", t, "--program", PROGRAMS / "fischer.pccl", cwd=ROOT)
    assert ok.exit_code == 1 and "reproduced" in ok.output and "warning" not in ok.output


def test_replay_mismatched_program_is_found_by_hash(tmp_path):
    made, t = _make_trace_elsewhere(tmp_path)
    other = tmp_path / "other.pccl"
    src = (PROGRAMS / "fischer.pccl").read_text()
    other.write_text(src.replace("inCs = true;", "inCs = false;", 1))
    res = cli("replay", t, "--program", other, cwd=ROOT)
    assert "is not the recorded program" in res.output
    assert "sha256" in res.output
    assert res.exit_code == 2, res.output             # it diverges where they differ
    # a recorded file edited after recording: found by path, flagged by hash
    (made / "fischer.pccl").write_text(other.read_text())
    res = cli("replay", t, cwd=ROOT)
    assert "has changed since the trace was recorded" in res.output and res.exit_code == 2


def test_older_trace_files_without_absolute_paths_replay(tmp_path):
    made, t = _make_trace_elsewhere(tmp_path)
    doc = json.loads(t.read_text())
    for k in ("absolute", "relative"):
        del doc["config"]["program"][k]
    old = made / "old.json"
    old.write_text(json.dumps(doc))
    res = cli("replay", old, cwd=made)
    assert res.exit_code == 1 and "reproduced" in res.output


def test_replay_shows_the_steps_on_a_terminal(tmp_path, monkeypatch):
    import pccl.cli.cmd_traces as C
    t = record(tmp_path, "run", PROGRAMS / "fischer.pccl", "--set", "k=1",
               "--invariant", "count(inCs) <= 1")
    plain = cli("replay", t)
    steps = cli("replay", t, "--view", "steps")
    monkeypatch.setattr(C, "_stdout_is_terminal", lambda: True)
    tty = cli("replay", t)
    assert tty.output == steps.output != plain.output
    assert len(tty.output.splitlines()) > len(plain.output.splitlines()) + 100
    swim = cli("replay", t, "--view", "swimlane")
    assert swim.output != tty.output                  # an explicit --view wins
