"""The native engine's C (pccl/model/native_c/, issue 45): the fixed files
and the module generated for a program compile with ``-Wall -Wextra
-Werror``; the generated source includes each fixed file, and only those;
a module's cache key and a checkpoint's source hash change with the fixed
files' content.  (The native engine's results against the Python engine's:
tests/test_native*.py.)"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sysconfig

import pytest

from pccl.api import make_model
from pccl.model import native as NV
from pccl.model import native_build as NB
from pccl.model.toolchain import native_unavailable

from conftest import ROOT, TEST_PROGRAMS

PROGRAMS = os.path.join(ROOT, "programs")

#: (program, options): every reduction (merge, symmetry, por, dead); none;
#: a program that moves, with memo sites (doReach through the blackbox)
CASES = {
    "fischer-reduced": ("fischer.pccl", {"reduce": "auto"}),
    "fischer-unreduced": ("fischer.pccl", {"reduce": "none", "abstract_time": False}),
    # symmetry keeping agent 0 in place (SYMFIX 1: the orbit argument, issue 46)
    "fischer-agent0-fixed": ("fischer.pccl", {"reduce": "auto", "agents": 3,
                                              "properties": ["forall i: wait[i] ~> inCs[i]"]}),
    "race_robust-world": ("race_robust.pccl", {"world": os.path.join(PROGRAMS, "race.toml")}),
    # property memo sites (dist(), positions), collisions, memo fall-backs of C's errors
    "formation-collisions": ("formation.pccl", {"world": os.path.join(PROGRAMS, "formation.toml"),
                                                "collisions": True, "blackbox": "straight"}),
    # the fixed C's other switches: local guards (guard(), por.c's evfp, dead.c's live events)
    # under --events first, counter saturation, the bound of ticks
    "eng_abs_maxtime-first": (str(TEST_PROGRAMS / "eng_abs_maxtime.pccl"),
                              {"reduce": "auto", "events": "first", "max_time": 6}),
    # the temporal predicates (tpred) and the robots under way (TPEND: fair arrival)
    "race-temporal-nondet": ("race.pccl", {"world": os.path.join(PROGRAMS, "race.toml"), "blackbox": "nondet",
                                           "properties": ["eventually forall i: exited[i]"]}),
}


def _source(case: str) -> str:
    prog, kw = CASES[case]
    m = make_model(os.path.join(PROGRAMS, prog), **kw)
    assert NV.unsupported(m) is None, NV.unsupported(m)
    return NV.Generator(m).source()


def test_the_generated_source_includes_every_fixed_file_once():
    fixed = sorted(n for n in os.listdir(NB.C_DIR) if n.endswith((".c", ".h")))
    assert {"native.h", "kernel.c", "module.c"} <= set(fixed)
    for case in ("fischer-reduced", "fischer-unreduced"):
        included = re.findall(r'^#include "([^"]+)"$', _source(case), re.M)
        # por.c only where partial-order reduction is on
        want = fixed if case == "fischer-reduced" else [n for n in fixed if n != "por.c"]
        assert sorted(included) == want, case
        assert included[0] == "native.h" and included[-1] == "kernel.c"


def test_the_cache_key_and_the_source_hash_read_the_fixed_files(tmp_path, monkeypatch):
    src = _source("fischer-unreduced")
    before = NB.source_digest(src)
    copy = tmp_path / "native_c"
    shutil.copytree(NB.C_DIR, copy)
    monkeypatch.setattr(NB, "C_DIR", str(copy))
    monkeypatch.setattr(NB, "_FIXED", [])
    assert NB.source_digest(src) == before          # the same files: the same key
    with open(copy / "kernel.c", "a") as f:
        f.write("/* an edit */\n")
    monkeypatch.setattr(NB, "_FIXED", [])
    assert NB.source_digest(src) != before
    assert NB.source_digest(src, "abi") != NB.source_digest(src)


def _gcc() -> str:
    cc = shutil.which("gcc")
    if cc is None or native_unavailable() is not None:
        pytest.skip("no gcc or no Python.h")
    return cc


@pytest.mark.slow
@pytest.mark.parametrize("case", sorted(CASES))
def test_the_module_compiles_without_warnings(case, tmp_path):
    """-O2 as the engine compiles (some warnings, -Warray-bounds among them,
    need the optimiser's analysis); -Werror: any warning fails."""
    c = tmp_path / "m.c"
    c.write_text('#define MODNAME "m"\n#define INITFN PyInit_m\n' + _source(case))
    inc = sysconfig.get_paths()["include"]
    p = subprocess.run([_gcc(), "-O2", "-fPIC", "-pthread", "-Wall", "-Wextra", "-Werror", f"-I{inc}",
                        f"-I{NB.C_DIR}", "-c", str(c), "-o", str(tmp_path / "m.o")],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-4000:]
