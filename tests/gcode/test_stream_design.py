"""A real design's front program streamed through the printer link to the simulated Marlin printer:
what the simulator deposited, in fabric coordinates, is compared with the design's ribbons."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
import shapely

from ribbond.printer import PrinterLink, Timeouts, prepare_program

from ..conftest import executed_program
from .conftest import SaddleDesign, centerline, layer_count, line_count, polyline_length, ribbon_lengths

#: Deposits lie within w_r/2 + this of a ribbon's centerline, mm.
SLACK = 0.1
#: ... or within this of a registration mark (a cross of 4 mm strokes), mm.
MARK_REACH = 3.0


@pytest.mark.timeout(60)
@pytest.mark.timing
async def test_streamed_front_program_deposits_the_front_ribbons(make_sim, saddle_design: SaddleDesign) -> None:
    sd = saddle_design
    design, prof = sd.design, sd.profile
    program = sd.read["front"]
    commands = prepare_program(sd.texts["front"].splitlines(), "front.gcode")
    sim = make_sim()
    assert tuple(sim.config.frame.center) == tuple(prof.frame.center)
    assert sim.config.frame.flip_axis == prof.frame.flip_axis
    link = PrinterLink(sim.port, sim.config.baud, timeouts=Timeouts(default_s=0.5, probes=4), boot_wait_s=1.0)
    await link.connect()
    started = time.monotonic()
    try:
        result = await link.stream(commands)
        assert sim.wait_idle(20.0), "the simulator did not finish the program's moves"
    finally:
        await link.close()
    elapsed = time.monotonic() - started
    assert result.lines == len(commands)
    assert executed_program(sim) == commands, "every line executed once, in order"
    assert elapsed < 20.0, f"streaming the front program took {elapsed:.1f} s"

    segments = sim.segments()
    assert segments and {s.side for s in segments} == {"front"}
    machine = np.array([[[s.x0, s.y0], [s.x1, s.y1]] for s in segments])
    fabric = np.array([[[s.fx0, s.fy0], [s.fx1, s.fy1]] for s in segments])
    np.testing.assert_allclose(fabric, machine, atol=1e-9, err_msg="front up: fabric = machine coordinates")

    # what was deposited is what the program prints, move for move
    prints = program.extruding_moves()
    assert len(segments) == len(prints)
    np.testing.assert_allclose(fabric, [[m.start[:2], m.end[:2]] for m in prints], atol=1e-6)
    np.testing.assert_allclose([s.e for s in segments], [m.e for m in prints], atol=1e-9)

    # every deposit lies on a front ribbon or a registration mark
    width = design.parameters.ribbon_width
    front = [i for i, r in enumerate(design.ribbons) if r.side == "front"]
    lines = [centerline(design, i, "front", prof) for i in front]
    allowed = shapely.union_all([shapely.LineString(c).buffer(width / 2 + SLACK) for c in lines]
                                + [shapely.Point(m).buffer(MARK_REACH) for m in design.registration_marks])
    deposits = shapely.linestrings(fabric)
    stray = np.flatnonzero(~shapely.covered_by(deposits, allowed))
    assert stray.size == 0, (f"{stray.size} deposit(s) off the ribbons and marks, first "
                             f"{fabric[stray[0]].round(3).tolist()}")

    # each ribbon got its lines × layers × length
    n_lines, _ = line_count(width, prof.extruder.nozzle_diameter)
    got = ribbon_lengths(fabric, lines, width / 2 + SLACK)
    bad = []
    for i, c, length in zip(front, lines, got):
        layers, _ = layer_count(design.ribbons[i].thickness, prof.layers.max_layer_height)
        expected = n_lines * layers * polyline_length(c)
        if abs(length - expected) > 0.02 * expected:
            bad.append(f"ribbon {i}: {length:.3f} mm deposited, expected {expected:.3f} mm")
    assert not bad, "\n".join(bad[:10])

    # the filament: all of the program's extrusion, and nothing else
    deposited = math.fsum(s.e for s in segments)
    assert deposited == pytest.approx(math.fsum(m.e for m in prints), rel=1e-3)
    assert deposited == pytest.approx(sd.result.programs.front.stats.filament_mm, rel=1e-3)
