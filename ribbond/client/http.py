"""``ribbonctl``'s daemon commands: one HTTP client (the standard library's) over the REST API; output for people by
default, ``--json`` for scripts. Nothing here imports the design engine (a command starts in a
fraction of a second, also on a Raspberry Pi).

Jobs: submit, print (a plain G-code program), status, watch, start, pause, resume, cancel,
flip-done, frame-ok, align, accept, re-seat, delete. The printer: printer, frame-ready, home, jog, goto, gcode, heat,
cool, adjust, stop, recover.

Exit status: 0 done; 1 refused (the job's state or the printer does not allow it now, the alignment
is refused, the job failed or was cancelled or interrupted); 2 bad input (a missing or unreadable
file, a value out of range, a program the profile refuses, a missing or wrong API token: the
daemon was reached and refused it); 3 the daemon cannot be reached (or answered an error of its
own); 4 no such job; 130 interrupted (Ctrl-C); 141 the output was closed (``ribbonctl status | head``).
"""

from __future__ import annotations

import argparse
import http.client
import json
import json as _json
import os
import select
import sys
import time
import urllib.parse
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

DEFAULT_URL = "http://127.0.0.1:7125"
ENDED = {"done", "cancelled", "failed", "interrupted"}
#: States that hold the printer: a job in them is followed by ``print`` and ``watch``.
RUNNING = {"heating", "printing_front", "printing_back"}


class ClientError(Exception):
    """A request that did not succeed; ``code`` is the exit status."""

    def __init__(self, message: str, code: int) -> None:
        super().__init__(message)
        self.code = code


class Client:
    """The REST API of one daemon, over the standard library's ``http.client`` (it imports in a
    few milliseconds; a full HTTP client library costs a tenth of a second per command)."""

    def __init__(self, url: str, token: str | None, timeout: float = 30.0) -> None:
        self.url = url.rstrip("/")
        parts = urllib.parse.urlsplit(self.url)
        if parts.scheme not in ("http", "https") or not parts.hostname:
            raise ClientError(f"--url {url!r}: give the daemon's address as http://HOST:PORT", 2)
        self._https = parts.scheme == "https"
        self._host = parts.hostname
        self._port = parts.port
        self._base = parts.path.rstrip("/")
        self.timeout = timeout
        self.headers = {"Authorization": f"Bearer {token}"} if token else {}

    def _connection(self, timeout: float) -> http.client.HTTPConnection:
        cls = http.client.HTTPSConnection if self._https else http.client.HTTPConnection
        return cls(self._host, self._port, timeout=timeout)

    @staticmethod
    def _error(status: int, body: bytes) -> ClientError:
        try:
            detail: Any = json.loads(body).get("detail", body.decode(errors="replace"))
        except (ValueError, AttributeError):
            detail = body.decode(errors="replace").strip() or f"HTTP {status}"
        if isinstance(detail, list):                       # FastAPI's validation errors
            detail = "; ".join(f"{'.'.join(map(str, d.get('loc', [])[1:]))}: {d.get('msg')}" for d in detail)
        code = {401: 2, 404: 4, 409: 1, 413: 2, 422: 2, 503: 1}.get(status, 3)
        return ClientError(f"{detail}" + (f" (HTTP {status})" if code == 3 else ""), code)

    def _refused_token(self) -> ClientError:
        """401: the daemon was reached and refused the token (or its absence): bad input, 2."""
        if self.headers:
            return ClientError(f"the daemon refused the token (HTTP 401): check --token, --token-file or "
                               f"RIBBOND_TOKEN against the daemon's api.token or api.token_file", 2)
        return ClientError("the daemon needs a token (HTTP 401): give --token or --token-file (or set "
                           "RIBBOND_TOKEN)", 2)

    def _send(self, method: str, path: str, params: dict[str, Any] | None, json_body: Any,
              body: Any, headers: dict[str, str], timeout: float | None) -> tuple[http.client.HTTPConnection,
                                                                                  http.client.HTTPResponse]:
        target = self._base + path + (("?" + urllib.parse.urlencode(params, doseq=True)) if params else "")
        head = {**self.headers, **headers}
        if json_body is not None:
            body = json.dumps(json_body).encode()
            head["Content-Type"] = "application/json"
        conn = self._connection(timeout or self.timeout)
        streamed = body is not None and not isinstance(body, (bytes, str))
        try:
            conn.request(method, target, body=_until_answered(conn, body) if streamed else body,
                         headers=head, encode_chunked=streamed)
            return conn, conn.getresponse()
        except (OSError, http.client.HTTPException) as exc:
            answer = _early_answer(conn) if body is not None else None
            if answer is not None:
                return conn, answer
            conn.close()
            raise ClientError(f"cannot reach ribbond at {self.url}: {exc}", 3) from None

    def request(self, method: str, path: str, *, params: dict[str, Any] | None = None, json: Any = None,
                body: Any = None, headers: dict[str, str] | None = None, timeout: float | None = None) -> Any:
        conn, r = self._send(method, path, params, json, body, headers or {}, timeout)
        try:
            data = r.read()
        except (OSError, http.client.HTTPException) as exc:
            raise ClientError(f"lost ribbond at {self.url}: {exc}", 3) from None
        finally:
            conn.close()
        if r.status == 401:
            raise self._refused_token()
        if r.status >= 400:
            raise self._error(r.status, data)
        if r.status == 204:
            return None
        if (r.getheader("content-type") or "").startswith("application/json"):
            return _json.loads(data)
        return data

    def upload(self, field: str, path: Path, data: dict[str, str], show: bool, to: str = "/jobs") -> dict[str, Any]:
        """POST ``to`` (/jobs, /projects) with the file ``path`` as ``field`` (``mesh`` or ``gcode``), streamed."""
        try:
            size = path.stat().st_size
            handle = path.open("rb")
        except OSError as exc:
            raise ClientError(f"{path}: {exc.strerror or exc}", 2) from None
        bar = Bar(f"upload {path.name}", show and sys.stderr.isatty())
        boundary = "ribbonctl-" + os.urandom(8).hex()

        def parts() -> Iterator[bytes]:
            for name, value in data.items():
                yield (f'--{boundary}\r\nContent-Disposition: form-data; name="{name}"\r\n\r\n'
                       f"{value}\r\n").encode()
            filename = path.name.replace('"', "_")
            yield (f'--{boundary}\r\nContent-Disposition: form-data; name="{field}"; filename="{filename}"\r\n'
                   "Content-Type: application/octet-stream\r\n\r\n").encode()
            while chunk := handle.read(1 << 16):
                bar.draw(handle.tell() / size if size else 1.0)
                yield chunk
            yield f"\r\n--{boundary}--\r\n".encode()

        try:
            return self.request("POST", to, body=parts(), timeout=600,  # type: ignore[no-any-return]
                                headers={"Content-Type": f"multipart/form-data; boundary={boundary}"})
        finally:
            handle.close()
            bar.close()

    def events(self) -> Iterator[dict[str, Any]]:
        """Server-sent events, parsed (the daemon sends a keep-alive every 15 s). Subscribed when
        this returns: a state read afterwards misses no change."""
        conn, r = self._send("GET", "/events", None, None, None, {"Accept": "text/event-stream"}, 60.0)
        if r.status >= 400:
            body = r.read()
            conn.close()
            raise self._refused_token() if r.status == 401 else self._error(r.status, body)
        return self._read_events(conn, r)

    def _read_events(self, conn: http.client.HTTPConnection, r: http.client.HTTPResponse) -> Iterator[dict[str, Any]]:
        try:
            data: list[str] = []
            while True:
                try:
                    raw = r.readline()
                except (OSError, http.client.HTTPException) as exc:
                    raise ClientError(f"lost ribbond at {self.url}: {exc}", 3) from None
                if not raw:
                    raise ClientError(f"lost ribbond at {self.url}: the event stream ended", 3)
                line = raw.decode("utf-8", errors="replace").rstrip("\r\n")
                if line.startswith("data:"):
                    data.append(line[5:].strip())
                elif not line and data:
                    yield _json.loads("\n".join(data))
                    data = []
        finally:
            conn.close()


def _until_answered(conn: http.client.HTTPConnection, body: Iterator[bytes]) -> Iterator[bytes]:
    """``body``'s chunks until the daemon answers: an answer before the whole body is sent is a
    refusal (401, 413, ...), read by ``getresponse`` rather than lost to a reset connection."""
    for chunk in body:
        sock = conn.sock
        if sock is not None and select.select([sock], [], [], 0)[0]:
            return
        yield chunk


def _early_answer(conn: http.client.HTTPConnection) -> http.client.HTTPResponse | None:
    """The daemon's answer after sending the body failed (it refused the request and closed the
    connection while the body was still being sent), or None when there is none."""
    try:
        return conn.getresponse()
    except (OSError, http.client.HTTPException):
        return None


# --------------------------------------------------------------------------------------- output


def _clock(seconds: float | None) -> str:
    if seconds is None:
        return "?"
    s = int(round(seconds))
    return f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}" if s >= 3600 else f"{s // 60}:{s % 60:02d}"


class Bar:
    """A one-line progress bar on a terminal (redrawn in place); nothing when ``live`` is False."""

    def __init__(self, label: str, live: bool, stream: Any = None) -> None:
        self.label, self.live = label, live
        self.stream = stream or sys.stderr
        self._shown = False

    def draw(self, fraction: float, text: str = "") -> None:
        if not self.live:
            return
        self.stream.write("\r\x1b[K" + bar_text(fraction, self.label, text))
        self.stream.flush()
        self._shown = True

    def close(self) -> None:
        if self._shown:
            self.stream.write("\r\x1b[K")
            self.stream.flush()
            self._shown = False


def bar_text(fraction: float, label: str = "", text: str = "", width: int = 24) -> str:
    f = min(max(fraction, 0.0), 1.0)
    filled = int(round(f * width))
    return f"{label + '  ' if label else ''}[{'#' * filled}{'.' * (width - filled)}] {100 * f:5.1f}%" \
           + (f"  {text}" if text else "")


def progress_text(info: dict[str, Any], kind: str | None = None) -> str:
    """``front  ribbon 3/8  elapsed 0:12  ETA 0:20`` from a job status or a progress event (of a job
    of ``kind``: a plain G-code job's side is named ``program``, it has no front or back)."""
    if info.get("waiting_for") and info.get("state") not in ENDED:
        # a wait for a person is not progress: what it waits for, no side printing, no time left
        return f"waiting for {info['waiting_for']}"
    parts = []
    side = info.get("print_side") or info.get("side")
    if (kind or info.get("kind")) == "gcode":
        side = "program" if side else None
    if side:
        parts.append(side)
    if info.get("ribbons"):
        parts.append(f"ribbon {info.get('ribbon') or 0}/{info['ribbons']}")
    if info.get("elapsed_s") is not None:
        parts.append(f"elapsed {_clock(info['elapsed_s'])}")
    if info.get("eta_s") is not None and info.get("state", "printing") not in ENDED:
        parts.append(f"ETA {_clock(info['eta_s'])}")
    return "  ".join(parts)


def _line(job: dict[str, Any]) -> str:
    pct = f"{100 * (job.get('progress') or 0):5.1f}%"
    stage = f" [{job['stage']}]" if job.get("stage") else ""
    err = f"  ({job['error']})" if job.get("error") else ""
    runs = f"  run {len(job.get('runs') or []) + 1}" if job.get("runs") else ""
    kind = "  (G-code)" if job.get("kind") == "gcode" else ""
    if job.get("project"):
        kind = f"  panel {job['panel']} of {job['panels']} ({job['project']})"
    state = job["state"]
    if job.get("kind") == "gcode" and state == "printing_front":
        state = "printing"                  # a plain program has no front (--json keeps the state's name)
    return f"{job['id']}  {state:<15} {pct}  {job['mesh_name']}{kind}{runs}{stage}{err}"


def temperatures_text(printer: dict[str, Any] | None) -> str:
    """``nozzle 187/210 °C  bed 55/60 °C`` (actual/target) from a printer status; "" when unknown."""
    heaters = (printer or {}).get("heaters") or {}
    parts = [f"{name} {h['current']:.0f}/{h.get('target') or 0:.0f} °C"
             for key, name in (("T", "nozzle"), ("B", "bed"))
             if isinstance(h := heaters.get(key), dict) and h.get("current") is not None]
    return "  ".join(parts)


#: Job states in which the temperatures are shown with the job (it holds or is about to heat the printer).
HOT = RUNNING | {"paused", "awaiting_check"}


def verdict_text(job: dict[str, Any]) -> list[str]:
    """A design job's verdict lines (``GET /jobs/{id}``'s ``verdict``), labelled as ``ribbonctl
    design`` labels them."""
    return [f"verdict     {line}" for line in job.get("verdict") or []]


def _detail(job: dict[str, Any], printer: dict[str, Any] | None = None, verdict: bool = False,
            notes: bool = False) -> str:
    """A job for people: its line, progress, the temperatures (``printer``: a printer status, while
    the job heats or prints), the design's verdict (``verdict``), the daemon's notes on its program
    (``notes``), what to do next."""
    lines = [_line(job)]
    more = progress_text(job, job.get("kind"))
    if job.get("lines_total") and job["state"] in ("heating", "printing_front", "printing_back", "paused"):
        # last_acked_line counts the lines of ``program`` the printer acknowledged (a resumed side's
        # program is not the whole side: its name says so)
        program = job.get("program") or job.get("side") or "front"
        if job.get("kind") == "gcode":
            program = "program"                 # a plain program has no front
        more = f"{program}: line {max(job.get('last_acked_line', -1), 0)} of {job['lines_total']}" + (
            f"  {more}" if more else "")
    if more:
        lines.append(f"  {bar_text(job.get('progress') or 0)}  {more}")
    if job.get("same_frame"):
        lines.append("  prints on the frame as it is (--same-frame: no fresh frame asked for)")
    temps = temperatures_text(printer) if job["state"] in HOT else ""
    if temps:
        lines.append(f"  temperatures  {temps}  (actual/target)")
    if verdict:
        lines += [f"  {line}" for line in verdict_text(job)]
    lines += [f"  note: {n}" for n in (job.get("notes") or []) if notes]
    nxt = job.get("next") or {}
    if nxt.get("instruction"):
        lines.append(f"  next: {nxt['instruction']}")
    return "\n".join(lines)


def _out(args: argparse.Namespace, obj: Any, text: str) -> None:
    print(json.dumps(obj, indent=1) if args.json else text, flush=True)


def waits(job: dict[str, Any]) -> bool:
    """The job waits for the operator (or its run ended): watching it can stop."""
    return bool(job.get("waits_for_operator")) or job["state"] in ENDED


def _exit_code(job: dict[str, Any]) -> int:
    return 1 if job["state"] in ("failed", "cancelled", "interrupted") else 0


# --------------------------------------------------------------------------------------- commands


def _client(args: argparse.Namespace) -> Client:
    token = args.token or os.environ.get("RIBBOND_TOKEN")
    if token is None and args.token_file:
        try:
            token = Path(args.token_file).read_text(encoding="utf-8").strip()
        except OSError as exc:
            raise ClientError(f"cannot read the token file {args.token_file}: {exc.strerror}", 2) from None
    return Client(args.url or os.environ.get("RIBBOND_URL", DEFAULT_URL), token)


def _wait_compile(c: Client, job_id: str, until: set[str], show: bool) -> dict[str, Any]:
    """Poll the job until its state is in ``until``: a bar over the compile's stages on a
    terminal, one line per stage otherwise."""
    last = None
    bar = Bar("compiling", show and sys.stderr.isatty())
    try:
        while True:
            job = c.request("GET", f"/jobs/{job_id}")
            key = (job["state"], job.get("stage"))
            if bar.live and job["state"] == "compiling":
                bar.draw(job.get("progress") or 0.0, job.get("stage") or "")
            elif show and key != last and not bar.live:
                print(f"{job['state']:<15} {job.get('stage') or ''}", file=sys.stderr, flush=True)
            last = key
            if job["state"] in until:
                return job
            time.sleep(0.3)
    finally:
        bar.close()


def cmd_submit(args: argparse.Namespace) -> int:
    c = _client(args)
    params: dict[str, Any] = {}
    if args.params:
        from ribbond.design.params import load_settings          # only here: it is the engine's reader
        settings = load_settings(args.params)
        params = settings.parameters.model_dump(mode="json", exclude_unset=True)
        solver = settings.solver.model_dump(mode="json", exclude_unset=True)
        if solver:                                        # the daemon applies it (or refuses it)
            params["solver"] = solver
    if args.size is not None:
        params["size"] = {"bbox_diagonal": args.size}
    if args.no_optimize:                                  # the paper's forward design
        params["solver"] = {**params.get("solver", {}), "optimize": False}
    if args.panels is not None:                          # a project: one job per panel (issue 26)
        from .projects import submit_project
        return submit_project(c, args, params)
    job = c.upload("mesh", args.mesh, {"parameters": json.dumps(params), "start": str(args.start).lower()},
                   show=not args.json)
    if args.no_wait:
        _out(args, job, job["id"])
        return 0
    job = _wait_compile(c, job["id"], {"ready", "heating", "printing_front", *ENDED}, show=not args.json)
    if job["state"] in ("failed", "cancelled"):
        _out(args, job, f"job {job['id']} {job['state']}: {job.get('error') or ''}")
        return 1
    design = c.request("GET", f"/jobs/{job['id']}/files/design.json")
    design = json.loads(design) if isinstance(design, (bytes, str)) else design
    r = design["report"]
    rr, pr = r.get("ribbons", {}), r.get("print", {})
    text = "\n".join([
        f"job         {job['id']} ({job['state']})",
        f"design      {r['faces']} faces, {design['parameters']['size']['bbox_diagonal']:.0f} mm, "
        f"{r['iterations']} iterations, {r['time_s']:.1f} s",
        f"ribbons     {rr.get('front', 0)} front, {rr.get('back', 0)} back; "
        f"{len(design.get('registration_marks') or [])} registration marks (numbered from 1 on the preview)",
        f"print       {_print_sides(pr)}",
        f"bounds      σ1 {r['sigma1_bad_pct']:.2f} %, σ2 {r['sigma2_bad_pct']:.2f} % of faces outside",
        *_deployed_lines(r, c.url, job),
        f"preview     {job['design_dir']}/preview.png  ({c.url}/jobs/{job['id']}/files/preview.png)",
        *verdict_text(job),
        f"next        {(job.get('next') or {}).get('instruction', '')}",
    ])
    _out(args, {"job": job, "report": r}, text)
    return 0


def _print_sides(report_print: dict[str, Any]) -> str:
    """``front ~3.2 min, back ~1.0 min``: the sides that have something to print (a one-sided
    design has no back to speak of)."""
    sides = [f"{side} ~{sp.get('time_s', 0) / 60:.1f} min" for side in ("front", "back")
             if (sp := report_print.get(side) or {}).get("lines")]
    return ", ".join(sides) or "nothing to print"


def _deployed_lines(report: dict[str, Any], url: str, job: dict[str, Any]) -> list[str]:
    """The predicted deployed shape's lines of the submit summary (none when it was not predicted)."""
    d = report.get("deployed")
    if not d:
        return []
    from ribbond.design.verdict import deployed_figures          # plain Python: no numpy on the client's path
    return [f"deployed    {deployed_figures(d)}; {url}/jobs/{job['id']}/files/deployed.png"]


def cmd_print(args: argparse.Namespace) -> int:
    c = _client(args)
    job = c.upload("gcode", args.program, {"start": str(not args.no_start).lower(),
                                           "same_frame": str(bool(args.same_frame)).lower()}, show=not args.json)
    if args.no_wait or args.no_start:
        _out(args, job, _detail(job, notes=True) if not args.json else "")
        return 0
    if not args.json:
        for note in job.get("notes") or []:
            print(f"note: {note}", flush=True)
    return _follow(c, args, job)


def cmd_status(args: argparse.Namespace) -> int:
    c = _client(args)
    if args.job:
        job = c.request("GET", f"/jobs/{args.job}")
        printer = c.request("GET", "/printer") if job["state"] in HOT and not args.json else None
        _out(args, job, _detail(job, printer, verdict=True, notes=True))
    else:
        params: dict[str, Any] = {"state": args.state} if args.state else {}
        if args.limit is not None:
            params["limit"] = args.limit
        jobs = c.request("GET", "/jobs", params=params)
        from .projects import active_projects_text
        projects = [] if args.json else active_projects_text(c)
        _out(args, jobs, "\n".join(projects + [_line(j) for j in jobs]) or "no jobs")
    return 0


def _follow(c: Client, args: argparse.Namespace, job: dict[str, Any]) -> int:
    """Follow a job over server-sent events until it waits for the operator or its run ends: a
    bar with the percentage, the side, the ribbon n of N, elapsed and ETA (on a terminal; one line
    per 10 % otherwise), the states as they change, the instructions."""
    job_id = job["id"]
    tty = sys.stdout.isatty() and not args.json
    bar = Bar(job_id, tty, stream=sys.stdout)
    temps = _Temperatures(job, tty and not args.json)
    if job["state"] in HOT and not args.json:
        temps.printer = c.request("GET", "/printer")
    print(json.dumps(job) if args.json else _detail(job, temps.printer), flush=True)
    if waits(job):
        return _exit_code(job)
    events = c.events()
    # the job may have changed between the first GET and the subscription: look once more
    job = c.request("GET", f"/jobs/{job_id}")
    temps.job = job
    state = job["state"]
    if waits(job):
        print(json.dumps(job) if args.json else _detail(job), flush=True)
        return _exit_code(job)
    shown = -1
    try:
        for event in events:
            kind = event.get("type")
            if kind == "job" and event["job"]["id"] == job_id:
                job = event["job"]
                temps.job = job
                if job["state"] != state or waits(job):
                    state = job["state"]
                    bar.close()
                    print(json.dumps(event) if args.json else _detail(job, temps.printer), flush=True)
                    shown = -1
                if waits(job):
                    return _exit_code(job)
            elif kind == "progress" and event.get("job_id") == job_id:
                fraction = event.get("progress") or 0.0
                text = "  ".join(t for t in (progress_text(event, job.get("kind")), temps.text()) if t)
                if args.json:
                    print(json.dumps(event), flush=True)
                elif tty:
                    bar.draw(fraction, text)
                elif int(fraction * 10) > shown:
                    shown = int(fraction * 10)
                    print(f"  {bar_text(fraction)}  {text}", flush=True)
            elif kind == "printer" and not args.json:
                line = temps.update(event.get("printer"))
                if line:
                    print(line, flush=True)
            elif kind == "deleted" and event.get("job_id") == job_id:
                bar.close()
                raise ClientError(f"job {job_id} was deleted", 4)
            elif event.get("job_id") == job_id and kind in ("alignment", "notice"):
                bar.close()
                print(json.dumps(event) if args.json else f"  {event.get('message')}", flush=True)
    finally:
        bar.close()
    return 3


class _Temperatures:
    """What ``watch`` shows of the printer's temperatures: with the progress while the job holds the
    printer, and while it heats a line of its own (on a terminal the line is redrawn in place, else
    one every ``EVERY_S`` seconds)."""

    EVERY_S = 2.0

    def __init__(self, job: dict[str, Any], live: bool) -> None:
        self.job, self.live = job, live
        self.printer: dict[str, Any] | None = None
        self._printed = 0.0

    def text(self) -> str:
        return temperatures_text(self.printer) if self.job["state"] in HOT else ""

    def update(self, printer: dict[str, Any] | None) -> str | None:
        """Take a printer event; the line to print now, if any."""
        self.printer = printer
        if self.job["state"] not in ("heating", "awaiting_check") or not self.text():
            return None
        now = time.monotonic()
        if self.live:
            sys.stdout.write(f"\r\x1b[K  heating  {self.text()}")
            sys.stdout.flush()
            return None
        if now - self._printed < self.EVERY_S:
            return None
        self._printed = now
        return f"  heating  {self.text()}  (actual/target)"


def cmd_watch(args: argparse.Namespace) -> int:
    c = _client(args)
    return _follow(c, args, c.request("GET", f"/jobs/{args.job}"))


def _action(name: str) -> Any:
    def cmd(args: argparse.Namespace) -> int:
        job = _client(args).request("POST", f"/jobs/{args.job}/{name}")
        _out(args, job, _detail(job))
        return 0
    return cmd


def cmd_resume(args: argparse.Namespace) -> int:
    """Resume a paused print, or an interrupted one (``--partial``: the part begun and not proven)."""
    body = {"partial": args.partial} if args.partial else None
    job = _client(args).request("POST", f"/jobs/{args.job}/resume", json=body)
    _out(args, job, _detail(job))
    return 0


def cmd_frame_ok(args: argparse.Namespace) -> int:
    job = _client(args).request("POST", f"/jobs/{args.job}/frame-ok",
                                json={"keep_alignment": bool(args.keep_alignment)})
    _out(args, job, _detail(job))
    return 0


def cmd_delete(args: argparse.Namespace) -> int:
    c = _client(args)
    for job in args.job:
        c.request("DELETE", f"/jobs/{job}")
        if not args.json:
            print(f"job {job} deleted", flush=True)
    if args.json:
        print(json.dumps({"deleted": args.job}))
    return 0


def _align_text(status: dict[str, Any]) -> str:
    got = f"mark {status['mark']} of {status['marks']}: offset ({status['offset'][0]:+.3f}, " \
          f"{status['offset'][1]:+.3f}) mm from where it was expected"
    if status.get("next_mark") is not None:
        return f"{got}; the head is now above mark {status['next_mark']}: jog it onto the mark, then align --here"
    fit = status.get("fit", {})
    return (f"{got}\nfit: rotation {fit.get('rotation_deg', 0):+.3f}°, offset ({fit.get('offset', [0, 0])[0]:+.3f}, "
            f"{fit.get('offset', [0, 0])[1]:+.3f}) mm, residual {fit.get('max_residual_mm', 0):.3f} mm: "
            + ("accepted, printing the back" if status.get("accepted") else
               "within the limits; accept it (ribbonctl accept JOB) or re-seat the frame (ribbonctl re-seat JOB)"
               if status.get("review") else "refused"))


def cmd_align(args: argparse.Namespace) -> int:
    c = _client(args)
    if args.here or args.jog is not None or args.mark is not None:
        if args.jog is None and not args.here and args.mark is not None:
            raise ClientError("--mark needs --jog DX DY (or use --here: the nozzle is on the mark)", 2)
        body: dict[str, Any] = {"here": bool(args.here), "jog": list(args.jog) if args.jog else None,
                                "review": bool(args.review)}
        if args.mark is not None:
            body["mark"] = args.mark
        status = c.request("POST", f"/jobs/{args.job}/align", json=body)
        _out(args, status, _align_text(status).replace("JOB", args.job))
        return 0
    job = c.request("GET", f"/jobs/{args.job}")
    if job["state"] != "aligning":
        raise ClientError(f"cannot align: job {args.job} is {job['state']}; "
                          + (job.get("next") or {}).get("instruction", ""), 1)
    shown = None
    while True:                                          # interactive: jog, then Enter, per mark
        job = c.request("GET", f"/jobs/{args.job}")
        instruction = (job.get("next") or {}).get("instruction", "")
        if instruction != shown:
            print(instruction.split(". Jog")[0] + ". Jog the nozzle onto the mark here:")
            shown = instruction
        try:
            answer = input("jog 'dx dy [dz]' (mm), Enter when the nozzle is on the mark: ").split()
        except EOFError:
            raise ClientError("no more input: the alignment goes on where it is (ribbonctl align "
                              f"{args.job} --here, or run ribbonctl align {args.job} again)", 2) from None
        if answer:
            try:
                d = [float(v) for v in answer]
                if len(d) not in (2, 3):
                    raise ValueError
            except ValueError:
                print("  two or three numbers, e.g. 0.3 -0.2, or Enter", file=sys.stderr)
                continue
            try:
                moved = c.request("POST", "/printer/jog", json={"dx": d[0], "dy": d[1],
                                                                "dz": d[2] if len(d) == 3 else 0})
                print(f"  {_position(moved)}")
            except ClientError as exc:
                print(f"  {exc}", file=sys.stderr)
            continue
        status = c.request("POST", f"/jobs/{args.job}/align", json={"here": True, "review": bool(args.review)})
        print(_align_text(status).replace("JOB", args.job))
        if status.get("next_mark") is None:
            return 0


def _printer_text(status: dict[str, Any]) -> str:
    heaters = ", ".join(f"{k} {v['current']:.0f}/{v.get('target') or 0:.0f} °C"
                        for k, v in (status.get("heaters") or {}).items())
    where = _head_text(status.get("head") or status.get("position"), status.get("homed"), 2)
    note = status.get("note") or ""
    return "  ".join(p for p in (status.get("state"), status.get("firmware") or "", heaters, _factors_text(status),
                                 where, note, _frame_text(status.get("frame"))) if p)


def _frame_text(frame: dict[str, Any] | None) -> str:
    """``frame fresh`` / ``frame used (job J)``, and the job waiting for a fresh one."""
    if not frame:
        return ""
    text = f"frame {frame['state']}" + (f" (job {frame['job_id']})" if frame.get("job_id") else "")
    if frame.get("waiting_job"):
        text += f"; job {frame['waiting_job']} waits for a fresh frame: ribbonctl frame-ready"
    return text


def cmd_frame_ready(args: argparse.Namespace) -> int:
    """A fresh stretched frame is loaded: the job waiting for it goes on."""
    frame = _client(args).request("POST", "/printer/frame-ready")
    _out(args, frame, _frame_text(frame))
    return 0


def cmd_printer(args: argparse.Namespace) -> int:
    status = _client(args).request("GET", "/printer", params={"refresh": "true"})
    _out(args, status, _printer_text(status))
    return 0


def _head_text(pos: list[float] | None, homed: list[str] | None, digits: int) -> str:
    """``head at x 10.00 y 20.00 z 5.00``; an axis not homed (``homed``: the axes that are; None
    from an older daemon: every one) says so, as Mainsail does: its number means nothing."""
    if not pos and not (homed is not None and len(homed) < 3):
        return ""
    axes = [f"{a} not homed" if homed is not None and a not in homed else
            f"{a} {pos[i]:.{digits}f}" if pos else f"{a} ?" for i, a in enumerate("xyz")]
    return "head at " + " ".join(axes)


def _position(status: dict[str, Any]) -> str:
    return _head_text(status.get("position"), status.get("homed"), 3) or "done"


def cmd_home(args: argparse.Namespace) -> int:
    status = _client(args).request("POST", "/printer/home", timeout=330)
    _out(args, status, _position(status))
    return 0


def cmd_jog(args: argparse.Namespace) -> int:
    status = _client(args).request("POST", "/printer/jog", json={"dx": args.dx, "dy": args.dy, "dz": args.dz},
                                   timeout=330)
    _out(args, status, _position(status))
    return 0


def cmd_goto(args: argparse.Namespace) -> int:
    status = _client(args).request("POST", "/printer/goto", json={"x": args.x, "y": args.y}, timeout=330)
    _out(args, status, _position(status))
    return 0


def cmd_gcode(args: argparse.Namespace) -> int:
    result = _client(args).request("POST", "/printer/gcode", json={"commands": args.commands}, timeout=630)
    text = "\n".join(f"> {a['command']}" + (f"  (sent as: {a['sent']})" if a.get("sent") else "") + "\n"
                     + "\n".join(a["answer"]) for a in result["answers"])
    text += "".join(f"\nnote: {n}" for n in result.get("notes") or [])
    _out(args, result, text)
    return 0


def cmd_heat(args: argparse.Namespace) -> int:
    status = _client(args).request("POST", "/printer/heat", json={"nozzle": args.nozzle, "bed": args.bed})
    _out(args, status, _printer_text(status))
    return 0


def _factors_text(status: dict[str, Any]) -> str:
    """``speed 80 %  flow 105 %``, as the printer last reported them (M220, M221), or nothing."""
    parts = [f"{name} {status[key]:g} %" for name, key in (("speed", "speed_percent"), ("flow", "flow_percent"))
             if status.get(key) is not None]
    return "  ".join(parts)


def cmd_adjust(args: argparse.Namespace) -> int:
    """Adjust the print in progress (or the printer between prints): speed, flow, nozzle, bed."""
    given = {"speed": args.speed, "flow": args.flow, "nozzle": args.nozzle, "bed": args.bed}
    body = {k: v for k, v in given.items() if v is not None}        # a field is a number or left out
    if not body:
        print("ribbonctl adjust: give --speed, --flow, --nozzle and/or --bed", file=sys.stderr)
        return 2
    result = _client(args).request("POST", "/printer/adjust", json=body, timeout=330)
    sent = ", ".join(a["command"] for a in result["answers"])
    where = f" beside job {result['printing']}'s program" if result.get("printing") else ""
    printer = result.get("printer") or {}
    _out(args, result, f"sent {sent}{where}\n{_printer_text(printer)}")
    return 0


def cmd_cool(args: argparse.Namespace) -> int:
    status = _client(args).request("POST", "/printer/cool")
    _out(args, status, _printer_text(status))
    return 0


def cmd_stop(args: argparse.Namespace) -> int:
    status = _client(args).request("POST", "/printer/emergency-stop")
    _out(args, status, f"emergency stop sent; printer {status.get('state')} (ribbonctl recover restarts it)")
    return 0


def cmd_recover(args: argparse.Namespace) -> int:
    status = _client(args).request("POST", "/printer/recover", timeout=60)
    _out(args, status, "recovered: " + _printer_text(status))
    return 0


def cmd_tables(args: argparse.Namespace) -> int:
    """ribbonctl tables list|show NAME|add FILE|remove NAME (the daemon's curvature tables)."""
    c = _client(args)
    if args.action == "list":
        tables = c.request("GET", "/tables")
        _out(args, tables, "\n".join(f"{t['name']:<28} {t['source']:<8} s = {t.get('prestretch', '?')}  "
                                      f"{t.get('material', '')} on {t.get('fabric', '') or '?'}" for t in tables))
    elif args.action == "show":
        if not args.arg:
            raise ClientError("tables show NAME: which table?", 2)
        t = c.request("GET", f"/tables/{urllib.parse.quote(args.arg, safe='')}")
        rows = [f"{t['name']} ({t['source']}): {t.get('description', '')}",
                f"prestretch {t['prestretch']}, material {t.get('material') or '?'}, fabric {t.get('fabric') or '?'}",
                "τ \\ μ2  " + " ".join(f"{m:>8g}" for m in t["spacing"])]
        for side in ("front", "back"):
            rows.append(f"{side}:")
            rows += [f"{tau:>7g}  " + " ".join(f"{v:>8.4g}" for v in row) for tau, row in zip(t["thickness"], t[side])]
        _out(args, t, "\n".join(rows))
    elif args.action == "add":
        if not args.arg:
            raise ClientError("tables add FILE: which file?", 2)
        try:
            text = Path(args.arg).read_text(encoding="utf-8")
        except OSError as exc:
            raise ClientError(f"{args.arg}: {exc.strerror or exc}", 2) from None
        t = c.request("POST", "/tables", json={"toml": text})
        _out(args, t, f"added table {t['name']!r}: designs use it with curvature_table = \"{t['name']}\"")
    else:
        if not args.arg:
            raise ClientError("tables remove NAME: which table?", 2)
        c.request("DELETE", f"/tables/{urllib.parse.quote(args.arg, safe='')}")
        _out(args, {"removed": args.arg}, f"removed table {args.arg!r}")
    return 0


def calibrate_remote(args: argparse.Namespace, spec: dict[str, Any]) -> int:
    """ribbonctl calibrate plan without -o: the daemon makes the plan, one job per sheet."""
    c = _client(args)
    r = c.request("POST", "/calibrations", json={**spec, "start": bool(getattr(args, "start", False))})
    if not args.json:
        print(f"calibration {r['calibration']}: making the plan on the daemon …", file=sys.stderr, flush=True)
    while r["state"] == "planning":                      # made in the planner's process, as a compile is
        time.sleep(0.5)
        r = c.request("GET", f"/calibrations/{r['calibration']}")
    if r["state"] == "failed":
        raise ClientError(f"calibration {r['calibration']}: {r['error']}", 1)
    base = c.url.rstrip("/")
    text = (f"calibration {r['calibration']}: {r['coupons']} coupons on {r['sheets']} sheet(s), one job per sheet: "
            f"{', '.join(r['jobs'])}\n  coupons: {base}/calibrations/{r['calibration']}/files/coupons.csv\n"
            f"  sheet maps: {base}/calibrations/{r['calibration']}/files/sheet-1.png …\n"
            f"  print each sheet: ribbonctl start JOB (a new fabric each); then measure and run\n"
            f"  ribbonctl calibrate record {r['calibration']} measurements.csv --add NAME")
    _out(args, r, text)
    return 0


def fetch_plan(args: argparse.Namespace, ident: str) -> Any:
    """``plan.json`` of a daemon calibration, by its id or the id of one of its jobs."""
    c = _client(args)
    if not ident.startswith("cal-"):
        job = c.request("GET", f"/jobs/{urllib.parse.quote(ident, safe='')}")
        ident = (job.get("parameters") or {}).get("calibration") or ""
        if not ident:
            raise ClientError(f"job {job['id']} is not a calibration job", 2)
    return c.request("GET", f"/calibrations/{ident}/files/plan.json")


def add_table_text(args: argparse.Namespace, text: str) -> dict[str, Any]:
    return _client(args).request("POST", "/tables", json={"toml": text})


# --------------------------------------------------------------------------------------- parser


def add_global_options(parser: argparse.ArgumentParser, *, in_subcommand: bool) -> None:
    """--url, --token, --token-file, --json: before the subcommand (``in_subcommand`` False) or
    after it (the defaults are then left to the main parser, so either place works)."""
    keep = {"default": argparse.SUPPRESS} if in_subcommand else {}
    parser.add_argument("--url", help=f"the daemon (default $RIBBOND_URL or {DEFAULT_URL})",
                        **({"default": None} | keep))
    parser.add_argument("--token", help="API token (default $RIBBOND_TOKEN)", **({"default": None} | keep))
    parser.add_argument("--token-file", type=Path, help="file holding the API token",
                        **({"default": None} | keep))
    parser.add_argument("--json", action="store_true", help="plain JSON output for scripts",
                        **({"default": False} | keep))


#: Adds one command: ``cmd(name, help, func, description=None)`` -> its parser.
Command = Callable[..., argparse.ArgumentParser]


def add_commands(sub: Any) -> None:
    """Add the daemon commands to ``ribbonctl``'s subparsers (in the order ``--help`` lists them)."""
    common = argparse.ArgumentParser(add_help=False)
    add_global_options(common, in_subcommand=True)

    def cmd(name: str, help: str, func: Any, description: str | None = None) -> argparse.ArgumentParser:
        p = sub.add_parser(name, parents=[common], help=help, description=description or help)
        p.set_defaults(func=func)
        return p

    for add in (_job_commands, _run_commands, _alignment_commands, _printer_commands, _table_commands):
        add(cmd)
    from .projects import add_project_commands
    add_project_commands(sub, common)
    from .notify import add_notify_commands
    add_notify_commands(sub, common)


def _job_commands(cmd: Command) -> None:
    """submit, print, status, watch: a job in and what it is doing."""
    s = cmd("submit", "upload a mesh to the daemon and compile it", cmd_submit)
    s.add_argument("mesh", type=Path)
    s.add_argument("--size", type=float, metavar="MM", help="bounding-box diagonal of the target, mm")
    s.add_argument("--params", type=Path, metavar="FILE",
                   help="TOML or JSON design parameters (and an optional [solver] table, applied by the daemon)")
    s.add_argument("--start", action="store_true", help="print as soon as it is compiled")
    s.add_argument("--panels", metavar="auto|N", help="print it in panels: a project, compiled once, one "
                   "two-sided job per panel in order (auto: as few as flatten within bounds and fit the frame)")
    s.add_argument("--seam-allowance", type=float, default=6.0, metavar="MM",
                   help="with --panels: fabric left around each panel for its seams (default 6 mm)")
    s.add_argument("--no-wait", action="store_true", help="print the job id and return at once")
    s.add_argument("--no-optimize", action="store_true", help="the paper's forward design: the layout not "
                   "optimized against the prediction (the job's [solver] optimize = false)")
    p = cmd("print", "print a plain G-code file through the daemon", cmd_print,
            "Upload a G-code program, checked line by line against the printer profile (frame, feeds, "
            "temperatures), and print it; follows the job like watch.")
    p.add_argument("program", type=Path, help="a .gcode file")
    p.add_argument("--no-start", action="store_true", help="upload and check only (start it later)")
    p.add_argument("--no-wait", action="store_true", help="return once it is queued")
    p.add_argument("--same-frame", action="store_true", help="it prints on the frame as it is: no fresh frame "
                   "is asked for before it (every design needs one)")
    st = cmd("status", "list the jobs, or show one with its progress and what to do next", cmd_status)
    st.add_argument("job", nargs="?")
    st.add_argument("--state", action="append", metavar="STATE", help="only jobs in this state (repeatable)")
    st.add_argument("--limit", type=int, metavar="N", help="at most N jobs (newest first)")
    w = cmd("watch", "follow a job (progress bar) until it waits for you or ends", cmd_watch)
    w.add_argument("job")


def _run_commands(cmd: Command) -> None:
    """start, pause, cancel, flip-done, accept, re-seat, resume, frame-ok, delete: a job's run."""
    for name, text in (("start", "print a job (again: a new run of the same design)"), ("pause", "pause a print"),
                       ("cancel", "cancel a job"),
                       ("flip-done", "the frame is turned over: go on to the alignment"),
                       ("accept", "print the back with the alignment's fit (after align --review)"),
                       ("re-seat", "refuse the alignment's fit: seat the frame again (back side up), measure every mark again")):
        a = cmd(name, text, _action(name))
        a.add_argument("job")
    r = cmd("resume", "resume a paused print, or an interrupted one where it was proven to stand", cmd_resume,
            "Paused: reheat and go on. Interrupted (daemon crash, power cut, lost USB): home, heat, wait for "
            "frame-ok, then print the side it stood on from the first ribbon not proven printed.")
    r.add_argument("job")
    r.add_argument("--partial", choices=("skip", "reprint"),
                   help="interrupted: the ribbon begun and not proven printed is skipped (default: a second "
                        "bead over a printed one is worse than a gap) or printed again")
    f = cmd("frame-ok", "a resumed print: the frame is checked, go on", cmd_frame_ok)
    f.add_argument("job")
    f.add_argument("--keep-alignment", action="store_true",
                   help="the back was being printed and the frame was not moved: keep the stored alignment "
                        "instead of measuring the marks again")
    d = cmd("delete", "remove jobs and their files (not while they print)", cmd_delete)
    d.add_argument("job", nargs="+")


def _alignment_commands(cmd: Command) -> None:
    """align: the registration marks after the flip."""
    a = cmd("align", "the alignment check after the flip: jog onto each mark, then --here", cmd_align,
            "Without options: interactive (type jogs, Enter when the nozzle is on the mark). --here: the "
            "nozzle is over the mark now. --mark N --jog DX DY: report a jog made another way.")
    a.add_argument("job")
    a.add_argument("--here", action="store_true", help="the nozzle is over the mark now")
    a.add_argument("--mark", type=int, metavar="N", help="the mark, numbered from 1 (default: the current one)")
    a.add_argument("--jog", type=float, nargs=2, metavar=("DX", "DY"), help="the mark's offset from where the "
                   "head was sent, mm")
    a.add_argument("--review", action="store_true", help="after the last mark, show the fit and wait for "
                   "ribbonctl accept or re-seat (default: an accepted fit prints the back at once)")


def _printer_commands(cmd: Command) -> None:
    """The printer and its frame, and manual control."""
    cmd("printer", "the printer's state, temperatures, head position and frame (fresh or used)", cmd_printer)
    cmd("frame-ready", "a fresh stretched frame is loaded: the job waiting for it goes on", cmd_frame_ready)
    cmd("home", "home the axes (G28)", cmd_home)
    j = cmd("jog", "move the head by DX DY [DZ] mm (within the frame)", cmd_jog)
    j.add_argument("dx", type=float)
    j.add_argument("dy", type=float)
    j.add_argument("dz", type=float, nargs="?", default=0.0)
    g = cmd("goto", "move the head to X Y (machine mm, within the frame)", cmd_goto)
    g.add_argument("x", type=float)
    g.add_argument("y", type=float)
    gc = cmd("gcode", "send G-code commands and print the printer's answers", cmd_gcode,
             "Send one command or a short list (one argument each, quoted: ribbonctl gcode \"G28 X\" M114). "
             "While a program streams only M220, M221, M104, M140 (within the profile's limits), M105 and M114 "
             "are accepted (ribbonctl adjust). Checked whole as a G-code job is (frame, fabric, temperatures; "
             "feed rates clamped, said in a note) before anything is sent; moves start from where home, "
             "jog or goto left the head, in absolute positioning (G90).")
    gc.add_argument("commands", nargs="+", metavar="COMMAND")
    h = cmd("heat", "heat the nozzle (default: the profile's temperature) and/or the bed", cmd_heat)
    h.add_argument("--nozzle", type=float, metavar="C")
    h.add_argument("--bed", type=float, metavar="C")
    cmd("cool", "heaters off", cmd_cool)
    a = cmd("adjust", "adjust a print in progress: speed (M220), flow (M221), nozzle, bed", cmd_adjust,
            "Change the feed override, the flow and the heater targets, also while a job prints (OctoPrint's "
            "and Mainsail's controls). The values are checked against the printer profile's [adjust] ranges "
            "and temperature limits (while printing the nozzle stays at or above adjust.nozzle_min); the "
            "printer reports back the speed and flow it now runs with.")
    a.add_argument("--speed", type=float, metavar="PCT", help="feed override, %% (M220 S)")
    a.add_argument("--flow", type=float, metavar="PCT", help="flow, %% (M221 S)")
    a.add_argument("--nozzle", type=float, metavar="C", help="nozzle target, °C (M104 S)")
    a.add_argument("--bed", type=float, metavar="C", help="bed target, °C (M140 S)")
    cmd("stop", "emergency stop (M112)", cmd_stop)
    cmd("recover", "after an emergency stop or a halt: restart the firmware (M999)", cmd_recover)


def _table_commands(cmd: Command) -> None:
    """tables: the daemon's curvature tables."""
    t = cmd("tables", "the daemon's curvature tables: list, show NAME, add FILE, remove NAME", cmd_tables)
    t.add_argument("action", choices=("list", "show", "add", "remove"))
    t.add_argument("arg", nargs="?", help="NAME (show, remove) or FILE (add)")
