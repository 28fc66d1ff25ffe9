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
import re
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from conftest import FISCHER, TEST_PROGRAMS, cli
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
    m = make_model(FISCHER, overrides={"k": "0", "d": "1"}, reduce="merge,symmetry,por")
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
    m = make_model(FISCHER, overrides={"k": "0", "d": "1"}, reduce="merge,symmetry,por")
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
    (dict(workers=2, ray="local"), "spill runs on this machine's processes: use workers=N "
                                   "without ray"),
    (dict(exact=True), "spill does not run with exact (it stores fingerprints)"),
    (dict(fastest=True), "spill does not run with fastest"),
    (dict(checkpoint="ck"), "spill does not run with checkpoint"),
])
def test_spill_refuses_what_it_does_not_support(opts, says, tmp_path):
    with pytest.raises(ArgumentError, match=says.replace("(", r"\(").replace(")", r"\)")):
        explore(FISCHER, overrides={"k": "0"}, spill=str(tmp_path), **opts)


#: the environment of a search that runs --workers N as processes (see
#: docs/scale-out.md: without a state graph it would run on threads)
PROCESSES = dict(os.environ, PCCL_THREADS="0")


def _cli(*args, env=None):
    return subprocess.run([sys.executable, "-c", "from pccl.cli import main; main()", *args],
                          capture_output=True, text=True, env=env, timeout=300)


class _Ran:
    """A command's exit status and output, as ``subprocess.run`` gives them."""

    def __init__(self, res):
        self.returncode, self.stdout, self.stderr = res.exit_code, res.stdout, res.stderr


def _cli_here(*args):
    """``pccl ARGS`` in this process (conftest.cli): for the refusals, which exit
    2 before any search, a process of its own (about 0.5 CPU-s to start) would
    test nothing more.  (The memory figures need processes of their own: _cli.)"""
    return _Ran(cli(*args))


def test_cli_refuses_ray_with_spill(tmp_path):
    r = _cli_here("explore", FISCHER, "--set", "k=0", "--spill", str(tmp_path), "--ray", "local")
    assert r.returncode == 2
    assert r.stderr.strip().splitlines() == [
        "--spill: error: --spill runs on this machine's processes: use --workers N without "
        "--ray (Ray's actors may run on nodes that do not see the directory)"]


def test_unwritable_spill_dir_is_one_message(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    r = _cli_here("explore", FISCHER, "--set", "k=0", "--spill", str(blocker / "sub"))
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert r.stderr.strip().splitlines() == [
        f"--spill: error: cannot write the search's files to {blocker / 'sub'}: Not a directory"]


def _disk_full_after(monkeypatch, n: int, here=lambda: True) -> None:
    """The spill files' writes fail with ENOSPC after ``n`` of them (counted
    in the processes where ``here()`` holds)."""
    real = np.ndarray.tofile
    calls = []

    def tofile(self, f, *a, **k):
        if here():
            calls.append(1)
            if len(calls) > n:
                raise OSError(errno.ENOSPC, "No space left on device")
        return real(self, f, *a, **k)
    monkeypatch.setattr(S, "_tofile", tofile)


def test_full_disk_while_spilling_is_one_message(tmp_path, monkeypatch, many_spills):
    """A write that fails with ENOSPC during a merge: the search stops with
    one message naming the option (``spill`` from the API, ``--spill`` as the
    CLI renders it), exit 2."""
    _disk_full_after(monkeypatch, 3)
    with pytest.raises(PcclError) as e:
        explore(FISCHER, overrides={"k": "0", "d": "1"}, spill=str(tmp_path),
                reduce="merge,symmetry,por")      # enough states for three writes
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
    # two thirds of the way: the search without --spill still passes it (by
    # about 7 MiB here), and the spilling one's floor (about 10 MiB above its
    # start: what cannot spill) stays about 4 MiB under it.  (Half-way left
    # under 1 MiB once the table's probes moved to C and the free peak fell.)
    bound = base + 2 * grow // 3
    cut = json.loads(_cli(*args, "--max-memory", str(bound)).stdout)
    assert cut["status"] == "bounded"
    spilled = json.loads(_cli(*args, "--max-memory", str(bound), "--spill", str(tmp_path)).stdout)
    assert spilled["status"] == "exhaustive", spilled["status"]
    for k in ("states", "transitions", "max_depth"):
        assert spilled["statistics"][k] == free["statistics"][k]
    assert spilled["statistics"]["peak_memory_bytes"] <= bound
    assert os.listdir(tmp_path) == []


# -- several workers (--spill DIR --workers N) ----------------------------------

def worker_spills(r, workers: int) -> list:
    """Per worker, from the report's note: (merges, states on disk, level segments)."""
    (note,) = [n for n in r.notes if n.startswith("spill=")]
    if f"nothing spilled by the {workers} workers" in note:
        return [(0, 0, 0)] * workers
    got = re.findall(r"worker (\d+): ([\d,]+) merge\(s\), ([\d,]+) states on disk, ([\d,]+) "
                     r"segment", note)
    assert [int(w) for w, *_ in got] == list(range(workers)), note
    return [tuple(int(x.replace(",", "")) for x in rest) for _, *rest in got]


@pytest.mark.parametrize("engine", ["auto", "python"])
@pytest.mark.parametrize("workers", [2, 3])
@pytest.mark.parametrize("name", sorted(CASES))
def test_spilling_workers_give_the_in_memory_result(name, workers, engine, tmp_path,
                                                     many_spills):
    """Each worker spills its partition (and, on wide levels, its share of
    the level) every 300 states: the result is one process's in memory and
    one process's spilling (figures, verdict, counterexamples), on the
    native engine (``auto``: every case but the temporal property, with the
    time-lock and stall recorder on and off) and on the Python engine."""
    program, opts = CASES[name]
    opts = dict(opts, engine=engine)
    mem = explore(program, **opts)
    one = explore(program, spill=str(tmp_path / "one"), **opts)
    disk = explore(program, spill=str(tmp_path / "w"), workers=workers, **opts)
    assert signature(disk) == signature(mem) == signature(one)
    # the native engine without a recorder, the Python engine with one
    # (a temporal property runs on the Python engine; a program that moves runs
    # native with workers too: stable interned ids)
    assert disk.model.engine_used == (
        "python" if engine == "python" or name == "liveness" else "native")
    spills = worker_spills(disk, workers)
    if mem.stats.states > 600 * workers:
        assert all(merges >= 1 for merges, _, _ in spills), spills
    if name in WIDE:
        assert sum(seg for _, _, seg in spills) >= 2 * workers, spills
    assert sum(on_disk for _, on_disk, _ in spills) <= disk.stats.states
    del disk, one
    gc.collect()
    assert sorted(os.listdir(tmp_path)) == ["one", "w"]
    assert os.listdir(tmp_path / "w") == [] and os.listdir(tmp_path / "one") == [], \
        "the search's files outlived it"


@pytest.mark.parametrize("name", ["leader", "fischer-native", "fischer-violation"])
def test_spilling_workers_hand_work_over_with_the_same_result(name, tmp_path, many_spills,
                                                               monkeypatch):
    """Balanced levels (every level, a few states at a time) while a
    worker's share of the level is read back from disk: what a worker hands
    over comes from memory or from its file, the result does not change."""
    from pccl.search import parallel_pipes as P
    monkeypatch.setattr(P, "_CHUNK", 4)
    monkeypatch.setattr(P, "_NATIVE_CHUNK", 1)
    monkeypatch.setattr(P, "_BALANCE_NATIVE", True)
    monkeypatch.setattr(P, "_MIN_GIVE", 2)
    monkeypatch.setattr(P, "_BALANCE_LEVEL", 0)
    program, opts = CASES[name]
    mem = explore(program, **opts)
    for workers in (2, 3):
        disk = explore(program, spill=str(tmp_path), workers=workers, **opts)
        assert signature(disk) == signature(mem), workers
        if name in WIDE:
            assert sum(seg for _, _, seg in worker_spills(disk, workers)) >= 2 * workers


def test_spilling_workers_answer_as_the_in_memory_ones(tmp_path, many_spills):
    """The partitions on disk hold every state under its number: the graph
    the workers hand over (their partitions read back) equals the in-memory
    workers', and the replay's lookups find every state."""
    from pccl.search.parallel import ParallelExplorer
    m = make_model(FISCHER, overrides={"k": "0", "d": "1"}, reduce="merge,symmetry,por")
    a = ParallelExplorer(m, workers=2)
    b = ParallelExplorer(m, workers=2, spill=str(tmp_path), max_states=5000)
    ra, rb = a.run(), ParallelExplorer(m, workers=2, max_states=5000).run()
    assert ra.status == "exhaustive"
    rs = b.run()
    assert signature_of(rs) == signature_of(rb)
    assert sum(f["merges"] for f in b.spiller.per_worker) >= 4
    assert sum(f["states_on_disk"] for f in b.spiller.per_worker) > 2500


def signature_of(sr):
    return (sr.status, sr.stats.states, sr.stats.transitions, sr.stats.max_depth,
            sorted(b.value for b in sr.bounds_hit))


def test_partition_table_agrees_with_a_fingerprint_table(tmp_path):
    """A worker's spilled partition against the in-memory table it
    replaces: global numbers found, absent fingerprints not, every entry
    read back, across many spills."""
    rng = np.random.default_rng(7)
    d = S.SpillDir(str(tmp_path))
    t = S.PartitionTable(d, FingerprintTable)
    ref = FingerprintTable()
    try:
        for step in range(12):
            q = rng.integers(0, 2**63, size=(int(rng.integers(1, 400)), 2), dtype=np.uint64)
            q = q[ref.lookup(q) < 0]
            q = np.unique(q, axis=0)
            nums = rng.permutation(len(q)).astype(np.int64) + 10 * ref.n
            t.insert(q, nums)
            ref.insert(q, nums)
            if step % 3 != 2:
                t.spill()
            probe = np.concatenate([ref.fps[:ref.n], q ^ np.uint64(1)])
            want = ref.lookup(probe)
            want = np.where(want >= 0, ref.parents[np.maximum(want, 0)].astype(np.int64), -1)
            assert (t.lookup(probe) == want).all()
        assert t.n == ref.n and t.disk.merges >= 6 and t.buffered
        fps, nums = t.entries()
        order = np.lexsort((fps[:, 1], fps[:, 0]))
        rorder = np.lexsort((ref.fps[:ref.n, 1], ref.fps[:ref.n, 0]))
        assert (fps[order] == ref.fps[:ref.n][rorder]).all()
        assert (nums[order] == ref.parents[:ref.n][rorder]).all()
        k = ref.fps[5].tobytes()
        assert t.number_of(k) == int(ref.parents[5])
        assert t.number_of((ref.fps[5] ^ np.uint64(2)).tobytes()) == -1
    finally:
        t.close()
        d.close()


def test_cli_workers_spill_says_what_each_worker_spilled(tmp_path):
    """``--spill DIR --workers 2`` on the command line, with a bound 15 MiB
    above what the two processes need before the first state: each
    process's share is its start plus 7.5 MiB, its buffer a quarter of that
    (54,000 states at 36 bytes), so both merge their partitions on a search
    of 200,000 states.  The figures of the run without it, the note per
    worker with the processes' sizes against the bound, the files gone."""
    args = ["explore", FISCHER, "--set", "k=2", "--set", "d=2", "--reduce", "none",
            "--max-states", "200000", "--no-timelock", "--no-stall", "--format", "json"]
    free = json.loads(_cli(*args).stdout)
    # worker processes (a search without --spill would run on threads)
    base = json.loads(_cli(*args, "--workers", "2", "--max-states", "1", env=PROCESSES).stdout)
    bound = base["statistics"]["peak_memory_bytes"] + (15 << 20)
    r = _cli(*args, "--workers", "2", "--spill", str(tmp_path), "--max-memory", str(bound))
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    for k in ("states", "transitions", "max_depth"):
        assert out["statistics"][k] == free["statistics"][k]
    assert out["status"] == free["status"] == "bounded"
    assert out["bounds"] == free["bounds"] == ["--max-states 200000"], out["bounds"]
    (note,) = [n for n in out["notes"] if n.startswith("--spill")]
    assert note.startswith(f"--spill {tmp_path}: the 2 workers merged their visited states "
                           f"to disk "), note
    merges = [int(m) for m in re.findall(r"worker \d: ([\d,]+) merge\(s\), [\d,]+ states on "
                                         r"disk, [\d,]+ segment", note)]
    assert len(merges) == 2 and min(merges) >= 1, note
    mib = re.search(r"the processes started at (\d+) \+ (\d+) = (\d+) MiB and peaked at "
                    r"(\d+) \+ (\d+) = (\d+) MiB together \(--max-memory \S+: (\d+) MiB\)$",
                    note)
    assert mib, note
    s0, s1, s, p0, p1, p, b = map(int, mib.groups())
    assert abs(s0 + s1 - s) <= 1 and abs(p0 + p1 - p) <= 1 and s <= p <= b == round(bound / 2**20)
    assert os.listdir(tmp_path) == []


def test_unwritable_spill_dir_with_workers_is_one_message(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    r = _cli_here("explore", FISCHER, "--set", "k=0", "--spill", str(blocker / "sub"),
                  "--workers", "2")
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert r.stderr.strip().splitlines() == [
        f"--spill: error: cannot write the search's files to {blocker / 'sub'}: Not a directory"]


@pytest.mark.parametrize("where", ["coordinator", "worker"])
def test_full_disk_in_a_spilling_worker_is_one_message(where, tmp_path, monkeypatch,
                                                        many_spills):
    """ENOSPC in worker 0 (the coordinator's process) or in a forked
    worker: one message naming the option, exit 2, no files left."""
    coordinator = os.getpid()
    _disk_full_after(monkeypatch, 3,
                     here=lambda: (os.getpid() == coordinator) == (where == "coordinator"))
    with pytest.raises(PcclError) as e:
        explore(FISCHER, overrides={"k": "0", "d": "1"}, spill=str(tmp_path), workers=2,
                reduce="merge,symmetry,por")
    assert e.value.render() == (f"spill: error: the search could not go on spilling to "
                                f"{tmp_path}: the disk is full")
    assert e.value.exit_status == 2
    assert os.listdir(tmp_path) == []



@pytest.mark.slow
@pytest.mark.parametrize("workers", [2, 3])
def test_cli_workers_spill_keeps_the_search_under_max_memory(workers, tmp_path):
    """A real bound with 2 and 3 workers: fischer k=2 d=2 unreduced
    (1,066,248 states) stops at ``--max-memory`` without ``--spill``; with
    it, it completes with one process's in-memory figures, the processes'
    peaks together within the bound.  The bound is measured here: the
    processes' peaks together at ``--max-states 1`` (their start: the
    interpreter, pccl, the program, each forked worker counting the pages it
    shares with the coordinator) plus two fifths of what the search adds to
    them in memory (measured 2026-12-02: the search keeps bounds down to
    about a sixth of it; the code before the shares by need stopped
    *bounded* at two fifths, 110-115M with 2 workers, 145-150M with 3)."""
    one = ["explore", FISCHER, "--set", "k=2", "--set", "d=2", "--reduce", "none",
           "--no-timelock", "--no-stall", "--format", "json"]
    args = [*one, "--workers", str(workers)]
    single = json.loads(_cli(*one).stdout)
    # worker processes (a search without --spill would run on threads)
    free = json.loads(_cli(*args, env=PROCESSES).stdout)
    base = json.loads(_cli(*args, "--max-states", "1", env=PROCESSES).stdout)[
        "statistics"]["peak_memory_bytes"]
    grow = free["statistics"]["peak_memory_bytes"] - base
    # (two fifths left 0.3 % of margin with 3 workers: 152 MiB against a
    # bound of 151.6M once, 2026-12-07; half left 0.3 % too: 148 MiB against
    # 148.5M, the spilled run keeping 47 % of the growth.  Three quarters keeps
    # a quarter of the growth on each side: the cut without --spill, the
    # spilled run under it)
    bound = base + grow * 3 // 4
    cut = json.loads(_cli(*args, "--max-memory", str(bound), env=PROCESSES).stdout)
    assert cut["status"] == "bounded", (bound, cut["statistics"])
    r = _cli(*args, "--max-memory", str(bound), "--spill", str(tmp_path))
    assert r.returncode == 0, r.stderr
    spilled = json.loads(r.stdout)
    (note,) = [n for n in spilled["notes"] if n.startswith("--spill")]
    assert spilled["status"] == free["status"] == single["status"] == "exhaustive", \
        (bound, base, grow, note)
    for k in ("states", "transitions", "max_depth", "initial_states"):
        assert spilled["statistics"][k] == free["statistics"][k] == single["statistics"][k], k
    assert spilled["message"] == single["message"]
    assert spilled["statistics"]["peak_memory_bytes"] <= bound
    assert all(int(m) >= 1 for m in re.findall(r"worker \d: ([\d,]+) merge", note)), note
    assert os.listdir(tmp_path) == []


def test_shares_follow_the_peaks():
    """The shares of a bound add up to it; each is its process's peak plus
    an even part of what is left (a larger start gets a larger share), and
    past the bound each is below its peak (so every process is pressed)."""
    mib = 1 << 20
    got = S.shares(110 * mib, [48 * mib, 38 * mib])
    assert got == [60 * mib, 50 * mib] and sum(got) == 110 * mib
    got = S.shares(150 * mib, [48 * mib, 38 * mib, 40 * mib])
    assert got == [56 * mib, 46 * mib, 48 * mib]
    assert all(s < p for s, p in zip(S.shares(80 * mib, [48 * mib, 38 * mib]),
                                     [48 * mib, 38 * mib]))


@pytest.mark.parametrize("first,more", [(40_000, 33_000), (200_000, 50_000), (200_000, 0)])
def test_partition_spill_cost_covers_a_merge_and_a_lookup(first, more, tmp_path):
    """What a worker keeps in reserve for a merge of its buffer (or, with
    nothing buffered, a lookup in its file) is at least what the merge or
    the lookup allocates (tracemalloc sees numpy's buffers)."""
    import tracemalloc
    rng = np.random.default_rng(3)
    d = S.SpillDir(str(tmp_path))
    t = S.PartitionTable(d, FingerprintTable)
    try:
        t.insert(rng.integers(0, 2**63, size=(first, 2), dtype=np.uint64), np.arange(first))
        t.spill()
        q = rng.integers(0, 2**63, size=(more, 2), dtype=np.uint64)
        t.insert(q, np.arange(more) + first)
        probe = np.concatenate([t.entries()[0][::7], q[:1000]])     # mostly present: read
        t.lookup(probe)                         # the largest batch yet
        cost = t.spill_cost()
        tracemalloc.start()
        try:
            base = tracemalloc.get_traced_memory()[0]
            if more:
                t.spill()
            else:
                assert (t.lookup(probe) >= 0).all()
            used = tracemalloc.get_traced_memory()[1] - base
        finally:
            tracemalloc.stop()
        assert 0 < used <= cost, (used, cost)
    finally:
        t.close()
        d.close()
