"""``ribbonctl``'s daemon commands: submit, status, watch, start, pause, resume, cancel, flip-done,
align, printer, stop. One HTTP client (httpx) over the REST API; output for people by default,
``--json`` for scripts.

Exit status: 0 done; 1 the daemon refused (the job's state does not allow it, alignment refused,
the job failed); 2 bad input; 3 the daemon cannot be reached or answered an error; 4 no such job;
130 interrupted.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
from tqdm import tqdm

DEFAULT_URL = "http://127.0.0.1:7125"
TERMINAL = {"done", "cancelled", "failed", "interrupted"}


class ClientError(Exception):
    """A request that did not succeed; ``code`` is the exit status."""

    def __init__(self, message: str, code: int) -> None:
        super().__init__(message)
        self.code = code


class Client:
    """The REST API of one daemon."""

    def __init__(self, url: str, token: str | None, timeout: float = 30.0) -> None:
        headers = {"Authorization": f"Bearer {token}"} if token else {}
        self.url = url.rstrip("/")
        self.http = httpx.Client(base_url=self.url, headers=headers, timeout=timeout)

    def _check(self, r: httpx.Response) -> Any:
        if r.status_code < 400:
            return r.json() if r.headers.get("content-type", "").startswith("application/json") else r.content
        try:
            detail = r.json().get("detail", r.text)
        except ValueError:
            detail = r.text
        if isinstance(detail, list):                       # FastAPI's validation errors
            detail = "; ".join(f"{'.'.join(map(str, d.get('loc', [])))}: {d.get('msg')}" for d in detail)
        code = {404: 4, 409: 1, 413: 2, 422: 2, 401: 3}.get(r.status_code, 3)
        raise ClientError(f"{detail}" + (f" (HTTP {r.status_code})" if code == 3 else ""), code)

    def request(self, method: str, path: str, **kw: Any) -> Any:
        try:
            return self._check(self.http.request(method, path, **kw))
        except httpx.TransportError as exc:
            raise ClientError(f"cannot reach ribbond at {self.url}: {exc}", 3) from None

    def submit(self, mesh: Path, parameters: dict[str, Any], start: bool, show: bool) -> dict[str, Any]:
        size = mesh.stat().st_size
        bar = tqdm(total=size, unit="B", unit_scale=True, desc=f"upload {mesh.name}", file=sys.stderr,
                   disable=not (show and sys.stderr.isatty()), leave=False)

        class Reader:                                       # a file that reports what was read
            def __init__(self, f: Any) -> None:
                self.f = f

            def read(self, n: int = -1) -> bytes:
                data = self.f.read(n)
                bar.update(len(data))
                return data

        try:
            with mesh.open("rb") as f:
                return self.request("POST", "/jobs", files={"mesh": (mesh.name, Reader(f))},  # type: ignore[dict-item]
                                    data={"parameters": json.dumps(parameters), "start": str(start).lower()},
                                    timeout=600)
        finally:
            bar.close()

    def events(self) -> Iterator[dict[str, Any]]:
        """Server-sent events, parsed."""
        try:
            with self.http.stream("GET", "/events", timeout=httpx.Timeout(30.0, read=60.0)) as r:
                if r.status_code >= 400:
                    r.read()
                    self._check(r)
                data: list[str] = []
                for line in r.iter_lines():
                    if line.startswith("data:"):
                        data.append(line[5:].strip())
                    elif not line and data:
                        yield json.loads("\n".join(data))
                        data = []
        except httpx.TransportError as exc:
            raise ClientError(f"lost ribbond at {self.url}: {exc}", 3) from None


# ---------------------------------------------------------------------------------------------


def _client(args: argparse.Namespace) -> Client:
    token = args.token or os.environ.get("RIBBOND_TOKEN")
    if token is None and args.token_file:
        try:
            token = Path(args.token_file).read_text(encoding="utf-8").strip()
        except OSError as exc:
            raise ClientError(f"cannot read the token file {args.token_file}: {exc.strerror}", 2) from None
    return Client(args.url or os.environ.get("RIBBOND_URL", DEFAULT_URL), token)


def _line(job: dict[str, Any]) -> str:
    progress = ""
    if job.get("lines_total"):
        progress = f"  line {max(job.get('last_acked_line', -1), 0)} of {job['lines_total']}"
    err = f"  ({job['error']})" if job.get("error") else ""
    if job.get("eta_s") is not None:
        progress += f", ~{job['eta_s'] / 60:.1f} min left"
    stage = f" [{job['stage']}]" if job.get("stage") else ""
    return f"{job['id']}  {job['state']:<15}{stage}  {job['mesh_name']}{progress}{err}"


def _out(args: argparse.Namespace, obj: Any, text: str) -> None:
    print(json.dumps(obj, indent=1) if args.json else text)


#: The compile's stages in order (``ribbond.design.pipeline``), for the progress bar.
COMPILE_STAGES = ("load", "curvature", "flatten", "stripes", "ribbons", "gcode", "preview", "write")


def _wait(c: Client, job_id: str, until: set[str], show: bool) -> dict[str, Any]:
    """Poll the job until its state is in ``until``: a progress bar over the compile's stages and
    the printed lines on a terminal, one line per stage otherwise."""
    last = None
    bar: tqdm | None = None
    tty = show and sys.stderr.isatty()
    try:
        while True:
            job = c.request("GET", f"/jobs/{job_id}")
            key = (job["state"], job.get("stage"))
            if tty and job["state"] == "compiling":
                if bar is None:
                    bar = tqdm(total=len(COMPILE_STAGES), desc="compiling", unit="stage", file=sys.stderr,
                               leave=False)
                stage = job.get("stage")
                if stage in COMPILE_STAGES:
                    bar.n = COMPILE_STAGES.index(stage)
                    bar.set_postfix_str(stage, refresh=False)
                    bar.refresh()
                last = key
            elif show and key != last:
                if bar is not None:
                    bar.close()
                    bar = None
                print(f"{job['state']:<15} {job.get('stage') or ''}", file=sys.stderr, flush=True)
                last = key
            if tty and job.get("lines_total") and job["state"].startswith("printing"):
                if bar is None:
                    bar = tqdm(total=job["lines_total"], unit="line", desc=job["state"], file=sys.stderr,
                               leave=False)
                bar.n = max(job.get("last_acked_line", 0), 0)
                bar.refresh()
            if job["state"] in until:
                return job
            time.sleep(0.5)
    finally:
        if bar is not None:
            bar.close()


def cmd_submit(args: argparse.Namespace) -> int:
    c = _client(args)
    params: dict[str, Any] = {}
    if args.params:
        from .design.params import load_settings
        params = load_settings(args.params).parameters.model_dump(mode="json", exclude_unset=True)
    if args.size is not None:
        params["size"] = {"bbox_diagonal": args.size}
    job = c.submit(args.mesh, params, args.start, show=not args.json)
    if args.no_wait:
        _out(args, job, job["id"])
        return 0
    job = _wait(c, job["id"], {"ready", "heating", "printing_front", *TERMINAL}, show=not args.json)
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
        f"ribbons     {rr.get('front', 0)} front, {rr.get('back', 0)} back",
        f"print       front ~{pr.get('front', {}).get('time_s', 0) / 60:.1f} min, back "
        f"~{pr.get('back', {}).get('time_s', 0) / 60:.1f} min",
        f"bounds      σ1 {r['sigma1_bad_pct']:.2f} %, σ2 {r['sigma2_bad_pct']:.2f} % of faces outside",
        f"preview     {job['design_dir']}/preview.png  ({c.url}/jobs/{job['id']}/files/preview.png)",
    ])
    _out(args, {"job": job, "report": r}, text)
    return 0


def cmd_status(args: argparse.Namespace) -> int:
    c = _client(args)
    if args.job:
        job = c.request("GET", f"/jobs/{args.job}")
        _out(args, job, _line(job))
    else:
        jobs = c.request("GET", "/jobs")
        _out(args, jobs, "\n".join(_line(j) for j in jobs) or "no jobs")
    return 0


def cmd_watch(args: argparse.Namespace) -> int:
    c = _client(args)
    job = c.request("GET", f"/jobs/{args.job}")
    print(_line(job), flush=True)
    if job["state"] in TERMINAL:
        return 0 if job["state"] == "done" else 1
    for event in c.events():
        if event.get("type") == "job" and event["job"]["id"] == args.job:
            job = event["job"]
            print(json.dumps(event) if args.json else _line(job), flush=True)
            if job["state"] in TERMINAL:
                return 0 if job["state"] == "done" else 1
        elif event.get("job_id") == args.job and event.get("type") in ("alignment", "notice"):
            print(json.dumps(event) if args.json else f"  {event.get('message')}", flush=True)
    return 3


def _action(name: str) -> Any:
    def cmd(args: argparse.Namespace) -> int:
        job = _client(args).request("POST", f"/jobs/{args.job}/{name}")
        _out(args, job, _line(job))
        return 0
    return cmd


def cmd_align(args: argparse.Namespace) -> int:
    c = _client(args)
    job = c.request("GET", f"/jobs/{args.job}")
    if args.mark is not None:
        status = c.request("POST", f"/jobs/{args.job}/align",
                           json={"mark": args.mark, "jog": list(args.jog) if args.jog else None})
        _out(args, status, _align_text(status))
        return 0 if status.get("accepted", True) else 1
    if job["state"] != "aligning":
        raise ClientError(f"job {args.job} is {job['state']}, not aligning: flip the frame and run "
                          f"'ribbonctl flip-done {args.job}' first", 1)
    design = c.request("GET", f"/jobs/{args.job}/files/design.json")
    marks = (json.loads(design) if isinstance(design, (bytes, str)) else design)["registration_marks"]
    mark = 0
    while mark is not None:
        answer = input(f"mark {mark + 1} of {len(marks)}: the head is above where it should be. "
                       "Enter if it is on the mark, or the jog 'dx dy' (mm) that put it there: ").split()
        try:
            jog = [float(v) for v in answer] if answer else None
        except ValueError:
            print("  two numbers, e.g. 0.3 -0.2, or Enter", file=sys.stderr)
            continue
        if jog is not None and len(jog) != 2:
            print("  two numbers, e.g. 0.3 -0.2, or Enter", file=sys.stderr)
            continue
        status = c.request("POST", f"/jobs/{args.job}/align", json={"mark": mark, "jog": jog})
        mark = status.get("next_mark")
    print(_align_text(status))
    return 0 if status.get("accepted") else 1


def _align_text(status: dict[str, Any]) -> str:
    if status.get("next_mark") is not None:
        return f"recorded; next: mark {status['next_mark'] + 1} of {status['marks']}"
    fit = status.get("fit", {})
    return (f"fit: rotation {fit.get('rotation_deg', 0):+.3f}°, offset ({fit.get('offset', [0, 0])[0]:+.3f}, "
            f"{fit.get('offset', [0, 0])[1]:+.3f}) mm, residual {fit.get('max_residual_mm', 0):.3f} mm: "
            + ("accepted, printing the back" if status.get("accepted") else f"refused: {status.get('refused')}"))


def cmd_printer(args: argparse.Namespace) -> int:
    status = _client(args).request("GET", "/printer", params={"refresh": "true"})
    heaters = ", ".join(f"{k} {v['current']:.0f}/{v.get('target') or 0:.0f} °C" for k, v in status.get("heaters", {}).items())
    _out(args, status, f"{status.get('state')}  {status.get('firmware') or ''}  {heaters}  "
                       f"position {status.get('position')}")
    return 0


def cmd_stop(args: argparse.Namespace) -> int:
    status = _client(args).request("POST", "/printer/emergency-stop")
    _out(args, status, f"emergency stop sent; printer {status.get('state')}")
    return 0


def add_commands(sub: Any) -> None:
    """Add the daemon commands to ``ribbonctl``'s subparsers."""
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--url", help=f"the daemon (default $RIBBOND_URL or {DEFAULT_URL})")
    common.add_argument("--token", help="API token (default $RIBBOND_TOKEN)")
    common.add_argument("--token-file", type=Path, help="file holding the API token")
    common.add_argument("--json", action="store_true", help="plain JSON output for scripts")

    s = sub.add_parser("submit", parents=[common], help="upload a mesh to the daemon and compile it")
    s.add_argument("mesh", type=Path)
    s.add_argument("--size", type=float, metavar="MM", help="bounding-box diagonal of the target, mm")
    s.add_argument("--params", type=Path, metavar="FILE", help="TOML or JSON design parameters")
    s.add_argument("--start", action="store_true", help="print as soon as it is compiled")
    s.add_argument("--no-wait", action="store_true", help="print the job id and return at once")
    s.set_defaults(func=cmd_submit)
    st = sub.add_parser("status", parents=[common], help="list the jobs, or show one")
    st.add_argument("job", nargs="?")
    st.set_defaults(func=cmd_status)
    w = sub.add_parser("watch", parents=[common], help="follow a job until it ends")
    w.add_argument("job")
    w.set_defaults(func=cmd_watch)
    for name in ("start", "pause", "resume", "cancel", "flip-done"):
        p = sub.add_parser(name, parents=[common], help=f"{name} a job")
        p.add_argument("job")
        p.set_defaults(func=_action(name))
    a = sub.add_parser("align", parents=[common], help="the alignment check after the flip (interactive)")
    a.add_argument("job")
    a.add_argument("--mark", type=int, help="report one mark (0-based) instead of asking")
    a.add_argument("--jog", type=float, nargs=2, metavar=("DX", "DY"), help="with --mark: the jog, mm")
    a.set_defaults(func=cmd_align)
    pr = sub.add_parser("printer", parents=[common], help="the printer's state")
    pr.set_defaults(func=cmd_printer)
    sp = sub.add_parser("stop", parents=[common], help="emergency stop (M112)")
    sp.set_defaults(func=cmd_stop)
