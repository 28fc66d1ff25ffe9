"""World files: loading, defaults, automatic layout, and every error rendered
with file:line:column (golden)."""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

import pytest

from pccl.lang.errors import PcclError
from pccl.lang.world import World, default_world, load_world, parse_world

PROGRAMS = Path(__file__).resolve().parents[2] / "programs"


def render_error(source: str, filename: str = "w.toml") -> str:
    with pytest.raises(PcclError) as info:
        parse_world(textwrap.dedent(source).lstrip("\n"), filename)
    return info.value.render()


# ----------------------------------------------------------------------
# good files
# ----------------------------------------------------------------------

FULL = """
agents = 3
resolution = 0.05
radius = 0.2
mass = 2
speed = 1.5
tolerance = 0.1
no_progress_time = 4
arena = [[-1, -1], [10, 5]]
start = [
  [0, 0],
  [1, 2, 3],   # with z
]

[functions]
getInput = [[1, 1], [4, 0]]
flag = true
name = "alpha"
nested = [[1, [2, 3]], []]

[[obstacles]]
polygon = [[2, 2], [3, 2], [3, 3]]

[[obstacles]]
polygon = [[5, 0], [6, 0], [6, 1], [5, 1]]
"""


@pytest.mark.parametrize("value, name", [("true", "boolean"), ("2.0", "float"), ('"two"', "string"),
                                         ("[2]", "array"), ("{ n = 2 }", "table"),
                                         ("1979-05-27", "date/time")])
def test_a_value_of_another_type_is_named_in_toml_words(value, name):
    # every kind of TOML value, named as TOML names it (pccl/lang/data.py)
    with pytest.raises(PcclError) as e:
        parse_world(f"agents = {value}\n", "w.toml")
    assert e.value.message == f"'agents' must be an integer, got {name}"


def test_full_file_parses():
    w = parse_world(FULL, "full.toml")
    assert w.n_agents == 3
    assert w.resolution == 0.05 and w.radius == 0.2 and w.mass == 2.0
    assert w.speed == 1.5 and w.tolerance == 0.1 and w.no_progress_time == 4.0
    assert w.arena == ((-1.0, -1.0), (10.0, 5.0))
    assert w.starts == ((0.0, 0.0, 0.0), (1.0, 2.0, 3.0))
    assert w.obstacles == (((2.0, 2.0), (3.0, 2.0), (3.0, 3.0)),
                           ((5.0, 0.0), (6.0, 0.0), (6.0, 1.0), (5.0, 1.0)))
    f = w.functions_dict()
    assert f["getInput"] == ((1, 1), (4, 0))
    assert f["flag"] is True and f["name"] == "alpha"
    assert f["nested"] == ((1, (2, 3)), ())
    # getObs not given: the world's obstacles
    assert f["getObs"] == w.obstacles
    assert w.filename == "full.toml"
    hash(w)  # blackboxes cache on worlds


def test_functions_are_sorted_and_getobs_explicit():
    w = parse_world("[functions]\nzeta = 1\ngetObs = [[[0, 0], [1, 0], [1, 1]]]\n")
    assert [name for name, _ in w.functions] == ["getInput", "getObs", "zeta"]
    assert w.functions_dict()["getObs"] == (((0, 0), (1, 0), (1, 1)),)
    assert w.functions_dict()["getInput"] == ()
    assert w.obstacles == ()


def test_defaults():
    w = parse_world("")
    assert w.n_agents is None and w.starts == () and w.arena is None
    assert w.resolution == 0.01 and w.radius == 0.25 and w.speed == 1.0
    assert w.mass == 1.0 and w.no_progress_time == 3.0
    assert w.tolerance == pytest.approx(5 * w.resolution)
    assert w.functions_dict() == {"getInput": (), "getObs": ()}
    assert parse_world("resolution = 0.1\n").tolerance == pytest.approx(0.5)


def test_default_world():
    w = default_world()
    assert w.functions_dict() == {"getInput": (), "getObs": ()}
    assert w.obstacles == () and w.filename is None
    pos = w.start_positions(3)
    assert pos == ((0.0, 0.0, 0.0), (0.75, 0.0, 0.0), (1.5, 0.0, 0.0))
    assert w == World(functions=(("getInput", ()), ("getObs", ())))


@pytest.mark.parametrize("name", ["race.toml", "race_obstacles.toml"])
def test_shipped_worlds_load(name):
    w = load_world(PROGRAMS / name)
    assert w.n_agents == 2
    assert len(w.functions_dict()["getInput"]) == 3
    assert w.functions_dict()["getObs"] == w.obstacles
    assert len(w.start_positions(2)) == 2
    if name == "race_obstacles.toml":
        assert len(w.obstacles) == 2


def test_race_world_arrival_times_differ_under_straight():
    """The two robots reach the first destination at clearly different steps."""
    w = load_world(PROGRAMS / "race.toml")
    d1 = w.functions_dict()["getInput"][0]
    (a, b) = w.start_positions(2)
    steps = [math.ceil(math.dist(p[:2], d1) / w.speed - 1e-9) for p in (a, b)]
    assert abs(steps[0] - steps[1]) >= 3


def test_more_starts_than_agents_is_fine():
    w = parse_world("agents = 1\nstart = [[0, 0], [5, 5]]\n")
    assert w.start_positions(1) == ((0.0, 0.0, 0.0),)


# ----------------------------------------------------------------------
# automatic layout
# ----------------------------------------------------------------------

def _check_layout(w: World, pos, n_given: int):
    assert pos[:n_given] == w.starts[:n_given]
    import shapely
    polys = [shapely.Polygon(p) for p in w.obstacles]
    for i, p in enumerate(pos):
        for q in pos[:i]:
            assert math.dist(p[:2], q[:2]) >= 3 * w.radius - 1e-9
        if i >= n_given:
            for g in polys:
                assert g.distance(shapely.Point(p[:2])) >= 1.5 * w.radius
            if w.arena:
                (x0, y0), (x1, y1) = w.arena
                assert x0 + w.radius <= p[0] <= x1 - w.radius
                assert y0 + w.radius <= p[1] <= y1 - w.radius


def test_auto_layout_on_a_line_skips_starts_and_obstacles():
    w = parse_world(textwrap.dedent("""
        start = [[0, 0], [2.2, 0]]
        [[obstacles]]
        polygon = [[3, -1], [4, -1], [4, 1], [3, 1]]
    """))
    pos = w.start_positions(6)
    _check_layout(w, pos, 2)
    # 1.5 is too close to the start at 2.2; 2.25 .. 3.75 too close to the
    # obstacle (1.5 * radius clearance)
    assert pos[2:] == ((0.75, 0.0, 0.0), (4.5, 0.0, 0.0), (5.25, 0.0, 0.0),
                       (6.0, 0.0, 0.0))
    assert w.start_positions(6) == pos  # deterministic


def test_auto_layout_in_arena_grid():
    w = parse_world(textwrap.dedent("""
        arena = [[0, 0], [3, 3]]
        start = [[1.5, 1.5]]
    """))
    pos = w.start_positions(6)
    _check_layout(w, pos, 1)
    assert pos[1] == (0.38, 0.38, 0.0)


def test_auto_layout_arena_too_small():
    w = parse_world("arena = [[0, 0], [1, 1]]\n", "small.toml")
    assert len(w.start_positions(1)) == 1
    with pytest.raises(PcclError) as info:
        w.start_positions(3)
    assert info.value.render() == (
        "small.toml: error: cannot place 3 agents: the arena has room for "
        "only 1 (robots are laid out 0.75 apart)")


def test_more_agents_than_starts_with_race_world():
    w = load_world(PROGRAMS / "race.toml")
    pos = w.start_positions(5)
    _check_layout(w, pos, 2)


# ----------------------------------------------------------------------
# errors, golden
# ----------------------------------------------------------------------

def test_missing_file(tmp_path):
    path = tmp_path / "nope.toml"
    with pytest.raises(PcclError) as info:
        load_world(path)
    assert info.value.render() == f"{path}: error: world file not found: {path}"


def test_directory_is_an_error(tmp_path):
    with pytest.raises(PcclError) as info:
        load_world(tmp_path)
    assert "world file is a directory" in info.value.render()


def test_load_world_reads_file_and_reports_its_name(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text("agents = 2\nspeed = 0\n")
    with pytest.raises(PcclError) as info:
        load_world(path)
    assert info.value.render() == (
        f"{path}:2:9: error: 'speed' must be positive, got 0\n"
        "    2 | speed = 0\n"
        "      |         ^")
    assert info.value.filename == str(path)


GOLDEN = {
    "toml_syntax": ("""
        agents = 2
        speed = = 1
        """, """\
w.toml:2:9: error: invalid TOML: Invalid value
    2 | speed = = 1
      |         ^"""),
    "toml_unclosed": ("""
        agents = [1, 2
        """, """\
w.toml:1:15: error: invalid TOML: Unclosed array at end of file
    1 | agents = [1, 2
      |               ^"""),
    "unknown_key": ("""
        agents = 2
        sped = 1.0
        """, """\
w.toml:2:1: error: unknown key 'sped' in world file; allowed keys: agents, arena, functions, mass, no_progress_time, obstacles, radius, resolution, speed, start, tolerance
    2 | sped = 1.0
      | ^^^^"""),
    "wrong_type": ("""
        agents = 2
        resolution = "fine"
        """, """\
w.toml:2:14: error: 'resolution' must be a number, got string
    2 | resolution = "fine"
      |              ^^^^^^"""),
    "zero_resolution": ("""
        resolution = 0
        """, """\
w.toml:1:14: error: 'resolution' must be positive, got 0
    1 | resolution = 0
      |              ^"""),
    "negative_speed": ("""
        # a comment
        speed = -1.5  # too slow
        """, """\
w.toml:2:9: error: 'speed' must be positive, got -1.5
    2 | speed = -1.5  # too slow
      |         ^^^^"""),
    "boolean_radius": ("""
        radius = true
        """, """\
w.toml:1:10: error: 'radius' must be a number, got boolean
    1 | radius = true
      |          ^^^^"""),
    "agents_zero": ("""
        agents = 0
        """, """\
w.toml:1:10: error: 'agents' must be at least 1, got 0
    1 | agents = 0
      |          ^"""),
    "agents_float": ("""
        agents = 2.5
        """, """\
w.toml:1:10: error: 'agents' must be an integer, got float
    1 | agents = 2.5
      |          ^^^"""),
    "bad_start_entry_multiline": ("""
        start = [
          [0, 0],  # first
          [1],
        ]
        speed = 2
        """, """\
w.toml:3:3: error: 'start' entry 2 must be [x, y] or [x, y, z] (numbers)
    3 |   [1],
      |   ^^^"""),
    "bad_arena": ("""
        arena = [[0, 0], [-1, 5]]
        """, """\
w.toml:1:9: error: 'arena' must be [[xmin, ymin], [xmax, ymax]] with xmin < xmax and ymin < ymax
    1 | arena = [[0, 0], [-1, 5]]
      |         ^^^^^^^^^^^^^^^^^"""),
    "polygon_two_points": ("""
        agents = 1

        [[obstacles]]
        polygon = [[0, 0], [1, 0]]
        """, """\
w.toml:4:11: error: obstacle 1: 'polygon' needs at least 3 points, got 2
    4 | polygon = [[0, 0], [1, 0]]
      |           ^^^^^^^^^^^^^^^^"""),
    "polygon_self_intersecting": ("""
        [[obstacles]]
        polygon = [[0, 0], [1, 0], [1, 1], [0, 1]]

        [[obstacles]]
        polygon = [[0, 0], [1, 1], [1, 0], [0, 1]]
        """, """\
w.toml:5:11: error: obstacle 2: 'polygon' is not a valid polygon (self-intersection at (0.5, 0.5))
    5 | polygon = [[0, 0], [1, 1], [1, 0], [0, 1]]
      |           ^^^^^^^^^^^^^^^^^^^^^^^^^^^^^^^^"""),
    "polygon_bad_point": ("""
        [[obstacles]]
        polygon = [
          [0, 0],
          [1, 0],
          [1, "x"],
        ]
        """, """\
w.toml:5:3: error: obstacle 1: 'polygon': point 3 must be [x, y] (numbers)
    5 |   [1, "x"],
      |   ^^^^^^^^"""),
    "polygon_zero_area": ("""
        [[obstacles]]
        polygon = [[0, 0], [1, 1], [2, 2]]
        """, None),
    "obstacle_unknown_key": ("""
        [[obstacles]]
        polygon = [[0, 0], [1, 0], [1, 1]]
        color = "red"
        """, """\
w.toml:3:1: error: unknown key 'color' in obstacle 1; allowed keys: polygon
    3 | color = "red"
      | ^^^^^"""),
    "obstacle_without_polygon": ("""
        agents = 1
        [[obstacles]]
        """, """\
w.toml:2:1: error: obstacle 1 has no 'polygon'
    2 | [[obstacles]]
      | ^^^^^^^^^^^^^"""),
    "obstacles_not_tables": ("""
        obstacles = [[0, 0], [1, 0], [1, 1]]
        """, """\
w.toml:1:13: error: 'obstacles' must be an array of tables: write each obstacle as [[obstacles]] with polygon = [[x, y], ...]
    1 | obstacles = [[0, 0], [1, 0], [1, 1]]
      |             ^^^^^^^^^^^^^^^^^^^^^^^^"""),
    "function_table_value": ("""
        [functions]
        getInput = [[1, 1]]
        weird = {a = 1}
        """, """\
w.toml:3:9: error: function 'weird': unsupported value of type table (use numbers, booleans, strings and arrays)
    3 | weird = {a = 1}
      |         ^^^^^^^"""),
    "getobs_bad_polygon": ("""
        [functions]
        getObs = [[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 0]]]
        """, """\
w.toml:2:37: error: 'getObs' polygon 2 needs at least 3 points, got 2
    2 | getObs = [[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 0]]]
      |                                     ^^^^^^^^^^^^^^^^"""),
    "functions_not_table": ("""
        functions = 3
        """, """\
w.toml:1:13: error: 'functions' must be a table: write [functions] and then name = value lines
    1 | functions = 3
      |             ^"""),
    "key_after_multiline_array": ("""
        start = [
          [0, 0],
          [1, 0],
        ]
        mass = -2
        """, """\
w.toml:5:8: error: 'mass' must be positive, got -2
    5 | mass = -2
      |        ^^"""),
    "same_key_in_function_table": ("""
        speed = 1
        [functions]
        speed = 3
        radius = [1, 2]
        [[obstacles]]
        polygon = [[0, 0], [1, 0], [1, 1]]
        radius = 2
        """, """\
w.toml:7:1: error: unknown key 'radius' in obstacle 1; allowed keys: polygon
    7 | radius = 2
      | ^^^^^^"""),
    "unknown_table": ("""
        agents = 1
        [foo]  # not a world table
        x = 1
        """, """\
w.toml:2:1: error: unknown key 'foo' in world file; allowed keys: agents, arena, functions, mass, no_progress_time, obstacles, radius, resolution, speed, start, tolerance
    2 | [foo]  # not a world table
      | ^^^^^"""),
    "second_obstacle_without_polygon": ("""
        [[obstacles]]
        polygon = [[0, 0], [1, 0], [1, 1]]
        [[obstacles]]
        """, """\
w.toml:3:1: error: obstacle 2 has no 'polygon'
    3 | [[obstacles]]
      | ^^^^^^^^^^^^^"""),
    "functions_array_of_tables": ("""
        [[functions]]
        a = 1
        """, """\
w.toml:1:1: error: 'functions' must be a table: write [functions] and then name = value lines
    1 | [[functions]]
      | ^^^^^^^^^^^^^"""),
    "nan": ("""
        speed = nan
        """, """\
w.toml:1:9: error: 'speed' must be a finite number, got nan
    1 | speed = nan
      |         ^^^"""),
}


@pytest.mark.parametrize("case", sorted(GOLDEN))
def test_error_golden(case):
    source, expected = GOLDEN[case]
    got = render_error(source)
    if expected is None:
        assert "w.toml:2:11: error: obstacle 1: 'polygon'" in got
    else:
        assert got == expected


def test_errors_are_pccl_errors_with_location():
    with pytest.raises(PcclError) as info:
        parse_world("agents = 2\nresolution = -0.1\n", "w.toml")
    err = info.value
    assert (err.filename, err.line, err.column) == ("w.toml", 2, 14)
    assert err.source.startswith("agents = 2")


# ---------------------------------------------------------------------------
# issue 27, item 3: pccl check --world runs the checks run and explore run
# ---------------------------------------------------------------------------

def _cli(*args):
    from conftest import cli as _c
    return _c(*args)


RACE_PROGRAM = Path(__file__).resolve().parents[2] / "programs" / "race.pccl"


@pytest.mark.parametrize("body, line, col, words", [
    ("agents = 2\nstart = [[0, 0], [5, 0]]\n\n[functions]\ngetInput = [1, 2, 3]\n", 5, 12,
     ["value of getInput() (read at", "race.pccl:7:30) does not fit List<ItemPosition>"]),
    ("agents = 2\nstart = [[0, 0], [0.3, 0]]\n", 2, 18,
     ["'start' entry 2 (0.3, 0) overlaps entry 1 (0, 0)"]),
    ("agents = 2\narena = [[0, 0], [4, 4]]\nstart = [[1, 1], [5, 1]]\n", 3, 18,
     ["'start' entry 2 (5, 1) lies outside the arena"]),
    ("agents = 1\nstart = [[1, 1]]\n[[obstacles]]\npolygon = [[0, 0], [2, 0], [2, 2], [0, 2]]\n",
     2, 10, ["'start' entry 1 (1, 1) lies inside obstacle 1"]),
])
def test_check_world_runs_the_world_checks(tmp_path, body, line, col, words):
    """check --world said ok for these; run then failed (a bad getInput at
    the program's line).  Now check, run and explore give one message, at
    the world file's line and column."""
    w = tmp_path / "w.toml"
    w.write_text(body)
    outs = []
    for cmd in ("check", "run", "explore"):
        res = _cli(cmd, RACE_PROGRAM, "--world", w)
        assert res.exit_code == 2, (cmd, res.output)
        assert "Traceback" not in res.output
        first = res.output.splitlines()[0]
        assert first.startswith(f"{w}:{line}:{col}: error: "), (cmd, first)
        for word in words:
            assert word in first, (cmd, first)
        outs.append(res.output)
    assert outs[0] == outs[1] == outs[2]


def test_check_world_ok_for_the_shipped_worlds():
    root = Path(__file__).resolve().parents[2]
    for prog, world in [("programs/race.pccl", "programs/race.toml"),
                        ("programs/collide_fixed.pccl", "programs/collide.toml"),
                        ("docs/examples/dock.pccl", "docs/examples/dock.toml")]:
        res = _cli("check", root / prog, "--world", root / world)
        assert res.exit_code == 0 and ": ok (" in res.output, res.output
