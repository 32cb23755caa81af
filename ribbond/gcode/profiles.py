"""Printer profiles: validated models loaded from TOML files.

A profile describes the printer and the reversible fabric frame on its bed. The files shipped
with ribbond live in ``ribbond/gcode/profiles/``; a user's own profile is a TOML file of the
same shape, given by path. (The G-code stage adds the extrusion and motion settings.)
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

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
    return sorted(p.stem for p in PROFILE_DIR.glob("*.toml"))


def load_profile(name_or_path: str | Path) -> PrinterProfile:
    """A shipped profile by name, or a profile file by path.

    Raises
    ------
    ValueError
        naming the profile and what is wrong with it.
    """
    path = Path(name_or_path)
    if path.suffix != ".toml":
        path = PROFILE_DIR / f"{name_or_path}.toml"
        if not path.is_file():
            raise ValueError(f"unknown printer profile {str(name_or_path)!r}; shipped profiles: "
                             f"{', '.join(available_profiles())}, or give the path of a .toml file")
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ValueError(f"{path}: cannot read the printer profile: {exc}") from None
    try:
        return PrinterProfile(**data)
    except ValidationError as exc:
        problems = "; ".join(f"{'.'.join(str(p) for p in e['loc'])}: {e['msg']}" for e in exc.errors())
        raise ValueError(f"{path}: invalid printer profile: {problems}") from None
