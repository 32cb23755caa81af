"""The predicted shape's deviation per vertex, for the dashboard's 3D view (issue 36 item 11): the
distance of each vertex of a design's ``deployed.obj`` (already registered onto ``target.obj`` by the
prediction) to the target surface, the same measure as ``report.deployed.deviation_pct``
(``ribbond.deploy.compare.registered_deviation``). The design folder keeps only the figures, so the
distances are measured here from the two meshes, once per prediction written, and kept in memory."""

from __future__ import annotations

import asyncio
from collections import OrderedDict
from pathlib import Path
from typing import Any

from ribbond.deploy.compare import registered_deviation
from ribbond.mesh.files import read_mesh

from ..records import NotFound
from ..store import JobRecord

#: Predictions whose distances are kept (the newest asked for; an older one is measured again).
KEPT = 16


class Shapes:
    """``deviation(job)``: the distance of each predicted vertex to the target, mm, and its figures."""

    def __init__(self) -> None:
        self._kept: OrderedDict[tuple[str, int, int], dict[str, Any]] = OrderedDict()

    async def deviation(self, job: JobRecord) -> dict[str, Any]:
        """``{"vertices", "distance_mm": [k], "diagonal_mm", "deviation_pct": {mean, p99, max}}``.

        Raises ``NotFound`` when the job has no prediction (no design, or ``deployed.obj`` absent). The
        meshes are read and measured in a thread (tens of ms): the event loop goes on."""
        folder = Path(job.design_dir) if job.kind == "design" and job.design_dir else None
        deployed = folder / "deployed.obj" if folder else None
        if deployed is None or not deployed.is_file() or not (folder / "target.obj").is_file():
            raise NotFound(f"job {job.id} has no predicted shape (deployed.obj)")
        stat = deployed.stat()
        # a new prediction replaces deployed.obj (a new file): its time and size name it
        key = (str(deployed), stat.st_mtime_ns, stat.st_size)
        if key in self._kept:
            self._kept.move_to_end(key)
            return self._kept[key]
        kept = await asyncio.to_thread(measure, deployed, folder / "target.obj")
        self._kept[key] = kept
        while len(self._kept) > KEPT:
            self._kept.popitem(last=False)
        return kept


def measure(deployed: Path, target: Path) -> dict[str, Any]:
    """The distances of ``deployed`` (an OBJ registered onto the target) to the ``target`` OBJ."""
    V, _ = read_mesh(deployed)
    target_V, target_F = read_mesh(target)
    d = registered_deviation(V, target_V, target_F)
    return {"vertices": len(V), "distance_mm": d.distance.tolist(), "diagonal_mm": d.diagonal,
            "deviation_pct": d.as_dict()}
