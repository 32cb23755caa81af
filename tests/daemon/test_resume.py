"""Resuming an interrupted print (issue 16), end to end: a real simulator on its pty (it outlives the
daemon, as a printer does), real ribbond processes killed with SIGKILL, real HTTP.

What was printed is what the simulator executed: its deposited segments, counted move by move
against the programs' own extruding moves (``deposits.py``); what was proven is the store's part
events. Nothing is compared with an earlier run.
"""

from __future__ import annotations

import json
import sqlite3
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import httpx
import pytest

from ribbond.daemon.jobs import JobState
from ribbond.daemon.store import SCHEMA_VERSION, JobStore
from ribbond.printer import Capabilities, PrinterLink, Timeouts
from sim import FaultConfig

from ..conftest import HOST_COMMANDS as LINK_COMMANDS
from ..conftest import moves
from .conftest import HOST_COMMANDS, ROOT, Daemon, Sim, own_printer, submit, wait_for
from .deposits import executed, integrity, outcome, part_events, program_parts
from .test_daemon_e2e import flip_and_align

pytestmark = pytest.mark.timeout(240)

MISALIGNMENT = (0.4, -0.3, 0.5)


def kill_at(daemon: Daemon, job: str, state: str, line: int) -> dict[str, Any]:
    """SIGKILL the daemon once ``job`` is in ``state`` with ``line`` program lines acknowledged."""
    assert daemon.client is not None
    seen = wait_for(daemon.client, job, state, timeout=120, poll=0.01, until=lambda j: j["last_acked_line"] >= line)
    daemon.kill()
    return seen


def restart(daemon: Daemon, sim: Sim) -> httpx.Client:
    """Start the daemon again; the printer it connects to is cold (whatever it kept running)."""
    before = len(sim.commands())
    daemon.start()
    daemon.wait_printer()
    assert daemon.client is not None
    deadline = time.monotonic() + 10
    while True:
        after = [c["command"] for c in sim.commands()[before:]]
        if "M104 S0" in after and "M140 S0" in after:
            break
        assert time.monotonic() < deadline, f"no heaters off after the restart: {after[:12]}"
        time.sleep(0.05)
    heaters = daemon.client.get("/printer", params={"refresh": "true"}).json()["heaters"]
    assert all(not (h.get("target") or 0) for h in heaters.values()), heaters
    return daemon.client


def ribbonctl(daemon: Daemon, *args: str) -> dict[str, Any]:
    proc = subprocess.run([sys.executable, "-m", "ribbond.client.cli", *args, "--url", daemon.url, "--json"], cwd=ROOT,
                          text=True, capture_output=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return dict(json.loads(proc.stdout))


def resume(api: httpx.Client, job: str, partial: str | None, keep: bool = False,
           daemon: Daemon | None = None) -> dict[str, Any]:
    """Resume (through the API, or with ribbonctl when ``daemon`` is given), check the frame, go on."""
    if daemon is not None:
        answer = ribbonctl(daemon, "resume", job, *(["--partial", partial] if partial else []))
    else:
        r = api.post(f"/jobs/{job}/resume", json={"partial": partial} if partial else None)
        assert r.status_code == 200, r.text
        answer = r.json()
    assert answer["state"] == "awaiting_check"
    checked = wait_for(api, job, "awaiting_check", timeout=60, until=lambda j: j["waits_for_operator"],
                       fresh_frame=False)
    assert f"ribbonctl frame-ok {job}" in checked["next"]["instruction"]
    # it prints on its own frame, used by its own first run: the frame check, not frame-ready
    assert "frame-ready" not in checked["next"]["instruction"] and "frame-ready" not in checked["next"]["commands"]
    assert api.get("/printer").json()["frame"]["state"] == "used"
    assert ("--keep-alignment" in checked["next"]["instruction"]) == keep
    # nothing prints before the operator says the frame is in place
    assert api.post(f"/jobs/{job}/resume").status_code == 409
    if daemon is not None:
        return ribbonctl(daemon, "frame-ok", job, *(["--keep-alignment"] if keep else []))
    r = api.post(f"/jobs/{job}/frame-ok", json={"keep_alignment": keep})
    assert r.status_code == 200, r.text
    return dict(r.json())


class Samples:
    """The job's progress as the operator sees it (``GET /jobs/{id}``), sampled while waiting."""

    def __init__(self, job: str) -> None:
        self.job, self.seen = job, []

    def wait(self, api: httpx.Client, states: set[str] | str, until: Any = None, timeout: float = 120) -> dict[str, Any]:
        wanted = {states} if isinstance(states, str) else states
        deadline = time.monotonic() + timeout
        while True:
            j = api.get(f"/jobs/{self.job}").json()
            self.seen.append((j["state"], j["progress"], j.get("program"), j["last_acked_line"], j["lines_total"]))
            if j["state"] in wanted and (until is None or until(j)):
                return dict(j)
            assert time.monotonic() < deadline, f"not {wanted} in {timeout} s: {self.seen[-3:]}"
            time.sleep(0.02)


@pytest.mark.timeout(300)
def test_progress_never_goes_back_through_pause_interruption_and_resume(tmp_path: Path,
                                                                       meshes: dict[str, Path]) -> None:
    """A one-sided print paused, resumed, killed past halfway and resumed where it was proven to
    stand: the job's progress, sampled all along (the restart included), never decreases; the
    resumed program adds to the parts printed before it (it ends at 100 %, not at its own share);
    its lines are named as the resumed program's, by the API and by ``ribbonctl status``."""
    with own_printer(tmp_path / "state") as (sim, daemon):
        api = daemon.client
        assert api is not None
        job = submit(api, meshes["one_sided"], start=True)
        seen = Samples(job)
        record = wait_for(api, job, "printing_front", timeout=120)
        total = record["lines_total"]
        assert record["program"] == "front"
        seen.wait(api, "printing_front", until=lambda j: j["last_acked_line"] >= total // 4)
        assert api.post(f"/jobs/{job}/pause").status_code == 200
        seen.wait(api, "paused", until=lambda j: j["stage"] == "paused (head parked)")
        assert api.post(f"/jobs/{job}/resume").status_code == 200
        before = seen.wait(api, "printing_front", until=lambda j: j["last_acked_line"] >= total * 3 // 5)
        daemon.kill()

        api = restart(daemon, sim)
        stopped = seen.wait(api, "interrupted")
        assert stopped["progress"] >= before["progress"] > 0.5
        r = api.post(f"/jobs/{job}/resume")
        assert r.status_code == 200, r.text
        seen.wait(api, "awaiting_check", until=lambda j: j["waits_for_operator"])
        assert api.post(f"/jobs/{job}/frame-ok").status_code == 200
        resumed = seen.wait(api, "printing_front", until=lambda j: j["last_acked_line"] > 20)
        program = resumed["program"]
        assert program.startswith("front (resumed at part ") and resumed["lines_total"] < total, resumed
        text = ribbonctl_text(daemon, "status", job)
        assert f"{program}: line " in text and f" of {resumed['lines_total']}" in text, text
        seen.wait(api, "done", timeout=150)

    progress = [p for _, p, *_ in seen.seen]
    drops = [(a, b) for a, b in zip(seen.seen, seen.seen[1:]) if b[1] < a[1] - 1e-9]
    assert not drops, f"progress went back: {drops[:3]}"
    states = [s for s, *_ in seen.seen]
    assert {"paused", "interrupted", "awaiting_check", "heating", "printing_front", "done"} <= set(states), set(states)
    # the resumed program adds to what was printed before: above what was shown at the interruption,
    # before its end (not stuck at the floor, not its own share of the side)
    last_resumed = max(p for (s, p, name, *_) in seen.seen if s == "printing_front" and name == program)
    assert last_resumed > stopped["progress"] + 0.05, (last_resumed, stopped["progress"])
    assert progress[-1] == 1.0


def ribbonctl_text(daemon: Daemon, *args: str) -> str:
    proc = subprocess.run([sys.executable, "-m", "ribbond.client.cli", *args, "--url", daemon.url], cwd=ROOT,
                          text=True, capture_output=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


def test_interrupted_front_and_back_resume_after_the_last_proven_part(tmp_path: Path,
                                                                      meshes: dict[str, Path]) -> None:
    """Killed on the front and resumed skipping the part begun, then killed on the back and resumed
    reprinting it (the alignment kept): every part of both sides printed, none twice except the
    reprinted one, no part left partial except the skipped one, each named by the store's events."""
    with own_printer(tmp_path / "state") as (sim, daemon):
        api = daemon.client
        assert api is not None
        job = submit(api, meshes["two_sided"], start=True)
        record = wait_for(api, job, "printing_front", timeout=90)
        front_text = Path(record["design_dir"], "front.gcode").read_text(encoding="utf-8")
        front = program_parts(front_text)
        assert front and all(p.moves for p in front)
        kill_at(daemon, job, "printing_front", record["lines_total"] // 2 if record["lines_total"] else 100)

        api = restart(daemon, sim)
        stopped = api.get(f"/jobs/{job}").json()
        assert stopped["state"] == "interrupted"
        assert f"ribbonctl resume {job}" in stopped["next"]["commands"]
        r = api.post(f"/jobs/{job}/resume", json={"partial": "halfway"})
        assert r.status_code == 422
        assert resume(api, job, "skip")["state"] in ("heating", "printing_front", "awaiting_flip")

        wait_for(api, job, "awaiting_flip", timeout=120)
        marks = api.get(f"/jobs/{job}/files/design.json").json()["registration_marks"]
        answers = flip_and_align(api, sim, job, marks, MISALIGNMENT)
        assert all(a.status_code == 200 for a in answers), [a.text for a in answers]
        record = wait_for(api, job, "printing_back", timeout=60, until=lambda j: j["lines_total"])
        back_text = (daemon.state_dir / "jobs" / job / "back-corrected.gcode").read_text(encoding="utf-8")
        back = program_parts(back_text)
        kill_at(daemon, job, "printing_back", record["lines_total"] * 2 // 5)

        api = restart(daemon, sim)
        resumed = resume(api, job, "reprint", keep=True, daemon=daemon)
        assert resumed["state"] in ("heating", "printing_back", "done")
        done = wait_for(api, job, "done", timeout=150)
        assert done["checkpoint"] == "back_done"
        states = [t["to_state"] for t in api.get(f"/jobs/{job}/transitions").json()]
        assert states.count("interrupted") == 2 and states.count("awaiting_check") == 2
        daemon.stop()

        segments = sim.segments()
        events = part_events(daemon.state_dir / "jobs.sqlite3", job)
        assert integrity(daemon.state_dir / "jobs.sqlite3") == "ok"
        for side, parts, choice in (("front", front, "skipped"), ("back", back, "reprint")):
            done_moves = executed(segments, side)
            result = {i: outcome(p, done_moves) for i, p in enumerate(parts)}
            chosen = {e["part"] for e in events if e["side"] == side and e["event"] == choice}
            assert len(chosen) <= 1, events
            odd = {i for i, o in result.items() if o != "full"}
            assert odd <= chosen, (side, result, chosen)
            expect = {"skipped": {"partial", "none"}, "reprint": {"over"}}[choice]
            assert all(result[i] in expect | {"full"} for i in chosen), (side, result, chosen)
            # a part the store says is done was printed completely
            proven = {e["part"] for e in events if e["side"] == side and e["event"] == "done"}
            assert proven and all(result[i] in ("full", "over") for i in proven), (side, result, proven)
            assert len(proven) >= len(parts) - 1
        # the resumed programs said where they went on, and the printer ran them
        resumed_at = [c["command"] for c in sim.commands() if c["command"].split()[0] not in HOST_COMMANDS]
        # (a side resumed at its first part prints its own program from the start, with no prelude)
        preludes = sum(1 for e in events if e["event"] in ("skipped", "reprint") and e["part"] > 0)
        assert preludes >= 1, "the kill on the front must have left proven parts behind it"
        assert resumed_at.count("G92 E0") >= preludes


@pytest.mark.parametrize("faults", [FaultConfig(), FaultConfig(corrupt_rate=0.03, drop_ok_rate=0.03)],
                         ids=["clean", "faults"])
async def test_a_barrier_line_goes_out_only_after_every_line_before_it_is_acknowledged(make_sim, faults) -> None:
    """The hook the part records rely on: while fewer than k program lines are acknowledged, line k
    has not been sent (so what the host records at that moment precedes it). Without barriers the
    window does send past k early (the check can fail); with them every line still runs once, in order."""
    sim = make_sim(faults)
    # the window of the simulated board (128 bytes), so that it can run past a barrier
    link = PrinterLink(sim.port, sim.config.baud, timeouts=Timeouts(default_s=0.5, probes=4), boot_wait_s=1.0,
                       capabilities=Capabilities(rx_buffer_bytes=sim.config.rx_buffer - 1))
    await link.connect()
    program = moves(400)
    barriers = frozenset(range(20, 400, 37))
    for use in (frozenset(), barriers):
        early: list[tuple[int, int, int]] = []

        def progress(p, use=use) -> None:
            early.extend((k, p.acknowledged, p.sent) for k in barriers if p.acknowledged < k < p.sent)

        before = len(sim.commands())
        await link.stream(program, progress, use)
        ran = [c.command for c in sim.commands()[before:] if c.command.split()[0] not in LINK_COMMANDS]
        assert ran == program
        if use:
            assert early == []
        else:
            assert early, "the window never ran past a barrier line: this test could not fail"
    await link.close()


def test_part_events_per_run_and_a_version_2_database_gains_the_table(tmp_path: Path) -> None:
    """The store's part records: the last event of a part decides, only the current run counts,
    bad input is refused naming it, deleting the job removes them; a schema-2 database is migrated."""
    db = tmp_path / "jobs.sqlite3"
    with JobStore(db) as store:
        job = store.create(mesh_name="m.obj", mesh_path="/m.obj", parameters={}, start_when_ready=False)
    conn = sqlite3.connect(db)                      # as ribbond before issue 16 left it
    # (and before issue 22's notes column, the frame, same_frame, program and print_progress)
    # (and before issue 26's projects)
    conn.executescript("DROP TABLE part_events; DROP TABLE frame; ALTER TABLE jobs DROP COLUMN notes; "
                       "ALTER TABLE jobs DROP COLUMN same_frame; ALTER TABLE jobs DROP COLUMN program; "
                       "ALTER TABLE jobs DROP COLUMN print_progress; DROP INDEX jobs_project; DROP TABLE projects; "
                       "ALTER TABLE jobs DROP COLUMN project; ALTER TABLE jobs DROP COLUMN panel; "
                       "ALTER TABLE jobs DROP COLUMN panels; PRAGMA user_version = 2;")
    conn.close()
    with JobStore(db) as store:
        assert SCHEMA_VERSION == 6
        assert store.get(job.id).notes == []
        assert store.frame()["state"] == "used"          # (schema 5: nothing confirmed yet)
        for part, event in ((0, "started"), (0, "done"), (1, "started"), (1, "reprint"), (1, "started"),
                            (2, "started"), (2, "skipped")):
            store.record_part(job.id, "front", part, event, line=part * 10, durable=part != 1)
        store.record_part(job.id, "back", 0, "started")
        assert store.part_states(job.id, "front") == {0: "done", 1: "started", 2: "skipped"}
        assert store.part_states(job.id, "back") == {0: "started"}
        for bad, match in ((dict(side="top"), "side 'top'"), (dict(part=-1), "part -1"),
                           (dict(event="finished"), "part event 'finished'")):
            args = {"side": "front", "part": 0, "event": "done", **bad}
            with pytest.raises(ValueError, match=match):
                store.record_part(job.id, args["side"], args["part"], args["event"])
        # a new run of the job (start_job appends the ended run to runs): its parts start afresh
        store.update(job.id, runs=[{"run": 1}])
        assert store.part_states(job.id, "front") == {}
        assert [e["run"] for e in store.part_events(job.id)] == [1] * 8
        assert store.integrity() == "ok"
        store.transition(job.id, JobState.CANCELLED)
        store.delete(job.id)
        assert sqlite3.connect(db).execute("SELECT count(*) FROM part_events").fetchone()[0] == 0
