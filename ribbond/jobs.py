"""The job state machine: one Enum, one transition table (issue 6 §2).

    submitted → compiling → ready → heating → printing_front → awaiting_flip → aligning
              → printing_back → done

plus ``paused`` (from either printing state, resumable to it), ``cancelled``, ``failed`` (with a
reason) and ``interrupted`` (the daemon stopped while the job held the printer). A one-sided design
goes from ``printing_front`` to ``done``. Every state change goes through ``check_transition``; a
request the current state does not allow raises ``IllegalTransition`` naming the state and what is
allowed (the API answers it with HTTP 409).
"""

from __future__ import annotations

import enum


class JobState(enum.Enum):
    SUBMITTED = "submitted"
    COMPILING = "compiling"
    READY = "ready"
    HEATING = "heating"
    PRINTING_FRONT = "printing_front"
    AWAITING_FLIP = "awaiting_flip"
    ALIGNING = "aligning"
    PRINTING_BACK = "printing_back"
    PAUSED = "paused"
    DONE = "done"
    CANCELLED = "cancelled"
    FAILED = "failed"
    INTERRUPTED = "interrupted"

    @property
    def terminal(self) -> bool:
        """No transition leaves this state (``interrupted`` may be resumed as a new run)."""
        return not TRANSITIONS[self]

    @property
    def holds_printer(self) -> bool:
        """The job is using the printer in this state."""
        return self in _HOLDS_PRINTER


_J = JobState
_HOLDS_PRINTER = frozenset({_J.HEATING, _J.PRINTING_FRONT, _J.AWAITING_FLIP, _J.ALIGNING,
                            _J.PRINTING_BACK, _J.PAUSED})
_ENDS = frozenset({_J.CANCELLED, _J.FAILED})

#: The only transitions a job makes.
TRANSITIONS: dict[JobState, frozenset[JobState]] = {
    _J.SUBMITTED: frozenset({_J.COMPILING}) | _ENDS,
    _J.COMPILING: frozenset({_J.READY}) | _ENDS | {_J.INTERRUPTED},
    _J.READY: frozenset({_J.HEATING}) | _ENDS,
    _J.HEATING: frozenset({_J.PRINTING_FRONT, _J.PRINTING_BACK}) | _ENDS | {_J.INTERRUPTED},
    _J.PRINTING_FRONT: frozenset({_J.AWAITING_FLIP, _J.DONE, _J.PAUSED}) | _ENDS | {_J.INTERRUPTED},
    _J.AWAITING_FLIP: frozenset({_J.ALIGNING}) | _ENDS | {_J.INTERRUPTED},
    _J.ALIGNING: frozenset({_J.PRINTING_BACK, _J.AWAITING_FLIP}) | _ENDS | {_J.INTERRUPTED},
    _J.PRINTING_BACK: frozenset({_J.DONE, _J.PAUSED}) | _ENDS | {_J.INTERRUPTED},
    _J.PAUSED: frozenset({_J.PRINTING_FRONT, _J.PRINTING_BACK}) | _ENDS | {_J.INTERRUPTED},
    _J.DONE: frozenset(),
    _J.CANCELLED: frozenset(),
    _J.FAILED: frozenset(),
    _J.INTERRUPTED: frozenset({_J.CANCELLED}),
}


class IllegalTransition(Exception):
    """A state change the transition table does not allow."""

    def __init__(self, current: JobState, requested: JobState | str) -> None:
        self.current = current
        self.requested = requested
        self.allowed = sorted(s.value for s in TRANSITIONS[current])
        name = requested.value if isinstance(requested, JobState) else requested
        super().__init__(f"cannot {name} a job that is {current.value}; from {current.value} a job can go to: "
                         + (", ".join(self.allowed) or "nothing (it is finished)"))


def check_transition(current: JobState, new: JobState) -> None:
    """Raise ``IllegalTransition`` unless ``current → new`` is in the table."""
    if new not in TRANSITIONS[current]:
        raise IllegalTransition(current, new)
