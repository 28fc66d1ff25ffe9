"""Search state as plain data: the encoding of checkpoints' ``state.json``
and of ``--spill`` level files (pccl/search/checkpoint.py, spill.py).

A checkpoint or a spill file may come from elsewhere (checkpoints are moved
between machines), so reading one must not run code: no ``pickle``.  This
module writes a closed set of types as JSON and reads back only those:

===================  ===========================================
Python               JSON
===================  ===========================================
None, bool, int,     themselves (non-finite floats as JSON's
float, str           ``NaN``/``Infinity``, which Python reads)
tuple                an array (the common case: states are tuples)
list                 ``{"l": [...]}``
set, frozenset       ``{"s": [...]}``, ``{"z": [...]}``
dict                 ``{"d": [[key, value], ...]}``
bytes                ``{"b": "<base64>"}``
Ellipsis (UNDEF)     ``{"e": 0}``
numpy array          ``{"n": [dtype, shape, "<base64>"]}`` (booleans,
                     integers, floats only)
a record            ``{tag: [fields]}``: a type a higher layer
                     registers (:func:`register_record`: a violation
                     ``"v"``, a source span ``"p"``)
States (a list)      ``{"m": "<base64 of MessagePack>"}`` (below)
===================  ===========================================

A list of states (tuples or bytes: a level, a bucket, a spilled segment)
is the bulk of the data and is written as one MessagePack blob (C on both
sides: about 8 us a state against 85 us through the JSON encoding above):
its arrays are read back as tuples, bytes as bytes, Ellipsis as an
extension; no maps, no other extension.  States are immutable values (they
are hashed), so they hold no lists: a list would come back a tuple, and the
tests compare states written and read back.  A list that MessagePack
cannot hold (an integer past 64 bits) takes the JSON encoding.

:func:`loads` builds nothing else; anything unexpected (an unknown tag, a
field of the wrong type, text that is not JSON) is a :class:`DataError`.
What the values *mean* (a state number in range, a level as long as the
table says) is checked by the reader (checkpoint.py's schemas).
"""

from __future__ import annotations

import base64
import binascii
import json
from collections.abc import Callable
from typing import Any, Optional

import msgpack
import numpy as np

__all__ = ["DataError", "States", "dumps", "loads", "encode", "decode", "pack_states",
           "unpack_states", "pack_segment", "unpack_segment"]


class DataError(ValueError):
    """Data that is not what :func:`dumps` writes."""


#: the dtype kinds an array may have (no objects, no strings, no records)
_KINDS = frozenset("biuf")


class States(list):
    """A list of states, marked for the MessagePack encoding (the writer
    knows which lists are states; read back as a plain list)."""


#: MessagePack's extension code of Ellipsis (UNDEF)
_EXT_UNDEF = 1


def _mp_default(x):
    if x is Ellipsis:
        return msgpack.ExtType(_EXT_UNDEF, b"")
    raise TypeError(f"{type(x).__name__} in a state")


def _mp_ext(code: int, data: bytes):
    if code == _EXT_UNDEF and not data:
        return Ellipsis
    raise DataError(f"unknown extension {code}")


def _mp_map(pairs):
    raise DataError("a mapping in a state")


def pack_states(states: list) -> bytes:
    """A list of states as MessagePack; TypeError or OverflowError when it
    cannot be (a value of another type, an integer past 64 bits)."""
    return msgpack.packb(states, default=_mp_default, use_bin_type=True)


def pack_segment(first, states: list) -> bytes:
    """``(first number or numbers, states)`` as one MessagePack value (a
    spilled level's record); TypeError or OverflowError as
    :func:`pack_states`."""
    return msgpack.packb((first, states), default=_mp_default, use_bin_type=True)


def unpack_segment(data: bytes) -> tuple:
    """The ``(first, states)`` :func:`pack_segment` wrote (``first`` an int
    or a list of ints, ``states`` a list of states); DataError for anything
    else."""
    try:
        out = msgpack.unpackb(data, use_list=False, raw=False, ext_hook=_mp_ext,
                              object_pairs_hook=_mp_map, strict_map_key=True)
    except DataError:
        raise
    except Exception as e:          # noqa: BLE001 - malformed: msgpack's own errors
        raise DataError(f"a segment: {type(e).__name__}") from None
    if type(out) is not tuple or len(out) != 2 or type(out[1]) is not tuple:
        raise DataError("not a segment")
    first, states = out
    if type(first) is tuple:
        first = list(first)
    return first, list(states)


def unpack_states(data: bytes) -> list:
    """The states :func:`pack_states` wrote; DataError for anything else."""
    try:
        out = msgpack.unpackb(data, use_list=False, raw=False, ext_hook=_mp_ext,
                              object_pairs_hook=_mp_map, strict_map_key=True)
    except DataError:
        raise
    except Exception as e:          # malformed: msgpack's own errors, ValueError, ...
        raise DataError(f"a list of states: {type(e).__name__}") from None
    if type(out) is not tuple or not all(type(s) is tuple or type(s) is bytes for s in out):
        raise DataError("a list of states: not states")
    return list(out)


def encode(x: Any) -> Any:
    """``x`` as JSON-ready values (see the module's table); TypeError for a
    type outside it."""
    t = type(x)
    if t is tuple:
        return [encode(y) for y in x]
    if t is int or t is str or t is bool or t is float or x is None:
        return x
    if t is bytes:
        return {"b": base64.b64encode(x).decode("ascii")}
    if t is States:
        if all(type(y) is tuple or type(y) is bytes for y in x):
            try:
                return {"m": base64.b64encode(pack_states(x)).decode("ascii")}
            except (TypeError, OverflowError, ValueError):
                pass                # the JSON encoding
        return {"l": [encode(y) for y in x]}
    if t is list:
        return {"l": [encode(y) for y in x]}
    return _encode_rest(x, t)


def _encode_rest(x: Any, t: type) -> Any:
    if x is Ellipsis:
        return {"e": 0}
    if t is dict:
        return {"d": [[encode(k), encode(v)] for k, v in x.items()]}
    if t is set:
        return {"s": [encode(y) for y in x]}
    if t is frozenset:
        return {"z": [encode(y) for y in x]}
    if isinstance(x, np.ndarray):
        if x.dtype.kind not in _KINDS:
            raise TypeError(f"an array of {x.dtype} is not checkpoint data")
        a = np.ascontiguousarray(x)
        return {"n": [a.dtype.str, list(a.shape), base64.b64encode(a.tobytes()).decode("ascii")]}
    if isinstance(x, np.generic) and x.dtype.kind in _KINDS:
        return x.item()
    rec = _RECORD_TAGS.get(t)
    if rec is not None:
        tag, to_fields = rec
        return {tag: [encode(f) for f in to_fields(x)]}
    raise TypeError(f"{t.__name__} is not checkpoint data")


#: Records of the model's own types (a violation, a source span): the layer
#: that owns each registers it (:func:`register_record`, pccl/model/properties.py),
#: so this module, in the search layer, knows none of them.  tag -> (class,
#: reader of the decoded fields); class -> (tag, fields of an object).
_RECORDS: dict = {}
_RECORD_TAGS: dict = {}


def register_record(tag: str, cls: type, to_fields: Callable[[Any], tuple],
                    from_fields: Callable[[tuple], Any]) -> None:
    """Let objects of class ``cls`` be data, written as ``{tag: [fields]}``:
    ``to_fields(x)`` gives the fields (values this module can write, records
    included), ``from_fields(fields)`` builds the object from the decoded
    fields, raising :class:`DataError` for anything it does not accept."""
    if tag in _TAGS and tag not in _RECORDS:
        raise ValueError(f"tag {tag!r} is taken")
    _RECORDS[tag] = (cls, from_fields)
    _RECORD_TAGS[cls] = (tag, to_fields)

    def read(v: Any) -> Any:
        return from_fields(tuple(decode(y) for y in _items(v)))
    _TAGS[tag] = read


def record_class(tag: str) -> Optional[type]:
    """The class registered under ``tag`` (None if none is)."""
    rec = _RECORDS.get(tag)
    return rec[0] if rec is not None else None


def _int(x, what: str) -> int:
    if type(x) is not int:
        raise DataError(f"{what}: expected an integer")
    return x


def _str(x, what: str) -> str:
    if type(x) is not str:
        raise DataError(f"{what}: expected a string")
    return x


def _b64(x) -> bytes:
    try:
        return base64.b64decode(_str(x, "bytes"), validate=True)
    except (binascii.Error, ValueError):
        raise DataError("bytes: not base64") from None


def _array(v) -> np.ndarray:
    if type(v) is not list or len(v) != 3 or type(v[1]) is not list:
        raise DataError("an array: expected [dtype, shape, data]")
    try:
        dt = np.dtype(_str(v[0], "an array's type"))
    except TypeError:
        raise DataError("an array: unknown type") from None
    shape = tuple(_int(s, "an array's shape") for s in v[1])
    if dt.kind not in _KINDS or any(s < 0 for s in shape):
        raise DataError("an array: not numbers")
    raw = _b64(v[2])
    if len(raw) != dt.itemsize * int(np.prod(shape, dtype=np.int64)):
        raise DataError("an array: its data and shape do not agree")
    return np.frombuffer(raw, dtype=dt).reshape(shape).copy()


def _items(v) -> list:
    if type(v) is not list:
        raise DataError("expected an array")
    return v


def _mapping(v) -> dict:
    out = {}
    for kv in _items(v):
        if type(kv) is not list or len(kv) != 2:
            raise DataError("a mapping: expected [key, value] pairs")
        out[decode(kv[0])] = decode(kv[1])
    return out


#: tag -> its reader (given the tag's value)
_TAGS = {
    "b": _b64,
    "e": lambda v: Ellipsis,
    "m": lambda v: unpack_states(_b64(v)),
    "n": _array,
    "l": lambda v: [decode(y) for y in _items(v)],
    "s": lambda v: {decode(y) for y in _items(v)},
    "z": lambda v: frozenset(decode(y) for y in _items(v)),
    "d": _mapping,
}


def decode(x: Any) -> Any:
    """The value :func:`encode` made ``x`` of; DataError for anything else."""
    t = type(x)
    if t is list:
        return tuple([decode(y) for y in x])
    if t is int or t is str or t is bool or t is float or x is None:
        return x
    if t is not dict or len(x) != 1:
        raise DataError(f"unexpected {t.__name__}")
    (tag, v), = x.items()
    read = _TAGS.get(tag)
    if read is None:
        raise DataError(f"unknown tag {tag!r}")
    try:
        return read(v)
    except TypeError:           # an unhashable key (a list, a mapping) in a set or mapping
        raise DataError("a set or mapping with an unhashable key") from None


def dumps(x: Any) -> bytes:
    """``x`` as UTF-8 JSON (:func:`encode`)."""
    return json.dumps(encode(x), separators=(",", ":"), ensure_ascii=False).encode("utf-8")


def loads(data: bytes) -> Any:
    """The value :func:`dumps` wrote; DataError for anything else (not
    JSON, nested too deep, an unknown type)."""
    try:
        raw = json.loads(data.decode("utf-8") if isinstance(data, (bytes, bytearray)) else data)
        return decode(raw)
    except DataError:
        raise
    except (ValueError, RecursionError, UnicodeDecodeError) as e:
        raise DataError(f"not pccl data ({type(e).__name__})") from None
