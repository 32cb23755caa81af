"""Parameter checks name the field the user set (issue 16), and the engine refuses designs that
would print nothing instead of writing an empty one."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ribbond.design.errors import DesignError
from ribbond.mesh.files import write_obj
from ribbond.design.params import (DesignParameters, SolverSettings, check_printable, load_settings,
                                   parameters_from_json, settings_from_dict)
from ribbond.pipeline.compile import design_mesh
from ribbond.design.stripes import chain_segments
from ribbond.design.surfaces import saddle
from ribbond.gcode.profiles import load_profile


def refused(data: dict[str, Any]) -> str:
    with pytest.raises(ValueError) as info:
        settings_from_dict(data)
    return str(info.value)


@pytest.mark.parametrize(("data", "expected"), [
    ({"ribbon_length": float("inf")}, "ribbon_length = inf: must be a finite number > 0"),
    ({"ribbon_width": float("nan")}, "ribbon_width = nan: must be a finite number > 0"),
    ({"size": {"bbox_diagonal": float("inf")}}, "size.bbox_diagonal = inf: must be a finite number > 0"),
    ({"max_trim_angle": float("-inf")}, "max_trim_angle = -inf: must be a finite number > 0 and < 90"),
    ({"sigma1_bounds": [1.0, float("nan")]}, "sigma1_bounds[1] = nan: must be a finite number"),
    ({"solver": {"tolerance": float("inf")}}, "solver.tolerance = inf: must be a finite number > 0"),
    ({"solver": {"max_iterations": 0}}, "solver.max_iterations = 0"),
])
def test_non_finite_and_out_of_range_values_name_the_field(data: dict[str, Any], expected: str) -> None:
    message = refused(data)
    assert expected in message
    assert "sigma2_bounds = [" not in message                 # never the derived field


def test_derived_bounds_errors_name_the_fields_the_user_set() -> None:
    width = refused({"ribbon_width": 20.0})                   # wider than the default length 15
    assert "ribbon_width = 20" in width and "ribbon_length = 15" in width and "sigma2_bounds = [" not in width
    long = refused({"ribbon_length": 1e300})
    assert "ribbon_length = 1e+300" in long
    stretch = refused({"prestretch": 1.2})                    # below the default sigma1 upper bound 1.3
    assert "prestretch = 1.2" in stretch and "the default sigma1_bounds" in stretch
    given = refused({"sigma1_bounds": [1.0, 1.7]})            # set by the user: named as theirs
    assert "sigma1_bounds = [1, 1.7]" in given and "default" not in given


def test_unknown_keys_are_refused_by_name() -> None:
    assert "colour: unknown setting" in refused({"colour": "red"})
    solver = refused({"solver": {"max_iteration": 1}})
    assert "solver.max_iteration: unknown setting" in solver and "max_iterations" in solver
    assert "size.diag: unknown setting" in refused({"size": {"bbox_diagonal": 50, "diag": 1}})
    assert "solver = 3" in refused({"solver": 3})


def test_min_ribbon_length_beyond_the_longest_ribbon_is_refused() -> None:
    message = refused({"min_ribbon_length": 1e9})
    assert "min_ribbon_length = 1e+09" in message and "ribbon_length = 15" in message
    assert settings_from_dict({"min_ribbon_length": 15.0}).parameters.min_ribbon_length == 15.0


def test_the_solver_table_is_read_and_kept(tmp_path: Path) -> None:
    path = tmp_path / "p.toml"
    path.write_text("ribbon_length = 12.0\n[solver]\nmax_iterations = 1\n", encoding="utf-8")
    settings = load_settings(path)
    assert settings.parameters.ribbon_length == 12.0 and settings.solver.max_iterations == 1
    path.write_text("ribbon_length = inf\n", encoding="utf-8")
    with pytest.raises(ValueError, match=r"p\.toml: invalid parameters: ribbon_length = inf: must be a finite"):
        load_settings(path)


def test_check_printable_measures_against_the_printer() -> None:
    profile = load_profile("ultimaker2-tpu")
    frame, nozzle = profile.frame.size, profile.extruder.nozzle_diameter
    check_printable(DesignParameters(), frame, nozzle)        # the defaults print
    diagonal = float(np.hypot(*frame))
    cases = {
        "ribbon_length": DesignParameters(ribbon_length=diagonal + 1, min_ribbon_length=2.0),
        "ribbon_width": DesignParameters(ribbon_width=nozzle / 2),
        "size.bbox_diagonal": DesignParameters(size={"bbox_diagonal": 1e-9}),
    }
    for field, params in cases.items():
        with pytest.raises(ValueError, match=field.replace(".", r"\.") + " = "):
            check_printable(params, frame, nozzle)


def test_chaining_no_segments_gives_no_polylines() -> None:
    """No isoline crossed the domain (a design too small for a ribbon): empty, not a scipy error."""
    pl = chain_segments(3, np.empty((0, 2), dtype=np.int64), np.empty(0, dtype=np.int64))
    assert len(pl.nodes) == 0 and list(pl.offsets) == [0] and len(pl.link_face) == 0


@pytest.fixture(scope="module")
def mesh(tmp_path_factory: pytest.TempPathFactory) -> Path:
    V, F = saddle(80.0, 1 / 50, 1 / 50, rings=13)
    path = tmp_path_factory.mktemp("params-checks") / "saddle.obj"
    write_obj(path, V, F)
    return path


def test_a_design_without_ribbons_is_refused(mesh: Path) -> None:
    # larger than a ribbon's width (check_printable passes), far too small for one ribbon
    with pytest.raises(DesignError, match="no ribbons") as info:
        design_mesh(mesh, DesignParameters(size={"bbox_diagonal": 2.0}), predict=False)
    assert "size" in str(info.value)


def test_degenerate_sizes_are_refused_before_any_work(mesh: Path) -> None:
    with pytest.raises(DesignError, match=r"size\.bbox_diagonal = 1e-09 mm"):
        design_mesh(mesh, DesignParameters(size={"bbox_diagonal": 1e-9}), SolverSettings(), predict=False)


@pytest.mark.parametrize("text, program, problem", [
    ("[1", False, "parameters: not valid JSON"),
    ("[1, 2]", False, "parameters: expected a JSON object"),
    ('{"prestretch": 1.5}', True, "parameters: a G-code program takes no design parameters"),
])
def test_parameters_from_json_names_the_field_and_the_problem(text: str, program: bool, problem: str) -> None:
    with pytest.raises(ValueError, match=problem):
        parameters_from_json(text, program=program)


def test_parameters_from_json_takes_an_object_and_a_program_without_any() -> None:
    assert parameters_from_json('{"prestretch": 1.5}') == {"prestretch": 1.5}
    assert parameters_from_json("{}", field="userdata", program=True) == {}
