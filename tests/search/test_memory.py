"""Memory linear in the program and the state (issue 20, item 5), no
MemoryError traceback anywhere, and the smaller honesty fixes that came
with it: stuck reasons in PCCL's words, ``rand`` beyond the tool's limit,
an error in a shared initialiser, ``pccl graph --max-states`` while the
initial states are enumerated.

The memory checks measure a fresh process (its peak resident set, VmHWM or
ru_maxrss) or tracemalloc's peak; they are acceptance checks of memory, not
of time."""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import textwrap
import tracemalloc

import pytest

from conftest import FISCHER, cli

GROW = textwrap.dedent("""\
    Agent::Grow

    loc:
      List<int> xs = [];
      int t = 0;

    Go():
      pre(true);
      eff:
        add(xs, t);
        t = t + 1;
    """)

# a search whose states grow with their depth and branch: it fills memory fast
HOG = "loc:\n  List<int> xs = [];\n\nGo():\n  pre(true);\n  eff:\n    add(xs, rand(3));\n"


def declarations(n: int) -> str:
    """A program with ``n`` local declarations."""
    lines = ["Agent::Many", "", "loc:"] + [f"  int v{i} = {i};" for i in range(n)]
    lines += ["", "Go():", "  pre(v0 < 2);", "  eff:", "    v0 = v0 + 1;"]
    return "\n".join(lines) + "\n"


def write(tmp_path, text, name="p.pccl"):
    p = tmp_path / name
    p.write_text(text)
    return str(p)


def _python(code: str, *, limit_as=None, timeout=600) -> subprocess.CompletedProcess:
    """Run ``code`` in a fresh interpreter (optionally under an address-space
    limit, in bytes)."""
    pre = None
    if limit_as is not None:
        def pre():
            resource.setrlimit(resource.RLIMIT_AS, (limit_as, limit_as))
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=timeout, preexec_fn=pre)


def _pccl(args, *, limit_as=None, timeout=600) -> subprocess.CompletedProcess:
    code = f"import sys; sys.argv = ['pccl'] + {list(map(str, args))!r}\n" \
           "from pccl.cli import main\nmain()\n"
    return _python(code, limit_as=limit_as, timeout=timeout)


# ---------------------------------------------------------------------------
# initial states: memory linear in the number of declarations
# ---------------------------------------------------------------------------

def _init_peak(n: int) -> int:
    """tracemalloc's peak while the initial states of ``declarations(n)``
    are built (the compiled initialisers made beforehand)."""
    from pccl.api import make_model
    m = make_model(declarations(n), agents=1, source=True)
    for vs in m.compiled.layout.local:
        m.compiled.decl_init(vs)
    tracemalloc.start()
    try:
        states = list(m.init_states())
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert len(states) == 1
    return peak


def test_initial_states_memory_is_linear_in_the_declarations():
    """One copy of the locals per declaration level made it quadratic:
    2,000 declarations peaked at 34 MB (4x the peak of 1,000)."""
    p1, p2 = _init_peak(1000), _init_peak(2000)
    assert p2 < 3 * p1, (p1, p2)
    assert p2 < 8 * 2**20, p2


def test_initial_states_of_many_declarations_are_those_of_few():
    """The mutable path builds the same configuration as the declarations
    evaluated one by one: every slot holds its initialiser's value."""
    from pccl.api import make_model
    from pccl.model.layout import AGS, LOC
    m = make_model(declarations(300), agents=2, source=True)
    (st,) = list(m.init_states())
    for ag in st[AGS]:
        assert ag[LOC] == tuple(range(300))


INIT_MIXED = textwrap.dedent("""\
    Agent::Mixed

    allwrite:
      int s = rand(1);
      int q = s + 1;

    allread:
      int r = q + rand(1);

    loc:
      int id = getAgentIndex();
      int x = 6 / rand(1);
      int y = x + r;
      int arr[2] = rand(1);

    Init:
      if (rand(1) == 1):
        s = s + 1;
      y = y + s;

    Go():
      pre(y < 0);
      eff:
        y = 1;
    """)


def test_initial_states_with_rand_errors_and_init_against_a_direct_enumeration(tmp_path):
    """The initial states, computed a second way: the product of every
    rand outcome, evaluated in declaration order per agent (shared first),
    with Init's outcome (s + 1 when its rand is 1)."""
    import itertools
    from pccl.api import make_model
    from pccl.output.display import status_text
    from pccl.model.layout import AGS, AR, LOC, SH, STATUS
    m = make_model(write(tmp_path, INIT_MIXED), agents=2, reduce="none")   # every outcome
    got = set()
    for st in m.init_states():
        ags = tuple((ag[LOC], ag[AR], status_text(m, ag[STATUS])) for ag in st[AGS])
        got.add((st[SH], ags))
    want = set()
    for s0, *rest in itertools.product((0, 1), *[(0, 1)] * 8):
        s, q = s0, s0 + 1
        ags = []
        for i in range(2):
            c_r, c_x, c_arr, c_init = rest[4 * i: 4 * i + 4]
            r = q + c_r
            if c_x == 0:                 # 6 / 0: stuck at the declaration of x
                ags.append(((i, None, None, None), (r,), None))
                continue
            x = 6
            y = x + r
            if c_init == 1:
                s += 1
            y += s
            ags.append(((i, x, y, (c_arr, c_arr)), (r,), "running"))
        want.add(((s, q), tuple(ags)))
    # the stuck agents: UNDEF slots and the reason at line 12
    norm = set()
    for sh, ags in got:
        out = []
        for loc, ar, status in ags:
            if status != "running":
                assert status == "stuck(division by zero at line 12)", status
                out.append(((loc[0], None, None, None), ar, None))
            else:
                out.append((loc, ar, status))
        norm.add((sh, tuple(out)))
    # a stuck agent skips its Init (its rand is not drawn): merge those outcomes
    assert norm == want


@pytest.mark.slow
def test_ten_thousand_declarations_build_their_initial_states_under_200_mib(tmp_path):
    """Issue 20: 10,000 `loc` declarations took 1.68 GiB for a 6-state program."""
    prog = write(tmp_path, declarations(10_000))
    r = _python(textwrap.dedent(f"""\
        from pccl.api import make_model
        from pccl.search.memory import peak_rss_bytes
        m = make_model({prog!r}, agents=1)
        assert len(list(m.init_states())) == 1
        print(peak_rss_bytes())
        """))
    assert r.returncode == 0, r.stderr
    peak = int(r.stdout.split()[-1])
    assert peak < 200 * 2**20, f"{peak / 2**20:.0f} MiB"


# ---------------------------------------------------------------------------
# pccl run: memory linear in the state, --max-memory
# ---------------------------------------------------------------------------

def test_run_summary_holds_a_bounded_number_of_list_elements(monkeypatch, tmp_path):
    """A list that grows each time step: one state per time step was
    quadratic; the summary is thinned once its states hold more than
    SUMMARY_BUDGET list elements of their own."""
    from pccl.tools import runner
    from pccl.api import run
    from pccl.model.layout import AGS, LOC
    monkeypatch.setattr(runner, "SUMMARY_BUDGET", 2_000)
    r = run(write(tmp_path, GROW), agents=1, max_time=300)
    assert r.status == "bounded" and len(r.final[AGS][0][LOC][0]) == 301
    held = sum(len(s[AGS][0][LOC][0]) for _, s in r.summary)
    assert held <= 2 * 2_000, held
    times = [t for t, _ in r.summary]
    assert times[0] == 0 and times == sorted(times) and len(times) >= 5
    # evenly thinned: equal gaps after the first entry
    gaps = {b - a for a, b in zip(times[1:], times[2:])}
    assert len(gaps) == 1, times


def test_run_summary_of_small_states_is_not_thinned(tmp_path):
    """The budget counts only list elements: a run of small states keeps
    every time step."""
    from pccl.api import run
    r = run(write(tmp_path, "loc:\n  int c = 0;\n\nGo():\n  pre(true);\n  eff:\n    c = 1 - c;\n"),
            agents=1, max_time=500)
    assert [t for t, _ in r.summary] == list(range(501))


@pytest.mark.slow
def test_run_of_20000_steps_with_a_growing_list_stays_under_500_mib(tmp_path):
    """Issue 20: 1.75 GB at t=12,000 and a MemoryError traceback at 20,000."""
    prog = write(tmp_path, GROW)
    r = _python(textwrap.dedent(f"""\
        import resource, subprocess, sys
        p = subprocess.run([sys.executable, "-m", "pccl.cli", "run", {prog!r}, "--agents", "1",
                            "--max-time", "20000"], stdout=subprocess.PIPE, text=True)
        assert p.returncode == 0, p.returncode
        assert "result: bounded" in p.stdout
        print(len(p.stdout), resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)
        """))
    assert r.returncode == 0, r.stderr
    size, peak_kib = map(int, r.stdout.split())
    assert peak_kib * 1024 < 500 * 2**20, f"{peak_kib / 1024:.0f} MiB"
    assert size < 2 * 2**20         # the summary lines shorten long lists


def test_run_max_memory_stops_as_a_bound(tmp_path):
    from pccl.api import run
    r = run(write(tmp_path, GROW), agents=1, max_time=100_000, max_memory=1)
    assert r.status == "bounded" and r.exit_status == 0
    assert r.message.startswith("stopped at max_memory=1:")
    assert r.steps == 256 and r.peak_memory > 1     # checked every MEMORY_CHECK transitions


def test_run_cli_max_memory(tmp_path):
    p = write(tmp_path, GROW)
    res = cli("run", p, "--agents", "1", "--max-time", "100000", "--max-memory", "1K")
    assert res.exit_code == 0, res.output
    assert "result: bounded — stopped at --max-memory 1K: the process's peak memory passed it" \
        in res.output
    assert "peak memory" in res.output and "final configuration:" in res.output
    res = cli("run", p, "--max-memory", "lots")
    assert res.exit_code == 2 and "--max-memory" in res.output
    # the default is explore's: 80 % of physical memory, not reached here
    res = cli("run", p, "--agents", "1", "--max-time", "50")
    assert res.exit_code == 0 and "result: bounded — stopped at --max-time 50" in res.output


def test_run_max_memory_api_checks_its_value():
    from pccl.api import run
    from pccl.lang.errors import ArgumentError
    with pytest.raises(ArgumentError, match="max_memory must be an integer >= 1"):
        run(GROW, source=True, max_memory=0)


def test_short_values_in_the_run_summary():
    from pccl.output.display import short_value
    assert short_value(tuple(range(5))) == "[0, 1, 2, 3, 4]"
    assert short_value(tuple(range(1000))) == "[0, 1, 2, 3, 4, 5, 6, 7, …, 998, 999] (1,000 elements)"
    assert short_value((tuple(range(20)),)) == \
        "[[0, 1, 2, 3, 4, 5, 6, 7, …, 18, 19] (20 elements)]"


# ---------------------------------------------------------------------------
# MemoryError: a clean "out of memory" result, never a traceback
# ---------------------------------------------------------------------------

def _baseline_vm() -> int:
    """The address space of a fresh interpreter that has imported pccl."""
    r = _python("import pccl.cli, pccl.api, pccl.search.explorer, pccl.search.liveness, click, rich\n"
                "print(open('/proc/self/status').read().split('VmPeak:')[1].split()[0])")
    assert r.returncode == 0, r.stderr
    return int(r.stdout) * 1024


needs_linux = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                 reason="RLIMIT_AS and /proc are Linux's")


@needs_linux
@pytest.mark.parametrize("command", ["explore", "run", "graph"])
def test_out_of_memory_is_a_clean_result(command, tmp_path):
    """Under an address-space limit below the default --max-memory (80 % of
    RAM): a MemoryError is a clean "out of memory" with the figures so far,
    exit 2, never a traceback."""
    limit = _baseline_vm() + 100 * 2**20
    if command == "explore":
        args = ["explore", write(tmp_path, HOG), "--agents", "1", "--no-progress"]
    elif command == "run":
        args = ["run", write(tmp_path, GROW), "--agents", "1", "--max-time", "1000000",
                "--trace-out", str(tmp_path / "t.json")]
    else:
        args = ["graph", write(tmp_path, HOG), "--agents", "1", "--max-states", "100000000",
                "-o", str(tmp_path / "g.json")]
    r = _pccl(args, limit_as=limit)
    assert "Traceback" not in r.stderr and "MemoryError" not in r.stderr + r.stdout, r.stderr
    assert r.returncode == 2, (r.returncode, r.stdout[-2000:], r.stderr)
    if command == "explore":
        assert "out of memory — the process could not allocate more after" in r.stdout
        assert "statistics:" in r.stdout and "peak memory" in r.stdout
    elif command == "run":
        assert "result: out-of-memory — out of memory after" in r.stdout
        assert "final configuration:" in r.stdout
        assert "nothing written to" in r.stderr and not (tmp_path / "t.json").exists()
    else:
        assert "out of memory after" in r.stderr and "nothing written" in r.stderr
        assert not (tmp_path / "g.json").exists()


def test_memory_error_in_any_command_is_one_line(monkeypatch, tmp_path):
    """A MemoryError the command does not handle itself: one line, exit 2."""
    from pccl.tools import replay as R

    def boom(path, **kw):
        raise MemoryError
    monkeypatch.setattr(R, "replay", boom)
    res = cli("replay", write(tmp_path, "{}", "t.json"))
    assert res.exit_code == 2
    assert res.output.startswith("pccl replay: out of memory: the process could not allocate")


def test_explorer_memory_error_keeps_the_statistics(monkeypatch, tmp_path):
    """The search's figures so far survive a MemoryError (the API's result
    has status out-of-memory, exit status 2)."""
    from pccl.search import explorer as E
    from pccl.api import explore
    calls = {"n": 0}
    real = E._Admission.flush

    def flush(self, d):
        calls["n"] += 1
        if calls["n"] > 5:
            raise MemoryError
        return real(self, d)
    monkeypatch.setattr(E._Admission, "flush", flush)
    r = explore(write(tmp_path, HOG), agents=1)
    assert r.status == "out-of-memory" and r.exit_status == 2
    assert r.stats.states >= 5 and r.verdict.startswith(
        f"out of memory — the process could not allocate more after {r.stats.states:,} states")
    monkeypatch.setattr(E._Admission, "flush", real)
    assert explore(write(tmp_path, HOG), agents=1, max_states=10).status == "bounded"


# ---------------------------------------------------------------------------
# stuck reasons in PCCL's words
# ---------------------------------------------------------------------------

BIG = "1" + "0" * 400       # an int beyond a float's range


@pytest.mark.parametrize("stmt", ["f = x * 1.5;", "f = x / 2.5;",
                                  "p = ItemPosition(x, 0);",
                                  "f = dist(ItemPosition(1.0e300, 0.0), ItemPosition(-1.0e300, 0.0));"])
def test_arithmetic_overflow_is_a_pccl_reason(stmt, tmp_path):
    """Issue 20: "OverflowError: int too large to convert to float"."""
    from pccl.api import explore
    prog = (f"loc:\n  int x = {BIG};\n  float f = 0.0;\n  ItemPosition p;\n\nGo():\n  pre(f == 0.0);\n"
            f"  eff:\n    {stmt}\n")
    r = explore(write(tmp_path, prog), agents=1)
    assert r.status == "violation", r.verdict
    msg = r.violation["message"]
    assert msg == "agent 0 stuck: arithmetic overflow: a number beyond the range of a float " \
                  "(about ±1.8e308)", msg
    assert r.violation["line"] == 9
    res = cli("run", write(tmp_path, prog), "--agents", "1")
    assert "Error" not in res.output and "stuck(arithmetic overflow" in res.output


def test_no_runtime_error_shows_python_text():
    """Every exception compiled code may raise (RUNTIME_ERRORS) is described
    in PCCL's terms: no Python class name, no Python message."""
    from pccl.semantics.rules import RUNTIME_ERRORS, describe_error
    from pccl.lang.values import PcclRuntimeError
    samples = {ZeroDivisionError: ZeroDivisionError("float division by zero"),
               OverflowError: OverflowError("int too large to convert to float"),
               TypeError: TypeError("unsupported operand type(s) for +: 'int' and 'tuple'"),
               IndexError: IndexError("tuple index out of range"),
               ValueError: ValueError("math domain error")}
    for cls in RUNTIME_ERRORS:
        if cls is PcclRuntimeError:
            assert describe_error(PcclRuntimeError("head of an empty list")) == \
                "head of an empty list"
            continue
        text = describe_error(samples[cls])
        assert "Error" not in text and str(samples[cls]) not in text, (cls, text)
    assert describe_error(ValueError("Exceeds the limit (4300 digits) for integer string "
                                     "conversion")) == \
        "arithmetic overflow: an integer too large to convert"
    assert describe_error(IndexError("x")) == "index out of range"


# ---------------------------------------------------------------------------
# rand beyond the tool's limit of outcomes
# ---------------------------------------------------------------------------

def test_rand_over_the_limit_is_a_limit_of_the_tool(tmp_path):
    """Issue 20: reported as a stuck agent (a violation, exit 1)."""
    stmt = "x = rand(999999) + rand(1);"
    p = write(tmp_path, f"loc:\n  int x = 0;\n\nGo():\n  pre(x == 0);\n  eff:\n    {stmt}\n")
    col = 5 + stmt.index("rand(1)")
    res = cli("explore", p, "--agents", "1", "--no-progress")
    assert res.exit_code == 2, res.output
    assert res.output.startswith(
        f"{p}:7:{col}: error: rand(1) at line 7: this transition would have 2,000,000 "
        f"outcomes, and explore enumerates at most 1,000,000 per transition: a limit of "
        f"the tool, not a violation of the program"), res.output
    assert "stuck" not in res.output
    # 1,000,000 outcomes: explored
    ok = write(tmp_path, "loc:\n  int x = 0;\n\nGo():\n  pre(x == 0);\n  eff:\n"
                         "    x = rand(999999) + 1;\n", "ok.pccl")
    # (--no-stall: the agent is done without exit(), a stall by design, which the
    # reductions' 4-state search now decides within the bound)
    res = cli("explore", ok, "--agents", "1", "--no-progress", "--max-states", "10", "--no-stall")
    assert res.exit_code == 0, res.output
    # a run draws one outcome: no limit
    res = cli("run", p, "--agents", "1", "--max-time", "3")
    assert res.exit_code in (0, 1) and "limit of the tool" not in res.output


def test_rand_limit_in_graph_and_init(tmp_path):
    p = write(tmp_path, "loc:\n  int x = 0;\n\nInit:\n  x = rand(2000000);\n\nGo():\n"
                        "  pre(x < 0);\n  eff:\n    x = 1;\n")
    res = cli("graph", p, "-o", str(tmp_path / "g.dot"))
    assert res.exit_code == 2 and f"{p}:5:7: error: rand(2,000,000) at line 5" in res.output


# ---------------------------------------------------------------------------
# an error in a shared initialiser
# ---------------------------------------------------------------------------

SHARED_ERR = textwrap.dedent("""\
    Agent::S

    allwrite:
      int k = 0;
      int d = 10 / k;

    loc:
      int x = 0;

    Go():
      pre(x < 1);
      eff:
        x = d;
    """)


@pytest.mark.parametrize("command", ["explore", "run", "simulate"])
def test_shared_initialiser_error_is_an_error_of_the_initialiser(command, tmp_path):
    """Issue 20: reported as "agent 0 stuck" -- but no agent runs a shared
    initialiser: the initial configuration cannot be built, exit 2."""
    p = write(tmp_path, SHARED_ERR)
    res = cli(command, p)
    assert res.exit_code == 2, res.output
    assert res.output.startswith(f"{p}:5:3: error: the initialiser of `d` at line 5: "
                                 f"division by zero\n    5 |   int d = 10 / k;"), res.output
    assert "agent 0" not in res.output
    # --set k=2 fixes it
    res = cli(command, p, "--set", "k=2")
    assert res.exit_code in (0, 1) and "the initialiser of" not in res.output


def test_shared_initialiser_error_in_the_api_and_per_agent_errors_stay_stuck_agents(tmp_path):
    from pccl.api import explore
    from pccl.lang.errors import PcclError
    with pytest.raises(PcclError, match="the initialiser of `d` at line 5: division by zero"):
        explore(write(tmp_path, SHARED_ERR))
    # a rand outcome of a shared initialiser that fails: the same error
    p = write(tmp_path, SHARED_ERR.replace("int k = 0;", "int k = rand(1);"), "r.pccl")
    with pytest.raises(PcclError, match="the initialiser of `d` at line 5"):
        explore(p)
    # an agent's own declaration: the agent is stuck (a violation), as before
    loc = write(tmp_path, "loc:\n  int k = 0;\n  int d = 10 / k;\n\nGo():\n  pre(d < 0);\n"
                          "  eff:\n    d = 1;\n", "l.pccl")
    r = explore(loc, agents=1)
    assert r.status == "violation" and r.violation["message"] == \
        "agent 0 stuck: division by zero"


# ---------------------------------------------------------------------------
# pccl graph --max-states while enumerating initial states
# ---------------------------------------------------------------------------

def test_graph_max_states_bounds_the_initial_states(tmp_path):
    """Issue 20: fischer with 4 agents (66**4 initial states) and
    --max-states 100 ran past 150 s."""
    out = tmp_path / "f.dot"
    r = _pccl(["graph", FISCHER, "--agents", "4", "--max-states", "100", "-o", out],
              timeout=60)
    assert r.returncode == 0, r.stderr
    assert "100 states" in r.stdout and "(truncated at --max-states 100)" in r.stdout
    assert out.exists()


def test_graph_initial_states_below_the_bound_are_all_there(tmp_path):
    from pccl.output import graph as G
    from pccl.api import make_model
    m = make_model(FISCHER, agents=1, reduce="none")
    n_init = len(list(m.init_states()))
    g = G.build(m, max_states=n_init)
    assert len(g.initial) == n_init
    g = G.build(m, max_states=n_init - 1)
    assert len(g.initial) == n_init - 1 and g.truncated


if __name__ == "__main__":      # pragma: no cover
    sys.exit(pytest.main([os.path.abspath(__file__), "-q"]))
