"""Jobs sent by slicers (issue 27): the part of OctoPrint's API that a slicer's "send to printer"
uses (PrusaSlicer, OrcaSlicer, Cura's OctoPrint Connection), as Moonraker also offers it to them.

A slicer checks ``/api/version`` (its ``text`` starts with ``OctoPrint``; Cura's plugin checks
the key with ``/api/settings``), uploads the file to
``/api/files/local`` (multipart ``file``, with ``print`` / ``select``) and then reads ``/api/job``
and ``/api/printer``. Here an upload becomes a job like any other: a G-code file a plain G-code job
(checked against the profile line by line), a mesh a design job (its surface read and checked as
the compile's intake will, before the job exists). ``print`` queues it to print, behind the
fabric gate as every job; ``select`` alone keeps it ready for ``ribbonctl start``. The job and the
printer are shown in OctoPrint's words: its state texts (``Operational``, ``Printing``, ...), its
flags, ``completion`` in percent, temperatures as ``tool0`` / ``bed``.

The state texts and flags are OctoPrint's (``octoprint.printer.connection.ConnectedPrinterState``
and the serial connector's ``OPERATIONAL_STATES`` / ``PRINTING_STATES``); where ribbond waits for
the operator in the middle of a job (the flip, the alignment, the frame check) OctoPrint has no
state of its own, and the nearest is ``Paused``: the print stopped until a person acts.
"""

from __future__ import annotations

import asyncio
import re
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any

from ribbond import __version__
from ribbond.design.params import parameters_from_json
from ..jobs import JobState
from ..records import JobRecords, ServiceError
from ..store import JobRecord
from .head import Head
from .run import PrintState

#: The OctoPrint release whose API this subset follows (``/api/server`` is from 1.5.0).
OCTOPRINT_VERSION = "1.5.0"
#: ``/api/version``: clients check that ``text`` starts with ``OctoPrint`` (PrusaSlicer does).
VERSION = {"api": "0.1", "server": OCTOPRINT_VERSION, "text": f"OctoPrint {OCTOPRINT_VERSION} (ribbond {__version__})"}

#: ``/api/settings``, the part clients read: Cura's OctoPrint Connection checks the API key with
#: this request (200: accepted) and reads the SD card and camera support from it.
SETTINGS = {"feature": {"sdSupport": False, "temperatureGraph": False},
            "webcam": {"webcamEnabled": False, "streamUrl": ""}, "plugins": {}}

#: OctoPrint's printer state texts.
OFFLINE, CONNECTING, ERROR = "Offline", "Connecting", "Error"
OPERATIONAL, STARTING, PRINTING, PAUSED, CANCELLING = "Operational", "Starting", "Printing", "Paused", "Cancelling"
#: States in which the printer is connected and answers (OctoPrint's OPERATIONAL_STATES).
_OPERATIONAL = frozenset({OPERATIONAL, STARTING, PRINTING, PAUSED, CANCELLING})
#: States in which a print is under way and not paused (the serial connector's PRINTING_STATES).
_PRINTING = frozenset({STARTING, PRINTING, CANCELLING})

_J = JobState
#: The job on the printer, in OctoPrint's words: streaming is printing (heating is a program's
#: first lines in OctoPrint too); waiting for the operator mid-job is paused.
_ON_PRINTER = {_J.HEATING: PRINTING, _J.PRINTING_FRONT: PRINTING, _J.PRINTING_BACK: PRINTING,
               _J.PAUSED: PAUSED, _J.AWAITING_FLIP: PAUSED, _J.ALIGNING: PAUSED, _J.FITTED: PAUSED,
               _J.AWAITING_CHECK: PAUSED}
#: The link's states in which the printer is not operational.
_LINK_DOWN = {None: OFFLINE, "disconnected": OFFLINE, "connecting": CONNECTING, "halted": ERROR}


class UploadRefused(ValueError):
    """The file a slicer sent cannot be made a job (empty, a bad mesh, a program the profile
    refuses, userdata that is not design parameters); the message names the problem."""


class UnsupportedFile(UploadRefused):
    """The file is neither a G-code program nor a mesh the engine reads."""


def state_text(link: str | None, job: JobState | None, *, queued: bool = False, cancelling: bool = False) -> str:
    """The printer's state as OctoPrint says it.

    ``link``: the link's state (None: no link); ``job``: the state of the job on the printer (None:
    none); ``queued``: a job is queued to print and waits (for the fresh frame, or its turn);
    ``cancelling``: the job on the printer is being cancelled."""
    if link in _LINK_DOWN:
        return _LINK_DOWN[link]
    if job is not None and cancelling:
        return CANCELLING
    if job is not None and job in _ON_PRINTER:
        return _ON_PRINTER[job]
    return STARTING if queued else OPERATIONAL


def state_flags(text: str) -> dict[str, bool]:
    """OctoPrint's state flags of a state text (``ready``: operational, as OctoPrint's is; the
    printer has no SD card here)."""
    operational = text in _OPERATIONAL
    error = text == ERROR
    return {"operational": operational, "printing": text in _PRINTING, "paused": text == PAUSED,
            "pausing": False, "resuming": False, "finishing": False, "cancelling": text == CANCELLING,
            "error": error, "ready": operational, "closedOrError": not operational,
            "sdReady": False}


def temperatures(heaters: dict[str, dict[str, Any]]) -> dict[str, dict[str, float | None]]:
    """The link's heaters (``T``, ``T0``, ``T1``, ``B``, ``C``) as OctoPrint names them (``tool0``,
    ``tool1``, ``bed``, ``chamber``); a bare ``T`` is tool 0 unless ``T0`` is reported too."""
    out: dict[str, dict[str, float | None]] = {}
    for name, heater in heaters.items():
        match = re.fullmatch(r"T(\d*)", name)
        if match is not None:
            if not match.group(1) and "T0" in heaters:
                continue
            key = f"tool{int(match.group(1) or 0)}"
        elif name in ("B", "C"):
            key = "bed" if name == "B" else "chamber"
        else:
            continue
        out[key] = {"actual": heater.get("current"), "target": heater.get("target"), "offset": 0}
    return out


def design_parameters(userdata: str, gcode: bool) -> dict[str, Any]:
    """The design parameters of an upload: OctoPrint's ``userdata`` form field (JSON), empty for none."""
    if not userdata.strip():
        return {}
    try:
        return parameters_from_json(userdata, field="userdata", program=gcode)
    except ValueError as exc:
        raise UploadRefused(str(exc)) from None


class OctoPrintCompat:
    """Slicer uploads made jobs, and the job and printer shown as OctoPrint shows them.

    ``submit_mesh`` and ``submit_gcode`` are the service's own submits (every check of theirs
    applies); ``status`` is a job as people see it (its progress and time left); ``printer_status``
    the manual control's view of the printer; ``suffixes`` the mesh and the G-code file suffixes
    the service takes."""

    def __init__(self, records: JobRecords, state: PrintState, head: Head,
                 submit_mesh: Callable[[Path, str, dict[str, Any], bool], Awaitable[JobRecord]],
                 submit_gcode: Callable[[Path, str, bool], Awaitable[JobRecord]],
                 status: Callable[[JobRecord], dict[str, Any]],
                 printer_status: Callable[[], Awaitable[dict[str, Any]]],
                 suffixes: tuple[tuple[str, ...], tuple[str, ...]]) -> None:
        self.records, self.state, self.head = records, state, head
        self.submit_mesh, self.submit_gcode, self.status = submit_mesh, submit_gcode, status
        self.printer_status = printer_status
        self.mesh_suffixes, self.gcode_suffixes = suffixes

    # ------------------------------------------------------------------ uploads

    async def upload(self, path: Path, name: str, *, start: bool, select: bool,
                     userdata: str = "") -> dict[str, Any]:
        """Make the uploaded file at ``path`` (named ``name`` by the client) a job, queued to print
        if ``start``. Raises ``UnsupportedFile`` or ``UploadRefused`` naming the problem, and
        whatever the service's submit refuses (a full queue: ``ServiceError``). Returns the job's
        id and stored name, ``done`` (no compile to wait for) and OctoPrint's ``effectiveSelect``
        and ``effectivePrint``."""
        if not name.strip():
            raise UploadRefused("file: the part has no file name (its suffix says what it is)")
        gcode = self._is_gcode(name)
        if path.stat().st_size == 0:
            raise UploadRefused(f"{name}: the file is empty")
        params = design_parameters(userdata, gcode)
        try:
            if gcode:
                job = await self.submit_gcode(path, name, start)
            else:
                job = await self._mesh_job(path, name, params, start)
        except UploadRefused:
            raise
        except ValueError as exc:                      # the file itself (ServiceError is not one)
            raise UploadRefused(str(exc)) from exc
        return {"job_id": job.id, "name": job.mesh_name, "done": gcode, "effectiveSelect": select or start,
                "effectivePrint": start}

    def _is_gcode(self, name: str) -> bool:
        """A G-code program (True) or a mesh (False), by the name's suffix; ``UnsupportedFile`` else."""
        suffix = Path(name).suffix.lower()
        if suffix in self.gcode_suffixes:
            return True
        if suffix in self.mesh_suffixes:
            return False
        shown = f"a {suffix} file" if suffix else "a file without an extension"
        raise UnsupportedFile(f"{name}: {shown} is neither a G-code program ({', '.join(self.gcode_suffixes)}) "
                              f"nor a mesh to make a design of ({', '.join(self.mesh_suffixes)})")

    async def _mesh_job(self, path: Path, name: str, params: dict[str, Any], start: bool) -> JobRecord:
        """A design job of the mesh: the service's submit reads and checks it as the compile's
        intake will before the job exists, as it does for every route."""
        return await self.submit_mesh(path, name, params, start)

    # ------------------------------------------------------------------ what a slicer is shown

    def current(self) -> JobRecord | None:
        """The job a slicer is shown: the one on the printer, else the next queued to print, else
        the newest."""
        run = self.state.run
        if run is not None and self.records.exists(run.job_id):
            return self.records.get(run.job_id)
        active = self.records.store.active()
        for job in active:
            if job.state.holds_printer:
                return job
        for job in active:
            if job.state is JobState.READY and job.start_when_ready:
                return job
        newest = self.records.store.list(limit=1)
        return newest[0] if newest else None

    def printer_state(self) -> str:
        """The printer's state text (``state_text``) from the link and the jobs."""
        link = self.head.link
        run = self.state.run
        active = self.records.store.active()
        holding = next((j for j in active if j.state.holds_printer), None)
        queued = any(j.state is JobState.READY and j.start_when_ready for j in active)
        return state_text(link.state.value if link is not None else None, holding.state if holding else None,
                          queued=queued, cancelling=run is not None and run.cancel_requested)

    def job(self) -> dict[str, Any]:
        """``GET /api/job``: the current job, its progress (``completion`` in percent) and the
        printer's state text."""
        job = self.current()
        text = self.printer_state()
        if job is None:
            return {"job": {"file": {"name": None}}, "progress": {}, "state": text}
        info = self.status(job)
        compiling = job.state in (JobState.SUBMITTED, JobState.COMPILING)
        mesh = Path(job.mesh_path)
        estimate = sum((job.estimate_s or {}).values()) or None
        return {
            "job": {"file": {"name": job.mesh_name, "display": job.mesh_name, "path": job.mesh_name,
                             "origin": "local", "size": mesh.stat().st_size if mesh.is_file() else None,
                             "date": int(job.created)},
                    "estimatedPrintTime": estimate, "lastPrintTime": None, "user": None},
            "progress": {"completion": 0.0 if compiling else round(100.0 * info["progress"], 3),
                         "filepos": None, "printTime": _seconds(info.get("elapsed_s")),
                         "printTimeLeft": _seconds(info.get("eta_s")),
                         "printTimeLeftOrigin": "estimate" if info.get("eta_s") is not None else None},
            "state": text,
            "error": job.error if job.state in (JobState.FAILED, JobState.INTERRUPTED) else None,
            "job_id": job.id, "job_state": job.state.value,
        }

    async def printer(self) -> dict[str, Any]:
        """``GET /api/printer``: temperatures and state; ``ServiceError`` (OctoPrint's 409) when the
        printer is not operational, as OctoPrint answers."""
        status = await self.printer_status()
        text = self.printer_state()
        if text not in _OPERATIONAL:
            note = status.get("note") or status.get("state", "not connected")
            raise ServiceError(f"the printer is not operational ({text}: {note})")
        return {"temperature": temperatures(status.get("heaters") or {}), "sd": {"ready": False},
                "state": {"text": text, "flags": state_flags(text)}}


def _seconds(value: float | None) -> int | None:
    return None if value is None else int(round(value))
