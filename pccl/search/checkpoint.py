"""Checkpoints of a one-process search, and resuming from them (``--checkpoint DIR``,
``--resume DIR``).

A checkpoint is taken at a breadth-first level boundary: the visited table
(fingerprints and parent links, numpy ``.npy`` files), the graph the
time-lock, stall and temporal checks record (numpy arrays), and a pickle of
the rest: the level about to be expanded (its states), the statistics, the
violations found so far, the bounds met, the labels of the transitions taken
(the never-fired events), the runaway detector and the model's lazily
interned tables (so that a resumed search numbers k cells, hence
fingerprints, exactly as an uninterrupted one).  An interrupt (Ctrl-C,
SIGTERM) in the middle of a level writes the checkpoint of that level's
start: the resumed search expands the level again, so its result is the
uninterrupted one.

Layout of ``DIR``::

    checkpoint.json          the manifest: format, pccl version, what the
                             search is (program hash, world hash, options),
                             the current generation and its files' sizes
                             and xxh3-128 digests
    gen-000007/              the current generation's files

A generation is written into ``DIR/tmp-*``, its files fsynced, renamed to
``gen-NNNNNN``, and only then the manifest is replaced (``os.replace`` of a
fsynced temporary file): a crash at any point leaves the previous manifest
naming the previous, complete generation.  Older generations are removed
after the new manifest is in place.
"""

from __future__ import annotations

import hashlib
import json
import os
import pickle
import re
import shutil
import tempfile
import time as _time
from typing import Any, Optional

import numpy as np
import xxhash

from pccl.lang.errors import PcclError

__all__ = ["FORMAT", "MANIFEST", "Checkpointer", "parse_interval", "search_identity",
           "DEFAULT_INTERVAL"]

#: The version of the checkpoint layout; a checkpoint of another format is refused.
FORMAT = 1
MANIFEST = "checkpoint.json"
#: Seconds between checkpoints by default (TLC's 30 minutes).
DEFAULT_INTERVAL = 1800.0



def parse_interval(text) -> float:
    """``--checkpoint-interval``: seconds, or a number with ``s``, ``m`` or ``h``
    (``90s``, ``10m``, ``1h``); 0 writes a checkpoint at every level."""
    m = re.fullmatch(r"\s*([0-9]+(?:\.[0-9]*)?)\s*([smh]?)\s*", str(text), re.I)
    if not m:
        raise ValueError(f"expected a duration such as 90s, 10m or 1h, got {text!r}")
    return float(m.group(1)) * {"": 1, "s": 1, "m": 60, "h": 3600}[m.group(2).lower()]


def _pccl_version() -> str:
    try:
        from importlib.metadata import version
        return version("pccl")
    except Exception:       # pragma: no cover - not installed
        return "unknown"


def _digest(data) -> str:
    return xxhash.xxh3_128_hexdigest(data)


def _array_digest(arr: np.ndarray) -> str:
    """The xxh3-128 of an array's bytes (C order), a slice at a time: no copy
    of a whole (possibly mapped) array."""
    h = xxhash.xxh3_128()
    flat = arr.reshape(-1) if arr.flags.c_contiguous else np.ascontiguousarray(arr).reshape(-1)
    step = max(1, (1 << 24) // max(1, flat.itemsize))
    for a in range(0, flat.size, step):
        h.update(np.ascontiguousarray(flat[a:a + step]).data.cast("B"))
    return h.hexdigest()


def _text_hash(text) -> str:
    if isinstance(text, str):
        text = text.encode()
    return hashlib.sha256(text).hexdigest()[:16]


def _jsonable(v):
    """An option value as plain JSON (dicts with string keys, lists)."""
    if isinstance(v, dict) or hasattr(v, "items"):
        return {str(k): _jsonable(x) for k, x in sorted(dict(v).items(), key=lambda kv: str(kv[0]))}
    if isinstance(v, (list, tuple, set, frozenset)):
        return [_jsonable(x) for x in v]
    if v is None or isinstance(v, (bool, int, float, str)):
        return v
    return getattr(v, "name", None) or repr(v)


def search_identity(model, options, names) -> dict:
    """What a checkpoint must match to be resumed: the program's source and
    the world file (hashes) and the options that define the search:
    ``names``, in the order a mismatch is reported (the caller's
    :data:`pccl.model.options.IDENTITY_OPTIONS`)."""
    prog = model.program
    world = options.world
    if world is None:
        world_hash = None
    elif isinstance(world, (str, os.PathLike)):
        try:
            with open(os.fspath(world), "rb") as f:
                world_hash = _text_hash(f.read())
        except OSError:
            world_hash = _text_hash(os.fspath(world))
    else:
        world_hash = _text_hash(repr(getattr(world, "source", None) or getattr(world, "path", "")))
    opts = {}
    for name in names:
        v = getattr(options, name, None)
        if name == "agents":
            v = model.N
        elif name == "blackbox":
            v = model.blackbox.name
        elif name == "reduce":
            red = getattr(model, "reduction", None)
            v = list(getattr(red, "on", ())) if red is not None else v
        opts[name] = _jsonable(v)
    return {"program": _text_hash(prog.source or repr(prog)), "program_file": prog.filename,
            "world": world_hash, "options": opts}


def describe_option(name: str, value) -> str:
    """An option's value as a text with the option as a placeholder, for a
    front end to spell (``{overrides=k=2}``: ``--set k=2`` on the command line)."""
    if name in ("deadlock", "timelock", "stall"):          # flags that turn a check off
        return f"{{{name}=False}}" if value is False else f"no {{{name}=False}}"
    if isinstance(value, bool):
        return f"{{{name}}}" if value else f"no {{{name}}}"
    if name == "reduce":
        return f"reductions {'+'.join(value) if value else 'none'}"
    if value is None:
        return f"no {{{name}}}" if name != "abstract_time" else f"{{{name}}} by default"
    if isinstance(value, dict):
        return " ".join(f"{{{name}={k}={v}}}" for k, v in value.items()) if value else f"no {{{name}}}"
    if isinstance(value, list):
        return " ".join(f"{{{name}={v!r}}}" for v in value) if value else f"no {{{name}}}"
    return f"{{{name}={value}}}"


class CheckpointError(PcclError):
    """A checkpoint that cannot be resumed (absent, corrupt, another search)."""


class Checkpointer:
    """Where a search writes its checkpoints (``directory``, None: nowhere),
    how often (``interval`` seconds; 0: at every level), and the checkpoint
    it resumes from (``resume``: a directory, loaded by :meth:`load`).
    ``identity`` is :func:`search_identity` of this search."""

    def __init__(self, directory: Optional[str], *, interval: float = DEFAULT_INTERVAL,
                 resume: Optional[str] = None, identity: Optional[dict] = None,
                 note=None):
        #: called with a line to show at once (the CLI's progress reporter)
        self.note = note
        self.dir = None if directory is None else os.fspath(directory)
        self.interval = float(interval)
        self.resume_dir = None if resume is None else os.fspath(resume)
        self.identity = identity or {}
        self.generation = 0
        self.last_write = _time.monotonic()
        self.written: Optional[dict] = None       # {"depth", "states"} of the last write
        self.resumed: Optional[dict] = None       # likewise, of the checkpoint resumed
        #: (depth, states) of the checkpoint last written or read: not written again
        self.last_saved: Optional[tuple] = None
        self.writes = 0
        self.write_seconds = 0.0
        self.bytes = 0
        #: why the last write failed (None: it did not)
        self.error: Optional[str] = None

    def failed(self, e: OSError) -> None:
        """A write failed (a full disk): the previous checkpoint stays; said
        at once and in the notes."""
        self.error = f"checkpoint not written to {self.dir}: {e.strerror or e}; the previous " \
            f"one stays"
        self.last_write = _time.monotonic()       # try again after an interval
        if self.note is not None:
            self.note(self.error)

    # -- writing ---------------------------------------------------------------
    def due(self) -> bool:
        return self.dir is not None and _time.monotonic() - self.last_write >= self.interval

    def prepare_dir(self) -> None:
        """Create the directory (a clear error when it cannot be)."""
        if self.dir is None:
            return
        try:
            os.makedirs(self.dir, exist_ok=True)
            probe = tempfile.NamedTemporaryFile(dir=self.dir, prefix="tmp-probe-")
            probe.close()
        except OSError as e:
            raise CheckpointError(f"cannot write checkpoints to {self.dir}: "
                                  f"{e.strerror or e}", filename="{checkpoint}") from None
        # a checkpoint already there stays valid until this search's first
        # manifest replaces it: number the generations after it
        try:
            with open(os.path.join(self.dir, MANIFEST), encoding="utf-8") as f:
                gen = json.load(f).get("generation", "")
            self.generation = max(self.generation, int(gen[4:]))
        except (OSError, ValueError, TypeError, AttributeError):
            pass

    def write(self, state: dict, arrays: dict) -> None:
        """Write a generation: ``arrays`` (name -> numpy array) and ``state``
        (pickled), then the manifest naming them."""
        assert self.dir is not None
        t0 = _time.perf_counter()
        d = self.dir
        os.makedirs(d, exist_ok=True)
        tmp = tempfile.mkdtemp(prefix="tmp-", dir=d)
        files: dict = {}
        for name, arr in arrays.items():
            arr = np.ascontiguousarray(arr)
            fname = f"{name}.npy"
            with open(os.path.join(tmp, fname), "wb") as f:
                np.save(f, arr, allow_pickle=False)
                f.flush()
                os.fsync(f.fileno())
                size = f.tell()
            files[fname] = {"bytes": size, "xxh3": _array_digest(arr)}
        blob = pickle.dumps(state, protocol=5)
        with open(os.path.join(tmp, "state.pkl"), "wb") as f:
            f.write(blob)
            f.flush()
            os.fsync(f.fileno())
        files["state.pkl"] = {"bytes": len(blob), "xxh3": _digest(blob)}
        _fsync_dir(tmp)
        self.generation += 1
        gen = f"gen-{self.generation:06d}"
        final = os.path.join(d, gen)
        if os.path.exists(final):          # left by a crash before its manifest
            shutil.rmtree(final, ignore_errors=True)
        os.rename(tmp, final)
        _fsync_dir(d)
        manifest = {"format": FORMAT, "pccl": _pccl_version(), "generation": gen,
                    "written": _time.strftime("%Y-%m-%dT%H:%M:%S%z"),
                    "depth": state["depth"], "states": state["n"],
                    "identity": self.identity, "files": files}
        fd, mtmp = tempfile.mkstemp(prefix="tmp-manifest-", dir=d)
        with os.fdopen(fd, "w") as mf:
            json.dump(manifest, mf, indent=1)
            mf.flush()
            os.fsync(mf.fileno())
        os.replace(mtmp, os.path.join(d, MANIFEST))
        _fsync_dir(d)
        for entry in os.listdir(d):         # older generations, stale temporaries
            if entry != gen and (entry.startswith("gen-") or entry.startswith("tmp-")):
                p = os.path.join(d, entry)
                if os.path.isdir(p):
                    shutil.rmtree(p, ignore_errors=True)
                else:
                    try:
                        os.unlink(p)
                    except OSError:
                        pass
        self.last_write = _time.monotonic()
        self.written = {"depth": state["depth"], "states": state["n"]}
        self.last_saved = (state["depth"], state["n"])
        self.writes += 1
        self.write_seconds += _time.perf_counter() - t0
        self.bytes = sum(f["bytes"] for f in files.values())

    # -- reading ---------------------------------------------------------------
    def _bad(self, why: str) -> CheckpointError:
        return CheckpointError(f"{self.resume_dir}: {why}", filename="{resume}", template=True)

    def load(self) -> tuple[dict, dict]:
        """The checkpoint in :attr:`resume_dir`: ``(state, arrays)``, after
        checking that it is whole and that it was written for this search."""
        d = self.resume_dir
        assert d is not None
        man = self._manifest(d)
        gen, files = man["generation"], man["files"]
        state, arrays = self._read_generation(os.path.join(d, gen), gen, files)
        self.generation = int(gen[4:])
        self.resumed = {"depth": state["depth"], "states": state["n"]}
        self.last_saved = (state["depth"], state["n"])
        if self.note is not None:
            self.note(f"resumed from {d} at depth {state['depth']}, {state['n']:,} states")
        self.last_write = _time.monotonic()
        return state, arrays

    def _manifest(self, d: str) -> dict:
        """The manifest of the checkpoint in ``d``, checked: format,
        identity, version, and the generation it names."""
        path = os.path.join(d, MANIFEST)
        if not os.path.isdir(d):
            raise self._bad("no such directory")
        if not os.path.exists(path):
            raise self._bad(f"no checkpoint here (no {MANIFEST}); write one with {{checkpoint=DIR}}")
        try:
            with open(path, encoding="utf-8") as f:
                man = json.load(f)
            if not isinstance(man, dict):
                raise ValueError("not an object")
        except (OSError, ValueError) as e:
            raise self._bad(f"the checkpoint is corrupt ({MANIFEST}: {e})") from None
        if man.get("format") != FORMAT:
            raise self._bad(f"the checkpoint has format {man.get('format')!r}; this pccl "
                            f"reads format {FORMAT}")
        self._check_identity(man.get("identity"))
        if man.get("pccl") != _pccl_version():
            raise self._bad(f"the checkpoint was written by pccl {man.get('pccl')}, this is pccl "
                            f"{_pccl_version()}; resume with that version")
        gen, files = man.get("generation"), man.get("files")
        if not isinstance(gen, str) or not re.fullmatch(r"gen-\d+", gen) \
                or not isinstance(files, dict) or "state.pkl" not in files:
            raise self._bad(f"the checkpoint is corrupt ({MANIFEST} names no generation)")
        return man

    def _read_generation(self, gdir: str, gen: str, files: dict) -> tuple[dict, dict]:
        """The generation's state and arrays, every file checked against
        its size and digest in the manifest."""
        arrays: dict = {}
        state: Any = None
        try:
            for fname, info in files.items():
                p = os.path.join(gdir, fname)
                size = os.path.getsize(p)
                if size != info["bytes"]:
                    raise ValueError(f"{gen}/{fname} has {size:,} bytes, the manifest "
                                     f"says {info['bytes']:,}")
                if fname == "state.pkl":
                    with open(p, "rb") as f:
                        data = f.read()
                    if _digest(data) != info["xxh3"]:
                        raise ValueError(f"{gen}/{fname} does not match its digest")
                    state = pickle.loads(data)
                    del data
                else:
                    # mapped, not read: the table is copied once, into the search's
                    arr = np.load(p, mmap_mode="r", allow_pickle=False)
                    if _array_digest(arr) != info["xxh3"]:
                        raise ValueError(f"{gen}/{fname} does not match its digest")
                    arrays[fname[:-4]] = arr
            if not isinstance(state, dict) or "depth" not in state:
                raise ValueError("state.pkl holds no search state")
        except Exception as e:          # a missing, truncated or altered file
            raise self._bad(f"the checkpoint is corrupt ({e}); write a new one with "
                            "{checkpoint}") from None
        return state, arrays

    def _check_identity(self, got) -> None:
        want = self.identity
        if not isinstance(got, dict):
            raise self._bad(f"the checkpoint is corrupt ({MANIFEST} has no identity)")
        if got.get("program") != want.get("program"):
            raise self._bad(f"the checkpoint was written for a different program ("
                            f"{got.get('program_file')}, hash {got.get('program')}; this run: "
                            f"{want.get('program_file')}, hash {want.get('program')})")
        if got.get("world") != want.get("world"):
            raise self._bad(f"the checkpoint was written with a different world (hash "
                            f"{got.get('world')}; this run: {want.get('world')})")
        go, wo = got.get("options") or {}, want.get("options") or {}
        for name in [*wo, *(k for k in go if k not in wo)]:     # this search's order
            if go.get(name) != wo.get(name):
                raise self._bad(f"the checkpoint was written with {describe_option(name, go.get(name))}, "
                                f"this run has {describe_option(name, wo.get(name))}")


def _fsync_dir(path: str) -> None:
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:             # pragma: no cover - platforms without directory fds
        return
    try:
        os.fsync(fd)
    except OSError:             # pragma: no cover
        pass
    finally:
        os.close(fd)
