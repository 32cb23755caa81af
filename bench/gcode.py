"""Benchmark of the G-code stage: ordering the ribbons and writing the programs, on designs of increasing size.

For each example surface (torus patch, saddle, cylinder of ``examples/meshes``, default resolution)
at two or three physical sizes (bounding-box diagonal 80 mm, 130 mm and ``--size fit``: the largest
the printer's frame and the curvature table allow), the design is made first (``design_mesh``: it is the input, not what is timed).
Then for each side with something to print: ``plan_side`` (the ordering, with its default budget
of ``MOVE_BUDGET`` candidate moves, and with a budget of 0: greedy and one 2-opt/Or-opt descent, no
kick) and ``render_side`` are timed apart, and the
travel between parts before and after ordering, the program's whole travel, its extrusion and its
estimated time are reported; also the corrected re-render of the back side that the daemon makes
after the flip.

Goals (per design, both sides together): travel at most 20 % of the extrusion length, and the
estimated print time within 1.25× the pure extrusion time at print speed (the physical limit).

    python bench/gcode.py [--quick] [--profile NAME]
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "examples" / "meshes"))

from ribbond.design.errors import DesignError, MeshError  # noqa: E402
from ribbond.design.format import Design  # noqa: E402
from ribbond.mesh.files import write_obj  # noqa: E402
from ribbond.design.params import DesignParameters, SizeSpec  # noqa: E402
from ribbond.pipeline.compile import design_mesh  # noqa: E402
from ribbond.gcode.ordering import MOVE_BUDGET  # noqa: E402
from ribbond.gcode.profiles import PrinterProfile, load_profile  # noqa: E402
from ribbond.gcode.program import Correction, GcodeError, mirror, plan_side, render_side  # noqa: E402

SURFACES = ("torus_patch", "saddle", "cylinder")
SIZES: tuple[float | None, ...] = (80.0, 130.0, None)      # None: --size fit (the frame and the curvature table)
SIDES = ("front", "back")
RENDER_REPEATS = 3              # render times: best of this many
CORRECTION = Correction(rotation_deg=0.5, center=(110.0, 110.0), offset=(0.3, -0.2))
GOAL_TRAVEL = 0.20
GOAL_TIME = 1.25


@dataclass
class SideRun:
    side: str
    parts: int
    ribbons: int
    plan_s: float
    improvements: int
    greedy_s: float
    greedy_after: float
    before: float
    after: float
    render_s: float
    lines: int
    travel: float
    extrusion: float
    time_s: float
    extrusion_time_s: float
    passes_ok: bool
    corrected_s: float | None = None
    nearest_sum: float = 0.0        # Σ over ribbons of the distance to the nearest end of another ribbon
    nearest_median: float = float("nan")


@dataclass
class DesignRun:
    surface: str
    size_label: str
    diagonal: float
    ribbons: int
    front: int
    back: int
    marks: int
    mean_length: float
    mean_lines: float
    mean_layers: float
    mean_passes: float
    design_s: float
    sides: list[SideRun] = field(default_factory=list)


def size_label(size: float | None) -> str:
    return "max" if size is None else f"{size:g}"


def passes_of(thickness: float, width: float, nozzle: float, max_layer_height: float) -> tuple[int, int]:
    """(lines, layers) of a ribbon: lines = max(1, round(w_r / nozzle)), layers = ceil(τ / max height)."""
    return max(1, round(width / nozzle)), max(1, math.ceil(thickness / max_layer_height - 1e-9))


def nearest_other_end(design: Design, side: str) -> np.ndarray:
    """(R,) per ribbon of ``side``: the distance from its nearer centerline end to the nearest end of
    another ribbon of that side, mm (the mirror of the back side keeps distances)."""
    ends = np.array([[r.points[0], r.points[-1]] for r in design.ribbons or [] if r.side == side], dtype=float)
    if len(ends) < 2:
        return np.zeros(len(ends))
    flat = ends.reshape(-1, 2)
    owner = np.repeat(np.arange(len(ends)), 2)
    dist, idx = cKDTree(flat).query(flat, k=min(4, len(flat)))
    dist = np.where(owner[idx] == owner[:, None], np.inf, dist)   # the ribbon's own ends do not count
    best = dist.min(axis=1)
    if not np.isfinite(best).all():                               # four nearest all its own: look further
        for k in np.flatnonzero(~np.isfinite(best)):
            other = owner != owner[k]
            best[k] = np.linalg.norm(flat[other] - flat[k], axis=1).min()
    return best.reshape(-1, 2).min(axis=1)


def run_side(design: Design, profile: PrinterProfile, side: str) -> SideRun | None:
    t = time.perf_counter()
    plan = plan_side(design, profile, side)
    plan_s = time.perf_counter() - t
    if not plan.parts:
        return None
    t = time.perf_counter()
    greedy = plan_side(design, profile, side, move_budget=0)
    greedy_s = time.perf_counter() - t
    render_s = math.inf
    for _ in range(RENDER_REPEATS):
        t = time.perf_counter()
        prog = render_side(plan, profile)
        render_s = min(render_s, time.perf_counter() - t)
    corrected_s = None
    if side == "back":
        corrected_s = math.inf
        for _ in range(RENDER_REPEATS):
            t = time.perf_counter()
            render_side(plan, profile, correction=CORRECTION)
            corrected_s = min(corrected_s, time.perf_counter() - t)
    # the planned passes agree with lines × layers
    p = design.parameters
    nozzle, max_h = profile.extruder.nozzle_diameter, profile.layers.max_layer_height
    ok = all(len(parts.paths) == math.prod(passes_of(design.ribbons[i].thickness, p.ribbon_width, nozzle, max_h))
             for parts, kind, i in zip(plan.parts, plan.kind, plan.index) if kind == "ribbon")
    nn = nearest_other_end(design, side)
    s = prog.stats
    return SideRun(side=side, parts=len(plan.parts), ribbons=len(plan.ribbons), plan_s=plan_s,
                   improvements=plan.tour.improvements, greedy_s=greedy_s,
                   greedy_after=greedy.tour.travel_after, before=plan.tour.travel_before,
                   after=plan.tour.travel_after, render_s=render_s, lines=s.lines, travel=s.travel_mm,
                   extrusion=s.extrusion_mm, time_s=s.time_s, extrusion_time_s=s.extrusion_time_s,
                   passes_ok=ok, corrected_s=corrected_s,
                   nearest_sum=float(nn.sum()), nearest_median=float(np.median(nn)) if len(nn) else float("nan"))


def describe(surface: str, size: float | None, design: Design, profile: PrinterProfile,
             design_s: float) -> DesignRun:
    ribbons = design.ribbons or []
    p = design.parameters
    nozzle, max_h = profile.extruder.nozzle_diameter, profile.layers.max_layer_height
    lp = np.array([passes_of(r.thickness, p.ribbon_width, nozzle, max_h) for r in ribbons],
                  dtype=float).reshape(-1, 2)
    length = np.array([np.linalg.norm(np.diff(np.asarray(r.points), axis=0), axis=1).sum() for r in ribbons])
    front = sum(r.side == "front" for r in ribbons)

    def mean(a: np.ndarray) -> float:
        return float(a.mean()) if len(a) else float("nan")

    return DesignRun(surface=surface, size_label=size_label(size), diagonal=p.size.bbox_diagonal,
                     ribbons=len(ribbons), front=front, back=len(ribbons) - front,
                     marks=len(design.registration_marks or []), mean_length=mean(length),
                     mean_lines=mean(lp[:, 0]), mean_layers=mean(lp[:, 1]), mean_passes=mean(lp[:, 0] * lp[:, 1]),
                     design_s=design_s)


def ratio(a: float, b: float) -> float:
    return a / b if b > 0 else float("nan")


def verdict(x: float, goal: float) -> str:
    return "met" if x <= goal else "NOT met"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true",
                    help=f"one size per surface ({size_label(SIZES[0])} mm; a smoke run)")
    ap.add_argument("--profile", default="ultimaker2-tpu", metavar="NAME",
                    help="printer profile, shipped name or .toml path (default ultimaker2-tpu)")
    args = ap.parse_args()
    try:
        profile = load_profile(args.profile)
    except (ValueError, OSError) as exc:
        ap.error(f"--profile {args.profile}: {exc}")
    sizes = SIZES[:1] if args.quick else SIZES

    from make_meshes import examples

    runs: list[DesignRun] = []
    failures: list[str] = []
    with tempfile.TemporaryDirectory() as tmp:
        meshes = {}
        for name in SURFACES:
            V, F = examples(1.0)[f"{name}.obj"][1]()
            meshes[name] = Path(tmp) / f"{name}.obj"
            write_obj(meshes[name], V, F, header=f"bench/gcode.py: {name}, scale 1")
        for name in SURFACES:
            for size in sizes:
                tag = f"[{name} {size_label(size)}]"
                print(f"{tag} designing ...", file=sys.stderr, flush=True)
                params = DesignParameters(size=None if size is None else SizeSpec(bbox_diagonal=size),
                                          printer_profile=args.profile)
                t = time.perf_counter()
                try:
                    design = design_mesh(meshes[name], params).design
                except (DesignError, MeshError, ValueError) as exc:
                    print(f"{tag} design FAILED", file=sys.stderr, flush=True)
                    failures.append(f"{name} {size_label(size)}: design: {exc}")
                    continue
                run = describe(name, size, design, profile, time.perf_counter() - t)
                print(f"{tag} {run.ribbons} ribbons ({run.front} front, {run.back} back) in {run.design_s:.1f} s; "
                      "planning and rendering ...", file=sys.stderr, flush=True)
                try:
                    for side in SIDES:
                        r = run_side(design, profile, side)
                        if r is not None:
                            run.sides.append(r)
                except GcodeError as exc:
                    print(f"{tag} G-code FAILED", file=sys.stderr, flush=True)
                    failures.append(f"{name} {size_label(size)}: G-code: {exc}")
                    continue
                runs.append(run)
                print(f"{tag} done: " + ", ".join(f"{s.side} plan {s.plan_s:.2f} s render {s.render_s:.3f} s"
                                                   for s in run.sides), file=sys.stderr, flush=True)

    print(f"profile {profile.name}: nozzle {profile.extruder.nozzle_diameter:g} mm, max layer "
          f"{profile.layers.max_layer_height:g} mm, print {profile.motion.print_speed:g} mm/s, travel "
          f"{profile.motion.travel_speed:g} mm/s, frame {profile.frame.size[0]:g} × {profile.frame.size[1]:g} mm")
    print("\ndesigns (the input; design time not part of the benchmark)")
    print(f"{'surface':<12} {'size':>5} {'diag mm':>7} {'ribbons':>7} {'front':>5} {'back':>5} {'marks':>5} "
          f"{'mean l_r':>8} {'lines':>5} {'layers':>6} {'passes':>6} {'design s':>8}")
    for d in runs:
        print(f"{d.surface:<12} {d.size_label:>5} {d.diagonal:>7.1f} {d.ribbons:>7} {d.front:>5} {d.back:>5} "
              f"{d.marks:>5} {d.mean_length:>8.2f} {d.mean_lines:>5.2f} {d.mean_layers:>6.2f} "
              f"{d.mean_passes:>6.2f} {d.design_s:>8.2f}")
    print("size: requested bounding-box diagonal (max = --size fit: the largest the frame and the curvature table allow), diag = the one used; "
          "mean l_r = mean centerline length, mm; lines, layers, passes = means per ribbon "
          "(lines = max(1, round(w_r / nozzle)), layers = ceil(τ / max layer height), passes = lines × layers)")

    print("\nper side: ordering (plan_side) and writing (render_side)")
    print(f"{'surface':<12} {'size':>5} {'side':<5} {'parts':>5} {'plan s':>7} {'impr':>4} {'greedy s':>8} "
          f"{'before':>7} {'greedy':>7} {'after':>7} {'travel':>7} {'extrude':>7} {'btw/ext':>7} "
          f"{'tot/ext':>7} {'t/t_ext':>7} {'render s':>8} {'lines':>6}")
    odd_passes = []
    for d in runs:
        for s in d.sides:
            print(f"{d.surface:<12} {d.size_label:>5} {s.side:<5} {s.parts:>5} {s.plan_s:>7.3f} "
                  f"{s.improvements:>4} {s.greedy_s:>8.3f} {s.before:>7.0f} {s.greedy_after:>7.0f} {s.after:>7.0f} "
                  f"{s.travel:>7.0f} "
                  f"{s.extrusion:>7.0f} {ratio(s.after, s.extrusion):>7.3f} {ratio(s.travel, s.extrusion):>7.3f} "
                  f"{ratio(s.time_s, s.extrusion_time_s):>7.3f} {s.render_s:>8.3f} {s.lines:>6}")
            if not s.passes_ok:
                odd_passes.append(f"{d.surface} {d.size_label} {s.side}")
    print(f"parts = ribbons + registration marks (front); plan s = plan_side with its default budget of "
          f"{MOVE_BUDGET:g} moves weighed (impr = 2-opt/Or-opt moves made), greedy s = with a budget of 0 (nearest "
          "neighbour, one descent, no kick); before / greedy / after = travel from the frame's corner and between parts, mm: "
          "in input order / greedy / after ordering; travel = the program's whole travel, mm (also from home, "
          "to park, and between a ribbon's passes); extrude = extrusion length, mm; btw/ext = after / extrude; "
          "tot/ext = travel / extrude; t/t_ext = estimated time / extrusion time at print speed; render s = "
          f"render_side, best of {RENDER_REPEATS}; lines = G-code commands")
    if odd_passes:
        print("ODD: the planned passes differ from lines × layers on: " + ", ".join(odd_passes))

    backs = [(d, s) for d in runs for s in d.sides if s.corrected_s is not None]
    if backs:
        print(f"\ncorrected re-render of the back side (render_side with correction: rotation "
              f"{CORRECTION.rotation_deg:g}° about {CORRECTION.center}, offset {CORRECTION.offset}; best of "
              f"{RENDER_REPEATS}):")
        for d, s in backs:
            print(f"{d.surface:<12} {d.size_label:>5} back: {s.parts} parts, {s.corrected_s:.3f} s "
                  f"(uncorrected {s.render_s:.3f} s)")
    else:
        print("\nno design has a back side: no corrected re-render timed")

    print("\nwhat limits the travel ratio: a ribbon printed in an even number of passes (lines × layers) is left "
          "at the end it was entered, so each ribbon costs about the distance to the nearest end of another "
          "ribbon (~6–9 mm in the staggered layout) against passes × l_r of printing; floor ≈ Σ nearest / "
          "extrusion (a rough lower estimate for any order):")
    print(f"{'surface':<12} {'size':>5} {'side':<5} {'ribbons':>7} {'nearest mm':>10} {'passes×l_r':>10} "
          f"{'floor':>6} {'btw/ext':>7}")
    for d in runs:
        for s in d.sides:
            if s.ribbons == 0:
                continue
            print(f"{d.surface:<12} {d.size_label:>5} {s.side:<5} {s.ribbons:>7} {s.nearest_median:>10.2f} "
                  f"{ratio(s.extrusion, s.ribbons):>10.1f} {ratio(s.nearest_sum, s.extrusion):>6.3f} "
                  f"{ratio(s.after, s.extrusion):>7.3f}")
    print("nearest mm = median over the side's ribbons of the distance from the nearer centerline end to the "
          "nearest end of another ribbon; passes×l_r = extrusion per ribbon, mm (marks included); floor = "
          "Σ nearest / extrusion: every ribbon but the last is left for another part, at best the nearest "
          "ribbon end (marks and the rails' offset from the centerline not counted)")

    print("\ngoals per design (both sides together; ribbons and mean passes per ribbon in parentheses):")
    for d in runs:
        if not d.sides:
            print(f"{d.surface:<12} {d.size_label:>5}: nothing to print")
            continue
        ext = sum(s.extrusion for s in d.sides)
        total = ratio(sum(s.travel for s in d.sides), ext)
        between = ratio(sum(s.after for s in d.sides), ext)
        tt = ratio(sum(s.time_s for s in d.sides), sum(s.extrusion_time_s for s in d.sides))
        head = f"{d.surface:<12} {d.size_label:>5} ({d.ribbons} ribbons, {d.mean_passes:.2f} passes):"
        print(f"{head} total travel/extrusion = {total:.3f} (goal ≤ {GOAL_TRAVEL:.2f}): "
              f"{verdict(total, GOAL_TRAVEL)}")
        print(f"{head} between-parts travel/extrusion = {between:.3f} (goal ≤ {GOAL_TRAVEL:.2f}): "
              f"{verdict(between, GOAL_TRAVEL)}")
        print(f"{head} time/extrusion-time = {tt:.3f} (goal ≤ {GOAL_TIME:.2f}): {verdict(tt, GOAL_TIME)}")

    if failures:
        print("\n" + "\n\n".join(failures), file=sys.stderr)
        print(f"\n{len(failures)} run(s) failed", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
