"""Global diversity, the patched nearest neighbour (PNN) cost of the paper's Eq. (19),
and local diversity, Eq. (20) (Section "Evaluation and Discussion", after GANimator):
how far generated motion is from a training clip, over its whole structure and window
by window.

Eq. (19): ``L_PNN = min_{l_t} 1/T sum_t ||G^t - X^{l_t}||``, the minimum over
segmentations of the generated clip into segments of at least ``T_min = 30`` frames,
each matched to consecutive frames of the training clip ``X``, of the mean per-frame
distance (the paper writes it squared, ``||.||_F^2``; GANimator's code and mrlib's
default use the plain norm, ``squared=True`` the paper's). Eq. (20): ``L_local =
1/|W(G, T_d)| sum_{w in W(G, T_d)} NN(w, X)``, the mean over the generated clip's
windows of ``T_d = 15`` frames of the distance to the nearest training window. Features,
distances and windows are described in ``mrlib.metrics.windows``.

Dimension letters (``mrlib`` glossary): T frames, D feature channels, N windows.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mrlib.errors import ClipTooShortError, MotionValueError
from mrlib.metrics.windows import (
    as_sample_list,
    centred_pair,
    check_positive_int,
    distance_rows,
    window_nn,
    windowed_pair,
)

__all__ = ["Segmentation", "global_diversity", "local_diversity"]

Segmentation = list[tuple[int, int, int]]


def global_diversity(
    generated: Any,
    reference: Any,
    tmin: int = 30,
    squared: bool = False,
    return_segmentation: bool = False,
) -> float | tuple[float, Segmentation | list[Segmentation]]:
    """Patched nearest neighbour (PNN) cost of a generated clip against a training clip,
    the global diversity of Eq. (19).

    Minimum, over segmentations of ``generated`` into contiguous segments of at least
    ``tmin`` frames, each matched to a window of ``reference`` of the same length
    (consecutive frames), of the mean per-frame distance. Exact.

    Args:
        generated: ``(T_g, D)`` features, or a list of clips (result: mean over clips).
        reference: ``(T_r, D)`` features.
        tmin: shortest segment ``T_min`` in frames (30 in the paper).
        squared: squared per-frame distances (the paper's formula) instead of plain.
        return_segmentation: also return the optimal segmentation, a list of
            ``(gen_start, gen_stop, ref_start)``: frames ``[gen_start, gen_stop)`` match
            reference frames from ``ref_start`` on. Adjacent segments that continue on
            the same reference frames are merged. For a list of clips, a list of those.

    Raises:
        ClipTooShortError: a clip is shorter than ``tmin``, or (when ``T_r < 2 tmin - 1``)
            no segmentation with segments of ``tmin`` to ``T_r`` frames exists.

    Time ``O(T_g * T_r * D)`` (the distance rows) plus ``O(T_g * T_r)`` for the dynamic
    programme, memory ``O(T_g + T_r)`` beyond one block of distance rows; see
    :func:`_pnn_dp`. GANimator's kernel tabulates all ``(start, stop, offset)`` triples,
    ``O(T_g^2 * T_r)`` memory.
    """
    t = check_positive_int("tmin", tmin)
    samples, single = as_sample_list(generated)
    values, segs = [], []
    for gen in samples:
        g, r = centred_pair(gen, reference)
        if len(g) < t:
            raise ClipTooShortError(f"generated has {len(g)} frames, fewer than tmin={t}")
        if len(r) < t:
            raise ClipTooShortError(f"reference has {len(r)} frames, fewer than tmin={t}")
        total, seg = _pnn_dp(g, r, t, squared)
        values.append(total / len(g))
        segs.append(_merge_segments(seg))
    if not values:
        raise MotionValueError("global_diversity: no generated samples")
    value = float(np.mean(values))
    if return_segmentation:
        return value, (segs[0] if single else segs)
    return value


def _pnn_dp(g: np.ndarray, r: np.ndarray, tmin: int, squared: bool) -> tuple[float, Segmentation]:
    """Exact PNN by dynamic programming over diagonals; returns (total cost, segments).

    Notation: ``D[t, l]`` frame distance (``T_g x T_r``); a diagonal ``d = l - t`` is stored
    at index ``k = d + T_g - 1``; ``P_k`` is the running sum of ``D`` along diagonal ``k``
    over the rows read so far. A segment of generated frames ``[a, b)`` on diagonal ``d``
    (reference frames ``[a + d, b + d)``) costs ``P_k[b] - P_k[a]``, and it is admissible
    when ``b - a >= tmin``, ``a + d >= 0`` and ``b + d <= T_r``. With ``best[b]`` the
    cheapest segmentation of frames ``[0, b)``,

        best[b] = min_k ( M_k(b) + P_k[b] ),  M_k(b) = min_{a <= b - tmin} best[a] - P_k[a],

    the min over diagonals whose row ``b - 1`` lies in the reference (so the segment ends
    inside it). ``M_k`` only grows a candidate per step (``a = b - tmin``), so it is a
    running minimum; the candidate's term ``best[a] - P_k[a]`` is computed at step ``a``
    (for the ``T_r`` diagonals on which a segment can start at ``a``) and kept in a ring
    of ``tmin`` rows until it becomes admissible. Each step touches ``T_r`` entries, and
    ``argmin`` bookkeeping (start of the best candidate per diagonal, and per ``b``) lets
    the segmentation be traced back. The row ``D[b - 1]`` is computed in blocks and never
    stored whole.

    Segments longer than ``2 tmin - 1`` frames never need to be split off (a segment of
    ``n >= 2 tmin`` frames is two segments of ``tmin`` and ``n - tmin`` frames on the same
    diagonal, same cost), but nothing here relies on it.
    """
    L, Lr = len(g), len(r)
    K = L + Lr - 1
    P = np.zeros(K)  # prefix sums along diagonals
    M = np.full(K, np.inf)  # running min of best[a] - P_k[a] over admitted a
    M_start = np.zeros(K, dtype=np.int64)  # the a attaining M
    best = np.full(L + 1, np.inf)
    best[0] = 0.0
    seg_start = np.zeros(L + 1, dtype=np.int64)
    seg_diag = np.zeros(L + 1, dtype=np.int64)
    ring = np.full((tmin, Lr), np.inf)  # ring[a % tmin] = best[a] - P[slice(a)]
    ring[0] = 0.0  # a = 0: best = 0, P = 0
    for b, row in enumerate(distance_rows(g, r, squared), start=1):  # row = D[b - 1]
        t = b - 1
        lo = L - 1 - t  # diagonals met by row t: k in [lo, lo + Lr)
        P[lo : lo + Lr] += row
        if b >= tmin:
            a = b - tmin
            if np.isfinite(best[a]):
                la = L - 1 - a
                Ma, cand = M[la : la + Lr], ring[a % tmin]
                better = cand < Ma
                Ma[better] = cand[better]
                M_start[la : la + Lr][better] = a
            vals = M[lo : lo + Lr] + P[lo : lo + Lr]
            k = int(vals.argmin())
            best[b] = vals[k]
            seg_start[b] = M_start[lo + k]
            seg_diag[b] = lo + k - (L - 1)
        if b < L:
            lb = L - 1 - b
            np.subtract(best[b], P[lb : lb + Lr], out=ring[b % tmin])
    if not np.isfinite(best[L]):
        raise ClipTooShortError(
            f"no segmentation of {L} frames into segments of {tmin}..{Lr} frames exists "
            f"(reference has {Lr} frames)"
        )
    segments: Segmentation = []
    b = L
    while b > 0:
        a = int(seg_start[b])
        segments.append((a, b, a + int(seg_diag[b])))
        b = a
    return float(best[L]), segments[::-1]


def _merge_segments(segments: Segmentation) -> Segmentation:
    """Join neighbours ``(a, b, r), (b, c, r + b - a)`` that continue on one diagonal."""
    out: Segmentation = []
    for a, b, r in segments:
        if out and out[-1][1] == a and out[-1][2] + (a - out[-1][0]) == r:
            out[-1] = (out[-1][0], b, out[-1][2])
        else:
            out.append((a, b, r))
    return out


def local_diversity(
    generated: Any, reference: Any, window: int = 15, squared: bool = False
) -> float:
    """Mean over generated windows of the distance to the nearest reference window, the
    local diversity of Eq. (20).

    Args:
        generated: one clip ``(T_g, D)`` or a list of clips (mean over clips).
        reference: ``(T_r, D)`` features of the training clip.
        window: window length ``T_d`` (15 in the paper and GANimator).
    """
    w = check_positive_int("window", window)
    samples, _ = as_sample_list(generated)
    values = []
    for gen in samples:
        _, g, r = windowed_pair(gen, reference, w)
        values.append(float(window_nn(g, r, w, squared)[0].mean()))
    if not values:
        raise MotionValueError("local_diversity: no generated samples")
    return float(np.mean(values))
