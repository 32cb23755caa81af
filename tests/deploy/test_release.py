"""The release along the physical path (ribbond.deploy.release)."""

from __future__ import annotations

import numpy as np
import pytest

from ribbond.deploy.predict import Material, sheet_for_layout
from ribbond.deploy.release import NOMINAL, Path, curl_kick, release
from ribbond.deploy.solver import newton
from ribbond.design import surfaces
from ribbond.design.thickness import load_curvature_table

from .patterns import staggered_pattern

TABLE = load_curvature_table("tpu95a-lycra-default")


def _sheet(side="front", size=(90.0, 60.0)):
    UV, F = surfaces.grid(24, 16)
    uv = UV * np.array(size)
    rib = staggered_pattern(size, 22.9, 6.0, 15.0, 0.6, side=side)
    sheet, _ = sheet_for_layout(uv, F, rib, prestretch=1.6, ribbon_width=1.5, table=TABLE)
    return sheet


def test_the_printed_state_is_at_rest():
    sheet = _sheet()
    X = np.column_stack([sheet.uv, np.zeros(len(sheet.uv))])
    E = sheet.energy_at(0.0)
    assert E.energy(X) < 1e-12 * sheet.energy_at(1.0).energy(X)
    assert np.abs(E.gradient(X)).max() < 1e-12


@pytest.mark.parametrize("side, sign", [("front", -1.0), ("back", 1.0)])
def test_the_curl_kick_lifts_toward_the_side_the_ribbons_bend(side, sign):
    # front ribbons bulge toward +z (design-format.md): the middle of the sheet rises over its ends
    sheet = _sheet(side)
    w = curl_kick(sheet)
    x = sheet.uv[:, 0]
    mid, ends = np.abs(x - 45.0) < 8.0, np.abs(x - 45.0) > 37.0
    assert sign * (w[ends].mean() - w[mid].mean()) > 0
    assert np.abs(w).max() == pytest.approx(1e-3 * sheet.diagonal)


def test_a_bare_sheet_releases_flat_and_contracted():
    UV, F = surfaces.grid(12, 8)
    uv = UV * np.array([60.0, 40.0])
    sheet, _ = sheet_for_layout(uv, F, [], prestretch=1.5, ribbon_width=1.5, table=TABLE, material=Material())
    assert not np.any(curl_kick(sheet))
    r = release(sheet, steps=5)
    assert r.converged
    assert np.abs(r.X[:, 2]).max() < 1e-6
    e = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    ratio = np.linalg.norm(r.X[e[:, 0]] - r.X[e[:, 1]], axis=1) / np.linalg.norm(uv[e[:, 0]] - uv[e[:, 1]], axis=1)
    assert ratio == pytest.approx(1.0 / 1.5, rel=1e-4)              # every length × 1/s


def test_release_converges_and_its_path_is_followed():
    sheet = _sheet()
    steps = []
    r = release(sheet, steps=8, progress=lambda k, n, it: steps.append((k, n)))
    assert r.converged and steps[-1][0] == steps[-1][1] and len(steps) >= 8
    # at equilibrium: the out-of-balance force of the released sheet is tiny against its force scale
    E = sheet.energy_at(1.0)
    g = E.gradient(r.X).reshape(-1, 3)
    assert np.abs(g).max() < 1e-4 * sheet.force_scale
    # front ribbons along x: the sheet bends about y toward +z (the middle above the ends)
    x = sheet.uv[:, 0]
    mid, ends = np.abs(x - 45.0) < 8.0, np.abs(x - 45.0) > 37.0
    assert r.X[mid, 2].mean() - r.X[ends, 2].mean() > 5.0


def test_steps_must_be_positive():
    with pytest.raises(ValueError, match="steps"):
        release(_sheet(), steps=0)


def test_newton_stops_on_force_and_step_not_on_a_creeping_energy():
    sheet = _sheet()
    X = np.column_stack([sheet.uv, curl_kick(sheet)])
    E = sheet.energy_at(0.3)
    gtol = 1e-6 * sheet.force_scale
    r = newton(E, X, max_iterations=200, gradient_tolerance=gtol, scale=sheet.diagonal)
    assert r.converged and r.gradient_norm <= gtol
    # a loose energy rule (the old default) stops earlier, out of balance
    loose = newton(E, X, max_iterations=200, energy_tolerance=0.5, window=2, scale=sheet.diagonal)
    assert loose.iterations < r.iterations and loose.gradient_norm > gtol
