"""``pccl fmt`` (pccl/tools/fmt.py): the canonical layout never changes a
program's meaning (the formatted text parses to the same AST), keeps every
comment, is idempotent and does not depend on the white space written."""

from __future__ import annotations

import random
import re
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings

from pccl.lang import ast as A
from pccl.lang.errors import PcclError
from pccl.tools.fmt import COMMENT, BCOMMENT, NL, WS, format_source, tokenize
from pccl.lang.parser import parse_program

import symattack
from cases import programs

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = sorted((ROOT / "programs").glob("*.pccl"))
ALL_FILES = sorted([*SHIPPED, *(ROOT / "tests" / "programs").glob("*.pccl"),
                    *(ROOT / "docs" / "examples").glob("*.pccl"),
                    *(ROOT / "tests" / "golden" / "checker").glob("*.pccl")])


def _parses(text: str) -> bool:
    try:
        parse_program(text)
    except PcclError:
        return False
    return True


def comments(text: str) -> list[str]:
    return [t.text for t in tokenize(text) if t.kind in (COMMENT, BCOMMENT)]


def assert_formats(text: str, name: str = "<input>") -> str:
    """format_source's promises, checked from outside."""
    out = format_source(text, name)
    assert parse_program(out) == parse_program(text)          # spans aside: same program
    assert format_source(out, name) == out                     # idempotent
    assert comments(out) == comments(text)                     # every comment, in order
    assert out.endswith("\n") and not out.endswith("\n\n")
    assert all(ln == ln.rstrip() for ln in out.split("\n"))
    assert "\n\n\n" not in out
    return out


def messy(text: str, rng: random.Random) -> str:
    """The same program written carelessly: every indentation doubled or in
    tabs, extra spaces between tokens (not on lines with a trailing comment,
    whose column the formatter keeps), trailing spaces, a blank line doubled."""
    out = []
    tab = rng.random() < 0.5
    for line in text.split("\n"):
        toks = tokenize(line)
        lead = toks[0].text if toks and toks[0].kind == WS else ""
        body = toks[1:] if lead else toks
        width = len(lead.expandtabs(8))
        indent = ("\t" * (width // 2) + " " * (width % 2)) if tab else " " * (2 * width)
        trailing_comment = any(t.kind == COMMENT for t in body) and any(
            t.kind not in (WS, COMMENT, BCOMMENT) for t in body)
        parts = []
        for t in body:
            if t.kind == WS:
                parts.append(t.text if trailing_comment else " " * rng.randint(1, 3))
            else:
                parts.append(t.text)
                if not trailing_comment and t.kind not in (COMMENT, NL) and rng.random() < 0.3:
                    parts.append(" " * rng.randint(1, 2))
        new = indent + "".join(parts) if body else ""
        out.append(new + (" " * rng.randint(0, 2)))
        if not body and rng.random() < 0.5:
            out.append("")                      # two blank lines for one
    return "\n".join(out)


@pytest.mark.parametrize("path", ALL_FILES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_shipped_and_test_program(path):
    text = path.read_text(encoding="utf-8")
    if not _parses(text):
        with pytest.raises(PcclError):
            format_source(text)
        return
    out = assert_formats(text, str(path))
    # the layout does not depend on the white space written
    assert format_source(messy(text, random.Random(str(path)))) == out
    # the line structure is kept: every code line keeps its relative order,
    # and only blank lines are added or removed
    nonblank = [ln.strip() for ln in text.split("\n") if ln.strip()]
    assert len([ln for ln in out.split("\n") if ln.strip()]) == len(nonblank)


def test_shipped_programs_are_canonical():
    """`pccl fmt --check programs/*.pccl` passes: docs and tests cite their
    line numbers, so they are already in the canonical layout."""
    r = subprocess.run([sys.executable, "-m", "pccl.cli", "fmt", "--check", *map(str, SHIPPED)],
                       capture_output=True, text=True, cwd=ROOT)
    assert (r.returncode, r.stdout, r.stderr) == (0, "", "")
    for p in SHIPPED:
        assert format_source(p.read_text(encoding="utf-8")) == p.read_text(encoding="utf-8")


@settings(max_examples=60, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(prog=programs())
def test_generated_programs(prog):
    text, _ = prog
    out = assert_formats(text)
    assert format_source(messy(text, random.Random(text))) == out


def test_symattack_programs():
    for seed in range(60):
        text = symattack.program(seed)[0]
        out = assert_formats(text)
        assert format_source(messy(text, random.Random(seed))) == out


MESSY = """\
// header comment
Agent  ::  Demo
allwrite :
    int   x=-1 ;   List< List<int> >ls=[ [1,2],[ ] ];
    enum  Stage{A,B,} ;
loc:
    int id=getAgentIndex( ) ;
    ItemPosition p=ItemPosition( 1.0,2 );
Init:
    x=x- -1;x=x - 1;
Go( ):
    pre ( !(x<=2)&&id!=0||p.x>1 ) ;
    eff :
        if(x<  2) : x = x+1 ;
        else if (x>3):
            // inside
            atomic : x=x*2%3
        /* block */ while ( x > 0 ) :
                x = x/2;    // trailing
    // before the next event

Stop():
  pre(true); eff: exit();
invariant:
    safe : x>=-1
"""

CANONICAL = """\
// header comment
Agent::Demo

allwrite:
  int x = -1; List<List<int>> ls = [[1, 2], []];
  enum Stage { A, B, };

loc:
  int id = getAgentIndex();
  ItemPosition p = ItemPosition(1.0, 2);

Init:
  x = x - -1; x = x - 1;

Go():
  pre(!(x <= 2) && id != 0 || p.x > 1);
  eff:
    if (x < 2): x = x + 1;
    else if (x > 3):
      // inside
      atomic: x = x * 2 % 3
    /* block */ while (x > 0):
      x = x / 2;  // trailing
  // before the next event

Stop():
  pre(true); eff: exit();

invariant:
  safe: x >= -1
"""


def test_canonical_layout_by_example():
    assert assert_formats(MESSY) == CANONICAL


def test_continuation_lines_align_after_their_bracket():
    text = "loc:\n  int x = f(1,\n  2, g(\n3,\n 4));\n  int y = f(\n 1);\n"
    assert assert_formats(text) == ("loc:\n  int x = f(1,\n            2, g(\n"
                                    "                3,\n                4));\n"
                                    "  int y = f(\n      1);\n")


def test_tokens_are_never_glued():
    # `<` `=` must not become `<=`, nor two words one, nor `1.` `x` a float
    for text in ("loc:\n  int a = 1;\n  bool b = a < -1;\n", "loc:\n  bool b = ! ! true;\n",
                 "loc:\n  int a = - - 1;\n"):
        out = assert_formats(text)
        assert parse_program(out) == parse_program(text)
    assert "- -1" in format_source("loc:\n  int a = - - 1;\n")


def test_multiline_block_comment_is_verbatim():
    text = "loc:\n  /* one\n     two */ int x = 1;\n  int y = 2; /* a\nb */\n"
    out = assert_formats(text)
    assert "/* one\n     two */ int x = 1;" in out and "/* a\nb */" in out


def test_syntax_error_is_reported_not_formatted():
    with pytest.raises(PcclError) as e:
        format_source("loc:\n  int x = ;\n", "bad.pccl")
    assert e.value.line == 2


def test_cli_check_rewrite_and_errors(tmp_path):
    f = tmp_path / "p.pccl"
    f.write_text(MESSY)

    def fmt(*args, stdin=None):
        return subprocess.run([sys.executable, "-m", "pccl.cli", "fmt", *args], input=stdin,
                              capture_output=True, text=True, cwd=tmp_path)

    r = fmt("--check", "p.pccl")
    assert (r.returncode, r.stdout) == (1, "would reformat p.pccl\n")
    assert f.read_text() == MESSY                      # --check writes nothing
    r = fmt("--diff", "p.pccl")
    assert r.returncode == 1 and "+  int x = -1;" in r.stdout and f.read_text() == MESSY
    r = fmt("p.pccl")
    assert (r.returncode, r.stdout) == (0, "reformatted p.pccl\n")
    assert f.read_text() == CANONICAL
    assert fmt("--check", "p.pccl").returncode == 0
    r = fmt("-", stdin=MESSY)
    assert (r.returncode, r.stdout) == (0, CANONICAL)
    bad = tmp_path / "bad.pccl"
    bad.write_text("loc:\n  int x = ;\n")
    r = fmt("--check", "bad.pccl")
    assert r.returncode == 2 and re.match(r"bad\.pccl:2:\d+: error: ", r.stderr)
    assert "Traceback" not in r.stderr
    r = fmt("missing.pccl")
    assert r.returncode == 2 and "missing.pccl" in r.stderr and "Traceback" not in r.stderr


def test_ast_equality_ignores_spans_only():
    """The check format_source relies on: equal ASTs mean the same program
    (spans differ), and a changed operator is a different AST."""
    a = parse_program("loc:\n  int x = 1 + 2;\n")
    b = parse_program("loc:\n  int   x =  1+2;\n")
    c = parse_program("loc:\n  int x = 1 - 2;\n")
    assert a == b and a != c
    assert isinstance(a.decls[0], A.VarDecl) and a.decls[0].span != b.decls[0].span
