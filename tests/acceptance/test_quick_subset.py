"""Issue 27, item 8: ``python -m pytest -m "not slow"`` is a quick subset.

tests/conftest.py marks the tests listed in tests/slow_tests.txt as slow
(measured, README "Tests"); the list must name tests that exist."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import conftest

ROOT = Path(__file__).resolve().parents[2]


def test_the_slow_list_names_existing_tests():
    assert len(conftest.SLOW_TESTS) > 100
    for nid in conftest.SLOW_TESTS:
        path, _, rest = nid.partition("::")
        func = rest.split("[", 1)[0]
        src = (ROOT / path).read_text()
        assert re.search(rf"^def {re.escape(func)}\(", src, re.M), nid


def test_listed_tests_are_marked_slow(request):
    """The hook marks every listed test that this session collected."""
    items = [i for i in request.session.items if conftest.portable_id(i.nodeid) in conftest.SLOW_TESTS]
    assert all(i.get_closest_marker("slow") for i in items)


def test_readme_states_both_commands_and_the_figures_are_in_benchmarks():
    """The README's test section is the two commands and a line each; the
    measured durations of both live in docs/benchmarks.md ("The test suite")."""
    text = (ROOT / "README.md").read_text()
    assert 'python -m pytest -m "not slow"' in text and "python -m pytest -q -n 2" in text
    assert "docs/benchmarks.md#the-test-suite" in text
    bench = (ROOT / "docs" / "benchmarks.md").read_text()
    section = bench.split("## The test suite", 1)[1].split("\n## ", 1)[0]
    assert re.search(r"\d+ s", section) and "min" in section


def test_the_slow_list_holds_no_path_of_a_checkout():
    """A parameter that is a path is written relative to the repository
    (conftest.portable_id): an id holding one clone's absolute path
    (``[/work/h-polish/programs/...]``) never matched in another, and the
    test it named ran in the quick subset."""
    assert conftest.portable_id(f"t.py::f[{ROOT}/programs/a.pccl-kw0]") == \
        "t.py::f[programs/a.pccl-kw0]"
    assert not [nid for nid in conftest.SLOW_TESTS if re.search(r"[\[-]/", nid)]


@pytest.mark.slow
def test_every_listed_parametrized_test_is_collected():
    """Each listed id with parameters is the id of a collected test (as
    conftest.portable_id writes it), so the hook marks it."""
    import subprocess
    import sys
    listed = {nid for nid in conftest.SLOW_TESTS if "[" in nid}
    files = sorted({nid.split("::", 1)[0] for nid in listed})
    r = subprocess.run([sys.executable, "-m", "pytest", "--collect-only", "-q",
                        "-p", "no:cacheprovider", *files], cwd=ROOT, capture_output=True,
                       text=True, timeout=900)
    collected = {conftest.portable_id(ln.strip()) for ln in r.stdout.splitlines() if "::" in ln}
    assert len(collected) > len(listed), r.stdout[-2000:] + r.stderr[-2000:]
    assert sorted(listed - collected) == []
