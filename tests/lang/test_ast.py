"""pccl.lang.ast.children: the one traversal of the AST, checked against a
reflective walk over every dataclass field (the two must agree on every
shipped program), and the walkers built on it."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from pccl.lang import ast
from pccl.model.compile import has_rand
from pccl.lang.parser import parse_program, parse_property

ROOT = Path(__file__).resolve().parents[2]
SOURCES = sorted((ROOT / "programs").glob("*.pccl")) + sorted((ROOT / "tests" / "programs").glob("*.pccl"))


def reflective_children(node) -> tuple:
    """Every AST node held in ``node``'s fields, in field order, looking
    inside tuples (an If's (condition, body) pairs): written without
    knowing any node class."""
    out: list = []

    def collect(v):
        if isinstance(v, (ast.Span, ast.TypeRef)) or v is None:
            return
        if isinstance(v, tuple):
            for x in v:
                collect(x)
        elif dataclasses.is_dataclass(v):
            out.append(v)

    for f in dataclasses.fields(node):
        collect(getattr(node, f.name))
    return tuple(out)


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: p.name)
def test_children_agrees_with_the_fields(path):
    prog = parse_program(path.read_text(), path.name)
    nodes = list(ast.walk(prog))
    assert {ast.Program, ast.Event, ast.Assign} <= {type(n) for n in nodes}
    for n in nodes:
        assert ast.children(n) == reflective_children(n), type(n).__name__


def test_walk_is_preorder_and_iterative():
    deep = parse_property(" + ".join(["x"] * 3000))
    names = [n for n in ast.walk(deep) if isinstance(n, ast.Name)]
    assert len(names) == 3000
    first = next(iter(ast.walk(deep)))
    assert first is deep


def test_walk_stmts_yields_statements_in_sid_order():
    src = ("Init:\n  if (true):\n    x = 1\n    while (x < 2):\n      x = x + 1\n"
           "  else:\n    atomic:\n      skip\n  y = 2\nloc:\n")
    src = "loc:\n  int x = 0\n  int y = 0\n" + src[:-5]
    prog = parse_program(src, "t.pccl")
    sids = [s.sid for s in ast.walk_stmts(prog.init)]
    assert sids == list(range(prog.n_statements))
    kinds = [type(s).__name__ for s in ast.walk_stmts(prog.init)]
    assert kinds == ["If", "Assign", "While", "Assign", "Atomic", "Skip", "Assign"]
    # the same statements, in the same order, as the full walk finds
    assert list(ast.walk_stmts(prog.init)) == [n for n in ast.walk(prog)
                                                if isinstance(n, ast.STMT_TYPES)]


def test_has_rand_looks_at_a_statements_own_expressions_only():
    src = ("loc:\n  int x = 0\nInit:\n  if (x < 1):\n    x = rand(0, 1)\n"
           "  while (rand(0, 1) == 0):\n    skip\n")
    prog = parse_program(src, "t.pccl")
    if_stmt, while_stmt = prog.init
    assert not has_rand(if_stmt)                 # the rand is in its branch
    assert has_rand(if_stmt.branches[0][1])      # ... here
    assert has_rand(while_stmt)                  # in the condition
    assert has_rand(prog.init)


def test_the_programs_exercise_every_node_class():
    """So that the agreement test above covers every branch of children()."""
    import typing
    seen = set()
    for path in SOURCES:
        seen |= {type(n) for n in ast.walk(parse_program(path.read_text(), path.name))}
    every = set(typing.get_args(ast.Node))
    assert every - seen == set()
