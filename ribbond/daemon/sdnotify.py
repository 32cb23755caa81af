"""sd_notify(3) without libsystemd: tell systemd the daemon is ready, what it is doing, and alive.

Under ``Type=notify`` systemd passes ``$NOTIFY_SOCKET``, an AF_UNIX datagram socket (a path, or an
abstract name written with a leading ``@``); each datagram is newline-separated ``KEY=value``
assignments. With ``WatchdogSec=`` it also passes ``$WATCHDOG_USEC`` (and ``$WATCHDOG_PID``) and
restarts the service when no ``WATCHDOG=1`` arrives in time.

Nothing here raises on a send error: a lost notification is logged (debug) and the daemon goes on.
Outside systemd (no ``$NOTIFY_SOCKET``) every call is a no-op.

Send the watchdog pings from the event loop itself (an asyncio task every
``watchdog_interval()`` seconds), not from a thread, so that a stalled loop stops them.
"""

from __future__ import annotations

import logging
import os
import socket
from collections.abc import Mapping

log = logging.getLogger(__name__)

#: Longest a send may block (a full receive queue at PID 1); past it the message is dropped.
SEND_TIMEOUT_S = 0.5


def _address(path: str) -> str | None:
    """The socket address for ``$NOTIFY_SOCKET``, or None when it is not one we can use."""
    if path.startswith("@") and len(path) > 1:
        return "\0" + path[1:]  # Linux abstract namespace
    if path.startswith("/"):
        return path
    return None  # e.g. systemd's "vsock:" addresses (VMs); not needed on a printer host


def notify(state: str, *, environ: Mapping[str, str] = os.environ) -> bool:
    """Send ``state`` (e.g. ``"READY=1"``) to ``$NOTIFY_SOCKET``.

    Returns True when the datagram was sent, False when not under systemd (no socket in
    ``environ``) or when sending failed (logged at debug level; never raised).
    """
    path = environ.get("NOTIFY_SOCKET", "")
    if not path:
        return False
    address = _address(path)
    if address is None:
        log.debug("sd_notify: unsupported NOTIFY_SOCKET %r, %r not sent", path, state)
        return False
    try:
        with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM | socket.SOCK_CLOEXEC) as sock:
            sock.settimeout(SEND_TIMEOUT_S)
            sock.sendto(state.encode("utf-8", "replace"), address)
    except (OSError, ValueError) as exc:  # ValueError: embedded NUL or similar in the address
        log.debug("sd_notify: could not send %r to %s: %s", state, path, exc)
        return False
    return True


def _one_line(text: str) -> str:
    """A value cannot hold a newline: it would start a new assignment (``\\nMAINPID=1``)."""
    return " ".join(text.splitlines())


class Notifier:
    """READY/STATUS/STOPPING/WATCHDOG for the daemon; every method is a no-op outside systemd.

    The relevant variables are read once, at construction, so that the daemon may remove them
    from ``os.environ`` afterwards (children must not notify on its behalf).
    """

    _KEYS = ("NOTIFY_SOCKET", "WATCHDOG_USEC", "WATCHDOG_PID")

    def __init__(self, environ: Mapping[str, str] = os.environ) -> None:
        self._environ = {key: environ[key] for key in self._KEYS if key in environ}
        self.enabled: bool = bool(self._environ.get("NOTIFY_SOCKET"))

    def _send(self, state: str) -> None:
        if self.enabled:
            notify(state, environ=self._environ)

    def ready(self, status: str = "") -> None:
        """The service is up (the HTTP API listens); systemd finishes starting it."""
        self._send(f"READY=1\nSTATUS={_one_line(status)}" if status else "READY=1")

    def status(self, text: str) -> None:
        """A one-line status shown by ``systemctl status ribbond``."""
        self._send(f"STATUS={_one_line(text)}")

    def stopping(self) -> None:
        """The daemon has begun shutting down."""
        self._send("STOPPING=1")

    def watchdog(self) -> None:
        """Keep-alive ping; due at least every ``WatchdogSec=``."""
        self._send("WATCHDOG=1")

    def watchdog_interval(self) -> float | None:
        """Seconds between watchdog pings (half of ``$WATCHDOG_USEC``), or None when no watchdog
        is set for this process (unset or invalid ``$WATCHDOG_USEC``, or ``$WATCHDOG_PID`` names
        another process)."""
        try:
            usec = int(self._environ.get("WATCHDOG_USEC", ""))
        except ValueError:
            return None
        if usec <= 0:
            return None
        pid = self._environ.get("WATCHDOG_PID")
        if pid is not None:
            try:
                if int(pid) != os.getpid():
                    return None
            except ValueError:
                return None
        return usec / 2 / 1_000_000
