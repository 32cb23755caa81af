"""The job state machine: one Enum, one transition table (issue 6 §2, issue 13).

    submitted → compiling → ready → heating → printing_front → awaiting_flip → aligning
              [→ fitted] → printing_back → done

``fitted`` (issue 14) is the review of the alignment's fit, when the last mark was measured with
``review``: the operator sees rotation, offset and residual, then ``accept`` (the back prints with
that correction) or ``re-seat`` (back to ``aligning``: the frame stays back side up, it is seated
again and every mark is measured again). Without ``review`` an accepted fit prints the back at once.
A fit the profile's tolerances refuse stays in ``aligning`` (issue 22): the marks that fitted are
kept, the bad one(s) are measured again (every one when the frame itself sits wrong); the frame is
never turned over a second time.

Plus ``paused`` (from either printing state, resumable to it), ``cancelled``, ``failed`` (with a
reason) and ``interrupted`` (the daemon stopped, or the print task failed, while the job held the
printer). A one-sided design goes from ``printing_front`` to ``done``; a plain G-code program needs
no compile (``submitted → ready``) and prints as ``printing_front``. A job that ended (``done``,
``failed``, ``cancelled``, ``interrupted``) goes back to ``ready`` when it is started again: a new
print run of the same design (the store keeps the earlier runs); an interrupted compile goes back to
``submitted`` to be compiled again.

Resuming an interrupted print (issue 16): ``resume`` on an ``interrupted`` design job (the same
verb resumes a ``paused`` one) goes to ``awaiting_check``: the printer is homed, the heaters set,
and the job waits for the operator to check the frame (``frame-ok``). Then the side it stood on is
printed from the first part (ribbon, registration mark) not proven printed: ``heating`` →
``printing_front`` (then the flip and the back as usual), or, for the back, ``aligning`` again (the
marks re-measured; a job whose front is printed and whose frame was never turned over (no
``flip-done``) goes from ``awaiting_check`` straight to ``awaiting_flip``: the flip step, told and
notified as after a front printed in one go; ``frame-ok --keep-alignment`` takes the stored correction instead and goes to
``heating`` → ``printing_back``). A part is proven printed when the ``M400`` after it was
acknowledged; the part that had begun and was not proven (at most one per interruption) is skipped
or printed again as ``resume --partial`` says. A job interrupted after its front was printed resumes
at the alignment of the back; one whose every part was proven printed is ``done`` on ``resume``.

Every state change goes through ``check_transition``. What a person can do in each state is
``COMMANDS`` (ribbonctl's verbs); a request the state does not allow raises ``IllegalTransition``
naming the command tried, the state, and the commands possible now (the API answers 409).
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
    FITTED = "fitted"
    PRINTING_BACK = "printing_back"
    PAUSED = "paused"
    DONE = "done"
    CANCELLED = "cancelled"
    FAILED = "failed"
    INTERRUPTED = "interrupted"
    AWAITING_CHECK = "awaiting_check"

    @property
    def terminal(self) -> bool:
        """The job's run has ended (``start`` begins a new run of the same design)."""
        return self in ENDED

    @property
    def holds_printer(self) -> bool:
        """The job is using the printer in this state."""
        return self in _HOLDS_PRINTER

    @property
    def streams(self) -> bool:
        """A program is being streamed to the printer (manual control is refused)."""
        return self in STREAMING

    @property
    def waits_for_person(self) -> bool:
        """Nothing happens until the operator acts (``ready`` only when not queued to print)."""
        return self in WAITING


_J = JobState
_HOLDS_PRINTER = frozenset({_J.HEATING, _J.PRINTING_FRONT, _J.AWAITING_FLIP, _J.ALIGNING, _J.FITTED,
                            _J.PRINTING_BACK, _J.PAUSED, _J.AWAITING_CHECK})
#: The run is over; the job can be printed again or deleted.
ENDED = frozenset({_J.DONE, _J.CANCELLED, _J.FAILED, _J.INTERRUPTED})
#: A program is streaming: the printer takes no manual commands.
STREAMING = frozenset({_J.HEATING, _J.PRINTING_FRONT, _J.PRINTING_BACK})
#: The job waits for the operator.
WAITING = frozenset({_J.READY, _J.AWAITING_FLIP, _J.ALIGNING, _J.FITTED, _J.PAUSED, _J.AWAITING_CHECK})
_ENDS = frozenset({_J.CANCELLED, _J.FAILED})

#: The only transitions a job makes.
TRANSITIONS: dict[JobState, frozenset[JobState]] = {
    _J.SUBMITTED: frozenset({_J.COMPILING, _J.READY}) | _ENDS,
    _J.COMPILING: frozenset({_J.READY}) | _ENDS | {_J.INTERRUPTED},
    _J.READY: frozenset({_J.HEATING}) | _ENDS,
    _J.HEATING: frozenset({_J.PRINTING_FRONT, _J.PRINTING_BACK}) | _ENDS | {_J.INTERRUPTED},
    _J.PRINTING_FRONT: frozenset({_J.AWAITING_FLIP, _J.DONE, _J.PAUSED}) | _ENDS | {_J.INTERRUPTED},
    _J.AWAITING_FLIP: frozenset({_J.ALIGNING}) | _ENDS | {_J.INTERRUPTED},
    # (a refused fit stays aligning: the bad marks are measured again, the frame is not flipped again)
    _J.ALIGNING: frozenset({_J.PRINTING_BACK, _J.FITTED}) | _ENDS | {_J.INTERRUPTED},
    # accept, or re-seat the frame (back side up) and measure the marks again
    _J.FITTED: frozenset({_J.PRINTING_BACK, _J.ALIGNING}) | _ENDS | {_J.INTERRUPTED},
    _J.PRINTING_BACK: frozenset({_J.DONE, _J.PAUSED}) | _ENDS | {_J.INTERRUPTED},
    _J.PAUSED: frozenset({_J.PRINTING_FRONT, _J.PRINTING_BACK}) | _ENDS | {_J.INTERRUPTED},
    # a new print run of the same design
    _J.DONE: frozenset({_J.READY}),
    _J.CANCELLED: frozenset({_J.READY}),
    _J.FAILED: frozenset({_J.READY}),
    # (and a compile the daemon's stop interrupted is made again)
    # (or the print is resumed where it was proven to stand: the frame is checked first)
    _J.INTERRUPTED: frozenset({_J.READY, _J.SUBMITTED, _J.CANCELLED, _J.AWAITING_CHECK, _J.DONE}),
    # (or, the front printed and the frame never turned over: the flip step)
    _J.AWAITING_CHECK: frozenset({_J.HEATING, _J.ALIGNING, _J.AWAITING_FLIP}) | _ENDS | {_J.INTERRUPTED},
}

#: What a person can do with a job in each state: ribbonctl's commands (``ribbonctl CMD JOB``).
COMMANDS: dict[JobState, tuple[str, ...]] = {
    _J.SUBMITTED: ("start", "cancel"),
    _J.COMPILING: ("start", "cancel"),
    _J.READY: ("start", "cancel", "delete"),
    _J.HEATING: ("cancel",),
    _J.PRINTING_FRONT: ("pause", "cancel"),
    _J.AWAITING_FLIP: ("flip-done", "cancel"),
    _J.ALIGNING: ("align", "cancel"),
    _J.FITTED: ("accept", "re-seat", "cancel"),
    _J.PRINTING_BACK: ("pause", "cancel"),
    _J.PAUSED: ("resume", "cancel"),
    _J.DONE: ("start", "delete"),
    _J.CANCELLED: ("start", "delete"),
    _J.FAILED: ("start", "delete"),
    _J.INTERRUPTED: ("resume", "start", "cancel", "delete"),
    _J.AWAITING_CHECK: ("frame-ok", "cancel"),
}

#: The command that asks for a state, for messages about refused transitions.
_VERB = {_J.HEATING: "start", _J.READY: "start", _J.PAUSED: "pause", _J.CANCELLED: "cancel",
         _J.ALIGNING: "flip-done", _J.PRINTING_FRONT: "resume", _J.PRINTING_BACK: "resume",
         _J.AWAITING_CHECK: "resume"}


def state_name(state: JobState, kind: str | None = None) -> str:
    """The state as people read it: a plain G-code job (``kind`` ``gcode``) prints one program, it
    has no front (``printing_front`` is ``printing (the program)``); else the state's value."""
    if kind == "gcode" and state is JobState.PRINTING_FRONT:
        return "printing (the program)"
    return state.value


class IllegalTransition(Exception):
    """A request the job's state does not allow.

    Attributes
    ----------
    current : the job's state.
    requested : the state or the command asked for.
    command : the command tried (``pause``, ``flip-done``, …).
    allowed : the commands possible now (``COMMANDS[current]``).
    allowed_states : the states the table allows next.
    """

    @classmethod
    def of(cls, job: object, requested: JobState | str, **kw: str | None) -> IllegalTransition:
        """The refusal of ``requested`` for ``job`` (a record with ``state`` and ``kind``): its
        state named as people read it (``state_name``)."""
        return cls(getattr(job, "state"), requested, kind=getattr(job, "kind", None), **kw)

    def __init__(self, current: JobState, requested: JobState | str, *, command: str | None = None,
                 hint: str | None = None, kind: str | None = None) -> None:
        self.current = current
        self.requested = requested
        if command is None:
            command = _VERB.get(requested, f"move to {requested.value}") if isinstance(requested, JobState) \
                else requested
        self.command = command
        self.allowed = list(COMMANDS[current])
        self.allowed_states = sorted(s.value for s in TRANSITIONS[current])
        possible = ", ".join(self.allowed) or "nothing"
        super().__init__(f"cannot {command}: the job is {state_name(current, kind)}; possible now: {possible}"
                         + (f" ({hint})" if hint else ""))


def check_transition(current: JobState, new: JobState) -> None:
    """Raise ``IllegalTransition`` unless ``current → new`` is in the table."""
    if new not in TRANSITIONS[current]:
        raise IllegalTransition(current, new)
