"""Refinement of coarse targets at intake (``ribbond.design.refine``), checked against geometry.

Analytic surfaces sampled coarsely are refined; expectations come from the surfaces: the new
vertices lie on the analytic surface far closer than the coarse chords do (the local fits are exact
to second order, the chords to first), the boundary loop keeps its vertices in order with
2^levels − 1 new ones between neighbours, the winding follows the analytic normal, a plane stays a
plane, and the curvature estimated on the refined mesh is near the exact one (plain midpoint
subdivision, the same mesh without the fits, is far off: its curvature sits on the coarse edges).
"""

from __future__ import annotations


import igl
import numpy as np
import pytest

from ribbond.design import surfaces as S
from ribbond.design.folder import read_design_folder
from ribbond.mesh.files import write_obj
from ribbond.design.params import DesignParameters, SolverSettings, settings_from_dict
from ribbond.pipeline.compile import design_mesh, write_design
from ribbond.design.refine import _subdivision, levels_for, refine
from ribbond.design.refine_smooth import refine_smooth

from .refine_cases import CASES, IDS, Mesh, assert_topology_and_boundary_order, curvature_errors


@pytest.mark.parametrize("levels", [1, 2])
@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_keeps_the_vertices_topology_and_boundary(case, levels):
    _, (V, F), _, _ = case
    r = refine(V, F, levels)
    assert np.array_equal(r.V[: len(V)], V)                       # the file's vertices, exactly
    assert_topology_and_boundary_order(V, F, r.V, r.F, levels)


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_new_vertices_lie_on_the_surface_closer_than_the_chords(case):
    _, (V, F), distance, _ = case
    r = refine(V, F, 2)
    S2, _ = _subdivision(F, len(V), 2)
    chords = distance((S2 @ V)[len(V):])                        # the coarse facets' points
    lifted = distance(r.V[len(V):])
    assert chords.max() > 0
    # second-order fits leave a third-order error: at these samplings (edges ≤ 1/5 of the radii)
    # well under a fifth of the chords' second-order sagitta
    assert lifted.max() < 0.2 * chords.max()
    assert np.median(lifted) < 0.1 * np.median(chords)
    # and never further from the coarse surface than the true surface is (plus that error)
    diagonal = np.linalg.norm(V.max(axis=0) - V.min(axis=0))
    assert r.offset_pct <= 100 * 1.2 * chords.max() / diagonal


SCHEMES = {"quadric": refine, "smooth": refine_smooth}


@pytest.mark.parametrize("scheme", list(SCHEMES))
@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_winding_follows_the_surface_normal(case, scheme):
    name, (V, F), _, exact = case
    r = SCHEMES[scheme](V, F, 2)
    tri = r.V[r.F]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    C = tri.mean(axis=1)
    want = np.column_stack([-C[:, 0] / 30, C[:, 1] / 60, np.ones(len(C))]) if name == "saddle" else (
        C if name == "sphere cap" else exact(C).normal)
    assert np.all(np.einsum("ij,ij->i", normal, want) > 0)


@pytest.mark.parametrize("scheme", list(SCHEMES))
def test_a_plane_stays_a_plane(scheme):
    V, F = S.plane_disk(80.0, rings=6)
    V = V + np.array([3.0, -2.0, 7.0])
    r = SCHEMES[scheme](V, F, 2)
    assert np.abs(r.V[:, 2] - 7.0).max() < 1e-9
    assert r.offset_pct < 1e-9


@pytest.mark.parametrize("case", [c for c in CASES if c[3] is not None], ids=[c[0] for c in CASES if c[3] is not None])
def test_curvature_on_the_refined_mesh_is_near_the_exact_one(case):
    _, (V, F), _, exact = case
    r = refine(V, F, 2)
    S2, F2 = _subdivision(F, len(V), 2)
    k_err, angle = curvature_errors(r.V, r.F, exact)
    k_mid, _ = curvature_errors(S2 @ V, F2, exact)
    assert k_err < 0.02 and angle < 0.5
    assert k_err < 0.1 * k_mid


def test_levels_for():
    assert levels_for(900, 3_000, 10_000, 400_000) == 2           # 900 → 14,400
    assert levels_for(900, 3_000, 3_600, 400_000) == 1            # 3,600 reached in one round
    assert levels_for(900, 3_000, 10_000, 10_000) == 1            # 14,400 would exceed max_faces
    assert levels_for(900, 0, 10_000, 400_000) == 0               # off
    assert levels_for(3_000, 3_000, 10_000, 400_000) == 0         # not coarse
    with pytest.raises(ValueError, match="refine_below = -1"):
        levels_for(900, -1, 10_000, 400_000)


def test_bad_input_is_named():
    V, F = S.plane_disk(80.0, rings=2)
    with pytest.raises(ValueError, match="levels = -1"):
        refine(V, F, -1)
    with pytest.raises(ValueError, match="indices into V"):
        refine(V, F + len(V), 1)
    with pytest.raises(ValueError, match=r"\(n, 3\)"):
        refine(V[:, :2], F, 1)


def test_solver_setting_is_accepted_or_refused():
    solver = settings_from_dict({"solver": {"refine_below_faces": 0, "refine_to_faces": 5000}}).solver
    assert (solver.refine_below_faces, solver.refine_to_faces) == (0, 5000)
    with pytest.raises(ValueError, match="solver.refine_below_faces = -5"):
        settings_from_dict({"solver": {"refine_below_faces": -5}})
    with pytest.raises(ValueError, match="solver.refine_to_faces = 0"):
        settings_from_dict({"solver": {"refine_to_faces": 0}})


def test_design_of_a_coarse_target_is_made_on_the_refined_mesh(tmp_path):
    V, F = S.torus_patch(50.0, 20.0, (0, 60), (-30, 30), 20, 10)        # 400 faces
    write_obj(tmp_path / "coarse.obj", V, F)
    params = DesignParameters(size={"bbox_diagonal": 120.0})
    result = design_mesh(tmp_path / "coarse.obj", params, SolverSettings(refine_to_faces=6_000),
                         predict=False)
    folder = read_design_folder(write_design(result, tmp_path / "refined"))
    rep = folder.design.report
    assert folder.design.source.faces == 400
    assert rep.refined is not None and (rep.refined.from_faces, rep.refined.faces, rep.refined.levels) == (400, 6400, 2)
    assert rep.faces == 6400 and len(folder.target_F) == 6400        # target.obj: the mesh the engine used
    # target.obj is the file's surface scaled to the size: its first vertices are the file's
    Vt = folder.target_V[: len(V)]
    ratio = np.linalg.norm(Vt - Vt[0], axis=1)[1:] / np.linalg.norm(V - V[0], axis=1)[1:]
    assert np.allclose(ratio, ratio[0], rtol=1e-6)                 # (OBJ keeps ~9 digits)
    off = design_mesh(tmp_path / "coarse.obj", params, SolverSettings(refine_below_faces=0), predict=False)
    assert off.design.report.refined is None and len(off.F) == 400
