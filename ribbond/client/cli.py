"""``ribbonctl``: the command-line client.

``ribbonctl design MESH -o DIR [--size MM] [--params FILE] [--profile NAME]`` runs the design
engine locally (no daemon) and writes the design folder; with ``--panels auto|N [--seam-allowance MM]``
it cuts the target into panels and writes the project folder (``ribbond.panels.project``). The daemon commands (``submit``,
``status``, ``watch``, ``start``, ``pause``, ``resume``, ``cancel``, ``flip-done``, ``frame-ok``, ``align``,
``printer``, ``stop``) are in ``ribbond.client.commands``.
``ribbonctl predict DESIGN_DIR [--table NAME]`` predicts again the deployed shape of a
design folder, locally (``ribbond.pipeline.repredict``).

Exit status of ``design``: 0 the design was written (a design outside its stretch bounds is still
written, and the summary says so); 1 the design cannot be made as asked; 2 bad input (mesh,
parameters); 130 interrupted. ``predict``: 0 the prediction was replaced; 2 bad input (not a design
folder, a ``design.json`` that does not parse, an unknown table): nothing rewritten. ``predict --job ID``
asks the daemon (``POST /jobs/{id}/predict``) and follows it: 1 refused or failed, 4 no such job.
The daemon commands: see ``ribbond.client.commands``.
"""

from __future__ import annotations

import argparse
import importlib
import math
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

from ribbond.design.errors import DesignError, MeshError
from ribbond.design.verdict import project_verdict_lines
from .commands import add_commands, add_global_options
from .http import ClientError

if TYPE_CHECKING:
    from ribbond.design.format import LineFieldChoice
    from ribbond.pipeline.compile import DesignResult


class _Lazy:
    """A module imported on first use: the daemon commands must not load the design engine
    (numpy, scipy, matplotlib: over a second per command, several on a Raspberry Pi)."""

    def __init__(self, name: str) -> None:
        self._name = name

    def __getattr__(self, attr: str) -> Any:
        return getattr(importlib.import_module(self._name), attr)


np = _Lazy("numpy")


class TerminalProgress:
    """Prints one line per stage and a live iteration counter for the flattening (stderr)."""

    def __init__(self, stream: TextIO = sys.stderr, quiet: bool = False) -> None:
        self.stream = stream
        self.quiet = quiet
        self._bar: Any = None                 # a tqdm bar while the flattening runs

    def stage_started(self, stage: str, description: str) -> None:
        if self.quiet:
            return
        if stage in ("flatten", "deploy") and self.stream.isatty():
            from tqdm import tqdm

            self._bar = tqdm(desc=f"{stage:<9} iterations", unit="it", file=self.stream,
                             leave=False, dynamic_ncols=True, mininterval=0.2)

    def iteration(self, stage: str, iteration: int, change: float, energy: float) -> None:
        if self._bar is not None:
            self._bar.update(1)
            if stage == "deploy":                  # change: the fraction of the releases done
                self._bar.set_postfix_str(f"{100 * change:.0f} % released", refresh=False)
            elif iteration % 10 == 0:
                self._bar.set_postfix_str(f"mean Δσ {change:.1e}, energy {energy:.3g}", refresh=False)

    def close(self) -> None:
        """Take the live counter off the screen (also when a stage fails)."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def stage_finished(self, stage: str, seconds: float, summary: str) -> None:
        self.close()
        if not self.quiet:
            print(f"{stage:<9} {seconds:7.2f} s  {summary}", file=self.stream, flush=True)


def _line_field_line(c: LineFieldChoice) -> str:
    """The CLI's line on ``report.optimization.line_field``: which field the prediction chose."""
    paper = c.paper
    head = (f"line field  one family of curvature lines through the ambiguous saddle regions ({c.switched_pct:.0f} % "
            f"of their area off the largest |κ|) against the paper's largest |κ|: ")
    if c.one_family is None:
        return head + f"the paper's kept: {c.reason}"
    one = c.one_family
    return head + (f"predicted mean {paper.deviation_pct.mean:.2f} → {one.deviation_pct.mean:.2f} %, ∫K "
                   f"{paper.total_gaussian_curvature.predicted:+.2f} → {one.total_gaussian_curvature.predicted:+.2f}; "
                   + ("one family kept" if c.kept == "one_family" else "the paper's kept") + f" ({c.reason})")


def summary(result: DesignResult, out_dir: Path) -> str:
    """A one-screen summary of the design's report."""
    d = result.design
    r, p = d.report, d.parameters
    (lo1, hi1), (lo2, hi2) = p.bounds
    s1, s2 = result.flattening.sigma[:, 0], result.flattening.sigma[:, 1]
    w, h = result.flat_uv.max(axis=0) - result.flat_uv.min(axis=0)
    timings = ", ".join(f"{k} {v:.2f}" for k, v in r.timings_s.items())
    lines = [
        f"design      {out_dir}  (target.obj, flat.obj, design.json, front/back/combined.gcode, "
        "preview.svg/.png)",
        f"surface     {d.source.file}: {r.faces} faces, {p.size.bbox_diagonal:.1f} mm bounding-box "
        f"diagonal; flat layout {w:.1f} × {h:.1f} mm",
        size_line(r, p.size.bbox_diagonal),
        *([f"refined     {r.refined.from_faces:,} → {r.refined.faces:,} faces ({r.refined.method}; at most "
           f"{r.refined.offset_pct:.2f} % of the diagonal off the file's surface) for the layout"]
          if r.refined is not None else []),
        f"k1 field    {result.field.method}, λ = {p.smoothing_lambda:g}; {k1_undefined_text(result)}; "
        f"{len(result.field.singular_vertices)} singular vertices"
        + ("" if result.field.aligned else " (no curvature direction: arbitrary smooth field)"),
        *_deviation_line("field vs k1", r.field_k1_deviation_deg),
        f"flattening  {r.iterations} iterations, "
        + ("converged" if r.converged else "NOT converged (iteration cap)")
        + f", {1000 * (r.time_per_iteration_s or 0):.1f} ms per iteration",
        f"k1 deviation {r.k1_deviation_deg:.3f}° (mean angle to the principal stretch direction)",
        f"σ1  bounds [{lo1:.2f}, {hi1:.2f}]  range [{s1.min():.3f}, {s1.max():.3f}]  "
        f"outside {r.sigma1_bad_pct:.2f} % of faces, max deviation {r.sigma1_max_dev:.4f}",
        f"σ2  bounds [{lo2:.2f}, {hi2:.2f}]  range [{s2.min():.3f}, {s2.max():.3f}]  "
        f"outside {r.sigma2_bad_pct:.2f} % of faces, max deviation {r.sigma2_max_dev:.4f}",
        f"energy      {r.avg_energy:.3g} (Eq. 3 over the total area)",
    ]
    rr = r.ribbons
    if rr is not None and d.ribbons is not None:
        tau = np.array([rb.thickness for rb in d.ribbons]) if d.ribbons else np.zeros(1)
        lines += [
            f"ribbons     {rr.front} front, {rr.back} back; {rr.dropped_short} dropped (< "
            f"{p.min_ribbon_length:g} mm), {rr.trimmed_angle} trimmed (> {p.max_trim_angle:g}° off the field)"
            + (f"; {rr.rim} along the outline where the rim was bare (replacing {rr.rim_replaced} short pieces)"
               if rr.rim else ""),
            f"thickness   {tau.min():.2f}–{tau.max():.2f} mm from table {p.curvature_table!r}"
            + (f"; {rr.thickness_clamped} clamped to its range" if rr.thickness_clamped else ""),
            f"layout      direction deviation median {rr.direction_deviation_deg.median:.2f}°, "
            f"p95 {rr.direction_deviation_deg.p95:.2f}° (from the field); spacing error median "
            f"{rr.spacing_error_pct.median:.1f} %, p95 {rr.spacing_error_pct.p95:.1f} % (Eq. 10)",
            *_deviation_line("ribbons vs k1", r.ribbon_k1_deviation_deg),
        ]
        if rr.spacing_error_across_pct is not None and rr.spacing_error_along_pct is not None:
            lines.append(f"spacing     across median {rr.spacing_error_across_pct.median:.1f} %, p95 "
                         f"{rr.spacing_error_across_pct.p95:.1f} % (gap to the next centerline against the "
                         f"harmonic mean of μ2); along median {rr.spacing_error_along_pct.median:.1f} %, p95 "
                         f"{rr.spacing_error_along_pct.p95:.1f} %")
    if r.deployed is not None:
        dv = r.deployed
        from ribbond.design.verdict import deployed_figures
        lines.append(f"deployed    {deployed_figures(dv.model_dump(exclude_none=True))} ({dv.faces} faces, "
                     f"{dv.iterations} Newton iterations, {dv.time_s:.1f} s); {out_dir}/deployed.png")
    if r.optimization is not None:
        o = r.optimization
        fo, op = o.forward, o.optimized
        if o.line_field is not None:
            lines.append(_line_field_line(o.line_field))
        lines.append(f"optimized   {', '.join(o.variables)}: predicted mean {fo.deviation_pct.mean:.2f} → "
                     f"{op.deviation_pct.mean:.2f} %, ∫K {fo.total_gaussian_curvature.predicted:+.2f} → "
                     f"{op.total_gaussian_curvature.predicted:+.2f} (target {op.total_gaussian_curvature.target:+.2f}); "
                     f"{o.iterations} iterations, {o.time_s:.1f} s; "
                     + (f"kept ({o.reason})" if o.kept else f"NOT kept, the forward layout is the design: {o.reason}"))
    pr = r.print_
    if pr is not None:
        for side, sp in (("front", pr.front), ("back", pr.back)):
            lines.append(f"{side + ' G-code':<11} {sp.lines} lines, ~{sp.time_s / 60:.1f} min, "
                         f"{sp.extrusion_mm:.0f} mm printed, {sp.travel_mm:.0f} mm travel, "
                         f"{sp.filament_mm:.0f} mm filament" if sp.lines else f"{side + ' G-code':<11} nothing to print")
    lines += [f"preview     {out_dir / 'preview.png'}",
              f"time        {r.time_s:.2f} s ({timings})"]
    lines += verdict_text({"report": r.model_dump(mode="json", by_alias=True),
                           "parameters": p.model_dump(mode="json")})
    return "\n".join(lines)


def k1_undefined_text(result: DesignResult) -> str:
    """Where k1 is not defined (anisotropy ≤ 0.3, ``report.umbilic_pct``), split by why (issue 34): a
    symmetric saddle's faces (|κ1| ≈ |κ2|, opposite signs) are not umbilic, their ribbon direction is
    ambiguous."""
    from ribbond.design.line_field import ANISOTROPY_THRESHOLD
    from ribbond.design.report import umbilic_split

    diagonal = float(np.linalg.norm(result.V.max(axis=0) - result.V.min(axis=0)))
    split = umbilic_split(result.curvature.kappa1, result.curvature.kappa2, result.field.anisotropy,
                          ANISOTROPY_THRESHOLD, 0.1 / max(diagonal, 1e-300))   # line_field's flat floor
    low, ambiguous = split["umbilic_pct"], split["ambiguous_pct"]
    if low == 0:
        return "k1 defined on every face (anisotropy > 0.3)"
    parts = [f"{ambiguous:.1f} % ribbon direction ambiguous (|κ1| ≈ |κ2|, opposite signs)"] if ambiguous else []
    if low - ambiguous > 0:
        parts.append(f"{low - ambiguous:.1f} % umbilic or flat (|κ1| ≈ |κ2|, same sign)")
    return f"k1 undefined on {low:.1f} % of faces (anisotropy ≤ 0.3): " + ", ".join(parts)


def verdict_text(design: dict[str, Any]) -> list[str]:
    """The design's verdict lines (``ribbond.design.verdict``), each labelled ``verdict``: the same
    lines ``submit``, ``status`` and the dashboard show."""
    from ribbond.design.verdict import verdict_lines

    return [f"verdict     {line}" for line in verdict_lines(design)]


def _deviation_line(what: str, dev: Any) -> list[str]:
    """The summary line of a deviation from the target's k1 (None: no face where k1 is defined)."""
    if dev is None:
        return [f"{what + ':':<15}not measured: k1 is nowhere well defined (anisotropy ≤ 0.3 on every face)"]
    return [f"{what + ':':<15}median {dev.median:.2f}°, mean {dev.mean:.2f}°, p95 {dev.p95:.2f}° "
            "(on faces where k1 is defined: anisotropy > 0.3)"]


def _cmd_design(args: argparse.Namespace) -> int:
    # the engine is imported here only: the daemon commands start without it
    from ribbond.design.params import DesignSettings, SizeSpec, load_settings
    from ribbond.design.folder import check_destination
    from ribbond.pipeline.compile import design_mesh, write_design
    from ribbond.gcode.profiles import load_profile

    settings = load_settings(args.params) if args.params else DesignSettings()
    params = settings.parameters
    updates: dict[str, object] = {}
    size = _size_argument(args.size, args.panels is not None)
    if size is not None:
        updates["size"] = SizeSpec(bbox_diagonal=size)
    if args.profile is not None:
        updates["printer_profile"] = args.profile
    if updates:
        params = params.model_validate({**params.model_dump(), **updates})
    frame = load_profile(params.printer_profile).frame
    solver = settings.solver if args.optimize else settings.solver.model_copy(update={"optimize": False})
    if args.panels is not None:
        return _design_project(args, params, solver)
    check_destination(args.output)              # before the design's minutes, not after them
    progress = TerminalProgress(quiet=args.quiet)
    try:
        # SIZE_RULE: without --size (nor a size in --params) the file's units are mm, as with --panels
        result = design_mesh(args.mesh, params, solver, frame=frame, progress=progress,
                             predict=not args.no_predict, optimize=args.optimize,
                             unsized="fit" if args.size == "fit" else "file")
        out = write_design(result, args.output, progress)
    finally:
        progress.close()
    print(summary(result, out))
    return 0


#: How ``design`` sizes a target, for a design and a project alike (``--help``).
SIZE_RULE = ("the target's size: its bounding-box diagonal in mm, or 'fit' (one design, not --panels: the "
             "largest size at which its layout fits the printer's frame). Without it (and without a size in "
             "--params) the file's units are read as mm, for a design and for --panels alike; a design "
             "larger than one sheet takes is refused, naming the largest size that fits. The summary's "
             "'size' line and design.json's report.scale say which rule gave the size")


def _size_argument(value: str | None, panels: bool) -> float | None:
    """``--size``: a diagonal in mm, ``fit`` (None here: the engine fits it) or absent (None)."""
    if value is None or value == "fit":
        if value == "fit" and panels:
            raise ValueError("--size fit: a project's panels keep one scale, and more panels make any size fit; "
                             "give --size MM, or leave it out to read the file's units as mm")
        return None
    try:
        size = float(value)
    except ValueError:
        raise ValueError(f"--size {value}: a bounding-box diagonal in mm, or 'fit'") from None
    if not math.isfinite(size) or size <= 0:
        raise ValueError(f"--size {value}: must be a finite number of mm > 0, or 'fit'")
    return size


def size_line(report: Any, bbox_diagonal: float) -> str:
    """The summary's ``size`` line: the design's size and the rule that gave it (``report.scale``)."""
    sc = report.scale
    if sc is None:
        return f"size        {bbox_diagonal:.1f} mm bounding-box diagonal"
    source = f"the file's {sc.source_diagonal:.4g} (its units)"
    why = {"size": f"as asked (--size or --params): {source} scaled × {sc.factor:.4g}",
           "fit": f"SCALED × {sc.factor:.4g} from {source} to the largest "
                  + (f"whose curvature the plastic can make: at the {sc.frame_diagonal:.0f} mm the frame would take, the "
                     "target is flatter than the thinnest plastic curls" if sc.limited_by == "curvature table"
                     else "that fits the frame")
                  + " (--size fit, or no size given to the daemon); --size MM to choose",
           "file": "the file's units read as mm (no --size); --size MM to scale it, --size fit for the largest "
                   "the frame and the curvature table allow"}[sc.rule]
    return f"size        {bbox_diagonal:.1f} mm bounding-box diagonal: {why}"


def _design_project(args: argparse.Namespace, params: Any, solver: Any) -> int:
    """``ribbonctl design MESH --panels auto|N``: the project folder (project.json, panels.png,
    panel-K/ design folders) and its summary."""
    import json

    from ribbond.panels.project import check_project_destination, design_project, write_project

    panels: int | str = args.panels
    if panels != "auto":
        if not str(panels).isdigit() or int(panels) < 2:
            raise ValueError(f"--panels {panels}: 'auto' or a whole number of panels, at least 2")
        panels = int(panels)
    check_project_destination(args.output)      # before the cut and the panels' designs
    progress = TerminalProgress(quiet=args.quiet)
    try:
        result = design_project(args.mesh, params, solver, panels=panels, seam_allowance=args.seam_allowance,
                                progress=progress, predict=not args.no_predict)
        out = Path(write_project(result, args.output, progress))
    finally:
        progress.close()
    project = json.loads((out / "project.json").read_text(encoding="utf-8"))
    first, *rest = project_summary(project, out).split("\n")
    diagonal = float(project["size"]["bbox_diagonal"])
    why = ("as asked (--size or --params)" if params.size is not None else
           "the file's units read as mm (no --size); --size MM to scale it")
    print("\n".join([first, f"size        {diagonal:.1f} mm bounding-box diagonal: {why}", *rest]))
    return 0


def project_summary(project: dict[str, Any], out: Path) -> str:
    """The project's summary: its panels (size, faces, outside the bounds), seams and files."""
    report = project.get("report") or {}
    lines = [f"project     {out}  ({len(project['panels'])} panels, {report.get('method', '')}, "
             f"{report.get('time_s', 0):.1f} s)"]
    for q in project["panels"]:
        w, h = q.get("flat_size_mm") or (0.0, 0.0)
        lines.append(f"panel {q['index']:<5} {out / q['folder']}: {q.get('faces')} faces, flat {w:.0f} × {h:.0f} mm, "
                     f"{q.get('bad_pct', 0):.1f} % outside the bounds")
    for s in project.get("seams") or []:
        target = (s.get("length_mm") or {}).get("target")
        deployed = (s.get("length_mm") or {}).get("deployed")
        lines.append(f"seam {s['label']:<6} panels {' and '.join(map(str, s['panels']))}"
                     + (f", {target:.0f} mm" if isinstance(target, (int, float)) else "")
                     + (f", predicted {deployed[0]:.1f} / {deployed[1]:.1f} mm ({s['mismatch_pct']:.1f} % apart)"
                        if deployed and s.get("mismatch_pct") is not None else "")
                     + (f", {s['marks']} stitch marks" if s.get("marks") else ""))
    deployed = report.get("deployed")
    if deployed:
        dev = deployed.get("deviation_pct") or {}
        lines.append(f"deployed    deviation mean {dev.get('mean', 0):.2f} %, p99 {dev.get('p99', 0):.2f} %, "
                     f"max {dev.get('max', 0):.2f} % of the diagonal")
    lines.append(f"panel map   {out / 'panels.png'}; seam allowance {project.get('seam_allowance_mm', 0):g} mm")
    if (out / "deployed.png").is_file():
        lines.append(f"sewn        {out / 'deployed.png'} (the panels as predicted, sewn and registered on the target)")
    lines += [f"verdict     {line}" for line in project_verdict_lines(project)]
    return "\n".join(lines)


class PredictProgress:
    """The re-prediction's progress on stderr: a bar on a terminal, a line per tenth elsewhere."""

    def __init__(self, stream: TextIO = sys.stderr, quiet: bool = False) -> None:
        self.stream, self.quiet = stream, quiet
        self._bar: Any = None
        self._shown = -1

    def __call__(self, fraction: float, message: str) -> None:
        if self.quiet:
            return
        if self.stream.isatty():
            if self._bar is None:
                from tqdm import tqdm

                self._bar = tqdm(total=100, desc="predict", unit="%", file=self.stream, leave=False,
                                 dynamic_ncols=True, mininterval=0.2)
            self._bar.n = round(100 * fraction)
            self._bar.set_postfix_str(message, refresh=True)
        elif int(10 * fraction) > self._shown:
            self._shown = int(10 * fraction)
            print(f"predict  {100 * fraction:3.0f} %  {message}", file=self.stream, flush=True)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None


def prediction_text(deployed: dict[str, Any], verdict: list[str], files: list[Path]) -> str:
    """What ``ribbonctl predict`` prints: the figures of ``verdict.deployed_parts`` (reached first), the
    verdict lines after the first, and the files."""
    from ribbond.design.verdict import deployed_parts

    parts = deployed_parts(deployed)
    lines = [f"{label:<11} {text}" for label, text in parts[:1] if label == "reached"]
    lines += [f"verdict     {line}" for line in verdict]
    what = f"{deployed.get('model', 'homogenized')} model" + (f", table {deployed['table']!r}" if deployed.get("table") else "")
    lines += [f"{label:<11} {text}" for label, text in parts if label != "reached"]
    lines[-1] += f" ({what}; {deployed['faces']} faces, {deployed['time_s']:.1f} s)"
    lines.append(f"files       {', '.join(str(f) for f in files)}")
    return "\n".join(lines)


def _predict_job(args: argparse.Namespace) -> int:
    """``ribbonctl predict --job ID``: POST /jobs/ID/predict, its progress followed until it ends."""
    import time

    from .http import _client

    c = _client(args)
    body: dict[str, Any] = {"table": args.table} if args.table else {}
    job = c.request("POST", f"/jobs/{args.job}/predict", json=body)
    progress = PredictProgress(quiet=args.quiet)
    try:
        while (job.get("prediction") or {}).get("state") == "running":
            p = job["prediction"]
            progress(float(p.get("fraction") or 0.0), str(p.get("message") or ""))
            time.sleep(0.5)
            job = c.request("GET", f"/jobs/{args.job}")
    finally:
        progress.close()
    p = job.get("prediction") or {}
    if p.get("state") != "done":
        raise ClientError(f"the prediction of job {args.job} failed: {p.get('error') or 'no result'}", 1)
    _print_prediction(args, p["deployed"], p.get("verdict") or [],
                      [Path(job["design_dir"]) / n for n in ("design.json", "deployed.obj", "deployed.png")])
    return 0


def _print_prediction(args: argparse.Namespace, deployed: dict[str, Any], verdict: list[str],
                      files: list[Path]) -> None:
    if getattr(args, "json", False):
        import json

        print(json.dumps({"deployed": deployed, "verdict": verdict, "files": [str(f) for f in files]}))
    else:
        print(prediction_text(deployed, verdict, files))


def _cmd_predict(args: argparse.Namespace) -> int:
    from ribbond.pipeline.repredict import repredict_folder

    if (args.design_dir is None) == (args.job is None):
        raise ValueError("give either a design folder or --job ID (a job of the daemon)")
    if args.job is not None:
        return _predict_job(args)
    progress = PredictProgress(quiet=args.quiet)
    try:
        done = repredict_folder(args.design_dir, table=args.table, progress=progress)
    finally:
        progress.close()
    _print_prediction(args, done.deployed, done.verdict, list(done.files))
    return 0


def _floats(text: str) -> list[float]:
    try:
        return [float(v) for v in text.replace(",", " ").split()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: a comma-separated list of numbers (mm)") from None


def _spec_from_args(args: argparse.Namespace) -> dict[str, Any]:
    spec: dict[str, Any] = {}
    for key in ("thicknesses", "spacings", "mu1", "prestretch", "fabric", "material", "base_table"):
        value = getattr(args, key, None)
        if value is not None:
            spec[key] = value
    if args.sides is not None:
        spec["sides"] = [s.strip() for s in args.sides.split(",") if s.strip()]
    if args.profile is not None:
        spec["printer_profile"] = args.profile
    return spec


def _cmd_calibrate_plan(args: argparse.Namespace) -> int:
    from .tables import calibrate_remote

    spec = _spec_from_args(args)
    if args.output is None:
        return calibrate_remote(args, spec)
    from pydantic import ValidationError

    from ribbond.calibration.plan import make_plan, write_plan
    from ribbond.calibration.spec import CalibrationSpec

    try:
        cal = CalibrationSpec.model_validate(spec)
    except ValidationError as exc:
        raise ValueError("; ".join(f"{'.'.join(map(str, e['loc']))}: {e['msg']}" for e in exc.errors())) from None
    plan = make_plan(cal)
    out = write_plan(plan, args.output)
    print(f"{len(plan.coupons)} coupons ({', '.join(cal.sides)}) on {len(plan.sheets)} sheet(s) of "
          f"{plan.profile.name}'s frame, in {out}:\n  coupons.csv, sheet-K.svg/.png (which coupon is which), "
          f"sheet-K/ (a two-sided design folder per sheet: front.gcode, back.gcode, combined.gcode)\n"
          f"  after release and cutting, measure each coupon (chord_mm and sagitta_mm, or radius_mm) and run\n"
          f"  ribbonctl calibrate record {out} measurements.csv -o my-table.toml")
    return 0


def _cmd_calibrate_record(args: argparse.Namespace) -> int:
    import json
    import time

    from ribbond.calibration.fit import design_mu2_range, fit_table, parse_measurements, plot_fit
    from ribbond.calibration.plan import read_plan
    from ribbond.design.thickness import TABLE_NAME

    plan_path = Path(args.plan)
    if plan_path.is_dir():
        plan = read_plan(plan_path)
    else:
        from .tables import fetch_plan

        got = fetch_plan(args, args.plan)
        plan = got if isinstance(got, dict) else json.loads(got)
    try:
        text = Path(args.measurements).read_text(encoding="utf-8")
    except OSError as exc:
        raise ValueError(f"{args.measurements}: {exc.strerror or exc}") from None
    measured = parse_measurements(text, {c["coupon"] for c in plan["coupons"]}, where=str(args.measurements))
    name = args.name or (args.output.stem if args.output else None)
    if not name or not TABLE_NAME.match(name):
        raise ValueError(f"table name {name!r}: give --name (letters, digits, '-', '_')")
    spec = plan["spec"]
    fit = fit_table(plan, measured, name=name, fabric=args.fabric or "", material=args.material or "",
                    date=time.strftime("%Y-%m-%d"),
                    design_mu2=design_mu2_range(spec["ribbon_length"], spec["ribbon_width"], spec["prestretch"]))
    out = args.output or Path(f"{name}.toml")
    out.write_text(fit.text, encoding="utf-8")
    png = out.with_suffix(".png")
    plot_fit(fit, png)
    lines = [f"table {name!r} from {fit.measured} coupons ({len(fit.failed)} failed"
             + (f": {', '.join(map(str, fit.failed))}" if fit.failed else "") + f"): {out}, plot {png}"]
    lines += [f"  {s}: residuals RMS {f.rms:.3g} 1/mm, largest {f.max_abs:.3g} 1/mm (what the monotone fit pooled); "
              f"leave-one-out RMS {f.loo_rms:.3g} 1/mm" for s, f in fit.sides.items()]
    lines += [f"  warning: {w}" for w in fit.warnings]
    if args.add:
        from .tables import add_table_text

        add_table_text(args, fit.text)
        lines.append(f"  added to the daemon: designs use it with curvature_table = \"{name}\"")
    print("\n".join(lines))
    return 0


EPILOG = """exit status: 0 done; 1 refused (the job's state or the printer does not allow it now, the
alignment is refused, the job failed); 2 bad input (also a missing or wrong API token); 3 the
daemon cannot be reached; 4 no such job;
130 interrupted; 141 the output was closed. 'ribbonctl COMMAND --help' describes each command."""


def _version() -> str:
    try:
        from importlib.metadata import version

        return version("ribbond")
    except Exception:  # noqa: BLE001 - not installed: the package's own number
        from ribbond import __version__

        return __version__


class _Parser(argparse.ArgumentParser):
    """Usage errors in one line, exit status 2 (as every bad input)."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="ribbonctl", epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter,
        description="ribbonctl: design self-actuated surfaces locally (design), and drive the ribbond "
                    "daemon and its printer (every other command).")
    parser.add_argument("--version", action="version", version=f"ribbonctl {_version()}")
    add_global_options(parser, in_subcommand=False)
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    d = sub.add_parser("design", help="compute a design locally (no daemon) and write its folder",
                       description="Compute the design of a target surface and write the design "
                                   "folder: target.obj, flat.obj, design.json.")
    d.add_argument("mesh", type=Path, help="target surface: OBJ, PLY, STL or OFF (a topological disk)")
    d.add_argument("-o", "--output", type=Path, required=True, help="design folder to write")
    d.add_argument("--size", metavar="MM|fit", help=SIZE_RULE)
    d.add_argument("--params", type=Path, metavar="FILE",
                   help="TOML or JSON file of design parameters (and an optional [solver] table)")
    d.add_argument("--profile", metavar="NAME", help="printer profile name or .toml path")
    d.add_argument("--no-predict", action="store_true",
                   help="skip the prediction of the deployed shape (deployed.obj, deployed.png)")
    d.add_argument("--no-optimize", dest="optimize", action="store_false",
                   help="the paper's forward design: the ribbons' thicknesses not optimized against the prediction "
                        "(stage optimize, on by default with the prediction; up to [solver] optimize_budget_s, and "
                        "kept only where the optimized layout's own prediction is better)")
    d.add_argument("-q", "--quiet", action="store_true", help="print only the summary")
    d.add_argument("--panels", metavar="auto|N", help="cut the target into panels and write a project folder "
                   "(project.json, panels.png, panel-1/ ...: each an ordinary design folder)")
    d.add_argument("--seam-allowance", type=float, default=6.0, metavar="MM",
                   help="with --panels: fabric left around each panel for its seams (default 6 mm)")
    d.set_defaults(func=_cmd_design)
    predict_common = argparse.ArgumentParser(add_help=False)
    add_global_options(predict_common, in_subcommand=True)
    pr = sub.add_parser("predict", parents=[predict_common],
                        help="predict again the deployed shape of a design folder (locally, or a job's with --job)",
                        description="Predict again the deployed shape of a design folder as its files are "
                                    "(ribbons and thicknesses as in design.json), and replace deployed.obj, "
                                    "deployed.png and report.deployed atomically. The ribbons, the G-code and "
                                    "parameters.curvature_table are left as they are.")
    pr.add_argument("design_dir", type=Path, nargs="?", help="a design folder written by ribbonctl design")
    pr.add_argument("--job", metavar="ID", help="predict a daemon job's design instead (POST /jobs/ID/predict)")
    pr.add_argument("--table", metavar="NAME",
                    help="curvature table name or .toml path for the prediction (default: the design's); "
                         "recorded as report.deployed.table")
    pr.add_argument("-q", "--quiet", action="store_true", help="print only the result")
    pr.set_defaults(func=_cmd_predict)
    add_commands(sub)
    common = argparse.ArgumentParser(add_help=False)
    add_global_options(common, in_subcommand=True)
    cal = sub.add_parser("calibrate", help="coupons to measure your own curvature table (plan, record)",
                         description="Calibration (issue 15): plan coupons, print them, measure them, fit a table.")
    csub = cal.add_subparsers(dest="calibrate_command", required=True, metavar="STEP")
    cp = csub.add_parser("plan", parents=[common], help="coupons laid out on sheets (-o DIR: locally; else the daemon)")
    cp.add_argument("-o", "--output", type=Path, help="write the plan folder here (no daemon)")
    cp.add_argument("--profile", metavar="NAME", help="printer profile (locally; the daemon uses its own)")
    cp.add_argument("--thicknesses", type=_floats, metavar="T,T,...", help="τ values, mm (default the paper's 8)")
    cp.add_argument("--spacings", type=_floats, metavar="M,M,...", help="μ2 values, mm (default the paper's 6)")
    cp.add_argument("--sides", metavar="front,back", help="sides to calibrate (default both)")
    cp.add_argument("--mu1", type=float, metavar="MM", help="spacing along the ribbons (default 22.5 mm)")
    cp.add_argument("--prestretch", type=float, metavar="S", help="the fabric's pre-stretch (default 1.6)")
    cp.add_argument("--base-table", dest="base_table", metavar="NAME", help="expected κ1 from this table")
    cp.add_argument("--fabric", help="the fabric (provenance)")
    cp.add_argument("--material", help="the filament (provenance)")
    cp.add_argument("--start", action="store_true", help="(daemon) print the first sheet at once")
    cp.set_defaults(func=_cmd_calibrate_plan)
    cr = csub.add_parser("record", parents=[common], help="measurements in, a fitted curvature table out")
    cr.add_argument("plan", help="a local plan folder, or a daemon calibration id (cal-…) or one of its jobs")
    cr.add_argument("measurements", type=Path, help="CSV: coupon, chord_mm, sagitta_mm or radius_mm")
    cr.add_argument("-o", "--output", type=Path, help="the table file to write (default NAME.toml)")
    cr.add_argument("--name", help="the table's name (default: the output file's stem)")
    cr.add_argument("--fabric", help="the fabric (provenance)")
    cr.add_argument("--material", help="the filament (provenance)")
    cr.add_argument("--add", action="store_true", help="also add the table to the daemon (ribbonctl tables add)")
    cr.set_defaults(func=_cmd_calibrate_record)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if isinstance(getattr(args, "size", None), float) and not (math.isfinite(args.size) and args.size > 0):
        parser.error(f"--size {args.size}: must be a positive number of millimetres")
    try:
        return args.func(args)
    except BrokenPipeError:
        # the reader went away (ribbonctl status | head): quietly, without a traceback at exit
        with open(os.devnull, "w") as devnull:
            os.dup2(devnull.fileno(), sys.stdout.fileno())
        return 141
    except OSError as exc:
        print(f"ribbonctl {args.command}: {exc.filename + ': ' if exc.filename else ''}{exc.strerror or exc}",
              file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("ribbonctl: interrupted" + ("; nothing was written" if args.command in ("design", "predict") else ""),
              file=sys.stderr)
        return 130
    except ClientError as exc:
        print(f"ribbonctl {args.command}: {exc}", file=sys.stderr)
        return exc.code
    except DesignError as exc:
        print(f"ribbonctl {args.command}: cannot make this design: {exc}", file=sys.stderr)
        return 1
    except (MeshError, ValueError) as exc:
        print(f"ribbonctl {args.command}: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
