"""The console (``POST /printer/gcode``, ``ribbonctl gcode``) checks typed G-code as a plain G-code
job is checked (issue 22, item 2): refused with the command and the limit named, nothing sent (the
simulator executes nothing); accepted commands run, clamped feeds said in the answer. The override
``[manual] raw_console = true`` sends unchecked, logged. Expected values from the profile's frame,
fabric height, temperatures and speeds."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from ribbond.daemon.config import load_config
from ribbond.gcode.profiles import load_profile
from tests.daemon.conftest import ROOT, Daemon, Sim, own_printer

PROFILE = load_profile("ultimaker2-tpu")
X0, Y0, X1, Y1 = PROFILE.frame.bounds
CX, CY = PROFILE.frame.center
FABRIC = PROFILE.layers.fabric_z
SAFE_Z = FABRIC + PROFILE.layers.safe_height
NOZZLE_MAX, BED_MAX = PROFILE.temperatures.nozzle_max, PROFILE.temperatures.bed_max
MAX_Z_F = PROFILE.motion.max_z_speed * 60          # mm/min


def printer_commands(sim: Sim) -> list[str]:
    """What the simulator executed, without the link's own probes (M105, M114, …)."""
    return sim.program_commands()


@pytest.fixture
def at_centre(api: httpx.Client) -> httpx.Client:
    """The head homed, then above the frame's centre at the safe height: its position known."""
    assert api.post("/printer/home").status_code == 200
    r = api.post("/printer/goto", json={"x": CX, "y": CY})
    assert r.status_code == 200 and r.json()["position"] == pytest.approx([CX, CY, SAFE_Z]), r.text
    return api


# (typed commands, the command refused (1-based), words of the reason) -- from the centre at SAFE_Z
REFUSED = [
    (["G1 Z-2 F600", "G1 X500 Y-50 F9000", "M400"], 1, f"below the fabric (z {FABRIC:g} mm)"),
    (["M400", "G1 X500 Y-50 F9000"], 2, f"outside the frame (x {X0:g} to {X1:g}, y {Y0:g} to {Y1:g} mm)"),
    ([f"G1 X{X0 - 0.5:g}"], 1, "outside the frame"),
    ([f"G1 X{X1 + 0.5:g}"], 1, "outside the frame"),
    ([f"G1 Y{Y0 - 0.5:g}"], 1, "outside the frame"),
    ([f"G1 Y{Y1 + 0.5:g}"], 1, "outside the frame"),
    (["G91", "G1 Z-1", f"G1 Z-{PROFILE.layers.safe_height:g}"], 3, "below the fabric"),
    (["G91", f"G1 X{X1 - CX + 1:g}"], 2, "outside the frame"),
    (["G1Z-2"], 1, "below the fabric"),
    ([f"M104 S{NOZZLE_MAX + 140:g}"], 1, f"nozzle_max ({NOZZLE_MAX:g} °C)"),
    ([f"M109 S{NOZZLE_MAX + 140:g}"], 1, "nozzle_max"),
    ([f"M109 R{NOZZLE_MAX + 1:g}"], 1, "nozzle_max"),
    ([f"M140 S{BED_MAX + 1:g}"], 1, f"bed_max ({BED_MAX:g} °C)"),
    ([f"M190 S{BED_MAX + 1:g}"], 1, "bed_max"),
    (["M104 S200", f"M190 R{BED_MAX + 1:g}"], 2, "bed_max"),
    (["G29"], 1, "not a command the check follows"),
    (["G92 Z10"], 1, "G92"),
    (["M203 Z100"], 1, "maximum feed rates"),
    (["M220 S200"], 1, "feed override above 100 %"),
    (["M211 S0"], 1, "software endstops"),
    (["G20"], 1, "inches"),
]


@pytest.mark.parametrize("commands, refused, words", REFUSED, ids=[" ; ".join(c) for c, _, _ in REFUSED])
def test_the_console_refuses_what_a_job_may_not_do_and_sends_nothing(
        at_centre: httpx.Client, shared_sim: Sim, commands: list[str], refused: int, words: str) -> None:
    before = printer_commands(shared_sim)
    r = at_centre.post("/printer/gcode", json={"commands": commands})
    assert r.status_code == 422, r.text
    detail = r.json()["detail"]
    assert f"command {refused} ({commands[refused - 1]})" in detail and words in detail, detail
    assert printer_commands(shared_sim) == before        # the batch is checked whole: nothing ran
    assert at_centre.get("/printer").json()["head"] == pytest.approx([CX, CY, SAFE_Z])


# (typed commands, what the simulator then executes, the head's commanded position after)
ACCEPTED = [
    (["G1 Z5 F600"], ["G90", "G1 Z5 F600"], [CX, CY, 5.0]),
    (["G91", "G1 X10 Y-10", "G90"], ["G90", "G91", "G1 X10 Y-10", "G90"], [CX + 10, CY - 10, SAFE_Z]),
    ([f"G1 X{X0:g} Y{Y1:g} Z{FABRIC:g} F3000"], ["G90", f"G1 X{X0:g} Y{Y1:g} Z{FABRIC:g} F3000"], [X0, Y1, FABRIC]),
    ([f"M104 S{NOZZLE_MAX:g}", "M104 S0", f"M140 S{BED_MAX:g}", "M140 S0"],
     [f"M104 S{NOZZLE_MAX:g}", "M104 S0", f"M140 S{BED_MAX:g}", "M140 S0"], [CX, CY, SAFE_Z]),
    (["M105", "M400"], ["M400"], [CX, CY, SAFE_Z]),
]


@pytest.mark.parametrize("commands, runs, head", ACCEPTED, ids=[" ; ".join(c) for c, _, _ in ACCEPTED])
def test_the_console_sends_what_a_job_may_do(at_centre: httpx.Client, shared_sim: Sim, commands: list[str],
                                             runs: list[str], head: list[float]) -> None:
    before = len(printer_commands(shared_sim))
    r = at_centre.post("/printer/gcode", json={"commands": commands})
    assert r.status_code == 200, r.text
    assert [a["command"] for a in r.json()["answers"]] == commands and r.json()["notes"] == []
    assert printer_commands(shared_sim)[before:] == runs
    assert at_centre.get("/printer").json()["head"] == pytest.approx(head)


def test_a_fast_z_move_is_clamped_and_the_answer_says_so(at_centre: httpx.Client, shared_sim: Sim) -> None:
    before = len(printer_commands(shared_sim))
    r = at_centre.post("/printer/gcode", json={"commands": ["G1 Z15 F6000", "G91", "G1 Z-5"]})
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["answers"][0]["sent"] == f"G1 Z15 F{MAX_Z_F:g}"
    assert body["notes"][0].startswith(f"2 moves' feed rates clamped to the profile (Z ≤ {MAX_Z_F / 60:g} mm/s)")
    assert "G90 sent after the commands" in body["notes"][1]
    assert printer_commands(shared_sim)[before:] == ["G90", f"G1 Z15 F{MAX_Z_F:g}", "G91", f"G1 Z-5 F{MAX_Z_F:g}",
                                                     "G90"]
    assert at_centre.get("/printer").json()["head"] == pytest.approx([CX, CY, 10.0])


def test_after_motors_off_a_move_needs_homing_first(at_centre: httpx.Client, shared_sim: Sim) -> None:
    assert at_centre.post("/printer/gcode", json={"commands": ["M84"]}).status_code == 200
    assert at_centre.get("/printer").json()["head"] is None
    before = printer_commands(shared_sim)
    for commands, words in ((["G1 Z5"], "the head's X, Y position is not known"),
                            (["G91", "G1 X1"], "before the X position is known")):
        r = at_centre.post("/printer/gcode", json={"commands": commands})
        assert r.status_code == 422 and words in r.json()["detail"] and "home" in r.json()["detail"], r.text
    assert printer_commands(shared_sim) == before
    # homing in the same batch makes the position known: the printer's, asked for after it
    r = at_centre.post("/printer/gcode", json={"commands": ["G28", "G1 Z3 F600"]})
    assert r.status_code == 200, r.text
    assert at_centre.get("/printer").json()["head"] is not None


def test_ribbonctl_gcode_prints_the_refusal_and_exits_2(shared_daemon: Daemon, at_centre: httpx.Client) -> None:
    proc = subprocess.run([sys.executable, "-m", "ribbond.client.cli", "gcode", "G1 Z-2 F600", "G1 X500 Y-50 F9000",
                           "M400", "--url", shared_daemon.url], cwd=ROOT, text=True, capture_output=True, timeout=60)
    assert proc.returncode == 2 and "command 1 (G1 Z-2 F600)" in proc.stderr and "below the fabric" in proc.stderr, \
        (proc.stdout, proc.stderr)


@pytest.fixture
def raw_console(tmp_path: Path) -> Iterator[tuple[Sim, Daemon]]:
    with own_printer(tmp_path / "state", extra="[manual]\nraw_console = true\n") as pair:
        yield pair


def test_raw_console_sends_unchecked_and_logs_it(raw_console: tuple[Sim, Daemon]) -> None:
    sim, daemon = raw_console
    api = daemon.client
    assert api is not None
    assert "raw_console = true: typed G-code is sent to the printer unchecked" in daemon.log_tail()
    r = api.post("/printer/gcode", json={"commands": ["G28", "G1 Z-2 F600"]})
    assert r.status_code == 200, r.text
    assert r.json()["unchecked"] is True and "raw_console = true" in r.json()["notes"][0]
    assert printer_commands(sim)[-2:] == ["G28", "G1 Z-2 F600"]
    assert "sending unchecked G-code: G1 Z-2 F600" in daemon.log_tail()
    # the other routes keep their checks
    r = api.post("/printer/jog", json={"dx": 0, "dy": 0, "dz": -1})
    assert r.status_code == 422, r.text


@pytest.mark.parametrize("value", ['"yes"', "1", '"true"'])
def test_raw_console_must_be_a_boolean(tmp_path: Path, value: str) -> None:
    path = tmp_path / "ribbond.toml"
    path.write_text(f"[manual]\nraw_console = {value}\n", encoding="utf-8")
    with pytest.raises(ValueError, match=r"manual\.raw_console"):
        load_config(path, environ={})


def test_an_unknown_manual_setting_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "ribbond.toml"
    path.write_text("[manual]\nraw = true\n", encoding="utf-8")
    with pytest.raises(ValueError, match=r"manual\.raw"):
        load_config(path, environ={})
