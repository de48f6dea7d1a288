"""The metrics of ``mrlib.metrics.coverage`` and ``mrlib.metrics.diversity`` written
straight from their definitions (the paper's Eq. 17-20): slow oracles (one row, one
window, one segmentation at a time) that the tests and ``bench/metrics_speed.py`` check
the fast, blocked versions against. Not for use on real clips: the global diversity
here is ``O(T_g^2 * T_r)``, and :func:`global_diversity_enumerate` lists every
segmentation (tiny inputs only).

Dimension letters (``mrlib`` glossary): T frames, D feature channels, N windows.
"""

from __future__ import annotations

import itertools

import numpy as np

from mrlib.errors import ClipTooShortError
from mrlib.metrics.diversity import Segmentation

__all__ = [
    "frame_distances_naive",
    "window_nn_naive",
    "coverage_naive",
    "local_diversity_naive",
    "global_diversity_naive",
    "global_diversity_enumerate",
]


def frame_distances_naive(x: np.ndarray, y: np.ndarray, squared: bool = False) -> np.ndarray:
    """``(T_x, T_y)`` distances, one row at a time from differences (no expansion)."""
    x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
    out = np.empty((len(x), len(y)))
    for i in range(len(x)):
        d2 = ((y - x[i]) ** 2).sum(1)
        out[i] = d2 if squared else np.sqrt(d2)
    return out


def window_nn_naive(x: np.ndarray, y: np.ndarray, w: int, squared: bool = False) -> np.ndarray:
    """Nearest-window distance for every window of ``x``, by trying every window of ``y``."""
    x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
    yw = np.lib.stride_tricks.sliding_window_view(y, w, axis=0).transpose(0, 2, 1)  # (N_y, w, D)
    out = np.empty(len(x) - w + 1)
    for i in range(len(out)):
        d2 = ((yw - x[i : i + w]) ** 2).sum(-1)  # (N_y, w)
        out[i] = (d2 if squared else np.sqrt(d2)).mean(1).min()
    return out


def coverage_naive(
    generated, reference, window: int = 30, eps: float = 2.0, squared: bool = False
) -> float:
    samples = [generated] if isinstance(generated, np.ndarray) else list(generated)
    return float(
        np.mean([(window_nn_naive(reference, g, window, squared) < eps).mean() for g in samples])
    )


def local_diversity_naive(generated, reference, window: int = 15, squared: bool = False) -> float:
    samples = [generated] if isinstance(generated, np.ndarray) else list(generated)
    return float(np.mean([window_nn_naive(g, reference, window, squared).mean() for g in samples]))


def global_diversity_naive(
    generated: np.ndarray, reference: np.ndarray, tmin: int = 30, squared: bool = False
) -> tuple[float, Segmentation]:
    """PNN by the plain O(T_g^2 * T_r) dynamic programme: for every segment start ``a``
    (in increasing order, so ``best[a]`` is final), extend the segment one frame at a time
    keeping its cost at every reference offset, and relax ``best[b]`` once it has
    ``tmin`` frames. Returns (mean per-frame cost, segmentation)."""
    D = frame_distances_naive(generated, reference, squared)
    L, Lr = D.shape
    best = np.full(L + 1, np.inf)
    best[0] = 0.0
    back: list[tuple[int, int]] = [(0, 0)] * (L + 1)
    for a in range(L):
        if not np.isfinite(best[a]):
            continue
        cost = np.zeros(Lr)  # cost[r]: frames [a, b) matched to reference frames [r, r + b - a)
        for b in range(a + 1, L + 1):
            n = b - a
            if n > Lr:
                break
            cost = cost[: Lr - n + 1] + D[b - 1, n - 1 :]
            if n >= tmin:
                r = int(cost.argmin())
                if best[a] + cost[r] < best[b]:
                    best[b] = best[a] + cost[r]
                    back[b] = (a, r)
    if not np.isfinite(best[L]):
        raise ClipTooShortError(
            f"no segmentation of {L} frames with segments of {tmin}..{Lr} frames"
        )
    seg: Segmentation = []
    b = L
    while b > 0:
        a, r = back[b]
        seg.append((a, b, r))
        b = a
    return float(best[L] / L), seg[::-1]


def global_diversity_enumerate(
    generated: np.ndarray,
    reference: np.ndarray,
    tmin: int,
    squared: bool = False,
    max_len: int | None = None,
) -> float:
    """PNN by listing every composition of ``T_g`` into parts of ``tmin..max_len`` frames
    (tiny inputs only). Each part independently takes its best reference offset."""
    D = frame_distances_naive(generated, reference, squared)
    L, Lr = D.shape
    hi = min(Lr, L) if max_len is None else min(max_len, Lr, L)

    def part_cost(a: int, b: int) -> float:
        return min(sum(D[a + m, r + m] for m in range(b - a)) for r in range(Lr - (b - a) + 1))

    def compositions(n: int):
        if n == 0:
            yield ()
        for first in range(tmin, min(hi, n) + 1):
            for rest in compositions(n - first):
                yield (first, *rest)

    best = np.inf
    for parts in compositions(L):
        bounds = list(itertools.accumulate(parts, initial=0))
        best = min(best, sum(part_cost(a, b) for a, b in itertools.pairwise(bounds)))
    return float(best / L)
