"""The native engine's optimisation level ($PCCL_NATIVE_OPT,
pccl/model/native_build.py opt_level): the suite compiles at -O0 for speed
(tests/conftest.py), users at -O2; the two must give the same results.

Each shipped program the native engine serves under the default reductions
is searched (with --all, bounded) once per level: verdicts, counts, depth and
counterexamples equal.  The level is part of a module's cache key, so the
two searches load two different modules."""

from __future__ import annotations

import glob
import os

import pytest

from pccl.api import explore
from pccl.lang.errors import PcclError
from pccl.model import native_build as NB

from test_native import ROOT, served, summary

SHIPPED = served(sorted(glob.glob(os.path.join(ROOT, "programs", "*.pccl"))), reduce="auto")


def test_every_shipped_program_that_the_engine_serves_is_here():
    assert {"programs/fischer.pccl", "programs/leader.pccl"} <= set(SHIPPED)


def _at(level, monkeypatch, program):
    monkeypatch.setenv("PCCL_NATIVE_OPT", level)
    r = explore(os.path.join(ROOT, program), engine="native", find_all=True, max_states=30_000)
    assert r.model.engine_used == "native", r.model.engine_reason
    return summary(r)


@pytest.mark.parametrize("program", SHIPPED)
def test_o0_and_o2_give_equal_results(program, monkeypatch):
    assert _at("0", monkeypatch, program) == _at("2", monkeypatch, program)


def test_the_level_is_in_the_cache_key(monkeypatch):
    names = set()
    for level in NB.OPT_LEVELS:
        monkeypatch.setenv("PCCL_NATIVE_OPT", level)
        names.add(NB.module_name("int x;"))
    assert len(names) == len(NB.OPT_LEVELS)


def test_a_bad_level_is_an_error_naming_the_variable(monkeypatch):
    monkeypatch.setenv("PCCL_NATIVE_OPT", "fast")
    with pytest.raises(PcclError, match="optimisation level 0, 1, 2, 3") as e:
        NB.opt_level()
    assert e.value.filename == "PCCL_NATIVE_OPT"
    monkeypatch.setenv("PCCL_NATIVE_OPT", "")
    assert NB.opt_level() == "2"
