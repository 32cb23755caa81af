"""The verdict of each job's design, for the job's status (issue 22 item 4): the lines of
``ribbond.design.verdict``, read from the job's ``design.json`` once per design and kept, in memory
and beside the job (``verdict.json`` in the job's folder): a design folder does not change once
written, and ``design.json`` can be tens of megabytes (its per-face fields), too much to read for
every status of a job list. A design predicted again (``predictor.Predictor``) is forgotten here
and read once more."""

from __future__ import annotations

import contextlib
import json
import logging
import os
from collections import OrderedDict
from pathlib import Path

from ribbond.design.verdict import verdict_lines
from ..store import JobRecord

log = logging.getLogger(__name__)

#: Designs whose verdict is kept in memory (the newest asked for; an older one is read again).
KEPT = 256
#: The file in a job's folder that keeps its design's verdict.
VERDICT_FILE = "verdict.json"


class Verdicts:
    """``lines(job)``: the verdict of a job's design, or None (no design yet, a plain G-code job, a
    design without the flattening's report such as a calibration sheet's)."""

    def __init__(self, jobs_dir: Path) -> None:
        self.jobs_dir = jobs_dir
        self._kept: OrderedDict[str, list[str] | None] = OrderedDict()

    def lines(self, job: JobRecord) -> list[str] | None:
        if job.kind != "design" or not job.design_dir:
            return None
        if job.design_dir in self._kept:
            self._kept.move_to_end(job.design_dir)
            return self._kept[job.design_dir]
        stored, lines = self._stored(job)
        if not stored:
            try:
                lines = self._read(job)
            except (OSError, ValueError):
                log.debug("no verdict for job %s yet", job.id, exc_info=True)
                return None                               # not kept: the design may be written later
            self._store(job, lines)
        self._kept[job.design_dir] = lines
        while len(self._kept) > KEPT:
            self._kept.popitem(last=False)
        return lines

    @staticmethod
    def _read(job: JobRecord) -> list[str] | None:
        design = json.loads((Path(job.design_dir or "") / "design.json").read_text(encoding="utf-8"))
        report = design.get("report") if isinstance(design, dict) else None
        return verdict_lines(design) if isinstance(report, dict) and "sigma1_bad_pct" in report else None

    def _stored(self, job: JobRecord) -> tuple[bool, list[str] | None]:
        """(True, the verdict kept beside the job) when it is the verdict of this design folder."""
        try:
            kept = json.loads((self.jobs_dir / job.id / VERDICT_FILE).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return False, None
        if not isinstance(kept, dict) or kept.get("design_dir") != job.design_dir:
            return False, None
        lines = kept.get("lines")
        return True, [str(line) for line in lines] if isinstance(lines, list) else None

    def forget(self, job_id: str, design_dir: str | None) -> None:
        """Drop the verdict kept for a design folder whose ``design.json`` changed (predicted again)."""
        if design_dir is not None:
            self._kept.pop(design_dir, None)
        with contextlib.suppress(OSError):
            (self.jobs_dir / job_id / VERDICT_FILE).unlink()

    def _store(self, job: JobRecord, lines: list[str] | None) -> None:
        folder = self.jobs_dir / job.id
        tmp = folder / f".{VERDICT_FILE}.tmp"
        try:
            tmp.write_text(json.dumps({"design_dir": job.design_dir, "lines": lines}), encoding="utf-8")
            os.replace(tmp, folder / VERDICT_FILE)
        except OSError:                                   # only a cache: the next daemon reads it again
            log.debug("cannot keep the verdict of job %s", job.id, exc_info=True)
