"""Shared fixtures: simulated printers on real ptys, and programs to stream."""

from __future__ import annotations

import os
import random
import shlex
import sys
from collections.abc import Callable, Iterator

import pytest

from sim import FaultConfig, SimConfig, SimulatedPrinter


def pytest_addoption(parser: pytest.Parser, pluginmanager: pytest.PytestPluginManager) -> None:
    parser.addoption("--hide-package", action="append", default=[], metavar="NAME",
                     help="run as if the optional package NAME were not installed (repeatable), e.g. "
                          "--hide-package cholespy: the engine's fallback path, as on a linux/aarch64 host")
    # Hidden now, while this conftest registers: the conftests below it (tests/gcode's) import the
    # engine when they load, before pytest_configure; the command line is not parsed yet, so read it.
    config = pluginmanager.get_plugin("pytestconfig")
    args = [*shlex.split(os.environ.get("PYTEST_ADDOPTS", "")), *config.invocation_params.args]
    for name in _hidden_in(args):
        if sys.modules.get(name) is None:
            sys.modules[name] = None  # type: ignore[assignment]  # every later `import name` fails


def _hidden_in(args: list[str]) -> list[str]:
    """The NAMEs of ``--hide-package NAME`` and ``--hide-package=NAME`` in ``args``."""
    names = [arg.partition("=")[2] for arg in args if arg.startswith("--hide-package=")]
    return names + [value for flag, value in zip(args, args[1:]) if flag == "--hide-package"]


def pytest_configure(config: pytest.Config) -> None:
    for name in config.getoption("--hide-package"):
        if sys.modules.get(name) is not None:
            raise pytest.UsageError(f"--hide-package {name}: {name} was imported before the tests "
                                    "started (by a plugin?); it cannot be hidden")
        sys.modules[name] = None  # type: ignore[assignment]


def pytest_report_header(config: pytest.Config) -> str | None:
    hidden = config.getoption("--hide-package")
    return f"hidden packages (imports fail): {', '.join(hidden)}" if hidden else None


#: The compile cache the tests' daemons share (``tests/daemon/conftest.py``: ``Daemon``): one folder
#: for the whole session and both xdist workers, so a mesh compiled by one module is served to the next.
COMPILE_CACHE_ENV = "RIBBOND_TESTS_COMPILE_CACHE"


@pytest.fixture(scope="session", autouse=True)
def shared_compile_cache(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """The session's compile-cache folder, named in ``COMPILE_CACHE_ENV``: beside the workers' own
    base folders (their common parent is this session's), or in the base folder without xdist.
    Entries are renamed into place whole, so two workers compiling one key at once are both right."""
    base = tmp_path_factory.getbasetemp()
    folder = (base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base) / "compile-cache"
    folder.mkdir(exist_ok=True)
    os.environ[COMPILE_CACHE_ENV] = str(folder)
    yield str(folder)


#: Commands the link sends on its own: the handshake and its probes. Test programs use none of them.
HOST_COMMANDS = ("M110", "M115", "M155", "M105", "M114")


@pytest.fixture
def make_sim() -> Iterator[Callable[..., SimulatedPrinter]]:
    """Start simulated printers (fast by default: 1 Mbaud, 1000× time) and stop them afterwards."""
    started: list[SimulatedPrinter] = []

    def make(faults: FaultConfig | None = None, **options: object) -> SimulatedPrinter:
        options.setdefault("baud", 1_000_000)
        options.setdefault("time_scale", 0.001)
        sim = SimulatedPrinter(SimConfig(faults=faults or FaultConfig(), **options))  # type: ignore[arg-type]
        sim.__enter__()
        started.append(sim)
        return sim

    yield make
    for sim in started:
        sim.__exit__(None, None, None)


def moves(count: int, seed: int = 1) -> list[str]:
    """A program of short extruding moves, each line distinct so that order errors show."""
    rng = random.Random(seed)
    lines = ["G92 E0", "G1 F3000"]  # the feed rate is modal, as in sliced G-code: lines stay short
    e = 0.0
    for _ in range(count - 2):
        e += 0.01
        lines.append(f"G1 X{100 + rng.uniform(-40, 40):.3f} Y{100 + rng.uniform(-40, 40):.3f} E{e:.4f}")
    return lines


def executed_program(sim: SimulatedPrinter) -> list[str]:
    """The commands the simulator executed, without the link's own."""
    return [c.command for c in sim.commands() if c.command.split()[0] not in HOST_COMMANDS]


def assert_prefix_without_duplicates(executed: list[str], program: list[str]) -> None:
    """After a failure mid-job: what ran is the program's beginning, each line once, in order."""
    assert executed == program[: len(executed)], "executed lines must be the program's first lines, in order"
