"""The API's gate against real daemon processes (issue 16): the token is checked before a body is
read (nothing is spooled for an unauthenticated upload), the Host header must name the daemon (DNS
rebinding), state-changing requests from another origin are refused, reflected values are cut,
and an upload over the limit is 413 through ribbonctl's chunked upload as through a declared length.
"""

from __future__ import annotations

import json
import os
import select
import socket
import subprocess
import sys
import threading
import time
import urllib.parse
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from .conftest import PARAMETERS, ROOT, Daemon

pytestmark = pytest.mark.timeout(240)

TOKEN = "gate-test-token"
#: The cut of a reflected value (ribbond.daemon.config.ECHO_MAX) and the bound a reply must stay under.
ECHO_MAX = 64
SMALL_REPLY = 4096


def no_printer(tmp_path: Path) -> str:
    """A serial port nobody serves: the daemon runs, the printer is away (the gate is tested)."""
    return str(tmp_path / "no-printer-here")


@pytest.fixture
def gated(tmp_path: Path) -> Iterator[Daemon]:
    """A daemon with a token, TMPDIR of its own (where the multipart parser spools) and a 16 MiB limit."""
    spool = tmp_path / "spool"
    spool.mkdir()
    daemon = Daemon(tmp_path / "state", no_printer(tmp_path), api=f'token = "{TOKEN}"',
                    extra="[limits]\nmax_upload_mb = 16\n", token=TOKEN)
    old = os.environ.get("TMPDIR")
    os.environ["TMPDIR"] = str(spool)          # the daemon process inherits it
    try:
        daemon.start()
    finally:
        if old is None:
            os.environ.pop("TMPDIR")
        else:
            os.environ["TMPDIR"] = old
    daemon.spool = spool                       # type: ignore[attr-defined]
    try:
        yield daemon
    finally:
        daemon.stop()


def spooled(daemon: Daemon, folder: Path) -> int:
    """Bytes in files under ``folder`` that the daemon process holds open, named or not (the
    multipart parser's spool files are unnamed: O_TMPFILE, so no listing of the folder shows them)."""
    assert daemon.proc is not None
    fds = Path(f"/proc/{daemon.proc.pid}/fd")
    total = 0
    for fd in fds.iterdir():
        try:
            if os.readlink(fd).startswith(str(folder) + "/"):
                total += os.stat(fd).st_size
        except OSError:                        # closed while counted
            pass
    return total + sum(p.stat().st_size for p in folder.rglob("*") if p.is_file())


def raw_upload(url: str, size: int, *, token: str | None = None, pause_after: int | None = None,
               paused: threading.Event | None = None, resume: threading.Event | None = None) -> tuple[int | None, int]:
    """POST /jobs with a ``size``-byte multipart body over a plain socket, streamed in 64 kB writes
    that stop as soon as the daemon answers. Returns (status or None, body bytes sent)."""
    parts = urllib.parse.urlsplit(url)
    boundary = "gate-test"
    head = (f'--{boundary}\r\nContent-Disposition: form-data; name="mesh"; filename="big.obj"\r\n'
            "Content-Type: application/octet-stream\r\n\r\n").encode()
    tail = f"\r\n--{boundary}--\r\n".encode()
    length = len(head) + size + len(tail)
    auth = f"Authorization: Bearer {token}\r\n" if token else ""
    request = (f"POST /jobs HTTP/1.1\r\nHost: {parts.netloc}\r\n{auth}Content-Length: {length}\r\n"
               f"Content-Type: multipart/form-data; boundary={boundary}\r\n\r\n").encode()
    sock = socket.create_connection((parts.hostname, parts.port), timeout=60)
    sent = 0
    try:
        sock.sendall(request + head)
        chunk = b"v 0 0 0\n" * 8192
        while sent < size:
            if select.select([sock], [], [], 0)[0]:
                break                                   # answered before the body was sent
            if pause_after is not None and sent >= pause_after and paused is not None and resume is not None:
                paused.set()
                resume.wait(60)
                pause_after = None
            piece = chunk[: size - sent]
            try:
                sock.sendall(piece)
            except OSError:
                break
            sent += len(piece)
        else:
            sock.sendall(tail)
        try:
            answer = sock.recv(4096)
        except OSError:
            return None, sent
        line = answer.split(b"\r\n", 1)[0].split()
        return (int(line[1]) if len(line) > 1 and line[1].isdigit() else None), sent
    finally:
        sock.close()


def test_an_upload_without_the_token_is_refused_before_its_body_is_read(gated: Daemon) -> None:
    spool: Path = gated.spool                            # type: ignore[attr-defined]
    size = 12 * 1024 * 1024                              # under the limit: only the token refuses it
    # The measure works: an authorized upload held mid-way is spooled to this TMPDIR.
    paused, resume = threading.Event(), threading.Event()
    result: list[tuple[int | None, int]] = []
    worker = threading.Thread(target=lambda: result.append(raw_upload(
        gated.url, 4 * 1024 * 1024, token=TOKEN, pause_after=3 * 1024 * 1024, paused=paused, resume=resume)))
    worker.start()
    assert paused.wait(60)
    deadline = time.monotonic() + 10
    while spooled(gated, spool) < 1024 * 1024 and time.monotonic() < deadline:
        time.sleep(0.05)
    assert spooled(gated, spool) >= 1024 * 1024, "an authorized upload should spool to the daemon's TMPDIR"
    resume.set()
    worker.join(60)
    assert result and result[0][0] == 422, result         # read whole, then refused at upload: no faces
    base = spooled(gated, spool)                                     # the spooled file is gone with the request

    # Ten unauthenticated uploads at once: each is answered 401 before its body is read.
    peak = [0]
    done = threading.Event()

    def watch() -> None:
        while not done.is_set():
            peak[0] = max(peak[0], spooled(gated, spool))
            time.sleep(0.01)

    watcher = threading.Thread(target=watch)
    watcher.start()
    answers: list[tuple[int | None, int]] = []
    threads = [threading.Thread(target=lambda: answers.append(raw_upload(gated.url, size))) for _ in range(10)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(120)
    done.set()
    watcher.join()
    assert [status for status, _ in answers] == [401] * 10, answers
    assert all(sent < size for _, sent in answers), answers  # answered before the body was through
    assert peak[0] <= base, f"the temporary directory grew by {peak[0] - base} bytes"
    r = httpx.post(f"{gated.url}/jobs", files={"mesh": ("m.obj", b"v 0 0 0\n")})
    assert r.status_code == 401 and r.json()["detail"].startswith("missing or wrong API token")
    assert r.headers["www-authenticate"] == "Bearer"
    # The open paths stay open: the documentation and the dashboard's files.
    for path in ("/openapi.json", "/docs", "/", "/ui/app.js"):
        assert httpx.get(f"{gated.url}{path}").status_code == 200, path


def test_host_must_name_the_daemon(tmp_path: Path) -> None:
    """DNS rebinding: a page of attacker.example whose name now resolves to 127.0.0.1 sends
    ``Host: attacker.example:PORT``; the daemon refuses it (421), also for reads. Its own
    addresses pass, with the port it serves; ``api.allowed_hosts`` adds names."""
    daemon = Daemon(tmp_path / "state", no_printer(tmp_path), api='allowed_hosts = ["printer.local", "proxy.lan:80"]')
    try:
        daemon.start()
        port = urllib.parse.urlsplit(daemon.url).port
        c = httpx.Client(base_url=daemon.url)
        for host in (f"attacker.example:{port}", "attacker.example", f"127.0.0.1:{port + 1}",
                     f"localhost.attacker.example:{port}", "proxy.lan:8080", f"{'x' * 10_000}:{port}"):
            r = c.get("/jobs", headers={"Host": host})
            assert r.status_code == 421, (host, r.text)
            assert r.json()["host"] == (host if len(host) <= ECHO_MAX else host[:ECHO_MAX] + "…")
            assert len(r.content) < SMALL_REPLY
        assert c.post("/printer/emergency-stop", headers={"Host": f"attacker.example:{port}"}).status_code == 421
        for host in (f"127.0.0.1:{port}", f"localhost:{port}", f"LOCALHOST.:{port}", "printer.local",
                     f"printer.local:{port}", "proxy.lan", "proxy.lan:80"):
            r = c.get("/jobs", headers={"Host": host})
            assert r.status_code == 200, (host, r.text)
        c.close()
    finally:
        daemon.stop()
    # Over IPv6 loopback: [::1] names it.
    v6 = Daemon(tmp_path / "state6", no_printer(tmp_path))
    v6.config.write_text(v6.config.read_text().replace('host = "127.0.0.1"', 'host = "::1"'))
    try:
        v6.start()
        port = urllib.parse.urlsplit(v6.url).port
        assert httpx.get(f"{v6.url}/jobs").status_code == 200
        assert httpx.get(f"{v6.url}/jobs", headers={"Host": f"attacker.example:{port}"}).status_code == 421
    finally:
        v6.stop()


def test_state_changing_requests_from_another_origin_are_refused(tmp_path: Path) -> None:
    """A page of another origin can POST a form (no preflight): an emergency stop, an upload.
    Origin (or Referer) not the daemon's is 403; the daemon's own and none at all pass."""
    daemon = Daemon(tmp_path / "state", no_printer(tmp_path))
    try:
        daemon.start()
        c = httpx.Client(base_url=daemon.url)
        own = daemon.url
        port = urllib.parse.urlsplit(own).port
        foreign = [{"Origin": "http://attacker.example"}, {"Origin": "null"},
                   {"Origin": own.replace("127.0.0.1", "localhost")},     # another origin, same machine
                   {"Origin": f"http://127.0.0.1:{port + 1}"}, {"Origin": "http://127.0.0.1"},
                   {"Referer": "http://attacker.example/page.html"}]
        form = {"Content-Type": "application/x-www-form-urlencoded"}        # what a <form> sends
        for headers in foreign:
            for method, path, body, more in (("POST", "/printer/emergency-stop", None, {}),
                                             ("POST", "/printer/gcode", b"commands=G28", form),
                                             ("DELETE", "/jobs/0123456789ab", None, {})):
                r = c.request(method, path, content=body, headers={**headers, **more})
                assert r.status_code == 403, (headers, path, r.text)
                given = headers.get("Origin", headers.get("Referer"))
                assert r.json()["origin"] == given and given in r.json()["detail"]
            r = c.post("/jobs", files={"mesh": ("m.obj", b"v 0 0 0\n")}, headers=headers)
            assert r.status_code == 403, (headers, r.text)
        assert c.get("/jobs").json() == []                       # no upload went through
        # Reads carry no Origin rule (the Host rule and the browser's same-origin policy cover them).
        assert c.get("/jobs", headers={"Origin": "http://attacker.example"}).status_code == 200
        # The daemon's own origin (the dashboard's fetches), a Referer of its own page, and no header.
        # (the scheme is not compared: behind a TLS proxy the page is https, and no other server can
        # have the daemon's host and port)
        for headers in ({"Origin": own}, {"Origin": own.replace("http:", "https:")},
                        {"Referer": own + "/ui/index.html"}, {}):
            r = c.post("/jobs/0123456789ab/cancel", headers=headers)
            assert r.status_code == 404, (headers, r.text)           # reached the service: no such job
        c.close()
    finally:
        daemon.stop()


def test_reflected_values_are_cut(gated: Daemon) -> None:
    c = gated.client
    assert c is not None
    long_id = "a" * 10_000                    # a URL's line is limited to 16 kB by the HTTP server
    for method, path in (("GET", f"/jobs/{long_id}"), ("DELETE", f"/jobs/{long_id}"),
                         ("POST", f"/jobs/{long_id}/cancel"), ("GET", f"/tables/{long_id}"),
                         ("GET", f"/calibrations/{long_id}/files/plan.json"),
                         ("GET", f"/jobs/0123456789ab/files/{long_id}")):
        r = c.request(method, path)
        assert r.status_code == 422 and len(r.content) < SMALL_REPLY, (path, len(r.content))
    huge = "b" * 100_000
    cases = [
        # (the multipart parser takes a part header of a few kB: a longer one is a 400, not echoed)
        c.post("/jobs", files={"mesh": (huge[:4000] + ".txt", b"v 0 0 0\n")}),
        c.post("/jobs", files={"mesh": ("m.obj", b"v 0 0 0\n")},
               data={"parameters": json.dumps({**PARAMETERS, "curvature_table": huge})}),
        c.post("/jobs", files={"mesh": ("m.obj", b"v 0 0 0\n")}, data={"parameters": json.dumps({huge: 1})}),
        c.post("/tables", json={"toml": f'name = "{huge}"\n'}),
        c.post("/calibrations", json={"base_table": "c" * 60, "fabric": huge, huge: 1}),
        c.post("/calibrations", json={"base_table": huge}),
        c.post("/printer/gcode", json={"commands": [huge]}),
    ]
    for r in cases:
        assert r.status_code == 422, r.text[:300]
        assert len(r.content) < SMALL_REPLY, (r.request.url, len(r.content), r.text[:300])
        body = r.json()
        assert isinstance(body["detail"], str) and isinstance(body["errors"], list)
    assert "b" * ECHO_MAX + "…" in cases[0].json()["detail"]         # the name, cut, is still shown


def ctl(daemon: Daemon, *args: str, token: str | None = None) -> subprocess.CompletedProcess[str]:
    extra = ["--token", token] if token else []
    return subprocess.run([sys.executable, "-m", "ribbond.client.cli", *args, "--url", daemon.url, *extra],
                          cwd=ROOT, text=True, capture_output=True, timeout=120)


def test_an_upload_over_the_limit_is_413_through_ribbonctl(gated: Daemon, tmp_path: Path) -> None:
    """ribbonctl streams its uploads chunked (no Content-Length): the limit is found while the body
    is read, and ribbonctl reports the 413, not a parse error or a reset connection."""
    limit = 16 * 1024 * 1024
    big = tmp_path / "big.obj"
    big.write_bytes(b"v 0 0 0\n" * ((4 * limit) // 8))
    program = tmp_path / "big.gcode"
    program.write_bytes(b"G1 X10 Y10\n" * ((2 * limit) // 11))
    for args in (("submit", str(big), "--no-wait"), ("print", str(program), "--no-wait")):
        proc = ctl(gated, *args, token=TOKEN)
        assert proc.returncode == 2, (args, proc.stderr)
        assert "exceeds the limit" in proc.stderr and "limits.max_upload_mb" in proc.stderr, proc.stderr
        # Without the token it is the token that is reported (before any of the body is read).
        proc = ctl(gated, *args)
        assert proc.returncode == 2 and "the daemon needs a token" in proc.stderr, proc.stderr
    # Through a declared length too, and nothing is left of the refused uploads.
    assert gated.client is not None
    with big.open("rb") as handle:
        r = gated.client.post("/jobs", files={"mesh": ("big.obj", handle)})
    assert r.status_code == 413 and r.json()["limit"] > limit, r.text
    uploads = gated.state_dir / "uploads"
    assert not uploads.exists() or not any(uploads.iterdir())
    assert gated.client.get("/jobs").json() == []


def test_allowed_hosts_entries_are_checked_when_the_file_is_read(tmp_path: Path) -> None:
    from ribbond.daemon.config import load_config

    good = tmp_path / "good.toml"
    good.write_text('[api]\nallowed_hosts = ["printer.local", "printer.local:8080", "[fe80::1]:7125", "10.0.0.5"]\n')
    assert load_config(good, environ={}).api.allowed_hosts == ["printer.local", "printer.local:8080",
                                                               "[fe80::1]:7125", "10.0.0.5"]
    for bad in ("http://printer.local", "printer.local:0", "printer.local:http", "fe80::1", "a b", ""):
        path = tmp_path / "bad.toml"
        path.write_text(f'[api]\nallowed_hosts = ["{bad}"]\n')
        with pytest.raises(ValueError, match=r"api\.allowed_hosts"):
            load_config(path, environ={})


def test_beyond_loopback_the_machine_name_passes_and_the_token_is_required(tmp_path: Path) -> None:
    """Listening on all interfaces: a token is generated; the host's own name (and NAME.local)
    passes the Host rule, and only then is the token asked for; a foreign name is still 421."""
    daemon = Daemon(tmp_path / "state", no_printer(tmp_path))
    daemon.config.write_text(daemon.config.read_text().replace('host = "127.0.0.1"', 'host = "0.0.0.0"'))
    try:
        daemon.start()
        port = urllib.parse.urlsplit(daemon.url).port
        token = (daemon.state_dir / "api-token").read_text().strip()
        name = socket.gethostname()
        for host in (f"{name}:{port}", f"{name}.local:{port}", f"127.0.0.1:{port}", f"0.0.0.0:{port}"):
            r = httpx.get(f"http://127.0.0.1:{port}/jobs", headers={"Host": host})
            assert r.status_code == 401, (host, r.text)
            r = httpx.get(f"http://127.0.0.1:{port}/jobs", headers={"Host": host, "Authorization": f"Bearer {token}"})
            assert r.status_code == 200, (host, r.text)
        r = httpx.get(f"http://127.0.0.1:{port}/jobs", headers={"Host": f"attacker.example:{port}",
                                                              "Authorization": f"Bearer {token}"})
        assert r.status_code == 421
    finally:
        daemon.stop()


def test_a_token_file_is_enforced_on_loopback_too(tmp_path: Path) -> None:
    """Issue 22 item 5: ``host = "127.0.0.1"`` with ``token_file`` set: a wrong token or none is 401,
    the file's token passes; the log says the API is protected and by which file; ribbonctl says the
    daemon refused the token and exits 2 (bad input), not 3 (cannot reach)."""
    token_file = tmp_path / "secret" / "token"
    token_file.parent.mkdir(mode=0o700)
    fd = os.open(token_file, os.O_CREAT | os.O_WRONLY, 0o600)
    os.write(fd, b"loopback-token\n")
    os.close(fd)
    daemon = Daemon(tmp_path / "state", no_printer(tmp_path), api=f'token_file = "{token_file}"',
                    token="loopback-token")
    try:
        daemon.start()
        wrong = httpx.get(f"{daemon.url}/jobs", headers={"Authorization": "Bearer not-the-token"})
        assert wrong.status_code == 401, wrong.text
        assert httpx.get(f"{daemon.url}/jobs").status_code == 401
        assert httpx.post(f"{daemon.url}/printer/emergency-stop").status_code == 401
        assert daemon.client is not None and daemon.client.get("/jobs").status_code == 200
        assert f"API on {daemon.url}: protected by the token in {token_file}" in daemon.log_tail()

        def ctl(*args: str) -> subprocess.CompletedProcess[str]:
            return subprocess.run([sys.executable, "-m", "ribbond.client.cli", *args, "--url", daemon.url], cwd=ROOT,
                                  text=True, capture_output=True, timeout=60)

        refused = ctl("status", "--token", "not-the-token")
        assert refused.returncode == 2, refused
        assert "the daemon refused the token" in refused.stderr and "cannot reach" not in refused.stderr
        assert len(refused.stderr.strip().splitlines()) == 1
        missing = ctl("status")
        assert missing.returncode == 2 and "the daemon needs a token" in missing.stderr, missing
        watch = ctl("watch", "0123456789ab", "--token", "not-the-token")   # the event stream's 401 too
        assert watch.returncode == 2 and "the daemon refused the token" in watch.stderr, watch
        right = ctl("status", "--token-file", str(token_file))
        assert right.returncode == 0 and "no jobs" in right.stdout, right
    finally:
        daemon.stop()


def test_loopback_without_a_token_is_open_and_says_so(tmp_path: Path) -> None:
    daemon = Daemon(tmp_path / "state", no_printer(tmp_path))
    try:
        daemon.start()
        assert httpx.get(f"{daemon.url}/jobs").status_code == 200
        assert (f"API on {daemon.url}: open: no token; anyone on this machine can drive the printer"
                in daemon.log_tail())
        assert not (daemon.state_dir / "api-token").exists()
    finally:
        daemon.stop()


def test_messages_are_not_cut_between_two_quoted_values(gated: Daemon) -> None:
    """Issue 22 item 10: the prose between a quoted value and an apostrophe ("daemon's") was taken
    for a long quoted value and cut mid-word ("…(designs are made for the da…'s printer)")."""
    c = gated.client
    assert c is not None
    r = c.post("/jobs", files={"mesh": ("m.obj", b"v 0 0 0\n")},
               data={"parameters": json.dumps({**PARAMETERS, "printer_profile": "generic-marlin"})})
    assert r.status_code == 422, r.text
    detail = r.json()["detail"]
    assert "…" not in detail, detail
    assert "leave printer_profile out (designs are made for the daemon's printer)" in detail, detail


def test_a_long_message_is_cut_after_a_whole_word() -> None:
    from ribbond.api.errors import DETAIL_MAX, bounded

    words = " ".join(["flattening"] * 1000)          # 10 999 characters; 2000 is not between two words
    cut = bounded(words)
    assert len(cut) <= DETAIL_MAX + 2 and cut.endswith(" …")
    assert set(cut[:-2].split(" ")) == {"flattening"}         # no word cut in two
    rest = ": unknown; the daemon's tables are listed by ribbonctl tables list"
    assert bounded(f"table {'x' * 100!r}{rest}") == f"table {'x' * ECHO_MAX + '…'!r}{rest}"
