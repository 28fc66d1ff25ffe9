"""Text views of a trace (``--view steps|swimlane``)."""

from __future__ import annotations

from . import display as D


def render(view, model, path, *, full=False, width=None) -> str:
    states, labels = path
    return "\n".join(D.format_step(model, n + 1, lab, states[n], states[n + 1])
                     for n, lab in enumerate(labels))
