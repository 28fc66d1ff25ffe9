"""The Promela model of benchmarks/spin/fischer.pml has exactly pccl's
unreduced state space for Fischer's protocol: SPIN's breadth-first search
(no partial-order reduction) finds as many states and transitions, and the
same depth, as ``pccl explore --reduce none`` (benchmarks/spin.py,
docs/benchmarks.md).  Skipped where spin or a C compiler is missing
(``apt-get install spin gcc``)."""

import importlib.util
import os
import sys

import pytest

from pccl.api import explore

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
_spec = importlib.util.spec_from_file_location("bench_spin", os.path.join(ROOT, "benchmarks",
                                                                          "spin.py"))
assert _spec is not None and _spec.loader is not None
spin = importlib.util.module_from_spec(_spec)
sys.modules["bench_spin"] = spin
_spec.loader.exec_module(spin)

MISSING = spin.missing_tools()


def pccl_counts(k, d, n):
    r = explore(spin.PROGRAM, overrides={"k": str(k), "d": str(d)}, agents=n, reduce="none",
                timelock=False, stall=False)
    assert r.status == "exhaustive"
    return {"states": r.stats.states, "transitions": r.stats.transitions,
            "depth": r.stats.max_depth}


@pytest.mark.slow
@pytest.mark.skipif(MISSING is not None, reason=MISSING or "")
@pytest.mark.parametrize("k, d, n", [(0, 1, 2), (0, 0, 2)])
def test_spin_state_space_equals_pccl(k, d, n, tmp_path):
    exe = spin.build(k, d, n, str(tmp_path), bfs=True)
    stats, _ = spin.run_pan(exe, bfs=True, n=n)
    mine = pccl_counts(k, d, n)
    assert mine["states"] > 1000
    assert spin.spin_counts(stats, spin.n_initial(k, n)) == mine


def test_generated_init_has_one_option_per_initial_state():
    text = spin.generated(1, 2, 2)
    assert text.count(":: d_step") == spin.n_initial(1, 2) == 144
    assert "#define ALLSPENT (cnt[0] == 1 && cnt[1] == 1)" in text


def test_without_spin_the_benchmark_says_so(monkeypatch, capsys):
    monkeypatch.setattr(spin.shutil, "which", lambda name: None)
    assert spin.main(["--repeat", "1"]) == 0
    assert capsys.readouterr().out == "skipped: spin is not installed (apt-get install spin)\n"
