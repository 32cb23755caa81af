"""Rest forms from a layout: coverage of regular staggered patterns against their definition (§3,
Eq. 10's model), the table's curvature and its sign, bare fabric."""

from __future__ import annotations

import numpy as np
import pytest

from scipy.ndimage import map_coordinates

from ribbond.deploy import rest_forms as rf
from ribbond.deploy.rest_forms import (CoverageImage, contraction, face_coverage, layout_raster, rest_forms,
                                       ribbon_samples)
from ribbond.design import surfaces
from ribbond.design.thickness import load_curvature_table, table_curvature

from .patterns import staggered_pattern

TABLE = load_curvature_table("tpu95a-lycra-default")


def _sheet(nx=40, ny=26, size=(120.0, 80.0)):
    UV, F = surfaces.grid(nx, ny)
    return UV * np.array(size), F


def _interior(uv, F, margin=25.0, size=(120.0, 80.0)):
    c = uv[F].mean(axis=1)
    return (c[:, 0] > margin) & (c[:, 0] < size[0] - margin) & (c[:, 1] > margin) & (c[:, 1] < size[1] - margin)


def test_contraction_is_eq10s_model():
    s = 1.6
    assert contraction(np.array([0.0]), s)[0] == pytest.approx(1 / s)
    assert contraction(np.array([1.0]), s)[0] == pytest.approx(1.0)
    # a motif of length μ1 holding a ribbon l_r contracts to l_r + (μ1 − l_r)/s (§6.1)
    mu1, lr = 22.9, 15.0
    assert contraction(np.array([lr / mu1]), s)[0] * mu1 == pytest.approx(lr + (mu1 - lr) / s)
    with pytest.raises(ValueError, match="prestretch"):
        contraction(np.array([0.5]), 1.0)


def test_ribbon_samples_keep_ends_and_spacing():
    rib = staggered_pattern((40.0, 10.0), 20.0, 5.0, 15.0, 0.5)
    S = ribbon_samples(rib, 0.1)
    assert set(np.unique(S.ribbon)) == set(range(len(rib)))
    for i, r in enumerate(rib):
        pts = S.xy[S.ribbon == i]
        a, b = np.array(r.points[0]), np.array(r.points[-1])
        np.testing.assert_allclose(pts[S.end[S.ribbon == i] == -1][0], a)
        np.testing.assert_allclose(pts[S.end[S.ribbon == i] == 1][0], b)
        gaps = np.linalg.norm(np.diff(pts[np.argsort(pts[:, 0])], axis=0), axis=1)
        assert gaps.max() <= 0.1 + 1e-9


@pytest.mark.parametrize("mu1,mu2,length,tau", [(22.9, 6.0, 15.0, 0.6), (18.0, 9.0, 12.0, 1.0)])
def test_regular_pattern_coverage_is_its_definition(mu1, mu2, length, tau):
    uv, F = _sheet()
    w = 1.5
    rib = staggered_pattern((120.0, 80.0), mu1, mu2, length, tau)
    cov = face_coverage(uv, F, rib, w, TABLE)
    inner = _interior(uv, F)
    assert not cov.bare[inner].any()
    np.testing.assert_allclose(np.abs(cov.direction[inner, 0]), 1.0, atol=1e-9)      # along x
    assert np.median(cov.f_along[inner]) == pytest.approx(length / mu1, rel=0.01)
    assert np.median(cov.f_across[inner]) == pytest.approx(w / mu2, rel=0.01)
    assert np.median(cov.mu2[inner]) == pytest.approx(mu2, rel=0.01)
    expected = table_curvature(TABLE, "front", np.array([tau]), np.array([mu2]))[0]
    assert np.median(cov.kappa[inner]) == pytest.approx(expected, rel=0.01)
    assert np.median(cov.thickness[inner]) == pytest.approx(tau)


def test_back_ribbons_give_negative_curvature_of_the_back_table():
    uv, F = _sheet()
    rib = staggered_pattern((120.0, 80.0), 22.9, 6.0, 15.0, 0.6, side="back")
    cov = face_coverage(uv, F, rib, 1.5, TABLE)
    inner = _interior(uv, F)
    expected = table_curvature(TABLE, "back", np.array([0.6]), np.array([6.0]))[0]
    assert np.median(cov.kappa[inner]) == pytest.approx(-expected, rel=0.01)


def test_rest_forms_of_a_pattern_and_of_bare_fabric():
    uv, F = _sheet(20, 14)
    s = 1.6
    bare = face_coverage(uv, F, [], 1.5, TABLE)
    assert bare.bare.all()
    rf = rest_forms(bare, s)
    np.testing.assert_allclose(rf.abar, np.tile(np.eye(2) / s ** 2, (len(F), 1, 1)), atol=1e-15)
    np.testing.assert_allclose(rf.bbar, 0.0)
    # ribbons along y: ā = c_d² along y, c_p² along x; b̄ = κ c_d² along y only
    rib = [r.model_copy(update={"points": [(y, x) for x, y in r.points]})
           for r in staggered_pattern((80.0, 120.0), 22.9, 6.0, 15.0, 0.6)]
    uv2 = uv[:, ::-1].copy()
    F2 = F[:, [0, 2, 1]]                                   # keep the faces counter-clockwise
    cov = face_coverage(uv2, F2, rib, 1.5, TABLE)
    rf = rest_forms(cov, s)
    inner = _interior(uv2[:, ::-1], F2)
    cd, cp = contraction(cov.f_along, s), contraction(cov.f_across, s)
    np.testing.assert_allclose(rf.abar[inner, 1, 1], cd[inner] ** 2, rtol=1e-9)
    np.testing.assert_allclose(rf.abar[inner, 0, 0], cp[inner] ** 2, rtol=1e-9)
    np.testing.assert_allclose(rf.bbar[inner, 1, 1], cov.kappa[inner] * cd[inner] ** 2, rtol=1e-9)
    np.testing.assert_allclose(rf.bbar[inner, 0, 0], 0.0, atol=1e-12)


def test_bad_input_is_refused():
    uv, F = _sheet(4, 4)
    with pytest.raises(ValueError, match="ribbon_width"):
        face_coverage(uv, F, [], 0.0, TABLE)
    with pytest.raises(ValueError, match="uv"):
        face_coverage(uv[:, :1], F, [], 1.5, TABLE)


def test_bilinear_sampling_is_map_coordinates_constant_mode():
    rng = np.random.default_rng(3)
    img = rng.random((7, 9))                                   # non-zero up to the edges
    ci = CoverageImage(covered=img, inside=img, origin=np.array([-3.0, 2.0]), pixel=0.5)
    xy = np.column_stack([rng.uniform(-5.0, 3.0, 4000), rng.uniform(0.0, 7.0, 4000)]).reshape(40, 100, 2)
    ij = (xy - ci.origin) / ci.pixel
    expected = map_coordinates(img, [ij[..., 1].ravel(), ij[..., 0].ravel()], order=1, mode="constant",
                               cval=0.0).reshape(40, 100)
    assert (expected == 0).any() and (expected > 0).any()      # points outside and inside the raster
    np.testing.assert_allclose(ci.sample(img, xy), expected, rtol=0, atol=1e-14)


def _map_coordinates_sample(self, image, xy):
    """The sampler face_coverage used before (scipy's), to compare the whole coverage against."""
    ij = (xy - self.origin) / self.pixel
    flat = ij.reshape(-1, 2)
    out = map_coordinates(image, [flat[:, 1], flat[:, 0]], order=1, mode="constant", cval=0.0)
    return out.reshape(xy.shape[:-1])


def test_coverage_equals_the_map_coordinates_one_and_a_shared_raster_its_own(monkeypatch):
    uv, F = _sheet()
    rib = staggered_pattern((120.0, 80.0), 22.9, 6.0, 15.0, 0.6)
    new = face_coverage(uv, F, rib, 1.5, TABLE)
    # a raster made once on a finer mesh of the same rectangle (same outline: same grid and domain)
    fine_uv, fine_F = _sheet(80, 52)
    raster = layout_raster(fine_uv, fine_F, rib, 1.5)
    shared = face_coverage(uv, F, rib, 1.5, TABLE, raster=raster)
    with monkeypatch.context() as mp:
        mp.setattr(rf.CoverageImage, "sample", _map_coordinates_sample)
        before = face_coverage(uv, F, rib, 1.5, TABLE)
    assert not before.bare.all()
    for got in (new, shared):
        np.testing.assert_array_equal(got.bare, before.bare)
        for name in ("direction", "f_along", "f_across", "kappa", "thickness", "mu2"):
            np.testing.assert_allclose(getattr(got, name), getattr(before, name), rtol=1e-12, atol=1e-14,
                                       err_msg=name)
    with pytest.raises(ValueError, match="raster was made for"):
        face_coverage(uv, F, rib, 2.0, TABLE, raster=raster)


def _bowtie():
    """Two sheets of 60 × 40 mm touching at one corner, (60, 40): one mesh whose boundary vertex
    there joins two fans of faces (a fresh triangulation of a curved outline can leave such)."""
    uv_a, F_a = _sheet(20, 14, (60.0, 40.0))
    uv_b = uv_a + np.array([60.0, 40.0])
    shared = int(np.flatnonzero(np.all(np.isclose(uv_a, [60.0, 40.0]), axis=1))[0])
    corner_b = int(np.flatnonzero(np.all(np.isclose(uv_b, [60.0, 40.0]), axis=1))[0])
    others = np.setdiff1d(np.arange(len(uv_b)), [corner_b])
    index_b = np.empty(len(uv_b), dtype=np.int64)
    index_b[others] = len(uv_a) + np.arange(len(others))
    index_b[corner_b] = shared
    return np.vstack([uv_a, uv_b[others]]), np.vstack([F_a, index_b[F_a]])


def test_the_outline_is_the_union_of_the_faces_even_where_two_fans_touch():
    uv, F = _bowtie()
    assert rf._outline(uv, F).area == pytest.approx(2 * 60.0 * 40.0)
    rib = staggered_pattern((120.0, 80.0), 22.9, 6.0, 15.0, 0.6)
    cov = face_coverage(uv, F, rib, 1.5, TABLE)
    c = uv[F].mean(axis=1)
    for lo in ((0.0, 0.0), (60.0, 40.0)):          # the middle of each sheet
        inner = np.all((c > np.add(lo, [20.0, 10.0])) & (c < np.add(lo, [40.0, 30.0])), axis=1)
        assert inner.sum() > 50
        assert np.median(cov.f_along[inner]) == pytest.approx(15.0 / 22.9, rel=0.01)
