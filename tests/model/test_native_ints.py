"""Issue 41, holes 5 and 6: the native engine on every int the language
allows, and equal figures under merge+por.

Hole 5: a native slot holds the ints INT64_MIN + 4 .. INT64_MAX (below
them the codes of undefined, the symmetry signature's own and other ids
and dead's DEADV).  Any other int, met when a state is encoded (an initial
state, a memo miss's successors) or made by the generated C's arithmetic,
stops the native search and the Python engine runs from the start: the
verdict is the Python engine's, never a traceback.

Hole 6: the Python engine's stall signature was Python's ``hash()``, equal
for -1 and -2, so a merged chain from ``s = -1`` to ``s = -2`` was cut as
if it had ended where it began: its figures differed from the native
engine's.  The reproducers are copied from the issue's cases."""

import random

import pytest
from click.testing import CliRunner

from pccl.api import explore, make_model
from pccl.cli import main
from pccl.model import native as NV

from cases import HOLE6_DEFAULT, HOLE6_MERGE_POR

_probe = make_model("Agent::A\n\nloc:\n  int x = 0;\n\nE():\n  pre(true);\n  eff:\n    exit();\n",
                    source=True, reduce="none")
MISSING = NV.unsupported(_probe)
pytestmark = pytest.mark.skipif(MISSING is not None, reason=f"native engine unavailable: {MISSING}")


# -- hole 5: the reproducers -------------------------------------------------------

#: clean; the native engine read -2^63 as undefined ("a value of the wrong type")
INT64MIN_CLEAN = """\
loc:
  int b = -9223372036854775807 - 1;

E():
  pre(true);
  eff:
    if (b < 0.5):
      exit();
    else:
      exit();
"""

#: an invariant violation; natively a traceback ("a merged transition did not re-execute")
INT64MIN_STORED = """\
loc:
  int b = 0;
  int st = 0;

E():
  pre(st == 0);
  eff:
    b = -9223372036854775807 - 1;
    st = 1;

F():
  pre(st == 1);
  eff:
    exit();

invariant:
  forall i: b[i] > -5;
"""

#: an assertion; natively a traceback (OverflowError) at a memo miss
BEYOND_64_BITS = """\
loc:
  int a = 9223372036854775807;
  int x1 = 0;

E():
  pre(true);
  eff:
    x1 = (((0 + 3) / (1000000007 % 4611686018427387904)) + ((a + 9223372036854775807) - 1));
    assert(false);
"""


def cli(path, *args) -> tuple:
    """(exit code, verdict line, engine of the header) of ``pccl explore``;
    a traceback fails the test."""
    r = CliRunner().invoke(main, ["explore", str(path), "--no-progress", *args])
    assert r.exception is None or isinstance(r.exception, SystemExit), r.output
    lines = r.output.splitlines()
    head = next(ln for ln in lines if ln.startswith("pccl explore"))
    return r.exit_code, lines[lines.index(head) + 1], head.split("engine ")[1].split(" ")[0]


@pytest.mark.parametrize("text, want_exit, want", [
    (INT64MIN_CLEAN, 0, "no violation — exhaustive"),
    (INT64MIN_STORED, 1, "violation: invariant 'forall i: b[i] > -5' violated"),
    (BEYOND_64_BITS, 1, "violation: agent 0: assertion failed")],
    ids=["int64min-clean", "int64min-stored", "beyond-64-bits"])
@pytest.mark.parametrize("args", [(), ("--engine", "native"), ("--reduce", "none"),
                                  ("--reduce", "merge"), ("--workers", "2")],
                         ids=["default", "native", "none", "merge", "workers2"])
def test_reproducers_native_verdict_is_python_verdict(tmp_path, text, want_exit, want, args):
    path = tmp_path / "p.pccl"
    path.write_text(text)
    py = cli(path, *args, "--engine", "python") if "--engine" not in args else None
    code, verdict, engine = cli(path, *args)
    assert (code, verdict.split(" [")[0]) == (want_exit, want)
    if py is not None:
        assert py[:2] == (code, verdict)
    # the native search met the int and the Python engine ran it
    assert engine == "python"


def test_an_int_beside_the_reserved_codes_stays_native():
    """INT64_MIN + 4 and INT64_MAX are native ints: the search stays native,
    with the Python engine's figures."""
    text = INT64MIN_CLEAN.replace("-9223372036854775807 - 1", "-9223372036854775807 + 3") \
        .replace("b < 0.5", "b < -9223372036854775800")
    text2 = INT64MIN_CLEAN.replace("-9223372036854775807 - 1", "9223372036854775807")
    for t in (text, text2):
        nat = explore(t, source=True)
        py = explore(t, source=True, engine="python")
        assert nat.model.engine_used == "native"
        assert summary(nat) == summary(py) and py.status == "exhaustive"


def test_the_vector_encoder_refuses_what_a_slot_cannot_hold():
    """Every Python int -> C path goes through NativeModel._v: an int a
    slot cannot hold is NativeOverflow (the Python engine runs), never an
    OverflowError or a reserved code."""
    nm = NV.NativeModel(make_model(INT64MIN_CLEAN.replace("-9223372036854775807 - 1", "0"),
                                   source=True, reduce="none"))
    for value in (-(1 << 63), -(1 << 63) + 1, -(1 << 63) + 2, -(1 << 63) + 3, 1 << 63,
                  -(1 << 63) - 1, 1 << 64, -(1 << 70)):
        with pytest.raises(NV.NativeOverflow):
            nm._v(value)
    for ok in (-(1 << 63) + 4, (1 << 63) - 1, 0, -1):
        assert nm._v(ok) == ok


# -- hole 6: merge+por and default figures ------------------------------------------

MERGEPOR, DEFAULT = HOLE6_MERGE_POR, HOLE6_DEFAULT


def figures(r) -> tuple:
    return r.status, r.exit_status, r.stats.states, r.stats.transitions, r.stats.max_depth


@pytest.mark.parametrize("text", [MERGEPOR, DEFAULT], ids=["mergepor", "default"])
@pytest.mark.parametrize("reduce", ["merge,por", "auto"])
@pytest.mark.parametrize("agents", [2, 3])
def test_merge_por_figures_equal(text, reduce, agents):
    nat = explore(text, source=True, reduce=reduce, agents=agents)
    py = explore(text, source=True, reduce=reduce, agents=agents, engine="python")
    assert nat.model.engine_used == "native"
    assert figures(nat) == figures(py)


def test_the_reproducers_figures():
    """The figures the issue measured, now on both engines (the native ones
    were right: the chain from s1 = -1 to -2 does not end where it began)."""
    assert figures(explore(MERGEPOR, source=True, reduce="merge,por", engine="python"))[2:4] == \
        (253, 326)
    assert figures(explore(DEFAULT, source=True, agents=3, engine="python"))[2:] == (133, 260, 17)


def test_stall_signature_tells_minus_one_from_minus_two():
    from pccl.model.layout import SH
    from pccl.model.stall import signature_fn
    m = make_model(MERGEPOR, source=True, reduce="none")
    st = next(iter(m.init_states()))
    sig = signature_fn(m)
    sts = [st[:SH] + ((v,),) + st[SH + 1:] for v in (-1, -2, 0, (1 << 61) - 1, 1 << 61, 3)]
    assert len({sig(s) for s in sts}) == len(sts)
    assert sig(sts[0]) == sig(st[:SH] + ((-1,),) + st[SH + 1:])
    assert all(-(1 << 63) <= sig(s) < (1 << 63) for s in sts)


# -- ints at the 64-bit edges, seeded: native == python ------------------------------

#: expressions of small literals (C serves literals under 62 bits) at the edges
EDGES = ["4611686018427387903 * 2 + 1",             # 2^63 - 1
         "-4611686018427387903 * 2 - 1",            # -(2^63 - 1): INT64_MIN + 1
         "-4611686018427387903 * 2 - 2",            # -2^63
         "-4611686018427387903 * 2 + 2",            # INT64_MIN + 4: the least native int
         "4294967296 * 4294967296",                 # 2^64
         "3037000500 * 3037000500",                 # just past 2^63
         "-3037000499 * 3037000499",
         "7", "-1", "0"]
#: statements over x (a loc int), y (allwrite)
STMTS = ["x = x + {e};", "x = x * {e};", "x = -x;", "x = x - {e};", "x = x / 2;",
         "x = x % 3;", "y = y * 2;", "y = {e};", "x = {e} - x;", "x = 0 - x;"]
GUARDS = ["true", "x > {e}", "x != {e}", "-x < {e}", "y * 2 != {e}"]


#: the EDGES a native slot holds (INT64_MIN + 4 .. INT64_MAX)
IN_RANGE = [x for x in EDGES if -(1 << 63) + 4 <= eval(x) < (1 << 63)]


def edge_program(rnd: random.Random, pool: list) -> str:
    e = lambda: rnd.choice(pool)  # noqa: E731
    ev = []
    for k in range(2):
        body = "\n".join("    " + rnd.choice(STMTS).format(e=e()) for _ in range(rnd.randint(1, 2)))
        tail = rnd.choice(["    exit();", f"    assert(x != {e()});", "    skip;"])
        ev.append(f"E{k}():\n  pre(st < 2 && ({rnd.choice(GUARDS).format(e=e())}));\n  eff:\n"
                  f"{body}\n{tail}\n    st = st + 1;\n")
    ev.append("Done():\n  pre(st >= 1);\n  eff:\n    exit();\n")
    inv = rnd.choice(["", f"invariant:\n  forall i: x[i] != {e()};\n"])
    return (f"allwrite:\n  int y = {e()};\n\nloc:\n  int x = {e()};\n  int st = 0;\n\n"
            + "\n".join(ev) + "\n" + inv)


def summary(r) -> tuple:
    return (r.status, r.exit_status, r.stats.states, r.stats.transitions, r.stats.max_depth,
            sorted((v.violation.identity, v.violation.message) for v in r.counterexamples))


@pytest.mark.parametrize("seed", range(12))
def test_edge_ints_native_is_python(seed):
    """Seeded programs holding and computing ints at and past the 64-bit
    edges in initialisers, statements, guards, asserts and invariants:
    both engines, default reductions and none, equal verdicts and figures
    (even seeds: only ints a native slot holds, so that the native search
    runs until its own arithmetic leaves the range, if it does)."""
    text = edge_program(random.Random(seed), EDGES if seed % 2 else IN_RANGE)
    for reduce in ("auto", "none"):
        kw = dict(source=True, reduce=reduce, find_all=True, max_states=3_000)
        nat = explore(text, **kw)
        py = explore(text, engine="python", **kw)
        assert summary(nat) == summary(py), text
