"""Issue 48: a release that installs anywhere, a changelog, a citation.

`python -m build` (from a copy of the sources, with this environment's
setuptools: `--no-isolation`) makes an sdist and, from the sdist, a wheel;
the wheel is installed into a fresh virtual environment outside the checkout
(no system site packages; pip takes the dependencies from the package index
and its cache) and `pccl check`, `run`, `explore` (native engine) and `view`
run from a directory outside the checkout on copies of the shipped
programs.  With pipx too where pipx is installed."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tarfile
import tomllib
import zipfile
from pathlib import Path

import pytest

import pccl

from conftest import ROOT

_OFFLINE = ("No matching distribution", "Could not find a version", "Failed to establish",
            "NewConnectionError", "Temporary failure in name resolution")
VERSION = pccl.__version__


@pytest.fixture(scope="module")
def dist(tmp_path_factory) -> dict[str, Path]:
    """The sdist and the wheel of this checkout (the wheel built from the sdist:
    what the sdist lacks, the wheel lacks too)."""
    tmp = tmp_path_factory.mktemp("release")
    # a copy: a checkout's build/ folder may hold files of an older layout
    src = tmp / "src"
    shutil.copytree(ROOT, src, ignore=shutil.ignore_patterns(".git", ".venv", "build", "dist", "*.egg-info",
                                                             "__pycache__", ".*_cache", ".hypothesis"))
    out = tmp / "dist"
    built = subprocess.run([sys.executable, "-m", "build", "--no-isolation", "--outdir", str(out), str(src)],
                           capture_output=True, text=True, timeout=900)
    assert built.returncode == 0, built.stdout[-3000:] + built.stderr[-3000:]
    [sdist] = out.glob("pccl-*.tar.gz")
    [wheel] = out.glob("pccl-*.whl")
    return {"sdist": sdist, "wheel": wheel}


def _source_modules() -> set[str]:
    """Every module of the source tree as the installed layout names it."""
    names = {"pccl/" + f.relative_to(ROOT / "pccl").as_posix() for f in (ROOT / "pccl").rglob("*.py")
             if "__pycache__" not in f.parts}
    for top in ("semantics", "blackboxes"):
        names |= {f"pccl/{top}/{f.name}" for f in (ROOT / top).glob("*.py")}
    return names


PACKAGE_DATA = {"pccl/py.typed", "pccl/lang/grammar.lark",
                *("pccl/output/viewer_assets/" + p.name for p in (ROOT / "pccl/output/viewer_assets").iterdir()),
                # the native engine's fixed C (docs/architecture.md, "The native engine's C")
                *("pccl/model/native_c/" + p.name for p in (ROOT / "pccl/model/native_c").iterdir())}


@pytest.mark.slow
def test_the_sdist_and_the_wheel_carry_everything(dist):
    assert dist["wheel"].name == f"pccl-{VERSION}-py3-none-any.whl"
    assert dist["sdist"].name == f"pccl-{VERSION}.tar.gz"
    names = set(zipfile.ZipFile(dist["wheel"]).namelist())
    expected = _source_modules()
    assert len(expected) > 60 and "pccl/model/engine.py" in expected and "pccl/semantics/rules.py" in expected
    assert expected <= names, sorted(expected - names)
    assert PACKAGE_DATA <= names, sorted(PACKAGE_DATA - names)
    info = f"pccl-{VERSION}.dist-info"
    assert f"{info}/licenses/LICENSE" in names
    meta = zipfile.ZipFile(dist["wheel"]).read(f"{info}/METADATA").decode()
    assert f"\nVersion: {VERSION}\n" in meta and "\nLicense-Expression: Apache-2.0\n" in meta
    assert "pccl = pccl.cli:main" in zipfile.ZipFile(dist["wheel"]).read(f"{info}/entry_points.txt").decode()
    # the sdist: the sources the wheel was built from, and what a reader needs beside them
    with tarfile.open(dist["sdist"]) as t:
        snames = {n.split("/", 1)[1] for n in t.getnames() if "/" in n}
    for top in ("semantics", "blackboxes"):
        assert {f"{top}/{f.name}" for f in (ROOT / top).glob("*.py")} <= snames
    assert {"pyproject.toml", "README.md", "LICENSE", "CHANGELOG.md", "CITATION.cff",
            "pccl/lang/grammar.lark", "programs/fischer.pccl", "programs/race.toml"} <= snames
    assert {m for m in expected if m.startswith("pccl/") and "/semantics/" not in m
            and "/blackboxes/" not in m} <= snames


def _run(cmd, cwd, env, timeout=300):
    return subprocess.run([str(c) for c in cmd], capture_output=True, text=True, cwd=str(cwd), env=env,
                          timeout=timeout)


def _use_installed_pccl(bindir: Path, python: Path, work: Path, cache: Path, *, where: Path) -> None:
    """The commands a user runs after installing the wheel, from ``work`` (a
    directory outside the checkout holding copies of the shipped programs)."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTHON") and k != "VIRTUAL_ENV"}
    env["PCCL_CACHE"] = str(cache)          # a cold, private cache: the native module is compiled
    pccl_bin = bindir / "pccl"
    res = _run([pccl_bin, "--version"], work, env)
    assert res.returncode == 0, res.stderr
    lines = res.stdout.splitlines()
    assert lines[0] == f"pccl {VERSION}"
    assert lines[1].startswith("native engine available"), res.stdout
    assert f"({where}" in lines[3] or str(where) in lines[3], lines[3]   # the environment's Python
    res = _run([pccl_bin, "check", "race.pccl", "--world", "race.toml"], work, env)
    assert (res.returncode, res.stdout.strip()) == (0, "race.pccl: ok (2 events, 10 statements)"), res.stderr
    res = _run([pccl_bin, "run", "race.pccl", "--world", "race.toml"], work, env)
    assert res.returncode == 0, res.stdout + res.stderr
    assert "final" in res.stdout
    res = _run([pccl_bin, "explore", "fischer.pccl", "--set", "k=1", "--invariant", "count(inCs) <= 1",
                "--trace-out", "fischer.json"], work, env)
    assert res.returncode == 1, res.stdout + res.stderr
    header = res.stdout.splitlines()[0]
    assert header.startswith("pccl explore fischer.pccl: 2 agents") and header.endswith("engine native"), header
    assert "violation: invariant 'count(inCs) <= 1' violated" in res.stdout
    assert any(p.name.startswith("pccl_native_") for p in cache.iterdir())
    res = _run([pccl_bin, "view", "fischer.json", "-o", "fischer.html"], work, env)
    assert res.returncode == 0, res.stderr
    page = (work / "fischer.html").read_text()
    assert page.lower().startswith("<!doctype html>") and "count(inCs) \\u003c= 1" in page
    # pccl itself was imported from the environment, not from a checkout
    res = _run([python, "-c", "import pccl, pccl.semantics.rules as r; print(pccl.__file__); "
                "print(r.__file__)"], work, env)
    assert res.returncode == 0, res.stderr
    assert all(Path(p).resolve().is_relative_to(where.resolve()) for p in res.stdout.split()), res.stdout


def _work_dir(tmp_path: Path) -> Path:
    work = tmp_path / "work"
    work.mkdir()
    for name in ("race.pccl", "race.toml", "fischer.pccl"):
        shutil.copy(ROOT / "programs" / name, work / name)
    return work


@pytest.mark.slow
def test_the_wheel_installs_into_a_fresh_environment_and_runs_outside_the_checkout(dist, tmp_path):
    """No extras: pymunk and Ray are not installed, and asking for them says
    which packages to install (pccl is not on the package index)."""
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, timeout=120)
    bindir = venv / ("Scripts" if os.name == "nt" else "bin")
    inst = subprocess.run([str(bindir / "python"), "-m", "pip", "install", "-q", str(dist["wheel"])],
                          capture_output=True, text=True, timeout=900)
    if inst.returncode != 0 and any(s in inst.stderr for s in _OFFLINE):
        pytest.skip("no package index reachable: " + inst.stderr.strip()[-300:])
    assert inst.returncode == 0, inst.stderr
    work = _work_dir(tmp_path)
    _use_installed_pccl(bindir, bindir / "python", work, tmp_path / "cache", where=venv)
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTHON") and k != "VIRTUAL_ENV"}
    for extra in ("pymunk", "ray"):
        assert _run([bindir / "python", "-c", f"import {extra}"], work, env).returncode != 0
    res = _run([bindir / "pccl", "run", "race.pccl", "--world", "race.toml", "-b", "pymunk"], work, env)
    assert res.returncode == 2 and "Traceback" not in res.stderr
    assert "pip install 'pymunk>=" in res.stderr, res.stderr
    res = _run([bindir / "pccl", "explore", "fischer.pccl", "--ray", "local"], work, env)
    assert res.returncode == 2 and "Traceback" not in res.stderr
    assert "pip install 'ray>=" in res.stderr, res.stderr


@pytest.mark.slow
def test_the_wheel_installs_with_pipx(dist, tmp_path):
    pipx = shutil.which("pipx")
    if pipx is None:
        pytest.skip("pipx is not installed")
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTHON") and k != "VIRTUAL_ENV"}
    env.update(PIPX_HOME=str(tmp_path / "pipx"), PIPX_BIN_DIR=str(tmp_path / "bin"),
               PIPX_MAN_DIR=str(tmp_path / "man"))
    inst = _run([pipx, "install", dist["wheel"]], tmp_path, env, timeout=900)
    if inst.returncode != 0 and any(s in inst.stdout + inst.stderr for s in _OFFLINE):
        pytest.skip("no package index reachable")
    assert inst.returncode == 0, inst.stdout + inst.stderr
    where = tmp_path / "pipx" / "venvs" / "pccl"
    _use_installed_pccl(tmp_path / "bin", where / "bin" / "python", _work_dir(tmp_path), tmp_path / "cache",
                        where=where)


# --------------------------------------------------------------------------
# The changelog and the citation
# --------------------------------------------------------------------------

def test_the_changelog_has_keep_a_changelog_shape():
    text = (ROOT / "CHANGELOG.md").read_text()
    heads = re.findall(r"^## \[([^\]]+)\](?: - (\d{4}-\d{2}-\d{2}))?$", text, re.M)
    assert heads[0] == ("Unreleased", "")
    versions = [v for v, _ in heads[1:]]
    assert versions[0] == VERSION and versions[-1] == "0.1.0"
    as_tuples = [tuple(map(int, v.split("."))) for v in versions]
    assert as_tuples == sorted(as_tuples, reverse=True) and len(set(as_tuples)) == len(as_tuples)
    dates = [d for _, d in heads[1:]]
    assert all(dates) and dates == sorted(dates, reverse=True)
    # every section is one of keep-a-changelog's kinds
    kinds = set(re.findall(r"^### (.+)$", text, re.M))
    assert kinds <= {"Added", "Changed", "Deprecated", "Removed", "Fixed", "Security"}, kinds
    assert text.count("**Verdict**") >= 5


def test_the_citation_names_the_software_and_the_paper():
    import yaml
    cff = yaml.safe_load((ROOT / "CITATION.cff").read_text())
    assert cff["cff-version"] == "1.2.0" and cff["type"] == "software"
    for key in ("message", "title", "authors", "version", "license", "date-released"):
        assert cff[key], key
    assert str(cff["version"]) == VERSION
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert cff["license"] == project["license"] == "Apache-2.0"
    released = re.search(rf"^## \[{re.escape(VERSION)}\] - (\S+)$", (ROOT / "CHANGELOG.md").read_text(), re.M)
    assert released and str(cff["date-released"]) == released.group(1)
    [paper] = cff["references"]
    assert paper["title"] == "Semantics of a Language for Distributed Coordination and Control"
    assert [(a["given-names"], a["family-names"]) for a in paper["authors"]] == \
        [("Ritwika", "Ghosh"), ("Sayan", "Mitra")]
    # the title the README and the docs cite
    assert paper["title"] in " ".join((ROOT / "README.md").read_text().split())
    cffconvert = shutil.which("cffconvert")
    if cffconvert is not None:              # the format's own validator, where installed
        res = subprocess.run([cffconvert, "--validate", "-i", str(ROOT / "CITATION.cff")],
                             capture_output=True, text=True, timeout=60)
        assert res.returncode == 0, res.stdout + res.stderr
