"""The test/control interface: a Unix socket taking JSON-line requests.

One JSON object per line in, one JSON object per line out.  Requests:
  {"cmd": "flip", "dx": 0.5, "dy": -0.2, "rotation_deg": 1.0}
  {"cmd": "reset"} {"cmd": "disconnect"} {"cmd": "runaway"}
  {"cmd": "stats"} {"cmd": "reset_stats"} {"cmd": "segments"} {"cmd": "commands"} {"cmd": "queued"}
  {"cmd": "port"} {"cmd": "corrupt_rate", "rate": 0.05}
  {"cmd": "render", "path": "/tmp/out.png"}
Answers are {"ok": true, ...} or {"ok": false, "error": "..."}.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import json
import os
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .printer import SimulatedPrinter

__all__ = ["serve_control", "remove_socket"]


def remove_socket(path: str | None) -> None:
    if path:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(path)


async def _answer(printer: SimulatedPrinter, req: dict[str, Any]) -> dict[str, Any]:
    cmd = req.get("cmd")
    if cmd == "flip":
        pose = printer.flip((float(req.get("dx", 0.0)), float(req.get("dy", 0.0))),
                            float(req.get("rotation_deg", 0.0)))
        return {"ok": True, "pose": dataclasses.asdict(pose)}
    if cmd == "reset":
        printer.trigger_reset()
        return {"ok": True}
    if cmd == "disconnect":
        printer.trigger_disconnect()
        return {"ok": True}
    if cmd == "runaway":
        printer.trigger_runaway()
        return {"ok": True}
    if cmd == "stats":
        return {"ok": True, "stats": dataclasses.asdict(printer.stats())}
    if cmd == "reset_stats":
        printer.reset_stats()
        return {"ok": True}
    if cmd == "queued":
        return {"ok": True, "queued": printer.queued()}
    if cmd == "segments":
        return {"ok": True, "segments": [dataclasses.asdict(s) for s in printer.segments()]}
    if cmd == "commands":
        return {"ok": True, "commands": [dataclasses.asdict(c) for c in printer.commands()]}
    if cmd == "corrupt_rate":
        try:
            printer.set_corrupt_rate(float(req.get("rate", 0.0)))
        except (TypeError, ValueError) as exc:
            return {"ok": False, "error": str(exc)}
        return {"ok": True}
    if cmd == "port":
        return {"ok": True, "port": printer.port}
    if cmd == "render":
        path = req.get("path")
        if not isinstance(path, str) or not path:
            return {"ok": False, "error": "render needs a \"path\""}
        # Rendering takes a while: keep the printer's loop (and its pacing) running.
        await asyncio.get_running_loop().run_in_executor(None, printer.render_png, path)
        return {"ok": True, "path": path}
    return {"ok": False, "error": f"unknown cmd {cmd!r}"}


async def serve_control(path: str, printer: SimulatedPrinter) -> asyncio.AbstractServer:
    """Listen on Unix socket ``path`` (replacing a stale one) on the running loop."""

    async def client(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        try:
            while line := await reader.readline():
                if not line.strip():
                    continue
                try:
                    req = json.loads(line)
                    if not isinstance(req, dict):
                        raise ValueError("request must be a JSON object")
                    answer = await _answer(printer, req)
                except Exception as exc:  # a bad request must not kill the server
                    answer = {"ok": False, "error": f"{type(exc).__name__}: {exc}"}
                writer.write(json.dumps(answer).encode() + b"\n")
                await writer.drain()
        except (ConnectionError, asyncio.IncompleteReadError):
            pass
        finally:
            writer.close()

    remove_socket(path)
    return await asyncio.start_unix_server(client, path, limit=1 << 20)
