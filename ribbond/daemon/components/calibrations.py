"""Calibration plans on the daemon (issue 15): a plan made for this daemon's printer, in its own
process (``python -m ribbond.calibration plan``), becomes one ``ready`` two-sided job per sheet;
its files (plan, coupon list, sheet maps) are served from ``<state_dir>/calibrations/cal-ID``."""

from __future__ import annotations

import asyncio
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


class Calibrations:
    """Calibration plans and their jobs; ``queue_print`` queues a job on the printer."""

    def __init__(self, config: DaemonConfig, records: JobRecords, queue_print: Callable[[str], None],
                 python: str) -> None:
        self.config, self.records, self.queue_print, self.python = config, records, queue_print, python
        self.calibrations_dir = Path(config.state_dir) / "calibrations"

    async def submit_calibration(self, spec: dict[str, Any], start: bool) -> dict[str, Any]:
        """Make a calibration plan (``python -m ribbond.calibration plan``, its own process) for this
        daemon's printer and one ``ready`` two-sided job per sheet (the first queued if ``start``)."""
        cal = self._spec(spec)
        if start:
            self.records.check_queue()
        cal_id = "cal-" + os.urandom(4).hex()
        folder = self.calibrations_dir / cal_id
        folder.parent.mkdir(parents=True, exist_ok=True)
        proc = await asyncio.create_subprocess_exec(
            self.python, "-m", "ribbond.calibration", "plan", "--spec", cal.model_dump_json(), "-o", str(folder),
            stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE, env=worker_environment())
        out, err = await proc.communicate()
        if proc.returncode != 0:
            tail = (err.decode(errors="replace").strip().splitlines() or ["no output"])[-1]
            shutil.rmtree(folder, ignore_errors=True)
            raise ValueError(f"the calibration plan cannot be made: {tail}")
        plan = json.loads((folder / "plan.json").read_text(encoding="utf-8"))
        jobs = [self._sheet_job(cal_id, folder, sheet, len(plan["sheets"]), start) for sheet in plan["sheets"]]
        return {"calibration": cal_id, "sheets": len(plan["sheets"]), "coupons": len(plan["coupons"]),
                "jobs": jobs, "folder": str(folder)}

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
        if not re.fullmatch(r"cal-[0-9a-f]{8}", cal_id) or not (self.calibrations_dir / cal_id).is_dir():
            raise NotFound(f"no calibration {cal_id!r}")
        if not re.fullmatch(r"plan\.json|coupons\.csv|sheet-[0-9]{1,3}\.(png|svg)", name):
            raise NotFound(f"{name!r} is not a calibration file; files: plan.json, coupons.csv, sheet-K.png, sheet-K.svg")
        path = self.calibrations_dir / cal_id / name
        if not path.is_file():
            raise NotFound(f"calibration {cal_id} has no {name}")
        return path
