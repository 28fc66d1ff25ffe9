"""Packaging: pymunk is an extra (``pccl[physics]``) imported only by the
pymunk blackbox; memory figures are portable (pccl.memory)."""

from __future__ import annotations

import os
import subprocess
import sys
import types

import pytest
from click.testing import CliRunner

from pccl.cli import main

from conftest import FISCHER, RACE, RACE_WORLD, ROOT

SMALL = ["--set", "k=1", "--set", "cstime=0"]


def test_explore_and_run_do_not_import_pymunk():
    code = f"""
import sys
from click.testing import CliRunner
from pccl.api import explore, run
from pccl.cli import main
assert explore({FISCHER!r}, overrides={{"k": "1", "cstime": "0"}},
               invariants=["count(inCs) <= 1"]).status == "violation"
run({RACE!r}, world={RACE_WORLD!r})
for args in (["explore", {RACE!r}, "--world", {RACE_WORLD!r}, "--depth", "20"],
             ["run", {RACE!r}, "--world", {RACE_WORLD!r}, "--blackbox", "nondet"],
             ["check", {FISCHER!r}]):
    res = CliRunner().invoke(main, args)
    assert res.exit_code in (0, 1), res.output
print("pymunk" in sys.modules)
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "False"


def test_pymunk_blackbox_without_pymunk_says_how_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "pymunk", None)      # import pymunk -> ImportError
    for cmd in ("run", "explore"):
        res = CliRunner().invoke(main, [cmd, RACE, "--world", RACE_WORLD, "-b", "pymunk"])
        assert res.exit_code == 2, res.output
        from pccl.errors import install_hint
        assert res.stderr.strip() == ("--blackbox: error: the pymunk blackbox needs pymunk: "
                                      + install_hint("physics"))
    # the object itself, passed through the API, says the same (init_env)
    from pccl.api import explore
    from pccl.blackboxes import PYMUNK
    from pccl.errors import PcclError
    with pytest.raises(PcclError, match=r"pip install -e '.*\[physics\]'"):
        explore(RACE, world=RACE_WORLD, blackbox=PYMUNK)


def test_install_hint_names_this_checkout():
    """pccl is not on the package index: the hint installs from the
    checkout this pccl runs from, a path that exists."""
    from pathlib import Path
    from pccl.errors import install_hint
    hint = install_hint("physics")
    root = Path(__file__).resolve().parent.parent
    assert hint == f"pip install -e '{root}[physics]'"
    assert (root / "pyproject.toml").is_file()


def test_packaging_metadata_makes_pymunk_an_extra():
    import tomllib
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    deps = " ".join(meta["dependencies"])
    assert "pymunk" not in deps and "psutil" in deps and "rich" in deps
    assert meta["optional-dependencies"]["physics"] == ["pymunk>=6.6"]
    assert any(d.startswith("pymunk") for d in meta["optional-dependencies"]["test"])
    assert meta["optional-dependencies"]["ray"] == ["ray>=2.9"]
    assert "ray>=2.9" in meta["optional-dependencies"]["test"]     # so CI runs the Ray tests
    assert not any(d.startswith("ray") for d in meta["dependencies"])


# ---------------------------------------------------------------------------
# memory
# ---------------------------------------------------------------------------

def test_peak_memory_units_per_platform():
    from pccl import memory
    fake = types.SimpleNamespace(RUSAGE_SELF=0,
                                 getrusage=lambda who: types.SimpleNamespace(ru_maxrss=1000))
    assert memory._maxrss_bytes(fake, "linux") == 1000 * 1024      # KiB on Linux
    assert memory._maxrss_bytes(fake, "darwin") == 1000            # bytes on macOS


def test_peak_memory_without_resource_uses_psutil(monkeypatch):
    import psutil
    from pccl import memory
    from pccl.explorer import peak_rss_bytes
    monkeypatch.setattr(memory, "_resource", None)                 # as on Windows
    monkeypatch.setattr(memory, "_vmhwm_bytes", lambda: 0)         # (no /proc there)
    rss = psutil.Process().memory_info().rss
    assert 0.5 * rss <= memory.peak_rss_bytes() <= 2 * rss
    assert 0.5 * rss <= peak_rss_bytes() <= 2 * rss                 # the explorer's figure
    assert memory.rss_bytes() > 0


def test_peak_memory_is_plausible():
    import psutil
    from pccl.explorer import peak_rss_bytes
    assert peak_rss_bytes() >= psutil.Process().memory_info().rss * 0.9


# ---------------------------------------------------------------------------
# a clean install, no extras
# ---------------------------------------------------------------------------

_OFFLINE = ("No matching distribution", "Could not find a version", "Failed to establish",
            "NewConnectionError", "Temporary failure in name resolution")


@pytest.mark.slow
def test_clean_install_without_extras_explores(tmp_path):
    """`pip install .` (no extras) in a fresh venv, then the README's explore
    command (Fischer, made small) works and pymunk is not installed."""
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, timeout=120)
    bindir = venv / ("Scripts" if os.name == "nt" else "bin")
    py = bindir / "python"
    inst = subprocess.run([str(py), "-m", "pip", "install", "-q", str(ROOT)],
                          capture_output=True, text=True, timeout=600)
    if inst.returncode != 0 and any(s in inst.stderr for s in _OFFLINE):
        pytest.skip("no package index reachable: " + inst.stderr.strip()[-300:])
    assert inst.returncode == 0, inst.stderr
    assert subprocess.run([str(py), "-c", "import pymunk"], capture_output=True).returncode != 0
    res = subprocess.run([str(bindir / "pccl"), "explore", FISCHER, "--invariant",
                          "count(inCs) <= 1", *SMALL],
                         capture_output=True, text=True, timeout=120, cwd=str(tmp_path))
    assert res.returncode == 1, res.stderr
    assert "violation: invariant 'count(inCs) <= 1' violated" in res.stdout
    assert "peak memory" in res.stdout
    res = subprocess.run([str(bindir / "pccl"), "run", RACE, "--world", RACE_WORLD,
                          "-b", "pymunk"], capture_output=True, text=True, timeout=120)
    assert res.returncode == 2
    assert "pip install -e '" in res.stderr and "[physics]'" in res.stderr
    res = subprocess.run([str(bindir / "pccl"), "explore", FISCHER, "--ray", "local"],
                         capture_output=True, text=True, timeout=120, cwd=str(tmp_path))
    assert res.returncode == 2 and "Traceback" not in res.stderr
    assert "pip install -e '" in res.stderr and "[ray]'" in res.stderr
