"""Notifications (issue 27, item 3): Apprise URLs in ``[notify]``, a message per event saying what to
do next, sent off the print path.

End to end: a real daemon on the simulator with two services on loopback, a JSON webhook (a small HTTP
server in this test, Apprise's ``json://``) and a service that accepts the connection and never
answers (listed first). One whole two-sided job: the flip notice reaches the webhook within 1 s of
the job entering ``awaiting_flip`` (both times measured), naming the next step; the job completes as
every job does (the documented states, every move of both programs deposited once, nothing more)
while every send to the other service hangs; those failures are shown by ``GET /notifications``.
Below: the words of each notice, the ``Watcher``'s reading of event sequences, the senders against
loopback servers in this process (refused, hanging, a full queue), and the configuration's checks.
"""

from __future__ import annotations

import asyncio
import json
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import replace
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

import httpx
import pytest

import ribbond.daemon.components.notifier as notifier_mod
from ribbond.daemon.components.frame import WAIT_STAGE
from ribbond.daemon.components.notifier import Notice, Notifier, Watcher, notice
from ribbond.daemon.config import NOTIFY_EVENTS, NotifySettings, load_config
from ribbond.daemon.events import EventBus
from tests.daemon.deposits import executed, outcome, program_parts
from tests.daemon.test_daemon_e2e import FULL_FLOW, MISALIGNMENT, operator_jogs, states

from .conftest import ROOT, Daemon, Sim, frame_ready, running, submit, wait_for

pytestmark = pytest.mark.timeout(120)

#: The daemon's [notify] timeout_s here: each send to the hanging service ends after this.
TIMEOUT_S = 1.0
#: The goal: the flip notice within this long of the job entering awaiting_flip (issue 27).
FLIP_NOTICE_S = 1.0


# ---------------------------------------------------------------------------------- services on loopback


class Hook:
    """A JSON webhook on loopback (what Apprise's ``json://`` posts): each body with its arrival time."""

    def __init__(self, status: int = 200) -> None:
        self.got: list[tuple[float, dict[str, Any]]] = []
        hook = self

        class Handler(BaseHTTPRequestHandler):
            def do_POST(self) -> None:  # noqa: N802 - http.server's name
                arrived = time.time()
                body = self.rfile.read(int(self.headers.get("Content-Length") or 0))
                hook.got.append((arrived, json.loads(body)))
                self.send_response(status)
                self.send_header("Content-Length", "0")
                self.end_headers()

            def log_message(self, *args: Any) -> None:
                pass

        self.server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"json://127.0.0.1:{self.server.server_address[1]}/ribbond"
        threading.Thread(target=self.server.serve_forever, daemon=True).start()

    def titled(self, start: str) -> list[tuple[float, dict[str, Any]]]:
        return [(t, body) for t, body in self.got if body["title"].startswith(start)]

    def close(self) -> None:
        self.server.shutdown()
        self.server.server_close()


class Hang:
    """A service that accepts every connection and never answers."""

    def __init__(self) -> None:
        self.sock = socket.create_server(("127.0.0.1", 0))
        self.url = f"json://127.0.0.1:{self.sock.getsockname()[1]}/hang"
        self.connections: list[socket.socket] = []
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            self.connections.append(conn)

    def close(self) -> None:
        self.sock.close()
        for conn in self.connections:
            conn.close()


def refused_url() -> str:
    """A loopback port nothing listens on (bound, then closed)."""
    with socket.create_server(("127.0.0.1", 0)) as s:
        port = s.getsockname()[1]
    return f"json://127.0.0.1:{port}/nobody"


# ---------------------------------------------------------------------------------- the daemon, one whole job


@pytest.fixture(scope="module")
def services() -> Iterator[tuple[Hook, Hang]]:
    hook, hang = Hook(), Hang()
    try:
        yield hook, hang
    finally:
        hook.close()
        hang.close()


@pytest.fixture(scope="module")
def notifying(shared_sim: Sim, services: tuple[Hook, Hang],
              tmp_path_factory: pytest.TempPathFactory) -> Iterator[Daemon]:
    hook, hang = services
    extra = f'[notify]\nurls = ["{hang.url}", "{hook.url}"]\ntimeout_s = {TIMEOUT_S}\n'
    with running(tmp_path_factory.mktemp("ribbond-notify"), shared_sim.port, extra=extra) as daemon:
        yield daemon


def turn_and_align(api: httpx.Client, sim: Sim, job: str, marks: list[list[float]]) -> list[httpx.Response]:
    """The operator turns the frame over (``MISALIGNMENT``), says so, waits until the head is above
    the first mark (the prompt), then reports the jog at every mark."""
    pose = sim.flip(*MISALIGNMENT)
    assert pose["side"] == "back"
    assert api.post(f"/jobs/{job}/flip-done").status_code == 200
    wait_for(api, job, "aligning", timeout=30, until=lambda j: j["waits_for_operator"])
    return [api.post(f"/jobs/{job}/align", json={"mark": i + 1, "jog": list(jog)})
            for i, jog in enumerate(operator_jogs(marks, *MISALIGNMENT))]


@pytest.fixture(scope="module")
def whole_job(notifying: Daemon, shared_sim: Sim, meshes: dict[str, Path]) -> dict[str, Any]:
    """A whole two-sided job on the notifying daemon: its id, record, transitions, programs, deposits."""
    api = notifying.client
    assert api is not None
    shared_sim.ensure_front()
    frame_ready(api)
    first = len(shared_sim.segments())
    job = submit(api, meshes["two_sided"], start=True)
    wait_for(api, job, "awaiting_flip", timeout=60)
    design = api.get(f"/jobs/{job}/files/design.json").json()
    answers = turn_and_align(api, shared_sim, job, design["registration_marks"])
    wait_for(api, job, "done", timeout=60)
    return {"id": job, "answers": answers, "record": api.get(f"/jobs/{job}").json(),
            "transitions": api.get(f"/jobs/{job}/transitions").json(),
            "front": api.get(f"/jobs/{job}/files/front.gcode").text,
            "back": api.get(f"/jobs/{job}/files/back-corrected.gcode").text,
            "segments": shared_sim.segments()[first:], "marks": len(design["registration_marks"])}


def test_the_flip_notice_reaches_the_webhook_within_a_second(whole_job: dict[str, Any],
                                                            services: tuple[Hook, Hang]) -> None:
    hook, _ = services
    job = whole_job["id"]
    entered = next(t["at"] for t in whole_job["transitions"] if t["to_state"] == "awaiting_flip")
    flips = hook.titled("Flip the frame")
    assert len(flips) == 1, [body["title"] for _, body in hook.got]
    arrived, body = flips[0]
    delay = arrived - entered
    print(f"\nthe flip notice arrived {delay * 1000:.0f} ms after the job entered awaiting_flip:\n"
          f"{body['title']}\n{body['message']}")
    assert 0 <= delay < FLIP_NOTICE_S, delay
    # what to do next, in the operator's words and the exact command
    assert f"ribbonctl flip-done {job}" in body["message"] and "Turn the frame over" in body["message"]
    assert "“Frame is flipped”" in body["message"] and body["type"] == "info"
    assert whole_job["record"]["mesh_name"] in body["title"]


def test_the_alignment_prompt_and_the_end_are_notified(whole_job: dict[str, Any],
                                                       services: tuple[Hook, Hang]) -> None:
    """One prompt per measuring pass (the first mark), and the job's end."""
    hook, _ = services
    job = whole_job["id"]
    prompts = hook.titled("Align the back")
    assert len(prompts) == 1, [body["title"] for _, body in hook.got]
    assert f"(mark 1 of {whole_job['marks']})" in prompts[0][1]["title"]
    assert f"ribbonctl align {job} --here" in prompts[0][1]["message"]
    done = hook.titled("Done")
    assert len(done) == 1 and done[0][1]["type"] == "success"
    assert "Take the frame off the printer" in done[0][1]["message"]
    ended = next(t["at"] for t in whole_job["transitions"] if t["to_state"] == "done")
    assert 0 <= done[0][0] - ended < FLIP_NOTICE_S


def test_the_job_completes_unchanged_while_a_service_hangs(whole_job: dict[str, Any],
                                                           services: tuple[Hook, Hang]) -> None:
    """The states, checkpoints and acknowledged lines every two-sided job has (test_daemon_e2e's
    test_full_two_sided_job, no notifications there), and the simulator deposited every extruding move
    of the front and of the corrected back exactly once, and nothing else."""
    _, hang = services
    record = whole_job["record"]
    assert states(whole_job["transitions"]) == FULL_FLOW
    assert record["state"] == "done" and record["error"] is None and record["checkpoint"] == "back_done"
    assert record["last_acked_line"] == record["lines_total"]
    assert [r.status_code for r in whole_job["answers"]] == [200] * whole_job["marks"]
    assert whole_job["answers"][-1].json()["accepted"] is True
    for side in ("front", "back"):
        parts = program_parts(whole_job[side])
        done = executed(whole_job["segments"], side)
        assert parts and all(outcome(p, done) == "full" for p in parts), side
        assert sum(done.values()) == sum(len(p.moves) for p in parts), f"{side}: moves beyond the program"
    # the hanging service was really asked, for each notice, and never answered
    assert len(hang.connections) >= 3


def test_the_hanging_service_is_shown_failed(notifying: Daemon, whole_job: dict[str, Any],
                                             services: tuple[Hook, Hang]) -> None:
    hook, hang = services
    api = notifying.client
    assert api is not None
    deadline = time.monotonic() + TIMEOUT_S + 2.0         # the done notice's send may still be hanging
    while True:
        view = api.get("/notifications").json()
        mine = [d for d in view["deliveries"] if d["job_id"] == whole_job["id"]]
        to_hang = [d for d in mine if d["url"] == hang.url]
        to_hook = [d for d in mine if d["url"] == hook.url]
        if len(to_hang) >= 3 or time.monotonic() > deadline:
            break
        time.sleep(0.1)
    assert view["enabled"] and view["timeout_s"] == TIMEOUT_S
    assert view["urls"] == [hang.url, hook.url]
    assert {d["event"] for d in to_hook} == {"awaiting_flip", "alignment", "done"}
    assert all(d["status"] == "sent" for d in to_hook), to_hook
    assert {d["event"] for d in to_hang} == {"awaiting_flip", "alignment", "done"}
    # given up after timeout_s
    assert all(d["status"] == "timeout" and "no answer in 1 s" in d["error"] for d in to_hang), to_hang
    assert all(TIMEOUT_S <= d["duration_s"] < TIMEOUT_S + 0.5 for d in to_hang), to_hang
    assert view["last_failed"]["url"] == hang.url and view["failed"] >= 3
    assert view["last_sent"]["url"] == hook.url


def test_the_printer_halt_is_notified(notifying: Daemon, whole_job: dict[str, Any],
                                      services: tuple[Hook, Hang]) -> None:
    """An emergency stop halts the printer (M112): the notice says so and how to recover; recovered,
    the printer is ready again (the next job's frame is unaffected)."""
    hook, _ = services
    api = notifying.client
    assert api is not None
    assert api.post("/printer/emergency-stop").status_code == 200
    stopped = time.time()
    deadline = time.monotonic() + 5.0
    while not hook.titled("Printer halted") and time.monotonic() < deadline:
        time.sleep(0.05)
    halts = hook.titled("Printer halted")
    assert len(halts) == 1, [body["title"] for _, body in hook.got]
    arrived, body = halts[0]
    # the daemon looks at the printer's state every 0.5 s (service.PRINTER_EVENT_S)
    assert arrived - stopped < 0.5 + FLIP_NOTICE_S
    assert "ribbonctl recover" in body["message"] and body["type"] == "failure"
    assert api.post("/printer/recover").status_code == 200
    notifying.wait_printer()


def test_ribbonctl_notify_test_reports_each_service(notifying: Daemon, whole_job: dict[str, Any],
                                                     services: tuple[Hook, Hang]) -> None:
    """``ribbonctl notify test`` waits for every service's answer: the webhook's sent, the hanging
    one's timeout, exit status 1 (one did not get it); ``notify status`` lists the deliveries."""
    hook, hang = services
    before = len(hook.titled("ribbond: test notification"))
    proc = subprocess.run([sys.executable, "-m", "ribbond.client.cli", "notify", "test", "--url", notifying.url],
                          cwd=ROOT, text=True, capture_output=True, timeout=60)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    lines = proc.stdout.splitlines()
    assert any(" sent " in line and hook.url in line for line in lines), lines
    assert any(hang.url in line and " timeout " in line for line in lines), lines
    assert "did not reach every service" in proc.stderr
    assert len(hook.titled("ribbond: test notification")) == before + 1
    status = subprocess.run([sys.executable, "-m", "ribbond.client.cli", "notify", "--url", notifying.url],
                            cwd=ROOT, text=True, capture_output=True, timeout=60)
    assert status.returncode == 0 and f"notifications on: {hang.url}, {hook.url}" in status.stdout, status


# ---------------------------------------------------------------------------------- the words


def status(state: str, instruction: str = "", **fields: Any) -> dict[str, Any]:
    """A job as ``GET /jobs/{id}`` shows it, as much of it as the notices read."""
    return {"id": "3f2a9c1b2d4e", "mesh_name": "saddle.obj", "state": state, "start_when_ready": True,
            "stage": None, "error": None, "next": {"instruction": instruction, "commands": []}, **fields}


FLIP = ("the front is printed. Turn the frame over about its y axis (the line x = 110), seat it again, "
        "then run: ribbonctl flip-done 3f2a9c1b2d4e")

# (event, job, info, words the title has, words the body has, Apprise's type)
WORDS = [
    ("awaiting_flip", status("awaiting_flip", FLIP), None, ["Flip the frame: saddle.obj"],
     ["saddle.obj (job 3f2a9c1b2d4e)", "The front is printed. Turn the frame over",
      "ribbonctl flip-done 3f2a9c1b2d4e", "“Frame is flipped”"], "info"),
    ("awaiting_flip", status("awaiting_flip", FLIP, panel=2, panels=3), None, ["(panel 2/3)"],
     ["(job 3f2a9c1b2d4e, panel 2 of 3)"], "info"),
    ("alignment", status("aligning"), {"mark": 1, "marks": 4, "message": "mark 1 of 4: jog the nozzle onto the "
                                                                       "mark, then run: ribbonctl align J --here"},
     ["Align the back (mark 1 of 4)"], ["Mark 1 of 4: jog the nozzle", "“Nozzle is on the mark”"], "info"),
    ("alignment", status("fitted", "the fit turns the back by 0.80°. Accept it (ribbonctl accept J)"), None,
     ["check the fit"], ["The fit turns the back by 0.80°", "“Accept, print the back”"], "info"),
    ("fresh_frame", status("ready", "waiting for a fresh frame: load a fresh stretched frame, then confirm: "
                                    "ribbonctl frame-ready", stage=WAIT_STAGE), None,
     ["Load a fresh frame: saddle.obj"], ["Waiting for a fresh frame", "ribbonctl frame-ready",
                                          "“Fresh frame loaded”"], "info"),
    ("done", status("done"), None, ["Done: saddle.obj"],
     ["is printed", "Take the frame off the printer", "ribbonctl start 3f2a9c1b2d4e"], "success"),
    ("failed", status("failed", "failed (printer halted: heater fault); print it again with ribbonctl start "
                                "3f2a9c1b2d4e", error="printer halted: heater fault"), None, ["Failed: saddle.obj"],
     ["Failed (printer halted: heater fault)", "ribbonctl start 3f2a9c1b2d4e"], "failure"),
    ("interrupted", status("interrupted", "interrupted (the daemon stopped); resume it: ribbonctl resume "
                                          "3f2a9c1b2d4e"), None, ["Interrupted: saddle.obj"],
     ["ribbonctl resume 3f2a9c1b2d4e"], "warning"),
    ("halted", None, {"state": "halted", "last_error": "Printer halted. kill() called!"}, ["Printer halted"],
     ["(Printer halted. kill() called!)", "ribbonctl recover", "“Recover”"], "failure"),
]


@pytest.mark.parametrize("event, job, info, title, body, kind", WORDS,
                         ids=[f"{w[0]}-{i}" for i, w in enumerate(WORDS)])
def test_each_notice_says_what_happened_and_what_to_do(event: str, job: dict[str, Any] | None,
                                                       info: dict[str, Any] | None, title: list[str],
                                                       body: list[str], kind: str) -> None:
    n = notice(event, job, info)
    assert n.event == event and n.kind == kind and n.job_id == (job["id"] if job else None)
    assert all(w in n.title for w in title), n.title
    assert all(w in n.body for w in body), n.body


# ---------------------------------------------------------------------------------- reading the events


def job_event(state: str, **fields: Any) -> dict[str, Any]:
    return {"type": "job", "job": status(state, **fields)}


MARK_1 = {"type": "alignment", "job_id": "3f2a9c1b2d4e", "mark": 1, "marks": 3, "message": "mark 1 of 3"}
MARK_2 = {**MARK_1, "mark": 2, "message": "mark 2 of 3"}
REFUSED = "alignment refused: the rotation 5.00° is beyond 2°"

# (events, the notices they call for, one list per event)
SEQUENCES = {
    "the flip, once": ([job_event("printing_front"), job_event("awaiting_flip"), job_event("awaiting_flip")],
                       [[], ["awaiting_flip"], []]),
    "the first mark of a pass": ([job_event("aligning"), MARK_1, job_event("aligning"), MARK_2],
                                 [[], ["alignment"], [], []]),
    "a refused fit: the next pass": ([job_event("aligning"), MARK_1, MARK_2, job_event("aligning", error=REFUSED),
                                      MARK_1], [[], ["alignment"], [], [], ["alignment"]]),
    "a fit to review": ([job_event("aligning"), job_event("fitted")], [[], ["alignment"]]),
    "no prompt outside aligning": ([MARK_1], [[]]),
    "the fresh-frame gate": ([job_event("ready"), job_event("ready", stage=WAIT_STAGE),
                              job_event("ready", stage=WAIT_STAGE), job_event("ready", stage="a fresh frame is loaded")],
                             [[], ["fresh_frame"], [], []]),
    "the ends": ([job_event("printing_back"), job_event("done")], [[], ["done"]]),
    "failed": ([job_event("heating"), job_event("failed", error="x")], [[], ["failed"]]),
    "interrupted": ([job_event("printing_front"), job_event("interrupted")], [[], ["interrupted"]]),
    "cancelled is the operator's own doing": ([job_event("printing_front"), job_event("cancelled")], [[], []]),
    "the printer halts once": ([{"type": "printer", "printer": {"state": "streaming"}},
                                {"type": "printer", "printer": {"state": "halted"}},
                                {"type": "printer", "printer": {"state": "halted", "last_error": "x"}},
                                {"type": "printer", "printer": {"state": "ready"}},
                                {"type": "printer", "printer": {"state": "halted"}}],
                               [[], ["halted"], [], [], ["halted"]]),
    "other events": ([{"type": "progress", "job_id": "3f2a9c1b2d4e"}, {"type": "notice", "message": "m"},
                      {"type": "notification", "notification": {}}], [[], [], []]),
}


@pytest.mark.parametrize("name", list(SEQUENCES))
def test_the_watcher_notices_each_change_once(name: str) -> None:
    events, wanted = SEQUENCES[name]
    watcher = Watcher(NOTIFY_EVENTS)
    assert [[n.event for n in watcher.see(e)] for e in events] == wanted


def test_the_watcher_sends_only_the_events_chosen_and_knows_the_jobs_at_start() -> None:
    watcher = Watcher(["done"])
    assert watcher.see(job_event("awaiting_flip")) == []
    assert [n.event for n in watcher.see(job_event("done"))] == ["done"]
    # a job done before the daemon started, published again (a prediction, a restart): not news
    known = Watcher(NOTIFY_EVENTS)
    known.know([status("done")])
    assert known.see(job_event("done")) == []
    assert [n.event for n in known.see(job_event("interrupted"))] == ["interrupted"]


# ---------------------------------------------------------------------------------- sending, in this process


def make_notifier(urls: list[str], timeout_s: float, events: list[str] | None = None) -> tuple[Notifier, EventBus]:
    bus = EventBus()
    settings = NotifySettings(urls=urls, timeout_s=timeout_s, **({"events": events} if events is not None else {}))
    return Notifier(settings, bus), bus


async def deliveries(n: Notifier, count: int, within: float) -> list[dict[str, Any]]:
    deadline = time.monotonic() + within
    while len(n.deliveries) < count and time.monotonic() < deadline:
        await asyncio.sleep(0.01)
    return list(n.deliveries)


TEST = Notice("test", "a title", "a body")


async def test_a_hanging_service_never_holds_up_the_others() -> None:
    hook, hang = Hook(), Hang()
    n, bus = make_notifier([hang.url, hook.url], timeout_s=0.4)
    seen = bus.subscribe()
    n.start([])
    try:
        started = time.time()
        for _ in range(3):
            n.send(TEST)
        got = await deliveries(n, 6, within=5.0)
    finally:
        await n.close()
        hook.close()
        hang.close()
    assert len(hook.got) == 3 and max(t for t, _ in hook.got) - started < 0.5      # not behind the hang
    to_hang = [d for d in got if d["url"] == hang.url]
    assert [d["status"] for d in to_hang] == ["timeout"] * 3, to_hang
    assert n.view()["sent"] == 3 and n.view()["failed"] == 3
    published = [seen.get_nowait() for _ in range(seen.qsize())]
    assert sum(e["type"] == "notification" for e in published) == 6


async def test_a_refusing_service_is_a_failure_with_apprise_s_reason() -> None:
    url = refused_url()
    n, _ = make_notifier([url], timeout_s=2.0)
    n.start([])
    try:
        n.send(TEST)
        got = await deliveries(n, 1, within=3.0)
    finally:
        await n.close()
    assert [d["status"] for d in got] == ["failed"]
    assert "connection" in got[0]["error"].lower(), got[0]["error"]
    assert n.view()["last_failed"] == got[0] and n.view()["last_sent"] is None


async def test_a_service_answering_an_error_is_a_failure() -> None:
    hook = Hook(status=500)
    n, _ = make_notifier([hook.url], timeout_s=2.0)
    n.start([])
    try:
        n.send(TEST)
        got = await deliveries(n, 1, within=3.0)
    finally:
        await n.close()
        hook.close()
    assert len(hook.got) == 1 and got[0]["status"] == "failed" and "500" in got[0]["error"], got


async def test_a_full_queue_drops_with_the_reason(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(notifier_mod, "QUEUE_MAX", 2)
    hang = Hang()
    n, _ = make_notifier([hang.url], timeout_s=0.3)
    n.start([])
    try:
        for i in range(5):
            n.send(replace(TEST, title=f"notice {i}"))
        got = await deliveries(n, 5, within=3.0)
    finally:
        await n.close()
        hang.close()
    dropped = [d for d in got if d["status"] == "dropped"]
    assert len(dropped) == 3 and all("2 notices already wait" in d["error"] for d in dropped), got
    assert sorted(d["title"] for d in got if d["status"] != "dropped") == ["notice 0", "notice 1"]


async def test_sends_that_keep_hanging_stop_new_threads(monkeypatch: pytest.MonkeyPatch) -> None:
    """A send whose thread outlives its timeout (here: the service's own read timeout made long) counts
    as hung; at MAX_HUNG, the next notices to that service are dropped rather than given threads."""
    monkeypatch.setattr(notifier_mod, "MAX_HUNG", 1)
    monkeypatch.setattr(notifier_mod, "SOCKET_GRACE_S", 30.0)
    hang = Hang()
    n, _ = make_notifier([hang.url], timeout_s=0.2)
    n.start([])
    try:
        n.send(replace(TEST, title="first"))
        n.send(replace(TEST, title="second"))
        got = await deliveries(n, 2, within=3.0)
    finally:
        await n.close()
        hang.close()
    assert [(d["title"], d["status"]) for d in reversed(got)] == [("first", "timeout"), ("second", "dropped")]
    assert got[0]["error"] == "1 earlier send(s) to this service still hang"
    assert len(hang.connections) == 1


async def test_without_urls_nothing_is_followed_and_the_test_is_refused() -> None:
    from ribbond.daemon.records import ServiceError

    n, bus = make_notifier([], timeout_s=1.0)
    n.start([])
    assert n.view()["enabled"] is False and n._events is None
    with pytest.raises(ServiceError, match=r"no \[notify\] urls"):
        n.test()
    await n.close()


# ---------------------------------------------------------------------------------- the configuration


def test_the_defaults_notify_nothing_and_name_every_event() -> None:
    settings = NotifySettings()
    assert settings.urls == [] and settings.events == list(NOTIFY_EVENTS) and settings.timeout_s > 0


@pytest.mark.parametrize("table, words", [
    ('events = ["awaiting_flip", "flipped"]', ["notify.events", "'flipped' is not an event", "awaiting_flip, alignment"]),
    ('urls = ["json://127.0.0.1/ok", "nosuch://x"]', ["notify.urls", "URL 2 (nosuch://…)",
                                                      "no Apprise service is called nosuch://"]),
    ('urls = ["tgram://SECRET-TOKEN"]', ["notify.urls", "URL 1 (tgram://…)", "Apprise cannot use this tgram:// URL"]),
    ('urls = ["hello"]', ["notify.urls", "not a URL"]),
    ('url = ["json://127.0.0.1/x"]', ["notify.url", "Extra inputs are not permitted"]),
    ("timeout_s = 0", ["notify.timeout_s", "greater than 0"]),
])
def test_bad_settings_are_refused_naming_them(tmp_path: Path, table: str, words: list[str]) -> None:
    path = tmp_path / "ribbond.toml"
    path.write_text(f"[notify]\n{table}\n", encoding="utf-8")
    with pytest.raises(ValueError) as caught:
        load_config(path)
    message = str(caught.value)
    assert all(w in message for w in words), message
    assert "SECRET" not in message


def test_the_daemon_refuses_to_start_on_a_url_apprise_cannot_use(tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """``ribbond``'s entry point (in this process: it reads the configuration before anything else)."""
    from ribbond.daemon.main import main

    path = tmp_path / "ribbond.toml"
    path.write_text(f'state_dir = "{tmp_path}"\n[notify]\nurls = ["nosuch://x"]\n', encoding="utf-8")
    assert main(["--config", str(path)]) == 2
    err = capsys.readouterr().err
    assert "notify.urls" in err and "nosuch://" in err and not (tmp_path / "jobs.sqlite3").exists(), err
