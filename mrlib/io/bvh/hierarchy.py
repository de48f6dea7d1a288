"""The BVH hierarchy model: ``BVHSkeleton`` (the HIERARCHY section) and ``BVH`` (a whole
file: skeleton, channel values, frame time), and the frame-time bounds that the reader
(``mrlib.io.bvh.reader``, which refuses others) and the writer (``mrlib.io.bvh.writer``,
which never writes them) share. Conventions: ``mrlib.io.bvh``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from mrlib.representation.motion import MAX_FPS

__all__ = [
    "BVHSkeleton",
    "BVH",
    "MIN_FRAME_TIME",
    "MAX_FRAME_TIME",
    "frame_time_problem",
]

# "Frame Time:" bounds in seconds per frame, one pair for the reader (which refuses
# others) and the writer (which never writes them): 1000 fps down to 0.01 fps
MIN_FRAME_TIME = 1.0 / MAX_FPS
MAX_FRAME_TIME = 100.0


def frame_time_problem(frame_time: float) -> str | None:
    """Why ``frame_time`` (seconds) is no BVH frame time, or None when it is one."""
    if math.isfinite(frame_time) and MIN_FRAME_TIME <= frame_time <= MAX_FRAME_TIME:
        return None
    return (
        f"'Frame Time:' must be seconds per frame between {MIN_FRAME_TIME:g} and "
        f"{MAX_FRAME_TIME:g} ({1 / MAX_FRAME_TIME:g} to {1 / MIN_FRAME_TIME:g} fps)"
    )


@dataclass(frozen=True)
class BVHSkeleton:
    """The HIERARCHY section.

    Attributes:
        names: ``J`` joint names in file order (parents precede children).
        parents: ``J`` parent indices, -1 for the root.
        offsets: ``(J, 3)`` float64 rest translations relative to the parent, file units.
        channels: per joint, the channel names in file order (``"Zrotation"``, ...).
        end_sites: ``(joint index, (3,) offset)`` pairs, one per ``End Site`` block.
    """

    names: tuple[str, ...]
    parents: tuple[int, ...]
    offsets: np.ndarray
    channels: tuple[tuple[str, ...], ...]
    end_sites: tuple[tuple[int, np.ndarray], ...] = ()

    @property
    def num_joints(self) -> int:
        return len(self.names)

    @property
    def num_channels(self) -> int:
        return sum(len(c) for c in self.channels)

    def index(self, name: str) -> int:
        """Index of the joint called ``name`` (KeyError if absent)."""
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(name) from None

    def channel_starts(self) -> np.ndarray:
        """``(J,)`` index of each joint's first channel in a frame line."""
        sizes = np.array([len(c) for c in self.channels], dtype=np.int64)
        return np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)


@dataclass(frozen=True)
class BVH:
    """A parsed BVH file: skeleton, channel values and frame time.

    Attributes:
        skeleton: the hierarchy.
        motion: ``(T, C)`` float64 channel values, angles in degrees.
        frame_time: seconds per frame.
        source: where it came from (a path or ``"<string>"``), used in error messages.
    """

    skeleton: BVHSkeleton
    motion: np.ndarray
    frame_time: float
    source: str = field(default="<string>")

    @property
    def num_frames(self) -> int:
        return len(self.motion)

    @property
    def fps(self) -> float:
        return 1.0 / self.frame_time
