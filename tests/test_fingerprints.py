"""State identity: fingerprints (``exact=False``) against full keys (``exact=True``).

``pccl explore`` remembers visited states by a fingerprint of ``model.key``.
Two distinct states that share a fingerprint are merged, so the second is
never expanded and whatever only it leads to is silently missed.  Python's
``hash()`` is such a fingerprint: hash(-1) == hash(-2), hash(-1.0) ==
hash(-2.0), hash(1) == hash(1.0) == hash(True), hash(0) == hash(2**61 - 1),
and a tuple's hash only depends on its items' hashes.  This file is the
guard for its replacement (xxh3_128 over a canonical encoding of the key,
:mod:`pccl.search.fingerprint`) and for canonical values (a float slot always holds
a float):

1. differential: every shipped program (programs/*.pccl, with its world) and
   every program in tests/programs/ explored with fingerprints and with
   exact keys must give the same status, states, transitions, depth,
   violations and counterexamples (and the counts pinned below);
2. the same over small random programs (hypothesis);
3. hand-made programs whose distinct states collide under ``hash()``: the
   violation must be reported with and without ``exact``;
4. unit tests of ``pccl.search.fingerprint.encode`` / ``fingerprint``.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as hs

from pccl.output import codec as C
from pccl.api import explore as _explore, make_model, run
from pccl.lang.values import UNDEF

from conftest import PROGRAMS, ROOT, SH, TEST_PROGRAMS, reachable


def explore(*args, **kw):
    """The unreduced search (reduce='none'): this file pins its counts and
    shortest counterexamples; tests/test_reduce.py covers the reductions."""
    kw.setdefault("reduce", "none")
    return _explore(*args, **kw)


MUTEX = "count(inCs) <= 1"
M61 = 2**61 - 1                  # hash(M61) == hash(0) == 0


# ---------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------

def src(text: str) -> str:
    return textwrap.dedent(text).lstrip("\n")


def identities(res) -> set:
    return {(v["kind"], v["name"], v["line"]) for v in res.violations}


def summary(res) -> dict:
    """Everything that must not depend on how states are identified."""
    return {
        "status": res.status,
        "exit_status": res.exit_status,
        "states": res.stats.states,
        "transitions": res.stats.transitions,
        "max_depth": res.stats.max_depth,
        "initial_states": res.stats.initial_states,
        "bounds": res.bounds,
        "violations": identities(res),
        # BFS order does not depend on the fingerprint, so each distinct
        # violation is found at the same depth, with the same trace
        "found": [(v["kind"], v["name"], v["line"], v["column"], v["depth"])
                  for v in res.violations],
        "traces": [[(s["rule"], s["agent"]) for s in v.trace] for v in res.violations],
    }


def explore_both(program, **kw):
    """(fingerprinted, exact) explorations of the same program."""
    return explore(program, exact=False, **kw), explore(program, exact=True, **kw)


def assert_agree(fp, ex):
    a, b = summary(fp), summary(ex)
    for k in a:
        assert a[k] == b[k], f"{k}: fingerprints {a[k]!r} != exact {b[k]!r}"


def violated(res, name) -> bool:
    return any(v["kind"] == "invariant" and v["name"] == name for v in res.violations)


# ---------------------------------------------------------------------------
# 1. differential: shipped programs and tests/programs
# ---------------------------------------------------------------------------

def P(name):
    return str(PROGRAMS / name)


def T(name):
    return str(TEST_PROGRAMS / name)


FISCHER_SMALL = {"k": "1", "cstime": "0"}

# (id, program, explore options); every search uses find_all=True
SHIPPED = [
    ("fischer-paper-k10-bounded", P("fischer.pccl"),
     dict(invariants=[MUTEX], max_states=60_000)),
    ("fischer-k1-cstime0", P("fischer.pccl"),
     dict(invariants=[MUTEX], overrides=FISCHER_SMALL)),
    ("fischer-k1-d1", P("fischer.pccl"),
     dict(invariants=[MUTEX], overrides={"k": "1", "d": "1", "cstime": "0"})),
    ("fischer-k1-first-timed", P("fischer.pccl"),
     dict(invariants=[MUTEX], overrides=FISCHER_SMALL, events="first",
          abstract_time=False, max_time=30)),
    ("fischer-k2-depth", P("fischer.pccl"),
     dict(invariants=[MUTEX], overrides={"k": "2"}, depth=60)),
    ("race-straight", P("race.pccl"), dict(world=P("race.toml"), blackbox="straight")),
    ("race-straight-3", P("race.pccl"),
     dict(world=P("race.toml"), blackbox="straight", agents=3)),
    ("race-instant", P("race.pccl"), dict(world=P("race.toml"), blackbox="instant")),
    ("race-nondet", P("race.pccl"), dict(world=P("race.toml"), blackbox="nondet")),
    ("race-delta-half-timed", P("race.pccl"),
     dict(world=P("race.toml"), blackbox="straight", delta=0.5, max_time=20,
          abstract_time=False)),
    ("race-obstacles-straight", P("race.pccl"),
     dict(world=P("race_obstacles.toml"), blackbox="straight")),
    ("race_nonatomic-instant", P("race_nonatomic.pccl"),
     dict(world=P("race.toml"), blackbox="instant")),
    ("race_nonatomic-nondet", P("race_nonatomic.pccl"),
     dict(world=P("race.toml"), blackbox="nondet")),
    ("race_safe-nondet", P("race_safe.pccl"),
     dict(world=P("race.toml"), blackbox="nondet")),
    ("race_robust-nondet", P("race_robust.pccl"),
     dict(world=P("race.toml"), blackbox="nondet")),
    ("collide-straight-collisions", P("collide.pccl"),
     dict(world=P("collide.toml"), blackbox="straight", collisions=True)),
    ("collide-nondet", P("collide.pccl"), dict(world=P("collide.toml"), blackbox="nondet")),
    ("collide_fixed-straight-collisions", P("collide_fixed.pccl"),
     dict(world=P("collide.toml"), blackbox="straight", collisions=True)),
    ("collide_fixed-nondet", P("collide_fixed.pccl"),
     dict(world=P("collide.toml"), blackbox="nondet")),
    ("formation-straight", P("formation.pccl"),
     dict(world=P("formation.toml"), blackbox="straight")),
    ("formation-nondet-2", P("formation.pccl"),
     dict(world=P("formation.toml"), blackbox="nondet", agents=2)),
    ("formation-instant-3", P("formation.pccl"),
     dict(world=P("formation.toml"), blackbox="instant", agents=3)),
    ("leader-nondet-2", P("leader.pccl"), dict(blackbox="nondet", agents=2)),
    ("leader-nondet-3-bounded", P("leader.pccl"),
     dict(blackbox="nondet", agents=3, max_states=30_000)),
    ("leader-nondet-3-exhaustive", P("leader.pccl"), dict(blackbox="nondet", agents=3)),
    ("rendezvous-straight-3-bounded", P("rendezvous.pccl"),
     dict(world=P("rendezvous.toml"), blackbox="straight", max_states=30_000)),
    ("rendezvous-nondet-2", P("rendezvous.pccl"),
     dict(world=P("rendezvous.toml"), blackbox="nondet", agents=2)),
    ("rendezvous-instant-3-bounded", P("rendezvous.pccl"),
     dict(world=P("rendezvous.toml"), blackbox="instant", agents=3, max_states=30_000)),
]

TESTPROGS = [
    ("eng_abs_maxtime", T("eng_abs_maxtime.pccl"), dict(blackbox="instant")),
    ("eng_assert", T("eng_assert.pccl"), dict(blackbox="instant")),
    ("eng_flags", T("eng_flags.pccl"), dict(blackbox="instant", agents=3)),
    ("eng_lock", T("eng_lock.pccl"), dict(blackbox="instant")),
    ("eng_lock-3-n0-2", T("eng_lock.pccl"),
     dict(blackbox="nondet", agents=3, n0=2, rates={1: 2}, max_states=20_000)),
    ("eng_loop-bounded", T("eng_loop.pccl"), dict(blackbox="instant", max_states=5_000)),
    ("eng_move1-straight", T("eng_move1.pccl"), dict(blackbox="straight")),
    ("eng_move1-nondet", T("eng_move1.pccl"), dict(blackbox="nondet")),
    ("ref_allread-3", T("ref_allread.pccl"), dict(blackbox="instant", agents=3)),
    ("ref_assert", T("ref_assert.pccl"), dict(blackbox="instant")),
    ("ref_atomic", T("ref_atomic.pccl"), dict(blackbox="instant")),
    ("ref_doreach-instant", T("ref_doreach.pccl"), dict(blackbox="instant")),
    ("ref_doreach-nondet-timed", T("ref_doreach.pccl"),
     dict(blackbox="nondet", max_time=3, abstract_time=False)),
    ("ref_events", T("ref_events.pccl"), dict(blackbox="instant")),
    ("ref_events-timed", T("ref_events.pccl"),
     dict(blackbox="instant", max_time=3, abstract_time=False)),
    ("ref_guard_error", T("ref_guard_error.pccl"), dict(blackbox="instant")),
    ("ref_ifchain-3", T("ref_ifchain.pccl"), dict(blackbox="instant", agents=3)),
    ("ref_init-3", T("ref_init.pccl"), dict(blackbox="instant", agents=3)),
    ("ref_list", T("ref_list.pccl"), dict(blackbox="instant")),
    ("ref_mutex_bad", T("ref_mutex_bad.pccl"), dict(blackbox="instant", invariants=[MUTEX])),
    ("ref_nested", T("ref_nested.pccl"), dict(blackbox="instant")),
    ("ref_rand", T("ref_rand.pccl"), dict(blackbox="instant")),
    ("ref_undef", T("ref_undef.pccl"), dict(blackbox="instant")),
    ("ref_values", T("ref_values.pccl"), dict(blackbox="instant")),
    ("ref_while", T("ref_while.pccl"), dict(blackbox="instant")),
    # temporal properties (tests/test_temporal.py)
    ("rdv_meet-wall", T("rdv_meet.pccl"),
     dict(blackbox="straight", world=T("rdv_wall.toml"),
          properties=["eventually forall i: exited[i]"])),
    ("rdv_meet-open-nondet", T("rdv_meet.pccl"),
     dict(world=T("rdv_open.toml"), blackbox="nondet",
          properties=["eventually forall i: exited[i]"])),
    ("token_ring-3", T("token_ring.pccl"),
     dict(agents=3, properties=["forall i: want[i] ~> has[i]", "want[1] ~> has[1] within 2"])),
    ("token_keep-3", T("token_keep.pccl"),
     dict(agents=3, properties=["forall i: want[i] ~> has[i]"])),
    ("tl_spin", T("tl_spin.pccl"), dict()),
    ("tl_spin_leave", T("tl_spin_leave.pccl"), dict()),
    ("fast_slow-2", T("fast_slow.pccl"), dict(agents=2)),
    ("runaway-bounded", T("runaway.pccl"), dict(max_states=3000)),
    ("alternate", T("alternate.pccl"), dict()),
    ("drive_exit", T("drive_exit.pccl"), dict(world=T("drive3.toml"), blackbox="nondet")),
    ("list_seen-2", T("list_seen.pccl"), dict(agents=2)),
    ("patrol-pillar", T("patrol.pccl"), dict(world=T("patrol_pillar.toml"), blackbox="straight",
                                              max_states=20_000)),
    ("peterson_swapped-n0-2", T("peterson_swapped.pccl"),
     dict(invariants=["count(inCs) <= 1"], n0=2)),
    ("viewer_marker", T("viewer_marker.pccl"), dict()),
]


SLOW = {"leader-nondet-3-exhaustive"}     # ~6 s per search, 12 s for the pair


def _params(cases):
    return [pytest.param(*c, id=c[0], marks=[pytest.mark.slow] if c[0] in SLOW else [])
            for c in cases]


# (status, states, transitions, max_depth) of each case: today's exact=True
# (a --max-states search admits exactly that many states and counts the
# transitions of the parents expanded up to the first state that did not fit)
# counts (identical to today's fingerprint counts).  They stay right as long
# as every variable has one value representation (canonical values): were a
# float slot to hold 1 in one state and 1.0 in another, an encoding that
# tells int from float would count them twice.
# The nondet rows grew when nondet began to cover straight and pymunk
# (docs/blackboxes.md): robots whose lanes meet, or pass near an obstacle,
# may also fail; the same counts come from the reference interpreter
# (tests/test_reference.py) for the race programs.
#: (a program whose agents end idling for ever without exiting is a stall
#: since the stall check, docs/decisions.md: "violation", same counts)
# "bounded" under nondet: complete for nondet, not exhaustive for straight/pymunk
# (positions read) or for pymunk (second legs); counts as before (issue 41)
PINNED = {
    "peterson_swapped-n0-2": ("violation", 1152, 2076, 87),
    "viewer_marker": ("violation", 16, 24, 6),
    "fischer-paper-k10-bounded": ("bounded", 60000, 78578, 4),
    "fischer-k1-cstime0": ("violation", 13696, 23238, 476),
    "fischer-k1-d1": ("violation", 16402, 27870, 556),
    "fischer-k1-first-timed": ("violation", 30007, 50694, 418),
    "fischer-k2-depth": ("bounded", 84996, 141552, 60),
    "race-straight": ("exhaustive", 615, 970, 189),
    "race-straight-3": ("exhaustive", 11097, 25655, 265),
    "race-instant": ("violation", 1211, 2046, 103),
    "race-nondet": ("violation", 5280, 8991, 94),          # 3729 before nondet could fail
    "race-delta-half-timed": ("exhaustive", 659, 1024, 292),
    "race-obstacles-straight": ("violation", 67, 112, 21),
    "race_nonatomic-instant": ("violation", 676, 1110, 96),
    "race_nonatomic-nondet": ("violation", 4647, 7869, 92),  # 3144 before
    # a stall since nondet covers robots blocking each other: both robots
    # drive to the same waypoint and race_safe never handles doReach_fail
    "race_safe-nondet": ("violation", 10143, 17737, 124),  # 7924 before
    # race_safe handling doReach_fail (picks again): no stall
    "race_robust-nondet": ("bounded", 24898, 44360, 128),
    "collide-straight-collisions": ("violation", 65, 96, 32),
    "collide-nondet": ("violation", 110, 176, 15),        # 60 before; a stall
    "collide_fixed-straight-collisions": ("exhaustive", 504, 794, 82),
    "collide_fixed-nondet": ("bounded", 416, 686, 45),
    "formation-straight": ("exhaustive", 8996, 25184, 185),
    "formation-nondet-2": ("bounded", 1341, 2396, 68),
    "formation-instant-3": ("exhaustive", 8716, 24624, 105),
    "leader-nondet-2": ("exhaustive", 3216, 6000, 94),
    "leader-nondet-3-bounded": ("bounded", 30000, 81351, 27),
    "leader-nondet-3-exhaustive": ("exhaustive", 202252, 572053, 171),
    "rendezvous-straight-3-bounded": ("bounded", 30000, 67339, 29),
    "rendezvous-nondet-2": ("bounded", 7540, 13488, 95),  # 6068 before
    "rendezvous-instant-3-bounded": ("bounded", 30000, 67339, 29),
    "eng_abs_maxtime": ("violation", 1059, 1972, 56),
    "eng_assert": ("violation", 46, 73, 17),
    "eng_flags": ("exhaustive", 157, 346, 28),
    "eng_lock": ("exhaustive", 5554, 9750, 136),
    "eng_lock-3-n0-2": ("bounded", 20000, 48077, 36),
    "eng_loop-bounded": ("bounded", 5000, 8746, 1251),
    "eng_move1-straight": ("violation", 56, 80, 31),
    "eng_move1-nondet": ("violation", 29, 44, 13),
    "ref_allread-3": ("violation", 895, 2032, 32),
    "ref_assert": ("violation", 101, 147, 22),
    "ref_atomic": ("violation", 867, 1428, 53),
    "ref_doreach-instant": ("violation", 119, 190, 48),
    "ref_doreach-nondet-timed": ("bounded", 273, 428, 34),
    "ref_events": ("violation", 676, 1316, 34),
    "ref_events-timed": ("bounded", 1212, 2294, 30),
    "ref_guard_error": ("violation", 6, 7, 3),
    "ref_ifchain-3": ("violation", 15148, 37792, 57),
    "ref_init-3": ("violation", 5888, 9984, 28),
    "ref_list": ("violation", 326, 528, 50),
    "ref_mutex_bad": ("violation", 111, 176, 16),
    "ref_nested": ("violation", 471, 768, 45),
    "ref_rand": ("violation", 3150, 5580, 12),
    "ref_undef": ("violation", 35, 58, 10),
    "ref_values": ("violation", 79, 132, 26),
    "ref_while": ("violation", 783, 1386, 26),
    "rdv_meet-wall": ("violation", 26, 38, 13),
    "rdv_meet-open-nondet": ("exhaustive", 36, 53, 14),
    "token_ring-3": ("violation", 724, 1632, 44),
    "token_keep-3": ("violation", 593, 1333, 43),
    "tl_spin": ("violation", 9, 18, 4),
    "tl_spin_leave": ("exhaustive", 24, 40, 8),
    "fast_slow-2": ("violation", 761, 1414, 44),
    "runaway-bounded": ("bounded", 3000, 5848, 76),
    "alternate": ("exhaustive", 26, 40, 9),
    "drive_exit": ("bounded", 340, 753, 21),
    "list_seen-2": ("exhaustive", 205, 302, 28),
    "patrol-pillar": ("violation", 10350, 24180, 153),
}


def test_every_program_is_covered():
    named = {Path(c[1]).name for c in SHIPPED + TESTPROGS}
    on_disk = {p.name for d in (PROGRAMS, TEST_PROGRAMS) for p in d.glob("*.pccl")}
    assert on_disk <= named, f"add a differential case for {sorted(on_disk - named)}"


@pytest.mark.parametrize("name,program,options", _params(SHIPPED + TESTPROGS))
def test_fingerprints_agree_with_exact(name, program, options):
    fp, ex = explore_both(program, find_all=True, **options)
    assert_agree(fp, ex)
    got = (ex.status, ex.stats.states, ex.stats.transitions, ex.stats.max_depth)
    assert got == PINNED[name], f"the exact search changed: {got} != pinned {PINNED[name]}"


# ---------------------------------------------------------------------------
# 2. random programs (hypothesis)
# ---------------------------------------------------------------------------

# literals that collide under hash(): -1/-2, 0/2**61-1, 1/1.0/true, -1.0/-2.0
INT_LITS = [0, 1, 2, 3, -1, -2, M61, -M61]
FLOAT_LITS = ["0.0", "1.0", "-1.0", "-2.0", "0.5", "1.5"]


@hs.composite
def int_expr(draw, ints, depth=2):
    """+ and - of ints and literals; * only by a literal in -1..2 (no
    squaring: values grow at most exponentially along a path)."""
    leaves = [hs.sampled_from(INT_LITS).map(str)]
    if ints:
        leaves.append(hs.sampled_from(ints))
    leaf = hs.one_of(*leaves)
    if depth == 0 or not draw(hs.booleans()):
        return draw(leaf)
    a = draw(int_expr(ints, depth - 1))
    if draw(hs.integers(0, 2)) == 0:
        return f"({a} * {draw(hs.sampled_from(['-1', '0', '1', '2']))})"
    op = draw(hs.sampled_from(["+", "-"]))
    return f"({a} {op} {draw(int_expr(ints, depth - 1))})"


@hs.composite
def float_expr(draw, floats, ints, depth=2):
    """Floats never overflow: * only by 0.5, -1.0 or 0 (no inf, no nan)."""
    leaves = [hs.sampled_from(FLOAT_LITS)]
    if floats:
        leaves.append(hs.sampled_from(floats))
    leaf = hs.one_of(*leaves)
    if depth == 0 or not draw(hs.booleans()):
        return draw(leaf)
    a = draw(float_expr(floats, ints, depth - 1))
    if draw(hs.integers(0, 2)) == 0:
        return f"({a} * {draw(hs.sampled_from(['0.5', '-1.0', '0', '-1']))})"
    op = draw(hs.sampled_from(["+", "-"]))
    b = draw(hs.one_of(float_expr(floats, ints, depth - 1), int_expr(ints, 0)))
    return f"({a} {op} {b})"


@hs.composite
def bool_expr(draw, v, depth=2):
    kind = draw(hs.sampled_from(["lit", "var", "icmp", "fcmp", "not", "and", "or"]
                                if depth else ["lit", "var", "icmp", "fcmp"]))
    if kind == "var" and v["bool"]:
        return draw(hs.sampled_from(v["bool"]))
    if kind == "fcmp" and v["float"]:
        op = draw(hs.sampled_from(["<", "<=", "==", "!=", ">"]))
        return (f"{draw(float_expr(v['float'], v['int'], 1))} {op} "
                f"{draw(float_expr(v['float'], v['int'], 1))}")
    if kind in ("icmp", "var", "fcmp"):
        op = draw(hs.sampled_from(["<", "<=", "==", "!=", ">", ">="]))
        return f"{draw(int_expr(v['int'], 1))} {op} {draw(int_expr(v['int'], 1))}"
    if kind == "not":
        return f"!({draw(bool_expr(v, depth - 1))})"
    if kind in ("and", "or"):
        op = "&&" if kind == "and" else "||"
        return f"({draw(bool_expr(v, depth - 1))} {op} {draw(bool_expr(v, depth - 1))})"
    return draw(hs.sampled_from(["true", "false"]))


@hs.composite
def statement(draw, v, indent, depth=2):
    pad = "  " * indent
    kinds = ["assign", "assign", "assign", "rand"]
    if v["list"]:
        kinds += ["list"]
    if depth:
        kinds += ["if", "atomic"]
    kind = draw(hs.sampled_from(kinds))
    if kind == "if":
        cond = draw(bool_expr(v, 1))
        body = draw(hs.lists(statement(v, indent + 1, depth - 1), min_size=1, max_size=2))
        text = f"{pad}if ({cond}):\n" + "".join(body)
        if draw(hs.booleans()):
            other = draw(hs.lists(statement(v, indent + 1, depth - 1), min_size=1, max_size=2))
            text += f"{pad}else:\n" + "".join(other)
        return text
    if kind == "atomic":
        body = draw(hs.lists(statement(v, indent + 1, depth - 1), min_size=1, max_size=2))
        return f"{pad}atomic:\n" + "".join(body)
    if kind == "rand" and v["int"]:
        return f"{pad}{draw(hs.sampled_from(v['int']))} = rand({draw(hs.integers(1, 2))});\n"
    if kind == "list":
        xs = draw(hs.sampled_from(v["list"]))
        op = draw(hs.sampled_from(["add", "head", "remove"]))
        if op == "add":
            return f"{pad}add({xs}, {draw(float_expr(v['float'], v['int'], 1))});\n"
        if op == "head" and v["float"]:
            return (f"{pad}if (!isEmpty({xs})):\n"
                    f"{pad}  {draw(hs.sampled_from(v['float']))} = head({xs}) / 2;\n")
        return (f"{pad}if (size({xs}) > 1):\n"
                f"{pad}  remove({xs}, head({xs}));\n")
    # assignment to a variable of a drawn type
    types = [t for t in ("int", "bool", "float") if v[t]]
    t = draw(hs.sampled_from(types))
    name = draw(hs.sampled_from(v[t]))
    if t == "int":
        rhs = draw(int_expr(v["int"]))
    elif t == "bool":
        rhs = draw(bool_expr(v, 1))
    else:
        rhs = draw(hs.one_of(float_expr(v["float"], v["int"]), int_expr(v["int"], 1)))
    return f"{pad}{name} = {rhs};\n"


@hs.composite
def programs(draw):
    """A small well-typed PCCL program (text) and its invariants."""
    v = {"int": [], "bool": [], "float": [], "list": []}          # every variable
    shared = {"int": [], "bool": [], "float": [], "list": []}     # allwrite ones
    sections = {"allwrite": [], "loc": []}
    n = 0
    for section in ("allwrite", "loc"):
        for t in draw(hs.lists(hs.sampled_from(["int", "int", "bool", "float", "list"]),
                               min_size=1 if section == "allwrite" else 0, max_size=3)):
            name = f"v{n}"
            n += 1
            if t == "int":
                init = draw(hs.sampled_from([str(i) for i in INT_LITS[:6]] + ["rand(1)"]))
                decl = f"int {name} = {init}"
            elif t == "bool":
                decl = f"bool {name} = {draw(hs.sampled_from(['true', 'false']))}"
            elif t == "float":
                decl = f"float {name} = {draw(hs.sampled_from(['0.0', '1.0', '-1.0', '1', '0']))}"
            else:
                decl = f"List<float> {name} = {draw(hs.sampled_from(['[]', '[1]', '[1.0, 2]']))}"
            sections[section].append(decl)
            v[t].append(name)
            if section == "allwrite":
                shared[t].append(name)
    if not v["int"]:
        sections["allwrite"].append(f"int v{n} = 0")
        v["int"].append(f"v{n}")
        shared["int"].append(f"v{n}")
    text = ""
    for section in ("allwrite", "loc"):
        if sections[section]:
            text += f"{section}:\n" + "".join(f"  {d};\n" for d in sections[section])
    for e in range(draw(hs.integers(1, 3))):
        guard = draw(bool_expr(v, 1))
        body = draw(hs.lists(statement(v, 2), min_size=1, max_size=3))
        text += f"\nE{e}():\n  pre({guard});\n  eff:\n" + "".join(body)
    invariants = draw(hs.lists(bool_expr(shared, 1), max_size=2))
    return text, invariants


@settings(max_examples=40, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(prog=programs(), agents=hs.integers(1, 2), blackbox=hs.sampled_from(["instant", "nondet"]))
def test_random_programs_fingerprints_agree_with_exact(prog, agents, blackbox):
    text, invariants = prog
    fp, ex = explore_both(text, source=True, agents=agents, blackbox=blackbox,
                          invariants=invariants, find_all=True, max_states=2000)
    assert_agree(fp, ex)


# ---------------------------------------------------------------------------
# 3. states that collide under hash(): the violation must be found
# ---------------------------------------------------------------------------

def assert_found_both_ways(program, invariant, **kw):
    fp, ex = explore_both(program, find_all=True, invariants=[invariant], **kw)
    for res, how in ((fp, "fingerprints"), (ex, "exact")):
        assert res.exit_status == 1, f"{how}: {res.verdict}"
        assert violated(res, invariant), f"{how}: {invariant!r} not reported: {res.verdict}"
    assert_agree(fp, ex)
    return fp, ex


COUNTDOWN_INT = src("""
    allwrite:
      int x = 0;

    Dec():
      pre(x > -5);
      eff:
        x = x - 1;
    """)

COUNTDOWN_LOCAL_INT = src("""
    loc:
      int x = 0;

    Dec():
      pre(x > -5);
      eff:
        x = x - 1;
    """)

COUNTDOWN_FLOAT = src("""
    allwrite:
      float x = 0.0;

    Dec():
      pre(x > -5.0);
      eff:
        x = x - 1.0;
    """)


@pytest.mark.parametrize("agents", [1, 2])
def test_int_minus_one_and_minus_two_are_distinct(agents):
    """hash(-1) == hash(-2): the state x = -2 looks like the visited x = -1."""
    fp, ex = assert_found_both_ways(COUNTDOWN_INT, "x != -2", source=True,
                                    blackbox="instant", agents=agents)
    assert fp.violation["depth"] == ex.violation["depth"]


def test_local_int_minus_one_and_minus_two_are_distinct():
    assert_found_both_ways(COUNTDOWN_LOCAL_INT, "forall i: x[i] != -2", source=True,
                           blackbox="instant", agents=2)


def test_float_minus_one_and_minus_two_are_distinct():
    """hash(-1.0) == hash(-2.0) (both are -2)."""
    assert_found_both_ways(COUNTDOWN_FLOAT, "x != -2.0", source=True,
                           blackbox="instant", agents=1)


def test_zero_and_two_to_the_61_minus_1_are_distinct():
    """hash(-M) == hash(0) == hash(M) for M = 2**61 - 1: x steps -M, 0, M."""
    prog = src(f"""
        allwrite:
          int x = -{M61};

        Up():
          pre(x < {M61});
          eff:
            x = x + {M61};
        """)
    assert_found_both_ways(prog, f"x != {M61}", source=True, blackbox="instant", agents=1)


def test_undefined_and_an_int_are_distinct():
    """UNDEF (Ellipsis) hashes by address; the int equal to that hash collides
    with it.  From the initial state (x undefined) B sets x to that int; the
    resulting state differs from the initial one in x only.  Only from it can
    D then C run; from the undefined x, C's guard gets the agent stuck."""
    h = hash(UNDEF)
    assert hash(h) == h
    prog = src(f"""
        allwrite:
          int x;
          int ph = 0;
          bool go = false;

        A():
          pre(ph == 0);
          eff:
            skip;

        B():
          pre(ph == 0);
          eff:
            x = {h};

        D():
          pre(ph == 0);
          eff:
            ph = 1;

        C():
          pre(ph == 1 && x == {h});
          eff:
            go = true;
        """)
    assert_found_both_ways(prog, "!go", source=True, blackbox="instant", agents=1)


ROBOT = src("""
    loc:
      bool sent = false;

    Go():
      pre(!sent);
      eff:
        doReach(ItemPosition(0, 0), getObs());
        sent = true;
    """)


@pytest.fixture
def west_world(tmp_path):
    """One robot at (-3, 0): under `straight` it passes (-2, 0) and (-1, 0),
    whose float coordinates collide under hash()."""
    w = tmp_path / "west.toml"
    w.write_text("agents = 1\nresolution = 0.01\nradius = 0.25\nspeed = 1.0\n"
                 "start = [[-3, 0]]\n")
    return str(w)


@pytest.mark.parametrize("blackbox", ["straight", "instant"])
@pytest.mark.parametrize("invariant", ["!doReach_done[0]", "pos[0].x < -0.5"])
def test_robot_reaches_the_origin(west_world, blackbox, invariant):
    assert_found_both_ways(ROBOT, invariant, source=True, world=west_world,
                           blackbox=blackbox)


# -- 3 (d): canonical values.  A float slot holds a float whatever literal
# initialised it: 1 and 1.0 are equal and hash alike, so today's explorer
# merges them, but the program can tell them apart (1 / 2 is 0, 1.0 / 2 is
# 0.5), and a type-aware encoding would not merge them.

HALF = """
    allwrite:
      {decl}
      float r = -1.0;

    Go():
      pre(r == -1.0);
      eff:
        {stmts}
        r = {expr} / 2;
        exit();
    """

HALF_CASES = [
    pytest.param("float f = 1;", "skip;", "f", id="float-var-int-literal"),
    pytest.param("float f = 0.0;", "f = 1;", "f", id="float-var-assigned-int"),
    pytest.param("float a[1];", "a[0] = 1;", "a[0]", id="float-array-element"),
    pytest.param("List<float> xs = [1];", "skip;", "head(xs)", id="list-literal-init"),
    pytest.param("List<float> xs = [];", "xs = [1];", "head(xs)", id="list-literal-assigned"),
    pytest.param("List<float> xs = [];", "add(xs, 1);", "head(xs)", id="list-add-int"),
    pytest.param("ItemPosition p = ItemPosition(1, 2);", "skip;", "p.x", id="position"),
]


def half_program(decl, stmts, expr):
    return src(HALF.format(decl=decl, stmts=stmts, expr=expr))


@pytest.mark.parametrize("decl,stmts,expr", HALF_CASES)
def test_float_slot_holding_one_halves_to_one_half(decl, stmts, expr):
    prog = half_program(decl, stmts, expr)
    res = run(prog, source=True, blackbox="instant", agents=1)
    assert res.status == "final", res.message
    state = C.encode_state(res.model, res.final)
    assert state["shared"]["r"] == 0.5
    assert_found_both_ways(prog, "r != 0.5", source=True, blackbox="instant", agents=1)


def floats_in(x):
    """The non-float scalars inside a float (or List<float>, float[n],
    ItemPosition) value."""
    if isinstance(x, tuple):
        return [y for z in x for y in floats_in(z)]
    return [] if (x is UNDEF or type(x) is float) else [x]


@pytest.mark.parametrize("decl,stmts,expr", HALF_CASES)
def test_float_slot_values_are_floats(decl, stmts, expr):
    """Every value held in a float slot is a Python float (not an int or a
    bool), in every reachable state."""
    m = make_model(half_program(decl, stmts, expr), source=True, blackbox="instant", agents=1)
    names = [n for n in ("f", "a", "xs", "p", "r") if n in m.compiled.layout.vars]
    for st in reachable(m):
        for n in names:
            val = st[SH][m.compiled.layout.vars[n].slot]
            assert not floats_in(val), f"{n} = {val!r} holds a non-float"


def test_list_of_float_int_literal_same_space_as_float_literal():
    """`List<float> xs = [1]` and `= [1.0]` are the same program."""
    a = explore(half_program("List<float> xs = [1];", "skip;", "head(xs)"), source=True,
                blackbox="instant", agents=2, find_all=True, invariants=["r != 0.5"])
    b = explore(half_program("List<float> xs = [1.0];", "skip;", "head(xs)"), source=True,
                blackbox="instant", agents=2, find_all=True, invariants=["r != 0.5"])
    assert_agree(a, b)


# ---------------------------------------------------------------------------
# 4. pccl.search.fingerprint
# ---------------------------------------------------------------------------

# pccl.search.fingerprint comes with the xxh3 change; imported inside each test so
# that sections 1-3 run without it.

def encode(key) -> bytes:
    from pccl.search.fingerprint import encode as enc
    return enc(key)


def fingerprint(key) -> bytes:
    from pccl.search.fingerprint import fingerprint as fp
    return fp(key)


def fresh(x):
    """A deep copy of x sharing no object with it (new tuples, ints, floats)."""
    if isinstance(x, tuple):
        return tuple([fresh(y) for y in x])
    if type(x) is bool or x is UNDEF or x is None:
        return x
    if type(x) is int:
        return int(str(x))
    if type(x) is float:
        return float.fromhex(x.hex())
    if type(x) is str:
        return "".join(list(x))
    return x


SCALARS = [0, 1, -1, -2, 2, M61, -M61, 2**61, 2**63, 2**64 + 1, -(2**64),
           0.0, 1.0, -1.0, -2.0, 0.5, 1e300,
           True, False, UNDEF, None]
NESTED = [(), (1,), (1.0,), (True,), (UNDEF,), ((1,),), ((1.0,),), (1, 1), (1, 1.0),
          (1.0, 1), ((1, 1),), (1, (1,)), ((1,), 1), (-1, -2), (-2, -1), ((), ()), ((),),
          (0, M61), (M61, 0)]
VALUES = SCALARS + NESTED

CONTEXTS = [
    ("bare", lambda v: v),
    ("1-tuple", lambda v: (v,)),
    ("nested-3", lambda v: (((v,),),)),
    ("state-like", lambda v: (0, (UNDEF, (v, 1.5), ()), (1, 2))),
    ("deep-last", lambda v: (1, (2, (3, (4, (5, v)))))),
    ("pair-first", lambda v: (v, 0)),
]


def shape(x):
    """x with the type of every item spelled out: 1, 1.0 and True differ."""
    return (type(x).__name__, tuple(shape(y) for y in x) if isinstance(x, tuple) else repr(x))


def same(a, b) -> bool:
    return shape(a) == shape(b)


def test_values_are_pairwise_different():
    # sanity of the table itself: no two entries are the same value of the same shape
    assert len({shape(v) for v in VALUES}) == len(VALUES)


def test_fingerprint_is_16_bytes_of_xxh3_128_of_encoding():
    import xxhash
    for v in VALUES:
        fp = fingerprint(v)
        assert isinstance(fp, bytes) and len(fp) == 16
        assert isinstance(encode(v), bytes)
        assert fp == xxhash.xxh3_128_digest(encode(v))
        assert fingerprint(v) == fp and encode(v) == encode(v)


@pytest.mark.parametrize("ctx", [c[1] for c in CONTEXTS], ids=[c[0] for c in CONTEXTS])
def test_distinct_values_distinct_fingerprints(ctx):
    keys = [ctx(v) for v in VALUES]
    encs = {}
    for v, k in zip(VALUES, keys):
        e = encode(k)
        assert e not in encs, f"{v!r} and {encs[e]!r} encode alike"
        encs[e] = v
    fps = {}
    for v, k in zip(VALUES, keys):
        f = fingerprint(k)
        assert f not in fps, f"{v!r} and {fps[f]!r} share a fingerprint"
        fps[f] = v


def test_distinct_values_distinct_across_contexts():
    # a value at one depth against every value at every depth
    keys = {}
    for cname, ctx in CONTEXTS:
        for v in VALUES:
            k = ctx(v)
            f = fingerprint(k)
            if f in keys:
                other = keys[f]
                assert same(other[2], k), f"{cname}({v!r}) collides with {other[0]}({other[1]!r})"
            keys[f] = (cname, v, k)


def test_shared_and_unshared_equal_keys_same_fingerprint():
    a = (1, 2.0, M61, -2, UNDEF)
    big = 2**70
    x = 0.1 + 0.2
    shared = (a, a, (a, (a,)), big, big, x, x, "pos", "pos")
    unshared = fresh(shared)
    assert unshared == shared
    assert unshared[0] is not unshared[1] and unshared[3] is not unshared[4]
    assert unshared[5] is not unshared[6]
    assert encode(unshared) == encode(shared)
    assert fingerprint(unshared) == fingerprint(shared)
    # sharing across a tuple and its copy inside another structure
    assert fingerprint(((a,), a)) == fingerprint(fresh(((a,), a)))


def test_real_states_fingerprint_independently_of_sharing():
    """Keys of reachable states, rebuilt without sharing, keep their
    fingerprint; distinct keys get distinct fingerprints."""
    for m in (make_model(P("race.pccl"), world=P("race.toml"), blackbox="nondet"),
              make_model(P("fischer.pccl"), overrides={"k": "1"}, abstract_time=False,
                         max_time=8)):
        keys = [m.key(st) for st in reachable(m, 3000)]
        fps = {fingerprint(k) for k in keys}
        assert len(fps) == len(keys)
        for k in keys[::7]:
            assert fingerprint(fresh(k)) == fingerprint(k)


def test_fingerprint_stable_across_processes():
    """Not derived from hash() of anything (str hashes are salted per process,
    UNDEF's by address): another interpreter computes the same bytes."""
    key = (0, (UNDEF, -1, -2.0, True, (M61, "s")), ())
    code = ("from pccl.search.fingerprint import fingerprint; "
            "print(fingerprint((0, (..., -1, -2.0, True, (2**61 - 1, 's')), ())).hex())")
    env = dict(os.environ, PYTHONHASHSEED="123")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=ROOT, env=env, check=True)
    assert out.stdout.strip() == fingerprint(key).hex()
