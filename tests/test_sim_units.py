"""Unit tests of the simulator's parts, without a pty."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim import FaultConfig, FrameConfig, SimConfig
from sim.emergency import EmergencyParser
from sim.faults import FaultInjector
from sim.frame import Frame
from sim.gcode import checksum, parse, strip_line_number, strtol
from sim.planner import Planner
from sim.serialport import InputPacer, OutputPacer
from sim.thermal import Heater


def test_checksum_and_strtol() -> None:
    assert checksum(b"N1 M105") == 0x4E ^ 0x31 ^ 0x20 ^ 0x4D ^ 0x31 ^ 0x30 ^ 0x35
    assert checksum(b"") == 0
    assert strtol("N12 G1", 1) == 12
    assert strtol("*  -7x", 1) == -7
    assert strtol("*", 1) == 0


def test_strip_and_parse() -> None:
    assert strip_line_number("N12 G1 X5*99") == "G1 X5"
    assert strip_line_number("G1 X5 *12") == "G1 X5"
    g = parse("G1 X-1.5 Y.5 E2 F3000")
    assert g is not None and g.code == "G1"
    assert g.params == {"X": -1.5, "Y": 0.5, "E": 2.0, "F": 3000.0}
    assert parse("m104 s200").params == {"S": 200.0}  # type: ignore[union-attr]
    assert parse("hello") is None


def test_input_pacer_times_bytes() -> None:
    p = InputPacer(byte_time=0.001)
    p.push(b"ab\ncd\n", 10.0)
    assert p.next_event() == pytest.approx(10.003)
    assert p.take(10.0025) == [(b"ab", pytest.approx(10.002))]
    assert p.take(10.0061) == [(b"\n", pytest.approx(10.003)), (b"cd\n", pytest.approx(10.006))]
    # A later read queues behind bytes still on the wire.
    p.push(b"x\n", 10.0)
    p.push(b"y\n", 10.0)
    assert p.take(100.0) == [(b"x\n", pytest.approx(10.008)), (b"y\n", pytest.approx(10.010))]
    assert p.pending() == 0


def test_output_pacer_preserves_order_and_rate() -> None:
    p = OutputPacer(byte_time=0.001)
    p.push(b"ok\n", 5.0)  # leaves at 5.003
    p.push(b"slow\n", 5.5)  # held back: leaves at 5.505
    p.push(b"ok\n", 5.0)  # cannot overtake: 5.508
    assert p.take(5.003) == b"ok\n"
    assert p.take(5.507) == b"slow\n"
    assert p.next_event() == pytest.approx(5.508)
    assert p.take(6.0) == b"ok\n"


def test_emergency_parser() -> None:
    ep = EmergencyParser()
    assert ep.feed(b"M11") == []
    assert ep.feed(b"2\n") == ["M112"]
    assert ep.feed(b"N12 M108*33\nG1 X1\n M410\r") == ["M108", "M410"]
    assert ep.feed(b"G1 M112\nM1120\n") == ["M112"]  # not after another command; M1120 as Marlin
    assert ep.feed(b"m112\n") == []


def test_corruption_spares_leading_n_and_newlines() -> None:
    inj = FaultInjector(FaultConfig(corrupt_rate=1.0), seed=1)
    lines = [f"N{i} G1 X{i}*{i}\n".encode() for i in range(200)]
    out, hits = inj.corrupt(b"".join(lines))
    assert hits >= 100  # a merged line (corrupted newline) is one line
    assert out.count(b"\r") == 0
    assert out.count(b"\n") < 200
    # Every byte changed is a printable replacement; N at each surviving line start is kept.
    assert all(b"\x20" <= bytes([c]) <= b"\x7e" or c == 0x0A for c in out)
    assert all(line.startswith(b"N") for line in out.split(b"\n")[:-1])


def test_corruption_off_is_identity() -> None:
    inj = FaultInjector(FaultConfig(), seed=1)
    assert inj.corrupt(b"N1 G1*1\n") == (b"N1 G1*1\n", 0)


def test_triggers_fire_once() -> None:
    inj = FaultInjector(FaultConfig(reset_after_lines=2, runaway_after_lines=3), seed=0)
    assert [inj.line_accepted() for _ in range(5)] == [[], ["reset"], ["runaway"], [], []]


def test_frame_round_trip_and_flip_back() -> None:
    f = Frame(FrameConfig(center=(100.0, 50.0), flip_axis="x"))
    pts = np.array([[10.0, 20.0], [130.0, 70.0]])
    assert np.allclose(f.to_fabric(pts), pts)
    f.flip(offset=(2.0, 3.0), rotation_deg=30.0)
    assert f.side == "back"
    assert np.allclose(f.to_fabric(f.to_machine(pts)), pts)
    mirrored = np.array([[10.0, 80.0], [130.0, 30.0]])  # y about y = 50
    a = math.radians(30.0)
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    assert np.allclose(f.to_machine(pts), (mirrored - [100, 50]) @ rot.T + [100, 50] + [2, 3])
    f.flip()
    assert f.side == "front" and np.allclose(f.to_fabric(pts), pts)


def test_planner_chains_in_virtual_time() -> None:
    p = Planner(4)
    assert p.moves_free() == 3
    a = p.add((0, 0, 0, 0), (10, 0, 0, 0), 600, 1.0, t=5.0)
    b = p.add((10, 0, 0, 0), (20, 0, 0, 0), 600, 1.0, t=5.5)  # starts when a ends
    assert (a.t_start, a.t_end, b.t_start, b.t_end) == (5.0, 6.0, 6.0, 7.0)
    assert p.position_at(6.5) == pytest.approx((15, 0, 0, 0))
    assert p.complete_head() is a
    partial = p.quickstop(6.25)
    assert partial is not None and partial.end == pytest.approx((12.5, 0, 0, 0))
    assert p.is_empty() and p.position_at(9.0) == pytest.approx((12.5, 0, 0, 0))
    c = p.add((0, 0, 0, 0), (1, 0, 0, 0), 600, 1.0, t=20.0)  # after idling: starts when added
    assert c.t_start == 20.0


def test_heater_first_order() -> None:
    h = Heater("T", tau_s=15.0, max_c=275.0)
    h.target = 200.0
    h.advance(15.0)
    assert h.temp == pytest.approx(200 - 175 * math.exp(-1))
    assert h.power == 127
    h.advance(h.time_to_reach())
    assert h.reached(wait_cooling=False) and h.temp == pytest.approx(199.0, abs=1e-3)


def test_config_validation() -> None:
    with pytest.raises(ValueError):
        FaultConfig(drop_ok_rate=1.5)
    with pytest.raises(ValueError):
        FrameConfig(flip_axis="z")
    with pytest.raises(ValueError):
        SimConfig(planner_blocks=1)
    assert SimConfig(baud=250000).byte_time == pytest.approx(40e-6)
