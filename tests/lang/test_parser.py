"""Tests for pccl.lang.parser: every surface construct, spans, sids, properties,
error messages (golden text) and robustness on truncated/mutated input."""

from __future__ import annotations

import random
from pathlib import Path

import pytest

from pccl.lang import ast
from pccl.lang.ast import (Assign, Atomic, Binary, BoolLit, Call, CallStmt, EnumDecl, Field, FloatLit, If, Index,
                           IntLit, ListLit, Name, Quant, Skip, Span, TypeRef, Unary, VarDecl, While, walk_stmts)
from pccl.lang.errors import PcclError
from pccl.lang.parser import parse_file, parse_program, parse_property

ROOT = Path(__file__).resolve().parents[2]
PROGRAMS = ROOT / "programs"


# --------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------

def event_program(body: str, pre: str = "true") -> str:
    """A one-event program whose eff block is ``body`` (indented 4)."""
    lines = "".join("    " + l + "\n" for l in body.strip("\n").split("\n"))
    return f"E():\n  pre({pre});\n  eff:\n{lines}"


def stmts(body: str):
    return parse_program(event_program(body)).events[0].body


def stmt(body: str):
    (s,) = stmts(body)
    return s


def expr(text: str):
    """Parse an ordinary expression through an assignment."""
    s = stmt(f"x = {text};")
    assert isinstance(s, Assign)
    return s.value


def prop(text: str):
    return parse_property(text)


def decls(text: str):
    return parse_program(text).decls


def error(source: str, filename: str = "t.pccl") -> str:
    with pytest.raises(PcclError) as info:
        parse_program(source, filename)
    return info.value.render()


def N(n):
    return Name(n)


# --------------------------------------------------------------------------
# header and sections
# --------------------------------------------------------------------------

def test_empty_program():
    p = parse_program("")
    assert p == ast.Program(None, (), (), (), ())
    assert p.n_statements == 0


def test_comment_only_program():
    p = parse_program("// nothing\n/* at\n all */\n")
    assert p.decls == () and p.events == ()


def test_header():
    assert parse_program("Agent::Fischer\n").name == "Fischer"
    assert parse_program("Agent :: Race // comment\n").name == "Race"
    assert parse_program("loc:\n  int x;\n").name is None


@pytest.mark.parametrize("header,section", [
    ("allwrite:", "allwrite"), ("MW:", "allwrite"), ("mw:", "allwrite"),
    ("allread:", "allread"), ("SW:", "allread"),
    ("loc:", "loc"), ("local:", "loc"), ("Loc:", "loc"),
])
def test_section_aliases(header, section):
    (d,) = decls(f"{header}\n  int x = 1;\n")
    assert d == VarDecl(section, TypeRef("int"), "x", None, IntLit(1))


def test_sections_in_order_and_filename():
    src = ("allwrite:\n  int a;\nallread:\n  int b;\nloc:\n  int c;\n"
           "Init:\n  c = 1;\nE():\n  pre(true);\n  eff:\n    skip;\n"
           "invariant:\n  c >= 0;\n")
    p = parse_program(src, "f.pccl")
    assert [(d.section, d.name) for d in p.decls] == [
        ("allwrite", "a"), ("allread", "b"), ("loc", "c")]
    assert p.init == (Assign(0, N("c"), IntLit(1)),)
    assert [e.name for e in p.events] == ["E"]
    assert len(p.invariants) == 1
    assert p.filename == "f.pccl" and p.source == src and p.n_statements == 2


def test_empty_sections():
    p = parse_program("allwrite:\nallread:\nloc:\nInit:\ninvariant:\n")
    assert p.decls == () and p.init == () and p.invariants == ()


def test_empty_sections_between_full_ones():
    p = parse_program("allwrite:\n  int a;\nallread:\n\nloc:\n  int c;\nInit:\n\n"
                      "E():\n  pre(true);\n  eff:\n    skip\n")
    assert [d.name for d in p.decls] == ["a", "c"]


@pytest.mark.parametrize("kw", ["Init:", "init:"])
def test_init_aliases(kw):
    p = parse_program(f"{kw}\n  doReach(getPosition(), obs);\n")
    assert p.init == (CallStmt(0, "doReach", (Call("getPosition", ()), N("obs"))),)


def test_sections_out_of_order_rejected():
    with pytest.raises(PcclError):
        parse_program("loc:\n  int x;\nallwrite:\n  int y;\n")


# --------------------------------------------------------------------------
# declarations and types
# --------------------------------------------------------------------------

@pytest.mark.parametrize("written,normal", [
    ("int", TypeRef("int")), ("bool", TypeRef("bool")), ("boolean", TypeRef("bool")),
    ("float", TypeRef("float")), ("double", TypeRef("float")),
    ("ItemPosition", TypeRef("ItemPosition")), ("ObstacleList", TypeRef("ObstacleList")),
    ("Stage", TypeRef("Stage")),
    ("List<int>", TypeRef("List", TypeRef("int"))),
    ("List<ItemPosition>", TypeRef("List", TypeRef("ItemPosition"))),
    ("List<List<boolean>>", TypeRef("List", TypeRef("List", TypeRef("bool")))),
])
def test_types(written, normal):
    (d,) = decls(f"loc:\n  {written} v;\n")
    assert d.type == normal
    assert str(d.type) == str(normal)


def test_declaration_forms():
    ds = decls("loc:\n  int a;\n  int b = 2;\n  int c[3];\n  int d[N + 1] = 0;\n"
               "  List<int> e = [];\n")
    assert ds == (
        VarDecl("loc", TypeRef("int"), "a", None, None),
        VarDecl("loc", TypeRef("int"), "b", None, IntLit(2)),
        VarDecl("loc", TypeRef("int"), "c", IntLit(3), None),
        VarDecl("loc", TypeRef("int"), "d", Binary("+", N("N"), IntLit(1)), IntLit(0)),
        VarDecl("loc", TypeRef("List", TypeRef("int")), "e", None, ListLit(())),
    )


def test_declarations_share_a_line_and_semicolon_optional():
    ds = decls("loc:\n  int a = 1; int b = 2\n  bool c\n")
    assert [d.name for d in ds] == ["a", "b", "c"]


@pytest.mark.parametrize("header,section", [
    ("allwrite:", "allwrite"), ("allread:", "allread"), ("loc:", "loc")])
def test_enum_in_any_section(header, section):
    ds = decls(f"{header}\n  enum Stage {{ PICK, GO, DONE }};\n  Stage s = PICK;\n")
    assert ds[0] == EnumDecl(section, "Stage", ("PICK", "GO", "DONE"))
    assert ds[1] == VarDecl(section, TypeRef("Stage"), "s", None, N("PICK"))


def test_enum_over_several_lines_trailing_comma_no_semicolon():
    ds = decls("loc:\n  enum S {\n    A,\n  B,\n      }\n  int x;\n")
    assert ds[0] == EnumDecl("loc", "S", ("A", "B"))
    assert ds[1].name == "x"


def test_list_without_element_type_rejected():
    assert error("loc:\n  List xs;\n") == (
        "t.pccl:2:3: error: 'List' needs an element type, e.g. 'List<int>'\n"
        "    2 |   List xs;\n"
        "      |   ^^^^")


def test_type_argument_on_non_list_rejected():
    with pytest.raises(PcclError, match="only 'List' takes a type argument"):
        parse_program("loc:\n  int<bool> x;\n")


def test_duplicate_enum_member_rejected():
    with pytest.raises(PcclError, match="duplicate member 'A'"):
        parse_program("loc:\n  enum S { A, B, A };\n")


# --------------------------------------------------------------------------
# events
# --------------------------------------------------------------------------

def test_event():
    p = parse_program("Start():\n  pre(start && reqid == -1);\n  eff:\n"
                      "    start = false;\n")
    (ev,) = p.events
    assert ev.name == "Start"
    assert ev.guard == Binary("&&", N("start"),
                              Binary("==", N("reqid"), Unary("-", IntLit(1))))
    assert ev.body == (Assign(0, N("start"), BoolLit(False)),)


@pytest.mark.parametrize("pre,eff", [("pre", "eff"), ("Pre", "Eff"), ("Pre", "eff")])
def test_pre_eff_case(pre, eff):
    p = parse_program(f"E():\n  {pre}(x);\n  {eff}:\n    skip\n")
    assert p.events[0].guard == N("x")
    assert p.events[0].body == (Skip(0),)


def test_empty_eff_block():
    p = parse_program("A():\n  pre(true);\n  eff:\nB():\n  pre(false);\n  eff:\n")
    assert [(e.name, e.body) for e in p.events] == [("A", ()), ("B", ())]


def test_pre_and_eff_on_one_line():
    p = parse_program("E():\n  pre(x); eff:\n    y = 1\n")
    assert p.events[0].body == (Assign(0, N("y"), IntLit(1)),)


def test_eff_statements_on_its_line():
    p = parse_program("E():\n  pre(x);\n  eff: y = 1; z = 2\n")
    assert [s.sid for s in p.events[0].body] == [0, 1]


# --------------------------------------------------------------------------
# statements
# --------------------------------------------------------------------------

def test_assignments():
    assert stmt("x = 1") == Assign(0, N("x"), IntLit(1))
    assert stmt("x[i] = 1") == Assign(0, Index(N("x"), N("i")), IntLit(1))
    assert stmt("x[i][j + 1] = y") == Assign(
        0, Index(Index(N("x"), N("i")), Binary("+", N("j"), IntLit(1))), N("y"))


@pytest.mark.parametrize("text,name,args", [
    ("doReach(t, o)", "doReach", (N("t"), N("o"))),
    ("exit()", "exit", ()),
    ("assert(x > 0)", "assert", (Binary(">", N("x"), IntLit(0)),)),
    ("add(xs, v)", "add", (N("xs"), N("v"))),
    ("remove(xs, head(xs))", "remove", (N("xs"), Call("head", (N("xs"),)))),
    ("frobnicate(1)", "frobnicate", (IntLit(1),)),
])
def test_call_statements(text, name, args):
    assert stmt(text + ";") == CallStmt(0, name, args)


def test_skip():
    assert stmt("skip;") == Skip(0)
    assert stmt("skip") == Skip(0)


def test_if_only():
    s = stmt("if (c):\n  x = 1")
    assert s == If(0, ((N("c"), (Assign(1, N("x"), IntLit(1)),)),), ())


def test_if_else():
    s = stmt("if (c):\n  x = 1\nelse:\n  x = 2")
    assert s == If(0, ((N("c"), (Assign(1, N("x"), IntLit(1)),)),),
                   (Assign(2, N("x"), IntLit(2)),))


def test_if_else_if_chain_is_one_statement():
    s = stmt("if (a):\n  x = 1\nelse if (b):\n  x = 2\nelse if (c):\n  x = 3\n"
             "  y = 3\nelse:\n  x = 4")
    assert isinstance(s, If)
    assert [c for c, _ in s.branches] == [N("a"), N("b"), N("c")]
    assert [[t.sid for t in b] for _, b in s.branches] == [[1], [2], [3, 4]]
    assert [t.sid for t in s.orelse] == [5]


def test_else_if_without_else():
    s = stmt("if (a):\n  x = 1\nelse if (b):\n  x = 2")
    assert len(s.branches) == 2 and s.orelse == ()


def test_while():
    s = stmt("while (i < n):\n  i = i + 1")
    assert s == While(0, Binary("<", N("i"), N("n")),
                      (Assign(1, N("i"), Binary("+", N("i"), IntLit(1))),))


@pytest.mark.parametrize("kw", ["atomic", "Atomic"])
def test_atomic(kw):
    s = stmt(f"{kw}:\n  reqid = id;")
    assert s == Atomic(0, (Assign(1, N("reqid"), N("id")),))


def test_nested_blocks():
    (s, after) = stmts("if (a):\n  while (b):\n    atomic:\n      if (c):\n        x = 1\n"
                       "      else:\n        skip\n    y = 2\nz = 3")
    assert isinstance(s, If)
    (w,) = s.branches[0][1]
    assert isinstance(w, While)
    at, y = w.body
    assert isinstance(at, Atomic) and y == Assign(6, N("y"), IntLit(2))
    (inner,) = at.body
    assert isinstance(inner, If) and inner.orelse == (Skip(5),)
    assert after == Assign(7, N("z"), IntLit(3))


def test_one_line_blocks():
    s = stmt("if (a): x = 1; y = 2\nelse: skip")
    assert [t.sid for t in s.branches[0][1]] == [1, 2]
    assert s.orelse == (Skip(3),)


def test_condition_without_parentheses():
    assert stmt("if a > 0:\n  skip").branches[0][0] == Binary(">", N("a"), IntLit(0))
    assert stmt("while a:\n  skip").cond == N("a")


def test_optional_semicolons_and_multi_statement_lines():
    ss = stmts("c1 = 0; wait = false;\nx = 1\ny = 2;\nz = 3; w = 4")
    assert [(s.target.name, s.sid) for s in ss] == [
        ("c1", 0), ("wait", 1), ("x", 2), ("y", 3), ("z", 4), ("w", 5)]


def test_newline_inside_parentheses_brackets_braces():
    s = stmt("if (contains(\n  dests, currentDest)):\n  x = [1,\n2,\n         3]")
    assert s.branches[0][0] == Call("contains", (N("dests"), N("currentDest")))
    assert s.branches[0][1][0].value == ListLit((IntLit(1), IntLit(2), IntLit(3)))
    s = stmt("doReach(\n    target,\n obs\n)")
    assert s == CallStmt(0, "doReach", (N("target"), N("obs")))


# --------------------------------------------------------------------------
# comments, blank lines, indentation
# --------------------------------------------------------------------------

def test_line_comments():
    p = parse_program("// top\nloc: // section\n  int x = 1; // decl\n"
                      "        // deeper comment-only line\n// column 0 comment\n"
                      "  int y;\n// last, no newline")
    assert [d.name for d in p.decls] == ["x", "y"]


def test_block_comments():
    p = parse_program("/* a\n   b */\nloc:\n  int /* inline */ x = /* c */ 1;\n"
                      "  /* a block comment\n     over lines */\n"
                      "      /* odd indentation */\n  int y;\n"
                      "  int z; /* spans\n lines */ int w;\n")
    assert [d.name for d in p.decls] == ["x", "y", "z", "w"]
    assert p.decls[0].init == IntLit(1)


def test_comment_markers_in_comments():
    p = parse_program("loc:\n  int x; // not /* a block\n  /* // nor a line */ int y;\n")
    assert [d.name for d in p.decls] == ["x", "y"]


def test_blank_lines_with_spaces_inside_blocks():
    ss = stmts("if (a):\n  x = 1\n\n         \n  y = 2")
    assert [t.sid for t in ss[0].branches[0][1]] == [1, 2]


def test_tabs_and_crlf():
    src = "E():\r\n\tpre(x);\r\n\teff:\r\n\t\tif (x):\r\n\t\t\ty = 1\r\n\t\tz = 2\r\n"
    p = parse_program(src)
    s, z = p.events[0].body
    assert isinstance(s, If) and z == Assign(2, N("z"), IntLit(2))
    assert p.source == src


def test_no_trailing_newline():
    p = parse_program("E():\n  pre(x);\n  eff:\n    y = 1")
    assert p.events[0].body == (Assign(0, N("y"), IntLit(1)),)


# --------------------------------------------------------------------------
# expressions
# --------------------------------------------------------------------------

def test_literals():
    assert expr("42") == IntLit(42)
    assert expr("true") == BoolLit(True) and expr("false") == BoolLit(False)
    assert expr("[]") == ListLit(())
    assert expr("[a, 1]") == ListLit((N("a"), IntLit(1)))
    assert expr("[[1], []]") == ListLit((ListLit((IntLit(1),)), ListLit(())))


@pytest.mark.parametrize("text,value", [
    ("1.5", 1.5), ("2.", 2.0), (".5", 0.5), ("1e3", 1000.0), ("2.5E-1", 0.25),
    ("1.e2", 100.0), (".5e+1", 5.0), ("0.0", 0.0)])
def test_float_forms(text, value):
    e = expr(text)
    assert isinstance(e, FloatLit) and e.value == value


def test_calls():
    assert expr("ItemPosition(1, 2)") == Call("ItemPosition", (IntLit(1), IntLit(2)))
    assert expr("getAgentIndex()") == Call("getAgentIndex", ())
    assert expr("f(g(x), [y])") == Call("f", (Call("g", (N("x"),)), ListLit((N("y"),))))


def test_postfix_chains():
    assert expr("a[i].x") == Field(Index(N("a"), N("i")), "x")
    assert expr("a[i][j]") == Index(Index(N("a"), N("i")), N("j"))
    assert expr("head(xs).y") == Field(Call("head", (N("xs"),)), "y")
    assert expr("p.x.y") == Field(Field(N("p"), "x"), "y")
    assert expr("f(x)[0]") == Index(Call("f", (N("x"),)), IntLit(0))


@pytest.mark.parametrize("text,tree", [
    # loosest to tightest
    ("a || b && c", Binary("||", N("a"), Binary("&&", N("b"), N("c")))),
    ("a && b || c", Binary("||", Binary("&&", N("a"), N("b")), N("c"))),
    ("!a && b", Binary("&&", Unary("!", N("a")), N("b"))),
    ("!a == b", Unary("!", Binary("==", N("a"), N("b")))),
    ("!a < b + 1", Unary("!", Binary("<", N("a"), Binary("+", N("b"), IntLit(1))))),
    ("a == b && c != d", Binary("&&", Binary("==", N("a"), N("b")),
                                Binary("!=", N("c"), N("d")))),
    ("a + b < c * d", Binary("<", Binary("+", N("a"), N("b")),
                             Binary("*", N("c"), N("d")))),
    ("a + b * c", Binary("+", N("a"), Binary("*", N("b"), N("c")))),
    ("a * b + c", Binary("+", Binary("*", N("a"), N("b")), N("c"))),
    ("(a + b) * c", Binary("*", Binary("+", N("a"), N("b")), N("c"))),
    ("-a * b", Binary("*", Unary("-", N("a")), N("b"))),
    ("a * -b", Binary("*", N("a"), Unary("-", N("b")))),
    ("-a.x", Unary("-", Field(N("a"), "x"))),
    ("- -a", Unary("-", Unary("-", N("a")))),
    ("!!a", Unary("!", Unary("!", N("a")))),
    ("a - -1", Binary("-", N("a"), Unary("-", IntLit(1)))),
    ("!(a || b)", Unary("!", Binary("||", N("a"), N("b")))),
])
def test_precedence(text, tree):
    assert expr(text) == tree


@pytest.mark.parametrize("op", ["||", "&&", "+", "-", "*", "/", "%"])
def test_left_associative(op):
    assert expr(f"a {op} b {op} c") == Binary(op, Binary(op, N("a"), N("b")), N("c"))


def test_mixed_same_level_left_associative():
    assert expr("a - b + c") == Binary("+", Binary("-", N("a"), N("b")), N("c"))
    assert expr("a / b * c % d") == Binary(
        "%", Binary("*", Binary("/", N("a"), N("b")), N("c")), N("d"))


@pytest.mark.parametrize("op", ["==", "!=", "<", "<=", ">", ">="])
def test_comparisons(op):
    assert expr(f"a {op} b") == Binary(op, N("a"), N("b"))


def test_comparisons_do_not_chain():
    assert error(event_program("x = a < b < c;")) == (
        "t.pccl:4:15: error: unexpected '<': comparisons cannot be chained (use '&&')\n"
        "    4 |     x = a < b < c;\n"
        "      |               ^")


# --------------------------------------------------------------------------
# properties and invariants
# --------------------------------------------------------------------------

def test_property_plain():
    assert prop("count(inCs) <= 1") == Binary("<=", Call("count", (N("inCs"),)), IntLit(1))
    assert prop("time < 10 && N == 2;") == Binary(
        "&&", Binary("<", N("time"), IntLit(10)), Binary("==", N("N"), IntLit(2)))


def test_property_implication_loosest_and_right_assoc():
    assert prop("a || b -> c && d") == Binary(
        "->", Binary("||", N("a"), N("b")), Binary("&&", N("c"), N("d")))
    assert prop("a -> b -> c") == Binary("->", N("a"), Binary("->", N("b"), N("c")))


def test_property_quantifiers():
    assert prop("forall i: pos[i].x >= 0") == Quant(
        "forall", "i", Binary(">=", Field(Index(N("pos"), N("i")), "x"), IntLit(0)))
    assert prop("exists j: v[j]") == Quant("exists", "j", Index(N("v"), N("j")))


def test_quantifier_body_extends_right():
    assert prop("forall i: a[i] -> b || c") == Quant(
        "forall", "i", Binary("->", Index(N("a"), N("i")), Binary("||", N("b"), N("c"))))
    assert prop("forall i: exists j: x[i] != x[j]") == Quant(
        "forall", "i", Quant("exists", "j", Binary("!=", Index(N("x"), N("i")),
                                                  Index(N("x"), N("j")))))
    assert prop("a -> forall i: b[i]") == Binary(
        "->", N("a"), Quant("forall", "i", Index(N("b"), N("i"))))
    assert prop("(forall i: a[i]) && b") == Binary(
        "&&", Quant("forall", "i", Index(N("a"), N("i"))), N("b"))


def test_property_over_several_lines():
    assert prop("forall i:\n    inCs[i]\n  -> c1[i] == 0") == Quant(
        "forall", "i", Binary("->", Index(N("inCs"), N("i")),
                              Binary("==", Index(N("c1"), N("i")), IntLit(0))))


def test_property_spans():
    e = prop("x ->\n  forall i: y[i]")
    assert e.span == Span(1, 1, 2, 17)
    assert e.right.span == Span(2, 3, 2, 17)
    assert e.right.body.span == Span(2, 13, 2, 17)


def test_property_errors():
    with pytest.raises(PcclError) as info:
        parse_property("a && forall i: b", "--invariant")
    assert info.value.render() == (
        "--invariant:1:6: error: unexpected 'forall': a quantifier inside an "
        "expression must be parenthesised, e.g. '(forall i: ...)'\n"
        "    1 | a && forall i: b\n"
        "      |      ^^^^^^")
    with pytest.raises(PcclError) as info:
        parse_property("count(inCs) <=")
    assert info.value.render() == (
        "<property>:1:15: error: unexpected end of input: expected an expression\n"
        "    1 | count(inCs) <=\n"
        "      |               ^")
    with pytest.raises(PcclError, match="expected an expression"):
        parse_property("")


def test_invariant_section():
    p = parse_program("invariant:\n  mutex: count(inCs) <= 1;\n  forall i: c[i] >= 0\n"
                      "  a: x; b: y\n")
    assert [(i.name, type(i.expr).__name__) for i in p.invariants] == [
        ("mutex", "Binary"), (None, "Quant"), ("a", "Name"), ("b", "Name")]
    assert p.invariants[0].span == Span(2, 3, 2, 26)


def test_property_syntax_rejected_in_programs():
    assert error(event_program("x = a -> b;")) == (
        "t.pccl:4:9: error: '->' is only allowed in properties and invariants\n"
        "    4 |     x = a -> b;\n"
        "      |         ^^^^^^")
    with pytest.raises(PcclError, match="'forall' is only allowed in properties"):
        parse_program(event_program("x = 1;", pre="(forall i: y[i])"))
    with pytest.raises(PcclError, match="'exists' is only allowed"):
        parse_program("loc:\n  bool b = (exists i: y[i]);\n")


# --------------------------------------------------------------------------
# spans and sids
# --------------------------------------------------------------------------

def test_spans():
    src = ("loc:\n  int waitTime = rand(k);\n"
           "Start():\n  pre(reqid != -1);\n  eff:\n    if (c1 < waitTime):\n"
           "      c1 = c1 + 1;\n    else:\n      a[i].x = 0\n")
    with pytest.raises(PcclError):  # field targets are not assignable
        parse_program(src)
    src = src.replace("a[i].x = 0", "a[i] = p.x")
    p = parse_program(src)
    (d,) = p.decls
    assert d.span == Span(2, 3, 2, 25)
    assert d.type.span == Span(2, 3, 2, 6)
    assert d.init.span == Span(2, 18, 2, 25)
    (ev,) = p.events
    assert ev.span == Span(3, 1, 9, 17)
    assert ev.guard.span == Span(4, 7, 4, 18)
    assert ev.guard.right.span == Span(4, 16, 4, 18)
    (s,) = ev.body
    assert s.span == Span(6, 5, 9, 17)
    cond, body = s.branches[0]
    assert cond.span == Span(6, 9, 6, 22)
    assert body[0].span == Span(7, 7, 7, 18)          # without the ';'
    assert body[0].value.left.span == Span(7, 12, 7, 14)
    (els,) = s.orelse
    assert els.target.span == Span(9, 7, 9, 11)
    assert els.value.span == Span(9, 14, 9, 17)


def test_span_of_parenthesised_expression_includes_parentheses():
    e = expr("(a + b) * c")
    assert e.span == Span(4, 9, 4, 20)
    assert e.left.span == Span(4, 10, 4, 15)


def test_sids_unique_and_in_source_order():
    p = parse_program((PROGRAMS / "fischer.pccl").read_text())
    order = [s for ev in p.events for s in walk_stmts(ev.body)]
    assert [s.sid for s in order] == list(range(p.n_statements))
    lines = [(s.span.line, s.span.column) for s in order]
    assert lines == sorted(lines)


def test_sids_span_init_and_events():
    p = parse_program("Init:\n  a = 1\n  if (a):\n    b = 2\nE():\n  pre(x);\n  eff:\n"
                      "    c = 3; d = 4\n")
    sids = [s.sid for s in walk_stmts(p.init)] + [s.sid for s in walk_stmts(p.events[0].body)]
    assert sids == [0, 1, 2, 3, 4]
    assert p.n_statements == 5


def test_equal_statements_differ_by_sid():
    a, b = stmts("x = 1\nx = 1")
    assert a != b and (a.target, a.value) == (b.target, b.value)


# --------------------------------------------------------------------------
# shipped programs
# --------------------------------------------------------------------------

def test_fischer():
    p = parse_file(PROGRAMS / "fischer.pccl")
    assert p.name == "Fischer"
    assert p.filename == str(PROGRAMS / "fischer.pccl")
    assert [(d.section, d.name) for d in p.decls] == (
        [("allwrite", n) for n in ["reqid", "k", "d"]]
        + [("loc", n) for n in ["id", "waitTime", "start", "assign", "delay", "wait",
                                "inCs", "c1", "c2", "cstime", "c3"]])
    assert p.decls[0].init == Unary("-", IntLit(1))
    assert p.decls[4].init == Call("rand", (N("k"),))
    assert [e.name for e in p.events] == ["Start", "Wait", "Assign", "Delay", "InCs"]
    assert p.init == () and p.invariants == ()
    assign = p.events[2]
    assert assign.guard == N("assign")
    assert isinstance(assign.body[0], Atomic)
    delay = p.events[3].body[0]
    assert isinstance(delay, If) and isinstance(delay.orelse[-1], If)
    assert p.n_statements == 28


@pytest.mark.parametrize("name,title", [("race", "Race"), ("race_nonatomic", "RaceNonAtomic")])
def test_race_programs(name, title):
    p = parse_file(PROGRAMS / f"{name}.pccl")
    assert p.name == title
    assert p.decls == (
        VarDecl("allwrite", TypeRef("List", TypeRef("ItemPosition")), "dests", None,
                Call("getInput", ())),
        VarDecl("loc", TypeRef("ObstacleList"), "obs", None, Call("getObs", ())),
        VarDecl("loc", TypeRef("bool"), "Pick", None, BoolLit(True)),
        VarDecl("loc", TypeRef("ItemPosition"), "currentDest", None, None),
    )
    pick, remove = p.events
    assert (pick.name, remove.name) == ("PickDest", "Remove")
    assert remove.guard == Unary("!", N("Pick"))
    calls = [s.name for s in walk_stmts(remove.body) if isinstance(s, CallStmt)]
    assert calls == ["remove"]
    kinds = [type(s).__name__ for s in walk_stmts(remove.body)]
    if name == "race":
        assert kinds == ["If", "Atomic", "If", "CallStmt", "Assign"]
    else:
        assert kinds == ["If", "If", "Atomic", "CallStmt", "Assign"]
    assert p.n_statements == 10


# --------------------------------------------------------------------------
# files
# --------------------------------------------------------------------------

def test_parse_file_missing(tmp_path):
    with pytest.raises(PcclError, match="cannot read") as info:
        parse_file(tmp_path / "nope.pccl")
    assert "Traceback" not in info.value.render()


def test_parse_file_directory(tmp_path):
    with pytest.raises(PcclError, match="cannot read"):
        parse_file(tmp_path)


def test_parse_file_bad_encoding(tmp_path):
    f = tmp_path / "bad.pccl"
    f.write_bytes(b"loc:\n  int x = 1; // caf\xe9\n")
    with pytest.raises(PcclError, match="not valid UTF-8") as info:
        parse_file(f)
    assert info.value.line == 2


def test_parse_file_bom_and_errors_name_the_file(tmp_path):
    f = tmp_path / "ok.pccl"
    f.write_bytes("\ufeffloc:\n  int x;\n".encode("utf-8"))
    assert parse_file(f).decls[0].name == "x"
    f.write_text("loc:\n  int x = ;\n")
    with pytest.raises(PcclError) as info:
        parse_file(f)
    assert info.value.render().startswith(f"{f}:2:11: error: ")


# --------------------------------------------------------------------------
# syntax errors: golden messages
# --------------------------------------------------------------------------

EV = "Start():\n  pre(x);\n  eff:\n"

GOLDEN = [
    # else without if
    (EV + "    x = 1;\n    else:\n      y = 2;\n",
     "t.pccl:5:5: error: unexpected 'else': expected a statement\n"
     "    5 |     else:\n"
     "      |     ^^^^"),
    # two statements on a line without ';'
    (EV + "    x = 1 y = 2\n",
     "t.pccl:4:11: error: unexpected 'y': expected ';' or end of line after statement\n"
     "    4 |     x = 1 y = 2\n"
     "      |           ^"),
    # block header at end of file
    (EV + "    if (c):\n",
     "t.pccl:4:12: error: unexpected end of file: expected an indented block\n"
     "    4 |     if (c):\n"
     "      |            ^"),
    # dedent to a column no block started at
    (EV + "    if (c):\n        x = 1;\n      y = 2;\n",
     "t.pccl:6:7: error: inconsistent indentation (dedent does not match any outer level)\n"
     "    6 |       y = 2;\n"
     "      |       ^"),
    # stray character
    (EV + "    x = $3;\n",
     "t.pccl:4:9: error: unexpected character '$'\n"
     "    4 |     x = $3;\n"
     "      |         ^"),
    (EV + "    x = a & b;\n",
     "t.pccl:4:11: error: unexpected character '&' (did you mean '&&'?)\n"
     "    4 |     x = a & b;\n"
     "      |           ^"),
    # missing expression
    (EV + "    x = ;\n",
     "t.pccl:4:9: error: unexpected ';': expected an expression\n"
     "    4 |     x = ;\n"
     "      |         ^"),
    # missing colon after if
    (EV + "    if (a)\n      x = 1\n",
     "t.pccl:4:11: error: unexpected end of line: expected ':'\n"
     "    4 |     if (a)\n"
     "      |           ^"),
    # missing closing parenthesis
    (EV + "    if (a b):\n      x = 1\n",
     "t.pccl:4:11: error: unexpected 'b': expected ')'\n"
     "    4 |     if (a b):\n"
     "      |           ^"),
    # '=' for '=='
    (EV + "    if (a = 1):\n      x = 1\n",
     "t.pccl:4:11: error: unexpected '=': expected ')' (did you mean '=='?)\n"
     "    4 |     if (a = 1):\n"
     "      |           ^"),
    # over-indented statement
    (EV + "    x = 1\n      y = 2\n",
     "t.pccl:5:7: error: unexpected indentation\n"
     "    5 |       y = 2\n"
     "      |       ^"),
    # event without eff
    ("Start():\n  pre(x);\nNext():\n",
     "t.pccl:3:1: error: unexpected dedent: expected 'eff'\n"
     "    3 | Next():\n"
     "      | ^"),
    # missing ';' between declarations
    ("loc:\n  int x = 1 int y;\n",
     "t.pccl:2:13: error: unexpected 'int': expected ';' or end of line after declaration\n"
     "    2 |   int x = 1 int y;\n"
     "      |             ^^^"),
    # declaration not indented under its section
    ("loc:\nint x = 1;\n",
     "t.pccl:2:5: error: unexpected 'x': expected '(' after event name 'int'\n"
     "    2 | int x = 1;\n"
     "      |     ^"),
    # unterminated block comment
    ("loc:\n  int x; /* open\n  int y;\n",
     "t.pccl:2:10: error: unterminated block comment ('/*' without '*/')\n"
     "    2 |   int x; /* open\n"
     "      |          ^^"),
    # sections out of order
    ("loc:\n  int x;\nallwrite:\n  int y;\n",
     "t.pccl:3:1: error: unexpected 'allwrite:': expected an event, 'Init:', "
     "'invariant:' or end of file; sections come in the order Agent::Name, allwrite:, "
     "allread:, loc:, Init:, the events Name():, invariant: (each optional)\n"
     "    3 | allwrite:\n"
     "      | ^^^^^^^^^"),
    # a misspelt section header
    ("allwrite:\n  int y;\nalread:\n  int x;\n",
     "t.pccl:3:1: error: unknown section 'alread:' (did you mean 'allread:'?); sections come "
     "in the order Agent::Name, allwrite:, allread:, loc:, Init:, the events Name():, "
     "invariant: (each optional)\n"
     "    3 | alread:\n"
     "      | ^^^^^^^"),
    ("Inti:\n  skip;\n",
     "t.pccl:1:1: error: unknown section 'Inti:' (did you mean 'Init:'?); sections come "
     "in the order Agent::Name, allwrite:, allread:, loc:, Init:, the events Name():, "
     "invariant: (each optional)\n"
     "    1 | Inti:\n"
     "      | ^^^^^"),
    # an event without '()' that is no section name keeps the event hint
    ("Start:\n  pre(true);\n",
     "t.pccl:1:6: error: unexpected ':': expected '(' after event name 'Start'\n"
     "    1 | Start:\n"
     "      |      ^"),
    # pre without parentheses
    ("Start():\n  pre x;\n  eff:\n",
     "t.pccl:2:7: error: unexpected 'x': expected '('\n"
     "    2 |   pre x;\n"
     "      |       ^"),
    # 'else' without ':'
    (EV + "    if (a):\n      x = 1\n    else\n      y = 2\n",
     "t.pccl:6:9: error: unexpected end of line: expected ':' or 'if'\n"
     "    6 |     else\n"
     "      |         ^"),
    # unclosed parenthesis at end of file
    (EV + "    x = (1 +\n",
     "t.pccl:4:13: error: unexpected end of file: expected an expression\n"
     "    4 |     x = (1 +\n"
     "      |             ^"),
    # unclosed enum
    ("loc:\n  enum S { A, B\n  int x;\n",
     "t.pccl:3:3: error: unexpected 'int': expected ',' or '}'\n"
     "    3 |   int x;\n"
     "      |   ^^^"),
]


@pytest.mark.parametrize("source,expected", GOLDEN, ids=range(len(GOLDEN)))
def test_golden_errors(source, expected):
    assert error(source) == expected


def test_error_context_names_the_kind_of_line():
    assert "after statement" in error("Init:\n  a = 1 b = 2\n")
    assert "after invariant" in error("invariant:\n  m: a b\n")
    assert "after 'pre(...)'" in error("E():\n  pre(x) eff:\n")


def test_indented_first_line_rejected():
    assert error("  loc:\n  int x;\n") == (
        "t.pccl:1:3: error: unexpected indentation\n"
        "    1 |   loc:\n"
        "      |   ^")
    assert error("// comment\n  loc:\n").startswith("t.pccl:2:3: error: unexpected indentation")
    # a comment before code on the first line is not indentation
    assert parse_program("/* c */ loc:\n  int x;\n").decls[0].name == "x"


def test_too_deeply_nested():
    # the parser builds any depth (iteratively); the checker refuses it, located
    from pccl.lang.checker import check_program
    src = "loc:\n  int x = 0;\n\nE():\n  pre(true);\n  eff:\n    x = " + "-" * 5000 + "1\n"
    with pytest.raises(PcclError, match="nested too deeply") as info:
        check_program(parse_program(src, "t.pccl"))
    assert (info.value.line, info.value.column) == (7, 109)


def test_error_carries_location_fields():
    with pytest.raises(PcclError) as info:
        parse_program(EV + "    x = 1 y = 2\n", "t.pccl")
    e = info.value
    assert (e.filename, e.line, e.column) == ("t.pccl", 4, 11)
    assert e.source.startswith("Start():")


# --------------------------------------------------------------------------
# robustness: never anything but a Program or a PcclError
# --------------------------------------------------------------------------

def _parse_or_error(src: str):
    try:
        return parse_program(src, "t.pccl")
    except PcclError as e:
        text = e.render()
        assert text.startswith("t.pccl")
        assert "Traceback" not in text and "lark" not in text.lower()
        return e


@pytest.mark.parametrize("path", sorted(PROGRAMS.glob("*.pccl")), ids=lambda p: p.name)
def test_truncations(path):
    """Prefixes of a shipped program: a bounded number of them, so the test
    is linear in the program's length (one parse per prefix of every length
    was quadratic: 3-9 s per program)."""
    src = path.read_text()
    full = parse_program(src, "t.pccl")
    # 1. Cut before a line at column 0 (a section header or an event): what
    #    precedes is a whole program, the shipped one's first events and decls.
    offset, events = 0, []
    for line in src.splitlines(keepends=True):
        if line[:1].strip() and not line.startswith("//"):
            prog = _parse_or_error(src[:offset])
            assert isinstance(prog, ast.Program), prog.render()
            assert [e.name for e in prog.events] == events
            assert prog.decls == full.decls[:len(prog.decls)]
            if line.split("(")[0].isidentifier() and line.rstrip().endswith("():"):
                events.append(line.split("(")[0])
        offset += len(line)
    assert events == [e.name for e in full.events]
    # 2. Cut anywhere (a fixed sample): a program or one rendered error that
    #    points inside the prefix (or at its end).
    rng = random.Random(path.name)
    outcomes = []
    for cut in sorted(rng.sample(range(len(src) + 1), 40)):
        o = _parse_or_error(src[:cut])
        if isinstance(o, PcclError) and o.line is not None:
            assert o.line <= src[:cut].count("\n") + 1, (cut, o.render())
        outcomes.append(o)
    assert any(isinstance(o, PcclError) for o in outcomes)


@pytest.mark.parametrize("path", sorted(PROGRAMS.glob("*.pccl")), ids=lambda p: p.name)
def test_random_mutations(path):
    src = path.read_text()
    rng = random.Random(path.name)
    alphabet = "()[]{}:;,.=<>!&|+-*/%\n\t  xyz019_\"'$#" + "/*"
    for _ in range(150):
        chars = list(src)
        for _ in range(rng.randint(1, 4)):
            i = rng.randrange(len(chars))
            op = rng.random()
            if op < 0.4:
                del chars[i]
            elif op < 0.8:
                chars.insert(i, rng.choice(alphabet))
            else:
                chars[i] = rng.choice(alphabet)
        _parse_or_error("".join(chars))


@pytest.mark.parametrize("src", [
    "x", "(", ")", "]]]", "}", "Agent::", "Agent::X\nAgent::Y\n", "loc:\n  int\n",
    "E():\n", "E():\n  pre(\n", "E():\n  pre(x);\n  eff:\n    )\n", "\t\t", "\n\n\n",
    "/*", "*/", "//", "invariant:\n  a:\n", "E():\n  pre(x)\n  eff:\n   a[\n",
    "if", "else", "\x00", "é", "((((((((((((((((((((x))))))))))))))))))))",
    "E():\n  pre(x);\n  eff:\n    x = " + "(" * 2000 + "1" + ")" * 2000 + "\n",
    "E():\n  pre(x);\n  eff:\n    x = " + "-" * 3000 + "1\n",
])
def test_garbage(src):
    _parse_or_error(src)


@pytest.mark.parametrize("path", sorted(PROGRAMS.glob("*.pccl")), ids=lambda p: p.name)
def test_declared_names_carry_their_span(path):
    """Every declared name (variable, enum and its members, event, named
    invariant) has the span of the name as written: the checker's messages
    point there without searching the source."""
    src = path.read_text()
    lines = src.splitlines()
    prog = parse_program(src, "t.pccl")

    def text(span: Span) -> str:
        assert span.line == span.end_line > 0
        return lines[span.line - 1][span.column - 1:span.end_column - 1]

    named = [(d.name, d.name_span) for d in prog.decls]
    named += [(m, s) for d in prog.decls if isinstance(d, EnumDecl)
              for m, s in zip(d.members, d.member_spans, strict=True)]
    named += [(e.name, e.name_span) for e in prog.events]
    named += [(i.name, i.name_span) for i in prog.invariants if i.name is not None]
    assert named
    for name, span in named:
        assert text(span) == name


# ---------------------------------------------------------------------------
# the grammar's tables, cached between runs ($PCCL_CACHE, else ~/.cache/pccl)
# ---------------------------------------------------------------------------

@pytest.fixture
def fresh_grammar(monkeypatch, tmp_path):
    """The parser built anew, its cache in a directory of this test's own;
    ``builds`` counts the times lark analyses a grammar (not a load from
    the cache)."""
    import lark
    from pccl.lang import parser
    monkeypatch.setattr(parser, "_LARK", None)
    monkeypatch.setenv("PCCL_CACHE", str(tmp_path / "cache"))
    builds = []
    real = lark.Lark._build_parser

    def counted(self):
        builds.append(1)
        return real(self)
    monkeypatch.setattr(lark.Lark, "_build_parser", counted)

    def again():
        monkeypatch.setattr(parser, "_LARK", None)
        return parser._get_lark()
    return parser, builds, again


FISCHER_TEXT = (Path(__file__).resolve().parents[2] / "programs" / "fischer.pccl").read_text()


def test_the_grammar_tables_are_cached_and_used(fresh_grammar, tmp_path):
    parser, builds, again = fresh_grammar
    want = parse_program(FISCHER_TEXT, "f.pccl")        # the cache directory is made
    assert builds == [1] and len(list((tmp_path / "cache").glob("lark-*.cache"))) == 1
    again()
    assert builds == [1]                                # loaded, not built
    assert parse_program(FISCHER_TEXT, "f.pccl") == want


@pytest.mark.slow          # builds the tables three times
def test_a_stale_or_broken_cache_is_not_used(fresh_grammar, tmp_path):
    from lark import Lark
    parser, builds, again = fresh_grammar
    with open(parser._GRAMMAR_PATH, encoding="utf-8") as f:
        grammar = f.read()
    edited = grammar.replace('SKIP: "skip"', 'SKIP: "pass"')
    assert edited != grammar
    # an edited grammar has a cache file of its own ...
    path = parser._lark_cache(grammar)
    assert parser._lark_cache(edited) != path
    # ... and the tables of the edited grammar under the name of the real
    # one (as a stale file would be) are not used: lark checks the file's hash
    Lark(edited, parser="lalr", lexer="basic", start=["program", "property"],
         postlex=parser._PcclIndenter(), propagate_positions=True, maybe_placeholders=False,
         cache=path)
    builds.clear()
    again()
    assert builds == [1]
    assert isinstance(stmt("skip;"), ast.Skip)
    again()                                             # rewritten: loaded now
    assert builds == [1]
    # a half-written file is built again too
    with open(path, "rb") as f:
        data = f.read()
    with open(path, "wb") as f:
        f.write(data[: len(data) // 2])
    again()
    assert builds == [1, 1]
    assert isinstance(stmt("skip;"), ast.Skip)


@pytest.mark.slow          # builds the tables three times
def test_a_cache_directory_that_cannot_be_made_or_written_is_no_error(fresh_grammar, tmp_path,
                                                                         monkeypatch):
    import lark.utils
    parser, builds, again = fresh_grammar
    # cannot be made: its parent is a file
    (tmp_path / "file").write_text("")
    monkeypatch.setenv("PCCL_CACHE", str(tmp_path / "file" / "cache"))
    assert parser._lark_cache("x") is None
    again()
    assert isinstance(stmt("skip;"), ast.Skip)
    # cannot be written (a read-only disk, a full one): every write fails
    monkeypatch.setenv("PCCL_CACHE", str(tmp_path / "ro"))
    real_open = lark.utils.FS.open

    def no_writes(name, mode="r", **kw):
        if "w" in mode:
            raise PermissionError(13, "Permission denied", name)
        return real_open(name, mode, **kw)
    monkeypatch.setattr(lark.utils.FS, "open", staticmethod(no_writes))
    builds.clear()
    again()
    again()
    assert builds == [1, 1]                             # built each time, never failing
    assert list((tmp_path / "ro").iterdir()) == []
    assert isinstance(stmt("skip;"), ast.Skip)


@pytest.mark.slow          # builds the tables three times
def test_the_cache_directory_is_private(fresh_grammar, tmp_path, monkeypatch):
    """lark's cache is a pickle (unpickling runs code): pccl makes its cache
    directory 0700 and reads nothing from one that others can write
    (pccl/lang/cachedir.py; docs/decisions.md, "The caches are private")."""
    import stat
    parser, builds, again = fresh_grammar
    parse_program(FISCHER_TEXT, "f.pccl")
    cache = tmp_path / "cache"
    assert stat.S_IMODE(cache.stat().st_mode) == 0o700
    [table] = cache.glob("lark-*.cache")
    assert not table.stat().st_mode & 0o022
    # a directory others can write: not used at all (built at every start, nothing written)
    shared = tmp_path / "shared"
    shared.mkdir()
    shared.chmod(0o777)
    monkeypatch.setenv("PCCL_CACHE", str(shared))
    builds.clear()
    again()
    again()
    assert builds == [1, 1] and list(shared.iterdir()) == []
    assert parser._lark_cache("x") is None


@pytest.mark.slow          # builds the tables twice
def test_a_cache_file_others_could_write_is_never_read(fresh_grammar, tmp_path, monkeypatch):
    """A table file writable by group or others (a umask of 002, or someone
    else's doing) is removed unread and written anew, private."""
    import lark.lark
    parser, builds, again = fresh_grammar
    again()
    [table] = (tmp_path / "cache").glob("lark-*.cache")
    table.chmod(0o666)
    loads = []
    real_load = lark.lark.pickle.load

    def counted(*a, **kw):
        loads.append(1)
        return real_load(*a, **kw)
    monkeypatch.setattr(lark.lark.pickle, "load", counted)
    builds.clear()
    again()
    assert builds == [1] and loads == []                # built; the file never unpickled
    assert not table.stat().st_mode & 0o022              # written anew, private
    again()
    assert builds == [1] and loads                      # and read from then on
    assert isinstance(stmt("skip;"), ast.Skip)

