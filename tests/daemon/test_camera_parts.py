"""The camera's pure parts (issue 27), table-tested: the MJPEG reader against bodies written as RFC 2046
and the webcam servers have them (ustreamer and mjpg-streamer: every part with its Content-Length;
others without it, with bare LF lines, or with the boundary parameter carrying its dashes), the
Content-Type's boundary, the side a job's state change ends, and the ``[camera]`` URLs refused."""

from __future__ import annotations

from pathlib import Path

import pytest

from ribbond.daemon.components.camera import ended_side, shown
from ribbond.daemon.components.mjpeg import MjpegParser, boundary_of, part
from ribbond.daemon.config import load_config

#: Two small "JPEG" bodies: the start-of-image marker, then bytes that look like a boundary and
#: line breaks, which only the Content-Length can tell from the body's end.
A = b"\xff\xd8\xff\xe0 frame A \r\n--notit\r\n\xff\xd9"
B = b"\xff\xd8\xff\xe1 frame B \n\n\xff\xd9"


def with_length(boundary: str, frames: list[bytes], nl: bytes = b"\r\n") -> bytes:
    return b"".join(f"--{boundary}".encode() + nl + b"Content-Type: image/jpeg" + nl
                    + f"Content-Length: {len(f)}".encode() + nl + b"X-Timestamp: 1.5" + nl + nl + f + nl
                    for f in frames)


def without_length(boundary: str, frames: list[bytes], nl: bytes = b"\r\n") -> bytes:
    return b"".join(f"--{boundary}".encode() + nl + b"Content-Type: image/jpeg" + nl + nl + f + nl
                    for f in frames) + f"--{boundary}".encode() + nl


C = b"\xff\xd8 no length: --xx and --lf mid-line \xff\xd9"   # a delimiter only begins a line
D = b"\xff\xd8 second \xff\xd9"

BODIES = [
    # (name, boundary parameter, body, frames)
    ("ustreamer: lengths, CRLF", "boundarydonotcross", with_length("boundarydonotcross", [A, B]), [A, B]),
    ("a preamble before the first part", "b1", b"preamble text\r\n" + with_length("b1", [A]), [A]),
    ("no lengths: each part ends at the next delimiter", "xx", without_length("xx", [C, D]), [C, D]),
    ("bare LF line ends", "lf", without_length("lf", [C, D], b"\n"), [C, D]),
    ("lengths and bare LF", "lf2", with_length("lf2", [A, B], b"\n"), [A, B]),
    ("the parameter carries the dashes", "--myboundary",
     b"--myboundary\r\nContent-Type: image/jpeg\r\nContent-Length: %d\r\n\r\n" % len(A) + A + b"\r\n", [A]),
    ("a part that is not a JPEG is skipped", "s",
     b"--s\r\nContent-Type: text/plain\r\nContent-Length: 5\r\n\r\nhello\r\n" + with_length("s", [B]), [B]),
    ("a body that does not start as a JPEG is skipped", "t", with_length("t", [b"GIF89a..", A]), [A]),
    ("a closing delimiter", "e", with_length("e", [A]) + b"--e--\r\n", [A]),
]


@pytest.mark.parametrize("name, boundary, body, frames", BODIES, ids=[b[0] for b in BODIES])
def test_frames_of_an_mjpeg_body_whole_and_byte_by_byte(name: str, boundary: str, body: bytes,
                                                        frames: list[bytes]) -> None:
    assert MjpegParser(boundary).feed(body) == frames
    parser = MjpegParser(boundary)
    got = [f for i in range(len(body)) for f in parser.feed(body[i:i + 1])]
    assert got == frames


def test_the_daemons_own_parts_read_back() -> None:
    body = part(A, "ribbondframe") + part(B, "ribbondframe")
    assert body.startswith(b"--ribbondframe\r\nContent-Type: image/jpeg\r\nContent-Length: %d\r\n\r\n" % len(A))
    assert MjpegParser("ribbondframe").feed(body) == [A, B]


@pytest.mark.parametrize("body, message", [
    (b"--b\r\nContent-Length: lots\r\n\r\n", "Content-Length is 'lots'"),
    (b"--b\r\nContent-Length: 99999999\r\n\r\n", "a frame of 99999999 bytes"),
    (b"--b\r\n" + b"X-Long: " + b"y" * 9000, "headers are longer than 8192 bytes"),
    (b"--b\r\nContent-Type: image/jpeg\r\n\r\n\xff\xd8" + b"z" * 2000, "a frame longer than the 1000 bytes"),
])
def test_a_stream_that_is_not_a_cameras_is_refused_naming_the_problem(body: bytes, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        MjpegParser("b", max_frame=1000 if b"z" in body else 8 * 1024 * 1024).feed(body)


@pytest.mark.parametrize("header, boundary", [
    ("multipart/x-mixed-replace;boundary=boundarydonotcross", "boundarydonotcross"),
    ('multipart/x-mixed-replace; boundary="quoted one"', "quoted one"),
    ("Multipart/X-Mixed-Replace; charset=x; BOUNDARY=--dashes", "--dashes"),
])
def test_the_boundary_of_a_content_type(header: str, boundary: str) -> None:
    assert boundary_of(header) == boundary


@pytest.mark.parametrize("header, message", [
    ("image/jpeg", "'image/jpeg', not multipart/x-mixed-replace"),
    ("", "'untyped', not multipart"),
    ("multipart/x-mixed-replace", "names no multipart boundary"),
    ("multipart/x-mixed-replace; boundary=", "names no multipart boundary"),
])
def test_a_content_type_that_is_not_mjpeg_is_refused(header: str, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        boundary_of(header)


DESIGN, GCODE = {"kind": "design"}, {"kind": "gcode"}


@pytest.mark.parametrize("before, job, side", [
    ("printing_front", {**DESIGN, "state": "awaiting_flip", "side": "front"}, "front"),
    ("printing_back", {**DESIGN, "state": "done", "side": "back"}, "back"),
    ("printing_front", {**DESIGN, "state": "done", "side": "front"}, "front"),      # a one-sided design
    ("printing_front", {**GCODE, "state": "done", "side": "front"}, "program"),
    ("printing_front", {**DESIGN, "state": "printing_front", "side": "front"}, None),  # published again
    ("printing_front", {**DESIGN, "state": "paused", "side": "front"}, None),
    ("printing_back", {**DESIGN, "state": "interrupted", "side": "back"}, None),
    ("printing_back", {**DESIGN, "state": "cancelled", "side": "back"}, None),
    (None, {**DESIGN, "state": "done", "side": "back"}, None),                       # not seen printing
    ("awaiting_check", {**DESIGN, "state": "done", "side": "back"}, None),           # a resume with nothing left
    ("done", {**DESIGN, "state": "done", "side": "back"}, None),
    ("aligning", {**DESIGN, "state": "awaiting_flip", "side": "front"}, None),
])
def test_the_side_a_state_change_ends(before: str | None, job: dict[str, str], side: str | None) -> None:
    assert ended_side(before, job) == side


def test_logs_show_a_cameras_url_without_its_password() -> None:
    assert shown("http://admin:secret@cam.local:8080/stream?x=1") == "http://cam.local:8080/stream?x=1"
    assert shown("http://127.0.0.1:8080/snapshot") == "http://127.0.0.1:8080/snapshot"


@pytest.mark.parametrize("line, message", [
    ('stream_url = "ftp://cam/stream"', "camera.stream_url: .*'ftp://cam/stream': expected an http:// or https:// URL"),
    ('snapshot_url = "127.0.0.1:8080/snapshot"', "camera.snapshot_url: .*expected an http:// or https:// URL"),
    ('snapshot_url = "http:///snapshot"', "camera.snapshot_url: .*URL with a host"),
    ('stream_url = "http://cam:70000/stream"', "camera.stream_url: .*the port is not a number from 0 to 65535"),
    ('url = "http://cam/stream"', "camera.url: Extra inputs are not permitted"),
])
def test_camera_settings_that_cannot_be_used_are_refused(tmp_path: Path, line: str, message: str) -> None:
    config = tmp_path / "ribbond.toml"
    config.write_text(f"[camera]\n{line}\n", encoding="utf-8")
    with pytest.raises(ValueError, match=f"{config}: invalid configuration: {message}"):
        load_config(config)


def test_either_url_may_be_empty(tmp_path: Path) -> None:
    config = tmp_path / "ribbond.toml"
    config.write_text('[camera]\nstream_url = " http://127.0.0.1:8080/stream "\nsnapshot_url = ""\n', encoding="utf-8")
    camera = load_config(config).camera
    assert camera.stream_url == "http://127.0.0.1:8080/stream" and camera.snapshot_url == ""
    assert camera.configured
    config.write_text("[camera]\n", encoding="utf-8")
    assert not load_config(config).camera.configured
