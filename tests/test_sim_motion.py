"""Motion timing, the planner, extrusion segments, the fabric frame and records."""

from __future__ import annotations

import json
import math
import time

import numpy as np
import pytest

from sim import FrameConfig, SimConfig
from sim.testing import connected


def test_moves_take_distance_over_feed_scaled() -> None:
    # 5 x 100 mm at 6000 mm/min = 5 physical seconds = 0.5 s wall at time_scale 0.1.
    with connected(SimConfig(time_scale=0.1)) as (sim, host):
        program = "".join(f"G1 X{100 * ((i + 1) % 2)} F6000\n" for i in range(5))
        t0 = host.write(program + "M400\n")
        oks = [host.readline(2.0) for _ in range(6)]
        t1 = time.monotonic()
        assert oks[:5] == [f"ok P{14 - i} B3" for i in range(5)]  # P drops as blocks queue
        assert oks[5] == "ok P15 B3"  # M400 answers once the planner is empty
        assert 0.5 <= t1 - t0 < 0.58, t1 - t0
        assert sim.stats().planner_peak == 5


def test_e_only_move_uses_e_length_and_g4_dwells() -> None:
    with connected(SimConfig(time_scale=0.1)) as (sim, host):
        t0 = host.write("M83\nG1 E3 F60\nM400\n")  # 3 mm at 1 mm/s: 0.3 s wall
        host.read_until(lambda s: s.startswith("ok P15"), timeout=2.0)
        host.read_until(lambda s: s.startswith("ok P15"), timeout=2.0)
        assert 0.3 <= time.monotonic() - t0 < 0.37
        t0 = host.send("G4 P2000")  # 2 s physical
        assert host.readline(2.0) == "ok P15 B3"
        assert 0.2 <= time.monotonic() - t0 < 0.26
        assert sim.segments() == []  # no XY motion: nothing deposited


def test_planner_full_holds_the_queue_slot() -> None:
    with connected(SimConfig(time_scale=1.0, planner_blocks=4, keepalive_s=0.2)) as (sim, host):
        for i in range(3):  # fills the 3 usable blocks: 1 s each
            assert host.command(f"G1 X{i + 1} F60") == [f"ok P{2 - i} B3"]
        t0 = host.send("G1 X10 F600")
        lines = host.read_until(lambda s: s.startswith("ok"), timeout=2.5)
        waited = time.monotonic() - t0
        # The fourth waits for the first block to finish (about 1 s after it started),
        # with keepalives meanwhile.
        assert 0.7 < waited < 1.2, waited
        assert "echo:busy: processing" in lines
        assert lines[-1] == "ok P0 B3"
        host.write(b"M410\n")


def test_segments_recorded_with_extrusion() -> None:
    with connected(SimConfig(time_scale=0.001)) as (sim, host):
        host.write("G92 E0\nG1 X10 Y10 F3000\nG1 X20 Y10 E1.5\nG1 X20 Y20 E1.5\n"
                   "G1 X30 Y30 E1.2\nG1 Z0.3 E2\nM83\nG1 X40 Y30 E0.5 F1200\nM400\n")
        assert sim.wait_idle(2.0)
        segs = sim.segments()
        assert [(s.x0, s.y0, s.x1, s.y1) for s in segs] == [(10, 10, 20, 10), (30, 30, 40, 30)]
        assert segs[0].e == pytest.approx(1.5) and segs[1].e == pytest.approx(0.5)
        assert segs[0].feed == 3000 and segs[1].feed == 1200
        assert segs[1].z == pytest.approx(0.3)
        assert all(s.side == "front" for s in segs)
        # Front up with no misalignment: fabric coordinates are machine coordinates.
        assert [(s.fx0, s.fy0, s.fx1, s.fy1) for s in segs] == [(10, 10, 20, 10), (30, 30, 40, 30)]
        assert segs[0].time < segs[1].time <= time.monotonic()


def test_m220_scales_the_feed_and_m221_the_filament_and_both_report_themselves() -> None:
    """Marlin's M220/M221: S sets the percentage, the bare command reports it ("FR:n%", "echo:E0
    Flow: n%"); a move runs at F × M220/100 (its time and its recorded feed) and pushes E × M221/100
    of filament, while the E position stays the commanded one (the next absolute E is not shifted)."""
    with connected(SimConfig(time_scale=0.1)) as (sim, host):
        assert host.command("M220") == ["FR:100%", "ok P15 B3"]
        assert host.command("M221") == ["echo:E0 Flow: 100%", "ok P15 B3"]
        assert host.command("M220 S50")[-1].startswith("ok") and host.command("M221 S120")[-1].startswith("ok")
        assert host.command("M220") == ["FR:50%", "ok P15 B3"]
        assert host.command("M221") == ["echo:E0 Flow: 120%", "ok P15 B3"]
        # 30 mm at 6000 mm/min at 50 %: 0.6 physical seconds = 0.06 s wall at time_scale 0.1
        t0 = host.write("G92 E0\nG1 X30 E2 F6000\nG1 X60 E3\nM400\n")
        host.read_until(lambda s: s.startswith("ok P15"), timeout=2.0)
        assert sim.wait_idle(2.0)
        assert time.monotonic() - t0 >= 2 * 30 / (6000 * 0.5 / 60) * 0.1
        segs = sim.segments()
        assert [s.feed for s in segs] == [3000, 3000]
        assert [s.e for s in segs] == pytest.approx([2 * 1.2, 1 * 1.2])


def _deposit(sim, host, p0, p1) -> None:
    host.write(f"G1 X{p0[0]:.6f} Y{p0[1]:.6f} F6000\nG1 X{p1[0]:.6f} Y{p1[1]:.6f} E1\nM400\n")
    assert sim.wait_idle(2.0)


@pytest.mark.parametrize("axis", ["x", "y"])
def test_flip_mirrored_point_lands_on_same_fabric_point(axis: str) -> None:
    cfg = SimConfig(time_scale=0.001, frame=FrameConfig(center=(110.0, 100.0), flip_axis=axis))
    with connected(cfg) as (sim, host):
        host.write("M83\n")
        a, b = (50.0, 60.0), (70.0, 85.0)
        _deposit(sim, host, a, b)
        sim.flip()
        # The back program is the front one mirrored about the same axis.
        mirror = (lambda p: (220.0 - p[0], p[1])) if axis == "y" else (lambda p: (p[0], 200.0 - p[1]))
        _deposit(sim, host, mirror(a), mirror(b))
        front, back = sim.segments()
        assert (front.side, back.side) == ("front", "back")
        assert (back.x0, back.y0) == pytest.approx(mirror(a))
        assert (back.fx0, back.fy0, back.fx1, back.fy1) == pytest.approx((*a, *b))
        sim.flip()
        _deposit(sim, host, a, b)
        assert sim.segments()[-1].side == "front"
        assert (sim.segments()[-1].fx0, sim.segments()[-1].fy0) == pytest.approx(a)


def test_flip_misalignment_rotation_then_offset() -> None:
    cfg = SimConfig(time_scale=0.001, frame=FrameConfig(center=(110.0, 110.0), flip_axis="y"))
    with connected(cfg) as (sim, host):
        host.write("M83\n")
        pose = sim.flip(offset=(3.0, -2.0), rotation_deg=10.0)
        assert (pose.side, pose.offset, pose.rotation_deg) == ("back", (3.0, -2.0), 10.0)
        # A fabric point q lies at p = Rot_c(10°)·Mirror(q) + offset on the bed.
        q = np.array([[60.0, 90.0], [80.0, 95.0]])
        m = np.column_stack([220.0 - q[:, 0], q[:, 1]])
        a = math.radians(10.0)
        rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
        p = (m - 110.0) @ rot.T + 110.0 + np.array([3.0, -2.0])
        _deposit(sim, host, p[0], p[1])
        seg = sim.segments()[-1]
        assert seg.side == "back"
        assert (seg.fx0, seg.fy0, seg.fx1, seg.fy1) == pytest.approx(tuple(q.ravel()), abs=1e-5)


def test_starvation_counted_only_without_sync() -> None:
    with connected(SimConfig(time_scale=0.001)) as (sim, host):
        host.command("G1 X10 F600")  # the first block is never a starvation
        time.sleep(0.1)  # 1 s physical = 1 ms wall: long done
        host.command("G1 X20")
        st = sim.stats()
        assert st.starvations == 1 and 0.08 < st.starved_s < 0.5
        host.command("M400")
        time.sleep(0.05)
        host.command("G1 X30")  # M400 in between: the host asked for the pause
        assert sim.stats().starvations == 1
        sim.reset_stats()
        time.sleep(0.05)
        host.command("G1 X40")
        assert sim.stats().starvations == 0
        host.command("M400")
        # Back to back (10 ms each, arriving 0.3 ms apart): the planner never runs dry.
        host.write("G1 X50 F60\nG1 X60\nG1 X70\n")
        assert sim.wait_idle(2.0)
        assert sim.stats().starvations == 0


def test_record_file_json_lines(tmp_path) -> None:
    path = tmp_path / "record.jsonl"
    with connected(SimConfig(), record_path=str(path)) as (sim, host):
        host.command("G90", 1)
        host.command("G1 X1 Y2", 2)
        host.command("M105")
        # Flushed as it goes: readable while the simulator runs.
        rows = [json.loads(s) for s in path.read_text().splitlines()]
    assert [(r["line"], r["command"]) for r in rows] == [(1, "G90"), (2, "G1 X1 Y2"), (None, "M105")]
    assert all(isinstance(r["time"], float) for r in rows)
    assert rows[0]["time"] <= rows[1]["time"] <= rows[2]["time"] <= time.monotonic()


def test_render_png(tmp_path) -> None:
    cfg = SimConfig(time_scale=0.0001, frame=FrameConfig(center=(110.0, 110.0), flip_axis="y"))
    with connected(cfg) as (sim, host):
        host.write("M83\n")
        # A spiral on the front, its mirror on the back slightly misaligned.
        pts = [(110 + (5 + 2 * t) * math.cos(t), 110 + (5 + 2 * t) * math.sin(t))
               for t in np.linspace(0, 6 * math.pi, 120)]
        program = [f"G1 X{pts[0][0]:.3f} Y{pts[0][1]:.3f} F6000"]
        program += [f"G1 X{x:.3f} Y{y:.3f} E0.05" for x, y in pts[1:]]
        host.write("\n".join(program) + "\n")
        assert sim.wait_idle(5.0)
        sim.flip(offset=(1.5, -1.0), rotation_deg=2.0)
        back = [f"G1 X{220 - x:.3f} Y{y:.3f} E0.05" for x, y in pts[1:60]]
        host.write(f"G1 X{220 - pts[0][0]:.3f} Y{pts[0][1]:.3f}\n" + "\n".join(back) + "\n")
        assert sim.wait_idle(5.0)
        out = tmp_path / "deposits.png"
        sim.render_png(str(out))
    data = out.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 20000
