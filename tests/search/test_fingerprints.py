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
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as hs

from pccl.output import codec as C
from pccl.api import explore as _explore, make_model, run
from pccl.lang.values import UNDEF

from conftest import PROGRAMS, ROOT, SH, TEST_PROGRAMS, reachable
from cases import (FLOAT_LITS, INT_LITS, M61, PINNED, SHIPPED, SLOW, TESTPROGS, P, T, _params,  # noqa: F401
                   programs, src)


def explore(*args, **kw):
    """The unreduced search (reduce='none'): this file pins its counts and
    shortest counterexamples; tests/model/test_reduce.py covers the reductions."""
    kw.setdefault("reduce", "none")
    return _explore(*args, **kw)


MUTEX = "count(inCs) <= 1"


# ---------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------

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
