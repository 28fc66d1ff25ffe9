"""Packaging: pymunk is an extra (``pccl[physics]``) imported only by the
pymunk blackbox; memory figures are portable (pccl.search.memory)."""

from __future__ import annotations

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
        from pccl.lang.errors import install_hint
        assert res.stderr.strip() == ("--blackbox: error: the pymunk blackbox needs pymunk: "
                                      + install_hint("physics"))
    # the object itself, passed through the API, says the same (init_env)
    from pccl.api import explore
    from pccl.blackboxes import PYMUNK
    from pccl.lang.errors import PcclError
    with pytest.raises(PcclError, match=r"pip install -e '.*\[physics\]'"):
        explore(RACE, world=RACE_WORLD, blackbox=PYMUNK)


def test_install_hint_names_this_checkout():
    """pccl is not on the package index: the hint installs from the
    checkout this pccl runs from, a path that exists."""
    from pathlib import Path
    from pccl.lang.errors import install_hint
    hint = install_hint("physics")
    root = Path(__file__).resolve().parents[2]
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
    from pccl.search import memory
    fake = types.SimpleNamespace(RUSAGE_SELF=0,
                                 getrusage=lambda who: types.SimpleNamespace(ru_maxrss=1000))
    assert memory._maxrss_bytes(fake, "linux") == 1000 * 1024      # KiB on Linux
    assert memory._maxrss_bytes(fake, "darwin") == 1000            # bytes on macOS


def test_peak_memory_without_resource_uses_psutil(monkeypatch):
    import psutil
    from pccl.search import memory
    from pccl.search.explorer import peak_rss_bytes
    monkeypatch.setattr(memory, "_resource", None)                 # as on Windows
    monkeypatch.setattr(memory, "_vmhwm_bytes", lambda: 0)         # (no /proc there)
    rss = psutil.Process().memory_info().rss
    assert 0.5 * rss <= memory.peak_rss_bytes() <= 2 * rss
    assert 0.5 * rss <= peak_rss_bytes() <= 2 * rss                 # the explorer's figure
    assert memory.rss_bytes() > 0


def test_peak_memory_is_plausible():
    import psutil
    from pccl.search.explorer import peak_rss_bytes
    assert peak_rss_bytes() >= psutil.Process().memory_info().rss * 0.9


# ---------------------------------------------------------------------------
# a clean install, no extras
# ---------------------------------------------------------------------------

# The wheel, the sdist and a fresh install: tests/acceptance/test_release.py.


def test_install_hints_name_the_checkout_when_run_from_elsewhere(tmp_path):
    """Run outside the checkout, the README's editable install imports pccl through
    setuptools' link tree (build/__editable__.pccl-*/, links to the checkout's files):
    the --ray hint (spelt in pccl.search.parallel) and install_hint still name the
    checkout, and agree."""
    code = ("from pccl.search.parallel import RAY_MISSING\n"
            "from pccl.lang.errors import install_hint\n"
            "print(RAY_MISSING); print(install_hint('ray'))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120, cwd=str(tmp_path))
    assert out.returncode == 0, out.stderr
    ray, hint = out.stdout.splitlines()
    assert hint == f"pip install -e '{ROOT}[ray]'"
    # the option as a placeholder, spelt by the front end (pccl.cli: --ray)
    assert ray == "{ray} needs Ray, an optional extra: " + hint
