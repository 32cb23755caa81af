"""``python -m sim``: serve a simulated Marlin printer on a pty until SIGTERM/SIGINT.

The first line on stdout is the pty device path (flushed at once); with ``--camera-port`` the
second is the camera's base address (``http://127.0.0.1:PORT/``: ``stream``, ``snapshot``). If a
disconnect fault later plugs in a new pty, its path is printed as a further line.
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading

from .config import FaultConfig, FrameConfig, SimConfig
from .dialects import DIALECTS
from .printer import SimulatedPrinter


def _pair(text: str) -> tuple[float, float]:
    try:
        x, y = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected X,Y, got {text!r}") from None
    return (x, y)


def _rate(text: str) -> float:
    v = float(text)
    if not 0.0 <= v <= 1.0:
        raise argparse.ArgumentTypeError(f"a probability in [0, 1] is needed, got {text!r}")
    return v


def build_parser() -> argparse.ArgumentParser:
    d = SimConfig()
    f = FaultConfig()
    p = argparse.ArgumentParser(
        prog="python -m sim",
        description="Simulated printer behind a pseudo-terminal, answering as Marlin 2.x or, with "
                    "--dialect, as another firmware. Prints the pty device path as the first line of "
                    "stdout, then serves until SIGTERM/SIGINT.")
    g = p.add_argument_group("serial and firmware")
    g.add_argument("--dialect", choices=tuple(DIALECTS), default=None,
                   help="answer as this firmware (banner, M115, M105/M114, ok forms, busy/wait, resend "
                        "requests, errors); the options below default to its values (default: the "
                        "historical board, Marlin 2.1 with ADVANCED_OK and 1.x's cut-tail check)")
    g.add_argument("--baud", type=int, default=d.baud,
                   help="serial speed; bytes are paced at 10/baud s each way (default %(default)s)")
    g.add_argument("--time-scale", type=float, default=d.time_scale,
                   help="wall seconds per physical second; 0.001 runs a 2 h print in 7.2 s "
                        "(default %(default)s)")
    g.add_argument("--advanced-ok", action=argparse.BooleanOptionalAction, default=None,
                   help="'ok N<line> P<planner free> B<queue free>' instead of a plain 'ok' "
                        "(default: the dialect's)")
    g.add_argument("--ok-after-resend", action=argparse.BooleanOptionalAction, default=None,
                   help="print 'ok' after each resend request (default: the dialect's)")
    g.add_argument("--m114-on-ok", action=argparse.BooleanOptionalAction, default=None,
                   help="answer M114 on the ok line, as Smoothieware does: "
                        "'ok C: X:10.0000 Y:20.0000 Z:0.0000 E:0.0000' (default: the dialect's)")
    g.add_argument("--ok-before-output", action="store_true",
                   help="print a command's ok before its output (M114's position, M115's report), as "
                        "OctoPrint's virtual printer does with okBeforeCommandOutput")
    g.add_argument("--rx-buffer", type=int, default=d.rx_buffer,
                   help="serial receive buffer in bytes; overflow is lost (default %(default)s)")
    g.add_argument("--bufsize", type=int, default=None,
                   help="command queue slots, Marlin BUFSIZE (default: the dialect's, 4)")
    g.add_argument("--planner-blocks", type=int, default=d.planner_blocks,
                   help="planner ring size, holds one move less (default %(default)s)")
    g.add_argument("--keepalive", type=float, default=None,
                   help="seconds between busy lines while a command blocks; 0 = off "
                        "(default: the dialect's, 2)")
    g.add_argument("--cut-tail", choices=("reject", "marlin2"), default=None,
                   help="the tail of a line cut by a receive-buffer flush: rejected (Marlin 1.x, "
                        "the default without a dialect) or queued as an unnumbered command (Marlin "
                        "2.x: Unknown command + ok)")
    g.add_argument("--read-latency", type=float, default=d.read_latency_s, metavar="S",
                   help="main-loop latency: bytes arriving this long after a bad line are flushed "
                        "with it, cutting the line being received (default 0)")
    g.add_argument("--blocking-intake", action="store_true",
                   help="read no serial while a command blocks (Marlin's main loop): lines pile up "
                        "in the receive buffer, and bytes beyond it are lost")
    g.add_argument("--seed", type=int, default=d.seed,
                   help="seed of every fault's random stream (default %(default)s)")
    g.add_argument("--boot-time", type=float, default=d.boot_s,
                   help="seconds a (re)boot takes; input meanwhile is lost (default %(default)s)")
    g = p.add_argument_group("faults")
    g.add_argument("--corrupt-rate", type=_rate, default=f.corrupt_rate,
                   help="per incoming line: probability one byte is corrupted")
    g.add_argument("--drop-ok-rate", type=_rate, default=f.drop_ok_rate,
                   help="per 'ok': probability it is never sent")
    g.add_argument("--spurious-resend-rate", type=_rate, default=f.spurious_resend_rate,
                   help="per accepted numbered line: probability of an unasked 'Resend:'")
    g.add_argument("--unsolicited-rate", type=_rate, default=f.unsolicited_rate,
                   help="per output line: probability of an unsolicited line before it")
    g.add_argument("--slow-rate", type=_rate, default=f.slow_rate,
                   help="per output line: probability it is held back --slow-delay seconds")
    g.add_argument("--slow-delay", type=float, default=f.slow_delay_s,
                   help="seconds a slow line is held back (default %(default)s)")
    g.add_argument("--skip-refused", action="store_true",
                   help="buggy firmware: a line refused for its checksum is marked received "
                        "(never run) and the next one is asked for")
    g.add_argument("--swallow-resent-after-lines", type=int, default=None, metavar="N",
                   help="buggy firmware, once after N accepted numbered lines: ask for the next line "
                        "again, take the re-sent line without running or answering it, lose the line "
                        "after it, and later ask for the one after the swallowed line")
    g.add_argument("--ignore-resent-after-lines", type=int, default=None, metavar="N",
                   help="firmware that times out after a resend request, once after N accepted numbered "
                        "lines: ask for the next line again, then mark the re-sent line received without "
                        "running or answering it; the lines after it run as usual")
    g.add_argument("--reset-after-lines", type=int, default=None, metavar="N",
                   help="reboot after N accepted numbered lines")
    g.add_argument("--disconnect-after-lines", type=int, default=None, metavar="N",
                   help="unplug (close the pty) after N accepted numbered lines")
    g.add_argument("--runaway-after-lines", type=int, default=None, metavar="N",
                   help="thermal runaway (halt) after N accepted numbered lines")
    g.add_argument("--mintemp-after-lines", type=int, default=None, metavar="N",
                   help="MINTEMP error (halt) after N accepted numbered lines")
    g.add_argument("--reconnect-after", type=float, default=None, metavar="S",
                   help="after an unplug, plug a new pty in after S seconds and print its path")
    g = p.add_argument_group("fabric frame")
    g.add_argument("--frame-center", type=_pair, default=FrameConfig().center, metavar="X,Y",
                   help="machine coordinates of the frame's flip centre (default 110,110)")
    g.add_argument("--flip-axis", choices=("x", "y"), default=FrameConfig().flip_axis,
                   help="axis the frame turns over about (y mirrors x) (default %(default)s)")
    g = p.add_argument_group("outputs")
    g.add_argument("--record", metavar="FILE",
                   help="write every executed command to FILE as JSON lines")
    g.add_argument("--render", metavar="FILE", help="write a PNG of the deposits at exit")
    g.add_argument("--camera-port", type=int, default=None, metavar="N",
                   help="serve a camera of the bed on 127.0.0.1:N (0: any free port; its address is the "
                        "second line of stdout): /stream (MJPEG), /snapshot (JPEG), and /?action=stream, "
                        "/?action=snapshot as mjpg-streamer spells them")
    g.add_argument("--camera-fps", type=float, default=5.0, metavar="F",
                   help="frames a second the camera renders and streams (default %(default)s)")
    g.add_argument("--control", metavar="SOCKET",
                   help="Unix socket for JSON-line control requests "
                        "(flip, reset, disconnect, runaway, stats, render, segments, commands, port)")
    return p


def config_from_args(args: argparse.Namespace) -> SimConfig:
    return SimConfig(
        baud=args.baud,
        time_scale=args.time_scale,
        dialect=args.dialect,
        advanced_ok=args.advanced_ok,
        ok_after_resend=args.ok_after_resend,
        m114_on_ok=args.m114_on_ok,
        ok_before_output=args.ok_before_output,
        rx_buffer=args.rx_buffer,
        bufsize=args.bufsize,
        planner_blocks=args.planner_blocks,
        keepalive_s=args.keepalive,
        cut_tail=args.cut_tail,
        read_latency_s=args.read_latency,
        blocking_intake=args.blocking_intake,
        seed=args.seed,
        boot_s=args.boot_time,
        faults=FaultConfig(
            corrupt_rate=args.corrupt_rate,
            drop_ok_rate=args.drop_ok_rate,
            spurious_resend_rate=args.spurious_resend_rate,
            unsolicited_rate=args.unsolicited_rate,
            slow_rate=args.slow_rate,
            slow_delay_s=args.slow_delay,
            skip_refused=args.skip_refused,
            swallow_resent_after_lines=args.swallow_resent_after_lines,
            ignore_resent_after_lines=args.ignore_resent_after_lines,
            reset_after_lines=args.reset_after_lines,
            disconnect_after_lines=args.disconnect_after_lines,
            runaway_after_lines=args.runaway_after_lines,
            mintemp_after_lines=args.mintemp_after_lines,
            reconnect_after_s=args.reconnect_after,
        ),
        frame=FrameConfig(center=args.frame_center, flip_axis=args.flip_axis),
    )


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        config = config_from_args(args)
    except ValueError as exc:
        parser.error(str(exc))
    done = threading.Event()
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: done.set())

    def announce(path: str) -> None:
        print(path, flush=True)

    if args.camera_port is not None and not 0 <= args.camera_port <= 65535:
        parser.error(f"--camera-port: a TCP port 0-65535 is needed, got {args.camera_port}")
    if args.camera_fps <= 0:
        parser.error(f"--camera-fps: must be > 0, got {args.camera_fps}")
    sim = SimulatedPrinter(config, record_path=args.record, control_path=args.control,
                           on_port_change=announce)
    sim.start()
    camera = None
    try:
        announce(sim.port)
        if args.camera_port is not None:
            from .camera import CameraServer
            camera = CameraServer(sim, args.camera_port, fps=args.camera_fps).start()
            announce(camera.url)
        while not done.wait(0.5):
            pass
        if args.render:
            sim.render_png(args.render)
    finally:
        if camera is not None:
            camera.stop()
        sim.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
