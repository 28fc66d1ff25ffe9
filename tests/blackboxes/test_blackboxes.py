"""The shipped blackboxes on small hand-made inputs, and load_blackbox."""

from __future__ import annotations

import math
import sys
import textwrap

import pytest
import shapely

from pccl.blackboxes import (BLACKBOXES, INSTANT, NONDET, PYMUNK, STRAIGHT,
                             load_blackbox)
from pccl.blackboxes.base import Motion, Outcome
from pccl.lang.errors import PcclError
from pccl.lang.world import World

SQUARE = ((1.5, -1.0), (2.5, -1.0), (2.5, 1.0), (1.5, 1.0))   # between 0 and 4


def mv(pos, target=None, obstacles=(), done=False, fail=False, active=True):
    pos = tuple(float(c) for c in pos) + (0.0,) * (3 - len(pos))
    if target is not None:
        target = tuple(float(c) for c in target) + (0.0,) * (3 - len(target))
    return Motion(pos, target, obstacles, 0.0, done, fail, active)


def one(bb, world, motions, env=None, delta=1.0) -> Outcome:
    if env is None:
        env = bb.init_env(world, len(motions))
    out = bb.step(world, motions, env, 0.0, delta)
    assert len(out) == 1
    return out[0]


def rounded(p, res):
    return tuple(round(round(c / res) * res, 9) for c in p)


def drive(bb, world, motions, steps, delta=1.0):
    """Run a deterministic blackbox for ``steps`` steps the way the engine
    does (positions rounded to the resolution, flags fed back)."""
    env = bb.init_env(world, len(motions))
    history = []
    for _k in range(steps):
        o = one(bb, world, motions, env, delta)
        history.append(o)
        env = o.env
        motions = [Motion(rounded(p, world.resolution), m.target, m.obstacles,
                          m.t0, d, f, m.active)
                   for m, p, d, f in zip(motions, o.positions, o.done, o.fail)]
    return history


# ----------------------------------------------------------------------
# common rules
# ----------------------------------------------------------------------

@pytest.mark.parametrize("name", sorted(BLACKBOXES))
def test_interface(name):
    bb = BLACKBOXES[name]
    assert bb.name == name and bb.uses_time is False
    w = World()
    env = bb.init_env(w, 2)
    hash(env)
    out = bb.step(w, [mv((0, 0)), mv((1, 0), (3, 0))], env, 0.0, 1.0)
    assert out and all(isinstance(o, Outcome) for o in out)
    for o in out:
        assert len(o.positions) == len(o.done) == len(o.fail) == 2
        assert all(len(p) == 3 and all(isinstance(c, float) for c in p)
                   for p in o.positions)
        hash(o.env)


@pytest.mark.parametrize("name", sorted(BLACKBOXES))
def test_no_target_holds_position_with_flags_false(name):
    bb = BLACKBOXES[name]
    w = World()
    for o in bb.step(w, [mv((1, 2, 3))], bb.init_env(w, 1), 0.0, 1.0):
        assert o.positions[0] == pytest.approx((1.0, 2.0, 3.0))
        assert o.done == (False,) and o.fail == (False,)


@pytest.mark.parametrize("name", sorted(BLACKBOXES))
def test_at_target_keeps_done_and_stays(name):
    bb = BLACKBOXES[name]
    w = World()
    m = mv((2, 2), (2, 2), done=True)
    for o in bb.step(w, [m], bb.init_env(w, 1), 0.0, 1.0):
        assert o.positions[0] == pytest.approx((2.0, 2.0, 0.0))
        assert o.done == (True,) and o.fail == (False,)


@pytest.mark.parametrize("name", sorted(BLACKBOXES))
def test_target_inside_obstacle_fails(name):
    bb = BLACKBOXES[name]
    w = World()
    outs = bb.step(w, [mv((0, 0), (2, 0), obstacles=(SQUARE,))],
                   bb.init_env(w, 1), 0.0, 1.0)
    assert len(outs) == 1
    o = outs[0]
    assert o.fail == (True,) and o.done == (False,)
    assert o.positions[0] == pytest.approx((0.0, 0.0, 0.0))


@pytest.mark.parametrize("name", sorted(BLACKBOXES))
def test_world_obstacles_are_solid_too(name):
    bb = BLACKBOXES[name]
    w = World(obstacles=(SQUARE,))
    o = bb.step(w, [mv((0, 0), (2, 0.5))], bb.init_env(w, 1), 0.0, 1.0)[0]
    assert o.fail == (True,)


@pytest.mark.parametrize("name", sorted(BLACKBOXES))
def test_fail_is_sticky(name):
    bb = BLACKBOXES[name]
    w = World()
    o = bb.step(w, [mv((0, 0), (1, 0), fail=True)], bb.init_env(w, 1), 0.0, 1.0)[0]
    assert o.fail == (True,) and o.done == (False,)
    assert o.positions[0] == pytest.approx((0.0, 0.0, 0.0))


# ----------------------------------------------------------------------
# instant
# ----------------------------------------------------------------------

def test_instant_arrives_next_step_and_keeps_z():
    o = one(INSTANT, World(), [mv((0, 0, 7), (10, -3, 99)), mv((5, 5))])
    assert o.positions == ((10.0, -3.0, 7.0), (5.0, 5.0, 0.0))
    assert o.done == (True, False) and o.fail == (False, False)
    assert o.env is None


def test_instant_ignores_obstacles_on_the_way():
    o = one(INSTANT, World(), [mv((0, 0), (4, 0), obstacles=(SQUARE,))])
    assert o.positions[0] == (4.0, 0.0, 0.0) and o.done == (True,)


def test_instant_target_on_obstacle_boundary_fails():
    o = one(INSTANT, World(), [mv((0, 0), (1.5, 0), obstacles=(SQUARE,))])
    assert o.fail == (True,)


# ----------------------------------------------------------------------
# straight
# ----------------------------------------------------------------------

def test_straight_moves_speed_times_delta():
    w = World(speed=2.0)
    o = one(STRAIGHT, w, [mv((0, 0), (3, 4)), mv((1, 1), (1, 11))], delta=0.5)
    (p, q) = o.positions
    assert p == pytest.approx((0.6, 0.8, 0.0))
    assert q == pytest.approx((1.0, 2.0, 0.0))
    assert o.done == (False, False) and o.fail == (False, False)


def test_straight_arrives_exactly_when_within_reach():
    o = one(STRAIGHT, World(), [mv((0, 0), (0.6, 0.8))])
    assert o.positions[0] == (0.6, 0.8, 0.0) and o.done == (True,)
    hist = drive(STRAIGHT, World(), [mv((0, 0), (3.5, 0))], 5)
    assert [h.done[0] for h in hist] == [False, False, False, True, True]
    assert [h.positions[0][0] for h in hist] == [1.0, 2.0, 3.0, 3.5, 3.5]


def test_straight_fails_when_path_crosses_obstacle():
    o = one(STRAIGHT, World(), [mv((0, 0), (4, 0), obstacles=(SQUARE,)),
                                mv((0, 3), (4, 3), obstacles=(SQUARE,))])
    assert o.fail == (True, False)
    assert o.positions[0] == (0.0, 0.0, 0.0)
    assert o.positions[1] == pytest.approx((1.0, 3.0, 0.0))


def test_straight_uses_each_agents_own_obstacles():
    o = one(STRAIGHT, World(), [mv((0, 0), (4, 0), obstacles=(SQUARE,)),
                                mv((0, 0), (4, 0))])
    assert o.fail == (True, False)


def test_straight_touching_obstacle_corner_fails():
    o = one(STRAIGHT, World(), [mv((0, 2), (4, 0), obstacles=(SQUARE,))])
    assert o.fail == (True,)   # the segment passes exactly through (2, 1)


def test_straight_is_deterministic_and_cached_consistently():
    w = World(obstacles=(SQUARE,))
    ms = [mv((0, 0), (4, 0)), mv((0, 1.5), (4, 1.5))]
    first = STRAIGHT.step(w, ms, None, 0.0, 1.0)
    for _ in range(3):
        assert STRAIGHT.step(w, ms, None, 0.0, 1.0) == first
    # an equal but distinct obstacle tuple gives the same answer
    w2 = World(obstacles=tuple(tuple(p) for p in (list(SQUARE),)))
    assert STRAIGHT.step(w2, ms, None, 0.0, 1.0) == first


# ----------------------------------------------------------------------
# nondet
# ----------------------------------------------------------------------

def test_nondet_enumerates_every_combination_in_fixed_order():
    w = World()
    ms = [mv((0, 0), (1, 0)),          # moving
          mv((5, 5)),                  # no target
          mv((2, 2), (3, 3)),          # moving
          mv((7, 7), (7, 7), done=True)]
    outs = NONDET.step(w, ms, None, 0.0, 1.0)
    assert len(outs) == 4
    moved = [(o.positions[0] == (1.0, 0.0, 0.0), o.positions[2] == (3.0, 3.0, 0.0))
             for o in outs]
    assert moved == [(False, False), (False, True), (True, False), (True, True)]
    assert [o.done for o in outs] == [(False, False, False, True),
                                      (False, False, True, True),
                                      (True, False, False, True),
                                      (True, False, True, True)]
    assert all(o.fail == (False,) * 4 for o in outs)
    assert all(o.positions[1] == (5.0, 5.0, 0.0) for o in outs)
    assert NONDET.step(w, ms, None, 0.0, 1.0) == outs


def test_nondet_two_to_the_m():
    w = World()
    for m in range(5):
        ms = [mv((i, 0), (i, 1)) for i in range(m)]
        assert len(NONDET.step(w, ms, None, 0.0, 1.0)) == 2 ** m


def test_nondet_obstacle_target_is_fail_only():
    outs = NONDET.step(World(), [mv((0, 0), (2, 0), obstacles=(SQUARE,)),
                                 mv((0, 3), (4, 3), obstacles=(SQUARE,))],
                       None, 0.0, 1.0)
    assert len(outs) == 2
    assert all(o.fail == (True, False) for o in outs)
    assert [o.done for o in outs] == [(False, False), (False, True)]


# ----------------------------------------------------------------------
# pymunk
# ----------------------------------------------------------------------

def test_pymunk_reaches_free_target_in_a_few_steps():
    w = World()
    hist = drive(PYMUNK, w, [mv((0, 0), (3, 0))], 6)
    first_done = next(i for i, h in enumerate(hist) if h.done[0])
    assert first_done <= 4                      # 3 units at speed 1, + accel
    assert hist[first_done].positions[0] == (3.0, 0.0, 0.0)   # snapped
    assert hist[-1].positions[0] == (3.0, 0.0, 0.0)
    assert not any(h.fail[0] for h in hist)
    # speed cap: never more than speed * delta per step (from the rounded
    # position the engine feeds back)
    prev = (0.0, 0.0)
    for h in hist:
        p = h.positions[0][:2]
        assert math.dist(p, prev) <= w.speed * 1.0 + 1e-6
        prev = rounded(p, w.resolution)


def test_pymunk_is_deterministic():
    w = World(obstacles=(SQUARE,))
    ms = [mv((0, 0.3), (4, 0)), mv((0, -2), (4, -1.2)), mv((3, 2), (0, 0))]
    env = ((( 0.5, 0.0), (0.0, 0.2), (0.0, 0.0)), (0.0, 1.0, 0.0))
    a = PYMUNK.step(w, ms, env, 0.0, 1.0)
    b = PYMUNK.step(w, ms, env, 0.0, 1.0)
    assert a == b
    h1 = drive(PYMUNK, w, ms, 8)
    h2 = drive(PYMUNK, w, ms, 8)
    assert h1 == h2


def test_pymunk_env_is_hashable_rounded_velocities_and_stalls():
    w = World()
    o = one(PYMUNK, w, [mv((0, 0), (5, 0)), mv((0, 2))])
    hash(o.env)
    vels, stalls = o.env
    assert len(vels) == 2 and len(stalls) == 2
    for v in vels:
        for c in v:
            assert abs(c / w.resolution - round(c / w.resolution)) < 1e-6
    assert vels[0][0] == pytest.approx(1.0) and vels[1] == (0.0, 0.0)
    assert PYMUNK.init_env(w, 2) == (((0.0, 0.0), (0.0, 0.0)), (0.0, 0.0))


def test_pymunk_head_on_robots_do_not_pass_through_each_other():
    w = World()
    hist = drive(PYMUNK, w, [mv((0, 0), (3, 0)), mv((2, 0), (-1, 0))], 8)
    for h in hist:
        (p, q) = h.positions
        assert p[0] < q[0]                                  # order kept
        assert math.dist(p[:2], q[:2]) >= 2 * w.radius - 0.02
    # they push against each other: no progress -> both fail
    assert hist[-1].fail == (True, True)
    assert hist[-1].done == (False, False)


def test_pymunk_robot_with_no_target_can_be_pushed():
    w = World()
    hist = drive(PYMUNK, w, [mv((0, 0), (3, 0)), mv((1.5, 0.1))], 3)
    q = hist[-1].positions[1]
    assert q != (1.5, 0.1, 0.0)
    assert hist[-1].done[1] is False and hist[-1].fail[1] is False


def test_pymunk_goes_around_an_obstacle():
    w = World(obstacles=(SQUARE,))
    hist = drive(PYMUNK, w, [mv((0, 0), (4, 0), obstacles=(SQUARE,))], 12)
    done_at = next((i for i, h in enumerate(hist) if h.done[0]), None)
    assert done_at is not None and done_at <= 8
    assert hist[done_at].positions[0] == (4.0, 0.0, 0.0)
    assert not any(h.fail[0] for h in hist)
    square = shapely.Polygon(SQUARE)
    for h in hist:
        p = shapely.Point(h.positions[0][:2])
        assert square.distance(p) >= w.radius * 0.95


def test_pymunk_goes_around_a_concave_obstacle():
    cup = ((2.0, -2.0), (3.0, -2.0), (3.0, 2.0), (2.0, 2.0), (2.0, 1.5),
           (2.5, 1.5), (2.5, -1.5), (2.0, -1.5))        # a U open to the left
    w = World(obstacles=(cup,))
    hist = drive(PYMUNK, w, [mv((0, 0), (5, 0))], 15)
    assert any(h.done[0] for h in hist)
    poly = shapely.Polygon(cup)
    for h in hist:
        assert poly.distance(shapely.Point(h.positions[0][:2])) >= w.radius * 0.9


def test_pymunk_target_inside_obstacle_fails_at_once_and_holds():
    w = World()
    o = one(PYMUNK, w, [mv((0, 0), (2, 0.5), obstacles=(SQUARE,))])
    assert o.fail == (True,) and o.done == (False,)
    assert o.positions[0] == pytest.approx((0.0, 0.0, 0.0))


def test_pymunk_fails_without_progress_after_no_progress_time():
    # target just behind a wall it cannot reach: closer than the radius
    wall = ((2.0, -3.0), (2.2, -3.0), (2.2, 3.0), (2.0, 3.0))
    w = World(obstacles=(wall,), no_progress_time=2.0)
    hist = drive(PYMUNK, w, [mv((1.0, 0), (2.3, 0))], 12)
    fails = [h.fail[0] for h in hist]
    assert True in fails
    k = fails.index(True)
    assert all(fails[k:])
    assert not any(h.done[0] for h in hist)


def test_pymunk_exited_robot_still_occupies_space():
    w = World()
    hist = drive(PYMUNK, w, [mv((0, 0), (3, 0)),
                             mv((3, 0), (3, 0), done=True, active=False)], 6)
    for h in hist:
        assert math.dist(h.positions[0][:2], h.positions[1][:2]) >= 2 * w.radius - 0.02
    assert not hist[-1].done[0]


def test_pymunk_z_is_carried_through():
    o = one(PYMUNK, World(), [mv((0, 0, 4.5), (1, 0, 9))])
    assert o.positions[0][2] == 4.5


# ----------------------------------------------------------------------
# load_blackbox
# ----------------------------------------------------------------------

@pytest.mark.parametrize("name", ["instant", "straight", "nondet", "pymunk"])
def test_load_by_name(name):
    assert load_blackbox(name) is BLACKBOXES[name]


def test_load_by_module_attribute_instance_and_class():
    assert load_blackbox("pccl.blackboxes.straight:STRAIGHT") is STRAIGHT
    bb = load_blackbox("pccl.blackboxes.nondet:Nondet")
    assert bb.name == "nondet" and bb is not NONDET


USER_MODULE = textwrap.dedent('''
    from pccl.blackboxes.base import Outcome

    class Teleport:
        name = "teleport"
        uses_time = False

        def init_env(self, world, n_agents):
            return None

        def step(self, world, motions, env, time, delta):
            pos = tuple(m.target if m.target is not None else m.position
                        for m in motions)
            done = tuple(m.target is not None for m in motions)
            return [Outcome(pos, done, (False,) * len(motions), None)]

    BLACKBOX = Teleport()

    def make():
        return Teleport()

    def broken():
        raise RuntimeError("boom")

    NOT_A_BLACKBOX = 42
''')


@pytest.fixture
def user_module(tmp_path, monkeypatch):
    path = tmp_path / "my_user_bb.py"
    path.write_text(USER_MODULE)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "path", list(sys.path))
    yield path
    sys.modules.pop("my_user_bb", None)


def test_load_user_module_from_current_directory(user_module):
    bb = load_blackbox("my_user_bb:BLACKBOX")
    assert bb.name == "teleport"
    o = bb.step(World(), [mv((0, 0), (1, 1))], None, 0.0, 1.0)[0]
    assert o.done == (True,)
    assert load_blackbox("my_user_bb:make").name == "teleport"
    assert load_blackbox("my_user_bb:Teleport").name == "teleport"


def test_load_user_module_from_file_path(user_module):
    bb = load_blackbox(f"{user_module}:BLACKBOX")
    assert bb.name == "teleport"


BAD = {
    "straigt": "unknown blackbox 'straigt' (did you mean 'straight'?); valid "
               "names: instant, nondet, nondet-fail, pymunk, straight, or module:attribute "
               "for your own",
    "box2d": "unknown blackbox 'box2d'; valid names: instant, nondet, nondet-fail, "
             "pymunk, straight, or module:attribute for your own",
    "nondet:fail": "bad blackbox 'nondet:fail': 'nondet' is a shipped blackbox, not a "
                   "module (did you mean 'nondet-fail'?); valid names: instant, nondet, "
                   "nondet-fail, pymunk, straight, or module:attribute for your own",
    "": "empty blackbox name; valid names: instant, nondet, nondet-fail, pymunk, straight "
        "(or module:attribute for your own)",
    "no_such_module_xyz:BB": "bad blackbox 'no_such_module_xyz:BB': cannot "
                             "import module 'no_such_module_xyz' (No module "
                             "named 'no_such_module_xyz')",
    "pccl.blackboxes.straight:NOPE": "bad blackbox "
                                     "'pccl.blackboxes.straight:NOPE': module "
                                     "'pccl.blackboxes.straight' has no "
                                     "attribute 'NOPE'",
    "pccl.blackboxes.straight:": "bad blackbox 'pccl.blackboxes.straight:': "
                                 "write module:attribute, e.g. "
                                 "mymodule:BLACKBOX (or one of: instant, "
                                 "nondet, nondet-fail, pymunk, straight)",
}


@pytest.mark.parametrize("spec", sorted(BAD))
def test_bad_blackbox_names(spec):
    with pytest.raises(PcclError) as info:
        load_blackbox(spec)
    assert info.value.render() == "<input>: error: " + BAD[spec]


def test_bad_user_objects(user_module):
    with pytest.raises(PcclError) as info:
        load_blackbox("my_user_bb:NOT_A_BLACKBOX")
    assert "NOT_A_BLACKBOX is not a blackbox (missing name, uses_time, " \
           "init_env, step" in info.value.message
    with pytest.raises(PcclError) as info:
        load_blackbox("my_user_bb:broken")
    assert info.value.message == ("bad blackbox 'my_user_bb:broken': calling "
                                  "broken() failed: RuntimeError: boom")


def test_user_module_with_syntax_error(tmp_path, monkeypatch):
    (tmp_path / "bad_syntax_bb.py").write_text("def oops(:\n")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "path", list(sys.path))
    with pytest.raises(PcclError) as info:
        load_blackbox("bad_syntax_bb:X")
    assert info.value.message.startswith(
        "bad blackbox 'bad_syntax_bb:X': importing 'bad_syntax_bb' failed: "
        "SyntaxError")


def test_pymunk_plans_one_mode_per_agent():
    """The step's plan: no target or a failed motion holds, a done motion
    holds its target, a target inside an obstacle fails; the rest drive
    along a path whose first leg avoids the obstacle."""
    from pccl.blackboxes.pymunk_bb import Mode, PymunkBlackbox
    w = World(obstacles=(SQUARE,))
    ms = [Motion((0.0, 0.0, 0.0), None, (), None, False, False),
          mv((0, 0), (4, 0)),
          Motion((4.0, 0.0, 0.0), (4.0, 0.0, 0.0), (), 0.0, True, False),
          mv((0, 0), (2, 0.5)),
          Motion((0.0, 0.0, 0.0), (4.0, 0.0, 0.0), (), 0.0, False, True)]
    obs, roadmap = PymunkBlackbox._obstacles(w, ms)
    plans = PymunkBlackbox._plan(ms, obs, roadmap)
    assert plans.mode == [Mode.HOLD, Mode.DRIVE, Mode.DONE, Mode.HOLD, Mode.HOLD]
    assert plans.fail == [False, False, False, True, True]
    assert plans.done == [False, False, True, False, False]
    legs = plans.paths[1]
    assert legs[-1] == (4.0, 0.0) and len(legs) > 1            # around the square
    assert plans.length0[1] > 4.0
    # Mode HOLD is false, as the simulation's "if mode[i]" reads it
    assert not Mode.HOLD and Mode.DRIVE and Mode.DONE


def test_fair_arrival_is_a_declared_capability_not_a_name():
    # liveness assumes a robot under way settles eventually only under a
    # blackbox that declares arrival_is_fair itself: a subclass of Nondet
    # that keeps the name "nondet" promises nothing, and its runs in which
    # robot 0 stays under way for ever are counterexamples
    from pccl.api import explore
    from pccl.blackboxes.nondet import Nondet
    from pccl.model.engine import blackbox_arrival_is_fair

    class Mine(Nondet):
        pass

    from conftest import ROOT
    prog = str(ROOT / "tests" / "programs" / "rdv_meet.pccl")
    world = str(ROOT / "tests" / "programs" / "rdv_open.toml")
    prop = "eventually forall i: exited[i]"
    fair = explore(prog, world=world, blackbox="nondet", properties=[prop])
    assert fair.status == "exhaustive" and blackbox_arrival_is_fair(fair.model.blackbox)
    mine = Mine("nondet")
    assert not blackbox_arrival_is_fair(mine)
    unfair = explore(prog, world=world, blackbox=mine, properties=[prop])
    assert unfair.status == "violation" and unfair.violation.kind == "liveness"
