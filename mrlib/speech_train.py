"""Co-speech gesture training and generation from audio (paper, Sec. 6).

The speech-conditioned model is the label-conditioned one with another control signal:
the same networks (``mrlib.models``), the same block-wise WGAN-GP training loop
(``mrlib.train.Trainer``), the same sampler (``mrlib.sample.sample_features``). Only the
condition changes: instead of a one-hot label, level i of the generator receives per-frame
speech features ``s_i (T_i, D)`` (``mrlib.speech.speech_conditions``: features aligned to
the motion's frame rate, downsampled to every pyramid level, residuals above level 1),
and FiLM modulates only the upper body (``ModelConfig.film_joints``).

What differs from label training, all in :class:`SpeechTrainer`:

* **reconstruction** (``L_rec``) runs on the *paired* clips only, each with its own
  speech and its fixed noise z* (paper: "we train with the reconstruction loss using
  paired data exclusively");
* **random generations** (adversarial, contact and smoothness terms) take their speech
  from the *unpaired* audio (``random_audio="unpaired"``, the paper's choice; ``"all"``
  adds the paired clips' audio, ``"paired"`` uses only those). Generation b follows the
  pyramid of paired clip ``b mod N`` (so the critic compares it with that clip, as in
  label training); its speech is a random window of that many motion frames from a
  random audio clip (played back and forth when the clip is shorter);
* **conditional critics** (beyond the paper; ``ModelConfig.critic_condition``, on in
  ``speech_tutorial``): the projection term of every level's critic reads that level's
  speech features frame by frame, next to the motion's detail band
  (``critic_band="detail"``). A real clip is scored with its own speech; a fake with the
  speech that drove it, but only where that is paired audio (a real clip never comes
  with unpaired audio, so the critic would tell fakes apart by their audio alone: its
  loss ran away to -1e5 within 1,400 iterations when we let it). With
  ``LossWeights.mismatch`` the critic also sees every real clip with its own speech
  shifted out of step (:meth:`SpeechTrainer.mismatched_real_conditions`) as a fake, so it
  learns whether motion and speech go *together*, not only whether each looks real;
  that is what ties the hand speed to the loudness at the syllable level (figures in
  :func:`speech_tutorial`). With conditional critics the random generations take paired
  audio by default;
* the paper alternates reconstruction and random generation; here both run in every
  generator step (the Trainer sums ``L_rec`` of the reconstruction half of its batch and
  the other terms of the random half, see ``mrlib.config``), so every iteration visits
  the paired and the unpaired data once;
* style mixing becomes *speech mixing*: with probability ``TrainConfig.mix_prob`` a
  random generation takes a second audio window from a random crossover level on. The
  speech presets turn it off (the paper does not mix speech).

Checkpoints are ordinary mrlib checkpoints (``mrlib.checkpoint``, loadable with
``weights_only=True``) with one more key, ``"speech"``: the feature configuration, the
speech normaliser, the alignment settings and the raw features of every training clip
(needed to resume; for WavLM features at paper scale that is ~100 MB per 10 minutes).

Typical use::

    data = SpeechTrainingSet.from_folders("talks/paired", "talks/unpaired",
                                          SpeechFeatureExtractor(kind="logmel"))
    result = speech_train(data, speech_tutorial(), "runs/speech")
    model = load_speech_model(result.checkpoint)
    motion = generate_from_audio(model, "new_talk.wav", seed=0)

Shapes: T_a speech frames at ``audio_fps`` (50), D speech feature size, T motion
frames at the motion fps, L levels, B samples, S packed frames (``mrlib.pyramid``).
"""

from __future__ import annotations

import dataclasses
import json
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from mrlib.checkpoint import CheckpointError, load_checkpoint, reading
from mrlib.config import ConfigError, LossWeights, ModelConfig, TrainConfig, config_from_json
from mrlib.data import TrainingSet
from mrlib.errors import MotionValueError
from mrlib.features import features_to_motion
from mrlib.models import build_critics, build_generator
from mrlib.motion import Motion
from mrlib.pyramid import PackedLevels, level_fps, pyramid_lengths
from mrlib.sample import GenerativeModel, _model_from_state, sample_features
from mrlib.skeleton import UPPER_BODY_JOINTS
from mrlib.speech.align import (
    SPEECH_NUM_LEVELS,
    SpeechNormalizer,
    downsample_levels,
    interpolate_to_fps,
    levels_to_residuals,
    speech_conditions,
)
from mrlib.speech.audio import FEATURE_FPS, FRAME_OFFSET_S, check_waveform, load_audio
from mrlib.speech.features import SpeechFeatureConfig, SpeechFeatureExtractor
from mrlib.train import Trainer, TrainResult

__all__ = [
    "SPEECH_LABEL",
    "RANDOM_AUDIO",
    "speech_paper",
    "speech_tutorial",
    "SpeechTrainingSet",
    "SpeechDraw",
    "SpeechTrainer",
    "speech_train",
    "SpeechModel",
    "load_speech_model",
    "speech_model_from_trainer",
    "is_speech_checkpoint",
    "audio_conditions",
    "generate_from_audio",
    "fit_audio_length",
    "wrist_lift",
    "phrase_loudness",
    "SyncResult",
    "evaluate_speech_sync",
]

SPEECH_LABEL = "speech"  # the one label every paired clip carries (sigma is averaged over them)
RANDOM_AUDIO = ("unpaired", "all", "paired")


# -- presets -------------------------------------------------------------------------------
def speech_paper() -> TrainConfig:
    """The paper's speech setting (Sec. 3.2, 6): L = 10, F = 4/3, FiLM on the upper body,
    the label setting's optimiser and loss weights. The paper gives no iteration counts
    for speech; we reuse its label schedule (15000 iterations for levels 1-2, 25000 per
    further block). No speech mixing (``mix_prob = 0``)."""
    return TrainConfig(
        model=ModelConfig(
            num_levels=SPEECH_NUM_LEVELS, scale_factor=4 / 3, film_joints=UPPER_BODY_JOINTS
        ),
        block_size=2,
        block_iterations=(15000, 25000, 25000, 25000, 25000),
        mix_prob=0.0,
    )


def speech_tutorial() -> TrainConfig:
    """A CPU budget for a dozen ~10 s clips at 25 fps (19-28 minutes of training measured
    on a 2-core CPU shared with other jobs): L = 10 as in the paper, narrower networks,
    one critic step per generator step, 3900 iterations in all, and conditional critics
    that learn whether motion and speech go together.

    The learning rate is 2e-3, not the paper's 1e-4: with a few thousand iterations
    instead of 115000 the steps must be larger. Measured on the synthetic set (12 paired
    clips, levels 1-2 only): the arms' reconstruction error falls below that of each
    clip's median pose after ~700 iterations at 2e-3; at 1e-4 the whole reconstruction
    error is still above it after 300.

    The smoothness weight is 0.5, not the paper's 5: the smoothness term penalises the
    fast beat strokes that carry the syllable-level coupling (loudness / hand-speed r on
    4 held-out utterances x 3 seeds: 0.125 with weight 5, 0.236 with 0.5).

    The critics (beyond the paper) are conditional on the speech, judged on the motion's
    detail band, with the mismatch term (``critic_condition=True``,
    ``critic_band="detail"``, ``LossWeights(mismatch=1)``); their random generations take
    paired audio (see :class:`SpeechTrainer`). Measured on the synthetic set (12 paired +
    12 unpaired clips; 12 further held-out utterances x 3 seeds; loudness / hand-speed r,
    own audio vs another utterance's, and the paired difference):

    ============================================  ===============  ========================
    critics (random generations' audio), seed      r own / other    own - other (s.e.)
    ============================================  ===============  ========================
    paper's, unconditional (unpaired), 0           0.216 / 0.158    +0.057 +- 0.022, 24/36
    paper's, unconditional (paired), 0 / 1         0.230 / 0.153    +0.077 +- 0.018, 27/36
                                                   0.153 / 0.163    -0.010 +- 0.018, 15/36
    conditional, no mismatch (paired), 0           0.242 / 0.158    +0.084 +- 0.026, 25/36
    conditional + mismatch (paired), 0 / 1 / 2     0.278 / 0.134    +0.144 +- 0.029, 26/36
                                                   0.259 / 0.137    +0.122 +- 0.029, 26/36
                                                   0.267 / 0.142    +0.126 +- 0.022, 28/36
    conditional + mismatch (paired + unpaired), 0  0.172 / 0.192    -0.020 +- 0.024, 14/36
    ============================================  ===============  ========================

    Beat alignment (speech onsets vs motion beats) stays close to the other-audio
    control in every row (differences -0.006 to +0.035); the phrase-level lift follows
    the speech in all of them (loudness / wrist-height r 0.69-0.77 vs 0.17-0.26). The
    mismatch term makes training ~1.5x slower (1689 s vs 1141 s, same machine and load).
    """
    return TrainConfig(
        model=ModelConfig(
            num_levels=SPEECH_NUM_LEVELS,
            scale_factor=4 / 3,
            gen_hidden=(48, 96, 96),
            disc_hidden=(48, 96, 96),
            film_joints=UPPER_BODY_JOINTS,
            critic_condition=True,
            critic_band="detail",
        ),
        block_size=2,
        loss=LossWeights(smooth=0.5, mismatch=1.0),
        block_iterations=(1500, 800, 600, 500, 500),
        lr=2e-3,
        n_critic=1,
        mix_prob=0.0,
        checkpoint_every=500,
        log_every=10,
    )


# -- data ----------------------------------------------------------------------------------
def _check_clip_features(f, what: str) -> torch.Tensor:
    f = torch.as_tensor(f, dtype=torch.float32)
    if f.ndim != 2 or f.shape[0] < 1:
        raise MotionValueError(f"{what} must have shape (T_a, D), got {tuple(f.shape)}")
    if not torch.isfinite(f).all():
        raise MotionValueError(f"{what} has NaN or inf values")
    return f


@dataclass
class SpeechTrainingSet:
    """Paired speech + motion clips and unpaired speech for one speech-conditioned model.

    Attributes:
        motion: the paired clips' motion (a ``TrainingSet``, every clip labelled
            ``SPEECH_LABEL``); clip k goes with ``paired_features[k]``.
        paired_features: N raw feature tensors ``(T_a,k, D)`` at ``audio_fps``.
        unpaired_features: M raw feature tensors ``(T_a,u, D)``.
        unpaired_frames: motion frames (at ``motion.fps``) each unpaired clip spans.
        normalizer: fitted on every frame of paired and unpaired audio.
        feature_config: how the features were computed (saved with the model, used again
            at generation time).
        audio_fps, frame_offset_s: the features' frame rate and the time of frame 0.
        downsample: ``"area"`` or ``"linear"`` (``mrlib.speech.downsample_levels``).
        unpaired_names: file stems of the unpaired clips.
    """

    motion: TrainingSet
    paired_features: list[torch.Tensor]
    unpaired_features: list[torch.Tensor]
    unpaired_frames: list[int]
    normalizer: SpeechNormalizer
    feature_config: SpeechFeatureConfig
    audio_fps: float = FEATURE_FPS
    frame_offset_s: float = FRAME_OFFSET_S
    downsample: str = "area"
    unpaired_names: list[str] = field(default_factory=list)

    def __post_init__(self):
        self.paired_features = [
            _check_clip_features(f, f"paired clip {k} features")
            for k, f in enumerate(self.paired_features)
        ]
        self.unpaired_features = [
            _check_clip_features(f, f"unpaired clip {k} features")
            for k, f in enumerate(self.unpaired_features)
        ]
        if len(self.paired_features) != self.motion.num_clips:
            raise MotionValueError(
                f"{self.motion.num_clips} motion clips but {len(self.paired_features)} "
                "paired feature tensors"
            )
        dims = {f.shape[1] for f in self.paired_features + self.unpaired_features}
        if len(dims) != 1:
            raise MotionValueError(f"speech clips have different feature sizes {sorted(dims)}")
        if self.normalizer.dim not in dims:
            raise MotionValueError(
                f"the normaliser has {self.normalizer.dim} dimensions, the features {dims}"
            )
        if len(self.unpaired_frames) != len(self.unpaired_features):
            raise MotionValueError("unpaired_frames needs one entry per unpaired clip")
        if any(int(n) < 1 for n in self.unpaired_frames):
            raise MotionValueError(f"unpaired_frames must be >= 1, got {self.unpaired_frames}")
        self.unpaired_frames = [int(n) for n in self.unpaired_frames]
        if not self.unpaired_names:
            self.unpaired_names = [f"unpaired{u}" for u in range(len(self.unpaired_features))]
        if self.downsample not in ("area", "linear"):
            raise MotionValueError(
                f"downsample must be 'area' or 'linear', got {self.downsample!r}"
            )
        if set(self.motion.labels) != {SPEECH_LABEL}:
            raise MotionValueError(
                f"every paired clip must carry the label {SPEECH_LABEL!r}, got {self.motion.labels}"
            )

    # -- construction ----------------------------------------------------------------------
    @classmethod
    def from_clips(
        cls,
        paired,
        unpaired=(),
        feature_config: SpeechFeatureConfig | None = None,
        *,
        fps: float | None = None,
        body=None,
        downsample: str = "area",
    ) -> SpeechTrainingSet:
        """From ``mrlib.speech_data`` clips: ``paired`` ``SpeechMotionPair`` s (features +
        motion) and ``unpaired`` ``SpeechClip`` s; motion resampled to ``fps`` (default
        the first pair's). ``feature_config``: the extractor's config (stored with the
        model so generation computes the same features)."""
        paired, unpaired = list(paired), list(unpaired)
        if not paired:
            raise MotionValueError("a speech training set needs at least one paired clip")
        fps = float(paired[0].motion.fps if fps is None else fps)
        rates = {float(c.fps) for c in paired + unpaired}
        offsets = {float(c.frame_offset_s) for c in paired + unpaired}
        if len(rates) != 1 or len(offsets) != 1:
            raise MotionValueError(f"speech clips have different frame grids: {rates}, {offsets}")
        motions = [p.motion.replace(label=SPEECH_LABEL, name=p.name) for p in paired]
        motion = TrainingSet.from_motions(motions, [SPEECH_LABEL] * len(motions), fps, body)
        feats = [p.features for p in paired] + [u.features for u in unpaired]
        return cls(
            motion=motion,
            paired_features=[p.features for p in paired],
            unpaired_features=[u.features for u in unpaired],
            unpaired_frames=[max(1, int(round(u.duration * fps))) for u in unpaired],
            normalizer=SpeechNormalizer.fit(list(feats)),
            feature_config=feature_config or SpeechFeatureConfig(kind="logmel"),
            audio_fps=rates.pop(),
            frame_offset_s=offsets.pop(),
            downsample=downsample,
            unpaired_names=[u.name for u in unpaired],
        )

    @classmethod
    def from_folders(
        cls,
        paired_dir: str | Path,
        unpaired_dir: str | Path | None = None,
        extractor: SpeechFeatureExtractor | None = None,
        *,
        fps: float = 25.0,
        body=None,
        downsample: str = "area",
    ) -> SpeechTrainingSet:
        """``paired_dir``: ``<stem>.wav`` + ``<stem>.npz|.bvh`` (``load_paired_folder``);
        ``unpaired_dir``: ``.wav`` files (``load_unpaired_folder``). ``extractor``
        defaults to WavLM (needs local weights); motion is resampled to ``fps`` (the
        paper uses 25)."""
        from mrlib.speech_data import load_paired_folder, load_unpaired_folder

        ex = extractor if extractor is not None else SpeechFeatureExtractor()
        pairs = load_paired_folder(paired_dir, ex, motion_fps=fps, body=body)
        unpaired = [] if unpaired_dir is None else load_unpaired_folder(unpaired_dir, ex)
        return cls.from_clips(pairs, unpaired, ex.config, fps=fps, body=body, downsample=downsample)

    # -- views -----------------------------------------------------------------------------
    @property
    def dim(self) -> int:
        return int(self.paired_features[0].shape[1])

    @property
    def fps(self) -> float:
        return float(self.motion.fps)

    @property
    def num_paired(self) -> int:
        return len(self.paired_features)

    @property
    def num_unpaired(self) -> int:
        return len(self.unpaired_features)

    def finest(self) -> tuple[list[torch.Tensor], list[str]]:
        """Every audio clip's normalised features at the motion frame rate (level L before
        downsampling): paired clips first (``(T_k, D)``, T_k = the motion's frames), then
        unpaired ones (``(unpaired_frames[u], D)``); and ``"paired"``/``"unpaired"`` per
        clip."""
        frames = self.motion.lengths + self.unpaired_frames
        feats = self.paired_features + self.unpaired_features
        out = [
            interpolate_to_fps(
                self.normalizer.normalize(f),
                self.audio_fps,
                self.fps,
                n,
                offset_s=self.frame_offset_s,
            )
            for f, n in zip(feats, frames, strict=True)
        ]
        return out, ["paired"] * self.num_paired + ["unpaired"] * self.num_unpaired

    def speech_state(self) -> dict:
        """What a checkpoint stores under ``"speech"`` (tensors, lists and strings only)."""
        return {
            "feature_config": json.dumps(self.feature_config.to_dict(), sort_keys=True),
            "normalizer": self.normalizer.state_dict(),
            "dim": self.dim,
            "audio_fps": float(self.audio_fps),
            "frame_offset_s": float(self.frame_offset_s),
            "downsample": self.downsample,
            "paired_features": [f.clone() for f in self.paired_features],
            "unpaired_features": [f.clone() for f in self.unpaired_features],
            "unpaired_frames": list(self.unpaired_frames),
            "unpaired_names": list(self.unpaired_names),
        }

    @classmethod
    def from_state(cls, state: dict) -> SpeechTrainingSet:
        """Rebuild from a checkpoint's state dict (see :meth:`speech_state`)."""
        sp = state["speech"]
        motion = TrainingSet.from_state(state)
        return cls(
            motion=motion,
            paired_features=list(sp["paired_features"]),
            unpaired_features=list(sp["unpaired_features"]),
            unpaired_frames=list(sp["unpaired_frames"]),
            normalizer=SpeechNormalizer.from_state_dict(sp["normalizer"]),
            feature_config=SpeechFeatureConfig.from_dict(json.loads(sp["feature_config"])),
            audio_fps=float(sp["audio_fps"]),
            frame_offset_s=float(sp["frame_offset_s"]),
            downsample=str(sp["downsample"]),
            unpaired_names=list(sp["unpaired_names"]),
        )

    def __repr__(self) -> str:
        return (
            f"SpeechTrainingSet({self.num_paired} paired, {self.num_unpaired} unpaired, "
            f"D={self.dim}, {self.feature_config.kind}, fps={self.fps:g})"
        )


# -- conditions of packed batches ------------------------------------------------------------
def residual_operators(lengths: Sequence[int], method: str = "area") -> list[torch.Tensor]:
    """The linear maps from a clip's finest-level speech features to its per-level
    conditions: ``s_i = R_i @ finest`` with ``R_i (T_i, T_L)``, i.e. exactly
    ``levels_to_residuals(downsample_levels(finest, lengths, method))`` (both steps are
    linear in time, so applying them to the identity gives their matrices)."""
    eye = torch.eye(int(lengths[-1]))
    return levels_to_residuals(downsample_levels(eye, list(lengths), method))


def _packed_operators(layout: PackedLevels, method: str) -> tuple[list[torch.Tensor], torch.Tensor]:
    """Per level a sparse ``(S_i, sum_b T_bL)`` matrix taking the concatenated finest
    windows of every sample of ``layout`` to its packed conditions (gap rows empty), and
    the ``(B,)`` offset of each sample's window in the concatenation."""
    table = layout.table
    B, L = table.shape
    T_last = table[:, -1]
    crop_off = torch.cumsum(T_last, 0) - T_last
    cache: dict[tuple[int, ...], list[torch.Tensor]] = {}
    rows: list[list[torch.Tensor]] = [[] for _ in range(L)]
    cols: list[list[torch.Tensor]] = [[] for _ in range(L)]
    vals: list[list[torch.Tensor]] = [[] for _ in range(L)]
    for b in range(B):
        key = tuple(int(n) for n in table[b])
        if key not in cache:
            cache[key] = residual_operators(key, method)
        for i, R in enumerate(cache[key]):
            r, c = R.nonzero(as_tuple=True)
            rows[i].append(r + int(layout.offsets[i][b]))
            cols[i].append(c + int(crop_off[b]))
            vals[i].append(R[r, c])
    total = int(T_last.sum())
    ops = []
    for i in range(L):
        idx = torch.stack([torch.cat(rows[i]), torch.cat(cols[i])])
        P = torch.sparse_coo_tensor(
            idx, torch.cat(vals[i]), (layout.sizes[i], total), check_invariants=True
        )
        ops.append(P.coalesce().to(layout.device))
    return ops, crop_off


def _back_and_forth(pos: torch.Tensor, n: torch.Tensor) -> torch.Tensor:
    """Indices ``pos >= 0`` folded into ``[0, n)`` by playing forward, then backward, ...
    (``mrlib.speech_data.loop_motion``'s rule); ``n >= 1`` per element."""
    period = (2 * (n - 1)).clamp_min(1)
    k = pos % period
    return torch.where(n == 1, torch.zeros_like(k), torch.where(k < n, k, period - k))


@dataclass
class SpeechDraw:
    """The speech of a batch of random generations (what ``SpeechTrainer.draw_random``
    returns in place of a label table).

    Attributes:
        source, start: ``(B,)`` audio clip (index into the trainer's bank: paired clips
            first, then unpaired) and first motion frame of each sample's window.
        source_b, start_b: the second window of mixed samples (equal to the first
            otherwise).
        cross: ``(B,)`` first level (0-based) that uses the second window; L = never.
    """

    source: torch.Tensor
    start: torch.Tensor
    source_b: torch.Tensor
    start_b: torch.Tensor
    cross: torch.Tensor


class SpeechTrainer(Trainer):
    """``mrlib.train.Trainer`` with speech as the control signal.

    Overrides only the Trainer's two condition hooks (``rec_conditions``, ``draw_random``)
    and what the checkpoint holds (``state_dict``, ``from_checkpoint``); the networks,
    losses, loop, logging, resume and Ctrl-C handling are the Trainer's.

    Args:
        data: a :class:`SpeechTrainingSet`.
        config: a ``TrainConfig`` (``speech_tutorial()``, ``speech_paper()``).
        random_audio: where random generations take their speech: ``"unpaired"`` (paper),
            ``"all"`` (paired and unpaired) or ``"paired"``; None (default): ``"paired"``
            with conditional critics (they hear paired audio only, see
            :meth:`_critic_keep`), else ``"unpaired"`` (``"paired"`` when there is no
            unpaired audio).
    """

    def __init__(
        self,
        data: SpeechTrainingSet,
        config: TrainConfig,
        out_dir: str | Path,
        body=None,
        *,
        random_audio: str | None = None,
    ):
        if not isinstance(data, SpeechTrainingSet):
            raise MotionValueError(
                f"SpeechTrainer needs a SpeechTrainingSet, got {type(data).__name__}"
            )
        if config.loss.detail:
            raise ConfigError(
                "loss.detail pulls each level to its label's detail statistics; speech has "
                "no labels (set LossWeights(detail=0))"
            )
        if random_audio is None:
            conditional = config.model.critic_condition
            random_audio = "paired" if conditional or data.num_unpaired == 0 else "unpaired"
        if random_audio not in RANDOM_AUDIO:
            raise MotionValueError(
                f"random_audio must be one of {RANDOM_AUDIO}, got {random_audio!r}"
            )
        if random_audio == "unpaired" and data.num_unpaired == 0:
            raise MotionValueError(
                "random_audio='unpaired' needs unpaired audio clips; add some or pass "
                "random_audio='paired'"
            )
        if config.model.critic_condition and random_audio == "unpaired":
            warnings.warn(
                "conditional critics hear the speech of paired audio only; with "
                "random_audio='unpaired' they judge realism alone (use 'paired')",
                stacklevel=2,
            )
        if config.model.film_joints is None:
            warnings.warn(
                "FiLM modulates every joint; the paper modulates the upper body only "
                "(ModelConfig(film_joints=mrlib.skeleton.UPPER_BODY_JOINTS))",
                stacklevel=2,
            )
        self.speech = data
        self.random_audio = random_audio
        super().__init__(data.motion, config, out_dir, body=body)

        # 1. the networks again, for D-dimensional speech instead of one label ----------------
        torch.manual_seed(config.seed)
        self.cond_dim = data.dim
        self.generator = build_generator(config.model, self.cond_dim).to(self.device)
        critic_cond = self.cond_dim if config.model.critic_condition else 0
        self.critics = build_critics(config.model, critic_cond).to(self.device)

        # 2. the audio bank: every clip's normalised features at the motion frame rate ---------
        finest, kinds = data.finest()
        self.bank = torch.cat(finest).to(self.device)  # (sum T, D)
        self.bank_lengths = torch.tensor([f.shape[0] for f in finest])
        self.bank_offsets = torch.cumsum(self.bank_lengths, 0) - self.bank_lengths
        use = {"unpaired": ("unpaired",), "paired": ("paired",), "all": ("paired", "unpaired")}
        self.sources = torch.tensor(
            [k for k, kind in enumerate(kinds) if kind in use[random_audio]]
        )

        # 3. reconstruction conditions: each paired clip with its own speech -----------------
        L = config.model.num_levels
        per_clip = [
            speech_conditions(
                f,
                data.audio_fps,
                data.fps,
                self.lengths[k].tolist(),
                normalizer=data.normalizer,
                offset_s=data.frame_offset_s,
                method=data.downsample,
            )
            for k, f in enumerate(data.paired_features)
        ]
        self.rec_conds = [
            self.rec_layout.pack([c[i].T for c in per_clip], i).transpose(1, 2) for i in range(L)
        ]  # (1, S_i, D)
        self._per_clip = per_clip
        # a conditional critic sees every real clip with its own speech
        self.real_rand_conds = (
            [
                self.rand_layout.pack([per_clip[k][i].T for k in self.rand_clip], i).transpose(1, 2)
                for i in range(L)
            ]
            if config.model.critic_condition
            else None
        )
        self._ops: dict[int, tuple[PackedLevels, list[torch.Tensor], torch.Tensor]] = {}

    # -- conditions ----------------------------------------------------------------------------
    def _operators(self, layout: PackedLevels) -> tuple[list[torch.Tensor], torch.Tensor]:
        key = id(layout)
        if key not in self._ops:
            ops, off = _packed_operators(layout, self.speech.downsample)
            self._ops[key] = (layout, ops, off)  # keeps the layout alive, so its id stays unique
        return self._ops[key][1], self._ops[key][2]

    def windows(
        self, layout: PackedLevels, source: torch.Tensor, start: torch.Tensor
    ) -> torch.Tensor:
        """Each sample's window of its audio clip at the finest level, concatenated:
        ``(sum_b T_bL, D)`` (back and forth where the clip is shorter than the sample)."""
        T = layout.table[:, -1]
        _, crop_off = self._operators(layout)
        owner = torch.repeat_interleave(torch.arange(len(T)), T)
        local = torch.arange(int(T.sum())) - crop_off[owner]
        n = self.bank_lengths[source][owner]
        pos = _back_and_forth(start[owner] + local, n)
        return self.bank[(self.bank_offsets[source][owner] + pos).to(self.bank.device)]

    def rec_conditions(self, stop: int) -> list[torch.Tensor]:
        """Conditions ``(1, S_i, D)`` of the reconstructions, levels ``0..stop-1``: every
        paired clip with its own speech (never unpaired audio)."""
        return self.rec_conds[:stop]

    def draw_speech(self, layout: PackedLevels) -> SpeechDraw:
        """Random speech for a layout's samples: a window of ``T_bL`` frames of a random
        audio clip of ``random_audio`` (uniform over clips, then over start frames); with
        probability ``mix_prob`` a second window and a crossover level."""
        L = self.config.model.num_levels
        T = layout.table[:, -1]
        source, start = self._draw_windows(T)
        mix = torch.rand(len(T), generator=self.rng) < self.config.mix_prob
        source_b, start_b = self._draw_windows(T)
        cross = torch.randint(1, max(L, 2), (len(T),), generator=self.rng)
        cross = torch.where(mix, cross, torch.full_like(cross, L))
        source_b = torch.where(mix, source_b, source)
        start_b = torch.where(mix, start_b, start)
        return SpeechDraw(source, start, source_b, start_b, cross)

    def _draw_windows(self, T: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        pick = torch.randint(len(self.sources), (len(T),), generator=self.rng)
        source = self.sources[pick]
        room = (self.bank_lengths[source] - T).clamp_min(0) + 1
        start = (torch.rand(len(T), generator=self.rng) * room).long().clamp_max(room - 1)
        return source, start

    def draw_conditions(
        self, draw: SpeechDraw, layout: PackedLevels, stop: int
    ) -> list[torch.Tensor]:
        """Conditions ``(1, S_i, D)`` of levels ``0..stop-1`` of the windows of ``draw``:
        ``speech_conditions`` of each window, computed for the whole packed batch at once
        (one sparse product per level, :func:`residual_operators`)."""
        ops, _ = self._operators(layout)
        xa = self.windows(layout, draw.source, draw.start)
        mixed = bool((draw.cross < len(ops)).any())
        xb = self.windows(layout, draw.source_b, draw.start_b) if mixed else None
        out = []
        for i in range(stop):
            c = torch.sparse.mm(ops[i], xa)  # (S_i, D)
            if mixed:
                use_b = layout.per_sample(draw.cross <= i, i)[:, None]  # (S_i, 1)
                c = torch.where(use_b, torch.sparse.mm(ops[i], xb), c)
            out.append(c[None])
        return out

    def draw_random(
        self, layout: PackedLevels, stop: int
    ) -> tuple[list[torch.Tensor], list[torch.Tensor]]:
        """Conditions ``[(1, S_i, D)]`` (:meth:`draw_speech`, :meth:`draw_conditions`) and
        noises ``[(1, 1, S_i)]`` of levels ``0..stop-1`` of a layout's random generations.
        Noise ``z_i ~ N(0, sigma_i)`` (sigma averaged over the paired clips), shared by all
        channels."""
        draw = self.draw_speech(layout)
        L = self.config.model.num_levels
        second = torch.arange(L)[None] >= draw.cross[:, None]  # (B, L) levels on window b
        P = self.speech.num_paired  # bank: paired clips first
        paired = torch.where(second, draw.source_b[:, None] < P, draw.source[:, None] < P)
        self._last_mixed, self._last_paired = second, paired  # read by the critics
        noises = []
        for i in range(stop):
            z = torch.randn(1, 1, layout.sizes[i], generator=self.rng).to(self.device)
            noises.append(z * self.sigma[0, i].to(self.device))
        return self.draw_conditions(draw, layout, stop), noises

    def _critic_keep(self) -> torch.Tensor:
        """A conditional critic hears the speech of a fake only where it is paired audio:
        a real clip always comes with paired audio, so a fake driven by unpaired audio
        would be told apart by its audio alone. Such fakes, and the real clips that share
        their slots, are judged on realism only (their conditions zeroed)."""
        return super()._critic_keep() * self._last_paired.float()

    def mismatched_real_conditions(self, level: int) -> torch.Tensor:
        """Speech that does not go with the real clips (``loss.mismatch``): each clip's own
        speech, circularly shifted by a random 25-75 % of its length, so the critic sees
        the same frames of speech, out of step with the motion."""
        ks = self.rand_clip.tolist()
        frac = 0.25 + 0.5 * torch.rand(len(ks), generator=self.rng)
        shifted = []
        for f, k in zip(frac.tolist(), ks, strict=True):
            c = self._per_clip[k][level]
            shifted.append(c.roll(max(1, round(f * len(c))), 0).T)
        return self.rand_layout.pack(shifted, level).transpose(1, 2).to(self.device)

    # -- checkpoints ---------------------------------------------------------------------------
    def state_dict(self) -> dict:
        state = super().state_dict()
        state["speech"] = {**self.speech.speech_state(), "random_audio": self.random_audio}
        return state

    @classmethod
    def from_checkpoint(
        cls,
        path: str | Path,
        out_dir: str | Path | None = None,
        body=None,
        device: str | None = None,
    ) -> SpeechTrainer:
        """Rebuild a speech trainer (data included) from a checkpoint to continue training."""
        state = load_checkpoint(path)
        if "speech" not in state:
            raise CheckpointError(
                Path(path), "not a speech-conditioned checkpoint (no 'speech' key)"
            )
        config = config_from_json(state["config"])
        if device is not None:
            config = config.replace(device=device)
        data = SpeechTrainingSet.from_state(state)
        trainer = cls(
            data,
            config,
            Path(path).parent if out_dir is None else out_dir,
            body=body,
            random_audio=str(state["speech"]["random_audio"]),
        )
        trainer.load_state_dict(state)
        return trainer


def speech_train(
    data: SpeechTrainingSet | None,
    config: TrainConfig | None,
    out_dir: str | Path,
    *,
    resume: str | Path | None = None,
    random_audio: str | None = None,
    body=None,
    progress: bool = True,
    callback: Callable[[Trainer, dict[int, dict[str, float]]], None] | None = None,
) -> TrainResult:
    """Train a speech-conditioned model (or continue one); ``mrlib.train.train`` for
    speech. ``data`` and ``config`` are ignored when resuming."""
    if resume is not None:
        trainer = SpeechTrainer.from_checkpoint(resume, out_dir=out_dir, body=body)
    else:
        if data is None or config is None:
            raise CheckpointError(
                None, "speech_train() needs data and config unless resume is given"
            )
        trainer = SpeechTrainer(data, config, out_dir, body=body, random_audio=random_audio)
    return trainer.fit(progress=progress, callback=callback)


# -- generation ----------------------------------------------------------------------------
@dataclass
class SpeechModel:
    """A trained speech-conditioned generator and what turns audio into its conditions.

    Attributes:
        model: the ``mrlib.sample.GenerativeModel`` (labels ``["speech"]``).
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
            "not a speech-conditioned checkpoint (no 'speech' key); use mrlib.sample.load_model",
        )
    sp = state["speech"]
    cfg = SpeechFeatureConfig.from_dict(json.loads(sp["feature_config"]))
    if wavlm_path is not None:
        cfg = dataclasses.replace(cfg, wavlm_path=str(wavlm_path))
    return SpeechModel(
        model=_model_from_state(state, device),
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


def speech_model_from_trainer(trainer: SpeechTrainer) -> SpeechModel:
    """A generation view of a :class:`SpeechTrainer` (shares nothing mutable with it)."""
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
    return check_waveform(audio, int(sr)), int(sr)


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
    mc = model.model.config.model
    lengths = pyramid_lengths(
        T, mc.num_levels, mc.scale_factor, min_length=(mc.kernel_size - 1) // 2 + 1
    )
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


def generate_from_audio(
    model: SpeechModel | str | Path,
    audio,
    seed: int | None = None,
    *,
    sr: int | None = None,
    num_samples: int = 1,
    return_levels: bool = False,
    fix_contacts: bool = False,
    body=None,
):
    """Gestures for an utterance: one motion frame per ``1 / fps`` s of audio.

    Args:
        model: a :class:`SpeechModel` (or a checkpoint path, loaded on CPU).
        audio: a file path (any rate, mixed to mono, resampled to 16 kHz), or a waveform
            ``(N,)`` with ``sr``.
        seed: noise seed (sample b uses stream ``(seed, b)``, as ``mrlib.sample``).
        num_samples: a list of Motions when > 1.
        return_levels: also return every level's output (at ``fps * T_i / T_L``).
        fix_contacts: foot-contact clean-up (``mrlib.sample.cleanup_foot_contacts``).
    Returns:
        ``Motion`` of ``round(duration * fps)`` frames (label ``"speech"``), or a list;
        with ``return_levels`` a ``(motion, levels)`` pair as ``mrlib.sample.generate``.
    """
    from mrlib.sample import cleanup_foot_contacts

    if not isinstance(model, SpeechModel):
        model = load_speech_model(model)
    if num_samples < 1:
        raise MotionValueError(f"num_samples must be >= 1, got {num_samples}")
    name = Path(audio).stem if isinstance(audio, (str, Path)) else "audio"
    conds, lengths, wav, rate = audio_conditions(model, audio, sr)
    gm = model.model
    amp = gm.sigma[0].float()  # (L,)
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
    single = num_samples == 1
    if not return_levels:
        return motions[0] if single else motions
    fps_i = level_fps(gm.fps, lengths)
    levels = [
        [to_motion(outs[i][b], fps_i[i], f"{name}_level{i + 1}") for i in range(len(lengths))]
        for b in range(num_samples)
    ]
    return (motions[0], levels[0]) if single else (motions, levels)


# -- does the motion follow the speech? --------------------------------------------------------
def fit_audio_length(wav: np.ndarray, num_samples: int) -> np.ndarray:
    """``wav (N,)`` cut or repeated (from its start) to ``num_samples`` samples."""
    wav = np.asarray(wav, np.float32)
    if num_samples < 1 or len(wav) == 0:
        raise MotionValueError(f"need a non-empty waveform and num_samples >= 1, got {num_samples}")
    reps = -(-num_samples // len(wav))
    return np.tile(wav, reps)[:num_samples]


def wrist_lift(motion: Motion, body=None) -> np.ndarray:
    """Height of the wrists above the pelvis, mean of both, metres: ``(T,)``."""
    if body is None:
        from mrlib.body import load_body_model

        body = load_body_model()
    j = body.motion_joints(motion)  # (T, 24, 3)
    return (j[:, [20, 21], 1] - j[:, [0], 1]).mean(1).astype(np.float64)


def phrase_loudness(
    wav: np.ndarray,
    sr: int,
    fps: float,
    num_frames: int,
    *,
    smooth_s: float = 0.5,
    floor_db: float = -40.0,
) -> np.ndarray:
    """Slow loudness ``(num_frames,)`` in [0, 1]: the energy envelope mapped from
    ``floor_db..0`` dB to 0..1 and smoothed with a Gaussian of ``smooth_s`` seconds
    (phrases rather than syllables; 0.5 s is the time scale of the synthetic set's arm
    lift, ``mrlib.speech_data.GestureParams.lift_smooth_s``)."""
    from scipy.ndimage import gaussian_filter1d

    from mrlib.speech.audio import energy_envelope

    e = energy_envelope(wav, sr, fps, num_frames, floor_db=floor_db)
    e = np.clip((e - floor_db) / -floor_db, 0, 1).astype(np.float64)
    return gaussian_filter1d(e, smooth_s * fps, mode="nearest")


@dataclass
class SyncResult:
    """What :func:`evaluate_speech_sync` measured.

    Attributes:
        rows: one dict per (utterance, seed) with ``utterance``, ``seed`` and, for the
            model driven by its own audio (``_model``) and by another utterance's
            (``_shuffled``): ``r`` energy / hand-speed correlation, ``beat`` beat
            alignment, ``lift`` phrase-loudness / wrist-height correlation; ``_data``
            versions for utterances with a reference motion.
    """

    rows: list[dict]

    KEYS = ("r", "beat", "lift")

    def mean(self, key: str) -> float:
        vals = [r[key] for r in self.rows if key in r]
        return float(np.mean(vals)) if vals else float("nan")

    def std(self, key: str) -> float:
        vals = [r[key] for r in self.rows if key in r]
        return float(np.std(vals)) if vals else float("nan")

    def paired(self, key: str) -> tuple[float, float, int, int]:
        """Own audio against the other utterance's, row by row (same utterance and
        noise): ``(mean difference, its standard error, rows where own > other, rows)``."""
        d = np.array(
            [r[f"{key}_model"] - r[f"{key}_shuffled"] for r in self.rows if f"{key}_model" in r]
        )
        if len(d) == 0:
            return float("nan"), float("nan"), 0, 0
        se = float(d.std(ddof=1) / np.sqrt(len(d))) if len(d) > 1 else float("nan")
        return float(d.mean()), se, int((d > 0).sum()), len(d)

    def summary(self) -> dict[str, float]:
        """Means over the rows: ``{"r_model": ..., "r_shuffled": ..., ...}``."""
        keys = [f"{k}_{w}" for w in ("model", "shuffled", "data") for k in self.KEYS]
        return {k: self.mean(k) for k in keys if any(k in r for r in self.rows)}

    def to_markdown(self) -> str:
        def cell(key: str) -> str:
            return f"{self.mean(key):.3f} +- {self.std(key):.3f}"

        lines = [
            "| | energy / hand-speed r | beat alignment | phrase loudness / wrist-height r |",
            "|---|---|---|---|",
        ]
        for who, name in (
            ("model", "model, own audio"),
            ("shuffled", "model, other utterance's audio"),
        ):
            lines.append(f"| {name} | " + " | ".join(cell(f"{k}_{who}") for k in self.KEYS) + " |")
        diffs = []
        for k in self.KEYS:
            m, se, wins, n = self.paired(k)
            diffs.append(f"{m:+.3f} +- {se:.3f} s.e. ({wins}/{n} higher)")
        lines.append("| own - other audio, paired | " + " | ".join(diffs) + " |")
        if any("r_data" in r for r in self.rows):
            lines.append(
                "| reference motion | " + " | ".join(cell(f"{k}_data") for k in self.KEYS) + " |"
            )
        return "\n".join(lines)


def evaluate_speech_sync(
    model: SpeechModel,
    utterances: Sequence[tuple[np.ndarray, int]],
    seeds: Sequence[int] = (0, 1, 2),
    *,
    references: Sequence[Motion | None] | None = None,
    body=None,
    max_lag_s: float = 0.3,
) -> SyncResult:
    """How well generated gestures follow the speech, against the same model driven by
    the wrong audio.

    For utterance k and every seed: gestures generated from k's audio, and gestures
    generated from utterance ``k + 1``'s audio cut or repeated to k's duration (the
    *shuffled* control, same noise); both scored against utterance k:

    * ``r``: Pearson correlation of k's energy envelope and the hand speed
      (``speech_motion_correlation``, best lag within ``max_lag_s``): syllable-level
      coupling;
    * ``beat``: ``beat_alignment_score`` of k's onsets against the motion beats;
    * ``lift``: correlation of k's :func:`phrase_loudness` and the :func:`wrist_lift`
      (best lag within ``max_lag_s``): phrase-level coupling, arms up while talking.

    ``references`` (e.g. the held-out pairs' own motions) are scored the same way once.

    Args:
        utterances: ``(wav (N,), sr)`` pairs, at least two.
    Returns:
        a :class:`SyncResult` (``.summary()``, ``.to_markdown()``).
    """
    from mrlib.speech.audio import detect_onsets, energy_envelope
    from mrlib.speech.evaluate import (
        beat_alignment_score,
        hand_speed,
        lagged_correlation,
        speech_motion_correlation,
    )

    if len(utterances) < 2:
        raise MotionValueError("the shuffled control needs at least two utterances")
    if body is None:
        from mrlib.body import load_body_model

        body = load_body_model()

    def score(motion: Motion, wav, sr, onsets, tag: str) -> dict[str, float]:
        v = hand_speed(motion, body)
        T = motion.num_frames
        energy = energy_envelope(wav, sr, motion.fps, T)
        lag = int(round(max_lag_s * motion.fps))
        r = speech_motion_correlation(energy, motion, body, max_lag_s=max_lag_s, speed=v).r
        phrase = phrase_loudness(wav, sr, motion.fps, T)
        lift = lagged_correlation(phrase, wrist_lift(motion, body), motion.fps, lag).r
        beat = beat_alignment_score(onsets, motion, body, speed=v)
        return {f"r_{tag}": r, f"beat_{tag}": beat, f"lift_{tag}": lift}

    rows = []
    for k, (wav, sr) in enumerate(utterances):
        other, osr = utterances[(k + 1) % len(utterances)]
        other = fit_audio_length(other if osr == sr else _resample(other, osr, sr), len(wav))
        onsets = detect_onsets(wav, sr)
        ref = None if references is None else references[k]
        extra = {} if ref is None else score(ref, wav, sr, onsets, "data")
        for seed in seeds:
            own = generate_from_audio(model, wav, seed, sr=sr)
            shuf = generate_from_audio(model, other, seed, sr=sr)
            rows.append(
                {
                    "utterance": k,
                    "seed": int(seed),
                    **score(own, wav, sr, onsets, "model"),
                    **score(shuf, wav, sr, onsets, "shuffled"),
                    **extra,
                }
            )
    return SyncResult(rows)


def _resample(wav: np.ndarray, sr_in: int, sr_out: int) -> np.ndarray:
    from mrlib.speech.audio import resample_audio

    return resample_audio(wav, sr_in, sr_out)
