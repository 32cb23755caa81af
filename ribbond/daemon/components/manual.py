"""Manual control (issue 13): home, jog, goto, typed G-code, heat, cool, between and around prints,
never while a program streams (a job paused, awaiting the flip or aligning, or no job at all);
the printer's status; the emergency stop and the recovery after it.

While a program streams, typed G-code, ``heat`` and ``adjust`` still go in beside it (issue 36), but
only the adjustments a print allows (feed override M220, flow M221, nozzle M104 and bed M140 within
the profile's ``[adjust]`` and temperature limits) and the queries M105 and M114: the checker's
``printing`` mode refuses everything else, a move first of all.

Moves stay inside the frame and above the fabric, temperatures within the profile: jog, goto, heat
and typed G-code are checked by the same ``checker.GcodeChecker`` as a plain G-code job (typed G-code
unchecked only with ``[manual] raw_console = true``). The head's commanded position is tracked
(``Head``) so a jog goes from where the head was sent, not from ``M114``'s rounded report.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from typing import Any

import numpy as np

from ribbond.gcode.checker import Checked, GcodeChecker, Modal, NotWhilePrinting, parse_command
from ribbond.gcode.profiles import PrinterProfile
from ribbond.printer import codec
from ribbond.printer.errors import LinkError
from ribbond.printer.link import LinkState, PrinterLink, prepare_program
from ..config import ManualSettings
from ..jobs import JobState, state_name
from ..records import JobRecords, ServiceError
from .head import Head
from .run import PrintState

log = logging.getLogger(__name__)

#: At most this many commands in one manual G-code request.
MAX_MANUAL_COMMANDS = 16
#: Jogs and gotos move at most this fast in X/Y, mm/s (the profile's travel speed if slower).
JOG_SPEED = 50.0
#: Seconds an adjustment sent beside a running program may wait for its ``ok`` (the program's
#: queued lines run first on firmware that answers in order).
ADJUST_TIMEOUT_S = 120.0


class ManualControl:
    """The operator's direct commands to the printer; the run (``state``) says when they may move it."""

    def __init__(self, head: Head, profile: PrinterProfile, records: JobRecords, state: PrintState,
                 settings: ManualSettings | None = None) -> None:
        self.head, self.profile, self.records, self.state = head, profile, records, state
        self.settings = settings if settings is not None else ManualSettings()
        if self.settings.raw_console:
            log.warning("[manual] raw_console = true: typed G-code is sent to the printer unchecked "
                        "(no frame, fabric, temperature or feed rate check)")

    def _manual_link(self, what: str) -> PrinterLink:
        """The link, if the operator may move the printer now: no program streaming (a job paused,
        awaiting the flip or aligning, or no job at all)."""
        run = self.state.run
        if run is not None:
            job = self.records.get(run.job_id)
            if job.state.streams or job.state not in (JobState.PAUSED, JobState.AWAITING_FLIP, JobState.ALIGNING,
                                                      JobState.FITTED, JobState.AWAITING_CHECK):
                hint = f"pause it first: ribbonctl pause {job.id}" if job.state in (
                    JobState.PRINTING_FRONT, JobState.PRINTING_BACK) else f"wait, or cancel it: ribbonctl cancel {job.id}"
                raise ServiceError(f"cannot {what}: job {job.id} is {state_name(job.state, job.kind)} (a program is streaming "
                                   f"to the printer); {hint}")
            if run.busy:
                raise ServiceError(f"cannot {what}: job {job.id} is pausing or resuming; try again in a moment")
        link = self.head.require_link()
        if link.state is LinkState.STREAMING:
            raise ServiceError(f"cannot {what}: a program is streaming to the printer")
        return link

    def _check(self, commands: list[str], start: tuple[float, float, float] | None, what: str,
               printing: bool = False) -> Checked:
        """``commands`` checked as a plain G-code job's lines are (``checker``), from ``start`` in
        absolute mode; refusals name ``what`` (e.g. "jog 5 0 0"), or for typed G-code (``what``
        "command") the command and its number ("command 2 (G1 Z-2)"). ``printing``: they go in
        beside a running program (only the adjustments and the queries pass)."""
        modal = Modal(pos=list(start) if start is not None else [None, None, None])

        def where(number: int, command: str) -> str:
            return f"command {number} ({command})" if what == "command" else what

        return GcodeChecker(self.profile, modal=modal, where=where, printing=printing).check(commands)

    def _streaming_job(self) -> str | None:
        """The job whose program is streaming now (heating or printing a side), or None."""
        run = self.state.run
        if run is None:
            return None
        job = self.records.get(run.job_id)
        return job.id if job.state.streams else None

    async def _beside_program(self, job_id: str, typed: list[str]) -> dict[str, Any]:
        """Typed G-code while ``job_id``'s program streams (issue 36): checked with ``printing``
        (the adjustments within the profile's ``[adjust]`` and the temperature limits, M105, M114;
        never a move or a wait), whole, before any is sent; each goes out through the link's one
        sender as the next numbered line ahead of the program's next lines, so the line numbers,
        the resends and the proof that a program line ran stay the sender's. A changed feed
        override or flow is read back (bare M220 / M221) so the status shows the printer's own.
        What is refused only because the program prints (a move, a wait, the nozzle below
        ``adjust.nozzle_min``) is a ``ServiceError`` (409); a value beyond the profile's limits a
        ``ValueError`` (422)."""
        run = self.state.run
        if run is not None and run.busy:
            raise ServiceError(f"cannot send G-code: job {job_id} is pausing or resuming; try again in a moment")
        try:
            checked = self._check(typed, None, "command", printing=True)
        except NotWhilePrinting as refused:         # allowed once the job is paused: a conflict (409)
            raise ServiceError(f"{refused}; job {job_id} is printing") from None
        link = self.head.require_link()
        answers = []
        for text, command in zip(typed, checked.commands):
            answer, lines = await link.send_collecting(command, timeout=ADJUST_TIMEOUT_S)
            answers.append({"command": text, "answer": _own_lines(lines, answer.line)})
        await _read_back(link, checked.commands)
        return {"answers": answers, "printing": job_id,
                "notes": [f"sent beside job {job_id}'s program: while it prints only M220, M221, M104, M140 "
                          "(within the profile's limits), M105 and M114 are accepted"]}

    async def adjust(self, speed: float | None = None, flow: float | None = None, nozzle: float | None = None,
                     bed: float | None = None) -> dict[str, Any]:
        """Set the feed override (M220 S, %), the flow (M221 S, %) and the heater targets (M104 S,
        M140 S, °C), while a program prints or not: sent as typed G-code (``gcode``), so through
        the same check; the printer's status after it."""
        values = {"speed": speed, "flow": flow, "nozzle": nozzle, "bed": bed}
        for name, value in values.items():
            if value is not None and not np.isfinite(value):
                raise ValueError(f"{name} must be a finite number")
        commands = [f"{code} S{value:g}" for code, value in zip(("M220", "M221", "M104", "M140"), values.values())
                    if value is not None]
        if not commands:
            raise ValueError("nothing to adjust: give speed, flow, nozzle or bed")
        result = await self.gcode(commands)
        return {**result, "printer": await self.printer_status(refresh=True)}

    def _move_commands(self, here: tuple[float, float, float], x: float, y: float, z: float) -> list[str]:
        """The moves to (x, y, z): up before moving across, down after (never dragged over the fabric)."""
        xy_feed = min(JOG_SPEED, self.profile.motion.travel_speed) * 60
        z_feed = self.profile.motion.z_speed * 60
        xy = f"G0 X{x:.3f} Y{y:.3f} F{xy_feed:.0f}"
        zz = f"G0 Z{z:.3f} F{z_feed:.0f}"
        return [zz, xy] if z >= here[2] else [xy, zz]

    async def _move_to(self, link: PrinterLink, x: float, y: float, z: float, what: str) -> None:
        """Check, then make the moves to (x, y, z) (``_move_commands``) and wait for them."""
        here = await self.head.where(link)
        moves = self._check(self._move_commands(here, x, y, z), here, what).commands
        for command in ("G90", *moves, "M400"):
            await link.send(command, timeout=300)
        self.head.set((x, y, z))

    def _position_status(self) -> dict[str, Any]:
        return {"position": list(self.head.position) if self.head.position is not None else None,
                "homed": self.head.homed()}

    async def home(self) -> dict[str, Any]:
        """Home all axes (``G28``); the head's position is then the printer's."""
        async with self.head.lock:
            link = self._manual_link("home")
            await link.send("G28", timeout=300)
            self.head.forget()
            self.head.ran(["G28"])
            await self.head.where(link)
            return self._position_status()

    async def jog(self, dx: float, dy: float, dz: float = 0.0) -> dict[str, Any]:
        """Move the head by (dx, dy, dz) mm at a safe feed, within the frame and above the fabric."""
        for name, v in (("dx", dx), ("dy", dy), ("dz", dz)):
            if not np.isfinite(v):
                raise ValueError(f"{name} must be a finite number of mm")
        async with self.head.lock:
            link = self._manual_link("jog")
            x, y, z = await self.head.where(link)
            await self._move_to(link, x + dx, y + dy, z + dz, what=f"jog {dx:g} {dy:g} {dz:g}")
            return self._position_status()

    async def goto(self, x: float, y: float) -> dict[str, Any]:
        """Move the head to (x, y) in the frame, at least at the safe height above the fabric."""
        if not (np.isfinite(x) and np.isfinite(y)):
            raise ValueError("x and y must be finite numbers of mm")
        async with self.head.lock:
            link = self._manual_link("goto")
            _, _, z = await self.head.where(link)
            z = max(z, self.profile.layers.fabric_z + self.profile.layers.safe_height)
            await self._move_to(link, x, y, z, what=f"goto {x:g} {y:g}")
            return self._position_status()

    async def gcode(self, commands: list[str]) -> dict[str, Any]:
        """Send typed G-code (one command or a short list) and return what the printer answered.

        The batch is checked whole, as a plain G-code job is (``checker``: inside the frame, above
        the fabric, temperatures, feed rates clamped as the firmware would; moves from the head's
        commanded position, which homing, jog or goto make known), before its first command goes
        out. It runs in absolute positioning (G90 is sent first when it moves the head) and leaves
        the printer so. ``[manual] raw_console = true`` sends it unchecked (logged)."""
        clean = _typed(commands)
        job_id = self._streaming_job()
        if job_id is not None:
            return await self._beside_program(job_id, clean)
        async with self.head.lock:
            link = self._manual_link("send G-code")
            if self.settings.raw_console:
                return await self._send_unchecked(link, clean)
            checked = self._check(clean, self.head.commanded(link), "command")
            notes = checked.notes(self.profile, unit="command")
            moves_head = any(_moves_head(c) for c in checked.commands)
            try:
                answers = await self._send_checked(link, clean, checked.commands, moves_head)
                if not checked.modal.absolute:
                    await link.send("G90", timeout=60)
                    notes.append("G90 sent after the commands: the printer is left in absolute positioning, as "
                                 "the daemon's moves and G-code jobs expect (give G91 and its moves in one request)")
            except BaseException:
                self.head.forget()              # stopped part way: where the head is, the printer says
                self.head.ran(checked.commands)   # (a G28 or M84 among them may have run: the worse is assumed)
                raise
            self.head.ran(checked.commands)
            await self._after_typed(link, checked.modal, moves_head)
            await _read_back(link, checked.commands)
            return {"answers": answers, "notes": notes}

    @staticmethod
    async def _send_checked(link: PrinterLink, typed: list[str], commands: list[str],
                            moves_head: bool) -> list[dict[str, Any]]:
        """Send the checked commands (G90 first when they move the head); the printer's answers."""
        if moves_head:
            await link.send("G90", timeout=60)
        answers = []
        for text, command in zip(typed, commands):
            _, lines = await link.send_collecting(command, timeout=600)
            answers.append({"command": text, **({"sent": command} if command != text else {}), "answer": lines})
        return answers

    async def _after_typed(self, link: PrinterLink, modal: Modal, moved: bool) -> None:
        """The head's position after checked G-code: the printer's own after a homing, the checked
        end position otherwise (forgotten where it is not known, e.g. motors switched off)."""
        if modal.homed:
            self.head.forget()
            with contextlib.suppress(LinkError, asyncio.TimeoutError):
                await self.head.where(link)
        elif modal.motors_off or modal.known() is None:
            self.head.forget()
        elif moved:
            self.head.set(modal.known())  # type: ignore[arg-type]

    async def _send_unchecked(self, link: PrinterLink, clean: list[str]) -> dict[str, Any]:
        """``[manual] raw_console = true``: sent as typed, each command logged as unchecked."""
        answers = []
        for command in clean:
            log.warning("raw console ([manual] raw_console = true): sending unchecked G-code: %s", command)
            _, lines = await link.send_collecting(command, timeout=600)
            self.head.forget()
            self.head.ran([command])
            answers.append({"command": command, "answer": lines})
        return {"answers": answers, "notes": ["sent unchecked: [manual] raw_console = true in the daemon's "
                                              "configuration"], "unchecked": True}

    async def heat(self, nozzle: float | None, bed: float | None) -> dict[str, Any]:
        """Set heater targets (no wait); defaults: the profile's nozzle temperature, the bed as it is."""
        t = self.profile.temperatures
        nozzle = t.nozzle if nozzle is None and bed is None else nozzle
        for name, value in (("nozzle", nozzle), ("bed", bed)):
            if value is not None and not np.isfinite(value):
                raise ValueError(f"{name} must be a finite number of °C")
        sets = ([f"M104 S{nozzle:.0f}"] if nozzle is not None else []) + ([f"M140 S{bed:.0f}"] if bed is not None else [])
        what = " ".join(f"--{n} {v:g}" for n, v in (("nozzle", nozzle), ("bed", bed)) if v is not None)
        if self._streaming_job() is not None:          # beside a running program: its checks
            await self.gcode(sets)
            return await self.printer_status(refresh=True)
        sets = self._check(sets, None, f"heat {what}").commands
        async with self.head.lock:
            link = self._manual_link("heat")
            for command in sets:
                await link.send(command)
        return await self.printer_status(refresh=True)

    async def cool(self) -> dict[str, Any]:
        """Heaters off."""
        async with self.head.lock:
            link = self._manual_link("cool")
            await link.send("M104 S0")
            await link.send("M140 S0")
        return await self.printer_status(refresh=True)

    async def printer_status(self, refresh: bool = False) -> dict[str, Any]:
        """What the link knows; with ``refresh``, the temperatures and position asked for first
        (``M105``, ``M114``: answered ahead of a running program). Halted or disconnected, no
        temperatures or position are shown: the last ones known would be stale."""
        if self.head.link is None:
            return {"state": "disconnected", "heaters": {}, "position": None, "profile": self._profile_info()}
        live = self.head.link.state in (LinkState.READY, LinkState.STREAMING, LinkState.PAUSED)
        if refresh and live:
            with contextlib.suppress(LinkError, asyncio.TimeoutError):
                await asyncio.wait_for(self.head.link.query_temperatures(), 10)
                await asyncio.wait_for(self.head.link.query_position(), 10)
        status = self.head.link.status.model_dump(mode="json")
        if not live:
            status["heaters"], status["position"] = {}, None
            status["note"] = {"halted": "halted: temperatures unknown; ribbonctl recover restarts the firmware",
                              "disconnected": "not connected: temperatures unknown",
                              "connecting": "connecting"}.get(status["state"])
        status["head"] = list(self.head.position) if self.head.position is not None else None
        status["homed"] = self.head.homed()          # the axes homed on this connection (Mainsail's homed_axes)
        status["profile"] = self._profile_info()
        return status

    def _profile_info(self) -> dict[str, Any]:
        """The daemon's printer profile as a person choosing a design's size needs it: its name and
        frame (the printable rectangle, its centre, the axis the frame is flipped about), and what a
        print may be adjusted within (``adjust``: the percentages, the temperature limits)."""
        frame, adjust, t = self.profile.frame, self.profile.adjust, self.profile.temperatures
        return {"name": self.profile.name, "frame": {"bounds": list(frame.bounds), "center": list(frame.center),
                                                     "size": list(frame.size), "flip_axis": frame.flip_axis},
                "adjust": {"speed_percent": list(adjust.speed_percent), "flow_percent": list(adjust.flow_percent),
                           "nozzle_min": adjust.nozzle_min, "nozzle_max": t.nozzle_max, "bed_max": t.bed_max}}

    def emergency_stop(self) -> None:
        link = self.head.link
        if link is None or link.state is LinkState.DISCONNECTED:
            raise LinkError("the printer is not connected")
        link.emergency_stop()

    async def recover(self) -> dict[str, Any]:
        """After an emergency stop or a halt: restart the firmware (``M999``) and shake hands again."""
        link = self.head.link
        if link is None or link.state is LinkState.DISCONNECTED:
            raise LinkError("the printer is not connected")
        if link.state is not LinkState.HALTED:
            raise ServiceError(f"cannot recover: the printer is {link.state.value}, not halted; nothing to recover")
        await link.recover()
        # the firmware restarted: its position is unknown until homed; the report is asked afresh
        self.head.unhome()
        return await self.printer_status(refresh=True)


def _typed(commands: list[str]) -> list[str]:
    """The typed commands, stripped; refused (ValueError naming the command) when empty, too many,
    the emergency stop, or what the link cannot send (M110, too long, not ASCII)."""
    clean = [c.strip() for c in commands if c.strip()]
    if not clean:
        raise ValueError("no G-code command given")
    if len(clean) > MAX_MANUAL_COMMANDS:
        raise ValueError(f"{len(clean)} commands: at most {MAX_MANUAL_COMMANDS} at a time "
                         "(print a longer program as a job: ribbonctl print FILE)")
    for i, command in enumerate(clean, start=1):
        if command.split()[0].upper() == "M112":
            raise ValueError("M112 is the emergency stop: use ribbonctl stop")
        if not prepare_program([command], f"command {i}"):       # M110, too long, not ASCII: refused
            raise ValueError(f"command {i} ({command}): only a comment, nothing to send")
        codec.check_sendable(codec.strip_comment(command) or command)
    return clean


async def _read_back(link: PrinterLink, commands: list[str]) -> None:
    """After an M220 S… or M221 S…, the bare command: the printer reports the value it now runs
    with (the codec's ``Factor``), which the link's status keeps. A firmware that reports nothing
    leaves the status as it was."""
    if {c.split()[0].upper() for c in commands if len(c.split()) > 1} & {"M220", "M221"}:
        for code in ("M220", "M221"):           # both: the status then shows both as the printer has them
            with contextlib.suppress(LinkError, asyncio.TimeoutError):
                await link.send(code, timeout=ADJUST_TIMEOUT_S)


def _own_lines(lines: list[str], number: int) -> list[str]:
    """A command's answer lines beside a running program, without the program lines'
    acknowledgements that arrived meanwhile (ADVANCED_OK's ``ok N…`` naming another line)."""
    def other_ok(line: str) -> bool:
        event = codec.parse_line(line)
        return isinstance(event, codec.Ok) and event.line is not None and event.line != number
    return [line for line in lines if not other_ok(line)]


def _moves_head(command: str) -> bool:
    """A checked command that moves the head (a G0/G1 with X, Y or Z)."""
    code, args = parse_command(command, command)
    return code in ("G0", "G1") and any(a in args for a in "XYZ")
