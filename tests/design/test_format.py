"""design.json: the models follow the format document key for key and refuse inconsistent content."""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pytest

from ribbond.design.format import (
    FORMAT,
    Design,
    Faces,
    Parameters,
    PrintReport,
    Report,
    Ribbon,
    RibbonsReport,
    Source,
    design_from_json,
    design_to_json,
)
from ribbond.design.params import DesignParameters

# The keys of the example in /work/shared/design-format.md, section by section.
DOC_TOP = {"format", "units", "source", "parameters", "faces", "ribbons", "registration_marks", "report"}
DOC_SOURCE = {"file", "sha256", "faces"}
DOC_PARAMETERS = {"prestretch", "ribbon_length", "ribbon_width", "sigma1_bounds", "sigma2_bounds",
                  "smoothing_lambda", "min_ribbon_length", "max_trim_angle", "size", "printer_profile",
                  "curvature_table"}
DOC_FACES = {"sigma1", "sigma2", "ribbon_direction", "kappa1"}
DOC_RIBBON = {"side", "points", "thickness", "kappa1", "spacing"}
DOC_REPORT = {"faces", "time_s", "iterations", "k1_deviation_deg", "sigma1_max_dev", "sigma2_max_dev",
              "sigma1_bad_pct", "sigma2_bad_pct", "avg_energy", "timings_s", "ribbons", "print"}
DOC_REPORT_RIBBONS = {"front", "back", "dropped_short", "trimmed_angle", "thickness_clamped",
                      "direction_deviation_deg", "spacing_error_pct"}
DOC_SIDE_PRINT = {"lines", "extrusion_mm", "travel_mm", "time_s", "filament_mm"}

SHA = "ab" * 32


def grid(n: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """An n×n grid of vertices on [0, 10]², a bump in z, 2 (n-1)² counter-clockwise triangles."""
    x, y = np.meshgrid(np.linspace(0, 10, n), np.linspace(0, 10, n))
    V = np.column_stack([x.ravel(), y.ravel(), 0.02 * (x.ravel() - 5) ** 2 - 0.01 * (y.ravel() - 5) ** 2])
    F = []
    for j in range(n - 1):
        for i in range(n - 1):
            a, b, c, d = j * n + i, j * n + i + 1, (j + 1) * n + i + 1, (j + 1) * n + i
            F += [(a, b, c), (a, c, d)]
    return V, np.array(F, dtype=np.int64)


def make_design(m: int, *, ribbons: bool = True, prints: bool = True, **report: Any) -> Design:
    """A design for m faces: σ1 = 1.1, σ2 = 1.4, ribbons along x, κ1 alternating in sign."""
    angle = np.linspace(0, 1, m)
    kappa = np.where(np.arange(m) % 2 == 0, 0.031, -0.02)
    faces = Faces.from_arrays(np.full(m, 1.1), np.full(m, 1.4), np.column_stack([np.cos(angle), np.sin(angle)]),
                              kappa)
    ribbon_list = [Ribbon(side="front", points=[(0.5, 1.0), (8.0, 1.5)], thickness=0.6, kappa1=0.031,
                          spacing=(22.9, 6.1)),
                   Ribbon(side="back", points=[(0.5, 4.0), (4.0, 4.2), (9.0, 4.1)], thickness=0.4,
                          kappa1=-0.02, spacing=(21.0, 5.0))]
    side = {"lines": 10, "extrusion_mm": 12.5, "travel_mm": 3.25, "time_s": 60.0, "filament_mm": 0.75}
    fields: dict[str, Any] = dict(
        faces=m, time_s=1.9, iterations=412, k1_deviation_deg=0.21, sigma1_max_dev=0.004,
        sigma2_max_dev=0.002, sigma1_bad_pct=3.1, sigma2_bad_pct=6.0, avg_energy=0.17,
        timings_s={"load": 0.01, "curvature": 0.1, "flatten": 1.2},
        ribbons=RibbonsReport(front=1, back=1, dropped_short=4, trimmed_angle=2, thickness_clamped=0,
                              direction_deviation_deg={"median": 1.1, "p95": 6.0},
                              spacing_error_pct={"median": 2.0, "p95": 9.0}) if ribbons else None,
        print_=PrintReport(front=side, back=side) if prints else None)
    fields.update(report)
    return Design(
        source=Source(file="saddle.obj", sha256=SHA, faces=m + 3),
        parameters=Parameters.resolved(DesignParameters(), 110.0),
        faces=faces,
        ribbons=ribbon_list if ribbons else None,
        registration_marks=[(-5.0, -5.0), (15.0, -5.0)] if ribbons else None,
        report=Report(**fields))


def as_dict(design: Design) -> dict[str, Any]:
    return json.loads(design_to_json(design))


def test_round_trip_is_exact() -> None:
    design = make_design(8, converged=True, time_per_iteration_s=0.0046)
    again = design_from_json(design_to_json(design))
    assert again == design
    assert design_to_json(again) == design_to_json(design)
    s1, s2, d, k = again.faces.arrays()
    assert d.shape == (8, 2) and np.allclose(np.hypot(d[:, 0], d[:, 1]), 1.0)
    assert np.array_equal(k, np.where(np.arange(8) % 2 == 0, 0.031, -0.02))


def test_keys_are_the_documented_ones() -> None:
    data = as_dict(make_design(8))
    assert set(data) == DOC_TOP
    assert data["format"] == FORMAT == "ribbond-design/4" and data["units"] == "mm"
    assert set(data["source"]) == DOC_SOURCE
    assert set(data["parameters"]) == DOC_PARAMETERS
    assert data["parameters"]["size"] == {"bbox_diagonal": 110.0}
    assert data["parameters"]["sigma1_bounds"] == [1.0, 1.3]
    assert len(data["parameters"]["sigma2_bounds"]) == 2  # filled in by DesignParameters
    assert set(data["faces"]) == DOC_FACES
    assert all(set(r) == DOC_RIBBON for r in data["ribbons"])
    assert set(data["report"]) == DOC_REPORT  # the engine's extra fields are None here: left out
    assert set(data["report"]["ribbons"]) == DOC_REPORT_RIBBONS
    assert data["report"]["ribbons"]["spacing_error_pct"] == {"median": 2.0, "p95": 9.0}
    assert set(data["report"]["print"]) == {"front", "back"}
    assert set(data["report"]["print"]["back"]) == DOC_SIDE_PRINT
    assert data["faces"]["ribbon_direction"][0] == [1.0, 0.0]
    assert data["registration_marks"] == [[-5.0, -5.0], [15.0, -5.0]]


def test_format_1_files_are_still_read() -> None:
    # format 2 only adds report fields: a format-1 file reads as it was written
    design = design_from_json(edited(lambda d: d.update(format="ribbond-design/1")))
    assert design.format == "ribbond-design/1" and design.report.field_k1_deviation_deg is None


def test_format_2_report_fields_round_trip() -> None:
    from ribbond.design.format import DeployedReport, Deviation, DeviationPct, Report
    d = make_design(8)
    report = Report(**{**d.report.model_dump(by_alias=True),
                       "field_k1_deviation_deg": Deviation(median=0.1, mean=0.2, p95=0.5),
                       "ribbon_k1_deviation_deg": Deviation(median=0.8, mean=1.0, p95=3.0),
                       "umbilic_pct": 12.5,
                       "deployed": DeployedReport(deviation_pct=DeviationPct(mean=0.4, p99=1.2, max=1.5),
                                                  faces=6000, iterations=12, time_s=2.5, start="target")})
    d2 = d.updated(report=report)
    data = json.loads(design_to_json(d2))["report"]
    assert data["field_k1_deviation_deg"] == {"median": 0.1, "mean": 0.2, "p95": 0.5}
    assert data["deployed"]["deviation_pct"] == {"mean": 0.4, "p99": 1.2, "max": 1.5}
    assert design_from_json(design_to_json(d2)) == d2


def test_print_key_is_spelled_print() -> None:
    text = design_to_json(make_design(8))
    assert '"print":' in text and "print_" not in text
    # and it is read back under that name
    assert design_from_json(text).report.print_ is not None


def test_optional_sections_are_omitted() -> None:
    data = as_dict(make_design(8, ribbons=False, prints=False))
    assert set(data) == DOC_TOP - {"ribbons", "registration_marks"}
    assert set(data["report"]) == DOC_REPORT - {"ribbons", "print"}
    assert "null" not in design_to_json(make_design(8, ribbons=False, prints=False))
    data = as_dict(make_design(8, converged=False, time_per_iteration_s=0.25))
    assert data["report"]["converged"] is False and data["report"]["time_per_iteration_s"] == 0.25


def test_per_face_arrays_are_one_line_each() -> None:
    text = design_to_json(make_design(50))
    lines = text.splitlines()
    for key in DOC_FACES:
        assert sum(f'"{key}": [' in line for line in lines) == 1
    assert len(lines) == len(design_to_json(make_design(8)).splitlines())  # independent of the face count


def test_parameters_require_the_size() -> None:
    data = DesignParameters().model_dump()
    with pytest.raises(ValueError, match="size"):
        Parameters(**data)  # size None
    assert Parameters.resolved(DesignParameters(), 80).size.bbox_diagonal == 80.0


def edited(change: Any) -> str:
    data = as_dict(make_design(8))
    change(data)
    return json.dumps(data)


def test_wrong_format_is_refused_by_name() -> None:
    with pytest.raises(ValueError, match=r"design\.json.*format.*'ribbond-design/5'"):
        design_from_json(edited(lambda d: d.update(format="ribbond-design/5")))
    with pytest.raises(ValueError, match="format"):
        Design(**{**make_design(8).__dict__, "format": "other/1"})


@pytest.mark.parametrize("change, pattern", [
    (lambda d: d["faces"]["sigma2"].pop(), r"faces.*sigma2 has 7 values but sigma1 has 8"),
    (lambda d: d["faces"]["kappa1"].append(0.1), r"faces.*kappa1 has 9 values"),
    (lambda d: d["faces"]["sigma1"].__setitem__(3, -1.0), r"faces.*sigma1\[3\].*> 0"),
    (lambda d: d["faces"]["ribbon_direction"].__setitem__(5, [1.0, 0.1]), r"faces.*ribbon_direction\[5\].*unit"),
    (lambda d: d["report"].update(faces=9), r"report\.faces = 9 but faces has 8"),
    (lambda d: d["ribbons"][1].update(side="front"), r"ribbons\[1\].*kappa1"),
    (lambda d: d["ribbons"][0].update(points=[[0, 0]]), r"ribbons\[0\]\.points"),
    (lambda d: d["ribbons"][0].update(thickness=0), r"ribbons\[0\]\.thickness"),
    (lambda d: d["report"]["ribbons"].update(front=7), r"report\.ribbons counts front = 7"),
    (lambda d: d.update(units="in"), r"units"),
    (lambda d: d["report"].update(surprise=1), r"report\.surprise"),
    (lambda d: d["parameters"].update(size=None), r"parameters\.size"),
    (lambda d: d["source"].update(sha256="xyz"), r"source\.sha256"),
    (lambda d: d["report"].pop("timings_s"), r"report\.timings_s"),
])
def test_invalid_content_names_the_field(change: Any, pattern: str) -> None:
    with pytest.raises(ValueError, match=r"^where\.json: invalid design: .*" + pattern):
        design_from_json(edited(change), where="where.json")


def test_nan_is_refused() -> None:
    text = edited(lambda d: d["faces"]["kappa1"].__setitem__(2, float("nan")))
    with pytest.raises(ValueError, match=r"design\.json: not valid JSON.*NaN"):
        design_from_json(text)
    with pytest.raises(ValueError, match=r"(?s)kappa1\.2.*finite"):
        Faces(sigma1=[1.0] * 3, sigma2=[1.0] * 3, ribbon_direction=[(1.0, 0.0)] * 3,
              kappa1=[0.0, 0.0, float("nan")])
    with pytest.raises(ValueError, match="avg_energy"):
        Report(**{**make_design(8).report.__dict__, "avg_energy": float("inf")})


def test_ribbon_side_follows_kappa_sign() -> None:
    design = make_design(8)
    flat = Ribbon(side="front", points=[(0, 0), (1, 0)], thickness=0.5, kappa1=0.0, spacing=(20, 5))
    with pytest.raises(ValueError, match=r"ribbons\[2\].*'front' exactly when kappa1 > 0"):
        Design(**{**design.__dict__, "ribbons": [*(design.ribbons or []), flat]})


def test_not_json_and_not_an_object() -> None:
    with pytest.raises(ValueError, match=r"x\.json: not valid JSON"):
        design_from_json("{", where="x.json")
    with pytest.raises(ValueError, match=r"x\.json: expected a JSON object"):
        design_from_json("[1]", where="x.json")


def test_updated_validates_again() -> None:
    design = make_design(8, ribbons=False, prints=False)
    ribbon = Ribbon(side="back", points=[(0, 0), (1, 0)], thickness=0.5, kappa1=-0.1, spacing=(20, 5))
    later = design.updated(ribbons=[ribbon], report=design.report.updated(converged=True))
    assert later.ribbons == [ribbon] and later.report.converged and design.ribbons is None
    with pytest.raises(ValueError, match=r"ribbons\[0\].*kappa1"):
        design.updated(ribbons=[ribbon.model_copy(update={"side": "front"})])
    with pytest.raises(ValueError, match="colour"):
        design.updated(colour="red")
