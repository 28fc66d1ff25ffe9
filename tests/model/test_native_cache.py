"""The native engine's module cache (pccl/model/native_build.py: ``build``,
``prune_cache``; ``pccl cache``): the size bound ($PCCL_CACHE_SIZE) is
held by removing the least recently used modules, never the one just
built nor one this process loaded, nor while another process loads one;
a bad bound is one error (exit 2); and a signal while a module compiles
(a cold cache) gives the search's interrupted report."""

import json
import os
import subprocess
import sys
import threading
import time

import pytest

from conftest import cli, started
from pccl.api import make_model
from pccl.model import native as NV
from pccl.model import native_build as NB

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
FISCHER = os.path.join(ROOT, "programs/fischer.pccl")
MISSING = NV.unsupported(make_model(FISCHER, reduce="none"))
needs_cc = pytest.mark.skipif(MISSING is not None, reason=f"native engine unavailable: {MISSING}")
EXT = NB._module_ext()


@pytest.fixture
def cache(tmp_path, monkeypatch):
    d = tmp_path / "cache"
    d.mkdir()
    monkeypatch.setenv("PCCL_CACHE", str(d))
    monkeypatch.delenv("PCCL_CACHE_SIZE", raising=False)
    return d


def fake(d, i: int, size: int, age: float) -> str:
    """A module file (not loadable: only its name, size and age matter to
    the pruner), last used ``age`` seconds ago."""
    p = os.path.join(str(d), f"pccl_native_{i:020x}{EXT}")
    with open(p, "wb") as f:
        f.write(b"\0" * size)
    t = time.time() - age
    os.utime(p, (t, t))
    return p


def names(d) -> set:
    return {p for _, _, p in NB.cache_modules(str(d))}


# -- the bound ---------------------------------------------------------------------

def test_prune_removes_the_least_recently_used_until_under_the_bound(cache):
    mods = [fake(cache, i, 1000, age=100 - i) for i in range(10)]     # mods[0] the oldest
    other = cache / "lark-0123.cache"
    other.write_bytes(b"x" * 5000)            # not a module: neither counted nor removed
    removed = NB.prune_cache(str(cache), 4500)
    assert removed == mods[:6]                # oldest first, until 4 x 1000 <= 4500
    assert names(cache) == set(mods[6:])
    assert other.exists()


def test_prune_keeps_the_module_named_even_when_it_is_the_oldest(cache):
    mods = [fake(cache, i, 1000, age=100 - i) for i in range(5)]
    NB.prune_cache(str(cache), 2500, keep=(mods[0],))
    assert names(cache) == {mods[0], mods[4]}


def test_a_module_loaded_by_this_process_is_never_pruned(cache, monkeypatch):
    mods = [fake(cache, i, 1000, age=100 - i) for i in range(3)]
    monkeypatch.setattr(NB, "_LOADED", {os.path.abspath(mods[0])})
    NB.prune_cache(str(cache), 0)
    assert names(cache) == {mods[0]}


def test_stale_compile_directories_are_removed(cache):
    old, new = cache / "tmpold", cache / "tmpnew"
    old.mkdir()
    new.mkdir()
    t = time.time() - NB.STALE_TMP - 10
    os.utime(old, (t, t))
    NB.prune_cache(str(cache), None)
    assert not old.exists() and new.exists()


@pytest.mark.parametrize("text, want", [(None, NB.CACHE_SIZE_DEFAULT), ("", NB.CACHE_SIZE_DEFAULT),
                                        ("0", None), ("2048", 2048), ("3K", 3072),
                                        ("1.5M", 3 * 2**19), ("1G", 2**30)])
def test_the_bound_from_the_environment(monkeypatch, text, want):
    if text is None:
        monkeypatch.delenv("PCCL_CACHE_SIZE", raising=False)
    else:
        monkeypatch.setenv("PCCL_CACHE_SIZE", text)
    assert NB.cache_bound() == want


@needs_cc
def test_building_a_module_prunes_the_cache_and_keeps_the_new_one(cache, monkeypatch):
    """A real compile into a cache over its bound: the old modules go,
    oldest first, the one just built (and loaded) stays; loading a cached
    module touches it (its last use)."""
    olds = [fake(cache, i, 30_000, age=1000 - i) for i in range(6)]
    monkeypatch.setenv("PCCL_CACHE_SIZE", "200K")
    nm = NV.NativeModel(make_model(FISCHER, reduce="none"))
    built = [p for p in names(cache) if p not in olds]
    assert len(built) == 1
    size = os.path.getsize(built[0])
    left = names(cache)
    assert built[0] in left
    # the newest old modules that fit beside it are kept, the oldest went
    kept = [p for p in olds if p in left]
    assert kept == olds[len(olds) - len(kept):]
    assert size + 30_000 * len(kept) <= 200 * 1024 < size + 30_000 * (len(kept) + 1)
    assert len(nm.successors(next(iter(nm.init_states())))) > 0     # loaded, it runs
    # loaded again (from the cache): touched
    t = time.time() - 5000
    os.utime(built[0], (t, t))
    NV.NativeModel(make_model(FISCHER, reduce="none"))
    assert os.path.getmtime(built[0]) > time.time() - 60


def test_a_prune_waits_for_a_process_that_is_loading(cache):
    """The pruner takes the cache's lock exclusively; a process loading a
    module holds it shared: the prune waits until the load is done."""
    fake(cache, 1, 1000, age=10)
    done = threading.Event()
    with NB._Lock(str(cache), exclusive=False):         # "another process loading"
        t = threading.Thread(target=lambda: (NB.prune_cache(str(cache), 0), done.set()))
        t.start()
        assert not done.wait(0.5)       # blocked while the load goes on
        assert len(names(cache)) == 1
    t.join(10)
    assert done.is_set() and not names(cache)


_BUILD = """
import os, sys
from pccl.api import make_model
from pccl.model import native as NV
nm = NV.NativeModel(make_model(sys.argv[1], agents=int(sys.argv[2]), reduce="none"))
print(len(nm.successors(next(iter(nm.init_states())))))
"""


@needs_cc
@pytest.mark.slow
def test_concurrent_processes_with_a_tiny_bound_each_load_their_module(cache, tmp_path):
    """Processes building modules at once into a cache whose bound holds
    none of them (each prune removes the others' modules): every process
    loads its own and searches, two of them the very same module; the
    cache holds no compile directory after."""
    script = tmp_path / "build.py"
    script.write_text(_BUILD)
    env = {**os.environ, "PCCL_CACHE": str(cache), "PCCL_CACHE_SIZE": "1"}
    procs = [subprocess.Popen([sys.executable, str(script), FISCHER, str(a)], env=env,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for a in (2, 3, 3, 4)]
    outs = [p.communicate(timeout=300) for p in procs]
    for p, (out, err) in zip(procs, outs):
        assert p.returncode == 0, err
        assert int(out) > 0
    assert outs[1][0] == outs[2][0]
    assert not [n for n in os.listdir(cache) if n.startswith("tmp")]
    assert len(names(cache)) <= 1      # the last prune's survivor at most


# -- bad values: one error, exit 2 -----------------------------------------------

@pytest.mark.parametrize("value", ["abc", "-3", "12Q", "0.1"])
def test_a_bad_cache_size_is_one_error(cache, value):
    res = cli("cache", env={"PCCL_CACHE_SIZE": value})
    assert res.exit_code == 2
    assert res.stderr.startswith("PCCL_CACHE_SIZE: error: expected a size such as 100M"), res.stderr
    assert res.stderr.count(": error: ") == 1 and repr(value) in res.stderr


@needs_cc
def test_a_bad_cache_size_stops_a_native_search_before_any_work(cache):
    res = cli("explore", FISCHER, "--engine", "native", "--no-progress",
              env={"PCCL_CACHE_SIZE": "lots"})
    assert res.exit_code == 2, res.output
    assert res.stderr.startswith("PCCL_CACHE_SIZE: error: "), res.stderr
    assert "Traceback" not in res.stderr and not res.stdout
    assert not names(cache)


# -- pccl cache ----------------------------------------------------------------------

def test_cache_command_shows_and_clears(cache):
    mods = [fake(cache, i, 2048, age=10) for i in range(3)]
    (cache / "lark-1.cache").write_bytes(b"x")
    res = cli("cache", "--format", "json", env={"PCCL_CACHE_SIZE": "1M"})
    assert res.exit_code == 0
    info = json.loads(res.stdout)
    assert info == {"directory": str(cache), "modules": 3, "bytes": 3 * 2048,
                    "bound_bytes": 2**20, "removed": 0, "removed_bytes": 0}
    res = cli("cache")
    assert res.exit_code == 0
    assert f"directory  {cache}" in res.stdout
    assert "modules    3 (6K)" in res.stdout and "bound      100M ($PCCL_CACHE_SIZE)" in res.stdout
    res = cli("cache", "--clear")
    assert res.exit_code == 0
    assert "removed 3 modules (6K)" in res.stdout and "modules    0" in res.stdout
    assert not any(os.path.exists(p) for p in mods)
    assert (cache / "lark-1.cache").exists()       # the parser's tables stay
    assert "bound      none" in cli("cache", env={"PCCL_CACHE_SIZE": "0"}).stdout


# -- a signal while the module compiles --------------------------------------------

SLOW_CC = """#!{python}
import os, sys, time
open(os.environ["SLOWCC_MARK"], "w").close()
time.sleep(120)
os.execvp("cc", ["cc"] + sys.argv[1:])
"""


@needs_cc
@pytest.mark.parametrize("sig, code", [("SIGTERM", 143), ("SIGINT", 130)])
@pytest.mark.parametrize("workers", ["1", "2"])
def test_a_signal_while_the_module_compiles_gives_the_interrupted_report(
        cache, tmp_path, sig, code, workers):
    """A cold cache and a compiler that takes long (a wrapper that waits):
    the signal arrives while it runs; pccl prints the header (engine
    native), the interrupted verdict, a note and the statistics (0 states),
    exits 130 or 143 -- not only ``pccl: interrupted`` -- and leaves no
    module or compile directory in the cache."""
    import signal
    cc, mark = tmp_path / "slowcc", tmp_path / "mark"
    cc.write_text(SLOW_CC.format(python=sys.executable))
    cc.chmod(0o755)
    env = {"PCCL_CACHE": str(cache), "CC": str(cc), "SLOWCC_MARK": str(mark)}
    p, _ = started(["explore", FISCHER, "--agents", "3", "--no-progress", "--workers", workers],
                   env=env)
    try:
        deadline = time.monotonic() + 120
        while not mark.exists():
            assert p.poll() is None, p.communicate()
            assert time.monotonic() < deadline, "the compiler never started"
            time.sleep(0.05)
        p.send_signal(getattr(signal, sig))
        out, err = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
            p.communicate()
    assert p.returncode == code, (out, err)
    lines = out.splitlines()
    assert lines[0].startswith(f"pccl explore {FISCHER}: 3 agents") and \
        lines[0].endswith("engine native"), lines[0]
    assert lines[1].startswith("interrupted — no violation found"), lines[1]
    assert "note: interrupted while the native engine's module was compiling" in out
    assert "statistics:" in out and "  states           0" in out
    assert "Traceback" not in out + err and "pccl: interrupted" not in err
    assert not names(cache)
    assert not [n for n in os.listdir(cache) if n.startswith("tmp")]


@needs_cc
def test_an_interrupt_while_compiling_through_the_api(cache, monkeypatch):
    """The API's explore: an interrupt in the compile is the interrupted
    result (status, exit status 130, nothing explored), not an exception."""
    from pccl.api import explore

    def interrupted(*a, **k):
        raise KeyboardInterrupt
    monkeypatch.setattr(NB, "_compile", interrupted)
    r = explore(FISCHER, engine="native")
    assert (r.status, r.exit_status, r.stats.states, r.stats.transitions) == \
        ("interrupted", 130, 0, 0)
    assert r.model.engine_used == "native"
    assert any("module was compiling" in n for n in r.notes)


def test_native_modules_of_a_shared_cache_directory_stay_private(tmp_path, monkeypatch):
    """The native engine loads shared objects: with a cache directory others
    can write, it compiles into a directory of the process's own."""
    import os
    import stat
    from pccl.model import native_build as native
    shared = tmp_path / "shared"
    shared.mkdir()
    shared.chmod(0o777)
    monkeypatch.setenv("PCCL_CACHE", str(shared))
    monkeypatch.setattr(native, "_PROCESS_DIR", [])
    d = native.module_dir()
    assert d != str(shared) and stat.S_IMODE(os.stat(d).st_mode) == 0o700
    assert native.module_dir() == d
    monkeypatch.setenv("PCCL_CACHE", str(tmp_path / "mine"))
    assert native.module_dir() == str(tmp_path / "mine")
