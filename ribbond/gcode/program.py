"""Print programs from a design: ``front.gcode``, ``back.gcode``, ``combined.gcode`` (§7).

Conventions of every program: millimetres, absolute positioning (G90), **relative extrusion**
(M83: every E is the filament of that move alone, so a resumed or corrected program needs no
``G92 E``), G0 for travel and G1 for printing, feed rates in mm/min, coordinates to 1 µm.

- ``front.gcode``: header, home, heat and wait, the registration marks (small crosses at the
  design's positions), the stitch marks of a panel (``design.stitch_marks``, issue 26: each a part
  ``;TYPE:STITCH i``, its strokes one layer high and a nozzle wide), the front ribbons, footer
  (retract, lift, park, heaters off); marks and ribbons are visited in one short tour.
- ``back.gcode``: the back ribbons mirrored about the profile's flip axis into back-side print
  coordinates. ``SidePlan`` keeps the planned passes, so the daemon regenerates it with a measured
  rigid ``Correction`` (rotation about a point, then an offset) with one ``render_side`` call;
  the order does not change, since a rigid motion keeps every distance.
- ``combined.gcode``: front, then an ``M0`` pause whose message says to flip the frame, then back.

Every part (a ribbon, a registration mark) is a section that begins with its ``;TYPE:`` comment and
ends retracted with an ``M400``: the daemon records a part as printed when that ``M400`` is
acknowledged (Marlin answers it once the planner has drained), and resumes an interrupted print
after the last part so proven (issue 16; ``ribbond.daemon.components.programs.program_parts``).

Before anything is returned every XY is checked against the frame rectangle and every feed rate and
temperature against the profile's maxima; a violation raises ``GcodeError`` naming it.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from ..design.format import Design
from .estimate import move_times
from .ordering import MOVE_BUDGET, Tour, order_ribbons
from .profiles import FrameSpec, PrinterProfile
from .toolpath import RibbonPasses, mark_passes, ribbon_passes

#: Size of a registration mark's cross, mm.
MARK_SIZE = 4.0
#: What a refusal calls a part of a kind other than "ribbon" and "mark" (default: the kind itself).
_PART_NAMES = {"stitch": "stitch mark"}
#: Coordinates may touch the frame rectangle's edge by this much (rounding to 1 µm).
_EDGE = 1e-6


class GcodeError(ValueError):
    """A program would break the profile's limits (frame, feed rates, temperatures)."""


class Correction(BaseModel):
    """A rigid correction of the back side: rotate by ``rotation_deg`` about ``center``, then shift by ``offset``."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)
    rotation_deg: float = Field(0.0, description="counter-clockwise, degrees")
    center: tuple[float, float] = (0.0, 0.0)
    offset: tuple[float, float] = (0.0, 0.0)

    def apply(self, xy: np.ndarray) -> np.ndarray:
        """(k, 2) points moved by the correction."""
        a = math.radians(self.rotation_deg)
        R = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
        c = np.asarray(self.center)
        return (np.asarray(xy, dtype=float) - c) @ R.T + c + np.asarray(self.offset)


def mirror(xy: np.ndarray, frame: FrameSpec) -> np.ndarray:
    """Front-side print coordinates (k, 2) to back-side ones: mirrored about the flip axis through
    the frame's centre (design-format.md). Its own inverse."""
    out = np.array(xy, dtype=float, copy=True)
    i = 0 if frame.flip_axis == "y" else 1
    out[:, i] = 2.0 * frame.center[i] - out[:, i]
    return out


@dataclass(frozen=True)
class SidePlan:
    """One side's passes in print order, in that side's print coordinates (before any correction).

    Attributes
    ----------
    side : "front" or "back".
    parts : the passes of each part (a ribbon, or on the front a registration or stitch mark), in
        print order and direction.
    kind : ("ribbon", "mark" or "stitch") and index : (in ``design.ribbons``,
        ``design.registration_marks`` or ``design.stitch_marks``) of each part.
    tour : the ordering's result (travel before and after, in mm).
    """

    side: str
    parts: list[RibbonPasses]
    kind: list[str]
    index: np.ndarray
    tour: Tour
    source: str

    def save(self, path: "str | os.PathLike[str]") -> None:
        """Write the plan to an ``.npz`` file (the daemon re-renders the back side from it after the
        flip without planning again)."""
        paths = [p for part in self.parts for p in part.paths]
        np.savez(path, side=self.side, source=self.source, kind=np.array(self.kind, dtype=str),
                 index=self.index, order=self.tour.order, reversed=self.tour.reversed,
                 travel=np.array([self.tour.travel_before, self.tour.travel_after, self.tour.improvements]),
                 passes=np.array([len(p.paths) for p in self.parts], dtype=np.int64),
                 points=np.array([len(q) for q in paths], dtype=np.int64),
                 xy=np.concatenate(paths) if paths else np.zeros((0, 2)),
                 layer=np.concatenate([p.layer for p in self.parts]) if self.parts else np.zeros(0, dtype=np.int64),
                 widths=np.array([[p.line_width, p.layer_height] for p in self.parts]).reshape(-1, 2))

    @classmethod
    def load(cls, path: "str | os.PathLike[str]") -> "SidePlan":
        """Read a plan written by ``save``."""
        with np.load(path) as z:
            xy = np.split(z["xy"], np.cumsum(z["points"])[:-1]) if len(z["points"]) else []
            cuts = np.cumsum(z["passes"])
            paths = [xy[a:b] for a, b in zip(np.concatenate([[0], cuts[:-1]]), cuts)] if len(cuts) else []
            layers = np.split(z["layer"], cuts[:-1]) if len(cuts) else []
            parts = [RibbonPasses(paths=list(p), layer=lay, line_width=float(w[0]), layer_height=float(w[1]))
                     for p, lay, w in zip(paths, layers, z["widths"])]
            travel = z["travel"]
            tour = Tour(order=z["order"], reversed=z["reversed"], travel_before=float(travel[0]),
                        travel_after=float(travel[1]), improvements=int(travel[2]))
            return cls(side=str(z["side"]), parts=parts, kind=[str(k) for k in z["kind"]], index=z["index"],
                       tour=tour, source=str(z["source"]))

    @property
    def ribbons(self) -> list[RibbonPasses]:
        """The ribbons' passes in print order."""
        return [p for p, k in zip(self.parts, self.kind) if k == "ribbon"]

    @property
    def ribbon_index(self) -> np.ndarray:
        """(R,) ``design.ribbons`` index of each ribbon in print order."""
        return np.array([i for i, k in zip(self.index, self.kind) if k == "ribbon"], dtype=np.int64)


@dataclass(frozen=True)
class ProgramStats:
    """What a program does (``report.print`` of design.json, plus its extents)."""

    lines: int
    extrusion_mm: float
    travel_mm: float
    time_s: float
    filament_mm: float
    extrusion_time_s: float
    bounds: tuple[float, float, float, float, float, float]

    def report(self) -> dict[str, float | int]:
        return {"lines": self.lines, "extrusion_mm": self.extrusion_mm, "travel_mm": self.travel_mm,
                "time_s": self.time_s, "filament_mm": self.filament_mm}


@dataclass(frozen=True)
class Program:
    """A program's text and its figures."""

    text: str
    stats: ProgramStats


@dataclass(frozen=True)
class Programs:
    """The three programs of a design and the plans they were made from."""

    front: Program
    back: Program
    combined: Program
    front_plan: SidePlan
    back_plan: SidePlan


# ---------------------------------------------------------------------------------------------
# planning


def _stroke_passes(strokes: list[np.ndarray], width: float, height: float) -> tuple[RibbonPasses, RibbonPasses]:
    """One-layer passes of ``strokes`` (each (k, 2)) ``width`` wide, ``height`` high: in their order,
    and the whole reversed (each stroke backwards, last first)."""
    layer = np.zeros(len(strokes), dtype=np.int64)
    return (RibbonPasses(list(strokes), layer, width, height),
            RibbonPasses([q[::-1] for q in strokes[::-1]], layer, width, height))


def plan_side(design: Design, profile: PrinterProfile, side: str, *, move_budget: int = MOVE_BUDGET) -> SidePlan:
    """Passes of ``side``'s ribbons, ordered for short travel, in that side's print coordinates; on the
    front the registration marks and the stitch marks (one layer, a nozzle wide) join the tour."""
    if side not in ("front", "back"):
        raise ValueError(f"side must be 'front' or 'back', not {side!r}")
    p = design.parameters
    ribbons = design.ribbons or []
    index = np.array([i for i, r in enumerate(ribbons) if r.side == side], dtype=np.int64)
    nozzle, max_h = profile.extruder.nozzle_diameter, profile.layers.max_layer_height

    def coords(points: list[tuple[float, float]]) -> np.ndarray:
        xy = np.asarray(points, dtype=float)
        return mirror(xy, profile.frame) if side == "back" else xy

    parts = [(ribbon_passes(coords(ribbons[i].points), p.ribbon_width, ribbons[i].thickness, nozzle, max_h),
              ribbon_passes(coords(ribbons[i].points)[::-1], p.ribbon_width, ribbons[i].thickness, nozzle,
                            max_h)) for i in index]
    kind = ["ribbon"] * len(parts)
    indices = list(index)
    if side == "front":
        # the registration marks join the tour: each is visited where the way passes nearest
        h0 = profile.layers.first_layer_height
        for m, xy in enumerate(design.registration_marks or []):
            a, b = mark_passes(np.asarray(xy), MARK_SIZE, nozzle)
            parts.append((RibbonPasses([a, b], np.zeros(2, dtype=np.int64), nozzle, h0),
                          RibbonPasses([b[::-1], a[::-1]], np.zeros(2, dtype=np.int64), nozzle, h0)))
            kind.append("mark")
            indices.append(m)
        for m, mark in enumerate(design.stitch_marks or []):
            parts.append(_stroke_passes(mark.arrays(), nozzle, h0))
            kind.append("stitch")
            indices.append(m)
    x0, y0, _, _ = profile.frame.bounds
    start = np.array([x0, y0])
    if parts:
        entry = np.array([[f.entry, r.entry] for f, r in parts])
        exit_ = np.array([[f.exit, r.exit] for f, r in parts])
        tour = order_ribbons(entry, exit_, start, move_budget=move_budget)
    else:
        tour = order_ribbons(np.zeros((0, 2, 2)), np.zeros((0, 2, 2)), start)
    return SidePlan(side=side, parts=[parts[k][int(tour.reversed[k])] for k in tour.order],
                    kind=[kind[k] for k in tour.order],
                    index=np.asarray([indices[k] for k in tour.order], dtype=np.int64), tour=tour,
                    source=design.source.file)


# ---------------------------------------------------------------------------------------------
# writing


@dataclass
class _Writer:
    """Emits moves and keeps the modal state and the move list for the figures."""

    profile: PrinterProfile
    transform: "Correction | None"
    lines: list[str] = field(default_factory=list)
    pos: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    retracted: bool = False
    moves: list[tuple[float, float, float, float, float, float, float, float, bool]] = field(default_factory=list)
    outside: list[str] = field(default_factory=list)
    _array: np.ndarray | None = None

    def raw(self, text: str) -> None:
        self.lines.append(text)

    def _move(self, cmd: str, xyz: np.ndarray, e: float, speed: float, extrude: bool) -> None:
        words = [cmd]
        for axis, new, old in zip("XYZ", xyz, self.pos):
            if not (abs(new - old) < 5e-7):
                words.append(f"{axis}{new:.3f}")
        if e != 0.0:
            words.append(f"E{e:.5f}")
        words.append(f"F{speed * 60:.0f}")
        self.lines.append(" ".join(words))
        start = np.where(np.isnan(self.pos), xyz, self.pos)
        self.moves.append((*start, *xyz, e, speed, extrude))
        self.pos = np.array(xyz, dtype=float)

    def _check(self, xy: np.ndarray, what: str) -> None:
        x0, y0, x1, y1 = self.profile.frame.bounds
        if not (x0 - _EDGE <= xy[0] <= x1 + _EDGE and y0 - _EDGE <= xy[1] <= y1 + _EDGE):
            self.outside.append(f"{what} at ({xy[0]:.2f}, {xy[1]:.2f})")

    def place(self, xy: np.ndarray) -> np.ndarray:
        return self.transform.apply(xy[None])[0] if self.transform is not None else xy

    def retract(self) -> None:
        r = self.profile.retraction
        if r.length > 0 and not self.retracted:
            self.lines.append(f"G1 E{-r.length:.5f} F{self.profile.motion.retract_speed * 60:.0f}")
            self.moves.append((*self.pos, *self.pos, -r.length, self.profile.motion.retract_speed, False))
            self.retracted = True

    def unretract(self) -> None:
        r = self.profile.retraction
        if self.retracted:
            self.lines.append(f"G1 E{r.length:.5f} F{self.profile.motion.retract_speed * 60:.0f}")
            self.moves.append((*self.pos, *self.pos, r.length, self.profile.motion.retract_speed, False))
            self.retracted = False

    def lift(self, z: float) -> None:
        if np.isnan(self.pos[2]) or z > self.pos[2] + 5e-7:
            self._move("G0", np.array([self.pos[0], self.pos[1], z]), 0.0, self.profile.motion.z_speed, False)

    def travel(self, xy: np.ndarray, z: float, what: str) -> None:
        """Go to ``xy`` at height ``z`` without printing: retract and hop when the way is long."""
        m, r = self.profile.motion, self.profile.retraction
        xy = self.place(xy)
        self._check(xy, what)
        dist = float(np.hypot(*(xy - self.pos[:2]))) if not np.isnan(self.pos[0]) else np.inf
        if dist > r.min_travel:
            self.retract()
            self.lift(max(z, self.pos[2] if not np.isnan(self.pos[2]) else z) + r.z_hop)
        if not (dist < 5e-7):
            self._move("G0", np.array([xy[0], xy[1], self.pos[2] if not np.isnan(self.pos[2]) else z]), 0.0,
                       m.travel_speed, False)
        if abs(self.pos[2] - z) > 5e-7:
            self._move("G0", np.array([xy[0], xy[1], z]), 0.0, m.z_speed, False)

    def extrude(self, path: np.ndarray, z: float, width: float, height: float, what: str) -> None:
        """Print along ``path`` (k, 2) at ``z`` with beads ``width`` × ``height``."""
        self.travel(path[0], z, what)
        self.unretract()
        pts = self.transform.apply(path) if self.transform is not None else path
        for q in pts:
            self._check(q, what)
        ext = self.profile.extruder
        area = math.pi * (0.5 * ext.filament_diameter) ** 2
        seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        e = width * height * seg / area * ext.extrusion_multiplier
        for q, de in zip(pts[1:], e):
            self._move("G1", np.array([q[0], q[1], z]), float(de), self.profile.motion.print_speed, True)

    def move_array(self) -> np.ndarray:
        """(k, 9) the moves written: start xyz, end xyz, e, speed, extruding (once writing is done)."""
        if self._array is None or len(self._array) != len(self.moves):
            self._array = np.array(self.moves, dtype=float).reshape(-1, 9)
        return self._array

    def stats(self) -> ProgramStats:
        if not self.moves:
            return ProgramStats(0, 0.0, 0.0, 0.0, 0.0, 0.0, (0.0,) * 6)
        M = self.move_array()
        start, end, e, speed, extruding = M[:, 0:3], M[:, 3:6], M[:, 6], M[:, 7], M[:, 8] > 0
        xy = np.linalg.norm(end[:, :2] - start[:, :2], axis=1)
        mo = self.profile.motion
        t = move_times(start, end, e, speed, mo.acceleration, mo.junction_deviation, mo.retract_speed)
        # extents of where the program goes: from its first move in XY on (not the home position)
        first = int(np.argmax(xy > 0)) if np.any(xy > 0) else 0
        lo, hi = end[first:].min(axis=0), end[first:].max(axis=0)
        commands = sum(1 for line in self.lines if line and not line.startswith(";"))
        return ProgramStats(lines=commands, extrusion_mm=float(xy[extruding].sum()),
                            travel_mm=float(xy[~extruding].sum()), time_s=float(t.sum()),
                            filament_mm=float(e[extruding].sum()),   # deposited (retractions return)
                            extrusion_time_s=float(xy[extruding].sum() / mo.print_speed),
                            bounds=(*map(float, lo), *map(float, hi)))


def _z(profile: PrinterProfile, layer: int, height: float) -> float:
    lay = profile.layers
    return lay.fabric_z + lay.first_layer_height + layer * height


def _body(w: _Writer, plan: SidePlan) -> None:
    prof = w.profile
    count = sum(k == "ribbon" for k in plan.kind)
    done = 0
    for passes, kind, index in zip(plan.parts, plan.kind, plan.index):
        if kind == "mark":
            w.raw(f";TYPE:REGISTRATION {int(index)}")
            what = f"registration mark {int(index)}"
        elif kind != "ribbon":                      # stitch marks, calibration labels and cut marks
            w.raw(f";TYPE:{kind.upper()} {int(index)}")
            what = f"{_PART_NAMES.get(kind, kind)} {int(index)}"
        else:
            done += 1
            w.raw(f";TYPE:RIBBON {int(index)} ({done} of {count})")
            what = f"ribbon {int(index)}"
        layer = -1
        for path, lay_k in zip(passes.paths, passes.layer):
            if kind == "ribbon" and lay_k != layer:
                w.raw(f";LAYER:{int(lay_k)}")
            layer = int(lay_k)
            w.extrude(path, _z(prof, layer, passes.layer_height), passes.line_width, passes.layer_height, what)
        # the part's sync point: retracted (no ooze while the host records it), then M400, whose ok
        # comes once every move before it has executed: the proof a resumed print skips the part by
        w.retract()
        w.raw(f"M400 ; end of {what}")


def _start(w: _Writer) -> None:
    prof = w.profile
    t = prof.temperatures
    if prof.gcode.emit_units:
        w.raw("G21")
    w.raw("G90 ; absolute positioning")
    w.raw("M83 ; relative extrusion")
    if t.bed > 0:
        w.raw(f"M140 S{t.bed:.0f}")
    w.raw(f"M104 S{t.nozzle:.0f}")
    w.raw("G28 ; home")
    w.pos = np.array([0.0, 0.0, 0.0])
    if t.bed > 0:
        w.raw(f"M190 S{t.bed:.0f}")
    w.raw(f"M109 S{t.nozzle:.0f}")
    w.lines.extend(line for line in prof.gcode.start.splitlines() if line.strip())
    w.raw(f"M106 S{round(2.55 * prof.fan_percent)}")
    w.lift(prof.layers.fabric_z + prof.layers.safe_height)


def _park(w: _Writer) -> None:
    """Retract, lift by ``park_lift`` and go to the frame rectangle's nearest corner."""
    prof = w.profile
    x0, y0, x1, y1 = prof.frame.bounds
    corners = np.array([[x0, y0], [x1, y0], [x0, y1], [x1, y1]])
    here = w.pos[:2] if not np.isnan(w.pos[0]) else corners[0]
    corner = corners[int(np.argmin(np.linalg.norm(corners - here, axis=1)))]
    w.retract()
    w.lift(prof.layers.fabric_z + prof.park_lift)
    w._move("G0", np.array([corner[0], corner[1], w.pos[2]]), 0.0, prof.motion.travel_speed, False)


def _finish(w: _Writer) -> None:
    _park(w)
    w.lines.extend(line for line in w.profile.gcode.end.splitlines() if line.strip())
    w.raw("M104 S0")
    if w.profile.temperatures.bed > 0:
        w.raw("M140 S0")
    w.raw("M107")
    w.raw("M84")


def flip_message(profile: PrinterProfile) -> str:
    """The operator's instruction at the flip."""
    axis = profile.frame.flip_axis
    c = profile.frame.center[0 if axis == "y" else 1]
    return f"Flip the frame about its {axis} axis ({'x' if axis == 'y' else 'y'} = {c:g}) and resume"


def _header(title: str, side: str, profile: PrinterProfile, stats: ProgramStats,
            plan_travel: tuple[float, float] | None) -> list[str]:
    x0, y0, z0, x1, y1, z1 = stats.bounds
    lines = [
        ";FLAVOR:Marlin",
        f";Generated by ribbond: {title}",
        f";SIDE:{side}",
        f";PROFILE:{profile.name}",
        f";TIME:{round(stats.time_s)}",
        f";Filament used: {stats.filament_mm / 1000:.4f}m",
        f";EXTRUSION_LENGTH:{stats.extrusion_mm:.1f}",
        f";TRAVEL_LENGTH:{stats.travel_mm:.1f}",
        f";Layer height: {profile.layers.max_layer_height:g}",
        f";MINX:{x0:.3f}", f";MINY:{y0:.3f}", f";MINZ:{z0:.3f}",
        f";MAXX:{x1:.3f}", f";MAXY:{y1:.3f}", f";MAXZ:{z1:.3f}",
        ";UNITS:mm",
        ";POSITIONING:absolute (G90)",
        ";EXTRUSION:relative (M83)",
        f";FILAMENT_DIAMETER:{profile.extruder.filament_diameter:g}",
        f";NOZZLE_DIAMETER:{profile.extruder.nozzle_diameter:g}",
    ]
    if plan_travel is not None:
        lines.append(f";TRAVEL_BEFORE_ORDERING:{plan_travel[0]:.1f}")
    return lines


def _check_limits(w: _Writer, what: str) -> None:
    prof = w.profile
    if w.outside:
        raise GcodeError(f"{what}: {len(w.outside)} point(s) outside the frame rectangle "
                         f"{tuple(round(b, 2) for b in prof.frame.bounds)}, first: {w.outside[0]}")
    m = prof.motion
    if w.moves:
        M = w.move_array()
        d = M[:, 3:6] - M[:, 0:3]
        xy = np.hypot(d[:, 0], d[:, 1]) > 0
        limit = np.where(xy, m.max_xy_speed, np.where(np.abs(d[:, 2]) > 0, m.max_z_speed, m.max_e_speed))
        over = np.flatnonzero(M[:, 7] > limit + 1e-9)
        if over.size:
            k = over[0]
            raise GcodeError(f"{what}: a feed rate of {M[k, 7]:g} mm/s exceeds the profile's maximum of "
                             f"{limit[k]:g} mm/s ({over.size} move(s))")


def render_side(plan: SidePlan, profile: PrinterProfile, *, correction: Correction | None = None) -> Program:
    """The whole program of one side (header, heating, its passes, footer); fast: no planning."""
    w = _Writer(profile, correction)
    _start(w)
    _body(w, plan)
    _finish(w)
    _check_limits(w, f"{plan.side}.gcode")
    stats = w.stats()
    title = f"{plan.side} side of {plan.source}" + (
        f", corrected by {correction.rotation_deg:+.3f}° about ({correction.center[0]:.2f}, "
        f"{correction.center[1]:.2f}) and ({correction.offset[0]:+.3f}, {correction.offset[1]:+.3f}) mm"
        if correction is not None else "")
    head = _header(title, plan.side, profile, stats, (plan.tour.travel_before, plan.tour.travel_after))
    return Program(text="\n".join(head + w.lines) + "\n", stats=stats)


def _empty_side(plan: SidePlan, profile: PrinterProfile) -> Program:
    stats = ProgramStats(0, 0.0, 0.0, 0.0, 0.0, 0.0, (0.0,) * 6)
    head = _header(f"{plan.side} side of {plan.source}: no {plan.side} ribbons, nothing to print",
                   plan.side, profile, stats, None)
    return Program(text="\n".join(head) + "\n", stats=stats)


def render_combined(front: SidePlan, back: SidePlan, profile: PrinterProfile) -> Program:
    """Front, a pause to flip the frame (``M0`` with the instruction), back: for other hosts."""
    w = _Writer(profile, None)
    _start(w)
    _body(w, front)
    if back.parts:
        _park(w)
        w.raw("M400")
        w.raw(f";FLIP: {flip_message(profile)}")
        w.raw(f"M117 {flip_message(profile)}")
        w.raw(f"M0 {flip_message(profile)}")
        _body(w, back)
    _finish(w)
    _check_limits(w, "combined.gcode")
    stats = w.stats()
    head = _header(f"front and back of {front.source} with a pause to flip the frame", "both", profile,
                   stats, None)
    return Program(text="\n".join(head + w.lines) + "\n", stats=stats)


def make_programs(design: Design, profile: PrinterProfile, *, move_budget: int = MOVE_BUDGET) -> Programs:
    """Plan and write the three programs of ``design`` for ``profile``.

    Raises
    ------
    GcodeError
        when a program would leave the frame rectangle or exceed the profile's maxima.
    """
    front = plan_side(design, profile, "front", move_budget=move_budget)
    back = plan_side(design, profile, "back", move_budget=move_budget)
    front_prog = render_side(front, profile)
    back_prog = render_side(back, profile) if back.parts else _empty_side(back, profile)
    combined = render_combined(front, back, profile)
    return Programs(front=front_prog, back=back_prog, combined=combined, front_plan=front, back_plan=back)
