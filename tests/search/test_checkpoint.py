"""Checkpoint and resume (``pccl explore --checkpoint DIR`` / ``--resume DIR``):
a search interrupted at any point and resumed gives exactly the result of
an uninterrupted one (pccl/search/checkpoint.py)."""

from __future__ import annotations

import json
import os
import random
import shutil
import signal
import subprocess
import sys
import time

import pytest

from pccl import api
from pccl.lang.errors import CheckpointFileError
from pccl.search import checkpoint as C
from pccl.search import safedata
from pccl.search.fingerprint import fingerprint
from conftest import TEST_PROGRAMS, cli, interrupted

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
PROG = os.path.join(ROOT, "programs")
TPROG = os.path.join(ROOT, "tests", "programs")

#: (name, program, options): every feature of the one-process search
CASES = [
    ("fischer-k1", f"{PROG}/fischer.pccl", dict(overrides={"k": "1"})),
    ("fischer-k2-depth", f"{PROG}/fischer.pccl",
     dict(overrides={"k": "2"}, depth=120, invariants=("count(inCs) <= 1",))),
    ("fischer-none-depth", f"{PROG}/fischer.pccl",
     dict(overrides={"k": "1"}, reduce="none", depth=40)),
    ("fischer-max-states", f"{PROG}/fischer.pccl",
     dict(overrides={"k": "1"}, max_states=20_000)),
    ("race-nondet-all", f"{PROG}/race_nonatomic.pccl",
     dict(world=f"{PROG}/race.toml", blackbox="nondet", find_all=True)),
    ("race-nondet", f"{PROG}/race_nonatomic.pccl",
     dict(world=f"{PROG}/race.toml", blackbox="nondet", reduce="none")),
    ("tl-spin", f"{TPROG}/tl_spin.pccl", dict()),
    ("rdv-stall", f"{TPROG}/rdv_meet.pccl",
     dict(world=f"{TPROG}/rdv_wall.toml", blackbox="straight")),
    ("rdv-stall-none", f"{TPROG}/rdv_meet.pccl",
     dict(world=f"{TPROG}/rdv_wall.toml", blackbox="straight", reduce="none")),
    ("list-seen", f"{TPROG}/list_seen.pccl", dict(agents=2)),
    ("fischer-temporal", f"{PROG}/fischer.pccl",
     dict(overrides={"k": "1"}, depth=80, exact=True,
          properties=("reachable count(inCs) == 1",))),
]

_OURS = ("resumed from", "checkpoint written to", "checkpoint not written")


def summary(r) -> dict:
    """Everything a result says but time, memory and the checkpoint notes."""
    s = r.stats
    checked = r.checked.to_json()
    checked["notes"] = [n for n in checked.get("notes", []) if not n.startswith(_OURS)]
    return {"status": r.status, "verdict": r.verdict, "exit": r.exit_status,
            "stats": (s.initial_states, s.states, s.transitions, s.max_depth, s.max_time),
            "bounds": r.bound_labels,
            "violations": [v.to_json() for v in r.violations],
            "witnesses": [(w["name"], w["depth"], [st.to_json() for st in w["trace"]])
                          for w in r.witnesses],
            "holds": r.holds, "timelock": r.timelock, "stall": r.stall,
            "notes": [n for n in r.notes if not n.startswith(_OURS)],
            "checked": checked}


class _Interrupt:
    """A progress callback that interrupts the search at its ``k``-th call (a
    batch admitted or a level finished), like Ctrl-C there."""

    def __init__(self, k: int):
        self.k, self.calls = k, 0

    def __call__(self, p) -> None:
        self.calls += 1
        if self.calls == self.k:
            raise KeyboardInterrupt


def resumed_until_done(program, opts: dict, d: str, rounds) -> tuple:
    """Run with checkpoints in ``d`` once for each item of ``rounds`` (that run's
    options: where it is interrupted, how many workers; read lazily, so a
    generator may set up the round's interruption), each run after the first
    checkpoint resuming from it, until a run is not interrupted; returns the
    last result and how often it resumed."""
    resumed = 0
    for extra in rounds:
        kw = dict(opts, checkpoint=d, **extra)
        if os.path.exists(os.path.join(d, C.MANIFEST)):
            kw["resume"] = d
            resumed += 1
        r = api.explore(program, **kw)
        if r.status != "interrupted":
            break
    return r, resumed


def interrupted_run(program, opts: dict, d: str, cuts: list, workers=None) -> tuple:
    """Run with checkpoints in ``d``, interrupted at each of ``cuts`` (progress
    calls since the run's start) and resumed (with ``workers[i % len]``
    workers in the i-th run, if given); returns the final result and how
    often it resumed."""
    def rounds():
        for i, k in enumerate(cuts + [None]):
            kw: dict = dict(progress_interval=1e-9)
            if workers:
                kw["workers"] = workers[i % len(workers)]
            if k is not None:
                kw["progress"] = _Interrupt(k)
            yield kw
    return resumed_until_done(program, opts, d, rounds())


def _calls(program, opts) -> int:
    counter = _Interrupt(0)
    api.explore(program, progress=counter, progress_interval=1e-9, **opts)
    return counter.calls


@pytest.mark.parametrize("name,program,opts", CASES, ids=[c[0] for c in CASES])
def test_interrupted_and_resumed_search_equals_uninterrupted(tmp_path, name, program, opts):
    # the Python engine (the native one: test_native_interrupted_and_resumed_...)
    opts = dict(opts, engine="python")
    full = api.explore(program, **opts)
    calls = _calls(program, opts)
    rng = random.Random(name)
    # interruptions at random points (batches, level ends), three resumes
    cuts = sorted(rng.sample(range(1, calls + 1), min(3, calls)))
    cuts = [c - (cuts[i - 1] if i else 0) for i, c in enumerate(cuts)]
    r, resumed = interrupted_run(program, opts, str(tmp_path / "ck"), cuts)
    assert summary(r) == summary(full)
    assert resumed >= 1
    assert any(n.startswith("resumed from") for n in r.notes)


RUNAWAY = str(TEST_PROGRAMS / "runaway.pccl")     # x grows for ever in zero time


def test_runaway_note_survives_a_resume(tmp_path):
    """A zero-time runaway noted before the checkpoint is in the resumed
    result too; one noted after it, once."""
    opts = dict(agents=1, reduce="none", max_states=1200)
    full = api.explore(RUNAWAY, **opts)
    assert sum("zero-time runaway" in n for n in full.notes) == 1
    calls = _calls(RUNAWAY, opts)
    for k in (calls // 10, calls // 2, calls - 3):
        r, resumed = interrupted_run(RUNAWAY, opts, str(tmp_path / f"ck{k}"), [k])
        assert resumed == 1 and summary(r) == summary(full), k


def test_interrupt_at_every_point_of_a_small_search(tmp_path):
    program, opts = f"{PROG}/race_nonatomic.pccl", dict(world=f"{PROG}/race.toml",
                                                         blackbox="nondet", find_all=True)
    full = summary(api.explore(program, **opts))
    calls = _calls(program, opts)
    assert calls > 5
    for k in range(1, calls + 1):
        d = str(tmp_path / f"ck{k}")
        r, _ = interrupted_run(program, opts, d, [k])
        assert summary(r) == full, k


def test_checkpoint_every_level_then_resume_from_each(tmp_path):
    """--checkpoint-interval 0: a checkpoint at every level; the one a crash
    leaves (any of them) resumes to the same result."""
    program, opts = f"{TPROG}/rdv_meet.pccl", dict(world=f"{TPROG}/rdv_wall.toml",
                                                    blackbox="straight", reduce="none")
    full = summary(api.explore(program, **opts))
    d = str(tmp_path / "every")
    saved = []
    orig = C.Checkpointer.write

    def spy(self, state, arrays, **kw):
        orig(self, state, arrays, **kw)
        snap = str(tmp_path / f"gen{len(saved)}")
        shutil.copytree(self.dir, snap)
        saved.append((state["depth"], snap))

    C.Checkpointer.write = spy
    try:
        api.explore(program, checkpoint=d, checkpoint_interval=0, **opts)
    finally:
        C.Checkpointer.write = orig
    depths = [dep for dep, _ in saved]
    assert depths == list(range(len(depths))) and len(depths) >= 10
    for _, snap in saved:
        assert summary(api.explore(program, resume=snap, **opts)) == full


def test_states_round_trip_through_a_checkpoint():
    """UNDEF (Ellipsis), floats, None: the frontier written as data
    (:mod:`pccl.search.safedata`, MessagePack for a list of states) and read
    back is the same states, with the same fingerprints."""
    m = api.make_model(f"{PROG}/race_nonatomic.pccl", world=f"{PROG}/race.toml",
                       blackbox="nondet")
    states = list(m.init_states())
    for _ in range(6):
        states += [s for st in states[-5:] for _, s in m.successors(st)]
    back = safedata.loads(safedata.dumps(safedata.States(states)))
    assert back == states
    assert [fingerprint(m.key(s)) for s in back] == [fingerprint(m.key(s)) for s in states]

    def cells(x):
        if isinstance(x, tuple):
            for y in x:
                yield from cells(y)
        else:
            yield x
    flat_a, flat_b = list(cells(tuple(states))), list(cells(tuple(back)))
    assert any(x is Ellipsis for x in flat_a)
    assert [x is Ellipsis for x in flat_a] == [x is Ellipsis for x in flat_b]
    assert [type(x) for x in flat_a] == [type(x) for x in flat_b]


def test_crash_while_writing_leaves_the_previous_checkpoint_usable(tmp_path, monkeypatch):
    program, opts = f"{PROG}/fischer.pccl", dict(overrides={"k": "1"}, depth=60)
    full = summary(api.explore(program, **opts))
    d = str(tmp_path / "ck")
    r = api.explore(program, checkpoint=d, progress=_Interrupt(40), progress_interval=1e-9,
                    **opts)
    assert r.status == "interrupted"
    before = json.load(open(os.path.join(d, C.MANIFEST)))

    # the process dies after the new generation's files, before its manifest
    def die(*a, **k):
        raise SystemExit("killed while writing")
    monkeypatch.setattr(C.os, "replace", die)
    with pytest.raises(SystemExit):
        api.explore(program, resume=d, checkpoint_interval=0, **opts)
    monkeypatch.undo()
    assert json.load(open(os.path.join(d, C.MANIFEST))) == before
    leftovers = [e for e in os.listdir(d) if e != C.MANIFEST and e != before["generation"]]
    assert leftovers                     # the half-written generation is there ...
    # ... and ignored: the previous checkpoint resumes to the uninterrupted result
    assert summary(api.explore(program, resume=d, **opts)) == full
    # a truncated file of a generation no manifest names is ignored too
    half = os.path.join(d, "gen-999999")
    os.makedirs(half)
    open(os.path.join(half, "state.json"), "wb").write(b"\x80\x05junk")
    assert summary(api.explore(program, resume=d, **opts)) == full


def test_checkpoints_append_the_rows_added_since_the_last(tmp_path):
    """The table and the graph only grow: a checkpoint writes the rows added
    since the last one and names the older generations' parts; the
    generations it names stay, the others go; a part damaged in an older
    generation is found; the result resumed from the last is the
    uninterrupted one."""
    opts = dict(overrides={"k": "1"}, max_states=20_000, engine="python")
    full = summary(api.explore(f"{PROG}/fischer.pccl", **opts))
    d = str(tmp_path / "ck")
    r = api.explore(f"{PROG}/fischer.pccl", checkpoint=d, checkpoint_interval=0,
                    progress=_Interrupt(40), progress_interval=1e-9, **opts)
    assert r.status == "interrupted"
    man = json.load(open(os.path.join(d, C.MANIFEST)))
    seg = man["segments"]
    assert set(seg) == {"fps", "parents", "rec_src", "rec_dst", "rec_dyn", "rec_sig"}
    parts = seg["fps"]["parts"]
    assert len(parts) >= 10 and parts[0]["start"] == 0 and parts[-1]["end"] == man["states"]
    assert all(a["end"] == b["start"] for a, b in zip(parts, parts[1:]))
    # each part holds the rows of its generation only: 16 bytes a state and the header
    for p in parts:
        size = os.path.getsize(os.path.join(d, p["gen"], p["file"]))
        assert size == 16 * (p["end"] - p["start"]) + 128
    named = {p["gen"] for s in seg.values() for p in s["parts"]} | {man["generation"]}
    assert {e for e in os.listdir(d) if e.startswith("gen-")} == named
    for g in named - {man["generation"]}:        # of an older one, only the parts named
        assert sorted(os.listdir(os.path.join(d, g))) == \
            sorted(p["file"] for s in seg.values() for p in s["parts"] if p["gen"] == g)
    snap = str(tmp_path / "snap")
    shutil.copytree(d, snap)
    assert summary(api.explore(f"{PROG}/fischer.pccl", resume=d, **opts)) == full
    # resumed from one directory, writing into another: whole there at first
    other = str(tmp_path / "other")
    r = api.explore(f"{PROG}/fischer.pccl", resume=snap, checkpoint=other, checkpoint_interval=0,
                    progress=_Interrupt(3), progress_interval=1e-9, **opts)
    assert r.status == "interrupted"
    oman = json.load(open(os.path.join(other, C.MANIFEST)))
    first = oman["segments"]["fps"]["parts"][0]
    assert first["start"] == 0 and first["gen"] == sorted(
        e for e in os.listdir(other) if e.startswith("gen-"))[0]
    assert summary(api.explore(f"{PROG}/fischer.pccl", resume=other, **opts)) == full
    # an older generation's part, damaged
    old = os.path.join(snap, parts[1]["gen"], parts[1]["file"])
    data = bytearray(open(old, "rb").read())
    data[-3] ^= 0xFF
    open(old, "wb").write(bytes(data))
    with pytest.raises(CheckpointFileError, match=f"the checkpoint is corrupt \\(.*../{parts[1]['gen']}/"
                       f"{parts[1]['file']} does not match its digest"):
        api.explore(f"{PROG}/fischer.pccl", resume=snap, **opts)


def test_a_failing_write_leaves_the_search_going_and_the_previous_checkpoint(tmp_path,
                                                                            monkeypatch):
    program, opts = f"{PROG}/fischer.pccl", dict(overrides={"k": "1"}, depth=60)
    full = summary(api.explore(program, **opts))
    d = str(tmp_path / "ck")
    api.explore(program, checkpoint=d, progress=_Interrupt(40), progress_interval=1e-9, **opts)
    before = json.load(open(os.path.join(d, C.MANIFEST)))
    real_save = C.np.save

    def full_disk(*a, **k):
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(C.np, "save", full_disk)
    r = api.explore(program, resume=d, checkpoint_interval=0, **opts)
    monkeypatch.setattr(C.np, "save", real_save)
    assert summary(r) == full                       # the search went on
    assert f"checkpoint not written to {d}: No space left on device; the previous one " \
           f"stays" in r.notes
    assert json.load(open(os.path.join(d, C.MANIFEST))) == before
    assert summary(api.explore(program, resume=d, **opts)) == full


def test_a_new_search_into_a_checkpoint_directory_keeps_the_old_one_until_replaced(tmp_path):
    d = _checkpoint_of(tmp_path)
    before = json.load(open(os.path.join(d, C.MANIFEST)))
    r = api.explore(f"{PROG}/fischer.pccl", checkpoint=d, progress=_Interrupt(3),
                    progress_interval=1e-9, overrides={"k": "1"})
    after = json.load(open(os.path.join(d, C.MANIFEST)))
    assert r.status == "interrupted"
    assert int(after["generation"][4:]) > int(before["generation"][4:])
    assert os.listdir(d) == [C.MANIFEST, after["generation"]] or \
        sorted(os.listdir(d)) == sorted([C.MANIFEST, after["generation"]])


class _Ran:
    """A command's exit status and output, as ``subprocess.run`` gives them."""

    def __init__(self, res):
        self.returncode, self.stdout, self.stderr = res.exit_code, res.stdout, res.stderr


def _cli_here(*args):
    """``pccl ARGS`` in this process (conftest.cli, from the repository root):
    for the refusals, which exit 2 before any search, and for the uninterrupted
    and resumed runs the signalled processes are compared with, a process of
    their own (about 0.5 CPU-s to start) would test nothing more (the signals
    go to processes of their own: conftest.interrupted, subprocess.Popen)."""
    return _Ran(cli(*args, cwd=ROOT))


def _checkpoint_of(tmp_path, *args):
    d = str(tmp_path / "ck")
    r = api.explore(f"{PROG}/fischer.pccl", checkpoint=d, progress=_Interrupt(5),
                    progress_interval=1e-9, overrides={"k": "1"})
    assert r.status == "interrupted"
    return d


def test_resume_with_other_options_or_program_exits_2(tmp_path):
    d = _checkpoint_of(tmp_path)
    p = _cli_here("explore", "programs/fischer.pccl", "--set", "k=2", "--resume", d)
    assert p.returncode == 2 and "Traceback" not in p.stderr
    assert f"--resume: error: {d}: the checkpoint was written with --set k=1, this run " \
           f"has --set k=2" in p.stderr
    p = _cli_here("explore", "programs/fischer.pccl", "--set", "k=1", "--depth", "9", "--resume", d)
    assert p.returncode == 2 and "with no --depth, this run has --depth 9" in p.stderr
    p = _cli_here("explore", "programs/race.pccl", "-w", "programs/race.toml", "--resume", d)
    assert p.returncode == 2 and "the checkpoint was written for a different program" in p.stderr
    p = _cli_here("explore", "programs/fischer.pccl", "--set", "k=1", "--reduce", "none",
                  "--resume", d)
    assert p.returncode == 2 and "reductions merge+symmetry+por+dead, this run has " \
                                 "reductions none" in p.stderr


@pytest.mark.parametrize("damage", ["manifest", "truncate", "flip", "missing", "format",
                                    "version", "empty-dir", "no-dir"])
def test_corrupt_checkpoint_exits_2_with_a_message(tmp_path, damage):
    d = _checkpoint_of(tmp_path)
    man = json.load(open(os.path.join(d, C.MANIFEST)))
    gen = os.path.join(d, man["generation"])
    if damage == "manifest":
        open(os.path.join(d, C.MANIFEST), "w").write("{not json")
    elif damage == "truncate":
        p = os.path.join(gen, "state.json")
        data = open(p, "rb").read()
        open(p, "wb").write(data[:len(data) // 2])
    elif damage == "flip":
        p = os.path.join(gen, "fps.0.npy")        # the first part (rows from 0)
        data = bytearray(open(p, "rb").read())
        data[-3] ^= 0xFF
        open(p, "wb").write(bytes(data))
    elif damage == "missing":
        os.unlink(os.path.join(gen, "parents.0.npy"))
    elif damage == "format":
        man["format"] = 99
        json.dump(man, open(os.path.join(d, C.MANIFEST), "w"))
    elif damage == "version":
        man["pccl"] = "0.0.1"
        json.dump(man, open(os.path.join(d, C.MANIFEST), "w"))
    elif damage == "empty-dir":
        d = str(tmp_path / "empty")
        os.makedirs(d)
    elif damage == "no-dir":
        d = str(tmp_path / "nowhere")
    p = _cli_here("explore", "programs/fischer.pccl", "--set", "k=1", "--resume", d)
    assert p.returncode == 2, p.stderr
    assert "Traceback" not in p.stderr and p.stderr.startswith(f"--resume: error: {d}: ")
    want = {"manifest": "corrupt", "truncate": "corrupt", "flip": "does not match its digest",
            "missing": "corrupt", "format": "format 99",
            "version": "the checkpoint was written by pccl 0.0.1, this is pccl",
            "empty-dir": "no checkpoint here",
            "no-dir": "no such directory"}[damage]
    assert want in p.stderr


@pytest.mark.parametrize("fastest", [False, True], ids=["bfs", "fastest"])
def test_coverage_interrupted_and_resumed_counts_as_uninterrupted(tmp_path, fastest):
    """--coverage tallies every expansion: a checkpoint holds the tallies of
    its mark (a level's or bucket's start), so the expansions the resumed
    search repeats are not counted twice, nor the counterexample's replay."""
    program, opts = f"{PROG}/race_nonatomic.pccl", dict(world=f"{PROG}/race.toml",
                                                         blackbox="nondet", find_all=True,
                                                         coverage=True, fastest=fastest,
                                                         max_states=700)
    full = api.explore(program, **opts)
    calls = _calls(program, opts)
    for cuts in ([2, calls // 2, 3],):
        r, resumed = interrupted_run(program, opts, str(tmp_path / f"ck{len(cuts)}"), cuts)
        assert resumed == len(cuts)
        assert summary(r) == summary(full)
        assert r.coverage.as_dict() == full.coverage.as_dict()
    assert full.coverage.expanded > 100 and full.bound_labels


def test_checkpoint_options_checked():
    p = _cli_here("explore", "programs/fischer.pccl", "--checkpoint-interval", "soon")
    assert p.returncode == 2 and "--checkpoint-interval" in p.stderr
    p = _cli_here("explore", "programs/fischer.pccl", "--checkpoint", "/dev/null/ck")
    assert p.returncode == 2 and "Traceback" not in p.stderr
    assert p.stderr.startswith("--checkpoint: error: cannot write checkpoints to /dev/null/ck")


def test_interval_spellings():
    assert [C.parse_interval(x) for x in ("90s", "10m", "1h", "0", "2.5", "30M")] == \
        [90, 600, 3600, 0, 2.5, 1800]
    for bad in ("", "-1", "1d", "ten"):
        with pytest.raises(ValueError):
            C.parse_interval(bad)


def test_sigterm_writes_a_checkpoint_and_says_how_to_resume(tmp_path):
    d = str(tmp_path / "ck")
    # the Python engine: the native one ends this search before its first
    # progress line (its checkpoints: the native tests below)
    args = ["explore", "programs/fischer.pccl", "--set", "k=2", "--engine", "python",
            "--reduce", "merge,symmetry,por", "--progress",
            "--progress-interval", "0.2", "--format", "json"]
    # signal once the search is under way (a progress line with its frontier)
    rc, out, err = interrupted([*args, "--checkpoint", d], "SIGTERM", cwd=ROOT, ready="frontier")
    if rc == 0:            # the machine was fast: nothing to resume
        pytest.skip("the search ended before the signal")
    assert rc == 143, err
    assert json.loads(out)["status"] == "interrupted"
    assert f"pccl: checkpoint written to {d}; resume with: pccl explore programs/fischer.pccl " \
           f"--set k=2 --engine python --reduce merge,symmetry,por --progress --progress-interval 0.2 " \
           f"--format json " \
           f"--resume {d}" in err
    p = _cli_here(*args, "--resume", d)
    q = _cli_here(*args)
    a, b = json.loads(p.stdout), json.loads(q.stdout)
    for k in ("status", "message", "violations", "bounds", "checked"):
        assert a[k] == b[k]
    for k in ("initial_states", "states", "transitions", "max_depth", "max_time"):
        assert a["statistics"][k] == b["statistics"][k]
    assert any(n.startswith("resumed from") for n in a["notes"])


@pytest.mark.slow
def test_sigkill_at_random_times_then_resume(tmp_path):
    """The issue's test: a search killed with SIGKILL (no chance to write
    anything) at random times, resumed each time from the last periodic
    checkpoint, ends with the uninterrupted result."""
    d = str(tmp_path / "ck")
    # the Python engine: the native one ends this search within the first
    # kill's delay (native kills: test_native_sigkill_three_times_then_resume)
    # (merge only: the default reductions end it within the first delay)
    args = ["explore", "programs/fischer.pccl", "--set", "k=2", "--no-progress",
            "--format", "json", "--checkpoint-interval", "0.3", "--engine", "python",
            "--reduce", "merge"]
    full = json.loads(_cli_here(*args).stdout)
    rng = random.Random(7)
    kills = 0
    for _ in range(8):
        extra = ["--resume", d] if os.path.exists(os.path.join(d, C.MANIFEST)) else \
            ["--checkpoint", d]
        proc = subprocess.Popen([sys.executable, "-m", "pccl.cli", *args, *extra], cwd=ROOT,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        time.sleep(rng.uniform(1.0, 2.5))
        if proc.poll() is not None:
            break
        proc.send_signal(signal.SIGKILL)
        proc.communicate()
        kills += 1
        if kills == 3:
            break
    p = _cli_here(*args, "--resume", d) if os.path.exists(os.path.join(d, C.MANIFEST)) \
        else _cli_here(*args)
    a = json.loads(p.stdout)
    for k in ("status", "message", "violations", "bounds", "checked"):
        assert a[k] == full[k]
    for k in ("initial_states", "states", "transitions", "max_depth", "max_time"):
        assert a["statistics"][k] == full["statistics"][k]
    assert kills >= 1


# ---------------------------------------------------------------------------
# Several workers (--workers N) and Ray (--ray): the partitions at a level
# boundary, the coordinator's manifest last; N workers resume with M
# ---------------------------------------------------------------------------

#: the cases the parallel search runs (--exact is one process's), kept small
PAR_CASES = [
    ("fischer-k1-depth", f"{PROG}/fischer.pccl", dict(overrides={"k": "1"}, depth=60)),
    ("fischer-max-states", f"{PROG}/fischer.pccl",
     dict(overrides={"k": "1"}, max_states=6_000)),
    *[c for c in CASES if c[0] in ("race-nondet-all", "tl-spin", "rdv-stall")],
]


def par_summary(r) -> dict:
    """:func:`summary`, without what says which backend ran (where the Ray
    actors were, "the transitions are taken in 3 worker processes")."""
    s = summary(r)
    s["notes"] = [n for n in s["notes"] if not n.startswith("Ray:")]
    s["checked"]["notes"] = [n for n in s["checked"]["notes"] if not n.startswith("Ray:")]
    ev = s["checked"].get("events")
    if ev and ev.get("reason"):
        ev["reason"] = "taken elsewhere"
    return s


@pytest.mark.parametrize("name,program,opts", PAR_CASES, ids=[c[0] for c in PAR_CASES])
def test_workers_interrupted_and_resumed_equal_uninterrupted(tmp_path, monkeypatch, name, program,
                                                            opts):
    """Interrupted at random level ends three times, resumed with 2, 3 and
    2 workers (a checkpoint of N workers resumes with M): the uninterrupted
    result of 2 workers; its figures and verdict are one process's.  (Worker
    processes throughout: a search with a checkpoint runs them, and two
    threads without one would compute the events never fired.)"""
    monkeypatch.setenv("PCCL_THREADS", "0")
    full = par_summary(api.explore(program, workers=2, **opts))
    one = summary(api.explore(program, **opts))
    for k in ("status", "verdict", "exit", "bounds", "violations", "witnesses", "holds",
              "timelock", "stall"):
        assert full[k] == one[k], k
    # the largest model time too (gathered from the workers; a checkpoint keeps it)
    assert full["stats"] == one["stats"]
    calls = full["stats"][3] + 1         # a level end each
    rng = random.Random(name)
    cuts = sorted(rng.sample(range(1, calls + 1), min(3, calls)))
    cuts = [c - (cuts[i - 1] if i else 0) for i, c in enumerate(cuts)]
    r, resumed = interrupted_run(program, opts, str(tmp_path / "ck"), cuts, workers=(2, 3))
    assert par_summary(r) == full
    assert resumed >= 1 and any(n.startswith("resumed from") for n in r.notes)


def _files_under(d: str, gen: str) -> set:
    root = os.path.join(d, gen)
    return {os.path.relpath(os.path.join(w, f), root) for w, _, fs in os.walk(root) for f in fs}


def test_workers_checkpoints_append_the_rows_added_since_the_last(tmp_path):
    """With workers each partition's table and recorded graph, and the
    coordinator's parent links, are appended as one process's arrays are:
    after the first checkpoint a worker writes only the rows added since the
    last one (parts that follow one another, each file holding its rows
    only); the generations named keep only the parts named; resumed with 2
    or 3 workers, the uninterrupted result; resumed with 3, the partitions
    (dealt out again) are written whole at first."""
    program, opts = f"{PROG}/fischer.pccl", dict(overrides={"k": "1"}, max_states=20_000,
                                                 reduce="merge,symmetry,por")
    full = par_summary(api.explore(program, workers=2, **opts))
    d = str(tmp_path / "ck")
    r = api.explore(program, checkpoint=d, checkpoint_interval=0, progress=_Interrupt(40),
                    progress_interval=1e-9, workers=2, **opts)
    assert r.status == "interrupted"
    man = json.load(open(os.path.join(d, C.MANIFEST)))
    seg = man["segments"]
    graph = ("fps", "parents", "g_src", "g_fps", "g_idx", "g_chg_idx", "g_chg", "g_col0")
    assert {"parents", *(f"w00{w}/{a}" for w in (0, 1) for a in graph)} <= set(seg)
    rows = 0
    for w in ("w000", "w001"):
        parts = seg[f"{w}/fps"]["parts"]
        assert len(parts) >= 30 and parts[0]["start"] == 0
        assert all(a["end"] == b["start"] for a, b in zip(parts, parts[1:]))
        for p in parts:         # 16 bytes a state of this generation and the header
            size = os.path.getsize(os.path.join(d, p["gen"], w, p["file"]))
            assert size == 16 * (p["end"] - p["start"]) + 128
        rows += parts[-1]["end"]
    assert rows == man["states"] == seg["parents"]["rows"]
    named = {p["gen"] for s in seg.values() for p in s["parts"]} | {man["generation"]}
    assert {e for e in os.listdir(d) if e.startswith("gen-")} == named
    for g in named - {man["generation"]}:       # of an older one, only the parts named
        assert _files_under(d, g) == {
            (k.split("/")[0] + "/" if "/" in k else "") + p["file"]
            for k, s in seg.items() for p in s["parts"] if p["gen"] == g}
    snap = str(tmp_path / "snap")
    shutil.copytree(d, snap)
    assert par_summary(api.explore(program, resume=d, workers=2, **opts)) == full
    # resumed with 3 workers: their partitions are new, written whole (from row 0) at first
    r = api.explore(program, resume=snap, checkpoint_interval=0, progress=_Interrupt(3),
                    progress_interval=1e-9, workers=3, **opts)
    assert r.status == "interrupted"
    man3 = json.load(open(os.path.join(snap, C.MANIFEST)))
    assert man3["partitions"] == 3
    for w in ("w000", "w001", "w002"):
        parts = man3["segments"][f"{w}/fps"]["parts"]
        assert parts[0]["start"] == 0 and parts[0]["gen"] > man["generation"], parts[0]
    assert man3["segments"]["parents"]["parts"][0]["gen"] <= man["generation"]   # appended on
    assert par_summary(api.explore(program, resume=snap, workers=2, **opts)) == full


def test_workers_every_level_checkpoint_resumes_with_any_number_of_workers(tmp_path, monkeypatch):
    """--checkpoint-interval 0 with 2 workers: the checkpoint of every level
    (a crash leaves any of them) resumes, with 2 or 3 workers, to the same
    result."""
    program, opts = f"{TPROG}/rdv_meet.pccl", dict(world=f"{TPROG}/rdv_wall.toml",
                                                    blackbox="straight", reduce="none")
    monkeypatch.setenv("PCCL_THREADS", "0")      # worker processes, as the checkpointed runs
    full = par_summary(api.explore(program, workers=2, **opts))
    d = str(tmp_path / "every")
    saved = []
    orig = C.Checkpointer.write_generation

    def spy(self, fill, state, extra=None):
        orig(self, fill, state, extra)
        snap = str(tmp_path / f"gen{len(saved)}")
        shutil.copytree(self.dir, snap)
        saved.append((state["depth"], snap))

    C.Checkpointer.write_generation = spy
    try:
        api.explore(program, checkpoint=d, checkpoint_interval=0, workers=2, **opts)
    finally:
        C.Checkpointer.write_generation = orig
    depths = [dep for dep, _ in saved]
    assert depths == list(range(len(depths))) and len(depths) >= 10
    for i, (_, snap) in enumerate(saved):
        man = json.load(open(os.path.join(snap, C.MANIFEST)))
        assert man["partitions"] == 2
        assert {f.split("/")[0] for f in man["files"]
                if "/" in f and not f.startswith("../")} == {"w000", "w001"}
        assert par_summary(api.explore(program, resume=snap, workers=2 + i % 2, **opts)) == full


_worker_save = C.worker_save


def _full_disk_in_worker_1(w, tmp, w_out, depth, *rest):
    """:func:`C.worker_save`, but worker 1's disk is full (module level: the
    function travels to the worker by name)."""
    if w.wid == 1:
        raise OSError(28, "No space left on device")
    return _worker_save(w, tmp, w_out, depth, *rest)


def test_workers_crash_while_writing_leaves_the_previous_checkpoint(tmp_path, monkeypatch):
    """The coordinator dies after the partitions, before the manifest; a
    worker's partition write fails (a full disk): the previous checkpoint
    stays and resumes to the uninterrupted result."""
    program, opts = f"{PROG}/fischer.pccl", dict(overrides={"k": "1"}, depth=40, workers=2)
    full = par_summary(api.explore(program, **opts))
    d = str(tmp_path / "ck")
    r = api.explore(program, checkpoint=d, progress=_Interrupt(20), progress_interval=1e-9,
                    **opts)
    assert r.status == "interrupted"
    before = json.load(open(os.path.join(d, C.MANIFEST)))
    assert before["depth"] == 20        # the level after the 20th

    def die(*a, **k):
        raise SystemExit("killed while writing")
    monkeypatch.setattr(C.os, "replace", die)
    with pytest.raises(SystemExit):
        api.explore(program, resume=d, checkpoint_interval=0, **opts)
    monkeypatch.undo()
    assert json.load(open(os.path.join(d, C.MANIFEST))) == before
    half = [e for e in os.listdir(d) if e not in (C.MANIFEST, before["generation"])]
    assert half and any(os.path.isdir(os.path.join(d, e, "w001")) for e in half)
    assert par_summary(api.explore(program, resume=d, **opts)) == full

    # worker 1 (a forked process: it writes its own partition) finds the disk full
    monkeypatch.setattr(C, "worker_save", _full_disk_in_worker_1)
    r = api.explore(program, resume=d, checkpoint_interval=0, **opts)
    monkeypatch.undo()
    assert par_summary(r) == full                   # the search went on
    assert f"checkpoint not written to {d}: No space left on device; the previous one " \
           f"stays" in r.notes
    assert json.load(open(os.path.join(d, C.MANIFEST))) == before
    assert par_summary(api.explore(program, resume=d, **opts)) == full


def test_one_process_and_workers_checkpoints_do_not_mix(tmp_path):
    """A checkpoint of one process resumes in one process, one of several
    workers with several (or Ray): otherwise exit 2 saying so; a damaged
    partition exits 2 too."""
    d1 = _checkpoint_of(tmp_path)
    with pytest.raises(CheckpointFileError) as e:
        api.explore(f"{PROG}/fischer.pccl", overrides={"k": "1"}, workers=2, resume=d1)
    assert f"{d1}: the checkpoint was written by one process (workers=1); resume it with " \
           f"workers=1 without ray" in str(e.value)                # the API's spelling
    d2 = str(tmp_path / "ck2")
    r = api.explore(f"{PROG}/fischer.pccl", checkpoint=d2, progress=_Interrupt(5),
                    progress_interval=1e-9, overrides={"k": "1"}, workers=3)
    assert r.status == "interrupted"
    p = _cli_here("explore", "programs/fischer.pccl", "--set", "k=1", "--resume", d2)
    assert p.returncode == 2 and "Traceback" not in p.stderr, p.stderr
    assert f"--resume: error: {d2}: the checkpoint was written by 3 workers; resume it with " \
           f"--workers N (N of 2 or more, not necessarily 3) or --ray" in p.stderr
    man = json.load(open(os.path.join(d2, C.MANIFEST)))
    last = man["segments"]["w002/fps"]["parts"][-1]     # its fingerprints' newest rows
    part = os.path.join(d2, last["gen"], "w002", last["file"])
    data = bytearray(open(part, "rb").read())
    data[-3] ^= 0xFF
    open(part, "wb").write(bytes(data))
    p = _cli_here("explore", "programs/fischer.pccl", "--set", "k=1", "--workers", "2",
                  "--resume", d2)
    assert p.returncode == 2 and "Traceback" not in p.stderr, p.stderr
    assert p.stderr.startswith(f"--resume: error: {d2}: the checkpoint is corrupt (")
    assert f"w002/{last['file']} does not match its digest" in p.stderr
    with pytest.raises(CheckpointFileError, match=r"with overrides=\{'k': '1'\}, this run has overrides=\{'k': '2'\}"):
        api.explore(f"{PROG}/fischer.pccl", overrides={"k": "2"}, workers=2, resume=d2)


#: (the reductions before dead: under dead the search ends before a signal can land in it)
_FISCHER_K1 = ["explore", "programs/fischer.pccl", "--set", "k=1", "--format", "json",
               "--reduce", "merge,symmetry,por"]


def _json_summary(text: str) -> dict:
    a = json.loads(text)
    return {"status": a["status"], "message": a["message"], "violations": a["violations"],
            "bounds": a["bounds"],
            "stats": [a["statistics"][k] for k in ("initial_states", "states", "transitions",
                                                   "max_depth")]}


@pytest.mark.slow
def test_workers_sigterm_and_sigkill_at_random_points_then_resume(tmp_path):
    """``pccl explore --workers 2 --checkpoint DIR`` sent SIGTERM (it writes
    the checkpoint and prints the resume command) and then SIGKILL twice
    (the periodic checkpoints, and partitions half written) at random points
    of the search, each time resumed: the uninterrupted result."""
    d = str(tmp_path / "ck")
    args = [*_FISCHER_K1, "--workers", "2", "--progress", "--progress-interval", "0.1",
            "--checkpoint-interval", "0.2"]
    full = _json_summary(_cli_here(*_FISCHER_K1, "--workers", "2", "--no-progress").stdout)
    rng = random.Random(25)
    rc, out, err = interrupted([*args, "--checkpoint", d], "SIGTERM", cwd=ROOT,
                               ready="frontier", after=rng.uniform(0, 1))
    assert rc in (0, 143), err
    if rc == 143:
        assert json.loads(out)["status"] == "interrupted"
        assert f"pccl: checkpoint written to {d}; resume with: pccl explore " \
               f"programs/fischer.pccl --set k=1 --format json --reduce merge,symmetry,por " \
               f"--workers 2" in err and \
               err.rstrip().endswith(f"--resume {d}")
        for _ in range(2):
            rc, out, err = interrupted([*args, "--resume", d], "SIGKILL", cwd=ROOT,
                                       ready="resumed from", after=rng.uniform(0.3, 1.5))
            assert rc in (0, -9), err
            if rc == 0:
                break
        p = _cli_here(*args, "--resume", d)
        assert p.returncode == 0, p.stderr
        out = p.stdout
    assert _json_summary(out) == full


# -- Ray ----------------------------------------------------------------------

@pytest.fixture(scope="module")
def local_ray():
    """A Ray instance on this machine for the module's tests (as in test_parallel)."""
    import logging
    ray = pytest.importorskip("ray")
    if ray.is_initialized():
        ray.shutdown()
    ray.init(num_cpus=2, include_dashboard=False, logging_level=logging.WARNING,
             log_to_driver=False)
    yield ray
    ray.shutdown()


def _cut_at(monkeypatch, k: int) -> None:
    """Interrupt the parallel search at its ``k``-th level end (in the
    coordinator: a progress callback would travel to the actors with the model)."""
    from pccl.search import parallel as P
    orig, calls = P.ParallelExplorer._report, [0]

    def report(self, *a):
        calls[0] += 1
        if calls[0] == k:
            raise KeyboardInterrupt
        return orig(self, *a)
    monkeypatch.setattr(P.ParallelExplorer, "_report", report)


@pytest.mark.slow
@pytest.mark.parametrize("fastest", [False, True], ids=["bfs", "fastest"])
def test_ray_interrupted_and_resumed_equals_uninterrupted(tmp_path, monkeypatch, local_ray,
                                                          fastest):
    """Ray actors send their partitions to the coordinator, which writes
    them (actors on other machines do not see DIR) and reads them back on
    resume: interrupted twice, resumed with Ray, then with forked workers
    (3 instead of 2), the uninterrupted result; and a checkpoint of forked
    workers resumes with Ray.  Breadth first and --fastest (interrupted
    between buckets)."""
    program, opts = f"{PROG}/race_nonatomic.pccl", dict(world=f"{PROG}/race.toml",
                                                         blackbox="nondet", find_all=True,
                                                         fastest=fastest)
    monkeypatch.setenv("PCCL_THREADS", "0")      # worker processes, as the checkpointed runs
    full = par_summary(api.explore(program, workers=2, **opts))
    d = str(tmp_path / "ck")
    for k, resume in ((7, False), (20, True)):
        _cut_at(monkeypatch, k)
        r = api.explore(program, workers=2, ray="auto", checkpoint=d,
                        **(dict(resume=d) if resume else {}), **opts)
        monkeypatch.undo()
        assert r.status == "interrupted"
    assert par_summary(api.explore(program, workers=3, resume=d, **opts)) == full
    assert par_summary(api.explore(program, workers=2, ray="auto", resume=d, **opts)) == full
    d2 = str(tmp_path / "ck2")
    _cut_at(monkeypatch, 12)
    r = api.explore(program, workers=2, checkpoint=d2, **opts)
    monkeypatch.undo()
    assert r.status == "interrupted"
    assert par_summary(api.explore(program, workers=3, ray="auto", resume=d2, **opts)) == full


# ---------------------------------------------------------------------------
# --fastest: the buckets are the frontier
# ---------------------------------------------------------------------------

FASTEST_CASES = [
    ("fischer-k1", f"{PROG}/fischer.pccl", dict(overrides={"k": "1"}, depth=20)),
    ("race-nondet-none", f"{PROG}/race_nonatomic.pccl",
     dict(world=f"{PROG}/race.toml", blackbox="nondet", reduce="none")),
    ("race-nondet-all", f"{PROG}/race_nonatomic.pccl",
     dict(world=f"{PROG}/race.toml", blackbox="nondet", find_all=True, max_states=900)),
    ("tl-spin", f"{TPROG}/tl_spin.pccl", dict()),
]


@pytest.mark.parametrize("name,program,opts", FASTEST_CASES, ids=[c[0] for c in FASTEST_CASES])
def test_fastest_interrupted_mid_bucket_and_resumed_equals_uninterrupted(tmp_path, monkeypatch,
                                                                        name, program, opts):
    """Interrupted in the middle of a bucket (a state's expansion) at random
    points, three times, and resumed: the uninterrupted --fastest result
    (the checkpoint is the bucket's start: the states queued since are
    dropped, the bucket is expanded again)."""
    from pccl.search import fastest as F
    opts = dict(opts, fastest=True)
    full = summary(api.explore(program, **opts))
    orig, count = F._Buckets._expand, [0]

    def counting(self, *a):
        count[0] += 1
        if count[0] == cut[0]:
            raise KeyboardInterrupt
        return orig(self, *a)
    monkeypatch.setattr(F._Buckets, "_expand", counting)
    cut = [0]
    api.explore(program, **opts)
    expansions = count[0]
    rng = random.Random(name)

    def rounds():
        for i in range(4):
            count[0], cut[0] = 0, rng.randint(1, max(1, expansions // 3)) if i < 3 else 0
            yield {}
    r, resumed = resumed_until_done(program, opts, str(tmp_path / "ck"), rounds())
    assert summary(r) == full
    assert resumed >= 1 and any(n.startswith("resumed from") for n in r.notes)


def test_fastest_and_breadth_first_checkpoints_do_not_mix(tmp_path):
    d = _checkpoint_of(tmp_path)
    p = _cli_here("explore", "programs/fischer.pccl", "--set", "k=1", "--fastest", "--resume", d)
    assert p.returncode == 2 and "Traceback" not in p.stderr, p.stderr
    assert "the checkpoint was written with no --fastest, this run has --fastest" in p.stderr


# ---------------------------------------------------------------------------
# The native engine (pccl/model/native.py): its vectors saved as they are; the
# identity names the engine and the generated source; a checkpoint resumes on
# the engine that wrote it
# ---------------------------------------------------------------------------

#: the cases of CASES the native engine serves (violations, bounds, the graph)
NATIVE_CASES = [c for c in CASES if c[0] in ("fischer-k1", "fischer-k2-depth",
                                             "fischer-none-depth", "fischer-max-states",
                                             "tl-spin", "race-nondet", "race-nondet-all",
                                             "list-seen")]


@pytest.mark.parametrize("name,program,opts", NATIVE_CASES, ids=[c[0] for c in NATIVE_CASES])
def test_native_interrupted_and_resumed_equals_uninterrupted(tmp_path, name, program, opts):
    """Interrupted at random points and resumed on the native engine: the
    uninterrupted native result, which is the Python engine's too."""
    full = api.explore(program, engine="native", **opts)
    assert full.model.engine_used == "native"
    assert summary(api.explore(program, engine="python", **opts)) == summary(full)
    calls = _calls(program, opts)
    rng = random.Random("native-" + name)
    cuts = sorted(rng.sample(range(1, calls + 1), min(3, calls)))
    cuts = [c - (cuts[i - 1] if i else 0) for i, c in enumerate(cuts)]
    r, resumed = interrupted_run(program, opts, str(tmp_path / "ck"), cuts)
    assert r.model.engine_used == "native"           # --checkpoint no longer sends it to Python
    assert summary(r) == summary(full)
    assert resumed >= 1 and any(n.startswith("resumed from") for n in r.notes)


def _native_checkpoint(tmp_path, engine="auto"):
    d = str(tmp_path / f"ck-{engine}")
    r = api.explore(f"{PROG}/fischer.pccl", checkpoint=d, progress=_Interrupt(5),
                    progress_interval=1e-9, overrides={"k": "1"}, engine=engine)
    assert r.status == "interrupted"
    assert r.model.engine_used == ("python" if engine == "python" else "native")
    return d


def test_a_checkpoint_resumes_on_the_engine_that_wrote_it(tmp_path):
    """A native checkpoint resumed on the Python engine (asked for, or no C
    compiler) and a Python one on the native engine: exit 2 saying why; an
    engine left to choose (auto) follows the checkpoint."""
    full = summary(api.explore(f"{PROG}/fischer.pccl", overrides={"k": "1"}))
    dn = _native_checkpoint(tmp_path)
    man = json.load(open(os.path.join(dn, C.MANIFEST)))
    assert man["identity"]["engine"] == "native" and len(man["identity"]["native"]) == 16
    p = _cli_here("explore", "programs/fischer.pccl", "--set", "k=1", "--engine", "python",
                  "--resume", dn)
    assert p.returncode == 2 and "Traceback" not in p.stderr, p.stderr
    assert f"--resume: error: {dn}: the checkpoint was written by the native engine, this run " \
           f"uses the Python engine (--engine python); a checkpoint's states and fingerprints " \
           f"are its engine's: resume it where the native engine can run this search" in p.stderr
    # no C compiler on the PATH (python is started by its full path)
    env = {k: v for k, v in os.environ.items() if k != "CC"}
    env["PATH"] = str(tmp_path)
    p = subprocess.run([sys.executable, "-m", "pccl.cli", "explore", "programs/fischer.pccl",
                        "--set", "k=1", "--resume", dn], capture_output=True, text=True,
                       cwd=ROOT, timeout=120, env=env)
    assert p.returncode == 2 and "Traceback" not in p.stderr, p.stderr
    assert "the checkpoint was written by the native engine, this run uses the Python engine " \
           "(no C compiler (cc) found)" in p.stderr
    # a Python checkpoint: auto resumes it on Python (and says why), native refuses it
    dp = _native_checkpoint(tmp_path, "python")
    r = api.explore(f"{PROG}/fischer.pccl", overrides={"k": "1"}, resume=dp)
    assert r.model.engine_used == "python"
    assert r.model.engine_reason == "resume: the checkpoint was written by the Python engine"
    assert summary(r) == full
    p = _cli_here("explore", "programs/fischer.pccl", "--set", "k=1", "--engine", "native",
                  "--resume", dp)
    assert p.returncode == 2 and "Traceback" not in p.stderr, p.stderr
    assert "the checkpoint was written by the Python engine, this run uses the native engine; " \
           "a checkpoint's states and fingerprints are its engine's: resume it with --engine " \
           "python or --engine auto" in p.stderr
    # the native engine resumes its own
    assert summary(api.explore(f"{PROG}/fischer.pccl", overrides={"k": "1"}, resume=dn)) == full


def test_a_native_checkpoint_of_another_generated_source_or_without_engine(tmp_path):
    """The generated source's hash is checked; a manifest naming no engine
    (written before the native engine saved checkpoints) is the Python
    engine's."""
    dn = _native_checkpoint(tmp_path)
    path = os.path.join(dn, C.MANIFEST)
    man = json.load(open(path))
    man["identity"]["native"] = "0123456789abcdef"
    json.dump(man, open(path, "w"))
    with pytest.raises(CheckpointFileError, match="written by the native engine from another "
                       "generated source \\(hash 0123456789abcdef; this run: [0-9a-f]{16}\\)"):
        api.explore(f"{PROG}/fischer.pccl", overrides={"k": "1"}, resume=dn)
    dp = _native_checkpoint(tmp_path, "python")
    path = os.path.join(dp, C.MANIFEST)
    man = json.load(open(path))
    del man["identity"]["engine"]
    json.dump(man, open(path, "w"))
    r = api.explore(f"{PROG}/fischer.pccl", overrides={"k": "1"}, resume=dp)
    assert r.model.engine_used == "python" and r.status == "exhaustive"
    with pytest.raises(CheckpointFileError, match="written by the Python engine, this run uses "
                       "the native engine"):
        api.explore(f"{PROG}/fischer.pccl", overrides={"k": "1"}, resume=dp, engine="native")


#: native runs of a few seconds: a violation (every one: the search goes on to
#: the end) and an exhaustive one.  (Two agents at k=6 took 0.5 s once the
#: table's probes moved to C: a resumed run ended before its first progress
#: line; three agents take 2.5-5 s.)
_NATIVE_KILLED = [
    ("violation", "violation", ["programs/fischer.pccl", "--agents", "3", "--set", "k=1",
                                "--set", "d=2", "--invariant", "count(inCs)<=1", "--all",
                                "--reduce", "merge,symmetry,por"]),
    ("exhaustive", "exhaustive", ["programs/fischer.pccl", "--agents", "3", "--set", "k=1",
                                  "--set", "d=2", "--reduce", "merge,symmetry,por"]),
    # a program that moves: the checkpoint keeps its interned values (positions,
    # lists), which the resumed process's states name by id
    ("robots", "bounded", ["programs/race_robust.pccl", "--world", "programs/race.toml",
                           "--agents", "4", "--max-states", "1500000", "--no-timelock",
                           "--no-stall"]),
]


@pytest.mark.slow
@pytest.mark.parametrize("name,status,extra", _NATIVE_KILLED, ids=[c[0] for c in _NATIVE_KILLED])
def test_native_sigkill_at_random_points_then_resume(tmp_path, name, status, extra):
    """The issue's test on the native engine: killed with SIGKILL three times
    at random points of the search (once it is under way), each time resumed
    from the last periodic checkpoint: the uninterrupted result."""
    d = str(tmp_path / "ck")
    base = ["explore", *extra, "--format", "json"]
    args = [*base, "--progress", "--progress-interval", "0.1", "--checkpoint-interval", "0.2"]
    q = _cli_here(*base, "--no-progress")
    full = json.loads(q.stdout)
    assert full["status"] == status, q.stderr
    rng = random.Random(name)
    kills, seconds = 0, full["statistics"]["seconds"]
    for _ in range(8):
        resume = os.path.exists(os.path.join(d, C.MANIFEST))
        # killed once the first checkpoint (every 0.2 s) is likely written
        rc, out, err = interrupted([*args, *(["--resume", d] if resume else ["--checkpoint", d])],
                                   "SIGKILL", cwd=ROOT, ready="frontier",
                                   after=0.3 + rng.uniform(0, seconds / 3))
        if rc != -9:
            break
        kills += os.path.exists(os.path.join(d, C.MANIFEST))
        if kills == 3:
            break
    assert kills >= 1
    p = _cli_here(*args, "--resume", d)
    assert p.returncode in (0, 1) and "Traceback" not in p.stderr, p.stderr
    a = json.loads(p.stdout)
    assert any(n.startswith("resumed from") for n in a["notes"])
    # the native engine's checkpoint (a Python search refuses it)
    assert json.load(open(os.path.join(d, C.MANIFEST)))["identity"]["engine"] == "native"
    for k in ("status", "message", "violations", "bounds", "checked"):
        assert a[k] == full[k], k
    for k in ("initial_states", "states", "transitions", "max_depth", "max_time"):
        assert a["statistics"][k] == full["statistics"][k], k


def test_native_overflow_with_a_checkpoint_writes_and_resumes_python_ones(tmp_path):
    """A native search that meets an int beyond 64 bits starts again on the
    Python engine; with a checkpoint directory that search writes Python
    checkpoints there (replacing the native ones), which resume on Python."""
    text = ("Agent::Grow\n\nallwrite:\n  int x = 1;\n\nallread:\n\nloc:\n\nInit:\n\n"
            "Double():\n  pre(x > 0);\n  eff:\n    x = x * 1000000;\n")
    opts = dict(source=True, max_states=200, reduce="none", timelock=False, stall=False)
    py = summary(api.explore(text, engine="python", **opts))
    d = str(tmp_path / "ck")
    r = api.explore(text, checkpoint=d, checkpoint_interval=0, **opts)
    assert r.model.engine_used == "python" and "64 bits" in r.model.engine_reason
    assert summary(r) == py
    man = json.load(open(os.path.join(d, C.MANIFEST)))
    assert man["identity"]["engine"] == "python" and man["depth"] >= 1
    r = api.explore(text, resume=d, **opts)
    assert r.model.engine_used == "python" and summary(r) == py
    assert any(n.startswith("resumed from") for n in r.notes)


# -- --fastest with several workers: the buckets are the frontier --------------

FAST_PAR_CASES = [c for c in PAR_CASES if c[0] in ("fischer-k1-depth", "race-nondet-all",
                                                   "tl-spin")]


@pytest.mark.parametrize("name,program,opts", FAST_PAR_CASES, ids=[c[0] for c in FAST_PAR_CASES])
def test_fastest_workers_interrupted_and_resumed_equal_uninterrupted(tmp_path, name, program,
                                                                      opts):
    """--fastest with workers, interrupted between buckets at random points
    three times and resumed with 2, 3 and 2 workers: the uninterrupted
    result (which is one process's --fastest result)."""
    opts = dict(opts, fastest=True)
    full = par_summary(api.explore(program, workers=2, **opts))
    one = summary(api.explore(program, **opts))
    for k in ("status", "verdict", "exit", "bounds", "violations", "witnesses", "timelock",
              "stall"):
        assert full[k] == one[k], k
    counter = _Interrupt(0)
    api.explore(program, workers=2, progress=counter, progress_interval=1e-9, **opts)
    rng = random.Random("fastest-" + name)
    cuts = sorted(rng.sample(range(1, counter.calls + 1), min(3, counter.calls)))
    # each run interrupted at its share of the cuts, with 2 and 3 workers in turn
    steps = [k - (cuts[i - 1] if i else 0) for i, k in enumerate(cuts)]
    r, resumed = interrupted_run(program, opts, str(tmp_path / "ck"), steps, workers=(2, 3))
    assert par_summary(r) == full
    assert resumed >= 1 and any(n.startswith("resumed from") for n in r.notes)
