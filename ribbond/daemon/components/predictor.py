"""Predicting a job's design again (``POST /jobs/{id}/predict``, issue 23 item 4): each prediction a
``python -m ribbond.pipeline.predict_worker`` subprocess, as a compile is a ``ribbond.pipeline.worker`` one, so the
event loop that feeds the printer never computes. Its JSON lines become the job's ``prediction``
(state, fraction, message; then the new ``report.deployed`` and verdict, or the error), published
with the job as compile progress is; its stderr is kept as the job's ``predict.log``.

The job's state does not change: a prediction replaces ``deployed.obj``, ``deployed.png`` and
``report.deployed`` of its design folder atomically (``ribbond.pipeline.repredict``) and nothing the
printer reads. It is refused (409) while the job compiles or holds the printer, when the job has no
design folder, and while a prediction of it runs; the job cannot be deleted meanwhile.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..jobs import IllegalTransition, JobState
from ..records import JobRecords, NotFound, ServiceError
from .compiler import run_worker

log = logging.getLogger(__name__)


def predict_command(python: str, design_dir: str, *, table: str | None,
                    tables: Path | None) -> list[str]:
    """The command line of one prediction (``python -m ribbond.pipeline.predict_worker``)."""
    return [python, "-m", "ribbond.pipeline.predict_worker", design_dir] + (["--table", table] if table else []) \
        + (["--tables", str(tables)] if tables is not None else [])


class Predictor:
    """The predictions of jobs' designs; ``view(job_id)`` is what the job's status shows of its last one.

    ``check_table`` refuses an unknown table name (ValueError, 422); ``forget_verdict`` drops the
    verdict kept for a design folder whose report changed.
    """

    def __init__(self, records: JobRecords, tables_dir: Path, python: str,
                 check_table: Callable[[str], None], forget_verdict: Callable[[str], None]) -> None:
        self.records, self.tables_dir, self.python = records, tables_dir, python
        self.check_table, self.forget_verdict = check_table, forget_verdict
        self._views: dict[str, dict[str, Any]] = {}
        self._procs: dict[str, asyncio.subprocess.Process] = {}
        self._tasks: dict[str, asyncio.Task[None]] = {}

    def running(self, job_id: str) -> bool:
        return job_id in self._tasks

    def view(self, job_id: str) -> dict[str, Any] | None:
        """The job's last prediction in this daemon's life: ``state`` running, done or failed,
        ``fraction``, ``message``, ``table``, then ``deployed`` and ``verdict`` or ``error``."""
        view = self._views.get(job_id)
        return dict(view) if view is not None else None

    def start(self, job_id: str, table: str | None = None) -> None:
        """Start predicting the job's design again (NotFound, ValueError for a bad table,
        IllegalTransition or ServiceError when the job cannot be predicted now)."""
        job = self.records.get(job_id)
        if table is not None:
            self.check_table(table)
        if job.state in (JobState.SUBMITTED, JobState.COMPILING):
            raise IllegalTransition.of(job, "predict", hint="its design is being compiled; the compile predicts it")
        if job.kind != "design" or not job.design_dir or not (Path(job.design_dir) / "design.json").is_file():
            raise ServiceError(f"cannot predict: job {job_id} has no design folder"
                               + (" (a plain G-code program)" if job.kind == "gcode" else ""))
        if job.state.holds_printer:
            raise IllegalTransition.of(job, "predict", hint="predict it again once the print has stopped")
        if self.running(job_id):
            raise ServiceError(f"cannot predict: a prediction of job {job_id} is already running")
        self._views[job_id] = {"state": "running", "fraction": 0.0, "message": "starting", "table": table,
                               "started": time.time()}
        self._tasks[job_id] = asyncio.create_task(self._run(job_id, job.design_dir, table),
                                                  name=f"predict {job_id}")
        self.records.publish(job)

    async def _run(self, job_id: str, design_dir: str, table: str | None) -> None:
        try:
            code, last = await self._worker(job_id, design_dir, table)
            self._finish(job_id, code, last)
        except Exception as exc:  # noqa: BLE001 - one prediction's failure never stops the daemon
            log.exception("predicting job %s", job_id)
            self._views[job_id].update(state="failed", error=f"internal error: {type(exc).__name__}: {exc}")
        finally:
            self._tasks.pop(job_id, None)
            with contextlib.suppress(NotFound):
                self.records.publish(self.records.get(job_id))

    async def _worker(self, job_id: str, design_dir: str, table: str | None) -> tuple[int, dict[str, Any]]:
        """Run the prediction worker to its end, its progress published; its exit status and last event."""
        def on_event(event: dict[str, Any]) -> None:
            if event.get("event") == "progress":
                self._views[job_id].update(fraction=float(event["fraction"]), message=str(event["message"]))
                with contextlib.suppress(NotFound):
                    self.records.publish(self.records.get(job_id))

        return await run_worker(predict_command(self.python, design_dir, table=table,
                                                tables=self.tables_dir),
                                self.records.dir(job_id) / "predict.log", on_event, self._procs, job_id)

    def _finish(self, job_id: str, code: int, last: dict[str, Any]) -> None:
        view = self._views[job_id]
        if code == 0 and last.get("event") == "done":
            self.forget_verdict(job_id)
            view.update(state="done", fraction=1.0, message="predicted", deployed=last.get("deployed"),
                        verdict=last.get("verdict"), table=last.get("table"), time_s=last.get("time_s"))
        elif last.get("event") == "error":
            view.update(state="failed", error=str(last.get("message")), message="failed")
        else:
            tail = (self.records.dir(job_id) / "predict.log").read_text(errors="replace").strip().splitlines()[-1:]
            view.update(state="failed", message="failed",
                        error=f"the prediction stopped ({code}): {tail[0] if tail else 'no output'}")

    def stop_all(self) -> None:
        for proc in self._procs.values():
            with contextlib.suppress(ProcessLookupError):
                proc.kill()
