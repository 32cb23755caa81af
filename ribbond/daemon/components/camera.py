"""The printer's camera (issue 27): its frames for the dashboard, and a snapshot kept with the job at
each side's end.

The camera is what crowsnest, ustreamer or mjpg-streamer serve: ``[camera] stream_url`` (MJPEG,
``multipart/x-mixed-replace``) and ``snapshot_url`` (one JPEG); either may be empty, the other then
stands in (the next frame of the stream as the snapshot, the snapshot polled as the stream).

The daemon fetches the camera itself and serves it as ``/camera/stream`` and ``/camera/snapshot``
(``ribbond.api.routers.camera``) instead of handing the page the camera's address: a camera bound
to the printer's host (ustreamer's default is 127.0.0.1) is out of a phone's reach while the daemon
is not; the page's requests carry the API token in their header like every other (an ``<img>``
pointing at the camera could not, and the token never goes in a URL); and the daemon bounds what a
stream may hold. One upstream connection (``_Feed``) serves every viewer: each gets the newest
frame when it is ready for one (a slow phone skips frames, it never slows the camera or the
others), and the feed closes once no viewer has asked for a frame for ``IDLE_S``, so a viewer
that vanished without closing its connection does not keep the camera streaming. A camera that
sends nothing for ``FRAME_TIMEOUT_S`` ends the stream; the page reconnects.

At each side's end (the front printed: ``awaiting_flip``; the back, a one-sided front or a plain
program printed: ``done``) a snapshot is fetched off the print path, within ``SNAPSHOT_TIMEOUT_S``,
and kept in the job's folder as ``snapshot-front.jpg``, ``snapshot-back.jpg`` or
``snapshot-program.jpg`` (written whole, then renamed over the old one); the job's ``snapshots``
lists them and ``GET /jobs/{id}/files/{name}`` serves them. A camera that is down, slow or answers
with something that is not a JPEG is logged (and shown by ``GET /camera``); the job is neither
delayed nor changed.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import os
import secrets
import time
import urllib.parse
from collections.abc import AsyncIterator, Coroutine
from pathlib import Path
from typing import Any

import httpx

from ..config import CameraSettings
from ..jobs import JobState
from ..records import JobRecords, NotFound
from .mjpeg import MAX_FRAME_BYTES, MjpegParser, boundary_of, is_jpeg, part

log = logging.getLogger(__name__)

#: The whole fetch of a side's snapshot, s: past it the side ends without one.
SNAPSHOT_TIMEOUT_S = 5.0
#: Connecting to the camera, s.
CONNECT_TIMEOUT_S = 5.0
#: A stream that sends nothing for this long has stopped, s.
FRAME_TIMEOUT_S = 10.0
#: The feed closes when no viewer has asked for a frame for this long, s.
IDLE_S = 30.0
#: ``snapshot_url`` polled as the stream (no ``stream_url``): a frame every this many s.
POLL_S = 0.5
#: The boundary of the daemon's own stream (``/camera/stream``).
BOUNDARY = "ribbondframe"
#: The snapshot file of each side's end.
SNAPSHOT_FILES = {"front": "snapshot-front.jpg", "back": "snapshot-back.jpg", "program": "snapshot-program.jpg"}
_PRINTING = {JobState.PRINTING_FRONT.value, JobState.PRINTING_BACK.value}


class CameraError(Exception):
    """The camera did not answer, or not with JPEG frames (the API answers 502)."""


class NoCamera(NotFound):
    """No camera is configured (404)."""


def shown(url: str) -> str:
    """``url`` as logs and errors show it: without a user name and password."""
    parts = urllib.parse.urlsplit(url)
    host = parts.netloc.rpartition("@")[2]
    return urllib.parse.urlunsplit((parts.scheme, host, parts.path, parts.query, ""))


def ended_side(before: str | None, job: dict[str, Any]) -> str | None:
    """The side whose printing just ended, from the job's state before (as last seen) and its
    status now: ``front`` (a design's front, now awaiting the flip; a one-sided design done),
    ``back``, ``program`` (a plain G-code job done); None when no side ended."""
    state = job.get("state")
    if before not in _PRINTING or state == before:
        return None
    if state == JobState.AWAITING_FLIP.value:
        return "front"
    if state == JobState.DONE.value:
        return "program" if job.get("kind") == "gcode" else job.get("side") or "front"
    return None


class _Feed:
    """One connection to the camera shared by its viewers: the newest frame and its number."""

    def __init__(self) -> None:
        self.frame, self.number = b"", 0
        self.error: str | None = None
        self.closed = False
        self.pulled = time.monotonic()
        self._changed = asyncio.Event()

    def put(self, frame: bytes) -> None:
        self.frame, self.number = frame, self.number + 1
        self._wake()

    def close(self, error: str | None = None) -> None:
        self.closed, self.error = True, self.error or error
        self._wake()

    def _wake(self) -> None:
        changed, self._changed = self._changed, asyncio.Event()
        changed.set()

    async def after(self, seen: int) -> tuple[bytes, int] | None:
        """The newest frame once it is newer than frame ``seen``; None once the feed closed."""
        self.pulled = time.monotonic()
        while self.number <= seen and not self.closed:
            await self._changed.wait()
        return None if self.number <= seen else (self.frame, self.number)


class Camera:
    """The camera of ``settings``; ``run()`` keeps the snapshots of the jobs ``records`` publishes."""

    def __init__(self, settings: CameraSettings, records: JobRecords) -> None:
        self.settings, self.records = settings, records
        self._client: httpx.AsyncClient | None = None
        self._feed: _Feed | None = None
        self._tasks: set[asyncio.Task[None]] = set()
        self.last_error: str | None = None
        self.last_error_at: float | None = None

    # ------------------------------------------------------------------ what the API shows

    def view(self) -> dict[str, Any]:
        """Whether a camera is configured, which URL serves the stream and the snapshot, the last failure."""
        s = self.settings
        return {"configured": s.configured,
                "stream": "stream_url" if s.stream_url else "snapshot_url" if s.snapshot_url else None,
                "snapshot": "snapshot_url" if s.snapshot_url else "stream_url" if s.stream_url else None,
                "last_error": self.last_error, "last_error_at": self.last_error_at}

    def snapshots(self, job_dir: Path) -> list[dict[str, Any]]:
        """The snapshots kept in a job's folder, front to back: ``{"name", "taken"}`` (unix s)."""
        out = []
        for name in SNAPSHOT_FILES.values():
            with contextlib.suppress(OSError):
                out.append({"name": name, "taken": (job_dir / name).stat().st_mtime})
        return out

    async def open_stream(self) -> AsyncIterator[bytes]:
        """The camera as the daemon's MJPEG body (parts of ``BOUNDARY``), its first frame already
        there: NoCamera or CameraError are raised here, before a response begins."""
        feed = self._running_feed()
        first = await self._next(feed, 0, CONNECT_TIMEOUT_S + FRAME_TIMEOUT_S)
        return self._parts(feed, first)

    async def snapshot(self) -> bytes:
        """One JPEG: ``snapshot_url``'s, else the stream's next frame."""
        if self.settings.snapshot_url:
            return await self._fetch_snapshot()
        feed = self._running_feed()
        frame, _ = await self._next(feed, feed.number, SNAPSHOT_TIMEOUT_S)
        return frame

    # ------------------------------------------------------------------ the snapshots of the jobs

    async def run(self) -> None:
        """Follow the jobs' events; at each side's end keep a snapshot (a task of its own)."""
        if not self.settings.configured:
            return
        queue = self.records.bus.subscribe()
        before: dict[str, str] = {}
        try:
            while True:
                event = await queue.get()
                if event.get("type") == "deleted":
                    before.pop(str(event.get("job_id")), None)
                if event.get("type") != "job" or not isinstance(event.get("job"), dict):
                    continue
                job = event["job"]
                side = ended_side(before.get(job["id"]), job)
                before[job["id"]] = job["state"]
                if side is not None:
                    self._spawn(self.keep(job["id"], side))
        finally:
            self.records.bus.unsubscribe(queue)

    async def keep(self, job_id: str, side: str) -> None:
        """Fetch a snapshot and keep it with the job as its side's file; a failure is logged."""
        name = SNAPSHOT_FILES[side]
        try:
            jpeg = await asyncio.wait_for(self.snapshot(), SNAPSHOT_TIMEOUT_S)
        except (CameraError, asyncio.TimeoutError) as exc:
            self._failed(f"no {name} for job {job_id}: {exc or 'the camera did not answer in time'}")
            return
        except Exception as exc:  # noqa: BLE001 - a snapshot never reaches the job
            log.exception("camera: the snapshot of job %s", job_id)
            self._failed(f"no {name} for job {job_id}: {exc}")
            return
        folder = self.records.dir(job_id)
        if not folder.is_dir():
            return                                             # the job was deleted meanwhile
        try:
            await asyncio.to_thread(_write_whole, folder / name, jpeg)
        except OSError as exc:
            self._failed(f"{name} for job {job_id} not written: {exc}")
            return
        log.info("job %s: %s kept (%d bytes)", job_id, name, len(jpeg))
        with contextlib.suppress(NotFound):
            self.records.publish(self.records.get(job_id))     # its snapshots changed

    def _failed(self, message: str) -> None:
        log.warning("camera: %s", message)
        self.last_error, self.last_error_at = message, time.time()

    def _spawn(self, work: Coroutine[Any, Any, None]) -> None:
        task = asyncio.create_task(work)
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)

    async def close(self) -> None:
        """Stop the feed and the snapshots under way; close the HTTP client."""
        for task in list(self._tasks):
            task.cancel()
        for task in list(self._tasks):
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task
        if self._client is not None:
            await self._client.aclose()

    # ------------------------------------------------------------------ the feed

    def _running_feed(self) -> _Feed:
        if not self.settings.configured:
            raise NoCamera("no camera is configured ([camera] stream_url and snapshot_url are empty)")
        if self._feed is None or self._feed.closed:
            self._feed = _Feed()
            self._spawn(self._fill(self._feed))
        return self._feed

    async def _next(self, feed: _Feed, seen: int, timeout: float) -> tuple[bytes, int]:
        try:
            got = await asyncio.wait_for(feed.after(seen), timeout)
        except asyncio.TimeoutError:
            raise CameraError(f"no frame from the camera in {timeout:.0f} s") from None
        if got is None:
            raise CameraError(feed.error or "the camera's stream ended")
        return got

    async def _parts(self, feed: _Feed, first: tuple[bytes, int]) -> AsyncIterator[bytes]:
        frame, seen = first
        yield part(frame, BOUNDARY)
        while (got := await feed.after(seen)) is not None:
            frame, seen = got
            yield part(frame, BOUNDARY)

    async def _fill(self, feed: _Feed) -> None:
        """Read the camera into ``feed`` until it fails or nobody watches."""
        source = self._stream_frames() if self.settings.stream_url else self._polled_frames()
        try:
            async for frame in source:
                feed.put(frame)
                if time.monotonic() - feed.pulled > IDLE_S:
                    break                                      # nobody asked for a frame lately
            feed.close()
        except CameraError as exc:
            self._failed(str(exc))
            feed.close(str(exc))
        except Exception as exc:  # noqa: BLE001 - a camera's failure never reaches the daemon
            log.exception("camera feed")
            feed.close(f"the camera's feed failed: {exc}")
        finally:
            feed.close()
            with contextlib.suppress(Exception):
                await source.aclose()

    def _http(self) -> httpx.AsyncClient:
        if self._client is None:
            # the camera is on the printer's network: no proxy from the environment, no .netrc; and
            # httpx logs each request at INFO: a polled snapshot would fill the journal
            logging.getLogger("httpx").setLevel(logging.WARNING)
            self._client = httpx.AsyncClient(trust_env=False, follow_redirects=True)
        return self._client

    async def _stream_frames(self) -> AsyncIterator[bytes]:
        url = self.settings.stream_url
        timeout = httpx.Timeout(FRAME_TIMEOUT_S, connect=CONNECT_TIMEOUT_S)
        try:
            async with self._http().stream("GET", url, timeout=timeout) as r:
                if r.status_code != 200:
                    raise CameraError(f"the camera's stream {shown(url)} answered HTTP {r.status_code}")
                parser = MjpegParser(boundary_of(r.headers.get("content-type", "")))
                async for chunk in r.aiter_raw():
                    for frame in parser.feed(chunk):
                        yield frame
        except ValueError as exc:
            raise CameraError(f"{shown(url)}: {exc}") from None
        except httpx.HTTPError as exc:
            raise CameraError(f"the camera's stream {shown(url)}: {type(exc).__name__} {exc}".rstrip()) from None
        raise CameraError(f"the camera's stream {shown(url)} ended")

    async def _polled_frames(self) -> AsyncIterator[bytes]:
        while True:
            yield await self._fetch_snapshot()
            await asyncio.sleep(POLL_S)

    async def _fetch_snapshot(self) -> bytes:
        url = self.settings.snapshot_url
        try:
            async with self._http().stream("GET", url, timeout=SNAPSHOT_TIMEOUT_S) as r:
                if r.status_code != 200:
                    raise CameraError(f"the camera's snapshot {shown(url)} answered HTTP {r.status_code}")
                body = bytearray()
                async for chunk in r.aiter_bytes():
                    body += chunk
                    if len(body) > MAX_FRAME_BYTES:
                        raise CameraError(f"the camera's snapshot {shown(url)} is over {MAX_FRAME_BYTES} bytes")
        except httpx.HTTPError as exc:
            raise CameraError(f"the camera's snapshot {shown(url)}: {type(exc).__name__} {exc}".rstrip()) from None
        if not is_jpeg(body):
            kind = r.headers.get("content-type", "no Content-Type")
            raise CameraError(f"the camera's snapshot {shown(url)} is not a JPEG image ({kind[:40]})")
        return bytes(body)


def _write_whole(path: Path, data: bytes) -> None:
    """``path`` holding ``data``: written beside it and renamed over it (never half a file)."""
    tmp = path.with_name(f".{path.name}.{secrets.token_hex(4)}.tmp")
    try:
        with open(tmp, "wb") as out:
            out.write(data)
            out.flush()
            os.fsync(out.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
