"""The back side's registration: rigid fits of the marks, and the checks that refuse bad ones.

Expectations come from geometry: marks moved by a known rotation about a known point and a known
offset (built here with plain rotation matrices, not with ``Correction``), and the simulator's flip
model re-implemented from ``sim/frame.py``'s docstring: back up, p = Rot_c(r)·Mirror(q) + offset.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from ribbond.gcode.alignment import AlignmentFit, AlignmentRefused, check_fit, expected_marks, fit_rigid
from ribbond.gcode.profiles import FrameSpec

FRAME = FrameSpec(center=(110.0, 110.0), size=(180.0, 180.0), flip_axis="y")

#: Back-side marks in general position (not symmetric about their centroid).
MARKS = np.array([[30.0, 25.0], [185.0, 32.0], [178.0, 190.0], [40.0, 170.0], [112.0, 96.0]])

#: Loose limits that a clean fit passes.
LOOSE = dict(max_residual=0.3, max_rotation_deg=2.0, max_offset=5.0)


def rot(deg: float) -> np.ndarray:
    a = math.radians(deg)
    return np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])


def moved(pts: np.ndarray, deg: float, about: tuple[float, float], offset: tuple[float, float]) -> np.ndarray:
    """Rotate ``pts`` by ``deg`` about ``about``, then shift by ``offset`` (one point at a time)."""
    R, c, d = rot(deg), np.asarray(about, dtype=float), np.asarray(offset, dtype=float)
    return np.array([R @ (p - c) + c + d for p in np.asarray(pts, dtype=float)])


def sim_machine(fabric: np.ndarray, frame: FrameSpec, r: float, offset: tuple[float, float]) -> np.ndarray:
    """Machine position of fabric points (front-side coordinates) with the frame back up, rotated by
    ``r`` degrees about the frame centre and shifted by ``offset`` (sim/frame.py's model)."""
    c = np.asarray(frame.center, dtype=float)
    i = 0 if frame.flip_axis == "y" else 1   # flipping about the y axis negates x
    out = []
    for q in np.asarray(fabric, dtype=float):
        m = q.copy()
        m[i] = 2.0 * c[i] - m[i]
        out.append(rot(r) @ (m - c) + c + np.asarray(offset))
    return np.array(out)


def grid(frame: FrameSpec, n: int = 7) -> np.ndarray:
    x0, y0, x1, y1 = frame.bounds
    gx, gy = np.meshgrid(np.linspace(x0, x1, n), np.linspace(y0, y1, n))
    return np.column_stack([gx.ravel(), gy.ravel()])


# ---------------------------------------------------------------------------------------------
# exact motions are recovered


@pytest.mark.parametrize("k", [3, 4, 5])
@pytest.mark.parametrize("deg", [0.0, 0.8, -1.7, 25.0, 90.0, -170.0])
def test_a_known_rotation_about_the_centroid_is_recovered(k: int, deg: float) -> None:
    expected = MARKS[:k]
    centroid = expected.mean(axis=0)
    measured = moved(expected, deg, tuple(centroid), (1.25, -0.75))
    fit = fit_rigid(expected, measured)
    assert fit.rotation_deg == pytest.approx(deg, abs=1e-10)
    assert fit.center == pytest.approx(tuple(centroid), abs=1e-12)
    assert fit.offset == pytest.approx((1.25, -0.75), abs=1e-9)
    assert np.abs(fit.correction().apply(expected) - measured).max() < 1e-9
    assert fit.max_residual < 1e-9 and fit.rms < 1e-9
    assert fit.residuals.shape == (k,)


@pytest.mark.parametrize("about", [(0.0, 0.0), (110.0, 110.0), (-40.0, 300.0)])
@pytest.mark.parametrize("deg", [1.3, -0.6, 12.0])
def test_a_rotation_about_another_point_is_the_same_physical_motion(about: tuple[float, float],
                                                                    deg: float) -> None:
    expected = MARKS[:4]
    measured = moved(expected, deg, about, (-2.0, 3.5))
    fit = fit_rigid(expected, measured)
    corr = fit.correction()
    assert fit.rotation_deg == pytest.approx(deg, abs=1e-10)
    assert np.abs(corr.apply(expected) - measured).max() < 1e-9
    # every point of the frame, not just the marks, goes where the true motion takes it
    pts = grid(FRAME)
    assert np.abs(corr.apply(pts) - moved(pts, deg, about, (-2.0, 3.5))).max() < 1e-9


def test_confirmed_marks_give_the_identity() -> None:
    fit = fit_rigid(MARKS, MARKS + np.zeros_like(MARKS))   # every jog (0, 0)
    assert fit.rotation_deg == 0.0
    assert fit.offset == pytest.approx((0.0, 0.0), abs=1e-12)
    assert np.abs(fit.correction().apply(grid(FRAME)) - grid(FRAME)).max() < 1e-12
    check_fit(fit, max_residual=0.0, max_rotation_deg=0.0, max_offset=1e-12)


def test_measured_is_expected_plus_the_jogs() -> None:
    expected = MARKS[:4]
    truth = moved(expected, 0.4, (110.0, 110.0), (0.3, 0.2))
    jogs = truth - expected
    fit = fit_rigid(expected, expected + jogs)
    assert np.abs(fit.correction().apply(expected) - truth).max() < 1e-9


def test_a_reflection_is_not_fitted() -> None:
    """Mirrored marks (the frame laid down the wrong way round) are not a rigid motion: the fit stays
    a rotation and the residuals show it."""
    expected = MARKS[:4]
    c = expected.mean(axis=0)
    measured = expected.copy()
    measured[:, 0] = 2 * c[0] - measured[:, 0]
    fit = fit_rigid(expected, measured)
    assert fit.max_residual > 10.0
    with pytest.raises(AlignmentRefused) as e:
        check_fit(fit, **LOOSE)
    assert e.value.which == "residual"


# ---------------------------------------------------------------------------------------------
# noise and misread marks


def test_noise_gives_residuals_of_its_order() -> None:
    rng = np.random.default_rng(7)
    expected = MARKS
    truth = moved(expected, 0.9, (110.0, 110.0), (1.0, -0.5))
    noise = rng.uniform(-0.05, 0.05, size=truth.shape)
    fit = fit_rigid(expected, truth + noise)
    # the least-squares fit is no worse than the true motion: rms ≤ rms of the noise ≤ 0.05·√2
    assert fit.rms <= math.sqrt(np.mean(np.sum(noise**2, axis=1))) + 1e-12
    assert 0.005 < fit.max_residual < 0.15
    # the marks are ~150 mm apart: 0.05 mm of noise turns the fit by a few hundredths of a degree
    assert fit.rotation_deg == pytest.approx(0.9, abs=0.05)
    pts = grid(FRAME)
    assert np.abs(fit.correction().apply(pts) - moved(pts, 0.9, (110.0, 110.0), (1.0, -0.5))).max() < 0.15
    check_fit(fit, **LOOSE)


@pytest.mark.parametrize("bad", range(5))
@pytest.mark.parametrize("direction", [(1.0, 0.0), (0.0, -1.0), (-0.6, 0.8)])
def test_one_mark_off_by_1_mm_is_refused_and_named(bad: int, direction: tuple[float, float]) -> None:
    expected = MARKS
    measured = moved(expected, 0.5, (110.0, 110.0), (0.4, 0.1))
    measured[bad] += np.asarray(direction)
    fit = fit_rigid(expected, measured)
    assert int(np.argmax(fit.residuals)) == bad
    with pytest.raises(AlignmentRefused) as e:
        check_fit(fit, **LOOSE)
    err = e.value
    assert isinstance(err, ValueError)
    assert err.which == "residual"
    assert err.mark == bad + 1                                  # numbered from 1, as people read it
    assert err.limit == 0.3
    assert 0.5 < err.value <= 1.0
    assert err.value == pytest.approx(fit.max_residual)
    msg = str(err)
    assert f"mark {bad + 1} " in msg and f"{err.value:.2f} mm" in msg and "0.30 mm" in msg


def test_two_marks_at_the_right_distance_fit_exactly() -> None:
    expected = MARKS[:2]
    measured = moved(expected, -1.1, (0.0, 0.0), (2.0, 1.0))
    fit = fit_rigid(expected, measured)
    assert fit.rotation_deg == pytest.approx(-1.1, abs=1e-10)
    assert np.abs(fit.correction().apply(expected) - measured).max() < 1e-9
    assert fit.max_residual < 1e-9
    check_fit(fit, max_residual=0.3, max_rotation_deg=2.0, max_offset=10.0)


def test_two_marks_compare_their_distance() -> None:
    """With 2 marks the residual is the difference between the measured and the expected distance."""
    expected = MARKS[:2]
    d = expected[1] - expected[0]
    u = d / np.linalg.norm(d)
    measured = expected.copy()
    measured[1] += 0.5 * u                                      # 0.5 mm further apart
    fit = fit_rigid(expected, measured)
    assert fit.residuals == pytest.approx([0.5, 0.5], abs=1e-9)
    assert fit.rms == pytest.approx(0.5, abs=1e-9)
    with pytest.raises(AlignmentRefused) as e:
        check_fit(fit, **LOOSE)
    assert e.value.which == "residual" and e.value.mark is None
    assert e.value.value == pytest.approx(0.5)
    assert "0.50 mm" in str(e.value) and "0.30 mm" in str(e.value)
    # a mark off across the line between them is indistinguishable from a rotation
    sideways = expected.copy()
    sideways[1] += 0.5 * np.array([-u[1], u[0]])
    fit = fit_rigid(expected, sideways)
    assert fit.max_residual < 1e-3
    assert fit.rotation_deg != 0.0


# ---------------------------------------------------------------------------------------------
# a frame turned or shifted too far


@pytest.mark.parametrize("deg", [3.2, -3.2])
def test_a_rotation_beyond_the_limit_is_refused(deg: float) -> None:
    expected = MARKS[:4]
    fit = fit_rigid(expected, moved(expected, deg, (110.0, 110.0), (0.0, 0.0)))
    with pytest.raises(AlignmentRefused) as e:
        check_fit(fit, max_residual=0.3, max_rotation_deg=2.0, max_offset=50.0)
    err = e.value
    assert err.which == "rotation"
    assert err.value == pytest.approx(3.2, abs=1e-9)
    assert err.limit == 2.0
    assert "3.20°" in str(err) and "2.00°" in str(err)
    assert ("counter-clockwise" in str(err)) == (deg > 0)


def test_a_rotation_within_the_limit_passes() -> None:
    expected = MARKS[:4]
    fit = fit_rigid(expected, moved(expected, 1.9, (110.0, 110.0), (0.0, 0.0)))
    check_fit(fit, max_residual=0.3, max_rotation_deg=2.0, max_offset=50.0)


def test_an_offset_beyond_the_limit_is_refused() -> None:
    expected = MARKS[:4]
    fit = fit_rigid(expected, expected + np.array([6.0, 8.0]))
    with pytest.raises(AlignmentRefused) as e:
        check_fit(fit, **LOOSE)
    err = e.value
    assert err.which == "offset"
    assert err.value == pytest.approx(10.0, abs=1e-9)
    assert err.limit == 5.0
    assert "10.00 mm" in str(err) and "5.00 mm" in str(err)
    check_fit(fit, max_residual=0.3, max_rotation_deg=2.0, max_offset=10.0 + 1e-9)


def test_the_offset_is_the_largest_displacement_of_a_mark() -> None:
    """A small rotation about the centroid moves no mark's centroid but the far marks by r·θ."""
    expected = MARKS[:4]
    c = expected.mean(axis=0)
    fit = fit_rigid(expected, moved(expected, 1.0, tuple(c), (0.0, 0.0)))
    radius = np.linalg.norm(expected - c, axis=1)
    far = int(np.argmax(radius))
    chord = 2 * radius[far] * math.sin(math.radians(1.0) / 2)
    assert chord > 1.0
    with pytest.raises(AlignmentRefused) as e:
        check_fit(fit, max_residual=0.3, max_rotation_deg=2.0, max_offset=1.0)
    assert e.value.which == "offset"
    assert e.value.mark == far + 1
    assert e.value.value == pytest.approx(chord, abs=1e-9)


def test_the_residual_is_checked_before_the_rotation_and_the_offset() -> None:
    expected = MARKS[:4]
    measured = moved(expected, 5.0, (110.0, 110.0), (20.0, 0.0))
    measured[3] += [2.0, 0.0]
    with pytest.raises(AlignmentRefused) as e:
        check_fit(fit_rigid(expected, measured), **LOOSE)
    assert e.value.which == "residual"


def test_a_fit_built_by_hand_checks_the_offset_at_its_centre() -> None:
    fit = AlignmentFit(rotation_deg=0.0, center=(110.0, 110.0), offset=(3.0, 4.0), residuals=np.zeros(3))
    with pytest.raises(AlignmentRefused) as e:
        check_fit(fit, max_residual=0.3, max_rotation_deg=2.0, max_offset=4.0)
    assert e.value.which == "offset" and e.value.value == pytest.approx(5.0)


@pytest.mark.parametrize("limits", [dict(max_residual=-0.1, max_rotation_deg=2.0, max_offset=5.0),
                                    dict(max_residual=0.3, max_rotation_deg=float("nan"), max_offset=5.0)])
def test_bad_limits_are_rejected(limits: dict[str, float]) -> None:
    fit = fit_rigid(MARKS, MARKS)
    with pytest.raises(ValueError) as e:
        check_fit(fit, **limits)
    assert not isinstance(e.value, AlignmentRefused)


# ---------------------------------------------------------------------------------------------
# the simulator's flip model


@pytest.mark.parametrize("axis", ["y", "x"])
@pytest.mark.parametrize(("r", "offset"), [(0.0, (0.0, 0.0)), (0.7, (1.2, -0.8)), (-1.3, (-2.5, 0.4)),
                                           (0.25, (0.0, 3.0))])
def test_the_correction_puts_the_back_program_where_the_simulated_fabric_is(
        axis: str, r: float, offset: tuple[float, float]) -> None:
    frame = FrameSpec(center=(110.0, 95.0), size=(180.0, 160.0), flip_axis=axis)
    design_marks = [(35.0, 30.0), (180.0, 40.0), (170.0, 165.0), (50.0, 150.0)]   # front-side coordinates

    expected = expected_marks(design_marks, frame)
    c = np.asarray(frame.center)
    i = 0 if axis == "y" else 1
    mirrored = np.array(design_marks, dtype=float)
    mirrored[:, i] = 2 * c[i] - mirrored[:, i]
    assert np.array_equal(expected, mirrored)

    measured = sim_machine(np.array(design_marks), frame, r, offset)   # where the head finds the marks
    fit = fit_rigid(expected, measured)
    assert fit.max_residual < 1e-9
    assert fit.rotation_deg == pytest.approx(r, abs=1e-10)
    corr = fit.correction()

    # every back-side program point p goes to where that fabric point lies: Rot_c(r)·p + offset
    p = grid(frame)
    assert np.abs(corr.apply(p) - moved(p, r, tuple(c), offset)).max() < 1e-9
    # the same, from the fabric's side: a front-side point q is printed at mirror(q) on the back
    q = grid(frame)
    back = q.copy()
    back[:, i] = 2 * c[i] - back[:, i]
    assert np.abs(corr.apply(back) - sim_machine(q, frame, r, offset)).max() < 1e-9
    check_fit(fit, max_residual=0.3, max_rotation_deg=2.0, max_offset=5.0)


def test_expected_marks_of_no_marks_is_empty() -> None:
    assert expected_marks([], FRAME).shape == (0, 2)


# ---------------------------------------------------------------------------------------------
# errors


def test_one_mark_is_not_enough() -> None:
    with pytest.raises(ValueError, match="at least 2"):
        fit_rigid(MARKS[:1], MARKS[:1] + 1.0)
    with pytest.raises(ValueError, match="at least 2"):
        fit_rigid(np.zeros((0, 2)), np.zeros((0, 2)))


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), -float("inf")])
@pytest.mark.parametrize("where", ["expected", "measured"])
def test_non_finite_values_are_rejected(bad: float, where: str) -> None:
    expected, measured = MARKS[:3].copy(), MARKS[:3].copy()
    (expected if where == "expected" else measured)[1, 0] = bad
    with pytest.raises(ValueError, match="not finite"):
        fit_rigid(expected, measured)


def test_mismatched_shapes_are_rejected() -> None:
    with pytest.raises(ValueError, match="3 expected marks but 4 measured"):
        fit_rigid(MARKS[:3], MARKS[:4])
    with pytest.raises(ValueError, match=r"\(k, 2\)"):
        fit_rigid(np.zeros((3, 3)), np.zeros((3, 3)))
    with pytest.raises(ValueError, match=r"\(k, 2\)"):
        fit_rigid(MARKS[:3].ravel(), MARKS[:3].ravel())


def test_duplicate_expected_marks_are_rejected() -> None:
    expected = np.array([[30.0, 25.0], [185.0, 32.0], [30.0, 25.0]])
    with pytest.raises(ValueError, match="marks 1 and 3 are at the same place"):
        fit_rigid(expected, expected + 0.1)
    with pytest.raises(ValueError, match="same place"):
        fit_rigid(np.array([[5.0, 5.0], [5.0, 5.0]]), np.array([[5.0, 5.0], [6.0, 5.0]]))


def test_the_fit_cannot_be_altered() -> None:
    fit = fit_rigid(MARKS, MARKS)
    with pytest.raises(ValueError):
        fit.residuals[0] = 1.0
    with pytest.raises(AttributeError):
        fit.rotation_deg = 1.0  # type: ignore[misc]


@pytest.mark.parametrize("bad", [0, 1, 2])
def test_the_misread_mark_is_the_one_whose_leaving_out_fits_the_others(bad: int) -> None:
    # three marks as a refined 70 mm saddle places them; one measured 10 mm off in x and y: the
    # least-squares fit of all three shares that error, and its largest residual can sit on a good
    # mark (for mark 1 here it sat on mark 3), so the refusal names the mark whose leaving out fits
    expected = np.array([[81.1, 80.9], [144.3, 90.7], [92.7, 144.5]])
    measured = expected.copy()
    measured[bad] += (10.0, 10.0)
    with pytest.raises(AlignmentRefused) as err:
        check_fit(fit_rigid(expected, measured), max_residual=0.3, max_rotation_deg=5.0, max_offset=10.0)
    assert err.value.mark == bad + 1 and f"mark {bad + 1} is" in str(err.value)
