"""The prediction worker: one design folder predicted again, in its own process, reporting progress
as JSON lines (as ``ribbond.pipeline.worker`` does for a compile).

    python -m ribbond.pipeline.predict_worker DESIGN_DIR [--table NAME] [--tables DIR]

Every line on stdout is one JSON object:

- ``{"event": "progress", "fraction": …, "message": …}`` (at most 4 a second),
- ``{"event": "done", "design_dir": …, "table": …, "deployed": {…}, "verdict": [...]}`` last,
- ``{"event": "error", "kind": "input" | "internal", "message": …}`` instead, exit status 2/3.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from ribbond.pipeline.worker import _emit, lower_priority


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m ribbond.pipeline.predict_worker", description=__doc__.split("\n\n")[0])
    parser.add_argument("design_dir", type=Path)
    parser.add_argument("--table", help="curvature table (default: the design's)")
    parser.add_argument("--tables", type=Path, help="named curvature tables (the daemon's) before the shipped ones")
    parser.add_argument("--nice", type=int, default=10, help="lower the CPU priority by this much")
    args = parser.parse_args(argv)
    lower_priority(args.nice)
    from ribbond.pipeline.repredict import repredict_folder      # the engine, after the priority is lowered

    last = [0.0]

    def progress(fraction: float, message: str) -> None:
        now = time.monotonic()
        if now - last[0] >= 0.25 or fraction >= 1.0:
            last[0] = now
            _emit({"event": "progress", "fraction": float(fraction), "message": message})

    try:
        done = repredict_folder(args.design_dir, table=args.table, progress=progress,
                                tables_dir=args.tables)
    except ValueError as exc:
        _emit({"event": "error", "kind": "input", "message": str(exc)})
        return 2
    except Exception as exc:  # noqa: BLE001 - reported to the daemon, which keeps running
        _emit({"event": "error", "kind": "internal", "message": f"{type(exc).__name__}: {exc}"})
        return 3
    _emit({"event": "done", "design_dir": str(done.folder), "table": done.table, "deployed": done.deployed,
           "verdict": done.verdict, "time_s": done.time_s})
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
