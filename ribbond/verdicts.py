"""The verdict of each job's design, for the job's status (issue 22 item 4): the lines of
``ribbond.design.verdict`` read once from the job's ``design.json`` and kept (a design folder does
not change once written), so a status costs no file read after the first."""

from __future__ import annotations

import json
import logging
from collections import OrderedDict
from pathlib import Path

from .design.verdict import verdict_lines
from .store import JobRecord

log = logging.getLogger(__name__)

#: Designs whose verdict is kept in memory (the newest jobs; an older one is read again if asked).
KEPT = 256


class Verdicts:
    """``lines(job)``: the verdict of a job's design, or None (no design yet, a plain G-code job, a
    design without the flattening's report such as a calibration sheet's)."""

    def __init__(self) -> None:
        self._kept: OrderedDict[str, list[str] | None] = OrderedDict()

    def lines(self, job: JobRecord) -> list[str] | None:
        if job.kind != "design" or not job.design_dir:
            return None
        if job.design_dir in self._kept:
            self._kept.move_to_end(job.design_dir)
            return self._kept[job.design_dir]
        path = Path(job.design_dir) / "design.json"
        try:
            design = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            log.debug("no verdict for job %s: %s unreadable", job.id, path, exc_info=True)
            return None                                   # not kept: it may be written later
        report = design.get("report") if isinstance(design, dict) else None
        lines = verdict_lines(design) if isinstance(report, dict) and "sigma1_bad_pct" in report else None
        self._kept[job.design_dir] = lines
        while len(self._kept) > KEPT:
            self._kept.popitem(last=False)
        return lines
