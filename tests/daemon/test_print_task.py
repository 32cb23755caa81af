"""The print task in process: the real service, store and link on the simulator over its pty.

A cancel can arrive after the job went to ``heating`` and before its program begins to stream
(while the program's time line is computed beside the loop). The link has no stream to cancel
then, so the print task itself must see the request before it starts one.
"""

from __future__ import annotations

import asyncio
import threading
from pathlib import Path
from typing import Any

from ribbond.daemon.components import printing
from ribbond.daemon.config import DaemonConfig
from ribbond.daemon.jobs import JobState
from ribbond.daemon.service import RibbonService
from ribbond.daemon.store import JobStore
from ribbond.gcode.profiles import load_profile
from ribbond.printer.link import PrinterLink

from ..conftest import executed_program


async def test_a_cancel_before_the_stream_begins_sends_no_program_line(tmp_path: Path, make_sim: Any,
                                                                       monkeypatch: Any) -> None:
    sim = make_sim()
    config = DaemonConfig(state_dir=tmp_path / "state")
    profile = load_profile(config.printer_profile)
    store = JobStore(tmp_path / "jobs.sqlite3")
    link = PrinterLink(sim.port, sim.config.baud, boot_wait_s=0.2)
    await link.connect()
    loop = asyncio.get_running_loop()
    entered, release = asyncio.Event(), threading.Event()
    timeline = printing.program_timeline

    def held(lines: list[str], profile: Any) -> Any:
        # the window made wide: the time line waits (in its thread) until the cancel was asked for
        loop.call_soon_threadsafe(entered.set)
        release.wait(30)
        return timeline(lines, profile)

    monkeypatch.setattr(printing, "program_timeline", held)
    service = RibbonService(config, profile, store, link)
    service.start()
    x0, y0, _, _ = profile.frame.bounds
    moves = [f"G1 X{x0 + 10 + i:.1f} Y{y0 + 10:.1f} F600" for i in range(20)]
    upload = tmp_path / "upload"
    upload.write_text("\n".join(["G28", "G90", "G1 Z5 F600", *moves]) + "\n")
    try:
        service.frame.ready()                  # the operator loaded a fresh frame (ribbonctl frame-ready)
        job = await service.submit_gcode(upload, "moves.gcode", start=True)
        await asyncio.wait_for(entered.wait(), 30)
        assert service.job(job.id).state is JobState.HEATING
        cancel = asyncio.create_task(service.cancel(job.id))
        while service.state.run is None or not service.state.run.cancel_requested:
            await asyncio.sleep(0.01)
        release.set()
        ended = await asyncio.wait_for(cancel, 60)
        assert ended.state is JobState.CANCELLED
        assert not set(moves) & set(executed_program(sim)), "the program streamed after the cancel"
    finally:
        release.set()
        await service.shutdown()
        await service.close()
        await link.close()
        store.close()
