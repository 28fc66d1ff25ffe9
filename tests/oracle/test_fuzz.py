"""Robustness: truncated and mutated versions of the shipped programs and
world files, fed to ``pccl check``, ``pccl run --max-time 3`` and
``pccl explore --depth 30`` in-process.  Whatever the input, the tool exits
with 0, 1 or 2, and a 2 is one rendered error (``file:line:col: error:``),
never a traceback.

The mutants are generated from a fixed seed, so the cases are the same on
every run; a failing case's id names the mutation.
"""

from __future__ import annotations

import random

import pytest
from click.testing import CliRunner

from pccl.cli import main

from conftest import PROGRAMS, RACE, RACE_WORLD, cli_robust
from sources import mutant_cases, mutate

SEED = 20240517
SOURCES = {name: (PROGRAMS / name).read_text()
           for name in ("fischer.pccl", "race.pccl", "race_nonatomic.pccl")}
WORLDS = {name: (PROGRAMS / name).read_text() for name in ("race.toml", "race_obstacles.toml")}

def cases(sources, n_mut, salt):
    return mutant_cases(dict(sorted(sources.items())), n_mut, random.Random(SEED + salt))


def invoke(args):
    return cli_robust(*args)


@pytest.mark.parametrize("name, text", cases(SOURCES, 45, 0))
def test_mutated_program(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(text)
    world = ["--world", RACE_WORLD] if name.startswith("race") else []
    c = invoke(["check", p])
    r = invoke(["run", p, *world, "--max-time", "3", "--max-steps", "3000", "--blackbox", "instant"])
    e = invoke(["explore", p, *world, "--depth", "30", "--max-states", "3000"])
    if c.exit_code == 2:
        # a program that does not load fails the same way everywhere
        assert r.exit_code == 2 and e.exit_code == 2
        assert r.stderr == c.stderr == e.stderr
    else:
        assert c.exit_code == 0


@pytest.mark.parametrize("name, text", cases(WORLDS, 35, 1))
def test_mutated_world(tmp_path, name, text):
    w = tmp_path / name
    w.write_text(text)
    c = invoke(["check", RACE, "--world", w])
    r = invoke(["run", RACE, "--world", w, "--max-time", "3"])
    e = invoke(["explore", RACE, "--world", w, "--depth", "30", "--max-states", "3000"])
    if c.exit_code == 2:
        assert str(w) in c.stderr
        assert r.exit_code == 2 and e.exit_code == 2


def test_fuzz_corpus_is_varied():
    """The generated corpus exercises all three outcomes of check (guards
    against a mutator that only ever produces garbage)."""
    codes = set()
    rng = random.Random(SEED)
    text = SOURCES["race.pccl"]
    ok = 0
    for _ in range(40):
        _, t = mutate(text, rng)
        try:
            from pccl.lang.checker import check_program
            from pccl.lang.parser import parse_program
            check_program(parse_program(t, "m.pccl"))
            ok += 1
        except Exception as exc:           # PcclError expected
            codes.add(type(exc).__name__)
    assert 0 < ok < 40
    assert codes == {"PcclError"}


# ---------------------------------------------------------------------------
# option values and API arguments
# ---------------------------------------------------------------------------

from conftest import FISCHER  # noqa: E402

SMALL = ["--set", "k=1", "--set", "cstime=0"]
VALUES = ["0", "-1", "1", "2", "3", "1e-12", "0.5", "nan", "inf", "-inf", "1e308", "", " ", "abc",
          "1=2", "0=1", "=", "k=", "k=1/0", "k=rand(3)", "k=" + "1+" * 200 + "1", "k=(((",
          "99999999999999999999999", "2.5", "é", "--", "0x10", "count(inCs) <= 1", "time < 2",
          "forall i: inCs[i]", "straight", "nondet", "instant", "json", "k", "first", "any",
          "pymunk", "os:path", "no.such:thing"]
# option -> usable in run / explore (value-independent bounds keep every case short)
OPTIONS = ["--agents", "--delta", "--n0", "--rate", "--events", "--set", "--blackbox",
           "--collisions", "--format", "--invariant", "--max-time", "--max-states", "--depth",
           "--seed", "--max-steps", "--abstract-time", "--exact", "--all", "--no-deadlock"]
EXPLORE_ONLY = {"--invariant", "--max-states", "--depth", "--abstract-time", "--exact", "--all",
                "--no-deadlock"}
RUN_ONLY = {"--seed", "--max-steps"}
SANE = {"--agents": ["1", "3"], "--delta": ["0.5", "1", "0.1"], "--n0": ["1", "2"],
        "--rate": ["1=1", "0=1"], "--events": ["first", "any"], "--set": ["d=1", "d=3"],
        "--blackbox": ["instant", "nondet", "straight"], "--format": ["json", "text"],
        "--invariant": ["count(inCs) <= 1", "time < 2"], "--max-time": ["2", "3.5"],
        "--max-states": ["100"], "--depth": ["10"], "--seed": ["1", "7"],
        "--max-steps": ["100", "5"]}
FLAGS = {"--collisions", "--abstract-time", "--exact", "--all", "--no-deadlock"}


def option_cases(n=80):
    rng = random.Random(SEED + 7)
    out = []
    for k in range(n):
        cmd = rng.choice(["run", "explore"])
        args = []
        for _ in range(rng.randint(1, 3)):
            opt = rng.choice([o for o in OPTIONS
                              if o not in (RUN_ONLY if cmd == "explore" else EXPLORE_ONLY)])
            if cmd == "run" and opt in ("--delta", "--max-time"):
                continue            # a run's length is max-time / δ: not a crash, just long
            if opt == "--agents" and cmd == "explore":
                args += [opt, rng.choice(["0", "-1", "1", "3", "20000", "abc", ""])]
                continue
            if opt in FLAGS:
                args += [opt]
            elif opt in SANE and rng.random() < 0.6:
                args += [opt, rng.choice(SANE[opt])]
            else:
                args += [opt, rng.choice(VALUES)]
        out.append(pytest.param(cmd, args, id=f"{cmd}{k}"))
    return out


@pytest.mark.parametrize("cmd, args", option_cases())
def test_fuzzed_option_values(cmd, args):
    import time
    bound = (["--max-time", "2", "--max-steps", "2000"] if cmd == "run"
             else ["--max-states", "300", "--depth", "40"])
    t = time.perf_counter()
    argv = [cmd, FISCHER, *SMALL, *bound, *args]
    res = CliRunner().invoke(main, [str(a) for a in argv], catch_exceptions=True)
    line = "pccl " + " ".join(map(str, argv))
    assert res.exception is None or isinstance(res.exception, SystemExit), \
        f"{line} raised {type(res.exception).__name__}: {res.exception}"
    assert res.exit_code in (0, 1, 2), f"{line}: exit {res.exit_code}\n{res.output}"
    assert "Traceback" not in res.output, res.output
    if res.exit_code == 2:
        # one message: ours (FILE: error: ...) or click's option parser (Error: ...)
        err = res.stderr
        assert err.count(": error: ") + err.count("Error: ") == 1, f"{line}:\n{err}"
        assert res.stdout == ""
    assert time.perf_counter() - t < 20


API_VALUES = [None, 0, -1, 1, 2, 2.5, float("nan"), float("inf"), "x", "", [], {}, (), True,
              10 ** 30, ["count(inCs) <= 1"], "count(inCs) <= 1", object(), {"k": "1"},
              {"k": 1}, {1: 2}, {0: 1}, "first", "instant", b"bytes"]
API_ARGS = {
    "explore": ["world", "blackbox", "agents", "depth", "max_states", "invariants", "overrides",
                "delta", "n0", "rates", "events", "max_time", "abstract_time", "deadlock",
                "find_all", "exact", "collisions", "functions", "progress"],
    "run": ["world", "blackbox", "agents", "seed", "max_steps", "overrides", "delta", "n0",
            "rates", "events", "max_time", "collisions", "record_trace", "functions"],
    "make_model": ["world", "blackbox", "agents", "invariants", "overrides", "delta", "n0",
                   "rates", "events", "max_time", "abstract_time", "collisions"],
    "check": ["world", "source"],
}


def api_cases(n=80):
    rng = random.Random(SEED + 11)
    out = []
    for k in range(n):
        fn = rng.choice(sorted(API_ARGS))
        kw = {a: rng.choice(API_VALUES) for a in rng.sample(API_ARGS[fn], min(len(API_ARGS[fn]), rng.randint(1, 3)))}
        out.append(pytest.param(fn, kw, id=f"{fn}{k}"))
    return out


@pytest.mark.parametrize("fn, kw", api_cases())
def test_fuzzed_api_arguments(fn, kw):
    import time
    from pccl import api
    from pccl.lang.errors import PcclError
    base = {"overrides": {"k": "1", "cstime": "0"}}
    if fn == "explore":
        base.update(max_states=300, depth=40)
        if kw.get("max_states", 1) is None:
            kw["max_states"] = 300
    if fn == "run":
        base.update(max_time=2, max_steps=2000)
        kw.pop("delta", None)
        kw.pop("max_time", None)
    if fn == "check":
        base = {}
    if kw.get("agents") == 10 ** 30 or (isinstance(kw.get("agents"), int) and kw["agents"] > 50):
        kw["agents"] = 20_000                       # refused, not built
    t = time.perf_counter()
    try:
        getattr(api, fn)(FISCHER, **{**base, **kw})
    except PcclError as e:
        assert e.render().count(": error: ") <= 1
    assert time.perf_counter() - t < 20
