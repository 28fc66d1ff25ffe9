"""Strongly connected components (iterative Tarjan) of a graph given by a
successor accessor: one function for the graph analyses over the recorded
CSR arrays (:meth:`pccl.search.liveness.Graph.sccs`) and for the exact
fairness search over real states (:mod:`pccl.search.lift`)."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import Any

import numpy as np


def tarjan(n: int, roots: Iterable[int], succ: Callable[[int], Any],
           allowed: Any = None) -> tuple[np.ndarray, np.ndarray]:
    """The strongly connected components of the graph over the nodes
    ``0..n-1`` whose successors are ``succ(v)`` (a sequence of node numbers,
    such as a slice of a CSR array), restricted to the nodes ``allowed``
    (a boolean per node; None: all), reached from ``roots`` (each an
    allowed node).  Returns ``(comp, nontrivial)``: the component id per
    node (-1 where not reached), ids in the order the components are
    completed (a component's successors' components first), and per
    component whether it has a cycle (more than one node, or a self-loop).
    Iterative, so deep graphs do not reach Python's recursion limit."""
    index = np.full(n, -1, dtype=np.int64)
    low = np.zeros(n, dtype=np.int64)
    comp = np.full(n, -1, dtype=np.int64)
    onstack = np.zeros(n, dtype=bool)
    stack: list = []
    nontrivial: list = []
    counter = 0
    for root in roots:
        if index[root] >= 0:
            continue
        work = [(root, succ(root), 0)]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        onstack[root] = True
        while work:
            v, out, e = work[-1]
            end = len(out)
            descended = False
            while e < end:
                w = int(out[e])
                e += 1
                if allowed is not None and not allowed[w]:
                    continue
                if index[w] < 0:
                    work[-1] = (v, out, e)
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    onstack[w] = True
                    work.append((w, succ(w), 0))
                    descended = True
                    break
                if onstack[w] and index[w] < low[v]:
                    low[v] = index[w]
            if descended:
                continue
            work.pop()
            if work:
                u = work[-1][0]
                if low[v] < low[u]:
                    low[u] = low[v]
            if low[v] == index[v]:
                cid = len(nontrivial)
                size = 0
                while True:
                    w = stack.pop()
                    onstack[w] = False
                    comp[w] = cid
                    size += 1
                    if w == v:
                        break
                nontrivial.append(size > 1 or bool(v in out))
    return comp, np.asarray(nontrivial, dtype=bool)
