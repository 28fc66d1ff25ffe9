"""Koord's list and record constructs beyond one record per variable
(issue 47, docs/koord.md "Not supported yet" closed): records inside
records, arrays and lists of records, record literals, ``for x in xs:``
over a list (a plain value or a record) and ``any``/``all`` over a list of
booleans.  Each is read into PCCL the checked program already has: the
program below and its hand-written PCCL twin parse to equal ASTs, and every
misuse is one message at its place."""

from __future__ import annotations

import random
from pathlib import Path

import pytest

from pccl.lang.checker import check_program
from pccl.lang.errors import PcclError
from pccl.lang.koord import parse_koord
from pccl.lang.parser import parse_program

PROGRAMS = Path(__file__).resolve().parents[1] / "programs"
#: the program (tests/programs/koord_lists.koord) and its hand-written twin
LISTS = (PROGRAMS / "koord_lists.koord").read_text()
TWIN = (PROGRAMS / "koord_lists_twin.pccl").read_text()


def test_lists_and_nested_records_are_the_pccl_twin():
    kp = parse_koord(LISTS, "lists.koord")
    pp = parse_program(TWIN, "lists.pccl")
    assert kp.decls == pp.decls
    assert kp.events == pp.events
    assert kp.invariants == pp.invariants
    assert kp == pp
    assert kp.n_statements == pp.n_statements
    check_program(kp)


def test_record_functions_take_elements_and_literals():
    """A function over a record is inlined with an element of a list of
    records or a literal as its argument."""
    text = "def fun xOf(Task r):\n  return r.at.x\n\n" + LISTS.replace(
        "    mine.at.x = 5\n", "    mine.at.x = xOf(Task(Pt(5, 0))) + xOf(todo[0]) - 3\n")
    kp = parse_koord(text, "f.koord")
    assert kp.events[0].body[0].value == parse_program(
        TWIN.replace("    mine_at_x = 5;\n", "    mine_at_x = 5 + todo_at_x[0] - 3;\n"),
        "t.pccl").events[0].body[0].value


def test_any_all_over_an_allread_list_and_a_literal():
    text = ("allread:\n  boolean[] votes[]\nlocal:\n  boolean ok = false\n"
            "ev:\n  pre: any(votes[(pid + 1) % numAgents]) or all([true, ok])\n"
            "  eff:\n    stop\n")
    twin = ("allread:\n  List<bool> votes;\nloc:\n  bool ok = false;\n"
            "ev():\n  pre(contains(votes[(getAgentIndex() + 1) % getNumAgents()], true) || "
            "!contains([true, ok], false));\n  eff:\n    exit();\n")
    assert parse_koord(text, "a.koord").events == parse_program(twin, "a.pccl").events


@pytest.mark.parametrize("change,where,message", [
    (("    for t in todo:\n", "    for t in nums:\n"), (31, 14), "'t' is a Task record: it walks a list"),
    (("    todo.add(Task(Pt(pid, 0), true))\n", "    todo.remove(mine)\n"), (28, 5),
     "'remove' on a list of records is not supported"),
    (("    todo.add(Task(Pt(pid, 0), true))\n", "    todo.add(3)\n"), (28, 14),
     "a Task record is expected here"),
    (("  pre: not mine.done", "  pre: todo.contains(mine)"), (23, 8),
     "'contains' on a list of records is not supported"),
    (("    jobs[1] = mine\n", "    jobs[1] = mine.at\n"), (26, 15), "assign another Task"),
    (("    mine.at.x = 5\n", "    mine.at = 5\n"), (25, 15), "assign another Pt"),
    (("    mine.at.x = 5\n", "    mine.at.z = 5\n"), (25, 5), "record 'Pt' has no field 'z'"),
    (("    mine.at.x = 5\n", "    v = mine.at\n"), (25, 9), "this is a record (Pt): read one of its fields (x, y)"),
    (("  Task mine = Task(Pt(1, 2))\n", "  Task mine = Task(3)\n"), (13, 20), "a Pt record is expected"),
    (("  Task mine = Task(Pt(1, 2))\n", "  Task mine = Task(Pt(1, 2), Pt(0, 0))\n"), (13, 30),
     "field 'done' of 'Task' is not a record"),
    (("  Pt at\n", "  Pt at = Pt(1, 1)\n"), (6, 11), "a record field takes its initial values"),
    (("  int[] nums = [1, 2, 3]\n", "  int[] nums = [1, 2, 3]\n  int job_at_x = 0\n"), (21, 7),
     "'job_at_x' is the name pccl gives field 'at.x' of record variable 'job'"),
    (("    job[pid].at = mine.at\n", "    job[1].at = mine.at\n"), (27, 9),
     "'job' is allread: a robot writes only its own entry, 'job[pid].at.x = ...'"),
])
def test_list_and_record_errors_have_their_place(change, where, message):
    text = LISTS.replace(*change, 1)
    assert text != LISTS
    with pytest.raises(PcclError) as e:
        parse_koord(text, "bad.koord")
    assert message in str(e.value), str(e.value)
    assert (e.value.line, e.value.column) == where, str(e.value)


def test_a_literal_without_a_field_that_has_no_initialiser():
    text = ("def Pt:\n  int x = 0\n  int y\n\nlocal:\n  Pt p = Pt(1)\n")
    with pytest.raises(PcclError) as e:
        parse_koord(text, "bad.koord")
    assert "'Pt(...)' gives no value to field 'y', which has no initialiser" in str(e.value)
    assert (e.value.line, e.value.column) == (6, 10)
    assert parse_koord(text.replace("Pt(1)", "Pt(1, 2)"), "ok.koord").decls == parse_program(
        "loc:\n  int p_x = 1;\n  int p_y = 2;\n", "ok.pccl").decls


def test_mutated_list_programs_never_raise_anything_but_a_message():
    """Truncations, insertions and deletions: a PcclError or a program."""
    rng = random.Random(4747)
    pieces = [" ", "\n", ":", ".", "[", "]", "(", ")", "=", "Task", "Pt(", "for ", " in ", "todo",
              "any(", "all(", ".at", "[]", "  ", "for t in todo:\n", "Task(Pt(1, 2))"]
    for _ in range(300):
        s = LISTS
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


def test_a_function_loop_over_its_parameter_or_an_argument_it_assigns_is_an_error():
    """The variable of `for x in xs:` counts as assigned by a function
    (inlining would otherwise put the argument where the variable is)."""
    text = ("def fun tot(int v):\n  for v in [1, 2]:\n    s = s + v\n\nlocal:\n  int s = 0\n"
            "  int w = 0\n\nev:\n  pre: s == 0\n  eff:\n    tot(1)\n    stop\n")
    with pytest.raises(PcclError) as e:
        parse_koord(text, "f.koord")
    assert "'tot' assigns its parameter 'v'" in str(e.value) and (e.value.line, e.value.column) == (1, 17)
    text = text.replace("for v in", "for w in").replace("s + v", "s + w").replace("tot(1)", "tot(w)")
    with pytest.raises(PcclError) as e:
        parse_koord(text, "f.koord")
    assert "this argument reads 'w', which 'tot' assigns" in str(e.value)
    assert (e.value.line, e.value.column) == (12, 9)
