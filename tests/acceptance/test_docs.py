"""The documentation is tested: every example in README.md and docs/*.md runs.

Conventions (also described in docs/tutorial.md, "How the examples are
tested"):

* A fenced block ```` ```console ```` is a terminal session.  Lines starting
  with ``$ `` are commands; a command ending in ``\\`` continues on the next
  line.  The lines up to the next command are its expected output: stdout and
  stderr together, as a terminal shows them.  Commands run one after the other
  in a shell (``bash -c``), from the repository root, with this Python's
  ``bin`` directory (hence ``pccl``) first on PATH.  A command must exit 0,
  unless it shows its status itself (``…; echo "exit $?"``): a doc never hides
  a failing command.
* Comparison is line by line after normalisation (:func:`normalise`):
  trailing whitespace and trailing blank lines are ignored, and the digits of
  volatile statistics (lines starting with ``seconds``, ``states/second``,
  ``peak memory``, ``fingerprints`` and the JSON keys ``"seconds"``,
  ``"states_per_second"``, ``"peak_memory_bytes"``,
  ``"collision_probability"``) (with their separators ``,`` and ``.``) are
  replaced by one ``N`` per number.  A line that is exactly ``...`` in the
  expected output matches any number of lines (zero or more).
* A fenced block ```` ```python ```` containing ``>>>`` prompts is run with
  :mod:`doctest` (option ELLIPSIS), from the repository root; the blocks of
  one document run in order and share their names, like one session.
* A fenced block whose info string has ``file=PATH`` (```` ```pccl
  file=docs/examples/patrol.pccl ````) shows that file: its text must equal
  the file's.
* Every other block is illustrative and not run (```` ```pccl ````,
  ```` ```toml ````, ```` ```sh ```` for commands too slow to test, ```` ```text ````).
  Every block must name its language: a bare ```` ``` ```` is an error, so
  that an untested command cannot slip in unnoticed.

Regenerating: ``PCCL_REGEN_DOCS=1 python -m pytest tests/acceptance/test_docs.py``
rewrites, in place, the expected output of every console block that no
longer matches and every ``file=`` listing that differs from its file.  A
block that still matches is left alone, and so is every line of a rewritten
block that still matches (masked figures do not churn).  In a block with ``...`` lines the
elisions are kept: the lines before the first ``...`` are replaced by as many
first lines of the new output, the lines after the last by as many last
lines, and lines between two ``...`` by the lines of the new output they
best match.  Review the result with ``git diff``.  Doctest blocks are not
rewritten.
"""

from __future__ import annotations

import difflib
import doctest
import os
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOC_FILES = [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md"))
REGEN = os.environ.get("PCCL_REGEN_DOCS", "") not in ("", "0")
# lua, elisp: editor set-up in docs/editors.md (illustrative, not run)
LANGUAGES = {"console", "sh", "pccl", "toml", "python", "text", "json", "lua", "elisp", "koord"}
TIMEOUT = 60            # seconds per command (a command should take < ~5 s)

WILDCARD = "..."
VOLATILE = re.compile(
    r'^\s*(seconds|states/second|peak memory|fingerprints|"seconds"|'
    r'"states_per_second"|"peak_memory_bytes"|"collision_probability")')
_FENCE = re.compile(r"^(`{3,}|~{3,})(.*)$")


# --------------------------------------------------------------------------
# Parsing
# --------------------------------------------------------------------------

@dataclass
class Block:
    path: Path
    line: int              # 1-based line of the opening fence
    fence: str             # the opening fence line
    info: str              # the info string: "console", "pccl file=x", ...
    body: list[str]        # the lines between the fences

    @property
    def lang(self) -> str:
        return self.info.split()[0] if self.info.split() else ""

    @property
    def file(self):
        m = re.search(r"\bfile=(\S+)", self.info)
        return m.group(1) if m else None

    @property
    def id(self) -> str:
        return f"{self.path.relative_to(ROOT)}:{self.line}"


def blocks_of(path: Path) -> list[Block]:
    out, lines = [], path.read_text(encoding="utf-8").split("\n")
    k = 0
    while k < len(lines):
        m = _FENCE.match(lines[k])
        if not m:
            k += 1
            continue
        fence, info = m.group(1), m.group(2).strip()
        end = k + 1
        while end < len(lines) and not (lines[end].startswith(fence[0] * len(fence))
                                        and lines[end].strip(fence[0]) == ""):
            end += 1
        out.append(Block(path, k + 1, lines[k], info, lines[k + 1:end]))
        k = end + 1
    return out


ALL_BLOCKS = [b for p in DOC_FILES for b in blocks_of(p)]


def session(block: Block) -> list[tuple[str, list[str]]]:
    """A console block as [(command, expected output lines)]."""
    steps: list[tuple[str, list[str]]] = []
    lines = iter(block.body)
    for line in lines:
        if line.startswith("$ "):
            cmd = line[2:]
            while cmd.endswith("\\"):
                cmd = cmd[:-1] + "\n" + next(lines, "")
            steps.append((cmd, []))
        elif steps:
            steps[-1][1].append(line)
        elif line.strip():
            raise AssertionError(f"{block.id}: output before the first `$ ` command")
    return steps


# --------------------------------------------------------------------------
# Running and comparing
# --------------------------------------------------------------------------

def run_command(cmd: str, tmp: Optional[Path] = None) -> tuple[int, list[str]]:
    """Run one ``$`` command.  With ``tmp``, the docs' ``/tmp/`` paths become
    that private folder (and back again in the output), so that two blocks
    run at once (pytest -n 2, or two checkouts on one machine) never share a
    file."""
    if tmp is not None:
        cmd = cmd.replace("/tmp/", f"{tmp}/")
    env = dict(os.environ)
    env["PATH"] = str(Path(sys.executable).parent) + os.pathsep + env.get("PATH", "")
    env.update(PYTHONUNBUFFERED="1", PYTHONIOENCODING="utf-8", COLUMNS="80",
               NO_COLOR="1", TERM="dumb")
    env.pop("PCCL_REGEN_DOCS", None)
    p = subprocess.run(["bash", "-c", cmd], cwd=ROOT, env=env, stdout=subprocess.PIPE,
                       stderr=subprocess.STDOUT, timeout=TIMEOUT)
    out = p.stdout.decode("utf-8", "replace")
    if tmp is not None:
        out = out.replace(f"{tmp}/", "/tmp/")
    return p.returncode, out.split("\n")


def normalise(lines: list[str]) -> list[str]:
    out = [ln.rstrip() for ln in lines]
    out = [re.sub(r"\d[\d,.]*", "N", ln) if VOLATILE.match(ln) else ln for ln in out]
    while out and not out[-1]:
        out.pop()
    return out


def matches(expected: list[str], actual: list[str]) -> bool:
    exp, act = normalise(expected), normalise(actual)
    if not any(ln.strip() == WILDCARD for ln in exp):
        return exp == act
    pattern = "".join(r"(?:[^\n]*\n)*?" if ln.strip() == WILDCARD else re.escape(ln) + r"\n"
                      for ln in exp)
    return re.fullmatch(pattern, "".join(ln + "\n" for ln in act)) is not None


def regenerate(expected: list[str], actual: list[str]) -> list[str]:
    """New expected output from ``actual``, keeping the ``...`` elisions."""
    act = [ln.rstrip() for ln in actual]
    while act and not act[-1]:
        act.pop()
    if not any(ln.strip() == WILDCARD for ln in expected):
        return act
    segs: list[list[str]] = [[]]
    for ln in expected:
        if ln.strip() == WILDCARD:
            segs.append([])
        else:
            segs[-1].append(ln)
    first, middle, last = segs[0], segs[1:-1], segs[-1]
    head = act[:len(first)]
    tail = act[len(act) - len(last):] if last else []
    lo, hi = len(head), len(act) - len(tail)
    out = head + [WILDCARD]
    for seg in middle:
        if not seg:
            continue
        window = normalise(act[lo:hi])
        sm = difflib.SequenceMatcher(None, normalise(seg), window, autojunk=False)
        blk = max(sm.get_matching_blocks(), key=lambda b: b.size)
        if blk.size == 0:
            continue                      # the segment no longer occurs: drop it
        start = max(lo, lo + blk.b - blk.a)
        new = act[start:min(hi, start + len(seg))]
        out += new + [WILDCARD]
        lo = start + len(new)
    return out + tail


def keep_unchanged(old: list[str], new: list[str]) -> list[str]:
    """``new``, but where a line equals an ``old`` one after normalisation,
    the old line: regenerating does not churn the masked figures."""
    sm = difflib.SequenceMatcher(None, normalise(old), normalise(new), autojunk=False)
    out = list(new)
    for tag, i1, i2, j1, j2 in sm.get_opcodes():
        if tag == "equal":
            out[j1:j2] = old[i1:i2]
    return out


def diff(expected: list[str], actual: list[str]) -> str:
    return "\n".join(difflib.unified_diff(normalise(expected), normalise(actual),
                                          "expected", "actual", lineterm=""))


def rewrite(block: Block, new_body: list[str]) -> None:
    """Replace the block's body in its file (located by its text, since
    earlier rewrites may have moved it)."""
    text = block.path.read_text(encoding="utf-8")
    old = "\n".join([block.fence] + block.body) + "\n"
    new = "\n".join([block.fence] + new_body) + "\n"
    assert old in text, f"{block.id}: block changed on disk; run again"
    block.path.write_text(text.replace(old, new), encoding="utf-8")
    block.body = new_body


# --------------------------------------------------------------------------
# Tests
# --------------------------------------------------------------------------

def _ids(kind):
    return [b for b in ALL_BLOCKS if kind(b)]


CONSOLE = _ids(lambda b: b.lang == "console")
DOCTESTS = _ids(lambda b: b.lang == "python" and not b.file
                and any(ln.lstrip().startswith(">>>") for ln in b.body))
LISTINGS = _ids(lambda b: b.file is not None)


def _documents(blocks) -> dict:
    """The console blocks of each document, in order.  One document's blocks
    form one shell session (a later block reads the files an earlier one
    wrote), so they run in one test, in order: under ``pytest -n`` two
    workers never split a document.  (xdist's ``--dist loadgroup`` would do
    it per block, but it does not group under pytest 9.)"""
    docs: dict = {}
    for b in blocks:
        docs.setdefault(str(b.path.relative_to(ROOT)), []).append(b)
    return docs


CONSOLE_DOCS = _documents(CONSOLE)


def run_block(block: Block, tmp: Path) -> list[str]:
    """Run one console block's commands; its failures (regenerated in place
    with PCCL_REGEN_DOCS=1, except a failing command)."""
    steps = session(block)
    assert steps, f"{block.id}: a console block without a `$ ` command"
    new_body, failures, statuses = [], [], []
    for cmd, expected in steps:
        status, actual = run_command(cmd, tmp)
        if status != 0 and "$?" not in cmd:
            statuses.append(f"$ {cmd}\nexited {status}: show the status in the doc "
                            f"(`{cmd}; echo \"exit $?\"`) or fix the command\n"
                            + "\n".join(actual))
        ok = matches(expected, actual)
        if not ok:
            failures.append(f"$ {cmd}\n{diff(expected, actual)}")
        cmd_lines = ("$ " + cmd.replace("\n", "\\\n")).split("\n")
        new_body += cmd_lines + (expected if ok else
                                  keep_unchanged(expected, regenerate(expected, actual)))
    if REGEN and failures:
        rewrite(block, new_body)
        failures = []
    return [f"{block.id}:\n" + "\n\n".join(failures + statuses)] if failures or statuses else []


@pytest.mark.parametrize("doc", sorted(CONSOLE_DOCS))
def test_console_blocks(doc: str, tmp_path: Path):
    """Every console block of one document, in order, in one session; the
    docs' ``/tmp/`` is this test's own folder (two runs at once on one
    machine never share a file)."""
    failures = [f for block in CONSOLE_DOCS[doc] for f in run_block(block, tmp_path)]
    assert not failures, "\n\n".join(failures)


DOCTEST_FILES = sorted({b.path for b in DOCTESTS})


@pytest.mark.parametrize("path", DOCTEST_FILES, ids=lambda p: str(p.relative_to(ROOT)))
def test_python_blocks(path: Path, monkeypatch):
    """The doctest blocks of one document run in order, sharing their names
    (like one interpreter session)."""
    monkeypatch.chdir(ROOT)
    globs: dict = {}
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
    report: list[str] = []
    for block in (b for b in DOCTESTS if b.path == path):
        text = "\n".join(block.body) + "\n"
        test = doctest.DocTestParser().get_doctest(text, globs, block.id, str(block.path),
                                                  block.line)
        runner.run(test, out=report.append, clear_globs=False)
        globs.update(test.globs)          # get_doctest copied them
    assert runner.failures == 0, "".join(report)


@pytest.mark.parametrize("block", LISTINGS, ids=lambda b: b.id)
def test_listing_matches_file(block: Block):
    path = ROOT / block.file
    assert path.is_file(), f"{block.id}: no such file {block.file}"
    want = path.read_text(encoding="utf-8").rstrip("\n").split("\n")
    if [ln.rstrip() for ln in block.body] != [ln.rstrip() for ln in want]:
        if REGEN:
            rewrite(block, want)
            return
        raise AssertionError(f"{block.id}: differs from {block.file}\n"
                             + "\n".join(difflib.unified_diff(block.body, want, "doc",
                                                              block.file, lineterm="")))


def test_every_block_names_its_language():
    bad = [f"{b.id}: ```{b.info}" for b in ALL_BLOCKS if b.lang not in LANGUAGES]
    assert not bad, ("fenced blocks must name one of " + ", ".join(sorted(LANGUAGES))
                     + ":\n" + "\n".join(bad))


def test_no_reference_outside_the_repository():
    """Users learn the language from docs/language.md, not from a spec
    outside the repository."""
    bad = [f"{p.relative_to(ROOT)}:{k}" for p in DOC_FILES
           for k, ln in enumerate(p.read_text(encoding="utf-8").split("\n"), 1)
           if "../shared" in ln or "/work/shared" in ln]
    assert not bad, "references outside the repository: " + ", ".join(bad)


def _slug(heading: str) -> str:
    """GitHub's anchor for a heading."""
    h = re.sub(r"[`*_]", "", heading.strip().lower())
    return re.sub(r"[^\w\- ]", "", h).replace(" ", "-")


def _anchors(path: Path) -> set[str]:
    text = re.sub(r"^```.*?^```", "", path.read_text(encoding="utf-8"), flags=re.M | re.S)
    return {_slug(m.group(1)) for m in re.finditer(r"^#+ (.*)$", text, flags=re.M)}


def test_relative_links_resolve():
    """Every relative link in the documents names an existing file, and an
    anchor (#...) names a heading of that file."""
    bad = []
    for p in DOC_FILES:
        text = re.sub(r"^```.*?^```", "", p.read_text(encoding="utf-8"), flags=re.M | re.S)
        for m in re.finditer(r"\]\(([^)\s]+)\)", text):
            target = m.group(1)
            if re.match(r"[a-z]+:", target):
                continue                              # http:, https:, mailto:
            file, _, anchor = target.partition("#")
            dest = (p.parent / file).resolve() if file else p
            if not dest.exists():
                bad.append(f"{p.relative_to(ROOT)}: {target} (no such file)")
            elif anchor and dest.suffix == ".md" and anchor not in _anchors(dest):
                bad.append(f"{p.relative_to(ROOT)}: {target} (no such heading)")
    assert not bad, "broken links:\n" + "\n".join(bad)


# ---- the harness itself ----------------------------------------------------

def test_wildcard_and_normalisation():
    assert matches(["a", "...", "z"], ["a", "b", "c", "z"])
    assert matches(["a", "...", "z"], ["a", "z"])
    assert not matches(["a", "...", "z"], ["a", "b"])
    assert matches(["  seconds          0.01"], ["  seconds          12.34  "])
    assert not matches(["  states           10"], ["  states           11"])
    assert regenerate(["a", "...", "c", "...", "z"], ["A", "b", "c", "d", "Z"]) == \
        ["A", "...", "c", "...", "Z"]
    assert regenerate(["x"], ["y", ""]) == ["y"]


def _json_examples():
    """Every JSON example: ```json blocks, and the expected output of each
    console command that prints JSON (its output starts with ``{``)."""
    out = []
    for b in ALL_BLOCKS:
        if b.lang == "json":
            out.append((b.id, "\n".join(b.body)))
        elif b.lang == "console":
            for cmd, expected in session(b):
                text = "\n".join(expected)
                if text.lstrip().startswith(("{", "[")) and "--format json" in cmd:
                    out.append((f"{b.id} ({cmd[:40]}…)", text))
    return out


def test_every_json_example_parses():
    """Issue 27: a JSON example must be valid JSON (no `...` elisions in it:
    filter the output instead)."""
    import json
    examples = _json_examples()
    assert examples
    bad = []
    for where, text in examples:
        try:
            json.loads(text)
        except ValueError as e:
            try:                    # JSON lines: one value per line
                for ln in text.splitlines():
                    if ln.strip():
                        json.loads(ln)
            except ValueError:
                bad.append(f"{where}: {e}")
    assert not bad, "\n".join(bad)
