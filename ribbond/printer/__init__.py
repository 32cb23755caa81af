"""The printer link: a Marlin codec, an asyncio serial transport, a sender with flow control and
resends, and :class:`PrinterLink`, the one API the rest of ribbond uses."""

from .capabilities import Capabilities
from .errors import (
    Disconnected,
    LinkError,
    NotReady,
    PrinterHalted,
    PrinterReset,
    PrinterSilent,
    ProtocolError,
    StreamCancelled,
)
from .link import LinkState, PrinterLink, PrinterStatus, prepare_program
from .sender import Answer, StreamProgress, StreamResult, Timeouts

__all__ = [
    "Answer",
    "Capabilities",
    "Disconnected",
    "LinkError",
    "LinkState",
    "NotReady",
    "PrinterHalted",
    "PrinterLink",
    "PrinterReset",
    "PrinterSilent",
    "PrinterStatus",
    "ProtocolError",
    "StreamCancelled",
    "StreamProgress",
    "StreamResult",
    "Timeouts",
    "prepare_program",
]
