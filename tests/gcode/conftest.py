"""Shared fixtures of the G-code tests: one real design (the symmetric saddle), its programs read
back by the independent reader, and the geometry the tests derive their expectations from.

Nothing here calls the writer's own geometry (``ribbond.gcode.toolpath``, ``program.mirror``):
line and layer counts, offsets, mitred rails and the mirror are re-derived from their definitions.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import shapely

from ribbond.mesh.files import write_obj
from ribbond.pipeline.compile import DesignResult, design_mesh, write_design
from ribbond.design.surfaces import saddle
from ribbond.gcode.profiles import PrinterProfile, load_profile

from .reader import Move, Program, read_gcode

PROFILE = "ultimaker2-tpu"
PROGRAMS = ("front", "back", "combined")


@dataclass(frozen=True)
class SaddleDesign:
    """The symmetric saddle's design, its folder and its programs as the reader sees them."""

    result: DesignResult
    folder: Path
    profile: PrinterProfile
    texts: dict[str, str]  # "front", "back", "combined" -> the file's text
    read: dict[str, Program]  # the same, read by tests/gcode/reader.py

    @property
    def design(self):
        return self.result.design


def build_saddle_design(tmp: Path) -> SaddleDesign:
    V, F = saddle(80.0, 1 / 50, 1 / 50, rings=24)
    mesh = tmp / "saddle.obj"
    write_obj(mesh, V, F)
    result = design_mesh(mesh, predict=False)
    folder = write_design(result, tmp / "design")
    texts = {name: (folder / f"{name}.gcode").read_text(encoding="utf-8") for name in PROGRAMS}
    return SaddleDesign(result=result, folder=folder, profile=load_profile(PROFILE), texts=texts,
                        read={name: read_gcode(text) for name, text in texts.items()})


@pytest.fixture(scope="module")
def saddle_design(tmp_path_factory: pytest.TempPathFactory) -> SaddleDesign:
    """Built once per test module (design_mesh takes a few seconds)."""
    return build_saddle_design(tmp_path_factory.mktemp("saddle"))


# ---------------------------------------------------------------------------------------------
# what the program says about itself: ;TYPE: labels


def type_labels(program: Program) -> list[tuple[str, int] | None]:
    """For each move of ``program``: the most recent ``;TYPE:<KIND> <index> ...`` comment before it,
    as (KIND, index), or None before the first one."""
    marks = [(line, text) for line, text in program.comments if text.startswith("TYPE:")]
    lines = [line for line, _ in marks]
    labels: list[tuple[str, int] | None] = []
    for move in program.moves:
        k = bisect.bisect_left(lines, move.line) - 1
        if k < 0:
            labels.append(None)
            continue
        words = marks[k][1][len("TYPE:"):].split()
        labels.append((words[0], int(words[1])))
    return labels


def pause_line(program: Program) -> int:
    """The line of the program's only M0."""
    m0 = [line for line, _ in program.pauses]
    assert len(m0) == 1, f"expected exactly one pause, got {program.pauses}"
    return m0[0]


# ---------------------------------------------------------------------------------------------
# geometry, from the definitions (design-format.md and the toolpath rules)


def line_count(width: float, nozzle: float) -> tuple[int, float]:
    """(L, line width): L = max(1, round(w_r / nozzle)) lines of w_r / L."""
    n = max(1, int(round(width / nozzle)))
    return n, width / n


def layer_count(thickness: float, max_layer_height: float) -> tuple[int, float]:
    """(n, layer height): n = ceil(τ / max_layer_height) layers of τ / n (1e-9 guards τ = k·h)."""
    n = max(1, math.ceil(thickness / max_layer_height - 1e-9))
    return n, thickness / n


def rail_offsets(width: float, nozzle: float) -> np.ndarray:
    """Signed offsets (left of travel) of the L lines' centres from the ribbon's centerline."""
    n, w = line_count(width, nozzle)
    return -0.5 * width + w * (np.arange(n) + 0.5)


def mirror_to_back(points: np.ndarray, profile: PrinterProfile) -> np.ndarray:
    """Front-side print coordinates to back-side ones: reflected about the flip axis through the
    frame's centre (flip about "y": x' = 2 cx − x; about "x": y' = 2 cy − y)."""
    out = np.array(points, dtype=float, copy=True)
    cx, cy = profile.frame.center
    if profile.frame.flip_axis == "y":
        out[:, 0] = 2.0 * cx - out[:, 0]
    else:
        out[:, 1] = 2.0 * cy - out[:, 1]
    return out


def centerline(design, index: int, side: str, profile: PrinterProfile) -> np.ndarray:
    """(k, 2) ribbon ``index``'s centerline in ``side``'s print coordinates."""
    pts = np.asarray(design.ribbons[index].points, dtype=float)
    return mirror_to_back(pts, profile) if side == "back" else pts


def polyline_length(points: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())


def mitred_rail(points: np.ndarray, offset: float, max_miter: float = 2.0) -> np.ndarray:
    """The polyline at signed distance ``offset`` to the left of ``points`` (k, 2), mitred: an end
    vertex moves along its segment's normal; an inner vertex goes to where the two offset segment
    lines meet (the point at distance |offset| from both legs), lengthened at most ``max_miter``
    times the offset for very sharp turns (toolpath.py's documented limit).

    Written from the geometric definition (the intersection of the legs' offset lines), not from the
    writer's bisector formula."""
    p = np.asarray(points, dtype=float)
    d = np.diff(p, axis=0)
    u = d / np.linalg.norm(d, axis=1)[:, None]
    nrm = np.column_stack([-u[:, 1], u[:, 0]])  # left normals of the segments
    out = np.empty_like(p)
    out[0] = p[0] + offset * nrm[0]
    out[-1] = p[-1] + offset * nrm[-1]
    for i in range(1, len(p) - 1):
        a, b = nrm[i - 1], nrm[i]
        # m with m·a = 1 and m·b = 1: m = (a + b) / (1 + a·b)
        m = (a + b) / (1.0 + float(a @ b))
        length = float(np.linalg.norm(m))
        if length > max_miter:
            m *= max_miter / length
        out[i] = p[i] + offset * m
    return out


def extrusion_area(profile: PrinterProfile) -> float:
    """Cross-section of the filament, mm²."""
    return math.pi * (0.5 * profile.extruder.filament_diameter) ** 2


def passes(program: Program, labels: list[tuple[str, int] | None], start: int = 0,
           stop: int | None = None) -> list[tuple[tuple[str, int], list[Move]]]:
    """The program's runs of consecutive extruding moves (a pass each), with their label, over
    ``program.moves[start:stop]``; any non-extruding move ends a pass."""
    out: list[tuple[tuple[str, int], list[Move]]] = []
    current: list[Move] = []
    label = None
    stop = len(program.moves) if stop is None else stop
    for move, lab in zip(program.moves[start:stop], labels[start:stop]):
        if move.extruding and current and lab == label:
            current.append(move)
            continue
        if current:
            out.append((label, current))
            current = []
        if move.extruding:
            current, label = [move], lab
    if current:
        out.append((label, current))
    return out


def ribbon_lengths(segments: np.ndarray, centerlines: list[np.ndarray], reach: float) -> np.ndarray:
    """For ``segments`` (k, 2, 2) and the ribbons' ``centerlines``: the XY length of the segments that
    lie within ``reach`` of each ribbon. A segment counts for one ribbon at most: the one whose
    centerline is nearest to the segment's farthest point (its start, middle or end)."""
    lines = shapely.linestrings(segments)
    lengths = shapely.length(lines)
    probes = np.stack([segments[:, 0], segments.mean(axis=1), segments[:, 1]], axis=1)  # (k, 3, 2)
    rails = [shapely.LineString(c) for c in centerlines]
    tree = shapely.STRtree([r.buffer(reach) for r in rails])
    # (segment, ribbon) pairs where the ribbon's buffer contains the segment
    seg_index, ribbon_index = tree.query(lines, predicate="within")
    best = np.full(len(segments), np.inf)
    owner = np.full(len(segments), -1)
    for s, r in zip(seg_index, ribbon_index):
        far = float(shapely.distance(rails[r], shapely.points(probes[s])).max())
        if far < best[s]:
            best[s], owner[s] = far, r
    out = np.zeros(len(centerlines))
    np.add.at(out, owner[owner >= 0], lengths[owner >= 0])
    return out
