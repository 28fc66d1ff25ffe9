"""Koord's ``Motion.path`` (issue 47 item 3; docs/koord.md, "Motion.path"):
a waypoint-following motion read as a hidden local list and a hidden
first event over ``doReach`` (compared with its hand-written PCCL twin),
served by ``straight`` and the covering ``nondet``; its errors."""

from __future__ import annotations

import pytest

from pccl.api import explore, run
from pccl.lang.errors import PcclError
from pccl.lang.koord import parse_koord
from pccl.lang.parser import parse_program
from pccl.model.layout import AGS, POS

PATH = """\
using Motion:
  sensors:
    pos position
    boolean reached
  actuators:
    pos target
    pos[] path

local:
  int st = 0

go:
  pre: st == 0
  eff:
    Motion.path = [pos(2, 0), (2, 2), pos(0, 2)]
    st = 1

arrive:
  pre: st == 1 and Motion.reached
  eff:
    st = 2
    stop

invariant:
  home: forall i: exited[i] -> pos[i].x < 0.001 and pos[i].y > 1.999
"""

PATH_PCCL = """\
loc:
  int st = 0;
  List<ItemPosition> Motion_path = [];

Motion_follow():
  pre(doReach_done && !isEmpty(Motion_path));
  eff:
    doReach(head(Motion_path), []);
    remove(Motion_path, head(Motion_path));

go():
  pre(st == 0);
  eff:
    Motion_path = [ItemPosition(2, 0), ItemPosition(2, 2), ItemPosition(0, 2)];
    if !isEmpty(Motion_path):
      doReach(head(Motion_path), []);
      remove(Motion_path, head(Motion_path));
    st = 1;

arrive():
  pre(st == 1 && (doReach_done && isEmpty(Motion_path)));
  eff:
    st = 2;
    exit();

invariant:
  home: forall i: exited[i] -> pos[i].x < 0.001 && pos[i].y > 1.999;
"""


def test_path_is_the_pccl_twin():
    kp = parse_koord(PATH, "path.koord")
    pp = parse_program(PATH_PCCL, "path.pccl")
    assert kp.decls == pp.decls
    assert kp.events == pp.events
    assert kp == pp


def test_a_run_visits_the_waypoints_in_order():
    r = run(parse_koord(PATH, "path.koord"), agents=1, blackbox="straight", record_trace=True,
            max_time=20)
    assert r.status == "final", r.message
    stops = []
    for st in r.trace.states:
        p = st[AGS][0][POS][:2]
        if not stops or stops[-1] != p:
            stops.append(p)
    for w in [(2.0, 0.0), (2.0, 2.0), (0.0, 2.0)]:
        assert w in stops, stops
    assert stops.index((2.0, 0.0)) < stops.index((2.0, 2.0)) < stops.index((0.0, 2.0))
    assert r.final[AGS][0][POS][:2] == (0.0, 2.0)


@pytest.mark.parametrize("bb", ["straight", "nondet"])
@pytest.mark.parametrize("semantics", ["koord", "pccl"])
def test_explore_every_robot_ends_at_the_last_waypoint(bb, semantics):
    r = explore(parse_koord(PATH, "path.koord"), agents=1, blackbox=bb, semantics=semantics,
                properties=["eventually (forall i: exited[i])"])
    assert r.status in ("exhaustive", "bounded") and not r.violations, r.verdict
    assert r.stats.states > 5


def test_a_wrong_last_waypoint_is_caught():
    wrong = PATH.replace("pos[i].x < 0.001", "pos[i].x > 1.0")
    r = explore(parse_koord(wrong, "path.koord"), agents=1, blackbox="nondet")
    assert r.status == "violation" and r.violations[0].name == "home"


def test_a_new_target_ends_the_path():
    text = PATH.split("invariant:")[0].replace("    st = 1\n", "    Motion.target = pos(5, 5)\n    st = 1\n", 1)
    r = run(parse_koord(text, "path.koord"), agents=1, blackbox="straight", max_time=20)
    assert r.status == "final"
    assert r.final[AGS][0][POS][:2] == (5.0, 5.0)


@pytest.mark.parametrize("text,where,message", [
    (PATH.replace("  int st = 0\n", "  int st = 0\n  int Motion_path = 0\n"), (11, 7),
     "'Motion_path' is the name pccl gives"),
    (PATH.replace("arrive:", "Motion_follow:"), (18, 1), "'Motion_follow' is the name"),
    (PATH.replace("    pos[] path\n", ""), (14, 5), "'Motion.path' is not declared"),
    (PATH.replace("    pos[] path\n", "    pos path\n"), (7, 5), "port Motion.path has type pos[]"),
    (PATH.replace("st = 1\n", "st = 1\n    st = Motion.path.size()\n", 1), (17, 10),
     "Motion.path is one of the actuators"),
])
def test_path_errors_have_their_place(text, where, message):
    with pytest.raises(PcclError) as e:
        parse_koord(text, "bad.koord")
    assert message in str(e.value), str(e.value)
    assert (e.value.line, e.value.column) == where, str(e.value)


def test_a_path_that_is_not_a_list_is_one_message_exit_2(tmp_path):
    from click.testing import CliRunner
    from pccl.cli import main
    p = tmp_path / "bad.koord"
    p.write_text("using Motion:\n  actuators:\n    pos[] path\n\nev:\n  pre: true\n  eff:\n"
                 "    Motion.path = 3\n")
    res = CliRunner().invoke(main, ["check", str(p)])
    assert res.exit_code == 2 and res.stdout == ""
    assert res.stderr.startswith(f"{p}:8:19: error: cannot assign int to 'Motion.path' of type "
                                 "List<ItemPosition>"), res.stderr
    assert res.stderr.rstrip("\n").split("\n")[-1].strip().startswith("|")
    assert "Traceback" not in res.output


def test_a_path_run_replays(tmp_path):
    from pathlib import Path

    from click.testing import CliRunner
    from pccl.cli import main
    koord = Path(__file__).resolve().parents[2] / "programs" / "koord"
    trace = tmp_path / "t.json"
    res = CliRunner().invoke(main, ["run", str(koord / "follow_path.koord"), "--world",
                                    str(koord / "allstop.toml"), "--agents", "2", "-b", "straight",
                                    "--trace-out", str(trace)])
    assert res.exit_code == 0, res.output
    res = CliRunner().invoke(main, ["replay", str(trace)])
    assert res.exit_code == 0, res.output
    assert "reproduced: final" in res.output
