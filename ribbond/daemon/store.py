"""The job store: jobs, their transitions, acknowledged lines and checkpoints, in SQLite (issue 6).

Every change is committed before the method that makes it returns, so what the daemon reports
(to the API, in logs) is what a restart finds, even after a power cut: the database runs with a
WAL journal and ``synchronous=FULL`` (each COMMIT is fsynced). State changes go through
``ribbond.daemon.jobs.check_transition``; the state, the fields that change with it and the row in
``transitions`` are written in one transaction.

The store is used from the daemon's asyncio event loop thread only. Its calls are short and
synchronous (one small transaction each), so they run on the loop directly rather than in a thread.
"""

from __future__ import annotations

import builtins
import json
import secrets
import sqlite3
import time
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from .jobs import JobState, check_transition

#: The layout this code reads and writes (PRAGMA user_version). Bump it with a migration in
#: ``_MIGRATIONS`` whenever the tables change.
SCHEMA_VERSION = 6

#: The frame on the printer (schema 5): fresh (confirmed by the operator, nothing printed on it since) or used.
FRAME_FRESH, FRAME_USED = "fresh", "used"


class JobRecord(BaseModel):
    """One job as stored, and as the API returns it."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    id: str = Field(min_length=1)
    state: JobState
    created: float = Field(description="unix time")
    updated: float = Field(description="unix time of the last change")
    mesh_name: str = Field(min_length=1, description="the uploaded file's name (a sanitized basename)")
    mesh_path: str = Field(min_length=1, description="where the upload is stored")
    parameters: dict[str, Any] = Field(description="design parameters as given")
    start_when_ready: bool = Field(description="begin printing as soon as compiled")
    design_dir: str | None = None
    error: str | None = Field(None, description="why the job failed or was interrupted")
    stage: str | None = Field(None, description="compile stage or print phase")
    progress: float | None = Field(None, ge=0.0, le=1.0, description="0..1 within the stage")
    lines_total: int | None = Field(None, ge=0, description="lines of the program being streamed")
    # Acknowledged means queued in the printer's buffer, not executed: resume from a checkpoint.
    last_acked_line: int = Field(-1, ge=-1, description="last line the printer acknowledged")
    checkpoint: str | None = Field(None, min_length=1, description="last synchronized (M400) checkpoint")
    checkpoint_line: int | None = Field(None, ge=-1)
    side: Literal["front", "back"] | None = Field(None, description="side being printed")
    correction: dict[str, Any] | None = Field(None, description="the fitted alignment correction")
    paused_from: JobState | None = None
    kind: Literal["design", "gcode"] = Field("design", description="a design compiled from a mesh, or a "
                                             "plain G-code program (mesh_name/mesh_path: the program)")
    runs: list[dict[str, Any]] = Field(default_factory=list, description="earlier print runs of this job, "
                                       "oldest first: run, started, ended, state, error, side, lines")
    estimate_s: dict[str, float] | None = Field(None, description="the programs' own time estimate per side "
                                                "(front, back), s: for progress and time left")
    notes: list[str] = Field(default_factory=list, description="what the daemon changed in the job's program "
                             "and why (e.g. feed rates clamped to the profile's limits)")
    same_frame: bool = Field(False, description="a plain G-code program that prints on the frame as it is "
                             "(no fresh frame needed before it)")
    program: str | None = Field(None, description="the program lines_total and last_acked_line count: front, "
                                "back, 'front (resumed at part N)', ...")
    print_progress: float | None = Field(None, ge=0.0, le=1.0, description="the most of this run's print "
                                         "(both sides, 0..1) reported so far: progress never goes back")
    project: str | None = Field(None, description="the project this job prints a panel of (GET /projects/{id})")
    panel: int | None = Field(None, ge=1, description="the panel this job prints, from 1")
    panels: int | None = Field(None, ge=1, description="the project's number of panels")

    @field_validator("mesh_name")
    @classmethod
    def _basename(cls, value: str) -> str:
        # The name ends up in paths and in Content-Disposition headers: a basename only.
        if value in (".", "..") or any(c in value for c in "/\\\0"):
            raise ValueError(f"{value!r} is not a plain file name")
        return value


#: A project's stored states: queued to compile, compiling, compiled (its panel jobs exist), failed, cancelled.
ProjectState = Literal["submitted", "compiling", "compiled", "failed", "cancelled"]


class ProjectRecord(BaseModel):
    """One project as stored (schema 6): a mesh compiled once into panels, one two-sided job per panel."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    id: str = Field(min_length=1)
    state: ProjectState
    created: float = Field(description="unix time")
    updated: float = Field(description="unix time of the last change")
    mesh_name: str = Field(min_length=1, description="the uploaded file's name (a sanitized basename)")
    mesh_path: str = Field(min_length=1, description="where the upload is stored")
    parameters: dict[str, Any] = Field(description="design parameters as given")
    panels_requested: str = Field(description="'auto' or the number of panels asked for")
    seam_allowance_mm: float = Field(ge=0.0, description="fabric left around each panel for its seams, mm")
    start_when_ready: bool = Field(description="print the panels, in order, as soon as compiled")
    folder: str | None = Field(None, description="the project folder (project.json, panel-1/, ...) once compiled")
    panel_count: int | None = Field(None, ge=1, description="the number of panels, once compiled")
    error: str | None = Field(None, description="why the compile failed")
    stage: str | None = Field(None, description="the compile's stage")


class ProjectNotFound(KeyError):
    """No project has this id."""

    def __init__(self, project_id: str) -> None:
        self.project_id = project_id
        super().__init__(project_id)

    def __str__(self) -> str:
        return f"no project with id {self.project_id!r}"


class Transition(BaseModel):
    """One state change of a job (``from_state`` is None for the job's creation)."""

    model_config = ConfigDict(frozen=True)

    job_id: str
    from_state: JobState | None
    to_state: JobState
    at: float
    reason: str | None


class JobNotFound(KeyError):
    """No job has this id (the API answers it with HTTP 404)."""

    def __init__(self, job_id: str) -> None:
        self.job_id = job_id
        super().__init__(job_id)

    def __str__(self) -> str:  # KeyError would quote the whole message
        return f"no job with id {self.job_id!r}"


#: Fields ``transition`` and ``update`` may set (the id, the state and the timestamps are the store's).
MUTABLE_FIELDS = frozenset(JobRecord.model_fields) - {"id", "state", "created", "updated"}
_JSON_FIELDS = frozenset({"parameters", "correction", "runs", "estimate_s", "notes"})
_COLUMNS = tuple(JobRecord.model_fields)
_PROJECT_COLUMNS = tuple(ProjectRecord.model_fields)
#: Project fields ``update_project`` may set.
PROJECT_MUTABLE = frozenset({"state", "folder", "panel_count", "error", "stage", "start_when_ready"})

#: The parts of a print proven printed (schema 3), for resuming an interrupted one.
_PART_EVENTS = """CREATE TABLE part_events (
    seq        INTEGER PRIMARY KEY AUTOINCREMENT,
    job_id     TEXT NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
    run        INTEGER NOT NULL CHECK (run >= 1),          -- the print run (len(runs) + 1 then)
    side       TEXT NOT NULL CHECK (side IN ('front', 'back')),
    part       INTEGER NOT NULL CHECK (part >= 0),         -- the part's place in the side's program
    event      TEXT NOT NULL CHECK (event IN ('started', 'done', 'skipped', 'reprint')),
    line       INTEGER,
    at         REAL NOT NULL
);
CREATE INDEX part_events_job ON part_events (job_id, run, side, part, seq)"""

#: The frame on the printer (schema 5): one row, absent until the first change (then: used).
_FRAME = """CREATE TABLE frame (
    id     INTEGER PRIMARY KEY CHECK (id = 1),
    state  TEXT NOT NULL CHECK (state IN ('fresh', 'used')),
    job_id TEXT,                                            -- the job that used it
    at     REAL NOT NULL
)"""

#: Projects (schema 6): a mesh compiled once into panels; their jobs name them (jobs.project, jobs.panel).
_PROJECTS = """CREATE TABLE projects (
    seq               INTEGER PRIMARY KEY AUTOINCREMENT,
    id                TEXT NOT NULL UNIQUE,
    state             TEXT NOT NULL,
    created           REAL NOT NULL,
    updated           REAL NOT NULL,
    mesh_name         TEXT NOT NULL,
    mesh_path         TEXT NOT NULL,
    parameters        TEXT NOT NULL,                     -- JSON
    panels_requested  TEXT NOT NULL,
    seam_allowance_mm REAL NOT NULL,
    start_when_ready  INTEGER NOT NULL CHECK (start_when_ready IN (0, 1)),
    folder            TEXT,
    panel_count       INTEGER,
    error             TEXT,
    stage             TEXT
)"""

_SCHEMA = """
CREATE TABLE jobs (
    seq              INTEGER PRIMARY KEY AUTOINCREMENT,  -- creation order
    id               TEXT NOT NULL UNIQUE,
    state            TEXT NOT NULL,
    created          REAL NOT NULL,
    updated          REAL NOT NULL,
    mesh_name        TEXT NOT NULL,
    mesh_path        TEXT NOT NULL,
    parameters       TEXT NOT NULL,                      -- JSON
    start_when_ready INTEGER NOT NULL CHECK (start_when_ready IN (0, 1)),
    design_dir       TEXT,
    error            TEXT,
    stage            TEXT,
    progress         REAL,
    lines_total      INTEGER,
    last_acked_line  INTEGER NOT NULL DEFAULT -1,
    checkpoint       TEXT,
    checkpoint_line  INTEGER,
    side             TEXT,
    correction       TEXT,                               -- JSON
    paused_from      TEXT,
    kind             TEXT NOT NULL DEFAULT 'design',
    runs             TEXT,                               -- JSON list, NULL: none
    estimate_s       TEXT,                               -- JSON
    notes            TEXT,                               -- JSON list, NULL: none
    same_frame       INTEGER NOT NULL DEFAULT 0 CHECK (same_frame IN (0, 1)),
    program          TEXT,
    print_progress   REAL,
    project          TEXT,
    panel            INTEGER,
    panels           INTEGER
);
CREATE INDEX jobs_state ON jobs (state);
CREATE INDEX jobs_project ON jobs (project, panel);
CREATE TABLE transitions (
    seq        INTEGER PRIMARY KEY AUTOINCREMENT,
    job_id     TEXT NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
    from_state TEXT,
    to_state   TEXT NOT NULL,
    at         REAL NOT NULL,
    reason     TEXT
);
CREATE INDEX transitions_job ON transitions (job_id, seq);
""" + _PART_EVENTS + ";\n" + _FRAME + ";\n" + _PROJECTS + ";\n"

#: ``_MIGRATIONS[v]`` brings a database from version v to v + 1.
_MIGRATIONS: dict[int, str] = {
    # 2: plain G-code jobs and the history of print runs (issue 13)
    1: "ALTER TABLE jobs ADD COLUMN kind TEXT NOT NULL DEFAULT 'design'; ALTER TABLE jobs ADD COLUMN runs TEXT; "
       "ALTER TABLE jobs ADD COLUMN estimate_s TEXT",
    # 3: the parts (ribbons, marks) of a print proven printed, for resuming an interrupted one (issue 16)
    2: _PART_EVENTS,
    # 4: what the daemon changed in a job's program, e.g. feed rates clamped (issue 22)
    3: "ALTER TABLE jobs ADD COLUMN notes TEXT",
    # 5: the frame on the printer and plain G-code jobs that need no fresh one (issue 22)
    # and the program the lines count, the most of the print reported (progress never goes back)
    4: "ALTER TABLE jobs ADD COLUMN same_frame INTEGER NOT NULL DEFAULT 0 CHECK (same_frame IN (0, 1)); "
       "ALTER TABLE jobs ADD COLUMN program TEXT; ALTER TABLE jobs ADD COLUMN print_progress REAL; " + _FRAME,
    # 6: projects, a mesh in panels, and the panel each job prints (issue 26)
    5: "ALTER TABLE jobs ADD COLUMN project TEXT; ALTER TABLE jobs ADD COLUMN panel INTEGER; "
       "ALTER TABLE jobs ADD COLUMN panels INTEGER; CREATE INDEX jobs_project ON jobs (project, panel); " + _PROJECTS,
}

#: What a part's events make of it (its last event decides).
PART_EVENTS = ("started", "done", "skipped", "reprint")


def _json(value: Any, where: str) -> str:
    try:
        # allow_nan=False: NaN/Infinity are not JSON, the API could not return them.
        return json.dumps(value, allow_nan=False, sort_keys=True)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{where}: not JSON-serializable: {exc}") from None


def _format_errors(exc: ValidationError) -> str:
    return "; ".join(f"{'.'.join(str(p) for p in e['loc']) or '(record)'}: {e['msg']}" for e in exc.errors())


def new_id() -> str:
    """A fresh job id (12 hex digits)."""
    return secrets.token_hex(6)


class JobStore:
    """The jobs database: one SQLite file, one connection.

    Used from the daemon's event loop thread only: calls are short and synchronous, and each
    returns after its transaction is committed (and, with ``synchronous=FULL``, on disk).

    Parameters
    ----------
    path
        the database file (created with its directory if missing).
    clock
        the source of unix timestamps (``time.time``; tests may pass their own).

    Raises
    ------
    ValueError
        the file was written by a newer ribbond (a higher schema version), is not a ribbond job
        database, or cannot be opened.
    """

    def __init__(self, path: Path, *, clock: Callable[[], float] = time.time) -> None:
        self.path = Path(path)
        self._clock = clock
        if not self.path.parent.exists():
            self.path.parent.mkdir(mode=0o700, parents=True)
        try:
            # isolation_level=None: no implicit transactions; every write is an explicit BEGIN/COMMIT.
            self._db = sqlite3.connect(self.path, isolation_level=None)
        except sqlite3.Error as exc:
            raise ValueError(f"{self.path}: cannot open the job database: {exc}") from None
        try:
            self._db.row_factory = sqlite3.Row
            self._db.execute("PRAGMA busy_timeout = 5000")
            mode = self._db.execute("PRAGMA journal_mode = WAL").fetchone()[0]
            if str(mode).lower() != "wal":
                raise ValueError(f"{self.path}: cannot use a WAL journal (SQLite chose {mode!r})")
            self._db.execute("PRAGMA synchronous = FULL")
            self._db.execute("PRAGMA foreign_keys = ON")
            self._open_schema()
        except sqlite3.DatabaseError as exc:
            self._db.close()
            raise ValueError(f"{self.path}: not a usable job database: {exc}") from None
        except BaseException:
            self._db.close()
            raise

    # -- schema -------------------------------------------------------------------------------

    def _open_schema(self) -> None:
        with self._transaction():
            version = self._db.execute("PRAGMA user_version").fetchone()[0]
            if version > SCHEMA_VERSION:
                raise ValueError(
                    f"{self.path}: the job database has schema version {version}, written by a newer "
                    f"ribbond; this one reads up to version {SCHEMA_VERSION}. Upgrade ribbond, or move "
                    "the file away to start with an empty job list")
            if version == 0:
                tables = self._db.execute(
                    "SELECT count(*) FROM sqlite_master WHERE type = 'table'").fetchone()[0]
                if tables:
                    raise ValueError(f"{self.path}: the file holds tables but no ribbond schema "
                                     "version; it is not a ribbond job database")
                for statement in _SCHEMA.split(";"):
                    if statement.strip():
                        self._db.execute(statement)
            else:
                for v in range(version, SCHEMA_VERSION):
                    for statement in _MIGRATIONS[v].split(";"):
                        if statement.strip():
                            self._db.execute(statement)
            # PRAGMA does not take parameters; the value is our own integer.
            self._db.execute(f"PRAGMA user_version = {SCHEMA_VERSION:d}")

    @contextmanager
    def _transaction(self) -> Iterator[sqlite3.Connection]:
        # IMMEDIATE: take the write lock up front, so the state read is the state written over.
        self._db.execute("BEGIN IMMEDIATE")
        try:
            yield self._db
        except BaseException:
            self._db.execute("ROLLBACK")
            raise
        self._db.execute("COMMIT")

    # -- reading ------------------------------------------------------------------------------

    @staticmethod
    def _record(row: sqlite3.Row) -> JobRecord:
        data = {name: row[name] for name in _COLUMNS}
        for name in _JSON_FIELDS:
            if data[name] is not None:
                data[name] = json.loads(data[name])
        data["start_when_ready"] = bool(data["start_when_ready"])
        data["same_frame"] = bool(data["same_frame"])
        if data["runs"] is None:
            data["runs"] = []
        if data["notes"] is None:
            data["notes"] = []
        return JobRecord.model_validate(data)

    def _row(self, job_id: str) -> sqlite3.Row:
        row = self._db.execute("SELECT * FROM jobs WHERE id = ?", (job_id,)).fetchone()
        if row is None:
            raise JobNotFound(job_id)
        return row

    def get(self, job_id: str) -> JobRecord:
        """The job ``job_id``; raises ``JobNotFound``."""
        return self._record(self._row(job_id))

    def list(self, states: Iterable[JobState] | None = None,
             limit: int | None = None, offset: int = 0) -> builtins.list[JobRecord]:
        """Jobs, newest first, optionally only those in ``states``, at most ``limit`` of them after
        skipping ``offset``."""
        sql = "SELECT * FROM jobs"
        args: builtins.list[Any] = []
        if states is not None:
            wanted = sorted({JobState(s).value for s in states})
            if not wanted:
                return []
            sql += f" WHERE state IN ({', '.join('?' * len(wanted))})"
            args += wanted
        sql += " ORDER BY seq DESC"
        if offset < 0:
            raise ValueError(f"offset = {offset}: must be >= 0")
        if limit is not None or offset:
            if limit is not None and limit < 0:
                raise ValueError(f"limit = {limit}: must be >= 0")
            sql += " LIMIT ? OFFSET ?"
            args += [-1 if limit is None else limit, offset]
        return [self._record(row) for row in self._db.execute(sql, args)]

    def count(self, states: Iterable[JobState] | None = None) -> int:
        """How many jobs there are (in ``states``)."""
        if states is None:
            return int(self._db.execute("SELECT count(*) FROM jobs").fetchone()[0])
        wanted = sorted({JobState(s).value for s in states})
        if not wanted:
            return 0
        return int(self._db.execute(f"SELECT count(*) FROM jobs WHERE state IN ({', '.join('?' * len(wanted))})",
                                    wanted).fetchone()[0])

    def active(self) -> builtins.list[JobRecord]:
        """Jobs whose run has not ended, oldest first: the queue (``interrupted`` has ended: it is
        started again or deleted by the operator)."""
        live = [s.value for s in JobState if not s.terminal]
        rows = self._db.execute(
            f"SELECT * FROM jobs WHERE state IN ({', '.join('?' * len(live))}) ORDER BY seq", live)
        return [self._record(row) for row in rows]

    def transitions(self, job_id: str) -> builtins.list[Transition]:
        """The state changes of ``job_id`` in the order they happened, creation first."""
        self._row(job_id)
        rows = self._db.execute(
            "SELECT job_id, from_state, to_state, at, reason FROM transitions WHERE job_id = ? ORDER BY seq",
            (job_id,))
        return [Transition.model_validate(dict(row)) for row in rows]

    # -- writing ------------------------------------------------------------------------------

    def _now(self, not_before: float) -> float:
        # Never before the job's last change, even if the wall clock steps back: a job's
        # timestamps stay in the order its changes were made.
        return max(self._clock(), not_before)

    def _validated(self, current: JobRecord, changes: dict[str, Any]) -> JobRecord:
        try:
            return JobRecord.model_validate({**current.model_dump(), **changes})
        except ValidationError as exc:
            raise ValueError(f"job {current.id}: {_format_errors(exc)}") from None

    def _write(self, record: JobRecord) -> None:
        values: dict[str, Any] = {}
        for name in _COLUMNS:
            value = getattr(record, name)
            if name in _JSON_FIELDS and value is not None:
                value = _json(value, f"job {record.id}: {name}")
            elif isinstance(value, JobState):
                value = value.value
            elif isinstance(value, bool):
                value = int(value)
            values[name] = value
        assignments = ", ".join(f"{name} = :{name}" for name in _COLUMNS if name != "id")
        self._db.execute(f"UPDATE jobs SET {assignments} WHERE id = :id", values)

    def _log(self, job_id: str, old: JobState | None, new: JobState, at: float, reason: str | None) -> None:
        self._db.execute("INSERT INTO transitions (job_id, from_state, to_state, at, reason) VALUES (?, ?, ?, ?, ?)",
                         (job_id, None if old is None else old.value, new.value, at, reason))

    @staticmethod
    def _check_fields(fields: dict[str, Any], what: str) -> None:
        unknown = sorted(set(fields) - MUTABLE_FIELDS)
        if unknown:
            raise ValueError(f"{what}: cannot set {', '.join(unknown)}; settable fields: "
                             + ", ".join(sorted(MUTABLE_FIELDS)))

    def create(self, *, mesh_name: str, mesh_path: str, parameters: dict[str, Any],
               start_when_ready: bool, kind: Literal["design", "gcode"] = "design",
               job_id: str | None = None, same_frame: bool = False,
               panel: tuple[str, int, int] | None = None) -> JobRecord:
        """A new job in state ``submitted`` (with its first ``transitions`` row), committed.

        ``job_id`` (from ``new_id``): the caller chose the id so that the job's files are in place
        before its row exists. ``panel``: (project id, panel index from 1, the project's panels)."""
        now = self._clock()
        project, index, count = panel if panel is not None else (None, None, None)
        try:
            record = JobRecord(id=job_id or new_id(), state=JobState.SUBMITTED, created=now, updated=now,
                               mesh_name=mesh_name, mesh_path=mesh_path, parameters=parameters,
                               start_when_ready=start_when_ready, kind=kind, same_frame=same_frame,
                               project=project, panel=index, panels=count)
        except ValidationError as exc:
            raise ValueError(f"new job: {_format_errors(exc)}") from None
        parameters_json = _json(record.parameters, "new job: parameters")
        with self._transaction() as db:
            db.execute("INSERT INTO jobs (id, state, created, updated, mesh_name, mesh_path, parameters, "
                       "start_when_ready, kind, same_frame, project, panel, panels) "
                       "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                       (record.id, record.state.value, now, now, mesh_name, mesh_path, parameters_json,
                        int(start_when_ready), kind, int(record.same_frame), project, index, count))
            self._log(record.id, None, record.state, now, None)
        return record

    def transition(self, job_id: str, new: JobState, *, reason: str | None = None, **fields: Any) -> JobRecord:
        """Move ``job_id`` to ``new``, setting ``fields`` with it, in one committed transaction.

        Entering ``failed`` or ``interrupted`` with a ``reason`` stores it as ``error`` (unless
        given). Entering ``paused`` records the state paused from in ``paused_from`` (unless given);
        leaving it clears ``paused_from`` (unless given).

        Raises
        ------
        IllegalTransition
            the transition table does not allow the change (nothing is written).
        JobNotFound
            no such job.
        ValueError
            an unknown field name or an invalid value.
        """
        self._check_fields(fields, f"job {job_id}")
        new = JobState(new)
        with self._transaction():
            current = self._record(self._row(job_id))
            check_transition(current.state, new)
            changes = dict(fields)
            if new in (JobState.FAILED, JobState.INTERRUPTED) and reason is not None:
                changes.setdefault("error", reason)
            if new is JobState.PAUSED:
                changes.setdefault("paused_from", current.state)
            elif current.state is JobState.PAUSED:
                changes.setdefault("paused_from", None)
            at = self._now(current.updated)
            record = self._validated(current, {**changes, "state": new, "updated": at})
            self._write(record)
            self._log(job_id, current.state, new, at, reason)
        return record

    def update(self, job_id: str, **fields: Any) -> JobRecord:
        """Set non-state fields of ``job_id`` (``state`` is refused: use ``transition``), committed."""
        if "state" in fields:
            raise ValueError(f"job {job_id}: update cannot set state; use transition() so the change "
                             "is checked and recorded")
        self._check_fields(fields, f"job {job_id}")
        with self._transaction():
            current = self._record(self._row(job_id))
            record = self._validated(current, {**fields, "updated": self._now(current.updated)})
            self._write(record)
        return record

    def record_ack(self, job_id: str, line: int, progress: float | None = None) -> None:
        """Raise ``last_acked_line`` to ``line`` (never lowers it), and ``print_progress`` to
        ``progress`` (0..1; never lowers it either), committed.

        Committed without waiting for the disk (``synchronous=NORMAL`` for this one write): it
        survives the daemon being killed, and it is written every half second while streaming, when
        an fsync on the event loop could keep the printer waiting (tens of ms on an SD card). State
        changes and checkpoints stay fsynced. A new program (the back side) starts its numbering
        over: reset ``last_acked_line`` with ``transition`` or ``update``.
        """
        if isinstance(line, bool) or not isinstance(line, int) or line < -1:
            raise ValueError(f"job {job_id}: acknowledged line {line!r}: must be an integer >= -1")
        if progress is not None and not 0.0 <= progress <= 1.0:
            raise ValueError(f"job {job_id}: progress {progress!r}: must be within 0..1")
        self._db.execute("PRAGMA synchronous = NORMAL")
        try:
            with self._transaction() as db:
                current = self._row(job_id)
                if line > current["last_acked_line"]:
                    db.execute("UPDATE jobs SET last_acked_line = ?, updated = ? WHERE id = ?",
                               (line, self._now(current["updated"]), job_id))
                if progress is not None and progress > (current["print_progress"] or 0.0):
                    db.execute("UPDATE jobs SET print_progress = ? WHERE id = ?", (float(progress), job_id))
        finally:
            self._db.execute("PRAGMA synchronous = FULL")

    def checkpoint(self, job_id: str, name: str, line: int) -> JobRecord:
        """Record the synchronized (M400) checkpoint ``name`` reached at line ``line``, committed.

        ``line`` is -1 when no line had been acknowledged. ``last_acked_line`` is left alone: the
        caller may count checkpoint lines differently from program lines.
        """
        if not isinstance(name, str) or not name.strip():
            raise ValueError(f"job {job_id}: checkpoint name {name!r}: must be a non-empty string")
        if isinstance(line, bool) or not isinstance(line, int) or line < -1:
            raise ValueError(f"job {job_id}: checkpoint line {line!r}: must be an integer >= -1")
        with self._transaction():
            current = self._record(self._row(job_id))
            record = self._validated(current, {"checkpoint": name, "checkpoint_line": line,
                                               "updated": self._now(current.updated)})
            self._write(record)
        return record

    def record_part(self, job_id: str, side: str, part: int, event: str, line: int | None = None,
                    *, durable: bool = True) -> None:
        """Record that part ``part`` (its place in the side's program, from 0) of the job's current
        run ``started`` (its first extruding line is about to be sent), is ``done`` (the ``M400``
        after it was acknowledged: proven executed), or was ``skipped`` / is to be reprinted
        (``reprint``) by the operator's choice on resuming, committed. ``durable=False`` commits
        without waiting for the disk (survives a kill of the daemon, not a power cut)."""
        if event not in PART_EVENTS:
            raise ValueError(f"job {job_id}: part event {event!r}: one of {', '.join(PART_EVENTS)}")
        if side not in ("front", "back"):
            raise ValueError(f"job {job_id}: side {side!r}: 'front' or 'back'")
        if isinstance(part, bool) or not isinstance(part, int) or part < 0:
            raise ValueError(f"job {job_id}: part {part!r}: must be an integer >= 0")
        if not durable:
            self._db.execute("PRAGMA synchronous = NORMAL")
        try:
            with self._transaction() as db:
                row = self._row(job_id)
                run = len(json.loads(row["runs"])) + 1 if row["runs"] else 1
                db.execute("INSERT INTO part_events (job_id, run, side, part, event, line, at) "
                           "VALUES (?, ?, ?, ?, ?, ?, ?)", (job_id, run, side, part, event, line, self._clock()))
        finally:
            if not durable:
                self._db.execute("PRAGMA synchronous = FULL")

    def part_states(self, job_id: str, side: str) -> dict[int, str]:
        """Each part of ``side`` with an event in the job's current run: its last event
        (``started``: begun and not proven done, i.e. possibly partial)."""
        row = self._row(job_id)
        run = len(json.loads(row["runs"])) + 1 if row["runs"] else 1
        out: dict[int, str] = {}
        for part, event in self._db.execute(
                "SELECT part, event FROM part_events WHERE job_id = ? AND run = ? AND side = ? ORDER BY seq",
                (job_id, run, side)):
            out[int(part)] = str(event)
        return out

    def part_events(self, job_id: str) -> builtins.list[dict[str, Any]]:
        """Every part event of the job, oldest first: run, side, part, event, line, at."""
        self._row(job_id)
        rows = self._db.execute("SELECT run, side, part, event, line, at FROM part_events WHERE job_id = ? "
                                "ORDER BY seq", (job_id,))
        return [dict(r) for r in rows]

    def frame(self) -> dict[str, Any]:
        """The frame on the printer: ``state`` (``fresh``, ``used``), ``since`` (unix time, None: never
        confirmed) and ``job_id`` (the job that used it). Nothing confirmed yet: used."""
        row = self._db.execute("SELECT state, job_id, at FROM frame WHERE id = 1").fetchone()
        if row is None:
            return {"state": FRAME_USED, "since": None, "job_id": None}
        return {"state": str(row["state"]), "since": float(row["at"]), "job_id": row["job_id"]}

    def set_frame(self, state: str, job_id: str | None) -> None:
        """Record the frame as ``fresh`` (the operator confirmed it) or ``used`` (by ``job_id``), committed."""
        if state not in (FRAME_FRESH, FRAME_USED):
            raise ValueError(f"frame state {state!r}: {FRAME_FRESH!r} or {FRAME_USED!r}")
        with self._transaction() as db:
            db.execute("INSERT INTO frame (id, state, job_id, at) VALUES (1, ?, ?, ?) ON CONFLICT (id) DO UPDATE "
                       "SET state = excluded.state, job_id = excluded.job_id, at = excluded.at",
                       (state, job_id, self._clock()))

    # -- projects (schema 6) --------------------------------------------------------------------

    @staticmethod
    def _project(row: sqlite3.Row) -> ProjectRecord:
        data = {name: row[name] for name in _PROJECT_COLUMNS}
        data["parameters"] = json.loads(data["parameters"])
        data["start_when_ready"] = bool(data["start_when_ready"])
        return ProjectRecord.model_validate(data)

    def create_project(self, *, project_id: str, mesh_name: str, mesh_path: str, parameters: dict[str, Any],
                       panels_requested: str, seam_allowance_mm: float, start_when_ready: bool) -> ProjectRecord:
        """A new project in state ``submitted``, committed."""
        now = self._clock()
        try:
            record = ProjectRecord(id=project_id, state="submitted", created=now, updated=now, mesh_name=mesh_name,
                                   mesh_path=mesh_path, parameters=parameters, panels_requested=panels_requested,
                                   seam_allowance_mm=seam_allowance_mm, start_when_ready=start_when_ready)
        except ValidationError as exc:
            raise ValueError(f"new project: {_format_errors(exc)}") from None
        with self._transaction() as db:
            db.execute("INSERT INTO projects (id, state, created, updated, mesh_name, mesh_path, parameters, "
                       "panels_requested, seam_allowance_mm, start_when_ready) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                       (record.id, record.state, now, now, mesh_name, mesh_path,
                        _json(parameters, "new project: parameters"), panels_requested, seam_allowance_mm,
                        int(start_when_ready)))
        return record

    def project(self, project_id: str) -> ProjectRecord:
        """The project ``project_id``; raises ``ProjectNotFound``."""
        row = self._db.execute("SELECT * FROM projects WHERE id = ?", (project_id,)).fetchone()
        if row is None:
            raise ProjectNotFound(project_id)
        return self._project(row)

    def projects(self, limit: int | None = None) -> builtins.list[ProjectRecord]:
        """Projects, newest first (at most ``limit``)."""
        rows = self._db.execute("SELECT * FROM projects ORDER BY seq DESC LIMIT ?", (-1 if limit is None else limit,))
        return [self._project(row) for row in rows]

    def update_project(self, project_id: str, **fields: Any) -> ProjectRecord:
        """Set ``fields`` of the project (``PROJECT_MUTABLE``), committed."""
        unknown = sorted(set(fields) - PROJECT_MUTABLE)
        if unknown:
            raise ValueError(f"project {project_id}: cannot set {', '.join(unknown)}")
        with self._transaction() as db:
            current = self.project(project_id)
            try:
                record = ProjectRecord.model_validate({**current.model_dump(), **fields,
                                                       "updated": max(self._clock(), current.updated)})
            except ValidationError as exc:
                raise ValueError(f"project {project_id}: {_format_errors(exc)}") from None
            names = sorted(fields) + ["updated"]
            values = [int(v) if isinstance(v, bool) else v for v in (getattr(record, n) for n in names)]
            db.execute(f"UPDATE projects SET {', '.join(f'{n} = ?' for n in names)} WHERE id = ?",
                       (*values, project_id))
        return record

    def project_jobs(self, project_id: str) -> builtins.list[JobRecord]:
        """The project's panel jobs, by panel."""
        rows = self._db.execute("SELECT * FROM jobs WHERE project = ? ORDER BY panel, seq", (project_id,))
        return [self._record(row) for row in rows]

    def integrity(self) -> str:
        """``PRAGMA integrity_check``'s answer (``ok`` for a sound database)."""
        return "; ".join(str(r[0]) for r in self._db.execute("PRAGMA integrity_check"))

    def delete(self, job_id: str) -> None:
        """Remove the job and its transitions, committed (its files are the caller's)."""
        with self._transaction() as db:
            self._row(job_id)
            db.execute("DELETE FROM part_events WHERE job_id = ?", (job_id,))
            db.execute("DELETE FROM transitions WHERE job_id = ?", (job_id,))
            db.execute("DELETE FROM jobs WHERE id = ?", (job_id,))

    def mark_interrupted(self, reason: str) -> builtins.list[JobRecord]:
        """At daemon start: move every job that held the printer, or was compiling, to ``interrupted``.

        All in one transaction; ``reason`` is stored as the jobs' ``error`` and the transitions'
        reason. Returns the jobs changed, oldest first.
        """
        changed: builtins.list[JobRecord] = []
        with self._transaction():
            for row in self._db.execute("SELECT * FROM jobs ORDER BY seq").fetchall():
                current = self._record(row)
                if not (current.state.holds_printer or current.state is JobState.COMPILING):
                    continue
                check_transition(current.state, JobState.INTERRUPTED)
                at = self._now(current.updated)
                record = self._validated(current, {"state": JobState.INTERRUPTED, "error": reason, "updated": at})
                self._write(record)
                self._log(current.id, current.state, JobState.INTERRUPTED, at, reason)
                changed.append(record)
        return changed

    def close(self) -> None:
        """Close the connection (everything is already committed)."""
        self._db.close()

    def __enter__(self) -> JobStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
