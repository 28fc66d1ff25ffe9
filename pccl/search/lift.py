"""Lassos of a quotient graph made real (issue 46).

Under ``symmetry`` (a state number stands for an orbit of states under
renaming agents) and ``dead`` (for a class of states that differ only in
values no step reads again) the recorded graph is a *quotient* of the
rules' graph.  A cycle of the quotient is a real run only up to the
equivalence: walked from a real state it comes back to a renamed state, or
to one with other dead values, not necessarily to the state it left.
docs/reductions.md ("Temporal properties under symmetry and dead") proves
that a fair accepting component of the quotient still stands for a fair
accepting cycle of the rules reachable from *any* real state of it: this
module finds that cycle by a search over real states (identified by the
unreduced identity, ``plain_key``) whose state numbers lie in the
component.  It serves two purposes:

* the counterexample of a liveness property under these reductions: the
  lasso's prefix is replayed as every counterexample is, and the cycle
  after it is this real cycle, so the printed lasso really closes;
* the fairness of a component under symmetry when the state numbers'
  representatives cannot decide it (fair arrival is per robot, and a
  representative shows robots renamed): the real search decides it
  exactly.
"""

from __future__ import annotations

from typing import Optional

import numpy as np

from pccl.search.scc import tarjan

__all__ = ["RealCycles"]


class RealCycles:
    """Searches over the real states whose state numbers lie in a set of
    the recorded graph (a component), from one real state.

    ``explorer``: the search that recorded the graph (its model's
    ``successors`` and ``key``, its table's numbering); ``dyn``: per state
    number whether it is a dynamic state (entered by TIME ADVANCE, a
    property of the whole class); ``n_fair``: the robots whose arrival is
    fair (0: no fairness); ``pending``: a real state's bit mask of robots
    under way."""

    def __init__(self, explorer, dyn: np.ndarray, n_fair: int, pending=None):
        m = explorer.model
        table = explorer.table
        key, key_of, index_of = m.key, table.key_of, table.index_of
        #: the transitions searched, and what expands a trace of them
        #: (under por: the ample sets of every eligible agent, so that the
        #: graph holds the reduced graph's transitions of every renaming)
        if hasattr(m, "lasso_successors"):
            self.successors, self.expand = m.lasso_successors()
        else:
            self.successors, self.expand = m.successors, (lambda trace: trace)
        self.number = lambda s: index_of(key_of(key(s)))
        inner = getattr(m, "model", m)
        self.ident = inner.plain_key
        self.dyn = dyn
        self.n_fair = n_fair
        self.pending = pending

    def explore(self, c, inside: np.ndarray) -> tuple:
        """The real states reachable from ``c`` through states numbered in
        ``inside``: ``(states, adj, parent)`` with ``adj[i]`` the
        ``(label, j)`` transitions of state i and ``parent[j]`` the
        ``(i, label)`` it was first reached by (breadth-first)."""
        ids = {self.ident(c): 0}
        states: list = [c]
        nums: list = [self.number(c)]
        parent: list = [None]
        adj: list = []
        i = 0
        while i < len(states):
            out = []
            for lab, t in self.successors(states[i]):
                q = self.number(t)
                if q < 0 or not inside[q]:
                    continue
                k = self.ident(t)
                j = ids.get(k)
                if j is None:
                    j = len(states)
                    ids[k] = j
                    states.append(t)
                    nums.append(q)
                    parent.append((i, lab))
                out.append((lab, j))
            adj.append(out)
            i += 1
        self._nums = nums
        return states, adj, parent

    def _fair_masks(self, states: list) -> list:
        """Per robot, the states (indexes) where it is not under way."""
        if not self.n_fair:
            return []
        pend = [int(self.pending(s)) for s in states]
        return [{i for i, p in enumerate(pend) if not (p >> r) & 1} for r in range(self.n_fair)]

    def fair_component(self, c, inside: np.ndarray) -> Optional[tuple]:
        """A fair accepting cycle of real states reachable from ``c`` inside
        ``inside``: ``(steps, k)``, the ``(label, state)`` steps of the path
        from c to the cycle's first state (the first ``k``), then of the
        cycle from it back to it (at least one step), visiting a dynamic
        state and, for every fair robot, a state where it is not under way.
        None when there is none."""
        states, adj, parent = self.explore(c, inside)
        dyn = [bool(self.dyn[q]) for q in self._nums]
        idle = self._fair_masks(states)
        best = self._first_fair(adj, dyn, idle)
        if best is None:
            return None
        d = min(best)                          # the first reached: a shortest path
        path = []
        v = d
        while parent[v] is not None:
            u, lab = parent[v]
            path.append((lab, v))
            v = u
        path.reverse()
        musts = [{i for i in best if dyn[i]}] + [s & best for s in idle]
        order = _visit(adj, d, musts, best)
        cycle = []
        for a, b in zip(order, order[1:]):
            lab = next(lab for lab, j in adj[a] if j == b)
            cycle.append((lab, b))
        self._states = states
        return self.walk(c, path + cycle), len(path)

    @staticmethod
    def _first_fair(adj: list, dyn: list, idle: list) -> Optional[set]:
        """The fair accepting component (a set of indexes) whose first
        state was reached first, or None: a cycle, a dynamic state, and for
        every fair robot a state where it is not under way."""
        members: dict = {}
        for i, cid in enumerate(_tarjan(adj)):
            members.setdefault(cid, []).append(i)
        best: Optional[set] = None
        for mem in members.values():
            if len(mem) == 1 and not any(j == mem[0] for _, j in adj[mem[0]]):
                continue                       # no cycle
            ms = set(mem)
            if not any(dyn[i] for i in mem):
                continue                       # a zero-time cycle: not a run
            if any(not (ms & s) for s in idle):
                continue                       # some robot under way throughout
            if best is None or min(ms) < min(best):
                best = ms
        return best

    def walk(self, c, steps: list) -> list:
        """The steps ``[(label, index)]`` found by :meth:`fair_component`
        re-executed from ``c``: ``[(label, state)]``, each state the very
        successor the rules make (a state found earlier under the same
        identity may differ in what the identity leaves out: the clock under
        time abstraction)."""
        out = []
        cur = c
        for lab, j in steps:
            want = self.ident(self._states[j])
            cur = next(t for lb, t in self.successors(cur) if lb == lab and self.ident(t) == want)
            out.append((lab, cur))
        return out

    def has_fair_cycle(self, c, inside: np.ndarray) -> bool:
        return self.fair_component(c, inside) is not None


def _visit(adj: list, d: int, musts: list, inside: set) -> list:
    """A cycle ``[d, ..., d]`` (at least one step) inside ``inside`` that
    visits a state of each set in ``musts``, in order."""
    order = [d]
    cur = d
    for goal in musts:
        if cur not in goal:
            order.extend(_bfs(adj, cur, goal, inside))
            cur = order[-1]
    back: Optional[list] = None
    for _, j in adj[cur]:
        if j not in inside:
            continue
        seg = [j] + ([] if j == d else _bfs(adj, j, {d}, inside))
        if back is None or len(seg) < len(back):
            back = seg
    assert back is not None, "a component with a cycle has a way back"
    return order + back


def _bfs(adj: list, start: int, goal: set, allowed: set) -> list:
    """The states after ``start`` on a shortest path to ``goal`` inside
    ``allowed`` (``[]`` when start is in goal)."""
    if start in goal:
        return []
    par: dict = {start: -1}
    front = [start]
    while front:
        nxt = []
        for v in front:
            for _, w in adj[v]:
                if w in par or w not in allowed:
                    continue
                par[w] = v
                if w in goal:
                    out = [w]
                    while par[out[-1]] != start:
                        out.append(par[out[-1]])
                    return out[::-1]
                nxt.append(w)
        front = nxt
    raise AssertionError("a goal inside a strongly connected component is reachable")


def _tarjan(adj: list) -> list:
    """Component id per state of the graph ``adj`` (lists of ``(label,
    successor)``; :func:`pccl.search.scc.tarjan`)."""
    comp, _ = tarjan(len(adj), range(len(adj)), lambda v: [j for _, j in adj[v]])
    return comp.tolist()
