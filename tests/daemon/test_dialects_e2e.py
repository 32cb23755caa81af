"""Every firmware dialect end to end (issue 27, item 1): a real simulator process answering as
Marlin 1.x, Marlin 2.x, Prusa, RepRapFirmware, Smoothieware or Repetier (``--dialect``), a real ribbond
process, HTTP. For each: manual control (home, goto, jog, heat and cool, the printer's own M105 and
M114 readings shown), then a whole two-sided job (front, flip with a misaligned frame, alignment,
back) to ``done``, every extruding move of the back program laid down once, and the printer left cool.

Expectations come from the firmwares' documented answers (the names they give in M115), from the
operator's own numbers (where the head was sent, the temperatures asked for), from the job's
programs and from the simulator's records, never from an earlier run.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from ribbond.gcode.profiles import load_profile
from sim.process import SimProcess

from .conftest import BAUD, ROOT, Daemon, Sim, running, submit, wait_for
from .test_daemon_e2e import FULL_FLOW, operator_jogs, program_deposits

pytestmark = pytest.mark.timeout(240)

#: Each simulator dialect, the start of the FIRMWARE_NAME its firmware prints for M115 (from the
#: firmwares' sources: Marlin's M115, Prusa's and Smoothieware's case 115, RepRapFirmware's
#: GCodes2.cpp, Repetier's Com::tFirmware) and the family ribbond names in its status.
DIALECTS = {
    "marlin1": ("Marlin 1.", "Marlin 1.x"),
    "marlin2": ("Marlin 2.", "Marlin 2.x"),
    "prusa": ("Prusa-Firmware 3.", "Prusa firmware (MK3)"),
    "reprapfirmware": ("RepRapFirmware for Duet", "RepRapFirmware"),
    "smoothieware": ("Smoothieware", "Smoothieware"),
    "repetier": ("Repetier_1.", "Repetier"),
}
#: Faster than the other end-to-end tests (they run at 0.02): heating and moves take less.
TIME_SCALE = 0.01
MISALIGNMENT = (0.4, -0.3, 0.6)
#: The small saddle compiled fast: not refined at intake (864 faces, not 10 000) and without the
#: spacing-integrability phase, still two-sided with registration marks; the compile is ~3 s of CPU
#: instead of ~15, which is what six jobs can afford.
FAST = {"size": {"bbox_diagonal": 70}, "solver": {"refine_below_faces": 0, "spacing_integrability_weight": 0}}
PROFILE = load_profile("ultimaker2-tpu")


class DialectSim(Sim):
    """A simulator process answering as one firmware."""

    def __init__(self, dialect: str) -> None:  # noqa: D107 - Sim's attributes
        self.process = SimProcess(["--time-scale", str(TIME_SCALE), "--baud", str(BAUD), "--dialect", dialect],
                                  cwd=ROOT).start()
        self.port = self.process.port
        self.side = "front"


@pytest.fixture(params=list(DIALECTS))
def printer(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[tuple[str, DialectSim, Daemon]]:
    sim = DialectSim(request.param)
    try:
        with running(tmp_path / "state", sim.port) as daemon:
            yield request.param, sim, daemon
    finally:
        sim.stop()


def post(api: httpx.Client, path: str, body: dict[str, Any] | None = None) -> dict[str, Any]:
    r = api.post(path, json=body) if body is not None else api.post(path)
    assert r.status_code == 200, f"{path}: {r.status_code} {r.text}"
    return dict(r.json())


def heater(status: dict[str, Any], name: str) -> dict[str, Any]:
    assert name in status["heaters"], f"no {name} reading in {status['heaters']}"
    return dict(status["heaters"][name])


def manual_control(api: httpx.Client) -> None:
    """Home, goto, jog: the printer's own M114 report agrees; heat: the M105 readings show the
    targets and a rising nozzle; cool: the targets are 0."""
    assert post(api, "/printer/home")["position"][:3] == [0.0, 0.0, 0.0]
    assert post(api, "/printer/goto", {"x": 60, "y": 70})["position"][:2] == [60.0, 70.0]
    assert post(api, "/printer/jog", {"dx": 1.5, "dy": -2, "dz": 0})["position"][:2] == [61.5, 68.0]
    reported = api.get("/printer", params={"refresh": "true"}).json()
    assert reported["position"][:2] == pytest.approx([61.5, 68.0], abs=1e-3), reported

    nozzle, bed = PROFILE.temperatures.nozzle, 40.0
    status = post(api, "/printer/heat", {"nozzle": nozzle, "bed": bed})
    assert heater(status, "T")["target"] == pytest.approx(nozzle) and heater(status, "B")["target"] == pytest.approx(bed)
    first = heater(status, "T")["current"]
    deadline = time.monotonic() + 20
    while heater(status, "T")["current"] < first + 5:            # readings follow the heating nozzle
        assert time.monotonic() < deadline, f"the nozzle reading stayed at {heater(status, 'T')}"
        time.sleep(0.1)
        status = api.get("/printer", params={"refresh": "true"}).json()
    cooled = post(api, "/printer/cool")
    assert heater(cooled, "T")["target"] == 0.0 and heater(cooled, "B")["target"] == 0.0


def two_sided_job(api: httpx.Client, sim: DialectSim, mesh: Path) -> tuple[str, list[dict[str, Any]]]:
    """Front, flip with a misaligned frame, alignment at every mark, back, done."""
    first = len(sim.segments())
    job = submit(api, mesh, start=True, parameters=FAST)
    wait_for(api, job, "awaiting_flip", timeout=120)
    marks = api.get(f"/jobs/{job}/files/design.json").json()["registration_marks"]
    dx, dy, rot = MISALIGNMENT
    assert sim.flip(dx, dy, rot)["side"] == "back"
    post(api, f"/jobs/{job}/flip-done")
    wait_for(api, job, "aligning", timeout=30)
    answers = [post(api, f"/jobs/{job}/align", {"mark": i + 1, "jog": list(jog)})
               for i, jog in enumerate(operator_jogs(marks, dx, dy, rot))]
    assert answers[-1]["accepted"] and answers[-1]["fit"]["rotation_deg"] == pytest.approx(rot, abs=1e-3)
    wait_for(api, job, "done", timeout=120)
    return job, sim.segments()[first:]


def left_cool(sim: DialectSim) -> None:
    """The last temperatures the printer was given are 0: M104 S0 and M140 S0 after the job."""
    commands = [c["command"].split() for c in sim.commands()]
    last = {word: args for word, *args in commands if word in ("M104", "M109", "M140", "M190")}
    assert last.get("M104") == ["S0"] and last.get("M140") == ["S0"], last


def test_manual_control_and_a_two_sided_job(printer: tuple[str, DialectSim, Daemon],
                                           meshes: dict[str, Path]) -> None:
    dialect, sim, daemon = printer
    api = daemon.client
    assert api is not None
    status = api.get("/printer").json()
    name, family = DIALECTS[dialect]
    assert status["firmware"].startswith(name) and status["dialect"] == family, status

    manual_control(api)
    job, segments = two_sided_job(api, sim, meshes["two_sided"])

    record = api.get(f"/jobs/{job}").json()
    assert [t["to_state"] for t in api.get(f"/jobs/{job}/transitions").json()] == FULL_FLOW
    assert record["error"] is None and record["last_acked_line"] == record["lines_total"]
    back = [s for s in segments if s["side"] == "back"]
    planned = program_deposits(api.get(f"/jobs/{job}/files/back.gcode").text)
    assert len(back) == len(planned), f"{len(back)} back deposits for {len(planned)} extruding moves"
    assert {s["side"] for s in segments} == {"front", "back"}
    left_cool(sim)
    final = api.get("/printer", params={"refresh": "true"}).json()
    assert heater(final, "T")["target"] == 0.0 and heater(final, "B")["target"] == 0.0, final["heaters"]
