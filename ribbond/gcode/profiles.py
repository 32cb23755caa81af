"""Printer profiles: validated models loaded from TOML files.

A profile describes the printer and the reversible fabric frame on its bed: the frame's printable
rectangle and flip axis, the extruder, temperatures, speeds and accelerations with the firmware's
maxima, layer heights, retraction, z-hop, fan, and the start/end snippets. The files shipped with
ribbond live in ``ribbond/gcode/profiles/``; a user's own profile is a TOML file of the same shape,
given by path. Everything but ``name`` and ``frame`` has a default (the paper's setup, §7).
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


_STRICT = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class Extruder(BaseModel):
    """Nozzle and filament."""

    model_config = _STRICT
    nozzle_diameter: float = Field(0.8, gt=0, description="mm")
    filament_diameter: float = Field(2.85, gt=0, description="mm")
    extrusion_multiplier: float = Field(1.0, gt=0, le=2, description="flow correction for this filament")


class Temperatures(BaseModel):
    """Target temperatures and the firmware's maxima, °C (a target of 0 leaves that heater off)."""

    model_config = _STRICT
    nozzle: float = Field(225.0, ge=0)
    bed: float = Field(0.0, ge=0, description="the fabric lies on a base, not on the bed: usually off")
    nozzle_max: float = Field(260.0, gt=0)
    bed_max: float = Field(100.0, gt=0)

    @model_validator(mode="after")
    def _within(self) -> "Temperatures":
        if self.nozzle > self.nozzle_max:
            raise ValueError(f"nozzle = {self.nozzle} °C exceeds nozzle_max = {self.nozzle_max} °C")
        if self.bed > self.bed_max:
            raise ValueError(f"bed = {self.bed} °C exceeds bed_max = {self.bed_max} °C")
        return self


class Motion(BaseModel):
    """Speeds (mm/s) and accelerations (mm/s²), with the firmware's maximum feed rates."""

    model_config = _STRICT
    print_speed: float = Field(15.0, gt=0, description="extruding moves (the paper: 15 mm/s)")
    travel_speed: float = Field(120.0, gt=0)
    z_speed: float = Field(10.0, gt=0)
    retract_speed: float = Field(25.0, gt=0, description="filament speed of retractions")
    max_xy_speed: float = Field(300.0, gt=0)
    max_z_speed: float = Field(40.0, gt=0)
    max_e_speed: float = Field(45.0, gt=0)
    acceleration: float = Field(1000.0, gt=0, description="for the time estimate")
    junction_deviation: float = Field(0.05, gt=0, description="mm, for the time estimate (Marlin's)")

    @model_validator(mode="after")
    def _within(self) -> "Motion":
        for name, limit in (("print_speed", "max_xy_speed"), ("travel_speed", "max_xy_speed"),
                            ("z_speed", "max_z_speed"), ("retract_speed", "max_e_speed")):
            if getattr(self, name) > getattr(self, limit):
                raise ValueError(f"{name} = {getattr(self, name)} mm/s exceeds {limit} = {getattr(self, limit)} mm/s")
        return self


class Layers(BaseModel):
    """Heights above the fabric, mm."""

    model_config = _STRICT
    fabric_z: float = Field(0.0, description="machine z of the fabric's surface")
    first_layer_height: float = Field(
        0.2, gt=0, description="nozzle above the fabric for a ribbon's first layer; each layer is "
        "extruded for the ribbon's layer height, so a thicker first bead is pressed into the fabric")
    max_layer_height: float = Field(0.3, gt=0, description="a ribbon's thickness is split into equal layers "
                                    "no thicker than this")
    safe_height: float = Field(2.0, gt=0, description="above the fabric, for moves between parts")


class Retraction(BaseModel):
    """Retraction and z-hop on travels longer than ``min_travel``."""

    model_config = _STRICT
    length: float = Field(1.0, ge=0, description="mm of filament")
    min_travel: float = Field(2.0, ge=0, description="mm: shorter travels neither retract nor hop")
    z_hop: float = Field(0.6, ge=0, description="mm lifted for those travels")


class AlignmentTolerance(BaseModel):
    """How far the flipped frame may sit from where it should before the back is refused."""

    model_config = _STRICT
    max_residual: float = Field(0.3, gt=0, description="mm a mark may be off a rigid fit of all marks")
    max_rotation_deg: float = Field(2.0, gt=0, description="degrees the frame may be turned")
    max_offset: float = Field(5.0, gt=0, description="mm any mark may be moved")


class Adjustments(BaseModel):
    """What a person may change while a program prints (issue 36): the feed override (``M220``)
    and the flow (``M221``) within these percentages, the nozzle's target (``M104``) between
    ``nozzle_min`` and the profile's ``nozzle_max`` and the bed's (``M140``) up to ``bed_max``.
    The override and the flow are refused outside these ranges by every check (jobs, console)."""

    model_config = _STRICT
    speed_percent: tuple[float, float] = Field(
        (25.0, 100.0), description="M220 S… allowed, %: the firmware clamps a move at its maximum feed rates "
        "(the profile's max_*_speed), so above 100 the profile's own speeds × the top must stay within them")
    flow_percent: tuple[float, float] = Field((80.0, 120.0), description="M221 S… allowed, %")
    nozzle_min: float = Field(180.0, ge=0, description="°C: an M104 while printing may not go below it "
                              "(a cold nozzle refuses to extrude and the rest of the program runs dry)")

    @model_validator(mode="after")
    def _ranges(self) -> "Adjustments":
        for name in ("speed_percent", "flow_percent"):
            low, high = getattr(self, name)
            if not 0 < low <= 100 <= high <= 999:
                raise ValueError(f"adjust.{name} = [{low:g}, {high:g}]: needs 0 < low ≤ 100 ≤ high ≤ 999 "
                                 "(100 % is the program as written; Marlin takes 10-999)")
        return self


class Snippets(BaseModel):
    """G-code inserted after heating (``start``) and before the heaters go off (``end``)."""

    model_config = _STRICT
    start: str = ""
    end: str = ""
    emit_units: bool = Field(False, description="send G21: Marlin without INCH_MODE_SUPPORT "
                             "answers it as an unknown command")


class PrinterProfile(BaseModel):
    """A printer and its fabric frame."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    name: str = Field(min_length=1)
    description: str = ""
    frame: FrameSpec
    extruder: Extruder = Extruder()
    temperatures: Temperatures = Temperatures()
    motion: Motion = Motion()
    layers: Layers = Layers()
    retraction: Retraction = Retraction()
    fan_percent: float = Field(50.0, ge=0, le=100, description="part cooling fan while printing")
    park_lift: float = Field(20.0, ge=0, description="mm lifted above the fabric when parked")
    alignment: AlignmentTolerance = AlignmentTolerance()
    adjust: Adjustments = Adjustments()
    gcode: Snippets = Snippets()

    @model_validator(mode="after")
    def _adjustments_within(self) -> "PrinterProfile":
        """The top speed override keeps the programs' own speeds within the maxima; the lowest
        nozzle target allowed while printing is below the print temperature."""
        top, mo, t = self.adjust.speed_percent[1] / 100.0, self.motion, self.temperatures
        for name, limit in (("print_speed", "max_xy_speed"), ("travel_speed", "max_xy_speed"),
                            ("z_speed", "max_z_speed")):
            if getattr(mo, name) * top > getattr(mo, limit) + 1e-9:
                raise ValueError(f"adjust.speed_percent's top {top * 100:g} % takes motion.{name} "
                                 f"({getattr(mo, name):g} mm/s) above motion.{limit} ({getattr(mo, limit):g} mm/s)")
        if self.adjust.nozzle_min > t.nozzle:
            raise ValueError(f"adjust.nozzle_min = {self.adjust.nozzle_min:g} °C must be at most the print "
                             f"temperature (temperatures.nozzle = {t.nozzle:g} °C)")
        return self


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
