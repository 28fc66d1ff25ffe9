"""Issue 27, item 8: ``python -m pytest -m "not slow"`` is a quick subset.

tests/conftest.py marks the tests listed in tests/slow_tests.txt as slow
(measured, README "Tests"); the list must name tests that exist."""

from __future__ import annotations

import re
from pathlib import Path

import conftest

ROOT = Path(__file__).resolve().parent.parent


def test_the_slow_list_names_existing_tests():
    assert len(conftest.SLOW_TESTS) > 100
    for nid in conftest.SLOW_TESTS:
        path, _, rest = nid.partition("::")
        func = rest.split("[", 1)[0]
        src = (ROOT / path).read_text()
        assert re.search(rf"^def {re.escape(func)}\(", src, re.M), nid


def test_listed_tests_are_marked_slow(request):
    """The hook marks every listed test that this session collected."""
    items = [i for i in request.session.items if i.nodeid in conftest.SLOW_TESTS]
    assert all(i.get_closest_marker("slow") for i in items)


def test_readme_states_both_durations():
    text = (ROOT / "README.md").read_text()
    assert 'python -m pytest -m "not slow"' in text
    section = text.split('python -m pytest -m "not slow"', 1)[1][:1500]
    assert re.search(r"\d+ s", section) and "minutes" in section
