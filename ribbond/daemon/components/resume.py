"""Pausing and resuming the job on the printer, and resuming an interrupted print (issue 16).

A pause stops the stream at a line boundary, waits for ``M400`` (every acknowledged line executed:
an exact checkpoint), keeps the modal state and parks the head; ``resume`` restores both and goes
on. An interrupted design print resumes at a part boundary: from the parts proven printed (their
``M400`` acknowledged, ``store.part_states``), with the part begun and not proven skipped or
printed again; the printer is homed and heated and the job waits in ``awaiting_check`` until the
operator checked the frame (``frame_ok``). The print task then prints the rest (``resumed_text``).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from ribbond.design.folder import read_design_folder
from ribbond.gcode.profiles import PrinterProfile
from ribbond.printer.errors import LinkError
from ribbond.printer.link import prepare_program
from ..jobs import IllegalTransition, JobState
from ..records import JobRecords, ServiceError, has_program
from ..store import JobRecord
from .head import Head
from .heaters import Heaters
from .programs import program_parts, resumed_program
from .run import PrintState, ResumePlan


def modal_state(commands: list[str], upto: int) -> dict[str, Any]:
    """The modal state after ``commands[:upto]``: positioning and extrusion modes, feed rate,
    fan and heater targets, and the last commanded X, Y, Z (what a resumed program must restore;
    the commanded position is exact, where ``M114`` reports it rounded to 10 µm)."""
    state: dict[str, Any] = {"absolute": True, "e_absolute": True, "feed": None, "fan": 0,
                             "nozzle": None, "bed": None, "x": None, "y": None, "z": None}
    for cmd in commands[:upto]:
        words = cmd.split()
        code = words[0].upper()
        args = {w[0].upper(): w[1:] for w in words[1:] if w}
        if code == "G90":
            state["absolute"] = state["e_absolute"] = True
        elif code == "G91":
            state["absolute"] = state["e_absolute"] = False
        elif code == "M82":
            state["e_absolute"] = True
        elif code == "M83":
            state["e_absolute"] = False
        elif code in ("G0", "G1"):
            if "F" in args:
                state["feed"] = float(args["F"])
            for axis in "XYZ":                     # last commanded position (absolute moves only)
                if axis in args:
                    key = axis.lower()
                    if state["absolute"]:
                        state[key] = float(args[axis])
                    elif state[key] is not None:
                        state[key] += float(args[axis])
        elif code == "G28":
            state["x"] = state["y"] = state["z"] = None
        elif code == "M106":
            state["fan"] = int(float(args.get("S", "255")))
        elif code == "M107":
            state["fan"] = 0
        elif code in ("M104", "M109") and "S" in args:
            state["nozzle"] = float(args["S"])
        elif code in ("M140", "M190") and "S" in args:
            state["bed"] = float(args["S"])
    return state


def resumed_text(text: str, side: str, start: int, resume: ResumePlan | None, profile: PrinterProfile) -> str:
    """The program ``text`` of ``side`` from part ``start`` (from 0): the modal state before it
    restored, then the rest (``programs.resumed_program``)."""
    lines = text.splitlines()
    cut = program_parts(lines)[start].begin
    modal = modal_state(prepare_program(lines, f"{side}.gcode"), cut)
    note = f"{side} from part {start + 1}" + (f" (part {resume.partial + 1}: {resume.choice})"
                                             if resume is not None and resume.partial is not None else "")
    return "\n".join(resumed_program(lines, start, modal, profile, note)) + "\n"


class Resumer:
    """Pause and resume of the run on the printer; the resume of an interrupted job (queued on
    ``state`` for the print task, which calls ``check_frame`` first)."""

    def __init__(self, head: Head, profile: PrinterProfile, records: JobRecords, state: PrintState,
                 heaters: Heaters) -> None:
        self.head, self.profile, self.records, self.state, self.heaters = head, profile, records, state, heaters

    # ------------------------------------------------------------------ pause and resume

    async def pause(self, job_id: str) -> JobRecord:
        """Pause the print at a line boundary: an exact checkpoint once ``M400`` returns, the modal
        state and position kept for ``resume``, the filament retracted, the head parked at the
        frame's corner, the heaters by the idle policy."""
        job = self.records.get(job_id)
        run = self.state.current(job_id)
        if job.state not in (JobState.PRINTING_FRONT, JobState.PRINTING_BACK) or run is None:
            raise IllegalTransition.of(job, "pause")
        link = self.head.require_link()
        run.busy = True
        try:
            link.pause()
            if run.stream is not None:
                run.stream.paused_at = time.monotonic()
            job = self.records.transition(job_id, JobState.PAUSED, paused_from=job.state, stage="paused")
            await link.send("M400", timeout=300)
            # every acknowledged line has now been executed: an exact checkpoint
            self.records.store.record_ack(job_id, self.state.acked)
            self.records.store.checkpoint(job_id, f"{job.side or 'front'}_paused", self.state.acked)
            pos = await link.query_position()
            modal = modal_state(self.state.commands, max(self.state.acked, 0))
            exact = {k: modal[k] if modal[k] is not None else getattr(pos, k) for k in ("x", "y", "z")}
            nozzle = link.status.heaters.get("T")
            if modal["nozzle"] is None and nozzle is not None and nozzle.target:
                modal["nozzle"] = nozzle.target               # the program set it before the pause point
            run.pause_snapshot = {**modal, **exact}
            lay, mo, r = self.profile.layers, self.profile.motion, self.profile.retraction
            x0, _, _, y1 = self.profile.frame.bounds
            z = max(pos.z, lay.fabric_z) + self.profile.park_lift
            async with self.head.lock:
                for command in ("G90", "M83", f"G1 E{-r.length:.5f} F{mo.retract_speed * 60:.0f}",
                                f"G0 Z{z:.3f} F{mo.z_speed * 60:.0f}",
                                f"G0 X{x0:.3f} Y{y1:.3f} F{mo.travel_speed * 60:.0f}"):
                    await link.send(command, timeout=120)
                self.head.set((x0, y1, z))
            run.heaters = await self.heaters.idle(job_id, "paused")
        finally:
            run.busy = False
        self.records.publish(self.records.store.update(job_id, stage="paused (head parked)"),
                             snapshot=run.pause_snapshot)
        return self.records.get(job_id)

    async def resume(self, job_id: str, partial: str | None = None) -> JobRecord:
        """Resume a paused print, or an interrupted one (``resume_interrupted``; ``partial``)."""
        job = self.records.get(job_id)
        if job.state is JobState.INTERRUPTED:
            return self.resume_interrupted(job_id, partial)
        if partial is not None:  # a request the job's state does not allow: 409, as other verbs
            raise IllegalTransition.of(job, "resume", command=f"resume with partial={partial!r}",
                                    hint="only an interrupted print has a partial part")
        run = self.state.current(job_id)
        if job.state is JobState.PAUSED and run is not None and run.pause_snapshot is None:
            raise IllegalTransition.of(job, "resume", hint="the head is still being parked: resume in a "
                                    "moment, when the job's stage says 'paused (head parked)'")
        if job.state is not JobState.PAUSED or run is None or run.pause_snapshot is None:
            raise IllegalTransition.of(job, "resume")
        link = self.head.require_link()
        if run.heaters is not None:
            run.heaters.cancel()
            run.heaters = None
        commands = self._resume_commands(run.pause_snapshot)
        run.busy = True
        try:
            self.records.publish(self.records.store.update(job_id, stage="resuming: reheating"))
            async with self.head.lock:
                for command in commands:
                    await link.send(command, timeout=1200)
                self.head.forget()
            back_to = job.paused_from or JobState.PRINTING_FRONT
            what = "the program" if job.kind == "gcode" else job.side or "front"   # a plain program has no sides
            job = self.records.transition(job_id, back_to, stage=f"printing {what}")
            run.pause_snapshot = None
            if run.stream is not None and run.stream.paused_at is not None:
                run.stream.paused_s += time.monotonic() - run.stream.paused_at
                run.stream.paused_at = None
            link.resume()
        finally:
            run.busy = False
        return job

    def _resume_commands(self, snap: dict[str, Any]) -> list[str]:
        """Back to where the pause left: reheat (and wait), above the spot at the safe height, down,
        the retraction undone, the modal state (modes, fan, feed) restored."""
        mo, r = self.profile.motion, self.profile.retraction
        commands: list[str] = []
        if snap.get("nozzle"):
            commands += [f"M104 S{snap['nozzle']:.0f}", f"M109 S{snap['nozzle']:.0f}"]
        if snap.get("bed"):
            commands += [f"M140 S{snap['bed']:.0f}", f"M190 S{snap['bed']:.0f}"]
        safe_z = max(snap["z"], self.profile.layers.fabric_z + self.profile.layers.safe_height)
        commands += ["G90", f"G0 Z{safe_z:.3f} F{mo.z_speed * 60:.0f}",
                     f"G0 X{snap['x']:.3f} Y{snap['y']:.3f} F{mo.travel_speed * 60:.0f}",
                     f"G0 Z{snap['z']:.3f} F{mo.z_speed * 60:.0f}", "M83",
                     f"G1 E{r.length:.5f} F{mo.retract_speed * 60:.0f}"]
        commands.append("G90" if snap["absolute"] else "G91")
        commands.append("M82" if snap["e_absolute"] else "M83")
        if snap["fan"]:
            commands.append(f"M106 S{snap['fan']}")
        if snap.get("feed"):
            commands.append(f"G0 F{snap['feed']:.0f}")
        return commands

    # ------------------------------------------------------------------ resuming an interrupted print

    def resume_interrupted(self, job_id: str, partial: str | None = None) -> JobRecord:
        """Resume an interrupted design print where it was proven to stand (issue 16).

        The printer is homed and the heaters set, then the job waits in ``awaiting_check`` for the
        operator to check the frame (``frame_ok``); then the side it stood on prints from the
        first part not proven printed, and the rest of the job as usual. ``partial``: the part that
        had begun and was not proven printed is ``skip``ped (the default: printing it again lays a
        second bead over what was printed of it, the nozzle ploughing through it) or ``reprint``ed.

        Raises
        ------
        IllegalTransition
            the job is not interrupted.
        ServiceError
            not a design job, nothing left to print, the printer busy or not connected.
        ValueError
            ``partial`` is not ``skip`` or ``reprint``.
        """
        job = self.records.get(job_id)
        if job.state is not JobState.INTERRUPTED:
            raise IllegalTransition.of(job, "resume")
        queued = any(j.state is JobState.READY and j.start_when_ready for j in self.records.store.active())
        if self.state.run is not None or queued:
            busy = self.state.run.job_id if self.state.run is not None else "queued jobs"
            raise ServiceError(f"cannot resume job {job_id} now: the printer is busy ({busy}); resume it when "
                               "it is free")
        if not self.head.connected():
            raise LinkError("the printer is not connected (or busy): resume when it is ready")
        plan = self._plan(job, partial)
        if plan is None:
            return self.records.transition(job_id, JobState.DONE, reason="resumed: every part was proven printed, "
                                           "nothing is left to print", error=None, stage=None, start_when_ready=False)
        if plan.partial is not None:
            self.records.store.record_part(job_id, job.side or "front", plan.partial,
                                           "skipped" if plan.choice == "skip" else "reprint")
        if plan.start >= plan.parts > 0:                     # every part proven printed (or the last skipped)
            return self.records.transition(job_id, JobState.DONE, reason="resumed: every part was proven printed or "
                                           "skipped, nothing is left to print", error=None, stage=None,
                                           start_when_ready=False)
        where = (f"the {plan.side} from part {plan.start + 1} of {plan.parts}" if plan.parts
                 else "the flip (the front is printed)" if plan.flip else "the alignment of the back")
        note = f"; part {plan.partial + 1} begun and not proven printed: {plan.choice}" \
            if plan.partial is not None else ""
        job = self.records.transition(job_id, JobState.AWAITING_CHECK, reason=f"resumed at {where}{note}",
                                      stage="homing", error=None, start_when_ready=False)
        self.state.resumes[job_id] = plan
        self.state.queue_print(job_id)
        return job

    def _plan(self, job: JobRecord, partial: str | None) -> ResumePlan | None:
        """Where the interrupted ``job`` goes on: the side it stood on, from the first part not
        proven printed (a part begun and not proven: skipped or printed again, as ``partial`` says);
        None: every part of the job was proven printed (or skipped)."""
        if job.kind != "design" or not has_program(job):
            raise ServiceError(f"cannot resume job {job.id}: only a compiled design is resumed at a part "
                               f"boundary; print it again from the start: ribbonctl start {job.id}")
        if partial is not None and partial not in ("skip", "reprint"):
            raise ValueError(f"partial={partial!r}: 'skip' (leave the part begun as it is) or 'reprint'")
        design = read_design_folder(Path(job.design_dir or "")).design
        has_back = any(r.side == "back" for r in design.ribbons or [])
        front_done = job.checkpoint in ("front_done", "flip", "flipped")
        side = "back" if job.side == "back" or front_done else "front"
        if side == "back" and job.side != "back":
            # the front is printed: the flip step unless the operator said flip-done, then the
            # alignment of the back (a one-sided design is complete)
            return ResumePlan(side="back", start=0, parts=0, flip=job.checkpoint != "flipped") if has_back else None
        parts = program_parts(self._side_program(job, side))
        unproven = [p.ordinal + 1 for p in parts if p.sync is None]
        if unproven:
            raise ServiceError(f"cannot resume job {job.id}: its {side} program has no sync point after "
                               f"part(s) {unproven[:5]} (compiled by an older ribbond); start it again")
        states = self.records.store.part_states(job.id, side)
        first = next((p.ordinal for p in parts if states.get(p.ordinal) not in ("done", "skipped")), len(parts))
        partial_at, choice = (first, partial or "skip") if states.get(first) == "started" else (None, None)
        start = first + 1 if choice == "skip" else first
        if start < len(parts):
            return ResumePlan(side=side, start=start, parts=len(parts), partial=partial_at, choice=choice)
        if side == "front" and has_back:                     # every front part proven: the flip, the back
            return ResumePlan(side="back", start=0, parts=0, partial=partial_at, choice=choice, flip=True)
        return ResumePlan(side=side, start=start, parts=len(parts), partial=partial_at, choice=choice)

    def _side_program(self, job: JobRecord, side: str) -> list[str]:
        """The lines of the program of ``side`` as last printed (the back: as corrected)."""
        base = self.records.dir(job.id) / "back-corrected.gcode" if side == "back" else \
            Path(job.design_dir or "") / "front.gcode"
        if side == "back" and not base.is_file():
            base = Path(job.design_dir or "") / "back.gcode"
        return base.read_text(encoding="utf-8").splitlines()

    async def check_frame(self, job_id: str) -> None:
        """Home, set the heaters (the idle policy applies while waiting), wait for ``frame_ok``.
        A resume at the flip (``ResumePlan.flip``) sets the heaters only: the flip step is the
        operator's check (it waits for ``flip-done``), and the alignment after it homes."""
        run = self.state.run
        assert run is not None
        link = self.head.require_link()
        await self.heaters.cooled()                           # the heaters-off of the daemon's start first
        t = self.profile.temperatures
        flip = run.resume is not None and run.resume.flip
        async with self.head.lock:
            if not flip:                                      # (not over the frame about to be turned)
                await link.send("G28", timeout=300)
                self.head.forget()
                self.head.ran(["G28"])
            if t.bed > 0:
                await link.send(f"M140 S{t.bed:.0f}")
            await link.send(f"M104 S{t.nozzle:.0f}")
        run.check()
        if flip:
            return
        self.records.publish(self.records.store.update(job_id, stage="check the frame"))
        await self.heaters.idle_until(run, job_id, "awaiting the frame check", run.checked)
        run.check()

    async def frame_ok(self, job_id: str, keep_alignment: bool = False) -> JobRecord:
        """The operator checked the frame of a resumed print: go on (returns once it moved on).
        ``keep_alignment``: the back was being printed and the frame was not moved: take the stored
        correction instead of measuring the marks again."""
        job = self.records.get(job_id)
        run = self.state.current(job_id)
        if job.state is not JobState.AWAITING_CHECK or run is None or run.resume is None:
            raise IllegalTransition.of(job, "frame-ok")
        if keep_alignment and (run.resume.side != "back" or job.side != "back" or not job.correction):
            raise ValueError("keep_alignment: there is no stored alignment of this print's back to keep "
                             "(it is measured after the flip); leave it out")
        run.keep_alignment = keep_alignment
        run.checked.set()
        return await self.records.wait_state(job_id, lambda s: s is not JobState.AWAITING_CHECK, 30)
