"""Projects (issue 26): a mesh too large or too curved for one sheet, compiled once into panels
(``python -m ribbond.daemon.components.project_worker``, one process, after the compiles queued
before it), then one two-sided job per panel, queued in order. Each panel job prints as any design
job does (the fresh-frame gate, the front, the flip and the alignment, the back); between panels the
operator loads a fresh stretched frame. The project's view (``view``) is its panel map, the panel
on the printer, those done and what the operator does next; ``cancel`` cancels what is left.

Files: ``<state_dir>/projects/ID/`` holds the upload, ``compile.log``, ``project/`` (``project.json``,
``panels.png``, ``panel-K/`` design folders) and ``plans/`` (each panel's front and back plans,
copied into its job's folder)."""

from __future__ import annotations

import json
import logging
import os
import shutil
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any

from ribbond.design.verdict import project_reached, project_verdict_lines
from ..config import DaemonConfig
from ..jobs import TRANSITIONS, JobState
from ..records import JobRecords, NotFound, ServiceError
from ..store import JobRecord, ProjectRecord
from .compiler import run_worker
from .frame import waits_at_gate

log = logging.getLogger(__name__)

#: Project ids: ``prj-`` and 8 hex digits (job ids are 12 hex digits: the two never meet).
PREFIX = "prj-"
#: The files of a project that can be fetched: where each is.
PROJECT_FILES = ("project.json", "panels.png", "target.obj", "deployed.obj", "deployed.png")
#: What the operator does between panels.
FRESH_FRAME = "load a fresh stretched frame, then confirm: ribbonctl frame-ready"


def sewing_instruction(n: int, seams: list[dict[str, Any]], allowance_mm: float) -> str:
    """``all 3 panels are printed: release them and sew seams A–C, in this order: A (panels 1 and 2),
    …`` (project.json's seams in their order: each joins a panel to those sewn before it)."""
    if not seams:
        return f"all {n} panels are printed: release them and sew them together, {allowance_mm:g} mm seam allowance"
    labels = [str(s["label"]) for s in seams]
    span = labels[0] if len(labels) == 1 else f"{labels[0]}–{labels[-1]}"
    order = ", ".join(f"{s['label']} (panels {' and '.join(map(str, s['panels']))})" for s in seams)
    return (f"all {n} panels are printed: release them and sew seam{'s' if len(seams) > 1 else ''} {span}, in this "
            f"order: {order}; pin each seam's stitch marks together first (A1 to A1, A2 to A2 …), "
            f"{allowance_mm:g} mm seam allowance")


def panel_instruction(job: JobRecord) -> str:
    """``panel 2 of 3: load a fresh stretched frame, then confirm: ribbonctl frame-ready``."""
    return f"panel {job.panel} of {job.panels}: {FRESH_FRAME}"


#: The most panels a project may ask for (the engine's ``ribbond.panels.project.MAX_PANELS``).
MAX_PANELS = 16


def check_panels(panels: str) -> str:
    """``auto`` or a whole number of panels from 2 to 16 (ValueError naming the field otherwise)."""
    text = panels.strip()
    if text == "auto" or (text.isdigit() and 2 <= int(text) <= MAX_PANELS):
        return text
    raise ValueError(f"panels = {panels!r}: 'auto' or a whole number of panels from 2 to {MAX_PANELS} "
                     "(one panel is an ordinary job: leave panels out)")


class Projects:
    """Projects and their panel jobs. ``describe`` is a job as people see it (the service's status),
    ``cancel_job`` and ``start_job`` the service's own commands on one job."""

    def __init__(self, config: DaemonConfig, records: JobRecords, tables_dir: Path, python: str,
                 queue_print: Callable[[str], None], describe: Callable[[JobRecord], dict[str, Any]],
                 cancel_job: Callable[[str], Awaitable[JobRecord]], start_job: Callable[[str], JobRecord]) -> None:
        self.config, self.records, self.tables_dir, self.python = config, records, tables_dir, python
        self.queue_print, self.describe, self.cancel_job, self.start_job = queue_print, describe, cancel_job, start_job
        self.projects_dir = Path(config.state_dir) / "projects"
        self._compiling: dict[str, Any] = {}
        self._layouts: dict[str, tuple[float, dict[str, Any]]] = {}

    def dir(self, project_id: str) -> Path:
        return self.projects_dir / project_id

    def new_id(self) -> str:
        return PREFIX + os.urandom(4).hex()

    def create(self, project_id: str, mesh: Path, parameters: dict[str, Any], panels: str,
               seam_allowance: float, start: bool) -> ProjectRecord:
        """The project's row, its mesh already in its folder; published."""
        project = self.records.store.create_project(
            project_id=project_id, mesh_name=mesh.name, mesh_path=str(mesh), parameters=parameters,
            panels_requested=panels, seam_allowance_mm=seam_allowance, start_when_ready=start)
        self.publish(project)
        return project

    def publish(self, project: ProjectRecord) -> None:
        self.records.bus.publish({"type": "project", "project": self.view(project)})

    def _update(self, project_id: str, **fields: Any) -> ProjectRecord:
        project = self.records.store.update_project(project_id, **fields)
        self.publish(project)
        return project

    def pending(self) -> list[str]:
        """At the daemon's start: projects to compile (again: a stop interrupted their compile)."""
        out = []
        for project in reversed(self.records.store.projects()):
            if project.state in ("submitted", "compiling"):
                self.records.store.update_project(project.id, state="submitted", stage=None)
                out.append(project.id)
        return out

    # ------------------------------------------------------------------ the compile

    def stop(self, project_id: str) -> bool:
        proc = self._compiling.get(project_id)
        if proc is None:
            return False
        proc.kill()
        return True

    def stop_all(self) -> None:
        for key in list(self._compiling):
            self.stop(key)

    async def compile(self, project_id: str) -> None:
        """The compile task's turn for a project: its worker, then one ready job per panel; an
        internal error fails the project, never the daemon."""
        try:
            await self._compile(project_id)
        except NotFound:
            return
        except Exception as exc:  # noqa: BLE001 - one project's failure never stops the daemon
            log.exception("compiling project %s", project_id)
            self._update(project_id, state="failed", stage=None, error=f"internal error while compiling: {exc}")

    async def _compile(self, project_id: str) -> None:
        project = self.records.project(project_id)
        if project.state != "submitted":
            return
        self._update(project_id, state="compiling", stage="load")
        folder = self.dir(project_id)
        params = {**project.parameters, "printer_profile": self.config.printer_profile}
        command = [self.python, "-m", "ribbond.daemon.components.project_worker", project.mesh_path,
                   str(folder / "project"), "--panels", project.panels_requested, "--seam-allowance",
                   str(project.seam_allowance_mm), "--params", json.dumps(params), "--plans", str(folder / "plans"),
                   "--tables", str(self.tables_dir), "--max-faces", str(self.config.limits.max_faces)] \
            + ([] if self.config.design.predict else ["--no-predict"]) \
            + ([] if self.config.design.optimize else ["--no-optimize"])

        def on_event(event: dict[str, Any]) -> None:
            if event.get("event") == "stage" and event.get("stage") != self.records.project(project_id).stage:
                self._update(project_id, stage=event["stage"])

        log_path = folder / "compile.log"
        code, last = await run_worker(command, log_path, on_event, self._compiling, project_id)
        if self.records.project(project_id).state != "compiling":
            return                                             # cancelled meanwhile
        if code == 0 and last.get("event") == "done":
            self._compiled(self.records.project(project_id), Path(last["project_dir"]))
        elif last.get("event") == "error":
            self._update(project_id, state="failed", stage=None, error=str(last["message"]))
        elif code < 0:
            self._update(project_id, state="cancelled", stage=None)
        else:
            tail = log_path.read_text(errors="replace").strip().splitlines()[-1:] or ["no output"]
            self._update(project_id, state="failed", stage=None, error=f"the compiler stopped ({code}): {tail[0]}")

    def _compiled(self, project: ProjectRecord, project_dir: Path) -> None:
        """One ``ready`` job per panel (its plans copied into the job's folder), queued in order when
        the project is to print as soon as compiled."""
        layout = json.loads((project_dir / "project.json").read_text(encoding="utf-8"))
        panels = layout["panels"]
        jobs = [self._panel_job(project, project_dir, entry, len(panels)) for entry in panels]
        project = self._update(project.id, state="compiled", stage=None, folder=str(project_dir),
                               panel_count=len(panels))
        log.info("project %s: %d panels, jobs %s", project.id, len(panels), ", ".join(j.id for j in jobs))
        if project.start_when_ready:
            for job in jobs:
                self.queue_print(job.id)

    def _panel_job(self, project: ProjectRecord, project_dir: Path, entry: dict[str, Any], count: int) -> JobRecord:
        records, k = self.records, int(entry["index"])
        design_dir = project_dir / entry["folder"]
        job = records.store.create(mesh_name=project.mesh_name, mesh_path=project.mesh_path,
                                   parameters=project.parameters, start_when_ready=project.start_when_ready,
                                   panel=(project.id, k, count))
        plans = records.dir(job.id) / "plans"
        plans.mkdir(parents=True, exist_ok=True)
        for side in ("front", "back"):
            shutil.copyfile(self.dir(project.id) / "plans" / f"panel-{k}-{side}-plan.npz", plans / f"{side}-plan.npz")
        report = json.loads((design_dir / "design.json").read_text(encoding="utf-8")).get("report") or {}
        printed = report.get("print") or {}
        estimate = {side: float((printed.get(side) or {}).get("time_s") or 0.0) for side in ("front", "back")}
        return records.transition(job.id, JobState.READY, reason=f"project {project.id}: panel {k} of {count}",
                                  design_dir=str(design_dir), estimate_s=estimate)

    # ------------------------------------------------------------------ commands

    def show(self, project_id: str) -> dict[str, Any]:
        """The project's view (``view``), or ``NotFound``."""
        return self.view(self.records.project(project_id))

    async def cancel(self, project_id: str) -> ProjectRecord:
        """Cancel what is left: the compile, or the panels not printed (those queued first, so the
        print task takes none of them once the one on the printer stops; that one as a job's cancel)."""
        project = self.records.project(project_id)
        if project.state in ("submitted", "compiling"):
            project = self._update(project_id, state="cancelled", stage=None)
            self.stop(project_id)
            return project
        left = [j for j in self.records.store.project_jobs(project_id)
                if JobState.CANCELLED in TRANSITIONS[j.state]]
        if project.state != "compiled" or not left:
            raise ServiceError(f"cannot cancel project {project_id}: it is {self.view(project)['state']}; "
                               "nothing is left to print")
        project = self._update(project_id, state="cancelled")
        for job in sorted(left, key=lambda j: j.state.holds_printer):
            await self.cancel_job(job.id)
        self.publish(self.records.project(project_id))
        return self.records.project(project_id)

    def start(self, project_id: str) -> ProjectRecord:
        """Print the panels not printed yet, in order (a cancelled project's too: a new run of each)."""
        project = self.records.project(project_id)
        if project.state in ("submitted", "compiling"):
            return self._update(project_id, start_when_ready=True)
        if project.folder is None:
            raise ServiceError(f"cannot start project {project_id}: it {project.state} before its panels were "
                               "made; submit the mesh again")
        jobs = [j for j in self.records.store.project_jobs(project_id)
                if j.state is not JobState.DONE and not j.state.holds_printer
                and not (j.state is JobState.READY and j.start_when_ready)]
        if not jobs and self.view(project)["state"] == "done":
            raise ServiceError(f"cannot start project {project_id}: every panel is printed")
        project = self._update(project_id, state="compiled", start_when_ready=True)
        for job in jobs:
            self.start_job(job.id)
        return project

    def file(self, project_id: str, name: str) -> Path:
        project = self.records.project(project_id)
        if name not in PROJECT_FILES:
            raise NotFound(f"{name!r} is not a project file; files: {', '.join(PROJECT_FILES)}")
        path = Path(project.folder) / name if project.folder else None
        if path is None or not path.is_file():
            raise NotFound(f"project {project_id} has no {name} (yet)")
        return path

    # ------------------------------------------------------------------ what a person sees

    def layout(self, project: ProjectRecord) -> dict[str, Any]:
        """``project.json`` (read once per change of the file), {} before the compile."""
        if project.folder is None:
            return {}
        path = Path(project.folder) / "project.json"
        try:
            mtime = path.stat().st_mtime
        except OSError:
            return {}
        cached = self._layouts.get(project.id)
        if cached is None or cached[0] != mtime:
            cached = (mtime, json.loads(path.read_text(encoding="utf-8")))
            self._layouts[project.id] = cached
        return cached[1]

    def view(self, project: ProjectRecord) -> dict[str, Any]:
        """The project as people see it: the record, its panel map with each job's state, the panel
        on the printer, the panels done, what the operator does next (``ProjectStatus``)."""
        layout = self.layout(project)
        jobs = {j.panel: j for j in self.records.store.project_jobs(project.id)}
        panels = [_panel_view(entry, jobs.get(int(entry["index"])), self.describe) for entry in layout.get("panels", [])]
        state, current = _project_state(project, panels)
        data = project.model_dump(mode="json")
        data.update(state=state, current_panel=current, panels=panels,
                    panels_done=sum(p["state"] == "done" for p in panels),
                    seams=layout.get("seams", []), report=layout.get("report"),
                    reached=project_reached(layout) if layout else None,
                    verdict=project_verdict_lines(layout) if layout else [],
                    has_deployed=bool(project.folder) and (Path(project.folder) / "deployed.png").is_file(),
                    next=_next_step(project, state, current, panels, layout))
        return data

    def done_instruction(self, job: JobRecord) -> str | None:
        """For a panel job that is ``done``: the sewing, once every panel of its project is printed
        (None otherwise, and for a job of no project)."""
        if job.project is None or job.state is not JobState.DONE:
            return None
        try:
            project = self.records.project(job.project)
        except NotFound:
            return None
        jobs = self.records.store.project_jobs(project.id)
        if not jobs or any(j.state is not JobState.DONE for j in jobs):
            return None
        layout = self.layout(project)
        return sewing_instruction(len(layout.get("panels") or jobs), layout.get("seams", []), project.seam_allowance_mm)

    def list(self, limit: int | None = None) -> list[dict[str, Any]]:
        return [self.view(p) for p in self.records.store.projects(limit)]


def _panel_view(entry: dict[str, Any], job: JobRecord | None,
                describe: Callable[[JobRecord], dict[str, Any]]) -> dict[str, Any]:
    status = describe(job) if job is not None else None
    return {"index": int(entry["index"]), "job_id": job.id if job else None,
            "state": job.state.value if job else "deleted", "stage": job.stage if job else None,
            "progress": status["progress"] if status else 0.0,
            "print_side": status["print_side"] if status else None,
            "waits_for_operator": bool(status and status["waits_for_operator"]),
            "at_gate": bool(job is not None and waits_at_gate(job)),
            "queued": bool(job is not None and job.state is JobState.READY and job.start_when_ready),
            "next": status["next"] if status else None,
            "faces": entry.get("faces"), "flat_size_mm": entry.get("flat_size_mm"), "bad_pct": entry.get("bad_pct"),
            "outline": entry.get("outline") or []}


def _project_state(project: ProjectRecord, panels: list[dict[str, Any]]) -> tuple[str, int | None]:
    """The project's state as shown, and the panel on the printer (or next to go on it)."""
    if project.state != "compiled":
        on = next((p["index"] for p in panels if p["state"] in _ON_PRINTER), None)
        return project.state, on
    if panels and all(p["state"] == "done" for p in panels):
        return "done", None
    on = next((p for p in panels if p["state"] in _ON_PRINTER), None) or \
        next((p for p in panels if p["queued"]), None)
    if on is not None:
        return ("waiting" if on["waits_for_operator"] else "printing"), on["index"]
    return "ready", None


_ON_PRINTER = {s.value for s in JobState if s.holds_printer}


def _next_step(project: ProjectRecord, state: str, current: int | None, panels: list[dict[str, Any]],
               layout: dict[str, Any]) -> dict[str, Any]:
    """What the operator does next, for the whole project."""
    p, n = project.id, len(panels) or project.panel_count
    stop = f"ribbonctl project cancel {p}"
    if state in ("submitted", "compiling"):
        stage = f" ({project.stage})" if project.stage else ""
        return {"instruction": f"compiling the panels{stage}; they then print one after the other"
                + ("" if project.start_when_ready else f" once started: ribbonctl project start {p}"),
                "commands": [stop]}
    if state == "failed":
        return {"instruction": f"the compile failed: {project.error}; submit the mesh again", "commands": []}
    if state == "done":
        return {"instruction": sewing_instruction(n, layout.get("seams", []), project.seam_allowance_mm),
                "commands": []}
    done = [q["index"] for q in panels if q["state"] == "done"]
    if state == "cancelled":
        printed = f"panels printed: {', '.join(map(str, done))}" if done else "no panel printed"
        return {"instruction": f"cancelled ({printed}); print what is left: ribbonctl project start {p}",
                "commands": [f"ribbonctl project start {p}"]}
    if current is None:
        left = next((q for q in panels if q["state"] != "done"), None)
        what = f"panel {left['index']} of {n} is {left['state']}; " if left and left["state"] != "ready" else ""
        return {"instruction": f"{what}print the panels left in order: ribbonctl project start {p}",
                "commands": [f"ribbonctl project start {p}", stop]}
    panel = next(q for q in panels if q["index"] == current)
    if panel["at_gate"]:
        return {"instruction": f"panel {current} of {n}: {FRESH_FRAME}", "commands": ["ribbonctl frame-ready", stop]}
    job_next = panel["next"] or {"instruction": "", "commands": []}
    return {"instruction": f"panel {current} of {n}: {job_next['instruction']}",
            "commands": [*job_next["commands"], stop]}
