"""Calibration: coupon layout, measurements, the fit (issue 15); expectations from geometry and from a known law."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from ribbond.calibration.fit import arc_curvature, fit_side, fit_table, parse_measurements, pav
from ribbond.calibration.plan import GAP, LABEL, coupon_ribbons, layout, make_plan, write_plan
from ribbond.calibration.spec import CalibrationSpec
from ribbond.design.folder import read_design_folder
from ribbond.design.thickness import ribbon_thickness
from ribbond.gcode.profiles import load_profile

from .law import law, law_thickness, measurement_rows


def plan_dict(spec: CalibrationSpec) -> dict:
    coupons = layout(spec, load_profile(spec.printer_profile))
    return {"spec": spec.model_dump(mode="json"), "profile": spec.printer_profile,
            "coupons": [{"coupon": c.number, "side": c.side, "thickness_mm": c.thickness, "spacing_mm": c.spacing,
                         "width_mm": c.width} for c in coupons]}


def test_default_grid_is_the_papers_and_fits_the_frame():
    spec = CalibrationSpec()
    frame = load_profile(spec.printer_profile).frame
    coupons = layout(spec, load_profile(spec.printer_profile))
    for side in ("front", "back"):
        mine = {(c.thickness, c.spacing) for c in coupons if c.side == side}
        assert len(mine) == 48 == len([c for c in coupons if c.side == side])      # 8 × 6, each once
    x0, y0, x1, y1 = frame.bounds
    for sheet in {c.sheet for c in coupons}:
        rects = [c for c in coupons if c.sheet == sheet]
        for c in rects:
            assert x0 < c.x and c.x + c.width < x1 and y0 < c.y and c.y + c.height < y1
        for a in rects:                                    # no overlap, room for the crop marks between
            for b in rects:
                if a.number < b.number:
                    apart_x = a.x + a.width + GAP - 1e-9 <= b.x or b.x + b.width + GAP - 1e-9 <= a.x
                    apart_y = a.y + a.height + GAP - 1e-9 <= b.y or b.y + b.height + GAP - 1e-9 <= a.y
                    assert apart_x or apart_y, (a, b)
    assert [c.number for c in coupons] == list(range(1, 97))


def test_plan_folder_is_a_two_sided_design(tmp_path: Path):
    spec = CalibrationSpec(thicknesses=(0.3, 0.6, 0.9), spacings=(5.0, 10.0))
    plan = make_plan(spec, move_budget=0)
    out = write_plan(plan, tmp_path / "plan")
    assert (out / "coupons.csv").read_text().splitlines()[0].startswith("coupon,side,thickness_mm,spacing_mm")
    for s in plan.sheets:
        folder = read_design_folder(out / f"sheet-{s.number}")
        d = folder.design
        assert len(d.registration_marks) == 3
        front = (out / f"sheet-{s.number}" / "front.gcode").read_text()
        back = (out / f"sheet-{s.number}" / "back.gcode").read_text()
        for c in s.coupons:
            # each coupon's ribbons: inside its cut rectangle, after the label strip, at its τ and μ2, on its side
            mine = [r for r in d.ribbons if c.x + LABEL - 1e-9 <= r.points[0][0] and r.points[-1][0] <= c.x + c.width + 1e-9
                    and c.y <= r.points[0][1] <= c.y + c.height]
            assert len(mine) == len(coupon_ribbons(spec, c)) == 3 * math.ceil(c.rows / 2) + c.rows // 2 - math.ceil(c.rows / 2)
            assert all(r.side == c.side and r.thickness == c.thickness and r.spacing[1] == c.spacing for r in mine)
            assert all((r.kappa1 > 0) == (c.side == "front") for r in mine)
            label = f";TYPE:LABEL {c.number}\n"
            assert (label in front) == (c.side == "front") and (label in back) == (c.side == "back")
            assert f";TYPE:CUT {c.number}\n" in front
        assert front.count(";TYPE:REGISTRATION") == 3


def test_arc_curvature_of_a_circle():
    r = np.array([20.0, 55.0, 130.0])
    half = np.array([0.4, 1.0, 1.5])                       # half the arc's angle
    chord, sag = 2 * r * np.sin(half), r * (1 - np.cos(half))
    np.testing.assert_allclose(arc_curvature(chord, sag), 1 / r, rtol=1e-12)


def test_measurements_refused_with_the_coupon_and_line():
    known = {1, 2, 3}
    ok = parse_measurements("coupon,chord_mm,sagitta_mm,radius_mm\n1,40,5,\n2,,,25\n3,,,\n", known)
    assert ok[1] == pytest.approx(8 * 5 / (40 ** 2 + 4 * 25)) and ok[2] == pytest.approx(1 / 25) and ok[3] is None
    bad = {"coupon,chord_mm,sagitta_mm\n1,40,\n": "line 2, coupon 1",
           "coupon,chord_mm,sagitta_mm\n1,40,5\n2,-3,1\n": "line 3, coupon 2",
           "coupon,radius_mm\n1,abc\n": "line 2, coupon 1",
           "coupon,radius_mm\n7,20\n": "coupon 7 is not in the plan",
           "coupon,radius_mm\n1,20\n1,21\n": "coupon 1 is measured twice",
           "coupon,chord_mm,sagitta_mm\n2,10,8\n": "coupon 2",
           "coupon,diameter\n1,20\n": "unknown column"}
    for text, where in bad.items():
        with pytest.raises(ValueError, match=where):
            parse_measurements(text, known)


def test_pav_is_the_isotonic_least_squares_fit():
    y = np.array([1.0, 3.0, 2.0, 4.0, 3.5, 5.0])
    np.testing.assert_allclose(pav(y), [1.0, 2.5, 2.5, 3.75, 3.75, 5.0])
    assert np.all(np.diff(pav(np.random.default_rng(1).normal(size=50))) >= 0)


def test_fit_recovers_the_law_within_the_noise():
    spec = CalibrationSpec()
    plan = plan_dict(spec)
    noise = 0.02
    text, _ = measurement_rows(plan["coupons"], noise, seed=7, failed=(5, 60))
    measured = parse_measurements(text, {c["coupon"] for c in plan["coupons"]})
    fit = fit_table(plan, measured, name="law-test", date="2026-12-01")
    assert fit.failed == [5, 60] and fit.measured == 94
    tau, mu = np.meshgrid(spec.thicknesses, spec.spacings, indexing="ij")
    for side in ("front", "back"):
        truth = law(side, tau, mu)
        err = np.abs(fit.table.grid(side) - truth) / truth
        assert err.max() < 4 * noise, (side, err.max())        # each point: one measurement of 2 % noise
        assert np.sqrt(np.mean(err ** 2)) < 1.5 * noise
        assert fit.sides[side].rms < 3 * noise * truth.max()
    assert "Measured: 94 coupons (2 failed)" in fit.table.description
    # the thicknesses the law implies, from the fitted table: a 2 % error in κ moves τ by little
    rng = np.random.default_rng(3)
    m = rng.uniform(3.5, 15.0, 40)
    for side, sign in (("front", 1), ("back", -1)):
        t_true = rng.uniform(0.3, 1.4, 40)
        k = law(side, t_true, m)
        got = ribbon_thickness(fit.table, sign * k, m)
        assert not got.clamped.any()
        want = np.array([law_thickness(side, float(a), float(b)) for a, b in zip(k, m)])
        np.testing.assert_allclose(want, t_true, rtol=1e-6)
        assert np.max(np.abs(got.thickness - t_true) / t_true) < 0.12


def test_fit_refuses_non_monotone_and_sparse_columns():
    tau = np.array([0.2, 0.4, 0.6, 0.8])
    mu = np.array([5.0, 10.0])
    T, M = np.meshgrid(tau, mu, indexing="ij")
    k = law("front", T, M)
    falling = k.copy()
    falling[:, 1] = falling[::-1, 1]                       # falls with τ at μ2 = 10: flat after pooling
    with pytest.raises(ValueError, match="front, μ2 = 10 mm: κ1 does not increase with τ even after the "
                       "monotone fit \\(from τ = 0.2 to 0.8 mm"):
        fit_side("front", T.ravel(), M.ravel(), falling.ravel(), tau, mu)
    keep = ~((M == 5.0) & (T > 0.3))                       # one thickness left at μ2 = 5
    with pytest.raises(ValueError, match="front, μ2 = 5 mm: 1 measured thickness.*too sparse"):
        fit_side("front", T[keep], M[keep], k[keep], tau, mu)


def test_residuals_show_the_pooled_points_and_the_noise():
    tau = np.array([0.2, 0.4, 0.6, 0.8, 1.0, 1.2])
    mu = np.array([5.0, 10.0])
    T, M = np.meshgrid(tau, mu, indexing="ij")
    k = law("front", T, M)
    exact = fit_side("front", T.ravel(), M.ravel(), k.ravel(), tau, mu)
    assert exact.rms < 1e-15                                   # nothing pooled: through every point
    noisy = k.copy()
    noisy[2, 0], noisy[3, 0] = k[3, 0], k[2, 0]                 # a swapped pair: pooled to their mean
    fit = fit_side("front", T.ravel(), M.ravel(), noisy.ravel(), tau, mu)
    # the pair is one point at τ = 0.7, κ their mean: the curve passes there and stays near the law,
    # so each swapped measurement is off by about the law's difference between 0.6 and 0.8 mm; every
    # other point lies exactly on the curve
    d = k[3, 0] - k[2, 0]
    p = fit.points
    pair = np.isclose(p[:, 1], 5.0) & (np.isclose(p[:, 0], 0.6) | np.isclose(p[:, 0], 0.8))
    np.testing.assert_allclose(np.abs(p[pair, 2] - p[pair, 3]), d, rtol=0.35)
    np.testing.assert_allclose(p[~pair, 2], p[~pair, 3], atol=1e-15)
    assert fit.max_abs == pytest.approx(np.abs(p[pair, 2] - p[pair, 3]).max())
    assert np.all(np.diff(fit.grid, axis=0) > 0)
    assert fit.loo_rms > exact.loo_rms


def test_ribbonctl_calibrate_locally(tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    from ribbond.client.cli import main

    out = tmp_path / "cal"
    assert main(["calibrate", "plan", "-o", str(out), "--thicknesses", "0.3,0.6,0.9", "--spacings", "5,10",
                 "--sides", "front"]) == 0
    rows = (out / "coupons.csv").read_text().splitlines()[1:]
    assert len(rows) == 6 and all(",front," in r for r in rows)
    assert (out / "sheet-1.png").read_bytes()[:4] == b"\x89PNG" and b"<svg" in (out / "sheet-1.svg").read_bytes()
    coupons = [dict(zip(("coupon", "side", "thickness_mm", "spacing_mm", "sheet", "x", "y", "width_mm"),
                        r.split(",")[:8])) for r in rows]
    coupons = [{**c, "coupon": int(c["coupon"]), "thickness_mm": float(c["thickness_mm"]),
                "spacing_mm": float(c["spacing_mm"]), "width_mm": float(c["width_mm"])} for c in coupons]
    text, _ = measurement_rows(coupons, 0.0, seed=1)
    (tmp_path / "m.csv").write_text(text)
    capsys.readouterr()
    assert main(["calibrate", "record", str(out), str(tmp_path / "m.csv"), "-o", str(tmp_path / "mine.toml")]) == 0
    said = capsys.readouterr().out
    assert "table 'mine' from 6 coupons" in said and "designs need" in said       # μ2 5-10 mm: a warning
    from ribbond.design.thickness import load_curvature_table

    t = load_curvature_table(tmp_path / "mine.toml")
    tau, mu = np.meshgrid(t.thickness, t.spacing, indexing="ij")
    np.testing.assert_allclose(t.grid("front"), law("front", tau, mu), rtol=1e-4)   # 5 digits, no noise
    # the back was not measured: the front times the shipped table's back/front ratio, said so
    assert "The back side was not measured" in t.description
    (tmp_path / "bad.csv").write_text("coupon,radius_mm\n1,20\n4,-2\n")
    assert main(["calibrate", "record", str(out), str(tmp_path / "bad.csv"), "-o", str(tmp_path / "x.toml")]) == 2
    assert "bad.csv, line 3, coupon 4" in capsys.readouterr().err
    assert not (tmp_path / "x.toml").exists()


def _shape(strokes: list[np.ndarray]) -> set[tuple[float, ...]]:
    """Strokes as a set of unordered segments, translated so that their lower left corner is at 0."""
    lo = np.vstack(strokes).min(axis=0)
    return {tuple(sorted([tuple(np.round(p - lo, 6)) for p in s])) for s in strokes}  # type: ignore[misc]


def test_back_labels_read_right_on_the_back():
    from ribbond.calibration.plan import Coupon, coupon_label, digit_strokes
    from ribbond.gcode.program import mirror

    frame = load_profile("ultimaker2-tpu").frame
    up, right = np.array([-1.0, 0.0]), np.array([0.0, 1.0])
    for number in (2, 47):
        glyph = _shape(digit_strokes(str(number), np.zeros(2), up, right))
        common = dict(number=number, thickness=0.4, spacing=6.0, sheet=1, x=40.0, y=50.0, width=49.5,
                      height=24.0, rows=4, expected_kappa=0.02)
        front = coupon_label(Coupon(side="front", **common), frame.flip_axis)
        back = coupon_label(Coupon(side="back", **common), frame.flip_axis)
        assert _shape(front) == glyph                              # as printed on the front
        assert _shape([mirror(s, frame) for s in back]) == glyph   # as printed on the back (mirrored program)
        assert _shape(back) != glyph                               # (the check can tell a mirrored label)
