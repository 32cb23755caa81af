"""Every dependency installs from wheels on the hosts people have: linux/aarch64 (Raspberry Pi 4/5,
Raspberry Pi OS / Debian 12) and linux/x86_64, CPython 3.11, glibc 2.28 and later.

``pip download --only-binary=:all:`` of the project's requirements (``pyproject.toml``: the runtime
dependencies and every extra) for each target platform must succeed: a dependency without a wheel
for a target is either given a wheel-less fallback and an environment marker that leaves it out
there (``cholespy``: ``ribbond.design.linalg`` falls back to scipy), or it cannot be added.

pip evaluates environment markers against the machine it runs on, not ``--platform``; so the
markers of the project's requirements are evaluated here for the target, and after the download
the markers of every downloaded wheel's own requirements too: what the target would need and pip
left out (a marker true on aarch64 only) is downloaded in a further round.

Skips, with the reason, only when the package index cannot be reached at all.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import tomllib
import urllib.error
import urllib.request
import zipfile
from email.parser import HeaderParser
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name, parse_wheel_filename

PYPROJECT = Path(__file__).resolve().parents[1] / "pyproject.toml"

#: The targets: platform_machine and the oldest glibc whose wheels count (manylinux_2_28: Debian 10+,
#: Raspberry Pi OS 10+; a host with glibc 2.28 takes manylinux_2_17 … 2_28 and manylinux2014).
TARGETS = {"linux-aarch64": "aarch64", "linux-x86_64": "x86_64"}
GLIBC_MINOR = 28
PYTHON = "3.11"

#: pip's rounds: the first resolves everything; later ones fetch what only the target's markers need.
MAX_ROUNDS = 4


def target_environment(machine: str) -> dict[str, str]:
    """The marker environment (PEP 508) of CPython 3.11 on linux/``machine``."""
    return {
        "implementation_name": "cpython", "implementation_version": f"{PYTHON}.0",
        "os_name": "posix", "platform_machine": machine, "platform_python_implementation": "CPython",
        "platform_release": "", "platform_system": "Linux", "platform_version": "",
        "python_full_version": f"{PYTHON}.0", "python_version": PYTHON, "sys_platform": "linux",
    }


def platform_tags(machine: str) -> list[str]:
    """pip's ``--platform`` values a glibc-2.28 linux/``machine`` host accepts (pip does not widen
    manylinux_2_28 to the older manylinux_2_Y by itself; manylinux2014 it widens to 2010 and 1)."""
    oldest = 5 if machine == "x86_64" else 17
    tags = [f"manylinux_2_{minor}_{machine}" for minor in range(GLIBC_MINOR, oldest - 1, -1)]
    return tags + [f"manylinux2014_{machine}"]


def project_requirements() -> list[Requirement]:
    """The runtime dependencies and those of every extra, from ``pyproject.toml``."""
    project = tomllib.loads(PYPROJECT.read_text())["project"]
    lines = list(project["dependencies"])
    for extra in project.get("optional-dependencies", {}).values():
        lines += extra
    return [Requirement(line) for line in lines]


def applies(req: Requirement, environment: dict[str, str], extras: set[str] | None = None) -> bool:
    """Whether ``req`` is needed in ``environment`` (with the requirer's ``extras`` asked for)."""
    if req.marker is None:
        return True
    return any(req.marker.evaluate({**environment, "extra": extra}) for extra in (extras or {""}) | {""})


def absent_on(machine: str) -> list[str]:
    """The project's requirements that ``pyproject.toml`` leaves out on linux/``machine`` (their
    marker is false there): the optional native packages the code must do without."""
    env = target_environment(machine)
    return sorted(canonicalize_name(r.name) for r in project_requirements() if not applies(r, env))


def without_marker(req: Requirement) -> str:
    """``req`` as pip reads it, its marker already evaluated for the target."""
    extras = f"[{','.join(sorted(req.extras))}]" if req.extras else ""
    return f"{req.name}{extras}{req.specifier}"


def wheel_requirements(wheel: Path) -> list[Requirement]:
    """The Requires-Dist of a wheel's METADATA."""
    with zipfile.ZipFile(wheel) as archive:
        name = next(n for n in archive.namelist() if n.endswith(".dist-info/METADATA"))
        metadata = HeaderParser().parsestr(archive.read(name).decode("utf-8"))
    return [Requirement(line) for line in metadata.get_all("Requires-Dist") or []]


def missing_for_target(wheels: dict[str, Path], roots: list[Requirement],
                       environment: dict[str, str]) -> list[Requirement]:
    """The requirements the target needs (from ``roots``, through each wheel's Requires-Dist with the
    target's markers and the extras asked for) that no downloaded wheel provides, one per name."""
    followed: dict[str, set[str]] = {}          # name -> the extras whose requirements were queued
    queue, missing = list(roots), {}
    while queue:
        req = queue.pop()
        name = canonicalize_name(req.name)
        if name not in wheels:
            missing.setdefault(name, req)
            continue
        if name in followed and set(req.extras) <= followed[name]:
            continue
        extras = followed.setdefault(name, set())
        extras |= set(req.extras)
        queue += [r for r in wheel_requirements(wheels[name]) if applies(r, environment, extras)]
    return list(missing.values())


def pip_download(requirements: list[str], machine: str, dest: Path) -> subprocess.CompletedProcess[str]:
    """``pip download --only-binary=:all:`` of ``requirements`` for CPython 3.11 on linux/``machine``."""
    platforms = [arg for tag in platform_tags(machine) for arg in ("--platform", tag)]
    command = [sys.executable, "-m", "pip", "download", "--only-binary=:all:", *platforms,
               "--python-version", PYTHON, "--implementation", "cp", "--abi", "cp311",
               "--progress-bar", "off", "--disable-pip-version-check", "-d", str(dest), *requirements]
    run = subprocess.run(command, capture_output=True, text=True, timeout=240)
    if run.returncode != 0 and "No matching distribution" not in run.stderr:   # a network hiccup: once more
        run = subprocess.run(command, capture_output=True, text=True, timeout=240)
    return run


def downloaded(dest: Path) -> dict[str, Path]:
    """The wheels in ``dest`` by canonical project name."""
    return {parse_wheel_filename(p.name)[0]: p for p in dest.glob("*.whl")}


def index_url() -> str:
    """The index pip is configured with (its default: PyPI)."""
    listing = subprocess.run([sys.executable, "-m", "pip", "config", "list"], capture_output=True,
                             text=True, timeout=60).stdout
    for line in listing.splitlines():
        key, _, value = line.partition("=")
        if key.endswith(".index-url") and not key.endswith("extra-index-url"):
            return value.strip().strip("'\"")
    return "https://pypi.org/simple/"


@pytest.fixture(scope="module")
def reachable_index() -> str:
    """The package index, or a skip saying why it cannot be reached at all."""
    url = index_url()
    try:
        with urllib.request.urlopen(f"{url.rstrip('/')}/pip/", timeout=20) as answer:
            answer.read(1)
    except (urllib.error.URLError, OSError) as exc:
        pytest.skip(f"the package index {url} cannot be reached ({exc}); the wheel check needs it")
    return url


def test_markers_are_evaluated_for_the_target_not_this_machine() -> None:
    """The check's own premise: a marker on platform_machine is read for the target."""
    req = Requirement('native; platform_machine == "aarch64"')
    assert applies(req, target_environment("aarch64"))
    assert not applies(req, target_environment("x86_64"))
    assert "manylinux_2_28_aarch64" in platform_tags("aarch64")
    assert "manylinux_2_17_aarch64" in platform_tags("aarch64")
    assert not any("2_29" in tag or "x86_64" in tag for tag in platform_tags("aarch64"))


@pytest.mark.parametrize("target", sorted(TARGETS))
def test_every_requirement_installs_from_wheels(target: str, reachable_index: str) -> None:
    machine = TARGETS[target]
    environment = target_environment(machine)
    roots = [r for r in project_requirements() if applies(r, environment)]
    with tempfile.TemporaryDirectory(prefix=f"wheels-{target}-") as tmp:
        dest = Path(tmp)
        asked = [without_marker(r) for r in roots]
        for _ in range(MAX_ROUNDS):
            run = pip_download(asked, machine, dest)
            assert run.returncode == 0, (
                f"{target}: pip download --only-binary=:all: of {asked} failed (a requirement has no "
                f"wheel for {', '.join(platform_tags(machine))}, CPython {PYTHON}):\n"
                + "\n".join([line for line in run.stderr.splitlines() if "is ignored" not in line][-10:]))
            missing = missing_for_target(downloaded(dest), roots, environment)
            if not missing:
                break
            asked = [without_marker(r) for r in missing]
        assert not missing, f"{target}: still missing after {MAX_ROUNDS} rounds: {missing}"
        accepted = set(platform_tags(machine)) | {"any"}
        for wheel in dest.iterdir():
            tags = parse_wheel_filename(wheel.name)[3] if wheel.suffix == ".whl" else frozenset()
            assert any(t.platform in accepted or t.platform.startswith(("manylinux1_", "manylinux2010_"))
                       for t in tags), f"{target}: {wheel.name} is not a wheel for {machine}"


def _fake_wheel(dest: Path, name: str, requires: list[str]) -> None:
    with zipfile.ZipFile(dest / f"{name}-1.0-py3-none-any.whl", "w") as archive:
        lines = ["Metadata-Version: 2.1", f"Name: {name}", "Version: 1.0"]
        archive.writestr(f"{name}-1.0.dist-info/METADATA",
                         "\n".join(lines + [f"Requires-Dist: {r}" for r in requires]) + "\n")


def test_a_dependency_only_the_target_needs_is_found_missing(tmp_path: Path) -> None:
    """pip, on x86_64, leaves out a dependency marked for aarch64: the closure over the downloaded
    wheels' own requirements, with the target's markers (and extras), names it."""
    _fake_wheel(tmp_path, "top", ['arm-only; platform_machine == "aarch64"',
                                  'extra-only; extra == "fast"', "plain"])
    _fake_wheel(tmp_path, "plain", [])
    wheels = downloaded(tmp_path)
    roots = [Requirement("top")]
    assert [r.name for r in missing_for_target(wheels, roots, target_environment("aarch64"))] == ["arm-only"]
    assert missing_for_target(wheels, roots, target_environment("x86_64")) == []
    assert sorted(r.name for r in missing_for_target(wheels, [Requirement("top[fast]")],
                                                     target_environment("x86_64"))) == ["extra-only"]
