"""The resume soak test (issue 16): a two-sided job on the simulator, the daemon SIGKILLed at random
moments of the front and the back and resumed each time (skipping the ribbon begun), until done.

The simulator is its own process and outlives every daemon, as a printer does. At the end, counted
move by move from the simulator's executed extrusions against the programs' own moves: every part
(ribbon, registration mark) printed exactly once, except at most one per kill, which the operator
skipped and which was printed partly (never a move twice); the parts the store calls done were
printed completely; and the store passes ``PRAGMA integrity_check``.

The kill moments come from a seeded generator; the seed is printed (``RIBBOND_SOAK_SEED`` sets it).
"""

from __future__ import annotations

import os
import random
import time
from pathlib import Path
from typing import Any

import httpx
import pytest

from .conftest import Sim, frame_ready, own_printer, submit
from .deposits import executed, integrity, outcome, part_events, program_parts
from .test_daemon_e2e import operator_jogs
from .test_resume import restart

pytestmark = pytest.mark.timeout(300)

KILLS = 5
MISALIGNMENT = (0.3, 0.2, -0.4)
#: The soak gives up after this long (the machine is shared; a normal run takes about a minute).
BUDGET_S = 240.0


class Operator:
    """Does what the job asks for: the flip, the marks, the frame check after a resume."""

    def __init__(self, sim: Sim, job: str) -> None:
        self.sim, self.job = sim, job
        self.back_programs: set[str] = set()

    def act(self, api: httpx.Client, j: dict[str, Any], state_dir: Path) -> None:
        s = j["state"]
        if s == "awaiting_flip":
            if self.sim.side == "front":
                self.sim.flip(*MISALIGNMENT[:2], MISALIGNMENT[2])
            api.post(f"/jobs/{self.job}/flip-done")
        elif s == "aligning" and j["waits_for_operator"]:
            marks = api.get(f"/jobs/{self.job}/files/design.json").json()["registration_marks"]
            for i, jog in enumerate(operator_jogs(marks, *MISALIGNMENT)):
                r = api.post(f"/jobs/{self.job}/align", json={"mark": i + 1, "jog": list(jog)})
                assert r.status_code == 200, r.text
        elif s == "awaiting_check" and j["waits_for_operator"]:
            back = "back side up" in j["next"]["instruction"]
            if back and self.sim.side == "front":
                self.sim.flip(*MISALIGNMENT[:2], MISALIGNMENT[2])
            keep = "--keep-alignment" in j["next"]["instruction"]     # the frame was not moved
            r = api.post(f"/jobs/{self.job}/frame-ok", json={"keep_alignment": keep})
            assert r.status_code == 200, r.text
        elif s == "printing_back":
            path = state_dir / "jobs" / self.job / "back-corrected.gcode"
            if path.is_file():
                self.back_programs.add(path.read_text(encoding="utf-8"))


@pytest.mark.timing
def test_killed_at_random_and_resumed_every_part_printed_once(tmp_path: Path, meshes: dict[str, Path]) -> None:
    seed = int(os.environ.get("RIBBOND_SOAK_SEED", random.randrange(1 << 30)))
    print(f"resume soak: seed {seed} (RIBBOND_SOAK_SEED={seed} repeats it)")
    rng = random.Random(seed)
    started = time.monotonic()
    kills: list[tuple[str, int, int]] = []
    with own_printer(tmp_path / "state") as (sim, daemon):
        api = daemon.client
        assert api is not None
        frame_ready(api)                         # a fresh frame loaded: the job prints at once
        job = submit(api, meshes["two_sided"], start=True)
        operator = Operator(sim, job)
        target: int | None = None
        drawn_for: tuple[str, int] | None = None
        base = 0
        while True:
            assert time.monotonic() - started < BUDGET_S, f"seed {seed}: not done in {BUDGET_S:.0f} s; kills {kills}"
            j = api.get(f"/jobs/{job}").json()
            if j["state"] == "done":
                break
            assert j["state"] not in ("failed", "cancelled"), (seed, j)
            if j["state"] == "interrupted":
                r = api.post(f"/jobs/{job}/resume", json={"partial": "skip"})
                assert r.status_code == 200, (seed, r.text)
                continue
            streaming = j["state"] in ("printing_front", "printing_back") and j["lines_total"]
            if streaming and len(kills) < KILLS:
                # Counted by the printer, not by the job's status: its acknowledged line is saved
                # every 0.5 s, and a short resumed program can stream to its end between two saves.
                # Drawn anew for each program (a new line count or side; right after a state change
                # the status can still show the last program's count).
                total, executed_now = j["lines_total"], sim.request({"cmd": "stats"})["stats"]["commands_executed"]
                if target is None or drawn_for != (j["state"], total):
                    base, drawn_for = executed_now, (j["state"], total)
                    target = rng.randint(1, max(2, int(total * 0.8)))
                if executed_now - base >= target:
                    daemon.kill()
                    kills.append((j["state"], executed_now - base, total))
                    target = None
                    api = restart(daemon, sim)
                    assert api.get(f"/jobs/{job}").json()["state"] == "interrupted"
                    continue
            operator.act(api, j, daemon.state_dir)
            time.sleep(0.005)
        print(f"resume soak: seed {seed}, kills (state, lines executed of the program, its lines): {kills}, "
              f"{time.monotonic() - started:.0f} s")
        design_dir = Path(api.get(f"/jobs/{job}").json()["design_dir"])
        states = [t["to_state"] for t in api.get(f"/jobs/{job}/transitions").json()]
        daemon.stop()

        db = daemon.state_dir / "jobs.sqlite3"
        assert integrity(db) == "ok"
        # A kill in the back's last part leaves nothing to print once that begun part is skipped: the
        # job is done on its resume (interrupted -> done) before the soak can kill it again.
        nothing_left = states[-2:] == ["interrupted", "done"]
        assert len(kills) == KILLS or nothing_left, \
            f"seed {seed}: the job ended after {len(kills)} kills: {states[-8:]}"
        assert len(operator.back_programs) == 1, "the back's corrected program changed between runs"
        events = part_events(db, job)
        assert {e["run"] for e in events} == {1}
        segments = sim.segments()
        skipped_total = 0
        sides = (("front", (design_dir / "front.gcode").read_text(encoding="utf-8")),
                 ("back", next(iter(operator.back_programs))))
        for side, text in sides:
            parts = program_parts(text)
            done = executed(segments, side)
            result = {i: outcome(p, done) for i, p in enumerate(parts)}
            skipped = {e["part"] for e in events if e["side"] == side and e["event"] == "skipped"}
            proven = {e["part"] for e in events if e["side"] == side and e["event"] == "done"}
            skipped_total += len(skipped)
            assert "over" not in result.values(), f"seed {seed}: {side}: a move printed twice: {result}"
            assert {i for i, o in result.items() if o != "full"} <= skipped, (seed, side, result, skipped)
            assert all(result[i] == "full" for i in proven), (seed, side, result, proven)
            assert proven | skipped == set(result), (seed, side, proven, skipped)
            ribbons = [i for i, p in enumerate(parts) if p.kind == "RIBBON"]
            assert ribbons and sum(result[i] == "full" for i in ribbons) >= len(ribbons) - len(skipped)
        assert skipped_total <= len(kills), (seed, skipped_total, kills)
