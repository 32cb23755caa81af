"""The realization measure (issue 34): what the printed plastic realizes against the flattening's σ.

The truth comes from Eq. 10 (a line keeps c = f + (1 − f)/s of its flat length, f its plastic share)
and from geometry: dashes placed by hand at Eq. 10's spacing realize the metric exactly; dashes half
as long realize the contraction Eq. 10 gives for them; rows that curve in the flat (arcs) are still
measured along and across the rows.
"""

from __future__ import annotations

import numpy as np
import pytest

from ribbond.deploy.agreement import total_gaussian_curvature
from ribbond.deploy.realization import (intended_metric, metric_total_curvature, plastic_share, realization)
from ribbond.design import surfaces
from ribbond.design.format import Ribbon
from ribbond.design.params import spacing_for_sigma
from ribbond.design.thickness import load_curvature_table, ribbon_thickness

TABLE = load_curvature_table("tpu95a-lycra-default")
S, LR, WR = 1.6, 15.0, 1.5
SIG1, SIG2 = 1.15, 1.4
KAPPA = 0.02
MU1, MU2 = spacing_for_sigma(SIG1, LR, S), spacing_for_sigma(SIG2, WR, S)


def grid_mesh(W: float, H: float, nx: int, ny: int) -> tuple[np.ndarray, np.ndarray]:
    x, y = np.meshgrid(np.linspace(0, W, nx), np.linspace(0, H, ny))
    uv = np.column_stack([x.ravel(), y.ravel()])
    i = np.arange(nx * ny).reshape(ny, nx)
    a, b, c, d = i[:-1, :-1].ravel(), i[:-1, 1:].ravel(), i[1:, 1:].ravel(), i[1:, :-1].ravel()
    return uv, np.vstack([np.column_stack([a, b, c]), np.column_stack([a, c, d])])


def thickness_for(kappa: float, mu2: float) -> float:
    return float(ribbon_thickness(TABLE, np.array([kappa]), np.array([mu2])).thickness[0])


def staggered_rows(W: float, H: float, length: float) -> list[Ribbon]:
    """Rows along x at (k + ½) μ2, dashes of ``length`` every μ1, every other row shifted by μ1/2 (§3),
    cut at the edges x = 0 and W: on W × H a whole number of periods each way, the pattern tiles."""
    tau = thickness_for(KAPPA, MU2)
    ribbons = []
    for k in range(int(round(H / MU2))):
        y = (k + 0.5) * MU2
        for j in range(int(round(W / MU1)) + 1):
            xc = (j + 0.5 * (1 - k % 2)) * MU1
            x0, x1 = max(xc - length / 2, 0.0), min(xc + length / 2, W)
            if x1 - x0 >= 2.0:
                ribbons.append(Ribbon(side="front", points=[[x0, y], [x1, y]], thickness=tau, kappa1=KAPPA,
                                      spacing=[MU1, MU2]))
    return ribbons


def measure(uv: np.ndarray, F: np.ndarray, ribbons: list[Ribbon], direction: np.ndarray):
    m = len(F)
    return realization(uv, F, np.tile([SIG1, SIG2], (m, 1)), direction, np.full(m, KAPPA), ribbons,
                       prestretch=S, ribbon_width=WR, ribbon_length=LR, table=TABLE)


W, H = 7 * MU1, 16 * MU2


@pytest.fixture(scope="module")
def rectangle():
    uv, F = grid_mesh(W, H, 161, 101)
    return uv, F, np.tile([1.0, 0.0], (len(F), 1))


def test_dashes_placed_by_eq_10_realize_the_metric(rectangle) -> None:
    uv, F, d = rectangle
    r = measure(uv, F, staggered_rows(W, H, LR), d)
    assert r.interior.sum() > 1000
    for figure in (r.along, r.across):
        assert np.all(np.abs(np.percentile(figure[r.interior], [5, 50, 95])) <= 0.5)
    assert not r.bare.any()
    # Eq. 10's plastic share f1 f2 of the area, printed (the pattern tiles the rectangle)
    assert r.plastic_printed == pytest.approx(r.plastic_eq10, rel=0.005)
    assert r.plastic_eq10 == pytest.approx(100 * plastic_share(SIG1, S) * plastic_share(SIG2, S), rel=1e-9)
    # τ inverted from the table at the realized μ2: the rest curvature is |κ1|
    assert np.nanmedian(np.abs(r.curvature)) < 0.5


def test_dashes_half_as_long_contract_as_eq_10_says(rectangle) -> None:
    uv, F, d = rectangle
    r = measure(uv, F, staggered_rows(W, H, 0.5 * LR), d)
    f = 0.5 * LR / MU1
    expected = 100.0 * ((f + (1 - f) / S) * SIG1 - 1.0)
    assert expected < -10
    np.testing.assert_allclose(np.percentile(r.along[r.interior], [5, 50, 95]), expected, atol=0.5)
    assert np.all(np.abs(np.percentile(r.across[r.interior], [5, 50, 95])) <= 0.5)


def arc_rows(R0: float, R1: float) -> list[Ribbon]:
    """Concentric rows every μ2 (a half annulus), dashes every μ1 of arc length, staggered."""
    tau = thickness_for(KAPPA, MU2)
    ribbons = []
    for k in range(int((R1 - R0) / MU2) + 1):
        rk = R0 + 1.0 + k * MU2
        if rk > R1 - 1.0:
            break
        arc = np.pi * rk
        for j in range(-1, int(arc / MU1) + 2):
            sc = j * MU1 + (k % 2) * MU1 / 2
            s0, s1 = max(sc - LR / 2, 1.0), min(sc + LR / 2, arc - 1.0)
            if s1 - s0 >= 2.0:
                t = np.linspace(s0 / rk, s1 / rk, 40)
                ribbons.append(Ribbon(side="front", points=np.column_stack([rk * np.cos(t), rk * np.sin(t)]).tolist(),
                                      thickness=tau, kappa1=KAPPA, spacing=[MU1, MU2]))
    return ribbons


def test_rows_that_curve_in_the_flat_are_measured_along_them() -> None:
    # rows of radius 30-90 mm: straight measuring lines read them 8.7 % too dense across (they cut each
    # curved row at two heights) before the lines followed the rows
    R0, R1 = 30.0, 90.0
    r, t = np.meshgrid(np.linspace(R0, R1, 80), np.linspace(0, np.pi, 200))
    uv = np.column_stack([(r * np.cos(t)).ravel(), (r * np.sin(t)).ravel()])
    _, F = grid_mesh(1.0, 1.0, 80, 200)
    e1, e2 = uv[F[:, 1]] - uv[F[:, 0]], uv[F[:, 2]] - uv[F[:, 0]]
    if np.mean(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]) < 0:
        F = F[:, ::-1]
    c = uv[F].mean(axis=1)
    d = np.column_stack([-c[:, 1], c[:, 0]]) / np.linalg.norm(c, axis=1)[:, None]    # along the arcs
    res = measure(uv, F, arc_rows(R0, R1), d)
    rc, tc = np.linalg.norm(c[res.faces], axis=1), np.arctan2(c[res.faces, 1], c[res.faces, 0])
    inner = (rc > R0 + 2 * MU2) & (rc < R1 - 2 * MU2) & (tc * rc > MU1) & ((np.pi - tc) * rc > MU1)
    assert abs(np.median(res.along[inner])) < 0.5
    assert abs(np.median(res.across[inner])) < 1.5 and np.percentile(np.abs(res.across[inner]), 95) < 2.5


def test_intended_metric_of_a_flattening_carries_the_targets_curvature() -> None:
    # the metric of a sphere cap pulled back to any flat map of it has the cap's ∫K = 2π (1 − cos α)
    V, F = surfaces.sphere_cap(radius=50.0, half_angle_deg=40.0, rings=30)
    uv = V[:, :2].copy()                                       # a flat map: the projection onto z = 0
    P3, P2 = V[F], uv[F]
    E3 = np.stack([P3[:, 1] - P3[:, 0], P3[:, 2] - P3[:, 0]], axis=2)        # (m, 3, 2)
    E2 = np.stack([P2[:, 1] - P2[:, 0], P2[:, 2] - P2[:, 0]], axis=2)        # (m, 2, 2)
    inv = np.linalg.inv(E2)
    abar = np.einsum("mji,mjk,mkl->mil", inv, np.einsum("mki,mkj->mij", E3, E3), inv)
    K = metric_total_curvature(uv, F, abar)
    assert K == pytest.approx(total_gaussian_curvature(V, F), abs=1e-9)
    # the defects at the interior vertices leave out the boundary vertices' half ring (1/30 of the radius)
    assert K == pytest.approx(2 * np.pi * (1 - np.cos(np.radians(40.0))), rel=0.05)
    # and a plane's metric (σ constant) has none
    m = len(F)
    assert abs(metric_total_curvature(uv, F, intended_metric(np.tile([1.1, 1.4], (m, 1)),
                                                             np.tile([1.0, 0.0], (m, 1))))) < 1e-9


def test_wrong_shapes_are_refused(rectangle) -> None:
    uv, F, d = rectangle
    with pytest.raises(ValueError, match="sigma"):
        realization(uv, F, np.ones((3, 2)), d, np.zeros(len(F)), [], prestretch=S, ribbon_width=WR,
                    ribbon_length=LR, table=TABLE)


def test_the_realized_metric_is_eq_10s_where_the_dashes_are(rectangle) -> None:
    # dashes placed by Eq. 10 on a constant σ: the rest metric built from the measured coverage (the
    # one the prediction uses) is d dᵀ/σ1² + n nᵀ/σ2² in the interior, and a constant metric on a flat
    # rectangle has no Gaussian curvature: ∫K realized = intended = 0 (up to the outline's rim, where
    # the measuring windows leave the pattern)
    from ribbond.deploy.rest_forms import rest_forms
    uv, F, d = rectangle
    r = measure(uv, F, staggered_rows(W, H, LR), d)
    abar = rest_forms(r.coverage, S).abar[r.interior]
    want = intended_metric(np.tile([SIG1, SIG2], (len(abar), 1)), d[r.faces][r.interior])
    assert np.abs(abar - want).max() <= 0.01 * np.abs(want).max()
    assert abs(r.k_intended) < 1e-9
    assert abs(r.k_realized) < 0.01
    assert r.report()["total_gaussian_curvature"]["realized"] == pytest.approx(r.k_realized, abs=1e-4)


def test_rows_short_of_plastic_inside_a_radius_realize_the_curvature_geometry_gives() -> None:
    # the half annulus of concentric rows, dashes half as long inside r = 60 mm. The realized metric is
    # a² dr² + g(r)² dθ² with a = 1/σ2 (across unchanged) and g' = c the circles' contraction (Eq. 10:
    # 1/σ1 outside, c_half = f/2 + (1 − f/2)/s inside); a rotationally symmetric metric has
    # ∫K dA = −∫∫ (g'/a)' dr dθ = −(π/a) (g'(R1) − g'(R0)) over θ ∈ [0, π]: −π σ2 (1/σ1 − c_half).
    # With whole dashes g' = 1/σ1 everywhere and ∫K = 0; the measuring windows at the two rims cost
    # 0.16 there, the tolerance.
    R0, R1 = 30.0, 90.0
    r, t = np.meshgrid(np.linspace(R0, R1, 80), np.linspace(0, np.pi, 200))
    uv = np.column_stack([(r * np.cos(t)).ravel(), (r * np.sin(t)).ravel()])
    _, F = grid_mesh(1.0, 1.0, 80, 200)
    C = uv[F].mean(axis=1)
    d = np.column_stack([-C[:, 1], C[:, 0]]) / np.linalg.norm(C, axis=1, keepdims=True)
    full = arc_rows(R0, R1)
    short = [Ribbon(side=rb.side, points=(np.asarray(rb.points)[10:30] if np.linalg.norm(rb.points[0]) < 60 else
                                          np.asarray(rb.points)).tolist(), thickness=rb.thickness,
                    kappa1=rb.kappa1, spacing=rb.spacing) for rb in full]
    m = len(F)
    kw = dict(prestretch=S, ribbon_width=WR, ribbon_length=LR, table=TABLE)
    whole = realization(uv, F, np.tile([SIG1, SIG2], (m, 1)), d, np.full(m, KAPPA), full, **kw)
    half = realization(uv, F, np.tile([SIG1, SIG2], (m, 1)), d, np.full(m, KAPPA), short, **kw)
    f_half = 0.5 * LR / MU1
    expected = -np.pi * SIG2 * (1 / SIG1 - (f_half + (1 - f_half) / S))
    assert expected < -0.5
    assert abs(whole.k_realized) < 0.2
    assert half.k_realized == pytest.approx(expected, abs=0.2)
