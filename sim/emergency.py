"""Marlin's EMERGENCY_PARSER: watches every byte as it arrives on the wire.

It runs in the serial interrupt on a real board, before the receive buffer, so it
acts even when the buffer is full and the byte itself is then lost.  It recognises
a line that is (optionally ``N<digits>`` then) ``M108``, ``M112`` or ``M410``; as in
Marlin's state machine anything after the code (such as ``*checksum``) is ignored.
"""

from __future__ import annotations

import re

__all__ = ["EmergencyParser"]

# Marlin's states: spaces, then N with digits/'-'/spaces, then M, spaces, the code.
_EMERGENCY = re.compile(rb" *(?:N[-0-9 ]*)?M *(108|112|410)")
_MAX_CARRY = 64  # longer lines cannot hold an emergency command near their start


class EmergencyParser:
    def __init__(self) -> None:
        self._carry = b""

    def reset(self) -> None:
        self._carry = b""

    def feed(self, data: bytes) -> list[str]:
        """Bytes in arrival order; return the emergency commands whose line just ended."""
        if b"\n" not in data and b"\r" not in data:
            if len(self._carry) < _MAX_CARRY:
                self._carry = (self._carry + data)[:_MAX_CARRY]
            return []
        text = self._carry + data
        parts = text.replace(b"\r", b"\n").split(b"\n")
        self._carry = parts.pop()[:_MAX_CARRY]
        found: list[str] = []
        for line in parts:
            if b"M" in line:
                m = _EMERGENCY.match(line)
                if m:
                    found.append("M" + m.group(1).decode())
        return found
