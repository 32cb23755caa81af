"""``ribbonctl``'s HTTP client: one client (the standard library's ``http.client``) over the daemon's REST
API, its errors (``ClientError``: the exit status), and the client a command's options name (``_client``).
Nothing here imports the design engine (a command starts in a fraction of a second, also on a
Raspberry Pi). The commands are in ``jobs``, ``printer``, ``tables``, ``projects`` and ``notify``;
``commands`` adds them to ``ribbonctl``'s parser; ``output`` is what people read.
"""

from __future__ import annotations

import argparse
import http.client
import json
import json as _json
import os
import select
import sys
import urllib.parse
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from .output import Bar


DEFAULT_URL = "http://127.0.0.1:7125"


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


def _client(args: argparse.Namespace) -> Client:
    token = args.token or os.environ.get("RIBBOND_TOKEN")
    if token is None and args.token_file:
        try:
            token = Path(args.token_file).read_text(encoding="utf-8").strip()
        except OSError as exc:
            raise ClientError(f"cannot read the token file {args.token_file}: {exc.strerror}", 2) from None
    return Client(args.url or os.environ.get("RIBBOND_URL", DEFAULT_URL), token)
