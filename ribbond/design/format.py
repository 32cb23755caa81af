"""``design.json``: the models of the file every consumer of a design reads (``/work/shared/design-format.md``).

The models mirror the format document key for key; they validate on construction, so a ``Design``
that exists is a consistent one: per-face arrays of one length, finite, σ > 0, unit ribbon
directions, ``report.faces`` equal to the face count, and each ribbon on the side its curvature asks
for (``front`` exactly when ``kappa1 > 0``).

``stitch_marks`` (issue 26, a panel's seam marks) is an addition to the shared text, absent unless a
panel has them, so files without it read and write as before (the format stays ``ribbond-design/3``).

``design_to_json`` writes the file (optional sections that are ``None`` are left out, the report's
``print_`` is written as ``"print"``), ``design_from_json`` reads it back and reports problems as
``ValueError`` naming the file and the field path. Floats are written losslessly (shortest repr), so
``design_from_json(design_to_json(d)) == d``.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from typing import Any, Literal, Self

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from ribbond.design.params import DesignParameters, SizeSpec

#: The format this module writes; it reads it and the formats of ``READABLE_FORMATS``.
FORMAT = "ribbond-design/4"

#: Every format this module reads (formats 2 and 3 only add report fields to format 1).
READABLE_FORMATS = ("ribbond-design/1", "ribbond-design/2", "ribbond-design/3", "ribbond-design/4")

#: Largest tolerated deviation of a ribbon direction from unit length.
UNIT_TOLERANCE = 1e-6

# Every model: no unknown keys, no NaN or infinity (they are not JSON), immutable once built.
_CONFIG = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

Point = tuple[float, float]


class _Updatable(BaseModel):
    def updated(self, **changes: Any) -> Self:
        """A copy with ``changes`` (by field name) applied and validated again.

        Unlike ``model_copy(update=…)``, which does not validate, this runs every check, the
        cross-checks of ``Design`` included; an unknown name is refused.
        """
        return self.model_validate({**dict(self), **changes})


class Source(BaseModel):
    """The mesh file the design was made from, as given (before cleaning)."""

    model_config = _CONFIG
    file: str = Field(min_length=1, description="file name of the source mesh")
    sha256: str = Field(pattern=r"^[0-9a-f]{64}$", description="SHA-256 of the source file, lower-case hex")
    faces: int = Field(ge=1, description="face count of the source file (before cleaning)")


class Parameters(DesignParameters):
    """The ``parameters`` section: ``DesignParameters`` with the size actually used (never null).

    The JSON keys are exactly those of ``DesignParameters``; ``sigma2_bounds`` is always resolved
    (the validator fills the default), bounds serialize as 2-element arrays.
    """

    model_config = ConfigDict(allow_inf_nan=False)  # merged with DesignParameters' config
    size: SizeSpec = Field(description="the physical size the design was made at")

    @field_validator("size")
    @classmethod
    def _finite_size(cls, v: SizeSpec) -> SizeSpec:
        if not np.isfinite(v.bbox_diagonal):
            raise ValueError(f"size.bbox_diagonal = {v.bbox_diagonal!r}: must be finite")
        return v

    @classmethod
    def resolved(cls, params: DesignParameters, bbox_diagonal: float) -> "Parameters":
        """``params`` with ``size`` set to the size used (``bbox_diagonal`` in mm)."""
        data = params.model_dump()
        data["size"] = {"bbox_diagonal": float(bbox_diagonal)}
        return cls(**data)


class Faces(BaseModel):
    """Per-face fields, in the engine's face order (the order of ``target.obj``/``flat.obj``)."""

    model_config = _CONFIG
    sigma1: list[float] = Field(description="principal stretch along the ribbons (target -> flat)")
    sigma2: list[float] = Field(description="principal stretch across the ribbons")
    ribbon_direction: list[Point] = Field(description="unit vector in flat coordinates: k1 pushed forward")
    kappa1: list[float] = Field(description="signed normal curvature along the ribbons, 1/mm")

    @model_validator(mode="after")
    def _check(self) -> "Faces":
        n = len(self.sigma1)
        if n == 0:
            raise ValueError("sigma1 is empty: a design has at least one face")
        for name in ("sigma2", "ribbon_direction", "kappa1"):
            if len(getattr(self, name)) != n:
                raise ValueError(f"{name} has {len(getattr(self, name))} values but sigma1 has {n}: "
                                 "all per-face fields have one value per face")
        s1, s2, d, _ = self.arrays()  # finite already: the config refuses NaN and infinity
        for name, values in (("sigma1", s1), ("sigma2", s2)):
            bad = np.flatnonzero(values <= 0)
            if bad.size:
                raise ValueError(f"{name}[{bad[0]}] = {float(values[bad[0]])!r}: stretches must be > 0")
        off = np.abs(np.hypot(d[:, 0], d[:, 1]) - 1.0)
        bad = np.flatnonzero(off > UNIT_TOLERANCE)
        if bad.size:
            i = bad[0]
            raise ValueError(f"ribbon_direction[{i}] = {d[i].tolist()} has length {float(np.hypot(*d[i])):.9g}: "
                             f"must be a unit vector (within {UNIT_TOLERANCE:g}); {bad.size} such face(s)")
        return self

    @classmethod
    def from_arrays(cls, sigma1: Any, sigma2: Any, ribbon_direction: Any, kappa1: Any) -> "Faces":
        """Build from numpy arrays (shapes (m,), (m,), (m, 2), (m,))."""
        d = np.asarray(ribbon_direction, dtype=float)
        if d.ndim != 2 or d.shape[1] != 2:
            raise ValueError(f"ribbon_direction must have shape (m, 2), got {d.shape}")
        return cls(sigma1=np.asarray(sigma1, dtype=float).ravel().tolist(),
                   sigma2=np.asarray(sigma2, dtype=float).ravel().tolist(),
                   ribbon_direction=[(x, y) for x, y in d.tolist()],
                   kappa1=np.asarray(kappa1, dtype=float).ravel().tolist())

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(sigma1 (m,), sigma2 (m,), ribbon_direction (m, 2), kappa1 (m,)) as float arrays."""
        d = np.asarray(self.ribbon_direction, dtype=float).reshape(-1, 2)
        return (np.asarray(self.sigma1, dtype=float), np.asarray(self.sigma2, dtype=float), d,
                np.asarray(self.kappa1, dtype=float))

    @property
    def count(self) -> int:
        """The number of faces."""
        return len(self.sigma1)


class Ribbon(BaseModel):
    """One ribbon: a polyline in front-side print coordinates, printed on ``side``."""

    model_config = _CONFIG
    side: Literal["front", "back"]
    points: list[Point] = Field(min_length=2, description="polyline, mm, front-side print coordinates")
    thickness: float = Field(gt=0, description="printed thickness, mm")
    kappa1: float = Field(description="target curvature where the ribbon sits, 1/mm")
    spacing: tuple[float, float] = Field(description="[mu1, mu2] of Eq. 10 where the ribbon sits, mm")

    @field_validator("spacing")
    @classmethod
    def _positive_spacing(cls, v: tuple[float, float]) -> tuple[float, float]:
        if not (v[0] > 0 and v[1] > 0):
            raise ValueError(f"spacing = {list(v)}: both spacings must be > 0")
        return v


class StitchMark(BaseModel):
    """A stitch mark on a panel's seam allowance (issue 26): a tick from the seam line to the cutting
    line and its label, printed on the front as one-layer lines (``ribbond.panels.stitch``)."""

    model_config = _CONFIG
    label: str = Field(pattern=r"^[A-Z0-9]+$", description="the mark's label, A-Z and 0-9 (\"A1\")")
    seam: str = Field(min_length=1, description="the seam's letter")
    at: Point = Field(description="the mark's point on the seam line, front-side print coordinates, mm")
    outward: Point = Field(description="unit normal of the seam line there, out of the panel")
    strokes: list[list[Point]] = Field(min_length=1, description="polylines printed (the tick first), mm, "
                                       "front-side print coordinates")

    @field_validator("outward")
    @classmethod
    def _unit(cls, v: Point) -> Point:
        length = float(np.hypot(*v))
        if abs(length - 1.0) > UNIT_TOLERANCE:
            raise ValueError(f"outward = {list(v)} has length {length:.9g}: must be a unit vector "
                             f"(within {UNIT_TOLERANCE:g})")
        return v

    @field_validator("strokes")
    @classmethod
    def _polylines(cls, v: list[list[Point]]) -> list[list[Point]]:
        short = [i for i, s in enumerate(v) if len(s) < 2]
        if short:
            raise ValueError(f"strokes[{short[0]}] has {len(v[short[0]])} point(s): a stroke needs at least 2")
        return v

    def arrays(self) -> list[np.ndarray]:
        """The strokes as (k, 2) float arrays."""
        return [np.asarray(s, dtype=float).reshape(-1, 2) for s in self.strokes]


class Quantiles(BaseModel):
    """A distribution summarized by its median and 95th percentile."""

    model_config = _CONFIG
    median: float
    p95: float


class Deviation(BaseModel):
    """An angle distribution (degrees): median, mean and 95th percentile."""

    model_config = _CONFIG
    median: float = Field(ge=0)
    mean: float = Field(ge=0)
    p95: float = Field(ge=0)


class DeviationPct(BaseModel):
    """A distance distribution as % of the target's bounding-box diagonal (Table 1's "Dev.")."""

    model_config = _CONFIG
    mean: float = Field(ge=0)
    p99: float = Field(ge=0)
    max: float = Field(ge=0)


class GaussianCurvature(BaseModel):
    """∫K dA of the prediction and of the target (format 3)."""

    model_config = _CONFIG
    predicted: float
    target: float


class Spread(BaseModel):
    """The deviation over the releases tried (format 3): [lo, hi] of the mean and of the max, % of the diagonal."""

    model_config = _CONFIG
    mean: list[float] = Field(min_length=2, max_length=2)
    max: list[float] = Field(min_length=2, max_length=2)
    releases: int = Field(ge=1)


class DeployedReport(BaseModel):
    """``report.deployed``: the predicted deployed shape against the target (format 2; format 3 adds
    the intrinsic measures, the spread, the verdict and the model, and releases from the flat sheet:
    ``start`` is then always "flat")."""

    model_config = _CONFIG
    deviation_pct: DeviationPct
    faces: int = Field(ge=1, description="faces of the mesh the prediction was computed on")
    iterations: int = Field(ge=0, description="Newton iterations")
    time_s: float = Field(ge=0)
    start: Literal["target", "flat"] = Field(description="where the solve started (format 3: the flat sheet)")
    total_gaussian_curvature: GaussianCurvature | None = None
    area_ratio: float | None = Field(default=None, ge=0, description="predicted area / target area")
    spread: Spread | None = None
    reached: bool | None = Field(default=None, description="the layout takes the target's shape (README's rule)")
    verdict: str | None = None
    model: Literal["homogenized"] | None = None
    table: str | None = Field(default=None, description="the curvature table of the prediction when it is "
                                                        "not parameters.curvature_table (ribbonctl predict --table)")


class PredictedShape(BaseModel):
    """A layout's predicted shape in ``report.optimization``: its deviation and ∫K (as ``report.deployed``)."""

    model_config = _CONFIG
    deviation_pct: DeviationPct
    total_gaussian_curvature: GaussianCurvature


class LineFieldChoice(BaseModel):
    """``report.optimization.line_field`` (optional; issue 34): on a target with ambiguous saddle regions
    (|κ1| ≈ |κ2|, K < 0) the paper's field (largest |κ|) and one family of curvature lines through each
    region were each laid out and predicted from the flat sheet; the better prediction is the design's."""

    model_config = _CONFIG
    switched_pct: float = Field(ge=0, le=100, description="share of the saddle regions' area where the one "
                                "family leaves the paper's k1, %")
    paper: PredictedShape
    one_family: PredictedShape | None = Field(description="null: its layout could not be made (reason says why)")
    kept: Literal["paper", "one_family"]
    reason: str = Field(description="why, in words")


class OptimizationReport(BaseModel):
    """``report.optimization`` (present when the layout was optimized against the prediction): the
    forward layout's predicted shape and the optimized one's (``report.deployed`` then describes the
    optimized layout), what was varied, L-BFGS-B's iterations and the wall time."""

    model_config = _CONFIG
    forward: PredictedShape
    optimized: PredictedShape
    variables: list[str] = Field(description="what was varied per ribbon (\"thickness\")")
    iterations: int = Field(ge=0)
    time_s: float = Field(ge=0)
    kept: bool = Field(True, description="whether the optimized layout is the design's (absent in older "
                       "folders: it always was); false: its prediction was not better than the forward "
                       "layout's, whose ribbons and prediction the design keeps")
    reason: str | None = Field(None, description="why it was kept or not, in words")
    line_field: LineFieldChoice | None = Field(None, description="the line field chosen by the prediction "
                                               "(absent when the target has no ambiguous saddle region)")


class RefinedReport(BaseModel):
    """``report.refined`` (optional; absent in older folders and when the target was not refined):
    the coarse target was subdivided at intake, and ``target.obj`` is the refined mesh."""

    model_config = _CONFIG
    from_faces: int = Field(ge=1, description="faces of the cleaned source mesh")
    faces: int = Field(ge=1, description="faces after refinement (those of target.obj)")
    levels: int = Field(ge=1, description="rounds of midpoint subdivision (each × 4 faces)")
    method: str = Field(min_length=1, description="the refinement scheme")
    offset_pct: float = Field(ge=0, description="largest distance of a refined vertex from the source "
                              "surface, % of its bounding-box diagonal")


class ScaleReport(BaseModel):
    """``report.scale`` (optional; absent in older folders): how the target got its physical size,
    ``parameters.size.bbox_diagonal`` = ``source_diagonal`` × ``factor``."""

    model_config = _CONFIG
    rule: Literal["size", "fit", "file"] = Field(
        description="size: the size asked for (--size, size.bbox_diagonal); fit: none asked, scaled to the "
        "largest at which the layout fits the frame and the curvature table reaches the target's curvature; file: none asked, the file's units read as mm (factor 1)")
    source_diagonal: float = Field(gt=0, description="the target's bounding-box diagonal in the file's units "
                                   "(as read, cleaned and refined)")
    factor: float = Field(gt=0, description="mm per file unit: the design's diagonal / source_diagonal")
    limited_by: Literal["frame", "curvature table"] | None = Field(
        None, description="fit only: what set the size: the frame (the largest flat layout it takes) or the "
        "curvature table (a larger target would be flatter than the thinnest plastic curls on more of its area)")
    frame_diagonal: float | None = Field(None, gt=0, description="fit only: the size the frame alone would take, mm")


class ThicknessFit(BaseModel):
    """The size factor (× the design's size: κ1 / scale, σ and μ2 unchanged) at which the fewest ribbon
    thicknesses clamp to the table, the closest to 1 among ties, and how many clamp there."""

    model_config = _CONFIG
    scale: float = Field(gt=0)
    clamped: int = Field(ge=0)


class RibbonsReport(BaseModel):
    """``report.ribbons``: what the ribbon stage made.

    ``spacing_error_across_pct`` and ``spacing_error_along_pct`` are the engine's extra fields: the
    two checks that ``spacing_error_pct`` pools.
    """

    model_config = _CONFIG
    front: int = Field(ge=0, description="ribbons on the front side")
    back: int = Field(ge=0, description="ribbons on the back side")
    dropped_short: int = Field(ge=0, description="ribbons dropped for being shorter than min_ribbon_length")
    trimmed_angle: int = Field(ge=0, description="ribbons trimmed where they turned beyond max_trim_angle")
    thickness_clamped: int = Field(ge=0, description="ribbons whose thickness was clamped to the table")
    direction_deviation_deg: Quantiles
    spacing_error_pct: Quantiles = Field(description="both spacing checks pooled, %")
    spacing_error_across_pct: Quantiles | None = Field(
        None, description="from each ribbon midpoint along its normal to the next centerline, against "
        "the harmonic mean of μ2 over that gap, %")
    spacing_error_along_pct: Quantiles | None = Field(
        None, description="neighbouring ribbon midpoints on a centerline against μ1, %")
    thickness_clamped_flat: int | None = Field(
        None, ge=0, description="of thickness_clamped: |κ1| below what the table's thinnest plastic curls "
        "(the surface too flat for the table there; issue 34)")
    thickness_clamped_curved: int | None = Field(
        None, ge=0, description="of thickness_clamped: |κ1| above what its thickest plastic curls (too curved)")
    thickness_fit: ThicknessFit | None = Field(
        None, description="the size at which the fewest thicknesses would clamp (thickness.fitting_scale)")
    rim: int | None = Field(None, ge=0, description="of the ribbons, the rows laid along the outline where the "
                            "rows run along a bare rim and the plastic fell short (design.rim; issue 34)")
    rim_replaced: int | None = Field(None, ge=0, description="the pattern's short chords those rows replaced")


class SidePrintReport(BaseModel):
    """One side's G-code program."""

    model_config = _CONFIG
    lines: int = Field(ge=0)
    extrusion_mm: float = Field(ge=0, description="length of extruding moves, mm")
    travel_mm: float = Field(ge=0, description="length of travel moves, mm")
    time_s: float = Field(ge=0, description="estimated print time, s")
    filament_mm: float = Field(ge=0, description="filament consumed, mm")


class PrintReport(BaseModel):
    """``report.print``: the G-code programs."""

    model_config = _CONFIG
    front: SidePrintReport
    back: SidePrintReport


class Percentiles(BaseModel):
    """p5, median and p95 of a per-face figure, %."""

    model_config = _CONFIG
    p5: float
    median: float
    p95: float


class PlasticShare(BaseModel):
    """The plastic area, % of the flat area: printed, and as Eq. 10 asks."""

    model_config = _CONFIG
    printed: float = Field(ge=0)
    eq10: float = Field(ge=0)


class IntendedCurvature(BaseModel):
    """∫K of the target, of the metric the flattening asks for and of the one the printed plastic
    realizes (dimensionless; ``realized`` absent in older folders)."""

    model_config = _CONFIG
    target: float
    intended: float
    realized: float | None = None


class RealizationReport(BaseModel):
    """``report.realization`` (format 4): how far the printed plastic realizes the flattening's metric
    and curvature (README, "The design format")."""

    model_config = _CONFIG
    along_pct: Percentiles | None = Field(None, description="100 (c_realized σ1 − 1) along the ribbons, interior faces")
    across_pct: Percentiles | None = Field(None, description="100 (c_realized σ2 − 1) across them, interior faces")
    along_pct_outline: Percentiles | None = Field(None, description="along, faces near the outline")
    across_pct_outline: Percentiles | None = Field(None, description="across, faces near the outline")
    plastic_pct: PlasticShare
    bare_pct: float = Field(ge=0, le=100, description="% of faces with no plastic within one μ2")
    curvature_pct: Percentiles | None = Field(None, description="100 (κ_rest / |κ1| − 1) where the table allows")
    clamped_pct: float = Field(ge=0, le=100, description="% of ribbons at the table's τ limits")
    total_gaussian_curvature: IntendedCurvature


class Report(_Updatable):
    """``report``: Table 1 of the paper, timings, and (when made) the ribbon and print stages.

    ``converged`` and ``time_per_iteration_s`` are the engine's extra fields; they, ``ribbons`` and
    ``print`` are left out of the file when ``None``.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False, populate_by_name=True)
    faces: int = Field(ge=1, description="face count of the design (of target.obj)")
    time_s: float = Field(ge=0, description="total design time, s")
    iterations: int = Field(ge=0, description="local/global iterations of the flattening")
    k1_deviation_deg: float = Field(ge=0, description="mean angle between k1 and the principal stretch direction")
    sigma1_max_dev: float = Field(ge=0, description="σ1 max deviation (Table 1)")
    sigma2_max_dev: float = Field(ge=0, description="σ2 max deviation (Table 1)")
    sigma1_bad_pct: float = Field(ge=0, le=100, description="% of faces with σ1 outside its bounds by > 1e-3")
    sigma2_bad_pct: float = Field(ge=0, le=100, description="% of faces with σ2 outside its bounds by > 1e-3")
    avg_energy: float = Field(ge=0, description="Eq. 3 divided by the total area")
    timings_s: dict[str, float] = Field(description="seconds per stage")
    converged: bool | None = Field(None, description="whether the flattening met its tolerance")
    time_per_iteration_s: float | None = Field(None, ge=0, description="mean time of one iteration, s")
    field_k1_deviation_deg: Deviation | None = Field(
        None, description="line field vs the target's k1 on faces with anisotropy > 0.3 (format 2)")
    ribbon_k1_deviation_deg: Deviation | None = Field(
        None, description="ribbon centerlines vs the target's k1 there, the angle on the target (the "
        "centerline pulled back through the flattening), length-weighted (format 2)")
    umbilic_pct: float | None = Field(None, ge=0, le=100,
                                      description="% of faces with anisotropy ≤ 0.3 (format 2)")
    ambiguous_pct: float | None = Field(
        None, ge=0, le=100, description="of umbilic_pct: faces where |κ1| ≈ |κ2| with opposite signs (K < 0, "
        "H ≈ 0, a symmetric saddle): not umbilic, the ribbon direction is ambiguous (issue 34)")
    panels_suggested: int | None = Field(
        None, ge=0, description="when more than 1 % of faces break the stretch bounds: how many panels "
        "`--panels auto` would cut the target into, searched on a copy of at most 6,000 faces (0: not even the "
        "most it tries) (issue 26)")
    ribbons: RibbonsReport | None = None
    print_: PrintReport | None = Field(None, alias="print")
    deployed: DeployedReport | None = None
    refined: RefinedReport | None = Field(None, description="the coarse target refined at intake")
    scale: ScaleReport | None = Field(None, description="how the target got its physical size (issue 36)")
    realization: RealizationReport | None = Field(None, description="the printed plastic against the "
                                                  "flattening's metric and curvature (format 4)")
    optimization: OptimizationReport | None = Field(None, description="the layout optimized against the "
                                                    "prediction (issue 34)")


class Design(_Updatable):
    """The whole ``design.json``."""

    model_config = _CONFIG
    format: str = FORMAT
    units: Literal["mm"] = "mm"
    source: Source
    parameters: Parameters
    faces: Faces
    ribbons: list[Ribbon] | None = None
    registration_marks: list[Point] | None = Field(None, description="front-side print coordinates, mm")
    stitch_marks: list[StitchMark] | None = Field(None, description="a panel's seam marks, printed on the "
                                                  "front (issue 26); absent for a design that is no panel")
    report: Report

    @field_validator("format")
    @classmethod
    def _known_format(cls, v: str) -> str:
        if v not in READABLE_FORMATS:
            raise ValueError(f"format {v!r} is not supported: this version reads "
                             f"{' and '.join(map(repr, READABLE_FORMATS))} and writes {FORMAT!r}")
        return v

    @model_validator(mode="after")
    def _consistent(self) -> "Design":
        m = self.faces.count
        if self.report.faces != m:
            raise ValueError(f"report.faces = {self.report.faces} but faces has {m} faces")
        if self.ribbons is not None:
            for i, r in enumerate(self.ribbons):
                want = "front" if r.kappa1 > 0 else "back"
                if r.side != want:
                    raise ValueError(f"ribbons[{i}] has side {r.side!r} but kappa1 = {r.kappa1!r}: "
                                     "the side is 'front' exactly when kappa1 > 0")
            rr = self.report.ribbons
            if rr is not None:
                front = sum(r.side == "front" for r in self.ribbons)
                back = len(self.ribbons) - front
                if (rr.front, rr.back) != (front, back):
                    raise ValueError(f"report.ribbons counts front = {rr.front}, back = {rr.back} but "
                                     f"ribbons holds {front} front and {back} back ribbons")
        return self


# ---------------------------------------------------------------------------------------------
# JSON


def design_to_dict(design: Design) -> dict[str, Any]:
    """The JSON object of ``design``: document keys (``"print"``), ``None`` sections left out."""
    return design.model_dump(mode="json", by_alias=True, exclude_none=True)


def _dump(value: Any, indent: int, level: int) -> str:
    """Objects one key per line; a list of objects one element per line; other lists on one line."""
    pad = " " * (indent * (level + 1))
    end = " " * (indent * level)
    if isinstance(value, dict) and value:
        items = (f"{pad}{json.dumps(k)}: {_dump(v, indent, level + 1)}" for k, v in value.items())
        return "{\n" + ",\n".join(items) + "\n" + end + "}"
    if isinstance(value, list) and value and isinstance(value[0], dict):
        items = (pad + json.dumps(v, separators=(",", ":"), allow_nan=False) for v in value)
        return "[\n" + ",\n".join(items) + "\n" + end + "]"
    return json.dumps(value, separators=(",", ":"), allow_nan=False)


def design_to_json(design: Design) -> str:
    """The text of ``design.json`` (ends with a newline).

    Objects are indented by one space, each array on one line (a list of ribbons one ribbon per
    line). Floats are written as their shortest exact representation.
    """
    return _dump(design_to_dict(design), 1, 0) + "\n"


def _path(loc: Sequence[int | str]) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out


def validation_problems(exc: ValidationError, limit: int = 5) -> str:
    """``path: message; …`` for the first ``limit`` errors of ``exc``."""
    errors = exc.errors(include_url=False)
    parts = []
    for err in errors[:limit]:
        msg = str(err["msg"]).removeprefix("Value error, ")
        parts.append(f"{_path(err['loc'])}: {msg}" if err["loc"] else msg)
    if len(errors) > limit:
        parts.append(f"and {len(errors) - limit} more problem(s)")
    return "; ".join(parts)


def _reject_constant(name: str) -> float:
    raise ValueError(f"{name} is not a number JSON allows")


def design_from_json(text: str, *, where: str = "design.json") -> Design:
    """Parse and validate the text of ``design.json``.

    Raises
    ------
    ValueError
        naming ``where`` and, for invalid content, the path of each offending field
        (``faces.sigma1[3]: …``).
    """
    try:
        data = json.loads(text, parse_constant=_reject_constant)
    except ValueError as exc:  # JSONDecodeError is a ValueError, as is the NaN refusal
        raise ValueError(f"{where}: not valid JSON: {exc}") from None
    if not isinstance(data, dict):
        raise ValueError(f"{where}: expected a JSON object at the top level")
    fmt = data.get("format")
    if fmt not in READABLE_FORMATS:
        raise ValueError(f"{where}: format: {fmt!r} is not supported: this version reads "
                         f"{' and '.join(map(repr, READABLE_FORMATS))}")
    try:
        return Design.model_validate(data)
    except ValidationError as exc:
        raise ValueError(f"{where}: invalid design: {validation_problems(exc)}") from None
