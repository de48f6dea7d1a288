"""Measures of restyling (``mrlib.sampling.restyling.restyle``): how far a clip is from
what a model's coarse levels produce (:func:`coarse_gap`), a restyled clip against the
method's three claims (:func:`restyle_evidence`, with the references of
:func:`restyle_references`: the path kept, the low band nearer the clip's than any
training clip's, the residual nearest the target label's), and how much of a result is
the clip's and how much the label's, level by level (:func:`restyle_shares`). The bench (``bench/restyle.py``), the tests and the restyle
widget (``mrlib.viz.widgets.interactive_restyle``) share them; measured figures:
``docs/notes/2026-12-04-restyle.md``.

The bands are split at level ``k``'s Nyquist frequency with ``mrlib.metrics.bands``, as
the crossover evidence (``mrlib.evaluation.crossover``) splits them.

Dimension letters (``mrlib`` glossary): T frames, C feature channels, D metric channels,
L levels, K labels.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from mrlib.errors import MotionValueError
from mrlib.metrics.bands import rms_profile, split_bands
from mrlib.metrics.windows import frame_distances, metric_features
from mrlib.model.pyramid import level_fps, resample_linear
from mrlib.representation.features import CONTACT_SLICE, motion_to_features
from mrlib.representation.motion import Motion
from mrlib.sampling.restyling import (
    at_model_rate,
    check_label_model,
    headings,
    mean_heading,
    restyle,
    restyle_lengths,
    restyle_level,
    training_heading,
    turn_about_vertical,
)

__all__ = [
    "REFERENCE_SEED",
    "CoarseGap",
    "coarse_gap",
    "RestyleReferences",
    "restyle_references",
    "RestyleEvidence",
    "restyle_evidence",
    "RestyleShares",
    "restyle_shares",
]

REFERENCE_SEED = 1_000_003  # the label references share no noise with the restyled clips


# -- how far the clip is from the coarse levels --------------------------------------------
@dataclass(frozen=True)
class CoarseGap:
    """How far a clip's level-k version is from the training clips' level-k versions.

    ``distance``: mean over the clip's level-k frames of the RMS per channel (normalised
    pose and root channels) to the nearest level-k frame of any training clip;
    ``spread``: the same for each training clip against the others, averaged (how far
    the training clips are from one another; NaN with one clip); ``ratio``: the two's
    quotient. Below 1 the clip is nearer the training data than its clips are to each
    other; well above 1 the fine levels see input unlike anything they were trained on
    (``mrlib.sampling.restyling``'s docstring says why the clip is not fitted first)."""

    level: int
    distance: float
    spread: float
    ratio: float
    nearest_clip: str


def _level_frames(model: Any, f: np.ndarray, n: int) -> np.ndarray:
    """Normalised pose and root channels of features ``(T, C)`` at ``n`` frames, ``(n, D)``."""
    x = model.normalizer.normalize(torch.as_tensor(np.asarray(f), dtype=torch.float32))
    x = resample_linear(x.T[None].cpu(), int(n))[0].T
    return x[:, : CONTACT_SLICE.start].double().numpy()


def coarse_gap(
    model: Any, motion: Motion | str | Path, level: int | None = None, *, align: bool = True,
    body: Any = None,
) -> CoarseGap:  # fmt: skip
    """How far ``motion`` is from what the coarse levels ``1..level`` produce
    (:class:`CoarseGap`), taking the training clips' level-k versions as that: the coarse
    levels reconstruct them (the training's reconstruction loss) and their samples stay
    near them."""
    from mrlib.representation.body import resolve_body

    model = check_label_model(model)
    k = restyle_level(model, level)
    source = at_model_rate(model, motion)
    lengths = restyle_lengths(model, source.num_frames, source.name or "the clip")
    f = motion_to_features(source, resolve_body(body, shared=True)).double().numpy()
    if align:
        f = turn_about_vertical(f, training_heading(model) - mean_heading(headings(f)))
    D = CONTACT_SLICE.start
    x = _level_frames(model, f, lengths[k - 1])
    refs = [
        _level_frames(model, np.asarray(c), int(model.lengths[n, k - 1]))
        for n, c in enumerate(model.features)
    ]
    per_clip = np.stack([frame_distances(x, r).min(1) for r in refs])  # (N, T_k)
    distance = float(per_clip.min(0).mean() / np.sqrt(D))
    nearest = model.clip_names[int(np.bincount(per_clip.argmin(0), minlength=len(refs)).argmax())]
    spreads = []
    for n, r in enumerate(refs):
        others = [q for j, q in enumerate(refs) if j != n]
        if others:
            d = np.min([frame_distances(r, q).min(1) for q in others], 0)
            spreads.append(d.mean() / np.sqrt(D))
    spread = float(np.mean(spreads)) if spreads else float("nan")
    return CoarseGap(k, distance, spread, distance / spread if spreads else float("nan"), nearest)


# -- measuring a restyled clip -------------------------------------------------------------
@dataclass(frozen=True)
class RestyleReferences:
    """What a restyled clip of ``length`` frames at level ``level`` is compared with:
    the band split's ``cutoff_hz`` (level k's Nyquist frequency), the low bands of the
    training clips and the mean residual RMS profile ``(D,)`` of every label's pure
    samples (or training clips). Built by :func:`restyle_references`."""

    level: int
    length: int
    cutoff_hz: float
    clip_names: tuple[str, ...]
    clip_lows: list[np.ndarray] = field(repr=False)
    label_profiles: dict[str, np.ndarray] = field(repr=False)
    reference: str = "samples"


def restyle_references(
    model: Any, length: int, level: int | None = None, *, num_samples: int = 4,
    seed: int = REFERENCE_SEED, reference: str = "samples", sampler: Any = None,
) -> RestyleReferences:  # fmt: skip
    """The references of :func:`restyle_evidence` for clips of ``length`` frames at the
    model's rate restyled at ``level``: per label, ``num_samples`` pure samples of that
    length (``reference="samples"``, as ``mrlib.evaluation.crossover.crossover_evidence``,
    drawn with ``sampler``, default the raw output of one draw, ``raw_sampler()``) or its
    training clips (``"clips"``)."""
    from mrlib.metrics.windows import model_references
    from mrlib.sampling.generation import generate
    from mrlib.sampling.sampler import raw_sampler

    sampler = raw_sampler(sampler)

    model = check_label_model(model)
    k = restyle_level(model, level)
    lengths = restyle_lengths(model, int(length))
    cutoff = level_fps(model.fps, lengths)[k - 1] / 2
    if reference not in ("samples", "clips"):
        raise MotionValueError(f"reference must be 'samples' or 'clips', got {reference!r}")
    names, clip_labels, feats = model_references(model, contacts=False)
    lows = [split_bands(f, model.fps, cutoff)[0] for f in feats]
    profiles = {}
    for lab in model.labels:
        if reference == "samples":
            ms = generate(model, lab, length=int(length), seed=seed, num=num_samples,
                          sampler=sampler)  # fmt: skip
            refs = [metric_features(m, contacts=False) for m in ms]
        else:
            refs = [f for f, cl in zip(feats, clip_labels, strict=True) if cl == lab]
        profiles[lab] = np.mean(
            [rms_profile(split_bands(r, model.fps, cutoff)[1]) for r in refs], 0
        )
    return RestyleReferences(k, int(length), float(cutoff), tuple(names), lows, profiles, reference)


@dataclass(frozen=True)
class RestyleEvidence:
    """A restyled clip against the three claims.

    ``trajectory_cm``: mean ground distance between the restyled and the source root
    (SMPL translation, same body); ``low_to_source`` / ``low_to_clips``: mean per-frame
    nearest-neighbour distance of the restyled clip's low band (6D local rotations below
    ``cutoff_hz``) to the source's low band and to each training clip's;
    ``residual_to_labels``: distance of its residual's RMS profile to each label's."""

    label: str
    level: int
    cutoff_hz: float
    trajectory_cm: float
    low_to_source: float
    low_to_clips: dict[str, float]
    residual_to_labels: dict[str, float]

    @property
    def low_holds(self) -> bool:
        """The low band is nearer the source's than any training clip's."""
        return self.low_to_source < min(self.low_to_clips.values())

    @property
    def nearest_label(self) -> str:
        """The label whose residual profile is nearest the restyled clip's."""
        return min(self.residual_to_labels, key=self.residual_to_labels.get)

    @property
    def high_holds(self) -> bool:
        """The residual is nearest the target label's."""
        return self.nearest_label == self.label


def restyle_evidence(
    model: Any, restyled: Motion, source: Motion | str | Path,
    references: RestyleReferences | None = None,
) -> RestyleEvidence:  # fmt: skip
    """Measure ``restyled`` (a result of :func:`restyle`, best without the foot clean-up)
    against its ``source`` clip; ``references`` from :func:`restyle_references` (built
    for the restyled clip's length and level when None). Both are measured at the model's
    frame rate (a restyled clip at its input's rate is resampled to it, as the input is)."""
    info = restyled.meta.get("restyle", {})
    source = at_model_rate(model, source)
    restyled = at_model_rate(model, restyled)
    if source.num_frames != restyled.num_frames:
        raise MotionValueError(
            f"the source has {source.num_frames} frames at {model.fps:g} fps, the restyled "
            f"clip {restyled.num_frames}: not a restyling of it"
        )
    ref = references or restyle_references(model, restyled.num_frames, info.get("level"))
    if ref.length != restyled.num_frames or info.get("level", ref.level) != ref.level:
        raise MotionValueError(
            f"references for {ref.length} frames at level {ref.level}, a restyled clip of "
            f"{restyled.num_frames} frames at level {info.get('level')}"
        )
    lab = restyled.label if restyled.label in ref.label_profiles else info.get("label")
    if lab not in ref.label_profiles:
        raise MotionValueError(f"the restyled clip's label {lab!r} is not one of the model's")
    d = np.linalg.norm(restyled.trans[:, [0, 2]] - source.trans[:, [0, 2]], axis=1)
    low, high = split_bands(metric_features(restyled, contacts=False), model.fps, ref.cutoff_hz)
    src_low = split_bands(metric_features(source, contacts=False), model.fps, ref.cutoff_hz)[0]
    p = rms_profile(high)
    return RestyleEvidence(
        label=lab,
        level=ref.level,
        cutoff_hz=ref.cutoff_hz,
        trajectory_cm=float(100 * d.mean()),
        low_to_source=_nn(low, src_low),
        low_to_clips={n: _nn(low, c) for n, c in zip(ref.clip_names, ref.clip_lows, strict=True)},
        residual_to_labels={k: float(np.linalg.norm(p - v)) for k, v in ref.label_profiles.items()},
    )


def _nn(x: np.ndarray, ref: np.ndarray) -> float:
    """Mean over the frames of ``x`` of the distance to the nearest frame of ``ref``."""
    return float(frame_distances(x, ref).min(1).mean())


# -- how much clip, how much label ---------------------------------------------------------
@dataclass(frozen=True)
class RestyleShares:
    """Per level ``k``: the mean per-frame nearest-neighbour distance of the restyled
    clip's poses (6D local rotations) to the source clip's (``to_source``) and to the
    target label's own sample (``to_label``; same seed and length), and the source's
    share ``to_label / (to_source + to_label)``: 1 when the result is the source, 0 when
    it is the label's sample, 0.5 halfway."""

    label: str
    keep: str
    levels: tuple[int, ...]
    to_source: np.ndarray
    to_label: np.ndarray
    label_sample: Motion | None = None  # the label's own sample compared with

    @property
    def source_share(self) -> np.ndarray:
        return self.to_label / np.maximum(self.to_source + self.to_label, 1e-12)

    def to_markdown(self) -> str:
        rows = [
            "| level k | to source | to label | source share | label share |",
            "|---|---|---|---|---|",
        ]
        for k, a, b, s in zip(self.levels, self.to_source, self.to_label, self.source_share,
                              strict=True):  # fmt: skip
            rows.append(f"| {k} | {a:.3f} | {b:.3f} | {100 * s:.0f}% | {100 * (1 - s):.0f}% |")
        return "\n".join(rows)


def restyle_shares(
    model: Any, motion: Motion | str | Path, label: str | int, *, keep: str = "coarse",
    seed: int = 0, levels: Any = None, body: Any = None, sampler: Any = None,
) -> RestyleShares:  # fmt: skip
    """How much of a restyling is the clip's and how much the label's, at every level
    (``levels``, default ``1..L-1``): :class:`RestyleShares` of ``restyle(model, motion,
    label, k, keep=keep, seed=seed, sampler=sampler)`` against the label's own sample
    ``generate(model, label, length=T, seed=seed, sampler=sampler)`` (kept as
    ``label_sample``); ``sampler`` default: the raw output (``raw_sampler()``: one draw, no clean-up)."""
    from mrlib.sampling.generation import generate
    from mrlib.sampling.sampler import raw_sampler

    model = check_label_model(model)
    source = at_model_rate(model, motion)
    levels = tuple(range(1, model.num_levels)) if levels is None else tuple(levels)
    ks = [restyle_level(model, k) for k in levels]
    tag = model.labels[model.label_index(label)]
    sampler = raw_sampler(sampler)
    label_sample = generate(model, tag, length=source.num_frames, seed=seed, sampler=sampler)
    src = metric_features(source, contacts=False)
    lab = metric_features(label_sample, contacts=False)
    to_src, to_lab = [], []
    for k in ks:
        r = restyle(model, source, tag, k, keep=keep, seed=seed, sampler=sampler, body=body)
        x = metric_features(r, contacts=False)
        to_src.append(_nn(x, src))
        to_lab.append(_nn(x, lab))
    return RestyleShares(tag, keep, tuple(ks), np.asarray(to_src), np.asarray(to_lab), label_sample)
