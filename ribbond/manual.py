"""Manual control (issue 13): home, jog, goto, typed G-code, heat, cool, between and around prints,
never while a program streams (a job paused, awaiting the flip or aligning, or no job at all);
the printer's status; the emergency stop and the recovery after it.

Moves stay inside the frame and above the fabric; the head's commanded position is tracked
(``Head``) so a jog goes from where the head was sent, not from ``M114``'s rounded report.
"""

from __future__ import annotations

import asyncio
import contextlib
from typing import Any

import numpy as np

from .gcode.profiles import PrinterProfile
from .head import Head
from .jobs import JobState
from .printer import codec
from .printer.errors import LinkError
from .printer.link import LinkState, PrinterLink, prepare_program
from .records import JobRecords, ServiceError
from .run import PrintState

#: At most this many commands in one manual G-code request.
MAX_MANUAL_COMMANDS = 16
#: Jogs and gotos move at most this fast in X/Y, mm/s (the profile's travel speed if slower).
JOG_SPEED = 50.0
#: Commands after which the head's position is no longer the one the daemon commanded.
_MOVES_HEAD = frozenset({"G0", "G1", "G2", "G3", "G28", "G29", "G92", "G30", "M206", "M428"})


class ManualControl:
    """The operator's direct commands to the printer; the run (``state``) says when they may move it."""

    def __init__(self, head: Head, profile: PrinterProfile, records: JobRecords, state: PrintState) -> None:
        self.head, self.profile, self.records, self.state = head, profile, records, state

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
                raise ServiceError(f"cannot {what}: job {job.id} is {job.state.value} (a program is streaming "
                                   f"to the printer); {hint}")
            if run.busy:
                raise ServiceError(f"cannot {what}: job {job.id} is pausing or resuming; try again in a moment")
        link = self.head.require_link()
        if link.state is LinkState.STREAMING:
            raise ServiceError(f"cannot {what}: a program is streaming to the printer")
        return link

    def _inside(self, x: float, y: float, z: float, what: str) -> None:
        x0, y0, x1, y1 = self.profile.frame.bounds
        fabric = self.profile.layers.fabric_z
        eps = 1e-6
        if not (x0 - eps <= x <= x1 + eps and y0 - eps <= y <= y1 + eps):
            raise ValueError(f"{what} would take the head to x {x:.3f}, y {y:.3f}: outside the frame "
                             f"(x {x0:g} to {x1:g}, y {y0:g} to {y1:g} mm)")
        if z < fabric - eps:
            raise ValueError(f"{what} would take the nozzle down to z {z:.3f}, below the fabric (z {fabric:g} mm)")

    async def _move_to(self, link: PrinterLink, x: float, y: float, z: float) -> None:
        here = await self.head.where(link)
        xy_feed = min(JOG_SPEED, self.profile.motion.travel_speed) * 60
        z_feed = self.profile.motion.z_speed * 60
        xy = f"G0 X{x:.3f} Y{y:.3f} F{xy_feed:.0f}"
        zz = f"G0 Z{z:.3f} F{z_feed:.0f}"
        # up before moving across, down after: never dragged over the fabric
        moves = [zz, xy] if z >= here[2] else [xy, zz]
        for command in ("G90", *moves, "M400"):
            await link.send(command, timeout=300)
        self.head.set((x, y, z))

    def _position_status(self) -> dict[str, Any]:
        return {"position": list(self.head.position) if self.head.position is not None else None}

    async def home(self) -> dict[str, Any]:
        """Home all axes (``G28``); the head's position is then the printer's."""
        async with self.head.lock:
            link = self._manual_link("home")
            await link.send("G28", timeout=300)
            self.head.forget()
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
            target = (x + dx, y + dy, z + dz)
            self._inside(*target, what=f"jog {dx:g} {dy:g} {dz:g}")
            await self._move_to(link, *target)
            return self._position_status()

    async def goto(self, x: float, y: float) -> dict[str, Any]:
        """Move the head to (x, y) in the frame, at least at the safe height above the fabric."""
        if not (np.isfinite(x) and np.isfinite(y)):
            raise ValueError("x and y must be finite numbers of mm")
        async with self.head.lock:
            link = self._manual_link("goto")
            _, _, z = await self.head.where(link)
            z = max(z, self.profile.layers.fabric_z + self.profile.layers.safe_height)
            self._inside(x, y, z, what=f"goto {x:g} {y:g}")
            await self._move_to(link, x, y, z)
            return self._position_status()

    async def gcode(self, commands: list[str]) -> dict[str, Any]:
        """Send typed G-code (one command or a short list) and return what the printer answered."""
        clean = [c.strip() for c in commands if c.strip()]
        if not clean:
            raise ValueError("no G-code command given")
        if len(clean) > MAX_MANUAL_COMMANDS:
            raise ValueError(f"{len(clean)} commands: at most {MAX_MANUAL_COMMANDS} at a time "
                             "(print a longer program as a job: ribbonctl print FILE)")
        for i, command in enumerate(clean, start=1):
            word = command.split()[0].upper()
            if word == "M112":
                raise ValueError("M112 is the emergency stop: use ribbonctl stop")
            prepare_program([command], f"command {i}")       # M110, too long, not ASCII: refused
            codec.check_sendable(codec.strip_comment(command) or command)
        async with self.head.lock:
            link = self._manual_link("send G-code")
            answers = []
            for command in clean:
                _, lines = await link.send_collecting(command, timeout=600)
                if command.split()[0].upper() in _MOVES_HEAD:
                    self.head.forget()
                answers.append({"command": command, "answer": lines})
            return {"answers": answers}

    async def heat(self, nozzle: float | None, bed: float | None) -> dict[str, Any]:
        """Set heater targets (no wait); defaults: the profile's nozzle temperature, the bed as it is."""
        t = self.profile.temperatures
        nozzle = t.nozzle if nozzle is None and bed is None else nozzle
        if nozzle is not None and not 0 <= nozzle <= t.nozzle_max:
            raise ValueError(f"nozzle {nozzle:g} °C: must be 0 to the profile's nozzle_max ({t.nozzle_max:g} °C)")
        if bed is not None and not 0 <= bed <= t.bed_max:
            raise ValueError(f"bed {bed:g} °C: must be 0 to the profile's bed_max ({t.bed_max:g} °C)")
        async with self.head.lock:
            link = self._manual_link("heat")
            if nozzle is not None:
                await link.send(f"M104 S{nozzle:.0f}")
            if bed is not None:
                await link.send(f"M140 S{bed:.0f}")
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
        status["profile"] = self._profile_info()
        return status

    def _profile_info(self) -> dict[str, Any]:
        """The daemon's printer profile as a person choosing a design's size needs it: its name and
        frame (the printable rectangle, its centre, the axis the frame is flipped about)."""
        frame = self.profile.frame
        return {"name": self.profile.name, "frame": {"bounds": list(frame.bounds), "center": list(frame.center),
                                                     "size": list(frame.size), "flip_axis": frame.flip_axis}}

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
        self.head.forget()
        return await self.printer_status()
