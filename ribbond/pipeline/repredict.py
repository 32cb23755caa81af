"""Predict again the deployed shape of a design folder as its files are (issue 23 item 4).

``repredict_folder`` reads a design folder (``ribbond.design.folder.read_design_folder``: a
``design.json`` a person edited badly is refused with the file and the field named), predicts the
deployed shape of its ribbons as they are in ``design.json`` (thicknesses included) with the design's
curvature table or another one, and replaces ``deployed.obj``, ``deployed.png`` and
``report.deployed`` of ``design.json`` atomically (``folder.replace_design_files``): everything is
computed before anything is written, so a failure leaves the folder as it was.

What ``table`` changes: only the prediction. The ribbons, their thicknesses (chosen with the
design's table), ``parameters.curvature_table`` and the print programs stay as they are;
``report.deployed.table`` records the table the prediction was made with, so the report says which
material it describes. Used by ``ribbonctl predict`` and by the daemon's ``POST /jobs/{id}/predict``
(through ``python -m ribbond.pipeline.predict_worker``, which prints JSON lines as the compile worker does).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..deploy.predict import Prediction, predict_deployed
from ..design.folder import DesignFolder, read_design_folder, replace_design_files
from ..design.format import FORMAT, DeployedReport, Design, design_to_dict, design_to_json
from ..mesh.files import obj_bytes
from ..design.thickness import CurvatureTable, load_curvature_table
from ..design.verdict import verdict_lines

#: The files a re-prediction replaces.
REPLACED = ("design.json", "deployed.obj", "deployed.png")

#: Progress: (fraction done in [0, 1], what is being done).
Progress = Callable[[float, str], None]


@dataclass(frozen=True)
class Repredicted:
    """A design folder predicted again.

    Attributes
    ----------
    folder : the design folder; files : the files replaced (``REPLACED``, as paths).
    design : the new ``design.json``; deployed : its ``report.deployed`` as a dict.
    table : the name of the curvature table the prediction was made with.
    verdict : the design's verdict lines (``ribbond.design.verdict``) after the new prediction.
    time_s : wall time of the whole re-prediction, s.
    """

    folder: Path
    files: tuple[Path, ...]
    design: Design
    deployed: dict[str, Any]
    table: str
    verdict: list[str]
    time_s: float


def _table(folder: DesignFolder, name: str | None, tables_dir: Path | None) -> CurvatureTable:
    """The curvature table asked for (default: the design's), checked against the design's pre-stretch."""
    params = folder.design.parameters
    asked = name or params.curvature_table
    table = load_curvature_table(asked, tables_dir=tables_dir)
    if abs(table.prestretch - params.prestretch) > 1e-9:
        raise ValueError(f"curvature table {table.name!r} was measured at pre-stretch s = {table.prestretch:g}, "
                         f"but the design in {folder.path} is made at s = {params.prestretch:g}: give a table "
                         "measured at the design's pre-stretch")
    return table


def _predict(folder: DesignFolder, table: CurvatureTable, progress: Progress) -> Prediction:
    """The prediction of the folder's ribbons, as they are in its design.json."""
    d = folder.design
    return predict_deployed(folder.flat_V, folder.target_V, folder.target_F, list(d.ribbons or []),
                            prestretch=d.parameters.prestretch, ribbon_width=d.parameters.ribbon_width,
                            table=table, progress=progress)


def _deployed_report(prediction: Prediction, table: CurvatureTable, design: Design) -> DeployedReport:
    """``report.deployed`` of the new prediction, recording the table when it is not the design's."""
    data = dict(prediction.report())
    if table.name != design.parameters.curvature_table:
        data["table"] = table.name
    return DeployedReport(**data)


def repredict_folder(folder: str | Path, *, table: str | None = None,
                     progress: Progress | None = None, tables_dir: Path | None = None) -> Repredicted:
    """Predict again the deployed shape of the design folder ``folder`` and replace its prediction.

    Parameters
    ----------
    folder : a design folder (``target.obj``, ``flat.obj``, ``design.json`` with ribbons).
    table : a curvature table's name or a ``.toml`` path (default: ``parameters.curvature_table``).
    progress : called with (fraction done in [0, 1], message) as the prediction goes.
    tables_dir : where named tables are looked up before the shipped ones (the daemon's).

    Returns
    -------
    Repredicted

    Raises
    ------
    ValueError
        naming the file and the problem: not a design folder, a ``design.json`` that does not parse
        or validate, no ribbons, an unknown table or one of another pre-stretch, a prediction that
        cannot be made. Nothing is written then.
    OSError
        when writing fails; the folder is left as it was.
    """
    t0 = time.perf_counter()
    report = progress or (lambda fraction, message: None)
    path = Path(folder)
    df = read_design_folder(path)
    if not df.design.ribbons:
        raise ValueError(f"{path / 'design.json'}: no ribbons: there is nothing to predict")
    tbl = _table(df, table, tables_dir)
    report(0.0, f"predicting the deployed shape (table {tbl.name!r})")
    try:
        prediction = _predict(df, tbl, report)
    except ValueError as exc:
        raise ValueError(f"{path}: the deployed shape cannot be predicted: {exc}") from None
    d = df.design
    deployed = _deployed_report(prediction, tbl, d)
    design = d.updated(format=FORMAT, report=d.report.updated(deployed=deployed))
    report(1.0, "writing deployed.obj, deployed.png and design.json")
    header = (f"ribbond design: predicted deployed surface, mm, registered to target.obj "
              f"({prediction.faces} faces, its own mesh)")
    title = f"{d.source.file}: predicted deployed shape"
    replace_design_files(path, {
        "design.json": design_to_json(design).encode(),
        "deployed.obj": obj_bytes(prediction.V, prediction.F, header=header),
        "deployed.png": prediction.render_png(df.target_V, df.target_F, title=title)})
    as_dict = design_to_dict(design)
    return Repredicted(folder=path, files=tuple(path / n for n in REPLACED), design=design,
                       deployed=as_dict["report"]["deployed"], table=tbl.name,
                       verdict=verdict_lines(as_dict), time_s=time.perf_counter() - t0)
