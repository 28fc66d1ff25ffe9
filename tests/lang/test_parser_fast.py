"""The parser's fast path (pccl/lang/lalrfast.py: lark's LALR tables run
without a parse tree, issue 42) against the ordinary one (lark's parse tree,
then the AST builder): on every program of the repository, on generated
ones and on 1,200 mutants, both give the same AST with the same
spans, and the same error for every text with one (message, position,
caret); the fast path accepts no text the ordinary path rejects."""

from __future__ import annotations

import dataclasses
import random
import threading

import pytest

from pccl.lang import ast
from pccl.lang import parser as P
from pccl.lang.errors import PcclError
from pccl.lang.lalrfast import Fallback

from conftest import PROGRAMS, ROOT, TEST_PROGRAMS
from sources import mutate
from sources import generated


def dump(x):
    """``x`` as nested tuples, every span included (spans are left out of
    the nodes' ``==``)."""
    if dataclasses.is_dataclass(x) and not isinstance(x, type):
        return (type(x).__name__,) + tuple((f.name, dump(getattr(x, f.name)))
                                           for f in dataclasses.fields(x))
    if isinstance(x, (tuple, list)):
        return tuple(dump(v) for v in x)
    if isinstance(x, dict):
        return tuple(sorted((k, dump(v)) for k, v in x.items()))
    return (type(x).__name__, x)


def fast(src: str):
    """The fast path's AST, dumped; None where it stops (at a syntax error,
    or leaving the text to the ordinary path).  Any other exception fails
    the test."""
    try:
        text = P._checked_text(src, "t.pccl", False)
    except PcclError:       # before either path: the same for both
        return None
    try:
        return dump(P._fast_program(text))
    except (Fallback, P._IndentError):
        return None


def parsed(src: str, fast: bool):
    """The AST (dumped) or the error of ``P._parse`` with or without the
    fast path."""
    try:
        return dump(P._parse(src, "t.pccl", "program", fast=fast))
    except PcclError as e:
        return e


def assert_agree(src: str) -> bool:
    """Both paths agree on ``src``: the same AST, spans included, or the
    same error (message, position, caret); True if it is a program."""
    want, got = parsed(src, False), parsed(src, True)
    if isinstance(want, PcclError):
        assert isinstance(got, PcclError), "the fast path accepted a text the parser rejects"
        assert (got.render(), got.line, got.column) == (want.render(), want.line, want.column)
        assert fast(src) is None
        return False
    assert got == want
    assert fast(src) == want            # and it was the fast path's
    return True


def test_the_fast_path_is_on():
    assert P._get_fast().usable and P._get_fast().lark is P._get_lark()


@pytest.mark.slow           # builds the tables
def test_the_fast_path_is_on_with_tables_built_or_loaded_from_the_cache(monkeypatch, tmp_path):
    """lark's objects differ in how they are made (built, or unpickled from
    its cache): the fast path reads both."""
    monkeypatch.setenv("PCCL_CACHE", str(tmp_path / "cache"))
    text = (PROGRAMS / "fischer.pccl").read_text()
    for _ in ("built", "loaded"):
        monkeypatch.setattr(P, "_LARK", None)
        fast_path = P._get_fast()
        assert fast_path.usable and fast_path.lark is P._LARK
        assert fast(text) == parsed(text, False)
    assert len(list((tmp_path / "cache").glob("lark-*.cache"))) == 1


@pytest.mark.slow           # builds the tables in two processes
def test_the_fast_path_runs_the_tables_of_the_lark_in_use(monkeypatch, tmp_path):
    """Tables built under two hash seeds number their states differently
    (the cache file keeps the numbering of the process that wrote it). The
    fast path runs the tables of the Lark in use: after the tests of the
    cache had swapped it, it ran another's, and its errors expected the
    wrong tokens."""
    import os
    import subprocess
    import sys
    larks = []
    for seed in ("1", "2"):
        cache = tmp_path / f"cache{seed}"
        subprocess.run([sys.executable, "-c", "from pccl.lang.parser import _get_lark; _get_lark()"],
                       env={**os.environ, "PCCL_CACHE": str(cache), "PYTHONHASHSEED": seed},
                       check=True)
        monkeypatch.setenv("PCCL_CACHE", str(cache))
        monkeypatch.setattr(P, "_LARK", None)
        larks.append(P._get_lark())                    # loaded: that process's numbering
    one, two = (lk.parser.parser.parser.parse_table.states for lk in larks)
    assert one != two
    wrong = ["loc:\n  bool b = true;;\n", "E():\n  pre(true)\n  eff: x = (1 +\n",
             "Agent::A\nloc:\n  int x\nAgent::B\n"]
    for lk in (larks[0], larks[1], larks[0]):
        monkeypatch.setattr(P, "_LARK", lk)
        for text in wrong:
            assert_agree(text)
        assert P._get_fast().lark is lk


REPO_PROGRAMS = sorted({*PROGRAMS.rglob("*.pccl"), *TEST_PROGRAMS.rglob("*.pccl"),
                        *(ROOT / "docs").rglob("*.pccl")})


@pytest.mark.slow
def test_every_program_of_the_repository_parses_the_same():
    assert len(REPO_PROGRAMS) > 30
    valid = [p for p in REPO_PROGRAMS if assert_agree(p.read_text())]
    assert len(valid) > 30


WRITTEN = [
    "",
    "// only a comment\n",
    "allwrite:\n  int a = 1;\n",
    "allwrite:\n  int a = (1 +\n     2) * 3;  /* a comment\n spanning lines */ int b = a;\n",
    "loc:\n\tint x = 0\n\tbool b = true;;\nE():\n\tpre(true);\n\teff:\n\t\tx = x + 1\n",
    "Agent:: A\nallwrite:\n  int c[3] = [1, 2, 3];\n  List<int> l = [];\n"
    "  enum Color {red, green,}\nloc:\n  float f = .5e3;\nInit:\n  c[0] = -(-c[1]);\n"
    "E():\n  pre(!(c[0] == 1) && c[1] >= 2 || f < 1.0);\n  eff: c[2] = c[2] % 2; skip\n"
    "F():\n  pre(true)\n  eff:\n    if c[0] > 0: c[0] = 0\n    elif c[1] > 0:\n      atomic:\n"
    "        c[1] = 0\n    else:\n      while (c[2] < 3):\n        c[2] = c[2] + 1\n"
    "    l = l + [((1))];\n    exit()\ninvariant:\n  ok: c[0] >= 0 -> c[1] >= 0; c[2] >= 0\n"
    "  forall i: (i < 0) || c[i] >= 0\n",
    "loc:\r\n  int x = 1\r\nE():\r\n  pre(x.y[1].z == f(1, (2), [3]))\r\n  eff: x = 1\r\n",
    "allwrite:\n  int a = 1\n\n   // indented comment\n\nE():\n  pre(true);\n  eff:\n",
]


@pytest.mark.parametrize("text", WRITTEN, ids=[f"text{i}" for i in range(len(WRITTEN))])
def test_written_programs_parse_the_same(text):
    assert_agree(text)


@pytest.mark.slow
def test_a_generated_program_parses_the_same():
    assert assert_agree(generated(2_000))


@pytest.mark.slow
def test_mutants_parse_the_same_or_are_left_to_the_ordinary_path():
    """1,200 mutants (test_fuzz's mutations): the fast path gives
    the ordinary path's AST for each program and accepts no other text."""
    rng = random.Random(4205)
    sources = [p.read_text() for p in REPO_PROGRAMS if p.stat().st_size < 6_000]
    valid = invalid = 0
    for k in range(1_200):
        text = sources[k % len(sources)]
        for _ in range(rng.randint(1, 3)):
            text = mutate(text, rng)[1]
        if assert_agree(text):
            valid += 1
        else:
            invalid += 1
    assert valid > 100 and invalid > 100, (valid, invalid)


def test_a_program_is_parsed_by_the_fast_path(monkeypatch):
    """parse_program does not call lark's parser for a program the fast
    path reads (and does for a property)."""
    lark = P._get_lark()

    def refused(*args, **kwargs):
        raise AssertionError("lark's parser was called")
    monkeypatch.setattr(lark, "parse", refused)
    prog = P.parse_program((PROGRAMS / "fischer.pccl").read_text(), "fischer.pccl")
    assert prog.n_statements > 20
    with pytest.raises(AssertionError):
        P.parse_property("count(inCs) <= 1")


def test_spans_of_parentheses_and_inlined_rules():
    """Spans as lark's PropagatePositions gives them: a parenthesised
    operand's parent starts at its '(' (the operand itself at its first
    token), a call ends at its ')'."""
    prog = P.parse_program("loc:\n  int x = (1 + 2) * f(3)\n")
    init = prog.decls[0].init
    assert isinstance(init, ast.Binary) and init.op == "*"
    assert (init.span.line, init.span.column, init.span.end_line, init.span.end_column) == (2, 11, 2, 25)
    left = init.left
    assert (left.span.column, left.span.end_column) == (12, 17)
    assert (init.right.span.column, init.right.span.end_column) == (21, 25)


def test_errors_are_those_of_the_ordinary_path(monkeypatch):
    """A text with an error gets the same message, position and caret as
    with the fast path off (the tests of test_parser.py check the messages
    themselves): a syntax error is reported from the fast path's stacks as
    lark would, an error of the AST builder by the ordinary path."""
    texts = ["loc:\n  int x = 1 +\n", "loc:\n  int x = 1\n   int y\n",
             f"loc:\n  int x = {'9' * 5000}\n", "loc:\n  int x = a < b < c\n",
             "E():\n  pre(forall i: true)\n  eff: skip\n", "loc:\n  int x = @\n"]
    for text in texts:
        with pytest.raises(PcclError) as on:
            P.parse_program(text, "t.pccl")
        with monkeypatch.context() as m:
            m.setattr(P._get_fast(), "usable", False)
            with pytest.raises(PcclError) as off:
                P.parse_program(text, "t.pccl")
        assert on.value.render() == off.value.render()


def test_a_syntax_error_lark_cannot_be_asked_about_goes_to_the_ordinary_path(monkeypatch):
    """Where lark's classes cannot be made from the fast path's stacks
    (another lark), the ordinary path reports the error, never a traceback."""
    from pccl.lang import lalrfast
    text = "loc:\n  bool b = true;;\n"
    want = parsed(text, False)

    def broken(self, failure):
        raise TypeError("another lark")
    monkeypatch.setattr(lalrfast.FastLALR, "unexpected_token", broken)
    got = parsed(text, True)
    assert isinstance(got, PcclError) and got.render() == want.render()


def test_a_cancelled_parse_stops_on_the_fast_path():
    event = threading.Event()
    event.set()
    with P.cancellable(event), pytest.raises(P.ParseCancelled):
        P._fast_program(P._normalise(generated(2_000)))
