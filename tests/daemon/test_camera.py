"""The camera end to end (issue 27): the simulator serving a camera of its bed (``python -m sim
--camera-port 0``), real ribbond processes reading ``[camera]``, real HTTP.

A snapshot is kept with the job at each side's end and served with its files: the front's when the
job waits for the flip (the bed shows the front's deposits, red, and nothing blue), the back's when
it is done (the back's, blue, face up); the camera also reaches a client through the daemon
(``/camera/stream``, ``/camera/snapshot``). A camera that is down (its stream refusing connections,
its snapshot accepting them and never answering) neither changes nor delays the jobs: they go
through the same states, the next one starts at once, and the failure is logged and shown.
"""

from __future__ import annotations

import io
import socket
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest
from PIL import Image

from ribbond.daemon.components.camera import SNAPSHOT_TIMEOUT_S
from ribbond.daemon.components.mjpeg import MjpegParser, boundary_of
from sim.camera import HEIGHT, SIDE_RGB, VIEW_MM, WIDTH
from sim.process import SimProcess

from .conftest import BAUD, CENTER, ROOT, Sim, frame_ready, running, submit, wait_for
from .test_daemon_e2e import FULL_FLOW, MISALIGNMENT, flip_and_align, states
from .test_frame_gate import queue

pytestmark = pytest.mark.timeout(180)

#: A small two-sided design (the saddle at 45 mm: about 8 front and 2 back ribbons), quick to print.
SMALL = {"size": {"bbox_diagonal": 45}}


#: The simulator runs 200× fast here (the harness's 50×): nothing in these tests waits on its clock.
FAST = 0.005


class CameraSim(Sim):
    """A simulator serving its camera; ``camera`` is its base address."""

    def __init__(self, time_scale: float = FAST) -> None:  # noqa: D107 - Sim's attributes and the camera's
        self.process = SimProcess(["--time-scale", str(time_scale), "--baud", str(BAUD), "--camera-port", "0",
                                   "--camera-fps", "10"], cwd=ROOT).start()
        self.port = self.process.port
        self.side = "front"
        self.camera = self.process.camera_url


@pytest.fixture(scope="module")
def camera_sim() -> Iterator[CameraSim]:
    sim = CameraSim()
    try:
        yield sim
    finally:
        sim.stop()


def camera_table(stream_url: str, snapshot_url: str) -> str:
    return f'[camera]\nstream_url = "{stream_url}"\nsnapshot_url = "{snapshot_url}"\n'


def wait_snapshot(client: httpx.Client, job: str, name: str, timeout: float = SNAPSHOT_TIMEOUT_S + 5) -> dict[str, Any]:
    """The job's record once its ``snapshots`` list ``name``."""
    deadline = time.monotonic() + timeout
    while True:
        record = client.get(f"/jobs/{job}").json()
        if name in [s["name"] for s in record["snapshots"]]:
            return dict(record)
        assert time.monotonic() < deadline, f"no {name} in {timeout:.0f} s: {record['snapshots']}"
        time.sleep(0.1)


def side_pixels(jpeg: bytes) -> dict[str, int]:
    """Pixels of each side's colour as printed face up (the simulator's colours), in a camera frame."""
    image = Image.open(io.BytesIO(jpeg)).convert("RGB")
    assert image.size == (WIDTH, HEIGHT)
    pixels = np.asarray(image, dtype=int)
    return {side: int((np.abs(pixels - rgb).max(axis=2) <= 50).sum()) for side, rgb in SIDE_RGB.items()}


NOZZLE_RGB = (255, 200, 0)
NOZZLE_REACH_PX = 20


def on_deposits(jpeg: bytes, segments: list[dict[str, Any]], side: str) -> float:
    """The share of ``side``'s deposits whose middle is in that side's colour in a camera frame: the
    view is VIEW_MM tall, centred on the frame's centre (CENTER)."""
    image = np.asarray(Image.open(io.BytesIO(jpeg)).convert("RGB"), dtype=int)
    scale = HEIGHT / VIEW_MM
    mids = [((s["x0"] + s["x1"]) / 2, (s["y0"] + s["y1"]) / 2) for s in segments if s["side"] == side]
    pixels = [(round(HEIGHT / 2 - (y - CENTER[1]) * scale), round(WIDTH / 2 + (x - CENTER[0]) * scale)) for x, y in mids]
    # the nozzle's marker (yellow, at most 17 px from its centre) is drawn over the deposits it is on
    nozzle = np.argwhere((np.abs(image - NOZZLE_RGB) <= 60).all(axis=2))
    if len(nozzle):
        centre = nozzle.mean(axis=0)
        pixels = [p for p in pixels if np.hypot(*(np.array(p) - centre)) > NOZZLE_REACH_PX]
    assert len(pixels) >= 10, f"only {len(pixels)} {side} deposits in view"
    hits = [np.abs(image[row, col] - SIDE_RGB[side]).max() <= 60 for row, col in pixels]
    return sum(hits) / len(hits)


def moves(tmp_path: Path, name: str) -> Path:
    """A plain program of head moves above the fabric (no heat: nothing here waits on it)."""
    path = tmp_path / name
    path.write_text("\n".join(["G28", "G90", "G0 Z5 F600", *(f"G0 X{60 + 10 * i} Y{60 + 5 * i} F6000"
                                                             for i in range(10))]) + "\n")
    return path


def transition_at(client: httpx.Client, job: str, state: str) -> float:
    return float(next(t["at"] for t in client.get(f"/jobs/{job}/transitions").json() if t["to_state"] == state))


def test_a_snapshot_is_kept_at_each_sides_end_and_served_with_the_jobs_files(
        camera_sim: CameraSim, tmp_path: Path, meshes: dict[str, Path]) -> None:
    table = camera_table(camera_sim.camera + "stream", camera_sim.camera + "?action=snapshot")
    with running(tmp_path / "ribbond", camera_sim.port, extra=table) as daemon:
        api = daemon.client
        assert api is not None
        assert api.get("/camera").json() == {"configured": True, "stream": "stream_url", "snapshot": "snapshot_url",
                                             "last_error": None, "last_error_at": None}
        # the camera through the daemon: its stream, framed anew, and a snapshot
        with api.stream("GET", "/camera/stream") as r:
            assert r.status_code == 200 and r.headers["cache-control"] == "no-store"
            parser, frames = MjpegParser(boundary_of(r.headers["content-type"])), []
            for chunk in r.iter_raw():
                frames += parser.feed(chunk)
                if len(frames) >= 2:
                    break
        assert all(Image.open(io.BytesIO(f)).size == (WIDTH, HEIGHT) for f in frames)
        snapshot = api.get("/camera/snapshot")
        assert snapshot.status_code == 200 and snapshot.headers["content-type"] == "image/jpeg"
        assert side_pixels(snapshot.content) == {"front": 0, "back": 0}            # a fresh frame

        frame_ready(api)
        first_segment = len(camera_sim.segments())
        job = submit(api, meshes["two_sided"], start=True, parameters=SMALL)
        wait_for(api, job, "awaiting_flip", timeout=90)
        record = wait_snapshot(api, job, "snapshot-front.jpg")
        taken = record["snapshots"][0]["taken"]
        flip_at = transition_at(api, job, "awaiting_flip")
        assert flip_at <= taken <= flip_at + SNAPSHOT_TIMEOUT_S
        front = api.get(f"/jobs/{job}/files/snapshot-front.jpg")
        assert front.status_code == 200 and front.headers["content-type"] == "image/jpeg"
        # the front's deposits, face up, where the simulator laid them; nothing blue
        assert on_deposits(front.content, camera_sim.segments()[first_segment:], "front") > 0.8
        assert side_pixels(front.content)["back"] == 0

        design = api.get(f"/jobs/{job}/files/design.json").json()
        flip_and_align(api, camera_sim, job, design["registration_marks"], MISALIGNMENT)
        wait_for(api, job, "done", timeout=90)
        record = wait_snapshot(api, job, "snapshot-back.jpg")
        assert [s["name"] for s in record["snapshots"]] == ["snapshot-front.jpg", "snapshot-back.jpg"]
        back = api.get(f"/jobs/{job}/files/snapshot-back.jpg")
        assert back.status_code == 200
        # the back's deposits, face up; the front's are under the fabric now: faint, nothing solid red
        assert on_deposits(back.content, camera_sim.segments()[first_segment:], "back") > 0.8
        assert side_pixels(back.content)["front"] == 0
        assert api.get(f"/jobs/{job}/files/snapshot-front.jpg").content == front.content
        assert states(api.get(f"/jobs/{job}/transitions").json()) == FULL_FLOW
        assert record["error"] is None
    camera_sim.ensure_front()


def test_a_camera_that_is_down_neither_changes_nor_delays_the_jobs(camera_sim: CameraSim, tmp_path: Path) -> None:
    with socket.socket() as silent, socket.socket() as closed:
        silent.bind(("127.0.0.1", 0))
        silent.listen(8)                   # connections are taken by the kernel and never answered
        closed.bind(("127.0.0.1", 0))      # bound, not listening: connections are refused
        table = camera_table(f"http://127.0.0.1:{closed.getsockname()[1]}/stream",
                             f"http://127.0.0.1:{silent.getsockname()[1]}/snapshot")
        with running(tmp_path / "ribbond", camera_sim.port, extra=table) as daemon:
            api = daemon.client
            assert api is not None
            r = api.get("/camera/stream")
            assert r.status_code == 502 and r.json()["detail"].startswith("camera: the camera's stream "), r.text
            frame_ready(api)
            first = queue(api, moves(tmp_path, "first.gcode"))
            second = queue(api, moves(tmp_path, "second.gcode"), same_frame=True)
            done = [wait_for(api, job, "done", timeout=60) for job in (first, second)]
            flow = ["submitted", "ready", "heating", "printing_front", "done"]
            for job, record in zip((first, second), done):
                assert states(api.get(f"/jobs/{job}/transitions").json()) == flow
                assert record["error"] is None and record["snapshots"] == []
                assert api.get(f"/jobs/{job}/files/snapshot-program.jpg").status_code == 404
            # the first's snapshot hangs for SNAPSHOT_TIMEOUT_S: the second heated at once all the same
            assert transition_at(api, second, "heating") - transition_at(api, first, "done") < 1.5
            # each failure logged, the last one shown; the daemon answers all along
            deadline = time.monotonic() + SNAPSHOT_TIMEOUT_S + 5
            while not str((view := api.get("/camera").json())["last_error"]).startswith(
                    f"no snapshot-program.jpg for job {second}"):
                assert time.monotonic() < deadline, view
                time.sleep(0.2)
            assert f"camera: no snapshot-program.jpg for job {first}" in daemon.log_tail(20000)
            assert api.get("/printer").status_code == 200
