"""The prediction against physics and geometry (issues 12 and 23).

- no ribbons: a flat sheet contracted by 1/s (area × 1/s²) within 0.5 %;
- parallel ribbons of one thickness on a rectangle: a cylinder whose curvature is the table's κ
  within 3 % and whose lengths follow Eq. 10 within 1 %;
- the design of a cylinder target (through the whole engine): mean deviation ≤ 0.5 %;
- a torus patch (front ribbons) and a saddle (back ribbons): the surface bends along the ribbons
  toward the side they are printed on;
- a hemisphere (infeasible): an intrinsically flatter prediction, ``reached`` false and a verdict
  that says so;
- the simulation never reads the target: another target.obj gives the same shape up to a rigid motion;
- the release converges in its steps: 10, 20 and 40 steps give the same shape within 0.3 % of the diagonal.
"""

from __future__ import annotations

import numpy as np
import pytest

from ribbond.deploy import predict_deployed
from ribbond.deploy.compare import kabsch
from ribbond.deploy.predict import RELEASES, interpolate
from ribbond.design import surfaces
from ribbond.mesh.files import write_obj
from ribbond.design.params import DesignParameters, SizeSpec, SolverSettings
from ribbond.pipeline.compile import design_mesh
from ribbond.design.thickness import load_curvature_table, table_curvature
from ribbond.design.verdict import verdict_lines

from .patterns import staggered_pattern

TABLE = load_curvature_table("tpu95a-lycra-default")
S = 1.6
W = 1.5


def _rect(nx: int, ny: int, size: tuple[float, float]):
    UV, F = surfaces.grid(nx, ny)
    uv = UV * np.array(size)
    return uv, F, np.column_stack([uv, np.zeros(len(uv))])


def coupon_circle(X: np.ndarray, uv: np.ndarray, F: np.ndarray, size: tuple[float, float]) -> tuple[float, float]:
    """(radius, the largest distance of a fitted vertex from the circle), mm, of a released coupon
    rolled along x: the vertices of its middle (the central half each way), projected along the
    cylinder's axis (the mean image of the flat y direction there), fitted by a circle (least
    squares, Kåsa)."""
    Xs, Ys = size
    c = uv[F].mean(axis=1)
    inner = (np.abs(c[:, 0] - Xs / 2) < Xs / 4) & (np.abs(c[:, 1] - Ys / 2) < Ys / 4)
    e = np.stack([X[F[:, 1]] - X[F[:, 0]], X[F[:, 2]] - X[F[:, 0]]], axis=2)
    u = np.stack([uv[F[:, 1]] - uv[F[:, 0]], uv[F[:, 2]] - uv[F[:, 0]]], axis=2)
    axis = (e @ np.linalg.inv(u) @ np.array([0.0, 1.0]))[inner].mean(axis=0)
    axis /= np.linalg.norm(axis)
    mid = (np.abs(uv[:, 0] - Xs / 2) < Xs / 4) & (np.abs(uv[:, 1] - Ys / 2) < Ys / 4)
    P = X[mid] - X[mid].mean(axis=0)
    P -= np.outer(P @ axis, axis)
    b1 = np.cross(axis, P[np.argmax(np.linalg.norm(P, axis=1))])
    b1 /= np.linalg.norm(b1)
    b2 = np.cross(axis, b1)
    x, y = P @ b1, P @ b2
    cx, cy, k0 = np.linalg.lstsq(np.column_stack([x, y, np.ones_like(x)]), x ** 2 + y ** 2, rcond=None)[0]
    radius = float(np.sqrt(k0 + cx ** 2 / 4 + cy ** 2 / 4))
    return radius, float(np.abs(np.hypot(x - cx / 2, y - cy / 2) - radius).max())


def _jacobian_stretch(X, uv, F, direction):
    """|J d| per face: the length a flat unit vector d (2,) takes on the deployed surface."""
    e = np.stack([X[F[:, 1]] - X[F[:, 0]], X[F[:, 2]] - X[F[:, 0]]], axis=2)            # (m, 3, 2)
    u = np.stack([uv[F[:, 1]] - uv[F[:, 0]], uv[F[:, 2]] - uv[F[:, 0]]], axis=2)        # (m, 2, 2)
    J = e @ np.linalg.inv(u)
    return np.linalg.norm(J @ np.asarray(direction, dtype=float), axis=1)


def test_no_ribbons_contract_the_sheet_by_one_over_s():
    uv, F, V = _rect(16, 12, (80.0, 60.0))
    p = predict_deployed(uv, V, F, [], prestretch=S, ribbon_width=W, table=TABLE)
    e1, e2 = p.V[p.F[:, 1]] - p.V[p.F[:, 0]], p.V[p.F[:, 2]] - p.V[p.F[:, 0]]
    area = 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1).sum()
    assert area == pytest.approx(80.0 * 60.0 / S ** 2, rel=0.005)
    # flat: every vertex on the plane of the registered sheet
    X = p.V - p.V.mean(axis=0)
    assert np.linalg.svd(X, compute_uv=False)[-1] / np.sqrt(len(X)) < 1e-3
    for k in ("mean", "p99", "max"):
        assert p.deviation_pct[k] >= 0
    assert p.faces == len(F) and p.iterations > 0 and p.converged
    assert set(p.report()) == {"deviation_pct", "faces", "iterations", "time_s", "start", "total_gaussian_curvature",
                               "area_ratio", "spread", "reached", "verdict", "model"}
    assert p.report()["start"] == "flat" and p.report()["model"] == "homogenized"
    assert p.report()["spread"]["releases"] == len(RELEASES)
    # the area ratio is against the target given (here the sheet as printed): 1/s²
    assert p.agreement.area_ratio == pytest.approx(1.0 / S ** 2, rel=0.005)


def test_parallel_ribbons_roll_into_the_tables_cylinder_with_eq10_lengths():
    mu1, mu2, lr, tau = 22.9, 6.0, 15.0, 0.6
    size = (120.0, 80.0)
    uv, F, V = _rect(40, 26, size)
    rib = staggered_pattern(size, mu1, mu2, lr, tau)
    p = predict_deployed(uv, V, F, rib, prestretch=S, ribbon_width=W, table=TABLE)
    c = p.uv[p.F].mean(axis=1)
    inner = (c[:, 0] > 30) & (c[:, 0] < 90) & (c[:, 1] > 20) & (c[:, 1] < 60)
    along = _jacobian_stretch(p.V, p.uv, p.F, [1.0, 0.0])[inner]
    across = _jacobian_stretch(p.V, p.uv, p.F, [0.0, 1.0])[inner]
    # Eq. 10: a motif μ1 contracts to l_r + (μ1 − l_r)/s, a motif μ2 to w_r + (μ2 − w_r)/s
    assert np.median(along) == pytest.approx((lr + (mu1 - lr) / S) / mu1, rel=0.01)
    assert np.median(across) == pytest.approx((W + (mu2 - W) / S) / mu2, rel=0.01)
    # the cylinder: its axis is the image of the across direction; the middle vertices, projected
    # along it, lie on a circle (least-squares fit, Kåsa) of curvature κ(τ, μ2) of the front table
    kappa = table_curvature(TABLE, "front", np.array([tau]), np.array([mu2]))[0]
    radius, off_circle = coupon_circle(p.V, p.uv, p.F, size)
    assert 1.0 / radius == pytest.approx(kappa, rel=0.03)
    assert off_circle < 0.01 * radius                                                  # a circle
    # and across the ribbons it stays straight
    t = np.linspace(20.0, 60.0, 9)
    P = interpolate(np.column_stack([np.full_like(t, 60.0), t]), p.uv, p.F, p.V)
    straight = np.linalg.norm(P[-1] - P[0]) / np.linalg.norm(np.diff(P, axis=0), axis=1).sum()
    assert straight > 0.999


def _design(tmp_path, name, V, F, size, solver=None):
    path = tmp_path / f"{name}.obj"
    write_obj(path, V, F)
    res = design_mesh(path, DesignParameters(size=SizeSpec(bbox_diagonal=size)), solver)    # its deploy stage
    p = res.prediction
    assert p is not None and res.deployed_png is not None
    assert res.design.report.deployed.model_dump(exclude_none=True) == p.report()
    return res, p


def test_designed_cylinder_deploys_onto_its_target(tmp_path):
    # the 1,600-face mesh as given: refined at intake (25,600 faces) its layout of 52 ribbons leaves
    # a dimple at one corner in the prediction (∫K 0.8, 1.9 %), an open finding of issue 23
    V, F = surfaces.cylinder_patch()
    res, p = _design(tmp_path, "cylinder", V, F, 100.0, SolverSettings(refine_below_faces=0))
    assert p.deviation_pct["mean"] <= 0.5
    assert p.deviation_pct["p99"] <= p.deviation_pct["max"]
    assert p.converged
    assert p.reached and "will take the target's shape" in p.verdict
    assert abs(p.agreement.curvature_predicted) < 0.1 and abs(p.agreement.curvature_target) < 0.1
    # the forward design unless asked (the optimization is off by default: docs/designing.md)
    assert res.design.report.optimization is None
    assert all(TABLE.thickness[0] <= r.thickness <= TABLE.thickness[-1] for r in res.design.ribbons)


def _bending_sign(p, ribbon_side):
    """Sign of the second difference along the ribbons against the predicted normal, at sample lines
    through the middle of the layout: −1 bulging toward +n (front), +1 toward −n (back)."""
    cov = p.coverage
    c = p.uv[p.F].mean(axis=1)
    centre = np.median(c, axis=0)
    near = np.argsort(np.linalg.norm(c - centre, axis=1))[:40]
    signs = []
    for f in near:
        d = cov.direction[f]
        t = np.array([-6.0, 0.0, 6.0])
        pts = c[f] + t[:, None] * d
        P = interpolate(pts, p.uv, p.F, p.V)
        N = interpolate(pts[1:2], p.uv, p.F, _vertex_normals(p.V, p.F))[0]
        signs.append(np.sign((P[0] + P[2] - 2 * P[1]) @ N))
    return np.mean(signs)


def _vertex_normals(V, F):
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    out = np.zeros_like(V)
    for k in range(3):
        np.add.at(out, F[:, k], n)
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def test_torus_front_ribbons_bend_toward_the_front(tmp_path):
    V, F = surfaces.torus_patch(nu=40, nv=20)
    res, p = _design(tmp_path, "torus", V, F, 120.0)
    sides = {r.side for r in res.design.ribbons}
    assert sides == {"front"}
    assert _bending_sign(p, "front") < -0.8
    # reported; large here because the layout misses the design's spacing across (its own report:
    # spacing_error_across_pct) and most thicknesses are clamped to the table (see docs/benchmarks.md)
    assert np.isfinite(p.deviation_pct["mean"]) and 0 < p.deviation_pct["mean"] <= p.deviation_pct["max"]


def test_saddle_back_ribbons_bend_toward_the_back(tmp_path):
    V, F = surfaces.saddle(rings=16)
    res, p = _design(tmp_path, "saddle", V, F, 100.0)
    assert {r.side for r in res.design.ribbons} == {"back"}
    assert _bending_sign(p, "back") > 0.8
    assert np.isfinite(p.deviation_pct["mean"]) and 0 < p.deviation_pct["mean"] <= p.deviation_pct["max"]


def test_front_and_back_ribbons_on_one_sheet_make_an_s():
    """Front ribbons on one half, back ribbons on the other: each half bends toward its side."""
    size = (120.0, 60.0)
    uv, F, V = _rect(40, 20, size)
    front = staggered_pattern((60.0, 60.0), 22.9, 6.0, 15.0, 0.6, side="front")
    back = staggered_pattern((60.0, 60.0), 22.9, 6.0, 15.0, 0.6, side="back", origin=(60.0, 0.0))
    p = predict_deployed(uv, V, F, front + back, prestretch=S, ribbon_width=W, table=TABLE)
    N = _vertex_normals(p.V, p.F)
    for x0, sign in ((25.0, -1.0), (95.0, 1.0)):
        t = np.array([x0 - 8.0, x0, x0 + 8.0])
        pts = np.column_stack([t, np.full(3, 30.0)])
        P = interpolate(pts, p.uv, p.F, p.V)
        n = interpolate(pts[1:2], p.uv, p.F, N)[0]
        assert np.sign((P[0] + P[2] - 2 * P[1]) @ n) == sign


def test_hemisphere_predicts_flatter_and_says_so(tmp_path):
    V, F = surfaces.sphere_cap(half_angle_deg=90.0, rings=13)
    res, p = _design(tmp_path, "hemisphere", V, F, 100.0)
    a = p.agreement
    # Gauss-Bonnet: a hemisphere's ∫K is 2π; the interior vertices' angle defects miss the rim's share
    assert 5.0 < a.curvature_target < 2 * np.pi
    assert a.curvature_predicted < 0.6 * a.curvature_target          # intrinsically flatter
    assert not p.reached
    assert p.verdict.startswith("will NOT take the target's shape") and "curvature" in p.verdict
    lines = verdict_lines(res.design.model_dump(mode="json", by_alias=True))
    assert any("will NOT take the target's shape" in line for line in lines)


@pytest.fixture(scope="module")
def small_saddle(tmp_path_factory):
    """One forward design (no deploy stage) for the tests below, which only read it."""
    V, F = surfaces.saddle(rings=12)
    path = tmp_path_factory.mktemp("small-saddle") / "saddle.obj"
    write_obj(path, V, F)
    res = design_mesh(path, DesignParameters(size=SizeSpec(bbox_diagonal=100.0)), predict=False)
    return res


def _registered_gap(X: np.ndarray, Y: np.ndarray) -> float:
    """Mean distance between corresponding vertices after the best rigid motion, mm."""
    R, t = kabsch(X, Y)
    return float(np.linalg.norm(X @ R.T + t - Y, axis=1).mean())


def test_the_simulation_never_reads_the_target(small_saddle):
    res = small_saddle
    kw = dict(prestretch=res.design.parameters.prestretch, ribbon_width=res.design.parameters.ribbon_width,
              table=TABLE, releases=RELEASES[:1])
    p = predict_deployed(res.flat_uv, res.V, res.F, res.design.ribbons, **kw)
    # another surface on the same vertices: a dome instead of the saddle
    other = res.V.copy()
    c = other[:, :2] - other[:, :2].mean(axis=0)
    other[:, 2] = 30.0 - 0.004 * (c ** 2).sum(axis=1)
    q = predict_deployed(res.flat_uv, other, res.F, res.design.ribbons, **kw)
    diag = float(np.linalg.norm(res.V.max(axis=0) - res.V.min(axis=0)))
    assert _registered_gap(p.V, q.V) <= 1e-6 * diag                  # the same shape, moved
    assert p.iterations == q.iterations
    assert p.deviation_pct["mean"] != pytest.approx(q.deviation_pct["mean"], rel=0.05)   # measured against each


def test_ten_twenty_and_forty_release_steps_agree(small_saddle):
    res = small_saddle
    kw = dict(prestretch=res.design.parameters.prestretch, ribbon_width=res.design.parameters.ribbon_width,
              table=TABLE, releases=RELEASES[:1])
    shapes = {n: predict_deployed(res.flat_uv, res.V, res.F, res.design.ribbons, steps=n, **kw) for n in (10, 20, 40)}
    diag = float(np.linalg.norm(res.V.max(axis=0) - res.V.min(axis=0)))
    for a, b in ((10, 40), (20, 40), (10, 20)):
        gap = _registered_gap(shapes[a].V, shapes[b].V)
        assert 100 * gap / diag <= 0.3, (a, b, 100 * gap / diag)
    assert all(p.converged for p in shapes.values())
