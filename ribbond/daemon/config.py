"""The daemon's configuration: one TOML file, validated into ``DaemonConfig`` (issue 6).

The file is ``/etc/ribbond/ribbond.toml`` unless ``--config PATH`` or the environment variable
``RIBBOND_CONFIG`` names another (the flag wins). Every setting has a default, so a missing default
file means "all defaults"; a file that was asked for by name and is missing is an error, because
running on defaults then would silently ignore what the user meant to configure.

Relative paths in the file (``state_dir``, ``api.token_file``, a ``printer_profile`` ending in
``.toml``, ``design.cache_dir``) are taken relative to the file's directory: the daemon runs with ``/`` as its working
directory under systemd, where a path relative to the working directory means nothing useful.

This module also decides how the API is protected (``resolve_token``, ``tokens_match``,
``protection``): a configured token (``api.token`` or ``api.token_file``) is enforced wherever the
daemon listens, loopback included (a reverse proxy on the same host makes loopback reachable from
afar); on a loopback address with none configured the API is open to local users; on any other
address a token is required and, if none is configured, generated once and kept in a file only the
daemon can read.
Whatever the address, the API answers only requests whose ``Host`` names the daemon (its listening
address, the loopback names on loopback, the machine's name beyond it, and ``api.allowed_hosts``,
e.g. ``allowed_hosts = ["printer.local"]``) and refuses state-changing requests from another
origin (``ribbond.api.guard``).
"""

from __future__ import annotations

import hmac
import ipaddress
import logging
import os
import secrets
import stat
import tomllib
import urllib.parse
from collections.abc import Mapping
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, ValidationInfo, field_validator

#: Where the daemon looks when neither ``--config`` nor ``RIBBOND_CONFIG`` names a file.
DEFAULT_CONFIG = Path("/etc/ribbond/ribbond.toml")
#: The environment variable that names the configuration file (``--config`` takes precedence).
CONFIG_ENV = "RIBBOND_CONFIG"
#: The token file's name in the state directory when ``api.token_file`` is not set.
TOKEN_FILE_NAME = "api-token"


class SerialSettings(BaseModel):
    """The printer's serial port."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    port: str = Field("/dev/ttyUSB0", min_length=1, description="serial device of the printer")
    baud: int = Field(250000, gt=0, description="baud rate")
    # Safe for 64-byte receive buffers (Marlin's default is 128: set 127 for such a board, the
    # sender shrinks a window found too large); fewer than 16 cannot hold one G-code line.
    rx_buffer: int = Field(63, ge=16, description="bytes the sender keeps in flight (the printer's "
                                                  "receive buffer less one)")


class ApiSettings(BaseModel):
    """Where the REST API listens and how it is protected."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    host: str = Field("127.0.0.1", min_length=1, description="address to listen on")
    # 0 lets the OS pick a free port (tests); the daemon reports the one it got.
    port: int = Field(7125, ge=0, le=65535, description="TCP port, 0 for any free port")
    # repr=False: the configuration is logged at start, the token must not be.
    token: str | None = Field(None, repr=False, description="bearer token clients must send")
    token_file: Path | None = Field(None, description="token file; default <state_dir>/api-token")
    # The Host check (ribbond.api.guard) refuses names it does not know: a DNS-rebinding page would
    # otherwise reach the daemon from a browser on the host. Add the names clients use here.
    allowed_hosts: list[str] = Field(default_factory=list, description="more names of the daemon a Host "
                                     "header may give (e.g. printer.local, or printer.local:80 behind a proxy)")

    @field_validator("token")
    @classmethod
    def _token_not_blank(cls, value: str | None) -> str | None:
        # An empty token would let anyone in while looking configured: refuse it outright.
        if value is not None and not value.strip():
            raise ValueError("the token is empty; remove the key to have one generated, or set a real token")
        return value

    @field_validator("allowed_hosts")
    @classmethod
    def _hosts_valid(cls, value: list[str]) -> list[str]:
        for entry in value:
            split_host(entry)                  # ValueError names the entry
        return value


class Limits(BaseModel):
    """What one client can ask of the daemon."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    max_upload_mb: float = Field(64.0, gt=0, description="largest mesh upload, MiB")
    max_faces: int = Field(400_000, gt=0, description="largest mesh, in faces")
    max_jobs: int = Field(100, gt=0, description="jobs kept queued or active at once")


class FlipPolicy(BaseModel):
    """What happens to the heaters while a job waits for the operator: the fabric to be flipped for
    the back side, or a pause (resume reheats first)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    heaters: Literal["keep", "lower", "off"] = Field(
        "lower", description="keep the print temperatures, lower the nozzle to lower_to, or turn them off")
    lower_to: float = Field(170.0, gt=0, description="nozzle temperature while waiting (heaters = 'lower'), °C")
    off_after_s: float = Field(1800.0, ge=0, description="heaters off after this long waiting (the flip, "
                               "a pause), s; 0: never")


class ManualSettings(BaseModel):
    """The operator's direct control of the printer (``ribbonctl gcode``, the dashboard's console)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    # Off: typed G-code passes the same check as a plain G-code job (frame, fabric, temperatures,
    # feed rates). On: sent unchecked, each command logged as such; for the few who need raw access.
    raw_console: bool = Field(False, strict=True, description="send typed G-code unchecked (logged); "
                              "default false: checked like a plain G-code job")


class DesignSettings(BaseModel):
    """What a compile makes."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    # The deploy stage (the released sheet, three ways) is 5-30 s of each compile; a slow host may
    # leave it to `ribbonctl predict --job` (POST /jobs/{id}/predict), asked for when wanted.
    predict: bool = Field(True, strict=True, description="predict the deployed shape in every compile "
                          "(deployed.obj, deployed.png, report.deployed); false: compile without it")
    optimize: bool = Field(True, strict=True, description="optimize each layout's ribbon thicknesses against "
                           "the prediction (up to [solver] optimize_budget_s, 45 s by default; with predict; kept "
                           "only where the optimized layout's own prediction is better); "
                           "false: the paper's forward design for every job")
    # A mesh submitted again with the same parameters gets its design at once (components/compile_cache.py);
    # the key holds the engine's own files, so an updated engine never serves an older design.
    cache_dir: str | None = Field(None, description="compiled designs kept by their inputs (mesh, parameters, "
                                  "tables, profile, engine) and served again at once; default "
                                  "<state_dir>/compile-cache; \"\" turns the cache off")

    @field_validator("cache_dir")
    @classmethod
    def _cache_dir_meant(cls, value: str | None) -> str | None:
        if value is not None and value != "" and not value.strip():
            raise ValueError('blank: give a folder, or "" to turn the compile cache off')
        return value


#: What ``[notify] events`` may name: each is one moment the operator is needed or told.
NOTIFY_EVENTS = ("awaiting_flip", "alignment", "fresh_frame", "done", "failed", "interrupted", "halted")


class NotifySettings(BaseModel):
    """Notifications (Apprise URLs) when a job needs the operator or ends; sent off the print path."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    # repr=False: service URLs carry tokens and passwords, and the configuration is logged at start.
    urls: list[str] = Field(default_factory=list, repr=False, description="Apprise URLs (ntfy://, tgram://, "
                            "mailto://, json://, ...); none: no notifications")
    events: list[str] = Field(default_factory=lambda: list(NOTIFY_EVENTS), description="the events notified: "
                              + ", ".join(NOTIFY_EVENTS))
    timeout_s: float = Field(10.0, gt=0, le=300, description="a send not done in this long counts as "
                             "failed (timeout), s; the service's own connect and read timeouts are 1 s longer")

    @field_validator("events")
    @classmethod
    def _events_known(cls, value: list[str]) -> list[str]:
        for name in value:
            if name not in NOTIFY_EVENTS:
                raise ValueError(f"{short(name)!r} is not an event; the events are: {', '.join(NOTIFY_EVENTS)}")
        return value

    @field_validator("urls")
    @classmethod
    def _urls_usable(cls, value: list[str]) -> list[str]:
        for i, url in enumerate(value):
            problem = notify_url_problem(url)
            if problem:
                raise ValueError(f"URL {i + 1} ({url_scheme(url)}): {problem}")
        return value


def url_scheme(url: str) -> str:
    """``"tgram://…"``: the URL named without the parts that may be secret."""
    scheme, sep, _ = url.strip().partition("://")
    return f"{short(scheme, 16)}://…" if sep and scheme else repr(short(url, 8) + "…")


def notify_url_problem(url: str) -> str | None:
    """Why Apprise cannot use ``url`` (None: it can). Imported here only when URLs are configured."""
    import apprise

    scheme, sep, _ = url.strip().partition("://")
    if not sep:
        return "not a URL: Apprise URLs are written SERVICE://..., e.g. ntfy://TOPIC or json://HOST/PATH"
    if scheme.lower() not in apprise.NotificationManager():
        return f"no Apprise service is called {short(scheme, 16)}://"
    quiet = logging.getLogger("apprise")           # its own error echoes the URL, secrets and all
    level, quiet.level = quiet.level, logging.CRITICAL
    try:
        plugin = apprise.Apprise.instantiate(url)
    finally:
        quiet.setLevel(level)
    if plugin is None:
        return (f"Apprise cannot use this {short(scheme, 16)}:// URL (parts missing or invalid; each service's "
                "form: https://github.com/caronc/apprise/wiki)")
    return None


def check_camera_url(value: str, name: str) -> str:
    """``value`` stripped if it is empty or an absolute http(s) URL with a host; else ValueError naming ``name``."""
    text = value.strip()
    if not text:
        return ""
    parts = urllib.parse.urlsplit(text)
    try:
        parts.port                             # noqa: B018 - raises ValueError on a bad port
    except ValueError:
        raise ValueError(f"{name} {short(text)!r}: the port is not a number from 0 to 65535") from None
    if parts.scheme not in ("http", "https") or not parts.hostname:
        raise ValueError(f"{name} {short(text)!r}: expected an http:// or https:// URL with a host, "
                         "e.g. http://127.0.0.1:8080/stream, or \"\" for none")
    return text


class CameraSettings(BaseModel):
    """The printer's camera, as crowsnest, ustreamer or mjpg-streamer serve one (issue 27)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    # Either may be empty: the other stands in (a frame of the stream as the snapshot, the snapshot
    # polled as the stream). The daemon fetches both itself: the page gets them through /camera.
    stream_url: str = Field("", description="MJPEG stream (multipart/x-mixed-replace), e.g. "
                            "http://127.0.0.1:8080/stream; empty: none")
    snapshot_url: str = Field("", description="one JPEG, e.g. http://127.0.0.1:8080/snapshot; empty: none")

    @field_validator("stream_url", "snapshot_url")
    @classmethod
    def _url(cls, value: str, info: ValidationInfo) -> str:
        return check_camera_url(value, str(info.field_name))

    @property
    def configured(self) -> bool:
        return bool(self.stream_url or self.snapshot_url)


class DaemonConfig(BaseModel):
    """Everything ``ribbond`` reads from its configuration file; every field has a default."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    serial: SerialSettings = SerialSettings()
    printer_profile: str = Field("ultimaker2-tpu", min_length=1,
                                 description="a shipped profile name or the path of a .toml file")
    state_dir: Path = Field(Path("/var/lib/ribbond"), description="jobs database, uploads, designs, token")
    api: ApiSettings = ApiSettings()
    limits: Limits = Limits()
    flip: FlipPolicy = FlipPolicy()
    manual: ManualSettings = ManualSettings()
    design: DesignSettings = DesignSettings()
    notify: NotifySettings = NotifySettings()
    camera: CameraSettings = CameraSettings()
    log_level: Literal["debug", "info", "warning", "error"] = "info"

    @property
    def compile_cache_dir(self) -> Path | None:
        """``[design] cache_dir``: ``<state_dir>/compile-cache`` when not set, None when ``""`` (off)."""
        if self.design.cache_dir is None:
            return Path(self.state_dir) / "compile-cache"
        return Path(self.design.cache_dir) if self.design.cache_dir else None

    @property
    def token_path(self) -> Path:
        """The API token file: ``api.token_file``, else ``<state_dir>/api-token``."""
        return self.api.token_file if self.api.token_file is not None else self.state_dir / TOKEN_FILE_NAME


def config_path(flag: str | Path | None, environ: Mapping[str, str]) -> tuple[Path, bool]:
    """The configuration file to read, and whether it was asked for explicitly.

    Parameters
    ----------
    flag
        the ``--config`` value, or None when the flag was not given.
    environ
        the environment; ``RIBBOND_CONFIG`` is used when the flag is absent (an empty value counts
        as unset, as shells make it easy to export one by accident).

    Returns
    -------
    (path, explicit)
        ``explicit`` is True for a path from the flag or the environment, False for
        ``DEFAULT_CONFIG``.
    """
    if flag is not None and str(flag) != "":
        return Path(flag), True
    from_env = environ.get(CONFIG_ENV, "")
    if from_env.strip():
        return Path(from_env), True
    return DEFAULT_CONFIG, False


def _format_errors(exc: ValidationError) -> str:
    return "; ".join(f"{'.'.join(str(p) for p in e['loc']) or '(file)'}: {e['msg']}" for e in exc.errors())


def _relative_to(base: Path, path: Path) -> Path:
    return path if path.is_absolute() else base / path


def load_config(path: str | Path | None = None, *, environ: Mapping[str, str] = os.environ) -> DaemonConfig:
    """Read and validate the daemon's configuration.

    Parameters
    ----------
    path
        the ``--config`` value (None when not given); see ``config_path`` for the precedence.
    environ
        the environment to read ``RIBBOND_CONFIG`` from.

    Raises
    ------
    ValueError
        ``"<path>: ..."``: the explicitly requested file is missing or unreadable, the TOML is
        invalid (the message gives the line and column), or fields are invalid (each named by its
        path, e.g. ``api.port: ...``).
    """
    file, explicit = config_path(path, environ)
    if not file.exists():
        if not explicit:
            return DaemonConfig()
        source = "--config" if path is not None and str(path) != "" else CONFIG_ENV
        raise ValueError(f"{file}: configuration file not found (named by {source})")
    if not file.is_file():
        raise ValueError(f"{file}: the configuration must be a file")
    try:
        data = tomllib.loads(file.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"{file}: cannot read the configuration: {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        # tomllib's message carries "(at line L, column C)".
        raise ValueError(f"{file}: invalid TOML: {exc}") from None
    try:
        config = DaemonConfig.model_validate(data)
    except ValidationError as exc:
        raise ValueError(f"{file}: invalid configuration: {_format_errors(exc)}") from None

    base = file.parent.absolute()
    api = config.api
    if api.token_file is not None:
        api = api.model_copy(update={"token_file": _relative_to(base, api.token_file)})
    profile = config.printer_profile
    if profile.endswith(".toml"):
        profile = str(_relative_to(base, Path(profile)))
    design = config.design
    if design.cache_dir:
        design = design.model_copy(update={"cache_dir": str(_relative_to(base, Path(design.cache_dir)))})
    return config.model_copy(update={"state_dir": _relative_to(base, config.state_dir),
                                      "api": api, "printer_profile": profile, "design": design})


#: Reflected values (a host, an origin) are cut to this many characters.
ECHO_MAX = 64


def short(value: str, limit: int = ECHO_MAX) -> str:
    """``value`` cut to ``limit`` characters, with "…" when it was longer: what an error echoes."""
    return value if len(value) <= limit else value[:limit] + "…"


def split_host(value: str) -> tuple[str, int | None]:
    """``(name, port)`` of a ``Host`` header or an ``allowed_hosts`` entry: lower case, without the
    brackets of an IPv6 literal or a trailing dot; port None when absent.

    Raises ValueError naming the value when it is not ``NAME``, ``NAME:PORT``, ``[V6]`` or ``[V6]:PORT``.
    """
    text = value.strip().lower()
    if text.startswith("["):
        name, sep, rest = text[1:].partition("]")
        if not sep or (rest and not rest.startswith(":")):
            raise ValueError(f"host {short(value)!r}: an IPv6 address is written [ADDRESS] or [ADDRESS]:PORT")
        port_text = rest[1:] if rest else None
    elif text.count(":") == 1:
        name, port_text = text.split(":")
    else:
        name, port_text = text, None
    name = name.rstrip(".")
    if not name or any(c.isspace() or c in "/@?#[]" for c in name) or (":" in name and not text.startswith("[")):
        raise ValueError(f"host {short(value)!r}: expected a host name or address, optionally with :PORT")
    if port_text is None:
        return name, None
    if not port_text.isdigit() or not 0 < int(port_text) < 65536:
        raise ValueError(f"host {short(value)!r}: the port must be 1 to 65535")
    return name, int(port_text)


def is_loopback(host: str) -> bool:
    """Whether listening on ``host`` accepts local connections only.

    True for ``localhost``, 127.0.0.0/8, ``::1`` (with or without brackets) and IPv4-mapped
    loopback addresses; False for everything else, including ``""`` and ``0.0.0.0`` (all
    interfaces) and other host names (what they resolve to can change).
    """
    name = host.strip()
    if name.lower().rstrip(".") == "localhost":
        return True
    if name.startswith("[") and name.endswith("]"):
        name = name[1:-1]
    try:
        address = ipaddress.ip_address(name)
    except ValueError:
        return False
    if isinstance(address, ipaddress.IPv6Address) and address.ipv4_mapped is not None:
        return address.ipv4_mapped.is_loopback
    return address.is_loopback


def _read_token_file(path: Path) -> str:
    try:
        with open(path, "rb") as handle:
            # fstat on the open file: the mode checked is the mode of the file read.
            mode = os.fstat(handle.fileno()).st_mode
            if mode & (stat.S_IRWXG | stat.S_IRWXO):
                raise ValueError(f"{path}: the API token file is accessible by group or others "
                                 f"(mode {stat.S_IMODE(mode):o}); run: chmod 600 {path}")
            raw = handle.read()
    except OSError as exc:
        raise ValueError(f"{path}: cannot read the API token file: {exc}") from None
    try:
        token = raw.decode("utf-8").strip()
    except UnicodeDecodeError:
        raise ValueError(f"{path}: the API token file is not UTF-8 text") from None
    if not token:
        raise ValueError(f"{path}: the API token file is empty; delete it to have a new token "
                         "generated, or write a token into it")
    return token


def _write_token_file(path: Path, token: str) -> None:
    """Create ``path`` holding ``token``, mode 0600, atomically (never a partly written file)."""
    directory = path.parent
    if not directory.exists():
        directory.mkdir(mode=0o700, parents=True)
    tmp = directory / f".{path.name}.{secrets.token_hex(4)}.tmp"
    fd = os.open(tmp, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o600)
    try:
        try:
            os.fchmod(fd, 0o600)  # exactly 0600, whatever the umask left
            os.write(fd, (token + "\n").encode("utf-8"))
            os.fsync(fd)
        finally:
            os.close(fd)
        os.rename(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    # The rename is durable only once the directory entry is on disk.
    dir_fd = os.open(directory, os.O_RDONLY)
    try:
        os.fsync(dir_fd)
    finally:
        os.close(dir_fd)


def resolve_token(config: DaemonConfig) -> str | None:
    """The token API clients must present, or None when none is needed.

    ``api.token`` if configured. Else, when ``api.token_file`` is configured or the address is not
    loopback, the content of the token file (``config.token_path``, stripped), else a new
    ``secrets.token_urlsafe(32)`` written to the token file (mode 0600, created atomically, its
    directory created with mode 0700 if missing) and reused on later starts. On a loopback address
    with neither configured: None (the default token file is not read there: an API left open on
    purpose stays open).

    Raises
    ------
    ValueError
        naming the token file: it is readable or writable by group or others (chmod 600), empty,
        or cannot be read or written.
    """
    if config.api.token is not None:
        return config.api.token
    if is_loopback(config.api.host) and config.api.token_file is None:
        return None
    path = config.token_path
    if path.exists():
        return _read_token_file(path)
    token = secrets.token_urlsafe(32)
    try:
        _write_token_file(path, token)
    except OSError as exc:
        raise ValueError(f"{path}: cannot create the API token file: {exc}") from None
    return token


def protection(config: DaemonConfig, token: str | None, url: str) -> str:
    """The log line saying whether the API at ``url`` is protected, and by what."""
    if token is None:
        return f"API on {url}: open: no token; anyone on this machine can drive the printer"
    where = "api.token in the configuration" if config.api.token is not None else str(config.token_path)
    return f"API on {url}: protected by the token in {where}"


def tokens_match(given: str | None, expected: str) -> bool:
    """Whether a client's token equals the expected one, in constant time.

    None or an empty string never matches (neither does anything when ``expected`` is empty).
    """
    if not given or not expected:
        return False
    return hmac.compare_digest(given.encode("utf-8"), expected.encode("utf-8"))
