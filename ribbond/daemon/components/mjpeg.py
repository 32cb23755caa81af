"""MJPEG over HTTP as webcam servers send it: a ``multipart/x-mixed-replace`` body, one JPEG per part
(issue 27). Pure: bytes in, frames out, no I/O; table-tested (``tests/daemon/test_camera_parts.py``).

The shape, as ustreamer, mjpg-streamer and most IP cameras write it (RFC 2046's multipart, with
``x-mixed-replace`` meaning each part replaces the one before)::

    Content-Type: multipart/x-mixed-replace;boundary=B       (the response's header)

    --B\\r\\n
    Content-Type: image/jpeg\\r\\n
    Content-Length: 12345\\r\\n                                 (most servers send it; not all)
    \\r\\n
    <12345 bytes of JPEG>\\r\\n
    --B\\r\\n ...

Some servers write the boundary parameter with its two dashes already (``boundary=--B`` and
delimiter lines ``--B``), some end lines with a bare LF; both are read. A part without
Content-Length ends where the next delimiter line begins. Parts that are not JPEG images are
skipped.
"""

from __future__ import annotations

__all__ = ["MAX_FRAME_BYTES", "MjpegParser", "boundary_of", "is_jpeg", "part"]

#: The largest frame taken (a 4K JPEG is well under it): beyond it the stream is not a camera's.
MAX_FRAME_BYTES = 8 * 1024 * 1024
#: The largest header block of one part.
MAX_HEADER_BYTES = 8192
#: The JPEG start-of-image marker every JPEG file begins with.
JPEG_SOI = b"\xff\xd8"


def is_jpeg(data: bytes) -> bool:
    """Whether ``data`` begins as a JPEG file does (its start-of-image marker)."""
    return data[:2] == JPEG_SOI


def boundary_of(content_type: str) -> str:
    """The boundary of a ``multipart/x-mixed-replace`` Content-Type header.

    Raises ValueError naming what was found when it is another type or has no boundary.
    """
    kind, _, params = content_type.partition(";")
    if kind.strip().lower() != "multipart/x-mixed-replace":
        raise ValueError(f"the camera's stream is {kind.strip() or 'untyped'!r}, not "
                         "multipart/x-mixed-replace (MJPEG): is stream_url the stream's address?")
    for param in params.split(";"):
        name, _, value = param.partition("=")
        if name.strip().lower() == "boundary":
            value = value.strip().strip('"')
            if value:
                return value
    raise ValueError("the camera's stream names no multipart boundary in its Content-Type")


def part(jpeg: bytes, boundary: str) -> bytes:
    """One part of a multipart/x-mixed-replace body, as the daemon writes it (always with its length)."""
    return (f"--{boundary}\r\nContent-Type: image/jpeg\r\nContent-Length: {len(jpeg)}\r\n\r\n"
            .encode("ascii") + jpeg + b"\r\n")


class MjpegParser:
    """Frames from the bytes of an MJPEG body, fed as they arrive: ``feed(chunk)`` -> JPEG frames.

    Raises ValueError when a part's headers or body pass their limits (``MAX_HEADER_BYTES``,
    ``max_frame``) or its Content-Length is not a number.
    """

    def __init__(self, boundary: str, max_frame: int = MAX_FRAME_BYTES) -> None:
        b = boundary.encode("latin-1")
        # "--B" as RFC 2046 has it; "B" too when the parameter carried the dashes itself
        self._delimiters = (b"--" + b, b) if b.startswith(b"--") else (b"--" + b,)
        self._max_frame = max_frame
        self._buf = bytearray()
        self._state = "seek"                       # seek -> headers -> body -> seek ...
        self._length: int | None = None
        self._jpeg = True

    def feed(self, data: bytes) -> list[bytes]:
        """The frames completed by ``data``, in order."""
        self._buf += data
        frames: list[bytes] = []
        while True:
            step = {"seek": self._seek, "headers": self._headers, "body": self._body}[self._state]
            done, frame = step()
            if frame is not None and self._jpeg and is_jpeg(frame):
                frames.append(frame)
            if not done:
                return frames

    def _find_delimiter(self, start: int = 0) -> tuple[int, int]:
        """Where the first delimiter at the start of a line is, and its length; (-1, 0) if none yet."""
        best = (-1, 0)
        for d in self._delimiters:
            at = start
            while (at := self._buf.find(d, at)) >= 0:
                if at == 0 or self._buf[at - 1:at] == b"\n":
                    break
                at += 1
            if at >= 0 and (best[0] < 0 or at < best[0]):
                best = (at, len(d))
        return best

    def _seek(self) -> tuple[bool, bytes | None]:
        at, size = self._find_delimiter()
        if at < 0:
            keep = max(len(d) for d in self._delimiters) + 1
            del self._buf[:max(0, len(self._buf) - keep)]       # a preamble or a part's tail: not kept
            return False, None
        end = self._buf.find(b"\n", at + size)
        if end < 0:
            return False, None
        del self._buf[:end + 1]
        self._state, self._length, self._jpeg = "headers", None, True
        return True, None

    def _headers(self) -> tuple[bool, bytes | None]:
        ends = [(i, n) for i, n in ((self._buf.find(b"\r\n\r\n"), 4), (self._buf.find(b"\n\n"), 2)) if i >= 0]
        if self._buf[:2] == b"\r\n" or self._buf[:1] == b"\n":          # a part with no headers
            ends.append((0, 2 if self._buf[:2] == b"\r\n" else 1))
        if not ends:
            if len(self._buf) > MAX_HEADER_BYTES:
                raise ValueError(f"a part's headers are longer than {MAX_HEADER_BYTES} bytes: not an MJPEG stream")
            return False, None
        at, size = min(ends)
        for line in bytes(self._buf[:at]).decode("latin-1").splitlines():
            name, _, value = line.partition(":")
            name, value = name.strip().lower(), value.strip()
            if name == "content-length":
                if not value.isdigit():
                    raise ValueError(f"a part's Content-Length is {value[:32]!r}, not a number")
                self._length = int(value)
            elif name == "content-type":
                self._jpeg = value.split(";")[0].strip().lower() in ("image/jpeg", "image/jpg", "image/pjpeg")
        if self._length is not None and self._length > self._max_frame:
            raise ValueError(f"a frame of {self._length} bytes: more than the {self._max_frame} taken")
        del self._buf[:at + size]
        self._state = "body"
        return True, None

    def _body(self) -> tuple[bool, bytes | None]:
        if self._length is not None:
            if len(self._buf) < self._length:
                return False, None
            frame = bytes(self._buf[:self._length])
            del self._buf[:self._length]
        else:
            at, _ = self._find_delimiter()
            if at < 0:
                if len(self._buf) > self._max_frame:
                    raise ValueError(f"a frame longer than the {self._max_frame} bytes taken, or no "
                                     "delimiter after it")
                return False, None
            frame = bytes(self._buf[:at])
            del self._buf[:at]
            # the line break before the delimiter belongs to it
            frame = frame[:-2] if frame.endswith(b"\r\n") else frame[:-1] if frame.endswith(b"\n") else frame
        self._state = "seek"
        return True, frame
