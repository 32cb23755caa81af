"""The job state machine's table and the modal state a pause must restore."""

from __future__ import annotations

import pytest

from ribbond.daemon.jobs import COMMANDS, TRANSITIONS, IllegalTransition, JobState, check_transition
from ribbond.daemon.service import modal_state

J = JobState
HAPPY_PATH = [J.SUBMITTED, J.COMPILING, J.READY, J.HEATING, J.PRINTING_FRONT, J.AWAITING_FLIP,
              J.ALIGNING, J.PRINTING_BACK, J.DONE]


def test_the_two_sided_path_is_allowed_step_by_step() -> None:
    for a, b in zip(HAPPY_PATH[:-1], HAPPY_PATH[1:]):
        check_transition(a, b)


def test_a_one_sided_job_goes_from_the_front_to_done() -> None:
    check_transition(J.PRINTING_FRONT, J.DONE)


@pytest.mark.parametrize("state", [J.PRINTING_FRONT, J.PRINTING_BACK])
def test_pause_from_either_printing_state_and_back(state: JobState) -> None:
    check_transition(state, J.PAUSED)
    check_transition(J.PAUSED, state)


def test_every_state_is_in_the_table_and_every_target_is_a_state() -> None:
    assert set(TRANSITIONS) == set(JobState)
    for targets in TRANSITIONS.values():
        assert targets <= set(JobState)


@pytest.mark.parametrize("state", [J.DONE, J.CANCELLED, J.FAILED, J.INTERRUPTED])
def test_an_ended_job_can_only_be_started_again(state: JobState) -> None:
    """An ended run goes back to ready (a new run of the same design); interrupted can also be
    cancelled; nothing else."""
    assert state.terminal and "start" in COMMANDS[state] and "delete" in COMMANDS[state]
    # (a compile made again; a print resumed after the frame is checked)
    extra = {J.CANCELLED, J.SUBMITTED, J.AWAITING_CHECK, J.DONE} if state is J.INTERRUPTED else set()
    for other in JobState:
        if other is J.READY or other in extra:
            check_transition(state, other)
        else:
            with pytest.raises(IllegalTransition):
                check_transition(state, other)


def test_a_gcode_program_needs_no_compile() -> None:
    check_transition(J.SUBMITTED, J.READY)


def test_every_command_names_a_possible_move() -> None:
    """Each state's commands lead somewhere the table allows (manual commands are not job commands)."""
    target = {"start": {J.READY, J.HEATING, J.SUBMITTED}, "cancel": {J.CANCELLED}, "pause": {J.PAUSED},
              "resume": {J.PRINTING_FRONT, J.PRINTING_BACK, J.AWAITING_CHECK, J.DONE}, "flip-done": {J.ALIGNING},
              "frame-ok": {J.HEATING, J.ALIGNING},
              "align": {J.PRINTING_BACK, J.FITTED}, "accept": {J.PRINTING_BACK},
              "re-seat": {J.ALIGNING}}
    assert set(COMMANDS) == set(JobState)
    for state, commands in COMMANDS.items():
        for command in commands:
            if command == "delete":
                assert state.terminal or state is J.READY
            elif state in (J.SUBMITTED, J.COMPILING) and command == "start":
                continue                                       # marks the job to print when ready
            else:
                assert target[command] & TRANSITIONS[state], (state, command)


#: The job life cycle of ``ribbond/daemon/jobs.py``'s docstring, written out by hand (not read from
#: ``TRANSITIONS``): for every state, every state it may go to next. Every other target is refused.
_STOPS = {J.CANCELLED, J.FAILED}                 # the operator cancels; the print task fails it
_ON_PRINTER = _STOPS | {J.INTERRUPTED}           # ... or the daemon stops while it holds the printer
LIFE_CYCLE: dict[JobState, set[JobState]] = {
    J.SUBMITTED: {J.COMPILING, J.READY} | _STOPS,                 # a plain G-code program needs no compile
    J.COMPILING: {J.READY} | _ON_PRINTER,                         # (a compile the stop cut is interrupted)
    J.READY: {J.HEATING} | _STOPS,                                # never straight to printing: it heats first
    J.HEATING: {J.PRINTING_FRONT, J.PRINTING_BACK} | _ON_PRINTER,  # the back: a resumed one, alignment kept
    J.PRINTING_FRONT: {J.AWAITING_FLIP, J.DONE, J.PAUSED} | _ON_PRINTER,   # done: a one-sided design
    J.AWAITING_FLIP: {J.ALIGNING} | _ON_PRINTER,                  # never to the back without the marks
    J.ALIGNING: {J.PRINTING_BACK, J.FITTED} | _ON_PRINTER,        # a refused fit stays aligning
    J.FITTED: {J.PRINTING_BACK, J.ALIGNING} | _ON_PRINTER,        # accept, or re-seat and measure again
    J.PRINTING_BACK: {J.DONE, J.PAUSED} | _ON_PRINTER,
    J.PAUSED: {J.PRINTING_FRONT, J.PRINTING_BACK} | _ON_PRINTER,  # resumed; never done from a pause
    J.DONE: {J.READY},                                            # a new run of the same design
    J.CANCELLED: {J.READY},
    J.FAILED: {J.READY},
    # a new run, a compile made again, cancelled, resumed (the frame checked first), or nothing left
    J.INTERRUPTED: {J.READY, J.SUBMITTED, J.CANCELLED, J.AWAITING_CHECK, J.DONE},
    J.AWAITING_CHECK: {J.HEATING, J.ALIGNING, J.AWAITING_FLIP} | _ON_PRINTER,   # the front heats; the back is aligned, or flipped first
}


def test_the_life_cycle_covers_every_state() -> None:
    assert set(LIFE_CYCLE) == set(JobState)


@pytest.mark.parametrize("state", list(JobState), ids=lambda s: s.value)
def test_every_state_allows_its_life_cycle_and_refuses_every_other_target(state: JobState) -> None:
    """Each allowed move passes ``check_transition``; each other target state (itself included)
    raises ``IllegalTransition`` (e.g. ready → printing_front without heating, awaiting_flip →
    printing_back without the alignment, awaiting_check → printing_front, paused → done)."""
    for target in JobState:
        if target in LIFE_CYCLE[state]:
            check_transition(state, target)
        else:
            with pytest.raises(IllegalTransition):
                check_transition(state, target)


def test_only_jobs_on_the_printer_can_be_interrupted() -> None:
    can = {s for s, targets in TRANSITIONS.items() if J.INTERRUPTED in targets}
    assert can == {s for s in JobState if s.holds_printer} | {J.COMPILING}


def test_cancel_and_fail_from_every_unfinished_state() -> None:
    for state in JobState:
        if state.terminal:
            continue
        check_transition(state, J.CANCELLED)
        check_transition(state, J.FAILED)


def test_an_illegal_request_names_the_command_the_state_and_the_commands_possible() -> None:
    with pytest.raises(IllegalTransition) as info:
        check_transition(J.READY, J.PAUSED)
    err = info.value
    assert err.current is J.READY
    assert err.allowed == list(COMMANDS[J.READY]) == ["start", "cancel", "delete"]
    assert err.allowed_states == sorted(s.value for s in TRANSITIONS[J.READY])
    assert str(err) == "cannot pause: the job is ready; possible now: start, cancel, delete"
    err = IllegalTransition(J.AWAITING_FLIP, "resume")
    assert str(err) == "cannot resume: the job is awaiting_flip; possible now: flip-done, cancel"


def test_modal_state_follows_the_program_up_to_the_pause() -> None:
    program = ["G90", "M83", "M104 S225", "M140 S60", "M106 S127", "G1 X1 E0.1 F900", "G91", "G1 X1",
               "M82", "G0 X5 F9000", "M107", "M109 S210"]
    s = modal_state(program, 6)
    assert s == {"absolute": True, "e_absolute": False, "feed": 900.0, "fan": 127, "nozzle": 225.0, "bed": 60.0,
                 "x": 1.0, "y": None, "z": None}
    s = modal_state(program, 8)
    assert s["absolute"] is False and s["e_absolute"] is False           # G91 sets E relative too
    assert s["x"] == 2.0                                                   # a relative move adds
    s = modal_state(program, len(program))
    assert s["e_absolute"] is True and s["feed"] == 9000.0 and s["fan"] == 0 and s["nozzle"] == 210.0
    assert s["x"] == 7.0
    assert modal_state(program, 0)["absolute"] is True                    # Marlin's power-on state


def test_an_illegal_transition_keeps_what_was_asked_and_says_it() -> None:
    error = IllegalTransition(JobState.READY, JobState.DONE)
    assert (error.current, error.requested, error.command) == (JobState.READY, JobState.DONE, "move to done")
    assert str(error) == "cannot move to done: the job is ready; possible now: start, cancel, delete"
    error = IllegalTransition(JobState.DONE, "pause", hint="nothing is printing")
    assert (error.requested, error.command) == ("pause", "pause")
    assert str(error) == "cannot pause: the job is done; possible now: start, delete (nothing is printing)"
    assert all(COMMANDS[state] for state in JobState)   # so "possible now: nothing" is never said
