"""Evaluation metrics: coverage, global (PNN) and local diversity, reconstruction error,
condition fidelity.

The module is long because every metric here runs on one blocked kernel of frame
distances and window nearest neighbours (``_dist_block``, ``_window_nn``,
``_CHUNK_ELEMS``), kept private to it so that its block size and numerics stay one
decision; the slow versions written from the definitions, which the tests check these
against, are in ``mrlib.metrics.oracles``.

The metrics follow Li et al., "GANimator: Neural Motion Synthesis from a Single Sequence"
(SIGGRAPH 2022) as used in Section "Evaluation and Discussion" of the mrlib paper.

**Features.** Every metric works on per-frame feature vectors ``(T, D)``; build them with
:func:`metric_features`: the local rotations of joints 1..23 (the root's global
orientation and translation are left out) in 6D, ``D = 23 * 6``, plus the 6 foot-contact
labels when the clip has them (``D = 144``); ``kind="rotmat"`` uses flattened rotation
matrices instead (the paper's "Frobenius norm on local joint rotation matrices").
Metric functions also accept a ``Motion`` directly (converted with the default features)
and numpy arrays or torch tensors of features.

**Distances.** The distance between frames ``x`` and ``y`` is the Euclidean norm
``|x - y|``; the distance between two windows of equal length is the mean over their
frames of the per-frame distance. This is what GANimator's evaluation code computes
(``evaluations/patched_nn.py`` in github.com/PeizhuoLi/ganimator: the frame cost is
``torch.norm(src - tgt, dim=2)``, a plain, not squared, L2 norm; windows and segments add
these costs and divide by the number of frames). The paper writes the PNN cost with
``||.||_F^2``; pass ``squared=True`` to any metric to use squared per-frame distances
instead (the coverage threshold ``eps`` then applies to the squared mean).

**Windows.** A clip of ``T`` frames has ``T - w + 1`` windows of ``w`` frames (every start
``0 .. T - w``). GANimator's code loops over ``range(T - w)`` and so leaves out the last
window; the difference is one window in ``T - w + 1``.

Dimension letters (``mrlib`` glossary): T frames, D feature channels, B samples,
N windows.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np
import torch

from mrlib.errors import ClipTooShortError, MotionValueError
from mrlib.representation.features import features_to_motion
from mrlib.representation.motion import Motion
from mrlib.representation.rotations import axis_angle_to_6d, axis_angle_to_matrix

__all__ = [
    "References",
    "model_references",
    "metric_features",
    "frame_distances",
    "nearest_windows",
    "coverage",
    "coverage_profile",
    "global_diversity",
    "local_diversity",
    "reconstruction_error",
    "condition_fidelity",
]

# Largest block of the frame-distance matrix held at once, in float64 elements (8 MiB;
# larger blocks were not faster).
# Every metric computes the matrix in row blocks of about this size.
_CHUNK_ELEMS = 1 << 20

Segmentation = list[tuple[int, int, int]]


# ---------------------------------------------------------------------------------------
# Features
# ---------------------------------------------------------------------------------------
def metric_features(motion_or_features: Any, kind: str = "6d", contacts: bool = True) -> np.ndarray:
    """Per-frame metric features ``(T, D)`` float64.

    Args:
        motion_or_features: a ``Motion`` (poses ``(T, 24, 3)`` axis-angle, optional
            contacts ``(T, 6)``), or an already built ``(T, D)`` numpy array / torch
            tensor, returned as float64 numpy after validation.
        kind: ``"6d"``: joints 1..23 in 6D (first two matrix columns), ``D = 138``;
            ``"rotmat"``: joints 1..23 as row-major flattened 3x3 matrices, ``D = 207``.
        contacts: append the 6 contact labels when the motion has them (``D + 6``).

    The root joint (global orientation) and the translation are not part of the features,
    so the metrics compare body poses independently of where the body is and faces.
    """
    if isinstance(motion_or_features, Motion):
        aa = torch.from_numpy(motion_or_features.poses[:, 1:].astype(np.float64))  # (T, 23, 3)
        if kind == "6d":
            rot = axis_angle_to_6d(aa)  # (T, 23, 6)
        elif kind == "rotmat":
            rot = axis_angle_to_matrix(aa)  # (T, 23, 3, 3)
        else:
            raise MotionValueError(f"metric_features: kind must be '6d' or 'rotmat', got {kind!r}")
        feats = rot.reshape(len(aa), -1).numpy()
        if contacts and motion_or_features.contacts is not None:
            feats = np.concatenate([feats, motion_or_features.contacts.astype(np.float64)], 1)
        return np.ascontiguousarray(feats)
    return _as_features(motion_or_features, "features")


def _as_features(x: Any, name: str) -> np.ndarray:
    """Motion / numpy / torch -> validated ``(T, D)`` float64 numpy array."""
    if isinstance(x, Motion):
        return metric_features(x)
    if isinstance(x, torch.Tensor):
        x = x.detach().cpu().numpy()
    try:
        arr = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise MotionValueError(f"{name}: cannot read as a (T, D) feature array ({exc})") from exc
    if arr.ndim != 2:
        raise MotionValueError(
            f"{name} must have shape (T, D) (per-frame features), got {arr.shape}"
        )
    if len(arr) == 0 or arr.shape[1] == 0:
        raise ClipTooShortError(f"{name} is empty, shape {arr.shape}")
    if not np.isfinite(arr).all():
        bad = np.argwhere(~np.isfinite(arr))[0, 0]
        raise MotionValueError(f"{name} has NaN or inf values (first at frame {bad})")
    return np.ascontiguousarray(arr)


def _as_sample_list(generated: Any) -> tuple[list | Iterable, bool]:
    """(samples, is_single): one clip, or an iterable of clips."""
    if isinstance(generated, (np.ndarray, torch.Tensor, Motion)):
        return [generated], True
    if isinstance(generated, Iterable):
        return generated, False
    raise MotionValueError(
        f"generated must be a (T, D) array, a Motion or a list of them, got {type(generated)}"
    )


def _pair(
    gen: Any, ref: Any, gname: str = "generated", rname: str = "reference"
) -> tuple[np.ndarray, np.ndarray]:
    """Validate a (generated, reference) pair and centre both on the reference mean (distances
    do not change; the |x|^2 + |y|^2 - 2 x.y expansion loses less precision)."""
    g, r = _as_features(gen, gname), _as_features(ref, rname)
    if g.shape[1] != r.shape[1]:
        raise MotionValueError(
            f"{gname} has {g.shape[1]} feature channels but {rname} has {r.shape[1]}"
        )
    mu = r.mean(0)
    return g - mu, r - mu


def _check_positive_int(name: str, value: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise MotionValueError(f"{name} must be a positive integer, got {value!r}")
    return int(value)


# ---------------------------------------------------------------------------------------
# Frame distances and window nearest neighbours
# ---------------------------------------------------------------------------------------
def frame_distances(x: Any, y: Any, squared: bool = False) -> np.ndarray:
    """All per-frame distances ``|x_t - y_l|`` (or squared), ``(T_x, T_y)`` float64.

    Args:
        x: ``(T_x, D)`` features; y: ``(T_y, D)`` features.
    """
    x, y = _pair(x, y, "x", "y")
    return _dist_block(x, y, (y * y).sum(1), squared)


def _dist_block(x: np.ndarray, y: np.ndarray, y2: np.ndarray, squared: bool) -> np.ndarray:
    """``(n, T_y)`` distances from rows ``x (n, D)`` to ``y (T_y, D)``; ``y2 = |y|^2``."""
    d2 = x @ y.T  # (n, T_y)
    d2 *= -2.0
    d2 += (x * x).sum(1)[:, None]
    d2 += y2[None, :]
    np.maximum(d2, 0.0, out=d2)  # rounding can make tiny distances negative
    return d2 if squared else np.sqrt(d2, out=d2)


def _window_nn(
    x: np.ndarray, y: np.ndarray, w: int, squared: bool
) -> tuple[np.ndarray, np.ndarray]:
    """For every ``w``-frame window of ``x``, its nearest ``w``-frame window of ``y``.

    Returns ``(dist (N_x,), start (N_x,))``, ``N_x = T_x - w + 1``: the mean per-frame
    distance to the nearest window of ``y`` and that window's first frame.

    A window pair ``(i, j)`` costs the sum of ``D[i + m, j + m]``, ``m < w``: a run along
    a diagonal of the frame-distance matrix ``D``. Rows of ``D`` come in blocks of ``R``;
    each block is sheared so that its diagonals become columns (``Z[i, j - i + R - 1] =
    D[i, j]``), one ``cumsum`` down the columns gives prefix sums along every diagonal,
    and each window sum is a difference of two prefix sums. Memory is ``O(R * (T_y + R))``.
    """
    tx, ty = len(x), len(y)
    nx, ny = tx - w + 1, ty - w + 1
    y2 = (y * y).sum(1)
    dist = np.empty(nx)
    start = np.empty(nx, dtype=np.int64)
    n_max = max(1, _CHUNK_ELEMS // (ty + w) - w)  # windows per block
    s = np.dtype(np.float64).itemsize
    for i0 in range(0, nx, n_max):
        n = min(n_max, nx - i0)
        R = n + w - 1  # frame rows this block needs
        W = ty + R - 1  # number of diagonals of an (R, T_y) block
        block = _dist_block(x[i0 : i0 + R], y, y2, squared)  # (R, T_y)
        Z = np.zeros((R, W))
        # Z[i, c] with c = j - i + R - 1 holds block[i, j]: flat offset R-1 + i*(W-1) + j.
        sheared = np.lib.stride_tricks.as_strided(
            Z.reshape(-1)[R - 1 :], shape=(R, ty), strides=((W - 1) * s, s)
        )
        sheared[...] = block
        Q = np.empty((R + 1, W))  # Q[i, c]: sum of Z[:i, c]
        Q[0] = 0.0
        np.cumsum(Z, axis=0, out=Q[1:])
        flat = Q.reshape(-1)
        # window (i, j) lies on column c = j - i + R - 1: sum = Q[i + w, c] - Q[i, c].
        hi = np.lib.stride_tricks.as_strided(
            flat[w * W + R - 1 :], shape=(n, ny), strides=((W - 1) * s, s), writeable=False
        )
        lo = np.lib.stride_tricks.as_strided(
            flat[R - 1 :], shape=(n, ny), strides=((W - 1) * s, s), writeable=False
        )
        sums = hi - lo  # (n, N_y)
        j = sums.argmin(1)
        start[i0 : i0 + n] = j
        dist[i0 : i0 + n] = sums[np.arange(n), j] / w
    return dist, start


def nearest_windows(
    generated: Any,
    reference: Any,
    window: int,
    squared: bool = False,
    *,
    names: tuple[str, str] = ("generated", "reference"),
) -> tuple[np.ndarray, np.ndarray]:
    """For every ``window``-frame window of ``generated``, its nearest window of
    ``reference``: ``(dist (N,), start (N,))`` with ``N = T_gen - window + 1``, the mean
    per-frame distance to it and its first frame in ``reference``.

    Args:
        generated, reference: ``(T, D)`` features or Motions (:func:`metric_features`).
        squared: per-frame squared distances instead of distances.
        names: how errors name the two inputs.
    """
    w = _check_positive_int("window", window)
    g, r = _pair(generated, reference, *names)
    _check_windows(w, {names[0]: g, names[1]: r})
    return _window_nn(g, r, w, squared)


def _check_windows(w: int, clips: dict[str, np.ndarray]) -> None:
    for name, arr in clips.items():
        if len(arr) < w:
            raise ClipTooShortError(f"{name} has {len(arr)} frames, fewer than the window of {w}")


# ---------------------------------------------------------------------------------------
# Coverage
# ---------------------------------------------------------------------------------------
def coverage_profile(
    generated: Any, reference: Any, window: int = 30, squared: bool = False
) -> np.ndarray:
    """Nearest-neighbour distance of every reference window in one generated clip.

    Args:
        generated: ``(T_g, D)`` features (or ``Motion``) of one generated clip.
        reference: ``(T_r, D)`` features of the training clip.
        window: window length in frames (the paper's ``T_c = 30``).

    Returns:
        ``(T_r - window + 1,)``: for each reference window (by first frame), the mean
        per-frame distance to the closest ``window``-frame window of ``generated``.
    """
    w = _check_positive_int("window", window)
    g, r = _pair(generated, reference)
    _check_windows(w, {"generated": g, "reference": r})
    return _window_nn(r, g, w, squared)[0]


def coverage(
    generated: Any, reference: Any, window: int = 30, eps: float = 2.0, squared: bool = False
) -> float:
    """Share of reference windows whose nearest generated window is closer than ``eps``.

    Args:
        generated: one generated clip ``(T_g, D)`` or a list (any iterable) of clips;
            for a list the result is the mean over clips (the paper's ``E_z``).
        reference: ``(T_r, D)`` features of the training clip.
        window: window length ``T_c`` in frames (30 in the paper and GANimator).
        eps: coverage threshold on the mean per-frame distance (GANimator: 2.0).

    Returns:
        coverage in [0, 1].
    """
    if not (np.isfinite(eps) and eps > 0):
        raise MotionValueError(f"eps must be a positive number, got {eps}")
    samples, _ = _as_sample_list(generated)
    values = [
        float((coverage_profile(g, reference, window, squared) < eps).mean()) for g in samples
    ]
    if not values:
        raise MotionValueError("coverage: no generated samples")
    return float(np.mean(values))


# ---------------------------------------------------------------------------------------
# Local diversity and reconstruction error
# ---------------------------------------------------------------------------------------
def local_diversity(
    generated: Any, reference: Any, window: int = 15, squared: bool = False
) -> float:
    """Mean over generated windows of the distance to the nearest reference window.

    Args:
        generated: one clip ``(T_g, D)`` or a list of clips (mean over clips).
        reference: ``(T_r, D)`` features of the training clip.
        window: window length ``T_d`` (15 in the paper and GANimator).
    """
    w = _check_positive_int("window", window)
    samples, _ = _as_sample_list(generated)
    values = []
    for gen in samples:
        g, r = _pair(gen, reference)
        _check_windows(w, {"generated": g, "reference": r})
        values.append(float(_window_nn(g, r, w, squared)[0].mean()))
    if not values:
        raise MotionValueError("local_diversity: no generated samples")
    return float(np.mean(values))


def reconstruction_error(a: Any, b: Any, squared: bool = False) -> float:
    """Mean per-frame distance between two clips of equal length, ``a, b (T, D)``."""
    x, y = _pair(a, b, "a", "b")
    if len(x) != len(y):
        raise MotionValueError(
            f"reconstruction_error needs equal lengths, got {len(x)} and {len(y)}"
        )
    d2 = ((x - y) ** 2).sum(1)
    return float((d2 if squared else np.sqrt(d2)).mean())


# ---------------------------------------------------------------------------------------
# Global diversity: patched nearest neighbour
# ---------------------------------------------------------------------------------------
def global_diversity(
    generated: Any,
    reference: Any,
    tmin: int = 30,
    squared: bool = False,
    return_segmentation: bool = False,
) -> float | tuple[float, Segmentation | list[Segmentation]]:
    """Patched nearest neighbour (PNN) cost of a generated clip against a training clip.

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
    t = _check_positive_int("tmin", tmin)
    samples, single = _as_sample_list(generated)
    values, segs = [], []
    for gen in samples:
        g, r = _pair(gen, reference)
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
    r2 = (r * r).sum(1)
    rows_per_block = max(1, _CHUNK_ELEMS // Lr)
    block = np.empty((0, Lr))
    for b in range(1, L + 1):
        t = b - 1
        if t % rows_per_block == 0:
            block = _dist_block(g[t : t + rows_per_block], r, r2, squared)
        lo = L - 1 - t  # diagonals met by row t: k in [lo, lo + Lr)
        P[lo : lo + Lr] += block[t % rows_per_block]
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


# ---------------------------------------------------------------------------------------
# Condition fidelity
# ---------------------------------------------------------------------------------------
def condition_fidelity(
    generated_with_labels: Iterable[Any],
    references: Mapping[str, Any],
    window: int = 30,
    squared: bool = False,
) -> float:
    """Share of generated windows whose nearest training window belongs to the requested label.

    Args:
        generated_with_labels: ``(features (T_g, D), label)`` pairs, or ``Motion``
            objects with ``.label`` set.
        references: label -> ``(T_label, D)`` features of that label's training clip.
            Windows never straddle two training clips.
        window: window length in frames.

    Returns:
        share in [0, 1], pooled over all windows of all generated clips.
    """
    w = _check_positive_int("window", window)
    if not references:
        raise MotionValueError("condition_fidelity: references is empty")
    labels = list(references)
    refs = [_as_features(references[k], f"references[{k!r}]") for k in labels]
    _check_windows(w, {f"references[{k!r}]": x for k, x in zip(labels, refs, strict=True)})
    hits, total = 0, 0
    for item in generated_with_labels:
        if isinstance(item, Motion):
            feats, label = item, item.label
        else:
            feats, label = item
        if label not in references:
            raise MotionValueError(f"condition_fidelity: label {label!r} has no reference clip")
        g = _as_features(feats, f"generated ({label})")
        _check_windows(w, {f"generated ({label})": g})
        nn = []
        for name, x in zip(labels, refs, strict=True):
            if x.shape[1] != g.shape[1]:
                raise MotionValueError(
                    f"generated has {g.shape[1]} channels but references[{name!r}] has {x.shape[1]}"
                )
            mu = x.mean(0)
            nn.append(_window_nn(g - mu, x - mu, w, squared)[0])
        winner = np.argmin(np.stack(nn), axis=0)  # (N,) label index per window
        hits += int((winner == labels.index(label)).sum())
        total += len(winner)
    if total == 0:
        raise MotionValueError("condition_fidelity: no generated samples")
    return hits / total


# -- a trained model's training clips, as references --------------------------------------
References = tuple[list[str], list[str], list[np.ndarray]]  # names, labels, (T_k, D) features


def model_references(
    model: Any, kind: str = "6d", contacts: bool = True
) -> tuple[list[str], list[str], list[np.ndarray]]:
    """Training clips of a model (a ``GenerativeModel``) as metric features:
    ``(names, labels, [(T_k, D)])``; ``kind`` and ``contacts`` as ``metric_features``."""
    names, labels, feats = [], [], []
    for k, x in enumerate(model.features):
        lab = model.labels[model.clip_labels[k]]
        m = features_to_motion(x, model.fps, betas=model.betas, label=lab, name=model.clip_names[k])
        names.append(model.clip_names[k])
        labels.append(lab)
        feats.append(metric_features(m, kind=kind, contacts=contacts))
    return names, labels, feats
