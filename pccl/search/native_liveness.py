"""The native engine's part in the temporal properties' graph (issue 46).

The graph of a temporal search is recorded as for the time-lock check
(:class:`pccl.search.liveness.GraphRecorder`), with the native engine's
state vectors: the per-state columns of the temporal properties (the P/Q
bits, the robots whose doReach is under way) come from one C call per
batch, or from the level kernel's threads as each state is admitted
(``tcols`` in the generated module, native_c/temporal.c), and Tarjan's
components are computed in C (``scc``) with the numbering of the Python
reference (:meth:`pccl.search.liveness.Graph.sccs`).  What stays Python is
what reads real configurations: the lassos of a quotient graph made real
(:mod:`pccl.search.lift`) and the traces.  This module gives them the
native search seen through the Python model: :func:`lasso_view`.
"""

from __future__ import annotations

from typing import Any, Optional

import numpy as np

__all__ = ["attach_scc", "lasso_view", "native_sccs"]


class _PythonSide:
    """The Python model as :class:`pccl.search.lift.RealCycles` reads a
    search's model, its states numbered as the native search numbered them:
    ``key`` is the native key of the encoded configuration."""

    def __init__(self, py, native):
        self.py, self.native = py, native
        #: the unreduced model (RealCycles' identity of a real state: plain_key)
        self.model = getattr(py, "model", py)

    def key(self, st):
        return self.native.key(self.native.encode(st))

    def lasso_successors(self) -> tuple:
        if hasattr(self.py, "lasso_successors"):
            return self.py.lasso_successors()
        return self.py.successors, getattr(self.py, "expand_trace", lambda trace: trace)

    def successors(self, st):
        return self.py.successors(st)


class _NativeLassoView:
    """A native search (``ex``, over the vectors of ``native``) seen as a
    search over configurations: replays decode, its model is the Python
    model's (:class:`_PythonSide`), its table the search's."""

    def __init__(self, ex, native, py):
        self.ex, self.native = ex, native
        self.table = ex.table
        self.model = _PythonSide(py, native)

    def replay(self, v: int):
        return self.native.decode_trace(self.ex.replay(v))

    def replay_chain(self, chain: list):
        return self.native.decode_trace(self.ex.replay_chain(chain))

    def __getattr__(self, name):
        return getattr(self.ex, name)


def lasso_view(explorer, model) -> Any:
    """``explorer`` as :mod:`pccl.search.lift` and the lasso's replay read
    it: itself for a Python search; a native one (the explorer of a
    :class:`~pccl.model.native.NativeModel`, or its decoding view) seen
    through the Python model ``model``."""
    native = getattr(explorer, "native", None)
    if native is not None and hasattr(explorer, "ex"):     # NativeModel.decoding's view
        return _NativeLassoView(explorer.ex, native, model)
    m = getattr(explorer, "model", None)
    if m is not None and hasattr(m, "decode_trace") and hasattr(m, "encode"):
        return _NativeLassoView(explorer, m, model)
    return explorer


def native_sccs(kernel, fptr: np.ndarray, fdst: np.ndarray, nodes: np.ndarray,
                allowed: np.ndarray) -> Optional[tuple]:
    """:meth:`pccl.search.liveness.Graph.sccs` in C (``kernel``: the
    native module's ``scc``): ``(comp, nontrivial)``, or None when the
    arrays are not of the kinds it takes (the Python reference then runs)."""
    if fdst.dtype != np.uint32 or fptr.dtype not in (np.uint32, np.int64) or allowed.dtype != np.bool_:
        return None
    n = len(allowed)
    comp = np.empty(n, dtype=np.int64)
    flags = kernel(np.ascontiguousarray(fptr), np.ascontiguousarray(fdst),
                   np.ascontiguousarray(allowed).view(np.uint8),
                   np.ascontiguousarray(nodes, dtype=np.int64), comp)
    return comp, np.frombuffer(flags, dtype=np.uint8).astype(bool)


def attach_scc(graph, kernel) -> None:
    """Give ``graph`` (a :class:`pccl.search.liveness.Graph`) Tarjan in C:
    its ``sccs`` computed by ``kernel`` (the native module's ``scc``), the
    Python reference where the arrays are not of the kinds C takes.  None:
    nothing changes."""
    if kernel is None:
        return
    python = graph.sccs

    def sccs(nodes: np.ndarray, allowed: np.ndarray) -> tuple:
        got = native_sccs(kernel, graph.fptr, graph.fdst, nodes, allowed)
        return got if got is not None else python(nodes, allowed)
    graph.sccs = sccs
