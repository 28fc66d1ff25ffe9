"""Robustness: truncated and mutated versions of the shipped programs and
world files, fed to ``pccl check``, ``pccl run --max-time 3`` and
``pccl explore --depth 30`` in-process.  Whatever the input, the tool exits
with 0, 1 or 2, and a 2 is one rendered error (``file:line:col: error:``),
never a traceback.

The mutants are generated from a fixed seed, so the cases are the same on
every run; a failing case's id names the mutation.
"""

from __future__ import annotations

import random
import re

import pytest
from click.testing import CliRunner

from pccl.cli import main

from conftest import PROGRAMS, RACE, RACE_WORLD

SEED = 20240517
SOURCES = {name: (PROGRAMS / name).read_text()
           for name in ("fischer.pccl", "race.pccl", "race_nonatomic.pccl")}
WORLDS = {name: (PROGRAMS / name).read_text() for name in ("race.toml", "race_obstacles.toml")}

JUNK = ["@", "$$", "((", ")", ":", ";", "=", "==", "->", "[", "]", "'", '"', "/*", "//", "\t",
        "atomic:", "eff:", "pre(", "rand(", "0", "-1", "99999999999999999999", "1.5e308",
        "true", "ItemPosition", "List<", "x", "exit()", "while (true):", "é", "\\", "{", "}",
        "inf", "nan", "[[", "]]", "= [", "= \"", "#"]


def truncations(text, n=14):
    step = max(1, len(text) // n)
    return [(f"trunc{k}", text[:k]) for k in range(step, len(text), step)]


def mutate(text, rng):
    lines = text.split("\n")
    kind = rng.choice(["delete", "duplicate", "swap", "token", "chars", "indent"])
    if kind == "delete" and len(lines) > 1:
        del lines[rng.randrange(len(lines))]
    elif kind == "duplicate":
        k = rng.randrange(len(lines))
        lines.insert(k, lines[k])
    elif kind == "swap" and len(lines) > 1:
        a, b = rng.randrange(len(lines)), rng.randrange(len(lines))
        lines[a], lines[b] = lines[b], lines[a]
    elif kind == "token":
        toks = list(re.finditer(r"\w+|[^\w\s]+", text))
        t = rng.choice(toks)
        return kind, text[:t.start()] + rng.choice(JUNK) + text[t.end():]
    elif kind == "indent":
        k = rng.randrange(len(lines))
        lines[k] = " " * rng.choice([1, 3, 5]) + lines[k]
    else:
        s = text
        for _ in range(rng.randint(1, 4)):
            p = rng.randrange(len(s) + 1)
            s = s[:p] + rng.choice(JUNK + list("(){}[]:;,.=<>!&|+-*/%\n ")) + s[p:]
        return "chars", s
    return kind, "\n".join(lines)


def cases(sources, n_mut, salt):
    rng = random.Random(SEED + salt)
    out = []
    for name, text in sorted(sources.items()):
        for tag, t in truncations(text):
            out.append(pytest.param(name, t, id=f"{name}-{tag}"))
        for k in range(n_mut):
            kind, t = mutate(text, rng)
            out.append(pytest.param(name, t, id=f"{name}-{kind}{k}"))
    return out


def invoke(args):
    res = CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=True)
    cmd = "pccl " + " ".join(map(str, args))
    assert res.exception is None or isinstance(res.exception, SystemExit), \
        f"{cmd} raised {type(res.exception).__name__}: {res.exception}"
    assert res.exit_code in (0, 1, 2), f"{cmd}: exit {res.exit_code}\n{res.output}"
    assert "Traceback" not in res.output, res.output
    if res.exit_code == 2:
        err = res.stderr
        assert err.count(": error: ") == 1, f"{cmd}: not one rendered error:\n{err}"
        assert res.stdout == ""
    return res


@pytest.mark.parametrize("name, text", cases(SOURCES, 45, 0))
def test_mutated_program(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(text)
    world = ["--world", RACE_WORLD] if name.startswith("race") else []
    c = invoke(["check", p])
    r = invoke(["run", p, *world, "--max-time", "3", "--max-steps", "3000", "--blackbox", "instant"])
    e = invoke(["explore", p, *world, "--depth", "30", "--max-states", "3000"])
    if c.exit_code == 2:
        # a program that does not load fails the same way everywhere
        assert r.exit_code == 2 and e.exit_code == 2
        assert r.stderr == c.stderr == e.stderr
    else:
        assert c.exit_code == 0


@pytest.mark.parametrize("name, text", cases(WORLDS, 35, 1))
def test_mutated_world(tmp_path, name, text):
    w = tmp_path / name
    w.write_text(text)
    c = invoke(["check", RACE, "--world", w])
    r = invoke(["run", RACE, "--world", w, "--max-time", "3"])
    e = invoke(["explore", RACE, "--world", w, "--depth", "30", "--max-states", "3000"])
    if c.exit_code == 2:
        assert str(w) in c.stderr
        assert r.exit_code == 2 and e.exit_code == 2


def test_fuzz_corpus_is_varied():
    """The generated corpus exercises all three outcomes of check (guards
    against a mutator that only ever produces garbage)."""
    codes = set()
    rng = random.Random(SEED)
    text = SOURCES["race.pccl"]
    ok = 0
    for _ in range(40):
        _, t = mutate(text, rng)
        try:
            from pccl.checker import check_program
            from pccl.parser import parse_program
            check_program(parse_program(t, "m.pccl"))
            ok += 1
        except Exception as exc:           # PcclError expected
            codes.add(type(exc).__name__)
    assert 0 < ok < 40
    assert codes == {"PcclError"}
