"""Printer profiles: validated models loaded from TOML files.

A profile describes the printer and the reversible fabric frame on its bed. The files shipped
with ribbond live in ``ribbond/gcode/profiles/``; a user's own profile is a TOML file of the
same shape, given by path. (The G-code stage adds the extrusion and motion settings.)
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from ..datafiles import load_toml_model, shipped_names

PROFILE_DIR = Path(__file__).with_name("profiles")


class FrameSpec(BaseModel):
    """The printable rectangle of the fabric frame on the bed, in machine coordinates (mm)."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    center: tuple[float, float] = Field(description="centre of the printable rectangle, mm")
    size: tuple[float, float] = Field(description="width (x) and depth (y) of the printable rectangle, mm")
    flip_axis: Literal["x", "y"] = Field(
        "y", description="the frame is turned over about this axis through the centre")

    @model_validator(mode="after")
    def _positive(self) -> "FrameSpec":
        if min(self.size) <= 0:
            raise ValueError(f"frame size {self.size} must be positive")
        return self

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(x_min, y_min, x_max, y_max)."""
        (cx, cy), (w, h) = self.center, self.size
        return cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2


class PrinterProfile(BaseModel):
    """A printer and its fabric frame."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    name: str = Field(min_length=1)
    description: str = ""
    frame: FrameSpec


def available_profiles() -> list[str]:
    """Names of the profiles shipped with ribbond."""
    return shipped_names(PROFILE_DIR)


def load_profile(name_or_path: str | Path) -> PrinterProfile:
    """A shipped profile by name, or a profile file by path.

    Raises
    ------
    ValueError
        naming the profile and what is wrong with it.
    """
    return load_toml_model(name_or_path, PROFILE_DIR, PrinterProfile, "printer profile")
