"""The flip and the alignment check of the back (issues 13 and 14). After the front the job waits
for the operator to turn the frame over (``flip_done``); the head is homed and sent above each
registration mark in turn, the operator jogs the nozzle onto it (``align_mark``: ``here``, or the
jog made another way); the last mark fits a rigid correction (``ribbond.gcode.alignment``) within the
profile's tolerances. With ``review`` the fit waits in ``fitted`` for ``accept_fit`` or ``re_seat``.
A refused fit, or a re-seat, stays in ``aligning`` (issue 22): the frame is back side up already, so
it is never turned over again; the marks that fitted are kept and the bad one is measured again
(every mark when the frame itself sits wrong). The print task waits in ``align`` for the accepted
correction."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from ribbond.gcode.alignment import AlignmentRefused, check_fit, fit_rigid
from ribbond.gcode.profiles import PrinterProfile
from ribbond.gcode.program import Correction
from ..jobs import IllegalTransition, JobState
from ..records import JobRecords, ServiceError
from ..store import JobRecord
from .head import Head
from .heaters import Heaters
from .run import MarkCheck, PrintState, Run


def _marks(marks: list[int] | tuple[int, ...]) -> str:
    """``1``, ``1 and 3``, ``1, 2 and 4``."""
    names = [str(m) for m in marks]
    return names[0] if len(names) == 1 else f"{', '.join(names[:-1])} and {names[-1]}"


def aligning_guidance(j: str, al: MarkCheck | None, error: str | None) -> str:
    """What the operator does while aligning: wait for the head, or measure the mark it is above;
    after a refused fit or a re-seat, first what that means for the frame and the marks."""
    before = ""
    if al is not None and al.remeasure:
        every = len(al.remeasure) == len(al.expected)
        why = f"{error[0].upper()}{error[1:]}. " if error else ""
        before = (f"{why}Re-seat the frame, back side up (do not turn it over again); every mark is "
                  "measured again. ") if every else (
            f"{why}The frame stays back side up (do not turn it over again); "
            f"mark{'s' if len(al.kept) > 1 else ''} {_marks(al.kept)} fitted and "
            f"{'are' if len(al.kept) > 1 else 'is'} kept: measure mark{'s' if len(al.remeasure) > 1 else ''} "
            f"{_marks(al.remeasure)} again. ")
    if al is None or al.current == 0:
        nxt = al.next_mark if al is not None else 1
        return f"{before}aligning: the head is on its way above registration mark {nxt}; wait for the prompt"
    k, n = al.current, len(al.expected)
    return (f"{before}mark {k} of {n}: the head is above where mark {k} should be. Jog the nozzle "
            f"onto the mark (ribbonctl jog DX DY), then run: ribbonctl align {j} --here "
            f"(or report a jog you made another way: ribbonctl align {j} --mark {k} --jog DX DY)")


class Aligner:
    """The flip and the marks of the job on the printer. ``instruction`` is what the operator is told
    to do next (the service's guidance), sent with each mark's event."""

    def __init__(self, head: Head, profile: PrinterProfile, records: JobRecords, state: PrintState,
                 heaters: Heaters, instruction: Callable[[JobRecord], str]) -> None:
        self.head, self.profile, self.records, self.state = head, profile, records, state
        self.heaters, self.instruction = heaters, instruction

    # ------------------------------------------------------------------ the print task's side

    async def align(self, job_id: str, expected: np.ndarray, *, flipped: bool) -> Correction:
        """The flip (unless ``flipped``: the frame is turned already) and the alignment check over the
        registration marks; after a refused fit or a re-seat, the marks to measure again (the frame
        stays back side up); the accepted correction."""
        link = self.head.require_link()
        run = self.state.run
        assert run is not None
        if not flipped:
            await self.await_flip(job_id)
            # the frame is turned over: a resume from here on aligns, it does not ask for the flip again
            self.records.store.checkpoint(job_id, "flipped", self.state.acked)
        run.alignment = al = MarkCheck(expected=expected)
        self.records.transition(job_id, JobState.ALIGNING, stage="aligning")
        # the front program ended with the motors off (M84) and the frame was handled: home again
        async with self.head.lock:
            await link.send("G28", timeout=300)
            self.head.forget()
            self.head.ran(["G28"])
        run.check()
        await self._go_to_mark(1)
        while True:
            await run.aligned.wait()
            run.check()
            if al.correction is not None:
                return al.correction
            # refused or re-seated (``_reopen``, done by the operator's request): the head to the
            # first mark to measure again
            run.aligned.clear()
            await self._go_to_mark(al.next_mark or 1)

    def _reopen(self, job_id: str, al: MarkCheck) -> None:
        """After a refused fit: the bad mark measured again, the others kept (a refusal naming no
        single mark, or the frame turned or shifted: every mark, once it is re-seated). After a
        re-seat of the fit under review: every mark. The refusal is the job's ``error`` until the
        operator measures again. Done in the operator's request, so its answer finds the job so."""
        refused, every = al.refused, list(range(1, len(al.expected) + 1))
        if al.reseat:
            al.reopen(every)
            self.records.transition(job_id, JobState.ALIGNING, error=None, stage="re-seat: every mark again",
                                    reason="the operator chose to re-seat the frame")
            return
        # a residual naming a mark: that mark was misread (the others agree on a rigid motion)
        bad = refused.mark if refused is not None and refused.which == "residual" else None
        al.reopen([bad] if bad is not None else every)
        marks = ", ".join(str(m) for m in al.remeasure)
        why = str(refused) if refused is not None else "the fit could not be made"
        self.records.publish(self.records.store.update(job_id, error=f"alignment refused: {why}",
                                                       stage=f"alignment refused: mark(s) {marks} again"))

    async def await_flip(self, job_id: str) -> None:
        """Wait in ``awaiting_flip`` (the heaters by the idle policy) until ``flip_done``."""
        run = self.state.run
        assert run is not None
        job = self.records.get(job_id)
        if job.state is not JobState.AWAITING_FLIP:
            self.records.transition(job_id, JobState.AWAITING_FLIP, stage="awaiting the flip",
                                    reason="the front is printed: turn the frame over, then flip-done")
        self.records.publish(self.records.store.checkpoint(job_id, "flip", self.state.acked))
        await self.heaters.idle_until(run, job_id, "awaiting the flip", run.flip)
        run.check()

    async def _go_to_mark(self, mark: int) -> None:
        """Move the head above where mark ``mark`` (from 1) should be now, at the safe height."""
        run = self.state.run
        assert run is not None and run.alignment is not None
        al = run.alignment
        link = self.head.require_link()
        lay, mo = self.profile.layers, self.profile.motion
        x, y = (float(v) for v in al.expected[mark - 1])
        z = lay.fabric_z + lay.safe_height
        al.current = 0
        async with self.head.lock:
            for command in ("G90", f"G0 Z{z:.3f} F{mo.z_speed * 60:.0f}",
                            f"G0 X{x:.3f} Y{y:.3f} F{mo.travel_speed * 60:.0f}", "M400"):
                await link.send(command, timeout=120)
            self.head.set((x, y, z))
        al.current = mark
        job = self.records.get(run.job_id)
        self.records.publish(job)
        self.records.bus.publish({"type": "alignment", "job_id": run.job_id, "mark": mark,
                                  "marks": len(al.expected), "expected": [x, y], "message": self.instruction(job)})

    # ------------------------------------------------------------------ the operator's side

    async def flip_done(self, job_id: str) -> JobRecord:
        """The operator turned the frame over: go on to the alignment (returns once aligning)."""
        job = self.records.get(job_id)
        run = self.state.current(job_id)
        if job.state is not JobState.AWAITING_FLIP or run is None:
            raise IllegalTransition.of(job, "flip-done")
        run.flip.set()
        return await self.records.wait_state(job_id, lambda s: s is not JobState.AWAITING_FLIP, 30)

    async def align_mark(self, job_id: str, mark: int | None, jog: tuple[float, float] | None,
                         here: bool = False, review: bool = False) -> dict[str, Any]:
        """Measure registration mark ``mark`` (numbered from 1; None: the one the head was sent to):
        ``here`` takes the head's commanded position (the operator jogged the nozzle onto the mark),
        else ``jog`` (dx, dy) is the offset of the mark from where the head was sent (None: it was
        on the mark). Returns the alignment's status; the last mark ends the check. With
        ``review``, a fit within the limits waits in ``fitted`` for ``accept`` or ``re_seat``."""
        run = self.state.current(job_id)
        job = self.records.get(job_id)
        if job.state is not JobState.ALIGNING or run is None or run.alignment is None:
            raise IllegalTransition.of(job, "align")
        al = run.alignment
        k = len(al.expected)
        if al.current == 0 and (here or mark is None):
            raise ServiceError(f"cannot align yet: the head is on its way above mark {al.next_mark}; "
                               f"wait for the prompt (ribbonctl watch {job_id})")
        mark = al.current if mark is None else mark
        if not 1 <= mark <= k:
            raise ValueError(f"mark {mark} does not exist: the design has marks 1 to {k}")
        expected = (float(al.expected[mark - 1][0]), float(al.expected[mark - 1][1]))
        measured = await self._measured(expected, jog, here)
        al.measured[mark] = measured
        if job.error or al.remeasure:                  # they acted on the refusal: it is no longer news
            al.remeasure = ()
            self.records.publish(self.records.store.update(job_id, error=None, stage="aligning"))
        nxt = al.next_mark
        status: dict[str, Any] = {"mark": mark, "marks": k, "next_mark": nxt,
                                  "offset": [measured[0] - expected[0], measured[1] - expected[1]],
                                  "measured": {str(i): v for i, v in sorted(al.measured.items())}}
        if nxt is not None:
            await self._go_to_mark(nxt)
            return status
        return self._fit(job_id, run, status, review)

    async def _measured(self, expected: tuple[float, float], jog: tuple[float, float] | None,
                        here: bool) -> tuple[float, float]:
        """Where the mark is: the head's position (``here``), or ``expected`` moved by ``jog``."""
        if here:
            if jog is not None:
                raise ValueError("give either --here (the head is on the mark) or a jog, not both")
            async with self.head.lock:
                x, y, _ = await self.head.where(self.head.require_link())
            return (x, y)
        dx, dy = jog or (0.0, 0.0)
        if not (np.isfinite(dx) and np.isfinite(dy)):
            raise ValueError("the jog must be two finite numbers (mm)")
        return (expected[0] + float(dx), expected[1] + float(dy))

    def _fit(self, job_id: str, run: Run, status: dict[str, Any], review: bool) -> dict[str, Any]:
        """Every mark is in: the fit, checked against the profile's tolerances; accepted, or (with
        ``review``) shown in ``fitted``. ``status`` gets the fit."""
        al = run.alignment
        assert al is not None
        # the fit is made once, here; the printer task takes its result from ``al``
        fit = fit_rigid(al.expected, np.array([al.measured[i] for i in range(1, len(al.expected) + 1)]))
        status["fit"] = {"rotation_deg": fit.rotation_deg, "offset": list(fit.offset),
                         "rms_mm": fit.rms, "max_residual_mm": fit.max_residual}
        tol = self.profile.alignment
        try:
            check_fit(fit, max_residual=tol.max_residual, max_rotation_deg=tol.max_rotation_deg,
                      max_offset=tol.max_offset)
        except BaseException as exc:  # refused, or the check itself failed: these marks again
            if isinstance(exc, AlignmentRefused):
                al.refused = exc
            self._reopen(job_id, al)
            run.aligned.set()
            raise
        al.correction = fit.correction()
        if review:
            al.fit = status["fit"]
            self.records.transition(job_id, JobState.FITTED, stage="the fit is ready: accept or re-seat")
            status["review"] = True
            return status
        status["accepted"] = True
        run.aligned.set()
        return status

    def _fitted_run(self, job_id: str, command: str) -> Run:
        run = self.state.current(job_id)
        job = self.records.get(job_id)
        if job.state is not JobState.FITTED or run is None or run.alignment is None:
            raise IllegalTransition.of(job, command)
        return run

    async def accept_fit(self, job_id: str) -> JobRecord:
        """The operator accepts the fit under review: the back prints with it (returns once printing)."""
        run = self._fitted_run(job_id, "accept")
        run.aligned.set()
        return await self.records.wait_state(job_id, lambda s: s is not JobState.FITTED, 30)

    async def re_seat(self, job_id: str) -> JobRecord:
        """The operator refuses the fit under review: the frame is seated again (back side up, not
        turned over) and every mark measured again (returns once aligning)."""
        run = self._fitted_run(job_id, "re-seat")
        al = run.alignment
        assert al is not None
        al.correction = None
        al.reseat = True
        self._reopen(job_id, al)
        run.aligned.set()
        return await self.records.wait_state(job_id, lambda s: s is not JobState.FITTED, 30)
