"""Ribbon thickness from measured curvature tables (§5).

A curvature table gives, for each side of the fabric, the curvature κ1 (1/mm) that a regular
ribbon pattern rolls into as a function of the plastic thickness τ (mm, rows) and the transverse
spacing μ2 (mm, columns). κ1 increases with τ at every μ2, so for a ribbon's target |κ1| and
spacing μ2 the thickness is found by inverse interpolation: each τ-row is interpolated linearly in
μ2 at the ribbon's μ2, giving κ(τ_i) for every tabulated τ_i, and that monotonic κ(τ) is inverted
piecewise-linearly at |κ1|. Ribbons with κ1 > 0 are printed on the stitch front, the others
(κ1 ≤ 0) on the stitch back (§6.2), so the sign of κ1 picks the table.

The tables shipped with ribbond live in ``ribbond/design/tables/``; a user's own table is a TOML
file of the same shape, given by path.
"""

from __future__ import annotations

import re

from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator

from ..datafiles import load_toml_model, shipped_names

TABLE_DIR = Path(__file__).with_name("tables")

_Positive = Annotated[float, Field(gt=0)]
_SIDES = ("front", "back")


class CurvatureTable(BaseModel):
    """Curvature κ1 of a regular ribbon pattern per side of the fabric, against τ and μ2 (§5).

    Attributes
    ----------
    name : the table's name (a shipped table's file stem).
    description : free text: what it is, how it was obtained.
    material, fabric : the plastic (e.g. ``"TPU 95A"``) and the fabric it was printed on.
    prestretch : the pre-stretch s at which it was measured, > 1.
    thickness : (T,) plastic thickness τ, mm, strictly increasing, > 0, T ≥ 2.
    spacing : (S,) transverse spacing μ2, mm, strictly increasing, > 0, S ≥ 2.
    front, back : (T, S) curvature κ1, 1/mm, > 0, of ribbons printed on the stitch front and
        back; every column (fixed μ2) strictly increasing in τ.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    name: str = Field(min_length=1)
    description: str = ""
    material: str = ""
    fabric: str = ""
    prestretch: float = Field(gt=1.0, description="fabric pre-stretch s of the measurements")
    thickness: list[_Positive] = Field(min_length=2, description="τ values (rows), mm")
    spacing: list[_Positive] = Field(min_length=2, description="μ2 values (columns), mm")
    front: list[list[_Positive]] = Field(description="κ1 on the stitch front, 1/mm, (τ, μ2)")
    back: list[list[_Positive]] = Field(description="κ1 on the stitch back, 1/mm, (τ, μ2)")

    @field_validator("thickness", "spacing")
    @classmethod
    def _increasing(cls, values: list[float], info: ValidationInfo) -> list[float]:
        for a, b in zip(values, values[1:]):
            if not b > a:
                raise ValueError(f"{info.field_name} must be strictly increasing; {a} is followed by {b}")
        return values

    @field_validator("front", "back")
    @classmethod
    def _grid(cls, values: list[list[float]], info: ValidationInfo) -> list[list[float]]:
        side = info.field_name
        tau, mu = info.data.get("thickness"), info.data.get("spacing")
        if tau is None or mu is None:      # already refused: their own errors say why
            return values
        if len(values) != len(tau):
            raise ValueError(f"{side} has {len(values)} rows, one per thickness is needed ({len(tau)})")
        for i, row in enumerate(values):
            if len(row) != len(mu):
                raise ValueError(f"{side} row {i} (τ = {tau[i]} mm) has {len(row)} values, "
                                 f"one per spacing is needed ({len(mu)})")
        k = np.asarray(values, dtype=np.float64)                    # (T, S)
        bad = np.argwhere(np.diff(k, axis=0) <= 0)                  # (i, j): κ[i+1, j] ≤ κ[i, j]
        if len(bad):
            i, j = (int(v) for v in bad[0])
            raise ValueError(
                f"{side}: at μ2 = {mu[j]} mm, κ1 must increase strictly with τ (the thickness is "
                f"found by inverting it), but κ1 = {k[i, j]} at τ = {tau[i]} mm and {k[i + 1, j]} at "
                f"τ = {tau[i + 1]} mm")
        return values

    def grid(self, side: Literal["front", "back"]) -> np.ndarray:
        """(T, S) curvature κ1 of one side, 1/mm, as an array."""
        if side not in _SIDES:
            raise ValueError(f"side must be 'front' or 'back', not {side!r}")
        return np.asarray(self.front if side == "front" else self.back, dtype=np.float64)


def available_tables() -> list[str]:
    """Names of the curvature tables shipped with ribbond."""
    return shipped_names(TABLE_DIR)


#: A table's name: what ``ribbonctl tables add`` accepts and a daemon's design may name (no path).
TABLE_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_-]{0,63}$")


def load_curvature_table(name_or_path: str | Path, tables_dir: Path | None = None) -> CurvatureTable:
    """A curvature table by name (``tables_dir/NAME.toml`` first, when given: the daemon's own
    tables; else a shipped one), or a table file by path (a ``.toml`` file).

    Raises
    ------
    ValueError
        naming the table file and what is wrong with it (the field path for invalid values).
    """
    if tables_dir is not None and TABLE_NAME.match(str(name_or_path)):
        own = Path(tables_dir) / f"{name_or_path}.toml"
        if own.is_file():
            return load_toml_model(own, TABLE_DIR, CurvatureTable, "curvature table")
    return load_toml_model(name_or_path, TABLE_DIR, CurvatureTable, "curvature table")


@dataclass(frozen=True)
class ThicknessResult:
    """The thickness of each ribbon.

    Attributes
    ----------
    thickness : (R,) float, plastic thickness τ, mm, within the table's range.
    clamped : (R,) bool, the ribbon's μ2 or |κ1| was outside the table's range, so its τ was
        taken at the nearest edge of the table.
    target : (R,) float, the |κ1| asked for, 1/mm.
    spacing_out : (R,) bool, μ2 outside the table's spacings (clamped whatever the size).
    reachable : (R, 2) float, [κ(τ_min), κ(τ_max)] of the ribbon's side at its μ2 (clamped to the
        table's spacings), 1/mm: the curvatures the table can give there.
    """

    thickness: np.ndarray
    clamped: np.ndarray
    target: np.ndarray
    spacing_out: np.ndarray
    reachable: np.ndarray

    @property
    def clamped_count(self) -> int:
        """How many ribbons were clamped."""
        return int(np.count_nonzero(self.clamped))

    @property
    def too_flat(self) -> np.ndarray:
        """(R,) bool: |κ1| below what the thinnest plastic curls (the ribbon curves too much)."""
        return self.target < self.reachable[:, 0]

    @property
    def too_curved(self) -> np.ndarray:
        """(R,) bool: |κ1| above what the thickest plastic curls (the ribbon curves too little)."""
        return self.target > self.reachable[:, 1]


def _vector(values: np.ndarray, what: str) -> np.ndarray:
    """``values`` as a (R,) float64 array; ValueError naming ``what`` otherwise."""
    a = np.asarray(values, dtype=np.float64)
    if a.ndim != 1:
        raise ValueError(f"{what} must be a 1-D array, got shape {a.shape}")
    return a


def _cells(grid: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cell index i (R,) and weight w (R,) in [0, 1] of x (already within the grid) on ``grid`` (N,)."""
    i = np.clip(np.searchsorted(grid, x, side="right") - 1, 0, len(grid) - 2)
    w = (x - grid[i]) / (grid[i + 1] - grid[i])
    return i, np.clip(w, 0.0, 1.0)


def ribbon_thickness(table: CurvatureTable, kappa1: np.ndarray, mu2: np.ndarray) -> ThicknessResult:
    """Thickness τ of each ribbon from its target curvature and spacing, by inverse interpolation.

    The front table is used where κ1 > 0, the back table where κ1 ≤ 0, at |κ1|. μ2 outside the
    table's spacing range is clamped to it; |κ1| below κ(τ_min) gives τ_min and above κ(τ_max)
    gives τ_max. Either makes the ribbon ``clamped``.

    Parameters
    ----------
    table : the curvature table.
    kappa1 : (R,) signed target curvature along the ribbons, 1/mm, finite.
    mu2 : (R,) spacing across the ribbons, mm, finite and > 0.

    Returns
    -------
    ThicknessResult with thickness (R,) in mm and clamped (R,) bool.

    Raises
    ------
    ValueError
        if the arrays are not 1-D of one length, or a value is not finite (or μ2 ≤ 0), naming the
        first bad index.
    """
    k = _vector(kappa1, "kappa1")
    mu = _vector(mu2, "mu2")
    if k.shape != mu.shape:
        raise ValueError(f"kappa1 and mu2 must have the same length, got {len(k)} and {len(mu)}")
    bad = np.flatnonzero(~np.isfinite(k))
    if len(bad):
        raise ValueError(f"kappa1[{bad[0]}] = {k[bad[0]]} is not finite ({len(bad)} such ribbons)")
    bad = np.flatnonzero(~(np.isfinite(mu) & (mu > 0)))
    if len(bad):
        raise ValueError(f"mu2[{bad[0]}] = {mu[bad[0]]} must be finite and > 0 ({len(bad)} such ribbons)")

    tau = np.asarray(table.thickness, dtype=np.float64)              # (T,)
    spacing = np.asarray(table.spacing, dtype=np.float64)            # (S,)
    grids = np.stack([table.grid("front"), table.grid("back")])       # (2, T, S)
    side = np.where(k > 0, 0, 1)                                      # (R,) 0 front, 1 back
    target = np.abs(k)

    mu_in = np.clip(mu, spacing[0], spacing[-1])
    j, w = _cells(spacing, mu_in)                                     # (R,)
    rows = np.arange(len(tau))[None, :]                               # (1, T)
    lo = grids[side[:, None], rows, j[:, None]]                       # (R, T) κ(τ_i) at μ2 = spacing[j]
    hi = grids[side[:, None], rows, j[:, None] + 1]                   # (R, T) at spacing[j + 1]
    curve = (1.0 - w)[:, None] * lo + w[:, None] * hi                 # (R, T) κ(τ_i) at μ2, increasing

    # Piecewise-linear inverse of the increasing κ(τ_i) at the target: the segment [i, i + 1].
    i = np.clip(np.count_nonzero(curve <= target[:, None], axis=1) - 1, 0, len(tau) - 2)
    r = np.arange(len(k))
    k0, k1 = curve[r, i], curve[r, i + 1]
    t = np.clip((target - k0) / (k1 - k0), 0.0, 1.0)
    thickness = tau[i] + t * (tau[i + 1] - tau[i])

    spacing_out = (mu < spacing[0]) | (mu > spacing[-1])
    clamped = spacing_out | (target < curve[:, 0]) | (target > curve[:, -1])
    return ThicknessResult(thickness=thickness, clamped=clamped, target=target, spacing_out=spacing_out,
                           reachable=np.column_stack([curve[:, 0], curve[:, -1]]))


def fitting_scale(result: ThicknessResult) -> tuple[float, int]:
    """The size at which the fewest ribbon thicknesses clamp (issue 34: "a smaller surface" is not always
    better).

    The target scaled by λ keeps its flattening (σ, so μ2 of Eq. 10) and divides κ1 by λ: ribbon i is
    within the table for λ ∈ [|κ1_i| / κ(τ_max), |κ1_i| / κ(τ_min)] (none where κ1 = 0 or μ2 is outside
    the table). The λ covered by the most intervals, the closest to 1 (in ratio) among ties.

    Returns
    -------
    (scale, clamped): λ (1.0 when no ribbon can fit at any size) and how many ribbons clamp at it.
    """
    k, reach = result.target, result.reachable
    ok = (k > 0) & ~result.spacing_out
    if not ok.any():
        return 1.0, len(k)
    x = np.concatenate([k[ok] / reach[ok, 1], k[ok] / reach[ok, 0]])
    step = np.concatenate([np.ones(ok.sum()), -np.ones(ok.sum())])
    order = np.lexsort((-step, x))                      # at a tie an interval opens before one closes
    x, cover = x[order], np.cumsum(step[order])
    best = np.flatnonzero(cover == cover.max())         # the segments [x_i, x_i+1] covered the most
    scale = np.clip(1.0, x[best], x[np.minimum(best + 1, len(x) - 1)])
    return float(scale[np.argmin(np.abs(np.log(scale)))]), int(len(k) - cover.max())


#: A face counts as within the table when its curvature is this far inside the table's range (relative):
#: a ribbon's κ1 and μ2 are averages along it, not the face's.
TABLE_MARGIN = 0.03
#: The largest size kept may cover this share of the area less than the best size at most the frame's.
TABLE_SLACK = 0.02


def largest_table_scale(table: CurvatureTable, kappa1: np.ndarray, mu2: np.ndarray, weight: np.ndarray,
                        at_most: float) -> float:
    """The largest size factor λ ≤ ``at_most`` at which the curvature table reaches the target's
    curvature on (almost) as much of the surface as at any size up to it.

    Scaling the target by λ keeps its flattening (σ, so μ2 of Eq. 10) and divides κ1 by λ: a face is
    within the table for λ ∈ [|κ1| (1 + m) / κ(τ_max, μ2), |κ1| / (κ(τ_min, μ2) (1 + m))], m =
    ``TABLE_MARGIN``, on the side the sign of κ1 picks (none where κ1 = 0 or μ2 is outside the table).
    Of the λ ≤ ``at_most`` whose covered weight is within ``TABLE_SLACK`` of the most, the largest.

    Parameters
    ----------
    table : the curvature table.
    kappa1 : (m,) signed curvature along the ribbon direction per face at the current size, 1/mm.
    mu2 : (m,) Eq. 10's spacing across the ribbons per face, mm (size-independent).
    weight : (m,) face weights (areas), ≥ 0.
    at_most : the largest factor allowed (the frame's), > 0.

    Returns
    -------
    λ, in (0, at_most]; ``at_most`` when no face can be within the table at any size.
    """
    k, mu, w = (np.asarray(a, dtype=np.float64) for a in (kappa1, mu2, weight))
    if not (k.shape == mu.shape == w.shape and k.ndim == 1):
        raise ValueError(f"kappa1, mu2 and weight must be 1-D of one length, got {k.shape}, {mu.shape}, {w.shape}")
    if not (at_most > 0 and np.isfinite(at_most)):
        raise ValueError(f"at_most = {at_most} must be finite and > 0")
    tau, spacing = np.asarray(table.thickness), np.asarray(table.spacing)
    inside = np.isfinite(k) & (k != 0) & (mu >= spacing[0]) & (mu <= spacing[-1]) & (w > 0)
    if not inside.any():
        return float(at_most)
    front = k[inside] > 0
    k, mu, w = np.abs(k[inside]), mu[inside], w[inside]
    reach = np.stack([np.where(front, table_curvature(table, "front", np.full(len(k), t), mu),
                               table_curvature(table, "back", np.full(len(k), t), mu)) for t in (tau[0], tau[-1])])
    lo = k * (1 + TABLE_MARGIN) / reach.max(axis=0)
    hi = k / (reach.min(axis=0) * (1 + TABLE_MARGIN))
    x = np.concatenate([lo, hi])
    step = np.concatenate([w, -w])
    order = np.lexsort((-step, x))                       # at a tie an interval opens before one closes
    x, cover = x[order], np.cumsum(step[order])          # cover on [x_i, x_i+1)
    end = np.append(x[1:], np.inf)
    usable = (x < at_most) & (end > x)
    if not usable.any():
        return float(at_most)
    best = cover[usable].max()
    good = np.flatnonzero(usable & (cover >= best - TABLE_SLACK * w.sum()))
    return float(min(end[good[-1]], at_most))


def table_curvature(table: CurvatureTable, side: Literal["front", "back"],
                    thickness: np.ndarray, mu2: np.ndarray) -> np.ndarray:
    """Forward bilinear interpolation of the table: the curvature κ(τ, μ2) of one side.

    τ and μ2 outside the table's ranges are clamped to them.

    Parameters
    ----------
    table : the curvature table.
    side : ``"front"`` or ``"back"``.
    thickness : (R,) plastic thickness τ, mm, finite.
    mu2 : (R,) spacing across the ribbons, mm, finite.

    Returns
    -------
    (R,) curvature κ1, 1/mm (positive).

    Raises
    ------
    ValueError
        for an unknown side, arrays that are not 1-D of one length, or a value that is not finite.
    """
    grid = table.grid(side)                                           # (T, S)
    tau = _vector(thickness, "thickness")
    mu = _vector(mu2, "mu2")
    if tau.shape != mu.shape:
        raise ValueError(f"thickness and mu2 must have the same length, got {len(tau)} and {len(mu)}")
    for name, a in (("thickness", tau), ("mu2", mu)):
        bad = np.flatnonzero(~np.isfinite(a))
        if len(bad):
            raise ValueError(f"{name}[{bad[0]}] = {a[bad[0]]} is not finite")
    tt = np.asarray(table.thickness, dtype=np.float64)
    ss = np.asarray(table.spacing, dtype=np.float64)
    i, u = _cells(tt, np.clip(tau, tt[0], tt[-1]))
    j, v = _cells(ss, np.clip(mu, ss[0], ss[-1]))
    return ((1 - u) * (1 - v) * grid[i, j] + (1 - u) * v * grid[i, j + 1]
            + u * (1 - v) * grid[i + 1, j] + u * v * grid[i + 1, j + 1])
