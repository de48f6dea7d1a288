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
    "check_seed",
    "check_path",
    "MAX_SEED",
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


MAX_SEED = 2**32 - 1  # numpy's and torch's seeds are 32/64-bit unsigned


def check_seed(name: str, value: Any) -> int | None:
    """``value`` as an int if it is None or an integer in ``[0, MAX_SEED]``, else a
    ``MotionValueError`` (``1.5`` is refused, not run as 1; ``"7"`` is not a seed)."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, Integral) or not 0 <= value <= MAX_SEED:
        raise MotionValueError(
            f"{name} must be an integer in [0, {MAX_SEED}] or None, got {value!r}"
        )
    return int(value)


def check_path(name: str, value: Any) -> Path:
    """``value`` as a ``Path``: a ``str``, ``os.PathLike`` or ``bytes`` (decoded as the
    file system does), else a ``MotionValueError`` naming what was given."""
    import os

    if not isinstance(value, (str, bytes, os.PathLike)):
        raise MotionValueError(f"{name} must be a file path (str or os.PathLike), got {value!r}")
    text = os.fsdecode(os.fspath(value))
    if not text:
        raise MotionValueError(f"{name} must be a file path, got an empty one")
    return Path(text)
