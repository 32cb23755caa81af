"""Write the example print program `make demo` streams until the daemon exists.

A staggered pattern of ribbons (15 mm × 1.5 mm, two 0.8 mm lines side by side, as in §6–7 of the
paper) laid along concentric arcs, like the flat layout of a torus patch: a program with the shape
of a real job (heat, home, print, park) that the simulator renders. It is an example for the link,
not the G-code stage.

    python examples/demo_program.py OUT.gcode
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

RIBBON_LENGTH = 15.0  # l_r, mm
RIBBON_WIDTH = 1.5  # w_r, mm
NOZZLE = 0.8
LAYER = 0.3
FILAMENT_AREA = math.pi * (2.85 / 2) ** 2
PRINT_FEED = 15 * 60  # 15 mm/s, the paper's speed
TRAVEL_FEED = 120 * 60
CENTER = np.array([110.0, 110.0])


def ribbons(radii: np.ndarray) -> list[np.ndarray]:
    """Centerlines (k × 2 points) of staggered ribbons along arcs of the given radii."""
    result: list[np.ndarray] = []
    for ring, radius in enumerate(radii):
        period = 1.5 * RIBBON_LENGTH  # mu1: ribbon plus gap
        count = int(2 * math.pi * radius / period)
        shift = 0.5 * (ring % 2)  # every second ring is offset by half a period (staggered)
        for k in range(count):
            middle = 2 * math.pi * (k + shift) / count
            half = RIBBON_LENGTH / 2 / radius
            angles = np.linspace(middle - half, middle + half, 16)
            result.append(CENTER + radius * np.c_[np.cos(angles), np.sin(angles)])
    return result


def offset(points: np.ndarray, distance: float) -> np.ndarray:
    """The polyline moved sideways by ``distance`` (left of its direction)."""
    tangent = np.gradient(points, axis=0)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    normal = np.c_[-tangent[:, 1], tangent[:, 0]]
    return points + distance * normal


def program() -> list[str]:
    lines = [
        "; ribbond demo program: staggered ribbons on concentric arcs",
        "G90 ; absolute positions", "M82 ; absolute extrusion",
        "M140 S60", "M104 S230", "G28", "M190 S60", "M109 S230", "G92 E0", "G1 Z5 F600",
    ]
    e = 0.0
    bead = NOZZLE * LAYER / FILAMENT_AREA  # filament mm per mm of line
    for ribbon in ribbons(np.arange(20.0, 62.0, 6.0)):
        for side, distance in enumerate((-0.35, 0.35)):
            path = offset(ribbon, distance)
            if side:
                path = path[::-1]  # boustrophedon: the second line comes back
            x, y = path[0]
            if side == 0:
                lines += [f"G1 Z2 F{TRAVEL_FEED}", f"G0 X{x:.3f} Y{y:.3f} F{TRAVEL_FEED}", f"G1 Z{LAYER} F600"]
            else:
                lines.append(f"G1 X{x:.3f} Y{y:.3f} F{PRINT_FEED}")
            steps = np.linalg.norm(np.diff(path, axis=0), axis=1)
            for (x, y), step in zip(path[1:], steps):
                e += step * bead
                lines.append(f"G1 X{x:.3f} Y{y:.3f} E{e:.5f} F{PRINT_FEED}")
    lines += ["G1 Z10 F600", "G0 X0 Y200 F6000", "M400", "M104 S0", "M140 S0", "M84"]
    return lines


def main() -> int:
    if len(sys.argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    Path(sys.argv[1]).write_text("\n".join(program()) + "\n", encoding="ascii")
    return 0


if __name__ == "__main__":
    sys.exit(main())
