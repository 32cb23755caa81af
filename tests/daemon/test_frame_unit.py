"""The fresh-frame gate (``daemon/components/frame.py``) in process, fast: a real store (SQLite in
tmp_path) and event bus, a heater that records being switched off. The end-to-end behaviour (real
daemon, simulator, HTTP) is ``test_frame_gate.py``; this file pins each rule for the mutation run
(issue 35), including the daemon stopping while a job waits at the gate."""

from __future__ import annotations

import asyncio
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

from ribbond.daemon.components.frame import WAIT_STAGE, FrameGate, needs_fresh_frame, waits_at_gate
from ribbond.daemon.components.run import PrintState
from ribbond.daemon.events import EventBus
from ribbond.daemon.jobs import JobState
from ribbond.daemon.records import JobRecords, ServiceError
from ribbond.daemon.store import FRAME_FRESH, FRAME_USED, JobStore

pytestmark = pytest.mark.timeout(30)


class Heaters:
    """Records ``off_if_on`` (the gate switches heaters a program left on off before waiting)."""

    def __init__(self) -> None:
        self.offs = 0

    async def off_if_on(self) -> None:
        self.offs += 1


class Gate(SimpleNamespace):
    gate: FrameGate
    store: JobStore
    state: PrintState
    heaters: Heaters
    events: asyncio.Queue[dict[str, Any]]


@pytest.fixture
def g(tmp_path: Path) -> Gate:
    store = JobStore(tmp_path / "jobs.db")
    bus = EventBus()
    events = bus.subscribe()
    records = JobRecords(store, bus, tmp_path, 10, lambda job: {"id": job.id, "stage": job.stage})
    state, heaters = PrintState(), Heaters()
    return Gate(gate=FrameGate(records, state, heaters), store=store, state=state, heaters=heaters, events=events)


def queued_job(store: JobStore, *, kind: str = "design", same_frame: bool = False, start: bool = True) -> str:
    job = store.create(mesh_name="m.obj", mesh_path="m.obj", parameters={}, start_when_ready=start,
                       kind=kind, same_frame=same_frame)  # type: ignore[arg-type]
    store.transition(job.id, JobState.READY)
    return job.id


def drain(events: asyncio.Queue[dict[str, Any]]) -> list[dict[str, Any]]:
    out = []
    while not events.empty():
        out.append(events.get_nowait())
    return out


def test_which_jobs_need_a_fresh_frame(g: Gate) -> None:
    design, gcode = queued_job(g.store), queued_job(g.store, kind="gcode")
    same = queued_job(g.store, kind="gcode", same_frame=True)
    design_same = queued_job(g.store, same_frame=True)     # a design always prints on a fresh frame
    assert [needs_fresh_frame(g.store.get(j)) for j in (design, gcode, same, design_same)] == [True, True, False, True]


def test_a_job_waits_at_the_gate_only_queued_ready_with_the_wait_stage(g: Gate) -> None:
    queued, idle = queued_job(g.store), queued_job(g.store, start=False)
    assert not waits_at_gate(g.store.get(queued))                       # no stage yet
    for job in (queued, idle):
        g.store.update(job, stage=WAIT_STAGE)
    assert waits_at_gate(g.store.get(queued)) and not waits_at_gate(g.store.get(idle))
    g.store.transition(queued, JobState.CANCELLED)
    assert not waits_at_gate(g.store.get(queued))


def test_at_first_start_the_frame_is_used_and_nothing_waits(g: Gate) -> None:
    assert g.gate.status() == {"state": FRAME_USED, "since": None, "job_id": None, "waiting_job": None}


def test_a_job_reaching_the_printer_marks_the_frame_used_once(g: Gate) -> None:
    g.store.set_frame(FRAME_FRESH, None)
    g.gate.used("a")
    assert g.store.frame()["state"] == FRAME_USED and g.store.frame()["job_id"] == "a"
    assert [(e["type"], e["frame"]["job_id"]) for e in drain(g.events)] == [("frame", "a")]
    g.gate.used("b")                                        # already used: kept as the first job left it
    assert g.store.frame()["job_id"] == "a" and drain(g.events) == []


async def test_a_job_waits_with_heaters_off_until_the_operator_confirms(g: Gate) -> None:
    job = queued_job(g.store)
    waiting = asyncio.create_task(g.gate.wait_fresh(job))
    await asyncio.sleep(0.3)
    assert not waiting.done()
    assert g.store.get(job).stage == WAIT_STAGE and g.heaters.offs == 1
    assert g.gate.status()["waiting_job"] == job
    answer = g.gate.ready()
    assert answer["state"] == FRAME_FRESH and answer["waiting_job"] is None
    assert g.store.get(job).stage == "a fresh frame is loaded"
    for _ in range(20):                                     # the confirmation wakes it within a few turns of
        await asyncio.sleep(0)                              # the loop, not at the next 0.2 s poll
    assert waiting.done()
    result = waiting.result()
    assert result is not None and result.id == job and result.stage is None
    assert g.store.get(job).stage is None
    stages = [e["job"]["stage"] for e in drain(g.events) if e["type"] == "job"]
    assert stages == [WAIT_STAGE, "a fresh frame is loaded", None]


async def test_a_fresh_frame_lets_the_job_go_at_once(g: Gate) -> None:
    g.store.set_frame(FRAME_FRESH, None)
    job = queued_job(g.store)
    result = await asyncio.wait_for(g.gate.wait_fresh(job), 1)
    assert result is not None and result.stage is None


async def test_the_daemon_stopping_ends_the_wait_and_the_job_stays_queued(g: Gate) -> None:
    job = queued_job(g.store)
    waiting = asyncio.create_task(g.gate.wait_fresh(job))
    await asyncio.sleep(0.1)
    g.state.stopping = True
    assert await asyncio.wait_for(waiting, 2) is None
    after = g.store.get(job)
    assert after.state is JobState.READY and after.start_when_ready   # printed after the restart, not lost


async def test_the_daemon_stopping_as_the_frame_is_confirmed_starts_nothing(g: Gate) -> None:
    g.store.set_frame(FRAME_FRESH, None)
    g.state.stopping = True
    assert await asyncio.wait_for(g.gate.wait_fresh(queued_job(g.store)), 1) is None


@pytest.mark.parametrize("how", ["cancel", "delete", "unqueue"])
async def test_a_job_cancelled_deleted_or_unqueued_while_waiting_is_not_printed(g: Gate, how: str) -> None:
    job = queued_job(g.store)
    waiting = asyncio.create_task(g.gate.wait_fresh(job))
    await asyncio.sleep(0.1)
    if how == "cancel":
        g.store.transition(job, JobState.CANCELLED)
    elif how == "delete":
        g.store.delete(job)
    else:
        g.store.update(job, start_when_ready=False)
    assert await asyncio.wait_for(waiting, 0.8) is None     # seen at the next 0.2 s look, not a second later
    g.gate.ready()                                          # a confirmation afterwards starts nothing either


@pytest.mark.parametrize("state", [JobState.HEATING, JobState.AWAITING_FLIP])
def test_a_fresh_frame_cannot_be_confirmed_under_a_job_on_the_printer(g: Gate, state: JobState) -> None:
    job = queued_job(g.store)
    g.store.transition(job, JobState.HEATING)
    if state is JobState.AWAITING_FLIP:
        g.store.transition(job, JobState.PRINTING_FRONT)
        g.store.transition(job, JobState.AWAITING_FLIP)
    with pytest.raises(ServiceError) as info:
        g.gate.ready()
    assert str(info.value) == (f"cannot confirm a fresh frame: job {job} is {state.value} on the printer (the "
                               "frame under a running job is not fresh); confirm it once that job has ended "
                               f"(ribbonctl cancel {job} ends it now)")
    assert g.store.frame()["state"] == FRAME_USED


def test_a_fresh_frame_cannot_be_confirmed_during_a_run(g: Gate) -> None:
    job = queued_job(g.store)
    g.state.run = SimpleNamespace(job_id=job)  # type: ignore[assignment]
    with pytest.raises(ServiceError, match=f"job {job} is ready on the printer"):
        g.gate.ready()
    g.state.run = None
    assert g.gate.ready()["state"] == FRAME_FRESH


async def test_the_journal_says_what_happened_to_the_frame(g: Gate, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level("INFO", logger="ribbond.daemon.components.frame")
    job = queued_job(g.store)
    g.store.set_frame(FRAME_FRESH, None)
    g.gate.used("a1")
    waiting = asyncio.create_task(g.gate.wait_fresh(job))
    await asyncio.sleep(0.05)
    g.gate.ready()
    await asyncio.wait_for(waiting, 2)
    assert [r.getMessage() for r in caplog.records if r.name == "ribbond.daemon.components.frame"] == [
        "the frame is used (job a1 printed on it)", f"job {job} waits for a fresh frame (ribbonctl frame-ready)",
        "the operator confirmed a fresh frame"]
