"""Motion planner: a ring of blocks executed back to back at constant speed.

Blocks run in virtual time: a block starts when the previous one ends, or when it
is added if the planner had run dry.  The loop only notices completions when it
wakes up, but since start times chain from the previous block's end rather than
from the moment of noticing, timer jitter never accumulates.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, replace

__all__ = ["Block", "Planner", "Position"]

Position = tuple[float, float, float, float]  # x, y, z, e (mm, machine coordinates)


@dataclass(frozen=True)
class Block:
    start: Position
    end: Position
    feed: float
    """mm/min, as run: the commanded feed × the M220 override."""
    t_start: float
    t_end: float

    def at(self, t: float) -> Position:
        """Where the toolhead is at wall time ``t`` within this block."""
        span = self.t_end - self.t_start
        f = 1.0 if span <= 0 else min(1.0, max(0.0, (t - self.t_start) / span))
        return tuple(a + (b - a) * f for a, b in zip(self.start, self.end))  # type: ignore[return-value]


class Planner:
    """Holds at most ``ring_size - 1`` blocks, like Marlin's block ring buffer."""

    def __init__(self, ring_size: int) -> None:
        self.capacity = ring_size - 1
        self._blocks: deque[Block] = deque()
        self._tail_end = float("-inf")
        self._pos: Position = (0.0, 0.0, 0.0, 0.0)

    def __len__(self) -> int:
        return len(self._blocks)

    def moves_free(self) -> int:
        """Marlin's planner.moves_free(): BLOCK_BUFFER_SIZE - 1 - blocks queued."""
        return self.capacity - len(self._blocks)

    def is_empty(self) -> bool:
        return not self._blocks

    def add(self, start: Position, end: Position, feed: float, duration: float, t: float) -> Block:
        """Queue a move taking ``duration`` wall seconds; the caller checks ``moves_free``."""
        t_start = max(self._tail_end, t)
        block = Block(start, end, feed, t_start, t_start + duration)
        self._blocks.append(block)
        self._tail_end = block.t_end
        return block

    def next_completion(self) -> float | None:
        return self._blocks[0].t_end if self._blocks else None

    def complete_head(self) -> Block:
        block = self._blocks.popleft()
        self._pos = block.end
        return block

    def quickstop(self, t: float) -> Block | None:
        """Drop every block; return the executing one truncated at ``t`` (if it had started).

        The caller completes the blocks that ended by ``t`` first.
        """
        partial: Block | None = None
        if self._blocks and self._blocks[0].t_start < t:
            head = self._blocks[0]
            partial = replace(head, end=head.at(t), t_end=t)
            self._pos = partial.end
        self._blocks.clear()
        self._tail_end = float("-inf")
        return partial

    def position_at(self, t: float) -> Position:
        """The steppers' actual position at ``t``."""
        pos = self._pos
        for block in self._blocks:  # blocks run back to back: find the one at t
            if block.t_start > t:
                break
            pos = block.at(t)
        return pos

    def set_position(self, pos: Position) -> None:
        """Position the steppers are taken to be at when idle (G92, G28)."""
        self._pos = pos

    def clear(self) -> None:
        self._blocks.clear()
        self._tail_end = float("-inf")
        self._pos = (0.0, 0.0, 0.0, 0.0)
