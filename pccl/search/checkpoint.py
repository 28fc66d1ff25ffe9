"""Checkpoints of a search, and resuming from them (``--checkpoint DIR``, ``--resume
DIR``): one process (breadth first or ``--fastest``), ``--workers N`` and ``--ray``.

A checkpoint is taken at a breadth-first level boundary: the visited table
(fingerprints and parent links, numpy ``.npy`` files), the graph the
time-lock, stall and temporal checks record (numpy arrays), and the rest as
data (``state.json``: JSON of a closed set of types, :mod:`pccl.search.safedata`,
each field checked on reading: :func:`check_state`; no pickle, so a checkpoint
from elsewhere runs no code): the level about to be expanded (its states, in
``level.msgpack``: :func:`_write_level`), the statistics, the
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

The parallel search's checkpoints (``--workers N``, ``--ray``) hold the
coordinator's part at the top of a generation and one partition per worker
in ``wNNN/``: see "The parallel search" below.  ``--fastest`` keeps its
bucket queue as the frontier (pccl/search/fastest.py).
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import tempfile
import time as _time
from typing import Any, Optional

import numpy as np
import xxhash

from pccl.search import safedata

__all__ = ["FORMAT", "MANIFEST", "Checkpointer", "parse_interval", "search_identity",
           "DEFAULT_INTERVAL"]

#: The version of the checkpoint layout; a checkpoint of another format is refused.
#: (Format 1 held a pickle, ``state.pkl``: never read, since reading one runs code.)
FORMAT = 2
#: the file of a generation (or partition) holding the state besides the arrays
STATE = "state.json"
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


#: an engine's name in messages
_ENGINE = {"native": "native", "python": "Python"}


class CheckpointError(Exception):
    """A checkpoint that cannot be written or resumed (absent, corrupt,
    another search's).  The front ends report it as one message naming
    ``option`` (``pccl.api`` raises it as :class:`pccl.lang.errors.CheckpointFileError`),
    exit 2; the message may name other options as placeholders (``{workers=1}``)."""

    def __init__(self, message: str, option: str, template: bool = False):
        super().__init__(message)
        #: the option a report names (a placeholder: ``--resume`` on the
        #: command line, ``resume`` in the API)
        self.option = option
        #: whether the message names options as placeholders
        self.template = template


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
        #: why this search runs on the Python engine (the message when the
        #: checkpoint resumed is the native engine's)
        self.engine_reason: Optional[str] = None
        #: the appended arrays of the last checkpoint in :attr:`dir` (written or
        #: resumed): name -> {"rows", "dtype", "shape", "parts"} (see :meth:`write`)
        self._segments: dict = {}

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
                                  f"{e.strerror or e}", "{checkpoint}") from None
        # a checkpoint already there stays valid until this search's first
        # manifest replaces it: number the generations after it
        try:
            with open(os.path.join(self.dir, MANIFEST), encoding="utf-8") as f:
                gen = json.load(f).get("generation", "")
            self.generation = max(self.generation, int(gen[4:]))
        except (OSError, ValueError, TypeError, AttributeError):
            pass

    def write(self, state: dict, arrays: dict, appended=()) -> None:
        """Write a generation: ``arrays`` (name -> numpy array) and ``state``
        (as data: ``state.json``), then the manifest naming them.  The arrays named in
        ``appended`` only grow (rows written before never change: the
        fingerprints, the parent links, the recorded edges): of those only
        the rows added since the last checkpoint in this directory are
        written, and the manifest names the older generations' files that
        hold the rest (``"segments"``; see "Appended arrays" below)."""
        before = self._segments
        after: dict = {}
        gen = self.next_generation()

        def fill(tmp: str) -> dict:
            files, segments = write_appended(tmp, "", gen, state, arrays, appended, before)
            after.update(segments)
            return files
        self.write_generation(fill, state, {"segments": after})     # filled by fill()
        self._segments = after

    def next_generation(self) -> str:
        """The name of the generation the next write makes."""
        return f"gen-{self.generation + 1:06d}"

    def write_generation(self, fill, state: dict, extra: Optional[dict] = None) -> None:
        """Write a generation: ``fill(tmp)`` writes its files into the
        temporary directory ``tmp`` and returns their ``{name: {"bytes",
        "xxh3"}}`` (:func:`write_part`; the parallel search's workers write
        their partitions there too); then the manifest (with ``extra``)
        names them.  ``state`` gives the depth and states it reports."""
        assert self.dir is not None
        t0 = _time.perf_counter()
        d = self.dir
        os.makedirs(d, exist_ok=True)
        tmp = tempfile.mkdtemp(prefix="tmp-", dir=d)
        files = fill(tmp)
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
                    "identity": self.identity, **(extra or {}), "files": files}
        fd, mtmp = tempfile.mkstemp(prefix="tmp-manifest-", dir=d)
        with os.fdopen(fd, "w") as mf:
            json.dump(manifest, mf, indent=1)
            mf.flush()
            os.fsync(mf.fileno())
        os.replace(mtmp, os.path.join(d, MANIFEST))
        _fsync_dir(d)
        # older generations (but those whose files this one names: of those,
        # the files it does not name), stale temporaries
        named: dict = {}
        for k in files:
            if k.startswith("../"):
                named.setdefault(k.split("/")[1], set()).add(k.split("/", 2)[2])
        for old, keep_files in named.items():
            root = os.path.join(d, old)
            for where, _, names in os.walk(root, topdown=False):    # partitions: wNNN/
                for f in names:
                    path = os.path.join(where, f)
                    if os.path.relpath(path, root) not in keep_files:
                        try:
                            os.unlink(path)
                        except OSError:
                            pass
                if where != root:
                    try:
                        os.rmdir(where)         # once empty
                    except OSError:
                        pass
        keep = {gen, *named}
        for entry in os.listdir(d):
            if entry not in keep and (entry.startswith("gen-") or entry.startswith("tmp-")):
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

    # -- the parallel search (below: parallel.py imports no checkpoint code) ----
    def save_parallel(self, ex) -> None:
        parallel_save(ex)

    def load_parallel(self, ex) -> tuple[dict, dict]:
        return parallel_load(ex)

    def restore_parallel(self, ex, state: dict, arrays: dict) -> dict:
        return parallel_restore(ex, state, arrays)

    # -- reading ---------------------------------------------------------------
    def _bad(self, why: str) -> CheckpointError:
        return CheckpointError(f"{self.resume_dir}: {why}", "{resume}", template=True)

    def load(self, parallel: bool = False) -> tuple[dict, dict]:
        """The checkpoint in :attr:`resume_dir`: ``(state, arrays)``, after
        checking that it is whole and that it was written for this search.
        ``parallel``: the search resuming is the parallel one (``--workers
        N``, ``--ray``), whose checkpoints hold partitions: their files are
        read later, by :func:`read_part` (:attr:`parts`: per partition its
        files in the manifest; :attr:`gen_dir`: where they are)."""
        d = self.resume_dir
        assert d is not None
        man = self._manifest(d)
        gen, files = man["generation"], man["files"]
        parts = man.get("partitions", 0)
        if parallel and not parts:
            raise self._bad("the checkpoint was written by one process ({workers=1}); resume "
                            "it with {workers=1} without {ray}")
        if parts and not parallel:
            raise self._bad(f"the checkpoint was written by {parts} workers; resume it with "
                            f"{{workers=N}} (N of 2 or more, not necessarily {parts}) or {{ray}}")
        self._check_engine(man["identity"], self.identity)
        top = {k: v for k, v in files.items() if _part_of(k) == ""}
        self.gen_dir = os.path.join(d, gen)
        names = [part_name(w) for w in range(parts)]
        self.parts = [{_within(k, p): v for k, v in files.items() if _part_of(k) == p}
                      for p in names]
        if any(not p for p in self.parts):
            raise self._bad(f"the checkpoint is corrupt ({MANIFEST} lacks a partition)")
        state, arrays = self._read_generation(self.gen_dir, gen, top)
        segments = man.get("segments") or {}
        #: per partition, its appended arrays (names without the partition's prefix)
        self.part_segments = [{k[len(p) + 1:]: v for k, v in segments.items()
                               if k.startswith(p + "/")} for p in names]
        try:
            arrays = joined_segments(arrays, {k: v for k, v in segments.items() if "/" not in k},
                                     gen)
        except (ValueError, KeyError, TypeError) as e:
            raise self._bad(f"the checkpoint is corrupt ({e}); write a new one with "
                            "{checkpoint}") from None
        if self.dir is not None and os.path.realpath(self.dir) == os.path.realpath(d):
            self._segments = segments       # the next checkpoint here appends to them
        self.generation = int(gen[4:])
        self.resumed = {"depth": state["depth"], "states": state["n"]}
        self.last_saved = (state["depth"], state["n"])
        if not parallel:            # the parallel search: once the partitions are read too
            self.say_resumed()
        self.last_write = _time.monotonic()
        return state, arrays

    def say_resumed(self) -> None:
        if self.note is not None and self.resumed is not None:
            self.note(f"resumed from {self.resume_dir} at depth {self.resumed['depth']}, "
                      f"{self.resumed['states']:,} states")

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
        if man.get("format") == 1 or (isinstance(man.get("files"), dict)
                                      and "state.pkl" in man["files"]):
            raise self._bad("the checkpoint was written by an older pccl (its state is a "
                            "pickle, which this pccl does not read: reading one can run "
                            "code); start the search again")
        if man.get("format") != FORMAT:
            raise self._bad(f"the checkpoint has format {man.get('format')!r}; this pccl "
                            f"reads format {FORMAT}")
        self._check_identity(man.get("identity"))
        if man.get("pccl") != _pccl_version():
            raise self._bad(f"the checkpoint was written by pccl {man.get('pccl')}, this is pccl "
                            f"{_pccl_version()}; resume with that version")
        gen, files = man.get("generation"), man.get("files")
        if not isinstance(gen, str) or not re.fullmatch(r"gen-\d+", gen) \
                or not isinstance(files, dict) or STATE not in files:
            raise self._bad(f"the checkpoint is corrupt ({MANIFEST} names no generation)")
        return man

    def _read_generation(self, gdir: str, gen: str, files: dict) -> tuple[dict, dict]:
        """The generation's state and arrays, every file checked against
        its size and digest in the manifest."""
        try:
            return read_part(gdir, files, gen)
        except ValueError as e:          # a missing, truncated or altered file
            raise self._bad(f"the checkpoint is corrupt ({e}); write a new one with "
                            "{checkpoint}") from None

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

    def _check_engine(self, got: dict, want: dict) -> None:
        """A checkpoint is continued by the engine that wrote it: its states
        are that engine's (native vectors or Python configurations) and so
        are the fingerprints of its table, which the other engine cannot
        compute again (it holds no states but the level's).  A checkpoint
        without an engine is the Python engine's."""
        ge, we = got.get("engine", "python"), want.get("engine", "python")
        if ge != we:
            why = f" ({self.engine_reason})" if we == "python" and self.engine_reason else ""
            hint = ("resume it where the native engine can run this search (a C compiler "
                    "and Python's headers)" if ge == "native" else
                    "resume it with {engine=python} or {engine=auto}")
            raise self._bad(f"the checkpoint was written by the {_ENGINE.get(ge, ge)} engine, this run "
                            f"uses the {_ENGINE.get(we, we)} engine{why}; a checkpoint's states and "
                            f"fingerprints are its engine's: {hint}")
        if ge == "native" and got.get("native") != want.get("native"):
            raise self._bad(f"the checkpoint was written by the native engine from another "
                            f"generated source (hash {got.get('native')}; this run: "
                            f"{want.get('native')}): resume it with the pccl that wrote it")


# Appended arrays
# ---------------
#
# The visited table and the recorded graph only grow, and a checkpoint at 12
# million states holds 450 MiB of them: written whole every interval, that
# is seconds a checkpoint (measured: 1.4 s each at 12M states on the shared
# machine, docs/scale-out.md).  So :meth:`Checkpointer.write` writes, of an
# array that only grows, the rows added since the last checkpoint in the
# same directory (``fps.1830030.npy``: rows from 1,830,030 on), and the
# manifest's ``"segments"`` names per array its parts in order, each in the
# generation that wrote it (``gen-000004/fps.0.npy``, then
# ``gen-000007/fps.1830030.npy``, ...); ``"files"`` lists them too (as
# ``../gen-000004/fps.0.npy``, with size and digest), so a resume checks
# every byte as before.  A generation whose files a newer one names is kept
# until no manifest names it.  After :data:`MAX_PARTS` parts, or when an
# array is not a continuation of the last (another directory, a search
# started anew), the array is written whole again.

#: parts of an appended array before it is written whole again
MAX_PARTS = 64


def joined_segments(arrays: dict, segments: dict, gen: str, up: str = "../",
                    prefix: str = "") -> dict:
    """The arrays read from generation ``gen``'s files (``arrays``: file
    names without ``.npy``, as :func:`read_part` returns them; an older
    generation's as ``../gen-NNNNNN/name``) with each appended array of
    ``segments`` joined from its parts; ValueError when the parts do not
    follow one another.  (A parallel search's partition ``wNNN`` is read
    from ``gen-NNNNNN/wNNN/``: an older generation's part of it is
    ``../../gen-MMMMMM/wNNN/name``, ``up="../../"``, ``prefix="wNNN/"``.)"""
    out = {k: v for k, v in arrays.items() if not k.startswith("../") and "." not in k}
    for name, seg in segments.items():
        pieces, at = [], 0
        for p in seg["parts"]:
            fname = p["file"][:-4]
            a = arrays.get(fname if p["gen"] == gen else f"{up}{p['gen']}/{prefix}{fname}")
            if a is None or p["start"] != at or p["end"] - p["start"] != len(a):
                raise ValueError(f"the parts of {name} do not follow one another")
            pieces.append(a)
            at = p["end"]
        if at != seg["rows"]:
            raise ValueError(f"the parts of {name} hold {at:,} rows, the manifest says "
                             f"{seg['rows']:,}")
        out[name] = pieces[0] if len(pieces) == 1 else np.concatenate(pieces)
    return out


def _part_of(key: str) -> str:
    """The partition (``wNNN``) a manifest's file belongs to, ``""`` for
    the top of the generation: ``w000/fps.npy`` and
    ``../gen-000004/w000/fps.0.npy`` are partition ``w000``'s."""
    rest = key.split("/", 2)[2] if key.startswith("../") else key
    return rest.split("/")[0] if "/" in rest else ""


def _within(key: str, part: str) -> str:
    """A manifest's file of partition ``part``, relative to its directory."""
    return "../" + key if key.startswith("../") else key[len(part) + 1:]


def write_appended(tmp: str, prefix: str, gen: str, state, arrays: dict, appended,
                   before: dict) -> tuple[dict, dict]:
    """Write ``state`` and ``arrays`` into ``tmp/prefix`` (:func:`write_part`)
    for generation ``gen``; of the arrays named in ``appended``, which only
    grow, only the rows added since ``before`` (their segments in the last
    checkpoint in this directory, as this function returned them; see
    "Appended arrays" above).  Returns the manifest's files (an older
    generation's part as ``../gen-NNNNNN/prefix/name``) and the appended
    arrays' segments (names without the prefix).  Used for one process's
    checkpoint (``prefix=""``) and for each partition of the parallel
    search's (``prefix="wNNN"``, in the worker's process with
    ``--workers N``)."""
    files: dict = {}
    pre = prefix + "/" if prefix else ""
    after: dict = {}
    for name in appended:
        if name not in arrays:
            continue
        arr = arrays[name]
        prev = before.get(name)
        if prev is not None and (prev["rows"] > len(arr) or len(prev["parts"]) >= MAX_PARTS
                                 or prev["dtype"] != arr.dtype.str
                                 or list(prev["shape"]) != list(arr.shape[1:])):
            prev = None             # written whole again (and the chain starts anew)
        parts = [dict(p) for p in prev["parts"]] if prev is not None else []
        start = prev["rows"] if prev is not None else 0
        for p in parts:             # an older generation's file, named from this one's
            files[f"../{p['gen']}/{pre}{p['file']}"] = p["info"]
        if start < len(arr) or not parts:
            fname = f"{name}.{start}.npy"
            info = write_part(tmp, prefix, None, {fname[:-4]: arr[start:]})[pre + fname]
            files[pre + fname] = info
            parts.append({"gen": gen, "file": fname, "start": start, "end": len(arr),
                          "info": info})
        after[name] = {"rows": len(arr), "dtype": arr.dtype.str,
                       "shape": list(arr.shape[1:]), "parts": parts}
    # the rest last: with a prefix, write_part fsyncs the directory once, after every file
    files.update(write_part(tmp, prefix, state, {k: v for k, v in arrays.items()
                                                 if k not in appended}))
    return files, after


def part_name(w: int) -> str:
    """The subdirectory of a generation holding partition ``w`` of a
    parallel search."""
    return f"w{w:03d}"


def write_part(tmp: str, prefix: str, state, arrays: dict) -> dict:
    """Write ``arrays`` (name -> numpy array, as ``.npy``) and ``state``
    (``state.json``, :mod:`pccl.search.safedata`) into ``tmp/prefix``, each file fsynced; their
    ``{"prefix/name": {"bytes", "xxh3"}}`` for the manifest.  (Called in a
    worker's process too: it writes its own partition.)"""
    where = os.path.join(tmp, prefix) if prefix else tmp
    os.makedirs(where, exist_ok=True)
    pre = prefix + "/" if prefix else ""
    files: dict = {}
    for name, arr in arrays.items():
        arr = np.ascontiguousarray(arr)
        fname = f"{name}.npy"
        with open(os.path.join(where, fname), "wb") as f:
            np.save(f, arr, allow_pickle=False)
            f.flush()
            os.fsync(f.fileno())
            size = f.tell()
        files[pre + fname] = {"bytes": size, "xxh3": _array_digest(arr)}
    if state is None:           # arrays only (an appended array's new rows)
        return files
    if isinstance(state.get("level"), list):    # the bulk: its own file, a record at a time
        files[pre + LEVEL] = _write_level(os.path.join(where, LEVEL), state["level"])
        state = {k: v for k, v in state.items() if k != "level"}
    blob = safedata.dumps(_marked_states(state))
    with open(os.path.join(where, STATE), "wb") as f:
        f.write(blob)
        f.flush()
        os.fsync(f.fileno())
    files[pre + STATE] = {"bytes": len(blob), "xxh3": _digest(blob)}
    if prefix:
        _fsync_dir(where)
    return files


#: the file of a generation (or partition) holding the level's states
LEVEL = "level.msgpack"
#: states a record of :data:`LEVEL` holds at most
LEVEL_CHUNK = 4096


def _write_level(path: str, level: list) -> dict:
    """The level's states into ``path`` as records (a kind byte, ``M``
    MessagePack or ``J`` JSON for an integer past 64 bits, an 8-byte length,
    :func:`safedata.pack_segment` of ``(first index, states)``), written and
    digested a record at a time: no copy of the whole level; its
    ``{"bytes", "xxh3"}``."""
    h = xxhash.xxh3_128()
    size = 0
    with open(path, "wb") as f:
        for a in range(0, len(level), LEVEL_CHUNK):
            part = level[a:a + LEVEL_CHUNK]
            try:
                kind, blob = b"M", safedata.pack_segment(a, part)
            except (TypeError, OverflowError, ValueError):
                kind, blob = b"J", safedata.dumps((a, part))
            rec = kind + len(blob).to_bytes(8, "little") + blob
            f.write(rec)
            h.update(rec)
            size += len(rec)
            del blob, rec
        f.flush()
        os.fsync(f.fileno())
    return {"bytes": size, "xxh3": h.hexdigest()}


def _read_level(path: str, info: dict, what: str) -> list:
    """The states :func:`_write_level` wrote, checked against ``info``'s
    digest; ValueError when they are not."""
    h = xxhash.xxh3_128()
    level: list = []
    with open(path, "rb") as f:
        while True:
            head = f.read(9)
            if not head:
                break
            if len(head) != 9 or head[:1] not in (b"M", b"J"):
                raise ValueError(f"{what}: not a record")
            blob = f.read(int.from_bytes(head[1:], "little"))
            if len(blob) != int.from_bytes(head[1:], "little"):
                raise ValueError(f"{what}: truncated")
            h.update(head)
            h.update(blob)
            if head[:1] == b"M":
                first, states = safedata.unpack_segment(blob)
            else:
                seg = safedata.loads(blob)
                if type(seg) is not tuple or len(seg) != 2 or type(seg[1]) is not list:
                    raise ValueError(f"{what}: not a record")
                first, states = seg
            if first != len(level) or not all(type(x) is tuple or type(x) is bytes
                                               for x in states):
                raise ValueError(f"{what}: the records do not follow one another")
            level.extend(states)
    if h.hexdigest() != info["xxh3"]:
        raise ValueError(f"{what} does not match its digest")
    return level


def _marked_states(state: dict) -> dict:
    """``state`` with its lists of states marked (:class:`safedata.States`:
    written as MessagePack, fast): a level, the fastest search's buckets."""
    out = dict(state)
    if isinstance(out.get("level"), list):
        out["level"] = safedata.States(out["level"])
    b = out.get("buckets")
    if isinstance(b, list):         # one process: [(key, [(state, number)])]
        out["buckets"] = [(k, safedata.States(entries)) for k, entries in b]
    elif isinstance(b, dict):       # a worker's: {key: ([numbers], [states])}
        out["buckets"] = {k: (ix, safedata.States(sts)) for k, (ix, sts) in b.items()}
    return out


def read_part(gdir: str, files: dict, gen: str = "") -> tuple[Any, dict]:
    """The state and arrays of the files ``files`` (names relative to
    ``gdir``, as :func:`write_part` returned them), each checked against
    its size and digest; ValueError saying what is wrong."""
    arrays: dict = {}
    state: Any = None
    level: Optional[list] = None
    label = f"{gen}/" if gen else ""
    try:
        for fname, info in files.items():
            p = os.path.join(gdir, fname)
            size = os.path.getsize(p)
            if size != info["bytes"]:
                raise ValueError(f"{label}{fname} has {size:,} bytes, the manifest "
                                 f"says {info['bytes']:,}")
            if fname == STATE:
                with open(p, "rb") as f:
                    data = f.read()
                if _digest(data) != info["xxh3"]:
                    raise ValueError(f"{label}{fname} does not match its digest")
                state = safedata.loads(data)        # data only: no code runs
                del data
            elif fname == LEVEL:
                level = _read_level(p, info, f"{label}{fname}")
            elif not fname.endswith(".npy") or "\\" in fname or fname.startswith("/") \
                    or any(part not in ("..",) and not re.fullmatch(r"[\w.-]+", part)
                           for part in fname.split("/")):
                raise ValueError(f"{label}{fname}: not a checkpoint's file")
            else:
                # mapped, not read: the table is copied once, into the search's
                arr = np.load(p, mmap_mode="r", allow_pickle=False)
                if _array_digest(arr) != info["xxh3"]:
                    raise ValueError(f"{label}{fname} does not match its digest")
                arrays[fname[:-4]] = arr
        if not isinstance(state, dict) or "depth" not in state:
            raise ValueError(f"{label}{STATE} holds no search state")
        if level is not None:
            if "level" in state:
                raise ValueError(f"{label}{STATE} holds a level besides {LEVEL}")
            state["level"] = level
        check_state(state, f"{label}{STATE}")
    except ValueError:
        raise
    except Exception as e:
        raise ValueError(f"{label}: {type(e).__name__}: {e}") from None
    return state, arrays


# What a checkpoint's state.json may hold
# -----------------------------------------
#
# :func:`safedata.loads` builds only plain data; here each field of the state
# is checked against what a search writes (types, ranges, how the fields
# agree), so that a checkpoint from elsewhere is refused with one message
# (exit 2) instead of failing somewhere in the search.  Its states cannot be
# checked against the program here: a forged but well-typed state is resumed
# like any other, and what the search reports of it (a counterexample) is
# replayed and checked against the program before it is shown.

def _nat(x) -> bool:
    return type(x) is int and x >= 0


def _num(x) -> bool:
    return type(x) in (int, float)


def _opt(pred):
    return lambda x: x is None or pred(x)


def _list_of(pred):
    return lambda x: type(x) is list and all(pred(y) for y in x)


def _is_state(x) -> bool:
    """A state of either engine: a tuple (Python) or bytes (native)."""
    return type(x) is tuple or type(x) is bytes


def _found(x) -> bool:
    return type(x) is tuple and len(x) == 3 and type(x[0]) is safedata.record_class("v") \
        and _nat(x[1]) and _nat(x[2])


def _str_dict(x) -> bool:
    return type(x) is dict and all(type(k) is str for k in x)


def _runaway(x) -> bool:
    return x is None or (type(x) is tuple and all(y is None or type(y) in (int, float, bool)
                                                 for y in x))


def _buckets_list(x) -> bool:       # the fastest search: [(key, [(state, number)])]
    return type(x) is list and all(
        type(kb) is tuple and len(kb) == 2 and type(kb[0]) is tuple and type(kb[1]) is list
        and all(type(e) is tuple and len(e) == 2 and _is_state(e[0]) and _nat(e[1])
                for e in kb[1]) for kb in x)


def _buckets_dict(x) -> bool:       # a worker's: {key: ([numbers], [states])}
    return type(x) is dict and all(
        type(k) is tuple and type(v) is tuple and len(v) == 2 and _list_of(_nat)(v[0])
        and _list_of(_is_state)(v[1]) and len(v[0]) == len(v[1]) for k, v in x.items())


def _exact(x) -> bool:
    return type(x) is dict and set(x) == {"keys", "parents"} \
        and _list_of(lambda k: type(k) is bytes)(x["keys"]) \
        and (_list_of(lambda p: type(p) is int)(x["parents"])
             or isinstance(x["parents"], np.ndarray) and x["parents"].dtype.kind in "iu"
             and x["parents"].ndim == 1) and len(x["parents"]) == len(x["keys"])


_COMMON = {"depth": _nat, "transitions": _nat, "max_depth": _nat, "initial_states": _nat,
           "max_time": _opt(_num), "bounds": _list_of(lambda b: type(b) is str),
           "found": _list_of(_found), "seconds": _num, "tables": _opt(_str_dict)}
#: field -> (required?, check) per kind of state
_SCHEMAS = {
    "search": {**_COMMON, "n": _nat, "budget": lambda x: type(x) is int,
               "labels": _opt(lambda x: type(x) is set and all(type(y) is tuple for y in x)),
               "runaway": _runaway, "runaway_info": _opt(_str_dict),
               "edges": _opt(_nat), "rec_complete": _opt(lambda x: type(x) is bool),
               "peak_memory": _nat, "level": _list_of(_is_state), "first": _nat,
               "exact": _exact, "kind": lambda x: x == "fastest",
               "buckets": _opt(_buckets_list)},
    "parallel": {**_COMMON, "kind": lambda x: x == "parallel", "workers": _nat, "n": _nat,
                 "level_base": _nat, "frontier": _nat, "peak_workers": _list_of(_nat),
                 "waiting": lambda x: type(x) is dict and all(_nat(v) for v in x.values())},
    "partition": {"depth": _nat, "wid": _nat, "workers": _nat, "level_idx": _list_of(_nat),
                  "level": _list_of(_is_state), "columns": lambda x: type(x) is bool,
                  "ncols": _nat, "buckets": _buckets_dict, "tables": _opt(_str_dict)},
}
#: the fields a state of each kind may lack
_OPTIONAL = {"search": {"exact", "kind", "buckets", "level", "first", "max_time"},
             "parallel": {"waiting", "max_time"},
             "partition": {"buckets"}}


def check_state(state, what: str) -> None:
    """ValueError unless ``state`` (read by :func:`safedata.loads`) is a
    search state a checkpoint holds: every field of the right type and
    range, none unknown, the figures agreeing with one another."""
    if type(state) is not dict or not all(type(k) is str for k in state):
        raise ValueError(f"{what} holds no search state")
    kind = "partition" if "wid" in state else \
        "parallel" if state.get("kind") == "parallel" else "search"
    schema = _SCHEMAS[kind]
    for k, v in state.items():
        check = schema.get(k)
        if check is None:
            raise ValueError(f"{what}: unknown field {k!r}")
        if not check(v):
            raise ValueError(f"{what}: field {k!r} has the wrong type or value")
    missing = [k for k in schema if k not in state and k not in _OPTIONAL[kind]]
    if missing:
        raise ValueError(f"{what}: no field {missing[0]!r}")
    n = state.get("n")
    for _, idx, _d in state.get("found", ()):
        if n is not None and idx >= max(n, 1):
            raise ValueError(f"{what}: a violation names state {idx:,} of {n:,}")
    if kind == "search" and state.get("kind") != "fastest":
        if "level" not in state or "first" not in state:
            raise ValueError(f"{what}: no level")
        if not state["first"] <= state["n"] or len(state["level"]) != state["n"] - state["first"]:
            raise ValueError(f"{what}: the level and the table's size do not agree")
    if kind == "parallel" and not (1 <= state["workers"] and state["level_base"] <= state["n"]):
        raise ValueError(f"{what}: the figures do not agree")
    if kind == "partition":
        if not state["wid"] < state["workers"] or len(state["level_idx"]) != len(state["level"]):
            raise ValueError(f"{what}: the partition's figures do not agree")


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


# ---------------------------------------------------------------------------
# The parallel search (pccl/search/parallel.py): --workers N and --ray
# ---------------------------------------------------------------------------
#
# A checkpoint is taken at a level boundary, the workers' synchronisation
# point, once the coordinator's decision on the last level is committed
# (every owner has recorded its new states, every generator holds the states
# it won): the coordinator writes its part (the global parent links, who
# holds each state of the level, the statistics, the violations, the
# bounds), each worker its partition (fingerprints and state numbers of the
# states it owns, the states of the level it holds, the graph it recorded)
# into ``tmp-*/wNNN/``, and the manifest, naming every file, is replaced
# last (:meth:`Checkpointer.write_generation`).  With ``--workers N`` the
# workers write their partitions themselves (one machine); with ``--ray``
# they send them to the coordinator, which writes them (the actors may be on
# machines that do not see ``DIR``), and it reads them back on resume.
#
# Owners are decided by fingerprints (the low word modulo the number of
# workers), so a checkpoint of N workers resumes with M: every new worker
# reads every partition and keeps the fingerprints it owns now and the
# states of the level numbered ``w`` modulo M.  (With M = N each reads its
# own partition only, and the level stays where it was.)

#: The arrays of a worker's recorded graph (see ``_Worker.graph_head``):
#: lists of arrays.
_ARRAYS = ("g_src", "g_fps", "g_idx", "g_chg_idx", "g_chg")
_GRAPH_TYPES = {"g_src": (np.uint32, (0,)), "g_fps": (np.uint64, (0, 2)),
                "g_idx": (np.int64, (0,)), "g_chg_idx": (np.int64, (0,)),
                "g_chg": (np.uint8, (0,))}


def _joined(parts: list, name: str) -> np.ndarray:
    dtype, shape = _GRAPH_TYPES[name]
    if not parts:
        return np.zeros(shape, dtype=dtype)
    return np.concatenate([np.asarray(p, dtype=dtype) for p in parts])


def worker_snapshot(w, depth: int) -> tuple[dict, dict]:
    """Worker ``w``'s partition (a ``parallel._Worker`` whose last decision
    is committed): ``(state, arrays)``."""
    assert w.pending is None and w.cand_keys is None, "a level boundary, decision committed"
    t = w.table
    arrays = {"fps": t.fps[:t.n], "parents": t.parents[:t.n]}
    state = {"depth": depth, "wid": w.wid, "workers": w.n, "level_idx": list(w.level_idx),
             "level": w.level, "columns": w.columns is not None, "ncols": 0}
    if w.fastest:               # the buckets I hold: (ticks, depth) -> [numbers, states]
        state["buckets"] = {b: (list(ix), list(sts)) for b, (ix, sts) in w.buckets.items()}
    # the model's lazily interned tables as this worker has them: the states it
    # holds may refer to entries only this process made (a stuck agent's reason)
    tables = getattr(w.m, "checkpoint_tables", None)
    state["tables"] = tables() if tables is not None else None
    if w.columns is not None:
        for name in _ARRAYS:         # joined once: the next snapshot joins only what is new
            joined = _joined(getattr(w, name), name)
            setattr(w, name, [joined] if len(joined) else [])
            arrays[name] = joined
        cols = [np.concatenate(c) for c in zip(*w.g_cols)] if w.g_cols else []
        w.g_cols = [tuple(cols)] if cols else []
        state["ncols"] = len(cols)
        for i, c in enumerate(cols):
            arrays[f"g_col{i}"] = c
    return state, arrays


def worker_restore(w, pieces: list, same: bool) -> int:
    """Fill the fresh worker ``w`` from partitions ``pieces`` (``(state,
    arrays)`` of :func:`worker_snapshot`): with ``same`` (as many workers as
    wrote them) its own partition, whole; else every partition, of which it
    keeps the fingerprints it owns and the level's states numbered ``w``
    modulo the number of workers, and the graphs of partitions ``w`` modulo
    that number.  Returns how many states its table holds."""
    n, wid = w.n, w.wid
    fps: list = []
    parents: list = []
    level: list = []
    restore = getattr(w.m, "restore_tables", None)
    for state, _ in pieces:
        if restore is not None and state.get("tables") is not None:
            restore(state["tables"])
    for state, arrays in pieces:
        if state.get("columns") != (w.columns is not None):
            raise ValueError("the checkpoint's recorded graph does not match this search's")
        f, p = arrays["fps"], arrays["parents"]
        if f.dtype != np.uint64 or f.ndim != 2 or f.shape[1:] != (2,) \
                or p.dtype != np.uint32 or p.shape != (len(f),):
            raise ValueError("the fingerprint arrays have the wrong shape or type")
        if not same:
            mine = (f[:, 1] % np.uint64(n)) == np.uint64(wid)
            f, p = f[mine], p[mine]
        fps.append(np.array(f))
        parents.append(np.array(p))
        idx, states = state["level_idx"], state["level"]
        if len(idx) != len(states):
            raise ValueError("a partition's level and its numbers do not agree")
        level.extend(zip(idx, states) if same else
                     ((g, s) for g, s in zip(idx, states) if g % n == wid))
        if w.columns is not None and (same or state["wid"] % n == wid):
            for name in _ARRAYS:
                a = np.array(arrays[name])
                if len(a):
                    getattr(w, name).append(a)
            cols = tuple(np.array(arrays[f"g_col{i}"]) for i in range(state["ncols"]))
            if cols and len(cols[0]):
                w.g_cols.append(cols)
    if fps:
        f = np.concatenate(fps) if len(fps) > 1 else fps[0]
        p = np.concatenate(parents) if len(parents) > 1 else parents[0]
        del fps, parents
        if len(f):
            w.table.insert(f, p)
    level.sort(key=lambda gs: gs[0])
    w.level_idx = [g for g, _ in level]
    w.level = [s for _, s in level]
    _restore_buckets(w, pieces, same)
    return int(w.table.n)


def _restore_buckets(w, pieces: list, same: bool) -> None:
    """The fastest search: worker ``w``'s buckets from the partitions
    ``pieces`` (with ``same``, its own whole; else the waiting states
    numbered ``w`` modulo the number of workers), each in number order
    (the order a bucket is expanded in)."""
    n, wid = w.n, w.wid
    buckets: dict = {}
    for state, _ in pieces:
        for b, (bidx, bstates) in (state.get("buckets") or {}).items():
            mine = list(zip(bidx, bstates)) if same else \
                [(g, s) for g, s in zip(bidx, bstates) if g % n == wid]
            if mine:
                buckets.setdefault(b, []).extend(mine)
    for b, items in buckets.items():
        items.sort(key=lambda gs: gs[0])
        w.buckets[b] = [[g for g, _ in items], [s for _, s in items]]


def worker_appended(arrays: dict) -> tuple:
    """The arrays of a partition (:func:`worker_snapshot`) that only grow
    (written a segment at a time: :func:`write_appended`): the fingerprints
    and state numbers of the table, and the recorded graph."""
    return ("fps", "parents", *_ARRAYS,
            *(k for k in arrays if k.startswith("g_col")))


def partition_save(tmp: str, w_out: int, gen: str, state, arrays: dict,
                   before: dict) -> tuple[dict, dict]:
    """Write partition ``w_out`` (``state``, ``arrays``: :func:`worker_snapshot`)
    into ``tmp/wNNN/`` for generation ``gen``, appending to ``before`` (its
    segments in the last checkpoint): the manifest's files and segments
    (keyed ``wNNN/name``)."""
    p = part_name(w_out)
    files, segs = write_appended(tmp, p, gen, state, arrays, worker_appended(arrays), before)
    return files, {f"{p}/{k}": v for k, v in segs.items()}


def worker_save(w, tmp: str, w_out: int, depth: int, gen: str = "",
                before: Optional[dict] = None) -> tuple[dict, dict]:
    """A worker writes its partition into ``tmp`` itself (``--workers N``):
    :func:`partition_save` in its process."""
    state, arrays = worker_snapshot(w, depth)
    return partition_save(tmp, w_out, gen, state, arrays, before or {})


def read_partition(gdir: str, name: str, files: dict, segments: dict) -> tuple[Any, dict]:
    """Partition ``name`` of the generation ``gdir`` (its ``files`` and
    appended arrays' ``segments``, from :meth:`Checkpointer.load`), each
    file checked, the appended arrays joined; ValueError saying what is
    wrong."""
    gen = os.path.basename(gdir)
    state, arrays = read_part(os.path.join(gdir, name), files, f"{gen}/{name}")
    return state, joined_segments(arrays, segments, gen, "../../", name + "/")


def worker_load(w, gdir: str, parts: list, same: bool) -> int:
    """A worker reads the partitions ``parts`` (``[(name, files, segments)]``)
    from the generation ``gdir`` itself, then :func:`worker_restore`."""
    pieces = [read_partition(gdir, *part) for part in parts]
    return worker_restore(w, pieces, same)


def parallel_save(ex) -> None:
    """Write the checkpoint of the parallel search ``ex`` (a
    ``ParallelExplorer``) at the level boundary of its mark."""
    ck, mark, T, n = ex.checkpoint, ex._ck_mark, ex.transport, ex.workers
    assert ck is not None and mark is not None
    if ex._decisions:           # the owners record the last level's states first
        ex._note_peaks(T.all("commit", [(d,) for d in ex._decisions]))
        ex._decisions = None
    res, total, depth = ex._res, ex._total, mark["depth"]
    stats = res.stats
    tables = getattr(ex.model, "checkpoint_tables", None)
    fastest = getattr(ex, "fastest", False)
    state = {"kind": "parallel", "workers": n, "depth": depth, "n": total,
             "level_base": total if fastest else mark["level_base"],
             "transitions": stats.transitions, "max_depth": stats.max_depth,
             "initial_states": stats.initial_states, "frontier": stats.frontier,
             "max_time": ex.max_time_now(),
             "bounds": [b.value for b in ex._bounds],
             "found": [(f.violation, f.index, f.depth) for f in res.found],
             "peak_workers": list(ex.peak_workers),
             "seconds": _time.perf_counter() - ex._t_start,
             "tables": tables() if tables is not None else None}
    arrays = {"parents": ex.parents[:total],
              "holder": np.asarray(mark["holder"] if not fastest else (), np.int64)}
    if fastest:     # between two buckets: the counts per bucket, who holds each state
        state["waiting"] = dict(ex._waiting)
        arrays["held"] = ex._held[:total]

    # the arrays that only grow are appended (see "Appended arrays"): the
    # coordinator's parent links, and of each partition its table and graph
    gen, before, after = ck.next_generation(), ck._segments, {}

    def mine(w: int) -> dict:
        p = part_name(w) + "/"
        return {k[len(p):]: v for k, v in before.items() if k.startswith(p)}

    def fill(tmp: str) -> dict:
        files, segs = write_appended(tmp, "", gen, state, arrays, ("parents",),
                                     {k: v for k, v in before.items() if "/" not in k})
        after.update(segs)
        if getattr(T, "shared_files", False):      # the workers write their own
            for f, segs in T.all("checkpoint", [(worker_save, tmp, w, depth, gen, mine(w))
                                                for w in range(n)]):
                files.update(f)
                after.update(segs)
        else:                                       # Ray: sent here, one at a time
            for w in range(n):
                wstate, warrays = T.call(w, "checkpoint", worker_snapshot, depth)
                f, segs = partition_save(tmp, w, gen, wstate, warrays, mine(w))
                files.update(f)
                after.update(segs)
                del wstate, warrays
        return files
    try:
        ck.write_generation(fill, state, {"partitions": n, "segments": after})
        ck._segments = after
    except OSError as e:        # a full disk: the search goes on, the last checkpoint stays
        ck.failed(e)


def parallel_load(ex) -> tuple[dict, dict]:
    """Read the coordinator's part of the checkpoint ``ex`` resumes from and
    restore the model's tables (before the workers start)."""
    ck = ex.checkpoint
    state, arrays = ck.load(parallel=True)
    try:
        if state.get("kind") != "parallel" or "parents" not in arrays or "holder" not in arrays:
            raise ValueError("the coordinator's state is not a parallel search's")
        restore = getattr(ex.model, "restore_tables", None)
        if restore is not None and state.get("tables") is not None:
            restore(state["tables"])
    except (ValueError, KeyError, TypeError) as e:
        raise ck._bad(f"the checkpoint is corrupt ({e}); write a new one with "
                      "{checkpoint}") from None
    return state, arrays


def parallel_restore(ex, state: dict, arrays: dict) -> dict:
    """Put the parallel search ``ex`` (its workers started) back where the
    checkpoint left it; returns where its level loop starts
    (``depth``, ``level_base``, ``holder``)."""
    from pccl.search.explorer import Bound, Counterexample
    ck, T, n = ex.checkpoint, ex.transport, ex.workers
    old = len(ck.parts)
    same = old == n
    try:
        total, base = int(state["n"]), int(state["level_base"])
        parents, holder = arrays["parents"], arrays["holder"]
        if len(parents) != total or len(holder) != total - base or not 0 <= base <= total:
            raise ValueError("the coordinator's arrays and figures do not agree")
        names = [(part_name(w), ck.parts[w], ck.part_segments[w]) for w in range(old)]
        if getattr(T, "shared_files", False):
            counts = T.all("checkpoint", [(worker_load, ck.gen_dir, [names[w]] if same else names, same)
                                    for w in range(n)])
        else:
            pieces = [read_partition(ck.gen_dir, *part) for part in names]
            counts = [T.call(w, "checkpoint", worker_restore, [pieces[w]] if same else pieces, same)
                      for w in range(n)]
            del pieces
        if sum(counts) != total:
            raise ValueError(f"the partitions hold {sum(counts):,} states, the coordinator "
                             f"{total:,}")
    except (ValueError, KeyError, TypeError, IndexError) as e:
        raise ck._bad(f"the checkpoint is corrupt ({e}); write a new one with "
                      "{checkpoint}") from None
    if not same:        # partitions dealt out again: the next checkpoint writes them whole
        ck._segments = {k: v for k, v in ck._segments.items() if "/" not in k}
    ex._put_parents(0, np.asarray(parents, dtype=np.uint32))
    res, stats = ex._res, ex._res.stats
    stats.transitions, stats.max_depth = state["transitions"], state["max_depth"]
    stats.initial_states, stats.frontier = state["initial_states"], state["frontier"]
    stats.max_time = state.get("max_time")      # (None in a checkpoint written before it)
    ex._bounds.update(Bound(b) for b in state["bounds"])
    for v, idx, d in state["found"]:
        res.found.append(Counterexample(v, idx, d))
        ex._reported.add(v.identity)
    if same:
        ex.peak_workers = list(state["peak_workers"])
    ck.say_resumed()
    held = None
    if getattr(ex, "fastest", False):
        # the waiting states of partitions dealt out again are numbered w modulo n
        held = np.zeros(max(total, 1024), dtype=np.uint16)
        held[:total] = np.asarray(arrays["held"]) if same else np.arange(total) % n
    return {"depth": state["depth"], "level_base": base, "held": held,
            "waiting": dict(state.get("waiting") or {}),
            "holder": np.array(holder, dtype=np.int64) if same else
            np.arange(base, total, dtype=np.int64) % n,
            "seconds": state["seconds"]}
