"""Plots (--plot): PNG size and content for runs and counterexamples, the
plotting API directly, the message when matplotlib is missing, a failed
doReach marked, and a timeline for programs without motion."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("matplotlib")
import matplotlib.image as mpimg  # noqa: E402

from pccl.output import plot as P  # noqa: E402
from pccl.api import explore, make_model  # noqa: E402
from conftest import cli

ROOT = Path(__file__).resolve().parents[2]
PROGRAMS = ROOT / "programs"
RACE = PROGRAMS / "race.pccl"
RACE_NA = PROGRAMS / "race_nonatomic.pccl"
RACE_WORLD = PROGRAMS / "race.toml"
RACE_OBS = PROGRAMS / "race_obstacles.toml"
FISCHER = PROGRAMS / "fischer.pccl"
COLLIDE = PROGRAMS / "collide.pccl"
FIXED = PROGRAMS / "collide_fixed.pccl"
COLLIDE_WORLD = PROGRAMS / "collide.toml"

BLUE = (31, 119, 180)      # tab10: agent 0
ORANGE = (255, 127, 14)    # tab10: agent 1




def all_output(res) -> str:
    out = res.output
    try:
        err = res.stderr
    except ValueError:
        err = ""
    return out + ("" if err in out else err)


def read_png(path: Path) -> np.ndarray:
    assert path.is_file() and path.stat().st_size > 0
    img = mpimg.imread(str(path))
    assert img.shape[:2] == (600, 800), img.shape
    return (img[:, :, :3] * 255).round().astype(np.int32)


def distinct_colours(rgb: np.ndarray) -> int:
    flat = rgb.reshape(-1, 3)
    return len(np.unique(flat[:, 0] * 65536 + flat[:, 1] * 256 + flat[:, 2]))


def non_white_fraction(rgb: np.ndarray) -> float:
    return float((rgb.min(axis=2) < 245).mean())


def has_colour(rgb: np.ndarray, colour, tol=12, min_pixels=20) -> bool:
    d = np.abs(rgb - np.array(colour)).max(axis=2)
    return int((d <= tol).sum()) >= min_pixels


def red_pixels(rgb: np.ndarray) -> int:
    r, g, b = rgb[:, :, 0], rgb[:, :, 1], rgb[:, :, 2]
    return int(((r > 200) & (g < 60) & (b < 60)).sum())


# ----------------------------------------------------------------------
# through the CLI
# ----------------------------------------------------------------------

def test_run_plot_race(tmp_path):
    out = tmp_path / "out.png"
    res = cli("run", RACE, "--world", RACE_WORLD, "--plot", out)
    assert res.exit_code == 0, res.output
    assert f"plot written to {out}" in res.output
    rgb = read_png(out)
    assert distinct_colours(rgb) > 50
    assert 0.02 < non_white_fraction(rgb) < 0.9
    assert has_colour(rgb, BLUE) and has_colour(rgb, ORANGE)
    assert red_pixels(rgb) < 50          # a clean run: no violation ring


def test_explore_plot_race_nonatomic_counterexample(tmp_path):
    out = tmp_path / "trace.png"
    res = cli("explore", RACE_NA, "--world", RACE_WORLD, "--blackbox", "instant",
              "--plot", out, "--no-progress")
    assert res.exit_code == 1, res.output
    assert "stuck" in res.output and f"plot written to {out}" in res.output
    rgb = read_png(out)
    assert distinct_colours(rgb) > 50
    assert 0.02 < non_white_fraction(rgb) < 0.9
    assert has_colour(rgb, BLUE) and has_colour(rgb, ORANGE)
    assert red_pixels(rgb) > 200         # the red ring and the red message


def test_explore_plot_collision(tmp_path):
    out = tmp_path / "collide.png"
    res = cli("explore", COLLIDE, "--world", COLLIDE_WORLD, "--collisions",
              "--plot", out, "--no-progress")
    assert res.exit_code == 1, res.output
    rgb = read_png(out)
    assert red_pixels(rgb) > 200
    assert has_colour(rgb, BLUE) and has_colour(rgb, ORANGE)


def test_run_plot_with_obstacles_and_pymunk(tmp_path):
    out = tmp_path / "obs.png"
    res = cli("run", RACE, "--world", RACE_OBS, "--blackbox", "pymunk", "--plot", out)
    assert res.exit_code in (0, 1), res.output
    rgb = read_png(out)
    assert has_colour(rgb, (158, 158, 158), tol=20, min_pixels=500)   # obstacle grey


def test_run_plot_without_motion(tmp_path):
    out = tmp_path / "still.png"
    res = cli("run", FISCHER, "--max-time", "8", "--plot", out)
    assert res.exit_code in (0, 1), res.output
    rgb = read_png(out)
    assert distinct_colours(rgb) > 20
    assert has_colour(rgb, BLUE) and has_colour(rgb, ORANGE)


def test_run_plot_violation_is_highlighted(tmp_path):
    out = tmp_path / "run_collide.png"
    res = cli("run", COLLIDE, "--world", COLLIDE_WORLD, "--collisions", "--plot", out)
    assert res.exit_code == 1, res.output
    assert red_pixels(read_png(out)) > 200


def test_plot_svg_extension_follows_format(tmp_path):
    out = tmp_path / "race.svg"
    res = cli("run", RACE, "--world", RACE_WORLD, "--plot", out)
    assert res.exit_code == 0, res.output
    assert out.read_text().lstrip().startswith("<?xml")


# ----------------------------------------------------------------------
# the API
# ----------------------------------------------------------------------

def test_plot_trace_api_and_title(tmp_path):
    from pccl.api import explore
    from pccl.output.plot import plot_trace
    r = explore(str(COLLIDE), world=str(COLLIDE_WORLD), collisions=True)
    raw = list(r.counterexamples[0].trace)
    assert raw[0][0] is None
    out = tmp_path / "t.png"
    plot_trace(r.model, raw, out, title=r.violation["message"])
    rgb = read_png(out)
    assert red_pixels(rgb) > 200
    # without a title, the culprits are still ringed
    out2 = tmp_path / "t2.png"
    plot_trace(r.model, raw, out2)
    assert red_pixels(read_png(out2)) > 100


def test_plot_trace_of_only_the_initial_state(tmp_path):
    from pccl.api import make_model
    from pccl.output.plot import plot_trace
    m = make_model(str(FISCHER))
    out = tmp_path / "init.png"
    plot_trace(m, [(None, next(iter(m.init_states())))], out, title="initial state")
    read_png(out)


def test_plot_run_api_without_trace(tmp_path):
    from pccl.api import run
    from pccl.output.plot import plot_run
    res = run(str(FIXED), world=str(COLLIDE_WORLD), collisions=True)
    assert res.status == "final" and res.trace is None      # not recorded
    out = tmp_path / "r.png"
    plot_run(res.model, res, out)
    rgb = read_png(out)
    assert has_colour(rgb, BLUE) and has_colour(rgb, ORANGE)


def test_plot_to_unwritable_path_is_a_pccl_error(tmp_path):
    from pccl.api import run
    from pccl.lang.errors import PcclError
    from pccl.output.plot import plot_run
    res = run(str(FIXED), world=str(COLLIDE_WORLD))
    with pytest.raises(PcclError, match="cannot write plot: No such file"):
        plot_run(res.model, res, tmp_path / "no" / "such" / "dir" / "x.png")


def test_importing_plot_leaves_pyplot_backend_alone():
    import matplotlib
    before = matplotlib.get_backend() if "matplotlib.pyplot" in sys.modules else None
    import pccl.output.plot  # noqa: F401
    if before is not None:
        assert matplotlib.get_backend() == before


# ----------------------------------------------------------------------
# matplotlib missing
# ----------------------------------------------------------------------

@pytest.fixture
def no_matplotlib(monkeypatch):
    for name in list(sys.modules):
        if name == "matplotlib" or name.startswith("matplotlib."):
            monkeypatch.setitem(sys.modules, name, None)
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    monkeypatch.delitem(sys.modules, "pccl.output.plot", raising=False)
    import builtins
    real_import = builtins.__import__

    def fake_import(name, *args, **kwargs):
        if name == "matplotlib" or name.startswith("matplotlib."):
            raise ImportError(f"No module named '{name}'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", fake_import)
    yield
    monkeypatch.delitem(sys.modules, "pccl.output.plot", raising=False)


def test_run_plot_without_matplotlib(no_matplotlib, tmp_path):
    out = tmp_path / "out.png"
    res = cli("run", RACE, "--world", RACE_WORLD, "--plot", out)
    text = all_output(res)
    assert res.exit_code == 2, text
    assert "--plot needs matplotlib" in text and "pip install" in text
    assert "Traceback" not in text
    assert not out.exists()


def test_explore_plot_without_matplotlib(no_matplotlib, tmp_path):
    out = tmp_path / "trace.png"
    res = cli("explore", RACE_NA, "--world", RACE_WORLD, "--blackbox", "instant",
              "--plot", out, "--no-progress")
    text = all_output(res)
    assert res.exit_code == 2, text
    assert "--plot needs matplotlib" in text
    assert "Traceback" not in text
    assert not out.exists()


# --- a failed doReach is marked; programs without motion get a timeline ---

WALL_SOURCE = '// One robot drives at a wall: straight fails its doReach; used by test_failed_doreach_is_marked.\nloc:\n  boolean go = true;\n\nGo():\n  pre(go);\n  eff:\n    doReach(ItemPosition(4, 0), getObs());\n    go = false;\n\nCheck():\n  pre(!go && doReach_fail);\n  eff:\n    assert(false);\n'  # noqa: E501
WALL_WORLD_SOURCE = '# A wall between the robot and its target (tests/programs/wall.pccl).\nagents = 1\nresolution = 0.01\nradius = 0.25\nspeed = 1.0\nstart = [[0, 0]]\n\n[[obstacles]]\npolygon = [[1.5, -1], [2.5, -1], [2.5, 1], [1.5, 1]]\n'  # noqa: E501
LOST = ROOT / "docs" / "examples" / "lost_update.pccl"
TAB20_1 = (174, 199, 232)     # the second event's colour in a timeline
RED_X = (255, 0, 0)




def pixels(path) -> np.ndarray:
    img = mpimg.imread(str(path))
    assert img.shape[:2] == (600, 800)
    return (img[:, :, :3] * 255).round().astype(np.int32)


def count(rgb, colour) -> int:
    return int(np.all(rgb == np.array(colour), axis=-1).sum())


@pytest.fixture
def wall(tmp_path):
    (tmp_path / "wall.pccl").write_text(WALL_SOURCE)
    (tmp_path / "wall.toml").write_text(WALL_WORLD_SOURCE)
    return tmp_path / "wall.pccl", tmp_path / "wall.toml"


def test_failed_doreach_is_marked(tmp_path, wall):
    WALL, WALL_WORLD = wall
    r = explore(str(WALL), world=str(WALL_WORLD), blackbox="straight")
    assert r.status == "violation"
    states = list(r.counterexamples[0].trace.states)
    assert P._failures(states, 1) == [(0, (0.0, 0.0))]
    out = tmp_path / "w.png"
    res = cli("explore", WALL, "--world", WALL_WORLD, "-b", "straight", "--plot", out)
    assert res.exit_code == 1
    with_marker = count(pixels(out), RED_X)
    out2 = tmp_path / "w2.png"
    P.plot_trace(r.model, list(r.counterexamples[0].trace), out2)
    with_marker = count(pixels(out2), RED_X)
    assert with_marker > 0
    # the same drawing without the marker has fewer red pixels
    orig = P._failures
    try:
        P._failures = lambda states, n: []
        P.plot_trace(r.model, list(r.counterexamples[0].trace), tmp_path / "w3.png")
    finally:
        P._failures = orig
    assert count(pixels(tmp_path / "w3.png"), RED_X) < with_marker


def test_programs_without_motion_get_a_timeline(tmp_path, wall):
    WALL, WALL_WORLD = wall
    assert not P.has_motion(make_model(str(FISCHER)))
    assert P.has_motion(make_model(str(WALL), world=str(WALL_WORLD)))
    out = tmp_path / "f.png"
    res = cli("explore", FISCHER, "--set", "k=1", "--invariant", "count(inCs) <= 1", "--plot", out)
    assert res.exit_code == 1 and "plot written" in res.output
    rgb = pixels(out)
    assert count(rgb, TAB20_1) > 1000          # Wait blocks, as bars


def test_run_of_a_program_without_motion_plots_a_timeline(tmp_path):
    out = tmp_path / "l.png"
    res = cli("run", LOST, "--plot", out)
    assert res.exit_code == 0
    assert count(pixels(out), TAB20_1) > 1000   # Done blocks
