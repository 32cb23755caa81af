"""The daemon's job service: jobs from upload to done, on one printer (issues 6 and 13), and the
one place where the daemon's components are wired together.

``RibbonService`` keeps the job life cycle: submit (a mesh, checked before anything is stored; a
plain G-code program, checked line by line against the profile), start (again: a new run of the
same design), cancel, delete, and what a person sees of a job (``status``: its progress, time left
and the next thing to do). The rest is one component per concern, each given only what it needs:

- ``records.JobRecords``: reads and state changes of the store, each committed before it is published
  on the ``events.EventBus``;
- ``compiler.Compiler``: the compile queue (each compile a ``ribbond.pipeline.worker`` subprocess, so the
  event loop that feeds the printer never computes a design);
- ``run.PrintState``: the print queue and the run on the printer (one job at a time);
- ``printing.PrintTask``: the print task (heating, front, flip, back, done; the safe stops);
- ``aligner.Aligner``: the flip and the alignment check over the registration marks;
- ``resume.Resumer``: pause and resume, and the resume of an interrupted print at a part boundary;
- ``heaters.Heaters``: the heaters the daemon sets on its own (idle policy, off after a crash);
- ``manual.ManualControl``: home, jog, goto, G-code, heat, cool, never while a program streams;
- ``head.Head``: the link, the lock of the head's moves and the head's commanded position;
- ``tables.TableLibrary`` and ``calibrations.Calibrations``: curvature tables and calibration plans;
- ``predictor.Predictor``: a design's deployed shape predicted again (a ``ribbond.pipeline.predict_worker``
  subprocess), its progress and result in the job's status;
- ``octoprint.OctoPrintCompat``: slicers' uploads made jobs, and the job and printer in OctoPrint's words;
- ``notifier.Notifier``: notifications through Apprise (``[notify]``), from the bus's events, off the
  print path;
- ``camera.Camera``: the printer's camera for the page, a snapshot kept with the job at each side's end.

It knows nothing of HTTP (``ribbond.api`` maps the components' methods and exceptions to routes and
status codes) and parses no printer answers (``PrinterLink`` does).
"""

from __future__ import annotations

import asyncio
import contextlib
import hashlib
import logging
import re
import shutil
import sys
import time
from pathlib import Path
from typing import Any

from ribbond.design.errors import MeshError
from ribbond.design.intake import load_target
from ribbond.design.params import check_printable, settings_from_dict
from ribbond.gcode.checker import Checked
from ribbond.gcode.profiles import PrinterProfile
from ribbond.printer.link import LinkState, PrinterLink
from .components.aligner import Aligner, aligning_guidance
from .components.calibrations import Calibrations
from .components.camera import Camera
from .components.compiler import COMPILE_STAGES, Compiler
from .components.frame import INSTRUCTION as FRESH_FRAME_INSTRUCTION, FrameGate, waits_at_gate
from .components.head import Head
from .components.heaters import Heaters
from .components.manual import MAX_MANUAL_COMMANDS, ManualControl
from .components.notifier import Notifier
from .components.octoprint import OctoPrintCompat
from .components.predictor import Predictor
from .components.printing import PrintTask
from .components.projects import Projects, check_panels, panel_instruction
from .components.programs import Timeline, check_plain_program, program_timeline
from .components.resume import Resumer, modal_state
from .components.run import PrintState, Stream, stream_rate
from .components.tables import TableLibrary
from .components.temperatures import TemperatureHistory
from .components.shapes import Shapes
from .components.verdicts import Verdicts
from .config import DaemonConfig
from .events import EventBus
from .jobs import COMMANDS, TRANSITIONS, IllegalTransition, JobState
from .records import JobRecords, NotFound, ServiceError, has_program
from .store import JobRecord, JobStore, new_id

#: What callers import from here: the service, and the names of its components they use.
__all__ = ["MAX_MANUAL_COMMANDS", "MAX_NAME_BYTES", "NotFound", "RibbonService", "ServiceError", "mesh_file_name",
           "modal_state"]

log = logging.getLogger(__name__)

#: Extensions of the mesh formats the engine reads.
MESH_SUFFIXES = (".obj", ".off", ".stl", ".ply")
#: Extensions of plain G-code programs.
GCODE_SUFFIXES = (".gcode", ".gco", ".g", ".nc")


#: Longest stored mesh file name, bytes (file systems allow 255); longer names are shortened.
MAX_NAME_BYTES = 120


def mesh_file_name(name: str) -> str:
    """The upload's name as stored: a sanitized basename, at most ``MAX_NAME_BYTES`` bytes.

    A longer name keeps its first 100 bytes, a hash of the whole name (two long names that share
    a start stay apart) and its extension: readable, and always a valid file name."""
    safe = re.sub(r"[^A-Za-z0-9._-]", "_", Path(name).name) or "mesh.obj"
    if len(safe.encode()) <= MAX_NAME_BYTES:
        return safe
    suffix = Path(safe).suffix if len(Path(safe).suffix) <= 10 else ""
    stem = safe[:len(safe) - len(suffix)].encode()[:100].decode("utf-8", errors="ignore")
    return f"{stem}-{hashlib.sha256(name.encode('utf-8', errors='surrogatepass')).hexdigest()[:8]}{suffix}"


#: Job states of a print under way in which a person acts (the flip, the marks, the fit, a pause,
#: the frame check of a resume): the time left is not told, nothing prints until they act.
PERSON_STATES = frozenset({JobState.AWAITING_FLIP, JobState.ALIGNING, JobState.FITTED, JobState.PAUSED,
                           JobState.AWAITING_CHECK})


#: How often the printer's status is checked for a change worth an event (seconds).
PRINTER_EVENT_S = 0.5


def _check_and_estimate(text: str, profile: PrinterProfile, source: str) -> tuple[Checked, Timeline]:
    """The program checked (feed rates clamped as the firmware would) and its time line."""
    checked = check_plain_program(text.splitlines(), profile, source=source)
    return checked, program_timeline(checked.lines, profile)


def _fitted_guidance(j: str, fit: dict[str, Any] | None) -> str:
    seen = (f"the fit turns the back by {fit['rotation_deg']:.2f}° and moves it by "
            f"({fit['offset'][0]:.2f}, {fit['offset'][1]:.2f}) mm, {fit['max_residual_mm']:.2f} mm "
            "off at the worst mark. ") if fit else ""
    return (f"{seen}Accept it to print the back with that correction (ribbonctl accept {j}), or "
            f"re-seat the frame, back side up, and measure every mark again (ribbonctl re-seat {j})")


def _ended_guidance(job: JobRecord) -> tuple[str, list[str] | None]:
    """A run that ended (failed, cancelled, interrupted): resume, print again, or nothing to print."""
    j, s = job.id, job.state
    why = f" ({job.error})" if job.error else ""
    if s is JobState.INTERRUPTED and job.kind == "design" and has_program(job) and job.side:
        return (f"interrupted{why}; resume it where it was proven to stand: ribbonctl resume {j} "
                f"[--partial skip|reprint] (the ribbon begun and not proven printed: skipped by "
                f"default), print it again from the start: ribbonctl start {j}, or remove it: "
                f"ribbonctl delete {j}"), None
    if has_program(job):
        return f"{s.value}{why}; print it again with ribbonctl start {j}, or remove it: ribbonctl delete {j}", None
    return (f"{s.value}{why}; nothing to print: submit the mesh again (ribbonctl delete {j} removes it)",
            [f"ribbonctl delete {j}"])


class RibbonService:
    """Jobs on one printer. Create it in the event loop; ``start()`` its tasks; ``close()``."""

    def __init__(self, config: DaemonConfig, profile: PrinterProfile, store: JobStore,
                 link: PrinterLink | None, *, python: str = sys.executable) -> None:
        self.config = config
        self.profile = profile
        self.store = store
        self.bus = EventBus()
        self.python = python
        self.jobs_dir = Path(config.state_dir) / "jobs"
        self.jobs_dir.mkdir(parents=True, exist_ok=True)
        # the wiring: each component gets what it uses; what it must ask of the service (how a job
        # is shown, how far it is) is a callable, so no component holds the service itself
        self.library = TableLibrary(config.state_dir, store)
        self.records = JobRecords(store, self.bus, self.jobs_dir, config.limits.max_jobs, self.status)
        self.state = PrintState()
        self.head = Head(link)
        self.heaters = Heaters(self.head, config.flip, self.records, self.state)
        self.aligner = Aligner(self.head, profile, self.records, self.state, self.heaters,
                               lambda job: self.guidance(job)["instruction"])
        self.resumer = Resumer(self.head, profile, self.records, self.state, self.heaters)
        self.frame = FrameGate(self.records, self.state, self.heaters)
        self.printing = PrintTask(self.head, profile, self.records, self.state, self.heaters, self.aligner,
                                  self.resumer, self.progress, self.frame)
        self.manual = ManualControl(self.head, profile, self.records, self.state, config.manual)
        self.calibrations = Calibrations(config, self.records, self.state.queue_print, python)
        self.compiler = Compiler(config, self.records, self.library.tables_dir, self.state.queue_print, python)
        self.verdicts = Verdicts(self.jobs_dir)          # the design's verdict in each status (issue 22)
        self.predictor = Predictor(self.records, self.library.tables_dir, python, self.library.check_table_name,
                                   lambda job_id: self.verdicts.forget(job_id, self.job(job_id).design_dir))
        self.shapes = Shapes()                           # the prediction's deviation per vertex (issue 36)
        self.temperatures = TemperatureHistory()         # the last 30 minutes, for the chart (issue 22)
        self.projects = Projects(config, self.records, self.library.tables_dir, python, self.state.queue_print,
                                 self.status, self.cancel, self.start_job)          # a mesh in panels (issue 26)
        self.compiler.project_compile = self.projects.compile
        # slicers' uploads and views in OctoPrint's words (issue 27)
        self.octoprint = OctoPrintCompat(self.records, self.state, self.head, self.submit, self.submit_gcode,
                                         self.status, self.manual.printer_status,
                                         (MESH_SUFFIXES, GCODE_SUFFIXES))
        self.notifier = Notifier(config.notify, self.bus)    # the operator's phone (issue 27)
        self.camera = Camera(config.camera, self.records)            # snapshots at each side's end (issue 27)
        self._tasks: list[asyncio.Task[None]] = []

    # ------------------------------------------------------------------ life cycle

    def start(self) -> None:
        """Mark jobs the last daemon left holding the printer as interrupted; start the queues."""
        # (before the interruptions below: those are news to the operator)
        self.notifier.start(j.model_dump(mode="json") for j in self.store.list())
        interrupted = self.store.mark_interrupted("the daemon stopped while this job was running")
        for job in interrupted:
            self.records.publish(job)
        self._remove_orphan_folders()
        if any(j.state is JobState.INTERRUPTED and j.side is not None for j in interrupted):
            self.heaters.cool_after_interruption()
        for project_id in self.projects.pending():
            self.compiler.queue(project_id)
        for job in self.store.active():
            if job.state is JobState.SUBMITTED:
                self.compiler.queue(job.id)
            elif job.state is JobState.READY and job.start_when_ready:
                self.state.queue_print(job.id)
        self._tasks = [asyncio.create_task(self.compiler.run(), name="compile"),
                       asyncio.create_task(self.printing.run(), name="print"),
                       asyncio.create_task(self._printer_events(), name="printer events"),
                       asyncio.create_task(self.camera.run(), name="camera")]

    async def _printer_events(self) -> None:
        """Publish the printer's status (state, temperatures, position, head) as an event whenever
        it changed, checked every PRINTER_EVENT_S: the dashboard and ``ribbonctl`` follow /events."""
        last: dict[str, Any] | None = None
        while True:
            await asyncio.sleep(PRINTER_EVENT_S)
            try:
                status = {**await self.manual.printer_status(), "frame": self.frame.status()}
            except Exception:  # noqa: BLE001 - a status that cannot be read is not worth a stop
                log.debug("printer status for the events", exc_info=True)
                continue
            self.temperatures.sample(status)
            if status != last:
                self.bus.publish({"type": "printer", "printer": status})
                last = status

    async def shutdown(self, reason: str = "the daemon was stopped") -> None:
        """Stop safely before the daemon exits (``PrintTask.shutdown``: the job on the printer
        ``interrupted`` at an exact checkpoint, heaters off, head lifted)."""
        await self.printing.shutdown(reason)

    async def close(self) -> None:
        await self.notifier.close()
        self.compiler.stop_all()
        self.projects.stop_all()
        self.predictor.stop_all()
        self.calibrations.stop_all()
        for task in self._tasks:
            task.cancel()
        for task in self._tasks:
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task
        await self.camera.close()

    # ------------------------------------------------------------------ jobs

    def job(self, job_id: str) -> JobRecord:
        return self.records.get(job_id)

    def jobs(self, states: list[JobState] | None = None, limit: int | None = None,
             offset: int = 0) -> list[JobRecord]:
        return self.store.list(states, limit=limit, offset=offset)

    def job_dir(self, job_id: str) -> Path:
        return self.records.dir(job_id)

    async def submit(self, upload: Path, name: str, parameters: dict[str, Any], start: bool) -> JobRecord:
        """Take an uploaded mesh (``upload``, moved into the job's folder) and queue its compile.

        Everything is checked first (the name, the parameters against the engine, the daemon's
        limits, its printer and its curvature tables, the mesh read and validated as the compile's
        intake reads it); the job's row is written only once the mesh is in its folder and
        checked, and if anything fails on the way neither the row nor the folder remains (no event,
        no notification)."""
        safe = mesh_file_name(name)
        if Path(safe).suffix.lower() in GCODE_SUFFIXES:
            raise ValueError(f"{name!r} is a G-code program, not a mesh: print it with 'ribbonctl print {name}'")
        if Path(safe).suffix.lower() not in MESH_SUFFIXES:
            raise ValueError(f"{name!r}: not a mesh file the engine reads ({', '.join(MESH_SUFFIXES)})")
        self._check_settings(parameters)
        self.records.check_queue()
        job_id = new_id()
        folder = self.job_dir(job_id)
        try:
            folder.mkdir(parents=True)
            mesh = folder / safe
            shutil.move(str(upload), mesh)
            await self._intake(mesh, parameters)
            self.records.check_queue()                  # again: other submits may have landed meanwhile
            job = self.store.create(mesh_name=safe, mesh_path=str(mesh), parameters=parameters,
                                    start_when_ready=start, job_id=job_id)
        except BaseException:
            shutil.rmtree(folder, ignore_errors=True)
            raise
        self.records.publish(job)
        self.compiler.queue(job.id)
        return job

    async def submit_project(self, upload: Path, name: str, parameters: dict[str, Any], panels: str,
                             seam_allowance: float, start: bool) -> dict[str, Any]:
        """Take an uploaded mesh to print in panels (``panels``: ``auto`` or 2 to 16): checked as a
        job's mesh is, then compiled once; its panels become one job each (``Projects``). Its view."""
        panels = check_panels(panels)
        safe = mesh_file_name(name)
        if Path(safe).suffix.lower() not in MESH_SUFFIXES:
            raise ValueError(f"{name!r}: not a mesh file the engine reads ({', '.join(MESH_SUFFIXES)})")
        self._check_settings(parameters)
        self.records.check_queue()
        project_id = self.projects.new_id()
        folder = self.projects.dir(project_id)
        try:
            folder.mkdir(parents=True)
            mesh = folder / safe
            shutil.move(str(upload), mesh)
            await self._intake(mesh, parameters)
            self.records.check_queue()
            project = self.projects.create(project_id, mesh, parameters, panels, seam_allowance, start)
        except BaseException:
            shutil.rmtree(folder, ignore_errors=True)
            raise
        self.compiler.queue(project_id)
        return self.projects.view(project)

    async def _intake(self, mesh: Path, parameters: dict[str, Any]) -> None:
        """The mesh read, cleaned and validated as the compile's intake will (``load_target``: a
        MeshError naming the problem and its file line), in a thread so the printer's stream goes on.
        Fast: no refinement, no flattening."""
        solver = settings_from_dict(parameters).solver
        limit = self.config.limits.max_faces
        try:
            await asyncio.to_thread(load_target, mesh, max_faces=min(solver.max_faces, limit),
                                    merge_tolerance=solver.merge_tolerance)
        except MeshError as exc:
            if exc.problem == "too_many_faces" and limit < solver.max_faces:
                raise MeshError(exc.problem, f"{exc} ([limits] max_faces = {limit})") from None
            raise

    def _check_settings(self, parameters: dict[str, Any]) -> None:
        """Refuse (ValueError naming the field sent) what the compile could not take: the engine's
        checks, this printer's frame and nozzle, its curvature tables (their name and the pre-stretch
        they were measured at) and ``[limits] max_faces``."""
        settings = settings_from_dict(parameters)
        asked = parameters.get("printer_profile")
        if asked is not None and asked != self.config.printer_profile:
            raise ValueError(f"printer_profile {asked!r}: this daemon drives a {self.config.printer_profile!r} "
                             "printer; leave printer_profile out (designs are made for the daemon's printer)")
        check_printable(settings.parameters, self.profile.frame.size, self.profile.extruder.nozzle_diameter)
        self.library.check_table_name(settings.parameters.curvature_table)
        self.library.check_prestretch(settings.parameters.curvature_table, settings.parameters.prestretch)
        limit = self.config.limits.max_faces
        if settings.solver.max_faces > limit and "max_faces" in settings.solver.model_fields_set:
            raise ValueError(f"solver.max_faces = {settings.solver.max_faces}: above this daemon's limit "
                             f"([limits] max_faces = {limit})")

    def _remove_orphan_folders(self) -> None:
        """Job folders without a job: a daemon stopped between storing an upload and its row."""
        known = {j.id for j in self.store.list()}
        for entry in self.jobs_dir.iterdir():
            if entry.is_dir() and re.fullmatch(r"[0-9a-f]{12}", entry.name) and entry.name not in known:
                log.warning("removing %s: a job folder without a job", entry)
                shutil.rmtree(entry, ignore_errors=True)

    async def submit_gcode(self, upload: Path, name: str, start: bool, same_frame: bool = False) -> JobRecord:
        """Take an uploaded G-code program, check it line by line against the profile (refused with
        the line named: nothing is kept), and make it a ``ready`` job (queued if ``start``).
        ``same_frame``: it prints on the frame as it is (no fresh frame is asked for before it)."""
        safe = re.sub(r"[^A-Za-z0-9._-]", "_", Path(name).name) or "program.gcode"
        if Path(safe).suffix.lower() not in GCODE_SUFFIXES:
            raise ValueError(f"{name!r}: not a G-code file ({', '.join(GCODE_SUFFIXES)})")
        try:
            text = upload.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            raise ValueError(f"{name}: not a text file (G-code is ASCII text)") from None
        # checked and estimated beside the loop: a long program must not hold up the printer's stream
        checked, timeline = await asyncio.to_thread(_check_and_estimate, text, self.profile, safe)
        commands, notes = checked.commands, checked.notes(self.profile)
        if start:
            self.records.check_queue()
        job = self.store.create(mesh_name=safe, mesh_path=str(upload), parameters={}, start_when_ready=start,
                                kind="gcode", same_frame=same_frame)
        folder = self.job_dir(job.id)
        folder.mkdir(parents=True, exist_ok=True)
        program = folder / "program.gcode"
        shutil.move(str(upload), program)
        if notes:                             # the program as it streams: the clamped F words
            program.write_text("\n".join(checked.lines) + "\n", encoding="utf-8")
        job = self.records.transition(job.id, JobState.READY, reason=f"G-code checked: {len(commands)} commands",
                                      mesh_path=str(program), design_dir=str(folder), lines_total=len(commands),
                                      estimate_s={"front": timeline.total}, notes=notes)
        if start:
            self.state.queue_print(job.id)
        return job

    def start_job(self, job_id: str) -> JobRecord:
        """Queue a job for printing: a compiled one, one still compiling (it prints when ready), or
        one whose run ended (a new run of the same design; the ended run is kept in ``runs``)."""
        job = self.job(job_id)
        if job.state in (JobState.SUBMITTED, JobState.COMPILING):
            job = self.store.update(job_id, start_when_ready=True)
            self.records.publish(job)
            return job
        if job.state is JobState.INTERRUPTED and job.kind == "design" and not has_program(job) \
                and Path(job.mesh_path).is_file():
            # the daemon stopped during the compile: compile it again
            self.records.check_queue()
            job = self.records.transition(job_id, JobState.SUBMITTED, reason="compiled again",
                                          start_when_ready=True, error=None, stage=None, progress=None)
            self.compiler.queue(job_id)
            return job
        if job.state.terminal:
            return self._start_again(job)
        if job.state is not JobState.READY:
            raise IllegalTransition.of(job, "start")
        if job.start_when_ready:
            return job                                        # already queued
        self.records.check_queue()
        job = self.store.update(job_id, start_when_ready=True)
        self.state.queue_print(job_id)
        self.records.publish(job)
        return job

    def _start_again(self, job: JobRecord) -> JobRecord:
        """A new run of an ended job's design: the ended run (if it reached the printer) kept in
        ``runs``, the job ``ready`` and queued."""
        job_id = job.id
        if not has_program(job):
            raise ServiceError(f"cannot start: job {job_id} has no design to print"
                               + (f" (its compile failed: {job.error})" if job.error else "")
                               + "; submit the mesh again")
        self.records.check_queue()
        runs = list(job.runs)
        started = [t.at for t in self.store.transitions(job_id) if t.to_state is JobState.HEATING]
        if started:
            runs.append({"run": len(runs) + 1, "started": started[-1], "ended": job.updated,
                         "state": job.state.value, "error": job.error, "side": job.side,
                         "lines_total": job.lines_total, "last_acked_line": job.last_acked_line,
                         "checkpoint": job.checkpoint, "checkpoint_line": job.checkpoint_line,
                         "correction": job.correction})
        job = self.records.transition(job_id, JobState.READY, reason=f"started again (run {len(runs) + 1})",
                                      runs=runs, start_when_ready=True, error=None, stage=None, progress=None,
                                      lines_total=None, last_acked_line=-1, checkpoint=None, checkpoint_line=None,
                                      side=None, correction=None, paused_from=None, program=None,
                                      print_progress=None)
        self.state.queue_print(job_id)
        return job

    async def cancel(self, job_id: str) -> JobRecord:
        job = self.job(job_id)
        if JobState.CANCELLED not in TRANSITIONS[job.state]:
            raise IllegalTransition.of(job, "cancel")
        if self.compiler.stop(job_id):
            return await self.records.wait_state(job_id, lambda s: s is not JobState.COMPILING, 30)
        run = self.state.current(job_id)
        if run is not None:
            run.cancel_requested = True
            self.printing.interrupt(run)
            # the printer task finishes the cancel (heaters off, head up)
            return await self.records.wait_state(job_id, lambda s: s.terminal, 60)
        return self.records.transition(job_id, JobState.CANCELLED, reason="cancelled by the operator",
                                       start_when_ready=False, stage=None)

    def delete(self, job_id: str) -> None:
        """Remove a job and its files (uploads, design, programs); refused while it compiles or
        holds the printer."""
        job = self.job(job_id)
        if job.state.holds_printer or job.state in (JobState.SUBMITTED, JobState.COMPILING) \
                or self.state.current(job_id) is not None:
            raise IllegalTransition.of(job, "delete", hint=f"cancel it first: ribbonctl cancel {job_id}")
        if self.predictor.running(job_id):
            raise ServiceError(f"cannot delete job {job_id} while its design is being predicted again; "
                               "delete it once the prediction ends")
        self.store.delete(job_id)
        shutil.rmtree(self.job_dir(job_id), ignore_errors=True)
        log.info("job %s deleted", job_id)
        self.bus.publish({"type": "deleted", "job_id": job_id})

    # ------------------------------------------------------------------ what a person sees

    def progress(self, job: JobRecord) -> dict[str, Any]:
        """How far the job is: ``progress`` 0–1 (of the compile while compiling, else of the print,
        both sides), ``eta_s`` (seconds left of the print: the programs' own time estimate, scaled
        by the rate measured once the stream is past the heating), ``elapsed_s`` of the run, the
        ``ribbon`` n of ``ribbons`` being printed, and ``print_side``. Reads no file: the totals are
        the job's ``estimate_s``; the program streaming now has its full time line."""
        s = job.state
        out: dict[str, Any] = {"progress": 0.0, "eta_s": None, "elapsed_s": None, "ribbon": None,
                               "ribbons": None, "print_side": job.side}
        if s is JobState.COMPILING:
            stage = job.stage if job.stage in COMPILE_STAGES else None
            out["progress"] = COMPILE_STAGES.index(stage) / len(COMPILE_STAGES) if stage else 0.0
            return out
        if s is JobState.DONE:
            out.update(progress=1.0, eta_s=0.0)
            return out
        totals = {k: float(v) for k, v in (job.estimate_s or {}).items() if v}
        if not totals:
            return out
        run = self.state.current(job.id)
        side, done_side, rate = self._side_progress(job, totals, run.stream if run is not None else None, out)
        total = sum(totals.values()) or 1.0
        front = totals.get("front", 0.0)
        if s in (JobState.READY, JobState.SUBMITTED):
            out.update(progress=0.0, eta_s=total * rate)
        elif s in (JobState.AWAITING_FLIP, JobState.ALIGNING, JobState.FITTED):
            # the back is next, but nothing prints until the operator acts: no time left is told
            out.update(progress=min(1.0, front / total), print_side="back")
        elif done_side is not None:
            done = (front if side == "back" else 0.0) + done_side
            out["progress"] = min(1.0, done / total)
            if not s.terminal and s not in PERSON_STATES:
                out["eta_s"] = max(0.0, total - done) * rate
        if run is not None:
            out["elapsed_s"] = time.time() - run.started
        if job.print_progress is not None and s not in (JobState.READY, JobState.SUBMITTED):
            # never less than was shown before (a pause, an interruption, a restart, the resume's reheat)
            out["progress"] = max(out["progress"], job.print_progress)
        return out

    def _side_progress(self, job: JobRecord, totals: dict[str, float], stream: Stream | None,
                       out: dict[str, Any]) -> tuple[str, float | None, float]:
        """The side printing, the estimated seconds of it done (None: not known from the lines) and
        the rate; a stream puts its own total in ``totals`` and its ribbon in ``out``."""
        s = job.state
        rate = self.state.rate or 1.0
        side: str = job.side or "front"
        if stream is not None:
            side, tl = stream.side, stream.timeline
            # the lines as stored (every 0.5 s while streaming): what is reported is what a restart finds
            acked = min(stream.acked, job.last_acked_line) if job.last_acked_line >= 0 else 0
            out["ribbon"] = tl.ribbon_at(acked) or None
            out["ribbons"] = tl.ribbons or None
            if stream.side_s is None:
                totals[side] = tl.total or totals.get(side, 0.0)
                return side, tl.done_s(acked), stream_rate(stream) or rate
            # a resumed side: the parts before it count, the resumed program's printing adds to them
            totals[side] = stream.side_s
            done = stream.base_s + max(0.0, tl.done_s(acked) - tl.done_s(tl.first))
            return side, min(done, stream.side_s), stream_rate(stream) or rate
        if s is JobState.PRINTING_BACK:
            return side, 0.0, rate  # the back's stream is not set up yet: the lines stored are the front's
        if job.lines_total and job.print_progress is None and s in (
                JobState.HEATING, JobState.PRINTING_FRONT, JobState.PAUSED, JobState.INTERRUPTED,
                JobState.FAILED, JobState.CANCELLED):
            # not streaming now and nothing stored: where it stood, by the lines acknowledged (a share
            # of lines is not a share of time: with a stored progress, that one is shown, never more)
            return side, totals.get(side, 0.0) * min(1.0, max(job.last_acked_line, 0) / job.lines_total), rate
        return side, None, rate

    def guidance(self, job: JobRecord) -> dict[str, Any]:
        """What the operator does next: an instruction and the exact commands, for every state."""
        j, s = job.id, job.state
        run = self.state.current(j)
        cmds: list[str] | None = None                    # None: the commands of the state (COMMANDS)
        if s in (JobState.SUBMITTED, JobState.COMPILING):
            text = "compiling; it prints when compiled" if job.start_when_ready else \
                f"compiling; then print it with: ribbonctl start {j}"
        elif s is JobState.READY:
            text, cmds = self._ready_guidance(job)
        elif s is JobState.HEATING:
            text = "heating; the print starts when the nozzle is hot"
        elif s in (JobState.PRINTING_FRONT, JobState.PRINTING_BACK):
            text = f"printing the {job.side or 'front'}" if job.kind == "design" else "printing the program"
        elif s is JobState.PAUSED:
            text = (f"paused, the head parked; move it with ribbonctl jog/goto/home if needed, then "
                    f"resume: ribbonctl resume {j} (it reheats first)")
        elif s is JobState.AWAITING_FLIP:
            text, cmds = self._flip_guidance(job), [f"ribbonctl flip-done {j}", f"ribbonctl cancel {j}"]
        elif s is JobState.ALIGNING:
            text = aligning_guidance(j, run.alignment if run is not None else None, job.error)
            cmds = ["ribbonctl jog DX DY", f"ribbonctl align {j} --here", f"ribbonctl cancel {j}"]
        elif s is JobState.FITTED:
            text = _fitted_guidance(j, run.alignment.fit if run is not None and run.alignment is not None else None)
        elif s is JobState.AWAITING_CHECK:
            text = self._check_guidance(job)
        elif s is JobState.DONE:
            text = self.projects.done_instruction(job) or \
                f"done; print it again with ribbonctl start {j}, or remove it: ribbonctl delete {j}"
        else:
            text, cmds = _ended_guidance(job)
        return {"instruction": text, "commands": cmds if cmds is not None else [f"ribbonctl {c} {j}"
                                                                                for c in COMMANDS[s]]}

    def _ready_guidance(self, job: JobRecord) -> tuple[str, list[str] | None]:
        j = job.id
        if not job.start_when_ready:
            return f"ready to print: ribbonctl start {j}", None
        if waits_at_gate(job) and job.panel is not None:
            return panel_instruction(job), ["ribbonctl frame-ready", f"ribbonctl cancel {j}"]
        if waits_at_gate(job):
            return f"waiting for a fresh frame: {FRESH_FRAME_INSTRUCTION}", ["ribbonctl frame-ready",
                                                                            f"ribbonctl cancel {j}"]
        link = self.head.link
        connected = link is not None and link.state in (LinkState.READY, LinkState.STREAMING, LinkState.PAUSED)
        text = "queued: it prints when the printer is free" + (
            "" if connected else " (the printer is not connected: it prints once it is)")
        return text, [f"ribbonctl cancel {j}"]

    def _flip_guidance(self, job: JobRecord) -> str:
        frame = self.profile.frame
        axis = frame.flip_axis
        other, c = ("x", frame.center[0]) if axis == "y" else ("y", frame.center[1])
        return (f"the front is printed. Turn the frame over about its {axis} axis (the line "
                f"{other} = {c:g}), seat it again, then run: ribbonctl flip-done {job.id}")

    def _check_guidance(self, job: JobRecord) -> str:
        j, run = job.id, self.state.current(job.id)
        plan = run.resume if run is not None and run.resume is not None else self.state.resumes.get(j)
        side = plan.side if plan is not None else job.side or "front"
        if plan is not None and plan.flip:
            return ("resuming at the flip: the front is printed and the frame was never turned over; the "
                    "heaters are being set, then you are told to turn the frame over (ribbonctl flip-done "
                    f"{j}), and the registration marks are measured")
        keep = f"; if the frame was not moved, ribbonctl frame-ok {j} --keep-alignment takes the " \
            "stored alignment" if job.side == "back" and job.correction else ""
        return (f"resuming: check the frame is seated, {side} side up, and nothing is in the way, then "
                f"run: ribbonctl frame-ok {j}" + (" (the registration marks are measured again"
                                                 f"{keep})" if side == "back" else ""))

    def status(self, job: JobRecord) -> dict[str, Any]:
        """The job as people see it: the record, its progress and time left, what to do next."""
        data = job.model_dump(mode="json")
        info = self.progress(job)
        data.update(progress=info.pop("progress"), **info, next=self.guidance(job),
                    compile_progress=job.progress, waits_for_operator=self._waits(job),
                    waiting_for=self._waiting_for(job))
        run = self.state.current(job.id)
        if job.state is JobState.FITTED and run is not None and run.alignment is not None:
            data["fit"] = run.alignment.fit
        if job.state is JobState.ALIGNING and run is not None and run.alignment is not None:
            data["alignment"] = {"marks": len(run.alignment.expected), "kept": run.alignment.kept,
                                 "remeasure": list(run.alignment.remeasure)}
        data["verdict"] = self.verdicts.lines(job)
        data["prediction"] = self.predictor.view(job.id)
        data["snapshots"] = self.camera.snapshots(self.job_dir(job.id))
        return data

    def _waiting_for(self, job: JobRecord) -> str | None:
        """What the job waits for while it waits for a person (``_waits``), in a few words; None
        when it does not wait (issue 36: a wait is not shown as progress with a time left)."""
        if not self._waits(job):
            return None
        s, run = job.state, self.state.current(job.id)
        if s is JobState.READY:
            return "a fresh frame" if waits_at_gate(job) else "you to start it"
        if s is JobState.ALIGNING and run is not None and run.alignment is not None:
            return f"mark {run.alignment.current} of {len(run.alignment.expected)}"
        # (what to do is the job's ``next``: here only what it waits for, the same words on every client)
        return {JobState.AWAITING_FLIP: "the flip", JobState.FITTED: "your review of the fit",
                JobState.PAUSED: "resume", JobState.AWAITING_CHECK: "the frame check"}.get(s)

    def _waits(self, job: JobRecord) -> bool:
        """Nothing happens until the operator acts (a ready job nobody started, the flip, a mark
        the head is above, a pause)."""
        if job.state is JobState.READY:
            return not job.start_when_ready or waits_at_gate(job)
        if job.state is JobState.ALIGNING:
            run = self.state.current(job.id)
            return run is not None and run.alignment is not None and run.alignment.current > 0
        return job.state in (JobState.AWAITING_FLIP, JobState.FITTED, JobState.PAUSED) or (
            job.state is JobState.AWAITING_CHECK and job.stage == "check the frame")
