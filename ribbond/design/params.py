"""The design parameters: one validated model with the paper's defaults (§4.3, §6.1).

``DesignParameters`` is what a user sets (``--params FILE``, the API) and what ``design.json``
records under ``parameters``; ``SolverSettings`` are the engine's numerical knobs, which do not
change the design the method aims at, only how closely and how fast it is reached.
"""

from __future__ import annotations

import json
import tomllib
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator


def sigma_for_spacing(spacing: float, ribbon_size: float, prestretch: float) -> float:
    """Invert Eq. 10: the stretch σ at which the pattern spacing μ equals ``spacing``.

    μ = r (s − 1) / (s − σ) σ, so σ = μ s / (μ + r (s − 1)), with r = l_r along the ribbons or
    w_r across them.
    """
    return spacing * prestretch / (spacing + ribbon_size * (prestretch - 1.0))


def spacing_for_sigma(sigma: float, ribbon_size: float, prestretch: float) -> float:
    """Eq. 10: the pattern spacing μ = r (s − 1) / (s − σ) σ that yields the average stretch σ."""
    return ribbon_size * (prestretch - 1.0) / (prestretch - sigma) * sigma


class SizeSpec(BaseModel):
    """The physical size of the target surface: its bounding-box diagonal in mm (as the paper)."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    bbox_diagonal: float = Field(gt=0, description="bounding-box diagonal of the target surface, mm")


class DesignParameters(BaseModel):
    """Everything that defines a design, with the paper's defaults.

    σ maps the target (deployed) surface to the flat (pre-stretched) one, so σ ≥ 1: the flat
    surface is larger. ``sigma2_bounds`` defaults to [1.3, σ2max] with σ2max from Eq. 10 at
    μ2max = l_r (≈ 1.51 for the defaults).
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    prestretch: float = Field(1.6, gt=1.0, description="fabric pre-stretch factor s")
    ribbon_length: float = Field(15.0, gt=0, description="ribbon length l_r, mm")
    ribbon_width: float = Field(1.5, gt=0, description="ribbon width w_r, mm")
    sigma1_bounds: tuple[float, float] = Field((1.0, 1.3), description="stretch bounds along k1")
    sigma2_bounds: tuple[float, float] | None = Field(
        None, description="stretch bounds across k1; default [1.3, σ2max(μ2max = l_r)]")
    smoothing_lambda: float = Field(
        0.0, le=0.0, description="line-field smoothing λ (Table 1): 0 default, negative smooths less; "
        "for the default aligned field in (-1, 0], the relative change of its smoothing length")
    min_ribbon_length: float = Field(2.0, gt=0, description="shorter ribbons are dropped, mm")
    max_trim_angle: float = Field(25.0, gt=0, lt=90, description="trim where a ribbon turns away "
                                  "from the direction field by more than this, degrees")
    size: SizeSpec | None = Field(None, description="physical size; None: the largest that fits the frame")
    printer_profile: str = Field("ultimaker2-tpu", min_length=1)
    curvature_table: str = Field("tpu95a-lycra-default", min_length=1)

    @model_validator(mode="after")
    def _check_bounds(self) -> "DesignParameters":
        s = self.prestretch
        if self.sigma2_bounds is None:
            hi = sigma_for_spacing(self.ribbon_length, self.ribbon_width, s)
            object.__setattr__(self, "sigma2_bounds", (min(1.3, hi), hi))
        for name in ("sigma1_bounds", "sigma2_bounds"):
            lo, hi = getattr(self, name)
            if not 1.0 <= lo <= hi:
                raise ValueError(f"{name} = [{lo}, {hi}]: need 1 <= lower <= upper "
                                 "(the flat surface is the stretched one)")
            if hi >= s:
                raise ValueError(f"{name} = [{lo}, {hi}]: the upper bound must stay below the "
                                 f"pre-stretch s = {s} (Eq. 10 diverges at σ = s)")
        return self

    @property
    def bounds(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """((σ1min, σ1max), (σ2min, σ2max))."""
        lo2, hi2 = self.sigma2_bounds or (0.0, 0.0)  # always set by the validator
        return ((self.sigma1_bounds[0], self.sigma1_bounds[1]), (lo2, hi2))


class SolverSettings(BaseModel):
    """Numerical settings of the engine: tolerances, caps and accelerations."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    tolerance: float = Field(1e-6, gt=0, description="stop when the mean change of σ1 and of σ2 is below")
    max_iterations: int = Field(3000, ge=1, description="cap on local/global iterations")
    local_passes: int = Field(2, ge=1, description="R/Σ alternations per global step (§4.3: twice)")
    anderson_window: int = Field(6, ge=0, description="Anderson acceleration history; 0 turns it off")
    slim_iterations: int = Field(2, ge=0, description="SLIM iterations after the Tutte embedding")
    mid_bounds_iterations: int = Field(
        500, ge=0, description="cap on the first phase, which aims every face at the middle of "
        "the bounds before the bounded iteration (the most uniform flattening); 0 turns it off")
    stripe_edge_fraction: float = Field(
        0.15, gt=0, le=1, description="the stripe patterns are computed on a triangulation of the flat "
        "surface with edges of this share of the shortest stripe period")
    stripe_spacing_weight: float | None = Field(
        None, gt=0, description="when set, θ's frequency is made integrable along the ribbon direction "
        "first, with this weight on Eq. 10's spacing (smaller: centerlines closer to the field, spacing "
        "further from Eq. 10); unset: Eq. 10's frequency as it is")
    stripe_direction_weight: float = Field(
        0.5, gt=0, description="θ's stripe energy weighs a phase change along the ribbons (their "
        "direction) this many times one across them (their spacing): below 1 the rows keep Eq. 10's "
        "spacing and turn a little instead; 1 is KCPS15's isotropic energy")
    stripe_max_faces: int = Field(
        150_000, ge=100, description="that triangulation is made coarser rather than exceed this many faces")
    coarse_faces: int = Field(
        12_000, ge=0, description="meshes of 4× more faces start from a flattening of a copy "
        "decimated to this many faces (coarse to fine); 0 turns it off")
    line_field: Literal["aligned", "kcps13"] = Field(
        "aligned", description="'aligned': k1 where it is defined, smooth where it is not; 'kcps13': "
        "the previous engine's (A − λB) z = B q with λ in units of the surface scaled to unit area")
    umbilic_tolerance: float = Field(
        0.3, ge=0, lt=1, description="a face is umbilic where the curvature anisotropy "
        "(|κ1| − |κ2|) / (|κ1| + |κ2|) is at most this")
    max_faces: int = Field(400_000, ge=1, description="meshes with more faces are refused")
    merge_tolerance: float = Field(
        1e-7, ge=0, description="vertices closer than this × bbox diagonal are merged")
    layout_margin: float = Field(
        10.0, ge=0, description="free border kept inside the frame around the flat layout, mm")


def check_smoothing(params: "DesignParameters", solver: "SolverSettings") -> None:
    """Raise ValueError when ``smoothing_lambda`` is outside what ``solver.line_field`` accepts."""
    if solver.line_field == "aligned" and not params.smoothing_lambda > -1.0:
        raise ValueError(
            f"smoothing_lambda = {params.smoothing_lambda:g}: the aligned line field takes λ in (-1, 0] "
            "(the relative change of its smoothing length; Table 1's -0.01 and -0.1 smooth slightly "
            "less); the previous engine's unbounded λ needs line_field = 'kcps13' under [solver]")


class DesignSettings(BaseModel):
    """What a ``--params`` file holds: the design parameters and, optionally, solver settings."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    parameters: DesignParameters = DesignParameters()
    solver: SolverSettings = SolverSettings()

    @model_validator(mode="after")
    def _smoothing(self) -> "DesignSettings":
        check_smoothing(self.parameters, self.solver)
        return self


def load_settings(path: Path) -> DesignSettings:
    """Read a ``--params`` file (TOML or JSON).

    Top-level keys are design parameters; an optional ``[solver]`` table holds solver settings.

    Raises
    ------
    ValueError
        naming the file and each offending field.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: cannot read the parameter file ({exc})") from None
    try:
        data: Any = json.loads(text) if path.suffix.lower() == ".json" else tomllib.loads(text)
    except (json.JSONDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ValueError(f"{path}: not valid {'JSON' if path.suffix.lower() == '.json' else 'TOML'}: {exc}") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path}: expected a table of parameters at the top level")
    solver = data.pop("solver", {})
    try:
        return DesignSettings(parameters=DesignParameters(**data), solver=SolverSettings(**solver))
    except ValidationError as exc:
        problems = "; ".join(
            f"{'.'.join(str(p) for p in err['loc']) or '(file)'}: {err['msg']}" for err in exc.errors())
        raise ValueError(f"{path}: invalid parameters: {problems}") from None
