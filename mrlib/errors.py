"""Typed errors raised at mrlib's public entry points.

Every error names the offending file (when there is one) and the problem, so that a
user sees ``BVHFormatError: walk.bvh, line 12: expected 'OFFSET', got 'OFSET'`` rather
than a traceback from deep inside numpy.
"""

from __future__ import annotations

from numbers import Integral
from pathlib import Path
from typing import Any

__all__ = [
    "check_count",
    "MrlibError",
    "MotionFileError",
    "BVHFormatError",
    "JointMapError",
    "MotionValueError",
    "UnsupportedFormatError",
    "ClipTooShortError",
    "BodyModelError",
]


class MrlibError(Exception):
    """Base class of every error mrlib raises on purpose."""


class MotionFileError(MrlibError, ValueError):
    """A motion file could not be read: missing keys, wrong shapes, bad values."""

    def __init__(self, path: str | Path | None, problem: str):
        self.path = None if path is None else Path(path)
        self.problem = problem
        where = f"{self.path}: " if self.path is not None else ""
        super().__init__(f"{where}{problem}")


class BVHFormatError(MotionFileError):
    """A BVH file is truncated or malformed."""


class JointMapError(MotionFileError):
    """A skeleton's joints cannot be mapped onto SMPL's."""


class UnsupportedFormatError(MotionFileError):
    """The file extension is not one mrlib can read or write."""


class MotionValueError(MrlibError, ValueError):
    """An in-memory motion or feature array has the wrong shape or non-finite values."""


class ClipTooShortError(MrlibError, ValueError):
    """A clip has fewer frames than the model or metric needs."""


class BodyModelError(MrlibError, ValueError):
    """A body model file is missing or does not look like SMPL."""


def check_count(name: str, value: Any) -> int:
    """``value`` as an int if it is a positive integer, else a ``MotionValueError``."""
    if isinstance(value, bool) or not isinstance(value, Integral) or value < 1:
        raise MotionValueError(f"{name} must be a positive integer, got {value!r}")
    return int(value)
