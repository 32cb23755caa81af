"""Predict the deployed shape of a printed layout (issues 12 and 23): the top level of ``ribbond.deploy``.

``predict_deployed`` takes the flat surface, the target and the ribbons, builds the printed sheet
(``rest_forms``: the homogenized model), releases it along the
physical path from the flat sheet as printed (``release``), and only then registers the result onto
the target and measures it (``compare``, ``agreement``). Nothing in the simulation reads the target:
no start, weight, bound or stopping rule; every tolerance is a fraction of the flat sheet's size.

The nominal release is followed by a few other plausible ones (``RELEASES``: the symmetry-breaking
lift against the curl, the curvature leading or lagging the contraction); the deviation over all of
them is the spread. Each release follows the path on a coarse uniform copy of the flat domain
(``coarse_faces``) and is finished at full release on the reference mesh, from the coarse result.

The reference mesh is the flat surface itself when it has at most ``1.25 × target_faces`` faces,
else a uniform triangulation of the flat domain with about ``target_faces`` faces
(``ribbond.design.remesh.remesh_flat``); the target positions reach its vertices through barycentric
coordinates of the flat mesh, for the registration only.

Material (``Material``): fabric and plastic moduli and thicknesses give, per face, the membrane
stiffness D_s = Y_f h_f + φ Y_p τ and the bending stiffness D_b = (Y_f h_f³ + φ Y_p τ³)/12, φ the
share of the face under plastic (f_d f_p).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import igl
import numpy as np

from ribbond.design.format import Ribbon
from ribbond.design.remesh import remesh_flat
from ribbond.design.thickness import CurvatureTable

from . import agreement
from .compare import surface_deviation
from .release import DEFAULT_STEPS, FORCE_TOLERANCE, NOMINAL, STEP_TOLERANCE, Path, Sheet, release
from .rest_forms import Coverage, face_coverage, rest_forms
from .solver import newton

__all__ = ["Material", "Prediction", "ReferenceMesh", "reference_mesh", "sheet_for_layout", "RELEASES",
           "predict_deployed", "barycentric", "interpolate"]

#: Default face count of the reference mesh.
DEFAULT_FACES = 3000
#: Face count of the coarse copy each release follows its path on.
COARSE_FACES = 600
#: The releases tried: the nominal one first, then the plausible variants behind the spread.
RELEASES = (NOMINAL,
            Path("lifted against the curl", 1.0, -1.0),
            Path("curvature lagging the contraction", 2.0, 1.0))
#: The finish's Newton cap, × the cap per release step. A step starts next to its equilibrium (the
#: last one, continued); the finish starts from the coarse release interpolated onto the reference
#: mesh, whose equilibrium can lie along a soft mode (a saddle's floppy rim) some way from it: Newton
#: then walks down that valley two iterations per stride, still converging quadratically at the end.
#: Measured on the small saddle of tests/deploy/test_predict.py refined at intake: 13 iterations
#: (midpoint subdivision) and 38 (the smooth refinement), where the per-step cap of 15 stopped it
#: out of balance (‖∇E‖∞ 3.6e-4 N against 1e-5) at 10, 20 and 40 steps alike.
FINISH_FACTOR = 4
#: The model: the homogenized shell (``rest_forms``; docs/engine.md says why there is no other).
MODELS = ("homogenized",)


@dataclass(frozen=True)
class Material:
    """Material constants (N, mm). Relative values matter; these are physically reasonable ones.

    Attributes
    ----------
    fabric_young : 1.0 MPa: knitted lycra (polyamide/elastane) in its working range is soft,
        about 0.5-2 MPa in tensile tests of elastane knits.
    fabric_thickness : 0.4 mm, a fine lycra knit.
    plastic_young : 26 MPa, TPU 95A (Ultimaker's technical data sheet gives a tensile modulus of 26 MPa).
    poisson : 0.3 for the homogenized sheet (plane stress).
    """

    fabric_young: float = 1.0
    fabric_thickness: float = 0.4
    plastic_young: float = 26.0
    poisson: float = 0.3

    def stiffness(self, area_fraction: np.ndarray, thickness: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(D_s, D_b) per face, N/mm and N·mm, from φ (m,) and τ (m,) mm."""
        if not (self.fabric_young > 0 and self.fabric_thickness > 0 and self.plastic_young >= 0
                and 0 <= self.poisson < 0.5):
            raise ValueError(f"material constants out of range: {self}")
        hf, yf = self.fabric_thickness, self.fabric_young
        Ds = yf * hf + area_fraction * self.plastic_young * thickness
        Db = (yf * hf ** 3 + area_fraction * self.plastic_young * thickness ** 3) / 12.0
        return Ds, Db


@dataclass(frozen=True)
class ReferenceMesh:
    """The mesh the prediction is computed on.

    Attributes
    ----------
    uv : (k, 2) flat positions, mm; F : (t, 3) faces (counter-clockwise);
    target : (k, 3) the target positions of its vertices; coarsened : it is a remesh of the flat mesh.
    """

    uv: np.ndarray
    F: np.ndarray
    target: np.ndarray
    coarsened: bool


def _flat_area(uv: np.ndarray, F: np.ndarray) -> float:
    P, Q = uv[F[:, 1]] - uv[F[:, 0]], uv[F[:, 2]] - uv[F[:, 0]]
    return 0.5 * float(np.abs(P[:, 0] * Q[:, 1] - P[:, 1] * Q[:, 0]).sum())


def reference_mesh(flat_uv: np.ndarray, target_V: np.ndarray, F: np.ndarray,
                   target_faces: int = DEFAULT_FACES, *, force: bool = False) -> ReferenceMesh:
    """The flat mesh itself (at most 1.25 × ``target_faces`` faces, unless ``force``), or a uniform
    remesh of its domain with about ``target_faces`` faces, the target reaching its vertices through
    barycentric coordinates of the flat mesh."""
    if len(F) <= 1.25 * target_faces and not force:
        return ReferenceMesh(uv=flat_uv, F=F, target=target_V, coarsened=False)
    spacing = float(np.sqrt(4.0 * _flat_area(flat_uv, F) / (np.sqrt(3.0) * target_faces)))
    boundary = np.asarray(igl.boundary_loop(F), dtype=np.int64)
    rm = remesh_flat(flat_uv, F, boundary, spacing)
    return ReferenceMesh(uv=rm.uv, F=rm.F, target=rm.vertex_values(target_V), coarsened=True)


def barycentric(points: np.ndarray, uv: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where ``points`` (p, 2) lie on the flat mesh (uv (n, 2), F (m, 3)): per point its face (p,),
    that face's vertices (p, 3) and their barycentric weights (p, 3) (≥ 0, summing to 1), of the
    nearest point of the mesh for points outside it."""
    P3 = np.column_stack([points, np.zeros(len(points))])
    V3 = np.column_stack([uv, np.zeros(len(uv))])
    _, face, closest = igl.point_mesh_squared_distance(P3, V3, np.asarray(F, dtype=np.int64))
    c = F[face]
    bary = igl.barycentric_coordinates(np.ascontiguousarray(closest), np.ascontiguousarray(V3[c[:, 0]]),
                                       np.ascontiguousarray(V3[c[:, 1]]), np.ascontiguousarray(V3[c[:, 2]]))
    bary = np.clip(np.asarray(bary), 0.0, None)
    bary /= bary.sum(axis=1, keepdims=True)
    return np.asarray(face, dtype=np.int64), c, bary


def interpolate(points: np.ndarray, uv: np.ndarray, F: np.ndarray, values: np.ndarray) -> np.ndarray:
    """``values`` (n, k) given at the vertices of the flat mesh (uv (n, 2), F), interpolated
    (piecewise linearly) at ``points`` (p, 2) (the nearest point of the mesh for points outside)."""
    _, c, bary = barycentric(points, uv, F)
    return np.einsum("pc,pck->pk", bary, values[c])


@dataclass(frozen=True)
class Prediction:
    """The predicted deployed surface.

    Attributes
    ----------
    V : (k, 3) predicted vertices registered (Kabsch) onto the target, mm.
    F : (t, 3) its faces (the reference mesh's, same winding as flat.obj).
    uv : (k, 2) the same vertices on the flat surface; target : (k, 3) on the target.
    distance : (k,) distance of each predicted vertex to the target surface, mm.
    deviation_pct : {"mean", "p99", "max"} in % of the target's bounding-box diagonal.
    agreement : the intrinsic measures and the spread (``agreement.Agreement``).
    releases : per release tried, its name and deviation_pct (the nominal one first).
    model : "homogenized".
    iterations : Newton iterations of all releases; converged : every release reached equilibrium.
    steps : release steps of each path; time_s : wall time of the whole prediction, s; faces : len(F).
    coverage : what the layout puts on each face of the reference mesh.
    sheet : the printed sheet the nominal release was finished on (its uv and F are ``uv`` and ``F``).
    X_released : (k, 3) the nominal release's equilibrium in the flat sheet's frame, before the
        registration (what ``assembly.assemble`` places and sews).
    """

    V: np.ndarray
    F: np.ndarray
    uv: np.ndarray
    target: np.ndarray
    distance: np.ndarray
    deviation_pct: dict[str, float]
    agreement: agreement.Agreement
    releases: list[dict]
    model: str
    iterations: int
    converged: bool
    steps: int
    time_s: float
    faces: int
    coverage: Coverage | None = field(repr=False, default=None)
    sheet: Sheet | None = field(repr=False, default=None)
    X_released: np.ndarray | None = field(repr=False, default=None)

    @property
    def reached(self) -> bool:
        """The layout takes the target's shape (``agreement.reached``)."""
        return agreement.reached(self.agreement)

    @property
    def verdict(self) -> str:
        return agreement.verdict(self.agreement)

    def render_png(self, target_V: np.ndarray, target_F: np.ndarray, title: str = "") -> bytes:
        """``deployed.png``: the target (target_V (n, 3), target_F (m, 3)) beside this prediction."""
        from .picture import render_deployed_png
        return render_deployed_png(target_V, target_F, self.V, self.F, self.distance, title=title)

    def report(self) -> dict:
        """``report.deployed`` of design.json (format 3)."""
        a = self.agreement
        return {"deviation_pct": dict(self.deviation_pct), "faces": self.faces, "iterations": self.iterations,
                "time_s": self.time_s, "start": "flat",
                "total_gaussian_curvature": {"predicted": a.curvature_predicted, "target": a.curvature_target},
                "area_ratio": a.area_ratio,
                "spread": {"mean": list(a.spread_mean), "max": list(a.spread_max), "releases": len(self.releases)},
                "reached": self.reached, "verdict": self.verdict, "model": self.model}


def sheet_for_layout(uv: np.ndarray, F: np.ndarray, ribbons: Sequence[Ribbon], *, prestretch: float,
                     ribbon_width: float, table: CurvatureTable, material: Material | None = None
                     ) -> tuple[Sheet, Coverage]:
    """The printed sheet of the layout on the mesh (uv (k, 2), F (t, 3)), homogenized, and its coverage."""
    material = material or Material()
    cov = face_coverage(uv, F, ribbons, ribbon_width, table)
    rest = rest_forms(cov, prestretch)
    Ds, Db = material.stiffness(cov.area_fraction, cov.thickness)
    return Sheet(uv=uv, F=F, abar=rest.abar, bbar=rest.bbar, stretch=Ds, bend=Db, nu=material.poisson), cov


def _check(flat_uv: np.ndarray, target_V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    uv = np.asarray(flat_uv, dtype=float)
    V = np.asarray(target_V, dtype=float)
    F = np.asarray(F, dtype=np.int64)
    if uv.ndim != 2 or uv.shape[1] != 2:
        raise ValueError(f"flat_uv must have shape (n, 2), got {uv.shape}")
    if V.shape != (len(uv), 3):
        raise ValueError(f"target_V must have shape ({len(uv)}, 3) (the flat surface's vertices), got {V.shape}")
    if F.ndim != 2 or F.shape[1] != 3 or len(F) < 2:
        raise ValueError(f"F must have shape (m, 3) with m ≥ 2, got {F.shape}")
    if F.min() < 0 or F.max() >= len(uv):
        raise ValueError(f"F refers to vertex {int(F.max()) if F.max() >= len(uv) else int(F.min())}, "
                         f"outside 0..{len(uv) - 1}")
    for name, a in (("flat_uv", uv), ("target_V", V)):
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{name} has non-finite values (first at row {int(np.argwhere(~np.isfinite(a))[0, 0])})")
    e1, e2 = uv[F[:, 1]] - uv[F[:, 0]], uv[F[:, 2]] - uv[F[:, 0]]
    signed = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    if np.any(signed <= 0):
        raise ValueError(f"flat face {int(np.flatnonzero(signed <= 0)[0])} is not counter-clockwise "
                         "(flat.obj faces must have positive area)")
    return uv, V, F


def _finish(sheet: Sheet, X0: np.ndarray, max_iterations: int):
    """The equilibrium at full release on ``sheet``, from X0 (a coarse release, interpolated)."""
    return newton(sheet.energy_at(1.0), X0, max_iterations=max_iterations, step_tolerance=STEP_TOLERANCE,
                  scale=sheet.diagonal, gradient_tolerance=FORCE_TOLERANCE * sheet.force_scale)


def _release_on(sheet: Sheet, coarse: Sheet | None, path: Path, steps: int, max_iterations: int,
                report: Callable[[int, int], None]) -> tuple[np.ndarray, int, bool]:
    """Release along ``path`` (on ``coarse`` when given, then finished on ``sheet``): X, iterations, converged."""
    if coarse is None:
        r = release(sheet, steps=steps, path=path, max_iterations=max_iterations,
                    progress=lambda k, n, it: report(k, n + 1))
        return r.X, r.iterations, r.converged
    r = release(coarse, steps=steps, path=path, max_iterations=max_iterations,
                progress=lambda k, n, it: report(k, n + 1))
    fin = _finish(sheet, interpolate(sheet.uv, coarse.uv, coarse.F, r.X), FINISH_FACTOR * max_iterations)
    report(1, 1)
    return fin.X, r.iterations + fin.iterations, r.converged and fin.converged


def _sheets(uv: np.ndarray, V: np.ndarray, F: np.ndarray, ribbons: Sequence[Ribbon], model: str,
            target_faces: int, coarse_faces: int, kw: dict):
    """The reference mesh, the sheet on it, the coarse sheet each path is followed on (or None) and
    the coverage."""
    ref = reference_mesh(uv, V, F, target_faces)
    sheet, cov = sheet_for_layout(ref.uv, ref.F, ribbons, **kw)
    coarse = None
    if coarse_faces and coarse_faces < 0.5 * len(ref.F):
        cm = reference_mesh(uv, V, F, coarse_faces, force=True)
        coarse, _ = sheet_for_layout(cm.uv, cm.F, ribbons, **kw)
    return ref, sheet, coarse, cov


def _agreement(devs: list, ref: ReferenceMesh) -> agreement.Agreement:
    """The nominal release (``devs[0]``) against the target, and the spread over all of them. ∫K
    and the area of both on the same mesh: the interior vertices' angle defects leave out a boundary
    strip whose width is the mesh's, so two meshes of one surface differ by it."""
    nominal = devs[0]
    means = [d.mean_pct for d in devs]
    maxes = [d.max_pct for d in devs]
    target_area = agreement.surface_area(ref.target, ref.F)
    return agreement.Agreement(
        mean_pct=nominal.mean_pct, max_pct=nominal.max_pct,
        curvature_predicted=agreement.total_gaussian_curvature(nominal.V, ref.F),
        curvature_target=agreement.total_gaussian_curvature(ref.target, ref.F),
        area_ratio=agreement.surface_area(nominal.V, ref.F) / target_area if target_area > 0 else float("nan"),
        spread_mean=(min(means), max(means)), spread_max=(min(maxes), max(maxes)))


def predict_deployed(flat_uv: np.ndarray, target_V: np.ndarray, F: np.ndarray, ribbons: Sequence[Ribbon], *,
                     prestretch: float, ribbon_width: float, table: CurvatureTable,
                     target_faces: int = DEFAULT_FACES, coarse_faces: int = COARSE_FACES,
                     material: Material | None = None, model: str = "homogenized",
                     steps: int = DEFAULT_STEPS, releases: Sequence[Path] = RELEASES,
                     max_iterations: int = 15,
                     progress: Callable[[float, str], None] | None = None) -> Prediction:
    """Predict the deployed shape of the printed layout and how well it agrees with the target.

    Parameters
    ----------
    flat_uv : (n, 2) the flat surface (flat.obj's x, y), front-side print coordinates, mm.
    target_V : (n, 3) the target (target.obj), same vertices; F : (m, 3) their faces (flat CCW).
        The target registers and measures the prediction; the simulation never reads it.
    ribbons : the ribbons as placed (design.json's ``ribbons``).
    prestretch : s; ribbon_width : w_r, mm; table : the curvature table of the design.
    target_faces : the reference mesh's size when the flat mesh is larger (``reference_mesh``).
    coarse_faces : each release follows its path on a uniform remesh of about this many faces and is
        finished on the reference mesh (0: the whole path on the reference mesh).
    material : the material constants (``Material()``).
    model : "homogenized" (the shell of ``rest_forms``), the only one.
    steps : release steps per path; releases : the paths (the first is the nominal prediction).
    max_iterations : Newton's cap per step (the finish on the reference mesh: ``FINISH_FACTOR`` × it).
    progress : called with (fraction done in [0, 1], what is being done).

    Returns
    -------
    Prediction (its ``report()`` is design.json's ``report.deployed``).

    Raises
    ------
    ValueError
        for arrays of the wrong shape, non-finite values, flat faces that are not counter-clockwise,
        bad parameters.
    """
    t0 = time.perf_counter()
    uv, V, F = _check(flat_uv, target_V, F)
    if not prestretch > 1:
        raise ValueError(f"prestretch must be > 1, got {prestretch!r}")
    if not ribbon_width > 0:
        raise ValueError(f"ribbon_width must be > 0, got {ribbon_width!r}")
    if target_faces < 50:
        raise ValueError(f"target_faces must be at least 50, got {target_faces}")
    if model not in MODELS:
        raise ValueError(f"model must be one of {', '.join(MODELS)}, not {model!r}")
    if not releases:
        raise ValueError("releases must name at least one path (the nominal one first)")
    kw = dict(prestretch=prestretch, ribbon_width=ribbon_width, table=table, material=material)
    ref, sheet, coarse, cov = _sheets(uv, V, F, ribbons, model, target_faces, coarse_faces, kw)
    results, iterations, converged = [], 0, True
    for i, path in enumerate(releases):
        def report(k: int, n: int, i: int = i, path: Path = path) -> None:
            if progress is not None:
                progress((i + k / n) / len(releases), f"release {i + 1} of {len(releases)} ({path.name}): "
                                                      f"step {k} of {n}")
        X, it, ok = _release_on(sheet, coarse, path, steps, max_iterations, report)
        iterations += it
        converged &= ok
        results.append((path, X))
    devs = [surface_deviation(X, ref.target, V, F) for _, X in results]
    nominal = devs[0]
    a = _agreement(devs, ref)
    return Prediction(V=nominal.V, F=ref.F, uv=ref.uv, target=ref.target, distance=nominal.distance,
                      deviation_pct=nominal.as_dict(), agreement=a,
                      releases=[{"name": p.name, "deviation_pct": d.as_dict()} for (p, _), d in zip(results, devs)],
                      model=model, iterations=iterations, converged=bool(converged), steps=steps,
                      time_s=time.perf_counter() - t0, faces=len(ref.F), coverage=cov, sheet=sheet,
                      X_released=results[0][1])
