"""What coverage (``mrlib.metrics.coverage``) and the diversities
(``mrlib.metrics.diversity``) share: per-frame metric features, frame distances, and
the nearest window of one clip in another.

The metrics follow Li et al., "GANimator: Neural Motion Synthesis from a Single Sequence"
(SIGGRAPH 2022) as used in Section "Evaluation and Discussion" of the mrlib paper
(Eq. 17-20). Every metric runs on the one blocked kernel here (:func:`window_nn`,
:func:`distance_rows`, both on ``_dist_block`` in blocks of ``_CHUNK_ELEMS``), so that
its block size and numerics stay one decision; the slow versions written from the definitions, which
the tests check these against, are in ``mrlib.metrics.oracles``.

**Features.** Every metric works on per-frame feature vectors ``(T, D)``; build them with
:func:`metric_features`: the local rotations of joints 1..23 (the root's global
orientation and translation are left out) in 6D, ``D = 23 * 6``, plus the 6 foot-contact
labels when the clip has them (``D = 144``); ``kind="rotmat"`` uses flattened rotation
matrices instead, and ``kind="rotmat", contacts=False`` is the paper's distance ("the
Frobenius norm on the local joint rotation matrices"; ``mrlib evaluate --features paper``).
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

from collections.abc import Iterable, Iterator
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
    "reconstruction_error",
    # what the metric modules build on (not re-exported by mrlib.metrics)
    "as_features",
    "as_sample_list",
    "centred_pair",
    "check_positive_int",
    "check_windows",
    "windowed_pair",
    "window_nn",
    "distance_rows",
]

# Largest block of the frame-distance matrix held at once, in float64 elements (8 MiB;
# larger blocks were not faster).
# Every metric computes the matrix in row blocks of about this size.
_CHUNK_ELEMS = 1 << 20


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
    return as_features(motion_or_features, "features")


def as_features(x: Any, name: str) -> np.ndarray:
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


def as_sample_list(generated: Any) -> tuple[list | Iterable, bool]:
    """(samples, is_single): one clip, or an iterable of clips."""
    if isinstance(generated, (np.ndarray, torch.Tensor, Motion)):
        return [generated], True
    if isinstance(generated, Iterable):
        return generated, False
    raise MotionValueError(
        f"generated must be a (T, D) array, a Motion or a list of them, got {type(generated)}"
    )


def centred_pair(
    gen: Any, ref: Any, gname: str = "generated", rname: str = "reference"
) -> tuple[np.ndarray, np.ndarray]:
    """Validate a (generated, reference) pair and centre both on the reference mean (distances
    do not change; the |x|^2 + |y|^2 - 2 x.y expansion loses less precision)."""
    g, r = as_features(gen, gname), as_features(ref, rname)
    if g.shape[1] != r.shape[1]:
        raise MotionValueError(
            f"{gname} has {g.shape[1]} feature channels but {rname} has {r.shape[1]}"
        )
    mu = r.mean(0)
    return g - mu, r - mu


def check_positive_int(name: str, value: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise MotionValueError(f"{name} must be a positive integer, got {value!r}")
    return int(value)


def check_windows(w: int, clips: dict[str, np.ndarray]) -> None:
    for name, arr in clips.items():
        if len(arr) < w:
            raise ClipTooShortError(f"{name} has {len(arr)} frames, fewer than the window of {w}")


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


# ---------------------------------------------------------------------------------------
# Frame distances and window nearest neighbours
# ---------------------------------------------------------------------------------------
def frame_distances(x: Any, y: Any, squared: bool = False) -> np.ndarray:
    """All per-frame distances ``|x_t - y_l|`` (or squared), ``(T_x, T_y)`` float64.

    Args:
        x: ``(T_x, D)`` features; y: ``(T_y, D)`` features.
    """
    x, y = centred_pair(x, y, "x", "y")
    return _dist_block(x, y, (y * y).sum(1), squared)


def reconstruction_error(a: Any, b: Any, squared: bool = False) -> float:
    """Mean per-frame distance between two clips of equal length, ``a, b (T, D)``."""
    x, y = centred_pair(a, b, "a", "b")
    if len(x) != len(y):
        raise MotionValueError(
            f"reconstruction_error needs equal lengths, got {len(x)} and {len(y)}"
        )
    d2 = ((x - y) ** 2).sum(1)
    return float((d2 if squared else np.sqrt(d2)).mean())


def _dist_block(x: np.ndarray, y: np.ndarray, y2: np.ndarray, squared: bool) -> np.ndarray:
    """``(n, T_y)`` distances from rows ``x (n, D)`` to ``y (T_y, D)``; ``y2 = |y|^2``."""
    d2 = x @ y.T  # (n, T_y)
    d2 *= -2.0
    d2 += (x * x).sum(1)[:, None]
    d2 += y2[None, :]
    np.maximum(d2, 0.0, out=d2)  # rounding can make tiny distances negative
    return d2 if squared else np.sqrt(d2, out=d2)


def distance_rows(x: np.ndarray, y: np.ndarray, squared: bool) -> Iterator[np.ndarray]:
    """The rows ``D[t] (T_y,)`` of the frame-distance matrix of ``x`` and ``y``, in order,
    computed in blocks of about ``_CHUNK_ELEMS`` elements; the whole matrix is never held."""
    y2 = (y * y).sum(1)
    rows_per_block = max(1, _CHUNK_ELEMS // len(y))
    for t0 in range(0, len(x), rows_per_block):
        yield from _dist_block(x[t0 : t0 + rows_per_block], y, y2, squared)


def window_nn(x: np.ndarray, y: np.ndarray, w: int, squared: bool) -> tuple[np.ndarray, np.ndarray]:
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


def windowed_pair(
    generated: Any, reference: Any, window: int, names: tuple[str, str] = ("generated", "reference")
) -> tuple[int, np.ndarray, np.ndarray]:
    """``(w, g, r)``: the window checked, and the two clips validated, centred on the
    reference mean (:func:`centred_pair`) and checked to hold at least one window each
    (``names`` name them in errors)."""
    w = check_positive_int("window", window)
    g, r = centred_pair(generated, reference, *names)
    check_windows(w, {names[0]: g, names[1]: r})
    return w, g, r


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
    w, g, r = windowed_pair(generated, reference, window, names)
    return window_nn(g, r, w, squared)
