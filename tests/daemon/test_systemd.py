"""systemd integration: sd_notify against a real datagram socket, the unit file, the example config.

``make verify-unit`` runs ``systemd-analyze verify`` on the unit; these tests check what verify
cannot: that the directives the daemon relies on are there.
"""

from __future__ import annotations

import os
import socket
import sys
import tempfile
import tomllib
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

from ribbond.daemon import sdnotify
from ribbond.daemon.sdnotify import Notifier, notify

ROOT = Path(__file__).resolve().parents[2]
UNIT = ROOT / "systemd" / "ribbond.service"
EXAMPLE_CONFIG = ROOT / "systemd" / "ribbond.toml"

linux_only = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="abstract sockets are Linux-only")


# ---------------------------------------------------------------------------------------- sd_notify


class Receiver:
    """The systemd side: a bound AF_UNIX datagram socket."""

    def __init__(self, sock: socket.socket, name: str) -> None:
        self.sock = sock
        self.name = name  # what goes into $NOTIFY_SOCKET

    def receive(self) -> str:
        return self.sock.recv(4096).decode("utf-8")

    def nothing_pending(self) -> bool:
        self.sock.setblocking(False)
        try:
            self.sock.recv(4096)
        except BlockingIOError:
            return True
        finally:
            self.sock.settimeout(2.0)
        return False


@pytest.fixture
def receiver(tmp_path: Path) -> Iterator[Receiver]:
    path = tmp_path / "notify"
    short_dir = None
    if len(os.fsencode(path)) > 100:  # sun_path holds 108 bytes; a long $TMPDIR would not fit
        short_dir = Path(tempfile.mkdtemp(prefix="sd", dir="/tmp"))
        path = short_dir / "notify"
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    sock.bind(str(path))
    sock.settimeout(2.0)
    yield Receiver(sock, str(path))
    sock.close()
    if short_dir is not None:
        path.unlink(missing_ok=True)
        short_dir.rmdir()


@pytest.fixture
def abstract_receiver() -> Iterator[Receiver]:
    name = f"ribbond-test-{uuid.uuid4().hex}"
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    sock.bind("\0" + name)
    sock.settimeout(2.0)
    yield Receiver(sock, "@" + name)
    sock.close()


def test_notify_sends_the_state_as_one_datagram(receiver: Receiver) -> None:
    assert notify("READY=1\nSTATUS=up", environ={"NOTIFY_SOCKET": receiver.name}) is True
    assert receiver.receive() == "READY=1\nSTATUS=up"


@linux_only
def test_notify_reaches_an_abstract_socket(abstract_receiver: Receiver) -> None:
    assert notify("WATCHDOG=1", environ={"NOTIFY_SOCKET": abstract_receiver.name}) is True
    assert abstract_receiver.receive() == "WATCHDOG=1"


@pytest.mark.parametrize("environ", [{}, {"NOTIFY_SOCKET": ""}], ids=["unset", "empty"])
def test_notify_without_systemd_is_a_no_op(environ: dict[str, str]) -> None:
    assert notify("READY=1", environ=environ) is False


@pytest.mark.parametrize("name", ["relative/socket", "@", "vsock:2:1234"])
def test_notify_ignores_addresses_it_cannot_use(name: str) -> None:
    assert notify("READY=1", environ={"NOTIFY_SOCKET": name}) is False


def test_notify_send_errors_are_returned_not_raised(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    missing = tmp_path / "gone"
    not_a_socket = tmp_path / "file"
    not_a_socket.write_text("")
    caplog.set_level("DEBUG", logger=sdnotify.__name__)
    for name in (str(missing), str(not_a_socket), "/x" + "y" * 200, "/nul\0byte"):
        assert notify("READY=1", environ={"NOTIFY_SOCKET": name}) is False
    assert any("could not send" in r.message for r in caplog.records)


def test_notifier_ready_status_watchdog_stopping(receiver: Receiver) -> None:
    notifier = Notifier({"NOTIFY_SOCKET": receiver.name})
    assert notifier.enabled
    notifier.ready()
    assert receiver.receive() == "READY=1"
    notifier.ready("API on http://127.0.0.1:7125")
    assert receiver.receive() == "READY=1\nSTATUS=API on http://127.0.0.1:7125"
    notifier.status("printing front, 12 %")
    assert receiver.receive() == "STATUS=printing front, 12 %"
    notifier.watchdog()
    assert receiver.receive() == "WATCHDOG=1"
    notifier.stopping()
    assert receiver.receive() == "STOPPING=1"
    assert receiver.nothing_pending()


@linux_only
def test_notifier_on_an_abstract_socket(abstract_receiver: Receiver) -> None:
    notifier = Notifier({"NOTIFY_SOCKET": abstract_receiver.name})
    notifier.ready("up")
    assert abstract_receiver.receive() == "READY=1\nSTATUS=up"


def test_status_text_cannot_inject_assignments(receiver: Receiver) -> None:
    # A job name with a newline must not become a second assignment (MAINPID=, READY=, ...).
    Notifier({"NOTIFY_SOCKET": receiver.name}).status("job a\nMAINPID=1\r\nREADY=1")
    message = receiver.receive()
    assert message.startswith("STATUS=")
    assert "\n" not in message and "\r" not in message


def test_notifier_reads_the_environment_once(receiver: Receiver) -> None:
    # The daemon may strip NOTIFY_SOCKET from os.environ (children must not notify); the
    # notifier keeps working.
    environ = {"NOTIFY_SOCKET": receiver.name}
    notifier = Notifier(environ)
    environ.clear()
    notifier.watchdog()
    assert receiver.receive() == "WATCHDOG=1"


def test_notifier_outside_systemd_does_nothing() -> None:
    notifier = Notifier({})
    assert not notifier.enabled
    notifier.ready("up")
    notifier.status("x")
    notifier.watchdog()
    notifier.stopping()
    assert notifier.watchdog_interval() is None


def test_notifier_survives_systemd_going_away(tmp_path: Path) -> None:
    notifier = Notifier({"NOTIFY_SOCKET": str(tmp_path / "gone")})
    assert notifier.enabled
    notifier.ready("up")
    notifier.watchdog()  # nothing raised


def test_notifier_defaults_to_os_environ(receiver: Receiver, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("NOTIFY_SOCKET", receiver.name)
    Notifier().ready()
    assert receiver.receive() == "READY=1"
    monkeypatch.delenv("NOTIFY_SOCKET")
    assert not Notifier().enabled


@pytest.mark.parametrize(
    ("environ", "expected"),
    [
        ({"WATCHDOG_USEC": "30000000"}, 15.0),
        ({"WATCHDOG_USEC": "30000000", "WATCHDOG_PID": str(os.getpid())}, 15.0),
        ({"WATCHDOG_USEC": "1000"}, 0.0005),
        ({"WATCHDOG_USEC": "30000000", "WATCHDOG_PID": str(os.getpid() + 1)}, None),
        ({"WATCHDOG_USEC": "30000000", "WATCHDOG_PID": "not-a-pid"}, None),
        ({"WATCHDOG_PID": str(os.getpid())}, None),
        ({"WATCHDOG_USEC": ""}, None),
        ({"WATCHDOG_USEC": "0"}, None),
        ({"WATCHDOG_USEC": "-5"}, None),
        ({"WATCHDOG_USEC": "30s"}, None),
        ({}, None),
    ],
    ids=["usec", "own-pid", "short", "other-pid", "bad-pid", "pid-only", "empty", "zero", "negative",
         "not-a-number", "unset"],
)
def test_watchdog_interval(environ: dict[str, str], expected: float | None) -> None:
    interval = Notifier({"NOTIFY_SOCKET": "/run/systemd/notify", **environ}).watchdog_interval()
    assert interval == (pytest.approx(expected) if expected is not None else None)


# ---------------------------------------------------------------------------------------- the unit


def unit_directives() -> dict[str, dict[str, list[str]]]:
    """section -> key -> values in file order (keys such as DeviceAllow= repeat)."""
    sections: dict[str, dict[str, list[str]]] = {}
    current: dict[str, list[str]] | None = None
    for number, raw in enumerate(UNIT.read_text(encoding="utf-8").splitlines(), 1):
        line = raw.strip()
        if not line or line.startswith(("#", ";")):
            continue
        assert not line.endswith("\\"), f"line {number}: keep directives on one line"
        if line.startswith("[") and line.endswith("]"):
            current = sections.setdefault(line[1:-1], {})
            continue
        assert current is not None, f"line {number}: directive outside a section"
        key, sep, value = line.partition("=")
        assert sep, f"line {number}: not a KEY=value line: {line!r}"
        current.setdefault(key.strip(), []).append(value.strip())
    return sections


@pytest.fixture(scope="module")
def service() -> dict[str, list[str]]:
    return unit_directives()["Service"]


def single(service: dict[str, list[str]], key: str) -> str:
    values = service.get(key)
    assert values, f"{key}= missing from {UNIT.name}"
    assert len(values) == 1, f"{key}= given {len(values)} times"
    return values[0]


@pytest.mark.parametrize(
    ("key", "value"),
    [
        ("Type", "notify"),
        ("NotifyAccess", "main"),
        ("WatchdogSec", "30"),
        ("Restart", "on-failure"),
        ("RestartSec", "5"),
        ("RestartPreventExitStatus", "2"),  # ribbond's exit status for a configuration error
        ("User", "ribbond"),
        ("Group", "ribbond"),
        ("SupplementaryGroups", "dialout"),
        ("StateDirectory", "ribbond"),
        ("StateDirectoryMode", "0750"),
        ("RuntimeDirectory", "ribbond"),
        ("ConfigurationDirectory", "ribbond"),
        ("UMask", "0027"),
        ("KillSignal", "SIGTERM"),
        ("TimeoutStopSec", "30"),
        ("ExecStart", "/usr/local/bin/ribbond --config /etc/ribbond/ribbond.toml"),
    ],
)
def test_unit_service_settings(service: dict[str, list[str]], key: str, value: str) -> None:
    assert single(service, key) == value


@pytest.mark.parametrize(
    ("key", "value"),
    [
        ("NoNewPrivileges", "yes"),
        ("ProtectSystem", "strict"),
        ("ProtectHome", "yes"),
        ("PrivateTmp", "yes"),
        ("PrivateDevices", "no"),  # the serial port lives in the host's /dev
        ("DevicePolicy", "closed"),
        ("ProtectKernelTunables", "yes"),
        ("ProtectKernelModules", "yes"),
        ("ProtectControlGroups", "yes"),
        ("RestrictNamespaces", "yes"),
        ("LockPersonality", "yes"),
        ("SystemCallArchitectures", "native"),
    ],
)
def test_unit_hardening(service: dict[str, list[str]], key: str, value: str) -> None:
    assert single(service, key) == value


def test_unit_address_families(service: dict[str, list[str]]) -> None:
    # AF_UNIX carries sd_notify; INET/INET6 the HTTP API. Nothing else.
    assert set(single(service, "RestrictAddressFamilies").split()) == {"AF_UNIX", "AF_INET", "AF_INET6"}


def test_unit_allows_the_usb_serial_devices_only(service: dict[str, list[str]]) -> None:
    allowed = [value.split() for value in service.get("DeviceAllow", [])]
    assert ["char-ttyUSB", "rw"] in allowed
    assert ["char-ttyACM", "rw"] in allowed
    assert all(device.startswith("char-tty") for device, *_ in allowed), allowed


def test_unit_leaves_write_execute_memory_allowed(service: dict[str, list[str]]) -> None:
    # numpy/scipy may need W+X mappings (BLAS JIT kernels, libffi closures): see the unit's comment.
    assert "MemoryDenyWriteExecute" not in service


def test_unit_install_section() -> None:
    assert unit_directives()["Install"]["WantedBy"] == ["multi-user.target"]


# ---------------------------------------------------------------------------------------- example config


def test_example_config_parses_and_has_every_section() -> None:
    data = tomllib.loads(EXAMPLE_CONFIG.read_text(encoding="utf-8"))
    assert {"printer_profile", "state_dir", "log_level"} <= data.keys()
    assert {"serial", "api", "limits", "flip"} <= data.keys()
    assert data["state_dir"] == "/var/lib/ribbond"  # the unit's StateDirectory=
    assert "token" not in data["api"]  # a token in a config file is opt-in, not the example


def _fields(model: type, prefix: str = "") -> Iterator[str]:
    from pydantic import BaseModel

    for name, field in model.model_fields.items():  # type: ignore[attr-defined]
        annotation = field.annotation
        if isinstance(annotation, type) and issubclass(annotation, BaseModel):
            yield from _fields(annotation, f"{prefix}{name}.")
        else:
            yield prefix + name


def test_example_config_documents_every_setting() -> None:
    """Every key of ``DaemonConfig`` appears in the example, set or commented out, in its section."""
    config = pytest.importorskip("ribbond.daemon.config")
    text = EXAMPLE_CONFIG.read_text(encoding="utf-8")
    section = ""
    present: set[str] = set()
    for raw in text.splitlines():
        line = raw.lstrip("# ").strip()
        if line.startswith("[") and line.endswith("]") and raw.startswith("["):
            section = line[1:-1] + "."
        elif "=" in line:
            key = line.partition("=")[0].strip()
            if key.isidentifier():
                present.add(section + key)
    missing = set(_fields(config.DaemonConfig)) - present
    assert not missing, f"{EXAMPLE_CONFIG.name} does not mention: {sorted(missing)}"


def test_example_config_shows_the_defaults() -> None:
    config = pytest.importorskip("ribbond.daemon.config")
    assert config.load_config(EXAMPLE_CONFIG, environ={}) == config.DaemonConfig()
