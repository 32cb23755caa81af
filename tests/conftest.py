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
