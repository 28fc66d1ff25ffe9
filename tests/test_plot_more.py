"""Plots: a failed doReach is marked; programs without motion get a timeline."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("matplotlib")
import matplotlib.image as mpimg  # noqa: E402

from pccl.output import plot as P  # noqa: E402
from pccl.api import explore, make_model  # noqa: E402
from conftest import cli

ROOT = Path(__file__).resolve().parent.parent
WALL_SOURCE = '// One robot drives at a wall: straight fails its doReach; used by test_failed_doreach_is_marked.\nloc:\n  boolean go = true;\n\nGo():\n  pre(go);\n  eff:\n    doReach(ItemPosition(4, 0), getObs());\n    go = false;\n\nCheck():\n  pre(!go && doReach_fail);\n  eff:\n    assert(false);\n'  # noqa: E501
WALL_WORLD_SOURCE = '# A wall between the robot and its target (tests/programs/wall.pccl).\nagents = 1\nresolution = 0.01\nradius = 0.25\nspeed = 1.0\nstart = [[0, 0]]\n\n[[obstacles]]\npolygon = [[1.5, -1], [2.5, -1], [2.5, 1], [1.5, 1]]\n'  # noqa: E501
FISCHER = ROOT / "programs" / "fischer.pccl"
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
