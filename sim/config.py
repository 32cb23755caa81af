"""Configuration of the simulated printer: firmware settings, faults and fabric frame.

Every field maps to one command-line option of ``python -m sim``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from .dialects import STOCK, Dialect, dialect_named

__all__ = ["FaultConfig", "FrameConfig", "SimConfig"]


def _check_rate(name: str, value: float) -> None:
    if not 0.0 <= value <= 1.0:
        raise ValueError(f"{name} must be a probability in [0, 1], got {value!r}")


def _check_trigger(name: str, value: int | None) -> None:
    if value is not None and value < 1:
        raise ValueError(f"{name} must be >= 1 or None, got {value!r}")


@dataclass(frozen=True)
class FaultConfig:
    """Faults injected on the serial link and in the firmware.

    Rates are probabilities drawn from per-fault random streams seeded by
    ``SimConfig.seed``, so a run is reproducible and enabling one fault does not
    change when another one fires.  ``*_after_lines`` triggers fire once, after that
    many numbered lines have been accepted since the simulator started.
    """

    corrupt_rate: float = 0.0
    """Per incoming line: replace one byte with another printable byte."""
    drop_ok_rate: float = 0.0
    """Per ``ok`` line of any kind: never send it."""
    spurious_resend_rate: float = 0.0
    """Per accepted numbered line: request an unasked ``Resend:``."""
    unsolicited_rate: float = 0.0
    """Per output line: first interleave an unsolicited line."""
    slow_rate: float = 0.0
    """Per output line: hold it back ``slow_delay_s`` before release."""
    slow_delay_s: float = 0.5
    reset_after_lines: int | None = None
    disconnect_after_lines: int | None = None
    runaway_after_lines: int | None = None
    mintemp_after_lines: int | None = None
    """A heater's thermistor reads below MINTEMP (unplugged, broken): Marlin's MINTEMP error, then
    halted as by kill()."""
    swallow_resent_after_lines: int | None = None
    """A buggy firmware, once after that many accepted numbered lines: the next numbered line N is
    refused as if corrupted (``Resend: N``); the re-sent N is then marked received but neither run
    nor answered, and the line after it is lost without a word (flushed with it), so the printer
    later asks for N + 1 with N never run nor acknowledged."""
    ignore_resent_after_lines: int | None = None
    """A firmware that times out after a resend request (OctoPrint's virtual printer simulates one),
    once after that many accepted numbered lines: the next numbered line N is refused as if
    corrupted (``Resend: N`` + ``ok``); the re-sent N is then marked received (its number is the last
    line) but neither run nor answered, and the lines after it run and are answered as usual."""
    skip_refused: bool = False
    """A buggy firmware: a line refused for its checksum is marked received without running, so
    the resend request asks for the line after it (that line is then missing)."""
    reconnect_after_s: float | None = None
    """After a disconnect, plug a new pty back in after this many seconds
    (``SimulatedPrinter.port`` then names the new device). None: stay unplugged."""

    def __post_init__(self) -> None:
        for name in ("corrupt_rate", "drop_ok_rate", "spurious_resend_rate",
                     "unsolicited_rate", "slow_rate"):
            _check_rate(name, getattr(self, name))
        for name in ("reset_after_lines", "disconnect_after_lines", "runaway_after_lines",
                     "mintemp_after_lines", "swallow_resent_after_lines", "ignore_resent_after_lines"):
            _check_trigger(name, getattr(self, name))
        if self.slow_delay_s < 0:
            raise ValueError("slow_delay_s must be >= 0")
        if self.reconnect_after_s is not None and self.reconnect_after_s < 0:
            raise ValueError("reconnect_after_s must be >= 0 or None")


@dataclass(frozen=True)
class FrameConfig:
    """Where the fabric frame's flip axis is, in machine coordinates (mm).

    ``flip_axis="y"`` turns the frame over about the line x = cx (x is mirrored);
    ``flip_axis="x"`` turns it over about y = cy (y is mirrored).
    """

    center: tuple[float, float] = (110.0, 110.0)
    flip_axis: str = "y"

    def __post_init__(self) -> None:
        if self.flip_axis not in ("x", "y"):
            raise ValueError(f"flip_axis must be 'x' or 'y', got {self.flip_axis!r}")
        if len(self.center) != 2:
            raise ValueError("center must be (x, y)")
        object.__setattr__(self, "center", (float(self.center[0]), float(self.center[1])))


@dataclass(frozen=True)
class SimConfig:
    """Settings of the simulated board.

    ``dialect`` chooses the firmware it answers as (``sim.dialects``); the options marked "None:
    the dialect's" take that dialect's value unless given.
    """

    baud: int = 250000
    """Serial speed; 8N1 framing, so a byte takes 10/baud seconds each way."""
    time_scale: float = 1.0
    """Wall seconds per physical second (0.001 runs a 2 h print in 7.2 s)."""
    dialect: str | None = None
    """marlin1, marlin2, prusa, reprapfirmware, smoothieware, repetier; None: the historical board
    (Marlin 2.1's answers with ADVANCED_OK on and Marlin 1.x's cut-tail check)."""
    advanced_ok: bool | None = None
    """Acks read ``ok N<line> P<planner free> B<queue free>`` (Marlin ADVANCED_OK). None: the dialect's."""
    ok_after_resend: bool | None = None
    """Print ``ok`` after every resend request (as Marlin does). None: the dialect's."""
    m114_on_ok: bool | None = None
    """Answer ``M114`` on the ``ok`` line, as Smoothieware does (``ok C: X:10.0000 Y:20.0000
    Z:0.0000 E:0.0000``, without ADVANCED_OK's fields), instead of Marlin's position line + ``ok``.
    None: the dialect's."""
    ok_before_output: bool = False
    """Print a command's ``ok`` before its output (``M114``'s position, ``M115``'s report), as some
    firmware builds do (OctoPrint's virtual printer: ``okBeforeCommandOutput``)."""
    rx_buffer: int = 128
    """Serial receive ring buffer in bytes (RX_BUFFER_SIZE); bytes beyond it are lost."""
    bufsize: int | None = None
    """Command queue slots (BUFSIZE). None: the dialect's (4; Repetier's 1)."""
    planner_blocks: int = 16
    """Planner ring size (BLOCK_BUFFER_SIZE); it holds planner_blocks - 1 moves."""
    keepalive_s: float | None = None
    """Busy-line interval while a command blocks (0 disables). None: the dialect's."""
    cut_tail: str | None = None
    """What becomes of the tail of a line cut by a receive-buffer flush (it has ``*`` but no
    ``N``): "reject" (Marlin 1.x: ``Error:No Line Number with checksum``, flush, ``Resend:``) or
    "marlin2" (Marlin 2.x: no such check; queued as an unnumbered command, so an unparsable tail
    is answered ``echo:Unknown command`` + ``ok``). None: the dialect's."""
    read_latency_s: float = 0.0
    """Wall time Marlin's main loop may take to come back to the receive buffer: bytes arriving
    that long after a bad line are already in the buffer when the error flushes it, so the line
    being received is cut in two (0: the line after a bad one is never cut)."""
    blocking_intake: bool = False
    """Marlin's main loop reads no serial while a command blocks (waiting for a planner block, a
    dwell, a heating wait): lines pile up in the receive buffer, and a host sending more than it
    holds loses bytes (False: lines move to free queue slots whenever they arrive)."""
    seed: int = 0
    boot_s: float = 0.05
    """Wall time a (re)boot takes: bytes arriving meanwhile are lost, then the banner."""
    faults: FaultConfig = field(default_factory=FaultConfig)
    frame: FrameConfig = field(default_factory=FrameConfig)

    def __post_init__(self) -> None:
        spec = dialect_named(self.dialect) or STOCK  # ValueError names the dialects
        for name in ("advanced_ok", "ok_after_resend", "m114_on_ok", "cut_tail", "keepalive_s", "bufsize"):
            if getattr(self, name) is None:
                object.__setattr__(self, name, getattr(spec, name))
        if self.baud <= 0:
            raise ValueError("baud must be > 0")
        if self.time_scale <= 0:
            raise ValueError("time_scale must be > 0")
        if self.rx_buffer < 2:
            raise ValueError("rx_buffer must be >= 2")
        if self.bufsize < 1:
            raise ValueError("bufsize must be >= 1")
        if self.planner_blocks < 2:
            raise ValueError("planner_blocks must be >= 2 (the ring keeps one slot free)")
        if self.cut_tail not in ("reject", "marlin2"):
            raise ValueError(f"cut_tail must be 'reject' or 'marlin2', got {self.cut_tail!r}")
        if self.read_latency_s < 0:
            raise ValueError("read_latency_s must be >= 0")
        if self.keepalive_s < 0:
            raise ValueError("keepalive_s must be >= 0")
        if self.boot_s < 0:
            raise ValueError("boot_s must be >= 0")

    @property
    def spec(self) -> Dialect:
        """The answers of the firmware this board plays (``STOCK`` without a dialect)."""
        return dialect_named(self.dialect) or STOCK

    @property
    def byte_time(self) -> float:
        """Seconds one byte occupies the wire (start + 8 data + stop bits)."""
        return 10.0 / self.baud
