"""``ribbonctl``'s curvature tables and calibrations on the daemon: tables list|show|add|remove, and what
``ribbonctl calibrate`` asks the daemon (a plan made there, a table added)."""

from __future__ import annotations

import argparse
import sys
import time
import urllib.parse
from pathlib import Path
from typing import Any

from .http import ClientError, _client
from .output import _out


def cmd_tables(args: argparse.Namespace) -> int:
    """ribbonctl tables list|show NAME|add FILE|remove NAME (the daemon's curvature tables)."""
    c = _client(args)
    if args.action == "list":
        tables = c.request("GET", "/tables")
        _out(args, tables, "\n".join(f"{t['name']:<28} {t['source']:<8} s = {t.get('prestretch', '?')}  "
                                      f"{t.get('material', '')} on {t.get('fabric', '') or '?'}" for t in tables))
    elif args.action == "show":
        if not args.arg:
            raise ClientError("tables show NAME: which table?", 2)
        t = c.request("GET", f"/tables/{urllib.parse.quote(args.arg, safe='')}")
        rows = [f"{t['name']} ({t['source']}): {t.get('description', '')}",
                f"prestretch {t['prestretch']}, material {t.get('material') or '?'}, fabric {t.get('fabric') or '?'}",
                "τ \\ μ2  " + " ".join(f"{m:>8g}" for m in t["spacing"])]
        for side in ("front", "back"):
            rows.append(f"{side}:")
            rows += [f"{tau:>7g}  " + " ".join(f"{v:>8.4g}" for v in row) for tau, row in zip(t["thickness"], t[side])]
        _out(args, t, "\n".join(rows))
    elif args.action == "add":
        if not args.arg:
            raise ClientError("tables add FILE: which file?", 2)
        try:
            text = Path(args.arg).read_text(encoding="utf-8")
        except OSError as exc:
            raise ClientError(f"{args.arg}: {exc.strerror or exc}", 2) from None
        t = c.request("POST", "/tables", json={"toml": text})
        _out(args, t, f"added table {t['name']!r}: designs use it with curvature_table = \"{t['name']}\"")
    else:
        if not args.arg:
            raise ClientError("tables remove NAME: which table?", 2)
        c.request("DELETE", f"/tables/{urllib.parse.quote(args.arg, safe='')}")
        _out(args, {"removed": args.arg}, f"removed table {args.arg!r}")
    return 0


def calibrate_remote(args: argparse.Namespace, spec: dict[str, Any]) -> int:
    """ribbonctl calibrate plan without -o: the daemon makes the plan, one job per sheet."""
    c = _client(args)
    r = c.request("POST", "/calibrations", json={**spec, "start": bool(getattr(args, "start", False))})
    if not args.json:
        print(f"calibration {r['calibration']}: making the plan on the daemon …", file=sys.stderr, flush=True)
    while r["state"] == "planning":                      # made in the planner's process, as a compile is
        time.sleep(0.5)
        r = c.request("GET", f"/calibrations/{r['calibration']}")
    if r["state"] == "failed":
        raise ClientError(f"calibration {r['calibration']}: {r['error']}", 1)
    base = c.url.rstrip("/")
    text = (f"calibration {r['calibration']}: {r['coupons']} coupons on {r['sheets']} sheet(s), one job per sheet: "
            f"{', '.join(r['jobs'])}\n  coupons: {base}/calibrations/{r['calibration']}/files/coupons.csv\n"
            f"  sheet maps: {base}/calibrations/{r['calibration']}/files/sheet-1.png …\n"
            f"  print each sheet: ribbonctl start JOB (a new fabric each); then measure and run\n"
            f"  ribbonctl calibrate record {r['calibration']} measurements.csv --add NAME")
    _out(args, r, text)
    return 0


def fetch_plan(args: argparse.Namespace, ident: str) -> Any:
    """``plan.json`` of a daemon calibration, by its id or the id of one of its jobs."""
    c = _client(args)
    if not ident.startswith("cal-"):
        job = c.request("GET", f"/jobs/{urllib.parse.quote(ident, safe='')}")
        ident = (job.get("parameters") or {}).get("calibration") or ""
        if not ident:
            raise ClientError(f"job {job['id']} is not a calibration job", 2)
    return c.request("GET", f"/calibrations/{ident}/files/plan.json")


def add_table_text(args: argparse.Namespace, text: str) -> dict[str, Any]:
    return _client(args).request("POST", "/tables", json={"toml": text})
