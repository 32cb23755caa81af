"""The shipped printer profiles, pinned against the hardware and materials they stand for, and the
validator that refuses a profile against itself (issue 35 item 4: a typo in ``nozzle_max`` or the
frame's width, or a bed target above ``bed_max``, must fail here). The numbers below are not copies of
the TOML files: each is the documented fact the file's number stands for (docs/designing.md, "What the
shipped profiles' numbers stand for"), with its source."""

from __future__ import annotations

from pathlib import Path

import pytest
from pydantic import ValidationError

from ribbond.gcode.profiles import (PROFILE_DIR, FrameSpec, Motion, PrinterProfile, Temperatures,
                                    available_profiles, load_profile)

# The paper's printer (§7) and Ultimaker's specification of the Ultimaker 2.
UM2_NOZZLE_RANGE = (180.0, 260.0)        # °C, the hot end's rated range
UM2_BED_RANGE = (50.0, 100.0)            # °C, the heated build plate's rated range
UM2_PLATE = (223.0, 223.0)               # mm, the build volume's X and Y
UM2_FILAMENT = 2.85                      # mm
UM2_MAX_SPEED = 300.0                    # mm/s, the fastest travel Ultimaker rates it for
PAPER_NOZZLE, PAPER_SPEED = 0.8, 15.0    # mm, mm/s (§7: "a large printing nozzle (0.8mm) ... (15mm/s)")
# Marlin's default Configuration.h: HEATER_0_MAXTEMP 275 with HOTEND_OVERSHOOT 15, BED_MAXTEMP 150 with
# BED_OVERSHOOT 10: the firmware refuses targets above MAXTEMP - OVERSHOOT.
MARLIN_NOZZLE_TARGET_MAX = 275.0 - 15.0
MARLIN_BED_TARGET_MAX = 150.0 - 10.0
GENERIC_BED = (220.0, 220.0)             # mm, the generic printer's bed ("a 220 x 220 mm bed")
GENERIC_FILAMENT = 1.75
# The reversible fabric frame (both profiles carry the same frame): a 180 mm printable square.
FRAME_SIDE = 180.0


def _inside_plate(frame: FrameSpec, plate: tuple[float, float]) -> bool:
    x0, y0, x1, y1 = frame.bounds
    return 0.0 <= x0 and x1 <= plate[0] and 0.0 <= y0 and y1 <= plate[1]


def test_the_shipped_profiles_are_the_two_documented() -> None:
    assert available_profiles() == ["generic-marlin", "ultimaker2-tpu"]


def test_the_ultimaker_profile_is_the_papers_printer() -> None:
    p = load_profile("ultimaker2-tpu")
    t = p.temperatures
    assert t.nozzle_max == UM2_NOZZLE_RANGE[1] and t.bed_max == UM2_BED_RANGE[1]
    assert UM2_NOZZLE_RANGE[0] <= t.nozzle <= UM2_NOZZLE_RANGE[1]
    assert p.extruder.filament_diameter == UM2_FILAMENT and p.extruder.nozzle_diameter == PAPER_NOZZLE
    assert p.motion.print_speed == PAPER_SPEED and p.motion.max_xy_speed <= UM2_MAX_SPEED
    assert _inside_plate(p.frame, UM2_PLATE)


def test_the_generic_profile_stays_within_marlins_default_targets() -> None:
    p = load_profile("generic-marlin")
    t = p.temperatures
    assert t.nozzle_max == MARLIN_NOZZLE_TARGET_MAX and t.bed_max <= MARLIN_BED_TARGET_MAX
    assert p.extruder.filament_diameter == GENERIC_FILAMENT
    assert _inside_plate(p.frame, GENERIC_BED)


@pytest.mark.parametrize("name", ["generic-marlin", "ultimaker2-tpu"])
def test_every_shipped_profile_carries_the_fabric_frame_and_keeps_the_bed_off(name: str) -> None:
    p = load_profile(name)
    assert p.frame.size == (FRAME_SIDE, FRAME_SIDE)
    x0, y0, x1, y1 = p.frame.bounds
    assert (x1 - x0, y1 - y0) == (FRAME_SIDE, FRAME_SIDE)
    assert p.temperatures.bed == 0.0          # the fabric lies on the frame's base, not on the bed
    assert p.layers.first_layer_height < p.extruder.nozzle_diameter


# ---------------------------------------------------------------------------------- the validator


def test_frame_bounds_of_a_rectangle_off_the_origin() -> None:
    assert FrameSpec(center=(100.0, 60.0), size=(120.0, 40.0)).bounds == (40.0, 40.0, 160.0, 80.0)


@pytest.mark.parametrize("size", [(0.0, 10.0), (10.0, 0.0), (-5.0, 10.0), (10.0, -1.0)])
def test_a_frame_without_area_is_refused(size: tuple[float, float]) -> None:
    with pytest.raises(ValidationError, match=r"frame size .* must be positive"):
        FrameSpec(center=(0.0, 0.0), size=size)


def test_targets_up_to_their_maximum_load_and_above_it_are_refused() -> None:
    Temperatures(nozzle=260.0, nozzle_max=260.0, bed=100.0, bed_max=100.0)
    with pytest.raises(ValidationError, match="nozzle = 260.5 °C exceeds nozzle_max = 260.0 °C"):
        Temperatures(nozzle=260.5, nozzle_max=260.0)
    with pytest.raises(ValidationError, match="bed = 100.5 °C exceeds bed_max = 100.0 °C"):
        Temperatures(bed=100.5, bed_max=100.0)


def test_a_profile_file_whose_bed_target_exceeds_its_bed_max_is_refused(tmp_path: Path) -> None:
    text = (PROFILE_DIR / "ultimaker2-tpu.toml").read_text(encoding="utf-8")
    path = tmp_path / "hot-bed.toml"
    path.write_text(text.replace("bed = 0.0 ", "bed = 101.0 ", 1), encoding="utf-8")
    with pytest.raises(ValueError, match=r"hot-bed\.toml: invalid printer profile: .*bed = 101.0 °C exceeds bed_max"):
        load_profile(path)


@pytest.mark.parametrize(("speed", "limit"), [("print_speed", "max_xy_speed"), ("travel_speed", "max_xy_speed"),
                                              ("z_speed", "max_z_speed"), ("retract_speed", "max_e_speed")])
def test_a_speed_above_its_firmware_maximum_is_refused(speed: str, limit: str) -> None:
    base = Motion().model_dump()
    Motion(**{**base, speed: base[limit]})
    with pytest.raises(ValidationError, match=f"{speed} = {base[limit] + 1} mm/s exceeds {limit} = {base[limit]} mm/s"):
        Motion(**{**base, speed: base[limit] + 1})


def test_a_profile_needs_a_name_and_a_frame_and_no_unknown_fields() -> None:
    frame = {"center": (0.0, 0.0), "size": (1.0, 1.0)}
    with pytest.raises(ValidationError):
        PrinterProfile(name="", frame=frame)
    with pytest.raises(ValidationError):
        PrinterProfile(name="x", frame=frame, nozzle_max=300)
    with pytest.raises(ValidationError):
        PrinterProfile(name="x", frame=frame, temperatures={"nozzle": float("nan")})


def test_an_unknown_profile_name_is_refused_naming_the_shipped_ones() -> None:
    with pytest.raises(ValueError, match="unknown printer profile 'nope'; shipped: .*ultimaker2-tpu"):
        load_profile("nope")
