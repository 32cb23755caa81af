"""The API's bodies in and out (pydantic models) and the names its paths accept.

The upper bounds of ``HeatRequest`` and ``GotoRequest`` are the printer profile's: the document
states them (``ribbond.api.openapi``), the manual control checks them.
"""

from __future__ import annotations

from enum import Enum
from typing import Annotated, Any, Literal

from fastapi import Path as PathParam
from pydantic import BaseModel, ConfigDict, Field, model_validator

from ribbond.daemon.components.camera import SNAPSHOT_FILES
from ribbond.daemon.components.manual import MAX_MANUAL_COMMANDS
from ribbond.daemon.components.projects import PROJECT_FILES
from ribbond.daemon.store import JobRecord, ProjectRecord
from ribbond.design.thickness import TABLE_DIR, TABLE_NAME

#: Files of a job that can be fetched.
JOB_FILES = {"preview.png": "design", "preview.svg": "design", "design.json": "design",
             "front.gcode": "design", "back.gcode": "design", "combined.gcode": "design",
             "target.obj": "design", "flat.obj": "design", "deployed.obj": "design", "deployed.png": "design",
             "back-corrected.gcode": "job",
             "program.gcode": "job",
             **{name: "job" for name in SNAPSHOT_FILES.values()}}
#: The media type of each kind of file served (named, so the OpenAPI document can list them).
MEDIA_TYPES = {".png": "image/png", ".jpg": "image/jpeg", ".svg": "image/svg+xml", ".json": "application/json",
               ".gcode": "text/x.gcode", ".obj": "model/obj", ".csv": "text/csv"}
#: A job file's name in a path: one of ``JOB_FILES`` (the document lists them).
JobFile = Enum("JobFile", {name: name for name in JOB_FILES}, type=str)  # type: ignore[misc]
#: A calibration's files (``Calibrations.calibration_file``).
CalibrationFileName = Annotated[str, PathParam(pattern=r"^(plan\.json|coupons\.csv|sheet-[0-9]{1,3}\.(png|svg))$")]
#: Ids and names in paths: longer ones cannot exist (job ids are 12 hex digits, table names at most
#: 64 characters), and are refused without being echoed.
Ident = Annotated[str, PathParam(max_length=64)]


class Body(BaseModel):
    """A request's JSON body: a field the document does not name is refused (422 naming it), never
    ignored (issue 36 item 14: a body of unknown keys once made a whole default plan)."""

    model_config = ConfigDict(extra="forbid")


class NextStep(BaseModel):
    """What the operator does next."""

    instruction: str
    commands: list[str] = Field(description="the exact commands possible now")


class ShapeDeviation(BaseModel):
    """The predicted shape (``deployed.obj``, registered onto ``target.obj``) against the target, per vertex."""

    vertices: int = Field(ge=1, description="vertices of deployed.obj, in its order")
    distance_mm: list[float] = Field(description="each vertex's distance to the target surface, mm, in "
                                                 "deployed.obj's order")
    diagonal_mm: float = Field(gt=0, description="the target's bounding-box diagonal, mm")
    deviation_pct: dict[str, float] = Field(description="mean, p99 and max of the distances, % of the diagonal "
                                                        "(report.deployed.deviation_pct's measure)")


class Snapshot(BaseModel):
    """A camera snapshot kept with a job at a side's end."""

    name: Literal["snapshot-front.jpg", "snapshot-back.jpg", "snapshot-program.jpg"]
    taken: float = Field(description="when, unix s")


class JobStatus(JobRecord):
    """A job as the API shows it: the stored record, its progress and what to do next."""

    progress: float = Field(0.0, ge=0.0, le=1.0, description="0–1: of the compile while compiling, else of "
                                                              "the print (both sides)")
    compile_progress: float | None = Field(None, description="the stored progress within a compile stage")
    eta_s: float | None = Field(None, description="seconds left of the print (the programs' time estimate "
                                                  "scaled by the measured rate); 0 when done")
    elapsed_s: float | None = Field(None, description="seconds since this run started (while it runs)")
    ribbon: int | None = Field(None, description="the ribbon being printed, from 1")
    ribbons: int | None = Field(None, description="ribbons on the side being printed")
    print_side: str | None = Field(None, description="the side printed now or next")
    waits_for_operator: bool = Field(False, description="nothing happens until the operator acts")
    waiting_for: str | None = Field(None, description="while waits_for_operator: what the job waits for, in "
                                    "a few words (the flip, mark 2 of 3, the frame check, …; next says what to do); eta_s is then "
                                    "None")
    fit: dict[str, Any] | None = Field(None, description="in state fitted: the alignment's fit under review "
                                                         "(rotation_deg, offset, rms_mm, max_residual_mm)")
    alignment: dict[str, Any] | None = Field(None, description="in state aligning: the registration marks "
                                               "(marks), those measured and kept (kept) and those to measure "
                                               "again after a refused fit or a re-seat (remeasure), from 1")
    verdict: list[str] | None = Field(None, description="a design's verdict, one sentence per line: the "
                                                        "stretch bounds, clamped thicknesses, ribbons dropped "
                                                        "or trimmed, the prediction (ribbond.design.verdict)")
    prediction: dict[str, Any] | None = Field(
        None, description="the design's last prediction asked for (POST /jobs/{id}/predict) in this daemon's "
        "life: state (running, done, failed), fraction 0–1, message, table; when done the new "
        "report.deployed (deployed) and verdict; when failed the error")
    snapshots: list[Snapshot] = Field(default_factory=list, description="the camera's snapshots kept at each "
                                      "side's end ([camera]), front to back (GET /jobs/{id}/files/{name})")
    next: NextStep


#: A project file's name in a path (``GET /projects/{id}/files/{name}``).
ProjectFile = Enum("ProjectFile", {name: name for name in PROJECT_FILES}, type=str)  # type: ignore[misc]


class ProjectPanel(BaseModel):
    """One panel of a project: its place in the panel map and the job that prints it."""

    index: int = Field(ge=1, description="the panel's number, from 1 (panel-K/ in the project folder)")
    job_id: str | None = Field(description="the job printing it (None: the job was deleted)")
    state: str = Field(description="the job's state (deleted: no job)")
    stage: str | None = None
    progress: float = Field(0.0, ge=0.0, le=1.0, description="of the panel's print, both sides")
    print_side: str | None = None
    waits_for_operator: bool = False
    at_gate: bool = Field(False, description="queued and waiting for a fresh stretched frame (frame-ready)")
    queued: bool = Field(False, description="ready and queued to print")
    next: NextStep | None = Field(None, description="what the operator does next for this panel's job")
    faces: int | None = None
    flat_size_mm: list[float] | None = Field(None, description="the flat panel's width and height, mm")
    bad_pct: float | None = Field(None, description="faces outside the stretch bounds, %")
    outline: list[tuple[float, float]] = Field(default_factory=list, description="the flat outline in the "
                                                                                "panel's front print coordinates, mm")


class ProjectSeam(BaseModel):
    """A seam between two panels (project.json's seams)."""

    label: str
    panels: list[int]
    length_mm: dict[str, Any] = Field(default_factory=dict, description="target and deployed lengths, mm")
    marks: int | None = Field(None, description="matching marks along the seam")


class ProjectStatus(ProjectRecord):
    """A project as the API shows it: the record, its panel map, the panel on the printer, what to do next."""

    state: Literal["submitted", "compiling", "ready", "printing", "waiting", "done", "failed",  # type: ignore[assignment]
                   "cancelled"] = Field(description="compiling, then ready (not started), printing or waiting "
                                                    "(for the operator: a fresh frame, the flip, a mark), done")
    current_panel: int | None = Field(None, description="the panel on the printer, or next to go on it")
    panels_done: int = Field(0, ge=0)
    panels: list[ProjectPanel] = Field(default_factory=list, description="the panel map, by panel")
    seams: list[ProjectSeam] = Field(default_factory=list)
    report: dict[str, Any] | None = Field(None, description="project.json's report")
    reached: bool | None = Field(None, description="the sewn panels are predicted to take the target's shape "
                                 "(every panel's prediction does and the sewn one lands within 2 % on average); "
                                 "None before the compile or without predictions")
    verdict: list[str] = Field(default_factory=list, description="the project's verdict, one sentence per line "
                               "(ribbond.design.verdict.project_verdict_lines); empty before the compile")
    has_deployed: bool = Field(False, description="the sewn prediction's picture exists (GET "
                               "/projects/{id}/files/deployed.png)")
    next: NextStep


class CameraView(BaseModel):
    """``GET /camera``: whether the daemon has a camera, where its stream and snapshot come from."""

    configured: bool = Field(description="a camera is configured ([camera] stream_url or snapshot_url)")
    stream: Literal["stream_url", "snapshot_url"] | None = Field(
        None, description="what /camera/stream shows: the stream, or the snapshot polled twice a second")
    snapshot: Literal["snapshot_url", "stream_url"] | None = Field(
        None, description="what /camera/snapshot and the jobs' snapshots take: the snapshot, or the stream's next frame")
    last_error: str | None = Field(None, description="the camera's last failure (a snapshot not kept, a stream "
                                                     "that failed), in this daemon's life")
    last_error_at: float | None = Field(None, description="when, unix s")


class PredictRequest(Body):
    """``POST /jobs/{id}/predict``: the prediction's curvature table (``fine``, the ribbon-resolved
    model, was taken out (issue 34): refused, as any other unknown field)."""

    table: str | None = Field(None, pattern=TABLE_NAME.pattern,
                              description="a curvature table's name (GET /tables); default the design's")


class JogRequest(Body):
    dx: float = Field(description="mm")
    dy: float = Field(description="mm")
    dz: float = Field(0.0, description="mm")


class GotoRequest(Body):
    x: float = Field(description="mm, machine coordinates")
    y: float = Field(description="mm, machine coordinates")


#: A command the link can send: printable ASCII without the checksum's ``*``, not only a comment, and
#: short enough to go out numbered (``codec.MAX_LINE_LENGTH`` less ``N<line> `` and ``*<sum>``).
GCODE_COMMAND = r"^[ \t]*[!-'+-:<-~][\t -)+-~]*$"
GCODE_COMMAND_MAX = 80


class GcodeRequest(Body):
    commands: list[Annotated[str, Field(pattern=GCODE_COMMAND, max_length=GCODE_COMMAND_MAX)]] = Field(
        min_length=1, max_length=MAX_MANUAL_COMMANDS, description="one G-code command or a short list")


class HeatRequest(Body):
    # the upper bounds are the profile's: written into the document by ribbond.api.openapi
    nozzle: float | None = Field(None, ge=0, description="°C; default the profile's print temperature")
    bed: float | None = Field(None, ge=0, description="°C")


class AdjustRequest(BaseModel):
    """``POST /printer/adjust``: what to change, at least one (issue 36). The bounds are the
    profile's (``[adjust]``, ``[temperatures]``), written into the document by ribbond.api.openapi;
    while a program prints the nozzle may not go below ``adjust.nozzle_min`` (422)."""

    model_config = ConfigDict(extra="forbid", strict=True, json_schema_extra={"minProperties": 1})
    speed: float | None = Field(None, gt=0, description="feed override, % (M220 S)")
    flow: float | None = Field(None, gt=0, description="flow, % (M221 S)")
    nozzle: float | None = Field(None, ge=0, description="nozzle target, °C (M104 S)")
    bed: float | None = Field(None, ge=0, description="bed target, °C (M140 S)")

    @model_validator(mode="before")
    @classmethod
    def _no_nulls(cls, data: Any) -> Any:
        """A field is a number or left out (the document says so): ``null`` is refused."""
        if isinstance(data, dict):
            for name, value in data.items():
                if value is None:
                    raise ValueError(f"{name}: give a number or leave it out (null is not a value)")
        return data



class CalibrationRequest(Body):
    """``POST /calibrations``: the plan's grid and ribbons (``ribbond.calibration.spec``), all optional."""

    # the spec's own bounds, so the document states them; its cross-field rules (increasing grids,
    # mu1 > ribbon_length) are the spec's to check (422)
    # at most 16 of each: one request's plan stays bounded (16 x 16 x 2 coupons)
    thicknesses: list[Annotated[float, Field(gt=0)]] | None = Field(None, min_length=2, max_length=16,
                                                                     description="mm, increasing")
    spacings: list[Annotated[float, Field(gt=0)]] | None = Field(None, min_length=2, max_length=16,
                                                                  description="mm, increasing")
    sides: list[Literal["front", "back"]] | None = Field(None, min_length=1, max_length=2)
    ribbon_length: float | None = Field(None, gt=0)
    ribbon_width: float | None = Field(None, gt=0)
    mu1: float | None = Field(None, gt=0)
    prestretch: float | None = Field(None, gt=1.0)
    base_table: str | None = Field(None, pattern=TABLE_NAME.pattern)
    fabric: str | None = Field(None, max_length=200, description="free text, kept in the table's provenance")
    material: str | None = Field(None, max_length=200, description="free text, kept in the table's provenance")
    min_coupon_width: float | None = Field(None, gt=0)
    # the document names the one profile the daemon drives (ribbond.api.openapi)
    printer_profile: str | None = Field(None, min_length=1)
    start: bool = False


class CalibrationStatus(BaseModel):
    """A calibration plan: made in its own process after ``POST /calibrations`` answers (``planning``),
    then one ready two-sided job per sheet (``ready``), or why it could not be made (``failed``)."""

    calibration: str = Field(description="its id, cal-XXXXXXXX")
    state: Literal["planning", "ready", "failed"]
    sheets: int | None = Field(None, ge=1, description="when ready: the sheets (one job each)")
    coupons: int | None = Field(None, ge=1, description="when ready: the coupons over all sheets")
    jobs: list[str] = Field(default_factory=list, description="when ready: each sheet's job, in order")
    error: str | None = Field(None, description="when failed: why")
    folder: str = Field(description="the plan's folder on the daemon's host")


def _example_table() -> str:
    """The shipped table's TOML as a daemon table named ``example``: the document's example body."""
    text = (TABLE_DIR / "tpu95a-lycra-default.toml").read_text(encoding="utf-8")
    return text.replace('name = "tpu95a-lycra-default"', 'name = "example"', 1)


class TableRequest(Body):
    toml: str = Field(min_length=1, description="the text of a curvature table's TOML file", examples=[_example_table()])


class ResumeRequest(Body):
    """Resuming: for an interrupted print, what to do with the part begun and not proven printed."""

    partial: Literal["skip", "reprint"] | None = Field(None, description="skip it (default) or print it again")


class FrameOkRequest(Body):
    """The frame of a resumed print is checked; for the back, whether the stored alignment holds."""

    keep_alignment: bool = Field(False, description="the frame was not moved: keep the stored correction")


class AlignRequest(Body):
    """One registration mark: the head is on it (``here``), or the jog from where the head was sent
    to the mark (no jog: it was on the mark)."""

    mark: int | None = Field(None, description="the mark, numbered from 1 (design.json's "
                                                     "registration_marks[mark - 1]); default: the one the head was sent to")
    jog: tuple[float, float] | None = Field(None, description="(dx, dy) mm from where the head was sent to the mark")
    here: bool = Field(False, description="the nozzle is over the mark now (after jogging it there)")
    review: bool = Field(False, description="after the last mark, wait in 'fitted' for accept or re-seat "
                                            "instead of printing the back at once")


# ------------------------------------------------------------------ OctoPrint's shapes (issue 27)
# What slicers parse (OctoPrint's documented data model, API before 2.0.0); fields ribbond adds
# say so. Names are OctoPrint's, hence camelCase.


class OctoPrintVersion(BaseModel):
    """``GET /api/version``."""

    api: str = Field(description="always 0.1")
    server: str = Field(description="the OctoPrint release whose API this follows")
    text: str = Field(description="starts with 'OctoPrint' (slicers check it)")


class OctoPrintServer(BaseModel):
    """``GET /api/server``."""

    version: str
    safemode: bool | str = Field(description="false: not in safe mode")


class OctoPrintSettings(BaseModel):
    """``GET /api/settings``: the part clients read (Cura's plugin checks the key with it)."""

    feature: dict[str, bool] = Field(description="sdSupport: false (no SD card here)")
    webcam: dict[str, bool | str] = Field(description="webcamEnabled, streamUrl")
    plugins: dict[str, Any] = Field(description="none")


class OctoPrintEntry(BaseModel):
    """The file uploaded, as OctoPrint names it."""

    name: str = Field(description="the job's file name as stored (a sanitized basename)")
    display: str
    path: str
    origin: Literal["local"] = "local"
    refs: dict[str, str] = Field(description="resource: the job (GET /jobs/{id}); download: its program "
                                             "(a G-code job only)")


class OctoPrintUpload(BaseModel):
    """``POST /api/files/local``: the file became a job."""

    files: dict[str, OctoPrintEntry] = Field(description="one entry, 'local'")
    done: bool = Field(description="true: a G-code job, ready; false: a design job, compiling first")
    effectiveSelect: bool = Field(description="select or print was asked for")
    effectivePrint: bool = Field(description="queued to print (behind the fresh-frame gate)")
    job_id: str = Field(description="ribbond's: the job made of the file (GET /jobs/{job_id})")


class OctoPrintJobFile(BaseModel):
    name: str | None = None
    display: str | None = None
    path: str | None = None
    origin: str | None = None
    size: int | None = Field(None, description="bytes")
    date: int | None = Field(None, description="unix time of the upload")


class OctoPrintJobInfo(BaseModel):
    file: OctoPrintJobFile
    estimatedPrintTime: float | None = Field(None, description="s, the programs' own estimate (both sides)")
    lastPrintTime: float | None = None
    user: str | None = None


class OctoPrintProgress(BaseModel):
    completion: float | None = Field(None, ge=0, le=100, description="percent of the print (both sides)")
    filepos: int | None = None
    printTime: int | None = Field(None, description="s since this run started")
    printTimeLeft: int | None = Field(None, description="s")
    printTimeLeftOrigin: str | None = None


class OctoPrintJob(BaseModel):
    """``GET /api/job``: the job on the printer, else the next queued to print, else the newest."""

    job: OctoPrintJobInfo
    progress: OctoPrintProgress
    state: str = Field(description="the printer's state text: Offline, Connecting, Error, Operational, "
                                   "Starting (a job queued, e.g. waiting for a fresh frame), Printing, Paused "
                                   "(also waiting for the flip, the alignment or the frame check), Cancelling")
    error: str | None = Field(None, description="why the job failed or was interrupted")
    job_id: str | None = Field(None, description="ribbond's: the job shown (GET /jobs/{job_id})")
    job_state: str | None = Field(None, description="ribbond's: that job's state")


class OctoPrintTemperature(BaseModel):
    actual: float | None = Field(description="°C")
    target: float | None = Field(description="°C; null: none set")
    offset: float = 0


class OctoPrintState(BaseModel):
    text: str = Field(description="as in GET /api/job")
    flags: dict[str, bool] = Field(description="operational, printing, paused, pausing, resuming, finishing, "
                                               "cancelling, error, ready, closedOrError, sdReady")


class OctoPrintPrinter(BaseModel):
    """``GET /api/printer``: 409 when the printer is not operational, as OctoPrint answers."""

    temperature: dict[str, OctoPrintTemperature] = Field(description="tool0 (tool1, ...), bed, chamber")
    sd: dict[str, bool] = Field(description="ready: false (no SD card here)")
    state: OctoPrintState
