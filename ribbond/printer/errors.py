"""Why a printer conversation ended. Each error says what happened and where (line numbers)."""

from __future__ import annotations


class LinkError(Exception):
    """Base class: the printer link could not do what was asked."""


class Disconnected(LinkError):
    """The serial port went away (unplugged, powered off, closed)."""


class PrinterHalted(LinkError):
    """The firmware halted (``M112``, thermal protection, kill()) and needs a reset."""


class PrinterReset(LinkError):
    """The firmware rebooted during a job: its queue, planner and line number are gone."""


class PrinterSilent(LinkError):
    """The printer stopped answering, even to probes."""


class ProtocolError(LinkError):
    """The printer asked for something the host cannot give (a line it never had, or one it had
    already acknowledged)."""


class StreamCancelled(LinkError):
    """The stream was cancelled before every line was sent."""


class NotReady(LinkError):
    """The link is not in a state that allows the request (not connected, halted, busy);
    ``state`` names the link's state when it is known (``halted``, ``disconnected``, ...)."""

    def __init__(self, message: str, state: str | None = None) -> None:
        super().__init__(message)
        self.state = state
