"""Collision checking (pccl.model.collide) and the swap programs that exercise it:
programs/collide.pccl collides, programs/collide_fixed.pccl does not."""

from __future__ import annotations

import math
import time
from pathlib import Path

import pytest

from pccl.api import explore
from pccl.model.collide import EPS, collisions, contacts
from pccl.lang.world import World, load_world, parse_world
from conftest import cli

ROOT = Path(__file__).resolve().parents[2]
PROGRAMS = ROOT / "programs"
COLLIDE = str(PROGRAMS / "collide.pccl")
FIXED = str(PROGRAMS / "collide_fixed.pccl")
WORLD = str(PROGRAMS / "collide.toml")

SQUARE = ((2.0, 2.0), (3.0, 2.0), (3.0, 3.0), (2.0, 3.0))
TRIANGLE = ((6.0, 0.0), (8.0, 0.0), (7.0, 1.0))


def world(radius=0.25, obstacles=()):
    return World(radius=radius, obstacles=tuple(obstacles))




# ----------------------------------------------------------------------
# agent pairs
# ----------------------------------------------------------------------

def test_no_agents_or_one_agent():
    assert collisions(world(), ()) == []
    assert collisions(world(), ((0.0, 0.0, 0.0),)) == []


def test_far_apart_pair_is_clear():
    assert collisions(world(), ((0, 0, 0), (3, 0, 0))) == []


def test_overlapping_pair_names_agents_and_positions():
    msgs = collisions(world(), ((0.0, 0.0, 0.0), (0.3, 0.2, 0.0)))
    assert len(msgs) == 1
    m = msgs[0]
    assert "agent 0 at (0, 0)" in m and "agent 1 at (0.3, 0.2)" in m
    assert "overlap" in m and "2 × radius 0.5" in m
    (c,) = contacts(world(), ((0.0, 0.0, 0.0), (0.3, 0.2, 0.0)))
    assert (c.i, c.j, c.obstacle) == (0, 1, None)
    assert c.distance == pytest.approx(math.hypot(0.3, 0.2))


def test_threshold_is_strict_with_epsilon():
    r = 0.25
    # exactly touching: not a collision
    assert collisions(world(r), ((0, 0, 0), (2 * r, 0, 0))) == []
    # within the epsilon of touching: not a collision
    assert collisions(world(r), ((0, 0, 0), (2 * r - EPS / 10, 0, 0))) == []
    # clearly overlapping
    assert len(collisions(world(r), ((0, 0, 0), (2 * r - 1e-6, 0, 0)))) == 1
    # same position
    assert len(collisions(world(r), ((1, 1, 0), (1, 1, 0)))) == 1
    # diagonal: distance sqrt(0.18) ~ 0.424 < 0.5
    assert len(collisions(world(r), ((0, 0, 0), (0.3, 0.3, 0)))) == 1
    # diagonal just outside: 0.36, 0.36 -> 0.509
    assert collisions(world(r), ((0, 0, 0), (0.36, 0.36, 0))) == []


def test_radius_comes_from_the_world():
    pos = ((0, 0, 0), (1.5, 0, 0))
    assert collisions(world(0.25), pos) == []
    assert len(collisions(world(1.0), pos)) == 1


def test_z_is_ignored_footprints_are_planar():
    assert len(collisions(world(), ((0, 0, 0), (0.1, 0, 5.0)))) == 1


def test_two_dimensional_positions_are_accepted():
    assert len(collisions(world(), ((0, 0), (0.1, 0)))) == 1


def test_every_pair_in_order():
    pos = ((0, 0, 0), (0.2, 0, 0), (0.4, 0, 0), (5, 5, 0))
    cs = contacts(world(), pos)
    assert [(c.i, c.j) for c in cs] == [(0, 1), (0, 2), (1, 2)]
    msgs = collisions(world(), pos)
    assert msgs[0].startswith("collision: agent 0 at (0, 0) and agent 1 at (0.2, 0)")
    assert "agent 3" not in " ".join(msgs)


def test_pair_message_golden():
    (m,) = collisions(world(), ((1.0, 0.0, 0.0), (1.25, 0.0, 0.0)))
    assert m == ("collision: agent 0 at (1, 0) and agent 1 at (1.25, 0) overlap "
                 "(centre distance 0.25 < 2 × radius 0.5)")


# ----------------------------------------------------------------------
# obstacles
# ----------------------------------------------------------------------

def test_agent_inside_obstacle():
    w = world(obstacles=(SQUARE,))
    (m,) = collisions(w, ((2.5, 2.5, 0.0),))
    assert m == "collision: agent 0 at (2.5, 2.5) overlaps obstacle 1 (inside)"


def test_agent_near_obstacle_edge():
    w = world(obstacles=(SQUARE,))
    # centre 0.1 left of the square's left edge: the disc of 0.25 reaches in
    (m,) = collisions(w, ((1.9, 2.5, 0.0),))
    assert "agent 0 at (1.9, 2.5) overlaps obstacle 1" in m and "0.1 from it" in m
    # touching: centre exactly one radius away
    assert collisions(w, ((1.75, 2.5, 0.0),)) == []
    # clear
    assert collisions(w, ((1.0, 2.5, 0.0),)) == []


def test_agent_near_obstacle_corner_uses_true_distance():
    w = world(obstacles=(SQUARE,))
    # diagonal from corner (2, 2): inside the grown bounding box, outside the disc
    assert collisions(w, ((1.8, 1.8, 0.0),)) == []          # distance 0.283
    assert len(collisions(w, ((1.85, 1.85, 0.0),))) == 1     # distance 0.212


def test_obstacles_numbered_from_one_in_world_order():
    w = world(obstacles=(SQUARE, TRIANGLE))
    msgs = collisions(w, ((7.0, 0.5, 0.0), (2.5, 2.5, 0.0)))
    assert msgs == ["collision: agent 0 at (7, 0.5) overlaps obstacle 2 (inside)",
                    "collision: agent 1 at (2.5, 2.5) overlaps obstacle 1 (inside)"]


def test_pairs_come_before_obstacles_and_order_is_deterministic():
    w = world(obstacles=(SQUARE,))
    pos = ((2.4, 2.5, 0.0), (2.6, 2.5, 0.0))
    msgs = collisions(w, pos)
    assert len(msgs) == 3
    assert "agent 0" in msgs[0] and "agent 1" in msgs[0]
    assert "agent 0 at (2.4, 2.5) overlaps obstacle 1" in msgs[1]
    assert "agent 1 at (2.6, 2.5) overlaps obstacle 1" in msgs[2]
    assert collisions(w, pos) == msgs


def test_world_file_obstacles_and_equal_worlds_share_the_cache():
    src = """
radius = 0.5
[[obstacles]]
polygon = [[0, 0], [1, 0], [1, 1], [0, 1]]
"""
    w1, w2 = parse_world(src, "a.toml"), parse_world(src, "b.toml")
    assert collisions(w1, ((1.3, 0.5, 0.0),)) == collisions(w2, ((1.3, 0.5, 0.0),))
    assert len(collisions(w1, ((1.3, 0.5, 0.0),))) == 1
    assert collisions(w1, ((1.6, 0.5, 0.0),)) == []


def test_fast_enough_for_exploration():
    w = world(obstacles=(SQUARE, TRIANGLE))
    pos = tuple((float(i), 0.0, 0.0) for i in range(6))
    collisions(w, pos)                       # warm the geometry cache
    t = time.perf_counter()
    for k in range(2000):
        collisions(w, tuple((x + k * 1e-4, y, z) for x, y, z in pos))
    per_call = (time.perf_counter() - t) / 2000
    assert per_call < 1e-3, per_call


# ----------------------------------------------------------------------
# the programs, through the API
# ----------------------------------------------------------------------

def test_unfixed_swap_collides_under_straight():
    r = explore(COLLIDE, world=WORLD, blackbox="straight", collisions=True)
    assert r.status == "violation" and r.exit_status == 1
    assert r.violation["kind"] == "collision"
    assert r.violation["message"] == ("collision: agent 0 at (2, 0) and agent 1 at (2, 0) overlap "
                                      "(centre distance 0 < 2 × radius 0.5)")
    assert r.trace[-1]["rule"] == "DOREACH INVOKE"
    assert r.trace[-1]["time"] == 2
    assert "[blackbox straight]" in r.verdict


def test_unfixed_swap_is_clean_without_collision_checking():
    r = explore(COLLIDE, world=WORLD, blackbox="straight")
    assert r.status == "exhaustive" and r.exit_status == 0


def test_unfixed_swap_stalls_under_the_covering_nondet():
    """Under the default nondet the robots' lanes meet, both doReach may
    fail, and collide.pccl never handles doReach_fail: a stall."""
    r = explore(COLLIDE, world=WORLD)
    assert r.status == "violation" and r.violation["kind"] == "stall", r.verdict
    assert "doReach_fail" in r.verdict


def test_unfixed_swap_collides_under_nondet_but_not_instant():
    r = explore(COLLIDE, world=WORLD, blackbox="nondet", collisions=True)
    assert r.status == "violation" and r.violation["kind"] == "collision"
    r = explore(COLLIDE, world=WORLD, blackbox="instant", collisions=True)
    assert r.status == "exhaustive"      # both jump to their goals in one step


@pytest.mark.parametrize("blackbox", ["straight", "instant", "nondet", "pymunk"])
def test_fixed_swap_is_collision_free(blackbox):
    r = explore(FIXED, world=WORLD, blackbox=blackbox, collisions=True)
    # nondet does not enumerate positions in mid-motion, which --collisions reads
    assert r.status == ("bounded" if blackbox == "nondet" else "exhaustive"), r.verdict
    assert r.exit_status == 0 and not r.violations
    assert r.stats.states > 100


def test_fixed_swap_needs_the_atomic_test_and_set():
    src = Path(FIXED).read_text()
    assert "    atomic:\n" in src
    broken = src.replace("    atomic:\n", "    if (true):\n", 1)
    from pccl.api import explore_model, make_model
    from pccl.lang.parser import parse_program
    prog = parse_program(broken, "broken.pccl")
    res = explore_model(make_model(prog, world=WORLD, collisions=True))
    assert res.status == "violation"
    assert res.violation["name"] == "one_winner"


def test_world_file_is_valid_and_starts_apart():
    w = load_world(WORLD)
    assert w.n_agents == 2
    starts = w.start_positions(2)
    assert collisions(w, starts) == []


# ----------------------------------------------------------------------
# the programs, through the CLI
# ----------------------------------------------------------------------

def test_cli_explore_unfixed_reports_collision_with_trace():
    res = cli("explore", COLLIDE, "--world", WORLD, "-b", "straight", "--collisions",
              "--no-progress")
    assert res.exit_code == 1, res.output
    out = res.output
    assert "violation: collision: agent 0 at (2, 0) and agent 1 at (2, 0) overlap" in out
    assert "counterexample (" in out and "DOREACH INVOKE" in out
    assert "violating state:" in out


def test_cli_explore_fixed_is_exhaustive():
    res = cli("explore", FIXED, "--world", WORLD, "--collisions", "--no-progress")
    assert res.exit_code == 0, res.output
    # by default explore tries every travel time (nondet) on a program that moves
    assert "blackbox nondet (default for programs that move)" in res.output
    assert ("no violation — not exhaustive for straight/pymunk: positions in mid-motion "
            "(--collisions) [blackbox nondet]") in res.output


def test_cli_run_unfixed_reports_collision():
    res = cli("run", COLLIDE, "--world", WORLD, "--collisions")
    assert res.exit_code == 1, res.output
    assert "result: violation — collision: agent 0 at (2, 0) and agent 1 at (2, 0)" in res.output


def test_cli_run_fixed_finishes_cleanly():
    res = cli("run", FIXED, "--world", WORLD, "--collisions")
    assert res.exit_code == 0, res.output
    assert "result: final" in res.output


def test_cli_run_unfixed_without_collisions_flag_is_clean():
    res = cli("run", COLLIDE, "--world", WORLD)
    assert res.exit_code == 0, res.output
    assert "result: final" in res.output
