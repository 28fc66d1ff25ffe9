"""A checkpoint or a spill file from elsewhere is data (issue 42, hole 3):
reading one runs no code.  A forged checkpoint is refused with one message
(exit 2) — a pickle of an older pccl is never unpickled — or, when every
field is well-formed, resumes a search (pccl/search/checkpoint.py,
pccl/search/safedata.py, pccl/search/spill.py)."""

from __future__ import annotations

import json
import os
import pickle

import numpy as np
import pytest
import xxhash

from pccl import api
from pccl.search import checkpoint as C
from pccl.search import safedata
from pccl.search import spill as S
from conftest import cli

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
PROG = os.path.join(ROOT, "programs")


class _Plant:
    """Unpickled, creates the file ``path`` (what a hostile pickle does with
    ``os.system``, without a shell)."""

    def __init__(self, path: str):
        self.path = path

    def __reduce__(self):
        return (open, (self.path, "w"))


class _Ran:
    """A command's exit status and output, as ``subprocess.run`` gives them."""

    def __init__(self, res):
        self.returncode, self.stdout, self.stderr = res.exit_code, res.stdout, res.stderr


def _cli(*args):
    """``pccl ARGS`` in this process (conftest.cli, from the repository root):
    every command here is a refusal that exits 2 before any search, so a
    process of its own (about 0.5 CPU-s to start) would test nothing more; an
    unpickled payload would create its marker file here as well."""
    return _Ran(cli(*args, cwd=ROOT))


class _Interrupt:
    def __init__(self, k):
        self.k, self.calls = k, 0

    def __call__(self, p):
        self.calls += 1
        if self.calls == self.k:
            raise KeyboardInterrupt


def _checkpoint(tmp_path) -> tuple[str, dict, str]:
    d = str(tmp_path / "ck")
    r = api.explore(f"{PROG}/fischer.pccl", checkpoint=d, progress=_Interrupt(5),
                    progress_interval=1e-9, overrides={"k": "1"})
    assert r.status == "interrupted"
    man = json.load(open(os.path.join(d, C.MANIFEST)))
    return d, man, os.path.join(d, man["generation"])


def _put(d: str, man: dict, gen: str, name: str, blob: bytes) -> None:
    """Write ``blob`` as the generation's file ``name`` with its size and
    digest fixed in the manifest (a forger's work: they detect corruption,
    not tampering)."""
    open(os.path.join(gen, name), "wb").write(blob)
    man["files"][name] = {"bytes": len(blob), "xxh3": xxhash.xxh3_128_hexdigest(blob)}
    json.dump(man, open(os.path.join(d, C.MANIFEST), "w"))


def test_the_plant_works(tmp_path):
    """The payload of the tests below does create its file when unpickled."""
    marker = tmp_path / "pwned"
    pickle.loads(pickle.dumps(_Plant(str(marker)))).close()
    assert marker.exists()


@pytest.mark.slow
@pytest.mark.parametrize("how", ["old-format", "pkl-in-new-format"])
def test_a_pickled_checkpoint_is_never_unpickled(tmp_path, how):
    d, man, gen = _checkpoint(tmp_path)
    marker = tmp_path / "pwned"
    blob = pickle.dumps({"depth": 0, "x": _Plant(str(marker))})
    os.unlink(os.path.join(gen, C.STATE))
    del man["files"][C.STATE]
    if how == "old-format":
        man["format"] = 1
    _put(d, man, gen, "state.pkl", blob)
    p = _cli("explore", "programs/fischer.pccl", "--set", "k=1", "--resume", d)
    assert not marker.exists()
    assert p.returncode == 2, p.stderr
    assert "Traceback" not in p.stderr and p.stderr.count("\n") == 1
    assert "the checkpoint was written by an older pccl" in p.stderr
    assert "start the search again" in p.stderr


@pytest.mark.slow
def test_a_pickle_named_state_json_is_refused(tmp_path):
    d, man, gen = _checkpoint(tmp_path)
    marker = tmp_path / "pwned"
    _put(d, man, gen, C.STATE, pickle.dumps({"depth": 0, "x": _Plant(str(marker))}))
    p = _cli("explore", "programs/fischer.pccl", "--set", "k=1", "--resume", d)
    assert not marker.exists()
    assert p.returncode == 2 and "Traceback" not in p.stderr, p.stderr
    assert "the checkpoint is corrupt" in p.stderr


def _whole_state(d: str, man: dict, gen: str) -> dict:
    """The generation's state with its level (read from level.msgpack), and
    the level file dropped: the forged state.json below holds it all (as a
    checkpoint may: the reader takes a level from either, not both)."""
    files = {k: v for k, v in man["files"].items() if k in (C.STATE, C.LEVEL)}
    state, _ = C.read_part(gen, files)
    if C.LEVEL in man["files"]:
        os.unlink(os.path.join(gen, C.LEVEL))
        del man["files"][C.LEVEL]
    return state


def _forged(state: dict, field: str):
    s = dict(state)
    if field == "unknown-field":
        s["__reduce__"] = 1
    elif field == "unknown-tag":
        s["depth"] = {"pickle": "gASV"}
    elif field == "negative":
        s["transitions"] = -5
    elif field == "level-length":
        s["level"] = s["level"][:-1]
    elif field == "state-type":
        s["level"] = ["not a state"] * len(s["level"])
    elif field == "violation":
        s["found"] = [("not a violation", 0, 0)]
    elif field == "found-range":
        from pccl.model.properties import Violation
        s["found"] = [(Violation("assert", "a", "m"), s["n"] + 10, 0)]
    elif field == "numpy-object":
        return {**safedata.encode(s), "exact": {"n": ["|O", [1], "AAAAAAAAAAA="]}}
    elif field == "msgpack-map":
        import base64
        import msgpack
        enc = safedata.encode(s)
        enc["d"] = [kv for kv in enc["d"] if kv[0] != "level"] + [
            ["level", {"m": base64.b64encode(msgpack.packb([{"a": 1}])).decode()}]]
        return enc
    return safedata.encode(s)


@pytest.mark.slow
@pytest.mark.parametrize("field", ["unknown-field", "unknown-tag", "negative", "level-length",
                                   "state-type", "violation", "found-range", "numpy-object",
                                   "msgpack-map"])
def test_a_forged_state_is_refused_with_one_message(tmp_path, field):
    d, man, gen = _checkpoint(tmp_path)
    state = _whole_state(d, man, gen)
    _put(d, man, gen, C.STATE, json.dumps(_forged(state, field)).encode())
    p = _cli("explore", "programs/fischer.pccl", "--set", "k=1", "--resume", d)
    assert p.returncode == 2, p.stderr
    assert "Traceback" not in p.stderr and p.stderr.count("\n") == 1, p.stderr
    assert p.stderr.startswith(f"--resume: error: {d}: the checkpoint is corrupt")


@pytest.mark.slow
def test_a_well_formed_state_written_back_resumes(tmp_path):
    """The encoding round-trips a real checkpoint: read, written again with
    its digest fixed, it resumes to the uninterrupted result."""
    d, man, gen = _checkpoint(tmp_path)
    state = _whole_state(d, man, gen)
    C.check_state(state, "state")
    _put(d, man, gen, C.STATE, json.dumps(safedata.encode(C._marked_states(state))).encode())
    full = api.explore(f"{PROG}/fischer.pccl", overrides={"k": "1"})
    r = api.explore(f"{PROG}/fischer.pccl", overrides={"k": "1"}, resume=d)
    assert (r.status, r.stats.states, r.stats.transitions) == \
        (full.status, full.stats.states, full.stats.transitions)


@pytest.mark.slow
@pytest.mark.parametrize("damage", ["record-kind", "order", "digest"])
def test_a_forged_level_file_is_refused(tmp_path, damage):
    d, man, gen = _checkpoint(tmp_path)
    p = os.path.join(gen, C.LEVEL)
    data = bytearray(open(p, "rb").read())
    if damage == "record-kind":
        data[0:1] = b"P"
    elif damage == "order":         # a record claiming to start elsewhere
        blob = safedata.pack_segment(5, [(1, 2)])
        data = bytearray(b"M" + len(blob).to_bytes(8, "little") + blob) + data
    if damage != "digest":
        _put(d, man, gen, C.LEVEL, bytes(data))
    else:
        man["files"][C.LEVEL]["xxh3"] = "0" * 32
        json.dump(man, open(os.path.join(d, C.MANIFEST), "w"))
    p = _cli("explore", "programs/fischer.pccl", "--set", "k=1", "--resume", d)
    assert p.returncode == 2 and "Traceback" not in p.stderr, p.stderr
    assert "the checkpoint is corrupt" in p.stderr


def test_data_round_trip_of_every_type():
    from pccl.lang.ast import Span
    from pccl.model.properties import Violation
    v = {"t": (1, -2, 2 ** 70, 1.5, float("inf"), None, True, ..., b"\x00\xff", "é"),
         "l": [1, (2,)], "s": {(1, 2)}, "z": frozenset({3}), "d": {(1, 2): [3]},
         "a": np.arange(6, dtype=np.uint32).reshape(2, 3),
         "v": Violation("assert", "n", "m", 1, Span(1, 2, 3, 4)),
         "st": safedata.States([(1, ..., (2.5,)), b"abc"]),
         "big": safedata.States([(2 ** 70,)])}
    back = safedata.loads(safedata.dumps(v))
    a = back.pop("a")
    assert a.dtype == np.uint32 and a.tolist() == [[0, 1, 2], [3, 4, 5]]
    want = {k: x for k, x in v.items() if k != "a"}
    assert back == want
    assert back["t"][7] is Ellipsis and back["st"][0][1] is Ellipsis
    assert type(back["st"]) is list and type(back["l"]) is list
    with pytest.raises(TypeError):
        safedata.dumps({"f": lambda: 0})


@pytest.mark.parametrize("blob", [b"not json", b'{"x": 1}', b'{"l": [{"q": 1}]}',
                                  b'{"d": [[{"l": []}, 1]]}', b'{"b": "***"}',
                                  b"[" * 100_000 + b"]" * 100_000,
                                  b'{"m": "' + b"gA==" + b'"}'])
def test_malformed_data_is_a_data_error(blob):
    with pytest.raises(safedata.DataError):
        safedata.loads(blob)


def test_a_forged_spill_level_file_runs_no_code(tmp_path):
    """A level file replaced while the search runs (the spill directory is a
    path on disk): its segments are data, a pickle in it is refused."""
    marker = tmp_path / "pwned"
    d = S.SpillDir(str(tmp_path / "sp"))
    lf = S.LevelFile(d, "level")
    lf.write([(1, ..., 2.5), (2, None, -1.0)], 7)
    lf.write([b"ab", b"cd"], [3, 9])
    lf.write([(2 ** 70, ...)], 11)          # past 64 bits: the JSON record
    many = [(i, (i * 0.5, None)) for i in range(2 * S.LevelFile.CHUNK + 5)]
    lf.write(many, 12)                      # three records
    lf.f.flush()
    got = [(st, n) for sts, nums in lf.segments() for st, n in zip(sts, nums)]
    assert got == [((1, ..., 2.5), 7), ((2, None, -1.0), 8), (b"ab", 3), (b"cd", 9),
                   ((2 ** 70, ...), 11)] + [(st, 12 + i) for i, st in enumerate(many)]
    assert got[0][0][1] is Ellipsis
    for i, kind in enumerate((b"M", b"J", b"")):        # a record of each kind; no kind
        lf = S.LevelFile(d, f"level{i + 2}")
        lf.write([(1,)], 0)
        lf.f.close()
        blob = pickle.dumps((0, [_Plant(str(marker))]))
        with open(lf.path, "wb") as f:
            f.write(kind + len(blob).to_bytes(8, "little") + blob)
        lf.f = open(lf.path, "ab")
        with pytest.raises(S.SpillError, match="not a level file this search wrote"):
            list(lf.segments())
    assert not marker.exists()
    d.close()
