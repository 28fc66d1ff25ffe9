"""Highlighting: the Pygments lexer (pccl/tools/lexer.py, entry point ``pccl``)
and the TextMate grammar of the VS Code extension
(editors/vscode/syntaxes/pccl.tmLanguage.json), on every shipped, test and
docs program.  Each is compared with the formatter's tokeniser, which
mirrors grammar.lark: same comments, same numbers, same words."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest
from pygments.lexers import get_lexer_by_name, get_lexer_for_filename
from pygments.token import Comment, Error, Keyword, Name, Number, Whitespace

from pccl.tools.fmt import BCOMMENT, COMMENT, HDR, NUM, WORD, tokenize
from pccl.tools.lexer import PcclLexer

ROOT = Path(__file__).resolve().parents[2]
FILES = sorted([*(ROOT / "programs").glob("*.pccl"), *(ROOT / "tests" / "programs").glob("*.pccl"),
                *(ROOT / "docs" / "examples").glob("*.pccl"),
                *(ROOT / "tests" / "golden" / "checker").glob("*.pccl")])


def docs_blocks() -> list[tuple[str, str]]:
    """The ```pccl blocks of README.md and docs/*.md: (id, text)."""
    out = []
    for p in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        lines = p.read_text(encoding="utf-8").split("\n")
        k = 0
        while k < len(lines):
            if re.match(r"^```pccl\b", lines[k]):
                end = lines.index("```", k + 1)
                out.append((f"{p.name}:{k + 1}", "\n".join(lines[k + 1:end]) + "\n"))
                k = end
            k += 1
    return out


SOURCES = [(str(p.relative_to(ROOT)), p.read_text(encoding="utf-8")) for p in FILES] + docs_blocks()
IDS = [name for name, *_ in SOURCES]


def test_registered_as_pccl():
    assert isinstance(get_lexer_by_name("pccl"), PcclLexer)
    assert isinstance(get_lexer_for_filename("x.pccl"), PcclLexer)
    r = subprocess.run([sys.executable, "-m", "pygments", "-l", "pccl", "-f", "raw",
                        str(ROOT / "programs" / "fischer.pccl")], capture_output=True, text=True)
    assert r.returncode == 0 and "Token.Keyword.Namespace" in r.stdout and "Token.Error" not in r.stdout


@pytest.mark.parametrize("name,text", SOURCES, ids=IDS)
def test_pygments_lexer(name, text):
    toks = list(PcclLexer().get_tokens(text))
    assert "".join(v for _, v in toks) == text if text.endswith("\n") else text + "\n"
    assert [v for t, v in toks if t in Error] == []
    mine = tokenize(text)
    # comments and numbers: the same as the formatter's tokeniser finds
    assert [v for t, v in toks if t in Comment] == [t.text for t in mine if t.kind in (COMMENT, BCOMMENT)]
    assert [v for t, v in toks if t in Number] == [t.text for t in mine if t.kind == NUM]
    # every word is a keyword or a name of some kind, never plain text
    words = [t.text for t in mine if t.kind == WORD] + \
        [re.match(r"[A-Za-z]+", t.text).group() for t in mine if t.kind == HDR]
    lexed = [v for t, v in toks if (t in Keyword or t in Name) and re.fullmatch(r"[A-Za-z_]\w*", v)]
    assert sorted(lexed) == sorted(w for w in words)
    assert all(t in Whitespace or v.strip() for t, v in toks)


def test_pygments_token_kinds_on_fischer():
    text = (ROOT / "programs" / "fischer.pccl").read_text()
    kinds = {(str(t), v) for t, v in PcclLexer().get_tokens(text)}
    assert ("Token.Name.Class", "Fischer") in kinds
    assert ("Token.Keyword.Namespace", "allwrite") in kinds
    assert ("Token.Name.Function", "Start") in kinds
    assert ("Token.Name.Builtin", "rand") in kinds
    assert ("Token.Keyword", "atomic") in kinds and ("Token.Keyword.Type", "int") in kinds
    assert ("Token.Name", "reqid") in kinds


# --------------------------------------------------------------------------
# The TextMate grammar.  No Oniguruma here: the grammar keeps to regexes
# whose meaning is the same in Python's re (checked below), and this is a
# faithful tokeniser for its shape (top-level match rules, and begin/end
# rules for block comments, tried at each position, earliest match first,
# then the first rule in order, as vscode-textmate does).
# --------------------------------------------------------------------------

GRAMMAR = json.loads((ROOT / "editors" / "vscode" / "syntaxes" / "pccl.tmLanguage.json").read_text())
#: constructs of Oniguruma that Python reads differently or not at all
_ONIG_ONLY = re.compile(r"\\[hHAzZGK]|\(\?<[a-z]|\\p\{|\[\[:|\(\?>|\\x\{")


def _rules() -> list[dict]:
    out = []
    for p in GRAMMAR["patterns"]:
        if "include" in p:
            out.extend(GRAMMAR["repository"][p["include"][1:]]["patterns"])
        else:
            out.append(p)
    return out


def tm_tokens(text: str) -> list[tuple[str, str]]:
    """(scope, text) for every token the grammar gives, line by line."""
    rules = [(r, re.compile(r.get("match") or r["begin"])) for r in _rules()]
    out: list[tuple[str, str]] = []
    in_block: str | None = None
    for line in text.split("\n"):
        k = 0
        while k < len(line):
            if in_block is not None:
                m = re.compile(in_block).search(line, k)
                end = m.end() if m else len(line)
                out.append(("comment.block.pccl", line[k:end]))
                k = end
                if m:
                    in_block = None
                continue
            best = None
            for rule, rx in rules:
                m = rx.search(line, k)
                if m and (best is None or m.start() < best[1].start()):
                    best = (rule, m)
            if best is None:
                break
            rule, m = best
            if m.start() > k:
                out.append(("", line[k:m.start()]))
            if "begin" in rule:
                e = re.compile(rule["end"]).search(line, m.end())
                end = e.end() if e else len(line)
                out.append((rule["name"], line[m.start():end]))
                if not e:
                    in_block = rule["end"]
                k = end
                continue
            caps = rule.get("captures")
            if caps:
                pos = m.start()
                for g in sorted(int(n) for n in caps):
                    if m.start(g) < 0:
                        continue
                    if m.start(g) > pos:
                        out.append((rule["name"], line[pos:m.start(g)]))
                    out.append((caps[str(g)]["name"], m.group(g)))
                    pos = m.end(g)
                if m.end() > pos:
                    out.append((rule["name"], line[pos:m.end()]))
            else:
                out.append((rule["name"], m.group()))
            k = max(m.end(), k + 1)
        if k < len(line):
            out.append(("", line[k:]))
    return out


def test_grammar_regexes_are_in_the_common_subset():
    for rule in _rules():
        for key in ("match", "begin", "end"):
            if key in rule:
                assert not _ONIG_ONLY.search(rule[key]), rule[key]
                re.compile(rule[key])
    assert GRAMMAR["scopeName"] == "source.pccl"
    pkg = json.loads((ROOT / "editors" / "vscode" / "package.json").read_text())
    assert pkg["contributes"]["grammars"][0]["scopeName"] == "source.pccl"
    conf = json.loads((ROOT / "editors" / "vscode" / "language-configuration.json").read_text())
    assert conf["comments"] == {"lineComment": "//", "blockComment": ["/*", "*/"]}


@pytest.mark.parametrize("name,text", SOURCES + [("block", "loc:\n  /* a\n b */ int x = 1; // c\n")],
                         ids=IDS + ["multi-line block comment"])
def test_textmate_grammar(name, text):
    toks = tm_tokens(text)
    # nothing but white space is left unscoped
    assert [v for s, v in toks if not s and v.strip()] == []
    mine = tokenize(text)
    comments = [v for s, v in toks if s.startswith("comment")]
    # a block comment over several lines comes line by line
    assert "\n".join(comments) == "\n".join(t.text for t in mine if t.kind in (COMMENT, BCOMMENT))
    assert [v for s, v in toks if s.startswith("constant.numeric")] == \
        [t.text for t in mine if t.kind == NUM]
    # the same scope for a word as Pygments gives, by kind
    pyg = {v: str(t) for t, v in PcclLexer().get_tokens(text)}
    for s, v in toks:
        if s.startswith("keyword.control.section"):
            assert pyg.get(v) == "Token.Keyword.Namespace", (v, s)
        elif s == "keyword.control.pccl":
            assert pyg.get(v) == "Token.Keyword", (v, s)


def test_textmate_scopes_on_fischer():
    toks = set(tm_tokens((ROOT / "programs" / "fischer.pccl").read_text()))
    assert ("entity.name.type.agent.pccl", "Fischer") in toks
    assert ("keyword.control.section.pccl", "allwrite") in toks
    assert ("entity.name.function.event.pccl", "Start") in toks
    assert ("support.function.builtin.pccl", "rand") in toks
    assert ("keyword.control.pccl", "atomic") in toks
    assert ("constant.numeric.integer.pccl", "10") in toks
    assert ("comment.line.double-slash.pccl", "// Fischer's protocol: Figure 6 of the PCCL paper, made legible.") \
        in toks
    assert ("variable.other.pccl", "reqid") in toks
