"""Program texts for robustness tests of several layers: mutants of a
source (``mutate``, ``truncations``: tests/oracle/test_fuzz.py,
tests/lang/test_parser_fast.py, tests/lang/test_koord.py) and large generated
programs (``generated``: tests/tools/test_lsp_robust.py, test_parser_fast.py)."""

from __future__ import annotations

import re


JUNK = ["@", "$$", "((", ")", ":", ";", "=", "==", "->", "[", "]", "'", '"', "/*", "//", "\t",
        "atomic:", "eff:", "pre(", "rand(", "0", "-1", "99999999999999999999", "1.5e308",
        "true", "ItemPosition", "List<", "x", "exit()", "while (true):", "é", "\\", "{", "}",
        "inf", "nan", "[[", "]]", "= [", "= \"", "#"]


def truncations(text, n=14):
    step = max(1, len(text) // n)
    return [(f"trunc{k}", text[:k]) for k in range(step, len(text), step)]


def mutate(text, rng, junk=JUNK):
    """One mutant of ``text``: ``(kind, text)``; ``junk`` the tokens it inserts."""
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
        return kind, text[:t.start()] + rng.choice(junk) + text[t.end():]
    elif kind == "indent":
        k = rng.randrange(len(lines))
        lines[k] = " " * rng.choice([1, 3, 5]) + lines[k]
    else:
        s = text
        for _ in range(rng.randint(1, 4)):
            p = rng.randrange(len(s) + 1)
            s = s[:p] + rng.choice(junk + list("(){}[]:;,.=<>!&|+-*/%\n ")) + s[p:]
        return "chars", s
    return kind, "\n".join(lines)


def mutant_cases(sources: dict, n_mut: int, rng, junk=JUNK, n_trunc: int = 14) -> list:
    """``pytest.param(name, text)`` per truncation (``n_trunc`` of them) and
    per mutant (``n_mut``, from ``rng``) of each of ``sources`` (name -> text,
    in the dict's order), with ids naming the mutation."""
    import pytest
    out = []
    for name, text in sources.items():
        for tag, t in truncations(text, n_trunc):
            out.append(pytest.param(name, t, id=f"{name}-{tag}"))
        for k in range(n_mut):
            kind, t = mutate(text, rng, junk)
            out.append(pytest.param(name, t, id=f"{name}-{kind}{k}"))
    return out


def generated(lines: int) -> str:
    """A program of about ``lines`` lines: a quarter shared declarations,
    the rest events of five lines (a guard, two assignments)."""
    nv = lines // 4
    out = ["allwrite:"] + [f"  int v{i} = {i % 7};" for i in range(nv)] + ["loc:", "  int x = 0;"]
    for i in range((lines - nv) // 5):
        out += [f"E{i}():", f"  pre(v{i % nv} >= 0);", "  eff:",
                f"    v{i % nv} = v{(i + 1) % nv} + 1;", f"    x = x + {i % 3};"]
    return "\n".join(out) + "\n"
