"""The design engine from a mesh file to the design folder, stage by stage.

Stages: ``load`` (read, clean, validate, scale), ``curvature`` (principal curvatures and the k1
line field), ``flatten`` (the bounded directional flattening, placed in the printer frame),
``stripes`` (spacing by Eq. 10 and the two stripe patterns), ``ribbons`` (the staggered ribbons,
their sides and thicknesses, the registration marks), ``gcode`` (the print programs), ``deploy``
(the predicted deployed shape, ``ribbond.deploy``), ``preview`` and ``write`` (the design folder). The arrays stay in the functions of the stage modules; this module only wires them
together, times them and reports progress.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np
import shapely

from ..deploy.predict import RELEASES, Prediction, predict_deployed
from ..gcode.profiles import FrameSpec, PrinterProfile, load_profile
from ..gcode.program import GcodeError, Programs, make_programs
from . import linalg
from .curvature import Curvature, face_curvature
from .errors import DesignError
from .flatten import BoundedFlattener, FlatteningResult
from .folder import write_design_folder
from .format import (DeployedReport, Deviation, Design, Faces, Parameters, PrintReport, Quantiles, RefinedReport,
                     Report, Ribbon, RibbonsReport, SidePrintReport, Source)
from .frames import face_frames
from .intake import TargetMesh, load_target
from .mesh_io import obj_bytes
from .line_field import ANISOTROPY_THRESHOLD, LineField, curvature_line_field, field_k1_deviation
from .params import DesignParameters, SolverSettings, check_printable, check_smoothing
from .placement import fit_scale, place_in_frame, registration_marks
from .preview import render_preview
from .refine import refine_target
from .report import flattening_report
from .ribbons import RibbonLayout, StripeGrid, layout_ribbons, ribbon_quantiles, stripe_grid
from .thickness import CurvatureTable, load_curvature_table, ribbon_thickness

#: How far outside the layout's bounding box the registration marks sit, mm.
MARK_OFFSET = 5.0

#: The size at which a surface is flattened when ``size`` is left to the frame (the flattening
#: is scale-invariant: the result is scaled afterwards).
NOMINAL_DIAGONAL = 100.0


class DesignProgress(Protocol):
    """Receives progress from the engine (the CLI prints it, the daemon publishes it)."""

    def stage_started(self, stage: str, description: str) -> None: ...

    def iteration(self, stage: str, iteration: int, change: float, energy: float) -> None: ...

    def stage_finished(self, stage: str, seconds: float, summary: str) -> None: ...


class NoProgress:
    """Progress that goes nowhere."""

    def stage_started(self, stage: str, description: str) -> None:
        pass

    def iteration(self, stage: str, iteration: int, change: float, energy: float) -> None:
        pass

    def stage_finished(self, stage: str, seconds: float, summary: str) -> None:
        pass


@dataclass(frozen=True)
class DesignResult:
    """Everything the engine computed for one design.

    Attributes
    ----------
    target : the cleaned target mesh, scaled to its physical size (V in mm).
    flat_uv : (n, 2) the flat surface in front-side print coordinates, mm.
    curvature, field, flattening : the stages' results (κ in 1/mm at the physical size).
    kappa1 : (m,) signed normal curvature of the target along the ribbon direction, 1/mm.
    ribbon_direction : (m, 2) unit k̄1 in print coordinates.
    stripes : the stripe patterns (on a triangulation of the flat domain at their own resolution).
    layout : the ribbons before thickness (``design.ribbons`` holds the final ones).
    frame : the printable rectangle the design was placed in.
    design : the ``design.json`` content.
    programs : the G-code programs (front, back, combined) and their plans.
    preview_svg, preview_png : the layout preview.
    prediction : the predicted deployed shape (None when not asked for); deployed_png : its picture.
    """

    target: TargetMesh
    V: np.ndarray
    F: np.ndarray
    flat_uv: np.ndarray
    curvature: Curvature
    field: LineField
    flattening: FlatteningResult
    kappa1: np.ndarray
    ribbon_direction: np.ndarray
    stripes: StripeGrid
    layout: RibbonLayout
    frame: FrameSpec
    design: Design
    programs: Programs
    preview_svg: bytes
    preview_png: bytes
    prediction: Prediction | None = None
    deployed_png: bytes | None = None


def _bbox_diagonal(V: np.ndarray) -> float:
    return float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))


def design_mesh(mesh_path: str | Path, parameters: DesignParameters | None = None,
                solver: SolverSettings | None = None, *, frame: FrameSpec | None = None,
                progress: DesignProgress | None = None, predict: bool = True,
                tables_dir: Path | None = None) -> DesignResult:
    """Run the engine on a mesh file: load, curvature and line field, flattening, placement.

    Parameters
    ----------
    mesh_path : an OBJ, PLY, STL or OFF file of the target (deployed) surface.
    parameters : the design parameters (``size`` None: the largest that fits the frame).
    solver : the solver settings.
    frame : the printable rectangle; default: that of ``parameters.printer_profile``.
    predict : predict the deployed shape of the layout (stage ``deploy``, ``ribbond.deploy``).
    tables_dir : where named curvature tables are looked up before the shipped ones (the daemon's).

    Raises
    ------
    MeshError
        when the mesh cannot be used (the message names the problem and where).
    DesignError
        when the design cannot be made as asked (it does not fit the frame, it folds).
    """
    params = parameters or DesignParameters()
    solver = solver or SolverSettings()
    progress = progress or NoProgress()
    profile = load_profile(params.printer_profile)
    frame = frame or profile.frame
    try:
        check_smoothing(params, solver)
        check_printable(params, frame.size, profile.extruder.nozzle_diameter)
    except ValueError as exc:
        raise DesignError(str(exc)) from None
    table = load_curvature_table(params.curvature_table, tables_dir=tables_dir)
    if abs(table.prestretch - params.prestretch) > 1e-9:
        raise DesignError(f"the curvature table {table.name!r} was measured at pre-stretch s = "
                          f"{table.prestretch:g}, but the design asks for s = {params.prestretch:g}: "
                          "give a table measured at that pre-stretch (curvature_table = path of a .toml file)")
    timings: dict[str, float] = {}
    t_start = time.perf_counter()

    # -- load -----------------------------------------------------------------------------------
    progress.stage_started("load", f"reading {Path(mesh_path).name}")
    t = time.perf_counter()
    target = load_target(mesh_path, max_faces=solver.max_faces, merge_tolerance=solver.merge_tolerance)
    coarse_faces = len(target.F)
    target, refined = refine_target(target, solver.refine_below_faces, solver.refine_to_faces,
                                     solver.max_faces)
    diag0 = _bbox_diagonal(target.V)
    size = params.size.bbox_diagonal if params.size is not None else NOMINAL_DIAGONAL
    V = (target.V - target.V.mean(axis=0)) * (size / diag0)
    F = target.F
    timings["load"] = time.perf_counter() - t
    progress.stage_finished("load", timings["load"],
                            f"{len(F)} faces, {len(V)} vertices"
                            + (f", {target.merged} duplicate vertices merged" if target.merged else "")
                            + (f"; refined {coarse_faces:,} → {len(F):,} faces ({refined.method}, at most "
                               f"{refined.offset_pct:.2f} % of the diagonal off the file's surface) for the layout"
                               if refined is not None else ""))

    # -- curvature and the k1 line field ---------------------------------------------------------
    progress.stage_started("curvature", "principal curvatures and the k1 line field")
    t = time.perf_counter()
    frames = face_frames(V, F)
    curvature = face_curvature(V, F, frames)
    field = curvature_line_field(V, F, frames, curvature, params.smoothing_lambda,
                                 solver.umbilic_tolerance, method=solver.line_field)
    timings["curvature"] = time.perf_counter() - t
    field_dev = field_k1_deviation(field, curvature)
    progress.stage_finished("curvature", timings["curvature"],
                            f"{100 * field.umbilic.mean():.1f} % of the surface umbilic, "
                            + (f"field {field_dev['median']:.2f}° median off k1, " if field_dev else "")
                            + f"{len(field.singular_vertices)} singular vertices"
                            + ("" if field.aligned else "; no curvature direction anywhere: "
                               "smoothest field in an arbitrary direction"))

    # -- flattening -------------------------------------------------------------------------------
    progress.stage_started("flatten", "bounded directional flattening")
    t = time.perf_counter()
    flattener = BoundedFlattener(V, F, field.angle, params.bounds, solver, frames=frames,
                                 prestretch=params.prestretch,
                                 k1_defined=field.anisotropy > ANISOTROPY_THRESHOLD)
    flat = flattener.solve(boundary=target.boundary,
                           progress=lambda i, dsig, e: progress.iteration("flatten", i, dsig, e))
    if flat.folded.any():
        bad = np.flatnonzero(flat.folded)
        raise DesignError(f"the flattening folded {len(bad)} faces over (first: face {bad[0]}); "
                          "the surface cannot be laid flat within the stretch bounds")
    uv, rotation = place_in_frame(flat.uv, frame, margin=0.0)
    if params.size is None:
        scale = fit_scale(uv, frame, solver.layout_margin)
        V, uv = V * scale, (uv - np.array(frame.center)) * scale + np.array(frame.center)
        size *= scale
    else:
        scale = 1.0
        fits = fit_scale(uv, frame, solver.layout_margin)
        if fits < 1.0:
            w, h = uv.max(axis=0) - uv.min(axis=0)
            raise DesignError(
                f"at size {size:.1f} mm (bounding-box diagonal) the flat layout is {w:.0f} × {h:.0f} mm, "
                f"larger than the frame's {frame.size[0]:.0f} × {frame.size[1]:.0f} mm less a "
                f"{solver.layout_margin:.0f} mm margin; the largest size that fits is "
                f"{size * fits:.1f} mm")
    timings["flatten"] = time.perf_counter() - t
    progress.stage_finished("flatten", timings["flatten"],
                            f"{flat.iterations} iterations, "
                            + ("converged" if flat.converged else "stopped at the iteration cap")
                            + f"; sparse solver {linalg.BACKEND_DESCRIPTION}")

    c, s = np.cos(rotation), np.sin(rotation)
    placed = np.array([[c, s], [-s, c]])
    direction = flat.ribbon_direction @ placed
    # print vector p -> flat (placed p) -> target frame J⁻¹ placed p: the report's angles on the target.
    # The adjugate is det J · J⁻¹: the same line for an angle, and defined where J is singular.
    J = flat.jacobians
    adjugate = np.stack([np.stack([J[:, 1, 1], -J[:, 0, 1]], axis=1),
                         np.stack([-J[:, 1, 0], J[:, 0, 0]], axis=1)], axis=1)
    pullback = adjugate @ placed
    k1_target = np.column_stack([np.cos(curvature.angle), np.sin(curvature.angle)])
    kappa1 = curvature.normal_curvature(field.local) / scale
    report = flattening_report(flat, frames.area, params.bounds, timings,
                               total_time=time.perf_counter() - t_start)

    # -- stripe patterns --------------------------------------------------------------------------
    progress.stage_started("stripes", "ribbon spacing (Eq. 10) and the stripe patterns θ and ψ")
    t = time.perf_counter()
    stripes = stripe_grid(uv, F, target.boundary, flat.sigma, direction, kappa1, params,
                          pullback=pullback, k1_target=k1_target,
                          anisotropic=field.anisotropy > ANISOTROPY_THRESHOLD,
                          edge_fraction=solver.stripe_edge_fraction, max_faces=solver.stripe_max_faces,
                          spacing_weight=solver.stripe_spacing_weight,
                          direction_weight=solver.stripe_direction_weight)
    timings["stripes"] = time.perf_counter() - t
    singular = int(stripes.theta.singular.sum() + stripes.psi.singular.sum())
    progress.stage_finished("stripes", timings["stripes"],
                            f"on {len(stripes.F)} faces of {stripes.spacing:.2f} mm, inverse iterations "
                            f"θ {stripes.theta.iterations}, ψ {stripes.psi.iterations}, {singular} singular faces")

    # -- ribbons ----------------------------------------------------------------------------------
    progress.stage_started("ribbons", "staggered ribbons, sides and thicknesses")
    t = time.perf_counter()
    outline = shapely.Polygon(uv[target.boundary])
    layout = layout_ribbons(stripes, outline, params)
    _check_some_ribbons(layout, params, size)
    ribbons, clamped = _ribbons(layout, table)
    try:
        marks = registration_marks(uv, frame, MARK_OFFSET)
    except ValueError as exc:
        raise DesignError(str(exc)) from None
    timings["ribbons"] = time.perf_counter() - t
    front = int(layout.front.sum())
    progress.stage_finished("ribbons", timings["ribbons"],
                            f"{layout.count} ribbons: {front} front, {layout.count - front} back; "
                            f"{layout.dropped_short} dropped as too short, {layout.trimmed_angle} trimmed, "
                            f"{clamped} thicknesses clamped to the table")

    q = ribbon_quantiles(layout)
    ribbon_dev = q.pop("ribbon_k1_deviation_deg", None)
    report["field_k1_deviation_deg"] = Deviation(**field_dev) if field_dev else None
    report["ribbon_k1_deviation_deg"] = Deviation(**ribbon_dev) if ribbon_dev else None
    report["umbilic_pct"] = float(100.0 * np.mean(field.anisotropy <= ANISOTROPY_THRESHOLD))
    if refined is not None:
        report["refined"] = RefinedReport(from_faces=coarse_faces, faces=len(F), levels=refined.levels,
                                          method=refined.method, offset_pct=refined.offset_pct)
    report["ribbons"] = RibbonsReport(
        front=front, back=layout.count - front, dropped_short=layout.dropped_short,
        trimmed_angle=layout.trimmed_angle, thickness_clamped=clamped,
        **{key: Quantiles(**value) for key, value in q.items()})
    parameters = Parameters.resolved(params, size)
    design = Design(
        source=Source(file=target.name, sha256=target.sha256, faces=target.source_faces),
        parameters=parameters,
        faces=Faces.from_arrays(flat.sigma[:, 0], flat.sigma[:, 1], direction, kappa1),
        ribbons=ribbons,
        registration_marks=[(float(x), float(y)) for x, y in marks],
        report=Report(**report))

    # -- G-code -----------------------------------------------------------------------------------
    progress.stage_started("gcode", f"print programs for {profile.name}")
    t = time.perf_counter()
    programs = _programs(design, profile if frame == profile.frame else profile.model_copy(update={"frame": frame}))
    timings["gcode"] = time.perf_counter() - t
    fs, bs = programs.front.stats, programs.back.stats
    progress.stage_finished("gcode", timings["gcode"],
                            f"front {fs.lines} lines, ~{fs.time_s / 60:.0f} min; back {bs.lines} lines, "
                            f"~{bs.time_s / 60:.0f} min; travel {fs.travel_mm + bs.travel_mm:.0f} mm for "
                            f"{fs.extrusion_mm + bs.extrusion_mm:.0f} mm printed")
    if fs.extrusion_mm + bs.extrusion_mm <= 0.0:
        raise DesignError(f"the print programs extrude nothing ({len(ribbons)} ribbons): the design would print "
                          "nothing; check ribbon_width and the curvature table's thicknesses")
    report["print"] = PrintReport(front=SidePrintReport(**fs.report()), back=SidePrintReport(**bs.report()))

    # -- deploy: the predicted deployed shape --------------------------------------------------------
    prediction = None
    if predict:
        progress.stage_started("deploy", "predicting the deployed shape (the flat sheet released, "
                                         f"{len(RELEASES)} ways)")
        t = time.perf_counter()
        prediction = _predict(uv, V, F, ribbons, params, table, progress)
        timings["deploy"] = time.perf_counter() - t
        progress.stage_finished("deploy", timings["deploy"], _deploy_summary(prediction))
        report["deployed"] = DeployedReport(**prediction.report())

    # -- preview ----------------------------------------------------------------------------------
    progress.stage_started("preview", "rendering the layout preview")
    t = time.perf_counter()
    deployed_png = (prediction.render_png(V, F, title=f"{target.name}: predicted deployed shape")
                    if prediction is not None else None)
    svg, png = render_preview(
        uv, F, flat.sigma[:, 1], ribbons, params.ribbon_width, marks=marks, frame_bounds=frame.bounds,
        sigma2_bounds=parameters.bounds[1], flip_axis=frame.flip_axis,
        title=f"{target.name}: {len(ribbons)} ribbons ({front} front, {len(ribbons) - front} back), "
              f"size {size:.0f} mm")
    timings["preview"] = time.perf_counter() - t
    progress.stage_finished("preview", timings["preview"],
                            f"{len(png) // 1024} kB PNG, {len(svg) // 1024} kB SVG")
    report["timings_s"] = dict(timings)
    report["time_s"] = time.perf_counter() - t_start
    design = design.updated(report=Report(**report))
    return DesignResult(target=target, V=V, F=F, flat_uv=uv, curvature=curvature, field=field,
                        flattening=flat, kappa1=kappa1, ribbon_direction=direction, stripes=stripes,
                        layout=layout, frame=frame, design=design, programs=programs,
                        preview_svg=svg, preview_png=png, prediction=prediction, deployed_png=deployed_png)


def _check_some_ribbons(layout: RibbonLayout, params: DesignParameters, size: float) -> None:
    """A design without ribbons prints nothing: refuse it, naming the parameter that emptied it."""
    if layout.count > 0:
        return
    if layout.dropped_short:
        raise DesignError(f"no ribbons: all {layout.dropped_short} pieces of ribbon were shorter than "
                          f"min_ribbon_length = {params.min_ribbon_length:g} mm (with max_trim_angle = "
                          f"{params.max_trim_angle:g}°, {layout.trimmed_angle} were trimmed); lower "
                          "min_ribbon_length or raise max_trim_angle, or make the design larger (size)")
    raise DesignError(f"no ribbons: at size {size:.1f} mm (bounding-box diagonal) the stripe patterns leave no "
                      f"ribbon of ribbon_width = {params.ribbon_width:g} mm inside the flat surface; make the "
                      "design larger (size) or the ribbons smaller (ribbon_length, ribbon_width)")


def _deploy_summary(p: Prediction) -> str:
    dev, a = p.deviation_pct, p.agreement
    return (f"{p.verdict}. Deviation mean {dev['mean']:.2f} %, p99 {dev['p99']:.2f} %, max {dev['max']:.2f} % of "
            f"the diagonal (over {len(p.releases)} releases: mean {a.spread_mean[0]:.2f}–{a.spread_mean[1]:.2f} %); "
            f"{p.faces} faces, {p.iterations} Newton iterations")


def _predict(uv: np.ndarray, V: np.ndarray, F: np.ndarray, ribbons: list[Ribbon], params: DesignParameters,
             table: CurvatureTable, progress: DesignProgress) -> Prediction:
    calls = [0]

    def relay(fraction: float, message: str) -> None:
        calls[0] += 1
        progress.iteration("deploy", calls[0], fraction, 0.0)

    try:
        return predict_deployed(uv, V, F, ribbons, prestretch=params.prestretch,
                                ribbon_width=params.ribbon_width, table=table, progress=relay)
    except ValueError as exc:
        raise DesignError(f"the deployed shape cannot be predicted: {exc}") from None


def _programs(design: Design, profile: PrinterProfile) -> Programs:
    try:
        return make_programs(design, profile)
    except GcodeError as exc:
        raise DesignError(f"the print programs cannot be made: {exc}") from None


def _ribbons(layout: RibbonLayout, table: CurvatureTable) -> tuple[list[Ribbon], int]:
    """The ``design.json`` ribbons (side by the sign of κ1, thickness from ``table``) and the
    number of thicknesses clamped to the table's range."""
    thick = ribbon_thickness(table, layout.kappa1, layout.spacing[:, 1])
    ribbons = [Ribbon(side="front" if k > 0 else "back", points=[(float(x), float(y)) for x, y in pts],
                      thickness=float(tau), kappa1=float(k), spacing=(float(mu[0]), float(mu[1])))
               for pts, tau, k, mu in zip(layout.points, thick.thickness, layout.kappa1, layout.spacing)]
    return ribbons, thick.clamped_count


def _deployed_files(result: DesignResult) -> dict[str, bytes]:
    """``deployed.obj`` and ``deployed.png`` when the design has a prediction."""
    if result.prediction is None or result.deployed_png is None:
        return {}
    header = (f"ribbond design: predicted deployed surface, mm, registered to target.obj "
              f"({result.prediction.faces} faces, its own mesh)")
    return {"deployed.obj": obj_bytes(result.prediction.V, result.prediction.F, header=header),
            "deployed.png": result.deployed_png}


def write_design(result: DesignResult, out_dir: str | Path,
                 progress: DesignProgress | None = None) -> Path:
    """Write the design folder (``target.obj``, ``flat.obj``, ``design.json``, ``front.gcode``,
    ``back.gcode``, ``combined.gcode``, ``preview.svg``, ``preview.png`` and, with a prediction,
    ``deployed.obj`` and ``deployed.png``) atomically."""
    progress = progress or NoProgress()
    progress.stage_started("write", f"writing {out_dir}")
    t = time.perf_counter()
    path = write_design_folder(Path(out_dir), target_V=result.V, target_F=result.F,
                               flat_V=result.flat_uv, design=result.design,
                               extra_files={"preview.svg": result.preview_svg,
                                            "preview.png": result.preview_png,
                                            "front.gcode": result.programs.front.text.encode(),
                                            "back.gcode": result.programs.back.text.encode(),
                                            "combined.gcode": result.programs.combined.text.encode(),
                                            **_deployed_files(result)})
    progress.stage_finished("write", time.perf_counter() - t, str(path))
    return path
