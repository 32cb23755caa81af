"""The simulator keeps up with a saturated 1,000,000 baud line in its single thread."""

from __future__ import annotations

import gc
import threading
import time

import pytest

from sim import SimConfig
from sim.testing import PtyHost, connected, numbered


@pytest.mark.timing
def test_sustains_one_megabaud() -> None:
    baud = 1_000_000
    program = [f"G1 X{100 + (i % 50) * 0.5:.3f} Y{100 + (i % 7) * 0.25:.3f} E{i * 0.01:.4f} F6000"
               for i in range(1, 2401)]
    data = b"".join(numbered(i, cmd) for i, cmd in enumerate(program, start=1))
    wire_s = len(data) * 10 / baud  # about one second of saturated wire
    # Default buffers: a line is processed as soon as it arrives or bytes are lost.
    cfg = SimConfig(baud=baud, time_scale=1e-4)
    # The simulator runs in this process here (as a thread): a collection of the whole test
    # session's heap (a full run: 341 and 326 ms late, alone 1-4 ms) would be timed as the
    # simulator's. A simulator of its own is a process of its own; so is its heap.
    gc.collect()
    gc.disable()
    try:
        _run(cfg, program, data, wire_s)
    finally:
        gc.enable()


def _run(cfg: SimConfig, program: list[str], data: bytes, wire_s: float) -> None:
    with connected(cfg) as (sim, host):
        oks: list[float] = []

        def reader(h: PtyHost = host) -> None:
            while len(oks) < len(program):
                line = h.readline(3.0)
                if line is None:
                    return
                if line.startswith("ok N"):
                    oks.append(time.monotonic())

        t = threading.Thread(target=reader)
        t.start()
        t0 = host.write(data)
        t.join(10.0)
        st = sim.stats()
        assert len(oks) == len(program), st
        assert st.dropped_bytes == 0 and st.checksum_errors == 0 and st.line_number_errors == 0
        assert st.commands_executed == len(program)
        lag = oks[-1] - (t0 + wire_s)
        # Paced input cannot finish before the wire would; a sim that fell behind would
        # finish well after it.
        print(f"wire {wire_s:.3f} s, last ok {lag * 1000:.1f} ms after the last byte")
        assert -0.01 < lag < 0.25, (wire_s, lag)
        assert st.segments == len(program)
