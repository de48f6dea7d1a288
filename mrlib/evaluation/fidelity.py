"""What the samples of a trained model are near: the training sequence nearest to every
generated window, condition fidelity per label with its confusion matrix, and coverage
of every training clip by its label's samples.

These answer "do samples of label X look like the clips of label X?", the first thing
to check before the crossover of ``mrlib.evaluation.crossover``. Distances are those of
``mrlib.metrics.windows`` (6D local rotations + contacts, windows of 30 frames by default);
pictures in ``mrlib.viz.plots`` (``plot_nearest_sequence``, ``plot_condition_fidelity``).

Dimension letters (``mrlib`` glossary): T frames, D feature channels, N windows,
K labels.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from mrlib.errors import MotionValueError, check_count
from mrlib.metrics.coverage import condition_fidelity, coverage
from mrlib.metrics.windows import (
    References,
    metric_features,
    model_references,
    nearest_windows,
)
from mrlib.representation.motion import Motion

__all__ = [
    "reference_features",
    "NearestSequenceStrip",
    "nearest_sequence_strip",
    "ConditionFidelity",
    "condition_fidelity_of_model",
    "coverage_per_sequence",
]


# -- nearest training sequence of every window ---------------------------------------------
@dataclass(frozen=True)
class NearestSequenceStrip:
    """For each ``window``-frame window of a generated clip (by first frame), the training
    sequence holding its nearest window.

    Attributes:
        names: the training sequences (clip names, or the keys of the references given).
        labels: their labels.
        index: ``(N,)`` int, index into ``names`` per generated window, ``N = T - w + 1``.
        start: ``(N,)`` int, first frame of the nearest window inside that sequence.
        distance: ``(N,)`` mean per-frame distance to it.
        window: ``w`` in frames; fps: frame rate of the generated clip.
    """

    names: tuple[str, ...]
    labels: tuple[str, ...]
    index: np.ndarray
    start: np.ndarray
    distance: np.ndarray
    window: int
    fps: float

    def shares(self) -> dict[str, float]:
        """Share of generated windows whose nearest window is in each sequence."""
        n = len(self.index)
        return {nm: float((self.index == k).sum() / n) for k, nm in enumerate(self.names)}

    def label_shares(self) -> dict[str, float]:
        """Share of generated windows per label of the nearest sequence."""
        out: dict[str, float] = {}
        for nm_share, lab in zip(self.shares().values(), self.labels, strict=True):
            out[lab] = out.get(lab, 0.0) + nm_share
        return out


def reference_features(model_or_references: Any) -> References:
    """The training sequences to compare generated windows with, as metric features:
    ``(names, labels, [(T_k, D)])``.

    Args:
        model_or_references: a ``GenerativeModel`` (its training clips), a mapping
            name -> ``Motion`` or ``(T_k, D)`` features (a Motion's label names its
            sequence, else the key does), or such a triple already computed (returned
            as it is, so callers can compute it once).
    """
    if isinstance(model_or_references, tuple) and len(model_or_references) == 3:
        return model_or_references
    if isinstance(model_or_references, Mapping):
        if not model_or_references:
            raise MotionValueError("references is empty")
        names, labels, feats = [], [], []
        for key, ref in model_or_references.items():
            names.append(str(key))
            labels.append(ref.label if isinstance(ref, Motion) and ref.label else str(key))
            feats.append(metric_features(ref))
        return names, labels, feats
    if hasattr(model_or_references, "features") and hasattr(model_or_references, "clip_labels"):
        return model_references(model_or_references)
    raise MotionValueError(
        "model_or_references must be a GenerativeModel or a mapping name -> Motion / (T, D) "
        f"features, got {type(model_or_references).__name__}"
    )


def nearest_sequence_strip(
    motion: Motion | np.ndarray, model_or_references: Any, window: int = 30
) -> NearestSequenceStrip:
    """Which training sequence every generated window is closest to.

    Args:
        motion: a generated ``Motion`` (or its ``(T, D)`` metric features).
        model_or_references: a ``GenerativeModel`` (its training clips), a mapping
            name -> ``Motion`` or ``(T_k, D)`` features (``mrlib.metrics.windows.metric_features``),
            or the triple of :func:`reference_features` computed once.
        window: window length in frames (30, as coverage and condition fidelity).
    Returns:
        :class:`NearestSequenceStrip`; the distances are those of
        ``mrlib.metrics.coverage.condition_fidelity`` (6D local rotations + contacts).
    """
    window = check_count("window", window)
    names, labels, refs = reference_features(model_or_references)
    x = metric_features(motion)
    fps = float(motion.fps) if isinstance(motion, Motion) else float("nan")
    if len(x) < window:
        raise MotionValueError(f"the clip has {len(x)} frames, fewer than the window {window}")
    dists, starts = [], []
    for nm, r in zip(names, refs, strict=True):
        if len(r) < window:
            raise MotionValueError(f"reference {nm!r} has {len(r)} frames < window {window}")
        d, s = nearest_windows(x, r, int(window), names=("generated", f"reference {nm!r}"))
        dists.append(d)
        starts.append(s)
    D, start = np.stack(dists), np.stack(starts)  # (K, N)
    idx = D.argmin(0)
    cols = np.arange(D.shape[1])
    return NearestSequenceStrip(
        names=tuple(names),
        labels=tuple(labels),
        index=idx,
        start=start[idx, cols],
        distance=D[idx, cols],
        window=int(window),
        fps=fps,
    )


# -- condition fidelity and coverage of a model ---------------------------------------------
@dataclass(frozen=True)
class ConditionFidelity:
    """Condition fidelity of single-condition samples
    (``mrlib.metrics.coverage.condition_fidelity``).

    ``overall`` pools every window of every sample (all samples have the same length, so
    it is the mean of ``per_label``). ``confusion (K, K)``: row = requested label, column
    = label of the nearest training window, shares of windows (rows sum to 1; with one
    clip per label its diagonal is ``per_label``), in the order of ``labels``."""

    overall: float
    per_label: dict[str, float]
    labels: tuple[str, ...]
    confusion: np.ndarray
    num_samples: int
    length: int
    window: int
    seed: int

    def to_markdown(self) -> str:
        rows = ["| label | condition fidelity |", "|---|---|"]
        rows += [f"| {k} | {100 * v:.1f}% |" for k, v in self.per_label.items()]
        rows.append(f"| **all** | **{100 * self.overall:.1f}%** |")
        return "\n".join(rows)


def condition_fidelity_of_model(
    model: Any,
    num_samples: int = 10,
    length: int | None = None,
    seed: int = 0,
    window: int = 30,
    *,
    sampler: Any = None,
) -> ConditionFidelity:
    """Generate ``num_samples`` samples of every label (one label at every level) and
    measure the share of their windows whose nearest training window has that label.

    Args:
        model: a ``GenerativeModel``.
        length: frames per sample; default twice the longest training clip (samples
            longer than the training clips, as the paper's evaluation uses).
        seed: noise seed (every label's samples use the same seed).
        window: window in frames (30, the paper's ``T_c``).
        sampler: a ``mrlib.Sampler``; default the paper's sampler without the
            foot-contact clean-up (``raw_sampler()``: one draw, no clean-up, the raw output).
    Returns:
        :class:`ConditionFidelity`. When several training clips share a label their
        frames are joined into one reference per label (``condition_fidelity`` takes
        one reference per label), so a few windows straddle two clips.
    """
    from mrlib.sampling.generation import generate
    from mrlib.sampling.sampler import raw_sampler

    num_samples = check_count("num_samples", num_samples)
    sampler = raw_sampler(sampler)
    _, labels, feats = model_references(model)
    refs = {
        lab: np.concatenate([f for f, lb in zip(feats, labels, strict=True) if lb == lab])
        for lab in dict.fromkeys(labels)
    }
    if length is None:
        length = 2 * int(model.lengths[:, -1].max())
    per_label, names = {}, list(refs)
    confusion = np.zeros((len(names), len(names)))
    for k, lab in enumerate(names):
        ms = generate(model, lab, length=int(length), seed=seed, num=num_samples, sampler=sampler)
        per_label[lab] = condition_fidelity(ms, refs, window=window)
        for m in ms:
            shares = nearest_sequence_strip(m, refs, window).shares()
            confusion[k] += [shares[n] / len(ms) for n in names]
    return ConditionFidelity(
        overall=float(np.mean(list(per_label.values()))),
        per_label=per_label,
        labels=tuple(names),
        confusion=confusion,
        num_samples=int(num_samples),
        length=int(length),
        window=int(window),
        seed=int(seed),
    )


def coverage_per_sequence(
    model: Any,
    num_samples: int = 20,
    length_factor: float = 2.0,
    seed: int = 0,
    eps: float | Sequence[float] = 2.0,
    window: int = 30,
    *,
    sampler: Any = None,
) -> dict[str, float] | dict[float, dict[str, float]]:
    """``mrlib.metrics.coverage.coverage`` of every training sequence by samples of its label.

    For clip k (label l, ``T_k`` frames): ``num_samples`` samples of label l, each
    ``round(length_factor * T_k)`` frames, and the mean over them of the share of clip
    k's ``window``-frame windows with a generated window closer than ``eps``.

    Args:
        eps: one threshold, or several (the same samples serve every threshold).
        sampler: a ``mrlib.Sampler``; default the raw output of one draw
            (``raw_sampler()``).
    Returns:
        clip name -> coverage in [0, 1]; for several thresholds, eps -> that dict.
    """
    from mrlib.sampling.generation import generate
    from mrlib.sampling.sampler import raw_sampler

    num_samples = check_count("num_samples", num_samples)
    sampler = raw_sampler(sampler)
    if not (np.isfinite(length_factor) and length_factor > 0):
        raise MotionValueError(f"length_factor must be positive, got {length_factor}")
    many = not isinstance(eps, (int, float, np.floating, np.integer))
    epss = [float(e) for e in (eps if many else [eps])]
    if not epss or not all(np.isfinite(e) and e > 0 for e in epss):
        raise MotionValueError(f"eps must be positive numbers, got {eps}")
    names, labels, feats = model_references(model)
    out: dict[float, dict[str, float]] = {e: {} for e in epss}
    for name, lab, ref in zip(names, labels, feats, strict=True):
        length = max(window, round(length_factor * len(ref)))
        ms = generate(model, lab, length=length, seed=seed, num=num_samples, sampler=sampler)
        for e, value in coverage(ms, ref, window, eps=epss).items():
            out[e][name] = value
    return out if many else out[epss[0]]
