"""The compile queue: each design compiled by a ``python -m ribbond.pipeline.worker`` subprocess, one at a
time, so the event loop that feeds the printer never computes a design. The worker's JSON lines
(stages, iterations, done or error) become the job's stage and events; its stderr is kept as the
job's ``compile.log``. A compile whose inputs were compiled before is served from the compile cache
(``compile_cache.py``, ``[design] cache_dir``): the same folder, events and report, at once."""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import os
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any

from ...datafiles import toml_path
from ...gcode.profiles import PROFILE_DIR
from ..config import DaemonConfig
from ..jobs import JobState
from ..records import JobRecords, NotFound
from ..store import JobRecord
from .compile_cache import CompileCache, engine_identity

log = logging.getLogger(__name__)

#: The compile's stages in order (``ribbond.pipeline.compile``): a compile's progress.
COMPILE_STAGES = ("load", "curvature", "flatten", "stripes", "ribbons", "optimize", "gcode", "deploy", "preview", "write")


def worker_command(python: str, mesh: str, out: Path, parameters: dict[str, Any], plans: Path,
                   tables: Path | None = None, max_faces: int | None = None, predict: bool = True,
                   optimize: bool = True) -> list[str]:
    """The command line of one compile (``python -m ribbond.pipeline.worker``); ``parameters`` in the
    ``--params`` layout (design parameters, an optional ``solver`` table), ``max_faces`` the
    daemon's ``[limits] max_faces``, ``predict`` its ``[design] predict``, ``optimize`` its
    ``[design] optimize``."""
    return [python, "-m", "ribbond.pipeline.worker", mesh, str(out), "--params", json.dumps(parameters),
            "--plans", str(plans)] + (["--tables", str(tables)] if tables is not None else []) \
        + (["--max-faces", str(max_faces)] if max_faces is not None else []) \
        + ([] if predict else ["--no-predict"]) + ([] if optimize else ["--no-optimize"])


async def run_worker(command: list[str], log_path: Path, on_event: Callable[[dict[str, Any]], None],
                     running: dict[str, asyncio.subprocess.Process], key: str) -> tuple[int, dict[str, Any]]:
    """Run a worker process (``command``) that speaks JSON lines on stdout, its stderr kept in
    ``log_path``, each event handed to ``on_event``; the process sits in ``running[key]`` while it
    runs (so that it can be stopped). Returns its exit status and its last event."""
    with log_path.open("wb") as errors:                  # the worker's stderr: kept for the operator
        proc = await asyncio.create_subprocess_exec(*command, stdout=asyncio.subprocess.PIPE, stderr=errors,
                                                    env=worker_environment())
    running[key] = proc
    last: dict[str, Any] = {}
    try:
        assert proc.stdout is not None
        async for raw in proc.stdout:
            try:
                event = json.loads(raw)
            except ValueError:
                continue
            last = event
            on_event(event)
        return await proc.wait(), last
    finally:
        running.pop(key, None)


def worker_environment() -> dict[str, str]:
    """The compile's environment: its numeric libraries use all cores but one, which is left to
    the event loop that feeds the printer (the worker also runs at nice +10)."""
    threads = str(max(1, (os.cpu_count() or 2) - 1))
    limits = {name: threads for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}
    return {**os.environ, **limits}


def open_cache(directory: Path | None) -> CompileCache | None:
    """The compile cache in ``directory`` (None: off), the engine's identity hashed once, now.

    Raises
    ------
    ValueError
        naming ``[design] cache_dir`` when the folder cannot be made or used."""
    if directory is None:
        return None
    try:
        return CompileCache(directory, engine_identity())
    except OSError as exc:
        raise ValueError(f"[design] cache_dir {str(directory)!r}: cannot use it: {exc.strerror or exc} "
                         '("" turns the compile cache off)') from None


def profile_file(profile: str) -> Path | None:
    """The printer profile's file: a path ending in ``.toml``, else a shipped profile's."""
    path = toml_path(profile, PROFILE_DIR)
    return path if path.is_file() else None


class Compiler:
    """The compile queue. A compiled job that is to print when ready goes to ``queue_print``."""

    def __init__(self, config: DaemonConfig, records: JobRecords, tables_dir: Path,
                 queue_print: Callable[[str], None], python: str) -> None:
        self.config, self.records, self.tables_dir = config, records, tables_dir
        self.queue_print, self.python = queue_print, python
        self._queue: asyncio.Queue[str] = asyncio.Queue()
        self._compiling: dict[str, asyncio.subprocess.Process] = {}
        #: A project's compile (``projects.Projects.compile``), queued here by its id (``prj-…``) so
        #: that one compile runs at a time.
        self.project_compile: Callable[[str], Awaitable[None]] | None = None
        self.cache = open_cache(config.compile_cache_dir)

    def queue(self, job_id: str) -> None:
        """Compile the (submitted) job, or project, after those queued before it."""
        self._queue.put_nowait(job_id)

    def stop(self, job_id: str) -> bool:
        """Kill the job's compile, if it runs (the compile task then ends the job); whether it ran."""
        proc = self._compiling.get(job_id)
        if proc is None:
            return False
        with contextlib.suppress(ProcessLookupError):
            proc.kill()
        return True

    def stop_all(self) -> None:
        for proc in self._compiling.values():
            with contextlib.suppress(ProcessLookupError):
                proc.kill()

    async def run(self) -> None:
        """The compile task: one job after the other, for the daemon's life."""
        while True:
            job_id = await self._queue.get()
            try:
                if job_id.startswith("prj-") and self.project_compile is not None:
                    await self.project_compile(job_id)
                    continue
                await self._compile(job_id)
            except NotFound:
                continue
            except Exception:  # noqa: BLE001 - one job's failure never stops the daemon
                log.exception("compiling job %s", job_id)
                with contextlib.suppress(Exception):
                    self.records.transition(job_id, JobState.FAILED,
                                            reason="internal error while compiling (see the log)")

    async def _compile(self, job_id: str) -> None:
        records = self.records
        job = records.get(job_id)
        if job.state is not JobState.SUBMITTED:
            return
        folder = records.dir(job_id)
        if not Path(job.mesh_path).is_file() or not folder.is_dir():
            # a job an older daemon left without its upload (its row was written first)
            records.transition(job_id, JobState.FAILED, reason="the uploaded mesh is missing",
                               error=f"the uploaded mesh {job.mesh_name!r} was never stored (the submit failed "
                                     "part way); submit it again")
            return
        records.transition(job_id, JobState.COMPILING, stage="load", progress=0.0)
        log_path = folder / "compile.log"
        key = await asyncio.to_thread(self._key, job) if self.cache is not None else None
        served = await asyncio.to_thread(self.cache.serve, key, folder) if self.cache and key else None
        events: list[dict[str, Any]] = []
        if served is not None and records.get(job_id).state is not JobState.COMPILING:
            return                                            # cancelled while it was copied
        if served is not None:
            log_path.write_text(f"served from the compile cache {self.cache.directory} ({key}): the same "
                                "mesh, parameters, tables, profile and engine were compiled before\n")
            for event in served:
                self._on_event(job, event)
            code, last = 0, served[-1]
        else:
            code, last = await self._run_worker(job, folder, log_path, events)
        if records.get(job_id).state is not JobState.COMPILING:
            return                                            # cancelled meanwhile
        if self.cache and key and served is None and code == 0 and last.get("event") == "done":
            await asyncio.to_thread(self.cache.store, key, folder, events)
        self._finish(job_id, code, last, log_path)

    def _key(self, job: JobRecord) -> str | None:
        """The job's compile-cache key: its mesh, what ``_run_worker`` gives the worker, the
        daemon's tables and profile (None if the mesh cannot be read: the compile says why)."""
        assert self.cache is not None
        inputs = {**self._worker_inputs(job), "threads": worker_environment()["OMP_NUM_THREADS"]}
        try:
            return self.cache.key(Path(job.mesh_path), inputs, self.tables_dir,
                                  profile_file(self.config.printer_profile))
        except OSError:
            return None

    def _worker_inputs(self, job: JobRecord) -> dict[str, Any]:
        """What the job's worker is given besides its mesh, tables and folders (``worker_command``'s
        keywords): the one place ``_run_worker`` and the cache's key read it from."""
        design = self.config.design
        return {"parameters": {**job.parameters, "printer_profile": self.config.printer_profile},
                "max_faces": self.config.limits.max_faces, "predict": design.predict,
                "optimize": design.optimize}

    def _on_event(self, job: JobRecord, event: dict[str, Any]) -> None:
        """One of the compile's events: a stage's start moves the job's stage, an iteration is progress."""
        if event.get("event") == "stage":
            self.records.publish(self.records.store.update(job.id, stage=event["stage"], progress=None))
        elif event.get("event") == "iteration":
            self.records.publish(self.records.get(job.id), progress_event=event)

    async def _run_worker(self, job: JobRecord, folder: Path, log_path: Path,
                          events: list[dict[str, Any]]) -> tuple[int, dict[str, Any]]:
        """Run the job's worker to its end, its events published as they come and kept in
        ``events`` (for the cache); its exit status and its last event."""
        def on_event(event: dict[str, Any]) -> None:
            events.append(event)
            self._on_event(job, event)

        inputs = self._worker_inputs(job)
        command = worker_command(self.python, job.mesh_path, folder / "design", inputs.pop("parameters"),
                                 folder / "plans", self.tables_dir, **inputs)
        return await run_worker(command, log_path, on_event, self._compiling, job.id)

    def _finish(self, job_id: str, code: int, last: dict[str, Any], log_path: Path) -> None:
        """The job after its worker ended: ``ready`` (queued to print if asked), failed or cancelled."""
        records = self.records
        if code == 0 and last.get("event") == "done":
            printed = (last.get("report") or {}).get("print") or {}
            estimate = {side: float((printed.get(side) or {}).get("time_s") or 0.0) for side in ("front", "back")}
            job = records.transition(job_id, JobState.READY, design_dir=last["design_dir"], stage=None,
                                     progress=None, estimate_s=estimate)
            if job.start_when_ready:
                self.queue_print(job_id)
        elif last.get("event") == "error":
            records.transition(job_id, JobState.FAILED, reason=last["message"], error=last["message"])
        elif code < 0:
            records.transition(job_id, JobState.CANCELLED, reason="the compile was stopped")
        else:
            tail = log_path.read_text(errors="replace").strip().splitlines()[-1:] or ["no output"]
            records.transition(job_id, JobState.FAILED, reason=f"the compiler stopped ({code}): {tail[0]}",
                               error=tail[0])
