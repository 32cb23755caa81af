"""``ribbond``: the daemon. One asyncio loop owns the printer link, the job store, the HTTP API and
the compile queue (compiles run in worker processes); this module only wires them together.

    ribbond [--config FILE] [--simulate [--sim-args ARGS]]

Configuration: ``--config``, else ``$RIBBOND_CONFIG``, else ``/etc/ribbond/ribbond.toml`` (missing:
defaults). Under systemd (``Type=notify``) it sends READY=1 once the API listens, STATUS lines, and
WATCHDOG=1 at half the watchdog interval. It writes the API's address to ``<state_dir>/api.url``.

SIGTERM or SIGINT (``systemctl stop``/``restart``) while a job holds the printer stops it safely
first (the stream ends at a line boundary, heaters off, head lifted; the job ``interrupted``), then
the daemon exits. Exit status: 0 stopped; 2 a configuration error (the file, the token file, the
state directory): the unit does not restart on it.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import fcntl
import logging
import os
import signal
import sys
from pathlib import Path

import uvicorn

from ribbond.api.app import create_app
from ribbond.gcode.profiles import load_profile
from ribbond.printer.capabilities import Capabilities
from ribbond.printer.errors import LinkError
from ribbond.printer.link import LinkState, PrinterLink
from .config import CONFIG_ENV, DaemonConfig, load_config, protection, resolve_token
from .sdnotify import Notifier
from .service import RibbonService
from .simulated import SIM_STATE_DIR, start_simulator, stop_simulator
from .store import JobStore

log = logging.getLogger("ribbond")

#: Seconds between attempts to reach a printer that is off or unplugged.
RECONNECT_S = 5.0


def _lock_state_dir(state_dir: Path) -> int:
    """Hold an exclusive lock on the state directory for the daemon's life: one daemon per store."""
    state_dir.mkdir(parents=True, exist_ok=True)
    fd = os.open(state_dir / "ribbond.lock", os.O_CREAT | os.O_RDWR, 0o600)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        raise SystemExit(f"ribbond: another ribbond is running with the state directory {state_dir}") from None
    return fd


async def _keep_connected(link: PrinterLink, notifier: Notifier, stop: asyncio.Event) -> None:
    """Connect the printer, and again whenever the link drops (a printer switched off and on)."""
    while not stop.is_set():
        if link.state is LinkState.DISCONNECTED:
            try:
                await link.connect()
                notifier.status(f"printer connected on {link.port}")
                log.info("printer connected on %s (%s)", link.port, link.capabilities.firmware_name or "firmware ?")
            except (LinkError, OSError) as exc:
                log.warning("printer on %s not reachable: %s", link.port, exc)
                with contextlib.suppress(Exception):
                    await link.close()
        with contextlib.suppress(asyncio.TimeoutError):
            await asyncio.wait_for(stop.wait(), RECONNECT_S)


def _open_service(config: DaemonConfig, state_dir: Path, lock: int) -> tuple[JobStore, PrinterLink, RibbonService]:
    """The job store, the printer link (not connected yet) and the service over them."""
    profile = load_profile(config.printer_profile)
    try:
        store = JobStore(state_dir / "jobs.sqlite3")
        link = PrinterLink(config.serial.port, config.serial.baud,
                           capabilities=Capabilities(rx_buffer_bytes=config.serial.rx_buffer))
        return store, link, RibbonService(config, profile, store, link)
    except OSError as exc:
        os.close(lock)
        raise ValueError(f"cannot use the state directory {state_dir}: {exc.strerror or exc}"
                         + (f" ({exc.filename})" if exc.filename else "")) from None


def _stop_on_signals(service: RibbonService, server: uvicorn.Server, notifier: Notifier,
                     stop: asyncio.Event) -> list[asyncio.Task[None]]:
    """SIGTERM and SIGINT stop a job on the printer safely, then the server; a second one stops at
    once. The list returned holds the safe stop once it has begun."""
    loop = asyncio.get_running_loop()
    stopping: list[asyncio.Task[None]] = []

    async def stop_safely(name: str) -> None:
        try:
            await service.shutdown(f"the daemon was stopped ({name})")
        finally:
            stop.set()
            server.should_exit = True

    def shutdown(sig: signal.Signals) -> None:
        if stopping:                                   # a second signal: stop at once
            server.force_exit = True
            return
        log.info("stopping (%s)", sig.name)
        notifier.stopping()
        stopping.append(loop.create_task(stop_safely(sig.name)))

    for sig in (signal.SIGTERM, signal.SIGINT):
        loop.add_signal_handler(sig, shutdown, sig)
    return stopping


async def _announce(server: uvicorn.Server, config: DaemonConfig, token: str | None, notifier: Notifier) -> None:
    """Once the API listens: its address into ``<state_dir>/api.url``, the log and systemd."""
    while not server.started:
        await asyncio.sleep(0.05)
    host, port = server.servers[0].sockets[0].getsockname()[:2]
    url = f"http://{host if ':' not in host else f'[{host}]'}:{port}"
    (Path(config.state_dir) / "api.url").write_text(url + "\n", encoding="utf-8")
    log.info("%s", protection(config, token, url))
    notifier.ready(f"API on {url}")


async def _watchdog(notifier: Notifier, stop: asyncio.Event) -> None:
    """Ping systemd's watchdog from the event loop (a stalled loop misses the pings)."""
    interval = notifier.watchdog_interval()
    if not interval:
        return
    while not stop.is_set():
        notifier.watchdog()
        with contextlib.suppress(asyncio.TimeoutError):
            await asyncio.wait_for(stop.wait(), interval)


async def run(config: DaemonConfig) -> int:
    """Serve until stopped: the printer link, the job service and the API on this event loop."""
    state_dir = Path(config.state_dir)
    try:
        lock = _lock_state_dir(state_dir)
    except OSError as exc:
        raise ValueError(f"cannot use the state directory {state_dir}: {exc.strerror or exc}") from None
    notifier = Notifier()
    store, link, service = _open_service(config, state_dir, lock)
    token = resolve_token(config)
    app = create_app(service, token)
    # a short graceful shutdown: event streams (ribbonctl watch) never end on their own
    server = uvicorn.Server(uvicorn.Config(app, host=config.api.host, port=config.api.port,
                                           log_level=config.log_level, lifespan="off", access_log=False,
                                           timeout_graceful_shutdown=2))
    server.install_signal_handlers = lambda: None        # type: ignore[method-assign]  # ours below
    stop = asyncio.Event()
    stopping = _stop_on_signals(service, server, notifier, stop)
    service.start()
    tasks = [asyncio.create_task(_announce(server, config, token, notifier)),
             asyncio.create_task(_watchdog(notifier, stop)),
             asyncio.create_task(_keep_connected(link, notifier, stop))]
    try:
        await server.serve()
    finally:
        stop.set()
        notifier.stopping()
        with contextlib.suppress(Exception):
            await (stopping[0] if stopping else service.shutdown("the daemon stopped"))
        for task in tasks:
            task.cancel()
        await _close(service, link, store, state_dir, lock)
    return 0


async def _close(service: RibbonService, link: PrinterLink, store: JobStore, state_dir: Path, lock: int) -> None:
    """The service, the link and the store closed; the address file removed, the lock released."""
    await service.close()
    with contextlib.suppress(Exception):
        await link.close()
    store.close()
    with contextlib.suppress(OSError):
        (state_dir / "api.url").unlink()
    os.close(lock)


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="ribbond", description="the ribbond daemon")
    parser.add_argument("--config", type=Path, help="configuration file (TOML)")
    parser.add_argument("--simulate", action="store_true",
                        help="run on the simulated printer: start `python -m sim` as a child and use its pty as "
                             "[serial] port (without --config, the jobs are kept in "
                             f"{SIM_STATE_DIR}, never a real printer's store)")
    parser.add_argument("--sim-args", default="", metavar="ARGS",
                        help="with --simulate: options of python -m sim, one string (e.g. --sim-args=\"--time-scale 0.1\" "
                             "to run 10x faster, \"--dialect prusa\")")
    return parser


def _simulated(config: DaemonConfig, explicit_config: bool, sim_args: str) -> tuple[DaemonConfig, object]:
    """The configuration on a simulator started now (its pty as the serial port), and the child."""
    proc, port = start_simulator(config.serial.baud, sim_args)
    update: dict[str, object] = {"serial": config.serial.model_copy(update={"port": port})}
    if not explicit_config:
        update["state_dir"] = SIM_STATE_DIR
    log.info("simulated printer on %s (python -m sim, pid %d)", port, proc.pid)
    return config.model_copy(update=update), proc


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    if args.sim_args and not args.simulate:
        print("ribbond: --sim-args goes with --simulate", file=sys.stderr)
        return 2
    try:
        config = load_config(args.config)
    except ValueError as exc:
        print(f"ribbond: {exc}", file=sys.stderr)
        return 2
    logging.basicConfig(level=config.log_level.upper(), stream=sys.stderr,
                        format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    sim = None
    try:
        if args.simulate:
            explicit = args.config is not None or bool(os.environ.get(CONFIG_ENV))
            config, sim = _simulated(config, explicit, args.sim_args)
        return asyncio.run(run(config))
    except ValueError as exc:
        print(f"ribbond: {exc}", file=sys.stderr)
        return 2
    finally:
        if sim is not None:
            stop_simulator(sim)  # type: ignore[arg-type]


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
