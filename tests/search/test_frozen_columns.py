"""What the graph recorder keeps for the frozen-team check
(pccl/search/liveness.py ``FrozenColumns``): each transition's label
number, each state's progress signature and change flag, and whether all
of it came (``whole``: else the check explores again)."""

from __future__ import annotations

import numpy as np

from pccl.search.liveness import FrozenColumns


class _Model:
    """States are (progress, anything) pairs; no native label list."""


def sigs(states):
    return np.asarray([progress for progress, _ in states], dtype=np.int64)


def test_labels_are_numbered_and_changes_flagged():
    fz = FrozenColumns(_Model(), sigs)
    fz.states([(0, "a"), (0, "b"), (1, "c")])
    src, dst = np.asarray([0, 0, 1]), np.asarray([1, 2, 0])
    fz.edges(src, dst, [("EVENT SELECT", 0, 1), ("STATEMENT", 0, 3), ("EVENT SELECT", 0, 1)],
             None, False)
    assert fz.whole
    labels = fz.label_list()
    assert [labels[k] for k in fz.lab.view()] == [("EVENT SELECT", 0, 1), ("STATEMENT", 0, 3),
                                                 ("EVENT SELECT", 0, 1)]
    # state 0 reaches state 2 (progress 0 -> 1); state 1 goes to 0 (0 -> 0)
    assert fz.pchg.view().tolist() == [1, 0, 0]


def test_changes_on_the_successors_as_made():
    """Under symmetry a target number stands for a renamed state: the
    change is decided on the successor the recorder is given."""
    fz = FrozenColumns(_Model(), sigs)
    fz.states([(0, "a"), (0, "b")])
    fz.edges(np.asarray([0]), np.asarray([1]), [("STATEMENT", 0, 0)], [(7, "as made")], True)
    assert fz.whole and fz.pchg.view().tolist() == [1, 0]


def test_a_transition_without_its_label_makes_the_graph_partial():
    fz = FrozenColumns(_Model(), sigs)
    fz.states([(0, "a"), (0, "b")])
    fz.edges(np.asarray([0]), np.asarray([1]), None, None, False)
    assert not fz.whole
    fz = FrozenColumns(_Model(), sigs)
    fz.states([(0, "a"), (0, "b")])
    fz.edges(np.asarray([0]), np.asarray([1]), [("STATEMENT", 0, 0)], None, True)   # no states
    assert not fz.whole


def test_native_label_numbers_are_kept_as_given():
    class Native:
        label_list = [("EVENT SELECT", 0, 0), ("TIME ADVANCE", None, None)]
    fz = FrozenColumns(Native(), sigs)
    fz.states([(0, "a"), (0, "b")])
    fz.edges(np.asarray([0, 1]), np.asarray([1, 0]), np.asarray([1, 0], dtype=np.int32), None,
             False)
    assert fz.lab.view().tolist() == [1, 0] and fz.label_list() == Native.label_list
