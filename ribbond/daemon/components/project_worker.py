"""The project compile worker: one mesh cut into panels, each an ordinary design folder, in its own
process (issue 26), reporting progress as JSON lines as ``ribbond.pipeline.worker`` does.

    python -m ribbond.daemon.components.project_worker MESH OUT_DIR --panels auto|N [--seam-allowance MM]
        [--params JSON] [--plans DIR] [--tables DIR] [--max-faces N] [--no-predict] [--no-optimize]

It runs ``ribbond.panels.project.design_project`` and ``write_project`` (OUT_DIR: ``project.json``,
``panels.png``, ``panel-1/`` …) and, with ``--plans``, writes each panel's front and back plans as
``panel-K-front-plan.npz`` / ``panel-K-back-plan.npz`` (the daemon renders the back again with the
alignment's correction from them). Its last line is ``{"event": "done", "project_dir": …, "panels": N,
"report": {…}}`` or ``{"event": "error", "kind": …, "message": …}`` (exit status 2 mesh, 1 design, 3 internal).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from ribbond.pipeline.worker import JsonProgress, lower_priority


def _emit(obj: dict[str, object]) -> None:
    sys.stdout.write(json.dumps(obj, allow_nan=False, default=str) + "\n")
    sys.stdout.flush()


def panels_arg(text: str) -> int | str:
    """``auto`` or a whole number of panels, at least 2."""
    if text == "auto":
        return text
    if not text.isdigit() or int(text) < 2:
        raise argparse.ArgumentTypeError(f"{text!r}: 'auto' or a whole number of panels, at least 2")
    return int(text)


def save_plans(result: Any, project_dir: Path, plans: Path, printer_profile: str) -> None:
    """Each panel's front and back plans in ``plans``: the engine's own (``result.panels[k].result.programs``,
    those its programs were written from), else planned again from the panel's design folder."""
    from ribbond.design.folder import read_design_folder
    from ribbond.gcode.profiles import load_profile
    from ribbond.gcode.program import plan_side

    plans.mkdir(parents=True, exist_ok=True)
    project = json.loads((project_dir / "project.json").read_text(encoding="utf-8"))
    results = list(getattr(result, "panels", None) or [])
    for k, panel in enumerate(project["panels"]):
        design_result = getattr(results[k], "result", None) if k < len(results) else None
        programs = getattr(design_result, "programs", None)
        if programs is not None:
            front, back = programs.front_plan, programs.back_plan
        else:
            design = read_design_folder(project_dir / panel["folder"]).design
            profile = load_profile(printer_profile)
            front, back = (plan_side(design, profile, side) for side in ("front", "back"))
        front.save(plans / f"panel-{panel['index']}-front-plan.npz")
        back.save(plans / f"panel-{panel['index']}-back-plan.npz")


def _arguments(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="python -m ribbond.daemon.components.project_worker",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("mesh", type=Path)
    parser.add_argument("out", type=Path)
    parser.add_argument("--panels", type=panels_arg, default="auto")
    parser.add_argument("--seam-allowance", type=float, default=6.0)
    parser.add_argument("--params", default="{}", help="design parameters (and a 'solver' table) as a JSON object")
    parser.add_argument("--max-faces", type=int, help="the daemon's [limits] max_faces")
    parser.add_argument("--plans", type=Path, help="also write each panel's front and back plans here")
    parser.add_argument("--tables", type=Path, help="named curvature tables (the daemon's) before the shipped ones")
    parser.add_argument("--no-predict", action="store_true", help="skip the deploy stage")
    parser.add_argument("--no-optimize", action="store_true", help="skip the optimization against the prediction")
    parser.add_argument("--nice", type=int, default=10, help="lower the CPU priority by this much")
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = _arguments(argv)
    lower_priority(args.nice)
    from ribbond.design.errors import DesignError, MeshError
    from ribbond.design.params import settings_from_dict
    from ribbond.panels.project import design_project, write_project

    try:
        settings = settings_from_dict(json.loads(args.params))
        solver = settings.solver
        if args.max_faces is not None and args.max_faces < solver.max_faces:
            solver = solver.model_copy(update={"max_faces": args.max_faces})
        if args.no_optimize:
            solver = solver.model_copy(update={"optimize": False})
        result = design_project(args.mesh, settings.parameters, solver, panels=args.panels,
                                seam_allowance=args.seam_allowance, progress=JsonProgress(),
                                predict=not args.no_predict, tables_dir=args.tables)
        path = Path(write_project(result, args.out, JsonProgress()))
        if args.plans is not None:
            save_plans(result, path, args.plans, settings.parameters.printer_profile)
        project = json.loads((path / "project.json").read_text(encoding="utf-8"))
    except MeshError as exc:
        _emit({"event": "error", "kind": "mesh", "message": str(exc)})
        return 2
    except (DesignError, ValueError) as exc:
        _emit({"event": "error", "kind": "design", "message": str(exc)})
        return 1
    except Exception as exc:  # noqa: BLE001 - reported to the daemon, which keeps running
        _emit({"event": "error", "kind": "internal", "message": f"{type(exc).__name__}: {exc}"})
        return 3
    _emit({"event": "done", "project_dir": str(path), "panels": len(project["panels"]), "report": project["report"]})
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
