"""pccl.lang.tomlpos: where keys, headers and array elements are written in TOML
text.  The positions are checked against tomllib itself: the text at a
located value, decoded on its own, is the value tomllib decoded from the
whole document."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from pccl.lang.tomlpos import TomlSource, Where, decode_error_location, long_integer_location

ROOT = Path(__file__).resolve().parents[2]
WORLDS = sorted((ROOT / "programs").glob("*.toml")) + sorted((ROOT / "docs" / "examples").glob("*.toml"))

TRICKY = '''\
# a comment with agents = 99 in it
agents = 3   # trailing comment
name = "x = [1, 2]"            # a string that looks like a key and an array
note = """
radius = 7
"""
start = [
  [0, 0],      # first
  # a comment line between elements
  [1.5, -2, 1],
  [ 3 , 4 ],
]
arena = [[-1, -1], [10, 10]]

[functions]
getInput = [[1, [2, 3]], "s,]", [4, 0]]
"quoted" = 5

[[obstacles]]
polygon = [[0, 0], [1, 0], [1, 1]]

[[obstacles]]
polygon = [
  [5, 5],
  [6, 5], [6, 6],
]
'''


def text_at(src: str, w: Where) -> str:
    return src.splitlines()[w.line - 1][w.column - 1:w.end_column - 1]


def decode_value(text: str):
    return tomllib.loads("v = " + text)["v"]


def paths(value, prefix=()):
    """Every array element path inside ``value``."""
    if isinstance(value, list):
        for i, x in enumerate(value):
            yield prefix + (i,)
            yield from paths(x, prefix + (i,))


def located_values(src: str):
    """(table, key, index, path, decoded value) for every key and every array
    element of every one-line value in ``src``."""
    data = tomllib.loads(src)
    out = []

    def table_items(table, items, index=0):
        for key, value in items.items():
            if isinstance(value, dict) or (isinstance(value, list) and value
                                           and isinstance(value[0], dict)):
                continue      # a table, an array of tables: not a value
            out.append((table, key, index, (), value))
            for p in paths(value):
                v = value
                for i in p:
                    v = v[i]
                out.append((table, key, index, p, v))

    table_items(None, data)
    for name, value in data.items():
        if isinstance(value, dict):
            table_items(name, value)
        elif isinstance(value, list) and value and all(isinstance(t, dict) for t in value):
            for k, t in enumerate(value):
                table_items(name, t, k)
    return out


@pytest.mark.parametrize("src", [TRICKY] + [p.read_text() for p in WORLDS],
                         ids=["tricky"] + [p.name for p in WORLDS])
def test_the_text_at_every_located_element_decodes_to_its_value(src):
    ts = TomlSource(src)
    checked = 0
    for table, key, index, path, value in located_values(src):
        w = ts.locate(table, key, index, path=path)
        assert w is not None, (table, key, path)
        text = text_at(src, w)
        if not path and (text.count("[") != text.count("]") or text == '"""'):
            continue          # a value over several lines: located by its first line
        assert decode_value(text) == value, (table, key, path, text)
        checked += 1
    assert checked > (20 if src is TRICKY else 0)


def test_keys_and_headers():
    ts = TomlSource(TRICKY)
    # the key itself (not its value), skipping comments, strings and continuation lines
    assert ts.locate(None, "agents", at_value=False) == Where(2, 1, 7)
    assert ts.locate(None, "agents") == Where(2, 10, 11)
    assert ts.locate(None, "radius") is None           # only inside a multi-line string
    assert ts.locate("functions", "quoted", at_value=False) == Where(17, 1, 9)
    # the second [[obstacles]] table's polygon, element 2 on a continuation line
    assert ts.locate("obstacles", "polygon", 1, path=(2,)) == Where(25, 11, 17)
    assert text_at(TRICKY, ts.locate("obstacles", "polygon", 0, path=(1, 0))) == "1"
    # elements across lines and comments
    assert text_at(TRICKY, ts.locate(None, "start", path=(1,))) == "[1.5, -2, 1]"
    assert text_at(TRICKY, ts.locate(None, "start", path=(2, 1))) == "4"
    assert text_at(TRICKY, ts.locate("functions", "getInput", path=(1,))) == '"s,]"'
    assert text_at(TRICKY, ts.locate("functions", "getInput", path=(0, 1, 1))) == "3"
    # past the end of an array: the whole value
    assert ts.locate(None, "arena", path=(5,)) == ts.locate(None, "arena")
    # a table named by its header when no key is written: [functions] itself
    assert ts.locate(None, "functions") == Where(15, 1, 12)


def test_decode_error_location_and_long_integers():
    src = "agents = 2\nradius = = 1\n"
    with pytest.raises(tomllib.TOMLDecodeError) as ei:
        tomllib.loads(src)
    msg, line, col = decode_error_location(ei.value, src)
    assert (line, col) == (2, 10) and "at line" not in msg
    src = "agents = 2\nstart = [[0, 0]"
    with pytest.raises(tomllib.TOMLDecodeError) as ei:
        tomllib.loads(src)
    msg, line, col = decode_error_location(ei.value, src)
    assert line == 2
    src = "a = 1\nb = " + "9" * 5000 + "\n"
    assert long_integer_location(src, 4300) == Where(2, 5, 5005)
    assert long_integer_location("a = 123\n", 4300) is None
