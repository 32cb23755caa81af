"""The printer link: one object the rest of ribbond talks to.

It wires the transport (bytes), the codec (lines → events) and the sender (flow control) together,
runs the connection handshake, keeps the printer's status (temperatures, position, firmware) and the
link's state. Everything above it (the job state machine, the API) uses only this module.
"""

from __future__ import annotations

import asyncio
import enum
import logging
import re
import time
from collections.abc import Callable, Iterable, Sequence

from pydantic import BaseModel

from . import codec
from .capabilities import Capabilities
from .errors import Disconnected, LinkError, NotReady, PrinterHalted, PrinterReset, ProtocolError
from .sender import Answer, Sender, StreamProgress, StreamResult, Timeouts
from .transport import SerialTransport

log = logging.getLogger(__name__)

#: How long a query's report may follow its ``ok`` where the ``ok`` means "processed" (the report is
#: printed right after it, as a firmware prints a command's output once it has run).
_POSITION_AFTER_OK_S = 1.0


class LinkState(enum.Enum):
    DISCONNECTED = "disconnected"
    CONNECTING = "connecting"
    READY = "ready"
    STREAMING = "streaming"
    PAUSED = "paused"
    HALTED = "halted"


_S = LinkState
#: The only transitions the link makes. Anything else is a bug, and raises.
TRANSITIONS: dict[LinkState, frozenset[LinkState]] = {
    _S.DISCONNECTED: frozenset({_S.CONNECTING}),
    _S.CONNECTING: frozenset({_S.READY, _S.DISCONNECTED, _S.HALTED}),
    _S.READY: frozenset({_S.STREAMING, _S.CONNECTING, _S.HALTED, _S.DISCONNECTED}),
    _S.STREAMING: frozenset({_S.READY, _S.PAUSED, _S.CONNECTING, _S.HALTED, _S.DISCONNECTED}),
    _S.PAUSED: frozenset({_S.STREAMING, _S.READY, _S.CONNECTING, _S.HALTED, _S.DISCONNECTED}),
    _S.HALTED: frozenset({_S.CONNECTING, _S.DISCONNECTED}),
}


class HeaterStatus(BaseModel):
    current: float
    target: float | None = None
    power: int | None = None


class PrinterStatus(BaseModel):
    """What the link knows about the printer right now."""

    state: LinkState
    firmware: str = ""
    #: The firmware family the link speaks to (``capabilities.DIALECTS``), from ``M115``.
    dialect: str = ""
    capabilities: dict[str, bool] = {}
    advanced_ok: bool = False
    heaters: dict[str, HeaterStatus] = {}
    #: x, y, z and e (None when the firmware reports no extruder position).
    position: tuple[float, float, float, float | None] | None = None
    last_error: str | None = None
    busy: str | None = None
    #: The feed override (M220) and the flow (M221) the printer last reported, % (None: not asked).
    speed_percent: float | None = None
    flow_percent: float | None = None
    lines_acknowledged: int = -1
    #: The sender's byte window now (smaller than configured once overflow was proven), and what
    #: to configure then.
    window_bytes: int | None = None
    window_advice: str | None = None


def prepare_program(lines: Iterable[str], source: str = "program") -> list[str]:
    """Turn G-code text lines into the commands to stream.

    Comments and blank lines go; an existing ``N…`` prefix or ``*…`` checksum is removed (the link
    numbers lines itself). Raises ValueError naming the line when a command cannot be sent: too
    long for the firmware's buffer, not ASCII, or one that would break the protocol (``M110``
    renumbers lines, ``M112`` is the emergency stop and is never part of a program).
    """
    commands: list[str] = []
    for index, raw in enumerate(lines, start=1):
        command = codec.strip_comment(raw)
        if not command:
            continue
        command = _EXISTING_NUMBER.sub("", command)
        command = command.split("*", 1)[0].strip()
        if not command:
            continue
        word = command.split()[0].upper()
        if word in ("M110", "M112"):
            raise ValueError(f"{source}, line {index}: {word} cannot be part of a program "
                             f"(the link manages line numbers and the emergency stop)")
        try:
            codec.check_sendable(command)
        except ValueError as exc:
            raise ValueError(f"{source}, line {index}: {exc}") from None
        commands.append(command)
    return commands


_EXISTING_NUMBER = re.compile(r"^N\d+\s+")


class PrinterLink:
    """A connection to one Marlin-compatible printer.

    Parameters
    ----------
    port, baud
        Serial device and baud rate.
    capabilities
        Starting assumptions about the firmware (receive buffer size, ok after resend); the
        handshake and the acknowledgements refine them.
    timeouts
        Silence allowed before probing, per kind of command.
    ping_pong
        One line in flight at a time instead of a window.
    boot_wait_s
        How long to wait for the boot banner after opening (boards that reset on open need 1–2 s;
        boards that do not reset send nothing, and the handshake goes on after this long).
    temperature_interval_s
        Autoreport interval asked for with ``M155`` when the firmware has AUTOREPORT_TEMP; a
        firmware whose dialect has no ``M155`` (RepRapFirmware, Smoothieware) is asked with
        ``M105`` this often instead, as hosts do.
    """

    def __init__(
        self,
        port: str,
        baud: int = 250000,
        *,
        capabilities: Capabilities | None = None,
        timeouts: Timeouts | None = None,
        ping_pong: bool = False,
        boot_wait_s: float = 2.5,
        reset_on_open: bool = False,
        temperature_interval_s: int = 2,
    ) -> None:
        self.port = port
        self.baud = baud
        self._initial_capabilities = capabilities or Capabilities()
        self.capabilities = self._initial_capabilities.model_copy(deep=True)
        self.timeouts = timeouts or Timeouts()
        self.ping_pong = ping_pong
        self.boot_wait_s = boot_wait_s
        self.temperature_interval_s = temperature_interval_s
        self._reset_on_open = reset_on_open
        self._transport: SerialTransport | None = None
        self._sender: Sender | None = None
        self._state = LinkState.DISCONNECTED
        self._status = PrinterStatus(state=self._state)
        self._listeners: list[Callable[[codec.Event], None]] = []
        self._boot_seen: asyncio.Event | None = None
        self._last_line_at = 0.0
        self._rehandshake: asyncio.Task[None] | None = None
        self._poller: asyncio.Task[None] | None = None
        self._state_changed: asyncio.Event | None = None
        self._position_at = 0.0
        self._temperatures_at = 0.0
        self._collectors: list[list[str]] = []
        self._event_collectors: list[list[codec.Event]] = []

    # ------------------------------------------------------------------ state

    @property
    def state(self) -> LinkState:
        return self._state

    def _set_state(self, new: LinkState) -> None:
        if new == self._state:
            return
        if new not in TRANSITIONS[self._state]:
            raise NotReady(f"link cannot go from {self._state.value} to {new.value}")
        log.info("link %s -> %s", self._state.value, new.value)
        self._state = new
        self._status.state = new
        if self._state_changed is not None:
            self._state_changed.set()
            self._state_changed = asyncio.Event()

    @property
    def status(self) -> PrinterStatus:
        """A snapshot of what is known about the printer."""
        status = self._status.model_copy(deep=True)
        status.capabilities = dict(self.capabilities.reported)
        status.advanced_ok = self.capabilities.advanced_ok
        status.firmware = self.capabilities.firmware_name
        status.dialect = self.capabilities.spec.label
        if self._sender is not None:
            status.lines_acknowledged = self._sender.last_acknowledged_line
            status.window_bytes = self._sender.window.window
            status.window_advice = self._sender.window.advice
        return status

    @property
    def sender(self) -> Sender:
        if self._sender is None:
            raise NotReady("not connected")
        return self._sender

    def add_listener(self, listener: Callable[[codec.Event], None]) -> None:
        """Call ``listener`` with every event parsed from the printer (for logs and live views)."""
        self._listeners.append(listener)

    # ------------------------------------------------------------------ connecting

    async def connect(self) -> None:
        """Open the port, wait for the boot banner, number lines from 1 and learn the firmware."""
        if self._state is not LinkState.DISCONNECTED:
            raise NotReady(f"cannot connect: link is {self._state.value}")
        self._state_changed = asyncio.Event()
        self._set_state(LinkState.CONNECTING)
        self.capabilities = self._initial_capabilities.model_copy(deep=True)
        self._boot_seen = asyncio.Event()
        self._transport = SerialTransport(
            self.port, self.baud, on_line=self._on_line, on_lost=self._on_lost,
            reset_on_open=self._reset_on_open,
        )
        try:
            await self._transport.open()
            await self._await_boot()
            await self._handshake()
        except BaseException:
            self._close_transport()
            if self._state is not LinkState.DISCONNECTED:
                self._set_state(LinkState.DISCONNECTED)
            raise
        self._set_state(LinkState.READY)
        if self._poller is None and not self.capabilities.m155 and self.temperature_interval_s > 0:
            self._poller = asyncio.get_running_loop().create_task(self._poll_temperatures())

    async def _poll_temperatures(self) -> None:
        """Ask for the temperatures (``M105``) every ``temperature_interval_s`` while the link is
        up and nothing else has reported them: the dashboard's readings stay live on a firmware that
        cannot autoreport them."""
        interval = self.temperature_interval_s
        while True:
            await asyncio.sleep(interval)
            if self._state not in (LinkState.READY, LinkState.STREAMING):
                continue
            if time.monotonic() - self._temperatures_at < interval:
                continue
            try:
                await asyncio.wait_for(self.query_temperatures(), self.timeouts.default_s)
            except (LinkError, asyncio.TimeoutError) as exc:
                log.debug("temperature poll: %s", exc)

    async def _await_boot(self) -> None:
        """Wait for the banner (boards that reset on open) or for the boot wait to pass."""
        assert self._boot_seen is not None
        try:
            await asyncio.wait_for(self._boot_seen.wait(), self.boot_wait_s)
        except asyncio.TimeoutError:
            return  # no reset on open: the firmware is already up
        # The banner is a burst of lines; let it finish before talking.
        deadline = time.monotonic() + 3.0
        while time.monotonic() < deadline and time.monotonic() - self._last_line_at < 0.3:
            await asyncio.sleep(0.05)

    async def _handshake(self, attempts: int = 3) -> None:
        last_error: Exception | None = None
        for _ in range(attempts):
            self._new_sender()
            sender = self.sender
            try:
                await asyncio.wait_for(sender.reset_line_numbers(), self.timeouts.default_s * 2)
                await self._learn_firmware(sender)
                if self.capabilities.autoreport_temperatures and self.temperature_interval_s > 0:
                    await asyncio.wait_for(sender.send(f"M155 S{self.temperature_interval_s}"),
                                           self.timeouts.default_s * 2)
                return
            except (LinkError, asyncio.TimeoutError) as exc:
                if isinstance(exc, (Disconnected, PrinterHalted)) or self._transport is None \
                        or not self._transport.is_open:
                    raise
                last_error = exc
                log.warning("handshake failed (%s); trying again", exc)
        raise LinkError(f"printer on {self.port} did not complete the handshake: {last_error}")

    async def _learn_firmware(self, sender: Sender) -> None:
        """``M115``: the firmware's name (and so its dialect) and its ``Cap:`` lines.

        Most firmwares print the report before their ``ok``; Repetier acknowledges ``M115`` on
        receipt and prints it when it runs. The report is complete once the answer to an ``M114``
        sent after it has come (commands run in order), so without a ``FIRMWARE_NAME`` by the
        ``ok`` the link asks for one and waits for it."""
        seen: list[codec.Event] = []
        self._event_collectors.append(seen)
        try:
            await asyncio.wait_for(sender.send("M115"), self.timeouts.default_s * 2)
            if not any(isinstance(event, codec.FirmwareInfo) for event in seen):
                mark = len(seen)
                try:  # best effort: a firmware that names itself nowhere still gets connected
                    answer = await asyncio.wait_for(sender.send("M114"), self.timeouts.default_s)
                except asyncio.TimeoutError:
                    log.warning("no answer to M114 after M115 within %.1f s", self.timeouts.default_s)
                else:
                    if answer.ok.position is None:
                        await self._wait_for(lambda: any(isinstance(e, codec.Position) for e in seen[mark:]),
                                             self.timeouts.default_s)
        finally:
            self._event_collectors.remove(seen)
        for event in seen:
            if isinstance(event, codec.FirmwareInfo):
                self.capabilities.learn_firmware(event)
            elif isinstance(event, codec.Capability):
                self.capabilities.learn_capability(event)
        await self._learn_position_report(sender)
        if not self.capabilities.firmware_name:
            log.warning("the printer on %s did not name its firmware (M115): speaking to it as %s",
                        self.port, self.capabilities.spec.label)

    async def _learn_position_report(self, sender: Sender) -> None:
        """Where this printer puts ``M114``'s report: before its ``ok``, on it, or after it. Not
        from the firmware's name: builds that name themselves Marlin may print a command's output
        after its ``ok`` (OctoPrint's virtual printer: ``okBeforeCommandOutput``). The sender's
        proof of a re-sent line needs to know which ``ok`` is the ``M114``'s."""
        seen: list[codec.Event] = []
        self._event_collectors.append(seen)
        try:
            try:  # best effort, as M115's: a printer that does not answer keeps its dialect's row
                answer = await asyncio.wait_for(sender.send("M114"), self.timeouts.default_s * 2)
            except asyncio.TimeoutError:
                log.warning("no answer to M114 at connect within %.1f s", self.timeouts.default_s * 2)
                return
            before = any(isinstance(event, codec.Position) for event in answer.events)
            after = False
            if answer.ok.position is None and not before:
                # the report may have come already: it follows the ok itself in what was seen
                mark = next((i + 1 for i, event in enumerate(seen) if event is answer.ok), len(seen))
                after = await self._wait_for(lambda: any(isinstance(e, codec.Position) for e in seen[mark:]),
                                             _POSITION_AFTER_OK_S)
        finally:
            self._event_collectors.remove(seen)
        self.capabilities.learn_position_report(before, answer.ok.position is not None, after)
        if not (before or after or answer.ok.position is not None):
            log.warning("the printer on %s answered M114 without a position within %.1f s of its ok",
                        self.port, _POSITION_AFTER_OK_S)

    @staticmethod
    async def _wait_for(condition: Callable[[], bool], timeout: float) -> bool:
        """Poll ``condition`` until it holds (True) or ``timeout`` seconds pass (False)."""
        deadline = time.monotonic() + timeout
        while not condition():
            if time.monotonic() >= deadline:
                return False
            await asyncio.sleep(0.02)
        return True

    def _new_sender(self) -> None:
        if self._sender is not None:
            self._sender.stop(LinkError("superseded by a new handshake"))
        assert self._transport is not None
        self._sender = Sender(self._transport.write, self.capabilities, timeouts=self.timeouts,
                              ping_pong=self.ping_pong, baud=self.baud)
        self._sender.start()

    async def close(self) -> None:
        """Close the port (in-flight work fails with Disconnected)."""
        if self._rehandshake is not None:
            self._rehandshake.cancel()
        if self._poller is not None:
            self._poller.cancel()
            self._poller = None
        if self._sender is not None:
            self._sender.stop(Disconnected("link closed by the host"))
        self._close_transport()
        if self._state is not LinkState.DISCONNECTED:
            self._set_state(LinkState.DISCONNECTED)

    def _close_transport(self) -> None:
        if self._transport is not None:
            self._transport.close()
            self._transport = None

    # ------------------------------------------------------------------ commands

    async def send(self, command: str, timeout: float | None = None) -> Answer:
        """Send one command (ahead of any running program) and wait for its acknowledgement."""
        self._require(LinkState.READY, LinkState.STREAMING, LinkState.PAUSED)
        word = command.split()[0].upper() if command.split() else ""
        if word == "M112":
            self.emergency_stop()
            raise PrinterHalted("emergency stop sent")
        if word == "M110":
            raise ValueError("M110 is managed by the link (line numbers)")
        future = self.sender.send(command)
        return await (asyncio.wait_for(future, timeout) if timeout else future)

    async def send_collecting(self, command: str, timeout: float | None = None) -> tuple[Answer, list[str]]:
        """``send``, and the lines the printer printed until its acknowledgement (with the ``ok``),
        as received: for people typing G-code (other lines arriving meanwhile, such as temperature
        autoreports, are among them)."""
        lines: list[str] = []
        self._collectors.append(lines)
        try:
            answer = await self.send(command, timeout)
        finally:
            self._collectors.remove(lines)
        return answer, lines

    def _report_grace_s(self) -> float:
        """How long a query's report may follow its ``ok``: a moment where the ``ok`` means
        "processed", as long as the commands before it take where it means "received" (Repetier) or
        where this printer was seen to print the report after the ``ok`` (learned at connect)."""
        if self.capabilities.ok_means == "received" or self.capabilities.position_report == "after_ok":
            return self.timeouts.default_s
        return _POSITION_AFTER_OK_S

    async def query_temperatures(self) -> codec.Temperatures:
        """Ask for the temperatures (``M105``): on the ``ok`` line (Marlin, RepRapFirmware,
        Smoothieware), on a line before it, or after it (Repetier: wait a little)."""
        asked_at = time.monotonic()
        answer = await self.send("M105")
        if answer.ok.temperatures is not None:
            return answer.ok.temperatures
        for event in answer.events:
            if isinstance(event, codec.TemperatureReport):
                return event.temperatures
        if await self._wait_for(lambda: self._temperatures_at >= asked_at, self._report_grace_s()):
            heaters = self._status.heaters
            return codec.Temperatures(tuple(codec.HeaterReading(name, h.current, h.target, h.power)
                                            for name, h in heaters.items()))
        raise LinkError(f"printer answered M105 without temperatures: {answer.ok.text!r}")

    async def query_position(self, grace_s: float | None = None) -> codec.Position:
        """Ask for the position (``M114``), wherever the firmware puts it: on its own line before
        the ``ok`` (Marlin), on the ``ok`` line (Smoothieware), or after the ``ok`` (Repetier, whose
        ``ok`` comes on receipt: wait for it, ``grace_s`` or as the dialect allows)."""
        asked_at = time.monotonic()
        answer = await self.send("M114")
        if answer.ok.position is not None:
            return answer.ok.position
        found = answer.first(codec.Position)
        if isinstance(found, codec.Position):
            return found
        grace = self._report_grace_s() if grace_s is None else grace_s
        if await self._wait_for(lambda: self._status.position is not None and self._position_at >= asked_at,
                                grace):
            assert self._status.position is not None
            return codec.Position(*self._status.position)
        raise LinkError("printer answered M114 without a position")

    # ------------------------------------------------------------------ streaming

    async def stream(
        self,
        commands: Sequence[str],
        progress: Callable[[StreamProgress], None] | None = None,
        barriers: frozenset[int] = frozenset(),
    ) -> StreamResult:
        """Stream prepared commands (see :func:`prepare_program`); returns when every line was
        acknowledged, raises a :class:`LinkError` saying why otherwise. ``barriers``: see
        ``Sender.stream``."""
        self._require(LinkState.READY)
        self._set_state(LinkState.STREAMING)
        try:
            return await self.sender.stream(commands, progress, barriers)
        except ProtocolError:
            await self._resync()
            raise
        finally:
            if self._state in (LinkState.STREAMING, LinkState.PAUSED):
                self._set_state(LinkState.READY)

    async def _resync(self) -> None:
        """After the sender stopped on a protocol error (the printer asked for what cannot be
        given, or never acknowledged a line), its line numbers no longer match the printer's:
        number from 0 again (a new handshake) so that the safe stop and a resume can be sent."""
        if self._state not in (LinkState.STREAMING, LinkState.PAUSED):
            return
        log.warning("numbering the printer's lines again after a protocol error")
        self._set_state(LinkState.CONNECTING)
        try:
            await self._handshake()
        except (LinkError, OSError) as exc:
            log.error("handshake after a protocol error failed: %s", exc)
            await self.close()
            return
        self._set_state(LinkState.READY)

    def pause(self) -> None:
        """Stop feeding lines; what the printer already has is still executed."""
        self._require(LinkState.STREAMING)
        self.sender.pause()
        self._set_state(LinkState.PAUSED)

    def resume(self) -> None:
        self._require(LinkState.PAUSED)
        self.sender.resume()
        self._set_state(LinkState.STREAMING)

    def cancel(self) -> None:
        """End the stream after the lines in flight (the stream raises StreamCancelled)."""
        self._require(LinkState.STREAMING, LinkState.PAUSED)
        self.sender.cancel()

    def emergency_stop(self) -> None:
        """Send the emergency stop at once, ahead of everything, and halt the link: ``M112``, or
        Ctrl-X for Smoothieware (acted on as it arrives; its ``M112`` waits its turn)."""
        if self._transport is None or not self._transport.is_open:
            raise Disconnected("cannot send the emergency stop: the port is not open")
        self._transport.write_urgent(self.capabilities.stop_bytes)
        if not self.capabilities.emergency_parser:
            log.warning("the firmware reports no EMERGENCY_PARSER: M112 waits behind the commands "
                        "it has queued; cut the power if the machine must stop now")
        if self.capabilities.emergency_stop == "reboots":
            log.warning("%s reboots on M112: its queue and position are lost; the link connects "
                        "again when its banner comes", self.capabilities.spec.label)
        if self._sender is not None:
            self._sender.stop(PrinterHalted("emergency stop (M112) sent by the host"))
        if self._state is not LinkState.HALTED:
            self._set_state(LinkState.HALTED)

    async def recover(self) -> None:
        """After a halt: ask the firmware to restart (``M999``) and shake hands again."""
        self._require(LinkState.HALTED)
        assert self._transport is not None
        if self._rehandshake is not None and not self._rehandshake.done():
            # a reset's handshake still under way (a banner came, then the halt again): this one replaces it
            self._rehandshake.cancel()
        self._set_state(LinkState.CONNECTING)
        self._boot_seen = asyncio.Event()
        self._transport.write(codec.encode_unnumbered("M999"))
        await self._await_boot()
        await self._handshake()
        self._set_state(LinkState.READY)

    async def wait_for_state(self, *states: LinkState, timeout: float | None = None) -> LinkState:
        """Wait until the link is in one of ``states``."""

        async def _wait() -> LinkState:
            while self._state not in states:
                assert self._state_changed is not None
                await self._state_changed.wait()
            return self._state

        return await asyncio.wait_for(_wait(), timeout)

    def _require(self, *states: LinkState) -> None:
        if self._state not in states:
            allowed = ", ".join(s.value for s in states)
            raise NotReady(f"link is {self._state.value}; this needs it {allowed}", self._state.value)

    # ------------------------------------------------------------------ what the printer says

    def _on_line(self, text: str) -> None:
        self._last_line_at = time.monotonic()
        for lines in self._collectors:
            lines.append(text)
        event = codec.parse_line(text)
        for events in self._event_collectors:
            events.append(event)
        log.debug("<< %s", text)
        self._observe(event)
        for listener in self._listeners:
            listener(event)
        if isinstance(event, codec.Start):
            self._on_boot()
            return
        if self._sender is not None:
            self._sender.handle(event)
        if isinstance(event, codec.Error) and event.fatal:
            self._on_halt(event.message)

    def _observe(self, event: codec.Event) -> None:
        temperatures = None
        if isinstance(event, codec.Ok):
            temperatures = event.temperatures
            self._status.busy = None
            if event.position is not None:
                self._observe(event.position)
        elif isinstance(event, codec.TemperatureReport):
            temperatures = event.temperatures
        elif isinstance(event, codec.Position):
            self._status.position = (event.x, event.y, event.z, event.e)
            self._position_at = time.monotonic()
        elif isinstance(event, codec.Busy):
            self._status.busy = event.reason
        elif isinstance(event, codec.Factor):
            setattr(self._status, f"{event.kind}_percent", event.percent)
        elif isinstance(event, codec.Error):
            self._status.last_error = event.message
        if temperatures is not None:
            self._temperatures_at = time.monotonic()
            self._status.heaters = {
                h.name: HeaterStatus(current=h.current, target=h.target, power=h.power)
                for h in temperatures.heaters
            }

    def _on_boot(self) -> None:
        self._status.speed_percent = self._status.flow_percent = None  # a reboot resets them
        if self._boot_seen is not None:
            self._boot_seen.set()
        if self._state is LinkState.CONNECTING:
            return
        if self._state in (LinkState.READY, LinkState.STREAMING, LinkState.PAUSED, LinkState.HALTED):
            acked = self._sender.last_acknowledged_line if self._sender else -1
            reason = PrinterReset(f"printer reset (boot banner) after line {acked} was acknowledged; "
                                  f"its queue, planner and line numbers are lost")
            if self._sender is not None:
                self._sender.stop(reason)
            self._set_state(LinkState.CONNECTING)
            self._rehandshake = asyncio.get_running_loop().create_task(self._after_reset())

    async def _after_reset(self) -> None:
        try:
            await self._await_boot()
            await self._handshake()
            self._set_state(LinkState.READY)
        except (LinkError, OSError) as exc:
            log.error("handshake after reset failed: %s", exc)
            await self.close()

    def _on_halt(self, message: str) -> None:
        if self._sender is not None:
            self._sender.stop(PrinterHalted(f"printer halted: {message}"))
        if self._state not in (LinkState.HALTED, LinkState.DISCONNECTED):
            self._set_state(LinkState.HALTED)

    def _on_lost(self, reason: Exception) -> None:
        acked = self._sender.last_acknowledged_line if self._sender else -1
        # One line: an unplugged printer is an event of the workshop, not a bug to trace.
        log.error("printer disconnected: %s: %s; reconnect it (ribbond connects again on its own; "
                  "a job it interrupted can be resumed)", self.port, reason)
        error = Disconnected(f"printer disconnected: {self.port}: {reason} (last acknowledged line: {acked})")
        if self._sender is not None:
            self._sender.stop(error)
        self._transport = None
        if self._state is not LinkState.DISCONNECTED:
            self._set_state(LinkState.DISCONNECTED)

