"""The daemon's configuration file and the API token: defaults, validation, precedence, token files."""

from __future__ import annotations

import json
import os
import stat
from pathlib import Path
from typing import Any

import pytest

import ribbond.daemon.config as config_mod
from ribbond.daemon.config import (
    CONFIG_ENV,
    ApiSettings,
    CameraSettings,
    DaemonConfig,
    DesignSettings,
    FlipPolicy,
    Limits,
    ManualSettings,
    NotifySettings,
    SerialSettings,
    config_path,
    is_loopback,
    load_config,
    resolve_token,
    tokens_match,
)


def to_toml(data: dict[str, Any]) -> str:
    """A minimal TOML writer for the configuration's shape: scalars, then one table per sub-dict."""
    def scalar(value: Any) -> str:
        return json.dumps(value)  # strings, numbers and booleans are spelled alike in TOML and JSON

    lines = [f"{k} = {scalar(v)}" for k, v in data.items() if not isinstance(v, dict) and v is not None]
    for key, table in data.items():
        if isinstance(table, dict):
            lines.append(f"\n[{key}]")
            lines += [f"{k} = {scalar(v)}" for k, v in table.items() if v is not None]
    return "\n".join(lines) + "\n"


def write_config(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


@pytest.fixture
def no_default(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """Point the default configuration path at a file that does not exist."""
    missing = tmp_path / "etc" / "ribbond.toml"
    monkeypatch.setattr(config_mod, "DEFAULT_CONFIG", missing)
    return missing


# -- defaults and round trip ------------------------------------------------------------------------

def test_defaults_are_valid_and_consistent() -> None:
    config = DaemonConfig()
    # Every section's default is the section's own default model.
    assert config.serial == SerialSettings()
    assert config.api == ApiSettings()
    assert config.limits == Limits()
    assert config.flip == FlipPolicy()
    # The defaults validate as given (what the daemon runs with when there is no file).
    assert DaemonConfig.model_validate(config.model_dump()) == config
    assert config.api.token is None and config.api.token_file is None
    assert config.token_path == config.state_dir / config_mod.TOKEN_FILE_NAME
    assert is_loopback(config.api.host), "by default the API must listen on loopback only"


def test_missing_default_file_means_defaults(no_default: Path) -> None:
    assert not no_default.exists()
    assert load_config(None, environ={}) == DaemonConfig()


def test_empty_file_means_defaults(tmp_path: Path) -> None:
    path = write_config(tmp_path / "ribbond.toml", "")
    assert load_config(path, environ={}) == DaemonConfig()


def test_full_round_trip(tmp_path: Path) -> None:
    config = DaemonConfig(
        serial=SerialSettings(port="/dev/ttyACM3", baud=115200, rx_buffer=127),
        printer_profile="generic-marlin",
        state_dir=tmp_path / "state",
        api=ApiSettings(host="0.0.0.0", port=8125, token="s3cret-token",
                        token_file=tmp_path / "secrets" / "token", allowed_hosts=["printer.local", "[::1]:8125"]),
        limits=Limits(max_upload_mb=12.5, max_faces=1000, max_jobs=3),
        flip=FlipPolicy(heaters="off", lower_to=150.0, off_after_s=60.0),
        manual=ManualSettings(raw_console=True),
        design=DesignSettings(predict=False, optimize=False, cache_dir=str(tmp_path / "cache")),
        notify=NotifySettings(urls=["json://127.0.0.1:9/hook"], events=["done", "halted"], timeout_s=3.0),
        camera=CameraSettings(stream_url="http://127.0.0.1:8080/stream", snapshot_url="http://cam.local/snapshot"),
        log_level="debug",
    )
    # Every field differs from its default, so a field the loader dropped would show.
    defaults = DaemonConfig().model_dump()
    for section, values in config.model_dump().items():
        if isinstance(values, dict):
            for key, value in values.items():
                assert value != defaults[section][key], f"{section}.{key}"
        else:
            assert values != defaults[section], section
    path = write_config(tmp_path / "ribbond.toml", to_toml(config.model_dump(mode="json")))
    assert load_config(path, environ={}) == config


def test_relative_paths_are_relative_to_the_file(tmp_path: Path) -> None:
    directory = tmp_path / "conf"
    directory.mkdir()
    path = write_config(directory / "ribbond.toml", 'state_dir = "state"\nprinter_profile = "p/mine.toml"\n'
                                                    '[api]\ntoken_file = "keys/token"\n')
    config = load_config(path, environ={})
    assert config.state_dir == directory / "state"
    assert config.api.token_file == directory / "keys" / "token"
    assert Path(config.printer_profile) == directory / "p" / "mine.toml"
    # A shipped profile name is a name, not a path.
    named = load_config(write_config(directory / "named.toml", 'printer_profile = "generic-marlin"\n'), environ={})
    assert named.printer_profile == "generic-marlin"


# -- refused files ------------------------------------------------------------------------------------

@pytest.mark.parametrize(("text", "field"), [
    ("[api]\nprot = 8000\n", "api.prot"),
    ("colour = 'red'\n", "colour"),
    ("[serial]\nport = '/dev/ttyS0'\nspeed = 9600\n", "serial.speed"),
    ("[webcam]\nurl = 'x'\n", "webcam"),
])
def test_unknown_key_refused_with_its_path(tmp_path: Path, text: str, field: str) -> None:
    path = write_config(tmp_path / "ribbond.toml", text)
    with pytest.raises(ValueError) as err:
        load_config(path, environ={})
    message = str(err.value)
    assert message.startswith(f"{path}:")
    assert f"{field}:" in message


@pytest.mark.parametrize(("text", "field"), [
    ("[serial]\nbaud = 'fast'\n", "serial.baud"),
    ("[serial]\nbaud = 0\n", "serial.baud"),
    ("[serial]\nrx_buffer = 15\n", "serial.rx_buffer"),
    ("[api]\nport = 65536\n", "api.port"),
    ("[api]\nport = -1\n", "api.port"),
    ("[api]\ntoken = ''\n", "api.token"),
    ("[api]\ntoken = '   '\n", "api.token"),
    ("[limits]\nmax_upload_mb = 0\n", "limits.max_upload_mb"),
    ("[limits]\nmax_jobs = 'many'\n", "limits.max_jobs"),
    ("[flip]\nheaters = 'cold'\n", "flip.heaters"),
    ("[flip]\noff_after_s = -1\n", "flip.off_after_s"),
    ("log_level = 'verbose'\n", "log_level"),
    ("[design]\npredict = 'yes'\n", "design.predict"),
    ("api = 7125\n", "api"),
    ("state_dir = 3\n", "state_dir"),
])
def test_bad_values_refused_with_their_path(tmp_path: Path, text: str, field: str) -> None:
    path = write_config(tmp_path / "ribbond.toml", text)
    with pytest.raises(ValueError) as err:
        load_config(path, environ={})
    message = str(err.value)
    assert message.startswith(f"{path}:")
    assert f"{field}:" in message


def test_port_zero_allowed_for_tests(tmp_path: Path) -> None:
    path = write_config(tmp_path / "ribbond.toml", "[api]\nport = 0\n")
    assert load_config(path, environ={}).api.port == 0


def test_toml_syntax_error_names_the_line(tmp_path: Path) -> None:
    text = "log_level = 'info'\n[serial]\nbaud = = 3\n"
    bad_line = text.splitlines().index("baud = = 3") + 1
    path = write_config(tmp_path / "ribbond.toml", text)
    with pytest.raises(ValueError) as err:
        load_config(path, environ={})
    assert str(err.value).startswith(f"{path}:")
    assert f"line {bad_line}" in str(err.value)


def test_explicit_missing_file_is_an_error(tmp_path: Path, no_default: Path) -> None:
    missing = tmp_path / "nowhere.toml"
    with pytest.raises(ValueError) as err:
        load_config(missing, environ={})
    assert str(missing) in str(err.value) and "--config" in str(err.value)
    with pytest.raises(ValueError) as err:
        load_config(None, environ={CONFIG_ENV: str(missing)})
    assert str(missing) in str(err.value) and CONFIG_ENV in str(err.value)


def test_directory_refused(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="must be a file"):
        load_config(tmp_path, environ={})


# -- which file ---------------------------------------------------------------------------------------

def test_config_path_precedence(tmp_path: Path, no_default: Path) -> None:
    flag, env = tmp_path / "flag.toml", tmp_path / "env.toml"
    assert config_path(flag, {CONFIG_ENV: str(env)}) == (flag, True)
    assert config_path(str(flag), {}) == (flag, True)
    assert config_path(None, {CONFIG_ENV: str(env)}) == (env, True)
    assert config_path(None, {}) == (no_default, False)
    assert config_path(None, {CONFIG_ENV: ""}) == (no_default, False)  # exported but empty: unset


def test_load_config_precedence(tmp_path: Path, no_default: Path) -> None:
    flag = write_config(tmp_path / "flag.toml", "log_level = 'debug'\n")
    env = write_config(tmp_path / "env.toml", "log_level = 'error'\n")
    no_default.parent.mkdir()
    write_config(no_default, "log_level = 'warning'\n")
    assert load_config(flag, environ={CONFIG_ENV: str(env)}).log_level == "debug"
    assert load_config(None, environ={CONFIG_ENV: str(env)}).log_level == "error"
    assert load_config(None, environ={}).log_level == "warning"


# -- loopback and tokens ------------------------------------------------------------------------------

@pytest.mark.parametrize(("host", "loopback"), [
    ("127.0.0.1", True), ("127.1.2.3", True), ("127.255.255.254", True),
    ("::1", True), ("[::1]", True), ("localhost", True), ("LOCALHOST", True), ("localhost.", True),
    ("::ffff:127.0.0.1", True),
    ("0.0.0.0", False), ("::", False), ("", False), ("192.168.1.20", False), ("10.0.0.1", False),
    ("128.0.0.1", False), ("::2", False), ("::ffff:192.168.1.1", False),
    ("localhost.example.com", False), ("printer.local", False), ("127.0.0.1.nip.io", False),
])
def test_is_loopback(host: str, loopback: bool) -> None:
    assert is_loopback(host) is loopback


def public(tmp_path: Path, **api: Any) -> DaemonConfig:
    return DaemonConfig(state_dir=tmp_path / "state", api=ApiSettings(host="0.0.0.0", **api))


def test_loopback_needs_no_token(tmp_path: Path) -> None:
    config = DaemonConfig(state_dir=tmp_path / "state")
    assert resolve_token(config) is None
    assert not config.token_path.exists() and not (tmp_path / "state").exists()
    configured = DaemonConfig(state_dir=tmp_path / "state", api=ApiSettings(token="abc"))
    assert resolve_token(configured) == "abc"


def test_configured_token_wins(tmp_path: Path) -> None:
    config = public(tmp_path, token="configured")
    assert resolve_token(config) == "configured"
    assert not config.token_path.exists()


def test_token_generated_once_with_mode_600(tmp_path: Path) -> None:
    config = public(tmp_path)
    token = resolve_token(config)
    assert token is not None and len(token) >= 32
    path = config.token_path
    assert path == tmp_path / "state" / config_mod.TOKEN_FILE_NAME
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    assert stat.S_IMODE(path.parent.stat().st_mode) & 0o077 == 0
    assert path.read_text(encoding="utf-8").strip() == token
    # No temporary file is left beside it.
    assert sorted(p.name for p in path.parent.iterdir()) == [path.name]
    # Later starts reuse it.
    assert resolve_token(config) == token
    assert resolve_token(public(tmp_path)) == token


def test_token_file_under_umask_is_still_600(tmp_path: Path) -> None:
    old = os.umask(0o000)
    try:
        config = public(tmp_path)
        resolve_token(config)
    finally:
        os.umask(old)
    assert stat.S_IMODE(config.token_path.stat().st_mode) == 0o600


def test_token_file_setting_used(tmp_path: Path) -> None:
    token_file = tmp_path / "elsewhere" / "tok"
    config = public(tmp_path, token_file=token_file)
    token = resolve_token(config)
    assert token_file.read_text(encoding="utf-8").strip() == token
    assert not (tmp_path / "state").exists()


def test_existing_token_file_read_stripped(tmp_path: Path) -> None:
    config = public(tmp_path)
    config.token_path.parent.mkdir(mode=0o700)
    fd = os.open(config.token_path, os.O_CREAT | os.O_WRONLY, 0o600)
    os.write(fd, b"  my-token \n\n")
    os.close(fd)
    assert resolve_token(config) == "my-token"


@pytest.mark.parametrize("content", [b"", b"  \n\t\n"])
def test_empty_token_file_refused(tmp_path: Path, content: bytes) -> None:
    config = public(tmp_path)
    config.token_path.parent.mkdir(mode=0o700)
    fd = os.open(config.token_path, os.O_CREAT | os.O_WRONLY, 0o600)
    os.write(fd, content)
    os.close(fd)
    with pytest.raises(ValueError, match="empty") as err:
        resolve_token(config)
    assert str(config.token_path) in str(err.value)


@pytest.mark.parametrize("mode", [0o640, 0o604, 0o660, 0o620])
def test_token_file_readable_by_others_refused(tmp_path: Path, mode: int) -> None:
    config = public(tmp_path)
    resolve_token(config)
    os.chmod(config.token_path, mode)
    with pytest.raises(ValueError, match="chmod 600") as err:
        resolve_token(config)
    assert str(config.token_path) in str(err.value)


def test_token_not_in_repr() -> None:
    config = DaemonConfig(api=ApiSettings(token="do-not-log-me"))
    assert "do-not-log-me" not in repr(config)
    assert "do-not-log-me" not in str(config)


@pytest.mark.parametrize(("given", "expected", "match"), [
    ("abc", "abc", True),
    ("abd", "abc", False),
    ("ab", "abc", False),
    ("abcd", "abc", False),
    ("", "abc", False),
    (None, "abc", False),
    ("", "", False),
    ("é-token", "é-token", True),
])
def test_tokens_match(given: str | None, expected: str, match: bool) -> None:
    assert tokens_match(given, expected) is match


def test_a_token_file_configured_on_loopback_is_used(tmp_path: Path) -> None:
    """Issue 22 item 5: a configured ``token_file`` counts on loopback too (created if missing);
    the default file in the state directory is not read there."""
    token_file = tmp_path / "keys" / "tok"
    config = DaemonConfig(state_dir=tmp_path / "state", api=ApiSettings(token_file=token_file))
    token = resolve_token(config)
    assert token is not None and token_file.read_text(encoding="utf-8").strip() == token
    assert resolve_token(config) == token
    assert resolve_token(DaemonConfig(state_dir=tmp_path / "state")) is None
