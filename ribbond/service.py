"""The daemon's business logic: jobs from upload to done, on one printer (issue 6).

``RibbonService`` owns the job store, the compile queue (each compile a ``ribbond.worker``
subprocess, so the event loop that feeds the printer never computes a design) and the print queue
(one job on the printer at a time). It drives each job through the states of ``ribbond.jobs``:
heating and the front program, the host's own pause for the flip (the head parked, the heaters by
the configured policy), the alignment check over the registration marks, the back program
re-rendered with the fitted correction, done. It knows nothing of HTTP (``api.py`` maps its
methods and exceptions to routes and status codes) and parses no printer answers (``PrinterLink``
does).

Every state change is committed to the store before it is published. What the printer
acknowledged is queued, not executed: ``last_acked_line`` is recorded as streaming goes, and the
synchronized checkpoints (after ``M400``: the front done, the flip) say honestly where an
interrupted job could be resumed from.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import os
import re
import shutil
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .alignment import AlignmentRefused, check_fit, expected_marks, fit_rigid
from .config import DaemonConfig
from .design.folder import read_design_folder
from .design.params import DesignParameters
from .gcode.profiles import PrinterProfile
from .gcode.program import Correction, SidePlan, flip_message, render_side
from .jobs import TRANSITIONS, IllegalTransition, JobState
from .printer.errors import LinkError, StreamCancelled
from .printer.link import LinkState, PrinterLink, prepare_program
from .printer.sender import StreamProgress
from .store import JobRecord, JobStore

log = logging.getLogger(__name__)

#: Acknowledged-line checkpoints are written at most this often while streaming, seconds.
ACK_INTERVAL_S = 0.5
#: Extensions of the mesh formats the engine reads.
MESH_SUFFIXES = (".obj", ".off", ".stl", ".ply")


def worker_command(python: str, mesh: str, out: Path, parameters: dict[str, Any], plans: Path) -> list[str]:
    """The command line of one compile (``python -m ribbond.worker``)."""
    return [python, "-m", "ribbond.worker", mesh, str(out), "--params", json.dumps(parameters),
            "--plans", str(plans)]


def worker_environment() -> dict[str, str]:
    """The compile's environment: its numeric libraries use all cores but one, which is left to
    the event loop that feeds the printer (the worker also runs at nice +10)."""
    threads = str(max(1, (os.cpu_count() or 2) - 1))
    limits = {name: threads for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}
    return {**os.environ, **limits}


class ServiceError(Exception):
    """A request that cannot be done now, with the reason (the API answers 409)."""


class NotFound(ServiceError):
    """No such job or file (the API answers 404)."""


class EventBus:
    """Fan-out of events to live subscribers (server-sent events); a slow one loses old events."""

    def __init__(self) -> None:
        self._subscribers: set[asyncio.Queue[dict[str, Any]]] = set()

    def subscribe(self) -> asyncio.Queue[dict[str, Any]]:
        q: asyncio.Queue[dict[str, Any]] = asyncio.Queue(maxsize=256)
        self._subscribers.add(q)
        return q

    def unsubscribe(self, q: asyncio.Queue[dict[str, Any]]) -> None:
        self._subscribers.discard(q)

    def publish(self, event: dict[str, Any]) -> None:
        for q in list(self._subscribers):
            if q.full():
                with contextlib.suppress(asyncio.QueueEmpty):
                    q.get_nowait()
            q.put_nowait(event)


@dataclass
class _Alignment:
    """The alignment check of one job: expected mark positions (back-side) and what was measured."""

    expected: np.ndarray
    measured: dict[int, tuple[float, float]] = field(default_factory=dict)
    correction: Correction | None = None        # the accepted fit, once every mark is in
    refused: AlignmentRefused | None = None     # or why it was refused

    @property
    def next_mark(self) -> int | None:
        missing = [i for i in range(len(self.expected)) if i not in self.measured]
        return missing[0] if missing else None


@dataclass
class _Run:
    """What the printer task knows of the job it is printing."""

    job_id: str
    flip: asyncio.Event = field(default_factory=asyncio.Event)
    aligned: asyncio.Event = field(default_factory=asyncio.Event)
    alignment: _Alignment | None = None
    pause_snapshot: dict[str, Any] | None = None
    cancel_requested: bool = False


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


class RibbonService:
    """Jobs on one printer. Create it in the event loop; ``start()`` its tasks; ``close()``."""

    def __init__(self, config: DaemonConfig, profile: PrinterProfile, store: JobStore,
                 link: PrinterLink | None, *, python: str = sys.executable) -> None:
        self.config = config
        self.profile = profile
        self.store = store
        self.link = link
        self.bus = EventBus()
        self.python = python
        self.jobs_dir = Path(config.state_dir) / "jobs"
        self.jobs_dir.mkdir(parents=True, exist_ok=True)
        self._compile_queue: asyncio.Queue[str] = asyncio.Queue()
        self._print_queue: asyncio.Queue[str] = asyncio.Queue()
        self._tasks: list[asyncio.Task[None]] = []
        self._compiling: dict[str, asyncio.subprocess.Process] = {}
        self._run: _Run | None = None
        self._acked = -1                 # program lines acknowledged in the current stream
        self._eta: dict[str, float] = {}  # seconds left of the program a job is streaming
        self._run_commands: list[str] = []

    # ------------------------------------------------------------------ life cycle

    def start(self) -> None:
        """Mark jobs the last daemon left holding the printer as interrupted; start the queues."""
        for job in self.store.mark_interrupted("the daemon stopped while this job was running"):
            self._publish(job)
        for job in self.store.active():
            if job.state is JobState.SUBMITTED:
                self._compile_queue.put_nowait(job.id)
            elif job.state is JobState.READY and job.start_when_ready:
                self._print_queue.put_nowait(job.id)
        self._tasks = [asyncio.create_task(self._compile_loop(), name="compile"),
                       asyncio.create_task(self._print_loop(), name="print")]

    async def close(self) -> None:
        for proc in self._compiling.values():
            with contextlib.suppress(ProcessLookupError):
                proc.kill()
        for task in self._tasks:
            task.cancel()
        for task in self._tasks:
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task

    # ------------------------------------------------------------------ events

    def _publish(self, job: JobRecord, **extra: Any) -> None:
        self.bus.publish({"type": "job", "job": job.model_dump(mode="json"), **extra})

    def _transition(self, job_id: str, new: JobState, **fields: Any) -> JobRecord:
        job = self.store.transition(job_id, new, **fields)     # committed before it is published
        log.info("job %s -> %s%s", job_id, new.value, f" ({fields['reason']})" if fields.get("reason") else "")
        self._publish(job)
        return job

    # ------------------------------------------------------------------ jobs

    def job(self, job_id: str) -> JobRecord:
        try:
            return self.store.get(job_id)
        except KeyError:
            raise NotFound(f"no job {job_id!r}") from None

    def jobs(self) -> list[JobRecord]:
        return self.store.list()

    def eta(self, job_id: str) -> float | None:
        """Seconds left of the program the job is streaming (from the rate so far), if it is."""
        return self._eta.get(job_id)

    def job_dir(self, job_id: str) -> Path:
        return self.jobs_dir / job_id

    def submit(self, upload: Path, name: str, parameters: dict[str, Any], start: bool) -> JobRecord:
        """Take an uploaded mesh (``upload``, moved into the job's folder) and queue its compile."""
        safe = re.sub(r"[^A-Za-z0-9._-]", "_", Path(name).name) or "mesh.obj"
        if Path(safe).suffix.lower() not in MESH_SUFFIXES:
            raise ValueError(f"{name!r}: not a mesh file the engine reads ({', '.join(MESH_SUFFIXES)})")
        DesignParameters.model_validate(parameters)              # refuse bad parameters now
        asked = parameters.get("printer_profile")
        if asked is not None and asked != self.config.printer_profile:
            raise ValueError(f"printer_profile {asked!r}: this daemon drives a {self.config.printer_profile!r} "
                             "printer; leave printer_profile out (designs are made for the daemon's printer)")
        if sum(j.state is not JobState.INTERRUPTED for j in self.store.active()) >= self.config.limits.max_jobs:
            raise ServiceError(f"{self.config.limits.max_jobs} jobs are already queued or running; "
                               "wait for some to finish or cancel them")
        job = self.store.create(mesh_name=safe, mesh_path=str(upload), parameters=parameters,
                                start_when_ready=start)
        folder = self.job_dir(job.id)
        folder.mkdir(parents=True, exist_ok=True)
        mesh = folder / safe
        shutil.move(str(upload), mesh)
        job = self.store.update(job.id, mesh_path=str(mesh))
        self._publish(job)
        self._compile_queue.put_nowait(job.id)
        return job

    def start_job(self, job_id: str) -> JobRecord:
        """Queue a compiled job for printing (or mark it to start as soon as it is compiled)."""
        job = self.job(job_id)
        if job.state in (JobState.SUBMITTED, JobState.COMPILING):
            job = self.store.update(job_id, start_when_ready=True)
            self._publish(job)
            return job
        if job.state is not JobState.READY:
            raise IllegalTransition(job.state, JobState.HEATING)
        if job.start_when_ready:
            return job                                        # already queued
        job = self.store.update(job_id, start_when_ready=True)
        self._print_queue.put_nowait(job_id)
        self._publish(job)
        return job

    async def cancel(self, job_id: str) -> JobRecord:
        job = self.job(job_id)
        if JobState.CANCELLED not in TRANSITIONS[job.state]:
            raise IllegalTransition(job.state, JobState.CANCELLED)
        proc = self._compiling.get(job_id)
        if proc is not None:
            with contextlib.suppress(ProcessLookupError):
                proc.kill()
        run = self._run
        if run is not None and run.job_id == job_id:
            run.cancel_requested = True
            if self.link is not None and self.link.state in (LinkState.STREAMING, LinkState.PAUSED):
                self.link.cancel()
            run.flip.set()
            run.aligned.set()
            return self.job(job_id)                          # the printer task finishes the cancel
        return self._transition(job_id, JobState.CANCELLED, reason="cancelled by the operator")

    # ------------------------------------------------------------------ compiling

    async def _compile_loop(self) -> None:
        while True:
            job_id = await self._compile_queue.get()
            try:
                await self._compile(job_id)
            except Exception:  # noqa: BLE001 - one job's failure never stops the daemon
                log.exception("compiling job %s", job_id)
                with contextlib.suppress(Exception):
                    self._transition(job_id, JobState.FAILED, reason="internal error while compiling (see the log)")

    async def _compile(self, job_id: str) -> None:
        job = self.job(job_id)
        if job.state is not JobState.SUBMITTED:
            return
        folder = self.job_dir(job_id)
        params = {**job.parameters, "printer_profile": self.config.printer_profile}
        self._transition(job_id, JobState.COMPILING, stage="load", progress=0.0)
        log_path = folder / "compile.log"
        with log_path.open("wb") as errors:                  # the worker's stderr: kept for the operator
            proc = await asyncio.create_subprocess_exec(
                *worker_command(self.python, job.mesh_path, folder / "design", params, folder / "plans"),
                stdout=asyncio.subprocess.PIPE, stderr=errors, env=worker_environment())
        self._compiling[job_id] = proc
        last: dict[str, Any] = {}
        try:
            assert proc.stdout is not None
            async for raw in proc.stdout:
                try:
                    event = json.loads(raw)
                except ValueError:
                    continue
                last = event
                if event.get("event") == "stage":
                    self._publish(self.store.update(job_id, stage=event["stage"], progress=None))
                elif event.get("event") == "iteration":
                    self._publish(self.job(job_id), progress_event=event)
            code = await proc.wait()
        finally:
            self._compiling.pop(job_id, None)
        if self.job(job_id).state is not JobState.COMPILING:
            return                                            # cancelled meanwhile
        if code == 0 and last.get("event") == "done":
            job = self._transition(job_id, JobState.READY, design_dir=last["design_dir"], stage=None, progress=None)
            if job.start_when_ready:
                self._print_queue.put_nowait(job_id)
        elif last.get("event") == "error":
            self._transition(job_id, JobState.FAILED, reason=last["message"], error=last["message"])
        elif code < 0:
            self._transition(job_id, JobState.CANCELLED, reason="the compile was stopped")
        else:
            tail = log_path.read_text(errors="replace").strip().splitlines()[-1:] or ["no output"]
            self._transition(job_id, JobState.FAILED, reason=f"the compiler stopped ({code}): {tail[0]}",
                             error=tail[0])

    # ------------------------------------------------------------------ printing

    async def _print_loop(self) -> None:
        while True:
            job_id = await self._print_queue.get()
            job = self.job(job_id)
            if job.state is not JobState.READY:
                continue
            self._run = _Run(job_id)
            try:
                await self._print(job)
            except StreamCancelled:
                await self._safe_stop()
                self._transition(job_id, JobState.CANCELLED, reason="cancelled by the operator")
            except (LinkError, OSError, ValueError) as exc:
                log.exception("printing job %s", job_id)
                await self._safe_stop()
                with contextlib.suppress(IllegalTransition):
                    self._transition(job_id, JobState.FAILED, reason=str(exc), error=str(exc))
            except Exception as exc:  # noqa: BLE001 - the daemon keeps running
                log.exception("printing job %s", job_id)
                with contextlib.suppress(Exception):
                    self._transition(job_id, JobState.FAILED, reason=f"internal error: {exc}", error=str(exc))
            finally:
                self._run = None

    def _require_link(self) -> PrinterLink:
        if self.link is None or self.link.state is LinkState.DISCONNECTED:
            raise LinkError("the printer is not connected")
        return self.link

    async def _print(self, job: JobRecord) -> None:
        link = self._require_link()
        run = self._run
        assert run is not None
        folder = read_design_folder(Path(job.design_dir or ""))
        design = folder.design
        has_back = any(r.side == "back" for r in design.ribbons or [])
        front = (Path(job.design_dir or "") / "front.gcode").read_text(encoding="utf-8")
        self._transition(job.id, JobState.HEATING, side="front", stage="heating")
        await self._stream(job.id, front, "front", JobState.PRINTING_FRONT)
        await link.send("M400")
        self._publish(self.store.checkpoint(job.id, "front_done", self._acked))
        if run.cancel_requested:
            raise StreamCancelled("cancelled by the operator")
        if not has_back:
            self._transition(job.id, JobState.DONE, stage=None, progress=None)
            return
        expected = expected_marks(design.registration_marks or [], self.profile.frame)
        while True:
            await self._await_flip(job.id)
            run.alignment = _Alignment(expected=expected)
            self._transition(job.id, JobState.ALIGNING, stage="aligning")
            # the front program ended with the motors off (M84) and the frame was handled: home again
            await link.send("G28", timeout=300)
            await self._go_to_mark(0, expected)
            await run.aligned.wait()
            if run.cancel_requested:
                raise StreamCancelled("cancelled by the operator")
            correction, refused = run.alignment.correction, run.alignment.refused
            if refused is not None or correction is None:
                run.flip.clear()
                run.aligned.clear()
                self._transition(job.id, JobState.AWAITING_FLIP, reason=f"alignment refused: {refused}",
                                 error=str(refused))
                continue
            break
        plan = SidePlan.load(self.job_dir(job.id) / "plans" / "back-plan.npz")
        program = render_side(plan, self.profile, correction=correction)
        corrected = self.job_dir(job.id) / "back-corrected.gcode"
        tmp = corrected.with_suffix(".tmp")
        tmp.write_text(program.text, encoding="utf-8")
        os.replace(tmp, corrected)
        self._transition(job.id, JobState.PRINTING_BACK, side="back", correction=correction.model_dump(mode="json"),
                         stage="printing back", error=None)
        await self._stream(job.id, program.text, "back", None)
        await link.send("M400")
        self._publish(self.store.checkpoint(job.id, "back_done", self._acked))
        self._transition(job.id, JobState.DONE, stage=None, progress=None)

    async def _stream(self, job_id: str, text: str, side: str, after_heating: JobState | None) -> None:
        """Stream one program; switch from ``heating`` to ``after_heating`` at its first part."""
        link = self._require_link()
        lines = text.splitlines()
        commands = prepare_program(lines, f"{side}.gcode")
        first_part = len(prepare_program(lines[: next((i for i, line in enumerate(lines)
                                                        if line.startswith(";TYPE:")), len(lines))]))
        self._run_commands = commands
        self._publish(self.store.update(job_id, lines_total=len(commands), last_acked_line=-1))
        last_write = 0.0
        switched = after_heating is None

        def progress(p: StreamProgress) -> None:
            nonlocal last_write, switched
            now = time.monotonic()
            self._acked = p.acknowledged
            if not switched and p.acknowledged >= first_part:
                switched = True
                job = self.job(job_id)
                if job.state is JobState.HEATING:
                    self._transition(job_id, after_heating, stage=f"printing {side}")
            if now - last_write >= ACK_INTERVAL_S or p.acknowledged == p.total:
                last_write = now
                self.store.record_ack(job_id, p.acknowledged)
                eta = (p.elapsed_s / p.acknowledged * (p.total - p.acknowledged)) if p.acknowledged else None
                if eta is not None:
                    self._eta[job_id] = eta
                self.bus.publish({"type": "progress", "job_id": job_id, "side": side, "line": p.acknowledged,
                                  "lines": p.total, "eta_s": eta})

        try:
            await link.stream(commands, progress)
        finally:
            self._eta.pop(job_id, None)
        if not switched and after_heating is not None:
            self._transition(job_id, after_heating, stage=f"printing {side}")

    async def _safe_stop(self) -> None:
        """Heaters off, head lifted: after a cancel or a failure."""
        link = self.link
        if link is None or link.state not in (LinkState.READY, LinkState.STREAMING, LinkState.PAUSED):
            return
        for command in ("M104 S0", "M140 S0", "M107", "G91", "G0 Z10 F600", "G90", "M84"):
            with contextlib.suppress(LinkError, asyncio.TimeoutError):
                await link.send(command, timeout=30)

    # ------------------------------------------------------------------ the flip

    async def _await_flip(self, job_id: str) -> None:
        run = self._run
        assert run is not None
        job = self.job(job_id)
        if job.state is not JobState.AWAITING_FLIP:
            self._transition(job_id, JobState.AWAITING_FLIP, stage="awaiting the flip",
                             reason=flip_message(self.profile))
        self._publish(self.store.checkpoint(job_id, "flip", self._acked))
        policy = self.config.flip
        link = self._require_link()
        if policy.heaters == "off":
            await link.send("M104 S0")
        elif policy.heaters == "lower":
            await link.send(f"M104 S{policy.lower_to:.0f}")
        try:
            await asyncio.wait_for(run.flip.wait(), policy.off_after_s if policy.off_after_s > 0 else None)
        except asyncio.TimeoutError:
            await link.send("M104 S0")
            await link.send("M140 S0")
            self.bus.publish({"type": "notice", "job_id": job_id,
                              "message": f"heaters off after {policy.off_after_s:.0f} s awaiting the flip"})
            await run.flip.wait()
        if run.cancel_requested:
            raise StreamCancelled("cancelled by the operator")

    def flip_done(self, job_id: str) -> JobRecord:
        job = self.job(job_id)
        run = self._run
        if job.state is not JobState.AWAITING_FLIP or run is None or run.job_id != job_id:
            raise IllegalTransition(job.state, JobState.ALIGNING)
        run.flip.set()
        return job

    async def _go_to_mark(self, index: int, expected: np.ndarray) -> None:
        """Move the head above where mark ``index`` should be now, at the safe height."""
        link = self._require_link()
        lay, mo = self.profile.layers, self.profile.motion
        x, y = expected[index]
        for command in ("G90", f"G0 Z{lay.fabric_z + lay.safe_height:.3f} F{mo.z_speed * 60:.0f}",
                        f"G0 X{x:.3f} Y{y:.3f} F{mo.travel_speed * 60:.0f}", "M400"):
            await link.send(command, timeout=120)
        self.bus.publish({"type": "alignment", "job_id": self._run.job_id if self._run else None,
                          "mark": index, "expected": [float(x), float(y)],
                          "message": f"the head is above where mark {index + 1} of {len(expected)} should be: "
                                     "confirm it, or jog the head onto the mark and report the jog"})

    async def align_mark(self, job_id: str, mark: int, jog: tuple[float, float] | None) -> dict[str, Any]:
        """Confirm mark ``mark`` (``jog`` None) or report the jog (dx, dy) that brought the head
        onto it. Returns the alignment's status; the last mark ends the check."""
        run = self._run
        job = self.job(job_id)
        if job.state is not JobState.ALIGNING or run is None or run.job_id != job_id or run.alignment is None:
            raise IllegalTransition(job.state, "align")
        al = run.alignment
        if not 0 <= mark < len(al.expected):
            raise ValueError(f"mark {mark} does not exist: the design has marks 0 to {len(al.expected) - 1}")
        dx, dy = jog or (0.0, 0.0)
        if not (np.isfinite(dx) and np.isfinite(dy)):
            raise ValueError("the jog must be two finite numbers (mm)")
        al.measured[mark] = (float(al.expected[mark][0] + dx), float(al.expected[mark][1] + dy))
        nxt = al.next_mark
        status: dict[str, Any] = {"measured": {str(k): v for k, v in al.measured.items()}, "next_mark": nxt,
                                  "marks": len(al.expected)}
        if nxt is not None:
            await self._go_to_mark(nxt, al.expected)
            return status
        # the fit is made once, here; the printer task takes its result from ``al``
        fit = fit_rigid(al.expected, np.array([al.measured[i] for i in range(len(al.expected))]))
        status["fit"] = {"rotation_deg": fit.rotation_deg, "offset": list(fit.offset),
                         "rms_mm": fit.rms, "max_residual_mm": fit.max_residual}
        tol = self.profile.alignment
        try:
            check_fit(fit, max_residual=tol.max_residual, max_rotation_deg=tol.max_rotation_deg,
                      max_offset=tol.max_offset)
        except AlignmentRefused as exc:
            al.refused = exc
            raise
        else:
            al.correction = fit.correction()
            status["accepted"] = True
        finally:
            run.aligned.set()
        return status

    # ------------------------------------------------------------------ pause and resume

    async def pause(self, job_id: str) -> JobRecord:
        job = self.job(job_id)
        run = self._run
        if job.state not in (JobState.PRINTING_FRONT, JobState.PRINTING_BACK) or run is None or run.job_id != job_id:
            raise IllegalTransition(job.state, JobState.PAUSED)
        link = self._require_link()
        link.pause()
        job = self._transition(job_id, JobState.PAUSED, paused_from=job.state, stage="paused")
        await link.send("M400", timeout=300)
        pos = await link.query_position()
        modal = modal_state(self._run_commands, max(self._acked, 0))
        exact = {k: modal[k] if modal[k] is not None else getattr(pos, k) for k in ("x", "y", "z")}
        run.pause_snapshot = {**modal, **exact}
        lay, mo, r = self.profile.layers, self.profile.motion, self.profile.retraction
        x0, _, _, y1 = self.profile.frame.bounds
        for command in ("G90", "M83", f"G1 E{-r.length:.5f} F{mo.retract_speed * 60:.0f}",
                        f"G0 Z{max(pos.z, lay.fabric_z) + self.profile.park_lift:.3f} F{mo.z_speed * 60:.0f}",
                        f"G0 X{x0:.3f} Y{y1:.3f} F{mo.travel_speed * 60:.0f}"):
            await link.send(command, timeout=120)
        self._publish(self.store.update(job_id, stage="paused (head parked)"), snapshot=run.pause_snapshot)
        return self.job(job_id)

    async def resume(self, job_id: str) -> JobRecord:
        job = self.job(job_id)
        run = self._run
        if job.state is not JobState.PAUSED or run is None or run.job_id != job_id or run.pause_snapshot is None:
            raise IllegalTransition(job.state, "resume")
        link = self._require_link()
        snap = run.pause_snapshot
        mo, r = self.profile.motion, self.profile.retraction
        commands = []
        if snap.get("nozzle"):
            commands += [f"M104 S{snap['nozzle']:.0f}", f"M109 S{snap['nozzle']:.0f}"]
        if snap.get("bed"):
            commands += [f"M140 S{snap['bed']:.0f}", f"M190 S{snap['bed']:.0f}"]
        commands += ["G90", f"G0 X{snap['x']:.3f} Y{snap['y']:.3f} F{mo.travel_speed * 60:.0f}",
                     f"G0 Z{snap['z']:.3f} F{mo.z_speed * 60:.0f}", "M83",
                     f"G1 E{r.length:.5f} F{mo.retract_speed * 60:.0f}"]
        commands.append("G90" if snap["absolute"] else "G91")
        commands.append("M82" if snap["e_absolute"] else "M83")
        if snap["fan"]:
            commands.append(f"M106 S{snap['fan']}")
        if snap.get("feed"):
            commands.append(f"G0 F{snap['feed']:.0f}")
        for command in commands:
            await link.send(command, timeout=1200)
        back_to = job.paused_from or JobState.PRINTING_FRONT
        job = self._transition(job_id, back_to, stage=f"printing {job.side or 'front'}")
        run.pause_snapshot = None
        link.resume()
        return job

    # ------------------------------------------------------------------ the printer

    async def printer_status(self, refresh: bool = False) -> dict[str, Any]:
        """What the link knows; with ``refresh``, the temperatures and position asked for first
        (``M105``, ``M114``: answered ahead of a running program)."""
        if self.link is None:
            return {"state": "disconnected"}
        if refresh and self.link.state in (LinkState.READY, LinkState.STREAMING, LinkState.PAUSED):
            with contextlib.suppress(LinkError, asyncio.TimeoutError):
                await asyncio.wait_for(self.link.query_temperatures(), 10)
                await asyncio.wait_for(self.link.query_position(), 10)
        return self.link.status.model_dump(mode="json")

    def emergency_stop(self) -> None:
        link = self._require_link()
        link.emergency_stop()

    async def recover(self) -> dict[str, Any]:
        """After an emergency stop or a halt: restart the firmware (``M999``) and shake hands again."""
        link = self._require_link()
        if link.state is not LinkState.HALTED:
            raise ServiceError(f"the printer is {link.state.value}, not halted: nothing to recover")
        await link.recover()
        return await self.printer_status()

