"""``ribbonctl``'s project commands (issue 26): a mesh printed in panels on the daemon.

``ribbonctl submit MESH --panels auto|N [--seam-allowance MM] [--start]`` uploads it (``POST
/projects``), follows the compile and prints the panel map; ``ribbonctl project [list|show|start|cancel]
[ID]`` shows a project (panel K of N, each panel's state, what to do next), prints the panels left
or cancels what is left; ``ribbonctl status`` lists the projects in progress above the jobs.
Standard library only, as every daemon command (``ribbond.client.http``)."""

from __future__ import annotations

import argparse
import json
import sys
import time
from typing import Any

from .http import Client, _client
from .output import Bar, _out, bar_text

#: Project states in which nothing more happens by itself.
OVER = {"done", "failed", "cancelled"}


def project_line(p: dict[str, Any]) -> str:
    """``prj-1a2b3c4d  printing  panel 2 of 3  1 done  bowl.obj``."""
    n = p.get("panel_count")
    where = f"  panel {p['current_panel']} of {n}" if p.get("current_panel") and n else ""
    done = f"  {p.get('panels_done', 0)}/{n} done" if n else ""
    return f"{p['id']}  {p['state']:<10}{where}{done}  {p['mesh_name']}"


def project_detail(p: dict[str, Any]) -> str:
    """A project for people: its line, each panel's state and size, the seams, what to do next."""
    lines = [project_line(p)]
    for q in p.get("panels") or []:
        size = q.get("flat_size_mm") or []
        flat = f"  {size[0]:.0f} × {size[1]:.0f} mm" if len(size) == 2 else ""
        mark = "▶" if q["index"] == p.get("current_panel") else " "
        lines.append(f"  {mark} panel {q['index']}  {q['state']:<15} {bar_text(q.get('progress') or 0, width=12)}"
                     f"  job {q.get('job_id') or '(deleted)'}{flat}")
    for s in p.get("seams") or []:
        target = (s.get("length_mm") or {}).get("target")
        length = f", {target:.0f} mm" if isinstance(target, (int, float)) else ""
        lines.append(f"    seam {s['label']}: panels {' and '.join(map(str, s['panels']))}{length}")
    lines += [f"  verdict     {line}" for line in p.get("verdict") or []]
    if p.get("error"):
        lines.append(f"  error: {p['error']}")
    lines.append(f"  next: {p['next']['instruction']}")
    return "\n".join(lines)


def active_projects_text(c: Client) -> list[str]:
    """``ribbonctl status``'s lines for the projects in progress (none: no line)."""
    projects = c.request("GET", "/projects", params={"limit": 20})
    return [line for p in projects if p["state"] not in OVER
            for line in (project_line(p), f"  next: {p['next']['instruction']}")]


def submit_project(c: Client, args: argparse.Namespace, params: dict[str, Any]) -> int:
    """``ribbonctl submit MESH --panels …``: upload, follow the compile, the panel map."""
    data = {"parameters": json.dumps(params), "panels": str(args.panels),
            "seam_allowance": str(args.seam_allowance), "start": str(args.start).lower()}
    p = c.upload("mesh", args.mesh, data, show=not args.json, to="/projects")
    if args.no_wait:
        _out(args, p, p["id"])
        return 0
    bar = Bar("compiling the panels", not args.json and sys.stderr.isatty())
    last = None
    try:
        while p["state"] in ("submitted", "compiling"):
            if not bar.live and not args.json and p.get("stage") != last:
                print(f"{p['state']:<15} {p.get('stage') or ''}", file=sys.stderr, flush=True)
            last = p.get("stage")
            bar.draw(0.0, p.get("stage") or "")
            time.sleep(0.3)
            p = c.request("GET", f"/projects/{p['id']}")
    finally:
        bar.close()
    files = f"\n  panel map: {c.url}/projects/{p['id']}/files/panels.png" + (
        f"\n  sewn prediction: {c.url}/projects/{p['id']}/files/deployed.png" if p.get("has_deployed") else "")
    _out(args, p, project_detail(p) + files)
    return 1 if p["state"] in ("failed", "cancelled") else 0


def cmd_project(args: argparse.Namespace) -> int:
    c = _client(args)
    if args.action == "list" or args.id is None:
        projects = c.request("GET", "/projects")
        _out(args, projects, "\n".join(project_line(p) for p in projects) or "no projects")
        return 0
    if args.action == "show":
        p = c.request("GET", f"/projects/{args.id}")
    else:
        p = c.request("POST", f"/projects/{args.id}/{args.action}")
    _out(args, p, project_detail(p))
    return 0


def add_project_commands(sub: Any, common: argparse.ArgumentParser) -> None:
    """``ribbonctl project ACTION [ID]``."""
    p = sub.add_parser("project", parents=[common], help="a mesh printed in panels: list, show, start, cancel",
                       description="Projects (ribbonctl submit MESH --panels auto|N): the panel map, the panel "
                                   "on the printer, what to do next; start prints the panels left in order, "
                                   "cancel cancels what is left.")
    p.add_argument("action", choices=("list", "show", "start", "cancel"), nargs="?", default="list")
    p.add_argument("id", nargs="?", help="the project (prj-…)")
    p.set_defaults(func=cmd_project)
