"""ribbond end to end: a real simulator process on a pty, a real daemon process, real HTTP.

The simulator runs 50× faster than the machine (``--time-scale 0.02``) at 250 kbaud; designs are
small (a 70 mm saddle). One daemon and one simulator are shared by the tests that do not stop or
reconfigure the daemon; each of those tests submits its own job and leaves the printer free. The
kill/restart and the authentication tests start their own daemons.
"""

from __future__ import annotations

import math
import threading
import time
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest

from ribbond.gcode.profiles import load_profile
from sim.config import FrameConfig
from sim.frame import Frame, FramePose

from .conftest import CENTER, PARAMETERS, Daemon, Sim, own_printer, submit, wait_for

pytestmark = pytest.mark.timeout(120)

#: How the frame is put back after the flip in the alignment tests.
MISALIGNMENT = (0.6, -0.4, 0.8)           # dx, dy (mm), rotation (degrees)
#: How close a deposit must be to where the design puts it, beyond half a ribbon width (mm).
TOLERANCE = 0.1
FULL_FLOW = ["submitted", "compiling", "ready", "heating", "printing_front", "awaiting_flip", "aligning",
             "printing_back", "done"]


# ---------------------------------------------------------------------------------- helpers


def operator_jogs(marks: list[list[float]], dx: float, dy: float, rotation_deg: float) -> list[tuple[float, float]]:
    """The jog an operator reports at each registration mark after a flip about x = 110 that put
    the frame back off by (dx, dy) and ``rotation_deg`` (as ``examples/demo.py`` computes it)."""
    a = math.radians(rotation_deg)
    cx, cy = CENTER
    jogs = []
    for x, y in marks:
        px, py = 2 * cx - x, y                                   # where the mark should be: mirrored
        mx = cx + math.cos(a) * (px - cx) - math.sin(a) * (py - cy) + dx
        my = cy + math.sin(a) * (px - cx) + math.cos(a) * (py - cy) + dy
        jogs.append((mx - px, my - py))
    return jogs


def flip_and_align(api: httpx.Client, sim: Sim, job: str, marks: list[list[float]],
                   misalignment: tuple[float, float, float]) -> list[httpx.Response]:
    """Turn the frame over with ``misalignment``, say flip-done, report the jog at every mark."""
    dx, dy, rot = misalignment
    pose = sim.flip(dx, dy, rot)
    assert pose["side"] == "back"
    r = api.post(f"/jobs/{job}/flip-done")
    assert r.status_code == 200, r.text
    wait_for(api, job, "aligning", timeout=30)
    answers = []
    for i, jog in enumerate(operator_jogs(marks, dx, dy, rot)):
        answers.append(api.post(f"/jobs/{job}/align", json={"mark": i + 1, "jog": list(jog)}))  # from 1
    return answers


def states(transitions: list[dict[str, Any]]) -> list[str]:
    return [t["to_state"] for t in transitions]


def assert_chained(transitions: list[dict[str, Any]]) -> None:
    """Each transition starts where the last ended, the first is the creation; times never go back."""
    assert transitions[0]["from_state"] is None
    for before, after in zip(transitions, transitions[1:]):
        assert after["from_state"] == before["to_state"]
        assert after["at"] >= before["at"], (before, after)


def distance_to_polylines(points: np.ndarray, polylines: list[np.ndarray]) -> np.ndarray:
    """For each point (N, 2), the distance to the nearest of ``polylines`` (each (M, 2))."""
    best = np.full(len(points), np.inf)
    for line in polylines:
        a, b = line[:-1], line[1:]
        ab = b - a
        length2 = np.maximum((ab * ab).sum(axis=1), 1e-18)
        rel = points[:, None, :] - a[None, :, :]
        t = np.clip((rel * ab[None]).sum(axis=2) / length2[None], 0.0, 1.0)
        closest = a[None] + t[..., None] * ab[None]
        d = np.hypot(*(points[:, None, :] - closest).transpose(2, 0, 1)).min(axis=1)
        best = np.minimum(best, d)
    return best


def deposit_points(segments: list[dict[str, Any]], fabric: bool = True) -> np.ndarray:
    """Start, middle and end of each deposit (in fabric or machine coordinates), (3N, 2)."""
    keys = ("fx0", "fy0", "fx1", "fy1") if fabric else ("x0", "y0", "x1", "y1")
    seg = np.array([[s[k] for k in keys] for s in segments], dtype=float).reshape(-1, 2, 2)
    return np.concatenate([seg[:, 0], seg.mean(axis=1), seg[:, 1]])


def program_deposits(text: str) -> list[tuple[float, float, float, float, float]]:
    """The extruding moves of a program (G90 positions, M83 extrusion): (x0, y0, x1, y1, e)."""
    x = y = float("nan")
    absolute_e = True
    moves = []
    for raw in text.splitlines():
        words = raw.split(";", 1)[0].split()
        if not words:
            continue
        code = words[0].upper()
        if code == "M83":
            absolute_e = False
        elif code == "M82":
            absolute_e = True
        elif code == "G91":
            raise AssertionError("program_deposits reads absolute positioning only")
        elif code in ("G0", "G1"):
            args = {w[0].upper(): float(w[1:]) for w in words[1:]}
            nx, ny = args.get("X", x), args.get("Y", y)
            e = args.get("E", 0.0)
            assert not absolute_e or "E" not in args, "the programs extrude relatively (M83)"
            if e > 0 and (nx != x or ny != y):
                moves.append((x, y, nx, ny, e))
            x, y = nx, ny
    return moves


def run_two_sided(api: httpx.Client, sim: Sim, mesh: Path, misalignment: tuple[float, float, float]
                  ) -> tuple[str, dict[str, Any], list[httpx.Response], list[dict[str, Any]]]:
    """A whole two-sided job: returns its id, its design.json, the align answers and its deposits."""
    first_segment = len(sim.segments())
    job = submit(api, mesh, start=True)
    wait_for(api, job, "awaiting_flip", timeout=60)
    design = api.get(f"/jobs/{job}/files/design.json").json()
    assert design["registration_marks"], "a two-sided design has registration marks"
    # the harness's daemons compile with [design] predict = false: no deploy stage, no deployed files
    assert "deployed" not in design["report"] and "deploy" not in design["report"]["timings_s"]
    assert api.get(f"/jobs/{job}/files/deployed.obj").status_code == 404
    answers = flip_and_align(api, sim, job, design["registration_marks"], misalignment)
    wait_for(api, job, "done", timeout=60)
    return job, design, answers, sim.segments()[first_segment:]


# ---------------------------------------------------------------------------------- the shared daemon


def test_full_two_sided_job(api: httpx.Client, shared_sim: Sim, meshes: dict[str, Path]) -> None:
    """A full two-sided job: compile, heat, front, flip, alignment, back, done."""
    job, design, answers, segments = run_two_sided(api, shared_sim, meshes["two_sided"], MISALIGNMENT)

    marks = len(design["registration_marks"])
    assert [r.status_code for r in answers] == [200] * marks, [r.text for r in answers]
    for i, r in enumerate(answers[:-1]):
        assert r.json()["mark"] == i + 1 and r.json()["next_mark"] == i + 2          # numbered from 1
    last = answers[-1].json()
    assert last["next_mark"] is None and last["accepted"] is True
    assert last["fit"]["rotation_deg"] == pytest.approx(MISALIGNMENT[2], abs=1e-6)
    assert last["fit"]["max_residual_mm"] < 1e-6

    record = api.get(f"/jobs/{job}").json()
    assert record["state"] == "done"
    assert record["error"] is None
    assert record["side"] == "back"
    assert record["correction"] is not None
    assert record["checkpoint"] == "back_done"
    assert record["lines_total"] is not None and record["last_acked_line"] == record["lines_total"]

    transitions = api.get(f"/jobs/{job}/transitions").json()
    assert states(transitions) == FULL_FLOW
    assert_chained(transitions)
    assert transitions[0]["at"] == pytest.approx(record["created"])
    assert transitions[-1]["at"] <= record["updated"]

    assert {s["side"] for s in segments} == {"front", "back"}
    # The corrected back program was kept with the job and can be fetched.
    back = api.get(f"/jobs/{job}/files/back-corrected.gcode")
    assert back.status_code == 200 and ";SIDE:back" in back.text


def test_back_side_lands_where_the_design_puts_it(api: httpx.Client, shared_sim: Sim,
                                                 meshes: dict[str, Path]) -> None:
    """The back side lands where the design puts it within 0.1 mm after a flip with a known offset
    and rotation: every deposit, in fabric coordinates, lies within w_r/2 + 0.1 mm of a ribbon
    centerline of its side."""
    job, design, answers, segments = run_two_sided(api, shared_sim, meshes["two_sided"], MISALIGNMENT)
    assert all(r.status_code == 200 for r in answers)
    half = design["parameters"]["ribbon_width"] / 2
    ribbons = {side: [np.asarray(r["points"], dtype=float) for r in design["ribbons"] if r["side"] == side]
               for side in ("front", "back")}
    assert ribbons["front"] and ribbons["back"]
    marks = np.asarray(design["registration_marks"], dtype=float)

    back = [s for s in segments if s["side"] == "back"]
    front = [s for s in segments if s["side"] == "front"]
    assert len(back) > 100 and len(front) > 10

    # The back side: its deposits in fabric coordinates, against the back ribbons.
    q = deposit_points(back)
    d = distance_to_polylines(q, ribbons["back"])
    assert d.max() <= half + TOLERANCE, (
        f"{int((d > half + TOLERANCE).sum())} of {len(d)} back deposit points are more than "
        f"w_r/2 + {TOLERANCE} = {half + TOLERANCE:.2f} mm off the back ribbons (worst {d.max():.3f} mm)")
    # Every back ribbon received deposits along it (nothing missing).
    for i, line in enumerate(ribbons["back"]):
        near = distance_to_polylines(line, [q]) if len(q) > 1 else np.array([np.inf])
        assert np.median(near) < half + TOLERANCE, f"back ribbon {i} has no deposits along it"

    # Sanity: the check can fail. Had the back program not been corrected, the head would have gone
    # to the mirrored design positions, and the misaligned frame would have put them here:
    frame = Frame(FrameConfig(center=CENTER, flip_axis="y"))
    frame.pose = FramePose("back", MISALIGNMENT[:2], MISALIGNMENT[2])
    uncorrected_machine = np.column_stack([2 * CENTER[0] - q[:, 0], q[:, 1]])
    wrong = distance_to_polylines(frame.to_fabric(uncorrected_machine), ribbons["back"])
    assert (wrong > half + TOLERANCE).any(), "this test could not tell a wrong alignment from a right one"
    # ...and the machine coordinates really were corrected: they differ from the plain mirror image.
    machine = deposit_points(back, fabric=False)
    assert np.abs(machine - uncorrected_machine).max() > 0.5

    # Tighter: move by move, each back deposit lies within 0.1 mm of where the uncorrected back
    # program (the design mirrored for the back side) puts it on the fabric; uncorrected, none would.
    planned = np.array(program_deposits(api.get(f"/jobs/{job}/files/back.gcode").text))
    assert planned.shape == (len(back), 5), f"{len(back)} back deposits for {len(planned)} extruding moves"
    planned_fabric = planned[:, :4].copy()
    planned_fabric[:, [0, 2]] = 2 * CENTER[0] - planned_fabric[:, [0, 2]]
    landed = np.array([[s["fx0"], s["fy0"], s["fx1"], s["fy1"]] for s in back])
    off = np.hypot(*(landed - planned_fabric).reshape(-1, 2, 2).transpose(2, 0, 1))
    assert off.max() <= TOLERANCE, f"back deposits up to {off.max():.3f} mm from where the design puts them"
    uncorrected = np.concatenate([frame.to_fabric(planned[:, 0:2]), frame.to_fabric(planned[:, 2:4])], axis=1)
    off_uncorrected = np.hypot(*(uncorrected - planned_fabric).reshape(-1, 2, 2).transpose(2, 0, 1))
    assert off_uncorrected.min() > TOLERANCE
    np.testing.assert_allclose([s["e"] for s in back], planned[:, 4], atol=1e-4)

    # The front side (frame front up, no misalignment): on the front ribbons or on a registration mark.
    p = deposit_points(front)
    on_mark = np.hypot(*(p[:, None, :] - marks[None]).transpose(2, 0, 1)).min(axis=1) <= 3.0
    assert on_mark.any() and (~on_mark).sum() > 30
    d_front = distance_to_polylines(p[~on_mark], ribbons["front"])
    assert d_front.max() <= half + TOLERANCE, (
        f"front deposits up to {d_front.max():.3f} mm off the front ribbons (limit {half + TOLERANCE:.2f})")
    np.testing.assert_allclose(deposit_points(front, fabric=False), p, atol=1e-9)


def test_alignment_beyond_tolerance_is_refused(api: httpx.Client, shared_sim: Sim,
                                               meshes: dict[str, Path]) -> None:
    """An alignment beyond tolerance is refused: a 5° rotation (the profile allows 2°) answers 409
    naming the rotation and the limit. The job stays aligning (the frame is back side up already:
    re-seat it, do not turn it over again), every mark to measure again (the frame sits wrong, so
    none is kept); the refusal is the job's error until the operator measures again; seated again
    properly, it is aligned and printed."""
    job = submit(api, meshes["two_sided"], start=True)
    wait_for(api, job, "awaiting_flip", timeout=60)
    marks = api.get(f"/jobs/{job}/files/design.json").json()["registration_marks"]

    answers = flip_and_align(api, shared_sim, job, marks, (0.3, -0.2, 5.0))
    assert [r.status_code for r in answers[:-1]] == [200] * (len(marks) - 1)
    refused = answers[-1]
    assert refused.status_code == 409, refused.text
    body = refused.json()
    assert body["refused"] == "rotation"
    assert body["value"] == pytest.approx(5.0, abs=1e-6)
    assert body["limit"] == pytest.approx(2.0)
    assert "turned by 5.00°" in body["detail"] and "limit 2.00°" in body["detail"], body["detail"]

    record = wait_for(api, job, "aligning", timeout=30, until=lambda j: j["waits_for_operator"])
    assert body["detail"] in record["error"]
    assert record["alignment"] == {"marks": len(marks), "kept": [], "remeasure": list(range(1, len(marks) + 1))}
    words = record["next"]["instruction"]
    assert "Re-seat the frame, back side up (do not turn it over again); every mark is measured again" in words
    assert "turn the frame over about" not in words.lower() and "flip-done" not in words, words
    assert "mark 1 of" in words, words
    transitions = api.get(f"/jobs/{job}/transitions").json()
    assert states(transitions)[-2:] == ["awaiting_flip", "aligning"]
    # The frame is not to be turned over again.
    r = api.post(f"/jobs/{job}/flip-done")
    assert r.status_code == 409 and r.json()["state"] == "aligning"

    # The operator takes the frame out and seats it better, back side up.
    shared_sim.flip()
    assert shared_sim.side == "front"
    dx, dy, rot = (-0.5, 0.3, -0.6)
    assert shared_sim.flip(dx, dy, rot)["side"] == "back"
    jogs = operator_jogs(marks, dx, dy, rot)
    answers = [api.post(f"/jobs/{job}/align", json={"mark": 1, "jog": list(jogs[0])})]
    assert api.get(f"/jobs/{job}").json()["error"] is None, "the refusal is cleared once they measure again"
    answers += [api.post(f"/jobs/{job}/align", json={"mark": i + 1, "jog": list(jog)})
                for i, jog in enumerate(jogs) if i > 0]
    assert [r.status_code for r in answers] == [200] * len(marks), [r.text for r in answers]
    assert answers[-1].json()["fit"]["rotation_deg"] == pytest.approx(-0.6, abs=1e-6)
    record = wait_for(api, job, "done", timeout=60)
    assert record["error"] is None
    transitions = api.get(f"/jobs/{job}/transitions").json()
    assert states(transitions) == FULL_FLOW
    assert_chained(transitions)


def test_cancel_while_awaiting_flip_turns_the_heaters_off(api: httpx.Client, shared_sim: Sim,
                                                        meshes: dict[str, Path]) -> None:
    job = submit(api, meshes["two_sided"], start=True)
    wait_for(api, job, "awaiting_flip", timeout=60)
    before = len(shared_sim.commands())
    r = api.post(f"/jobs/{job}/cancel")
    assert r.status_code == 200, r.text
    wait_for(api, job, "cancelled", timeout=30)
    after = [c["command"] for c in shared_sim.commands()[before:]]
    assert "M104 S0" in after, after


def test_pause_and_resume(api: httpx.Client, shared_sim: Sim, meshes: dict[str, Path]) -> None:
    """Pause while printing the front: the printer gets no more program lines; resume: the front
    is completed, each extruding move exactly once."""
    first_segment = len(shared_sim.segments())
    job = submit(api, meshes["one_sided"], start=True)
    wait_for(api, job, "printing_front", timeout=60, poll=0.02)

    r = api.post(f"/jobs/{job}/pause")
    assert r.status_code == 200, r.text
    paused = r.json()
    assert paused["state"] == "paused" and paused["paused_from"] == "printing_front"
    assert paused["last_acked_line"] < paused["lines_total"] - 100, "the pause came too late to test"

    # The queue has drained (the pause waited for M400) and the head is parked: nothing more comes.
    executed = len(shared_sim.program_commands())
    acked = api.get(f"/jobs/{job}").json()["last_acked_line"]
    time.sleep(1.0)
    assert len(shared_sim.program_commands()) == executed, "the printer kept receiving lines while paused"
    record = api.get(f"/jobs/{job}").json()
    assert record["state"] == "paused" and record["last_acked_line"] == acked

    # Pausing twice or flipping now are refused with the state and what it allows.
    r = api.post(f"/jobs/{job}/pause")
    assert r.status_code == 409
    assert r.json()["state"] == "paused"
    assert r.json()["allowed"] == ["resume", "cancel"]
    assert r.json()["detail"] == "cannot pause: the job is paused; possible now: resume, cancel"

    r = api.post(f"/jobs/{job}/resume")
    assert r.status_code == 200, r.text
    assert r.json()["state"] == "printing_front" and r.json()["paused_from"] is None
    wait_for(api, job, "done", timeout=60)

    transitions = api.get(f"/jobs/{job}/transitions").json()
    assert states(transitions) == ["submitted", "compiling", "ready", "heating", "printing_front", "paused",
                                   "printing_front", "done"]
    assert_chained(transitions)

    # What was deposited is the front program's extruding moves, in order, each once: the resume
    # went back to where the head was and went on with the next line.
    front = api.get(f"/jobs/{job}/files/front.gcode").text
    expected = np.array(program_deposits(front))
    segments = shared_sim.segments()[first_segment:]
    got = np.array([[s["x0"], s["y0"], s["x1"], s["y1"], s["e"]] for s in segments])
    assert {s["side"] for s in segments} == {"front"}
    assert got.shape == expected.shape, f"{len(got)} deposits for {len(expected)} extruding moves"
    # The head returns to the position M114 reported, which Marlin rounds to 0.01 mm: the first move
    # after the resume may start up to 5 µm from where the last one ended.
    np.testing.assert_allclose(got[:, :4], expected[:, :4], atol=6e-3)
    np.testing.assert_allclose(got[:, 4], expected[:, 4], atol=1e-5)
    assert got[:, 4].sum() == pytest.approx(expected[:, 4].sum(), rel=1e-3)


def test_cancel_while_printing(api: httpx.Client, shared_sim: Sim, meshes: dict[str, Path]) -> None:
    """Cancel while printing: the job ends cancelled, the heaters are turned off and the head lifted;
    a request the cancelled job does not allow answers 409 with its state and what is allowed."""
    job = submit(api, meshes["one_sided"], start=True)
    wait_for(api, job, "printing_front", timeout=60, poll=0.02, until=lambda j: j["last_acked_line"] > 50)
    before = len(shared_sim.commands())
    r = api.post(f"/jobs/{job}/cancel")
    assert r.status_code == 200, r.text
    record = wait_for(api, job, "cancelled", timeout=30)
    assert record["last_acked_line"] < record["lines_total"] - 1, "the program ran to its end"

    after = [c["command"] for c in shared_sim.commands()[before:]]
    profile = load_profile("ultimaker2-tpu")
    safe_stop = ["M104 S0", "M140 S0", "M107", "G91", f"G0 Z{profile.park_lift:.3f} F{profile.motion.z_speed * 60:.0f}",
                 "G90", "M400", "M84"]
    at = next((i for i in range(len(after)) if after[i:i + len(safe_stop)] == safe_stop), None)
    assert at is not None, f"no heaters-off-and-lift sequence after the cancel: {after[-20:]}"
    assert "M104 S0" not in after[:at], "the program's own end ran: the cancel came too late to test"
    lift = after[at + 4].split()
    assert after[at + 3] == "G91" and float(next(w[1:] for w in lift if w[0] == "Z")) > 0

    transitions = api.get(f"/jobs/{job}/transitions").json()
    assert states(transitions)[-2:] == ["printing_front", "cancelled"]
    assert transitions[-1]["reason"] == "cancelled by the operator"

    for action in ("resume", "pause", "cancel", "flip-done"):
        r = api.post(f"/jobs/{job}/{action}")
        assert r.status_code == 409, (action, r.text)
        body = r.json()
        assert body["state"] == "cancelled" and body["allowed"] == ["start", "delete"], (action, body)
        assert body["detail"] == f"cannot {action}: the job is cancelled; possible now: start, delete"
    assert api.post("/jobs/000000000000/resume").status_code == 404


def test_two_submissions_at_once(api: httpx.Client, shared_daemon: Daemon, meshes: dict[str, Path]) -> None:
    """Two submissions at once both compile and queue: the second waits in ready until the first
    is done, then prints."""
    barrier = threading.Barrier(2)
    ids: list[str | None] = [None, None]
    errors: list[BaseException] = []

    def post(slot: int) -> None:
        try:
            with httpx.Client(base_url=shared_daemon.url, timeout=60) as client:
                barrier.wait(10)
                ids[slot] = submit(client, meshes["one_sided"], start=True)
        except BaseException as exc:  # noqa: BLE001 - reported below
            errors.append(exc)

    threads = [threading.Thread(target=post, args=(i,)) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    assert not errors, errors
    assert ids[0] and ids[1] and ids[0] != ids[1]
    jobs = [wait_for(api, job, "done", timeout=90) for job in ids if job]

    history = {j["id"]: {t["to_state"]: t["at"] for t in api.get(f"/jobs/{j['id']}/transitions").json()}
               for j in jobs}
    for j in jobs:
        assert states(api.get(f"/jobs/{j['id']}/transitions").json()) == [
            "submitted", "compiling", "ready", "heating", "printing_front", "done"]
        folder = Path(j["design_dir"])
        assert folder.is_dir() and (folder / "design.json").is_file() and (folder / "front.gcode").is_file()
        assert api.get(f"/jobs/{j['id']}/files/design.json").status_code == 200
    first, second = sorted(history.values(), key=lambda h: h["heating"])
    # One printer: the second job heats only once the first is done. (Its compile, ~2 s, normally
    # ends while the first job heats and prints, ~4.5 s, so it waited in ready meanwhile.)
    assert second["heating"] >= first["done"], "both jobs held the printer at once"
    assert first["ready"] <= first["heating"] and second["ready"] <= second["heating"]


# ---------------------------------------------------------------------------------- own daemons


@pytest.mark.timeout(150)
def test_daemon_killed_mid_print_and_restarted(tmp_path: Path, meshes: dict[str, Path]) -> None:
    """The daemon killed mid-print and started again shows the job interrupted with its last
    acknowledged line, and nothing in the store is lost."""
    with own_printer(tmp_path / "state") as (sim, daemon):
        assert daemon.client is not None
        other = submit(daemon.client, meshes["two_sided"], start=False)
        wait_for(daemon.client, other, "ready", timeout=60)
        job = submit(daemon.client, meshes["one_sided"], start=True)
        seen = wait_for(daemon.client, job, "printing_front", timeout=60, poll=0.02,
                        until=lambda j: j["last_acked_line"] > 50)
        before = {j["id"]: j for j in daemon.client.get("/jobs").json()}
        transitions_before = daemon.client.get(f"/jobs/{job}/transitions").json()
        daemon.kill()

        daemon.start()                                  # same state directory, same printer port
        client = daemon.client
        assert client is not None
        record = client.get(f"/jobs/{job}").json()
        assert record["state"] == "interrupted"
        assert record["last_acked_line"] >= seen["last_acked_line"] > 0
        assert record["last_acked_line"] < record["lines_total"]
        assert "daemon stopped" in record["error"]
        for key in ("created", "mesh_name", "mesh_path", "parameters", "design_dir", "lines_total", "side"):
            assert record[key] == before[job][key], key

        transitions = client.get(f"/jobs/{job}/transitions").json()
        assert transitions[:-1] == transitions_before
        assert states(transitions) == ["submitted", "compiling", "ready", "heating", "printing_front",
                                       "interrupted"]
        assert_chained(transitions)

        jobs = {j["id"]: j for j in client.get("/jobs").json()}
        assert set(jobs) == {job, other}
        assert jobs[other] == before[other]              # untouched: still ready, not started
        assert Path(jobs[other]["design_dir"], "design.json").is_file()
        assert client.get(f"/jobs/{other}/files/front.gcode").status_code == 200

        # The new daemon reconnects to the printer that kept running.
        daemon.wait_printer()
        # What the interrupted job allows: resume (issue 16), start again, cancel, delete; the ready
        # job: start, cancel, delete.
        r = client.post(f"/jobs/{job}/pause")
        assert r.status_code == 409 and r.json()["state"] == "interrupted"
        assert r.json()["allowed"] == ["resume", "start", "cancel", "delete"]
        r = client.post(f"/jobs/{other}/pause")
        assert r.status_code == 409
        assert r.json()["state"] == "ready" and r.json()["allowed"] == ["start", "cancel", "delete"]
        r = client.post(f"/jobs/{job}/cancel")
        assert r.status_code == 200 and r.json()["state"] == "cancelled"


def test_api_token_and_upload_limit(tmp_path: Path, meshes: dict[str, Path]) -> None:
    """With a token configured, requests without it or with a wrong one answer 401, with it 200;
    an upload over limits.max_upload_mb answers 413."""
    daemon = Daemon(tmp_path / "state", str(tmp_path / "no-printer-here"), api='token = "secret-token"',
                    extra="[limits]\nmax_upload_mb = 0.01\n", token="secret-token")
    try:
        daemon.start()
        assert daemon.client is not None
        url = daemon.url
        for headers in ({}, {"Authorization": "Bearer wrong-token"}, {"Authorization": "secret-token"},
                        {"Authorization": "Basic secret-token"}):
            r = httpx.get(f"{url}/jobs", headers=headers)
            assert r.status_code == 401, headers
            assert r.headers.get("www-authenticate") == "Bearer"
        assert httpx.post(f"{url}/jobs/x/cancel").status_code == 401
        assert httpx.get(f"{url}/printer").status_code == 401
        r = httpx.get(f"{url}/jobs", headers={"Authorization": "Bearer secret-token"})
        assert r.status_code == 200 and r.json() == []
        assert daemon.client.get("/printer").status_code == 200
        assert httpx.get(f"{url}/openapi.json").status_code == 200      # the documentation is open

        limit = int(0.01 * 1024 * 1024)
        big = tmp_path / "big.obj"
        big.write_bytes(meshes["two_sided"].read_bytes()[: limit // 2] + b"#" * limit + b"\n")
        with big.open("rb") as handle:
            r = daemon.client.post("/jobs", files={"mesh": ("big.obj", handle)}, data={"start": "false"})
        assert r.status_code == 413, r.text
        assert "limit" in r.json()["detail"]

        # Without a Content-Length (chunked), the limit holds while the upload is read.
        boundary = "ribbond-e2e-boundary"
        head = (f'--{boundary}\r\nContent-Disposition: form-data; name="mesh"; filename="big.obj"\r\n'
                "Content-Type: application/octet-stream\r\n\r\n").encode()
        tail = f"\r\n--{boundary}--\r\n".encode()

        def chunks() -> Any:
            yield head
            data = big.read_bytes()
            for i in range(0, len(data), 4096):
                yield data[i:i + 4096]
            yield tail

        r = daemon.client.post("/jobs", content=chunks(),
                               headers={"Content-Type": f"multipart/form-data; boundary={boundary}"})
        assert r.status_code == 413, r.text
        # Nothing of the refused uploads is kept, and no job was made.
        uploads = daemon.state_dir / "uploads"
        assert not uploads.exists() or not any(uploads.iterdir())
        assert daemon.client.get("/jobs").json() == []
        # A small upload passes the limit (the design itself is not needed here).
        small = tmp_path / "small.obj"
        small.write_bytes(b"v 0 0 0\nv 10 0 0\nv 0 10 1\nv 10 10 0\nf 1 2 3\nf 2 4 3\n")   # two faces: intake's least
        job = submit(daemon.client, small, start=False, parameters=PARAMETERS)
        assert daemon.client.get(f"/jobs/{job}").status_code == 200
    finally:
        daemon.stop()
