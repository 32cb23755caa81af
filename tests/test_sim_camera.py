"""The simulator's camera (issue 27): a JPEG of the bed that decodes, an MJPEG stream in the
multipart/x-mixed-replace format webcam servers use (read here by a strict reader of RFC 2046's
parts, not by the daemon's), at ustreamer's and mjpg-streamer's paths, and a picture that shows the
deposits where the bed has them: in their side's colour, and faintly through the fabric once the
frame is turned over (mirrored about the flip axis, as the documented view places them)."""

from __future__ import annotations

import http.client
import io
import socket
import time
from collections.abc import Iterator

import pytest
from PIL import Image

from sim import SimConfig, SimulatedPrinter
from sim.camera import BOUNDARY, FABRIC, HEIGHT, SIDE_RGB, VIEW_MM, WIDTH, CameraServer
from sim.testing import PtyHost, connected

FPS = 50.0           # a fresh frame for every request of these tests
CENTER = (110.0, 110.0)


@pytest.fixture
def bed() -> Iterator[tuple[SimulatedPrinter, PtyHost, CameraServer]]:
    with connected(SimConfig(time_scale=0.001, baud=1_000_000)) as (sim, host):
        with CameraServer(sim, fps=FPS) as camera:
            yield sim, host, camera


def get(camera: CameraServer, path: str) -> http.client.HTTPResponse:
    host, port = camera.url.removeprefix("http://").rstrip("/").split(":")
    conn = http.client.HTTPConnection(host, int(port), timeout=10)
    conn.request("GET", path)
    return conn.getresponse()


def snapshot(camera: CameraServer, path: str = "/snapshot") -> Image.Image:
    time.sleep(2 / FPS)
    r = get(camera, path)
    assert r.status == 200 and r.getheader("Content-Type") == "image/jpeg"
    image = Image.open(io.BytesIO(r.read()))
    assert image.format == "JPEG"
    return image.convert("RGB")


def pixel(image: Image.Image, x: float, y: float) -> tuple[int, int, int]:
    """The colour at machine point (x, y): the view is VIEW_MM tall, centred on the frame's centre."""
    scale = HEIGHT / VIEW_MM
    return image.getpixel((round(WIDTH / 2 + (x - CENTER[0]) * scale), round(HEIGHT / 2 - (y - CENTER[1]) * scale)))


def near(colour: tuple[int, int, int], want: tuple[int, int, int], tolerance: int = 40) -> bool:
    return all(abs(a - b) <= tolerance for a, b in zip(colour, want))


def test_a_snapshot_is_a_jpeg_of_the_bed_at_both_paths(bed: tuple[SimulatedPrinter, PtyHost, CameraServer]) -> None:
    _, _, camera = bed
    for path in ("/snapshot", "/?action=snapshot"):
        image = snapshot(camera, path)
        assert image.size == (WIDTH, HEIGHT)
        assert near(pixel(image, *CENTER), FABRIC)             # nothing printed yet: the bare fabric
    assert get(camera, "/nothing").status == 404


def read_parts(camera: CameraServer, path: str, count: int) -> tuple[str, list[tuple[dict[str, str], bytes]]]:
    """The stream's Content-Type and its first ``count`` parts (headers, body), read off the socket."""
    host, port = camera.url.removeprefix("http://").rstrip("/").split(":")
    with socket.create_connection((host, int(port)), timeout=10) as sock:
        sock.sendall(f"GET {path} HTTP/1.1\r\nHost: {host}\r\n\r\n".encode())
        data = b""
        while data.count(b"\r\n--" + BOUNDARY.encode() + b"\r\n") < count:
            chunk = sock.recv(65536)
            assert chunk, "the stream ended"
            data += chunk
    head, _, body = data.partition(b"\r\n\r\n")
    status, *lines = head.decode("latin-1").split("\r\n")
    assert status.split()[1] == "200", status
    headers = {k.lower(): v.strip() for k, _, v in (line.partition(":") for line in lines)}
    parts = []
    delimiter = b"--" + headers["content-type"].split("boundary=")[1].encode() + b"\r\n"
    for _ in range(count):
        assert body.startswith(delimiter), body[:60]                     # RFC 2046: each part opens with it
        block, _, body = body[len(delimiter):].partition(b"\r\n\r\n")
        fields = {k.lower(): v.strip() for k, _, v in (line.partition(":") for line in block.decode().split("\r\n"))}
        size = int(fields["content-length"])
        parts.append((fields, body[:size]))
        assert body[size:size + 2] == b"\r\n"                          # the part's body, then its line break
        body = body[size + 2:]
    return headers["content-type"], parts


@pytest.mark.parametrize("path", ["/stream", "/?action=stream"])
@pytest.mark.timing
def test_the_stream_is_multipart_x_mixed_replace_with_one_jpeg_a_part(
        bed: tuple[SimulatedPrinter, PtyHost, CameraServer], path: str) -> None:
    _, _, camera = bed
    started = time.monotonic()
    kind, parts = read_parts(camera, path, 4)
    elapsed = time.monotonic() - started
    assert kind == f"multipart/x-mixed-replace;boundary={BOUNDARY}"
    for fields, jpeg in parts:
        assert fields["content-type"] == "image/jpeg"
        assert Image.open(io.BytesIO(jpeg)).size == (WIDTH, HEIGHT)
    assert elapsed >= 3 / FPS * 0.9                                    # paced at its frame rate


def test_the_picture_shows_the_deposits_where_the_bed_has_them(
        bed: tuple[SimulatedPrinter, PtyHost, CameraServer]) -> None:
    sim, host, camera = bed
    before = snapshot(camera)
    for line in ("G28", "M83", "G0 X120 Y130 Z0.2 F3000", "G1 X145 Y130 E2 F1200", "G0 Z10", "G0 X30 Y30 F6000"):
        host.command(line)
    assert sim.wait_idle(10)
    on_line, beside = (132.0, 130.0), (132.0, 150.0)
    after = snapshot(camera)
    assert near(pixel(before, *on_line), FABRIC)
    assert near(pixel(after, *on_line), SIDE_RGB["front"], 60), pixel(after, *on_line)
    assert near(pixel(after, *beside), FABRIC)
    # Turned over about x = 110: the front's line now lies at x 75-100, under the fabric, faint.
    sim.flip()
    flipped = snapshot(camera)
    mirrored = (2 * CENTER[0] - on_line[0], on_line[1])
    assert near(pixel(flipped, *on_line), FABRIC)
    faint = pixel(flipped, *mirrored)
    assert not near(faint, FABRIC, 15) and faint[0] > faint[1] + 20, faint        # reddish, not the fabric
    assert sum(faint) > sum(SIDE_RGB["front"]) + 150, faint                        # and much lighter
