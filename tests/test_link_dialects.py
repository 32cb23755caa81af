"""The printer link against the simulator answering as each firmware (``SimConfig.dialect``): the
handshake finds the dialect from what the firmware prints (Repetier prints its M115 report after its
ok), the readings stay live without autoreports, and the emergency stop and its recovery go as each
firmware does them."""

from __future__ import annotations

import asyncio
import time

import pytest

from ribbond.printer import LinkState, PrinterHalted, PrinterLink, Timeouts

FAST = Timeouts(default_s=0.5, probes=4)

#: The FIRMWARE_NAME each simulated dialect prints (sim/dialects.py, from the firmwares' sources)
#: and the family the link must take it for.
NAMES = {"marlin1": ("Marlin 1.1.9 (Github)", "marlin1"), "marlin2": ("Marlin 2.1.2.1", "marlin2"),
         "prusa": ("Prusa-Firmware 3.13.2", "prusa"),
         "reprapfirmware": ("RepRapFirmware for Duet 2 WiFi/Ethernet", "reprapfirmware"),
         "smoothieware": ("Smoothieware", "smoothieware"), "repetier": ("Repetier_1.0.4", "repetier")}


def link_for(sim, **kwargs) -> PrinterLink:
    kwargs.setdefault("timeouts", FAST)
    kwargs.setdefault("boot_wait_s", 0.3)
    return PrinterLink(sim.port, sim.config.baud, **kwargs)


@pytest.mark.parametrize("dialect", list(NAMES))
async def test_the_handshake_finds_each_dialect(make_sim, dialect: str) -> None:
    sim = make_sim(dialect=dialect)
    link = link_for(sim)
    await link.connect()
    name, family = NAMES[dialect]
    assert link.capabilities.firmware_name.startswith(name)
    assert link.capabilities.dialect == family
    assert (await link.query_position()).x == 0.0
    assert (await link.query_temperatures()).hotend is not None
    await link.close()


async def test_temperatures_are_asked_for_where_they_are_not_autoreported(make_sim) -> None:
    """Smoothieware has no M155: the link asks with M105 every temperature_interval_s, so the
    status follows a heating nozzle without anyone asking."""
    sim = make_sim(dialect="smoothieware", time_scale=0.01)
    link = link_for(sim, temperature_interval_s=1)
    await link.connect()
    await link.send("M104 S200")
    deadline = time.monotonic() + 3.5
    while time.monotonic() < deadline:
        heater = link.status.heaters.get("T")
        if heater is not None and heater.target == 200.0 and heater.current > 30.0:
            break
        await asyncio.sleep(0.1)
    else:
        raise AssertionError(f"no live reading: {link.status.heaters}")
    assert "M155 S1" not in [c.command for c in sim.commands()]
    await link.close()


async def test_smoothieware_stops_at_once_on_ctrl_x_and_m999_recovers(make_sim) -> None:
    """Smoothieware acts on Ctrl-X as it arrives (SerialConsole.cpp), its M112 only in turn: the
    link's emergency stop sends Ctrl-X; M999 leaves the halt without a reboot."""
    sim = make_sim(dialect="smoothieware", baud=250000, time_scale=1.0)
    link = link_for(sim)
    await link.connect()
    streaming = asyncio.ensure_future(link.stream([f"G1 X{10 + (i % 2) * 50} Y10 F600" for i in range(100)]))
    await asyncio.sleep(0.3)
    called = time.monotonic()
    link.emergency_stop()
    with pytest.raises(PrinterHalted):
        await asyncio.wait_for(streaming, 2)
    while sim.halted_at is None and time.monotonic() < called + 1:
        await asyncio.sleep(0.005)
    assert sim.halted_at is not None and sim.halted_at - called < 0.1
    await link.recover()
    assert link.state is LinkState.READY and sim.halted_at is None
    await link.close()


async def test_a_firmware_that_reboots_on_m112_is_connected_again_by_itself(make_sim) -> None:
    """Prusa's kill() ends in a soft reset (Marlin_main.cpp): after the stop the board reboots, prints
    its banner, and the link shakes hands again without a recover."""
    sim = make_sim(dialect="prusa", boot_s=0.05)
    link = link_for(sim)
    await link.connect()
    await link.send("M104 S200")
    link.emergency_stop()
    assert link.state is LinkState.HALTED
    await link.wait_for_state(LinkState.READY, timeout=5)
    temps = await link.query_temperatures()
    assert temps.hotend is not None and temps.hotend.target == 0.0, "the reboot forgot the target"
    await link.close()
