"""``ribbonctl``'s printer commands: printer, frame-ready, home, jog, goto, gcode, heat, cool, adjust, stop,
recover."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from .http import _client
from .output import _out


def _printer_text(status: dict[str, Any]) -> str:
    heaters = ", ".join(f"{k} {v['current']:.0f}/{v.get('target') or 0:.0f} °C"
                        for k, v in (status.get("heaters") or {}).items())
    where = _head_text(status.get("head") or status.get("position"), status.get("homed"), 2)
    note = status.get("note") or ""
    return "  ".join(p for p in (status.get("state"), status.get("firmware") or "", heaters, _factors_text(status),
                                 where, note, _frame_text(status.get("frame"))) if p)


def _frame_text(frame: dict[str, Any] | None) -> str:
    """``frame fresh`` / ``frame used (job J)``, and the job waiting for a fresh one."""
    if not frame:
        return ""
    text = f"frame {frame['state']}" + (f" (job {frame['job_id']})" if frame.get("job_id") else "")
    if frame.get("waiting_job"):
        text += f"; job {frame['waiting_job']} waits for a fresh frame: ribbonctl frame-ready"
    return text


def cmd_frame_ready(args: argparse.Namespace) -> int:
    """A fresh stretched frame is loaded: the job waiting for it goes on."""
    frame = _client(args).request("POST", "/printer/frame-ready")
    _out(args, frame, _frame_text(frame))
    return 0


def cmd_printer(args: argparse.Namespace) -> int:
    status = _client(args).request("GET", "/printer", params={"refresh": "true"})
    _out(args, status, _printer_text(status))
    return 0


def _head_text(pos: list[float] | None, homed: list[str] | None, digits: int) -> str:
    """``head at x 10.00 y 20.00 z 5.00``; an axis not homed (``homed``: the axes that are; None
    from an older daemon: every one) says so, as Mainsail does: its number means nothing."""
    if not pos and not (homed is not None and len(homed) < 3):
        return ""
    axes = [f"{a} not homed" if homed is not None and a not in homed else
            f"{a} {pos[i]:.{digits}f}" if pos else f"{a} ?" for i, a in enumerate("xyz")]
    return "head at " + " ".join(axes)


def _position(status: dict[str, Any]) -> str:
    return _head_text(status.get("position"), status.get("homed"), 3) or "done"


def cmd_home(args: argparse.Namespace) -> int:
    status = _client(args).request("POST", "/printer/home", timeout=330)
    _out(args, status, _position(status))
    return 0


def cmd_jog(args: argparse.Namespace) -> int:
    status = _client(args).request("POST", "/printer/jog", json={"dx": args.dx, "dy": args.dy, "dz": args.dz},
                                   timeout=330)
    _out(args, status, _position(status))
    return 0


def cmd_goto(args: argparse.Namespace) -> int:
    status = _client(args).request("POST", "/printer/goto", json={"x": args.x, "y": args.y}, timeout=330)
    _out(args, status, _position(status))
    return 0


def cmd_gcode(args: argparse.Namespace) -> int:
    result = _client(args).request("POST", "/printer/gcode", json={"commands": args.commands}, timeout=630)
    text = "\n".join(f"> {a['command']}" + (f"  (sent as: {a['sent']})" if a.get("sent") else "") + "\n"
                     + "\n".join(a["answer"]) for a in result["answers"])
    text += "".join(f"\nnote: {n}" for n in result.get("notes") or [])
    _out(args, result, text)
    return 0


def cmd_heat(args: argparse.Namespace) -> int:
    status = _client(args).request("POST", "/printer/heat", json={"nozzle": args.nozzle, "bed": args.bed})
    _out(args, status, _printer_text(status))
    return 0


def _factors_text(status: dict[str, Any]) -> str:
    """``speed 80 %  flow 105 %``, as the printer last reported them (M220, M221), or nothing."""
    parts = [f"{name} {status[key]:g} %" for name, key in (("speed", "speed_percent"), ("flow", "flow_percent"))
             if status.get(key) is not None]
    return "  ".join(parts)


def cmd_adjust(args: argparse.Namespace) -> int:
    """Adjust the print in progress (or the printer between prints): speed, flow, nozzle, bed."""
    given = {"speed": args.speed, "flow": args.flow, "nozzle": args.nozzle, "bed": args.bed}
    body = {k: v for k, v in given.items() if v is not None}        # a field is a number or left out
    if not body:
        print("ribbonctl adjust: give --speed, --flow, --nozzle and/or --bed", file=sys.stderr)
        return 2
    result = _client(args).request("POST", "/printer/adjust", json=body, timeout=330)
    sent = ", ".join(a["command"] for a in result["answers"])
    where = f" beside job {result['printing']}'s program" if result.get("printing") else ""
    printer = result.get("printer") or {}
    _out(args, result, f"sent {sent}{where}\n{_printer_text(printer)}")
    return 0


def cmd_cool(args: argparse.Namespace) -> int:
    status = _client(args).request("POST", "/printer/cool")
    _out(args, status, _printer_text(status))
    return 0


def cmd_stop(args: argparse.Namespace) -> int:
    status = _client(args).request("POST", "/printer/emergency-stop")
    _out(args, status, f"emergency stop sent; printer {status.get('state')} (ribbonctl recover restarts it)")
    return 0


def cmd_recover(args: argparse.Namespace) -> int:
    status = _client(args).request("POST", "/printer/recover", timeout=60)
    _out(args, status, "recovered: " + _printer_text(status))
    return 0
