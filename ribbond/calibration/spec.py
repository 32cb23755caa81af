"""What a calibration plan asks for (pydantic only: the daemon validates it without the engine).

The defaults are the paper's grid (§5, Fig. 6): 8 thicknesses × 6 spacings per side, ribbons of the
design defaults (l_r = 15 mm, w_r = 1.5 mm) at μ1 = 22.5 mm (Fig. 5's μ1), on both sides.
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator, model_validator

#: The paper's grid (Fig. 6), and the shipped table's: τ rows, mm.
DEFAULT_THICKNESSES = (0.2, 0.4, 0.6, 0.8, 1.0, 1.2, 1.4, 1.6)
#: μ2 columns, mm: Eq. 10 with the defaults gives μ2 ≈ 3.9–15.1 mm.
DEFAULT_SPACINGS = (3.0, 4.5, 6.0, 8.0, 11.0, 16.0)


class CalibrationSpec(BaseModel):
    """A calibration plan's parameters.

    Attributes
    ----------
    printer_profile : the printer profile (name, or a path locally; the daemon's own on the daemon).
    thicknesses, spacings : the grid, mm, strictly increasing, > 0 (at least 2 of each).
    sides : which sides of the fabric to calibrate.
    ribbon_length, ribbon_width : l_r and w_r, mm (the designs' own).
    mu1 : spacing along the ribbons, mm (> l_r: ribbons of one row do not touch).
    prestretch : s of the fabric, as it will be mounted.
    base_table : the curvature table whose values are written as each coupon's expected κ1.
    fabric, material : free text, carried into the fitted table's provenance.
    min_coupon_width : a coupon has at least 3 rows of ribbons and is at least this wide, mm.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    printer_profile: str = Field("ultimaker2-tpu", min_length=1)
    thicknesses: tuple[float, ...] = Field(DEFAULT_THICKNESSES, min_length=2)
    spacings: tuple[float, ...] = Field(DEFAULT_SPACINGS, min_length=2)
    sides: tuple[Literal["front", "back"], ...] = Field(("front", "back"), min_length=1)
    ribbon_length: float = Field(15.0, gt=0)
    ribbon_width: float = Field(1.5, gt=0)
    mu1: float = Field(22.5, gt=0)
    prestretch: float = Field(1.6, gt=1.0)
    base_table: str = Field("tpu95a-lycra-default", min_length=1)
    fabric: str = ""
    material: str = ""
    min_coupon_width: float = Field(20.0, gt=0)

    @field_validator("thicknesses", "spacings")
    @classmethod
    def _increasing(cls, values: tuple[float, ...], info: ValidationInfo) -> tuple[float, ...]:
        for v in values:
            if not v > 0:
                raise ValueError(f"{info.field_name}: {v} must be > 0")
        for a, b in zip(values, values[1:]):
            if not b > a:
                raise ValueError(f"{info.field_name} must be strictly increasing; {a} is followed by {b}")
        return values

    @field_validator("sides")
    @classmethod
    def _unique(cls, values: tuple[str, ...]) -> tuple[str, ...]:
        if len(set(values)) != len(values):
            raise ValueError(f"sides {list(values)}: each side once")
        return tuple(s for s in ("front", "back") if s in values)

    @model_validator(mode="after")
    def _geometry(self) -> "CalibrationSpec":
        if not self.mu1 > self.ribbon_length:
            raise ValueError(f"mu1 = {self.mu1} mm must exceed ribbon_length = {self.ribbon_length} mm "
                             "(the ribbons of a row would touch)")
        if not self.spacings[0] > self.ribbon_width:
            raise ValueError(f"spacings start at {self.spacings[0]} mm: every spacing must exceed "
                             f"ribbon_width = {self.ribbon_width} mm (the rows would overlap)")
        return self
