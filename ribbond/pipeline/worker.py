"""The compile worker: one design, in its own process, reporting progress as JSON lines.

    python -m ribbond.pipeline.worker MESH OUT_DIR [--params JSON] [--plans DIR] [--max-faces N]

``--params`` has the layout of a ``--params`` file: design parameters at the top level and an
optional ``solver`` table (``SolverSettings``), both applied; ``--max-faces`` is the daemon's
``[limits] max_faces``, which the solver's own ``max_faces`` cannot raise.

The daemon runs it with ``asyncio.create_subprocess_exec`` so that a 160k-face compile runs beside
the event loop that streams to the printer, never in it (and at a lower CPU priority). Every line
on stdout is one JSON object:

- ``{"event": "stage", "stage": …, "description": …}`` when a stage starts,
- ``{"event": "iteration", "stage": …, "iteration": …, "change": …}`` (at most a few per second),
- ``{"event": "finished", "stage": …, "seconds": …, "summary": …}`` when it ends,
- ``{"event": "done", "design_dir": …, "ribbons": {"front": …, "back": …}, "report": {…}}`` last,
- ``{"event": "error", "kind": "mesh" | "design" | "internal", "message": …}`` instead, exit status 2/1/3.

With ``--plans DIR`` the front and back plans (``SidePlan.save``) are written there too, so the
back side can be re-rendered with the alignment correction without planning again.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

# The engine (numpy, scipy, libigl) is imported in ``main`` after the priority is lowered: on Linux
# a thread's nice value is its own, and the BLAS threads those imports start inherit it only if
# they are created after ``os.nice``.


def _emit(obj: dict[str, object]) -> None:
    sys.stdout.write(json.dumps(obj, allow_nan=False, default=str) + "\n")
    sys.stdout.flush()


class JsonProgress:
    """``DesignProgress`` that prints JSON lines (iterations throttled to 4 a second)."""

    def __init__(self) -> None:
        self._last = 0.0

    def stage_started(self, stage: str, description: str) -> None:
        _emit({"event": "stage", "stage": stage, "description": description})

    def iteration(self, stage: str, iteration: int, change: float, energy: float) -> None:
        now = time.monotonic()
        if now - self._last >= 0.25:
            self._last = now
            _emit({"event": "iteration", "stage": stage, "iteration": iteration, "change": change})

    def stage_finished(self, stage: str, seconds: float, summary: str) -> None:
        _emit({"event": "finished", "stage": stage, "seconds": seconds, "summary": summary})



def lower_priority(nice: int) -> None:
    """Lower this process's CPU priority by ``nice`` before numpy is imported, so that the BLAS
    threads it starts inherit it (the daemon's loop must keep feeding the printer)."""
    if nice > 0 and hasattr(os, "nice"):
        try:
            os.nice(nice)
        except OSError:
            pass

def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m ribbond.pipeline.worker", description=__doc__.split("\n\n")[0])
    parser.add_argument("mesh", type=Path)
    parser.add_argument("out", type=Path)
    parser.add_argument("--params", default="{}", help="design parameters (and a 'solver' table) as a JSON object")
    parser.add_argument("--max-faces", type=int, help="the daemon's [limits] max_faces")
    parser.add_argument("--plans", type=Path, help="also write the front and back plans into this folder")
    parser.add_argument("--tables", type=Path, help="named curvature tables (the daemon's) before the shipped ones")
    parser.add_argument("--no-predict", action="store_true", help="skip the deploy stage (the daemon's "
                        "[design] predict = false)")
    parser.add_argument("--no-optimize", action="store_true", help="skip the optimization of the layout "
                        "against the prediction (the daemon's [design] optimize = false)")
    parser.add_argument("--nice", type=int, default=10, help="lower the CPU priority by this much")
    args = parser.parse_args(argv)
    lower_priority(args.nice)
    from ..design.errors import DesignError, MeshError
    from ..design.format import design_to_dict
    from ..design.params import settings_from_dict
    from .compile import design_mesh, write_design

    limited = False                                   # the daemon's limit is below the solver's
    try:
        settings = settings_from_dict(json.loads(args.params))
        solver = settings.solver
        limited = args.max_faces is not None and args.max_faces < solver.max_faces
        if limited:
            solver = solver.model_copy(update={"max_faces": args.max_faces})
        result = design_mesh(args.mesh, settings.parameters, solver, predict=not args.no_predict,
                             optimize=not args.no_optimize, progress=JsonProgress(),
                             tables_dir=args.tables)
        path = write_design(result, args.out, JsonProgress())
        if args.plans is not None:
            args.plans.mkdir(parents=True, exist_ok=True)
            result.programs.front_plan.save(args.plans / "front-plan.npz")
            result.programs.back_plan.save(args.plans / "back-plan.npz")
    except MeshError as exc:
        where = " ([limits] max_faces in the daemon's configuration)" \
            if limited and exc.problem == "too_many_faces" else ""
        _emit({"event": "error", "kind": "mesh", "message": f"{exc}{where}"})
        return 2
    except (DesignError, ValueError) as exc:
        _emit({"event": "error", "kind": "design", "message": str(exc)})
        return 1
    except Exception as exc:  # noqa: BLE001 - reported to the daemon, which keeps running
        _emit({"event": "error", "kind": "internal", "message": f"{type(exc).__name__}: {exc}"})
        return 3
    d = result.design
    ribbons = d.ribbons or []
    _emit({"event": "done", "design_dir": str(path),
           "ribbons": {"front": sum(r.side == "front" for r in ribbons),
                       "back": sum(r.side == "back" for r in ribbons)},
           "report": design_to_dict(d)["report"]})
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
