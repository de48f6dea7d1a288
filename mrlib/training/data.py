"""Training sets: labelled clips turned into normalised feature sequences.

A :class:`TrainingSet` holds, for N clips, the ``(T_k, 153)`` features, the label of
every clip (the condition it is generated with), the frame rate they share, and the
normaliser fitted on all of them. Several clips may share a label.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from mrlib.errors import (
    ArgumentError,
    ClipTooShortError,
    MotionValueError,
    check_args,
    check_list,
    check_number,
    check_path,
    check_text,
    shown,
)
from mrlib.io.jointmap import check_joint_map
from mrlib.model.checkpoint import clip_rates
from mrlib.model.config import ConfigError
from mrlib.representation.body import check_body
from mrlib.representation.features import NUM_FEATURES, FeatureNormalizer, motion_to_features
from mrlib.representation.motion import MAX_FPS, Motion, check_motions

__all__ = ["TrainingSet", "MAX_TRAIN_CLIP_FRAMES", "check_training_fps"]

# frames of one training clip at the training rate: 10 minutes at 30 fps (the bound of
# `mrlib train`, mrlib.app.cli.train, which says it in the command's words)
MAX_TRAIN_CLIP_FRAMES = 18_000


def instance_or_none(kind: type, what: str):
    """An argument check (``mrlib.errors.check_args``): ``kind`` or None."""

    def check(name: str, value):
        if value is None or isinstance(value, kind):
            return value
        raise ArgumentError(f"{name} must be {what} or None, got {shown(value)}")

    return check


def _labels(name: str, value):
    if value is None:
        return None
    return check_list(name, value, check_text, what="a list of label names, one per clip")


def _fps(name: str, value):
    return check_number(name, value, low=0, high=MAX_FPS, open_low=True, optional=True)


@dataclass
class TrainingSet:
    """Clips for one model.

    Attributes:
        features: N tensors ``(T_k, 153)``, *unnormalised* (``mrlib.representation.features`` layout).
        clip_labels: ``(N,)`` index into ``labels`` for every clip.
        labels: condition names, e.g. ``["walk_angry", "walk_happy"]`` (sorted, unique).
        fps: frame rate of every clip.
        names: clip names (file stems).
        normalizer: fitted on all clips (root channels only by default).
        betas: ``(10,)`` body shape used by the body-model losses (mean of the clips').
        source_fps: every clip's own frame rate before it was resampled to ``fps``
            (``Motion.meta["source_fps"]``, else its rate); None where unknown.
    """

    features: list[torch.Tensor]
    clip_labels: list[int]
    labels: list[str]
    fps: float
    names: list[str]
    normalizer: FeatureNormalizer
    betas: np.ndarray = field(default_factory=lambda: np.zeros(10, np.float32))
    source_fps: list[float] | None = None

    def __post_init__(self):
        if not self.features:
            raise MotionValueError("a TrainingSet needs at least one clip")
        for k, f in enumerate(self.features):
            if f.ndim != 2 or f.shape[1] != NUM_FEATURES:
                raise MotionValueError(
                    f"clip {k} features must be (T, {NUM_FEATURES}), got {tuple(f.shape)}"
                )
        if len(self.clip_labels) != len(self.features) or len(self.names) != len(self.features):
            raise MotionValueError("features, clip_labels and names must have one entry per clip")
        if any(not 0 <= c < len(self.labels) for c in self.clip_labels):
            raise MotionValueError(f"clip_labels must index labels ({len(self.labels)} of them)")
        if not (np.isfinite(self.fps) and 0 < self.fps <= MAX_FPS):
            raise MotionValueError(f"fps must be a number in (0, {MAX_FPS:g}], got {self.fps}")
        for k, f in enumerate(self.features):
            if not np.isfinite(np.asarray(f)).all():
                raise MotionValueError(f"clip {k} ({self.names[k]}): features contain NaN or inf")

    # -- construction ----------------------------------------------------------------------
    @classmethod
    @check_args(motions=check_motions, labels=_labels, fps=_fps, body=check_body)
    def from_motions(
        cls,
        motions: Sequence[Motion],
        labels: Sequence[str] | None = None,
        fps: float | None = None,
        body=None,
    ) -> TrainingSet:
        """Features of every motion; labels from ``labels`` or else ``Motion.label`` (or the
        clip name when a motion has no label). Clips are resampled to ``fps`` (default: the
        first clip's) and contact labels computed on ``body`` when a motion has none."""
        motions = list(motions)
        if not motions:
            raise MotionValueError("from_motions needs at least one Motion")
        if labels is not None and len(labels) != len(motions):
            raise MotionValueError(f"got {len(labels)} labels for {len(motions)} motions")
        fps = float(motions[0].fps if fps is None else fps)
        if not (np.isfinite(fps) and 0 < fps <= MAX_FPS):
            raise MotionValueError(f"fps must be a number in (0, {MAX_FPS:g}], got {fps}")
        for k, m in enumerate(motions):  # every clip's length first, before any resampling
            if not isinstance(m, Motion):
                raise MotionValueError(f"item {k} is a {type(m).__name__}, not a Motion")
            frames = m.resampled_frames(fps)
            if frames > MAX_TRAIN_CLIP_FRAMES:
                where = m.meta.get("source", m.name or f"clip{k}")
                raise MotionValueError(
                    f"{where}: {m.num_frames} frames at {m.fps:g} fps ({m.duration:.4g} s) are "
                    f"{frames} frames at {fps:g} fps, more than the {MAX_TRAIN_CLIP_FRAMES} a "
                    "training clip may have; cut it into shorter clips, train at a lower fps, "
                    "or check its frame rate"
                )
        names, clip_label_names, feats = [], [], []
        source_fps = [float(m.meta.get("source_fps", m.fps)) for m in motions]
        for k, m in enumerate(motions):
            if abs(m.fps - fps) > 1e-6:
                m = m.resample(fps)
            name = m.name or f"clip{k}"
            lab = labels[k] if labels is not None else (m.label or name)
            try:
                feats.append(motion_to_features(m, body))
            except (ClipTooShortError, MotionValueError) as e:
                where = m.meta.get("source", name)
                raise type(e)(f"{where}: {e}") from None
            names.append(name)
            clip_label_names.append(str(lab))
        label_names = sorted(set(clip_label_names))
        clip_labels = [label_names.index(lab) for lab in clip_label_names]
        betas = np.mean([np.asarray(m.betas, np.float32)[:10] for m in motions], 0)
        normalizer = FeatureNormalizer.fit(feats)
        return cls(feats, clip_labels, label_names, fps, names, normalizer, betas, source_fps)

    @classmethod
    def from_state(cls, state: dict) -> TrainingSet:
        """The training set stored in a checkpoint's state dict (``mrlib.model.checkpoint``)."""
        return cls(
            features=list(state["features"]),
            clip_labels=list(state["clip_labels"]),
            labels=list(state["labels"]),
            fps=float(state["fps"]),
            names=list(state["clip_names"]),
            normalizer=FeatureNormalizer.from_state_dict(state["normalizer"]),
            betas=state["betas"].numpy(),
            source_fps=clip_rates(state),
        )

    @classmethod
    @check_args(
        paths=lambda n, v: check_list(n, v, check_path, what="a list of file paths"),
        labels=_labels,
        fps=_fps,
        body=check_body,
        joint_map=check_joint_map,
    )
    def from_files(
        cls,
        paths: Sequence[str | Path],
        labels: Sequence[str] | None = None,
        fps: float | None = None,
        body=None,
        joint_map=None,
    ) -> TrainingSet:
        """Load every file with ``mrlib.io.load_motion`` and build the set (labels from the
        files, e.g. Bandai ``walk_happy``, unless given; ``joint_map`` for BVH files whose
        skeleton is neither shipped nor recognised; given to the BVH files only, and refused
        when there is none)."""
        from mrlib.io import joint_maps_for, load_motion

        maps = joint_maps_for(paths, joint_map)
        motions = [load_motion(p, joint_map=m, body=body) for p, m in zip(paths, maps, strict=True)]
        return cls.from_motions(motions, labels, fps, body)

    # -- views -----------------------------------------------------------------------------
    @property
    def num_clips(self) -> int:
        return len(self.features)

    @property
    def num_labels(self) -> int:
        return len(self.labels)

    @property
    def lengths(self) -> list[int]:
        return [int(f.shape[0]) for f in self.features]

    def normalized(self) -> list[torch.Tensor]:
        """Normalised clips as ``(C, T_k)`` (the networks' layout)."""
        return [self.normalizer.normalize(f).T.contiguous() for f in self.features]

    def label_index(self, label: str | int) -> int:
        """Index of a label given by name or index."""
        if isinstance(label, (int, np.integer)):
            if not 0 <= int(label) < self.num_labels:
                raise MotionValueError(f"label index {label} out of range [0, {self.num_labels})")
            return int(label)
        if label not in self.labels:
            raise MotionValueError(f"unknown label {label!r}; known: {self.labels}")
        return self.labels.index(label)

    def __repr__(self) -> str:
        return (
            f"TrainingSet({self.num_clips} clips, labels={self.labels}, fps={self.fps:g}, "
            f"lengths={self.lengths})"
        )


def check_training_fps(data: TrainingSet, fps: float | None) -> None:
    """Refuse a training set whose frame rate is not ``fps``, the rate a config trains at
    (``TrainConfig.fps``; None: any). A training set holds features, not motions, so it
    cannot be resampled exactly here: it is built at the right rate instead, as
    ``mrlib train`` does.

    Raises:
        ConfigError: the two rates, and how to build the set at the config's.
    """
    if fps is None or abs(float(data.fps) - float(fps)) <= 1e-6:
        return
    raise ConfigError(
        f"the config trains at {fps:g} fps (TrainConfig.fps) but the training set is at "
        f"{data.fps:g} fps; build it at the config's rate, TrainingSet.from_files(paths, "
        f"fps=config.fps) or TrainingSet.from_motions(motions, fps=config.fps) (speech: "
        f"SpeechTrainingSet.from_folders(..., fps=config.fps)), or train at the clips' own "
        f"rate with config.replace(fps=None)"
    )
