"""One Tarjan for both graph analyses (pccl/search/scc.py): the liveness
graph's components over its CSR arrays (``Graph.sccs``, restricted to a
subgraph) and the exact fairness search's over adjacency lists
(``lift._tarjan``) are the same components, and both are the brute-force
ones (mutual reachability) on generated graphs."""

from __future__ import annotations

import random

import numpy as np
import pytest

from pccl.search import lift
from pccl.search.liveness import Graph
from pccl.search.scc import tarjan


def _random_graph(rng: random.Random, n: int, density: float) -> list:
    """Adjacency lists of ``n`` nodes, self-loops and parallel edges included."""
    return [[w for w in range(n) if rng.random() < density] + ([v] if rng.random() < 0.1 else [])
            for v in range(n)]


def _csr_graph(adj: list) -> Graph:
    n = len(adj)
    esrc = np.asarray([v for v in range(n) for _ in adj[v]], dtype=np.uint32)
    fdst = np.asarray([w for v in range(n) for w in adj[v]], dtype=np.uint32)
    return Graph(n, None, fdst, esrc, np.ones(n, dtype=bool), np.zeros(n, dtype=np.uint64),
                 np.zeros(n, dtype=bool))


def _brute(adj: list, roots: list, allowed: list) -> tuple[set, dict]:
    """The components reached from ``roots`` inside ``allowed`` (each a
    frozenset) and, per component, whether it has a cycle."""
    n = len(adj)
    reach = [set() for _ in range(n)]           # reach[v]: nodes reachable from v in one or more steps
    for v in range(n):
        if not allowed[v]:
            continue
        todo = [w for w in adj[v] if allowed[w]]
        while todo:
            w = todo.pop()
            if w not in reach[v]:
                reach[v].add(w)
                todo.extend(x for x in adj[w] if allowed[x])
    seen = set()
    for r in roots:
        seen |= {r} | reach[r]
    comps, cyclic = set(), {}
    for v in seen:
        c = frozenset({v} | {w for w in reach[v] if v in reach[w]})
        comps.add(c)
        cyclic[c] = len(c) > 1 or v in reach[v]
    return comps, cyclic


def _partition(comp, nontrivial) -> tuple[set, dict]:
    members: dict = {}
    for v, c in enumerate(np.asarray(comp).tolist()):
        if c >= 0:
            members.setdefault(c, set()).add(v)
    comps = {frozenset(m) for m in members.values()}
    return comps, {frozenset(m): bool(nontrivial[c]) for c, m in members.items()}


@pytest.mark.parametrize("seed", range(40))
def test_the_two_graph_forms_give_the_brute_force_components(seed):
    rng = random.Random(seed)
    n = rng.randrange(0, 30)
    adj = _random_graph(rng, n, rng.choice([0.02, 0.08, 0.2]))
    g = _csr_graph(adj)
    # the whole graph: liveness's CSR form and lift's adjacency lists agree with brute force
    want, cyclic = _brute(adj, list(range(n)), [True] * n)
    got, got_cyclic = _partition(*g.sccs(np.arange(n), np.ones(n, dtype=bool)))
    assert got == want and got_cyclic == cyclic
    labelled = [[(f"e{v}{w}", w) for w in adj[v]] for v in range(n)]
    assert _partition(lift._tarjan(labelled), [True] * n)[0] == want
    # a subgraph from some roots (as the fairness and leads-to checks ask)
    allowed = [rng.random() < 0.7 for _ in range(n)]
    roots = [v for v in range(n) if allowed[v] and rng.random() < 0.3]
    want, cyclic = _brute(adj, roots, allowed)
    comp, nontrivial = g.sccs(np.asarray(roots, dtype=np.int64), np.asarray(allowed, dtype=bool))
    assert _partition(comp, nontrivial) == (want, cyclic)
    # ids in completion order: an edge between components goes to an earlier id
    for v in range(n):
        for w in adj[v]:
            if comp[v] >= 0 and comp[w] >= 0 and comp[v] != comp[w]:
                assert comp[w] < comp[v]


def test_a_long_chain_needs_no_recursion():
    """A path of 5,000 nodes closing into one cycle: one component, found
    without Python's recursion limit."""
    n = 5_000
    comp, nontrivial = tarjan(n, [0], lambda v: [(v + 1) % n])
    assert set(comp.tolist()) == {0} and nontrivial.tolist() == [True]
    comp, nontrivial = tarjan(n, [0], lambda v: [v + 1] if v + 1 < n else [])
    assert len(set(comp.tolist())) == n and not nontrivial.any()
