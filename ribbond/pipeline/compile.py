"""The design engine from a mesh file to the design folder, stage by stage.

Stages: ``load`` (read, clean, validate, scale), ``curvature`` (principal curvatures and the k1
line field), ``flatten`` (the bounded directional flattening, placed in the printer frame),
``stripes`` (spacing by Eq. 10 and the two stripe patterns), ``ribbons`` (the staggered ribbons,
their sides and thicknesses, the registration marks), ``gcode`` (the print programs), ``deploy``
(the predicted deployed shape, ``ribbond.deploy``), ``preview`` and ``write`` (the design folder).
``STAGES`` lists them in order; ``design_mesh`` runs them in one loop that times each and reports
its progress. The arrays stay in the functions of the stage modules; the stages here only wire them
together, on one ``_Run`` that carries what each stage made to the next.
"""

from __future__ import annotations

import copy
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, NamedTuple, Protocol

import numpy as np
import shapely
from scipy.spatial import cKDTree

from ..deploy.optimize import Optimization, optimize_layout
from ..deploy.predict import RELEASES, Prediction, predict_deployed
from ..deploy.realization import realization
from ..deploy.rest_forms import contraction, face_coverage, layout_raster
from ..gcode.profiles import FrameSpec, PrinterProfile, load_profile
from ..gcode.program import GcodeError, Programs, make_programs
from ..design import linalg
from ..design.curvature import Curvature, face_curvature
from ..design.errors import DesignError
from ..design.flatten import BoundedFlattener, FlatteningResult
from ..design.folder import write_design_folder
from ..design.format import (DeployedReport, Deviation, Design, Faces, LineFieldChoice, OptimizationReport, Parameters,
                             PredictedShape, PrintReport,
                             Quantiles, RealizationReport, RefinedReport, Report, Ribbon, RibbonsReport, ScaleReport, SidePrintReport,
                             Source, StitchMark, ThicknessFit)
from ..design.frames import FaceFrames, face_frames
from ..design.intake import TargetMesh, check_disk, load_target
from ..mesh.files import obj_bytes
from ..design.line_field import ANISOTROPY_THRESHOLD, LineField, curvature_line_field, field_k1_deviation
from ..design.params import DesignParameters, SolverSettings, check_printable, check_smoothing
from ..design.placement import fit_scale, place_in_frame, registration_marks
from ..design.preview import render_preview
from ..design.refine import Refined, refine_target
from ..design.report import flattening_report, umbilic_split
from ..design.saddle_family import SaddleFamily, saddle_family
from ..design.ribbons import (RibbonLayout, StripeGrid, face_spacing, layout_ribbons, ribbon_quantiles, stripe_grid,
                              with_rim)
from ..design.rim import RIM_SHORT
from ..design.thickness import (CurvatureTable, ThicknessResult, fitting_scale, largest_table_scale, load_curvature_table,
                                ribbon_thickness)

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
    programs: Programs | None
    preview_svg: bytes
    preview_png: bytes
    prediction: Prediction | None = None
    deployed_png: bytes | None = None


def _bbox_diagonal(V: np.ndarray) -> float:
    return float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))


@dataclass(eq=False, repr=False)
class _Run:
    """One design in the making: what was asked, then what each stage made, in stage order (a stage's
    fields are unset until it has run)."""

    mesh_path: str | Path
    params: DesignParameters
    solver: SolverSettings
    profile: PrinterProfile
    frame: FrameSpec
    table: CurvatureTable
    progress: DesignProgress
    predict: bool
    t_start: float
    optimize: bool = True
    timings: dict[str, float] = field(default_factory=dict)
    flat_start: np.ndarray | None = None
    unsized: str = "fit"
    # load
    target: TargetMesh = field(init=False)
    coarse_faces: int = field(init=False)
    refined: Refined | None = field(init=False)
    size: float = field(init=False)
    source_diagonal: float = field(init=False)
    V: np.ndarray = field(init=False)
    F: np.ndarray = field(init=False)
    # curvature
    frames: FaceFrames = field(init=False)
    curvature: Curvature = field(init=False)
    line_field: LineField = field(init=False)
    field_dev: dict[str, float] | None = field(init=False)
    # flatten, then the flat sheet in print coordinates
    flat: FlatteningResult = field(init=False)
    uv: np.ndarray = field(init=False)
    rotation: float = field(init=False)
    scale: float = field(init=False)
    table_scale: float = field(init=False)    # unsized "fit": the largest the curvature table reaches (× curvature's)
    frame_size: float | None = None           # unsized "fit", once scaled: the size the frame alone would take, mm
    direction: np.ndarray = field(init=False)
    pullback: np.ndarray = field(init=False)
    k1_target: np.ndarray = field(init=False)
    kappa1: np.ndarray = field(init=False)
    report: dict[str, Any] = field(init=False)
    # stripes, ribbons
    stripes: StripeGrid = field(init=False)
    layout: RibbonLayout = field(init=False)
    ribbons: list[Ribbon] = field(init=False)
    thickness: ThicknessResult = field(init=False)
    marks: np.ndarray = field(init=False)
    front: int = field(init=False)
    parameters: Parameters = field(init=False)
    design: Design = field(init=False)
    # gcode, deploy, preview
    programs: Programs | None = None
    # the optimization, the forward and the optimized layouts' predictions, whether it was kept and why
    optimization: tuple[Optimization, Prediction, Prediction, bool, str] | None = None
    family: SaddleFamily | None = None
    field_choice: dict[str, Any] | None = None
    prediction: Prediction | None = None
    deployed_png: bytes | None = None
    preview_svg: bytes = b""
    preview_png: bytes = b""

    @property
    def mesh_name(self) -> str:
        return Path(self.mesh_path).name


class _Stage(NamedTuple):
    """A stage of the engine as the progress shows it.

    Attributes
    ----------
    name : the stage's name (``timings_s`` is keyed by it).
    description : what it does, formatted with the run (``{run.mesh_name}``).
    work : does it on the run and returns the summary line.
    after : what follows its report, untimed (the report's entries, the checks on its result).
    applies : whether the run has this stage.
    """

    name: str
    description: str
    work: Callable[[_Run], str]
    after: Callable[[_Run], None] | None = None
    applies: Callable[[_Run], bool] = lambda run: True


def design_mesh(mesh_path: str | Path, parameters: DesignParameters | None = None,
                solver: SolverSettings | None = None, *, frame: FrameSpec | None = None,
                progress: DesignProgress | None = None, predict: bool = True,
                tables_dir: Path | None = None, flat_start: np.ndarray | None = None,
                finish: bool = True, optimize: bool = False, unsized: str = "fit") -> DesignResult:
    """Run the engine's ``STAGES`` on a mesh file: load, curvature and line field, flattening, stripes,
    ribbons, G-code, the predicted deployed shape and the preview.

    Parameters
    ----------
    mesh_path : an OBJ, PLY, STL or OFF file of the target (deployed) surface.
    parameters : the design parameters (``size`` None: as ``unsized`` says).
    solver : the solver settings.
    frame : the printable rectangle; default: that of ``parameters.printer_profile``.
    predict : predict the deployed shape of the layout (stage ``deploy``, ``ribbond.deploy``).
    tables_dir : where named curvature tables are looked up before the shipped ones (the daemon's).
    flat_start : (n, 2) a converged flattening of the same mesh at its physical size, in the file's vertex
        order (a panel's, from the cut's check): the flattening then only runs its last phase from it.
        Used when the file's vertices reach the engine unchanged (no merge, no refinement).
    finish : False leaves out the print programs and the pictures (``programs`` None, no previews) for
        ``finish_design`` to make once the design is complete (a project's panels get their stitch
        marks after every panel's prediction).
    optimize : with ``predict``, optimize the ribbons' thicknesses against the prediction (stage
        ``optimize``, ``ribbond.deploy.optimize``, within ``solver.optimize_budget_s``; also off when
        ``solver.optimize`` is false); False: the paper's forward design.
    unsized : what a missing ``parameters.size`` means: ``"fit"`` the largest size at which the layout
        fits the frame, ``"file"`` the file's units read as mm (a design larger than the frame takes
        is then refused, naming the largest size that fits). ``report.scale`` says which was applied.

    Raises
    ------
    MeshError
        when the mesh cannot be used (the message names the problem and where).
    DesignError
        when the design cannot be made as asked (it does not fit the frame, it folds).
    """
    run = _prepare(mesh_path, parameters or DesignParameters(), solver or SolverSettings(), frame,
                   progress or NoProgress(), predict, tables_dir)
    if unsized not in ("fit", "file"):
        raise ValueError(f"unsized = {unsized!r}: 'fit' or 'file'")
    run.flat_start = flat_start
    run.optimize = optimize and run.solver.optimize
    run.unsized = unsized
    for stage in STAGES:
        if stage.applies(run) and (finish or stage.name not in FINISHING):
            _run_stage(run, stage)
    return _result(run)


def _run_stage(run: _Run, stage: _Stage) -> None:
    """One stage between its start and finish reports, timed; then what follows its report."""
    run.progress.stage_started(stage.name, stage.description.format(run=run))
    t = time.perf_counter()
    summary = stage.work(run)
    run.timings[stage.name] = time.perf_counter() - t
    run.progress.stage_finished(stage.name, run.timings[stage.name], summary)
    if stage.after is not None:
        stage.after(run)


def _prepare(mesh_path: str | Path, params: DesignParameters, solver: SolverSettings, frame: FrameSpec | None,
             progress: DesignProgress, predict: bool, tables_dir: Path | None) -> _Run:
    """Check what was asked before any stage: printable, and a curvature table for the pre-stretch."""
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
    return _Run(mesh_path=mesh_path, params=params, solver=solver, profile=profile, frame=frame, table=table,
                progress=progress, predict=predict, t_start=time.perf_counter())


def _load(run: _Run) -> str:
    """Read, clean, validate and refine the target; centre it and scale it to the design size."""
    solver = run.solver
    target = load_target(run.mesh_path, max_faces=solver.max_faces, merge_tolerance=solver.merge_tolerance)
    run.coarse_faces = len(target.F)
    run.target, run.refined = refine_target(target, solver.refine_below_faces, solver.refine_to_faces,
                                            solver.max_faces, solver.refine_method)
    run.source_diagonal = diag0 = _bbox_diagonal(run.target.V)
    run.size = _first_size(run, diag0)
    run.V = (run.target.V - run.target.V.mean(axis=0)) * (run.size / diag0)
    run.F = run.target.F
    refined, F = run.refined, run.F
    return (f"{len(F)} faces, {len(run.V)} vertices"
            + (f", {run.target.merged} duplicate vertices merged" if run.target.merged else "")
            + (f"; refined {run.coarse_faces:,} → {len(F):,} faces ({refined.method}, at most "
               f"{refined.offset_pct:.2f} % of the diagonal off the file's surface) for the layout"
               if refined is not None else ""))


def _first_size(run: _Run, diag0: float) -> float:
    """The size the target is designed at (bbox diagonal, mm): ``size``, the file's own (``unsized``
    "file": refused below one ribbon's width), or a nominal one that the frame's fit scales later."""
    if run.params.size is not None:
        return run.params.size.bbox_diagonal
    if run.unsized == "fit":
        return NOMINAL_DIAGONAL
    if diag0 < run.params.ribbon_width:
        raise DesignError(f"the file's units read as mm make the target {diag0:.3g} mm across (bounding-box "
                          f"diagonal), narrower than one ribbon ({run.params.ribbon_width:g} mm): give its size "
                          "(--size MM, size.bbox_diagonal) or --size fit")
    return diag0


def _curvature(run: _Run) -> str:
    """The principal curvatures and the k1 line field."""
    run.frames = face_frames(run.V, run.F)
    run.curvature = face_curvature(run.V, run.F, run.frames)
    run.line_field = lines = curvature_line_field(run.V, run.F, run.frames, run.curvature,
                                                  run.params.smoothing_lambda, run.solver.umbilic_tolerance,
                                                  method=run.solver.line_field)
    run.field_dev = field_dev = field_k1_deviation(lines, run.curvature)
    if run.solver.line_field == "aligned":
        run.family = saddle_family(run.F, run.frames.area, run.curvature, lines.anisotropy,
                                   run.solver.umbilic_tolerance, 0.1 / _bbox_diagonal(run.V))
    return (f"k1 undefined on {100 * lines.umbilic.mean():.1f} % of the surface (umbilic, flat, or |κ1| ≈ |κ2| "
            "with opposite signs: the ribbon direction ambiguous), "
            + (f"field {field_dev['median']:.2f}° median off k1, " if field_dev else "")
            + f"{len(lines.singular_vertices)} singular vertices"
            + ("" if lines.aligned else "; no curvature direction anywhere: "
               "smoothest field in an arbitrary direction"))


def _flatten(run: _Run) -> str:
    """The bounded directional flattening, placed in the frame (and scaled to fill it when no size)."""
    params, lines = run.params, run.line_field
    flattener = BoundedFlattener(run.V, run.F, lines.angle, params.bounds, run.solver, frames=run.frames,
                                 prestretch=params.prestretch,
                                 k1_defined=lines.anisotropy > ANISOTROPY_THRESHOLD)
    run.flat = flat = flattener.solve(_flat_start(run), boundary=run.target.boundary,
                                      progress=lambda i, dsig, e: run.progress.iteration("flatten", i, dsig, e))
    if flat.folded.any():
        bad = np.flatnonzero(flat.folded)
        raise DesignError(f"the flattening folded {len(bad)} faces over (first: face {bad[0]}); "
                          "the surface cannot be laid flat within the stretch bounds")
    run.uv, run.rotation = place_in_frame(flat.uv, run.frame, margin=0.0)
    _fit_in_frame(run)
    return (f"{flat.iterations} iterations, "
            + ("converged" if flat.converged else "stopped at the iteration cap")
            + f"; sparse solver {linalg.BACKEND_DESCRIPTION}")


def _flat_start(run: _Run) -> np.ndarray | None:
    """The given start of the flattening, when the file's vertices reached the engine as they were."""
    start, target = run.flat_start, run.target
    if (start is None or run.refined is not None or target.merged or target.unreferenced
            or np.shape(start) != (len(run.V), 2)):
        return None
    return np.asarray(start, dtype=float) * (run.size / _bbox_diagonal(target.V))


def _fit_in_frame(run: _Run) -> None:
    """Scale the design to the largest that fits the frame and the curvature table, or refuse a given
    size that does not fit the frame. Without a size every flattening of the run is so scaled (the line
    field's alternative too, from the size the first one chose); ``scale`` is the size over the one the
    curvature was measured at."""
    frame, margin = run.frame, run.solver.layout_margin
    fits = fit_scale(run.uv, frame, margin)
    if run.params.size is None and run.unsized == "fit":
        fitted = run.frame_size is not None
        before = run.scale if fitted else 1.0
        if not fitted:
            run.table_scale = _table_scale(run, fits)
        total = min(fits * before, run.table_scale)
        factor = total / before
        run.frame_size = run.size * fits
        run.scale = total
        run.V, run.uv = run.V * factor, (run.uv - np.array(frame.center)) * factor + np.array(frame.center)
        run.size *= factor
        return
    run.scale = 1.0
    if fits < 1.0:
        w, h = run.uv.max(axis=0) - run.uv.min(axis=0)
        units = ", the file's units read as mm" if run.params.size is None else ""
        raise DesignError(
            f"at size {run.size:.1f} mm (bounding-box diagonal{units}) the flat layout is {w:.0f} × {h:.0f} mm, "
            f"larger than the frame's {frame.size[0]:.0f} × {frame.size[1]:.0f} mm less a "
            f"{margin:.0f} mm margin; the largest size that fits is {run.size * fits:.1f} mm"
            + (" (--size fit)" if units else "") + _panels_hint(run))


def _table_scale(run: _Run, at_most: float) -> float:
    """The largest factor up to ``at_most`` at which the curvature table reaches the target's curvature
    along the field (``largest_table_scale``): a larger sheet of a shape the plastic cannot curl so flat
    would fold, not take it."""
    kappa1 = run.curvature.normal_curvature(run.line_field.local)
    mu2 = face_spacing(run.flat.sigma, run.params)[:, 1]
    return largest_table_scale(run.table, kappa1, mu2, run.frames.area, at_most)


def _panels_hint(run: _Run) -> str:
    """How many panels ``--panels auto`` would cut a design too large for one sheet into (issue 26)."""
    from ..panels.project import SEAM_ALLOWANCE, cut_target, panel_margin
    margin = panel_margin(run.solver, SEAM_ALLOWANCE, run.params.prestretch)
    cut = cut_target(*_search_copy(run.V, run.F), run.params, _search_settings(run.solver), run.frame, "auto", margin)
    return (f", or --panels auto would cut it into about {cut.count} panels that fit" if cut.feasible
            else "; not even the most panels --panels auto tries would fit")


def _in_print_coordinates(run: _Run) -> None:
    """The ribbon direction and κ1 in print coordinates, the map back to the target, the flattening's report."""
    c, s = np.cos(run.rotation), np.sin(run.rotation)
    placed = np.array([[c, s], [-s, c]])
    run.direction = run.flat.ribbon_direction @ placed
    # print vector p -> flat (placed p) -> target frame J⁻¹ placed p: the report's angles on the target.
    # The adjugate is det J · J⁻¹: the same line for an angle, and defined where J is singular.
    J = run.flat.jacobians
    adjugate = np.stack([np.stack([J[:, 1, 1], -J[:, 0, 1]], axis=1),
                         np.stack([-J[:, 1, 0], J[:, 0, 0]], axis=1)], axis=1)
    run.pullback = adjugate @ placed
    run.k1_target = np.column_stack([np.cos(run.curvature.angle), np.sin(run.curvature.angle)])
    run.kappa1 = run.curvature.normal_curvature(run.line_field.local) / run.scale
    run.report = flattening_report(run.flat, run.frames.area, run.params.bounds, run.timings,
                                   total_time=time.perf_counter() - run.t_start)
    _suggest_panels(run)


def _suggest_panels(run: _Run) -> None:
    """A surface one sheet cannot make: how many panels ``--panels auto`` would make (issue 26)."""
    from ..panels.project import MAX_BAD_PCT, SEAM_ALLOWANCE, cut_target, panel_margin
    bad = max(run.report["sigma1_bad_pct"], run.report["sigma2_bad_pct"])
    if bad <= MAX_BAD_PCT:
        return
    margin = panel_margin(run.solver, SEAM_ALLOWANCE, run.params.prestretch)
    V, F = _search_copy(run.V, run.F)
    cut = cut_target(V, F, run.params, _search_settings(run.solver), run.frame, "auto", margin, fewest=2)
    run.report["panels_suggested"] = cut.count if cut.feasible else 0


#: The verdict's panel count is searched on a copy of at most this many faces: each candidate panel is
#: flattened, which on a 40k-face target took 30 s for a count it finds as well on this copy.
SEARCH_FACES = 6000


def _search_settings(solver: SolverSettings) -> SolverSettings:
    """The flattening's settings for the verdict's quick search: a looser tolerance and no row-count
    phase (2-4× faster per panel; the share of faces out moves by a few tenths of a percent)."""
    return solver.model_copy(update={"tolerance": max(solver.tolerance, 1e-5), "spacing_integrability_weight": 0.0})


def _search_copy(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The target, or a decimated copy of it (libigl's edge collapse) when it is larger than
    ``SEARCH_FACES`` and the copy is still one disk."""
    if len(F) <= SEARCH_FACES:
        return V, F
    import igl
    U, G, _, _ = igl.decimate(np.asfortranarray(V), np.asfortranarray(F.astype(np.int32)), SEARCH_FACES)
    U, G = np.ascontiguousarray(U), np.ascontiguousarray(G, dtype=np.int64)
    try:
        check_disk(U, G)
    except ValueError:
        return V, F
    return U, G


def _stripes(run: _Run) -> str:
    """The ribbon spacing (Eq. 10) and the two stripe patterns."""
    solver = run.solver
    run.stripes = stripes = stripe_grid(
        run.uv, run.F, run.target.boundary, run.flat.sigma, run.direction, run.kappa1, run.params,
        pullback=run.pullback, k1_target=run.k1_target,
        anisotropic=run.line_field.anisotropy > ANISOTROPY_THRESHOLD,
        edge_fraction=solver.stripe_edge_fraction, max_faces=solver.stripe_max_faces,
        spacing_weight=solver.stripe_spacing_weight, direction_weight=solver.stripe_direction_weight)
    singular = int(stripes.theta.singular.sum() + stripes.psi.singular.sum())
    return (f"on {len(stripes.F)} faces of {stripes.spacing:.2f} mm, inverse iterations "
            f"θ {stripes.theta.iterations}, ψ {stripes.psi.iterations}, {singular} singular faces")


def _cut_ribbons(run: _Run) -> str:
    """The staggered ribbons cut to the outline, their sides and thicknesses; the registration marks."""
    outline = shapely.Polygon(run.uv[run.target.boundary])
    run.layout = layout = layout_ribbons(run.stripes, outline, run.params)
    _check_some_ribbons(layout, run.params, run.size)
    run.ribbons, run.thickness = _ribbons(layout, run.table)
    run.layout = layout = with_rim(layout, run.stripes, outline, run.params, _along_short(run, outline))
    if layout.rim:
        run.ribbons, run.thickness = _ribbons(layout, run.table)
    try:
        run.marks = registration_marks(run.uv, run.frame, MARK_OFFSET)
    except ValueError as exc:
        raise DesignError(str(exc)) from None
    run.front = front = int(layout.front.sum())
    return (f"{layout.count} ribbons: {front} front, {layout.count - front} back; "
            f"{layout.dropped_short} dropped as too short, {layout.trimmed_angle} trimmed, "
            f"{run.thickness.clamped_count} thicknesses clamped to the table"
            + (f"; {layout.rim} along the outline (replacing {layout.rim_replaced} short pieces)" if layout.rim else ""))


#: The rim's shortfall is measured on the faces this close to the outline, mm (they hold the rim's points).
RIM_BAND = 3.0


def _along_short(run: _Run, outline: shapely.Polygon) -> Callable[[np.ndarray], np.ndarray]:
    """Where the ribbons as printed fall short along the rows (``rim.RIM_SHORT``): the realized
    contraction along them (the coverage the prediction uses, ``rest_forms.face_coverage``) against
    Eq. 10's 1/σ1, on the faces along the outline; a point reads its nearest measured face."""
    centroid = run.uv[run.F].mean(axis=1)
    faces = np.flatnonzero(shapely.distance(outline.boundary, shapely.points(centroid)) < RIM_BAND)
    if len(faces) == 0 or not run.ribbons:
        return lambda P: np.zeros(len(P), dtype=bool)
    p = run.params
    raster = layout_raster(run.uv, run.F, run.ribbons, p.ribbon_width)          # the whole flat domain
    cov = face_coverage(run.uv, run.F[faces], run.ribbons, p.ribbon_width, run.table, raster=raster)
    along = 100.0 * (contraction(cov.f_along, p.prestretch) * run.flat.sigma[faces, 0] - 1.0)
    short = along < -RIM_SHORT                                      # bare faces too: f = 0
    tree = cKDTree(centroid[faces])
    return lambda P: short[tree.query(P, workers=-1)[1]]


def _design_document(run: _Run) -> None:
    """The ``design.json`` content so far: the ribbons' report, the resolved parameters, the faces."""
    layout, report = run.layout, run.report
    q = ribbon_quantiles(layout)
    ribbon_dev = q.pop("ribbon_k1_deviation_deg", None)
    report["field_k1_deviation_deg"] = Deviation(**run.field_dev) if run.field_dev else None
    report["ribbon_k1_deviation_deg"] = Deviation(**ribbon_dev) if ribbon_dev else None
    report["umbilic_pct"] = float(100.0 * np.mean(run.line_field.anisotropy <= ANISOTROPY_THRESHOLD))
    diagonal = float(np.linalg.norm(run.V.max(axis=0) - run.V.min(axis=0)))
    report["ambiguous_pct"] = umbilic_split(run.curvature.kappa1, run.curvature.kappa2, run.line_field.anisotropy,
                                            ANISOTROPY_THRESHOLD, 0.1 / diagonal)["ambiguous_pct"]
    if run.refined is not None:
        report["refined"] = RefinedReport(from_faces=run.coarse_faces, faces=len(run.F), levels=run.refined.levels,
                                          method=run.refined.method, offset_pct=run.refined.offset_pct)
    report["ribbons"] = RibbonsReport(
        front=run.front, back=layout.count - run.front, dropped_short=layout.dropped_short,
        trimmed_angle=layout.trimmed_angle, thickness_clamped=run.thickness.clamped_count,
        thickness_clamped_flat=int(run.thickness.too_flat.sum()), thickness_clamped_curved=int(run.thickness.too_curved.sum()),
        thickness_fit=ThicknessFit(**dict(zip(("scale", "clamped"), fitting_scale(run.thickness)))),
        rim=layout.rim, rim_replaced=layout.rim_replaced,
        **{key: Quantiles(**value) for key, value in q.items()})
    report["realization"] = _realization(run)
    rule = "size" if run.params.size is not None else run.unsized
    limit = {} if rule != "fit" or run.frame_size is None else {
        "frame_diagonal": run.frame_size,
        "limited_by": "curvature table" if run.size < run.frame_size * (1 - 1e-9) else "frame"}
    report["scale"] = ScaleReport(rule=rule, source_diagonal=run.source_diagonal, factor=run.size / run.source_diagonal,
                                  **limit)
    run.parameters = Parameters.resolved(run.params, run.size)
    target, flat = run.target, run.flat
    run.design = Design(
        source=Source(file=target.name, sha256=target.sha256, faces=target.source_faces),
        parameters=run.parameters,
        faces=Faces.from_arrays(flat.sigma[:, 0], flat.sigma[:, 1], run.direction, run.kappa1),
        ribbons=run.ribbons,
        registration_marks=[(float(x), float(y)) for x, y in run.marks],
        report=Report(**report))


def _realization(run: _Run) -> RealizationReport:
    """How far the ribbons as printed realize the flattening's σ and the target's κ1 (format 4)."""
    p = run.params
    r = realization(run.uv, run.F, run.flat.sigma, run.direction, run.kappa1, run.ribbons,
                    prestretch=p.prestretch, ribbon_width=p.ribbon_width, ribbon_length=p.ribbon_length,
                    table=run.table, target_V=run.V)
    return RealizationReport(**r.report())


def _gcode(run: _Run) -> str:
    """The print programs, for the frame the design was placed in."""
    profile, frame = run.profile, run.frame
    run.programs = _programs(run.design, profile if frame == profile.frame
                             else profile.model_copy(update={"frame": frame}))
    fs, bs = run.programs.front.stats, run.programs.back.stats
    return (f"front {fs.lines} lines, ~{fs.time_s / 60:.0f} min; back {bs.lines} lines, "
            f"~{bs.time_s / 60:.0f} min; travel {fs.travel_mm + bs.travel_mm:.0f} mm for "
            f"{fs.extrusion_mm + bs.extrusion_mm:.0f} mm printed")


def _check_extrusion(run: _Run) -> None:
    """A program that extrudes nothing prints nothing: refuse it; else the report's print figures."""
    fs, bs = run.programs.front.stats, run.programs.back.stats
    if fs.extrusion_mm + bs.extrusion_mm <= 0.0:
        raise DesignError(f"the print programs extrude nothing ({len(run.ribbons)} ribbons): the design would print "
                          "nothing; check ribbon_width and the curvature table's thicknesses")
    run.report["print"] = PrintReport(front=SidePrintReport(**fs.report()), back=SidePrintReport(**bs.report()))


def _deploy(run: _Run) -> str:
    """The predicted deployed shape (``ribbond.deploy``): the stage optimize's when it ran (it predicted
    the layout it kept), else made here."""
    if run.prediction is None:
        run.prediction = _predict(run.uv, run.V, run.F, run.ribbons, run.params, run.table, run.progress)
    return _deploy_summary(run.prediction)


def _deployed_report(run: _Run) -> None:
    assert run.prediction is not None
    run.report["deployed"] = DeployedReport(**run.prediction.report())
    if run.optimization is not None:
        opt, forward, optimized, kept, why = run.optimization
        run.report["optimization"] = OptimizationReport(**opt.report(forward, optimized), kept=kept, reason=why,
                                                        line_field=_field_choice_report(run.field_choice))


def _field_choice_report(choice: dict[str, Any] | None) -> LineFieldChoice | None:
    """``report.optimization.line_field`` of the stage's field choice (None: no choice was made)."""
    if choice is None:
        return None
    one = choice["one_family"]
    return LineFieldChoice(switched_pct=choice["switched_pct"], paper=PredictedShape(**Optimization.shape(choice["paper"])),
                           one_family=None if one is None else PredictedShape(**Optimization.shape(one)),
                           kept=choice["kept"], reason=choice["reason"])


def _optimize(run: _Run) -> str:
    """The forward layout's prediction (every release), then its ribbons' thicknesses optimized against
    it and the optimized layout predicted from the flat sheet as printed; the optimized layout is kept
    only where that prediction is better (``optimization_kept``), and the design (ribbons,
    realization) is made again with it. Either prediction is the one the stage deploy reports."""
    forward = _predict(run.uv, run.V, run.F, run.ribbons, run.params, run.table, run.progress, stage="optimize")
    if run.family is not None:
        forward = _choose_field(run, run.family, forward)
    p, t0 = run.params, time.perf_counter()
    calls = [0]

    def relay(fraction: float, message: str) -> None:
        calls[0] += 1
        run.progress.iteration("optimize", calls[0], fraction, 0.0)

    try:
        opt = optimize_layout(run.uv, run.V, run.F, run.ribbons, forward, prestretch=p.prestretch,
                              ribbon_width=p.ribbon_width, table=run.table,
                              budget_s=max(run.solver.optimize_budget_s - (time.perf_counter() - t0), 1.0),
                              progress=relay)
    except ValueError as exc:
        raise DesignError(f"the layout cannot be optimized: {exc}") from None
    optimized = _predict(run.uv, run.V, run.F, opt.ribbons, p, run.table, run.progress, stage="optimize")
    kept, why = optimization_kept(forward, optimized)
    run.optimization = (opt, forward, optimized, kept, why)
    run.prediction = optimized if kept else forward
    if kept:
        run.ribbons = opt.ribbons
        _design_document(run)
    choice = run.field_choice
    field = ("" if choice is None else
             f"line field: {'one family through the saddle regions' if choice['kept'] == 'one_family' else 'the paper’s'}"
             f" ({choice['reason']}); ")
    return (field + f"{len(opt.ribbons)} thicknesses, {opt.iterations} iterations ({opt.stopped}); predicted mean "
            f"{forward.deviation_pct['mean']:.2f} → {optimized.deviation_pct['mean']:.2f} %: "
            f"{'kept' if kept else 'the forward layout kept'} ({why})")


def _choose_field(run: _Run, family: SaddleFamily, paper: Prediction) -> Prediction:
    """The layout of one family of curvature lines through the ambiguous saddle regions
    (``saddle_family``) made and predicted beside the paper's; the run continues with the one whose
    prediction is better (``optimization_kept``'s rule). Returns the kept layout's prediction."""
    run.progress.iteration("optimize", 0, 0.0, 0.0)
    alt = copy.copy(run)
    alt.timings, alt.progress = {}, NoProgress()
    alt.frames = face_frames(alt.V, alt.F)        # at V's size: a fit to the frame scaled V after the curvature
    try:
        alt.line_field = curvature_line_field(alt.V, alt.F, alt.frames, alt.curvature, alt.params.smoothing_lambda,
                                              alt.solver.umbilic_tolerance, targets=(family.angle, family.weight))
        alt.field_dev = field_k1_deviation(alt.line_field, alt.curvature)
        _flatten(alt)
        _in_print_coordinates(alt)
        _stripes(alt)
        _cut_ribbons(alt)
        _design_document(alt)
        one = _predict(alt.uv, alt.V, alt.F, alt.ribbons, alt.params, alt.table, run.progress, stage="optimize")
    except DesignError as exc:
        run.field_choice = {"switched_pct": family.switched_pct, "kept": "paper", "paper": paper, "one_family": None,
                            "reason": f"the one-family layout could not be made: {exc}"}
        return paper
    kept, why = optimization_kept(paper, one)
    run.field_choice = {"switched_pct": family.switched_pct, "kept": "one_family" if kept else "paper",
                        "paper": paper, "one_family": one, "reason": why}
    if not kept:
        return paper
    keep = {"timings", "progress", "t_start", "field_choice"}
    run.__dict__.update({k: v for k, v in alt.__dict__.items() if k not in keep})
    return one


def optimization_kept(forward: Prediction, optimized: Prediction) -> tuple[bool, str]:
    """Whether the optimized layout replaces the forward one, and why: its prediction (released from
    the flat sheet, every release) must be closer to the target on the mean and no worse on the
    worst release, and keep ``reached`` where the forward one has it. The optimization itself follows
    one release on a coarser mesh: a layout that it improves can settle elsewhere when released."""
    fm, om = forward.deviation_pct["mean"], optimized.deviation_pct["mean"]
    fw, ow = forward.agreement.spread_mean[1], optimized.agreement.spread_mean[1]
    if om >= fm:
        return False, f"its predicted mean {om:.2f} % is not below the forward layout's {fm:.2f} %"
    if ow > fw:
        return False, f"its worst release {ow:.2f} % is above the forward layout's {fw:.2f} %"
    if forward.reached and not optimized.reached:
        return False, "the forward layout is reached (predicted to take the shape) and the optimized one is not"
    return True, f"predicted mean {fm:.2f} → {om:.2f} %, worst release {fw:.2f} → {ow:.2f} %"


def _preview(run: _Run) -> str:
    """The picture of the predicted shape and the layout preview."""
    name = run.target.name
    run.deployed_png = (run.prediction.render_png(run.V, run.F, title=f"{name}: predicted deployed shape")
                        if run.prediction is not None else None)
    run.preview_svg, run.preview_png = _layout_preview(name, run.uv, run.F, run.flat.sigma[:, 1], run.design,
                                                       run.frame)
    return f"{len(run.preview_png) // 1024} kB PNG, {len(run.preview_svg) // 1024} kB SVG"


def _layout_preview(name: str, uv: np.ndarray, F: np.ndarray, sigma2: np.ndarray, design: Design,
                    frame: FrameSpec) -> tuple[bytes, bytes]:
    """``preview.svg`` and ``preview.png`` of a design's layout, its marks and stitch marks."""
    ribbons = design.ribbons or []
    n, front = len(ribbons), sum(r.side == "front" for r in ribbons)
    marks = np.asarray(design.registration_marks) if design.registration_marks else None
    return render_preview(
        uv, F, sigma2, ribbons, design.parameters.ribbon_width, marks=marks, frame_bounds=frame.bounds,
        sigma2_bounds=design.parameters.bounds[1], flip_axis=frame.flip_axis, stitch_marks=design.stitch_marks,
        title=f"{name}: {n} ribbons ({front} front, {n - front} back), size {design.parameters.size.bbox_diagonal:.0f} mm")


def finish_design(result: DesignResult, name: str, stitch_marks: list[StitchMark] | None = None) -> DesignResult:
    """The print programs and the pictures of a design made with ``finish=False``, with stitch marks on
    its front when given (issue 26); the layout, the prediction and the report's other figures as they are.

    Raises
    ------
    DesignError
        when the programs cannot be made or extrude nothing.
    """
    profile = load_profile(result.design.parameters.printer_profile)
    design = result.design.updated(stitch_marks=stitch_marks or None)
    programs = _programs(design, profile if result.frame == profile.frame
                         else profile.model_copy(update={"frame": result.frame}))
    fs, bs = programs.front.stats, programs.back.stats
    if fs.extrusion_mm + bs.extrusion_mm <= 0.0:
        raise DesignError("the print programs extrude nothing: the design would print nothing")
    design = design.updated(report=design.report.updated(print_=PrintReport(
        front=SidePrintReport(**fs.report()), back=SidePrintReport(**bs.report()))))
    svg, png = _layout_preview(name, result.flat_uv, result.F, result.flattening.sigma[:, 1], design, result.frame)
    deployed = (result.prediction.render_png(result.V, result.F, title=f"{name}: predicted deployed shape")
                if result.prediction is not None else None)
    return replace(result, design=design, programs=programs, preview_svg=svg, preview_png=png, deployed_png=deployed)


#: The stages ``finish=False`` leaves to ``finish_design``.
FINISHING = ("gcode", "preview")

#: The engine's stages in order: what the worker, the daemon and ``ribbonctl design`` show.
STAGES = (
    _Stage("load", "reading {run.mesh_name}", _load),
    _Stage("curvature", "principal curvatures and the k1 line field", _curvature),
    _Stage("flatten", "bounded directional flattening", _flatten, after=_in_print_coordinates),
    _Stage("stripes", "ribbon spacing (Eq. 10) and the stripe patterns θ and ψ", _stripes),
    _Stage("ribbons", "staggered ribbons, sides and thicknesses", _cut_ribbons, after=_design_document),
    _Stage("optimize", "the ribbons' thicknesses optimized against the prediction", _optimize,
           applies=lambda run: run.predict and run.optimize),
    _Stage("gcode", "print programs for {run.profile.name}", _gcode, after=_check_extrusion),
    _Stage("deploy", f"predicting the deployed shape (the flat sheet released, {len(RELEASES)} ways)", _deploy,
           after=_deployed_report, applies=lambda run: run.predict),
    _Stage("preview", "rendering the layout preview", _preview),
)


def _result(run: _Run) -> DesignResult:
    """The design with its timings, and everything the stages computed."""
    run.report["timings_s"] = dict(run.timings)
    run.report["time_s"] = time.perf_counter() - run.t_start
    design = run.design.updated(report=Report(**run.report))
    return DesignResult(target=run.target, V=run.V, F=run.F, flat_uv=run.uv, curvature=run.curvature,
                        field=run.line_field, flattening=run.flat, kappa1=run.kappa1,
                        ribbon_direction=run.direction, stripes=run.stripes, layout=run.layout, frame=run.frame,
                        design=design, programs=run.programs, preview_svg=run.preview_svg,
                        preview_png=run.preview_png, prediction=run.prediction, deployed_png=run.deployed_png)


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
             table: CurvatureTable, progress: DesignProgress, releases=RELEASES, stage: str = "deploy") -> Prediction:
    calls = [0]

    def relay(fraction: float, message: str) -> None:
        calls[0] += 1
        progress.iteration(stage, calls[0], fraction, 0.0)

    try:
        return predict_deployed(uv, V, F, ribbons, prestretch=params.prestretch, releases=releases,
                                ribbon_width=params.ribbon_width, table=table, progress=relay)
    except ValueError as exc:
        raise DesignError(f"the deployed shape cannot be predicted: {exc}") from None


def _programs(design: Design, profile: PrinterProfile) -> Programs:
    try:
        return make_programs(design, profile)
    except GcodeError as exc:
        raise DesignError(f"the print programs cannot be made: {exc}") from None


def _ribbons(layout: RibbonLayout, table: CurvatureTable) -> tuple[list[Ribbon], ThicknessResult]:
    """The ``design.json`` ribbons (side by the sign of κ1, thickness from ``table``) and their
    thicknesses (which clamped to the table's range, at which end)."""
    thick = ribbon_thickness(table, layout.kappa1, layout.spacing[:, 1])
    ribbons = [Ribbon(side="front" if k > 0 else "back", points=[(float(x), float(y)) for x, y in pts],
                      thickness=float(tau), kappa1=float(k), spacing=(float(mu[0]), float(mu[1])))
               for pts, tau, k, mu in zip(layout.points, thick.thickness, layout.kappa1, layout.spacing)]
    return ribbons, thick


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
