"""A project of panels (ribbond.panels.project): a hemisphere one sheet cannot make, cut, designed, written."""

from __future__ import annotations

import json

import numpy as np
import pytest
import shapely

from ribbond.deploy.predict import interpolate
from ribbond.design import surfaces
from ribbond.design.errors import DesignError
from ribbond.design.folder import read_design_folder
from ribbond.mesh.files import write_obj
from ribbond.design.params import DesignParameters, SolverSettings
from ribbond.panels.project import MAX_BAD_PCT, PROJECT_FILE, design_project, write_project
from ribbond.gcode.profiles import load_profile

RADIUS = 50.0
SOLVER = SolverSettings(refine_below_faces=0)           # 2,400 faces as they are: a quicker test


@pytest.fixture(scope="module")
def hemisphere(tmp_path_factory):
    path = tmp_path_factory.mktemp("hemi") / "hemisphere.obj"
    write_obj(path, *surfaces.sphere_cap(RADIUS, 90.0, rings=20))
    return path


@pytest.fixture(scope="module")
def project(hemisphere):
    return design_project(hemisphere, DesignParameters(), SOLVER, panels=5, predict=False)   # auto finds 5 here


def test_a_hemisphere_needs_panels_and_each_is_within_the_bounds_and_the_frame(project):
    assert project.cut.count == 5 and project.cut.feasible
    frame = load_profile(DesignParameters().printer_profile).frame
    x0, y0, x1, y1 = frame.bounds
    for panel in project.panels:
        r = panel.result.design.report
        bad = np.maximum(r.sigma1_bad_pct, r.sigma2_bad_pct)
        assert bad <= MAX_BAD_PCT + 1e-9
        lo, hi = panel.result.flat_uv.min(axis=0), panel.result.flat_uv.max(axis=0)
        room = project.seam_allowance * 1.6                         # the allowance on the stretched fabric
        assert lo[0] - room >= x0 and lo[1] - room >= y0 and hi[0] + room <= x1 and hi[1] + room <= y1


def test_the_panels_keep_the_target_whole_and_at_its_scale(project):
    faces = np.concatenate([p.face_index for p in project.panels])
    assert np.array_equal(np.sort(faces), np.arange(len(project.F)))       # every face in one panel
    for p in project.panels:                                               # at the target's scale, not refit
        assert np.allclose(p.result.V[p.local] + p.offset, project.V[p.vertex_index], atol=1e-6)


def test_seams_are_great_circle_arcs_joining_all_panels(project):
    """Gores of a sphere meet along great circles: each seam (straightened, not the mesh's zigzag) is
    as long as the arc between its ends, and the seams join every panel into one piece to sew."""
    joined = {0}
    for _ in project.seams:
        joined |= {p for s in project.seams if set(s.panels) & joined for p in s.panels}
    assert joined == set(range(project.cut.count))
    centre = project.V[:, :2].mean(axis=0)
    base = project.V[:, 2].min()
    for seam in project.seams:
        P = project.V[seam.vertices] - np.r_[centre, base]                 # the sphere's centre at the rim plane
        ends = P[[0, -1]] / np.linalg.norm(P[[0, -1]], axis=1)[:, None]
        arc = RADIUS * np.arccos(np.clip(ends[0] @ ends[1], -1, 1))
        if arc > 20.0:
            assert seam.target_length == pytest.approx(arc, rel=0.01)
        for side, flat in zip(seam.panels, seam.flat):                     # on each panel's flat outline
            outline = project.panels[side].outline()
            d = np.linalg.norm(flat[:, None] - outline[None], axis=2).min(axis=1)
            assert d.max() < 1e-9
        assert len(seam.marks[0]) == len(seam.marks[1]) >= 1


def test_the_project_folder(project, tmp_path):
    out = write_project(project, tmp_path / "bowl")
    doc = json.loads((out / PROJECT_FILE).read_text())
    assert doc["format"] == "ribbond-project/1" and doc["report"]["panels"] == project.cut.count
    assert [p["folder"] for p in doc["panels"]] == [f"panel-{k}" for k in range(1, project.cut.count + 1)]
    for entry in doc["panels"]:
        folder = read_design_folder(out / entry["folder"])
        assert len(folder.design.ribbons) == entry["ribbons"] > 0
        assert (out / entry["folder"] / "front.gcode").stat().st_size > 0
    assert {tuple(s["panels"]) for s in doc["seams"]} == {tuple(sorted((a + 1, b + 1))) for a, b in
                                                         (s.panels for s in project.seams)}
    assert (out / "panels.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    write_project(project, out)                                            # a project folder is replaced
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("mine")
    with pytest.raises(ValueError, match="not a project folder"):
        write_project(project, tmp_path / "other")
    assert (tmp_path / "other" / "notes.txt").read_text() == "mine"


def test_bad_requests_are_refused_naming_the_setting(hemisphere):
    with pytest.raises(DesignError, match="panels = 0"):
        design_project(hemisphere, panels=0)
    with pytest.raises(DesignError, match="seam_allowance"):
        design_project(hemisphere, seam_allowance=-1.0)
    with pytest.raises(DesignError, match="2 panels leave"):
        design_project(hemisphere, solver=SOLVER, panels=2, predict=False)


def test_stitch_marks_pin_the_same_points_of_the_target_on_both_sides(project):
    """Without a prediction the marks sit at matched fractions of the target's seam length: mapped back
    through each panel's flattening, mark A3 of one side and A3 of the other are the same target point."""
    tick = project.seam_allowance * 1.6
    for seam in project.seams:
        where = []
        for side, marks in zip(seam.panels, seam.marks):
            r = project.panels[side].result
            where.append(interpolate(marks, r.flat_uv, r.F, r.V + project.panels[side].offset))
        assert np.linalg.norm(where[0] - where[1], axis=1).max() < 0.05
    for k, panel in enumerate(project.panels):
        marks = panel.result.design.stitch_marks
        mine = [s for s in project.seams if k in s.panels]
        assert sorted(m.label for m in marks) == sorted(f"{s.label}{j + 1}" for s in mine for j in range(len(s.marks[0])))
        outline = panel.outline()
        for m in marks:
            tick_end = np.asarray(m.strokes[0][-1])
            assert np.linalg.norm(tick_end - np.asarray(m.at)) == pytest.approx(tick)
            assert not shapely.Polygon(outline).contains(shapely.Point(*tick_end))                                      # the tick reaches out into the allowance
        front = panel.result.programs.front.text
        assert front.count(";TYPE:STITCH") == len(marks)
        assert ";TYPE:STITCH" not in panel.result.programs.back.text


def test_one_sheet_says_how_many_panels_auto_would_make(tmp_path):
    """The verdict of a design one sheet cannot make (a 120° cap: a quarter of its faces out of bounds)
    names the panel count, found by the same cut as --panels auto."""
    from ribbond.pipeline.compile import design_mesh
    from ribbond.design.verdict import verdict_lines
    write_obj(tmp_path / "cap.obj", *surfaces.sphere_cap(RADIUS, 60.0, rings=12))
    r = design_mesh(tmp_path / "cap.obj", DesignParameters(), SOLVER, predict=False)
    n = r.design.report.panels_suggested
    assert max(r.design.report.sigma1_bad_pct, r.design.report.sigma2_bad_pct) > MAX_BAD_PCT
    assert n is not None and n >= 2
    lines = verdict_lines(r.design.model_dump(by_alias=True))
    assert any(f"--panels auto would cut it into about {n} panels" in line for line in lines), lines
    project = design_project(tmp_path / "cap.obj", DesignParameters(size=r.design.parameters.size), SOLVER,
                             predict=False)
    assert 2 <= project.cut.count <= n                 # the quick search's count, or fewer on the whole mesh
