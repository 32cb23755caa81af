"""The stage optimize's choice of line field (issue 34): on a saddle whose largest |κ| switches family,
the one-family layout is made beside the paper's and the better prediction is kept, its whole design with it.

The predictions are stand-ins (their figures are set here): what is tested is the choice and that the kept
layout is the design, not the model (tests/deploy/test_predict.py).
"""

from __future__ import annotations

import copy
from types import SimpleNamespace

import numpy as np
import pytest

from ribbond.design import surfaces
from ribbond.design.errors import DesignError
from ribbond.design.params import DesignParameters, SizeSpec, SolverSettings
from ribbond.design.stripes import face_areas
from ribbond.mesh.files import write_obj
from ribbond.pipeline import compile as C


def _stand_in(mean: float, worst: float, k: float = -1.0):
    return SimpleNamespace(deviation_pct={"mean": mean, "p99": 2 * mean, "max": 3 * mean}, reached=False,
                           agreement=SimpleNamespace(spread_mean=(mean, worst), curvature_predicted=k,
                                                     curvature_target=-1.3))


@pytest.fixture(scope="module")
def saddle_run(tmp_path_factory):
    """The stages up to the ribbons of a small symmetric saddle (|κ1| = |κ2| at its centre)."""
    V, F = surfaces.saddle(80.0, 1 / 50.0, 1 / 50.0, rings=12)
    path = tmp_path_factory.mktemp("saddle") / "saddle.obj"
    write_obj(path, V, F)

    run = C._prepare(path, DesignParameters(size=SizeSpec(bbox_diagonal=90.0)), SolverSettings(), None,
                     C.NoProgress(), True, None)
    for stage in C.STAGES[:5]:
        C._run_stage(run, stage)
    return lambda: copy.copy(run)                     # the choice replaces a run's attributes, never mutates them


def _sides(run) -> set[str]:
    return {r.side for r in run.ribbons}


def test_the_paper_field_switches_sides_and_the_alternative_is_proposed(saddle_run):
    run = saddle_run()
    assert run.family is not None and not run.line_field.one_family
    assert _sides(run) == {"front", "back"}           # the largest |κ| switches family: both sides


def test_a_better_one_family_prediction_makes_its_layout_the_design(saddle_run, monkeypatch):
    run = saddle_run()
    paper, one = _stand_in(3.0, 3.4), _stand_in(1.0, 1.0, k=-1.1)
    monkeypatch.setattr(C, "_predict", lambda *a, **k: one)
    kept = C._choose_field(run, run.family, paper)
    assert kept is one
    assert run.line_field.one_family
    assert len(_sides(run)) == 1                      # one family of a saddle: one sign of κ, one side
    assert run.design.ribbons == run.ribbons          # the design document is the kept layout's
    np.testing.assert_array_equal(np.array([f for f in run.design.faces.sigma1]), run.flat.sigma[:, 0])
    report = C._field_choice_report(run.field_choice)
    assert report.kept == "one_family" and report.one_family.deviation_pct.mean == 1.0
    assert report.paper.deviation_pct.mean == 3.0 and "3.00 → 1.00" in report.reason
    assert report.switched_pct == pytest.approx(run.family.switched_pct)
    from ribbond.client.cli import _line_field_line
    line = _line_field_line(report)
    assert line.startswith("line field") and "3.00 → 1.00 %" in line and "one family kept" in line


def test_a_worse_one_family_prediction_leaves_the_paper_layout(saddle_run, monkeypatch):
    run = saddle_run()
    ribbons, design = run.ribbons, run.design
    monkeypatch.setattr(C, "_predict", lambda *a, **k: _stand_in(2.0, 9.0))
    kept = C._choose_field(run, run.family, _stand_in(3.0, 3.4))
    assert kept.deviation_pct["mean"] == 3.0
    assert run.ribbons is ribbons and run.design is design and not run.line_field.one_family
    report = C._field_choice_report(run.field_choice)
    assert report.kept == "paper" and "worst release 9.00" in report.reason


def test_a_one_family_layout_that_cannot_be_made_is_reported_and_the_paper_kept(saddle_run, monkeypatch):
    run = saddle_run()
    ribbons = run.ribbons

    def refuse(alt):
        raise DesignError("the flattening folded 3 faces over")
    monkeypatch.setattr(C, "_flatten", refuse)
    paper = _stand_in(3.0, 3.4)
    assert C._choose_field(run, run.family, paper) is paper
    assert run.ribbons is ribbons
    report = C._field_choice_report(run.field_choice)
    assert report.kept == "paper" and report.one_family is None and "folded 3 faces" in report.reason


def test_the_rim_is_measured_short_where_the_plastic_is_taken_off_the_outline(saddle_run):
    """``_along_short``: the realized contraction along the rows by the outline, against Eq. 10's."""
    import shapely
    run = saddle_run()
    outline = shapely.Polygon(run.uv[run.target.boundary])
    ring = shapely.get_coordinates(shapely.line_interpolate_point(
        outline.exterior, np.linspace(0.0, outline.exterior.length, 400, endpoint=False)))
    as_made = C._along_short(run, outline)(ring)
    bare = copy.copy(run)
    bare.ribbons = [r for r in run.ribbons
                    if shapely.distance(outline.exterior, shapely.LineString(r.points)) > 10.0]
    assert 0 < len(bare.ribbons) < len(run.ribbons)
    stripped = C._along_short(bare, outline)(ring)
    assert stripped.mean() > 0.8                       # a bare 10 mm band: every row short by the outline
    assert stripped.mean() > as_made.mean() + 0.3


def test_a_cylinder_whose_rows_reach_its_edges_gets_no_rim(tmp_path):
    """A cylinder's rows run along two straight edges with the pattern's own spacing: no shortfall, no rim
    (a rim there adds plastic the flattening did not ask for and curves the sheet: ∫K ≠ 0)."""
    from ribbond.pipeline.compile import design_mesh
    V, F = surfaces.cylinder_patch(n_around=40, n_along=20)
    path = tmp_path / "cylinder.obj"
    write_obj(path, V, F)
    res = design_mesh(path, DesignParameters(size=SizeSpec(bbox_diagonal=100.0)), predict=False, finish=False)
    assert res.layout.rim == 0 and res.design.report.ribbons.rim == 0


def test_a_size_chosen_to_fit_the_frame_fits_the_one_family_layout(tmp_path, monkeypatch):
    """Without a size the one-family layout too is scaled to the largest that fits the frame (its flat
    sheet is larger than the paper's here) and the curvature table; the target is at that size, the flat sheet at
    least as large as the target (σ ≥ 1), and κ1 is the target's at that size."""
    V, F = surfaces.saddle(80.0, 1 / 50.0, 1 / 50.0, rings=12)
    path = tmp_path / "saddle.obj"
    write_obj(path, V, F)
    run = C._prepare(path, DesignParameters(), SolverSettings(), None, C.NoProgress(), True, None)
    run.unsized = "fit"
    for stage in C.STAGES[:5]:
        C._run_stage(run, stage)
    monkeypatch.setattr(C, "_predict", lambda *a, **k: _stand_in(1.0, 1.0))
    C._choose_field(run, run.family, _stand_in(3.0, 3.4))
    assert run.line_field.one_family, run.field_choice["reason"]
    fits = C.fit_scale(run.uv, run.frame, run.solver.layout_margin)
    assert fits == pytest.approx(1.0) or (fits > 1.0 and run.scale == run.table_scale)   # the frame or the table
    assert C._bbox_diagonal(run.V) == pytest.approx(run.size)
    assert run.design.parameters.size.bbox_diagonal == pytest.approx(run.size)
    e1, e2 = run.V[run.F[:, 1]] - run.V[run.F[:, 0]], run.V[run.F[:, 2]] - run.V[run.F[:, 0]]
    target_area = 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1).sum()
    assert face_areas(run.uv, run.F).sum() >= 0.99 * target_area       # σ1 σ2 ≥ 1: never smaller than the target
    centre = np.argmin(np.linalg.norm(run.V - run.V.mean(axis=0), axis=1))
    faces = np.flatnonzero((run.F == centre).any(axis=1))
    radius = 50.0 * run.size / C._bbox_diagonal(V)                       # κ = ±1/50 at the file's scale
    assert np.abs(run.kappa1[faces]) == pytest.approx(1 / radius, rel=0.1)
