"""Panels (issue 26): a target one sheet cannot make, cut into panels, each an ordinary design.

``design_project`` reads and scales the target once, computes its curvature and line field, and
cuts it (``panels``: a spectral partition whose seams prefer the k1 direction and low curvature)
into the fewest panels that each flatten within the stretch bounds (at most ``MAX_BAD_PCT`` of
faces outside) and fit the frame with the seam allowance. Each panel is then designed by the
engine's own stages (``pipeline.design_mesh``) at the target's physical scale, the seams measured
on the target, the flat panels and their predicted shapes, and stitch marks placed at matched
arc lengths. ``write_project`` writes the project folder (``project.json``, ``panel-K/``, …).
"""

from __future__ import annotations

import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from .sewing import Assembly, ReleasedPanel, SeamPairing, assemble
from ..gcode.profiles import FrameSpec, load_profile
from ..gcode.program import GcodeError
from ..design.curvature import face_curvature
from ..design.errors import DesignError
from ..design.flatten import BoundedFlattener
from ..design.frames import face_frames
from ..design.intake import TargetMesh, load_target
from ..design.line_field import ANISOTROPY_THRESHOLD, curvature_line_field
from ..mesh.files import write_obj
from .cut import (bisect, boundary_loops, grid_partition, interior_edges, longest_axis, straighten_seams, panel_submesh, partition, seam_weights,
                  spectral_embedding)
from ..design.params import DesignParameters, SizeSpec, SolverSettings
from ..pipeline.compile import DesignProgress, DesignResult, NoProgress, design_mesh, finish_design
from .stitch import make_stitch_marks
from ..design.placement import fit_scale, place_in_frame
from ..design.refine import refine_target
from ..design.report import BAD_TOLERANCE, bounds_deviation
from .seams import (SeamChain, mark_fractions, outward_normals, points_at_fractions, polyline_length, seam_chains,
                    seam_label)

#: A panel may have at most this share of its faces outside the stretch bounds, %.
MAX_BAD_PCT = 1.0
#: The most panels ``auto`` tries.
MAX_PANELS = 16
#: Default seam allowance outside each cut line, mm on the released fabric.
SEAM_ALLOWANCE = 6.0
#: About how far apart stitch marks are along a seam, mm (deployed).
MARK_SPACING = 20.0
PROJECT_FILE = "project.json"
PROJECT_FORMAT = "ribbond-project/1"


@dataclass(frozen=True)
class PanelCheck:
    """Whether one panel can be made from one sheet: its flattening against the bounds and the frame.

    Attributes
    ----------
    bad_pct : % of its faces outside the stretch bounds; flat_size : (w, h) of its flat layout placed
    in the frame, mm; fits : it fits the frame less the margin; feasible : bad_pct ≤ MAX_BAD_PCT and fits.
    """

    bad_pct: float
    flat_size: tuple[float, float]
    fits: bool
    uv: np.ndarray | None = field(default=None, repr=False, compare=False)

    @property
    def feasible(self) -> bool:
        return self.bad_pct <= MAX_BAD_PCT and self.fits


@dataclass(frozen=True)
class Cut:
    """A partition of the target's faces into panels and each panel's check.

    Attributes
    ----------
    labels : (m,) panel of each face (0-based, by decreasing area); V : (n, 3) the target with its seams
    straightened (``panels.straighten_seams``: the same surface); checks : per panel;
    tried : per panel count tried, the worst bad_pct and whether all fit; feasible : every panel is.
    """

    labels: np.ndarray
    V: np.ndarray
    checks: list[PanelCheck]
    tried: list[dict] = field(default_factory=list)

    @property
    def count(self) -> int:
        return len(self.checks)

    @property
    def feasible(self) -> bool:
        return all(c.feasible for c in self.checks)


def panel_margin(solver: SolverSettings, seam_allowance: float, prestretch: float) -> float:
    """The free border a panel keeps inside the frame, mm: the layout margin, or more when the seam
    allowance (printed on the stretched fabric, so s × the released allowance) needs it."""
    return max(solver.layout_margin, seam_allowance * prestretch + 1.0)


def check_panel(V: np.ndarray, F: np.ndarray, params: DesignParameters, solver: SolverSettings,
                frame: FrameSpec, margin: float, geometry: tuple | None = None) -> PanelCheck:
    """Flatten one panel (V (n, 3) at physical scale, mm; F (m, 3)) and check it against the bounds and the
    frame; ``geometry``: its (frames, curvature, line field) when already computed."""
    frames, curv, lines = geometry or _geometry(V, F, params, solver)
    flat = BoundedFlattener(V, F, lines.angle, params.bounds, solver, frames=frames, prestretch=params.prestretch,
                            k1_defined=lines.anisotropy > ANISOTROPY_THRESHOLD).solve(boundary=boundary_loops(F)[0])
    (b1, b2) = params.bounds
    bad = ((bounds_deviation(flat.sigma[:, 0], *b1) > BAD_TOLERANCE)
           | (bounds_deviation(flat.sigma[:, 1], *b2) > BAD_TOLERANCE) | flat.folded)
    placed, _ = place_in_frame(flat.uv, frame, margin)
    w, h = placed.max(axis=0) - placed.min(axis=0)
    return PanelCheck(bad_pct=float(100.0 * bad.mean()), flat_size=(float(w), float(h)),
                      fits=fit_scale(placed, frame, margin) >= 1.0, uv=flat.uv)


def _geometry(V: np.ndarray, F: np.ndarray, params: DesignParameters, solver: SolverSettings) -> tuple:
    """(frames, curvature, line field) of a mesh, as the engine's curvature stage computes them."""
    frames = face_frames(V, F)
    curv = face_curvature(V, F, frames)
    lines = curvature_line_field(V, F, frames, curv, params.smoothing_lambda, solver.umbilic_tolerance,
                                 method=solver.line_field)
    return frames, curv, lines


def _is_disk(F: np.ndarray, n_vertices: int) -> bool:
    e_int = len(interior_edges(F)[0])
    e_bnd = 3 * len(F) - 2 * e_int
    return len(boundary_loops(F)) == 1 and n_vertices - (e_int + e_bnd) + len(F) == 1


class _Checker:
    """Checks panels by their faces, each distinct panel once (the searches meet the same ones again)."""

    def __init__(self, V: np.ndarray, F: np.ndarray, params: DesignParameters, solver: SolverSettings,
                 frame: FrameSpec, margin: float, whole: tuple) -> None:
        self.V, self.F, self.params, self.solver, self.frame, self.margin = V, F, params, solver, frame, margin
        self.whole = whole                     # the whole target's geometry: one panel is the whole
        self.seen: dict[bytes, PanelCheck] = {}

    def __call__(self, X: np.ndarray, labels: np.ndarray, j: int) -> PanelCheck:
        key = np.flatnonzero(labels == j).tobytes()
        if key not in self.seen:
            Vp, Fp, _, _ = panel_submesh(X, self.F, labels, j)
            whole = self.whole if len(Fp) == len(self.F) else None
            self.seen[key] = (check_panel(Vp, Fp, self.params, self.solver, self.frame, self.margin, whole)
                              if _is_disk(Fp, len(Vp)) else PanelCheck(100.0, (np.inf, np.inf), False))
        return self.seen[key]

    def all(self, X: np.ndarray, labels: np.ndarray, stop_early: bool) -> list[PanelCheck]:
        """Each panel's check in order (X (n, 3): the target as cut); with ``stop_early``, up to the first
        that is not feasible."""
        checks = []
        for j in range(int(labels.max()) + 1):
            checks.append(self(X, labels, j))
            if stop_early and not checks[-1].feasible:
                break
        return checks


def _face_graph(V: np.ndarray, F: np.ndarray, geometry: tuple) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The face graph with its seam weights (``panels.seam_weights``) and the face areas."""
    frames, curv, lines = geometry
    pairs, verts = interior_edges(F)
    return pairs, seam_weights(V, verts, pairs, lines.direction, lines.anisotropy, np.abs(curv.kappa1)), frames.area


def _halve(halves: np.ndarray, V: np.ndarray, F: np.ndarray, check: _Checker, pairs: np.ndarray,
           weights: np.ndarray, area: np.ndarray) -> np.ndarray:
    """Recursive bisection's next step: the largest panel that fails is halved (across its longest extent
    when it is too large for the frame, else along its Fiedler vector)."""
    checks = check.all(straighten_seams(V, F, halves), halves, stop_early=False)
    sizes = np.bincount(halves, weights=area) * np.array([not c.feasible for c in checks])
    j = int(np.argmax(sizes))
    across = None if checks[j].fits else longest_axis(V[F].mean(axis=1), area, np.flatnonzero(halves == j))
    return bisect(halves, j, pairs, weights, area, across)


def fewest_panels(area: float, params: DesignParameters, frame: FrameSpec, margin: float) -> int:
    """A lower bound on the panels a target of ``area`` mm² needs: within the bounds a face's flat area is
    at least σ1_min σ2_min times its own (but on the 1 % allowed out), and a panel's flat layout lies in
    the frame less the margin."""
    (s1, _), (s2, _) = params.bounds
    room = (frame.size[0] - 2 * margin) * (frame.size[1] - 2 * margin)
    return max(1, int(np.ceil(area * s1 * s2 * (1.0 - MAX_BAD_PCT / 100.0) / room - 1e-9)))


def _too_few(k: int, fewest: int) -> Cut:
    """The cut that is not tried: k panels cannot hold the target's flat area."""
    return Cut(labels=np.zeros(0, dtype=np.int64), V=np.zeros((0, 3)),
               checks=[PanelCheck(bad_pct=0.0, flat_size=(np.inf, np.inf), fits=False)],
               tried=[{"panels": k, "cut": f"area: at least {fewest} panels", "worst_bad_pct": 0.0, "fit": False,
                       "checked": 0}])


def cut_target(V: np.ndarray, F: np.ndarray, params: DesignParameters, solver: SolverSettings, frame: FrameSpec,
               panels: int | str, margin: float, progress: Callable[[int, str], None] | None = None,
               fewest: int = 1) -> Cut:
    """Cut the target (V (n, 3) mm, F (m, 3)) into ``panels`` panels, or with ``"auto"`` into the fewest
    (up to ``MAX_PANELS``) that are each feasible.

    For each count k the k-means cut of the spectral embedding is tried (gores on a bowl); when one of
    its panels is too large for the frame, the r × (k / r) tilings along the principal axes are tried
    (``panels.grid_partition``), then recursive bisection (auto only), which halves the largest panel
    that failed until there are k. Each cut's seams are straightened before its panels are flattened.
    The search starts at ``fewest`` or at the area's lower bound (``fewest_panels``), whichever is more;
    beyond ``MAX_PANELS`` (or the count asked for) nothing is tried. Returns the first feasible cut, or
    the last tried."""
    frames = face_frames(V, F)
    fewest = max(fewest, fewest_panels(float(frames.area.sum()), params, frame, margin))
    if fewest > (MAX_PANELS if panels == "auto" else int(panels)):
        return _too_few(MAX_PANELS if panels == "auto" else int(panels), fewest)
    whole = _geometry(V, F, params, solver)
    pairs, weights, area = _face_graph(V, F, whole)
    counts = range(fewest, MAX_PANELS + 1) if panels == "auto" else [int(panels)]
    dims = min(max(counts) - 1, len(F) - 3)
    embedding = spectral_embedding(pairs, weights, area, dims) if dims >= 1 else np.zeros((len(F), 0))
    check = _Checker(V, F, params, solver, frame, margin, whole)
    halves = np.zeros(len(F), dtype=np.int64)
    tried: list[dict] = []
    centroids = V[F].mean(axis=1)

    def _try(k: int, how: str, labels: np.ndarray) -> Cut:
        X = straighten_seams(V, F, labels) if labels.max() > 0 else V
        checks = check.all(X, labels, stop_early=panels == "auto")
        tried.append({"panels": int(labels.max()) + 1, "cut": how, "worst_bad_pct": round(max(c.bad_pct for c in checks), 3),
                      "fit": all(c.fits for c in checks), "checked": len(checks)})
        return Cut(labels=labels, V=X, checks=checks, tried=list(tried))

    def made(cut: Cut, k: int) -> bool:
        return cut.feasible and len(cut.checks) == k

    cut: Cut | None = None
    for k in counts:
        cut = _try(k, "spectral", partition(embedding[:, :max(k - 1, 1)], k, pairs, weights, area))
        too_large = k > 1 and not all(c.fits for c in cut.checks)
        for rows in (range(1, k + 1) if too_large else []):      # a tiling, for a surface wider than the frame
            if k % rows == 0 and not made(cut, k):
                cut = _try(k, f"grid {rows}×{k // rows}", grid_partition(centroids, area, rows, k // rows, pairs, weights))
        if too_large and panels == "auto" and not made(cut, k):
            while halves.max() + 1 < k:
                halves = _halve(halves, V, F, check, pairs, weights, area)
            cut = _try(k, "bisection", halves)
        if progress is not None:
            t = tried[-1]
            progress(k, f"{k} panels ({t['cut']}): " + ("feasible" if made(cut, k) else
                     f"worst {t['worst_bad_pct']:.1f} % outside" + ("" if t["fit"] else ", too large for the frame")))
        if made(cut, k):
            return cut
    assert cut is not None
    return cut


@dataclass(frozen=True)
class PanelDesign:
    """One panel's design.

    Attributes
    ----------
    result : the engine's design of the panel (its own flat layout, ribbons, G-code, prediction).
    vertex_index : (p,) the panel's vertices in the target; face_index : (q,) its faces in the target.
    local : (p,) where each of those vertices is in ``result.V`` (the engine's own order).
    offset : (3,) the panel's centre: ``result.V[local] + offset`` is the target's vertex.
    """

    result: DesignResult
    vertex_index: np.ndarray
    face_index: np.ndarray
    local: np.ndarray
    offset: np.ndarray

    def flat_at(self, target_vertices: np.ndarray) -> np.ndarray:
        """(k, 2) flat (print) positions of target vertices (k,) of this panel."""
        where = np.searchsorted(self.vertex_index, target_vertices)
        return self.result.flat_uv[self.local[where]]

    def outline(self) -> np.ndarray:
        """(q, 2) the flat outline, counter-clockwise, print coordinates."""
        loop = self.result.flat_uv[self.result.target.boundary]
        x, y = loop[:, 0], loop[:, 1]
        ccw = (x * np.roll(y, -1) - np.roll(x, -1) * y).sum() > 0
        return loop if ccw else loop[::-1]


def _prefixed(progress: DesignProgress, k: int, n: int) -> DesignProgress:
    """The engine's progress for panel k of n: stages named ``panel-k/stage``."""

    class _Panel:
        def stage_started(self, stage: str, description: str) -> None:
            progress.stage_started(f"panel-{k}/{stage}", f"panel {k} of {n}: {description}")

        def iteration(self, stage: str, iteration: int, change: float, energy: float) -> None:
            progress.iteration(f"panel-{k}/{stage}", iteration, change, energy)

        def stage_finished(self, stage: str, seconds: float, summary: str) -> None:
            progress.stage_finished(f"panel-{k}/{stage}", seconds, summary)

    return _Panel()


def _load_scaled(mesh_path: str | Path, params: DesignParameters, solver: SolverSettings
                 ) -> tuple[TargetMesh, np.ndarray, float]:
    """The cleaned, refined target, centred, at its physical size: ``size`` or, without one, the
    file's own units read as mm (a project's panels must keep one scale: "largest that fits" has no
    meaning when more panels make anything fit)."""
    target = load_target(mesh_path, max_faces=solver.max_faces, merge_tolerance=solver.merge_tolerance)
    target, _ = refine_target(target, solver.refine_below_faces, solver.refine_to_faces, solver.max_faces,
                              solver.refine_method)
    diag = float(np.linalg.norm(target.V.max(axis=0) - target.V.min(axis=0)))
    size = params.size.bbox_diagonal if params.size is not None else diag
    return target, (target.V - target.V.mean(axis=0)) * (size / diag), size


def _infeasible_message(cut: Cut, panels: int | str) -> str:
    if cut.tried and cut.tried[-1]["cut"].startswith("area"):
        return (f"the target's flat area needs {cut.tried[-1]['cut'].split('at least ')[1]} of the frame "
                + (f"(at most {MAX_PANELS} are tried)" if panels == "auto" else f"(asked for {panels})")
                + "; make the target smaller (size)")
    worst = max(cut.checks, key=lambda c: (not c.fits, c.bad_pct))
    what = (f"{worst.bad_pct:.1f} % of a panel's faces outside the stretch bounds (at most {MAX_BAD_PCT:g} %)"
            if worst.fits else f"a panel of {worst.flat_size[0]:.0f} × {worst.flat_size[1]:.0f} mm too large "
                               "for the frame with its seam allowance")
    if panels == "auto":
        return (f"even {cut.count} panels leave {what}; make the target smaller (size) or smoother, "
                "or widen the stretch bounds")
    return f"{cut.count} panels leave {what}; try panels = auto"


def _design_panel(V: np.ndarray, F: np.ndarray, cut: Cut, j: int, name: str,
                  params: DesignParameters, solver: SolverSettings, frame: FrameSpec, progress: DesignProgress,
                  predict: bool, tables_dir: Path | None, workdir: Path) -> PanelDesign:
    """Design panel j (0-based) of the cut with the engine's stages, at the target's scale (its flattening
    starts from the cut's check of it, which ran the same flattening)."""
    labels, n = cut.labels, cut.count
    Vp, Fp, vertex_index, face_index = panel_submesh(V, F, labels, j)
    path = workdir / f"{Path(name).stem}-panel-{j + 1}.obj"
    write_obj(path, Vp, Fp, header=f"ribbond project: panel {j + 1} of {n} of {name}, mm")
    diag = float(np.linalg.norm(Vp.max(axis=0) - Vp.min(axis=0)))
    result = design_mesh(path, params.model_copy(update={"size": SizeSpec(bbox_diagonal=diag)}), solver,
                         frame=frame, progress=_prefixed(progress, j + 1, n), predict=predict,
                         tables_dir=tables_dir, flat_start=cut.checks[j].uv, finish=False)
    offset = Vp.mean(axis=0)
    dist, local = cKDTree(result.V + offset).query(Vp)
    if dist.max() > 1e-6 * diag:
        raise DesignError(f"panel {j + 1}: the engine moved its vertices ({dist.max():.3g} mm); "
                          "its seams cannot be matched")
    return PanelDesign(result=result, vertex_index=vertex_index, face_index=face_index, local=local, offset=offset)


@dataclass(frozen=True)
class Seam:
    """A seam between two panels.

    Attributes
    ----------
    label : its letters (A, B, …); panels : (a, b) 0-based; vertices : (p,) target vertices along it.
    flat : per side, (p, 2) the seam line on that panel's flat layout, print coordinates, mm.
    target_length : on the target, mm; deployed_length : per side on its predicted shape (None without one).
    marks : per side, (k, 2) the stitch marks on the seam line (matched fractions of each side's
    deployed length, or of the target's without a prediction); outward : per side (k, 2) unit normals.
    """

    label: str
    panels: tuple[int, int]
    vertices: np.ndarray
    flat: tuple[np.ndarray, np.ndarray]
    target_length: float
    deployed_length: tuple[float, float] | None
    marks: tuple[np.ndarray, np.ndarray]
    outward: tuple[np.ndarray, np.ndarray]

    @property
    def length_mismatch_pct(self) -> float | None:
        """The largest of |La − Lb|, |La − L|, |Lb − L| in % of the target's length L."""
        if self.deployed_length is None:
            return None
        a, b = self.deployed_length
        t = self.target_length
        return float(100.0 * max(abs(a - b), abs(a - t), abs(b - t)) / t)


def _deployed_polyline(panel: PanelDesign, flat: np.ndarray) -> np.ndarray | None:
    from ..deploy.predict import interpolate
    p = panel.result.prediction
    return None if p is None else interpolate(flat, p.uv, p.F, p.V)


def _seam(i: int, chain: SeamChain, V: np.ndarray, panels: list[PanelDesign]) -> Seam:
    """Seam i on the target: its flat and deployed polylines per side and its stitch marks."""
    sides = [panels[chain.panels[0]], panels[chain.panels[1]]]
    flat = tuple(side.flat_at(chain.vertices) for side in sides)
    target_length = polyline_length(V[chain.vertices])
    deployed = [_deployed_polyline(side, f) for side, f in zip(sides, flat)]
    measures = deployed if all(d is not None for d in deployed) else [V[chain.vertices]] * 2
    fractions = mark_fractions(target_length, MARK_SPACING)
    marks = tuple(points_at_fractions(f, m, fractions) for f, m in zip(flat, measures))
    outward = tuple(outward_normals(side.outline(), mk) for side, mk in zip(sides, marks))
    return Seam(label=seam_label(i), panels=chain.panels, vertices=chain.vertices, flat=flat,   # type: ignore[arg-type]
                target_length=target_length,
                deployed_length=(tuple(polyline_length(d) for d in deployed)                     # type: ignore[arg-type]
                                 if all(d is not None for d in deployed) else None),
                marks=marks, outward=outward)                                                   # type: ignore[arg-type]


def stitch_panels(panels: list[PanelDesign], seams: list[Seam], tick_length: float, name: str) -> list[PanelDesign]:
    """Each panel finished (``pipeline.finish_design``: its programs and pictures) with the stitch marks of
    its seams printed on its front: mark j of seam A is "A{j+1}" on both sides, a tick across the allowance
    (``tick_length``, mm on the stretched fabric; 0: no marks) and its label."""
    out = []
    for k, panel in enumerate(panels):
        at, outward, labels = [], [], []
        for seam in seams:
            for side in (0, 1):
                if seam.panels[side] == k:
                    at.append(seam.marks[side])
                    outward.append(seam.outward[side])
                    labels += [f"{seam.label}{j + 1}" for j in range(len(seam.marks[side]))]
        title = f"{Path(name).stem} panel {k + 1}"
        try:
            marks = (make_stitch_marks(np.vstack(at), np.vstack(outward), labels, tick_length)
                     if labels and tick_length > 0 else None)
            result = finish_design(panel.result, title, marks)
        except (ValueError, GcodeError) as exc:
            raise DesignError(f"panel {k + 1}: the stitch marks cannot be printed: {exc}") from None
        out.append(replace(panel, result=result))
    return out


def project_seams(V: np.ndarray, F: np.ndarray, panels: list[PanelDesign]) -> list[Seam]:
    """The seams between the designed panels (V (n, 3), F (m, 3): the target they were cut from)."""
    loops = []
    for panel in panels:
        local = np.searchsorted(panel.vertex_index, F[panel.face_index])
        loops.append(panel.vertex_index[boundary_loops(local)[0]])
    return [_seam(i, chain, V, panels) for i, chain in enumerate(seam_chains(loops))]


@dataclass(frozen=True)
class ProjectResult:
    """Everything ``design_project`` made.

    Attributes
    ----------
    target : the cleaned (refined) target as read; V : (n, 3) it centred at its physical size, mm; F : (m, 3).
    cut : the partition and its checks; panels : each panel's design (panel K is ``panels[K − 1]``);
    seams : the seams; seam_allowance : mm on the released fabric; size : the target's bbox diagonal, mm;
    timings : seconds per step; assembly : the panels' predictions sewn together (None without predictions).
    """

    target: TargetMesh
    V: np.ndarray
    F: np.ndarray
    cut: Cut
    panels: list[PanelDesign]
    seams: list[Seam]
    seam_allowance: float
    size: float
    timings: dict[str, float]
    assembly: Assembly | None = None


def _check_request(panels: int | str, seam_allowance: float) -> None:
    if panels != "auto" and not (isinstance(panels, int) and 1 <= panels <= MAX_PANELS):
        raise DesignError(f"panels = {panels!r}: give 'auto' or a number of panels from 1 to {MAX_PANELS}")
    if not (np.isfinite(seam_allowance) and 0.0 <= seam_allowance <= 30.0):
        raise DesignError(f"seam_allowance = {seam_allowance!r} mm: give a number from 0 to 30 mm")


def design_project(mesh_path: str | Path, parameters: DesignParameters | None = None,
                   solver: SolverSettings | None = None, *, panels: int | str = "auto",
                   seam_allowance: float = SEAM_ALLOWANCE, frame: FrameSpec | None = None,
                   progress: DesignProgress | None = None, predict: bool = True,
                   tables_dir: Path | None = None) -> ProjectResult:
    """Cut the target into panels that one sheet each can make, and design every panel.

    Parameters
    ----------
    mesh_path : the target mesh file (OBJ, PLY, STL, OFF).
    parameters : as for ``design_mesh``; ``size`` None reads the file's units as mm.
    solver : as for ``design_mesh`` (its refinement applies to the whole target, before the cut).
    panels : "auto" (the fewest feasible, up to ``MAX_PANELS``) or a number of panels.
    seam_allowance : fabric left outside each cut line for sewing, mm (released).
    frame : the printable rectangle; default: the printer profile's.

    Raises
    ------
    MeshError, DesignError
        as ``design_mesh``; DesignError also when no cut makes every panel feasible.
    """
    params, solver, progress = parameters or DesignParameters(), solver or SolverSettings(), progress or NoProgress()
    _check_request(panels, seam_allowance)
    frame = frame or load_profile(params.printer_profile).frame
    timings: dict[str, float] = {}
    t = time.perf_counter()
    progress.stage_started("cut", f"cutting {Path(mesh_path).name} into panels")
    target, V, size = _load_scaled(mesh_path, params, solver)
    margin = panel_margin(solver, seam_allowance, params.prestretch)
    cut = cut_target(V, target.F, params, solver, frame, panels, margin,
                     progress=lambda k, text: progress.iteration("cut", k, 0.0, 0.0))
    timings["cut"] = time.perf_counter() - t
    progress.stage_finished("cut", timings["cut"], f"{cut.count} panels; " + ", ".join(
        f"{d['panels']}: {d['worst_bad_pct']:.1f} % out" for d in cut.tried))
    if not cut.feasible:
        raise DesignError(_infeasible_message(cut, panels))
    panel_solver = solver.model_copy(update={"refine_below_faces": 0, "layout_margin": margin})
    t = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="ribbond-panels-") as tmp:
        designs = [_design_panel(cut.V, target.F, cut, j, target.name, params, panel_solver, frame,
                                 progress, predict, tables_dir, Path(tmp)) for j in range(cut.count)]
    timings["panels"] = time.perf_counter() - t
    t = time.perf_counter()
    seams = project_seams(cut.V, target.F, designs)
    timings["seams"] = time.perf_counter() - t
    t = time.perf_counter()
    progress.stage_started("finish", f"stitch marks, print programs and previews of the {cut.count} panels")
    designs = stitch_panels(designs, seams, seam_allowance * params.prestretch, target.name)
    timings["finish"] = time.perf_counter() - t
    progress.stage_finished("finish", timings["finish"], f"{sum(len(s.marks[0]) for s in seams)} stitch marks "
                            f"on each side of {len(seams)} seams")
    assembly = None
    if predict:
        t = time.perf_counter()
        progress.stage_started("assemble", f"sewing the {cut.count} predicted panels together")
        assembly = assemble_prediction(cut.V, target.F, designs, seams)
        timings["assemble"] = time.perf_counter() - t
        progress.stage_finished("assemble", timings["assemble"], _assembly_summary(assembly))
    return ProjectResult(target=target, V=cut.V, F=target.F, cut=cut, panels=designs, seams=seams,
                         seam_allowance=seam_allowance, size=size, timings=timings, assembly=assembly)


#: Matched points along a seam for the sewing, about this far apart (deployed), mm.
SEWING_SPACING = 2.0


def assemble_prediction(V: np.ndarray, F: np.ndarray, panels: list[PanelDesign], seams: list[Seam]) -> Assembly:
    """The panels as released, sewn along their seams (``ribbond.panels.sewing``): each seam's two
    sides paired at matched fractions of their deployed lengths, as the stitch marks pin them. The whole
    target (V (n, 3), F (m, 3)) only registers and measures the result."""
    released = []
    for panel in panels:
        p = panel.result.prediction
        assert p is not None
        released.append(ReleasedPanel(sheet=p.sheet, X=p.X_released, target=p.target + panel.offset))
    pairings = []
    for seam in seams:
        a, b = (panels[k] for k in seam.panels)
        fractions = np.linspace(0.0, 1.0, max(2, int(round(seam.target_length / SEWING_SPACING)) + 1))
        points = [points_at_fractions(flat, _deployed_polyline(side, flat), fractions)
                  for side, flat in zip((a, b), seam.flat)]
        pairings.append(SeamPairing(panel_a=seam.panels[0], points_a=points[0], panel_b=seam.panels[1],
                                    points_b=points[1]))
    try:
        return assemble(released, pairings, V, F)
    except ValueError as exc:
        raise DesignError(f"the panels cannot be sewn together: {exc}") from None


def _assembly_summary(a: Assembly) -> str:
    d = a.deviation_pct
    return (f"deviation mean {d['mean']:.2f} %, p99 {d['p99']:.2f} %, max {d['max']:.2f} % of the diagonal; "
            f"seams closed to {a.seam_gap_mm['max']:.3f} mm; {a.iterations} Newton iterations")


def _panel_entry(k: int, panel: PanelDesign, check: PanelCheck, V: np.ndarray) -> dict:
    report = panel.result.design.report
    return {"index": k, "folder": f"panel-{k}", "faces": int(len(panel.face_index)),
            "flat_size_mm": [round(float(x), 2) for x in check.flat_size],
            "bad_pct": round(float(check.bad_pct), 3),
            "ribbons": len(panel.result.design.ribbons or []),
            "outline": np.round(panel.outline(), 2).tolist(),
            "centroid_3d": np.round(V[panel.vertex_index].mean(axis=0), 2).tolist(),
            "deployed": (None if report.deployed is None
                         else {"deviation_pct": report.deployed.deviation_pct.model_dump(),
                               "reached": report.deployed.reached, "verdict": report.deployed.verdict})}


def _seam_entry(seam: Seam) -> dict:
    return {"label": seam.label, "panels": [seam.panels[0] + 1, seam.panels[1] + 1],
            "length_mm": {"target": round(seam.target_length, 3),
                          "deployed": None if seam.deployed_length is None
                          else [round(x, 3) for x in seam.deployed_length]},
            "mismatch_pct": None if seam.length_mismatch_pct is None else round(seam.length_mismatch_pct, 3),
            "marks": int(len(seam.marks[0]))}


def project_document(result: ProjectResult) -> dict:
    """The content of ``project.json``."""
    t = result.target
    return {"format": PROJECT_FORMAT, "units": "mm",
            "source": {"file": t.name, "sha256": t.sha256, "faces": t.source_faces},
            "size": {"bbox_diagonal": round(result.size, 3)},
            "seam_allowance_mm": result.seam_allowance,
            "panels": [_panel_entry(k + 1, p, c, result.V)
                       for k, (p, c) in enumerate(zip(result.panels, result.cut.checks))],
            "seams": [_seam_entry(s) for s in result.seams],
            "report": {"panels": result.cut.count,
                       "method": "spectral normalized cut of the face graph (seams weighted toward k1 and low "
                                 "curvature), the fewest panels each within the stretch bounds and the frame",
                       "tried": result.cut.tried,
                       "seam_mismatch_pct_max": max((s.length_mismatch_pct or 0.0 for s in result.seams),
                                                    default=0.0) if result.seams and
                       result.seams[0].deployed_length is not None else None,
                       "deployed": None if result.assembly is None else result.assembly.report(),
                       "timings_s": {k: round(v, 3) for k, v in result.timings.items()},
                       "time_s": round(sum(result.timings.values()), 3)}}


def render_project_png(result: ProjectResult) -> bytes:
    """``panels.png`` of the project."""
    from .picture import render_panels_png
    seams = [(s.label, s.panels[0], s.panels[1], s.flat[0], s.flat[1]) for s in result.seams]
    return render_panels_png(result.V, result.F, result.cut.labels, [p.outline() for p in result.panels], seams,
                             title=f"{result.target.name}: {result.cut.count} panels, {len(result.seams)} seams")


def check_project_destination(out_dir: str | Path) -> None:
    """Refuse, before any work, a destination a project folder could not replace (ValueError naming
    it): a file, or a directory with content and no ``project.json``; ``write_project`` checks it
    again."""
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise ValueError(f"{out_dir} exists and is not a directory; not replacing it")
    if out_dir.exists() and any(out_dir.iterdir()) and not (out_dir / PROJECT_FILE).is_file():
        raise ValueError(f"{out_dir} exists and is not a project folder (no {PROJECT_FILE}); not replacing it")


def write_project(result: ProjectResult, out_dir: str | Path, progress: DesignProgress | None = None) -> Path:
    """Write the project folder: ``project.json``, ``target.obj``, ``panels.png`` and ``panel-K/`` (each a
    design folder), into a temporary folder beside ``out_dir`` that then replaces it (a half-written
    project never replaces a good one)."""
    import json
    import secrets
    import shutil

    from ..pipeline.compile import write_design
    progress = progress or NoProgress()
    out_dir = Path(out_dir)
    check_project_destination(out_dir)
    progress.stage_started("write", f"writing {out_dir}")
    t = time.perf_counter()
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    tmp = out_dir.parent / f".{out_dir.name}.tmp-{secrets.token_hex(6)}"
    tmp.mkdir()
    try:
        for k, panel in enumerate(result.panels, start=1):
            write_design(panel.result, tmp / f"panel-{k}")
        write_obj(tmp / "target.obj", result.V, result.F, header="ribbond project: the whole target, mm")
        (tmp / "panels.png").write_bytes(render_project_png(result))
        if result.assembly is not None:
            a = result.assembly
            write_obj(tmp / "deployed.obj", a.V, a.F, header=f"ribbond project: the {result.cut.count} panels "
                      "predicted, sewn and registered to target.obj, mm")
            (tmp / "deployed.png").write_bytes(a.render_png(result.V, result.F, title=(
                f"{result.target.name}: {result.cut.count} panels sewn, predicted")))
        (tmp / PROJECT_FILE).write_text(json.dumps(project_document(result), indent=1) + "\n")
        old = None
        if out_dir.exists():
            old = out_dir.parent / f".{out_dir.name}.old-{secrets.token_hex(6)}"
            out_dir.rename(old)
        tmp.rename(out_dir)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    progress.stage_finished("write", time.perf_counter() - t, str(out_dir))
    return out_dir
