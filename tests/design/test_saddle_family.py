"""One family of curvature lines through each ambiguous saddle region (``ribbond.design.saddle_family``).

Expected values come from the geometry of z = (κx x² − κy y²) / 2: on a saddle κ_max > 0 > κ_min, so
a family of curvature lines has one sign of normal curvature everywhere; with κx = κy the largest |κ|
switches family on the diagonals (H = 0), on half the area by symmetry.
"""

from __future__ import annotations

import numpy as np
import pytest

from ribbond.design import surfaces
from ribbond.design.curvature import face_curvature
from ribbond.design.frames import face_frames
from ribbond.design.line_field import ANISOTROPY_THRESHOLD, curvature_anisotropy, curvature_line_field
from ribbond.design.saddle_family import saddle_family


def _setup(V, F):
    frames = face_frames(V, F)
    curv = face_curvature(V, F, frames)
    diag = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))
    aniso = curvature_anisotropy(curv, diag)
    return frames, curv, aniso, 0.1 / diag


def _family(V, F):
    frames, curv, aniso, flat = _setup(V, F)
    return frames, curv, aniso, saddle_family(F, frames.area, curv, aniso, ANISOTROPY_THRESHOLD, flat)


def _normal_curvature(curv, angle):
    return curv.normal_curvature(np.column_stack([np.cos(angle), np.sin(angle)]))


def test_a_symmetric_saddle_follows_one_family_and_half_of_it_leaves_the_largest_curvature():
    V, F = surfaces.saddle(80.0, 1 / 40.0, 1 / 40.0, rings=24)
    frames, curv, aniso, fam = _family(V, F)
    assert fam is not None
    region = fam.region >= 0
    ambiguous = (aniso <= ANISOTROPY_THRESHOLD) & (curv.kappa1 * curv.kappa2 < 0)
    np.testing.assert_array_equal(region, ambiguous)
    sizes = np.bincount(fam.region[region], weights=frames.area[region])
    assert sizes.max() > 0.95 * sizes.sum()                       # the centre and the diagonals: one region
    assert fam.switched_pct == pytest.approx(50.0, abs=3.0)       # the diagonals split it in halves
    kn = _normal_curvature(curv, fam.angle)
    for r in range(fam.region.max() + 1):                         # one family a region: one sign of κ
        sign = np.sign(kn[fam.region == r])
        assert np.all(sign == sign[0])
    principal = np.where(np.sign(curv.kappa1) == np.sign(kn), curv.kappa1, curv.kappa2)
    np.testing.assert_allclose(kn[region], principal[region], rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(fam.weight[region], 1.0)


def test_the_family_that_bends_more_is_chosen():
    # κx > κy: the family along x bends more over the region (|κ| ≈ κx near the centre)
    V, F = surfaces.saddle(80.0, 1 / 40.0, 1 / 46.0, rings=24)
    frames, curv, aniso, fam = _family(V, F)
    assert fam is not None
    region = fam.region >= 0
    k_max, k_min = np.maximum(curv.kappa1, curv.kappa2), np.minimum(curv.kappa1, curv.kappa2)
    bend = {1: np.sum((frames.area * np.abs(k_max))[region]), -1: np.sum((frames.area * np.abs(k_min))[region])}
    chosen = int(np.sign(_normal_curvature(curv, fam.angle)[region][0]))
    assert bend[chosen] > bend[-chosen]
    # and it is the family along x: at the centre the lines run along the x axis
    centre = np.argmin(np.linalg.norm(V[F].mean(axis=1)[:, :2], axis=1))
    direction = frames.to_world(np.column_stack([np.cos(fam.angle), np.sin(fam.angle)]))[centre]
    assert abs(direction[0]) > 0.99


@pytest.mark.parametrize("name, build", [
    ("skew saddle (k1 defined)", lambda: surfaces.saddle(80.0, 1 / 35.0, 1 / 80.0, rings=24)),
    ("spherical cap (K > 0)", lambda: surfaces.sphere_cap(radius=80.0, half_angle_deg=25.0, rings=24)),
    ("plane", lambda: surfaces.saddle(80.0, 0.0, 0.0, rings=12)),
])
def test_no_alternative_where_no_saddle_region_switches_family(name, build):
    V, F = build()
    *_, fam = _family(V, F)
    assert fam is None, name


def test_the_line_field_follows_the_family_without_corners():
    V, F = surfaces.saddle(80.0, 1 / 40.0, 1 / 40.0, rings=24)
    frames, curv, aniso, fam = _family(V, F)
    paper = curvature_line_field(V, F, frames, curv)
    one = curvature_line_field(V, F, frames, curv, targets=(fam.angle, fam.weight))
    assert one.one_family and not paper.one_family
    np.testing.assert_array_equal(one.anisotropy, paper.anisotropy)      # the report's k1 stays the curvature's
    off = np.abs(np.angle(np.exp(2j * (one.angle - fam.angle)))) / 2
    assert np.degrees(np.median(off)) < 2.0
    sign = np.sign(_normal_curvature(curv, one.angle))
    assert np.mean(sign == np.sign(np.median(sign))) > 0.98                # one side: no corners
    paper_sign = np.sign(_normal_curvature(curv, paper.angle))
    assert 0.2 < np.mean(paper_sign > 0) < 0.8                            # the paper's switches sides


def test_the_targets_are_the_aligned_fields_only():
    V, F = surfaces.saddle(80.0, 1 / 40.0, 1 / 40.0, rings=12)
    frames, curv, aniso, fam = _family(V, F)
    with pytest.raises(ValueError, match="aligned"):
        curvature_line_field(V, F, frames, curv, method="kcps13", targets=(fam.angle, fam.weight))


def test_bad_input_is_refused():
    V, F = surfaces.saddle(80.0, 1 / 40.0, 1 / 40.0, rings=12)
    frames, curv, aniso, flat = _setup(V, F)
    with pytest.raises(ValueError, match="one value per face"):
        saddle_family(F, frames.area[:-1], curv, aniso, ANISOTROPY_THRESHOLD, flat)
