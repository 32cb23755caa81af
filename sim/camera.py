"""A camera above the simulated bed, served over HTTP as MJPEG (issue 27).

Real hosts watch the printer through a webcam served by ustreamer (crowsnest) or mjpg-streamer:
``/stream`` is ``multipart/x-mixed-replace`` with one JPEG per part, ``/snapshot`` one JPEG, and
mjpg-streamer's spellings ``/?action=stream`` and ``/?action=snapshot`` name the same two. This
camera serves the same paths, showing what a camera above the bed would see: the fabric frame in
its current pose (a flip turns it over, misaligned as the flip said), the deposits on the face up in
their side's colour, those on the face down faintly (through the fabric), and the nozzle.

Rendering is cheap: Pillow draws only the segments laid down since the last frame onto a kept
layer (all of them again only when the frame's pose changed), and one rendered frame is shared by
every viewer, at most ``fps`` a second.
"""

from __future__ import annotations

import io
import threading
import time
import urllib.parse
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import TYPE_CHECKING

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from .config import FrameConfig
from .frame import Frame, FramePose
from .record import Segment

if TYPE_CHECKING:
    from .printer import SimulatedPrinter

__all__ = ["BOUNDARY", "BedCamera", "CameraServer"]

#: The multipart boundary of /stream (the body's delimiter lines are ``--`` + this).
BOUNDARY = "simcameraframe"
#: Image size, pixels (4:3, as a webcam's).
WIDTH, HEIGHT = 640, 480
#: Millimetres of the bed across the image's height, centred on the frame's centre.
VIEW_MM = 210.0
#: The fabric inside the frame, mm square (the ultimaker2-tpu profile's printable 180 mm), and the
#: frame's border around it.
FABRIC_MM, BORDER_MM = 180.0, 8.0
BED, FRAME, FABRIC = (92, 96, 102), (52, 52, 56), (238, 234, 222)
#: The side's colour when it was printed face up (as render.py's), and seen through the fabric.
SIDE_RGB = {"front": (214, 39, 40), "back": (31, 79, 214)}
#: How much of a face-down deposit shows through the fabric (0: none, 1: as if face up).
THROUGH = 0.3
JPEG_QUALITY = 80


def _mix(colour: tuple[int, int, int], into: tuple[int, int, int], share: float) -> tuple[int, int, int]:
    return tuple(round(a * share + b * (1 - share)) for a, b in zip(colour, into))  # type: ignore[return-value]


class BedCamera:
    """Frames of the bed as JPEG bytes, from a running ``SimulatedPrinter`` (thread-safe)."""

    def __init__(self, printer: SimulatedPrinter, fps: float = 5.0) -> None:
        if fps <= 0:
            raise ValueError(f"the camera's frame rate must be > 0, got {fps!r}")
        self.printer, self.fps = printer, fps
        self.config: FrameConfig = printer.config.frame
        self._lock = threading.Lock()
        self._layer: Image.Image | None = None
        self._pose: FramePose | None = None
        self._drawn = 0                                   # segments on the layer
        self._jpeg = b""
        self._at = float("-inf")
        self._font = ImageFont.load_default(size=14)
        cx, cy = self.config.center
        self._scale = HEIGHT / VIEW_MM                    # px per mm
        self._origin = (cx - WIDTH / 2 / self._scale, cy + HEIGHT / 2 / self._scale)

    def frame(self) -> bytes:
        """The current frame: rendered again when the last one is older than 1/fps."""
        with self._lock:
            now = time.monotonic()
            if now - self._at >= 1.0 / self.fps:
                self._jpeg = self._render()
                self._at = now
            return self._jpeg

    # --- drawing ---------------------------------------------------------------------

    def _px(self, pts: np.ndarray) -> np.ndarray:
        """Machine points (N, 2), mm, to pixels (N, 2): +y up in the image."""
        x0, y0 = self._origin
        return np.column_stack([(pts[:, 0] - x0) * self._scale, (y0 - pts[:, 1]) * self._scale])

    def _render(self) -> bytes:
        pose = self.printer.frame_pose()
        if pose != self._pose or self._layer is None:
            self._layer, self._drawn = self._base(pose)
            self._pose = pose
        new = self.printer.segments(self._drawn)
        self._deposit(ImageDraw.Draw(self._layer), new, pose)
        self._drawn += len(new)
        image = self._layer.copy()
        draw = ImageDraw.Draw(image)
        x, y, z = self.printer.head_position()[:3]
        self._nozzle(draw, x, y, z)
        caption = f"sim camera · {pose.side} up · {self._drawn} deposits · nozzle x {x:.1f} y {y:.1f} z {z:.1f}"
        draw.rectangle((0, HEIGHT - 22, WIDTH, HEIGHT), fill=(0, 0, 0))
        draw.text((8, HEIGHT - 19), caption, fill=(235, 235, 235), font=self._font)
        out = io.BytesIO()
        image.save(out, format="JPEG", quality=JPEG_QUALITY)
        return out.getvalue()

    def _base(self, pose: FramePose) -> tuple[Image.Image, int]:
        """The bed, the frame and the fabric in ``pose``, every deposit so far, and their count."""
        image = Image.new("RGB", (WIDTH, HEIGHT), BED)
        draw = ImageDraw.Draw(image)
        frame = self._frame(pose)
        cx, cy = self.config.center
        for half, colour in ((FABRIC_MM / 2 + BORDER_MM, FRAME), (FABRIC_MM / 2, FABRIC)):
            corners = np.array([[cx - half, cy - half], [cx + half, cy - half], [cx + half, cy + half],
                                [cx - half, cy + half]])
            draw.polygon([tuple(p) for p in self._px(frame.to_machine(corners))], fill=colour)
        everything = self.printer.segments()
        # the face down first: what is on top of the fabric covers what shows through it
        self._deposit(draw, [s for s in everything if s.side != pose.side], pose)
        self._deposit(draw, [s for s in everything if s.side == pose.side], pose)
        return image, len(everything)

    def _frame(self, pose: FramePose) -> Frame:
        frame = Frame(self.config)
        frame.pose = pose
        return frame

    def _deposit(self, draw: ImageDraw.ImageDraw, segments: list[Segment], pose: FramePose) -> None:
        """``segments`` where their fabric is now: solid when face up, faint when face down."""
        if not segments:
            return
        frame = self._frame(pose)
        fabric = np.array([[s.fx0, s.fy0, s.fx1, s.fy1] for s in segments], dtype=float)
        ends = self._px(frame.to_machine(fabric.reshape(-1, 2))).reshape(-1, 4)
        width = max(2, round(0.6 * self._scale))
        for s, (a, b, c, d) in zip(segments, ends):
            colour = SIDE_RGB.get(s.side, (0, 0, 0))
            if s.side != pose.side:
                colour = _mix(colour, FABRIC, THROUGH)
            draw.line((a, b, c, d), fill=colour, width=width)

    def _nozzle(self, draw: ImageDraw.ImageDraw, x: float, y: float, z: float) -> None:
        (px, py), = self._px(np.array([[x, y]]))
        r = 5 + min(z, 20.0) * 0.4                        # higher: nearer the camera, larger
        draw.ellipse((px - r, py - r, px + r, py + r), outline=(255, 200, 0), width=2)
        draw.line((px - r - 4, py, px + r + 4, py), fill=(255, 200, 0), width=1)
        draw.line((px, py - r - 4, px, py + r + 4), fill=(255, 200, 0), width=1)


class _Handler(BaseHTTPRequestHandler):
    server: _Server
    server_version = "ribbond-sim-camera"

    def do_GET(self) -> None:  # noqa: N802 - http.server's name
        path, _, query = self.path.partition("?")
        action = urllib.parse.parse_qs(query).get("action", [""])[0]
        if path == "/stream" or (path == "/" and action == "stream"):
            self._stream()
        elif path == "/snapshot" or (path == "/" and action == "snapshot"):
            self._send(200, "image/jpeg", self.server.camera.frame())
        elif path == "/" and not action:
            self._send(200, "text/html; charset=utf-8", b"<!doctype html><title>sim camera</title>"
                       b'<p><a href="/stream">/stream</a> <a href="/snapshot">/snapshot</a>'
                       b'<p><img src="/stream" alt="the simulated bed">')
        else:
            self._send(404, "text/plain; charset=utf-8", b"not found: /stream or /snapshot\n")

    def _send(self, status: int, kind: str, body: bytes) -> None:
        self.send_response(status)
        self.send_header("Content-Type", kind)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        self.wfile.write(body)

    def _stream(self) -> None:
        """One part per frame until the viewer goes away or the server stops."""
        camera, stop = self.server.camera, self.server.stopping
        self.send_response(200)
        self.send_header("Content-Type", f"multipart/x-mixed-replace;boundary={BOUNDARY}")
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        try:
            while not stop.is_set():
                jpeg = camera.frame()
                head = (f"--{BOUNDARY}\r\nContent-Type: image/jpeg\r\nContent-Length: {len(jpeg)}\r\n"
                        f"X-Timestamp: {time.time():.6f}\r\n\r\n").encode("ascii")
                self.wfile.write(head + jpeg + b"\r\n")
                self.wfile.flush()
                stop.wait(1.0 / camera.fps)
        except (BrokenPipeError, ConnectionResetError):
            pass                                          # the viewer left

    def log_message(self, format: str, *args: object) -> None:  # noqa: A002 - http.server's name
        pass                                              # quiet: the simulator's stdout carries its ports


class _Server(ThreadingHTTPServer):
    daemon_threads = True

    def __init__(self, address: tuple[str, int], camera: BedCamera) -> None:
        self.camera = camera
        self.stopping = threading.Event()
        super().__init__(address, _Handler)


class CameraServer:
    """``BedCamera`` over HTTP on ``host``:``port`` (0: any free port), on threads of its own.

    ``url`` is the base address, e.g. ``http://127.0.0.1:8080/``: ``url + "stream"`` and
    ``url + "snapshot"``.
    """

    def __init__(self, printer: SimulatedPrinter, port: int = 0, host: str = "127.0.0.1",
                 fps: float = 5.0) -> None:
        self.camera = BedCamera(printer, fps)
        self._server = _Server((host, port), self.camera)
        # a short poll: stop() waits for the serving loop to notice
        self._thread = threading.Thread(target=self._server.serve_forever, args=(0.05,), name="sim-camera",
                                        daemon=True)

    @property
    def url(self) -> str:
        host, port = self._server.server_address[:2]
        return f"http://{host}:{port}/"

    def start(self) -> CameraServer:
        self._thread.start()
        return self

    def stop(self) -> None:
        """Streams end at their next frame; the socket is closed."""
        self._server.stopping.set()
        if self._thread.is_alive():
            self._server.shutdown()
        self._server.server_close()

    def __enter__(self) -> CameraServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
