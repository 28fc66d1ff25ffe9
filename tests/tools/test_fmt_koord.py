"""``pccl fmt`` on Koord files (issue 47; docs/koord.md, "Formatting"):
the layout is idempotent, the formatted program is the same checked
program, comments and line structure are kept, and the language server
offers the same edit."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from pccl.cli import main
from pccl.lang.koord import parse_koord
from pccl.tools import lsp as L
from pccl.tools.fmt import _koord_layout, format_source

ROOT = Path(__file__).resolve().parents[2]
KOORD = sorted((ROOT / "programs" / "koord").glob("*.koord")) + [
    ROOT / "tests" / "programs" / "koord_lists.koord"]

MESSY = """\


# top comment
def fun twice( int v ) :
    return v*2

using Motion :
    actuators:
        pos target
    sensors:
        pos position
local:
    int x=-1   # trailing
    list<int> xs=[ 1,2 ,
          3 ]



ev :
    pre :x== -1 and not(x>2)
    eff :
            # inside
            x = twice( pid+1 ) ; x = x-1
            if x<0 :
              stop
            elif x >= 0:
              Motion.target = pos( 1.0 , -2 )   /* here */
            for x in xs :
                stdout<<"x is"<<x
            stop
invariant:
    ok : forall i : x[i] >= -1
"""

TIDY = """\
# top comment
def fun twice(int v):
  return v * 2

using Motion:
  actuators:
    pos target
  sensors:
    pos position
local:
  int x = -1  # trailing
  list<int> xs = [1, 2,
      3]

ev:
  pre: x == -1 and not (x > 2)
  eff:
    # inside
    x = twice(pid + 1); x = x - 1
    if x < 0:
      stop
    elif x >= 0:
      Motion.target = pos(1.0, -2) /* here */
    for x in xs:
      stdout << "x is" << x
    stop
invariant:
  ok: forall i: x[i] >= -1
"""


def test_a_messy_koord_program_gets_the_canonical_layout():
    out = format_source(MESSY, "m.koord")
    assert out == TIDY
    assert parse_koord(out, "m.koord") == parse_koord(MESSY, "m.koord")


@pytest.mark.parametrize("path", KOORD, ids=lambda p: p.name)
def test_every_koord_program_round_trips(path):
    """fmt is idempotent on each program, and a re-indented copy (four
    spaces a level, spacing squeezed) formats back to the same text and
    the same checked program."""
    src = path.read_text()
    once = format_source(src, path.name)
    assert format_source(once, path.name) == once
    assert parse_koord(once, path.name) == parse_koord(src, path.name)
    wide = "\n".join(_squeeze(_double_indent(line)) for line in src.split("\n"))
    assert wide != src
    assert format_source(wide, path.name) == once


def _squeeze(line: str) -> str:
    """Spacing squeezed out of a line without a comment or a string."""
    if any(c in line for c in ("#", "//", "/*", '"')):
        return line
    return line.replace(" == ", "==").replace(", ", ",").replace(" = ", "=")


def _double_indent(line: str) -> str:
    stripped = line.lstrip(" ")
    return " " * (2 * (len(line) - len(stripped))) + stripped


def test_the_shipped_koord_programs_are_formatted():
    res = CliRunner().invoke(main, ["fmt", "--check", *map(str, KOORD)])
    assert res.exit_code == 0, res.output


def test_fmt_rewrites_a_koord_file_and_refuses_a_broken_one(tmp_path):
    p = tmp_path / "m.krd"
    p.write_text(MESSY)
    res = CliRunner().invoke(main, ["fmt", str(p)])
    assert res.exit_code == 0 and p.read_text() == TIDY, res.output
    bad = tmp_path / "bad.koord"
    bad.write_text(MESSY.replace("pre :x==", "pre :x=", 1))
    res = CliRunner().invoke(main, ["fmt", str(bad)])
    assert res.exit_code == 2 and "bad.koord:20:" in res.output + (res.stderr or "")
    assert bad.read_text() == MESSY.replace("pre :x==", "pre :x=", 1)


def test_the_language_server_formats_koord():
    assert L.format_text(MESSY, "/w/m.koord") == TIDY
    assert L.format_text(MESSY.replace("stop\ninvariant", "stop(\ninvariant"), "/w/m.koord") is None


def test_the_koord_layout_keeps_lines_and_comments():
    out = _koord_layout(MESSY)
    for c in ("# top comment", "# trailing", "# inside", "/* here */"):
        assert c in out
    # two blank lines at the start and three in a row are dropped, nothing else
    assert len(out.split("\n")) == len(MESSY.split("\n")) - 2 - 2


def test_mutated_koord_programs_that_parse_format_to_the_same_program():
    """White space, comments, brackets and operators inserted at random
    places: every variant that parses formats (no FormatterBug: the
    formatted text parses to the same program and is a fixed point)."""
    import random
    srcs = [p.read_text() for p in KOORD]
    rng = random.Random(47)
    pieces = [" ", "\n", "  ", "\t", "(", ")", "-", "- ", "/* c */", "# c\n", "// c", "!", ",",
              ";", " = ", "<<", '"s"', "\n\n", "-1"]
    formatted = 0
    for _ in range(150):
        s = rng.choice(srcs)
        k = rng.randrange(len(s))
        s = s[:k] + rng.choice(pieces) + s[k:]
        try:
            parse_koord(s, "f.koord")
        except Exception:
            continue
        out = format_source(s, "f.koord")
        assert format_source(out, "f.koord") == out
        formatted += 1
    assert formatted > 40
