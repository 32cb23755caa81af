"""Registration of the back side: fit the flipped frame's misalignment from the registration marks.

After the flip the head goes above where each registration mark should now be: the design's marks
(front-side print coordinates) mirrored about the flip axis into back-side print coordinates
(``expected_marks``). The operator confirms a mark (jog (0, 0)) or reports the jog (dx, dy) that put
the head exactly over it; the measured position is expected + jog. ``fit_rigid`` fits the rigid
motion (rotation and translation: no scale, no reflection) that best maps the expected marks onto
the measured ones in the least-squares sense (2-D Kabsch/Procrustes, closed form), ``check_fit``
refuses a fit whose marks do not agree with a rigid motion or whose frame is turned or shifted too
far, and ``AlignmentFit.correction()`` is the ``Correction`` the back program is rendered with: it
maps back-side program coordinates onto where the fabric actually is.

Marks are numbered from 1 in everything a person reads (messages, ``AlignmentRefused.mark``): mark
i is row i - 1 of the arrays given (``design.registration_marks[i - 1]``, the programs'
``;TYPE:REGISTRATION i-1`` comment).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from .profiles import FrameSpec
from .program import Correction, mirror

__all__ = ["AlignmentFit", "AlignmentRefused", "check_fit", "expected_marks", "fit_rigid"]

#: Expected marks closer than this (mm) are one mark given twice: the rotation about them is unknown.
COINCIDENT = 1e-6


def _points(xy: object, what: str) -> np.ndarray:
    a = np.asarray(xy, dtype=float)
    if a.ndim != 2 or a.shape[1] != 2:
        raise ValueError(f"{what} must be (k, 2) points, got an array of shape {a.shape}")
    if not np.all(np.isfinite(a)):
        bad = int(np.flatnonzero(~np.all(np.isfinite(a), axis=1))[0])
        raise ValueError(f"{what}: mark {bad + 1} is not finite: {tuple(a[bad])}")
    return a


@dataclass(frozen=True, eq=False)
class AlignmentFit:
    """The rigid motion that maps the expected marks onto the measured ones.

    measured ≈ R(rotation_deg)·(expected − center) + center + offset.

    Attributes
    ----------
    rotation_deg : counter-clockwise, degrees, in (−180, 180].
    center : the point the rotation is about: the centroid of the expected marks.
    offset : the translation after the rotation (the centroid's displacement), mm.
    residuals : (k,) distance of each measured mark from the fitted image of its expected
        position, mm. With exactly 2 marks any rigid motion of the right length fits them, so the
        least-squares residuals say little; there, both residuals are instead the difference
        between the measured and the expected distance of the two marks (the only thing two marks
        can show to be wrong: a mark off across the line between them is taken for a rotation).
    expected, measured : (k, 2) the marks the fit was made from (back-side print coordinates);
        ``check_fit`` uses ``expected`` for the marks' displacements (empty: the centre's alone).
    """

    rotation_deg: float
    center: tuple[float, float]
    offset: tuple[float, float]
    residuals: np.ndarray
    expected: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    measured: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))

    @property
    def rms(self) -> float:
        """Root mean square of the residuals, mm."""
        r = np.asarray(self.residuals, dtype=float)
        return float(np.sqrt(np.mean(r**2))) if r.size else 0.0

    @property
    def max_residual(self) -> float:
        """The largest residual, mm."""
        r = np.asarray(self.residuals, dtype=float)
        return float(r.max()) if r.size else 0.0

    def correction(self) -> Correction:
        """The back side's correction: ``correction().apply(expected) ≈ measured``."""
        return Correction(rotation_deg=self.rotation_deg, center=self.center, offset=self.offset)

    def displacements(self) -> np.ndarray:
        """(k,) how far the fitted motion moves each expected mark, mm ((1,): the centre's, when
        the fit has no marks)."""
        pts = np.asarray(self.expected, dtype=float).reshape(-1, 2)
        if len(pts) == 0:
            pts = np.asarray([self.center], dtype=float)
        return np.linalg.norm(self.correction().apply(pts) - pts, axis=1)


def expected_marks(design_marks: Sequence[tuple[float, float]], frame: FrameSpec) -> np.ndarray:
    """(k, 2) where the design's registration marks (front-side print coordinates) are expected
    after the flip, in back-side print coordinates (mirrored about the frame's flip axis)."""
    pts = np.asarray(design_marks, dtype=float)
    if pts.size == 0:
        return np.zeros((0, 2))
    return mirror(_points(pts, "registration marks"), frame)


def fit_rigid(expected: np.ndarray, measured: np.ndarray) -> AlignmentFit:
    """Least-squares rigid motion (rotation + translation) mapping ``expected`` onto ``measured``.

    The rotation is about the centroid of the expected marks: with centred points a_i (expected)
    and b_i (measured), θ = atan2(Σ a_i × b_i, Σ a_i · b_i) minimises Σ |R(θ) a_i − b_i|², and the
    offset is the centroids' difference. An angle always gives a proper rotation: no reflection.

    With exactly 2 marks the residuals are the difference between the measured and the expected
    distance of the marks (see ``AlignmentFit.residuals``).

    Raises
    ------
    ValueError
        fewer than 2 marks, arrays not (k, 2) or of different shapes, non-finite values, or two
        expected marks at the same place.
    """
    p = _points(expected, "expected marks")
    q = _points(measured, "measured marks")
    if p.shape != q.shape:
        raise ValueError(f"{len(p)} expected marks but {len(q)} measured ones "
                         f"(shapes {p.shape} and {q.shape})")
    k = len(p)
    if k < 2:
        raise ValueError(f"at least 2 registration marks are needed to fit the frame's rotation, got {k}")
    d = np.linalg.norm(p[:, None, :] - p[None, :, :], axis=2)
    i, j = np.triu_indices(k, 1)
    close = d[i, j] <= COINCIDENT
    if np.any(close):
        a, b = int(i[close][0]), int(j[close][0])
        raise ValueError(f"expected marks {a + 1} and {b + 1} are at the same place {tuple(p[a])}: "
                         "a rotation cannot be fitted to coincident marks")
    cp, cq = p.mean(axis=0), q.mean(axis=0)
    a, b = p - cp, q - cq
    cross = float(np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]))
    dot = float(np.sum(a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1]))
    theta = math.atan2(cross, dot)
    rotation_deg = math.degrees(theta)
    if rotation_deg == -180.0:
        rotation_deg = 180.0
    c, s = math.cos(theta), math.sin(theta)
    R = np.array([[c, -s], [s, c]])
    if k == 2:
        gap = abs(float(np.linalg.norm(q[1] - q[0])) - float(d[0, 1]))
        residuals = np.full(2, gap)
    else:
        residuals = np.linalg.norm(a @ R.T - b, axis=1)
    residuals.setflags(write=False)
    offset = cq - cp
    exp, meas = p.copy(), q.copy()
    exp.setflags(write=False)
    meas.setflags(write=False)
    return AlignmentFit(rotation_deg=rotation_deg, center=(float(cp[0]), float(cp[1])),
                        offset=(float(offset[0]), float(offset[1])), residuals=residuals,
                        expected=exp, measured=meas)


class AlignmentRefused(ValueError):
    """The marks do not allow printing the back side: what is wrong (``which``: "residual",
    "rotation" or "offset"), by how much (``value``), the limit (``limit``) and the mark concerned
    (``mark``, None when no single mark is)."""

    def __init__(self, message: str, *, which: str, value: float, limit: float, mark: int | None = None) -> None:
        super().__init__(message)
        self.which = which
        self.value = value
        self.limit = limit
        self.mark = mark


def _misread_mark(fit: AlignmentFit) -> int:
    """The index of the mark whose leaving out lets the others fit best (smallest largest residual):
    the misread one. (The largest residual of the fit of all the marks can sit on a good mark: the
    least-squares motion shares one mark's error among them all.) Without the marks, or with fewer
    than three, the largest residual's."""
    exp = np.asarray(fit.expected, dtype=float).reshape(-1, 2)
    meas = np.asarray(fit.measured, dtype=float).reshape(-1, 2)
    res = np.asarray(fit.residuals, dtype=float)
    if len(exp) < 3 or len(meas) != len(exp):
        return int(np.argmax(res))
    keep = ~np.eye(len(exp), dtype=bool)                       # a loop over the few marks, not the mesh
    left = [fit_rigid(exp[k], meas[k]).max_residual for k in keep]
    return int(np.argmin(left))


def check_fit(fit: AlignmentFit, *, max_residual: float, max_rotation_deg: float, max_offset: float) -> None:
    """Refuse ``fit`` when it is not good enough to print the back side with.

    In this order (the first failing one is reported): a residual above ``max_residual`` mm (the
    marks do not agree with a rigid motion: a mark was misread or jogged wrong), the rotation's
    magnitude above ``max_rotation_deg`` degrees, the largest displacement of any expected mark
    under the fit above ``max_offset`` mm (the frame sits too far off: seat it again). A value equal
    to its limit passes.

    Raises
    ------
    AlignmentRefused
        naming what failed, by how much and the limit.
    ValueError
        a limit that is negative or NaN.
    """
    for name, lim in (("max_residual", max_residual), ("max_rotation_deg", max_rotation_deg),
                      ("max_offset", max_offset)):
        if not (lim >= 0):
            raise ValueError(f"{name} must be a non-negative number, not {lim}")
    res = np.asarray(fit.residuals, dtype=float)
    if res.size and fit.max_residual > max_residual:
        worst = float(fit.max_residual)
        if res.size == 2:
            exp = np.asarray(fit.expected, dtype=float).reshape(-1, 2)
            meas = np.asarray(fit.measured, dtype=float).reshape(-1, 2)
            if len(exp) == 2 and len(meas) == 2:
                de, dm = float(np.linalg.norm(exp[1] - exp[0])), float(np.linalg.norm(meas[1] - meas[0]))
                detail = f"the two marks are {dm:.2f} mm apart instead of {de:.2f} mm"
            else:
                detail = "the distance between the two marks is wrong"
            raise AlignmentRefused(
                f"the marks do not fit a rigid motion: {detail}, {worst:.2f} mm off (limit "
                f"{max_residual:.2f} mm); re-check both marks",
                which="residual", value=worst, limit=max_residual)
        m = _misread_mark(fit)
        raise AlignmentRefused(
            f"the marks do not fit a rigid motion: mark {m + 1} is {worst:.2f} mm off (limit "
            f"{max_residual:.2f} mm); re-check that mark",
            which="residual", value=worst, limit=max_residual, mark=m + 1)
    turn = abs(fit.rotation_deg)
    if turn > max_rotation_deg:
        sense = "counter-clockwise" if fit.rotation_deg > 0 else "clockwise"
        raise AlignmentRefused(
            f"the frame is turned by {turn:.2f}° {sense} (limit {max_rotation_deg:.2f}°): seat the frame again",
            which="rotation", value=turn, limit=max_rotation_deg)
    disp = fit.displacements()
    shift = float(disp.max())
    if shift > max_offset:
        has_marks = np.asarray(fit.expected).reshape(-1, 2).shape[0] > 0
        m = int(np.argmax(disp)) if has_marks else None
        where = f"at mark {m + 1}" if m is not None else "at the marks' centre"
        raise AlignmentRefused(
            f"the frame is shifted by {shift:.2f} mm {where} (limit {max_offset:.2f} mm): seat the frame again",
            which="offset", value=shift, limit=max_offset, mark=None if m is None else m + 1)
