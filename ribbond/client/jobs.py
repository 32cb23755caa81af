"""``ribbonctl``'s job commands: submit, print (a plain G-code program), status, watch, start, pause,
resume, cancel, flip-done, frame-ok, align, accept, re-seat, delete."""

from __future__ import annotations

import argparse
import json
import sys
import time
from typing import Any

from .http import Client, ClientError, _client
from .output import (Bar, ENDED, HOT, _detail, _exit_code, _line, _out, bar_text, progress_text, temperatures_text,
                     verdict_text, waits)
from .printer import _position


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
