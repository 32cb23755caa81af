"""The job store on a real SQLite file: records, the transition table, durability, schema versions."""

from __future__ import annotations

import itertools
import sqlite3
import subprocess
import sys
import textwrap
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from ribbond.daemon.jobs import TRANSITIONS, IllegalTransition, JobState
from ribbond.daemon.store import SCHEMA_VERSION, JobNotFound, JobRecord, JobStore

J = JobState
REPO = Path(__file__).resolve().parents[2]


class TickClock:
    """A clock that advances by ``step`` on every reading (``step`` < 0: a wall clock stepping back)."""

    def __init__(self, start: float = 1_700_000_000.0, step: float = 1.0) -> None:
        self.now, self.step = start, step
        self.readings: list[float] = []

    def __call__(self) -> float:
        self.now += self.step
        self.readings.append(self.now)
        return self.now


@pytest.fixture
def db(tmp_path: Path) -> Path:
    return tmp_path / "state" / "jobs.sqlite3"


@pytest.fixture
def store(db: Path) -> Iterator[JobStore]:
    s = JobStore(db)
    yield s
    s.close()


def new_job(store: JobStore, name: str = "saddle.obj", **params: object) -> JobRecord:
    return store.create(mesh_name=name, mesh_path=f"/uploads/{name}", parameters=dict(params),
                        start_when_ready=False)


#: A two-sided job's way through the table, from submitted to done.
TWO_SIDED = [J.COMPILING, J.READY, J.HEATING, J.PRINTING_FRONT, J.AWAITING_FLIP, J.ALIGNING,
             J.PRINTING_BACK, J.DONE]


def walk(store: JobStore, job_id: str, states: list[JobState]) -> JobRecord:
    record = store.get(job_id)
    for state in states:
        record = store.transition(job_id, state)
    return record


def path_to(state: JobState) -> list[JobState]:
    """The shortest chain of states from submitted to ``state``, found in the transition table."""
    frontier: list[list[JobState]] = [[J.SUBMITTED]]
    seen = {J.SUBMITTED}
    while frontier:
        chain = frontier.pop(0)
        if chain[-1] is state:
            return chain[1:]
        for nxt in sorted(TRANSITIONS[chain[-1]], key=lambda s: s.value):
            if nxt not in seen:
                seen.add(nxt)
                frontier.append(chain + [nxt])
    raise AssertionError(f"{state} unreachable")


#: The tables as schema version 1 wrote them (before G-code jobs and print runs).
V1_SCHEMA = """
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
    paused_from      TEXT
);
CREATE INDEX jobs_state ON jobs (state);
CREATE TABLE transitions (
    seq        INTEGER PRIMARY KEY AUTOINCREMENT,
    job_id     TEXT NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
    from_state TEXT,
    to_state   TEXT NOT NULL,
    at         REAL NOT NULL,
    reason     TEXT
);
CREATE INDEX transitions_job ON transitions (job_id, seq);
"""


# -- records ------------------------------------------------------------------------------------------

def test_create_and_get(store: JobStore) -> None:
    params = {"prestretch": 1.5, "size": {"bbox_diagonal": 120.0}, "tags": ["a", "b"]}
    job = store.create(mesh_name="torus.obj", mesh_path="/up/torus.obj", parameters=params,
                       start_when_ready=True)
    assert job.state is J.SUBMITTED
    assert len(job.id) == 12 and int(job.id, 16) >= 0
    assert job.created == job.updated
    assert job.last_acked_line == -1 and job.checkpoint is None and job.paused_from is None
    got = store.get(job.id)
    assert got == job
    assert got.parameters == params and got.start_when_ready is True
    [t] = store.transitions(job.id)
    assert (t.from_state, t.to_state, t.at) == (None, J.SUBMITTED, job.created)


def test_ids_are_distinct(store: JobStore) -> None:
    ids = {new_job(store).id for _ in range(50)}
    assert len(ids) == 50


def test_list_newest_first_and_filters(store: JobStore) -> None:
    jobs = [new_job(store, f"m{i}.obj") for i in range(5)]
    assert [j.id for j in store.list()] == [j.id for j in reversed(jobs)]
    assert [j.id for j in store.list(limit=2)] == [jobs[4].id, jobs[3].id]
    assert store.list(limit=0) == []
    store.transition(jobs[1].id, J.COMPILING)
    store.transition(jobs[3].id, J.CANCELLED)
    assert [j.id for j in store.list([J.COMPILING, J.CANCELLED])] == [jobs[3].id, jobs[1].id]
    assert [j.id for j in store.list([J.SUBMITTED], limit=2)] == [jobs[4].id, jobs[2].id]
    assert store.list([]) == []
    with pytest.raises(ValueError, match="limit"):
        store.list(limit=-1)
    # pages: offset skips the newest
    everything = [j.id for j in store.list()]
    assert [j.id for j in store.list(limit=2, offset=2)] == everything[2:4]
    assert [j.id for j in store.list(offset=3)] == everything[3:]
    assert store.count() == 5 and store.count([J.CANCELLED]) == 1


def test_delete_removes_the_job_and_its_transitions(store: JobStore) -> None:
    keep, gone = new_job(store, "a.obj"), new_job(store, "b.obj")
    store.transition(gone.id, J.CANCELLED)
    store.delete(gone.id)
    assert [j.id for j in store.list()] == [keep.id]
    with pytest.raises(JobNotFound):
        store.transitions(gone.id)
    with pytest.raises(JobNotFound):
        store.delete(gone.id)
    assert len(store.transitions(keep.id)) == 1


def test_a_version_1_database_is_migrated(db: Path) -> None:
    """A database written before G-code jobs and runs (schema 1) opens with its jobs as designs."""
    db.parent.mkdir(parents=True)
    conn = sqlite3.connect(db)
    conn.executescript(V1_SCHEMA)
    conn.execute("INSERT INTO jobs (id, state, created, updated, mesh_name, mesh_path, parameters, "
                 "start_when_ready) VALUES ('abcdefabcdef', 'done', 1.0, 2.0, 'm.obj', '/m.obj', '{}', 0)")
    conn.execute("PRAGMA user_version = 1")
    conn.commit()
    conn.close()
    with JobStore(db) as store:
        job = store.get("abcdefabcdef")
        assert job.kind == "design" and job.runs == [] and job.state is J.DONE
        assert store.update(job.id, runs=[{"run": 1}]).runs == [{"run": 1}]


def test_active_is_the_queue_oldest_first(store: JobStore) -> None:
    jobs = [new_job(store, f"m{i}.obj") for i in range(4)]
    walk(store, jobs[0].id, TWO_SIDED)
    store.transition(jobs[2].id, J.FAILED, reason="bad mesh")
    walk(store, jobs[3].id, [J.COMPILING])
    expected = [j.id for j in jobs if not store.get(j.id).state.terminal]
    assert [j.id for j in store.active()] == expected == [jobs[1].id, jobs[3].id]


def test_create_refuses_bad_input(store: JobStore) -> None:
    for name in ("", "..", "a/b.obj", "..\\x.obj"):
        with pytest.raises(ValueError, match="mesh_name"):
            store.create(mesh_name=name, mesh_path="/x", parameters={}, start_when_ready=False)
    with pytest.raises(ValueError, match="parameters"):
        store.create(mesh_name="a.obj", mesh_path="/x", parameters={"x": float("nan")}, start_when_ready=False)
    with pytest.raises(ValueError, match="parameters"):
        store.create(mesh_name="a.obj", mesh_path="/x", parameters={"x": object()}, start_when_ready=False)
    assert store.list() == []


def test_job_not_found(store: JobStore) -> None:
    new_job(store)
    for call in (lambda: store.get("000000000000"), lambda: store.transition("nope", J.COMPILING),
                 lambda: store.update("nope", stage="x"), lambda: store.record_ack("nope", 3),
                 lambda: store.checkpoint("nope", "flip", 3), lambda: store.transitions("nope")):
        with pytest.raises(JobNotFound) as err:
            call()
        assert isinstance(err.value, KeyError)
        assert err.value.job_id in str(err.value)


# -- transitions --------------------------------------------------------------------------------------

@pytest.mark.parametrize("current", list(JobState), ids=lambda s: s.value)
def test_transition_table_enforced(db: Path, current: JobState) -> None:
    """From each state, exactly the table's transitions are accepted; the others change nothing."""
    with JobStore(db) as store:
        for new in JobState:
            job = new_job(store)
            walk(store, job.id, path_to(current))
            before = store.get(job.id), store.transitions(job.id)
            if new in TRANSITIONS[current]:
                assert store.transition(job.id, new).state is new
                continue
            with pytest.raises(IllegalTransition) as err:
                store.transition(job.id, new)
            assert current.value in str(err.value)
            assert err.value.allowed_states == sorted(s.value for s in TRANSITIONS[current])
            assert (store.get(job.id), store.transitions(job.id)) == before


def test_every_transition_recorded_with_increasing_timestamps(db: Path) -> None:
    clock = TickClock()
    with JobStore(db, clock=clock) as store:
        job = new_job(store)
        reasons = [f"step {i}" for i in range(len(TWO_SIDED))]
        records = [store.transition(job.id, s, reason=r) for s, r in zip(TWO_SIDED, reasons)]
        log = store.transitions(job.id)
    assert [(t.from_state, t.to_state) for t in log] == list(
        zip([None, J.SUBMITTED, *TWO_SIDED[:-1]], [J.SUBMITTED, *TWO_SIDED]))
    assert [t.reason for t in log] == [None, *reasons]
    assert all(t.job_id == job.id for t in log)
    times = [t.at for t in log]
    assert times == sorted(times) and len(set(times)) == len(times)
    assert times == clock.readings  # one clock reading per change, stored as read
    assert [r.updated for r in records] == times[1:]
    assert all(r.created == times[0] for r in records)


def test_timestamps_never_go_back_with_the_clock(db: Path) -> None:
    with JobStore(db, clock=TickClock(step=-5.0)) as store:
        job = new_job(store)
        walk(store, job.id, TWO_SIDED[:4])
        times = [t.at for t in store.transitions(job.id)]
    assert times == sorted(times)


def test_real_clock_timestamps(store: JobStore) -> None:
    before = time.time()
    job = new_job(store)
    walk(store, job.id, TWO_SIDED)
    after = time.time()
    times = [t.at for t in store.transitions(job.id)]
    assert times == sorted(times) and before <= times[0] and times[-1] <= after


def test_transition_sets_fields_in_the_same_change(store: JobStore) -> None:
    job = new_job(store)
    walk(store, job.id, [J.COMPILING])
    ready = store.transition(job.id, J.READY, design_dir="/d/x", stage=None, progress=1.0, lines_total=1234)
    assert (ready.design_dir, ready.progress, ready.lines_total) == ("/d/x", 1.0, 1234)
    assert store.get(job.id) == ready


def test_transition_refuses_bad_fields_and_writes_nothing(store: JobStore) -> None:
    job = new_job(store)
    before = store.get(job.id), store.transitions(job.id)
    with pytest.raises(ValueError, match="colour"):
        store.transition(job.id, J.COMPILING, colour="red")
    with pytest.raises(ValueError, match="progress"):
        store.transition(job.id, J.COMPILING, progress=1.5)
    with pytest.raises(ValueError, match="state"):
        store.transition(job.id, J.COMPILING, state=J.READY)
    assert (store.get(job.id), store.transitions(job.id)) == before


def test_failure_reason_is_the_error(store: JobStore) -> None:
    job = new_job(store)
    failed = store.transition(job.id, J.FAILED, reason="mesh is not a disk")
    assert failed.error == "mesh is not a disk"
    assert store.transitions(job.id)[-1].reason == "mesh is not a disk"


def test_pause_remembers_where_from(store: JobStore) -> None:
    job = new_job(store)
    walk(store, job.id, TWO_SIDED[:TWO_SIDED.index(J.PRINTING_BACK) + 1])
    paused = store.transition(job.id, J.PAUSED, reason="user")
    assert paused.paused_from is J.PRINTING_BACK
    assert store.get(job.id).paused_from is J.PRINTING_BACK
    resumed = store.transition(job.id, J.PRINTING_BACK)
    assert resumed.paused_from is None


# -- update, acks, checkpoints ------------------------------------------------------------------------

def test_update(store: JobStore) -> None:
    job = new_job(store)
    correction = {"dx": 0.25, "dy": -0.5, "theta": 0.01}
    updated = store.update(job.id, stage="flatten", progress=0.5, correction=correction, side="front")
    assert (updated.stage, updated.progress, updated.correction, updated.side) == ("flatten", 0.5, correction, "front")
    assert updated.state is job.state and updated.updated >= job.updated
    assert store.get(job.id) == updated
    assert len(store.transitions(job.id)) == 1  # not a state change


def test_update_refuses_state_and_unknown_fields(store: JobStore) -> None:
    job = new_job(store)
    with pytest.raises(ValueError, match="state"):
        store.update(job.id, state=J.COMPILING)
    with pytest.raises(ValueError, match="state"):
        store.update(job.id, state="compiling")
    for field in ("id", "created", "updated", "nonsense"):
        with pytest.raises(ValueError, match=field):
            store.update(job.id, **{field: 1})
    with pytest.raises(ValueError, match="side"):
        store.update(job.id, side="left")
    assert store.get(job.id) == job


def test_record_ack_is_monotonic(store: JobStore) -> None:
    job = new_job(store)
    acks = [0, 5, 3, 9, 9, 2, 12, -1]
    for line, highest in zip(acks, itertools.accumulate(acks, max)):
        store.record_ack(job.id, line)
        assert store.get(job.id).last_acked_line == highest
    for bad in (-2, 1.5, "3", True):
        with pytest.raises(ValueError):
            store.record_ack(job.id, bad)  # type: ignore[arg-type]
    # A new program (the back side) starts its numbering over: reset explicitly.
    assert store.update(job.id, last_acked_line=-1).last_acked_line == -1


def test_checkpoint(store: JobStore) -> None:
    job = new_job(store)
    store.record_ack(job.id, 40)
    record = store.checkpoint(job.id, "front_done", 30)
    assert (record.checkpoint, record.checkpoint_line, record.last_acked_line) == ("front_done", 30, 40)
    record = store.checkpoint(job.id, "flip", 55)
    assert (record.checkpoint, record.checkpoint_line, record.last_acked_line) == ("flip", 55, 40)
    assert store.get(job.id) == record
    assert store.checkpoint(job.id, "start", -1).checkpoint_line == -1  # nothing acknowledged yet
    for name, line in (("", 3), (" ", 3), ("x", -2), ("x", 1.0)):
        with pytest.raises(ValueError):
            store.checkpoint(job.id, name, line)


# -- restart ------------------------------------------------------------------------------------------

def test_mark_interrupted(store: JobStore) -> None:
    by_state = {}
    for state in JobState:
        job = new_job(store, f"{state.value}.obj")
        walk(store, job.id, path_to(state))
        by_state[state] = job.id
    changed = store.mark_interrupted("daemon restarted")
    hit = [s for s in JobState if s.holds_printer or s is J.COMPILING]
    assert [r.id for r in changed] == [by_state[s] for s in hit]
    for state, job_id in by_state.items():
        record = store.get(job_id)
        if state in hit:
            assert record.state is J.INTERRUPTED and record.error == "daemon restarted"
            last = store.transitions(job_id)[-1]
            assert (last.from_state, last.to_state, last.reason) == (state, J.INTERRUPTED, "daemon restarted")
        else:
            assert record.state is state
    assert store.mark_interrupted("again") == []


def test_reopen_sees_everything_committed(db: Path) -> None:
    first = JobStore(db)  # never closed: as if the daemon were killed
    job = new_job(first, prestretch=1.4)
    walk(first, job.id, TWO_SIDED[:5])
    first.record_ack(job.id, 77)
    first.checkpoint(job.id, "front_done", 70)
    first.update(job.id, side="front", correction={"dx": 1.0})
    expected, log = first.get(job.id), first.transitions(job.id)
    second = JobStore(db)
    assert second.get(job.id) == expected
    assert second.transitions(job.id) == log
    second.close()


def test_killed_process_loses_nothing_committed(db: Path) -> None:
    """A child process writes, then dies without closing (os._exit); a new store finds it all."""
    script = textwrap.dedent(f"""
        import os, sys
        from pathlib import Path
        from ribbond.daemon.jobs import JobState as J
        from ribbond.daemon.store import JobStore
        s = JobStore(Path({str(db)!r}))
        job = s.create(mesh_name="a.obj", mesh_path="/a", parameters={{"k": [1, 2]}}, start_when_ready=True)
        for state in (J.COMPILING, J.READY, J.HEATING, J.PRINTING_FRONT):
            s.transition(job.id, state, reason=state.value)
        s.record_ack(job.id, 123)
        s.checkpoint(job.id, "purge_done", 100)
        print(job.id, flush=True)
        os._exit(0)
    """)
    out = subprocess.run([sys.executable, "-c", script], cwd=REPO, capture_output=True, text=True, check=True)
    job_id = out.stdout.strip()
    with JobStore(db) as store:
        job = store.get(job_id)
        assert (job.state, job.last_acked_line, job.checkpoint, job.checkpoint_line) == (
            J.PRINTING_FRONT, 123, "purge_done", 100)
        assert job.parameters == {"k": [1, 2]} and job.start_when_ready
        assert [t.to_state for t in store.transitions(job_id)] == [
            J.SUBMITTED, J.COMPILING, J.READY, J.HEATING, J.PRINTING_FRONT]
        [interrupted] = store.mark_interrupted("daemon was killed")
        assert interrupted.id == job_id


def test_database_settings(store: JobStore, db: Path) -> None:
    with sqlite3.connect(db) as other:
        assert other.execute("PRAGMA journal_mode").fetchone()[0] == "wal"  # persistent in the file
        assert other.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION


# -- schema versions ----------------------------------------------------------------------------------

def set_user_version(db: Path, version: int) -> None:
    conn = sqlite3.connect(db)
    conn.execute(f"PRAGMA user_version = {version:d}")
    conn.commit()
    conn.close()


def test_newer_schema_refused(db: Path) -> None:
    with JobStore(db) as store:
        job = new_job(store)
    set_user_version(db, SCHEMA_VERSION + 1)
    with pytest.raises(ValueError) as err:
        JobStore(db)
    message = str(err.value)
    assert str(db) in message and "newer" in message
    assert str(SCHEMA_VERSION + 1) in message and str(SCHEMA_VERSION) in message
    # Refusing changed nothing: back at our version, the job is there.
    set_user_version(db, SCHEMA_VERSION)
    with JobStore(db) as store:
        assert store.get(job.id) == job


def test_foreign_database_refused(tmp_path: Path) -> None:
    path = tmp_path / "other.sqlite3"
    conn = sqlite3.connect(path)
    conn.execute("CREATE TABLE notes (x TEXT)")
    conn.commit()
    conn.close()
    with pytest.raises(ValueError, match="not a ribbond job database"):
        JobStore(path)


def test_not_a_database_refused(tmp_path: Path) -> None:
    path = tmp_path / "garbage.sqlite3"
    path.write_bytes(b"this is not sqlite at all" * 100)
    with pytest.raises(ValueError) as err:
        JobStore(path)
    assert str(path) in str(err.value)


