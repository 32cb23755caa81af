"""The assembled prediction of a target cut into panels (ribbond.panels.sewing, issue 26).

- the seams' springs: gradient and Hessian against central finite differences;
- two bare halves of a rectangle, each in its own print frame and meshed differently, released and
  sewn: one rectangle contracted by 1/s (physics: bare fabric contracts by 1/s), the seam closed;
- placement and sewing never read the target: another whole target gives the same positions;
- two halves of a cylinder of parallel ribbons: one cylinder, as good as each half alone;
- two halves of a sphere cap, each designed by the engine: sewn within a hundredth of a mm, smooth
  across the seam, and no farther from the cap than the halves are on their own.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from ribbond.panels.sewing import ReleasedPanel, SeamPairing, assemble, place_panels, seam_energy
from ribbond.deploy.compare import surface_deviation
from ribbond.deploy.predict import RELEASES, predict_deployed, sheet_for_layout
from ribbond.deploy.release import release
from ribbond.design import surfaces
from ribbond.mesh.files import write_obj
from ribbond.design.params import DesignParameters, SizeSpec, SolverSettings
from ribbond.pipeline.compile import design_mesh
from ribbond.design.thickness import load_curvature_table, table_curvature

from .patterns import staggered_pattern

TABLE = load_curvature_table("tpu95a-lycra-default")
S, W = 1.6, 1.5


def _rect(nx: int, ny: int, size, origin=(0.0, 0.0)):
    UV, F = surfaces.grid(nx, ny)
    return UV * np.array(size) + np.array(origin), F


def _frame(angle: float, at, to):
    """A print frame of its own: rotated by ``angle`` about ``at``, moved to ``to``."""
    R = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    return lambda p: (np.asarray(p, dtype=float) - at) @ R.T + to


def test_seam_springs_match_finite_differences():
    rng = np.random.default_rng(3)
    C = sp.random(5, 7, density=0.5, random_state=4, format="csr") - sp.random(5, 7, density=0.3, random_state=5)
    k = rng.uniform(0.5, 2.0, 5)
    X = rng.standard_normal((7, 3))
    E, g, H = seam_energy(X, C.tocsr(), k, derivatives=2)
    assert E == pytest.approx(0.5 * np.sum(k * np.sum((C @ X) ** 2, axis=1)))
    h = 1e-6
    num_g, num_H = np.zeros(21), np.zeros((21, 21))
    for i in range(21):
        d = np.zeros(21)
        d[i] = h
        num_g[i] = (seam_energy(X + d.reshape(7, 3), C, k) - seam_energy(X - d.reshape(7, 3), C, k)) / (2 * h)
        num_H[:, i] = (seam_energy(X + d.reshape(7, 3), C, k, 1)[1] - seam_energy(X - d.reshape(7, 3), C, k, 1)[1]) / (2 * h)
    np.testing.assert_allclose(g, num_g, rtol=1e-6, atol=1e-8)
    np.testing.assert_allclose(H.toarray(), num_H, rtol=1e-6, atol=1e-8)


def test_two_bare_halves_sew_into_one_rectangle_contracted_by_one_over_s():
    # the rectangle [0, 70] × [0, 60] cut at x = 30; B printed in its own frame, meshed more finely
    uvA, FA = _rect(10, 12, (30.0, 60.0))
    wholeB, FB = _rect(14, 15, (40.0, 60.0), (30.0, 0.0))
    toB = _frame(np.pi / 2, (30.0, 0.0), (100.0, 5.0))
    panels = []
    for uv, F, whole in ((uvA, FA, uvA), (toB(wholeB), FB, wholeB)):
        sheet, _ = sheet_for_layout(uv, F, [], prestretch=S, ribbon_width=W, table=TABLE)
        r = release(sheet, steps=3)
        assert r.converged
        panels.append(ReleasedPanel(sheet=sheet, X=r.X, target=np.column_stack([whole / S, np.zeros(len(whole))])))
    y = np.linspace(0.0, 60.0, 17)                      # matched marks, not the meshes' vertices
    seam = np.column_stack([np.full_like(y, 30.0), y])
    Vt, Ft = _rect(7, 6, (70.0, 60.0))
    a = assemble(panels, [SeamPairing(0, seam, 1, toB(seam))], np.column_stack([Vt / S, np.zeros(len(Vt))]), Ft)
    # the contracted rectangle, every vertex where it belongs (the target here is the exact answer)
    assert a.deviation_pct["max"] < 1e-6 and a.seam_gap_mm["max"] < 1e-6 and a.converged
    assert a.F.shape == (len(FA) + len(FB), 3) and np.bincount(a.panel).tolist() == [len(uvA), len(wholeB)]
    assert np.allclose(a.uv[a.panel == 1], toB(wholeB))


def _cylinder_halves():
    """Parallel front ribbons on the rectangle [0, 120] × [0, 80] cut at y = 30 (the seam runs along
    the ribbons: a circle of the cylinder); the upper half printed in a frame of its own."""
    mu1, mu2, lr, tau = 22.9, 6.0, 15.0, 0.6
    L, H, cut = 120.0, 80.0, 30.0
    kappa = table_curvature(TABLE, "front", np.array([tau]), np.array([mu2]))[0]
    along, across = (lr + (mu1 - lr) / S) / mu1, (W + (mu2 - W) / S) / mu2       # Eq. 10

    def on_cylinder(uv):                                 # the exact deployed sheet
        t = along * (uv[:, 0] - L / 2) * kappa
        return np.column_stack([np.sin(t) / kappa, across * uv[:, 1], (np.cos(t) - 1) / kappa])

    toB = _frame(2.0, (0.0, cut), (200.0, 50.0))
    panels, alone = [], []
    Vt, Ft = _rect(60, 40, (L, H))
    for size, origin, frame in (((L, cut), (0.0, 0.0), lambda p: p), ((L, H - cut), (0.0, cut), toB)):
        whole, F = _rect(30, round(36 * size[1] / L), size, origin)
        rib = [r.model_copy(update={"points": [tuple(map(float, frame(np.array([q]))[0])) for q in r.points]})
               for r in staggered_pattern(size, mu1, mu2, lr, tau, origin=origin)]
        sheet, _ = sheet_for_layout(frame(whole), F, rib, prestretch=S, ribbon_width=W, table=TABLE)
        r = release(sheet)
        panels.append(ReleasedPanel(sheet=sheet, X=r.X, target=on_cylinder(whole)))
        alone.append(surface_deviation(r.X, on_cylinder(whole), on_cylinder(Vt), Ft))
    x = np.linspace(0.0, L, 41)
    seam = np.column_stack([x, np.full_like(x, cut)])
    return panels, [SeamPairing(0, seam, 1, toB(seam))], (on_cylinder(Vt), Ft), alone


@pytest.fixture(scope="module")
def cylinder():
    panels, seams, target, alone = _cylinder_halves()
    return panels, seams, target, alone, assemble(panels, seams, *target)


def test_two_cylinder_halves_sew_into_the_cylinder(cylinder):
    panels, seams, target, alone, a = cylinder
    assert a.converged and a.seam_gap_mm["max"] < 0.01
    # each half alone is the cylinder; sewn, the whole is too, as close as the halves are (mm)
    worst_alone = max(d.distance.mean() for d in alone)
    assert a.distance.mean() <= 1.1 * worst_alone
    assert a.deviation_pct["mean"] < 0.5


def test_placement_and_sewing_never_read_the_target(cylinder):
    panels, seams, (V, F), _, a = cylinder
    other = V.copy()
    other[:, 2] = 0.01 * (V[:, 0] ** 2 + V[:, 1] ** 2)              # a bowl instead of the cylinder
    shifted = [ReleasedPanel(sheet=p.sheet, X=p.X, target=p.target * 1.3 + 7.0) for p in panels]
    b = assemble(shifted, seams, other, F)
    assert np.array_equal(a.X, b.X) and a.iterations == b.iterations
    placed = place_panels(panels, seams)
    assert all(np.array_equal(p, q) for p, q in zip(placed, place_panels(shifted, seams)))
    assert a.deviation_pct["mean"] != pytest.approx(b.deviation_pct["mean"], rel=0.05)   # measured against each


def _sphere(xy, radius=60.0):
    return np.column_stack([xy, np.sqrt(radius ** 2 - (xy ** 2).sum(axis=1))])


def test_two_designed_halves_of_a_sphere_cap_sew_smoothly(tmp_path):
    A, n = 30.0, 12
    UV, FW = surfaces.grid(2 * n, 2 * n)
    VW = _sphere(2 * A * UV - A)
    panels, alone_mm, seam_pts = [], [], []
    for i, x0 in enumerate((-A, 0.0)):
        UV, F = surfaces.grid(n, 2 * n)
        xy = np.column_stack([x0 + A * UV[:, 0], -A + 2 * A * UV[:, 1]])
        V = _sphere(xy)
        write_obj(tmp_path / f"half{i}.obj", V, F)
        res = design_mesh(tmp_path / f"half{i}.obj",
                          DesignParameters(size=SizeSpec(bbox_diagonal=float(np.linalg.norm(np.ptp(V, axis=0))))),
                          SolverSettings(refine_below_faces=0), predict=False)
        p = predict_deployed(res.flat_uv, res.V, res.F, res.design.ribbons, table=TABLE, releases=RELEASES[:1],
                             prestretch=res.design.parameters.prestretch, ribbon_width=res.design.parameters.ribbon_width)
        shift = V.mean(axis=0) - res.V.mean(axis=0)                   # the design centres its target
        assert np.abs(res.V + shift - V).max() < 1e-6
        panels.append(ReleasedPanel(sheet=p.sheet, X=p.X_released, target=p.target + shift))
        alone_mm.append(p.distance.mean())
        on_seam = np.flatnonzero(np.isclose(xy[:, 0], 0.0))
        seam_pts.append(res.flat_uv[on_seam[np.argsort(xy[on_seam, 1])]])   # the shared vertices, mark for mark
    a = assemble(panels, [SeamPairing(0, seam_pts[0], 1, seam_pts[1])], VW, FW)
    assert a.converged and a.seam_gap_mm["max"] < 0.01 and a.placed_gap_mm["max"] > 10 * a.seam_gap_mm["max"]
    assert a.distance.mean() <= max(alone_mm)
    # smooth across the seam: the angle between the two sides' boundary faces at the matched points
    # is, on average, within 1° of the target's own (the faces' centroids are apart on the sphere)
    sewn = np.degrees(_seam_angles([a.X[a.panel == k] for k in (0, 1)], panels, seam_pts))
    truth = np.degrees(_seam_angles([p.target for p in panels], panels, seam_pts))
    assert sewn.mean() <= truth.mean() + 1.0
    print(f"cap: alone {alone_mm} mm, sewn {a.distance.mean():.3f} mm, {a.report()}, "
          f"seam angle mean {sewn.mean():.2f}° max {sewn.max():.2f}° (target {truth.mean():.2f}°)")


def _seam_angles(X, panels, seam_pts):
    """(p,) angle between the two panels' faces at each matched point, X per panel (n_k, 3)."""
    from ribbond.deploy.predict import barycentric
    normals = []
    for k, pts in enumerate(seam_pts):
        face, _, _ = barycentric(pts, panels[k].sheet.uv, panels[k].sheet.F)
        c = panels[k].sheet.F[face]
        nrm = np.cross(X[k][c[:, 1]] - X[k][c[:, 0]], X[k][c[:, 2]] - X[k][c[:, 0]])
        normals.append(nrm / np.linalg.norm(nrm, axis=1, keepdims=True))
    return np.arccos(np.clip(np.sum(normals[0] * normals[1], axis=1), -1.0, 1.0))


def test_bad_seams_are_refused_with_their_name():
    uv, F = _rect(4, 4, (20.0, 20.0))
    sheet, _ = sheet_for_layout(uv, F, [], prestretch=S, ribbon_width=W, table=TABLE)
    panel = ReleasedPanel(sheet=sheet, X=np.column_stack([uv, np.zeros(len(uv))]), target=np.zeros((len(uv), 3)))
    edge = np.column_stack([np.full(5, 20.0), np.linspace(0.0, 20.0, 5)])
    other = edge - [20.0, 0.0]
    cases = [([panel, panel], [], "panel 1 is not connected"),
             ([panel, panel], [SeamPairing(0, edge, 2, other)], "seam 0: panel_b = 2"),
             ([panel, panel], [SeamPairing(0, edge, 1, other[:3])], "seam 0: points_a and points_b"),
             ([panel, panel], [SeamPairing(0, edge + [30.0, 0.0], 1, other)], "seam 0: point 0 lies"),
             ([panel, panel], [SeamPairing(1, edge, 1, other)], "sews panel 1 to itself")]
    for panels, seams, message in cases:
        with pytest.raises(ValueError, match=message):
            place_panels(panels, seams)
