"""Notifications (issue 27): a message to the operator's phone, chat, mail or webhook when a job
needs them or has ended, sent through Apprise and never on the print path.

The notifier follows the event bus like any other subscriber. ``Watcher`` (pure: events in, notices
out) sees a job enter ``awaiting_flip``, the head wait above the first mark of an alignment pass (or
a fit wait for review), a queued job wait for a fresh frame, a job end ``done``, ``failed`` or
``interrupted``, and the printer halt; ``notice`` words each one: what happened and what to do next,
with the job's file name, id and panel. ``[notify] events`` chooses which of them are sent.

Each configured URL has its own ``Sender``: a bounded queue (when full, the notice is dropped, logged
and kept as dropped) and one send at a time in a thread of its own (Apprise's calls block), waited
for at most ``timeout_s``. A send still running then is a ``timeout`` (the service may still get it
late) and the next notice goes on; the service's own connect and read timeouts, a second longer,
end the thread soon after, and while ``MAX_HUNG`` sends to a service still hang (a service that
trickles its answer), its next notices are dropped instead of piling up threads. The print task never waits for any
of it. The last ``DELIVERIES`` deliveries (sent, failed, timeout, dropped) are kept for ``GET
/notifications`` and each is published as a ``notification`` event (the dashboard's line).
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import logging
import re
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

from ..config import NotifySettings
from ..events import EventBus
from ..records import ServiceError
from .frame import WAIT_STAGE

log = logging.getLogger(__name__)

#: Notices waiting for one service at most; more are dropped (and kept as dropped).
QUEUE_MAX = 20
#: Sends to one service that may still hang past their timeout before its next notices are dropped.
MAX_HUNG = 4
#: The service's own connect and read timeouts are ours and this much more: ours decides (a send
#: given up on is a ``timeout``, whatever the service's library would have said), theirs ends the thread.
SOCKET_GRACE_S = 1.0
#: Deliveries kept for the API, newest first.
DELIVERIES = 50
#: Longest reason kept for a failed delivery, characters.
REASON_MAX = 300
#: At the daemon's stop, how long the notices already made (an interrupted job) may take to go out.
CLOSE_GRACE_S = 3.0

#: Per event: the title's first words and Apprise's notification type.
HEADLINES = {"awaiting_flip": ("Flip the frame", "info"), "alignment": ("Align the back", "info"),
             "fresh_frame": ("Load a fresh frame", "info"), "done": ("Done", "success"),
             "failed": ("Failed", "failure"), "interrupted": ("Interrupted", "warning"),
             "halted": ("Printer halted", "failure"), "test": ("Test", "info")}
#: The dashboard's button for the next step, where there is one (ribbond/web/index.html, app.js).
BUTTONS = {"awaiting_flip": "“Frame is flipped”", "fresh_frame": "“Fresh frame loaded”",
           "alignment": "“Nozzle is on the mark”", "fitted": "“Accept, print the back” or “Re-seat the frame”"}
#: Job states whose entry is notified under their own name.
ENTERED = ("awaiting_flip", "done", "failed", "interrupted")


@dataclass(frozen=True)
class Notice:
    """One message to every configured service."""

    event: str                                  # a name of NOTIFY_EVENTS, or "test"
    title: str
    body: str
    kind: str = "info"                          # Apprise's type: info, success, warning, failure
    job_id: str | None = None
    id: int = 0                                 # given by the notifier when it is sent


# ------------------------------------------------------------------------------ the words


def job_label(job: dict[str, Any]) -> str:
    """``saddle.obj (job 3f2a9c1b2d4e, panel 2 of 3)``."""
    panel = f", panel {job['panel']} of {job['panels']}" if job.get("panel") and job.get("panels") else ""
    return f"{job.get('mesh_name', '?')} (job {job['id']}{panel})"


def _sentence(text: str) -> str:
    """``text`` as a sentence's start, without its full stop (the caller ends it)."""
    text = text.strip().rstrip(".")
    return (text[:1].upper() + text[1:]) if text else text


def _title(event: str, job: dict[str, Any] | None, detail: str = "") -> str:
    head = HEADLINES[event][0] + detail
    if job is None:
        return head
    panel = f" (panel {job['panel']}/{job['panels']})" if job.get("panel") and job.get("panels") else ""
    return f"{head}: {job.get('mesh_name', '?')}{panel}"


def _button(key: str) -> str:
    return f" On the dashboard: {BUTTONS[key]}." if key in BUTTONS else ""


def notice(event: str, job: dict[str, Any] | None, info: dict[str, Any] | None = None) -> Notice:
    """The message for ``event`` about ``job`` (its status as the API shows it, with ``next``), or
    about the printer (``halted``: ``info`` is its status). ``alignment``: ``info`` is the mark's
    prompt (``mark``, ``marks``, ``message``), or None when a fit waits for review (``fitted``)."""
    kind = HEADLINES[event][1]
    if event == "halted":
        why = (info or {}).get("last_error")
        body = (f"The printer halted{f' ({why})' if why else ''}: nothing moves or heats until it is "
                "recovered. Check the machine, then press “Recover” on the dashboard or run: ribbonctl recover; "
                "then the job's next step: ribbonctl status.")
        return Notice(event, _title(event, None), body, kind)
    assert job is not None
    label, instruction = job_label(job), _sentence(job.get("next", {}).get("instruction", ""))
    if event == "alignment" and info is not None:
        detail = f" (mark {info.get('mark')} of {info.get('marks')})"
        body = f"{label}: {_sentence(info.get('message') or instruction)}.{_button('alignment')}"
        return Notice(event, _title(event, job, detail), body, kind, job["id"])
    if event == "alignment":
        return Notice(event, _title(event, job, " (check the fit)"), f"{label}: {instruction}.{_button('fitted')}",
                      kind, job["id"])
    if event == "done" and job.get("panel") and instruction.startswith("All "):
        # the project's last panel: the sewing, not "print it again" (issue 36)
        detail = f" (all {job.get('panels')} panels)"
        return Notice(event, _title(event, job, detail), f"{label} is printed. {instruction}.", kind, job["id"])
    if event == "done":
        body = (f"{label} is printed. Take the frame off the printer (the next job asks for a fresh one). "
                f"To print it again: ribbonctl start {job['id']}.")
        return Notice(event, _title(event, job), body, kind, job["id"])
    return Notice(event, _title(event, job), f"{label}: {instruction}.{_button(event)}", kind, job["id"])


def at_gate(job: dict[str, Any]) -> bool:
    """The job is queued and waits for the operator to confirm a fresh frame (``frame.waits_at_gate``)."""
    return job.get("state") == "ready" and bool(job.get("start_when_ready")) and job.get("stage") == WAIT_STAGE


# ------------------------------------------------------------------------------ what the events mean


@dataclass
class _Seen:
    state: str | None = None
    gate: bool = False
    error: str | None = None
    job: dict[str, Any] = field(default_factory=dict)


class Watcher:
    """What the bus's events mean to the operator: ``see(event)`` gives the notices they call for
    (only the ``events`` wanted). It keeps, per job, what it last saw (a change is news, a repeat is
    not) and whether an alignment pass waits for its first prompt."""

    def __init__(self, events: Iterable[str]) -> None:
        self.wanted = set(events)
        self._jobs: dict[str, _Seen] = {}
        self._armed: set[str] = set()               # jobs whose next mark prompt is notified
        self._printer: str | None = None

    def know(self, jobs: Iterable[dict[str, Any]]) -> None:
        """The jobs as they stand at the start: what they are already is not news."""
        for job in jobs:
            self._jobs[job["id"]] = _Seen(job["state"], at_gate(job), job.get("error"), job)

    def see(self, event: dict[str, Any]) -> list[Notice]:
        kind = event.get("type")
        if kind == "job" and isinstance(event.get("job"), dict):
            found = self._job(event["job"])
        elif kind == "alignment":
            found = self._prompt(event)
        elif kind == "printer" and isinstance(event.get("printer"), dict):
            found = self._printer_state(event["printer"])
        else:
            if kind == "deleted":
                self._jobs.pop(str(event.get("job_id")), None)
            found = []
        return [n for n in found if n.event in self.wanted]

    def _job(self, job: dict[str, Any]) -> list[Notice]:
        before = self._jobs.get(job["id"], _Seen())
        now = _Seen(job["state"], at_gate(job), job.get("error"), job)
        self._jobs[job["id"]] = now
        out = []
        if now.state != before.state:
            if now.state in ENTERED:
                out.append(notice(now.state, job))
            elif now.state == "fitted":
                out.append(notice("alignment", job))
            if now.state == "aligning":
                self._armed.add(job["id"])           # the head is on its way to the first mark
        elif now.state == "aligning" and now.error != before.error and (now.error or "").startswith("alignment refused"):
            self._armed.add(job["id"])               # marks measured again: the next prompt is news
        if now.state != "aligning":
            self._armed.discard(job["id"])
        if now.gate and not before.gate:
            out.append(notice("fresh_frame", job))
        return out

    def _prompt(self, event: dict[str, Any]) -> list[Notice]:
        job_id = str(event.get("job_id"))
        if job_id not in self._armed or job_id not in self._jobs:
            return []
        self._armed.discard(job_id)
        return [notice("alignment", self._jobs[job_id].job, event)]

    def _printer_state(self, status: dict[str, Any]) -> list[Notice]:
        state, before = status.get("state"), self._printer
        self._printer = state
        return [notice("halted", None, status)] if state == "halted" and before != "halted" else []


# ------------------------------------------------------------------------------ sending


class _ThreadLog(logging.Handler):
    """What Apprise logs (warnings and errors) in one thread: the reason a send failed."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.thread = threading.get_ident()
        self.lines: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        if record.thread == self.thread:
            self.lines.append(record.getMessage())


def deliver(plugin: Any, notice: Notice) -> tuple[bool, str | None]:
    """In a worker thread: ``notice`` to one Apprise service; (accepted, why not)."""
    said = _ThreadLog()
    apprise_log = logging.getLogger("apprise")
    apprise_log.addHandler(said)
    try:
        ok = bool(plugin.notify(body=notice.body, title=notice.title, notify_type=notice.kind))
    finally:
        apprise_log.removeHandler(said)
    why = "; ".join(said.lines[-2:]) or "the service did not accept it"
    return ok, None if ok else why[:REASON_MAX]


def in_thread(fn: Callable[[], tuple[bool, str | None]]) -> asyncio.Future[tuple[bool, str | None]]:
    """``fn()`` in a daemon thread of its own (never the loop's executor: a hanging send must not
    take a worker the print path's ``to_thread`` calls need); its result as a future of the loop."""
    loop = asyncio.get_running_loop()
    future: asyncio.Future[tuple[bool, str | None]] = loop.create_future()

    def settle(result: tuple[bool, str | None]) -> None:
        if not future.done():
            future.set_result(result)

    def run() -> None:
        try:
            result = fn()
        except Exception as exc:  # noqa: BLE001 - a plugin's bug is a failed delivery, said as such
            result = (False, f"{type(exc).__name__}: {exc}"[:REASON_MAX])
        with contextlib.suppress(RuntimeError):         # the loop closed meanwhile: nobody waits
            loop.call_soon_threadsafe(settle, result)

    threading.Thread(target=run, name="ribbond-notify", daemon=True).start()
    return future


def shown_url(plugin: Any, url: str) -> str:
    """The URL as Apprise shows it with its secrets masked, without its query of options."""
    try:
        return str(plugin.url(privacy=True)).split("?", 1)[0]
    except Exception:  # noqa: BLE001 - a plugin that cannot print itself is still named by its scheme
        return url.split("://", 1)[0] + "://…"


class Sender:
    """One service: its queue of notices and one send at a time. ``record`` keeps each delivery."""

    def __init__(self, url: str, timeout_s: float, record: Callable[[dict[str, Any]], None]) -> None:
        import apprise                                 # only when notifications are configured

        plugin = apprise.Apprise.instantiate(url)
        if plugin is None:                             # the configuration checked it: not expected
            raise ValueError(f"[notify] urls: Apprise cannot use {url.split('://', 1)[0]}://…")
        for option, attribute in (("cto", "socket_connect_timeout"), ("rto", "socket_read_timeout")):
            if not re.search(rf"[?&]{option}=", url) and hasattr(plugin, attribute):
                setattr(plugin, attribute, timeout_s + SOCKET_GRACE_S)   # unless the URL says
        self.plugin, self.url, self.timeout_s, self.record = plugin, shown_url(plugin, url), timeout_s, record
        self.queue: asyncio.Queue[Notice] = asyncio.Queue(QUEUE_MAX)
        self.hung = 0
        self.busy = False

    def offer(self, item: Notice) -> None:
        try:
            self.queue.put_nowait(item)
        except asyncio.QueueFull:
            self._record(item, "dropped", f"{QUEUE_MAX} notices already wait for this service", None)

    async def run(self) -> None:
        while True:
            item = await self.queue.get()
            if self.hung >= MAX_HUNG:
                self._record(item, "dropped", f"{self.hung} earlier send(s) to this service still hang", None)
                continue
            self.busy = True
            try:
                await self._send(item)
            finally:
                self.busy = False

    async def _send(self, item: Notice) -> None:
        started = time.monotonic()
        done = in_thread(lambda: deliver(self.plugin, item))
        try:
            ok, why = await asyncio.wait_for(asyncio.shield(done), self.timeout_s)
        except asyncio.TimeoutError:
            self.hung += 1
            done.add_done_callback(self._unhang)
            self._record(item, "timeout", f"no answer in {self.timeout_s:g} s ([notify] timeout_s)",
                         time.monotonic() - started)
            return
        self._record(item, "sent" if ok else "failed", why, time.monotonic() - started)

    def _unhang(self, _: asyncio.Future[Any]) -> None:
        self.hung -= 1

    def _record(self, item: Notice, status: str, error: str | None, took: float | None) -> None:
        self.record({"id": item.id, "at": time.time(), "event": item.event, "job_id": item.job_id,
                     "title": item.title, "url": self.url, "status": status, "error": error,
                     "duration_s": None if took is None else round(took, 3)})


class Notifier:
    """The notices of the bus's events, sent to every ``[notify] urls`` service; off without URLs."""

    def __init__(self, settings: NotifySettings, bus: EventBus) -> None:
        self.settings, self.bus = settings, bus
        self.watcher = Watcher(settings.events)
        self.senders = [Sender(url, settings.timeout_s, self._record) for url in settings.urls]
        self.deliveries: deque[dict[str, Any]] = deque(maxlen=DELIVERIES)
        self.last: dict[str, dict[str, Any] | None] = {"sent": None, "failed": None}
        self.counts = {"sent": 0, "failed": 0}
        self._ids = itertools.count(1)
        # subscribed now, before the service publishes the jobs a stop left interrupted
        self._events = bus.subscribe() if self.senders else None
        self._tasks: list[asyncio.Task[None]] = []

    def start(self, jobs: Iterable[dict[str, Any]]) -> None:
        """Follow the bus; ``jobs`` as they stand now (what they already are is not news)."""
        if self._events is None:
            return
        self.watcher.know(jobs)
        self._tasks = [asyncio.create_task(self._follow(), name="notify"),
                       *(asyncio.create_task(s.run(), name=f"notify {s.url}") for s in self.senders)]
        log.info("notifications on: %s to %s", ", ".join(self.settings.events) or "no events",
                 ", ".join(s.url for s in self.senders))

    async def _follow(self) -> None:
        assert self._events is not None
        while True:
            event = await self._events.get()
            try:
                found = self.watcher.see(event)
            except Exception:  # noqa: BLE001 - an event that cannot be worded is not worth a stop
                log.exception("notifications: cannot word the event %s", event.get("type"))
                continue
            for item in found:
                self.send(item)

    def send(self, item: Notice) -> Notice:
        """Queue ``item`` for every service (never waits); the notice with its id."""
        item = Notice(item.event, item.title, item.body, item.kind, item.job_id, next(self._ids))
        log.info("notify %s: %s", item.event, item.title)
        for sender in self.senders:
            sender.offer(item)
        return item

    def test(self) -> dict[str, Any]:
        """A test message to every service (``ribbonctl notify test``); its id and the URLs."""
        if not self.senders:
            raise ServiceError("notifications are off: no [notify] urls in the daemon's configuration")
        item = self.send(Notice("test", "ribbond: test notification",
                                "Notifications from ribbond reach you here. Nothing to do.", "info"))
        return {"id": item.id, "urls": [s.url for s in self.senders]}

    def view(self) -> dict[str, Any]:
        """What ``GET /notifications`` shows: the setup, the counts, the last sent and failed, the
        last deliveries (newest first)."""
        return {"enabled": bool(self.senders), "urls": [s.url for s in self.senders],
                "events": list(self.settings.events), "timeout_s": self.settings.timeout_s,
                "sent": self.counts["sent"], "failed": self.counts["failed"], "last_sent": self.last["sent"],
                "last_failed": self.last["failed"], "deliveries": list(self.deliveries)}

    def _record(self, delivery: dict[str, Any]) -> None:
        ok = delivery["status"] == "sent"
        self.deliveries.appendleft(delivery)
        self.last["sent" if ok else "failed"] = delivery
        self.counts["sent" if ok else "failed"] += 1
        if ok:
            log.info("notification %s sent to %s in %.2f s", delivery["event"], delivery["url"],
                     delivery["duration_s"])
        else:
            log.warning("notification %s to %s %s: %s", delivery["event"], delivery["url"], delivery["status"],
                        delivery["error"])
        self.bus.publish({"type": "notification", "notification": delivery})

    async def close(self) -> None:
        """Give the notices already made (a job the stop interrupted) a moment to go out, then stop."""
        deadline = time.monotonic() + min(CLOSE_GRACE_S, self.settings.timeout_s)
        while self._tasks and time.monotonic() < deadline and not self._idle():
            await asyncio.sleep(0.02)
        for task in self._tasks:
            task.cancel()
        for task in self._tasks:
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task
        if self._events is not None:
            self.bus.unsubscribe(self._events)

    def _idle(self) -> bool:
        return (self._events is None or self._events.empty()) and all(
            s.queue.empty() and not s.busy for s in self.senders)
