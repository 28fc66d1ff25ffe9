"""``--spill DIR`` (pccl/search/spill.py): the visited set and the frontier
on disk give the in-memory search's result, the disk set agrees with a
Python dict, and a directory that cannot be written is one message, exit 2.

Many spills on small searches: :attr:`Spiller.STATES` makes the search
spill whenever a few hundred states are in memory (in a real search the
memory decides, ``test_cli_spill_keeps_the_search_under_max_memory``)."""

from __future__ import annotations

import errno
import gc
import json
import os
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from conftest import FISCHER, TEST_PROGRAMS
from pccl.api import explore, make_model
from pccl.lang.errors import ArgumentError, PcclError
from pccl.search import spill as S
from pccl.search.explorer import Explorer, FingerprintTable

MUTEX = "count(inCs) <= 1"
RACE_WORLD = "programs/race.toml"


def signature(r):
    """Everything a search's result says: the figures, the verdict, the
    counterexamples' state numbers and steps."""
    return (r.status, r.exit_status, r.stats.states, r.stats.transitions, r.stats.max_depth,
            r.stats.initial_states, r.bounds,
            [(v["kind"], v["name"], v["line"], v["depth"]) for v in r.violations],
            [cx.index for cx in r.counterexamples],
            [cx.trace and tuple(cx.trace.labels) for cx in r.counterexamples],
            [v["trace"] for v in r.violations])


CASES = {
    # timelock on: the Python engine with the graph recorder
    "fischer-exhaustive": (FISCHER, dict(overrides={"k": "0", "d": "1"})),
    # timelock and stall off: the native engine, no recorder
    "fischer-native": (FISCHER, dict(overrides={"k": "1", "d": "1"}, reduce="none",
                                     timelock=False, stall=False, max_states=40_000)),
    "fischer-violation": (FISCHER, dict(overrides={"k": "1"}, invariants=[MUTEX])),
    "fischer-all": (FISCHER, dict(overrides={"k": "0"}, invariants=[MUTEX], find_all=True)),
    "fischer-max-states": (FISCHER, dict(overrides={"k": "1", "d": "1"}, max_states=3000)),
    "fischer-depth": (FISCHER, dict(overrides={"k": "1", "d": "1"}, depth=15)),
    "race-nonatomic-stuck": ("programs/race_nonatomic.pccl",
                             dict(world=RACE_WORLD, blackbox="nondet", agents=3)),
    "leader": ("programs/leader.pccl", dict(agents=3, max_states=8_000)),
    "liveness": (str(TEST_PROGRAMS / "token_ring.pccl"),
                 dict(agents=3, properties=["forall i: want[i] ~> has[i]"])),
    "timelock": (str(TEST_PROGRAMS / "tl_spin.pccl"), dict()),
}


class Spills(list):
    """The sizes of the merges done (a list), and the level segments written."""
    segments = 0


#: cases whose levels hold more than 300 states (so they are written to disk)
WIDE = {"fischer-native", "leader"}


@pytest.fixture
def many_spills(monkeypatch):
    monkeypatch.setattr(S.Spiller, "STATES", 300)
    spills = Spills()
    merge, write = S.DiskSet.merge_sorted, S.LevelFile.write

    def counted_merge(self, new):
        spills.append(len(new))
        return merge(self, new)

    def counted_write(self, *a):
        spills.segments += 1
        return write(self, *a)
    monkeypatch.setattr(S.DiskSet, "merge_sorted", counted_merge)
    monkeypatch.setattr(S.LevelFile, "write", counted_write)
    return spills


@pytest.mark.parametrize("name", sorted(CASES))
def test_spilled_search_gives_the_in_memory_result(name, tmp_path, many_spills):
    program, opts = CASES[name]
    mem = explore(program, **opts)
    disk = explore(program, spill=str(tmp_path), **opts)
    assert signature(disk) == signature(mem)
    if mem.stats.states > 600:
        assert len(many_spills) >= 2, "the search never merged to disk twice"
    if name in WIDE:
        assert many_spills.segments >= 2, "no level was written to disk"
    assert any(n.startswith(f"spill={tmp_path}") for n in disk.notes)
    del disk
    gc.collect()
    assert os.listdir(tmp_path) == [], "the search's files outlived it"


def test_spill_files_are_removed_with_the_search(tmp_path, many_spills):
    m = make_model(FISCHER, overrides={"k": "0", "d": "1"})
    ex = Explorer(m, spill=str(tmp_path))
    r = ex.run()
    assert r.status == "exhaustive" and ex.spiller.table.disk.merges >= 2
    (sub,) = os.listdir(tmp_path)
    assert any(f.startswith("fingerprints.") for f in os.listdir(tmp_path / sub))
    # the replay and the graph analyses read the table after the search
    idx = r.stats.states - 1
    chain = []
    while idx != -1:
        chain.append(idx)
        idx = ex.table.parent(idx)
    assert chain[-1] < r.stats.initial_states
    del ex, r
    assert os.listdir(tmp_path) == []


def test_spilled_table_answers_as_the_in_memory_one(tmp_path, many_spills):
    """Every state's parent and fingerprint lookup, disk against memory."""
    m = make_model(FISCHER, overrides={"k": "0", "d": "1"})
    a, b = Explorer(m), Explorer(m, spill=str(tmp_path))
    a.run(), b.run()
    n = a.table.n
    assert b.table.n == n and b.table.base > n // 2
    assert [a.table.parent(i) for i in range(n)] == [b.table.parent(i) for i in range(n)]
    fps = a.table.fps[:n]
    assert (b.table.lookup(fps) == np.arange(n)).all()
    absent = fps.copy()
    absent[:, 1] ^= np.uint64(1)
    assert (b.table.lookup(absent) == -1).all()


# -- the disk set against a dict ---------------------------------------------

@settings(max_examples=40, deadline=None)
@given(batches=st.lists(st.lists(st.tuples(st.integers(0, 7), st.integers(0, 2**64 - 1)),
                                 max_size=40), max_size=6),
       probes=st.lists(st.tuples(st.integers(0, 7), st.integers(0, 2**64 - 1)), max_size=30),
       page=st.sampled_from([1, 2, 3, 256]), queries=st.sampled_from([1, 5, 1024]))
def test_disk_set_agrees_with_a_dict(tmp_path_factory, batches, probes, page, queries):
    """k0 from a handful of values: long runs of equal first halves, across
    pages (a page of 1 to 3 entries), found by lookups in slices of 1 to
    1024 queries."""
    d = S.SpillDir(str(tmp_path_factory.mktemp("ds")))
    ds = S.DiskSet(d)
    ds.PAGE, ds.QUERIES = page, queries
    ref: dict = {}
    try:
        for batch in batches:
            new = [k for k in dict.fromkeys(batch) if k not in ref]
            for k in new:
                ref[k] = len(ref)
            if new:
                arr = np.array(new, dtype=np.uint64).reshape(-1, 2)
                ds.merge(arr[:, 0].copy(), arr[:, 1].copy(),
                         np.arange(len(ref) - len(new), len(ref), dtype=np.uint32))
            assert ds.n == len(ref)
            q = list(ref) + probes
            if q:
                qa = np.array(q, dtype=np.uint64).reshape(-1, 2)
                got = ds.lookup(qa[:, 0].copy(), qa[:, 1].copy()).tolist()
                assert got == [ref.get(k, -1) for k in q]
        keys = np.fromfile(ds.path, dtype=S.RECORD)["k0"] if ds.n else []
        assert list(keys) == sorted(k0 for k0, _ in ref)
    finally:
        ds.close()
        d.close()


@settings(max_examples=30, deadline=None)
@given(ops=st.lists(st.one_of(
    st.lists(st.integers(0, 60), min_size=1, max_size=12).map(lambda b: ("batch", b)),
    st.just(("spill", None))), max_size=25))
def test_spill_table_agrees_with_a_dict(tmp_path_factory, ops):
    """Batches of candidates admitted (new ones numbered in order), spills
    in between: lookups and parents as a dict of the admitted says."""
    from pccl.search.fingerprint import fingerprint
    d = S.SpillDir(str(tmp_path_factory.mktemp("st")))
    t = S.SpillTable(d, FingerprintTable)
    ref: dict = {}
    parents: list = []
    try:
        for op, batch in ops:
            if op == "spill":
                t.spill()
                continue
            keys = [fingerprint(x) for x in batch]
            first = np.array(sorted({k: i for i, k in reversed(list(enumerate(keys)))}.values()),
                             dtype=np.int64)
            new = t.new_positions(keys, first).tolist()
            assert new == [p for p in first.tolist() if keys[p] not in ref]
            par = np.array([len(ref) // 2 if ref else 0xFFFF_FFFF] * len(new), dtype=np.int64)
            t.add(len(new), par)
            for p in new:
                ref[keys[p]] = len(ref)
                parents.append(-1 if par[0] == 0xFFFF_FFFF else int(par[0]))
            assert t.n == len(ref)
        assert [t.index_of(k) for k in ref] == list(range(len(ref)))
        assert t.index_of(fingerprint("absent")) == -1
        assert [t.parent(i) for i in range(len(ref))] == parents
    finally:
        t.close()
        d.close()


# -- refusals and errors -----------------------------------------------------

@pytest.mark.parametrize("opts, says", [
    (dict(workers=2), "spill runs in one process for now: use workers=1 without ray"),
    (dict(exact=True), "spill does not run with exact (it stores fingerprints)"),
    (dict(fastest=True), "spill does not run with fastest"),
    (dict(checkpoint="ck"), "spill does not run with checkpoint"),
])
def test_spill_refuses_what_it_does_not_support(opts, says, tmp_path):
    with pytest.raises(ArgumentError, match=says.replace("(", r"\(").replace(")", r"\)")):
        explore(FISCHER, overrides={"k": "0"}, spill=str(tmp_path), **opts)


def _cli(*args, env=None):
    return subprocess.run([sys.executable, "-c", "from pccl.cli import main; main()", *args],
                          capture_output=True, text=True, env=env, timeout=300)


def test_cli_refuses_workers_with_spill(tmp_path):
    r = _cli("explore", FISCHER, "--set", "k=0", "--spill", str(tmp_path), "--workers", "2")
    assert r.returncode == 2
    assert r.stderr.strip().splitlines() == [
        "--spill: error: --spill runs in one process for now: use --workers 1 without --ray"]


def test_unwritable_spill_dir_is_one_message(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    r = _cli("explore", FISCHER, "--set", "k=0", "--spill", str(blocker / "sub"))
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert r.stderr.strip().splitlines() == [
        f"--spill: error: cannot write the search's files to {blocker / 'sub'}: Not a directory"]


def test_full_disk_while_spilling_is_one_message(tmp_path, monkeypatch, many_spills):
    """A write that fails with ENOSPC during a merge: the search stops with
    one message naming the option (``spill`` from the API, ``--spill`` as the
    CLI renders it), exit 2."""
    real = np.ndarray.tofile
    calls = []

    def tofile(self, f, *a, **k):
        calls.append(1)
        if len(calls) > 3:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(self, f, *a, **k)
    monkeypatch.setattr(S, "_tofile", tofile)
    with pytest.raises(PcclError) as e:
        explore(FISCHER, overrides={"k": "0", "d": "1"}, spill=str(tmp_path))
    assert e.value.render() == (f"spill: error: the search could not go on spilling to "
                                f"{tmp_path}: the disk is full")          # the API's spelling
    assert e.value.exit_status == 2
    from pccl.cli import cli_spelling
    assert e.value.respell(cli_spelling).render() == (
        f"--spill: error: the search could not go on spilling to {tmp_path}: the disk is full")


@pytest.mark.slow
def test_cli_spill_keeps_the_search_under_max_memory(tmp_path):
    """A real bound: fischer k=1 d=1 unreduced (590,472 states) without
    --spill stops at --max-memory; with it, it completes with the in-memory
    search's figures and a peak below the bound."""
    args = ["explore", FISCHER, "--set", "k=1", "--set", "d=1", "--reduce", "none",
            "--no-timelock", "--no-stall", "--format", "json"]
    free = json.loads(_cli(*args).stdout)
    base = json.loads(_cli(*args, "--max-states", "1").stdout)["statistics"]["peak_memory_bytes"]
    grow = free["statistics"]["peak_memory_bytes"] - base
    bound = base + grow // 2
    cut = json.loads(_cli(*args, "--max-memory", str(bound)).stdout)
    assert cut["status"] == "bounded"
    spilled = json.loads(_cli(*args, "--max-memory", str(bound), "--spill", str(tmp_path)).stdout)
    assert spilled["status"] == "exhaustive", spilled["status"]
    for k in ("states", "transitions", "max_depth"):
        assert spilled["statistics"][k] == free["statistics"][k]
    assert spilled["statistics"]["peak_memory_bytes"] <= bound
    assert os.listdir(tmp_path) == []
