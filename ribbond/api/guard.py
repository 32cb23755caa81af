"""The API's gate: an ASGI middleware that decides from the request line and headers alone, before
the application reads one byte of the body (issue 16).

In order:

1. ``Host`` must name this daemon (``HostRule``): the address of the socket the request came in on,
   the configured ``api.host``, ``localhost``/``127.0.0.1``/``[::1]`` for a loopback connection, the
   machine's host name (and ``NAME.local``) when listening beyond loopback, and ``api.allowed_hosts``.
   Anything else is a DNS-rebinding page in a local browser: 421.
2. A state-changing request (not GET/HEAD/OPTIONS) whose ``Origin`` (or, without one, ``Referer``)
   is not the daemon's own origin is a cross-site form or script: 403. No header (curl, ribbonctl)
   passes; the dashboard's own fetches carry its origin, which is the daemon's.
3. Every path but the documentation and the dashboard's static files needs the token, when one is
   configured: 401 before the body is read, so an unauthenticated upload is never spooled. It is
   sent as ``Authorization: Bearer <token>`` or, as OctoPrint's clients send it (issue 27), as
   ``X-Api-Key: <token>``, on every path alike.
4. The body: a declared ``Content-Length`` over the limit is 413 at once; an undeclared (chunked)
   one is counted as it is read and answered 413 the moment it passes the limit, whatever the
   application was doing with it (the multipart parser would otherwise turn the abort into a 400).

Every refusal is JSON (``{"detail": ...}`` plus the field it is about) with ``Connection: close``.
"""

from __future__ import annotations

import contextlib
import ipaddress
import json
import socket
import urllib.parse
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field
from typing import Any

from ribbond.daemon.config import is_loopback, short, split_host, tokens_match

Scope = dict[str, Any]
Message = dict[str, Any]
Receive = Callable[[], Awaitable[Message]]
Send = Callable[[Message], Awaitable[None]]

#: Methods that do not change state: the Origin rule does not apply to them.
SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})
#: Paths served without the token: the API's documentation and the dashboard's static files (they
#: hold no data; the page asks for the token when the API answers 401).
OPEN_PATHS = frozenset({"/", "/docs", "/openapi.json", "/favicon.ico"})
OPEN_PREFIXES = ("/docs-assets/", "/ui/")
_DEFAULT_PORTS = {"http": 80, "https": 443}


def _address(name: str) -> str:
    """An IP literal in one spelling (``::1`` for ``0:0::1``); other names as they are."""
    with contextlib.suppress(ValueError):
        return str(ipaddress.ip_address(name))
    return name


@dataclass(frozen=True)
class HostRule:
    """Which ``Host`` headers name this daemon.

    ``listen``: the configured ``api.host``; ``allowed``: ``api.allowed_hosts`` entries (a name
    without a port matches any port, e.g. behind a reverse proxy). The local socket's own address
    and, on loopback, the loopback names match with the port the request came in on.
    """

    listen: str
    allowed: tuple[str, ...] = ()
    names: frozenset[str] = field(init=False)
    pinned: frozenset[tuple[str, int]] = field(init=False)

    def __post_init__(self) -> None:
        names: set[str] = set()
        pinned: set[tuple[str, int]] = set()
        for entry in self.allowed:
            name, port = split_host(entry)
            if port is None:
                names.add(_address(name))
            else:
                pinned.add((_address(name), port))
        object.__setattr__(self, "names", frozenset(names))
        object.__setattr__(self, "pinned", frozenset(pinned))

    def _own_names(self, local: str) -> set[str]:
        # the listening address as configured, also 0.0.0.0 or :: (the daemon's api.url names it)
        own = {_address(local), _address(self.listen.strip().strip("[]").lower().rstrip("."))}
        if is_loopback(self.listen) or is_loopback(local):
            own |= {"localhost", "127.0.0.1", "::1"}
        if not is_loopback(self.listen):
            hostname = socket.gethostname().lower()
            own |= {hostname, f"{hostname}.local"}
        return own

    def allows(self, host: str, server: tuple[str, int] | None) -> bool:
        """Whether the ``Host`` header ``host`` names this daemon, for a request that came in on the
        local socket ``server`` (address, port; None when unknown: a test transport)."""
        try:
            name, port = split_host(host)
        except ValueError:
            return False
        name, port = _address(name), port if port is not None else 80
        if name in self.names or (name, port) in self.pinned:
            return True
        return server is not None and name in self._own_names(server[0]) and port == server[1]


def origin_of(url: str) -> str | None:
    """``host[:port]`` of an ``Origin`` or ``Referer`` value, lower case, the scheme's default port
    dropped; None for an opaque origin (``null``) or anything that is not an http(s) URL."""
    try:
        parts = urllib.parse.urlsplit(url.strip())
        port = parts.port
    except ValueError:
        return None
    if parts.scheme not in _DEFAULT_PORTS or not parts.hostname:
        return None
    host = parts.hostname.lower().rstrip(".")
    host = f"[{host}]" if ":" in host else host
    return host if port in (None, _DEFAULT_PORTS[parts.scheme]) else f"{host}:{port}"


def _host_key(host: str) -> str:
    """A ``Host`` header as ``origin_of`` spells it (the default ports dropped)."""
    name, port = split_host(host)
    name = f"[{name}]" if ":" in name else name
    return name if port in (None, 80, 443) else f"{name}:{port}"


@dataclass(frozen=True)
class Refusal:
    """A request answered by the gate: its status, JSON body and extra headers."""

    status: int
    body: dict[str, Any]
    headers: tuple[tuple[bytes, bytes], ...] = ()


@dataclass(frozen=True)
class Policy:
    """What the gate enforces: the token (None: none needed), the ``Host`` rule, the body limit."""

    token: str | None
    hosts: HostRule
    body_limit: int

    def check(self, scope: Scope) -> Refusal | None:
        """The refusal for a request's line and headers, or None to let it through."""
        headers = _headers(scope)
        host = headers.get("host")
        server = scope.get("server")
        if host is not None and not self.hosts.allows(host, tuple(server) if server else None):
            return Refusal(421, {"detail": f"Host {short(host)!r} does not name this daemon (a name for "
                                           "it goes in api.allowed_hosts)", "host": short(host)})
        if scope.get("method", "GET") not in SAFE_METHODS:
            refusal = _cross_origin(headers, host)
            if refusal is not None:
                return refusal
        if self.token is not None and not _is_open(scope.get("path", "")):
            if not tokens_match(given_token(headers), self.token):
                return Refusal(401, {"detail": "missing or wrong API token (Authorization: Bearer <token>, "
                                               "or X-Api-Key: <token> as OctoPrint's clients send it)"},
                               ((b"www-authenticate", b"Bearer"),))
        length = headers.get("content-length", "")
        if length.isdigit() and int(length) > self.body_limit:
            return self.too_large(int(length))
        return None

    def too_large(self, size: int) -> Refusal:
        return Refusal(413, {"detail": f"a request body of {size} bytes or more exceeds the limit of "
                                       f"{self.body_limit} bytes (limits.max_upload_mb)",
                             "limit": self.body_limit})


def _headers(scope: Scope) -> dict[str, str]:
    # latin-1: HTTP header bytes map one to one; a repeated header keeps its first value
    out: dict[str, str] = {}
    for key, value in scope.get("headers") or ():
        out.setdefault(key.decode("latin-1").lower(), value.decode("latin-1"))
    return out


def given_token(headers: dict[str, str]) -> str | None:
    """The token a request presents: ``Authorization: Bearer <token>``, else ``X-Api-Key: <token>``
    (all that OctoPrint's clients, the slicers among them, send)."""
    auth = headers.get("authorization", "")
    if auth[:7].lower() == "bearer ":
        return auth[7:]
    return headers.get("x-api-key")


def _is_open(path: str) -> bool:
    return path in OPEN_PATHS or path.startswith(OPEN_PREFIXES)


def _cross_origin(headers: dict[str, str], host: str | None) -> Refusal | None:
    """403 when a state-changing request comes from a page of another origin."""
    given = headers.get("origin")
    header = "Origin"
    if given is None:
        given, header = headers.get("referer"), "Referer"
    if given is None:
        return None
    try:
        own = _host_key(host) if host is not None else None
    except ValueError:
        own = None
    if own is not None and origin_of(given) == own:
        return None
    return Refusal(403, {"detail": f"cross-origin request refused: {header} {short(given)!r} is not this "
                                   "daemon's origin", "origin": short(given)})


class _Refused(Exception):
    """Raised inside the application's ``receive`` once the body passed the limit."""


class Guard:
    """The ASGI middleware enforcing ``policy`` in front of ``app`` (see the module's text)."""

    def __init__(self, app: Any, policy: Policy) -> None:
        self.app, self.policy = app, policy

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        refusal = self.policy.check(scope)
        if refusal is not None:
            await respond(send, refusal)
            return
        await self._limited(scope, receive, send)

    async def _limited(self, scope: Scope, receive: Receive, send: Send) -> None:
        """Run the app with its body counted: past the limit, 413 is sent at once and whatever the
        app sends afterwards (its own error for the aborted read) is dropped."""
        seen = 0
        refused = False
        started = False

        async def counted() -> Message:
            nonlocal seen, refused
            if refused:
                return {"type": "http.disconnect"}
            message = await receive()
            seen += len(message.get("body", b""))
            if seen > self.policy.body_limit:
                refused = True
                if not started:
                    await respond(send, self.policy.too_large(seen))
                raise _Refused()
            return message

        async def guarded_send(message: Message) -> None:
            nonlocal started
            if refused:
                return
            started = True
            await send(message)

        try:
            await self.app(scope, counted, guarded_send)
        except Exception:
            if not refused:
                raise


async def respond(send: Send, refusal: Refusal) -> None:
    """Send ``refusal`` as a complete JSON response that closes the connection (its body, if any,
    is not read)."""
    body = json.dumps(refusal.body).encode()
    headers = [(b"content-type", b"application/json"), (b"connection", b"close"),
               (b"content-length", str(len(body)).encode()), *refusal.headers]
    with contextlib.suppress(Exception):           # the client may be gone already
        await send({"type": "http.response.start", "status": refusal.status, "headers": headers})
        await send({"type": "http.response.body", "body": body})

