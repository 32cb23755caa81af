"""Calibration coupons laid out on sheets, as two-sided design folders the daemon prints (§5, Fig. 6).

A coupon is the paper's regular pattern of parallel ribbons: rows across (spacing μ2), ribbons of
length l_r and width w_r along x every μ1, every other row shifted by μ1/2 (staggered), one
thickness τ per coupon. In front-side print coordinates a coupon is the rectangle

    x ∈ [x0, x0 + LABEL + 2 μ1],  y ∈ [y0, y0 + n μ2],  n = max(3, ⌈min_coupon_width / μ2⌉)

whose first ``LABEL`` mm (along x) hold its number in raised seven-segment digits (one layer, one
nozzle wide, read with the label strip on top; on back coupons the digits are drawn mirrored so
that they read right on the back), then two periods of ribbons. Cut lines are crop marks: at each
corner the two edges continued outside the rectangle (``TICK_GAP`` to ``TICK_GAP + TICK`` mm),
printed on the front so no plastic crosses the coupon. Coupons are packed in shelves (rows) inside
the frame less ``MARGIN``, front and back coupons mixed, over as many sheets as needed. Each sheet
is one design folder (``design.json`` with the coupons' ribbons, front exactly where κ1 > 0: the
expected κ1 of the base table, negative on the back; the sheet rectangle as ``target.obj`` /
``flat.obj``; three registration marks; ``front.gcode``, ``back.gcode``, ``combined.gcode``; the
sheet map as ``preview.svg``/``preview.png``), printed as one two-sided job.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..design.folder import write_design_folder
from ..design.format import (Design, Faces, Parameters, PrintReport, Quantiles, Report, Ribbon,
                             RibbonsReport, SidePrintReport, Source)
from ..design.params import DesignParameters
from ..design.placement import registration_marks
from ..design.thickness import load_curvature_table, table_curvature
from ..gcode.ordering import MOVE_BUDGET, order_ribbons
from ..gcode.profiles import PrinterProfile, load_profile
from ..gcode.program import (MARK_SIZE, Program, Programs, SidePlan, _empty_side, mirror, render_combined,
                             render_side)
from ..gcode.toolpath import RibbonPasses, mark_passes, ribbon_passes
from .spec import CalibrationSpec

#: Label strip at the start of each coupon (along the ribbons), mm.
LABEL = 4.5
#: Seven-segment digit: height (along -x), width and advance (along y), mm.
DIGIT_H, DIGIT_W, DIGIT_ADVANCE = 3.6, 2.0, 3.0
#: Crop marks: gap from the corner and length, mm.
TICK_GAP, TICK = 0.8, 1.7
#: Between neighbouring coupons (room for both coupons' crop marks), mm.
GAP = 2 * (TICK_GAP + TICK) + 0.5
#: Inside the frame: room for the registration marks 5 mm outside the layout.
MARGIN = 7.5
#: The plan folder's own files (besides one design folder per sheet).
PLAN_FILE, COUPONS_FILE = "plan.json", "coupons.csv"
PLAN_FORMAT = "ribbond-calibration/1"

# segments of a seven-segment digit in (u across, v up), unit box [0, 1] × [0, 2]
_SEG = {"a": ((0, 2), (1, 2)), "b": ((1, 2), (1, 1)), "c": ((1, 1), (1, 0)), "d": ((1, 0), (0, 0)),
        "e": ((0, 0), (0, 1)), "f": ((0, 1), (0, 2)), "g": ((0, 1), (1, 1))}
_DIGITS = {"0": "abcdef", "1": "bc", "2": "abged", "3": "abgcd", "4": "fgbc", "5": "afgcd",
           "6": "afgedc", "7": "abc", "8": "abcdefg", "9": "abcdfg"}


@dataclass(frozen=True)
class Coupon:
    """One coupon: its number (from 1), side, τ and μ2, sheet (from 1) and cut rectangle (mm, front-side
    print coordinates: x, y the lower left corner), its rows and expected κ1 (the base table's)."""

    number: int
    side: str
    thickness: float
    spacing: float
    sheet: int
    x: float
    y: float
    width: float
    height: float
    rows: int
    expected_kappa: float


@dataclass(frozen=True)
class Sheet:
    """One sheet: its number, coupons, design (``design.json``), programs and plans."""

    number: int
    coupons: list[Coupon]
    design: Design
    programs: Programs
    labels: dict[str, list[np.ndarray]]   # side -> strokes, front-side coordinates
    cuts: list[np.ndarray]


@dataclass(frozen=True)
class CalibrationPlan:
    spec: CalibrationSpec
    profile: PrinterProfile
    coupons: list[Coupon]
    sheets: list[Sheet]
    created: str


def coupon_size(spec: CalibrationSpec, spacing: float) -> tuple[float, float, int]:
    """(width along x, height along y, rows) of a coupon's cut rectangle at ``spacing`` μ2, mm."""
    rows = max(3, math.ceil(spec.min_coupon_width / spacing - 1e-9))
    return LABEL + 2 * spec.mu1, rows * spacing, rows


def digit_strokes(text: str, origin: np.ndarray, up: np.ndarray, right: np.ndarray) -> list[np.ndarray]:
    """Seven-segment strokes (each (2, 2)) of ``text`` (digits): the first digit's lower left corner at
    ``origin`` (2,), ``up`` and ``right`` unit vectors (2,) of the glyphs."""
    out = []
    for k, ch in enumerate(text):
        base = origin + k * DIGIT_ADVANCE * right
        for s in _DIGITS[ch]:
            (u0, v0), (u1, v1) = _SEG[s]
            a = base + u0 * DIGIT_W * right + v0 * 0.5 * DIGIT_H * up
            b = base + u1 * DIGIT_W * right + v1 * 0.5 * DIGIT_H * up
            out.append(np.array([a, b]))
    return out


def coupon_ribbons(spec: CalibrationSpec, c: Coupon) -> list[np.ndarray]:
    """The ribbons' centerlines (each (2, 2), along +x) of coupon ``c``: rows every μ2, ribbons every μ1,
    odd rows shifted by μ1/2 (one ribbon between the even rows' two)."""
    x0 = c.x + LABEL
    half = 0.5 * spec.ribbon_length
    out = []
    for r in range(c.rows):
        y = c.y + (r + 0.5) * c.spacing
        centres = [x0 + 0.5 * spec.mu1, x0 + 1.5 * spec.mu1] if r % 2 == 0 else [x0 + spec.mu1]
        out.extend(np.array([[m - half, y], [m + half, y]]) for m in centres)
    return out


def coupon_label(c: Coupon, frame_flip_axis: str) -> list[np.ndarray]:
    """The strokes of the coupon's number in its label strip (mirrored on the back: reads right there)."""
    text = str(c.number)
    up, right = np.array([-1.0, 0.0]), np.array([0.0, 1.0])     # read with the label strip on top
    length = (len(text) - 1) * DIGIT_ADVANCE + DIGIT_W
    cx = c.x + 0.5 * LABEL
    origin = np.array([cx + 0.5 * DIGIT_H, c.y + 0.5 * (c.height - length)])
    strokes = digit_strokes(text, origin, up, right)
    if c.side == "back":
        i = 0 if frame_flip_axis == "y" else 1
        centre = np.array([cx, c.y + 0.5 * c.height])
        for s in strokes:
            s[:, i] = 2 * centre[i] - s[:, i]
    return strokes


def crop_marks(c: Coupon) -> list[np.ndarray]:
    """Eight strokes (2, 2): at each corner of the cut rectangle both edges continued outside it."""
    x0, y0, x1, y1 = c.x, c.y, c.x + c.width, c.y + c.height
    a, b = TICK_GAP, TICK_GAP + TICK
    out = []
    for cx, sx in ((x0, -1), (x1, 1)):
        for cy, sy in ((y0, -1), (y1, 1)):
            out.append(np.array([[cx + sx * a, cy], [cx + sx * b, cy]]))
            out.append(np.array([[cx, cy + sy * a], [cx, cy + sy * b]]))
    return out


def layout(spec: CalibrationSpec, profile: PrinterProfile) -> list[Coupon]:
    """Every coupon of ``spec`` placed on a sheet (shelves left to right, bottom to top, inside the frame
    less ``MARGIN``); numbers follow the sheets and shelves.

    Raises
    ------
    ValueError
        when one coupon does not fit the frame at all (its size and the room named).
    """
    table = load_curvature_table(spec.base_table)
    x_lo, y_lo, x_hi, y_hi = profile.frame.bounds
    x_lo, y_lo, x_hi, y_hi = x_lo + MARGIN + TICK_GAP + TICK, y_lo + MARGIN + TICK_GAP + TICK, \
        x_hi - MARGIN - TICK_GAP - TICK, y_hi - MARGIN - TICK_GAP - TICK
    wanted = [(side, tau, mu) for j, mu in enumerate(spec.spacings) for tau in spec.thicknesses
              for side in spec.sides]
    coupons: list[Coupon] = []
    sheet, x, y, shelf = 1, x_lo, y_lo, 0.0
    for side, tau, mu in wanted:
        w, h, rows = coupon_size(spec, mu)
        if w > x_hi - x_lo or h > y_hi - y_lo:
            raise ValueError(f"a coupon at μ2 = {mu} mm is {w:.1f} × {h:.1f} mm: it does not fit the frame's "
                             f"{x_hi - x_lo:.1f} × {y_hi - y_lo:.1f} mm (less the margins)")
        if x + w > x_hi + 1e-9:                      # next shelf
            x, y, shelf = x_lo, y + shelf + GAP, 0.0
        if y + h > y_hi + 1e-9:                      # next sheet
            sheet, x, y, shelf = sheet + 1, x_lo, y_lo, 0.0
        kappa = float(table_curvature(table, side, np.array([tau]), np.array([mu]))[0])
        coupons.append(Coupon(number=len(coupons) + 1, side=side, thickness=tau, spacing=mu, sheet=sheet,
                              x=round(x, 6), y=round(y, 6), width=w, height=h, rows=rows,
                              expected_kappa=kappa))
        x += w + GAP
        shelf = max(shelf, h)
    return coupons


def _passes(strokes: list[np.ndarray], width: float, height: float) -> tuple[RibbonPasses, RibbonPasses]:
    return (RibbonPasses([s for s in strokes], np.zeros(len(strokes), dtype=np.int64), width, height),
            RibbonPasses([s[::-1] for s in strokes[::-1]], np.zeros(len(strokes), dtype=np.int64), width, height))


def plan_sheet_side(design: Design, profile: PrinterProfile, side: str, labels: dict[int, list[np.ndarray]],
                    cuts: dict[int, list[np.ndarray]], *, move_budget: int = MOVE_BUDGET) -> SidePlan:
    """One side's passes in print order: the ribbons (as ``gcode.program.plan_side``), on the front the
    registration marks and the crop marks, and the labels of that side's coupons (``labels``: coupon
    number -> strokes, ``cuts`` likewise, front-side coordinates), ordered together."""
    p = design.parameters
    ribbons = design.ribbons or []
    nozzle, max_h = profile.extruder.nozzle_diameter, profile.layers.max_layer_height
    h0 = profile.layers.first_layer_height

    def coords(xy: np.ndarray) -> np.ndarray:
        xy = np.asarray(xy, dtype=float)
        return mirror(xy, profile.frame) if side == "back" else xy

    parts, kind, indices = [], [], []
    for i, r in enumerate(ribbons):
        if r.side != side:
            continue
        pts = coords(np.asarray(r.points))
        parts.append((ribbon_passes(pts, p.ribbon_width, r.thickness, nozzle, max_h),
                      ribbon_passes(pts[::-1], p.ribbon_width, r.thickness, nozzle, max_h)))
        kind.append("ribbon")
        indices.append(i)
    if side == "front":
        for m, xy in enumerate(design.registration_marks or []):
            parts.append(_passes(mark_passes(np.asarray(xy), MARK_SIZE, nozzle), nozzle, h0))
            kind.append("mark")
            indices.append(m)
        for n, strokes in cuts.items():
            parts.append(_passes(strokes, nozzle, h0))
            kind.append("cut")
            indices.append(n)
    for n, strokes in labels.items():
        parts.append(_passes([coords(s) for s in strokes], nozzle, h0))
        kind.append("label")
        indices.append(n)
    x0, y0, _, _ = profile.frame.bounds
    start = np.array([x0, y0])
    entry = np.array([[f.entry, r.entry] for f, r in parts]).reshape(-1, 2, 2)
    exit_ = np.array([[f.exit, r.exit] for f, r in parts]).reshape(-1, 2, 2)
    tour = order_ribbons(entry, exit_, start, move_budget=move_budget)
    return SidePlan(side=side, parts=[parts[k][int(tour.reversed[k])] for k in tour.order],
                    kind=[kind[k] for k in tour.order],
                    index=np.asarray([indices[k] for k in tour.order], dtype=np.int64), tour=tour,
                    source=design.source.file)


def _side_report(prog: Program) -> SidePrintReport:
    s = prog.stats
    return SidePrintReport(lines=s.lines, extrusion_mm=s.extrusion_mm, travel_mm=s.travel_mm, time_s=s.time_s,
                           filament_mm=s.filament_mm)


def _sheet_design(spec: CalibrationSpec, profile: PrinterProfile, number: int, coupons: list[Coupon],
                  marks: np.ndarray, digest: str, report_print: PrintReport | None) -> Design:
    x0, y0, x1, y1 = profile.frame.bounds
    params = Parameters.resolved(
        DesignParameters(prestretch=spec.prestretch, ribbon_length=spec.ribbon_length,
                         ribbon_width=spec.ribbon_width, printer_profile=spec.printer_profile,
                         curvature_table=spec.base_table),
        float(math.hypot(x1 - x0, y1 - y0)))
    ribbons = []
    for c in coupons:
        sign = 1.0 if c.side == "front" else -1.0
        for line in coupon_ribbons(spec, c):
            ribbons.append(Ribbon(side=c.side, points=[tuple(map(float, q)) for q in line], thickness=c.thickness,
                                  kappa1=sign * c.expected_kappa, spacing=(spec.mu1, c.spacing)))
    front = sum(r.side == "front" for r in ribbons)
    zero = Quantiles(median=0.0, p95=0.0)
    report = Report(faces=2, time_s=0.0, iterations=0, k1_deviation_deg=0.0, sigma1_max_dev=0.0,
                    sigma2_max_dev=0.0, sigma1_bad_pct=0.0, sigma2_bad_pct=0.0, avg_energy=0.0, timings_s={},
                    ribbons=RibbonsReport(front=front, back=len(ribbons) - front, dropped_short=0, trimmed_angle=0,
                                          thickness_clamped=0, direction_deviation_deg=zero, spacing_error_pct=zero),
                    print_=report_print)
    faces = Faces.from_arrays(np.ones(2), np.ones(2), np.array([[1.0, 0.0], [1.0, 0.0]]), np.zeros(2))
    return Design(source=Source(file=f"calibration-sheet-{number}", sha256=digest, faces=2), parameters=params,
                  faces=faces, ribbons=ribbons, registration_marks=[tuple(map(float, m)) for m in marks],
                  report=report)


def make_plan(spec: CalibrationSpec, *, move_budget: int = MOVE_BUDGET // 4) -> CalibrationPlan:
    """Lay out the coupons of ``spec`` and make each sheet's design and programs.

    Raises
    ------
    ValueError
        for an unknown profile or base table, a coupon that does not fit the frame, or a program the
        profile refuses (``GcodeError``).
    """
    profile = load_profile(spec.printer_profile)
    table = load_curvature_table(spec.base_table)
    if abs(table.prestretch - spec.prestretch) > 1e-9:
        raise ValueError(f"base_table {spec.base_table!r} was measured at s = {table.prestretch:g}, the plan asks "
                         f"for s = {spec.prestretch:g}: give a table at that pre-stretch as base_table (its values "
                         "are only the coupons' expected curvature)")
    coupons = layout(spec, profile)
    digest = hashlib.sha256(spec.model_dump_json().encode()).hexdigest()
    sheets = []
    for number in sorted({c.sheet for c in coupons}):
        mine = [c for c in coupons if c.sheet == number]
        cuts = {c.number: crop_marks(c) for c in mine}
        labels = {c.number: coupon_label(c, profile.frame.flip_axis) for c in mine}
        corners = np.concatenate([np.vstack(v) for v in cuts.values()])
        marks = registration_marks(corners, profile.frame, offset=5.0)
        design = _sheet_design(spec, profile, number, mine, marks, digest, None)
        front_labels = {c.number: labels[c.number] for c in mine if c.side == "front"}
        front = plan_sheet_side(design, profile, "front", front_labels, cuts, move_budget=move_budget)
        back_labels = {c.number: labels[c.number] for c in mine if c.side == "back"}
        back = plan_sheet_side(design, profile, "back", back_labels, {}, move_budget=move_budget)
        fp = render_side(front, profile)
        bp = render_side(back, profile) if back.parts else _empty_side(back, profile)
        combined = render_combined(front, back, profile)
        programs = Programs(front=fp, back=bp, combined=combined, front_plan=front, back_plan=back)
        design = _sheet_design(spec, profile, number, mine, marks, digest,
                               PrintReport(front=_side_report(fp), back=_side_report(bp)))
        sheets.append(Sheet(number=number, coupons=mine, design=design, programs=programs,
                            labels={s: [q for c in mine if c.side == s for q in labels[c.number]]
                                    for s in ("front", "back")},
                            cuts=[q for v in cuts.values() for q in v]))
    return CalibrationPlan(spec=spec, profile=profile, coupons=coupons, sheets=sheets,
                           created=time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()))


# ---------------------------------------------------------------------------------------------
# files


COUPON_COLUMNS = ("coupon", "side", "thickness_mm", "spacing_mm", "sheet", "x_mm", "y_mm", "width_mm",
                  "height_mm", "rows", "expected_kappa_per_mm")


def coupons_csv(coupons: list[Coupon]) -> str:
    """``coupons.csv``: one coupon a line; x, y the cut rectangle's lower left corner (front-side print
    coordinates, mm), the expected κ1 of the base table."""
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(COUPON_COLUMNS)
    for c in coupons:
        w.writerow([c.number, c.side, f"{c.thickness:g}", f"{c.spacing:g}", c.sheet, f"{c.x:.3f}", f"{c.y:.3f}",
                    f"{c.width:.3f}", f"{c.height:.3f}", c.rows, f"{c.expected_kappa:.6g}"])
    return out.getvalue()


def plan_json(plan: CalibrationPlan) -> str:
    return json.dumps({"format": PLAN_FORMAT, "created": plan.created, "profile": plan.profile.name,
                       "spec": plan.spec.model_dump(mode="json"),
                       "sheets": [{"sheet": s.number, "folder": f"sheet-{s.number}",
                                   "coupons": [c.number for c in s.coupons],
                                   "time_s": {"front": s.programs.front.stats.time_s,
                                              "back": s.programs.back.stats.time_s}} for s in plan.sheets],
                       "coupons": [dict(zip(COUPON_COLUMNS, (c.number, c.side, c.thickness, c.spacing, c.sheet, c.x,
                                                              c.y, c.width, c.height, c.rows, c.expected_kappa)))
                                   for c in plan.coupons]}, indent=1) + "\n"


def read_plan(folder: Path) -> dict[str, Any]:
    """``plan.json`` of a plan folder, checked for its format; ValueError naming the file."""
    path = Path(folder) / PLAN_FILE
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ValueError(f"{path}: missing: {folder} is not a calibration plan folder") from None
    except (OSError, ValueError) as exc:
        raise ValueError(f"{path}: cannot read the plan: {exc}") from None
    if not isinstance(data, dict) or data.get("format") != PLAN_FORMAT:
        raise ValueError(f"{path}: not a calibration plan ({PLAN_FORMAT})")
    return data


def write_plan(plan: CalibrationPlan, out: Path) -> Path:
    """Write the plan folder: ``plan.json``, ``coupons.csv``, ``sheet-K.svg``/``.png`` (the sheet maps),
    ``sheet-K/`` (each sheet's design folder, its map as the preview) and ``plans/sheet-K-front|back-plan.npz``."""
    from .sheetmap import sheet_png, sheet_svg

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    x0, y0, x1, y1 = plan.profile.frame.bounds
    P = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=float)
    F = np.array([[0, 1, 2], [0, 2, 3]])
    V = np.column_stack([P, np.zeros(4)])
    (out / "plans").mkdir(exist_ok=True)
    for s in plan.sheets:
        svg, png = sheet_svg(plan, s), sheet_png(plan, s)
        (out / f"sheet-{s.number}.svg").write_bytes(svg)
        (out / f"sheet-{s.number}.png").write_bytes(png)
        write_design_folder(out / f"sheet-{s.number}", target_V=V, target_F=F, flat_V=P, design=s.design,
                            extra_files={"front.gcode": s.programs.front.text.encode(),
                                         "back.gcode": s.programs.back.text.encode(),
                                         "combined.gcode": s.programs.combined.text.encode(),
                                         "preview.svg": svg, "preview.png": png})
        s.programs.front_plan.save(out / "plans" / f"sheet-{s.number}-front-plan.npz")
        s.programs.back_plan.save(out / "plans" / f"sheet-{s.number}-back-plan.npz")
    (out / COUPONS_FILE).write_text(coupons_csv(plan.coupons), encoding="utf-8")
    (out / PLAN_FILE).write_text(plan_json(plan), encoding="utf-8")
    return out
