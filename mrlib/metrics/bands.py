"""The frequency bands of a motion: a zero-phase low-pass split at a cutoff, and the
per-channel RMS profile of a residual. The crossover evidence
(``mrlib.evaluation.crossover``) and restyling (``mrlib.sampling.restyling``) split a
clip at a pyramid level's Nyquist frequency with these; why the split is made this way
is in ``mrlib.evaluation.crossover``'s docstring.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mrlib.errors import MotionValueError

__all__ = [
    "FILTER_ORDER",
    "check_cutoff",
    "check_split_level",
    "lowpass",
    "split_bands",
    "rms_profile",
]


FILTER_ORDER = 4  # Butterworth order of each pass (forward and backward)


def check_cutoff(fps: float, cutoff_hz: float) -> None:
    if not (np.isfinite(fps) and fps > 0):
        raise MotionValueError(f"fps must be a positive number, got {fps}")
    if not (np.isfinite(cutoff_hz) and 0 < cutoff_hz < fps / 2):
        raise MotionValueError(
            f"cutoff must lie in (0, fps/2) = (0, {fps / 2:g}) Hz, got {cutoff_hz}"
        )


def check_split_level(level: Any, num_levels: int, what: str, meaning: str) -> int:
    """``level`` as an int if it splits a pyramid of ``num_levels`` levels into ``1..level``
    and ``level+1..num_levels`` (an integer in ``1..num_levels-1``), else a
    ``MotionValueError`` naming it ``what`` and saying what the two parts are
    (``meaning``)."""
    if isinstance(level, bool) or not isinstance(level, (int, np.integer)):
        raise MotionValueError(f"{what} must be an integer, got {level!r}")
    if not 1 <= level <= num_levels - 1:
        raise MotionValueError(f"{what} must be in 1..{num_levels - 1} ({meaning}), got {level}")
    return int(level)


def lowpass(x: np.ndarray, fps: float, cutoff_hz: float) -> np.ndarray:
    """Zero-phase Butterworth low-pass along time (``scipy.signal.sosfiltfilt``).

    Order ``FILTER_ORDER`` run forwards and backwards: no delay, and an amplitude
    response ``1 / (1 + (tan(pi f / fps) / tan(pi f_c / fps))^8)`` (the digital
    Butterworth's), i.e. ``1/2`` at the cutoff and under 0.4% from twice the cutoff on.

    Args:
        x: ``(T, D)`` per-frame features.
        fps: frame rate of ``x``.
        cutoff_hz: cutoff frequency, in ``(0, fps / 2)``.
    Returns:
        ``(T, D)`` float64. Clip ends are padded by odd reflection (scipy's default), so
        constants and straight lines pass (to about 1e-4 of their range).
    """
    from scipy.signal import butter, sosfiltfilt

    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 2:
        raise MotionValueError(f"lowpass expects (T, D) features, got shape {x.shape}")
    check_cutoff(fps, cutoff_hz)
    if len(x) < 2:
        return x.copy()
    sos = butter(FILTER_ORDER, cutoff_hz, btype="low", fs=fps, output="sos")
    pad = min(len(x) - 1, 3 * (2 * len(sos) + 1))  # scipy's default, shortened for short clips
    return sosfiltfilt(sos, x, axis=0, padlen=pad)


def split_bands(x: np.ndarray, fps: float, cutoff_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """``x (T, D)`` -> ``(low, high)``, both ``(T, D)``, with ``low + high == x``:
    :func:`lowpass` and the residual."""
    low = lowpass(x, fps, cutoff_hz)
    return low, np.asarray(x, np.float64) - low


def rms_profile(x: np.ndarray) -> np.ndarray:
    """Per-channel root mean square over time, ``(T, D) -> (D,)``."""
    x = np.asarray(x, np.float64)
    if x.ndim != 2 or len(x) == 0:
        raise MotionValueError(f"rms_profile expects (T, D) with T >= 1, got shape {x.shape}")
    return np.sqrt((x * x).mean(0))
