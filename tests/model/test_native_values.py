"""Issue 43.1: the native engine for the programs that fell back to the
Python engine: invariants over positions, floats and lists (``dist()``,
``mine[i] != mine[j]``: property memo sites), collision checking,
indexed assignments, rand() in statements, more than 16 agents, and the
frozen-team check on the native model.  Python stays the reference: each construct is checked on
programs using it, native against Python (verdict, states, transitions,
depth, violations with their messages, counterexample labels and
configurations), including the edge cases of floats and ints (division by
zero, NaN, infinities, ints beyond 64 bits, an index out of range: the same
stuck reason or violation message and line)."""

import os

import pytest

from pccl.api import explore, make_model
from pccl.model import native as NV
from pccl.model.layout import AGS, PC

from cases import src

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
_probe = make_model(os.path.join(ROOT, "programs/fischer.pccl"), reduce="none")
MISSING = NV.unsupported(_probe)
# (every test compiles native modules and runs both engines: seconds each)
pytestmark = [pytest.mark.skipif(MISSING is not None, reason=f"native engine unavailable: {MISSING}"),
              pytest.mark.slow]

UNREDUCED = dict(reduce="none", timelock=False, stall=False)


@pytest.fixture(autouse=True)
def _cache(tmp_path_factory, monkeypatch):
    monkeypatch.setenv("PCCL_CACHE", str(tmp_path_factory.getbasetemp() / "native-cache"))


def P(*parts):
    return os.path.join(ROOT, *parts)


def canonical(model, st) -> tuple:
    """A configuration with each pc replaced by its k cell (the engines
    intern pcs in different orders)."""
    ags = tuple((tuple(model.ctl.ks[a[PC]]),) + a[PC + 1:] for a in st[AGS])
    return st[:4] + (ags,) + st[5:]


def summary(r) -> dict:
    s = r.stats
    return {"status": r.status, "exit": r.exit_status, "states": s.states,
            "transitions": s.transitions, "depth": s.max_depth, "verdict": r.verdict,
            "violations": [(v.violation.identity, v.violation.message) for v in r.counterexamples],
            "traces": [(cx.trace.labels, tuple(canonical(r.model, st) for st in cx.trace.states))
                       for cx in r.counterexamples]}


def both(program, **kw):
    """(python, native) summaries; the native search must have run natively."""
    py = explore(program, engine="python", find_all=True, **kw)
    nat = explore(program, engine="native", find_all=True, **kw)
    assert nat.model.engine_used == "native", nat.model.engine_reason
    return summary(py), summary(nat)


# -- the programs that fell back: shipped, tutorial, tests -------------------------------

DOCK = dict(world=P("docs/examples/dock.toml"), blackbox="nondet")
FALLEN = [
    ("formation", P("programs/formation.pccl"), dict(world=P("programs/formation.toml"))),
    ("formation-instant-3", P("programs/formation.pccl"),
     dict(world=P("programs/formation.toml"), blackbox="instant")),
    ("rendezvous", P("programs/rendezvous.pccl"),
     dict(world=P("programs/rendezvous.toml"), max_states=8000)),
    ("rendezvous-straight", P("programs/rendezvous.pccl"),
     dict(world=P("programs/rendezvous.toml"), blackbox="straight", max_states=8000)),
    ("dock", P("docs/examples/dock.pccl"), DOCK),
    ("dock_atomic", P("docs/examples/dock_atomic.pccl"), DOCK),
    ("dock_nearest", P("docs/examples/dock_nearest.pccl"), DOCK),
    ("dock_nearest-dist", P("docs/examples/dock_nearest.pccl"),
     dict(DOCK, invariants=["forall i: forall j: (i != j && parked[i] && parked[j]) "
                            "-> dist(pos[i], pos[j]) >= 1"])),
    ("dock_retry", P("docs/examples/dock_retry.pccl"), DOCK),
    ("patrol-pillar", P("tests/programs/patrol.pccl"),
     dict(world=P("tests/programs/patrol_pillar.toml"), blackbox="straight", max_states=6000)),
    ("ref_undef", P("tests/programs/ref_undef.pccl"), dict(blackbox="instant")),
    # --collisions: a memo site over the positions (the Python model's own check on a miss)
    ("collide-collisions", P("programs/collide.pccl"),
     dict(world=P("programs/collide.toml"), blackbox="straight", collisions=True)),
    ("collide_fixed-collisions", P("programs/collide_fixed.pccl"),
     dict(world=P("programs/collide.toml"), blackbox="straight", collisions=True)),
    ("dock_retry-collisions", P("docs/examples/dock_retry.pccl"),
     dict(DOCK, blackbox="straight", collisions=True)),
]


@pytest.mark.parametrize("name, program, kw", FALLEN, ids=[c[0] for c in FALLEN])
@pytest.mark.parametrize("reduce", ["default", "none"])
def test_programs_that_fell_back_run_natively_with_equal_results(name, program, kw, reduce):
    kw = dict(kw, **(UNREDUCED if reduce == "none" else {}))
    py, nat = both(program, **kw)
    assert nat == py


def test_the_tutorial_dock_finds_the_same_double_booking():
    py, nat = both(P("docs/examples/dock.pccl"), **DOCK)
    assert nat == py
    assert py["status"] == "violation"
    assert any("remove of an element not in the list" in m for _, m in py["violations"])


@pytest.mark.parametrize("workers", [2])
def test_property_memo_sites_on_the_kernels_threads(workers):
    """The level kernel's threads evaluate the invariants in C: a property
    memo site's miss on a helper thread is left to the calling thread."""
    kw = dict(world=P("programs/rendezvous.toml"), blackbox="nondet", agents=2)
    one = explore(P("programs/rendezvous.pccl"), engine="native", find_all=True, **kw)
    many = explore(P("programs/rendezvous.pccl"), engine="native", find_all=True,
                   workers=workers, **kw)
    py = explore(P("programs/rendezvous.pccl"), engine="python", find_all=True, **kw)
    assert many.model.engine_used == "native"
    assert summary(one) == summary(many) == summary(py)


# -- properties over floats, positions and lists: the edge cases --------------------------

FLOATS = src("""
    allwrite:
      float f = 1.0;
      float z = 0.0;
      int big = 9223372036854775807;
      List<int> xs = [1, 2];

    loc:
      ItemPosition p = getPosition();
      float g = 0.5;
      int n = 0;

    Step():
      pre(n < 3);
      eff:
        n = n + 1;
        g = g * 2.0;
        f = f - 0.5;
        p = ItemPosition(g, f);
        add(xs, n);

    Done():
      pre(n == 3);
      eff:
        exit();

    invariant:
      %s
""")

#: (invariant, what the Python engine reports: a substring of a violation message)
PROPS = [
    ("half: forall i: g[i] <= 3.0;", "invariant 'half' violated"),
    ("div: forall i: g[i] / f < 10.0;", "could not be evaluated"),          # f reaches 0.0
    ("nan: forall i: (g[i] * 0.0) / z != 1.0;", "could not be evaluated"),  # 0.0 / 0.0
    ("inf: forall i: g[i] * 1e308 * 10.0 > 0.0;", None),
    ("wide: big + 1 > big;", None),                                         # beyond 64 bits
    ("wide2: big * big > 0;", None),
    ("where: forall i: dist(p[i], ItemPosition(0.0, 0.0)) < 4.0;", "invariant 'where' violated"),
    ("ix: head(xs) == 1 && size(xs) < 4;", "invariant 'ix' violated"),
    ("oob: forall i: n[i] < 2 || g[0] > 0.0;", None),
    ("agent: forall i: g[(n[i] + 1) % 3] >= 0.5;", "could not be evaluated"),  # agent 2 of 2
    ("mix: forall i: (p[i].x > 1.0) -> (n[i] >= 1 && f < 1.0);", None),
]


@pytest.mark.parametrize("prop, want", PROPS, ids=[p.split(":")[0] for p, _ in PROPS])
@pytest.mark.parametrize("reduce", ["default", "none"])
def test_property_edge_cases_equal(prop, want, reduce):
    kw = dict(source=True, agents=2, blackbox="instant",
              **(UNREDUCED if reduce == "none" else {}))
    py, nat = both(FLOATS % prop, **kw)
    assert nat == py
    msgs = " | ".join(m for _, m in py["violations"])
    if want is None:
        assert not any("invariant" in m for m in msgs.split(" | ")), msgs
    else:
        assert want in msgs, msgs


#: statements over floats, positions, lists and arrays that get an agent
#: stuck (True), or whose int leaves 64 bits (False: PCCL's ints are
#: unbounded; the native search stops there and the Python engine runs)
STUCK = [
    ("float-div", "float f = 1.0;", "f = f / (f - 1.0);", True),
    ("float-nan", "float f = 0.0;", "f = (f * 0.0) / f;", True),
    ("float-inf", "float f = 1e308;", "f = f * 10.0;", True),
    ("int-div", "int a = 1;", "a = a / (a - 1);", True),
    ("int-mod", "int a = 1;", "a = a % (a - 1);", True),
    ("int-wide", "int a = 9223372036854775807;", "a = a + 1;", False),
    ("int-wide-mul", "int a = 4611686018427387904;", "a = a * 4;", False),
    ("array-oob", "int arr[2] = 0;", "arr[getAgentIndex() + 1] = 1;", True),
    ("array-neg", "int arr[2] = 0;", "arr[getAgentIndex() - 1] = 1;", True),
    ("list-head", "List<int> xs = [];", "xs = [head(xs)];", True),
    ("pos-field", "ItemPosition q = getPosition();", "q = ItemPosition(q.x / (q.y - q.y), 0.0);", True),
]


@pytest.mark.parametrize("name, decl, stmt, stuck", STUCK, ids=[c[0] for c in STUCK])
def test_stuck_edge_cases_give_the_same_reason_and_line(name, decl, stmt, stuck):
    text = src(f"""
        loc:
          {decl}
          bool done = false;

        Go():
          pre(!done);
          eff:
            done = true;
            {stmt}
            exit();
    """)
    py = explore(text, source=True, agents=2, blackbox="instant", engine="python", find_all=True)
    nat = explore(text, source=True, agents=2, blackbox="instant", engine="native", find_all=True)
    assert summary(nat) == summary(py)
    # the reason and the line: the same violations, the stuck agent's on the statement's line
    where = [(cx.violation.kind, cx.violation.message, cx.violation.span and cx.violation.span.line)
             for cx in py.counterexamples]
    assert [(cx.violation.kind, cx.violation.message, cx.violation.span and cx.violation.span.line)
            for cx in nat.counterexamples] == where
    if stuck:
        assert nat.model.engine_used == "native"
        assert any(k == "stuck" and line == 9 for k, _, line in where), where
    else:
        assert not any(k == "stuck" for k, _, _ in where), where
        assert "beyond 64 bits" in nat.model.engine_reason


# -- indexed assignments, rand() in statements, more agents --------------------------------

ARRAYS = src("""
    allwrite:
      bool taken[3] = false;
      int hits[3] = 0;

    loc:
      int at = getAgentIndex();
      bool holding = false;

    Take():
      pre(!holding);
      eff:
        atomic:
          if (!taken[at]):
            taken[at] = true;
            holding = true;
            hits[(at + 1) % 3] = hits[(at + 1) % 3] + 1;

    Move():
      pre(holding);
      eff:
        taken[at] = false;
        holding = false;
        at = (at + 1) % 3;

    invariant:
      forall i: hits[i] < 3;
""")


@pytest.mark.parametrize("reduce", ["default", "none"])
def test_indexed_assignments_are_memo_sites(reduce):
    # `--all` keeps expanding past the violation and `hits` grows without
    # bound: the search is infinite, so both engines stop at the same cut
    kw = dict(source=True, agents=2, blackbox="instant", max_states=2_000,
              **(UNREDUCED if reduce == "none" else {}))
    py, nat = both(ARRAYS, **kw)
    assert nat == py and py["status"] == "violation"


@pytest.mark.parametrize("program, agents", [("ref_rand", 2), ("eng_lock", 2), ("ref_init", 3)])
@pytest.mark.parametrize("reduce", ["none", "por", "dead,por"])
def test_rand_in_statements_natively_where_no_chain_runs_them(program, agents, reduce):
    kw = dict(agents=agents, blackbox="instant", reduce=reduce, max_states=20_000)
    py, nat = both(P("tests/programs", program + ".pccl"), **kw)
    assert nat == py


def test_rand_that_merging_runs_through_falls_back_with_the_reason():
    r = explore(P("tests/programs/ref_rand.pccl"), blackbox="instant", max_states=100)
    assert r.model.engine_used == "python"
    assert "rand() in a statement that statement merging runs through (line 14" \
        in r.model.engine_reason


@pytest.mark.parametrize("program, reduce", [("ref_atomic", "none"), ("eng_flags", "default"),
                                             ("ref_allread", "default")])
def test_more_than_sixteen_agents(program, reduce):
    kw = dict(agents=20, blackbox="instant", max_states=3000,
              **(UNREDUCED if reduce == "none" else {}))
    py, nat = both(P("tests/programs", program + ".pccl"), **kw)
    assert nat == py


def test_more_agents_than_the_generated_c_holds_says_so():
    m = make_model(P("tests/programs/eng_flags.pccl"), agents=NV.MAX_AGENTS + 1, blackbox="instant")
    assert NV.unsupported(m) == f"more than {NV.MAX_AGENTS} agents"
