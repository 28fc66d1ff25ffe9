"""Canonical state encodings and 128-bit fingerprints.

A model checker's "exhaustive" is only as good as its notion of state
identity.  Python's ``hash()`` is not one: ``hash(-1) == hash(-2)``,
``hash(1) == hash(1.0) == hash(True)``, small ints hash to themselves, and
tuple hashes inherit all of it, so two distinct states can be merged
*deterministically*, whatever probability a report prints.

Here a state key is first turned into a **canonical byte string**
(:func:`encode`), then hashed with xxHash's ``xxh3_128`` (:func:`fingerprint`).

The encoding is ``marshal`` format version 2.  Version 2 is chosen on
purpose: from version 3 on marshal writes back-references for objects that
are referenced more than once, so two equal keys with different internal
sharing would encode differently (measured: a BFS "found" 1,957,968 states
instead of 1,066,248).  ``pickle`` memoises by identity and has the same
flaw.  Version 2 writes every object in full, and it tags each type: an
``int`` (``i``/``l``, any size), a ``float`` (8 IEEE bytes, ``g``), ``True``
/ ``False`` (``T``/``F``), ``None``, ``Ellipsis`` (PCCL's undefined value,
:data:`pccl.lang.values.UNDEF`), ``str``, ``bytes`` and tuples (length, then the
items) are all distinct.  So ``encode`` is injective on keys built from
those types, and ``--exact`` (which stores the encodings themselves) is a
sound, collision-free identity.

Not canonical, hence not allowed in keys: ``set``/``frozenset`` and ``dict``
(their order depends on history) and objects marshal cannot write (it raises
``ValueError``: "unmarshallable object", loudly rather than silently).
:func:`check_canonical` is the guard used on values that come from outside
the engine (a user blackbox's environment).

The collision bound: with ``n`` distinct states and a 128-bit hash that
behaves as a random function, the probability that any two of them share a
fingerprint is at most ``n (n - 1) / 2 / 2**128`` (the birthday bound).  That
is what :func:`collision_bound` returns and what ``pccl explore`` prints.
"""

from __future__ import annotations

import marshal

import xxhash

__all__ = ["BITS", "encode", "fingerprint", "collision_bound", "check_canonical"]

#: Width of a fingerprint.
BITS = 128

_dumps = marshal.dumps
_xxh3_128 = xxhash.xxh3_128_digest


def encode(key) -> bytes:
    """The canonical byte encoding of a state key (marshal version 2)."""
    return _dumps(key, 2)


def fingerprint(key) -> bytes:
    """The 16-byte xxh3_128 digest of :func:`encode` (``key``)."""
    return _xxh3_128(_dumps(key, 2))


def collision_bound(n: int) -> float:
    """Upper bound on the probability that ``n`` distinct states include two
    with the same fingerprint."""
    return min(1.0, n * (n - 1) / 2.0 / 2.0 ** BITS)


_ATOMS = (int, float, str, bytes, type(None), type(Ellipsis))


def check_canonical(value, what: str = "value") -> None:
    """Raise ``TypeError`` unless ``value`` is built only from types with a
    canonical encoding (ints, floats, bools, None, strings, bytes,
    ``Ellipsis`` and tuples of those)."""
    stack = [value]
    while stack:
        v = stack.pop()
        t = type(v)
        if t is tuple:
            stack.extend(v)
        elif t not in _ATOMS and t is not bool:
            raise TypeError(f"{what} holds a {t.__name__} ({v!r:.60}); state values must be "
                            "ints, floats, bools, None, strings, bytes or tuples of those")
