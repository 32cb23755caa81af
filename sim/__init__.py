"""A simulated Marlin 2.x printer behind a pseudo-terminal, for testing hosts; with
``SimConfig(dialect=…)`` (``--dialect``) it answers as Marlin 1.x, Prusa's firmware,
RepRapFirmware, Smoothieware or Repetier instead (``sim.dialects``).

Stands in for firmware written by others: it shares no code with ``ribbond`` and
uses only the standard library, numpy, matplotlib and Pillow (which matplotlib
needs: the camera draws with it).

    from sim import SimConfig, SimulatedPrinter
    with SimulatedPrinter(SimConfig(time_scale=0.01)) as sim:
        host = serial.Serial(sim.port, 250000)
        ...

``python -m sim --help`` runs it as a program.
"""

from .config import FaultConfig, FrameConfig, SimConfig
from .frame import FramePose
from .printer import SimulatedPrinter
from .record import CommandRecord, Segment
from .stats import Stats

__all__ = [
    "CommandRecord",
    "FaultConfig",
    "FramePose",
    "FrameConfig",
    "Segment",
    "SimConfig",
    "SimulatedPrinter",
    "Stats",
]
