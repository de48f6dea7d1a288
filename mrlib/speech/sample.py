"""Generating gestures from audio with a trained speech-conditioned model.

``load_speech_model`` reads a checkpoint of :func:`mrlib.speech.speech_train`;
``generate_from_audio`` turns an utterance into motion, one frame per ``1 / fps`` s of
audio: features -> motion frames -> pyramid lengths -> per-level conditions
(``mrlib.speech.speech_conditions``) -> the same sampler as labels
(``mrlib.sampling.generation.sample_features``).

Typical use::

    model = load_speech_model("runs/speech/checkpoint.pt")
    motion = generate_from_audio(model, "new_talk.wav", seed=0)
    takes = generate_from_audio(model, "new_talk.wav", seed=0, num=4,
                                sampler=Sampler(fine_noise=0.5))  # a list of 4
"""

from __future__ import annotations

import dataclasses
import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from mrlib.errors import (
    ArgumentError,
    ClipTooShortError,
    MotionValueError,
    check_args,
    check_flag,
    check_seed,
    shown,
)
from mrlib.model.checkpoint import CheckpointError, load_checkpoint, reading
from mrlib.model.pyramid import level_fps
from mrlib.model.trained import GenerativeModel, model_from_state
from mrlib.representation.body import check_body
from mrlib.representation.features import features_to_motion
from mrlib.representation.motion import Motion
from mrlib.sampling.arguments import check_sampler, optional_count
from mrlib.sampling.cleanup import cleanup_foot_contacts
from mrlib.sampling.generation import noise_amplitude, sample_features, shaped_samples
from mrlib.sampling.sampler import Sampler
from mrlib.speech.align import SpeechNormalizer, level_lengths, speech_conditions
from mrlib.speech.audio import (
    MAX_AUDIO_SECONDS,
    check_audio_seconds,
    check_rate,
    check_waveform,
    load_audio,
)
from mrlib.speech.data import SPEECH_LABEL
from mrlib.speech.features import WAVLM_PATH_ENV, SpeechFeatureConfig, SpeechFeatureExtractor

__all__ = [
    "SpeechModel",
    "load_speech_model",
    "speech_model_from_trainer",
    "is_speech_checkpoint",
    "audio_conditions",
    "generate_from_audio",
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
            "a label model, not a speech-conditioned one: sample it with a label (mrlib sample "
            "--label, mrlib.generate), or train a speech model (mrlib train-speech)",
        )
    sp = state["speech"]
    cfg = SpeechFeatureConfig.from_dict(json.loads(sp["feature_config"]))
    recorded = cfg.wavlm_path
    if (
        wavlm_path is None
        and recorded
        and not (Path(recorded).expanduser() / "config.json").is_file()
    ):
        wavlm_path = os.environ.get(WAVLM_PATH_ENV) or None  # the folder moved: this machine's
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
    ``wavlm_path`` replaces the WavLM folder recorded at training time; where that folder
    is gone (another machine), ``$MRLIB_WAVLM_PATH`` does when set."""
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
    sr = check_rate(sr)
    wav = check_waveform(audio, sr)
    check_audio_seconds(len(wav) / sr, "the audio array", MAX_AUDIO_SECONDS)
    return wav, sr


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
    try:
        lengths = level_lengths(T, model.model.config.model)
    except ClipTooShortError as e:
        what = str(audio) if isinstance(audio, (str, Path)) else "the audio array"
        raise ClipTooShortError(
            f"{what}: {len(wav) / rate:.2f} s of audio are {T} frames at the model's "
            f"{model.fps:g} fps, too few for it: {e}"
        ) from None
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
    model: SpeechModel, audio, sr, seed, num: int, sampler: Sampler, body, levels: bool
) -> tuple[list[Motion], list[list[Motion]] | None]:
    """``num`` Motions of an utterance and, with ``levels``, each one's per-level
    Motions (raw)."""
    name = Path(audio).stem if isinstance(audio, (str, Path)) else "audio"
    conds, lengths, wav, rate = audio_conditions(model, audio, sr)
    gm = model.model
    amp = noise_amplitude(gm, None, sampler)  # (L,)
    outs = sample_features(
        gm, [c[None] for c in conds], lengths, amp, seed=seed, num_samples=num, keep=True
    )
    meta = {"audio": name, "audio_seconds": round(len(wav) / rate, 4), "seed": seed}

    def to_motion(x: torch.Tensor, fps: float, tag: str) -> Motion:
        m = features_to_motion(
            x.T, fps, betas=gm.betas, normalizer=gm.normalizer, label=SPEECH_LABEL, name=tag
        )
        return m.replace(meta=dict(meta))

    motions = [to_motion(outs[-1][b], gm.fps, f"{name}_seed{seed}_{b}") for b in range(num)]
    if sampler.fix_contacts:
        motions = [cleanup_foot_contacts(m, body) for m in motions]
    if not levels:
        return motions, None
    fps_i = level_fps(gm.fps, lengths)
    per_level = [
        [to_motion(outs[i][b], fps_i[i], f"{name}_level{i + 1}") for i in range(len(lengths))]
        for b in range(num)
    ]
    return motions, per_level


def _speech_model(name: str, value) -> SpeechModel:
    """A :class:`SpeechModel`, or a checkpoint path (loaded on CPU)."""
    if isinstance(value, SpeechModel):
        return value
    if isinstance(value, (str, Path)):
        return load_speech_model(value)
    raise ArgumentError(
        f"{name} must be a speech model (mrlib.speech.load_speech_model(checkpoint)) or its "
        f"checkpoint, got {shown(value)}"
    )


def _speech_sampler(name: str, value) -> Sampler | None:
    value = check_sampler(name, value)
    if value is not None and value.guidance != 0:
        raise MotionValueError(
            f"{name}: guidance pushes label mixes apart; a speech model's condition is "
            "audio: leave guidance at 0"
        )
    return value


@check_args(
    model=_speech_model, seed=check_seed, num=optional_count, sampler=_speech_sampler,
    levels=check_flag, body=check_body,
)  # fmt: skip
def generate_from_audio(
    model: SpeechModel | str | Path,
    audio,
    *,
    sr: int | None = None,
    seed: int | None = None,
    num: int | None = None,
    sampler: Sampler | None = None,
    levels: bool = False,
    body=None,
):
    """Gestures for an utterance: one motion frame per ``1 / fps`` s of audio.

    Args:
        model: a :class:`SpeechModel` (or a checkpoint path, loaded on CPU).
        audio: a file path (any rate, mixed to mono, resampled to 16 kHz), or a waveform
            ``(N,)`` with ``sr``.
        sr: the sample rate (Hz) of a waveform.
        seed: noise seed: sample b is noise stream ``(seed, b)``, as
            ``mrlib.generate``'s, whatever ``num``.
        num: None for one sample; a count ``k`` for a batch of ``k``.
        sampler: a ``mrlib.Sampler``: its ``fine_noise`` and ``fix_contacts`` (the
            foot-contact clean-up, ``mrlib.sampling.cleanup.cleanup_foot_contacts``);
            guidance applies to label models only (refused here unless 0).
        levels: also return every level's raw output as Motions at the level's frame
            rate (``fps * T_i / T_L``).
    Returns:
        As ``mrlib.generate``: a ``Motion`` of ``round(duration * fps)`` frames (label
        ``"speech"``); with ``num=k`` a list of k; with ``levels`` ``(motion, [level
        Motions])`` in place of each motion.
    """
    sampler = Sampler() if sampler is None else sampler
    count = 1 if num is None else num
    motions, per_level = _audio_samples(model, audio, sr, seed, count, sampler, body, levels)
    return shaped_samples(motions, per_level, num)
