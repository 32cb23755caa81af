"""``ribbonctl notify [status|test]`` (issue 27): the daemon's notifications, what was last sent and
what failed (``GET /notifications``), and a test message to every configured service, followed
until each has answered (``POST /notifications/test``). Standard library only, as every daemon
command (``ribbond.client.http``)."""

from __future__ import annotations

import argparse
import time
from typing import Any

from .http import Client, ClientError, _client
from .output import _out

#: Seconds beyond the daemon's own timeout that ``notify test`` waits for the deliveries.
WAIT_MARGIN_S = 3.0


def _clock(t: float) -> str:
    return time.strftime("%H:%M:%S", time.localtime(t))


def delivery_line(d: dict[str, Any]) -> str:
    """``14:02:11  sent     awaiting_flip  json://host/hook  0.01 s  Flip the frame: saddle.obj``."""
    took = f"{d['duration_s']:.2f} s" if d.get("duration_s") is not None else "–"
    why = f"  ({d['error']})" if d.get("error") else ""
    return f"{_clock(d['at'])}  {d['status']:<8} {d['event']:<14} {d['url']}  {took}  {d['title']}{why}"


def status_text(v: dict[str, Any]) -> str:
    """The notifications for people: on or off, the services, the events, the last deliveries."""
    if not v["enabled"]:
        return ("notifications are off: set [notify] urls in the daemon's configuration "
                "(e.g. urls = [\"ntfy://my-topic\"]) and restart it")
    lines = [f"notifications on: {', '.join(v['urls'])}", f"events: {', '.join(v['events']) or 'none'}",
             f"sent {v['sent']}, failed {v['failed']} since the daemon started"]
    lines += [delivery_line(d) for d in v["deliveries"][:10]]
    return "\n".join(lines)


def _wait_test(c: Client, sent: dict[str, Any]) -> list[dict[str, Any]]:
    """The test's deliveries, one per service, once each has answered (or the wait ran out)."""
    view = c.request("GET", "/notifications")
    deadline = time.monotonic() + float(view["timeout_s"]) + WAIT_MARGIN_S
    while True:
        mine = [d for d in view["deliveries"] if d["id"] == sent["id"]]
        if len(mine) >= len(sent["urls"]) or time.monotonic() > deadline:
            return mine
        time.sleep(0.1)
        view = c.request("GET", "/notifications")


def cmd_notify(args: argparse.Namespace) -> int:
    c = _client(args)
    if args.action == "status":
        view = c.request("GET", "/notifications")
        _out(args, view, status_text(view))
        return 0
    sent = c.request("POST", "/notifications/test")
    mine = _wait_test(c, sent)
    answered = {d["url"] for d in mine}
    lines = [delivery_line(d) for d in mine] + [f"{url}: no answer yet (see ribbonctl notify status)"
                                                for url in sent["urls"] if url not in answered]
    _out(args, {"id": sent["id"], "deliveries": mine}, "\n".join(lines))
    if len(mine) < len(sent["urls"]) or any(d["status"] != "sent" for d in mine):
        raise ClientError("the test message did not reach every service", 1)
    return 0


def add_notify_commands(sub: Any, common: argparse.ArgumentParser) -> None:
    """``ribbonctl notify [status|test]``."""
    p = sub.add_parser("notify", parents=[common], help="notifications: status (last sent and failed), test",
                       description="The daemon's notifications ([notify] urls): status shows what was last "
                                   "sent and what failed and why; test sends a test message to every service "
                                   "and waits for each answer (exit status 1 if one was not sent).")
    p.add_argument("action", choices=("status", "test"), nargs="?", default="status")
    p.set_defaults(func=cmd_notify)
