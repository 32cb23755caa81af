"""What ``ribbonctl``'s daemon commands print for people (``--json``: the daemon's answer as is): progress
bars, job lines, temperatures, verdicts, and the exit status a job's state gives."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any


ENDED = {"done", "cancelled", "failed", "interrupted"}
#: States that hold the printer: a job in them is followed by ``print`` and ``watch``.
RUNNING = {"heating", "printing_front", "printing_back"}


def _clock(seconds: float | None) -> str:
    if seconds is None:
        return "?"
    s = int(round(seconds))
    return f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}" if s >= 3600 else f"{s // 60}:{s % 60:02d}"


class Bar:
    """A one-line progress bar on a terminal (redrawn in place); nothing when ``live`` is False."""

    def __init__(self, label: str, live: bool, stream: Any = None) -> None:
        self.label, self.live = label, live
        self.stream = stream or sys.stderr
        self._shown = False

    def draw(self, fraction: float, text: str = "") -> None:
        if not self.live:
            return
        self.stream.write("\r\x1b[K" + bar_text(fraction, self.label, text))
        self.stream.flush()
        self._shown = True

    def close(self) -> None:
        if self._shown:
            self.stream.write("\r\x1b[K")
            self.stream.flush()
            self._shown = False


def bar_text(fraction: float, label: str = "", text: str = "", width: int = 24) -> str:
    f = min(max(fraction, 0.0), 1.0)
    filled = int(round(f * width))
    return f"{label + '  ' if label else ''}[{'#' * filled}{'.' * (width - filled)}] {100 * f:5.1f}%" \
           + (f"  {text}" if text else "")


def progress_text(info: dict[str, Any], kind: str | None = None) -> str:
    """``front  ribbon 3/8  elapsed 0:12  ETA 0:20`` from a job status or a progress event (of a job
    of ``kind``: a plain G-code job's side is named ``program``, it has no front or back)."""
    if info.get("waiting_for") and info.get("state") not in ENDED:
        # a wait for a person is not progress: what it waits for, no side printing, no time left
        return f"waiting for {info['waiting_for']}"
    parts = []
    side = info.get("print_side") or info.get("side")
    if (kind or info.get("kind")) == "gcode":
        side = "program" if side else None
    if side:
        parts.append(side)
    if info.get("ribbons"):
        parts.append(f"ribbon {info.get('ribbon') or 0}/{info['ribbons']}")
    if info.get("elapsed_s") is not None:
        parts.append(f"elapsed {_clock(info['elapsed_s'])}")
    if info.get("eta_s") is not None and info.get("state", "printing") not in ENDED:
        parts.append(f"ETA {_clock(info['eta_s'])}")
    return "  ".join(parts)


def _line(job: dict[str, Any]) -> str:
    pct = f"{100 * (job.get('progress') or 0):5.1f}%"
    stage = f" [{job['stage']}]" if job.get("stage") else ""
    err = f"  ({job['error']})" if job.get("error") else ""
    runs = f"  run {len(job.get('runs') or []) + 1}" if job.get("runs") else ""
    kind = "  (G-code)" if job.get("kind") == "gcode" else ""
    if job.get("project"):
        kind = f"  panel {job['panel']} of {job['panels']} ({job['project']})"
    state = job["state"]
    if job.get("kind") == "gcode" and state == "printing_front":
        state = "printing"                  # a plain program has no front (--json keeps the state's name)
    return f"{job['id']}  {state:<15} {pct}  {job['mesh_name']}{kind}{runs}{stage}{err}"


def temperatures_text(printer: dict[str, Any] | None) -> str:
    """``nozzle 187/210 °C  bed 55/60 °C`` (actual/target) from a printer status; "" when unknown."""
    heaters = (printer or {}).get("heaters") or {}
    parts = [f"{name} {h['current']:.0f}/{h.get('target') or 0:.0f} °C"
             for key, name in (("T", "nozzle"), ("B", "bed"))
             if isinstance(h := heaters.get(key), dict) and h.get("current") is not None]
    return "  ".join(parts)


#: Job states in which the temperatures are shown with the job (it holds or is about to heat the printer).
HOT = RUNNING | {"paused", "awaiting_check"}


def verdict_text(job: dict[str, Any]) -> list[str]:
    """A design job's verdict lines (``GET /jobs/{id}``'s ``verdict``), labelled as ``ribbonctl
    design`` labels them."""
    return [f"verdict     {line}" for line in job.get("verdict") or []]


def _detail(job: dict[str, Any], printer: dict[str, Any] | None = None, verdict: bool = False,
            notes: bool = False) -> str:
    """A job for people: its line, progress, the temperatures (``printer``: a printer status, while
    the job heats or prints), the design's verdict (``verdict``), the daemon's notes on its program
    (``notes``), what to do next."""
    lines = [_line(job)]
    more = progress_text(job, job.get("kind"))
    if job.get("lines_total") and job["state"] in ("heating", "printing_front", "printing_back", "paused"):
        # last_acked_line counts the lines of ``program`` the printer acknowledged (a resumed side's
        # program is not the whole side: its name says so)
        program = job.get("program") or job.get("side") or "front"
        if job.get("kind") == "gcode":
            program = "program"                 # a plain program has no front
        more = f"{program}: line {max(job.get('last_acked_line', -1), 0)} of {job['lines_total']}" + (
            f"  {more}" if more else "")
    if more:
        lines.append(f"  {bar_text(job.get('progress') or 0)}  {more}")
    if job.get("same_frame"):
        lines.append("  prints on the frame as it is (--same-frame: no fresh frame asked for)")
    temps = temperatures_text(printer) if job["state"] in HOT else ""
    if temps:
        lines.append(f"  temperatures  {temps}  (actual/target)")
    if verdict:
        lines += [f"  {line}" for line in verdict_text(job)]
    lines += [f"  note: {n}" for n in (job.get("notes") or []) if notes]
    nxt = job.get("next") or {}
    if nxt.get("instruction"):
        lines.append(f"  next: {nxt['instruction']}")
    return "\n".join(lines)


def _out(args: argparse.Namespace, obj: Any, text: str) -> None:
    print(json.dumps(obj, indent=1) if args.json else text, flush=True)


def waits(job: dict[str, Any]) -> bool:
    """The job waits for the operator (or its run ended): watching it can stop."""
    return bool(job.get("waits_for_operator")) or job["state"] in ENDED


def _exit_code(job: dict[str, Any]) -> int:
    return 1 if job["state"] in ("failed", "cancelled", "interrupted") else 0
