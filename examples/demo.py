"""`make demo`: a two-sided job, end to end, on the simulated printer.

Starts the simulator (`python -m sim`, its own process on a pty, as firmware runs on its own board)
and the daemon (`ribbond`, its own process, in a temporary state directory), then as an operator
would:

0. `ribbonctl frame-ready`: a fresh pre-stretched frame is on the printer (ribbond heats for no job
   until the operator says so: a frame printed on before must not be printed on again);
1. `ribbonctl submit examples/meshes/saddle.obj --start`: upload, compile, heat, print the front;
2. `ribbonctl watch`: the progress bar of the front, until the job waits for the flip (it prints the
   instruction and the command to run); turns the simulated frame over with a small known
   misalignment and says `ribbonctl flip-done`;
3. the alignment check: the head goes above where each registration mark should be, and the
   operator jogs the nozzle onto the mark (`ribbonctl jog dx dy`; here the jog is computed from the
   known misalignment, as a person would find it by looking through the nozzle), then says
   `ribbonctl align JOB --here`;
4. ribbond fits the correction, prints the back, and the demo prints the job's summary and the path
   of a PNG of what the simulator deposited, front and back, in machine and fabric coordinates.

Everything lands in ``out/demo/``.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
from sim.process import SimProcess  # noqa: E402

OUT = ROOT / "out" / "demo"
MESH = ROOT / "examples" / "meshes" / "saddle.obj"
SIZE_MM = 90.0
TIME_SCALE = 0.05                      # 20× faster than the real machine
MISALIGNMENT = {"dx": 0.6, "dy": -0.4, "rotation_deg": 0.8}   # how the frame is put back
CENTER = (110.0, 110.0)                # the profile's frame centre; flip about the y axis


def ribbonctl(url: str, *args: str, check: bool = True) -> subprocess.CompletedProcess[str]:
    proc = subprocess.run([sys.executable, "-m", "ribbond.client.cli", *args, "--url", url],
                          cwd=ROOT, text=True, stdout=subprocess.PIPE)
    if check and proc.returncode != 0:
        raise SystemExit(f"demo: ribbonctl {' '.join(args)} failed ({proc.returncode})")
    return proc


def wait_for(url: str, job: str, states: set[str], timeout: float = 300.0,
             until: Any = None) -> dict[str, Any]:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        status = json.loads(ribbonctl(url, "status", job, "--json").stdout)
        if status["state"] in states and (until is None or until(status)):
            return status
        if status["state"] in ("failed", "cancelled", "interrupted"):
            raise SystemExit(f"demo: the job {status['state']}: {status.get('error')}")
        time.sleep(0.3)
    raise SystemExit(f"demo: the job did not reach {states} in {timeout:.0f} s")


def main() -> int:
    started = time.monotonic()
    OUT.mkdir(parents=True, exist_ok=True)
    if not MESH.exists():
        subprocess.run([sys.executable, str(ROOT / "examples" / "meshes" / "make_meshes.py")], check=True)
    state = Path(tempfile.mkdtemp(prefix="ribbond-demo-"))
    sim = SimProcess(["--time-scale", str(TIME_SCALE), "--baud", "250000"], cwd=ROOT).start()
    config = state / "ribbond.toml"
    # the simulated board has Marlin's standard 128-byte receive buffer, and its owner says so: the
    # default window (63, safe for 64-byte boards) keeps one line in flight and starves the planner
    config.write_text(f'state_dir = "{state}"\n[serial]\nport = "{sim.port}"\nbaud = 250000\n'
                      'rx_buffer = 127\n[api]\nport = 0\n', encoding="utf-8")
    log = (OUT / "ribbond.log").open("w")
    daemon = subprocess.Popen([sys.executable, "-m", "ribbond", "--config", str(config)], cwd=ROOT,
                              stderr=log, env={**os.environ, "PYTHONUNBUFFERED": "1"})
    try:
        for _ in range(300):
            if (state / "api.url").exists():
                break
            time.sleep(0.1)
        url = (state / "api.url").read_text().strip()
        print(f"simulator on {sim.port}, ribbond on {url} (state in {state})")
        print("a fresh stretched frame is loaded, front side up")
        print("$ ribbonctl frame-ready")
        print("  " + ribbonctl(url, "frame-ready").stdout.strip())
        print(f"$ ribbonctl submit {MESH.relative_to(ROOT)} --size {SIZE_MM:g} --start")
        submit = ribbonctl(url, "submit", str(MESH), "--size", str(SIZE_MM), "--start")
        print(submit.stdout.rstrip())
        job = submit.stdout.split()[1]
        print(f"$ ribbonctl watch {job}")
        watch = ribbonctl(url, "watch", job)
        print("\n".join("  " + line for line in watch.stdout.rstrip().splitlines()[-4:]))
        wait_for(url, job, {"awaiting_flip", "done"})
        sim.request({"cmd": "flip", **MISALIGNMENT})
        print(f"frame turned over about its y axis and put back off by ({MISALIGNMENT['dx']}, "
              f"{MISALIGNMENT['dy']}) mm and {MISALIGNMENT['rotation_deg']}°")
        print(f"$ ribbonctl flip-done {job}")
        print("  " + ribbonctl(url, "flip-done", job).stdout.splitlines()[0])
        design = json.loads((Path(json.loads(ribbonctl(url, "status", job, "--json").stdout)["design_dir"])
                             / "design.json").read_text())
        a = math.radians(MISALIGNMENT["rotation_deg"])
        cx, cy = CENTER
        for k, (x, y) in enumerate(design["registration_marks"], start=1):
            status = wait_for(url, job, {"aligning"}, until=lambda s: s.get("waits_for_operator"))
            print(f"  {status['next']['instruction'].split('. ')[0]}")
            px, py = 2 * cx - x, y                             # where the mark should be: mirrored
            mx = cx + math.cos(a) * (px - cx) - math.sin(a) * (py - cy) + MISALIGNMENT["dx"]
            my = cy + math.sin(a) * (px - cx) + math.cos(a) * (py - cy) + MISALIGNMENT["dy"]
            head = json.loads(ribbonctl(url, "printer", "--json").stdout)["head"]
            jog = (f"{mx - head[0]:.3f}", f"{my - head[1]:.3f}")   # what the operator's eye finds
            print(f"$ ribbonctl jog {jog[0]} {jog[1]}")
            print("  " + ribbonctl(url, "jog", *jog).stdout.strip())
            print(f"$ ribbonctl align {job} --here")
            print("  " + ribbonctl(url, "align", job, "--here").stdout.strip().replace("\n", "\n  "))
        final = wait_for(url, job, {"done"})
        png = OUT / "deposits.png"
        sim.request({"cmd": "render", "path": str(png)})
        stats = sim.stats()
        print(f"job {job}: {final['state']}; the simulator executed {stats['commands_executed']} commands, "
              f"{stats['starvations']} planner starvations, {stats['resends_requested']} resends")
        print(f"deposits: {png.relative_to(ROOT)}  (front red, back blue; machine and fabric coordinates)")
        print(f"demo took {time.monotonic() - started:.0f} s")
        return 0
    finally:
        daemon.terminate()
        try:
            daemon.wait(15)
        except subprocess.TimeoutExpired:
            daemon.kill()
        sim.stop()
        log.close()


if __name__ == "__main__":
    sys.exit(main())
