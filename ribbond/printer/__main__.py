"""``python -m ribbond.printer``: talk to a Marlin-compatible printer from the shell.

    python -m ribbond.printer stream --port /dev/ttyUSB0 --baud 115200 part.gcode
    python -m ribbond.printer send --port /dev/ttyUSB0 M105
    python -m ribbond.printer info --port /dev/ttyUSB0

Exit status: 0 when every line was acknowledged, 1 when the printer or the link failed (the reason
is printed), 2 for a bad command line or an unreadable/unsendable file, 130 when interrupted.
"""

from __future__ import annotations

import argparse
import asyncio
import logging
import signal
import sys
from pathlib import Path

from tqdm import tqdm

from .capabilities import Capabilities
from .errors import LinkError, StreamCancelled
from .link import PrinterLink, prepare_program
from .sender import StreamProgress, Timeouts

EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m ribbond.printer", description=__doc__.split("\n\n")[0])
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--port", required=True, help="serial device, e.g. /dev/ttyUSB0 or the simulator's pty")
    common.add_argument("--baud", type=int, default=250000, help="baud rate (default 250000)")
    common.add_argument("--ping-pong", action="store_true",
                        help="one line in flight at a time (slower; for firmwares that mishandle windows)")
    common.add_argument("--rx-buffer", type=int, default=63, metavar="BYTES",
                        help="unacknowledged bytes allowed in flight (default 63, safe for 64-byte receive "
                             "buffers; 127 for Marlin's standard 128-byte buffer)")
    common.add_argument("--no-ok-after-resend", action="store_true",
                        help="the firmware sends no 'ok' after a resend request (Marlin does; by default "
                             "the firmware's dialect, from M115, says)")
    common.add_argument("--timeout", type=float, default=8.0, metavar="S",
                        help="seconds of silence before probing the printer (default 8)")
    common.add_argument("--boot-wait", type=float, default=2.5, metavar="S",
                        help="seconds to wait for the boot banner after opening (default 2.5)")
    common.add_argument("--reset-on-open", action="store_true", help="pulse DTR to reset the board on connect")
    common.add_argument("-v", "--verbose", action="count", default=0, help="log the protocol (-vv: every line)")
    sub = parser.add_subparsers(dest="command", required=True)
    stream = sub.add_parser("stream", parents=[common], help="stream a G-code file")
    stream.add_argument("file", type=Path, help="G-code file")
    stream.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    send = sub.add_parser("send", parents=[common], help="send commands and print the answers")
    send.add_argument("commands", nargs="+", help="commands, e.g. M105 'G1 X10'")
    sub.add_parser("info", parents=[common], help="print the firmware and its capabilities")
    return parser


def _link(args: argparse.Namespace) -> PrinterLink:
    # only a flag given overrides the dialect M115 names (Capabilities pins what it is given)
    explicit = {"ok_after_resend": False} if args.no_ok_after_resend else {}
    capabilities = Capabilities(rx_buffer_bytes=args.rx_buffer, **explicit)
    return PrinterLink(
        args.port, args.baud, capabilities=capabilities, timeouts=Timeouts(default_s=args.timeout),
        ping_pong=args.ping_pong, boot_wait_s=args.boot_wait, reset_on_open=args.reset_on_open,
    )


async def _stream(args: argparse.Namespace, commands: list[str]) -> int:
    link = _link(args)
    await link.connect()
    # In a log (not a terminal) a bar redrawn ten times a second is noise: redraw every 5 s there.
    bar = tqdm(total=len(commands), unit="line", disable=args.quiet, file=sys.stderr, dynamic_ncols=True,
               mininterval=0.1 if sys.stderr.isatty() else 5.0)
    loop = asyncio.get_running_loop()
    loop.add_signal_handler(signal.SIGINT, link.cancel)

    def progress(p: StreamProgress) -> None:
        bar.update(p.acknowledged - bar.n)
        if p.resends:
            bar.set_postfix(resends=p.resends, refresh=False)

    try:
        result = await link.stream(commands, progress)
    except StreamCancelled as exc:
        bar.close()
        print(f"interrupted: {exc}; the printer finishes the lines it has", file=sys.stderr)
        return EXIT_INTERRUPTED
    finally:
        loop.remove_signal_handler(signal.SIGINT)
        bar.close()
        status = link.status
        await link.close()
    rate = result.lines / result.elapsed_s if result.elapsed_s > 0 else float("inf")
    print(f"{args.file}: {result.lines} lines acknowledged in {result.elapsed_s:.1f} s ({rate:.0f} lines/s), "
          f"{result.resends} resends, {result.probes} probes; firmware {status.firmware or 'unknown'}"
          f"{', ADVANCED_OK' if status.advanced_ok else ''}")
    return EXIT_OK


async def _send(args: argparse.Namespace) -> int:
    link = _link(args)
    await link.connect()
    try:
        for command in args.commands:
            answer = await link.send(command)
            for event in answer.events:
                print(getattr(event, "text", None) or event)
            print(f"ok {answer.ok.text}".rstrip())
    finally:
        await link.close()
    return EXIT_OK


async def _info(args: argparse.Namespace) -> int:
    link = _link(args)
    await link.connect()
    try:
        status = link.status
        print(f"firmware: {status.firmware or 'unknown'} (spoken to as {status.dialect})")
        print(f"advanced ok: {'yes' if status.advanced_ok else 'no'}")
        for name, enabled in sorted(status.capabilities.items()):
            print(f"  {name}: {'yes' if enabled else 'no'}")
    finally:
        await link.close()
    return EXIT_OK


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    level = logging.WARNING if args.verbose == 0 else logging.INFO if args.verbose == 1 else logging.DEBUG
    logging.basicConfig(level=level, format="%(asctime)s %(name)s %(levelname)s %(message)s")
    try:
        if args.command == "stream":
            try:
                text = args.file.read_text(encoding="ascii")
                commands = prepare_program(text.splitlines(), source=str(args.file))
            except (OSError, UnicodeDecodeError, ValueError) as exc:
                print(f"error: {exc}", file=sys.stderr)
                return EXIT_USAGE
            return asyncio.run(_stream(args, commands))
        if args.command == "send":
            return asyncio.run(_send(args))
        return asyncio.run(_info(args))
    except (LinkError, OSError, asyncio.TimeoutError) as exc:
        print(f"error: {exc or type(exc).__name__}", file=sys.stderr)
        return EXIT_FAILED
    except KeyboardInterrupt:
        return EXIT_INTERRUPTED


if __name__ == "__main__":
    sys.exit(main())
