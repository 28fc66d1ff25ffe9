"""The default exploring blackbox (``nondet``) covers ``straight``
(docs/blackboxes.md, "What each blackbox covers").

Differential: for every shipped and test program with a world, and for
generated two-robot programs with a random wall, every configuration in
which a seeded ``pccl run --blackbox straight`` ends (final, stalled, a
violation) is reachable in ``pccl explore`` under the default blackbox, as
far as a program can observe it: statuses, variables, the doReach flags and
positions.  And a property that holds under the default blackbox holds on
those runs.
"""

from __future__ import annotations

import math
import random
import textwrap

import pytest

from pccl import api
from pccl.blackboxes import load_blackbox
from pccl.blackboxes.base import Motion
from pccl.model.layout import AGS, AR, DONE, FAIL, LOC, POS, REACH, SH, START, STATUS
from pccl.lang.world import parse_world

from conftest import PROGRAMS, TEST_PROGRAMS

SEEDS = range(4)

#: The searches of the generated programs' properties: what they assert is
#: the blackbox's covering, not the engine or the counterexample's path, so
#: the Python engine runs them without shortening (their few hundred states
#: cost it milliseconds; a native module per program and property, for the
#: search and for the shortening, cost about a CPU-second each).  The native
#: engine is held to the Python one on these programs by
#: test_generated_retargets_native_equals_python.
PY_SEARCH = dict(engine="python", shorten=False)

#: (program, world, agents or None for the world's): every shipped program
#: with a world, and the test programs with one.
WORLD_PROGRAMS = [
    ("race.pccl", "race.toml", None),
    ("race.pccl", "race_obstacles.toml", None),
    ("race_nonatomic.pccl", "race.toml", None),
    ("race_nonatomic.pccl", "race_obstacles.toml", None),
    ("race_safe.pccl", "race.toml", None),
    ("race_safe.pccl", "race_obstacles.toml", None),
    ("race_robust.pccl", "race.toml", None),
    ("collide.pccl", "collide.toml", None),
    ("collide_fixed.pccl", "collide.toml", None),
    ("formation.pccl", "formation.toml", 2),
    ("rendezvous.pccl", "rendezvous.toml", 2),
    ("rdv_meet.pccl", "rdv_wall.toml", None),
    ("rdv_meet.pccl", "rdv_open.toml", None),
]


def _path(name: str) -> str:
    p = PROGRAMS / name
    return str(p if p.exists() else TEST_PROGRAMS / name)


def observable(st) -> tuple:
    """What a program that reads only the doReach flags can observe of a
    configuration (time and positions left out: where the robots are is
    compared by :func:`positions_covered`)."""
    return (st[SH], tuple((ag[STATUS], ag[LOC], ag[AR], ag[REACH][DONE], ag[REACH][FAIL])
                          for ag in st[AGS]))


def where(st) -> tuple:
    """Per robot, where nondet says it may be: (position, leg start)."""
    return tuple((ag[POS], ag[REACH][START]) for ag in st[AGS])


def positions_covered(world, delta, places, positions) -> bool:
    """Whether each robot's position under straight lies where nondet's
    state says that robot may be: its position, or within the drift of the
    hull of its position and leg start (blackboxes/nondet.py)."""
    from pccl.blackboxes.nondet import NONDET
    from pccl.blackboxes._geometry import convex_hull, shapely
    for (p, start), q in zip(places, positions):
        if p[:2] == q[:2]:
            continue
        if not start:
            return False
        hull = convex_hull((p,) + tuple(start))
        g = shapely.MultiPoint(list(hull)).convex_hull
        if g.distance(shapely.Point(q[0], q[1])) > NONDET.drift(world, hull, delta):
            return False
    return True


def explored(program, world, agents, invariants=()) -> dict:
    """The observable parts of every state ``explore`` reaches under its
    default blackbox (no reductions: every state of the rules), each with
    where the robots may be (:func:`where`)."""
    prog = api.load_program(program)
    bb, _ = api.explore_blackbox(prog)
    assert bb == "nondet"                       # the default for programs that move
    m = api.make_model(program, world=world, agents=agents, blackbox=bb, reduce="none",
                       invariants=list(invariants))
    seen, todo = set(), list(m.init_states())
    out: dict = {}
    while todo:
        st = todo.pop()
        k = m.key(st)
        if k in seen:
            continue
        seen.add(k)
        out.setdefault(observable(st), set()).add(where(st))
        todo.extend(s for _, s in m.successors(st))
    return out


def straight_runs(program, world, agents, invariants=()):
    return [api.run(program, world=world, agents=agents, blackbox="straight", seed=s,
                    max_time=60, invariants=list(invariants)) for s in SEEDS]


def check_covered(program, world, agents, seeds=SEEDS):
    reach = explored(program, world, agents)
    w = api.make_model(program, world=world, agents=agents).world
    for res in straight_runs(program, world, agents):
        places = reach.get(observable(res.final))
        assert places is not None, (
            f"{program} with {world}: run under straight ends {res.status} "
            f"({res.message}) in a configuration nondet never reaches")
        pos = tuple(ag[POS] for ag in res.final[AGS])
        assert any(positions_covered(w, 1, pl, pos) for pl in places), (
            f"{program} with {world}: run under straight ends with the robots at {pos}, "
            f"where nondet's matching states cannot have them: {sorted(places)[:3]}")


@pytest.mark.parametrize("program,world,agents", WORLD_PROGRAMS,
                         ids=[f"{p}-{w}" for p, w, _ in WORLD_PROGRAMS])
def test_straight_runs_are_reachable_under_the_default(program, world, agents):
    check_covered(_path(program), _path(world), agents)


def test_walled_rendezvous_fail_is_explored():
    """Issue 21: the blocked robot's doReach fails under straight (the run
    stalls); under the default blackbox that is explored too, so
    `eventually forall i: exited[i]` no longer holds."""
    prog, world = _path("rdv_meet.pccl"), _path("rdv_wall.toml")
    res = api.run(prog, world=world, blackbox="straight", seed=0)
    assert res.status == "stalled"
    r = api.explore(prog, world=world, properties=["eventually forall i: exited[i]"])
    assert r.blackbox == "nondet" and r.status == "violation", r.verdict
    assert r.final_state.agents[0].doReach_fail is True
    # without the wall it still holds (fair arrival, no failure possible)
    r = api.explore(prog, world=_path("rdv_open.toml"),
                    properties=["eventually forall i: exited[i]"])
    assert r.status == "exhaustive", r.verdict


# --------------------------------------------------------------------------
# generated programs: two robots, random targets, a random wall
# --------------------------------------------------------------------------

GEN_PROGRAM = """\
allwrite:
  int arrived = 0;
  int failed = 0;
loc:
  int id = getAgentIndex();
  bool started = false;
  bool second = false;

Go():
  pre(!started);
  eff:
    started = true;
    if (id == 0):
      doReach(ItemPosition({x0}, {y0}), getObs());
    else:
      doReach(ItemPosition({x1}, {y1}), getObs());

Again():
  pre(started && !second && doReach_done && id == 0);
  eff:
    second = true;
    doReach(ItemPosition({x2}, {y2}), getObs());

Done():
  pre(started && doReach_done && (second || id == 1));
  eff:
    atomic:
      arrived = arrived + 1;
    exit();

Failed():
  pre(started && doReach_fail);
  eff:
    atomic:
      failed = failed + 1;
    exit();
"""

GEN_WORLD = """\
agents = 2
resolution = 0.01
radius = {r}
speed = {speed}
start = [[{sx0}, {sy0}], [{sx1}, {sy1}]]

[[obstacles]]
polygon = [[{wx0}, {wy0}], [{wx1}, {wy0}], [{wx1}, {wy1}], [{wx0}, {wy1}]]
"""

#: Candidate invariants: where one holds under the default blackbox it must
#: hold on every straight run.
GEN_PROPERTIES = ["failed == 0", "arrived <= 1", "failed <= 1", "arrived + failed <= 2"]


def generated(seed: int, tmp_path):
    rnd = random.Random(seed)

    def c():
        return round(rnd.uniform(0, 6), 1)
    vals = {f"{k}{i}": c() for k in "xy" for i in range(3)}
    text = GEN_PROGRAM.format(**vals)
    wx0, wy0 = round(rnd.uniform(1, 4), 1), round(rnd.uniform(-1, 4), 1)
    vertical = rnd.random() < 0.5
    wx1 = round(wx0 + (0.3 if vertical else rnd.uniform(1, 3)), 1)
    wy1 = round(wy0 + (rnd.uniform(1, 3) if vertical else 0.3), 1)
    r, speed = rnd.choice([0.1, 0.25]), rnd.choice([0.7, 1.0, 1.5])

    def valid(sx0, sy0, sx1, sy1):
        """A robot cannot start inside the wall or on the other (the world
        file rejects such starts, pccl check --world too)."""
        inside = any(wx0 <= x <= wx1 and wy0 <= y <= wy1 for x, y in ((sx0, sy0), (sx1, sy1)))
        return not inside and math.hypot(sx0 - sx1, sy0 - sy1) >= 2 * r
    starts = (c(), c(), c(), c())
    while not valid(*starts):
        starts = (c(), c(), c(), c())
    world = GEN_WORLD.format(r=r, speed=speed,
                             sx0=starts[0], sy0=starts[1], sx1=starts[2], sy1=starts[3],
                             wx0=wx0, wy0=wy0, wx1=wx1, wy1=wy1)
    prog_path = tmp_path / f"gen{seed}.pccl"
    world_path = tmp_path / f"gen{seed}.toml"
    prog_path.write_text(text)
    world_path.write_text(world)
    return str(prog_path), str(world_path)


@pytest.mark.parametrize("seed", range(24))
def test_generated_walls(seed, tmp_path):
    prog, world = generated(seed, tmp_path)
    check_covered(prog, world, None)
    for prop in GEN_PROPERTIES:
        r = api.explore(prog, world=world, invariants=[prop], **PY_SEARCH)
        if r.violations or r.bounds:    # "not exhaustive for pymunk" still holds for straight
            continue
        for res in straight_runs(prog, world, None, invariants=[prop]):
            assert res.status != "violation", (prop, res.message)


def test_generated_walls_do_fail_under_straight(tmp_path):
    """The generator is not vacuous: some straight runs fail on the wall,
    and some arrive."""
    statuses = set()
    for seed in range(24):
        prog, world = generated(seed, tmp_path)
        res = api.run(prog, world=world, blackbox="straight", seed=0, max_time=60)
        failed, arrived = res.final_state.shared["failed"], res.final_state.shared["arrived"]
        statuses.add((failed > 0, arrived > 0))
    assert (True, False) in statuses or (True, True) in statuses
    assert (False, True) in statuses


# --------------------------------------------------------------------------
# the blackbox itself
# --------------------------------------------------------------------------

WALL = parse_world(textwrap.dedent("""\
    resolution = 0.01
    radius = 0.25
    [[obstacles]]
    polygon = [[0.9, -1], [1.1, -1], [1.1, 1], [0.9, 1]]
    """))


def motion(p, t, **kw):
    return Motion(position=p, target=t, obstacles=(), t0=None, done=False, fail=False, **kw)


def test_nondet_outcomes_blocked_and_free():
    nd = load_blackbox("nondet")
    # blocked path: stay, arrive, fail (in that order), fail where it stands
    outs = nd.step(WALL, [motion((0.0, 0.0, 0.0), (2.0, 0.0, 0.0))], None, 0, 1.0)
    assert [(o.positions[0][:2], o.done[0], o.fail[0]) for o in outs] == [
        ((0.0, 0.0), False, False), ((2.0, 0.0), True, False), ((0.0, 0.0), False, True)]
    # the same path, clear of the wall by more than a radius: no fail outcome
    outs = nd.step(WALL, [motion((0.0, 2.0, 0.0), (2.0, 2.0, 0.0))], None, 0, 1.0)
    assert [o.fail for o in outs] == [(False,), (False,)]
    # within a radius of the wall (pymunk's disc would touch it): may fail
    outs = nd.step(WALL, [motion((0.0, 1.2, 0.0), (2.0, 1.2, 0.0))], None, 0, 1.0)
    assert len(outs) == 3


def test_nondet_fail_when_straight_fails():
    """Wherever straight fails a robot at a step, nondet has an outcome with
    the same flags and positions (random segments against the wall)."""
    nd, st = load_blackbox("nondet"), load_blackbox("straight")
    rnd = random.Random(7)
    fails = 0
    for _ in range(300):
        ms = [motion((round(rnd.uniform(-2, 4), 2), round(rnd.uniform(-2, 2), 2), 0.0),
                     (round(rnd.uniform(-2, 4), 2), round(rnd.uniform(-2, 2), 2), 0.0))
              for _ in range(2)]
        (o,) = st.step(WALL, ms, None, 0, 1.0)
        if not any(o.fail):
            continue
        fails += 1
        flags = [(x.done, x.fail) for x in nd.step(WALL, ms, None, 0, 1.0)]
        pos = {x.positions for x in nd.step(WALL, ms, None, 0, 1.0)
               if x.fail == o.fail}
        assert any(f[1] == o.fail for f in flags)
        # a robot straight fails stands where nondet's failing robot stands
        assert any(all(p[i] == o.positions[i] for i in range(2) if o.fail[i]) for p in pos)
    assert fails > 20


def test_robots_blocking_each_other():
    nd = load_blackbox("nondet")
    empty = parse_world("resolution = 0.01\nradius = 0.25\n")
    # head-on: both may fail (pymunk's discs meet)
    outs = nd.step(empty, [motion((0.0, 0.0, 0.0), (4.0, 0.0, 0.0)),
                           motion((4.0, 0.0, 0.0), (0.0, 0.0, 0.0))], None, 0, 1.0)
    assert len(outs) == 9
    # parallel lanes 2 apart: neither can touch the other
    outs = nd.step(empty, [motion((0.0, 0.0, 0.0), (4.0, 0.0, 0.0)),
                           motion((0.0, 2.0, 0.0), (4.0, 2.0, 0.0))], None, 0, 1.0)
    assert len(outs) == 4
    # a robot parked on the lane blocks it
    outs = nd.step(empty, [motion((0.0, 0.0, 0.0), (4.0, 0.0, 0.0)),
                           motion((2.0, 0.3, 0.0), None)], None, 0, 1.0)
    assert [o.fail for o in outs] == [(False, False), (False, False), (True, False)]


def test_nondet_fail_may_fail_anywhere():
    nf = load_blackbox("nondet-fail")
    empty = parse_world("resolution = 0.01\n")
    outs = nf.step(empty, [motion((0.0, 0.0, 0.0), (4.0, 0.0, 0.0))], None, 0, 1.0)
    assert [(o.done, o.fail) for o in outs] == [((False,), (False,)), ((True,), (False,)),
                                                ((False,), (True,))]
    # under nondet the same free move cannot fail
    assert len(load_blackbox("nondet").step(empty, [motion((0.0, 0.0, 0.0), (4.0, 0.0, 0.0))],
                                            None, 0, 1.0)) == 2


def test_nondet_fail_includes_nondet(tmp_path):
    """Every state nondet reaches, nondet-fail reaches too."""
    prog, world = generated(3, tmp_path)
    a = {(o, tuple(p for p, _ in w)) for o, ws in explored(prog, world, None).items()
         for w in ws}
    m = api.make_model(prog, world=world, blackbox="nondet-fail", reduce="none")
    seen, out, todo = set(), set(), list(m.init_states())
    while todo:
        st = todo.pop()
        if m.key(st) in seen:
            continue
        seen.add(m.key(st))
        out.add((observable(st), tuple(ag[POS] for ag in st[AGS])))
        todo.extend(s for _, s in m.successors(st))
    assert a <= out and len(out) > len(a)


def test_header_says_positions_in_motion_not_covered():
    from conftest import cli
    r = cli("explore", _path("rendezvous.pccl"), "--world", _path("rendezvous.toml"),
            "--agents", "2", "--no-progress")
    head = r.output.splitlines()[0]
    assert "blackbox nondet (default for programs that move), not exhaustive for " \
           "straight/pymunk: positions in mid-motion (getPosition() at line 29)" in head
    assert "not exhaustive for straight/pymunk: positions in mid-motion" in r.output.splitlines()[1]
    assert r.exit_code == 0
    # a program that observes motion only through the flags: nothing to say
    r = cli("explore", _path("rdv_meet.pccl"), "--world", _path("rdv_open.toml"),
            "--no-progress")
    assert "not exhaustive" not in r.output
    # pos in a property; --collisions
    # (the note is the model's: PY_SEARCH, no module to compile)
    r = api.explore(_path("rdv_meet.pccl"), world=_path("rdv_open.toml"),
                    invariants=["forall i: pos[i].x <= 3"], **PY_SEARCH)
    assert r.not_covered == "not exhaustive for straight/pymunk: positions in mid-motion " \
                            "(pos in property `forall i: pos[i].x <= 3`)"
    r = api.explore(_path("rdv_meet.pccl"), world=_path("rdv_open.toml"), collisions=True,
                    **PY_SEARCH)
    assert r.not_covered == "not exhaustive for straight/pymunk: positions in mid-motion " \
                            "(collisions)"     # the keyword
    # a deterministic blackbox has nothing to say
    r = api.explore(_path("rendezvous.pccl"), world=_path("rendezvous.toml"), agents=2,
                    blackbox="straight", **PY_SEARCH)
    assert r.not_covered is None


# --------------------------------------------------------------------------
# issue 41, holes 3 and 4: re-targets in mid-motion, failures part-way
# --------------------------------------------------------------------------

COVER = "covering/"


@pytest.mark.parametrize("name", ["gap_turn", "cover_rounding_flags", "cover_rounding_thin"])
def test_straight_violation_is_found_by_the_default(name):
    """A robot re-targeted in mid-motion (gap_turn: the new leg starts where
    the robot really is and meets a wall) and a robot straight fails
    part-way (cover_rounding_flags: rounded positions graze a triangle, the
    next trip from there crosses a box): run under straight fails an
    assertion, and so does explore under the default blackbox, on both
    engines with the same figures.  cover_rounding_thin is cover_rounding_flags
    with thin robots (radius and tolerance 0.01), so that only the leg start
    after the failure part-way, not pymunk's margin, finds the box."""
    prog, world = _path(COVER + name + ".pccl"), _path(COVER + name + ".toml")
    res = api.run(prog, world=world, blackbox="straight", seed=0)
    assert res.status == "violation" and "assertion failed" in res.message, res.message
    figures = set()
    for engine in ("native", "python"):
        r = api.explore(prog, world=world, engine=engine)
        assert r.blackbox == "nondet" and r.status == "violation", r.verdict
        assert r.exit_status == 1 and "assertion failed" in r.verdict
        figures.add((r.stats.states, r.stats.transitions))
    assert len(figures) == 1, figures


def test_positions_read_after_a_failure_part_way_is_not_exhaustive():
    """cover_rounding_position reads getPosition() after straight failed the
    robot part-way: nondet cannot enumerate that position, so the verdict is
    not "exhaustive" but says why, and exits as a bounded search (0)."""
    from conftest import cli
    prog, world = _path(COVER + "cover_rounding_position.pccl"), \
        _path(COVER + "cover_rounding_position.toml")
    res = api.run(prog, world=world, blackbox="straight", seed=0)
    assert res.status == "violation", res.message
    r = api.explore(prog, world=world)
    assert r.status == "bounded" and not r.exhaustive and r.exit_status == 0, r.verdict
    assert r.verdict == ("no violation — not exhaustive for straight/pymunk: positions in "
                         "mid-motion (getPosition() at line 7) [blackbox nondet]")
    out = cli("explore", prog, "--world", world, "--no-progress")
    assert out.exit_code == 0
    assert "exhaustive [" not in out.output.replace("not exhaustive for", "")


def test_retarget_starts_from_the_swept_region():
    """nondet's retarget: a robot still moving may be anywhere between its
    start and its target; one at rest keeps its start."""
    nd = load_blackbox("nondet")
    moving = ((4.0, 0.0, 0.0), (), None, False, False, ())
    assert nd.retarget((0.0, 0.0, 0.0), moving) == ((0.0, 0.0), (4.0, 0.0))
    arrived = ((4.0, 0.0, 0.0), (), None, True, False, ())
    assert nd.retarget((4.0, 0.0, 0.0), arrived) == ()
    failed = ((4.0, 0.0, 0.0), (), None, False, True, ((0.0, 0.0), (4.0, 0.0)))
    assert nd.retarget((0.0, 0.0, 0.0), failed) == ((0.0, 0.0), (4.0, 0.0))
    # the leg from the swept region meets the wall that the leg from the start misses
    w = parse_world("resolution = 0.01\nradius = 0.1\n[[obstacles]]\n"
                    "polygon = [[3.0, 1.0], [3.5, 1.0], [3.5, 1.5], [3.0, 1.5]]\n")
    m = motion((0.0, 0.0, 0.0), (3.2, 3.0, 0.0))
    assert [o.fail for o in nd.step(w, [m], None, 0, 1.0)] == [(False,), (False,)]
    m = motion((0.0, 0.0, 0.0), (3.2, 3.0, 0.0), start=((0.0, 0.0), (4.0, 0.0)))
    assert (True,) in [o.fail for o in nd.step(w, [m], None, 0, 1.0)]


# generated programs: a robot re-targeted after a number of steps, walls near
# the segments (near-tangent), several resolutions and speeds

RETARGET_PROGRAM = """\
allwrite:
  int arrived = 0;
  int failed = 0;
loc:
  int phase = 0;
  int ticks = 0;
Go():
  pre(phase == 0);
  eff:
    doReach(ItemPosition({x0}, {y0}), getObs());
    phase = 1;
Tick():
  pre(phase == 1 && ticks < {k});
  eff:
    ticks = ticks + 1;
Turn():
  pre(phase == 1 && ticks == {k});
  eff:
    doReach(ItemPosition({x1}, {y1}), getObs());
    phase = 2;
Again():
  pre(phase == 2 && doReach_fail);
  eff:
    phase = 3;
    doReach(ItemPosition({x2}, {y2}), getObs());
Failed():
  pre(phase == 3 && doReach_fail);
  eff:
    atomic:
      failed = failed + 1;
    exit();
Arrived():
  pre(phase >= 2 && doReach_done);
  eff:
    atomic:
      arrived = arrived + 1;
    exit();
"""

RETARGET_WORLD = """\
agents = 1
resolution = {res}
tolerance = {res}
radius = {r}
speed = {speed}
start = [[0, 0]]

[[obstacles]]
polygon = [[{wx0}, {wy0}], [{wx1}, {wy0}], [{wx1}, {wy1}], [{wx0}, {wy1}]]
"""


def retarget_generated(seed: int, tmp_path):
    rnd = random.Random(1000 + seed)
    res = rnd.choice([0.01, 0.05, 0.1])
    x0, y0 = round(rnd.uniform(4, 8), 1), round(rnd.uniform(-1, 1), 1)
    # the wall: a box whose corner grazes the first leg (near-tangent) or sits
    # off it, so that some re-targeted legs from mid-motion meet it
    t = rnd.uniform(0.3, 0.8)
    cx, cy = x0 * t, y0 * t + rnd.choice([0.02, 0.1, 0.3, 0.6])
    wx0, wy0 = round(cx, 2), round(cy, 2)
    wx1, wy1 = round(cx + rnd.uniform(0.3, 1.5), 2), round(cy + rnd.uniform(0.3, 1.5), 2)
    x1, y1 = round(rnd.uniform(cx - 1, cx + 2), 1), round(cy + rnd.uniform(2, 4), 1)
    x2, y2 = round(rnd.uniform(-2, 2), 1), round(rnd.uniform(2, 5), 1)
    text = RETARGET_PROGRAM.format(x0=x0, y0=y0, x1=x1, y1=y1, x2=x2, y2=y2,
                                   k=rnd.randint(1, 5))
    world = RETARGET_WORLD.format(res=res, r=rnd.choice([0.01, 0.05, 0.25]),
                                  speed=rnd.choice([0.7, 1.0, 1.5]),
                                  wx0=wx0, wy0=wy0, wx1=wx1, wy1=wy1)
    prog_path = tmp_path / f"rt{seed}.pccl"
    world_path = tmp_path / f"rt{seed}.toml"
    prog_path.write_text(text)
    world_path.write_text(world)
    return str(prog_path), str(world_path)


@pytest.mark.parametrize("seed", range(16))
def test_generated_retargets(seed, tmp_path):
    """Every end state of seeded straight runs is one explore reaches under
    the default blackbox; an invariant that holds there holds on the runs."""
    prog, world = retarget_generated(seed, tmp_path)
    check_covered(prog, world, None)
    for prop in ("failed == 0", "arrived == 0"):
        r = api.explore(prog, world=world, invariants=[prop], **PY_SEARCH)
        if r.violations or r.bounds:    # "not exhaustive for pymunk" still holds for straight
            continue
        res = api.run(prog, world=world, blackbox="straight", seed=0, max_time=60,
                      invariants=[prop])
        assert res.status != "violation", (prop, res.message)


def test_generated_retargets_are_not_vacuous(tmp_path):
    """Some generated re-targeted legs fail under straight, some arrive."""
    got = set()
    for seed in range(16):
        prog, world = retarget_generated(seed, tmp_path)
        res = api.run(prog, world=world, blackbox="straight", seed=0, max_time=60)
        got.add((res.final_state.shared["failed"] > 0, res.final_state.shared["arrived"] > 0))
    assert (True, False) in got and (False, True) in got


def test_second_legs_under_pymunk_are_not_exhaustive():
    """Where pymunk leaves a robot after a detour, a push or a failure is
    not followed by nondet: a program whose robots may start a second leg
    gets "not exhaustive for pymunk" (exit 0, as a bounded search), with the
    doReach that starts it; nondet-fail covers those legs; a program whose
    robots make one trip each is exhaustive."""
    race = _path("race_robust.pccl"), _path("race.toml")
    r = api.explore(race[0], world=race[1])
    assert r.status == "bounded" and r.exit_status == 0 and not r.violations
    assert r.verdict.startswith("no violation — not exhaustive for pymunk: a second leg starts "
                                "where pymunk left the robot (doReach at line 36; "
                                "blackbox=nondet-fail covers it) [blackbox nondet]"), r.verdict
    r = api.explore(race[0], world=race[1], blackbox="nondet-fail")
    assert r.status == "exhaustive" and r.not_covered is None, r.verdict
    one = textwrap.dedent("""\
        Init:
          doReach(ItemPosition(2, 0), getObs());
        Done():
          pre(doReach_done || doReach_fail);
          eff:
            exit();
        """)
    r = api.explore(one, source=True, world=race[1], agents=2)
    assert r.blackbox == "nondet" and r.status == "exhaustive", r.verdict
    assert api.second_leg(api.load_program(race[0])) == "doReach at line 36"


@pytest.mark.parametrize("seed", range(4))
def test_generated_retargets_native_equals_python(seed, tmp_path):
    """The leg start is a slot of the native engine's vector: both engines
    give the same verdict and figures, unreduced and with the default
    reductions."""
    prog, world = retarget_generated(seed, tmp_path)
    for reduce in ("none", "auto"):
        got = set()
        for engine in ("native", "python"):
            r = api.explore(prog, world=world, engine=engine, reduce=reduce,
                            invariants=["failed == 0"])
            got.add((r.verdict, r.stats.states, r.stats.transitions))
        assert len(got) == 1, (reduce, got)


def test_straight_stays_within_the_drift_of_its_region():
    """Nondet.drift bounds how far straight's rounded positions stray from
    the exact segment (the bound nondet's fail relies on): random legs,
    shallow and steep, resolutions 0.01 to 0.2, speeds 0.3 to 2, stepped
    through the engine's rounding; the largest stray seen is a real fraction
    of the bound (the bound is not vacuous)."""
    from pccl.blackboxes._geometry import convex_hull, shapely
    from pccl.blackboxes.nondet import NONDET
    from pccl.model.environment import Environment
    st = load_blackbox("straight")
    rnd = random.Random(3)
    worst = 0.0
    beyond_one_rounding = 0     # strays a single rounding (resolution·√2/2) does not cover
    for _ in range(300):
        res = rnd.choice([0.01, 0.05, 0.1, 0.2])
        w = parse_world(f"resolution = {res}\nspeed = {rnd.choice([0.3, 0.7, 1.0, 2.0])}\n")
        env = Environment(w, st, 1, 1.0)
        p = env.round_pos((0.0, 0.0, 0.0))
        t = env.round_pos((rnd.uniform(-20, 20), rnd.uniform(-3, 3), 0.0))
        region = convex_hull((p, t))
        bound = NONDET.drift(w, region, 1.0)
        seg = shapely.LineString([region[0], region[-1]]) if len(region) > 1 else \
            shapely.Point(region[0])
        m = motion(p, t)
        for _ in range(200):
            (o,) = st.step(w, [m], None, 0, 1.0)
            q = env.round_pos(o.positions[0])
            d = seg.distance(shapely.Point(q[0], q[1]))
            assert d <= bound, (res, w.speed, p, t, q, d, bound)
            worst = max(worst, d / bound)
            beyond_one_rounding += d > res * math.sqrt(0.5) + 1e-9
            if o.done[0]:
                break
            m = motion(q, t)
    assert worst > 0.05
    # rounding accumulates: inflating the segment by one rounding is not enough
    assert beyond_one_rounding > 0


def test_json_says_what_is_not_exhaustive():
    """pccl explore --format json: status bounded, exit 0, and what the
    covering blackbox leaves out in not_exhaustive_for."""
    import json
    from conftest import cli
    r = cli("explore", _path("race_robust.pccl"), "--world", _path("race.toml"),
            "--format", "json", "--no-progress")
    d = json.loads(r.output)
    assert r.exit_code == 0 and d["status"] == "bounded" and d["exit_status"] == 0
    assert d["not_exhaustive_for"].startswith("pymunk: a second leg starts where pymunk left "
                                              "the robot (doReach at line 36")
    r = cli("explore", _path(COVER + "cover_rounding_position.pccl"), "--world",
            _path(COVER + "cover_rounding_position.toml"), "--format", "json", "--no-progress")
    d = json.loads(r.output)
    assert d["not_exhaustive_for"] == ("straight/pymunk: positions in mid-motion "
                                       "(getPosition() at line 7)")


# generated failures part-way (hole 4): straight's rounded positions graze a
# triangle's vertex and fail the robot part-way; a small box stands on the
# second trip's path from there, away from its path from the start

def partway_generated(seed: int, tmp_path):
    from pccl.blackboxes._geometry import shapely
    from pccl.model.environment import Environment
    rnd = random.Random(5000 + seed)
    st = load_blackbox("straight")
    while True:
        res = rnd.choice([0.01, 0.05, 0.1])
        speed = rnd.choice([0.7, 1.0, 1.5])
        L, h = round(rnd.uniform(3, 8), 2), round(rnd.uniform(-2, 2), 2)
        s = rnd.uniform(0.3, 0.8)
        n = (-h / math.hypot(L, h), L / math.hypot(L, h))      # unit normal of the leg
        off = rnd.choice([0.0005, 0.002, 0.005, 0.01])
        vx, vy = L * s + n[0] * off, h * s + n[1] * off
        tri = ((round(vx, 4), round(vy, 4)),
               (round(vx + n[0] * 0.8 + 0.3, 4), round(vy + n[1] * 0.8, 4)),
               (round(vx + n[0] * 0.8 - 0.3, 4), round(vy + n[1] * 0.8, 4)))
        w = parse_world(f"resolution = {res}\nspeed = {speed}\nradius = 0.01\n"
                        f"tolerance = {res}\n[[obstacles]]\npolygon = {[list(p) for p in tri]}\n")
        env = Environment(w, st, 1, 1.0)
        q, t = env.round_pos((0.0, 0.0, 0.0)), env.round_pos((L, h, 0.0))
        if w.obstacles and shapely.Polygon(tri).distance(shapely.LineString([(0, 0), (L, h)])) == 0:
            continue
        fail_at = None
        for _ in range(100):
            (o,) = st.step(w, [motion(q, t)], None, 0, 1.0)
            if o.fail[0]:
                fail_at = q
                break
            if o.done[0]:
                break
            q = env.round_pos(o.positions[0])
        if fail_at is None or fail_at[:2] == (0.0, 0.0):
            continue
        # the second trip: a box on its path from the failure point, clear of
        # its path from the start and of the triangle
        t2 = (round(rnd.uniform(-3, 3), 2), round(rnd.uniform(3, 6), 2))
        mid = (fail_at[0] + (t2[0] - fail_at[0]) * 0.5, fail_at[1] + (t2[1] - fail_at[1]) * 0.5)
        box = [[round(mid[0] - 0.05, 3), round(mid[1] - 0.05, 3)],
               [round(mid[0] + 0.05, 3), round(mid[1] - 0.05, 3)],
               [round(mid[0] + 0.05, 3), round(mid[1] + 0.05, 3)],
               [round(mid[0] - 0.05, 3), round(mid[1] + 0.05, 3)]]
        g = shapely.Polygon(box)
        if (g.distance(shapely.LineString([(0, 0), t2])) < 0.5
                or g.distance(shapely.Polygon(tri)) < 0.1):
            continue
        break
    text = (open(_path("covering/cover_rounding_flags.pccl")).read()
            .replace("ItemPosition(3, 1)", f"ItemPosition({L}, {h})")
            .replace("ItemPosition(0.95, 2)", f"ItemPosition({t2[0]}, {t2[1]})"))
    world = (f"agents = 1\nresolution = {res}\nspeed = {speed}\nradius = 0.01\n"
             f"tolerance = {res}\nstart = [[0, 0]]\n[[obstacles]]\n"
             f"polygon = {[list(p) for p in tri]}\n[[obstacles]]\npolygon = {box}\n")
    prog_path, world_path = tmp_path / f"pw{seed}.pccl", tmp_path / f"pw{seed}.toml"
    prog_path.write_text(text)
    world_path.write_text(world)
    return str(prog_path), str(world_path)


@pytest.mark.parametrize("seed", range(6))
def test_generated_failures_part_way(seed, tmp_path):
    """straight fails the first trip part-way and the second trip from there
    on the box: explore under the default blackbox finds the assertion too,
    and covers every end state of the runs."""
    prog, world = partway_generated(seed, tmp_path)
    res = api.run(prog, world=world, blackbox="straight", seed=0)
    assert res.status == "violation" and "assertion failed" in res.message, res.message
    r = api.explore(prog, world=world, **PY_SEARCH)
    assert r.status == "violation" and "assertion failed" in r.verdict, r.verdict
    check_covered(prog, world, None)
