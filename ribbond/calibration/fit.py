"""Measurements in, a fitted curvature table out (§5, Fig. 6).

Measurements (``measurements.csv``, one coupon a line): ``coupon`` and either ``chord_mm`` and
``sagitta_mm`` of the rolled arc (κ = 8h / (c² + 4h²)), or ``radius_mm`` (κ = 1/r), or neither
(the coupon failed: left out). Per side, each μ2 column is made monotone in τ by isotonic regression
(pool-adjacent-violators, weighted by the number of coupons at each τ), then interpolated onto the
table's τ grid with a monotone cubic (PCHIP); the result must increase strictly in τ (the thickness
is found by inverting it), else it is refused with the column named.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

if TYPE_CHECKING:
    from ..design.thickness import CurvatureTable

#: A fitted column must rise by at least this factor of its mean over its τ range (else: flat).
MIN_RISE = 1e-3
#: Fewest measured thicknesses per column, and measured columns per side.
MIN_POINTS, MIN_COLUMNS = 3, 2


class Measurement(BaseModel):
    """One line of ``measurements.csv``."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    coupon: int = Field(ge=1)
    chord_mm: float | None = Field(None, gt=0, allow_inf_nan=False)
    sagitta_mm: float | None = Field(None, gt=0, allow_inf_nan=False)
    radius_mm: float | None = Field(None, gt=0, allow_inf_nan=False)

    @model_validator(mode="after")
    def _one_way(self) -> "Measurement":
        arc = (self.chord_mm is not None, self.sagitta_mm is not None)
        if any(arc) and not all(arc):
            raise ValueError("give both chord_mm and sagitta_mm (or radius_mm alone)")
        if all(arc) and self.radius_mm is not None:
            raise ValueError("give chord_mm and sagitta_mm, or radius_mm, not both")
        if all(arc) and not 2 * self.sagitta_mm <= self.chord_mm + 1e-12:  # type: ignore[operator]
            # beyond a half circle the chord is no longer the widest span: measure the radius
            raise ValueError(f"sagitta {self.sagitta_mm} mm is more than half the chord {self.chord_mm} mm: "
                             "for a coupon rolled beyond a half circle give radius_mm")
        return self

    @property
    def kappa(self) -> float | None:
        """κ in 1/mm, or None for a failed coupon."""
        if self.radius_mm is not None:
            return 1.0 / self.radius_mm
        if self.chord_mm is not None and self.sagitta_mm is not None:
            c, h = self.chord_mm, self.sagitta_mm
            return 8.0 * h / (c * c + 4.0 * h * h)
        return None


def arc_curvature(chord: np.ndarray, sagitta: np.ndarray) -> np.ndarray:
    """κ = 8h / (c² + 4h²) (1/mm) of circular arcs of chord c (n,) and sagitta h (n,), mm."""
    c, h = np.asarray(chord, dtype=float), np.asarray(sagitta, dtype=float)
    return 8.0 * h / (c * c + 4.0 * h * h)


def parse_measurements(text: str, known: set[int], where: str = "measurements.csv") -> dict[int, float | None]:
    """Coupon number -> κ (1/mm, None: failed) from the CSV text.

    Raises
    ------
    ValueError
        naming the file, the line and the coupon: an unknown column, a value that is not a positive
        number, an incomplete arc, an unknown or repeated coupon.
    """
    reader = csv.DictReader(io.StringIO(text))
    cols = set(reader.fieldnames or [])
    allowed = {"coupon", "chord_mm", "sagitta_mm", "radius_mm"}
    if "coupon" not in cols:
        raise ValueError(f"{where}: no 'coupon' column (columns: coupon, chord_mm, sagitta_mm, radius_mm)")
    extra = cols - allowed - {"side", "thickness_mm", "spacing_mm", "notes"}
    if extra:
        raise ValueError(f"{where}: unknown column(s) {', '.join(sorted(extra))} "
                         "(columns: coupon, chord_mm, sagitta_mm, radius_mm)")
    out: dict[int, float | None] = {}
    for row in reader:
        line = reader.line_num
        raw = {k: (row.get(k) or "").strip() for k in allowed}
        name = raw["coupon"] or "?"
        try:
            m = Measurement(**{k: v for k, v in raw.items() if v != ""})
        except ValidationError as exc:
            msg = "; ".join((f"{'.'.join(map(str, e['loc']))}: " if e["loc"] else "")
                            + e["msg"].removeprefix("Value error, ") for e in exc.errors())
            raise ValueError(f"{where}, line {line}, coupon {name}: {msg}") from None
        if m.coupon not in known:
            raise ValueError(f"{where}, line {line}: coupon {m.coupon} is not in the plan "
                             f"(coupons 1 to {max(known) if known else 0})")
        if m.coupon in out:
            raise ValueError(f"{where}, line {line}: coupon {m.coupon} is measured twice")
        out[m.coupon] = m.kappa
    return out


def pav(y: np.ndarray, w: np.ndarray | None = None) -> np.ndarray:
    """Isotonic (non-decreasing) least-squares fit of ``y`` (n,) with weights ``w`` (n,), by
    pool-adjacent-violators."""
    vals, sizes = pav_blocks(y, w)
    return np.repeat(vals, sizes)


def pav_blocks(y: np.ndarray, w: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The blocks of the isotonic fit of ``y`` (n,): their values (B,), strictly increasing, and their
    sizes (B,), summing to n (pool-adjacent-violators)."""
    y = np.asarray(y, dtype=float)
    w = np.ones_like(y) if w is None else np.asarray(w, dtype=float)
    vals, wts, sizes = [], [], []
    for yi, wi in zip(y, w):
        vals.append(yi)
        wts.append(wi)
        sizes.append(1)
        while len(vals) > 1 and vals[-2] > vals[-1]:
            v1, w1, s1 = vals.pop(), wts.pop(), sizes.pop()
            vals[-1] = (vals[-1] * wts[-1] + v1 * w1) / (wts[-1] + w1)
            wts[-1] += w1
            sizes[-1] += s1
    return np.asarray(vals, dtype=float), np.asarray(sizes, dtype=np.int64)


@dataclass(frozen=True)
class SideFit:
    """One side's fit: ``grid`` (T, S) κ on the table's τ × μ2 grid, per measured point its τ, μ2,
    κ measured and fitted (``points``: (n, 4)), the residuals' RMS and largest, 1/mm (with one coupon
    per (τ, μ2) the fit goes through every point the isotonic step kept, so these show only what it
    pooled), and ``loo_rms``: the RMS of each interior point against the fit of its column without it
    (leave-one-out: the measurement noise plus the interpolation error), 1/mm, NaN when no column has
    an interior point."""

    grid: np.ndarray
    points: np.ndarray
    rms: float
    max_abs: float
    loo_rms: float = float("nan")


def fit_side(side: str, tau: np.ndarray, mu: np.ndarray, kappa: np.ndarray,
             thickness: np.ndarray, spacing: np.ndarray) -> SideFit:
    """Fit κ(τ, μ2) of one side from points (τ (n,), μ2 (n,), κ (n,)) onto ``thickness`` (T,) × ``spacing`` (S,).

    Per spacing column: the points' mean κ per τ, isotonic regression over τ (weighted by the count);
    each block of the isotonic fit (thicknesses pooled to one value) becomes one point at its mean τ
    (weighted), so the points rise strictly; PCHIP through them onto ``thickness`` (PCHIP keeps
    monotone data monotone; τ beyond them is extrapolated linearly from the last two, then must
    still rise).

    Raises
    ------
    ValueError
        naming the side and μ2: fewer than ``MIN_POINTS`` measured thicknesses in a column (too
        sparse), or a column that is not monotone even after the fit: one block pools more than half
        of its thicknesses (at least 3; the measurements fall with τ or do not change there).
    """
    from scipy.interpolate import PchipInterpolator

    tau, mu, kappa = (np.asarray(a, dtype=float) for a in (tau, mu, kappa))
    T, S = len(thickness), len(spacing)
    grid = np.zeros((T, S))
    fitted = np.zeros(len(kappa))
    loo: list[float] = []
    for j, m in enumerate(spacing):
        sel = np.isclose(mu, m)
        ts = np.unique(tau[sel])
        if len(ts) < MIN_POINTS:
            raise ValueError(f"{side}, μ2 = {m:g} mm: {len(ts)} measured thickness(es), at least {MIN_POINTS} are "
                             "needed (too sparse: measure more coupons of this column)")
        means = np.array([kappa[sel][tau[sel] == t].mean() for t in ts])
        counts = np.array([np.count_nonzero(tau[sel] == t) for t in ts], dtype=float)
        vals, sizes = pav_blocks(means, counts)
        ends = np.cumsum(sizes)
        starts = ends - sizes
        widest = int(np.argmax(sizes))
        if len(vals) < 2 or sizes[widest] > max(2, len(ts) // 2) \
                or not vals[-1] - vals[0] > MIN_RISE * max(abs(vals.mean()), 1e-12):
            a, b = ts[starts[widest]], ts[ends[widest] - 1]
            raise ValueError(
                f"{side}, μ2 = {m:g} mm: κ1 does not increase with τ even after the monotone fit (from "
                f"τ = {a:g} to {b:g} mm the measurements fall or stay level: "
                f"{', '.join(f'{v:.4g}' for v in means[starts[widest]:ends[widest]])} 1/mm); re-measure those "
                "coupons or leave them out")
        ct = np.array([np.average(ts[a:b], weights=counts[a:b]) for a, b in zip(starts, ends)])  # block centres

        def f(x: np.ndarray, _f=PchipInterpolator(ct, vals), _c=ct, _v=vals) -> np.ndarray:  # noqa: ANN001
            """The column's curve: PCHIP through the blocks, linear beyond them."""
            x = np.asarray(x, dtype=float)
            y = _f(np.clip(x, _c[0], _c[-1]))
            y = np.where(x < _c[0], _v[0] + (x - _c[0]) * (_v[1] - _v[0]) / (_c[1] - _c[0]), y)
            return np.where(x > _c[-1], _v[-1] + (x - _c[-1]) * (_v[-1] - _v[-2]) / (_c[-1] - _c[-2]), y)

        col = f(thickness)
        if np.any(col <= 0) or np.any(np.diff(col) <= 0):
            raise ValueError(f"{side}, μ2 = {m:g} mm: the fitted κ1 is not positive and strictly increasing on the "
                             f"table's τ grid {thickness.min():g}–{thickness.max():g} mm (measured "
                             f"{ts[0]:g}–{ts[-1]:g} mm): measure the whole range")
        grid[:, j] = col
        fitted[sel] = f(tau[sel])
        full = np.repeat(vals, sizes)
        for i in range(1, len(ts) - 1):               # leave one out: the interior points
            keep = np.arange(len(ts)) != i
            loo.append(float(means[i] - PchipInterpolator(ts[keep], full[keep])(ts[i])))
    res = kappa - fitted
    pts = np.column_stack([tau, mu, kappa, fitted])
    return SideFit(grid=grid, points=pts, rms=float(np.sqrt(np.mean(res ** 2))) if len(res) else 0.0,
                   max_abs=float(np.abs(res).max(initial=0.0)),
                   loo_rms=float(np.sqrt(np.mean(np.square(loo)))) if loo else float("nan"))


@dataclass(frozen=True)
class TableFit:
    """The fitted table (its TOML text and model), the per-side fits, what was left out."""

    text: str
    table: CurvatureTable
    sides: dict[str, SideFit]
    failed: list[int]
    measured: int
    warnings: list[str]


def _rows(name: str, values: np.ndarray, tau: np.ndarray, mu: np.ndarray) -> str:
    head = f"# κ1 on the stitch {name}, 1/mm; columns μ2 = {', '.join(f'{m:g}' for m in mu)} mm\n{name} = [\n"
    body = "".join("    [" + ", ".join(f"{_sig(v)!r:>10}" for v in row) + f"],  # τ = {t:g} mm\n"
                   for row, t in zip(values, tau))
    return head + body + "]\n"


def _sig(v: float) -> float:
    """``v`` to 5 significant digits."""
    return float(format(float(v), ".5g"))


def _quote(s: str) -> str:
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"').replace("\n", " ") + '"'


def fit_table(plan: dict[str, Any], measurements: dict[int, float | None], *, name: str, fabric: str = "",
              material: str = "", date: str = "", design_mu2: tuple[float, float] | None = None) -> TableFit:
    """Fit a curvature table from a plan (``plan.json``'s content) and the measured κ per coupon.

    A side the plan did not calibrate is refused unless the other is there: the table needs both
    sides, so a plan of one side gives a table whose other side is the first side's values divided
    by the base table's front/back ratio at each point (said in the description). ``design_mu2``:
    the μ2 range the designs need (Eq. 10); a table that does not cover it is written with a warning.

    Raises
    ------
    ValueError
        for a side too sparse or not monotone (``fit_side``), or nothing measured.
    """
    from ..design.thickness import CurvatureTable, load_curvature_table

    spec = plan["spec"]
    tau = np.asarray(spec["thicknesses"], dtype=float)
    mu = np.asarray(spec["spacings"], dtype=float)
    coupons = {c["coupon"]: c for c in plan["coupons"]}
    failed = sorted(n for n, k in measurements.items() if k is None)
    sides: dict[str, SideFit] = {}
    for side in spec["sides"]:
        pts = [(coupons[n]["thickness_mm"], coupons[n]["spacing_mm"], k) for n, k in measurements.items()
               if k is not None and coupons[n]["side"] == side]
        if not pts:
            raise ValueError(f"{side}: no coupon of this side was measured")
        a = np.asarray(pts, dtype=float)
        sides[side] = fit_side(side, a[:, 0], a[:, 1], a[:, 2], tau, mu)
    if not sides:
        raise ValueError("nothing was measured")
    base = load_curvature_table(spec.get("base_table", "tpu95a-lycra-default"))
    grids = {s: f.grid for s, f in sides.items()}
    note = ""
    if len(grids) == 1:
        from ..design.thickness import table_curvature

        (have, g), = grids.items()
        other = "back" if have == "front" else "front"
        T, M = np.meshgrid(tau, mu, indexing="ij")
        ratio = (table_curvature(base, other, T.ravel(), M.ravel())
                 / table_curvature(base, have, T.ravel(), M.ravel())).reshape(T.shape)
        grids[other] = g * ratio
        note = f" The {other} side was not measured: it is the {have} side times the ratio of {base.name!r}."
    warnings = []
    if design_mu2 is not None and (design_mu2[0] < mu[0] - 1e-9 or design_mu2[1] > mu[-1] + 1e-9):
        warnings.append(f"the table covers μ2 = {mu[0]:g}–{mu[-1]:g} mm but designs need "
                        f"{design_mu2[0]:.2f}–{design_mu2[1]:.2f} mm: ribbons outside are clamped")
    count = sum(1 for k in measurements.values() if k is not None)
    resid = "; ".join(f"{s}: RMS {f.rms:.3g}, max {f.max_abs:.3g}, leave-one-out RMS {f.loo_rms:.3g} 1/mm"
                      for s, f in sides.items())
    desc = (f"Measured: {count} coupons ({len(failed)} failed) of calibration plan printed with profile "
            f"{plan.get('profile', spec.get('printer_profile'))!r}, l_r {spec['ribbon_length']:g} mm, w_r "
            f"{spec['ribbon_width']:g} mm, μ1 {spec['mu1']:g} mm, s = {spec['prestretch']:g}, on {date or 'an unknown date'}"
            f"; isotonic regression per μ2, then PCHIP; residuals {resid}.{note}")
    text = "".join([
        f"# Fitted by ribbonctl calibrate record from {count} measured coupons ({date}).\n",
        f"# Printer profile {plan.get('profile', spec.get('printer_profile'))}, fabric {fabric or spec.get('fabric') or '?'}, "
        f"filament {material or spec.get('material') or '?'}, pre-stretch s = {spec['prestretch']:g}.\n",
        f"# Fit residuals (measured - fitted): {resid}.\n",
        f"name = {_quote(name)}\n", f"description = {_quote(desc)}\n",
        f"material = {_quote(material or spec.get('material') or '')}\n",
        f"fabric = {_quote(fabric or spec.get('fabric') or '')}\n",
        f"prestretch = {float(spec['prestretch'])!r}\n\n",
        f"thickness = [{', '.join(repr(float(t)) for t in tau)}]   # τ, mm (rows)\n",
        f"spacing = [{', '.join(repr(float(m)) for m in mu)}]   # μ2, mm (columns)\n\n",
        _rows("front", grids["front"], tau, mu), "\n", _rows("back", grids["back"], tau, mu)])
    import tomllib

    try:
        table = CurvatureTable(**tomllib.loads(text))
    except ValidationError as exc:
        raise ValueError(f"the fitted table is refused: {exc.errors()[0]['msg']}") from None
    return TableFit(text=text, table=table, sides=sides, failed=failed, measured=count, warnings=warnings)


def plot_fit(fit: TableFit, path: Path | None = None) -> bytes:
    """Fig. 6: κ against τ, one curve per μ2 (the table's values, linear in between as the designs
    interpolate them), the measured points, one panel per side (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    t = fit.table
    tau = np.asarray(t.thickness)
    fig = Figure(figsize=(10, 4.2), dpi=110)
    for k, side in enumerate(("front", "back")):
        ax = fig.add_subplot(1, 2, k + 1)
        grid = t.grid(side)
        cmap = matplotlib.colormaps["viridis"]
        for j, m in enumerate(t.spacing):
            col = cmap(j / max(1, len(t.spacing) - 1))
            # the table as designs read it: its grid values, linear in between
            ax.plot(tau, grid[:, j], "-x", color=col, ms=4, label=f"μ2 = {m:g} mm")
            if side in fit.sides:
                p = fit.sides[side].points
                sel = np.isclose(p[:, 1], m)
                ax.plot(p[sel, 0], p[sel, 2], "o", color=col, ms=3)
        ax.set_title(f"{side}" + ("" if side in fit.sides else " (not measured)"), fontsize=9)
        ax.set_xlabel("τ (mm)")
        ax.set_ylabel("κ1 (1/mm)")
        ax.legend(fontsize=6)
    fig.suptitle("fitted curvature table (lines, x: the table) and the measured coupons (dots)", fontsize=9)
    fig.tight_layout()
    import io as _io

    buf = _io.BytesIO()
    fig.savefig(buf, format="png")
    data = buf.getvalue()
    if path is not None:
        Path(path).write_bytes(data)
    return data


def design_mu2_range(ribbon_length: float, ribbon_width: float, prestretch: float) -> tuple[float, float]:
    """μ2 the default design bounds need: Eq. 10 at σ2 = 1.3 and at σ2max (μ2 = l_r)."""
    from ..design.params import DesignParameters, spacing_for_sigma

    p = DesignParameters(ribbon_length=ribbon_length, ribbon_width=ribbon_width, prestretch=prestretch)
    lo, hi = p.sigma2_bounds  # type: ignore[misc]
    return (spacing_for_sigma(lo, ribbon_width, prestretch), spacing_for_sigma(hi, ribbon_width, prestretch))


__all__ = ["Measurement", "arc_curvature", "parse_measurements", "pav", "fit_side", "fit_table", "plot_fit",
           "TableFit", "SideFit", "design_mu2_range"]
