"""Calibration plans on the daemon (issue 15): a plan made for this daemon's printer, in its own
process (``python -m ribbond.calibration plan``), becomes one ``ready`` two-sided job per sheet;
its files (plan, coupon list, sheet maps) are served from ``<state_dir>/calibrations/cal-ID``.

A plan takes seconds to minutes of CPU, so it is made as a compile is (issue 36 item 14): the request
is checked (the spec, the base table, every coupon within the frame) and answered at once with the
calibration ``planning``; the planner runs in its own process and the sheets' jobs appear when it
ends (``ready``), or the calibration says why it ``failed``. ``status.json`` in the plan's folder
keeps that state across restarts; a plan the daemon stopped in the middle of is ``failed``.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import re
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ribbond.design.thickness import available_tables
from ..config import DaemonConfig
from ..jobs import JobState
from ..records import JobRecords, NotFound
from .compiler import worker_environment

if TYPE_CHECKING:
    from ribbond.calibration.spec import CalibrationSpec

#: The file of a plan's folder that says where its planning stands.
STATUS_FILE = "status.json"
_CAL_ID = re.compile(r"cal-[0-9a-f]{8}")


class Calibrations:
    """Calibration plans and their jobs; ``queue_print`` queues a job on the printer."""

    def __init__(self, config: DaemonConfig, records: JobRecords, queue_print: Callable[[str], None],
                 python: str) -> None:
        self.config, self.records, self.queue_print, self.python = config, records, queue_print, python
        self.calibrations_dir = Path(config.state_dir) / "calibrations"
        self._planning: dict[str, asyncio.subprocess.Process | None] = {}
        self._tasks: set[asyncio.Task[None]] = set()

    async def submit_calibration(self, spec: dict[str, Any], start: bool) -> dict[str, Any]:
        """Check ``spec`` for this daemon's printer (ValueError naming what is refused) and start
        making its plan in a process of its own; the calibration as ``calibration()`` shows it
        (``planning``). When the plan is made, one ``ready`` two-sided job per sheet (the first
        queued if ``start``)."""
        cal = self._spec(spec)
        await asyncio.to_thread(_check_layout, cal)          # a coupon larger than the frame: 422 now
        if start:
            self.records.check_queue()
        cal_id = "cal-" + os.urandom(4).hex()
        folder = self.calibrations_dir / cal_id
        folder.mkdir(parents=True)
        self._write_status(folder, {"state": "planning"})
        self._planning[cal_id] = None
        task = asyncio.create_task(self._plan(cal_id, folder, cal, start), name=f"plan {cal_id}")
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)
        return self.calibration(cal_id)

    async def _plan(self, cal_id: str, folder: Path, cal: CalibrationSpec, start: bool) -> None:
        """The planner's process, then the sheets' jobs; the outcome in ``status.json``."""
        try:
            proc = await asyncio.create_subprocess_exec(
                self.python, "-m", "ribbond.calibration", "plan", "--spec", cal.model_dump_json(), "-o", str(folder),
                stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE, env=worker_environment())
            self._planning[cal_id] = proc
            _, err = await proc.communicate()
            if proc.returncode != 0:
                tail = (err.decode(errors="replace").strip().splitlines() or ["no output"])[-1]
                raise ValueError(f"the calibration plan cannot be made: {tail}")
            plan = json.loads((folder / "plan.json").read_text(encoding="utf-8"))
            jobs = [self._sheet_job(cal_id, folder, sheet, len(plan["sheets"]), start) for sheet in plan["sheets"]]
            self._write_status(folder, {"state": "ready", "sheets": len(plan["sheets"]),
                                        "coupons": len(plan["coupons"]), "jobs": jobs})
        except asyncio.CancelledError:
            raise
        except Exception as exc:  # noqa: BLE001 - any failure is the calibration's, told to the client
            self._write_status(folder, {"state": "failed", "error": str(exc)})
        finally:
            self._planning.pop(cal_id, None)

    def calibration(self, cal_id: str) -> dict[str, Any]:
        """``GET /calibrations/{id}``: ``state`` planning, ready (``sheets``, ``coupons``, ``jobs``)
        or failed (``error``); a plan left ``planning`` by a daemon that stopped is failed."""
        folder = self._folder(cal_id)
        try:
            status = json.loads((folder / STATUS_FILE).read_text(encoding="utf-8"))
        except FileNotFoundError:                # made before status.json: ready if its plan is there
            status = _status_of_old_plan(folder, self.records)
        if status.get("state") == "planning" and cal_id not in self._planning:
            status = {"state": "failed", "error": "the daemon stopped while the plan was being made: ask for it again"}
        return {"calibration": cal_id, "state": status["state"], "sheets": status.get("sheets"),
                "coupons": status.get("coupons"), "jobs": status.get("jobs", []), "error": status.get("error"),
                "folder": str(folder)}

    def stop_all(self) -> None:
        """Stop the planners (the daemon is stopping)."""
        for proc in self._planning.values():
            if proc is not None:
                with contextlib.suppress(ProcessLookupError):
                    proc.kill()
        for task in self._tasks:
            task.cancel()

    @staticmethod
    def _write_status(folder: Path, status: dict[str, Any]) -> None:
        tmp = folder / f".{STATUS_FILE}.tmp"
        tmp.write_text(json.dumps(status), encoding="utf-8")
        os.replace(tmp, folder / STATUS_FILE)

    def _folder(self, cal_id: str) -> Path:
        if not _CAL_ID.fullmatch(cal_id) or not (self.calibrations_dir / cal_id).is_dir():
            raise NotFound(f"no calibration {cal_id!r}")
        return self.calibrations_dir / cal_id

    def _spec(self, spec: dict[str, Any]) -> CalibrationSpec:
        """The plan's ``CalibrationSpec`` for this daemon's printer; ValueError naming what is refused."""
        from ribbond.calibration.spec import CalibrationSpec     # the engine's models: loaded when first used

        asked = spec.get("printer_profile")
        if asked is not None and asked != self.config.printer_profile:
            raise ValueError(f"printer_profile {asked!r}: this daemon drives a {self.config.printer_profile!r} "
                             "printer; leave printer_profile out")
        base = spec.get("base_table", CalibrationSpec().base_table)
        if base not in available_tables():
            raise ValueError(f"base_table {base!r}: give a shipped table ({', '.join(available_tables())})")
        return CalibrationSpec.model_validate({**spec, "printer_profile": self.config.printer_profile})

    def _sheet_job(self, cal_id: str, folder: Path, sheet: dict[str, Any], sheets: int, start: bool) -> str:
        """The ``ready`` job of one sheet (its plans copied into the job's folder); its id."""
        records, k = self.records, sheet["sheet"]
        job = records.store.create(mesh_name=f"{cal_id}-sheet-{k}", mesh_path=str(folder),
                                   parameters={"calibration": cal_id, "sheet": k}, start_when_ready=start and k == 1)
        (records.dir(job.id) / "plans").mkdir(parents=True, exist_ok=True)
        for side in ("front", "back"):
            shutil.copyfile(folder / "plans" / f"sheet-{k}-{side}-plan.npz",
                            records.dir(job.id) / "plans" / f"{side}-plan.npz")
        job = records.transition(job.id, JobState.READY,
                                 reason=f"calibration {cal_id}: sheet {k} of {sheets}, coupons "
                                        f"{sheet['coupons'][0]}-{sheet['coupons'][-1]}",
                                 design_dir=str(folder / f"sheet-{k}"), estimate_s=sheet["time_s"])
        if job.start_when_ready:
            self.queue_print(job.id)
        return job.id

    def calibration_file(self, cal_id: str, name: str) -> Path:
        """A file of a calibration plan: plan.json, coupons.csv, sheet-K.png or sheet-K.svg."""
        folder = self._folder(cal_id)
        if not re.fullmatch(r"plan\.json|coupons\.csv|sheet-[0-9]{1,3}\.(png|svg)", name):
            raise NotFound(f"{name!r} is not a calibration file; files: plan.json, coupons.csv, sheet-K.png, sheet-K.svg")
        path = folder / name
        if not path.is_file():
            state = self.calibration(cal_id)["state"]
            raise NotFound(f"calibration {cal_id} has no {name}" + (" yet (planning)" if state == "planning" else ""))
        return path


def _check_layout(cal: CalibrationSpec) -> None:
    """Every coupon of the plan fits the frame (``ribbond.calibration.plan.layout``, fast: no design);
    ValueError naming the coupon and the room."""
    from ribbond.calibration.plan import layout
    from ribbond.gcode.profiles import load_profile

    layout(cal, load_profile(cal.printer_profile))


def _status_of_old_plan(folder: Path, records: JobRecords) -> dict[str, Any]:
    """The status of a plan made before ``status.json`` (its jobs found by their parameters)."""
    if not (folder / "plan.json").is_file():
        return {"state": "failed", "error": "the plan was never written"}
    plan = json.loads((folder / "plan.json").read_text(encoding="utf-8"))
    jobs = [j.id for j in reversed(records.store.list())
            if (j.parameters or {}).get("calibration") == folder.name]
    return {"state": "ready", "sheets": len(plan["sheets"]), "coupons": len(plan["coupons"]), "jobs": jobs}
