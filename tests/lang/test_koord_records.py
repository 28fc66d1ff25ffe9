"""Koord record types ``def Name:`` (issue 47 item 1, "ADT records";
docs/koord.md, "Records"): a record variable is one PCCL variable per
field (compared with its hand-written PCCL twin, and explored alike), and
every misuse is one message at its place."""

from __future__ import annotations

import pytest

from pccl.api import explore
from pccl.lang.errors import PcclError
from pccl.lang.koord import parse_koord
from pccl.lang.parser import parse_program

RECORDS = """\
def Task:
  int site = -1
  boolean done = false

allwrite:
  Task shared

allread:
  Task job[]

local:
  Task mine
  Task copy

pick:
  pre: mine.site == -1
  eff:
    mine.site = pid
    job[pid].site = pid * 2
    copy = mine

finish:
  pre: mine.site != -1 and not mine.done
  eff:
    mine.done = true
    job[pid].done = job[(pid + 1) % numAgents].site >= 0
    shared.site = pid
    stop

invariant:
  mineDone: forall i: exited[i] -> mine[i].done and copy[i].site == i
  jobSite: forall i: job[i].site == -1 or job[i].site == 2 * i
"""

TWIN = """\
allwrite:
  int shared_site = -1;
  bool shared_done = false;

allread:
  int job_site = -1;
  bool job_done = false;

loc:
  int mine_site = -1;
  bool mine_done = false;
  int copy_site = -1;
  bool copy_done = false;

pick():
  pre(mine_site == -1);
  eff:
    mine_site = getAgentIndex();
    job_site = getAgentIndex() * 2;
    copy_site = mine_site;
    copy_done = mine_done;

finish():
  pre(mine_site != -1 && !mine_done);
  eff:
    mine_done = true;
    job_done = job_site[(getAgentIndex() + 1) % getNumAgents()] >= 0;
    shared_site = getAgentIndex();
    exit();

invariant:
  mineDone: forall i: exited[i] -> mine_done[i] && copy_site[i] == i;
  jobSite: forall i: job_site[i] == -1 || job_site[i] == 2 * i;
"""


def test_records_are_their_fields_the_pccl_twin():
    kp = parse_koord(RECORDS, "rec.koord")
    pp = parse_program(TWIN, "rec.pccl")
    assert kp.decls == pp.decls
    assert kp.events == pp.events
    assert kp.invariants == pp.invariants
    assert kp == pp


@pytest.mark.parametrize("semantics", ["koord", "pccl"])
def test_records_explore_as_the_twin(semantics):
    a = explore(parse_koord(RECORDS, "rec.koord"), semantics=semantics, reduce="none", agents=3)
    twin = parse_koord(RECORDS, "rec.koord") if semantics == "koord" else parse_program(TWIN, "t")
    b = explore(twin, reduce="none", agents=3, **({"semantics": "koord"} if semantics == "koord" else {}))
    assert a.status == b.status == "exhaustive", a.verdict
    assert (a.stats.states, a.stats.transitions) == (b.stats.states, b.stats.transitions)


def test_a_record_invariant_that_fails_is_caught():
    bad = RECORDS.replace("copy = mine\n", "copy = mine\n    copy.site = 7\n")
    r = explore(parse_koord(bad, "rec.koord"))
    assert r.status == "violation" and r.violations[0].name == "mineDone"


@pytest.mark.parametrize("change,where,message", [
    (("    mine.site = pid\n", "    mine.spot = pid\n"), (18, 5), "record 'Task' has no field 'spot'"),
    (("    copy = mine\n", "    copy = 3\n"), (20, 12), "'copy' is a record (Task): assign another Task"),
    (("  pre: mine.site == -1\n", "  pre: mine == -1\n"), (16, 8), "'mine' is a record (Task): read one"),
    (("    job[pid].site = pid * 2\n", "    job[0].site = pid * 2\n"), (19, 9), "'job' is allread"),
    (("  Task mine\n", "  Task mine = 3\n"), (12, 15),
     "a Task variable's initial value is a record literal 'Task(...)'"),
    (("  Task mine\n", "  Task mine = Task(1, false, 3)\n"), (12, 30), "record 'Task' has 2 fields"),
    (("  Task mine\n", "  Task[] mine = 3\n"), (12, 17), "a list of Task records starts as"),
    (("  Task mine\n", "  Task[] mine = [3]\n"), (12, 18), "a Task record is expected here"),
    (("  Task job[]\n", "  Task job\n"), (9, 8), "an allread record is an array indexed by robot"),
    (("  boolean done = false\n", "  boolean done = false\n  Task inner\n"), (4, 3),
     "record 'Task' cannot contain itself"),
    (("def Task:\n", "def Pair:\n  Later a\n\ndef Later:\n  int z = 0\n\ndef Task:\n"), (2, 3),
     "define record type 'Later' before 'Pair'"),
    (("  Task copy\n", "  Task copy\n  int mine_site = 0\n"), (14, 7),
     "'mine_site' is the name pccl gives field 'site'"),
    (("allwrite:\n", "def Task:\n  int x\n\nallwrite:\n"), (5, 5), "record type 'Task' is defined twice"),
])
def test_record_errors_have_their_place(change, where, message):
    text = RECORDS.replace(*change, 1)
    assert text != RECORDS
    with pytest.raises(PcclError) as e:
        parse_koord(text, "bad.koord")
    assert message in str(e.value), str(e.value)
    assert (e.value.line, e.value.column) == where, str(e.value)


def test_a_function_takes_a_record():
    text = "def fun siteOf(Task t):\n  return t.site\n\n" + RECORDS.replace(
        "  pre: mine.site == -1\n", "  pre: siteOf(mine) == -1\n")
    assert parse_koord(text, "f.koord").events == parse_koord(RECORDS, "rec.koord").events


def test_mutated_records_and_paths_never_raise_anything_but_a_message():
    """Truncations, insertions and deletions of a program with records and
    one with Motion.path: a PcclError (file:line:column) or a program,
    never another exception."""
    import random
    from pathlib import Path

    from pccl.lang.checker import check_program
    path = (Path(__file__).resolve().parents[2] / "programs" / "koord" / "follow_path.koord").read_text()
    rng = random.Random(47)
    pieces = [" ", "\n", ":", ".", "[", "]", "=", "Task", "def ", "path", "site", "pid", "  ",
              "Motion.path", "def Task:\n  int a\n", "Task q[]", ".site", "Motion_path"]
    for _ in range(400):
        s = rng.choice([RECORDS, path])
        k = rng.randrange(len(s))
        r = rng.random()
        if r < 0.3:
            s = s[:k]
        elif r < 0.6:
            s = s[:k] + rng.choice(pieces) + s[k:]
        else:
            s = s[:k] + s[min(len(s), k + rng.randint(1, 8)):]
        try:
            check_program(parse_koord(s, "f.koord"))
        except PcclError as e:
            assert e.line is None or e.line >= 1
