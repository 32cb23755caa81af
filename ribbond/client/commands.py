"""``ribbonctl``'s daemon commands, added to its parser (``add_commands``): each runs over the daemon's REST
API (``http``, the standard library's client); output for people by default, ``--json`` for scripts.
Nothing here imports the design engine (a command starts in a fraction of a second, also on a
Raspberry Pi).

Jobs: submit, print (a plain G-code program), status, watch, start, pause, resume, cancel,
flip-done, frame-ok, align, accept, re-seat, delete. The printer: printer, frame-ready, home, jog, goto, gcode, heat,
cool, adjust, stop, recover.

Exit status: 0 done; 1 refused (the job's state or the printer does not allow it now, the alignment
is refused, the job failed or was cancelled or interrupted); 2 bad input (a missing or unreadable
file, a value out of range, a program the profile refuses, a missing or wrong API token: the
daemon was reached and refused it); 3 the daemon cannot be reached (or answered an error of its
own); 4 no such job; 130 interrupted (Ctrl-C); 141 the output was closed (``ribbonctl status | head``).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .http import DEFAULT_URL
from .jobs import _action, cmd_align, cmd_delete, cmd_frame_ok, cmd_print, cmd_resume, cmd_status, cmd_submit, cmd_watch
from .printer import (cmd_adjust, cmd_cool, cmd_frame_ready, cmd_gcode, cmd_goto, cmd_heat, cmd_home, cmd_jog,
                      cmd_printer, cmd_recover, cmd_stop)
from .tables import cmd_tables


def add_global_options(parser: argparse.ArgumentParser, *, in_subcommand: bool) -> None:
    """--url, --token, --token-file, --json: before the subcommand (``in_subcommand`` False) or
    after it (the defaults are then left to the main parser, so either place works)."""
    keep = {"default": argparse.SUPPRESS} if in_subcommand else {}
    parser.add_argument("--url", help=f"the daemon (default $RIBBOND_URL or {DEFAULT_URL})",
                        **({"default": None} | keep))
    parser.add_argument("--token", help="API token (default $RIBBOND_TOKEN)", **({"default": None} | keep))
    parser.add_argument("--token-file", type=Path, help="file holding the API token",
                        **({"default": None} | keep))
    parser.add_argument("--json", action="store_true", help="plain JSON output for scripts",
                        **({"default": False} | keep))


#: Adds one command: ``cmd(name, help, func, description=None)`` -> its parser.
Command = Callable[..., argparse.ArgumentParser]


def add_commands(sub: Any) -> None:
    """Add the daemon commands to ``ribbonctl``'s subparsers (in the order ``--help`` lists them)."""
    common = argparse.ArgumentParser(add_help=False)
    add_global_options(common, in_subcommand=True)

    def cmd(name: str, help: str, func: Any, description: str | None = None) -> argparse.ArgumentParser:
        p = sub.add_parser(name, parents=[common], help=help, description=description or help)
        p.set_defaults(func=func)
        return p

    for add in (_job_commands, _run_commands, _alignment_commands, _printer_commands, _table_commands):
        add(cmd)
    from .projects import add_project_commands
    add_project_commands(sub, common)
    from .notify import add_notify_commands
    add_notify_commands(sub, common)


def _job_commands(cmd: Command) -> None:
    """submit, print, status, watch: a job in and what it is doing."""
    s = cmd("submit", "upload a mesh to the daemon and compile it", cmd_submit)
    s.add_argument("mesh", type=Path)
    s.add_argument("--size", type=float, metavar="MM", help="bounding-box diagonal of the target, mm")
    s.add_argument("--params", type=Path, metavar="FILE",
                   help="TOML or JSON design parameters (and an optional [solver] table, applied by the daemon)")
    s.add_argument("--start", action="store_true", help="print as soon as it is compiled")
    s.add_argument("--panels", metavar="auto|N", help="print it in panels: a project, compiled once, one "
                   "two-sided job per panel in order (auto: as few as flatten within bounds and fit the frame)")
    s.add_argument("--seam-allowance", type=float, default=6.0, metavar="MM",
                   help="with --panels: fabric left around each panel for its seams (default 6 mm)")
    s.add_argument("--no-wait", action="store_true", help="print the job id and return at once")
    s.add_argument("--no-optimize", action="store_true", help="the paper's forward design: the layout not "
                   "optimized against the prediction (the job's [solver] optimize = false)")
    p = cmd("print", "print a plain G-code file through the daemon", cmd_print,
            "Upload a G-code program, checked line by line against the printer profile (frame, feeds, "
            "temperatures), and print it; follows the job like watch.")
    p.add_argument("program", type=Path, help="a .gcode file")
    p.add_argument("--no-start", action="store_true", help="upload and check only (start it later)")
    p.add_argument("--no-wait", action="store_true", help="return once it is queued")
    p.add_argument("--same-frame", action="store_true", help="it prints on the frame as it is: no fresh frame "
                   "is asked for before it (every design needs one)")
    st = cmd("status", "list the jobs, or show one with its progress and what to do next", cmd_status)
    st.add_argument("job", nargs="?")
    st.add_argument("--state", action="append", metavar="STATE", help="only jobs in this state (repeatable)")
    st.add_argument("--limit", type=int, metavar="N", help="at most N jobs (newest first)")
    w = cmd("watch", "follow a job (progress bar) until it waits for you or ends", cmd_watch)
    w.add_argument("job")


def _run_commands(cmd: Command) -> None:
    """start, pause, cancel, flip-done, accept, re-seat, resume, frame-ok, delete: a job's run."""
    for name, text in (("start", "print a job (again: a new run of the same design)"), ("pause", "pause a print"),
                       ("cancel", "cancel a job"),
                       ("flip-done", "the frame is turned over: go on to the alignment"),
                       ("accept", "print the back with the alignment's fit (after align --review)"),
                       ("re-seat", "refuse the alignment's fit: seat the frame again (back side up), measure every mark again")):
        a = cmd(name, text, _action(name))
        a.add_argument("job")
    r = cmd("resume", "resume a paused print, or an interrupted one where it was proven to stand", cmd_resume,
            "Paused: reheat and go on. Interrupted (daemon crash, power cut, lost USB): home, heat, wait for "
            "frame-ok, then print the side it stood on from the first ribbon not proven printed.")
    r.add_argument("job")
    r.add_argument("--partial", choices=("skip", "reprint"),
                   help="interrupted: the ribbon begun and not proven printed is skipped (default: a second "
                        "bead over a printed one is worse than a gap) or printed again")
    f = cmd("frame-ok", "a resumed print: the frame is checked, go on", cmd_frame_ok)
    f.add_argument("job")
    f.add_argument("--keep-alignment", action="store_true",
                   help="the back was being printed and the frame was not moved: keep the stored alignment "
                        "instead of measuring the marks again")
    d = cmd("delete", "remove jobs and their files (not while they print)", cmd_delete)
    d.add_argument("job", nargs="+")


def _alignment_commands(cmd: Command) -> None:
    """align: the registration marks after the flip."""
    a = cmd("align", "the alignment check after the flip: jog onto each mark, then --here", cmd_align,
            "Without options: interactive (type jogs, Enter when the nozzle is on the mark). --here: the "
            "nozzle is over the mark now. --mark N --jog DX DY: report a jog made another way.")
    a.add_argument("job")
    a.add_argument("--here", action="store_true", help="the nozzle is over the mark now")
    a.add_argument("--mark", type=int, metavar="N", help="the mark, numbered from 1 (default: the current one)")
    a.add_argument("--jog", type=float, nargs=2, metavar=("DX", "DY"), help="the mark's offset from where the "
                   "head was sent, mm")
    a.add_argument("--review", action="store_true", help="after the last mark, show the fit and wait for "
                   "ribbonctl accept or re-seat (default: an accepted fit prints the back at once)")


def _printer_commands(cmd: Command) -> None:
    """The printer and its frame, and manual control."""
    cmd("printer", "the printer's state, temperatures, head position and frame (fresh or used)", cmd_printer)
    cmd("frame-ready", "a fresh stretched frame is loaded: the job waiting for it goes on", cmd_frame_ready)
    cmd("home", "home the axes (G28)", cmd_home)
    j = cmd("jog", "move the head by DX DY [DZ] mm (within the frame)", cmd_jog)
    j.add_argument("dx", type=float)
    j.add_argument("dy", type=float)
    j.add_argument("dz", type=float, nargs="?", default=0.0)
    g = cmd("goto", "move the head to X Y (machine mm, within the frame)", cmd_goto)
    g.add_argument("x", type=float)
    g.add_argument("y", type=float)
    gc = cmd("gcode", "send G-code commands and print the printer's answers", cmd_gcode,
             "Send one command or a short list (one argument each, quoted: ribbonctl gcode \"G28 X\" M114). "
             "While a program streams only M220, M221, M104, M140 (within the profile's limits), M105 and M114 "
             "are accepted (ribbonctl adjust). Checked whole as a G-code job is (frame, fabric, temperatures; "
             "feed rates clamped, said in a note) before anything is sent; moves start from where home, "
             "jog or goto left the head, in absolute positioning (G90).")
    gc.add_argument("commands", nargs="+", metavar="COMMAND")
    h = cmd("heat", "heat the nozzle (default: the profile's temperature) and/or the bed", cmd_heat)
    h.add_argument("--nozzle", type=float, metavar="C")
    h.add_argument("--bed", type=float, metavar="C")
    cmd("cool", "heaters off", cmd_cool)
    a = cmd("adjust", "adjust a print in progress: speed (M220), flow (M221), nozzle, bed", cmd_adjust,
            "Change the feed override, the flow and the heater targets, also while a job prints (OctoPrint's "
            "and Mainsail's controls). The values are checked against the printer profile's [adjust] ranges "
            "and temperature limits (while printing the nozzle stays at or above adjust.nozzle_min); the "
            "printer reports back the speed and flow it now runs with.")
    a.add_argument("--speed", type=float, metavar="PCT", help="feed override, %% (M220 S)")
    a.add_argument("--flow", type=float, metavar="PCT", help="flow, %% (M221 S)")
    a.add_argument("--nozzle", type=float, metavar="C", help="nozzle target, °C (M104 S)")
    a.add_argument("--bed", type=float, metavar="C", help="bed target, °C (M140 S)")
    cmd("stop", "emergency stop (M112)", cmd_stop)
    cmd("recover", "after an emergency stop or a halt: restart the firmware (M999)", cmd_recover)


def _table_commands(cmd: Command) -> None:
    """tables: the daemon's curvature tables."""
    t = cmd("tables", "the daemon's curvature tables: list, show NAME, add FILE, remove NAME", cmd_tables)
    t.add_argument("action", choices=("list", "show", "add", "remove"))
    t.add_argument("arg", nargs="?", help="NAME (show, remove) or FILE (add)")
