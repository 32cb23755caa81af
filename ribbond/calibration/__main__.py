"""``python -m ribbond.calibration plan --spec JSON -o DIR``: write a calibration plan folder.

The daemon runs it in its own process (at a lower priority) for ``POST /calibrations``: the
ordering of the sheets' passes never runs on the loop that feeds the printer. Exit status 0
written (the last stdout line is ``{"event": "done", ...}``), 2 the plan is refused (the reason on
stderr, one line).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ribbond.pipeline.worker import lower_priority


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m ribbond.calibration")
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("plan")
    p.add_argument("--spec", default="{}", help="CalibrationSpec as JSON")
    p.add_argument("-o", "--output", type=Path, required=True)
    p.add_argument("--nice", type=int, default=10)
    args = parser.parse_args(argv)
    lower_priority(args.nice)
    from pydantic import ValidationError

    from .plan import make_plan, write_plan
    from .spec import CalibrationSpec

    try:
        spec = CalibrationSpec.model_validate(json.loads(args.spec))
        plan = make_plan(spec)
        write_plan(plan, args.output)
    except ValidationError as exc:
        print("; ".join(f"{'.'.join(map(str, e['loc']))}: {e['msg']}" for e in exc.errors()), file=sys.stderr)
        return 2
    except ValueError as exc:
        print(str(exc).replace("\n", " "), file=sys.stderr)
        return 2
    print(json.dumps({"event": "done", "folder": str(args.output), "sheets": len(plan.sheets),
                      "coupons": len(plan.coupons)}))
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
