"""``SimulatedPrinter``: the firmware, the pty and the faults on their own thread.

The simulator owns a thread running an asyncio loop.  Everything that changes
state runs on that loop; public methods hand work to it (call_soon_threadsafe) or
read snapshots kept under a lock, so they are safe from any thread.

The loop is event driven: after each step it computes when the next thing happens
(a newline arriving, a block finishing, a reply leaving the wire, a timer) and
sleeps until then.  Inside a step, input is handed to the firmware with each
line's arrival time, so the firmware works in accurate virtual time even when the
loop wakes up late.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import dataclasses
import logging
import threading
import time
from collections.abc import Callable
from typing import TypeVar

from .config import SimConfig
from .faults import FaultInjector
from .firmware import Firmware
from .frame import Frame, FramePose
from .gcode import strip_line_number
from .record import CommandRecord, Recorder, Segment
from .serialport import PtyPort
from .stats import Stats

__all__ = ["SimulatedPrinter"]

log = logging.getLogger("sim")

T = TypeVar("T")

_MIN_GAP_S = 0.0002  # batch work instead of waking for every byte
_IDLE_WAKE_S = 0.5
_CALL_TIMEOUT_S = 10.0

_UNSOLICITED_TEXT = {
    "busy": "echo:busy: processing",
    "action": "//action:notification Printing...",
    "settings": "echo:Settings Stored (sim)",
}


class _Core:
    """Everything that lives on the simulator's loop: port, firmware, faults, frame."""

    def __init__(self, config: SimConfig, loop: asyncio.AbstractEventLoop, recorder: Recorder,
                 on_port_change: Callable[[str], None] | None) -> None:
        self.config = config
        self.loop = loop
        self.recorder = recorder
        self.on_port_change = on_port_change
        self.stats = Stats()
        self.faults = FaultInjector(config.faults, config.seed)
        self.frame = Frame(config.frame)
        self.port = PtyPort(loop, config.byte_time, self.stats, on_read=self._on_read,
                            on_open=self._on_open, on_close=self._on_close,
                            on_activity=self.reschedule)
        self.fw = Firmware(config, emit=self._emit, recorder=recorder, stats=self.stats,
                           frame=self.frame, faults=self.faults, on_trigger=self._on_trigger,
                           on_reset=self.port.output.clear)
        self._timer: asyncio.TimerHandle | None = None
        self._timer_at = float("inf")
        self._replug: asyncio.TimerHandle | None = None
        self.errors: list[BaseException] = []
        """Internal failures; public calls re-raise the first so a bug cannot hide."""

    def start(self) -> str:
        now = time.monotonic()
        self.fw.t = now
        self.fw.update_thermal()
        path = self.port.open()
        self.reschedule()
        return path

    def close(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
        if self._replug is not None:
            self._replug.cancel()
        self.port.close()

    # --- scheduling ------------------------------------------------------------------

    def step(self) -> None:
        """Bring the world up to now: arrived input in order, then time itself."""
        self._timer = None
        self._timer_at = float("inf")
        now = time.monotonic()
        try:
            for piece, t in self.port.input.take(now):
                self.fw.advance(t)
                self.fw.receive(piece, t)
            self.fw.advance(now)
            self.port.flush(now)
        except Exception as exc:  # keep serving, but make the failure visible
            log.exception("simulated printer step failed")
            self.errors.append(exc)
        self.reschedule()

    def reschedule(self) -> None:
        now = time.monotonic()
        times = (self.fw.next_event(), self.port.input.next_event(), self.port.output.next_event())
        at = min((x for x in times if x is not None), default=now + _IDLE_WAKE_S)
        at = max(at, now + _MIN_GAP_S)
        if self._timer is not None:
            if self._timer_at <= at:
                return
            self._timer.cancel()
        self._timer = self.loop.call_at(at, self.step)
        self._timer_at = at

    # --- port callbacks --------------------------------------------------------------

    def _on_read(self, data: bytes, t: float) -> bytes:
        data, hits = self.faults.corrupt(data)
        self.stats.corrupted_lines += hits
        return data

    def _on_open(self, t: float) -> None:
        # Opening the port reboots the board, as the DTR line does on boards with a USB-serial
        # chip; native USB boards (Duet, Smoothieboard) keep running.
        self.stats.connections += 1
        self.step()
        if self.config.spec.resets_on_open:
            self.fw.reset(t, count=False)
        self.reschedule()

    def _on_close(self, t: float) -> None:
        self.reschedule()

    # --- output path (faults on the way out) -----------------------------------------

    def _emit(self, text: str, t: float, is_ok: bool) -> None:
        if is_ok:
            if self.faults.drop_ok():
                self.stats.oks_dropped += 1
                return
            self.stats.oks_sent += 1
        kind = self.faults.unsolicited()
        if kind is not None:
            extra = _UNSOLICITED_TEXT.get(kind) or " " + self.fw.temperature_report()
            self.stats.unsolicited_lines += 1
            self.port.send(extra.encode("latin-1") + b"\n", t)
        delay = self.faults.slow_delay()
        if delay > 0:
            self.stats.slow_lines += 1
        self.port.send(text.encode("latin-1", "replace") + b"\n", t + delay)

    # --- actions ---------------------------------------------------------------------

    def _on_trigger(self, name: str) -> None:
        if name == "disconnect":
            # Not from inside the firmware's intake loop: unplug once it returns.
            self.loop.call_soon(self.disconnect)

    def disconnect(self) -> None:
        self.step()
        self.stats.disconnects += 1
        self.port.close()
        delay = self.config.faults.reconnect_after_s
        if delay is not None:
            self._replug = self.loop.call_later(delay, self._plug_in)
        self.reschedule()

    def _plug_in(self) -> None:
        self._replug = None
        path = self.port.open()
        if self.on_port_change is not None:
            self.on_port_change(path)

    def reset(self) -> None:
        self.step()
        self.fw.reset(time.monotonic())
        self.reschedule()

    def runaway(self) -> None:
        self.step()
        self.fw.thermal_error("runaway")
        self.port.flush(time.monotonic())
        self.reschedule()

    def flip(self, offset: tuple[float, float], rotation_deg: float) -> FramePose:
        self.step()  # moves finished so far were laid down in the old pose
        return self.frame.flip(offset, rotation_deg)

    def reset_stats(self) -> None:
        self.step()
        for f in dataclasses.fields(Stats):
            setattr(self.stats, f.name, f.default)
        self.fw.reset_stats()

    def snapshot_stats(self) -> Stats:
        self.step()
        return dataclasses.replace(self.stats)

    def queued(self) -> list[str]:
        """The command queue, oldest first (the one running heads it), without N<line> and *checksum."""
        self.step()
        return [strip_line_number(c.text) for c in self.fw.queue]

    def is_idle(self) -> bool:
        self.step()
        # Bytes the host has not read yet do not count: an idle host may not read.
        return (self.fw.is_idle() and self.port.input.pending() == 0
                and self.port.output.pending() == 0)


class SimulatedPrinter:
    """A simulated Marlin 2.x printer behind a pty, for tests and as a program.

    Use as a context manager (or ``start()``/``stop()``).  ``port`` is the device
    path a host opens.  All methods are thread-safe.
    """

    def __init__(self, config: SimConfig | None = None, *, record_path: str | None = None,
                 control_path: str | None = None,
                 on_port_change: Callable[[str], None] | None = None) -> None:
        self.config = config or SimConfig()
        self._record_path = record_path
        self._control_path = control_path
        self._on_port_change = on_port_change
        self._recorder: Recorder | None = None
        self._core: _Core | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._stop_future: asyncio.Future[None] | None = None
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._port: str | None = None

    # --- life cycle ------------------------------------------------------------------

    def start(self) -> SimulatedPrinter:
        if self._thread is not None:
            raise RuntimeError("already started")
        self._recorder = Recorder(self._record_path)
        self._thread = threading.Thread(target=self._thread_main, name="sim-printer", daemon=True)
        self._thread.start()
        self._ready.wait()
        if self._error is not None:
            self._thread.join()
            raise RuntimeError("simulated printer failed to start") from self._error
        return self

    def stop(self) -> None:
        """Close the pty and the control socket and join the thread. Idempotent."""
        loop, thread = self._loop, self._thread
        if loop is not None and thread is not None and thread.is_alive():
            def _finish() -> None:
                if self._stop_future is not None and not self._stop_future.done():
                    self._stop_future.set_result(None)
            try:
                loop.call_soon_threadsafe(_finish)
            except RuntimeError:
                pass  # loop already closed
            thread.join()
        if self._recorder is not None:
            self._recorder.close()

    def __enter__(self) -> SimulatedPrinter:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _thread_main(self) -> None:
        loop = asyncio.new_event_loop()
        self._loop = loop
        asyncio.set_event_loop(loop)
        try:
            loop.run_until_complete(self._serve())
        except BaseException as exc:  # surface start-up failures to start()
            self._error = exc
        finally:
            self._ready.set()
            loop.close()

    async def _serve(self) -> None:
        loop = asyncio.get_running_loop()
        assert self._recorder is not None
        core = _Core(self.config, loop, self._recorder, self._port_changed)
        self._core = core
        self._port = core.start()
        server = None
        try:
            if self._control_path:
                from .control import serve_control
                server = await serve_control(self._control_path, self)
            self._stop_future = loop.create_future()
            self._ready.set()
            await self._stop_future
        finally:
            if server is not None:
                server.close()
                await server.wait_closed()
                from .control import remove_socket
                remove_socket(self._control_path)
            core.close()

    def _port_changed(self, path: str) -> None:
        self._port = path
        if self._on_port_change is not None:
            self._on_port_change(path)

    def _call(self, fn: Callable[[], T]) -> T:
        """Run ``fn`` on the simulator's loop and return its result."""
        if self._loop is None or self._core is None:
            raise RuntimeError("simulated printer is not running")
        if threading.current_thread() is self._thread:
            return fn()
        fut: concurrent.futures.Future[T] = concurrent.futures.Future()

        def run() -> None:
            try:
                fut.set_result(fn())
            except BaseException as exc:
                fut.set_exception(exc)

        self._loop.call_soon_threadsafe(run)
        result = fut.result(timeout=_CALL_TIMEOUT_S)
        if self._core.errors:
            raise RuntimeError("the simulated printer failed internally") from self._core.errors[0]
        return result

    def _c(self) -> _Core:
        if self._core is None:
            raise RuntimeError("simulated printer is not running")
        return self._core

    # --- public API ------------------------------------------------------------------

    @property
    def port(self) -> str:
        """Device path of the pty slave (e.g. /dev/pts/3) for the host to open."""
        if self._port is None:
            raise RuntimeError("simulated printer is not running")
        return self._port

    @property
    def halted_at(self) -> float | None:
        """time.monotonic() when the firmware halted (M112, kill), else None."""
        return self._core.fw.halted_at if self._core is not None else None

    def commands(self) -> list[CommandRecord]:
        """Every command executed so far, in order."""
        return self._recorder.commands() if self._recorder is not None else []

    def segments(self, start: int = 0) -> list[Segment]:
        """Every extrusion segment laid down so far, in order (from the ``start``-th on)."""
        return self._recorder.segments(start) if self._recorder is not None else []

    def stats(self) -> Stats:
        return self._call(lambda: self._c().snapshot_stats())

    def reset_stats(self) -> None:
        self._call(lambda: self._c().reset_stats())

    def queued(self) -> list[str]:
        """The firmware's command queue: the command running (if any) first, then those received behind it."""
        return self._call(lambda: self._c().queued())

    def set_corrupt_rate(self, rate: float) -> None:
        """Change the share of incoming lines corrupted from now on (benchmarks start the noise
        after the handshake)."""
        config = dataclasses.replace(self.config.faults, corrupt_rate=rate)  # validates the rate

        def apply() -> None:
            self._c().faults.config = config
        self._call(apply)

    def trigger_reset(self) -> None:
        """Reboot the board now: banner, all state lost."""
        self._call(lambda: self._c().reset())

    def trigger_disconnect(self) -> None:
        """Unplug: close the pty master (the host's reads fail with EIO)."""
        self._call(lambda: self._c().disconnect())

    def trigger_runaway(self) -> None:
        """Thermal runaway: error, then halted as by kill()."""
        self._call(lambda: self._c().runaway())

    def flip(self, offset: tuple[float, float] = (0.0, 0.0), rotation_deg: float = 0.0) -> FramePose:
        """Turn the fabric frame over, misaligned by ``rotation_deg`` then ``offset``."""
        return self._call(lambda: self._c().flip(offset, rotation_deg))

    def frame_pose(self) -> FramePose:
        return self._call(lambda: self._c().frame.pose)

    def head_position(self) -> tuple[float, float, float, float]:
        """Where the nozzle is now (x, y, z, e; mm), as the steppers move it (the camera draws it)."""
        return self._call(lambda: self._c().fw.planner.position_at(time.monotonic()))

    def render_png(self, path: str) -> None:
        """PNG of the deposits, in machine and in fabric coordinates."""
        from .render import render_png
        render_png(self.segments(), path, self.config.frame)

    def wait_idle(self, timeout: float = 10.0) -> bool:
        """Block until nothing is in flight, queued or planned; False on timeout."""
        deadline = time.monotonic() + timeout
        streak = 0
        while True:
            if self._call(lambda: self._c().is_idle()):
                streak += 1
                if streak >= 2:  # seen twice, so a line just written is not missed
                    return True
            else:
                streak = 0
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.01)
