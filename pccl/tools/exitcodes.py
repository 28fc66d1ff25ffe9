"""Exit statuses: the default ones (0/1/2/130/143) and ``--exit-codes
detailed``, which tells the kinds of violation apart for scripts (as TLC's
exit codes do).  docs/language.md ("Exit codes") has the table."""

from __future__ import annotations

from collections.abc import Iterable

#: ``--exit-codes detailed``: the status of a violation by its kind.  0, 2,
#: 130 and 143 keep their meaning; 1 stays for a kind not listed here.
DETAILED = {
    "deadlock": 11, "stall": 11, "stalled": 11,          # the team can never progress
    "frozen": 11,
    "invariant": 12, "collision": 12,                    # a bad state (safety)
    "liveness": 13, "response": 13, "unreachable": 13,   # temporal properties
    "eventually": 13, "leadsto": 13, "within": 13, "reachable": 13,
    "assert": 14, "stuck": 14,                           # an agent's runtime failure
    "timelock": 15,                                      # time can never pass
    "max-steps": 16,                                     # a run stopped as looping
}

#: the rows of the documented table, in order: (status, meaning)
TABLE = [
    (11, "deadlock, stall or frozen team (explore), deadlock or stalled run (run)"),
    (12, "invariant violated (the program's invariant:, --invariant), or collision"),
    (13, "a temporal property: liveness lasso, bounded response missed, `reachable P` "
         "unreachable, or a run's --property violated"),
    (14, "failed assertion or stuck agent (a runtime error)"),
    (15, "time-lock"),
    (16, "run stopped by --max-steps (an event that never ends)"),
]


def status(code: int, kinds: Iterable[str], mode: str = "default") -> int:
    """The exit status: ``code`` (the default status) unless ``mode`` is
    ``detailed`` and ``code`` is 1; then the status of the first violation's
    kind (``kinds`` in the order reported)."""
    if mode != "detailed" or code != 1:
        return code
    for k in kinds:
        if k in DETAILED:
            return DETAILED[k]
    return 1
