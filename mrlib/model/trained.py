"""A trained model as sampling sees it: the generator pyramid, its configuration, labels,
normaliser, noise amplitudes and the training clips' reconstruction noise, loaded from a
checkpoint (``mrlib.model.checkpoint``) or taken from a live trainer.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from mrlib.errors import ArgumentError, MotionValueError, check_args, check_path, shown
from mrlib.model.checkpoint import clip_rates, contact_choice, load_checkpoint, reading
from mrlib.model.config import TrainConfig, config_from_json
from mrlib.model.config import check_device as usable_device
from mrlib.model.critic import build_critics
from mrlib.model.generator import MultiResGenerator, build_generator
from mrlib.representation.features import FeatureNormalizer

__all__ = [
    "GenerativeModel",
    "model_from_state",
    "load_model",
    "model_from_trainer",
    "check_model",
    "check_label_model",
    "is_speech_model",
    "check_device",
    "MIN_SOURCE_FPS",
]

# Clips recorded below this rate (and below the model's) are keyframes, not a capture
# rate: the model's samples stay at its own rate (GenerativeModel.source_fps).
MIN_SOURCE_FPS = 10.0


@dataclass(eq=False)  # compared (and hashed) by identity: a model holds tensors
class GenerativeModel:
    """A trained generator and what it needs to sample (see ``mrlib.model.checkpoint`` keys).
    How it is sampled (fine noise, guidance, the foot clean-up) is no part of it: each
    sampling call takes a ``mrlib.Sampler``; only how each label's contact outputs are
    read by default (``contact_at_rate``) was chosen when its training ended."""

    generator: MultiResGenerator
    config: TrainConfig
    labels: list[str]
    clip_labels: list[int]
    clip_names: list[str]
    fps: float
    betas: np.ndarray
    normalizer: FeatureNormalizer
    lengths: torch.Tensor  # (N, L) pyramid lengths of the training clips
    sigma: torch.Tensor  # (K, L) noise amplitude per label and level
    zstar: list[torch.Tensor]  # N x (1, T_1,k)
    features: list[torch.Tensor]  # N x (T_k, C) training clips, unnormalised
    trained_levels: int  # levels whose training finished (all of them for a done run)
    progress: dict | None = None  # the checkpoint's {"block", "iteration", "done"}
    clip_fps: list[float] | None = None  # the clips' own rates before training resampled them
    # the patch critics, one per level (``mrlib.model.critic``), for critic-ranked sampling
    # (``mrlib.Sampler.candidates``); None where a model comes without them
    critics: torch.nn.ModuleList | None = None
    # the labels whose samples read their contact labels at the label's contact rate
    # (``mrlib.sampling.contact_choice``, chosen at the end of training); None: no choice
    # recorded (a checkpoint written before models chose, a speech model): read at 0.5
    contact_at_rate: tuple[str, ...] | None = None

    @property
    def source_fps(self) -> float | None:
        """The frame rate the training clips were captured at (the highest, if they
        differ) when the checkpoint records it and it is not the model's own rate (a
        ``demo`` model at 30 fps of 24-fps captures, a ``preview`` model at 15 fps of
        30-fps ones): the rate ``mrlib sample`` writes by default. None otherwise, and
        for clips under ``MIN_SOURCE_FPS`` below the model's rate (keyframes a second
        apart are not a rate to write motion at)."""
        if not self.clip_fps:
            return None
        r = max(self.clip_fps)
        if r < min(MIN_SOURCE_FPS, self.fps):
            return None
        return r if abs(r - self.fps) > 1e-6 else None

    @property
    def num_levels(self) -> int:
        return self.config.model.num_levels

    @property
    def device(self) -> torch.device:
        return next(self.generator.parameters()).device

    def label_index(self, label: str | int) -> int:
        if isinstance(label, bool) or not isinstance(label, (str, int, np.integer)):
            raise MotionValueError(f"a label is one of {self.labels} or its index, got {label!r}")
        if isinstance(label, (int, np.integer)):
            if not 0 <= int(label) < len(self.labels):
                raise MotionValueError(f"label index {label} out of range [0, {len(self.labels)})")
            return int(label)
        if label not in self.labels:
            raise MotionValueError(f"unknown label {label!r}; this model knows {self.labels}")
        return self.labels.index(label)

    def unfinished(self) -> str | None:
        """Where an unfinished run stopped (``"block 2 of 4, iteration 150 of 800; levels
        1-4 of 8 trained"``), or None for a finished one (or one of unknown progress)."""
        p = self.progress
        if not p or p.get("done", True):
            return None
        its = self.config.block_iterations
        b = int(p.get("block", 0))
        where = f"block {b + 1} of {len(its)}"
        if b < len(its):
            where += f", iteration {int(p.get('iteration', 0))} of {its[b]}"
        done = self.trained_levels
        trained = f"levels 1-{done} of {self.num_levels} trained" if done else "no level trained"
        return f"{where}; {trained}"

    def __repr__(self) -> str:
        return (
            f"GenerativeModel(labels={self.labels}, levels={self.num_levels}, fps={self.fps:g}, "
            f"clips={self.clip_names})"
        )


def model_from_state(state: dict, device: str | torch.device = "cpu") -> GenerativeModel:
    """A :class:`GenerativeModel` from a checkpoint's state dict (``mrlib.model.checkpoint``)."""
    config = config_from_json(state["config"])
    gen = build_generator(config.model, int(state["cond_dim"]))
    gen.load_state_dict(state["generator"])
    gen.to(device).eval().requires_grad_(False)
    critics = None
    if state.get("critics"):
        cond_dim = int(state["cond_dim"]) if config.model.critic_condition else 0
        critics = build_critics(config.model, cond_dim)
        critics.load_state_dict(state["critics"])
        critics.to(device).eval().requires_grad_(False)
    p = state["progress"]
    done_levels = (
        config.model.num_levels if p["done"] else sum(len(b) for b in config.blocks[: p["block"]])
    )
    return GenerativeModel(
        generator=gen,
        config=config,
        labels=list(state["labels"]),
        clip_labels=list(state["clip_labels"]),
        clip_names=list(state["clip_names"]),
        fps=float(state["fps"]),
        betas=state["betas"].numpy(),
        normalizer=FeatureNormalizer.from_state_dict(state["normalizer"]),
        lengths=state["lengths"],
        sigma=state["sigma"],
        zstar=list(state["zstar"]),
        features=list(state["features"]),
        trained_levels=int(done_levels),
        progress={"block": int(p["block"]), "iteration": int(p["iteration"]),
                  "done": bool(p["done"])},
        clip_fps=clip_rates(state),
        critics=critics,
        contact_at_rate=contact_choice(state),
    )  # fmt: skip


def check_device(name: str, value) -> str | torch.device:
    """``value`` if it is a device name (``"cpu"``, ``"cuda:0"``) or a ``torch.device``
    that PyTorch can run on here (``mrlib.model.config.check_device``)."""
    if isinstance(value, (str, torch.device)) and str(value):
        usable_device(str(value))
        return value
    raise ArgumentError(
        f"{name} must be a device ('cpu', 'cuda', a torch.device), got {shown(value)}"
    )


def _checkpoint_path(name: str, value) -> Path:
    if isinstance(value, GenerativeModel) or hasattr(value, "generator"):
        raise ArgumentError(f"{name} must be a checkpoint file; this is a model already loaded")
    return check_path(name, value)


def check_model(name: str, value):
    """``value`` if it is a trained model (a :class:`GenerativeModel`, or a speech model
    wrapping one), else an ``ArgumentError``. A checkpoint's path is refused with the line
    that loads it: mrlib never loads a model behind a call that samples, so that a loop
    of calls does not read the file each time and the device stays the caller's choice."""
    if isinstance(value, GenerativeModel):
        return value
    if hasattr(value, "generator") and hasattr(value, "labels") and hasattr(value, "num_levels"):
        return value  # a stand-in with the same attributes (tests, wrappers)
    if hasattr(value, "feature_config") and hasattr(value, "model"):
        return value  # mrlib.speech.SpeechModel (refused where a label model is needed)
    if isinstance(value, (str, bytes)) or hasattr(value, "__fspath__"):
        raise ArgumentError(
            f"{name} must be a trained model, got the path {shown(value)}; load it first: "
            f"model = mrlib.load_model({str(value)!r})"
        )
    raise ArgumentError(
        f"{name} must be a trained model (mrlib.load_model(checkpoint)), got {shown(value)}"
    )


def is_speech_model(model) -> bool:
    """Whether ``model``'s condition is audio (a speech model), not one-hot labels."""
    return hasattr(model, "feature_config") or (
        int(getattr(model.generator, "cond_dim", len(model.labels))) != len(model.labels)
    )


def check_label_model(name: str, value):
    """:func:`check_model` for the functions that condition on labels: a speech model
    (whose condition is audio) is refused with what to use instead."""
    value = check_model(name, value)
    if is_speech_model(value):
        raise ArgumentError(
            f"{name} is a speech-conditioned model (its condition is audio, not a label): "
            "generate from audio with mrlib.speech.generate_from_audio"
        )
    return value


@check_args(path=_checkpoint_path, device=check_device)
def load_model(path: str | Path, device: str | torch.device = "cpu") -> GenerativeModel:
    """Load a checkpoint written by ``mrlib.training.trainer`` for sampling. The functions
    that sample take the loaded model: pass ``load_model(path)``, not the path (they
    refuse a path with the line that loads it)."""
    state = load_checkpoint(path)
    with reading(path):
        return model_from_state(state, device)


def model_from_trainer(trainer) -> GenerativeModel:
    """A sampling view of a ``mrlib.training.trainer.Trainer`` (shares nothing mutable with it)."""
    return model_from_state(trainer.state_dict(), trainer.device)
