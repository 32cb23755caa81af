"""The fabric frame's pose on the bed: which side is up and how it is misaligned.

The pose maps fabric coordinates q (the front side's print coordinates) to machine
coordinates p.  Front up: p = Rot_c(r)·q + offset.  Back up:
p = Rot_c(r)·Mirror(q) + offset, where Mirror reflects about the flip axis through
the centre c and Rot_c(r) rotates by r degrees about c.  The simulator starts front
up with no misalignment, i.e. the identity.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .config import FrameConfig

__all__ = ["FramePose", "Frame"]


@dataclass(frozen=True)
class FramePose:
    side: str = "front"
    offset: tuple[float, float] = (0.0, 0.0)
    rotation_deg: float = 0.0


class Frame:
    """Converts deposited machine points to fabric coordinates under the current pose."""

    def __init__(self, config: FrameConfig) -> None:
        self._center = np.array(config.center, dtype=float)
        # Index of the coordinate the flip negates: about the y axis, x flips.
        self._mirror_index = 0 if config.flip_axis == "y" else 1
        self.pose = FramePose()

    @property
    def side(self) -> str:
        return self.pose.side

    def flip(self, offset: tuple[float, float] = (0.0, 0.0), rotation_deg: float = 0.0) -> FramePose:
        """Turn the frame over, then misalign it by ``rotation_deg`` and ``offset``."""
        side = "back" if self.pose.side == "front" else "front"
        self.pose = FramePose(side, (float(offset[0]), float(offset[1])), float(rotation_deg))
        return self.pose

    def reset(self) -> None:
        self.pose = FramePose()

    def _rotation(self) -> np.ndarray:
        a = math.radians(self.pose.rotation_deg)
        return np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])

    def _mirror(self, pts: np.ndarray) -> np.ndarray:
        if self.pose.side == "front":
            return pts
        out = pts.copy()
        i = self._mirror_index
        out[:, i] = 2.0 * self._center[i] - out[:, i]
        return out

    def to_machine(self, fabric: np.ndarray) -> np.ndarray:
        """Fabric points (N, 2) to machine points (N, 2)."""
        q = self._mirror(np.asarray(fabric, dtype=float).reshape(-1, 2))
        c = self._center
        return (q - c) @ self._rotation().T + c + np.asarray(self.pose.offset)

    def to_fabric(self, machine: np.ndarray) -> np.ndarray:
        """Machine points (N, 2) to fabric points (N, 2): the inverse of ``to_machine``."""
        p = np.asarray(machine, dtype=float).reshape(-1, 2)
        c = self._center
        # Rotation matrices are orthogonal: the inverse is the transpose.
        q = (p - np.asarray(self.pose.offset) - c) @ self._rotation() + c
        return self._mirror(q)  # a mirror is its own inverse
