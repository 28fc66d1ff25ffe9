"""Koord's ``string`` (issue 47; docs/koord.md, "Strings"): a string is
one of the program's string literals, read into the enum ``string`` whose
members are the literals (quotes included); ``==``/``!=`` compare them,
``+`` of two literals is folded when the program is read, ``stdout <<`` of
a string is a log line.  The program explores exactly as its twin with the
strings replaced by numbers, under both semantics; what is not supported
is an error at its place."""

from __future__ import annotations

import pytest

from pccl.api import explore, run
from pccl.lang import ast
from pccl.lang.errors import PcclError
from pccl.lang.koord import parse_koord

from conftest import cli

LEADER = '''\
allwrite:
  string leader = "none"

local:
  string greeting = "hel" + "lo"
  string[] seen = []
  boolean done = false

claim:
  pre: leader == "none" and not done
  eff:
    leader = "robot " + "one"
    seen.add(greeting)
    stdout << "claimed " << leader
    done = true

finish:
  pre: done and leader != "none"
  eff:
    stop

invariant:
  named: forall i: exited[i] -> leader == "robot one"
'''

#: LEADER with each string a number: "none" 0, "hello" 1, "robot one" 2
NUMBERS = (LEADER.replace('string leader = "none"', "int leader = 0")
           .replace('string greeting = "hel" + "lo"', "int greeting = 1")
           .replace("string[] seen", "int[] seen")
           .replace('leader = "robot " + "one"', "leader = 2")
           .replace('"none"', "0").replace('"robot one"', "2"))


def test_strings_are_an_enum_of_the_literals():
    prog = parse_koord(LEADER, "s.koord")
    enum = prog.decls[0]
    assert isinstance(enum, ast.EnumDecl) and enum.name == "string"
    # folded, in the order first written; the log line's literals are not members
    assert enum.members == ('"none"', '"hello"', '"robot one"')
    decl = {d.name: d for d in prog.decls if isinstance(d, ast.VarDecl)}
    assert decl["leader"].type.name == "string" and decl["leader"].init == ast.Name('"none"')
    assert decl["greeting"].init.name == '"hello"'
    assert decl["seen"].type == ast.TypeRef("List", ast.TypeRef("string"))
    assert "string" not in NUMBERS and '"none"' not in NUMBERS


def test_a_program_without_strings_is_unchanged():
    """A log line's text adds no enum (the shipped programs' ASTs stay
    those of their PCCL twins)."""
    prog = parse_koord("local:\n  int x = 0\ne:\n  pre: x == 0\n  eff:\n"
                       "    stdout << \"x is \" << x\n    x = 1\n")
    assert not any(isinstance(d, ast.EnumDecl) for d in prog.decls)
    only = parse_koord("local:\n  string s\ne:\n  pre: true\n  eff:\n    stop\n")
    assert only.decls[0].members == ('""',)


@pytest.mark.parametrize("semantics", ["koord", "pccl"])
def test_strings_explore_as_their_twin_with_numbers(semantics):
    a = explore(parse_koord(LEADER, "s.koord"), semantics=semantics, reduce="none",
                engine="python", stall=False)
    b = explore(parse_koord(NUMBERS, "n.koord"), semantics=semantics, reduce="none",
                engine="python", stall=False)
    assert a.status == b.status == "exhaustive", (a.verdict, b.verdict)
    assert (a.stats.states, a.stats.transitions) == (b.stats.states, b.stats.transitions)
    # the default (reduced; native engine under PCCL's semantics) agrees on the verdict
    c = explore(parse_koord(LEADER, "s.koord"), semantics=semantics, stall=False)
    assert c.status == "exhaustive"


def test_a_wrong_string_is_caught_and_shown_quoted():
    bad = LEADER.replace('leader = "robot " + "one"', 'leader = "robot " + "two"')
    r = explore(parse_koord(bad, "s.koord"), stall=False)
    assert r.status == "violation" and r.violations[0].name == "named"
    assert r.violations[0].state.shared["leader"] == '"robot two"'
    k = run(parse_koord(LEADER, "s.koord"), seed=3)
    assert k.final_state.shared["leader"] == '"robot one"'
    assert [a.variables["seen"] for a in k.final_state.agents] == [['"hello"']] * 2 or \
        [a.variables["seen"] for a in k.final_state.agents] == [('"hello"',)] * 2


def test_a_string_trace_replays(tmp_path):
    p = tmp_path / "s.koord"
    p.write_text(LEADER)
    t = tmp_path / "t.json"
    r = cli("explore", p, "--no-stall", "--invariant", "count(done) < 2", "--trace-out", t)
    assert r.exit_code == 1 and 'leader "none" -> "robot one"' in r.output, r.output
    r = cli("replay", t)
    assert r.exit_code == 1 and "reproduced" in r.output, r.output


@pytest.mark.parametrize("stmt, message, col", [
    ('greeting = greeting + "x"', "'+' joins strings only when both are known", 16),
    ('greeting = "a" + seen[0]', "'+' joins strings only when both are known", 16),
    ('done = "a" + 1 == 2', "'+' joins strings only when both are known", 12),
    ('done = greeting < "b"', "operands of '<' must be numbers, got string", 12),
    ('done = 1 == "b"', "cannot compare int with string using '=='", 12),
    ('greeting = 3', "cannot assign int to 'greeting' of type string", 16),
    ('done = "unterminated', "unexpected character '\"'", 12),
])
def test_what_strings_do_not_support_is_an_error_at_its_place(tmp_path, stmt, message, col):
    src = LEADER.replace("    done = true\n", f"    {stmt}\n")
    p = tmp_path / "bad.koord"
    p.write_text(src)
    r = cli("check", p)
    assert r.exit_code == 2, r.output
    assert f"{p}:15:{col}: error: {message}" in r.output and "^" in r.output, r.output
    with pytest.raises(PcclError):
        parse_koord(src, "bad.koord") if "'+'" in message or "unexpected" in message else \
            explore(parse_koord(src, "bad.koord"))


def test_the_other_unsupported_types_are_still_refused():
    for t in ("queue", "map", "stream"):
        with pytest.raises(PcclError, match=f"type '{t}' is not supported yet"):
            parse_koord(f"local:\n  {t} q\n")
    with pytest.raises(PcclError, match="'string' is a type already"):
        parse_koord("def string:\n  int x = 0\n")
