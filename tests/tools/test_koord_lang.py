"""``--lang koord`` (issue 47; docs/koord.md, "Running a Koord file"): a
Koord program in a file with another suffix, Koord text given to the API,
and ``pccl fmt --lang koord -`` on standard input.  Each is read by the
Koord front end exactly as a ``.koord`` file is (the same AST, the same
search, the same trace); a syntax error points at its place with a caret
(exit 2, no traceback); ``--lang pccl`` reads a ``.koord`` file as PCCL."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

import pccl.api as api
from pccl.lang.errors import ArgumentError, PcclError
from pccl.lang.files import parse_program_file, parse_program_text
from pccl.lang.koord import parse_koord

from conftest import cli

ROOT = Path(__file__).resolve().parents[2]
LOST = ROOT / "programs" / "koord" / "add_numbers_lost.koord"

BROKEN = "local:\n  int x = 0\nev:\n  pre: x <\n  eff:\n    x = 1\n"
MESSY = "local:\n    int x=0\nev:\n  pre: x<1\n  eff:\n      x = 1\n"
TIDY = "local:\n  int x = 0\nev:\n  pre: x < 1\n  eff:\n    x = 1\n"


@pytest.fixture
def txt(tmp_path):
    """add_numbers_lost.koord copied to a file ending .txt."""
    p = tmp_path / "lost.txt"
    shutil.copy(LOST, p)
    return p


def _strip(prog):
    """The program without its file name (which differs by design)."""
    import dataclasses
    return dataclasses.replace(prog, filename="", source="")


def test_lang_koord_reads_another_suffix_as_the_koord_file(txt):
    a = parse_program_file(txt, "koord")
    b = parse_program_file(LOST)
    assert a.language == "koord" and _strip(a) == _strip(b)
    # without --lang the suffix decides: .txt is PCCL, and Koord is no PCCL
    with pytest.raises(PcclError):
        parse_program_file(txt)
    text = LOST.read_text()
    assert _strip(parse_program_text(text, "<input>", "koord")) == _strip(b)
    assert _strip(parse_program_text(text, "x.koord")) == _strip(b)


def test_cli_lang_koord_explores_check_and_replays_a_txt_file(txt, tmp_path):
    r = cli("check", txt)
    assert r.exit_code == 2 and f"{txt}:1:1" in r.output and "^" in r.output
    r = cli("check", "--lang", "koord", txt)
    assert r.exit_code == 0 and "ok (2 events, 3 statements)" in r.output
    trace = tmp_path / "t.json"
    r = cli("explore", txt, "--lang", "koord", "--trace-out", trace)
    assert r.exit_code == 1, r.output
    assert "violation: invariant 'noLostUpdate' violated" in r.output
    assert "not argued for Koord's round semantics" in r.output   # the Koord semantics
    ref = cli("explore", LOST)
    # the same search as the .koord file's: its figures, its counterexample
    def lines(out, path):
        return [x for x in out.replace(str(path), "P").splitlines()[1:]
                if not any(w in x for w in ("trace written", "second", "memory"))]
    assert lines(r.output, txt) == lines(ref.output, LOST)
    cfg = json.loads(trace.read_text())["config"]
    assert cfg["options"]["lang"] == "koord"
    r = cli("replay", trace)
    assert r.exit_code == 1 and "reproduced: invariant 'noLostUpdate' violated" in r.output, r.output
    r = cli("run", txt, "--lang", "koord")
    assert r.exit_code == 1 and "noLostUpdate" in r.output


def test_lang_pccl_reads_a_koord_suffix_as_pccl(tmp_path):
    p = tmp_path / "plain.koord"
    p.write_text("Agent::Plain\n\nloc:\n  int x = 0;\n\nGo():\n  pre(x == 0);\n  eff:\n"
                 "    x = 1;\n    exit();\n")
    assert cli("check", p).exit_code == 2
    r = cli("check", "--lang", "pccl", p)
    assert r.exit_code == 0, r.output
    r = cli("explore", "--lang", "pccl", p)
    assert r.exit_code == 0 and "no violation" in r.output, r.output


def test_lang_koord_syntax_error_has_its_caret(tmp_path):
    p = tmp_path / "broken.prog"
    p.write_text(BROKEN)
    for args in (("check", "--lang", "koord", p), ("explore", p, "--lang", "koord"),
                 ("run", p, "--lang", "koord")):
        r = cli(*args)
        assert r.exit_code == 2, r.output
        assert f"{p}:4:11: error:" in r.output and "|           ^" in r.output, r.output


def test_fmt_lang_koord_on_standard_input():
    r = cli("fmt", "--lang", "koord", "-", input=MESSY)
    assert r.exit_code == 0 and r.output == TIDY
    assert parse_koord(r.output) == parse_koord(MESSY)
    r = cli("fmt", "--lang", "koord", "-", input=BROKEN)
    assert r.exit_code == 2 and "<stdin>:4:11: error:" in r.output and "^" in r.output
    # standard input without --lang is PCCL: the Koord text does not parse
    r = cli("fmt", "-", input=MESSY)
    assert r.exit_code == 2 and "<stdin>:" in r.output
    r = cli("fmt", "--lang", "koord", "--check", "-", input=MESSY)
    assert r.exit_code == 1


def test_fmt_lang_koord_rewrites_a_file_with_another_suffix(tmp_path):
    p = tmp_path / "prog.txt"
    p.write_text(MESSY)
    r = cli("fmt", "--lang", "koord", p)
    assert r.exit_code == 0 and p.read_text() == TIDY


def test_the_api_takes_lang(txt):
    res = api.explore(LOST.read_text(), source=True, lang="koord")
    ref = api.explore(LOST)
    assert res.violation is not None and res.stats.states == ref.stats.states == 4
    assert res.violation.trace == ref.violation.trace and len(res.violation.trace) == 2
    assert api.explore(txt, lang="koord").stats.states == ref.stats.states
    assert set(api.check(LOST.read_text(), source=True, lang="koord").variables) == {
        "sum", "added"}
    with pytest.raises(ArgumentError, match="lang must be None, 'pccl' or 'koord'"):
        api.explore(LOST, lang="python")
    with pytest.raises(ArgumentError, match="lang must be None"):
        api.check(LOST, lang="k")
