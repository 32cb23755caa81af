"""A plain G-code job prints one program and has no front (``jobs.state_name``): wherever a refusal
names its state, ``printing_front`` reads ``printing (the program)``; a design job's states, and a
plain job's other states, read as their values. In process and fast, for the mutation run (issue 35):
the refusals of the daemon's end-to-end tests run in other processes."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest

from ribbond.daemon.components.frame import FrameGate
from ribbond.daemon.components.run import PrintState
from ribbond.daemon.events import EventBus
from ribbond.daemon.jobs import COMMANDS, IllegalTransition, JobState, state_name
from ribbond.daemon.records import JobRecords, ServiceError
from ribbond.daemon.store import JobStore

J = JobState
PROGRAM = "printing (the program)"


def test_only_a_plain_programs_front_is_named_the_program() -> None:
    assert state_name(J.PRINTING_FRONT, "gcode") == PROGRAM
    for kind in (None, "design", "calibration", "GCODE"):           # the kind is compared exactly
        assert state_name(J.PRINTING_FRONT, kind) == "printing_front"
    assert state_name(J.PRINTING_FRONT) == "printing_front"
    for state in JobState:
        if state is not J.PRINTING_FRONT:
            assert state_name(state, "gcode") == state.value


def test_a_refusal_names_a_plain_programs_state_as_people_read_it() -> None:
    error = IllegalTransition(J.PRINTING_FRONT, "flip-done", kind="gcode")
    assert str(error) == f"cannot flip-done: the job is {PROGRAM}; possible now: pause, cancel"
    error = IllegalTransition(J.PRINTING_FRONT, "flip-done", kind="design")
    assert str(error) == "cannot flip-done: the job is printing_front; possible now: pause, cancel"


@pytest.mark.parametrize("kind, name", [("gcode", PROGRAM), ("design", "printing_front")])
def test_the_refusal_of_a_job_reads_its_state_and_kind(kind: str, name: str) -> None:
    job = SimpleNamespace(state=J.PRINTING_FRONT, kind=kind)
    error = IllegalTransition.of(job, "align", hint="nothing to align")
    assert (error.current, error.requested, error.command) == (J.PRINTING_FRONT, "align", "align")
    assert error.allowed == list(COMMANDS[J.PRINTING_FRONT])
    assert str(error) == f"cannot align: the job is {name}; possible now: pause, cancel (nothing to align)"
    error = IllegalTransition.of(job, J.DONE, command="finish")
    assert (error.requested, error.command) == (J.DONE, "finish")
    assert str(error) == f"cannot finish: the job is {name}; possible now: pause, cancel"
    error = IllegalTransition.of(SimpleNamespace(state=J.PRINTING_FRONT), J.DONE)   # a record without kind
    assert str(error) == "cannot move to done: the job is printing_front; possible now: pause, cancel"


def test_the_frame_gate_names_a_plain_program_printing(tmp_path: Path) -> None:
    store = JobStore(tmp_path / "jobs.db")
    records = JobRecords(store, EventBus(), tmp_path, 10, lambda job: {"id": job.id})
    gate = FrameGate(records, PrintState(), SimpleNamespace())  # type: ignore[arg-type]
    job = store.create(mesh_name="p.gcode", mesh_path="p.gcode", parameters={}, start_when_ready=True,
                       kind="gcode", same_frame=False)  # type: ignore[arg-type]
    for state in (J.READY, J.HEATING, J.PRINTING_FRONT):
        store.transition(job.id, state)
    with pytest.raises(ServiceError) as info:
        gate.ready()
    assert str(info.value).startswith(f"cannot confirm a fresh frame: job {job.id} is {PROGRAM} on the printer ")
