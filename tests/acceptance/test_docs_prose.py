"""The prose around the documentation's console blocks is tested too
(issue 44.7): test_docs.py holds every console block equal to what the
command prints; this file holds the sentences that *describe* a block to
what it shows.  A claim is a sentence form the checker knows, written in the
paragraphs after a console block (up to the next block or heading):

* ``step N: robot R`` / ``steps N–M: robot R`` (an emphasised clause
  ``*...*`` after the colon is skipped): those steps of the counterexample
  are agent R's;
* ``symmetry is on`` / ``symmetry is off``: the header's reductions;
* ``robot R is **stuck** at line L``: the verdict;
* ``robots A and B collide``: the collision verdict's pair;
* ``takes the dock at x = X`` after ``robot R``: not checked (free text).

Every claim found is checked against the block's expected output (which
test_docs.py holds equal to the real output), and each document that has
such sentences must have at least one claim found, so the checker cannot
pass by reading nothing.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from test_docs import ROOT, blocks_of

DOCS = [ROOT / "README.md", ROOT / "docs" / "tutorial.md", ROOT / "docs" / "blackboxes.md",
        ROOT / "docs" / "language.md", ROOT / "docs" / "temporal.md"]

STEP = re.compile(r"^\s*(\d+)\. t=\S+\s+agent (\d+)\s")
STEP_CLAIM = re.compile(r"\bsteps? (\d+)(?:\s*[–-]\s*(\d+))?: robots? (\d+)")
SYM_CLAIM = re.compile(r"\bsymmetry is (on|off)\b")
STUCK_CLAIM = re.compile(r"\brobot (\d+) is \*\*stuck\*\* at line (\d+)")
COLLIDE_CLAIM = re.compile(r"\brobots (\d+) and (\d+) collide")


def _prose_after(path: Path) -> list:
    """[(block, prose)] for every console block of ``path``: the text after
    it up to the next fenced block or section heading (``#``, ``##``)."""
    lines = path.read_text(encoding="utf-8").split("\n")
    blocks = blocks_of(path)
    out = []
    for k, b in enumerate(blocks):
        if b.lang != "console":
            continue
        start = b.line + len(b.body) + 1          # the line after the closing fence
        end = blocks[k + 1].line - 1 if k + 1 < len(blocks) else len(lines)
        prose = []
        for ln in lines[start:end]:
            if re.match(r"#{1,2} ", ln):
                break
            prose.append(ln)
        out.append((b, " ".join(prose)))
    return out


def claims(path: Path) -> list:
    """Every claim of ``path`` as ``(block, kind, text, check)``; ``check()``
    returns an error message or None."""
    found = []
    for b, prose in _prose_after(path):
        body = b.body
        steps = {int(m.group(1)): int(m.group(2)) for m in map(STEP.match, body) if m}
        header = next((ln for ln in body if ln.startswith("pccl ") and "reductions" in ln), "")
        verdict = next((ln for ln in body if ln.startswith(("violation:", "no violation"))), "")
        # emphasised clauses skipped (``*before robot 0 removes it*,``), not bullets
        flat = re.sub(r"(?<![*\w])\*(?=[^\s*])[^*]+?(?<=\S)\*(?!\*),?\s*", "", prose)
        for m in STEP_CLAIM.finditer(flat):
            lo, hi, who = int(m.group(1)), int(m.group(2) or m.group(1)), int(m.group(3))

            def check(lo=lo, hi=hi, who=who, steps=steps):
                bad = [n for n in range(lo, hi + 1) if steps.get(n) != who]
                return (f"steps {lo}-{hi} are not all agent {who}'s: "
                        + ", ".join(f"{n}: agent {steps.get(n)}" for n in bad)) if bad else None
            found.append((b, "step", m.group(0), check))
        for m in SYM_CLAIM.finditer(prose):
            on = m.group(1) == "on"

            def check(on=on, header=header):
                red = re.search(r"reductions (\S+?)[;,]", header)
                has = bool(red) and "symmetry" in red.group(1).split("+")
                return None if has == on else f"the header says reductions {red.group(1) if red else '?'}"
            found.append((b, "symmetry", m.group(0), check))
        for m in STUCK_CLAIM.finditer(prose):
            who, line = m.group(1), m.group(2)

            def check(who=who, line=line, verdict=verdict, body=body):
                ok = f"agent {who} stuck" in verdict and any(
                    re.search(rf":{line}:\d+$", ln.strip()) for ln in body)
                return None if ok else f"the verdict is {verdict!r}"
            found.append((b, "stuck", m.group(0), check))
        for m in COLLIDE_CLAIM.finditer(prose):
            pair = {m.group(1), m.group(2)}

            def check(pair=pair, verdict=verdict):
                got = set(re.findall(r"agent (\d+) at", verdict)) if "collision" in verdict else set()
                return None if got == pair else f"the verdict is {verdict!r}"
            found.append((b, "collide", m.group(0), check))
    return found


CLAIMS = [c for p in DOCS for c in claims(p)]


@pytest.mark.parametrize("claim", CLAIMS, ids=[f"{c[0].id}:{c[1]}:{c[2]}" for c in CLAIMS])
def test_prose_claim_matches_its_block(claim):
    block, kind, text, check = claim
    err = check()
    assert err is None, f"{block.id}: the prose says {text!r}, but {err}"


def test_the_tutorial_has_claims_of_every_kind():
    kinds = {c[1] for c in claims(ROOT / "docs" / "tutorial.md")}
    assert kinds >= {"step", "symmetry", "stuck", "collide"}


def test_the_command_reference_lists_every_command():
    # language.md §13 is the complete list: every command `pccl --help` shows
    from pccl.cli import main
    text = (ROOT / "docs" / "language.md").read_text(encoding="utf-8")
    section = text[text.index("## 13. Commands"):]
    rows = set(re.findall(r"^\| `pccl (\w+)", section, flags=re.M))
    assert set(main.commands) <= rows, sorted(set(main.commands) - rows)
    assert "--html" in section


def test_the_help_names_no_deprecated_option():
    from click.testing import CliRunner
    from pccl.cli import main
    out = CliRunner().invoke(main, ["--help"]).output
    assert "simulate PROGRAM --runs N" in out and " -n N" not in out
