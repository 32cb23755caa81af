"""``ribbonctl predict DESIGN_DIR``: the real command in a subprocess, on a small design folder made
here with ``ribbonctl design`` (a cylinder patch of 256 faces, ~2 s).

Expectations follow from the files and the physics of the layout: the written report matches the
written ``deployed.obj`` (its distance to ``target.obj`` measured here with libigl), ribbons made
thinner or a table with half the curvature bend the sheet less (the table's κ rises with τ), so the
cylinder is missed by more; refused input leaves every file byte for byte and inode for inode.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path
from typing import Any

import igl
import numpy as np
import pytest

from ribbond.design import surfaces
from ribbond.design.folder import read_design_folder
from ribbond.design.format import DeployedReport
from ribbond.mesh.files import read_mesh, write_obj
from ribbond.design.thickness import TABLE_DIR

ROOT = Path(__file__).resolve().parents[2]
TABLE = "tpu95a-lycra-default"
KEPT = ("target.obj", "flat.obj", "front.gcode", "back.gcode", "combined.gcode", "preview.png", "preview.svg")


def ribbonctl(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "ribbond.client.cli", *args], cwd=ROOT, capture_output=True,
                          text=True, timeout=300)


@pytest.fixture(scope="module")
def made(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A cylinder patch (radius 40 mm, 120°, 60 mm high) designed at 70 mm, with its prediction."""
    d = tmp_path_factory.mktemp("predict")
    V, F = surfaces.cylinder_patch(40.0, 120.0, 60.0, n_around=16, n_along=8)
    write_obj(d / "cyl.obj", V, F)
    r = ribbonctl("design", str(d / "cyl.obj"), "-o", str(d / "design"), "--size", "70", "-q", "--no-optimize")
    assert r.returncode == 0, r.stderr
    return d / "design"


@pytest.fixture
def folder(made: Path, tmp_path: Path) -> Path:
    out = tmp_path / "design"
    shutil.copytree(made, out)
    return out


def snapshot(folder: Path) -> dict[str, tuple[bytes, int]]:
    """Every file's bytes and inode."""
    return {p.name: (p.read_bytes(), p.stat().st_ino) for p in folder.iterdir()}


def edit(folder: Path, change: Any) -> None:
    path = folder / "design.json"
    data = json.loads(path.read_text())
    change(data)
    path.write_text(json.dumps(data))


def mean_deviation_pct(folder: Path) -> float:
    """Mean distance of deployed.obj's vertices to target.obj's surface, % of the target's diagonal."""
    V, F = read_mesh(folder / "target.obj")
    P, _ = read_mesh(folder / "deployed.obj")
    d2, _, _ = igl.point_mesh_squared_distance(P, V, F.astype(np.int64))
    return float(100.0 * np.sqrt(d2).mean() / np.linalg.norm(V.max(axis=0) - V.min(axis=0)))


def deployed(folder: Path) -> dict[str, Any]:
    return json.loads((folder / "design.json").read_text())["report"]["deployed"]


def test_predict_replaces_the_prediction_and_links_the_rest(folder: Path) -> None:
    before = snapshot(folder)
    r = ribbonctl("predict", str(folder))
    assert r.returncode == 0, r.stderr
    after = snapshot(folder)
    assert set(after) == set(before)
    for name in KEPT:                                 # never written again: the same files (inodes)
        assert after[name] == before[name], name
    for name in ("design.json", "deployed.obj", "deployed.png"):
        assert after[name][1] != before[name][1], f"{name} was not replaced"
    dep = deployed(folder)
    # the report describes the written shape: its mean deviation is deployed.obj's distance to target.obj
    assert dep["deviation_pct"]["mean"] == pytest.approx(mean_deviation_pct(folder), rel=0.02, abs=0.01)
    assert re.search(r"^deviation +mean [0-9.]+ %", r.stdout, re.M)
    assert re.search(r"^verdict ", r.stdout, re.M)
    assert str(folder / "deployed.obj") in r.stdout
    assert "predict" in r.stderr                      # progress on stderr
    assert not [p for p in folder.parent.iterdir() if p.name.startswith(".")]   # no leftovers
    read_design_folder(folder)                        # still a valid design folder


def test_edited_thicknesses_are_what_is_predicted(folder: Path) -> None:
    """Ribbons edited in design.json to the table's thinnest τ bend less (κ rises with τ): the
    cylinder is missed by more than with the thicknesses the design chose."""
    assert ribbonctl("predict", str(folder)).returncode == 0
    designed = deployed(folder)["deviation_pct"]["mean"]
    thin = shipped()["thickness"][0]

    def thinner(data: dict[str, Any]) -> None:
        for rb in data["ribbons"]:
            assert rb["thickness"] > thin
            rb["thickness"] = thin
    edit(folder, thinner)
    r = ribbonctl("predict", str(folder))
    assert r.returncode == 0, r.stderr
    assert deployed(folder)["deviation_pct"]["mean"] > designed + 0.5
    assert json.loads((folder / "design.json").read_text())["ribbons"][0]["thickness"] == thin


def shipped() -> dict[str, Any]:
    return tomllib.loads((TABLE_DIR / f"{TABLE}.toml").read_text(encoding="utf-8"))


def half_table(tmp_path: Path) -> Path:
    """The shipped table with every κ halved, named ``half``."""
    t = shipped()
    rows = lambda side: "[" + ", ".join(str([k / 2 for k in row]) for row in t[side]) + "]"  # noqa: E731
    path = tmp_path / "half.toml"
    path.write_text(f'name = "half"\nprestretch = {t["prestretch"]!r}\nthickness = {t["thickness"]}\n'
                    f'spacing = {t["spacing"]}\nfront = {rows("front")}\nback = {rows("back")}\n')
    return path


def test_another_table_changes_only_the_prediction(folder: Path, tmp_path: Path) -> None:
    assert ribbonctl("predict", str(folder)).returncode == 0
    own = deployed(folder)["deviation_pct"]["mean"]
    before = json.loads((folder / "design.json").read_text())
    r = ribbonctl("predict", str(folder), "--table", str(half_table(tmp_path)))
    after = json.loads((folder / "design.json").read_text())
    if "table" not in DeployedReport.model_fields:    # the format cannot say which table: refused
        assert r.returncode == 2 and "report.deployed.table" in r.stderr
        assert after == before
        return
    assert r.returncode == 0, r.stderr
    assert after["report"]["deployed"]["table"] == "half"
    assert after["report"]["deployed"]["deviation_pct"]["mean"] > own   # half the curvature: flatter
    assert after["parameters"]["curvature_table"] == TABLE
    assert after["ribbons"] == before["ribbons"]


@pytest.mark.parametrize("problem", ["not a design folder", "unknown table", "bad json", "invalid field",
                                     "unknown table in design.json"])
def test_refused_input_rewrites_nothing(folder: Path, tmp_path: Path, problem: str) -> None:
    args: list[str] = []
    target = folder
    if problem == "not a design folder":
        target = tmp_path / "empty"
        target.mkdir()
        named = "design.json"
    elif problem == "unknown table":
        args, named = ["--table", "no-such-table"], "no-such-table"
    elif problem == "bad json":
        text = (folder / "design.json").read_text()
        (folder / "design.json").write_text(text[: len(text) // 2])
        named = "design.json: not valid JSON"
    elif problem == "invalid field":
        edit(folder, lambda d: d["ribbons"][0].update(thickness=-1.0))
        named = "ribbons[0].thickness"
    else:
        edit(folder, lambda d: d["parameters"].update(curvature_table="gone-table"))
        named = "gone-table"
    before = snapshot(target)
    r = ribbonctl("predict", str(target), *args)
    assert r.returncode == 2, (r.stdout, r.stderr)
    assert named in r.stderr
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert snapshot(target) == before
    assert not [p for p in target.parent.iterdir() if p.name.startswith(".")]


def test_a_failure_while_writing_leaves_the_old_folder(folder: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The disk fails after deployed.obj is written, before deployed.png: the folder is as it was."""
    from ribbond.design import folder as folder_module
    from ribbond.pipeline.repredict import repredict_folder

    before = snapshot(folder)
    real = folder_module._write_synced
    written: list[str] = []

    def failing(path: Path, data: bytes) -> None:
        if written:
            raise OSError(28, "No space left on device", str(path))
        written.append(path.name)
        real(path, data)
    monkeypatch.setattr(folder_module, "_write_synced", failing)
    with pytest.raises(OSError):
        repredict_folder(folder)
    assert written                                    # it failed half way, not before writing
    assert snapshot(folder) == before
    assert not [p for p in folder.parent.iterdir() if p.name.startswith(".")]
    assert os.listdir(folder) == os.listdir(folder)   # still there, readable
    read_design_folder(folder)
