"""Ribbon thickness from curvature tables (§5): inverse interpolation, sides, clamping, table files.

Expected values come from the definitions: a synthetic table whose κ is linear in τ and μ2 is
reproduced exactly by bilinear interpolation, so both the forward value and the inverse are known
in closed form.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ribbond.design.thickness import (
    TABLE_DIR,
    TABLE_MARGIN,
    CurvatureTable,
    ThicknessResult,
    available_tables,
    largest_table_scale,
    load_curvature_table,
    ribbon_thickness,
    table_curvature,
)

TAU = [0.2, 0.5, 0.7, 1.0]           # uneven on purpose
MU = [3.0, 5.0, 9.0]
# κ_front = A + B τ − C μ2 > 0 on the grid; κ_back = κ_front / 2.
A, B, C = 0.02, 0.04, 0.001


def kappa_front(tau, mu):
    return A + B * np.asarray(tau) - C * np.asarray(mu)


def synthetic(**changes) -> CurvatureTable:
    t, m = np.meshgrid(TAU, MU, indexing="ij")
    data = dict(name="linear", prestretch=1.6, thickness=TAU, spacing=MU,
                front=kappa_front(t, m).tolist(), back=(kappa_front(t, m) / 2).tolist())
    data.update(changes)
    return CurvatureTable(**data)


def table_toml(table: CurvatureTable) -> str:
    def rows(k: list[list[float]]) -> str:
        return "[" + ", ".join(repr(list(r)) for r in k) + "]"

    return (f'name = "{table.name}"\nprestretch = {table.prestretch}\n'
            f"thickness = {list(table.thickness)}\nspacing = {list(table.spacing)}\n"
            f"front = {rows(table.front)}\nback = {rows(table.back)}\n")


# --- the synthetic table: forward and inverse against closed forms ---------------------------

def test_forward_interpolation_is_exact_on_a_linear_table():
    table = synthetic()
    rng = np.random.default_rng(1)
    tau = rng.uniform(TAU[0], TAU[-1], 200)
    mu = rng.uniform(MU[0], MU[-1], 200)
    assert np.allclose(table_curvature(table, "front", tau, mu), kappa_front(tau, mu), rtol=0, atol=1e-12)
    assert np.allclose(table_curvature(table, "back", tau, mu), kappa_front(tau, mu) / 2, rtol=0, atol=1e-12)


def test_inverse_matches_the_closed_form_on_both_sides():
    table = synthetic()
    rng = np.random.default_rng(2)
    tau = rng.uniform(TAU[0], TAU[-1], 300)
    mu = rng.uniform(MU[0], MU[-1], 300)
    front = rng.random(300) < 0.5
    k = np.where(front, kappa_front(tau, mu), -kappa_front(tau, mu) / 2)
    res = ribbon_thickness(table, k, mu)
    assert isinstance(res, ThicknessResult)
    # κ = A + B τ − C μ2 (front), twice |κ1| on the back: τ = (κ − A + C μ2) / B.
    expected = (np.where(front, k, -2 * k) - A + C * mu) / B
    assert np.allclose(res.thickness, expected, rtol=0, atol=1e-9)
    assert np.allclose(res.thickness, tau, rtol=0, atol=1e-9)
    assert res.clamped.dtype == bool and not res.clamped.any() and res.clamped_count == 0


def test_ribbon_thickness_inverts_table_curvature_on_the_shipped_table():
    table = load_curvature_table("tpu95a-lycra-default")
    rng = np.random.default_rng(3)
    n = 500
    tau = rng.uniform(table.thickness[0], table.thickness[-1], n)
    mu = rng.uniform(table.spacing[0], table.spacing[-1], n)
    front = rng.random(n) < 0.5
    k = np.where(front, table_curvature(table, "front", tau, mu), -table_curvature(table, "back", tau, mu))
    res = ribbon_thickness(table, k, mu)
    assert np.allclose(res.thickness, tau, rtol=0, atol=1e-9)
    assert res.clamped_count == 0
    # At the grid nodes the table's own values give its own thicknesses.
    t, m = np.meshgrid(table.thickness, table.spacing, indexing="ij")
    res = ribbon_thickness(table, np.asarray(table.front).ravel(), m.ravel())
    assert np.allclose(res.thickness, t.ravel(), rtol=0, atol=1e-12) and res.clamped_count == 0


def test_the_sign_chooses_the_side_and_zero_is_the_back():
    table = synthetic()
    mu = np.full(3, 5.0)
    kf = kappa_front(0.7, 5.0)
    res = ribbon_thickness(table, np.array([kf, -kf, -kf / 2]), mu)
    # +kf on the front is τ = 0.7; |−kf| on the back (half as curved) needs more than τ_max;
    # −kf/2 on the back is κ_back(0.7).
    assert res.thickness[0] == pytest.approx(0.7, abs=1e-12)
    assert res.thickness[1] == TAU[-1] and res.clamped[1]
    assert res.thickness[2] == pytest.approx(0.7, abs=1e-12)
    assert res.clamped.tolist() == [False, True, False]
    # κ1 = 0 uses the back table: below its smallest curvature, so τ_min, clamped.
    res = ribbon_thickness(table, np.array([0.0]), np.array([5.0]))
    assert res.thickness[0] == TAU[0] and res.clamped[0]


def test_clamping_below_above_and_outside_the_spacing_range():
    table = synthetic()
    low = kappa_front(TAU[0], 5.0) * 0.5
    high = kappa_front(TAU[-1], 5.0) * 2
    mid_k = kappa_front(0.5, MU[0])             # τ = 0.5 at μ2 = 3, the lower end of the range
    mid_k_hi = kappa_front(0.5, MU[-1])         # τ = 0.5 at μ2 = 9, the upper end
    k = np.array([low, high, -0.1 * low, mid_k, mid_k_hi, kappa_front(0.5, 5.0)])
    mu = np.array([5.0, 5.0, 5.0, 1.0, 40.0, 5.0])
    res = ribbon_thickness(table, k, mu)
    assert res.thickness[0] == TAU[0]
    assert res.thickness[1] == TAU[-1]
    assert res.thickness[2] == TAU[0]
    # μ2 clamped to the range: the curvature is looked up at the end spacing.
    assert res.thickness[3] == pytest.approx(0.5, abs=1e-12)
    assert res.thickness[4] == pytest.approx(0.5, abs=1e-12)
    assert res.thickness[5] == pytest.approx(0.5, abs=1e-12)
    assert res.clamped.tolist() == [True, True, True, True, True, False]
    assert res.clamped_count == 5
    # which end (issue 34): too flat for the thinnest plastic, too curved for the thickest, or the spacing
    assert res.too_flat.tolist() == [True, False, True, False, False, False]
    assert res.too_curved.tolist() == [False, True, False, False, False, False]
    assert res.spacing_out.tolist() == [False, False, False, True, True, False]
    # what the table can give at each ribbon's side and spacing (μ2 clamped to the range)
    front = [0, 1, 3, 4, 5]
    mu_in = np.clip(mu, MU[0], MU[-1])
    assert res.reachable[front, 0] == pytest.approx(kappa_front(TAU[0], mu_in[front]), abs=1e-15)
    assert res.reachable[front, 1] == pytest.approx(kappa_front(TAU[-1], mu_in[front]), abs=1e-15)
    assert res.reachable[2] == pytest.approx([kappa_front(TAU[0], 5.0) / 2, kappa_front(TAU[-1], 5.0) / 2], abs=1e-15)
    # The table's end values themselves are inside the range.
    ends = ribbon_thickness(table, kappa_front(np.array([TAU[0], TAU[-1]]), np.array(MU[::2])),
                            np.array(MU[::2]))
    assert ends.thickness.tolist() == pytest.approx([TAU[0], TAU[-1]], abs=1e-12)
    assert ends.clamped_count == 0


def test_forward_interpolation_clamps_to_the_grid():
    table = synthetic()
    got = table_curvature(table, "front", np.array([0.0, 5.0]), np.array([0.5, 99.0]))
    assert got == pytest.approx([kappa_front(TAU[0], MU[0]), kappa_front(TAU[-1], MU[-1])], abs=1e-15)
    with pytest.raises(ValueError, match="side"):
        table_curvature(table, "top", np.array([0.5]), np.array([5.0]))  # type: ignore[arg-type]


def test_empty_input():
    res = ribbon_thickness(synthetic(), np.zeros(0), np.zeros(0))
    assert res.thickness.shape == (0,) and res.clamped.shape == (0,) and res.clamped_count == 0
    assert table_curvature(synthetic(), "back", np.zeros(0), np.zeros(0)).shape == (0,)


def test_bad_ribbon_input_is_refused_naming_the_index():
    table = synthetic()
    with pytest.raises(ValueError, match=r"mu2\[2\]"):
        ribbon_thickness(table, np.full(3, 0.03), np.array([4.0, 5.0, 0.0]))
    with pytest.raises(ValueError, match=r"mu2\[1\]"):
        ribbon_thickness(table, np.full(3, 0.03), np.array([4.0, np.inf, 5.0]))
    with pytest.raises(ValueError, match=r"kappa1\[0\]"):
        ribbon_thickness(table, np.array([np.nan, 0.03]), np.array([4.0, 5.0]))
    with pytest.raises(ValueError, match="same length"):
        ribbon_thickness(table, np.full(3, 0.03), np.full(2, 5.0))
    with pytest.raises(ValueError, match="1-D"):
        ribbon_thickness(table, np.full((2, 2), 0.03), np.full((2, 2), 5.0))


# --- validation of tables -------------------------------------------------------------------

def test_a_column_that_does_not_increase_in_tau_is_refused_naming_side_and_mu2():
    t, m = np.meshgrid(TAU, MU, indexing="ij")
    back = kappa_front(t, m) / 2
    back[2, 1] = back[1, 1]                  # flat between τ = 0.5 and 0.7 at μ2 = 5
    with pytest.raises(ValueError, match=r"back: at μ2 = 5\.0 mm.*τ = 0\.5 mm.*τ = 0\.7 mm"):
        synthetic(back=back.tolist())
    front = kappa_front(t, m)
    front[3, 0] = front[0, 0] * 0.5          # decreasing at μ2 = 3
    with pytest.raises(ValueError, match=r"front: at μ2 = 3\.0 mm"):
        synthetic(front=front.tolist())


def test_shape_mismatch_is_refused():
    with pytest.raises(ValueError, match="front has 3 rows"):
        synthetic(front=synthetic().front[:3])
    with pytest.raises(ValueError, match="back row 1"):
        back = [list(r) for r in synthetic().back]
        back[1] = back[1][:2]
        synthetic(back=back)


@pytest.mark.parametrize("field,value", [
    ("front", [[np.nan, 1.0, 1.0]] * 4),
    ("back", [[np.inf, 1.0, 1.0]] * 4),
    ("thickness", [0.2, np.nan, 0.7, 1.0]),
    ("prestretch", np.nan),
])
def test_non_finite_values_are_refused(field, value):
    with pytest.raises(ValueError, match=field):
        synthetic(**{field: value})


@pytest.mark.parametrize("changes,match", [
    ({"thickness": [0.2, 0.5, 0.5, 1.0]}, "thickness must be strictly increasing"),
    ({"spacing": [3.0, 2.0, 9.0]}, "spacing must be strictly increasing"),
    ({"spacing": [5.0]}, "spacing"),
    ({"prestretch": 1.0}, "prestretch"),
    ({"name": ""}, "name"),
    ({"front": [[0.0] * 3] * 4}, "front"),
    ({"colour": "red"}, "colour"),
])
def test_other_invalid_tables_are_refused(changes, match):
    with pytest.raises(ValueError, match=match):
        synthetic(**changes)


# --- files ----------------------------------------------------------------------------------

def test_unknown_name_lists_the_shipped_tables():
    with pytest.raises(ValueError, match="unknown curvature table 'nope'.*tpu95a-lycra-default"):
        load_curvature_table("nope")


def test_a_user_table_loads_by_path(tmp_path: Path):
    table = synthetic()
    path = tmp_path / "mine.toml"
    path.write_text(table_toml(table), encoding="utf-8")
    assert load_curvature_table(path) == table
    assert load_curvature_table(str(path)) == table


def test_table_file_errors_name_the_file_and_the_field(tmp_path: Path):
    path = tmp_path / "bad.toml"
    path.write_text(table_toml(synthetic()).replace("prestretch = 1.6", "prestretch = 0.9"), encoding="utf-8")
    with pytest.raises(ValueError, match=r"bad\.toml: invalid curvature table: prestretch"):
        load_curvature_table(path)
    text = table_toml(synthetic())
    path.write_text(text.replace("front = [[", "front = [[nan, "), encoding="utf-8")
    with pytest.raises(ValueError, match=r"bad\.toml: invalid curvature table: front\.0\.0"):
        load_curvature_table(path)
    path.write_text(text.replace("spacing = [3.0, 5.0, 9.0]", "spacing = [3.0, 5.0]"), encoding="utf-8")
    with pytest.raises(ValueError, match=r"bad\.toml: invalid curvature table: front: .*row 0"):
        load_curvature_table(path)
    path.write_text("name = [", encoding="utf-8")
    with pytest.raises(ValueError, match=r"bad\.toml: cannot read the curvature table"):
        load_curvature_table(path)
    with pytest.raises(ValueError, match=r"missing\.toml: cannot read"):
        load_curvature_table(tmp_path / "missing.toml")


def test_the_shipped_table():
    assert "tpu95a-lycra-default" in available_tables()
    assert (TABLE_DIR / "tpu95a-lycra-default.toml").is_file()
    table = load_curvature_table("tpu95a-lycra-default")
    assert table.name == "tpu95a-lycra-default"
    assert table.prestretch == 1.6
    assert "not measured" in table.description.lower() and "docs/calibration.md" in table.description
    front, back = np.asarray(table.front), np.asarray(table.back)
    assert len(table.thickness) == 8 and len(table.spacing) == 6
    assert front.shape == back.shape == (8, 6)
    assert np.all((front / back >= 1.5) & (front / back <= 1.6))   # front 50-60 % more (§5)
    for k in (front, back):
        assert np.all(np.diff(k, axis=0) > 0)                      # increasing in τ
        assert np.all(np.diff(k, axis=1) < 0)                      # decreasing in μ2
    # The magnitude the estimate aims at: κ_front ≈ 0.025-0.03 /mm at τ = 0.5 mm, μ2 = 6 mm.
    assert 0.025 <= table_curvature(table, "front", np.array([0.5]), np.array([6.0]))[0] <= 0.03
    # The spacing range covers Eq. 10 at the default σ2 bounds (μ2 ≈ 3.9-15.1 mm) within rounding.
    assert table.spacing[0] <= 3.9 and table.spacing[-1] >= 15.0


# --- the largest size the table reaches ------------------------------------------------------


def test_one_curvature_scales_to_where_the_thinnest_plastic_curls_it():
    """A sphere-like target (one |κ1|, one μ2): too flat at the frame's size, the size drops until
    |κ1| / λ = κ(τ_min, μ2) (1 + m): κ goes as 1/size."""
    table, mu, kappa = synthetic(), 5.0, 0.002              # κ(τ_min = 0.2, 5) = 0.023: too flat at λ = 1
    k_min = kappa_front(TAU[0], mu)
    lam = largest_table_scale(table, np.full(10, kappa), np.full(10, mu), np.ones(10), at_most=1.0)
    assert lam == pytest.approx(kappa / (k_min * (1 + TABLE_MARGIN)))
    # on the back the table is half: twice the curvature at the same size, half the size
    lam_back = largest_table_scale(table, np.full(10, -kappa), np.full(10, mu), np.ones(10), at_most=1.0)
    assert lam_back == pytest.approx(2 * lam)


def test_a_size_within_the_table_is_kept_and_no_size_is_made_larger():
    table, mu = synthetic(), 5.0
    inside = 0.5 * (kappa_front(TAU[0], mu) + kappa_front(TAU[-1], mu))
    assert largest_table_scale(table, np.full(4, inside), np.full(4, mu), np.ones(4), at_most=1.0) == 1.0
    # too curved for the thickest plastic at the frame's size: only a larger size helps, and none is allowed
    assert largest_table_scale(table, np.full(4, 1.0), np.full(4, mu), np.ones(4), at_most=1.0) == 1.0
    # nothing within reach at any size (κ1 = 0, μ2 outside the table)
    assert largest_table_scale(table, np.zeros(3), np.full(3, mu), np.ones(3), at_most=0.7) == 0.7
    assert largest_table_scale(table, np.full(3, 0.01), np.full(3, 40.0), np.ones(3), at_most=0.7) == 0.7


def test_the_area_decides_between_two_curvatures():
    """Faces of two curvatures whose size ranges do not overlap: the size serves the larger area,
    unless the other is within the slack of it."""
    table, mu = synthetic(), 5.0
    k_min, k_max = kappa_front(TAU[0], mu), kappa_front(TAU[-1], mu)
    flat, curved = 0.1 * k_min, 3.0 * k_max                 # ranges [0.1 k_min/k_max, 0.1] and [3, 3 k_max/k_min]·(margin)
    kappa = np.array([flat, curved])
    mus = np.full(2, mu)
    lam = largest_table_scale(table, kappa, mus, np.array([0.3, 0.7]), at_most=10.0)
    assert lam == pytest.approx(curved / (k_min * (1 + TABLE_MARGIN)))
    lam = largest_table_scale(table, kappa, mus, np.array([0.7, 0.3]), at_most=10.0)
    assert lam == pytest.approx(flat / (k_min * (1 + TABLE_MARGIN)))
    lam = largest_table_scale(table, kappa, mus, np.array([0.7, 0.3]), at_most=1.0)
    assert lam == pytest.approx(flat / (k_min * (1 + TABLE_MARGIN)))


def test_bad_input_to_the_table_scale_is_refused():
    table = synthetic()
    with pytest.raises(ValueError, match="one length"):
        largest_table_scale(table, np.ones(3), np.ones(2), np.ones(3), at_most=1.0)
    with pytest.raises(ValueError, match="at_most"):
        largest_table_scale(table, np.ones(3), np.ones(3), np.ones(3), at_most=0.0)
