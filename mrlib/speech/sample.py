"""Generating gestures from audio with a trained speech-conditioned model.

``load_speech_model`` reads a checkpoint of :func:`mrlib.speech.speech_train`;
``generate_from_audio`` turns an utterance into motion, one frame per ``1 / fps`` s of
audio: features -> motion frames -> pyramid lengths -> per-level conditions
(``mrlib.speech.speech_conditions``) -> the same sampler as labels
(``mrlib.sampling.generation.sample_features``).

Typical use::

    model = load_speech_model("runs/speech/checkpoint.pt")
    motion = generate_from_audio(model, "new_talk.wav", seed=0)
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from mrlib.errors import MotionValueError
from mrlib.model.checkpoint import CheckpointError, load_checkpoint, reading
from mrlib.model.pyramid import level_fps
from mrlib.model.trained import GenerativeModel, model_from_state
from mrlib.representation.features import features_to_motion
from mrlib.representation.motion import Motion
from mrlib.sampling.cleanup import cleanup_foot_contacts
from mrlib.sampling.generation import noise_amplitude, sample_features
from mrlib.speech.align import SpeechNormalizer, level_lengths, speech_conditions
from mrlib.speech.audio import (
    MAX_AUDIO_SECONDS,
    check_audio_seconds,
    check_waveform,
    load_audio,
)
from mrlib.speech.data import SPEECH_LABEL
from mrlib.speech.features import SpeechFeatureConfig, SpeechFeatureExtractor
from mrlib.threads import with_policy

__all__ = [
    "SpeechModel",
    "load_speech_model",
    "speech_model_from_trainer",
    "is_speech_checkpoint",
    "audio_conditions",
    "generate_from_audio",
    "generate_many_from_audio",
    "generate_levels_from_audio",
]


@dataclass
class SpeechModel:
    """A trained speech-conditioned generator and what turns audio into its conditions.

    Attributes:
        model: the ``mrlib.sampling.generation.GenerativeModel`` (labels ``["speech"]``).
        feature_config, normalizer, audio_fps, frame_offset_s, downsample: as trained.
    """

    model: GenerativeModel
    feature_config: SpeechFeatureConfig
    normalizer: SpeechNormalizer
    audio_fps: float
    frame_offset_s: float
    downsample: str
    _extractor: SpeechFeatureExtractor | None = field(default=None, repr=False)

    @property
    def fps(self) -> float:
        return self.model.fps

    @property
    def num_levels(self) -> int:
        return self.model.num_levels

    @property
    def dim(self) -> int:
        return int(self.model.generator.cond_dim)

    def extractor(self) -> SpeechFeatureExtractor:
        """The feature extractor of training (built once; WavLM loads on first use)."""
        if self._extractor is None:
            self._extractor = SpeechFeatureExtractor(self.feature_config)
        return self._extractor


def _speech_model_from_state(state: dict, device, wavlm_path: str | None) -> SpeechModel:
    if "speech" not in state:
        raise CheckpointError(
            None,
            "not a speech-conditioned checkpoint (no 'speech' key); use mrlib.sampling.generation.load_model",
        )
    sp = state["speech"]
    cfg = SpeechFeatureConfig.from_dict(json.loads(sp["feature_config"]))
    if wavlm_path is not None:
        cfg = dataclasses.replace(cfg, wavlm_path=str(wavlm_path))
    return SpeechModel(
        model=model_from_state(state, device),
        feature_config=cfg,
        normalizer=SpeechNormalizer.from_state_dict(sp["normalizer"]),
        audio_fps=float(sp["audio_fps"]),
        frame_offset_s=float(sp["frame_offset_s"]),
        downsample=str(sp["downsample"]),
    )


def load_speech_model(
    path: str | Path, device: str | torch.device = "cpu", *, wavlm_path: str | Path | None = None
) -> SpeechModel:
    """Load a checkpoint written by :func:`speech_train` for generation from audio.
    ``wavlm_path`` replaces the WavLM folder recorded at training time."""
    state = load_checkpoint(path)
    with reading(path):
        return _speech_model_from_state(state, device, wavlm_path)


def speech_model_from_trainer(trainer) -> SpeechModel:
    """A generation view of a ``mrlib.speech.SpeechTrainer`` (shares nothing mutable with it)."""
    return _speech_model_from_state(trainer.state_dict(), trainer.device, None)


def is_speech_checkpoint(path: str | Path) -> bool:
    """Whether ``path`` is a checkpoint of a speech-conditioned model."""
    return "speech" in load_checkpoint(path)


def _read_audio(audio, sr: int | None) -> tuple[np.ndarray, int]:
    """A path (read, mono, 16 kHz) or an in-memory ``(N,)`` waveform with its rate."""
    if isinstance(audio, (str, Path)):
        return load_audio(audio)
    if sr is None:
        raise MotionValueError("pass sr= with an audio array (its sample rate in Hz)")
    wav = check_waveform(audio, int(sr))
    check_audio_seconds(len(wav) / int(sr), "the audio array", MAX_AUDIO_SECONDS)
    return wav, int(sr)


def audio_conditions(
    model: SpeechModel, audio, sr: int | None = None
) -> tuple[list[torch.Tensor], list[int], np.ndarray, int]:
    """The per-level conditions of an utterance for ``model``.

    Features -> length ``T = round(duration * fps)`` motion frames -> pyramid lengths ->
    ``speech_conditions`` (normalise, align, downsample, residuals).

    Args:
        audio: a file path, or a waveform ``(N,)`` with its rate ``sr``.
    Returns:
        ``[(T_1, D), ..., (T_L, D)]``, the lengths ``[T_1..T_L]``, the waveform and its rate.
    Raises:
        ClipTooShortError: the audio gives fewer motion frames than an L-level pyramid needs.
    """
    wav, rate = _read_audio(audio, sr)
    feats = model.extractor()(wav, rate)
    if feats.shape[1] != model.dim:
        raise MotionValueError(
            f"the extractor gives {feats.shape[1]}-dimensional features, the model was "
            f"trained on {model.dim} ({model.feature_config})"
        )
    T = max(2, int(round(len(wav) / rate * model.fps)))
    lengths = level_lengths(T, model.model.config.model)
    conds = speech_conditions(
        feats,
        model.audio_fps,
        model.fps,
        lengths,
        normalizer=model.normalizer,
        offset_s=model.frame_offset_s,
        method=model.downsample,
    )
    return conds, lengths, wav, rate


def _audio_samples(
    model, audio, seed, num_samples: int, sr, fix_contacts: bool, body, levels: bool
) -> tuple[list[Motion], list[list[Motion]] | None]:
    """What the three audio samplers share: ``num_samples`` Motions and, with
    ``levels``, each one's per-level Motions."""
    if not isinstance(model, SpeechModel):
        model = load_speech_model(model)
    name = Path(audio).stem if isinstance(audio, (str, Path)) else "audio"
    conds, lengths, wav, rate = audio_conditions(model, audio, sr)
    gm = model.model
    amp = noise_amplitude(gm)  # (L,)
    outs = sample_features(
        gm, [c[None] for c in conds], lengths, amp, seed=seed, num_samples=num_samples, keep=True
    )
    meta = {"audio": name, "audio_seconds": round(len(wav) / rate, 4), "seed": seed}

    def to_motion(x: torch.Tensor, fps: float, tag: str) -> Motion:
        m = features_to_motion(
            x.T, fps, betas=gm.betas, normalizer=gm.normalizer, label=SPEECH_LABEL, name=tag
        )
        return m.replace(meta=dict(meta))

    motions = [to_motion(outs[-1][b], gm.fps, f"{name}_seed{seed}_{b}") for b in range(num_samples)]
    if fix_contacts:
        motions = [cleanup_foot_contacts(m, body) for m in motions]
    if not levels:
        return motions, None
    fps_i = level_fps(gm.fps, lengths)
    per_level = [
        [to_motion(outs[i][b], fps_i[i], f"{name}_level{i + 1}") for i in range(len(lengths))]
        for b in range(num_samples)
    ]
    return motions, per_level


@with_policy
def generate_from_audio(
    model: SpeechModel | str | Path,
    audio,
    seed: int | None = None,
    *,
    sr: int | None = None,
    fix_contacts: bool = True,
    body=None,
) -> Motion:
    """Gestures for an utterance: one motion frame per ``1 / fps`` s of audio (several:
    :func:`generate_many_from_audio`; every level too: :func:`generate_levels_from_audio`).

    Args:
        model: a :class:`SpeechModel` (or a checkpoint path, loaded on CPU).
        audio: a file path (any rate, mixed to mono, resampled to 16 kHz), or a waveform
            ``(N,)`` with ``sr``.
        seed: noise seed (sample b of a batch uses stream ``(seed, b)``, as
            ``mrlib.sampling.generation``; this one is b = 0).
        fix_contacts: foot-contact clean-up (``mrlib.sampling.generation.cleanup_foot_contacts``).
    Returns:
        a ``Motion`` of ``round(duration * fps)`` frames (label ``"speech"``).
    """
    return _audio_samples(model, audio, seed, 1, sr, fix_contacts, body, False)[0][0]


@with_policy
def generate_many_from_audio(
    model: SpeechModel | str | Path,
    audio,
    seed: int | None = None,
    *,
    num_samples: int,
    sr: int | None = None,
    fix_contacts: bool = True,
    body=None,
) -> list[Motion]:
    """``num_samples`` motions of :func:`generate_from_audio`'s kind in one batch: always
    a list; sample b is noise stream ``(seed, b)``, whatever the batch size."""
    return _audio_samples(model, audio, seed, num_samples, sr, fix_contacts, body, False)[0]


@with_policy
def generate_levels_from_audio(
    model: SpeechModel | str | Path,
    audio,
    seed: int | None = None,
    *,
    sr: int | None = None,
    fix_contacts: bool = True,
    body=None,
) -> tuple[Motion, list[Motion]]:
    """:func:`generate_from_audio`'s motion and every level's raw output as Motions at
    the level's frame rate (``fps * T_i / T_L``)."""
    motions, levels = _audio_samples(model, audio, seed, 1, sr, fix_contacts, body, True)
    return motions[0], levels[0]
