"""Co-speech gesture training (paper, Sec. 6).

The speech-conditioned model is the label-conditioned one with another control signal:
the same networks (``mrlib.model.generator``, ``mrlib.model.critic``), the same block-wise
WGAN-GP training loop (``mrlib.training.trainer``), the same sampler
(``mrlib.sampling.generation.sample_features``). Only the condition changes: instead of a
one-hot label, level i of the generator receives per-frame
speech features ``s_i (T_i, D)`` (``mrlib.speech.speech_conditions``: features aligned to
the motion's frame rate, downsampled to every pyramid level, residuals above level 1),
and FiLM modulates only the upper body (``ModelConfig.film_joints``).

What differs from label training, all in :class:`SpeechSignal` (the control signal,
``mrlib.training.signals``) and :class:`SpeechTrainer` (the trainer that uses it, and
what its checkpoint holds):

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
  shifted out of step (:meth:`SpeechSignal.mismatched_real_conditions`) as a fake, so it
  learns whether motion and speech go *together*, not only whether each looks real;
  that is what ties the hand speed to the loudness at the syllable level
  (``docs/results.md``). With conditional critics the random generations take paired
  audio by default;
* the paper alternates reconstruction and random generation; here both run in every
  generator step (the trainer sums ``L_rec`` of the reconstruction half of its batch and
  the other terms of the random half, ``mrlib.training.objective``), so every iteration visits
  the paired and the unpaired data once;
* style mixing becomes *speech mixing*: with probability ``TrainConfig.mix_prob`` a
  random generation takes a second audio window from a random crossover level on. The
  speech presets turn it off (the paper does not mix speech).

Checkpoints are ordinary mrlib checkpoints (``mrlib.model.checkpoint``, loadable with
``weights_only=True``) with one more key, ``"speech"``: the feature configuration, the
speech normaliser, the alignment settings and the raw features of every training clip
(needed to resume; for WavLM features at paper scale that is ~100 MB per 10 minutes).
Generation from audio is :mod:`mrlib.speech.sample`.

Shapes: T_a speech frames at ``audio_fps`` (50), D speech feature size, T motion
frames at the motion fps, L levels, B samples, S packed frames (``mrlib.model.pyramid``).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import torch

from mrlib.errors import MotionValueError
from mrlib.model.checkpoint import CheckpointError
from mrlib.model.config import ConfigError, TrainConfig
from mrlib.model.pyramid import PackedLevels
from mrlib.speech.align import downsample_levels, levels_to_residuals, speech_conditions
from mrlib.speech.data import SpeechTrainingSet
from mrlib.training.run import TrainResult
from mrlib.training.signals import LabelSignal, RandomDraw
from mrlib.training.trainer import Trainer

__all__ = [
    "RANDOM_AUDIO",
    "residual_operators",
    "SpeechDraw",
    "SpeechSignal",
    "SpeechTrainer",
    "speech_train",
]

RANDOM_AUDIO = ("unpaired", "all", "paired")


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
    (``mrlib.speech.synthetic.loop_motion``'s rule); ``n >= 1`` per element."""
    period = (2 * (n - 1)).clamp_min(1)
    k = pos % period
    return torch.where(n == 1, torch.zeros_like(k), torch.where(k < n, k, period - k))


@dataclass
class SpeechDraw:
    """The speech of a batch of random generations (what ``SpeechSignal.draw_speech``
    draws in place of a label table).

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


class SpeechSignal(LabelSignal):
    """Speech as the control signal (``mrlib.training.signals``): per-frame speech
    features ``(1, S_i, D)`` per level. Overrides what the label signal gives the steps:
    ``dim`` (D), ``real_conds`` (each paired clip's own speech), :meth:`rec_conditions`,
    :meth:`draw_random`, :meth:`critic_keep` and :meth:`mismatched_real_conditions`; the
    noise amplitudes are those of the one label every paired clip carries (their mean).

    Args:
        data: the training set; ``b``, ``config``, ``rng``: the trainer's batches, config
            and generator of random draws; ``random_audio``: see :class:`SpeechTrainer`.
    """

    def __init__(self, data: SpeechTrainingSet, b, config: TrainConfig, rng, random_audio: str):
        super().__init__(data.motion, b, config, rng)
        self.speech = data
        self.dim = data.dim
        self.mismatch = bool(config.loss.mismatch)

        # the audio bank: every clip's normalised features at the motion frame rate
        finest, kinds = data.finest()
        self.bank = torch.cat(finest).to(b.device)  # (sum T, D)
        self.bank_lengths = torch.tensor([f.shape[0] for f in finest])
        self.bank_offsets = torch.cumsum(self.bank_lengths, 0) - self.bank_lengths
        use = {"unpaired": ("unpaired",), "paired": ("paired",), "all": ("paired", "unpaired")}
        self.sources = torch.tensor(
            [k for k, kind in enumerate(kinds) if kind in use[random_audio]]
        )

        # reconstruction conditions: each paired clip with its own speech
        L = config.model.num_levels
        per_clip = [
            speech_conditions(
                f,
                data.audio_fps,
                data.fps,
                b.lengths[k].tolist(),
                normalizer=data.normalizer,
                offset_s=data.frame_offset_s,
                method=data.downsample,
            )
            for k, f in enumerate(data.paired_features)
        ]
        self.rec_conds = [
            b.rec_layout.pack([c[i].T for c in per_clip], i).transpose(1, 2) for i in range(L)
        ]  # (1, S_i, D)
        self._per_clip = per_clip
        # a conditional critic sees every real clip with its own speech
        self.real_conds = (
            [
                b.rand_layout.pack([per_clip[k][i].T for k in b.rand_clip], i).transpose(1, 2)
                for i in range(L)
            ]
            if config.model.critic_condition
            else None
        )
        self._ops: dict[int, tuple[PackedLevels, list[torch.Tensor], torch.Tensor]] = {}

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

    def draw_random(self, layout: PackedLevels, stop: int) -> RandomDraw:
        """Conditions ``[(1, S_i, D)]`` (:meth:`draw_speech`, :meth:`draw_conditions`) and
        noises ``[(1, 1, S_i)]`` of levels ``0..stop-1`` of a layout's random generations.
        Noise ``z_i ~ N(0, sigma_i)`` (sigma averaged over the paired clips), shared by all
        channels."""
        draw = self.draw_speech(layout)
        L = self.config.model.num_levels
        second = torch.arange(L)[None] >= draw.cross[:, None]  # (B, L) levels on window b
        P = self.speech.num_paired  # bank: paired clips first
        paired = torch.where(second, draw.source_b[:, None] < P, draw.source[:, None] < P)
        noises = []
        for i in range(stop):
            z = torch.randn(1, 1, layout.sizes[i], generator=self.rng).to(self.b.device)
            noises.append(z * self.sigma[0, i].to(self.b.device))
        conds = self.draw_conditions(draw, layout, stop)
        return RandomDraw(conds, noises, second, paired=paired)

    def critic_keep(self, draw: RandomDraw) -> torch.Tensor:
        """A conditional critic hears the speech of a fake only where it is paired audio:
        a real clip always comes with paired audio, so a fake driven by unpaired audio
        would be told apart by its audio alone. Such fakes, and the real clips that share
        their slots, are judged on realism only (their conditions zeroed)."""
        return super().critic_keep(draw) * draw.paired.float()

    def mismatched_real_conditions(self, level: int) -> torch.Tensor:
        """Speech that does not go with the real clips (``loss.mismatch``): each clip's own
        speech, circularly shifted by a random 25-75 % of its length, so the critic sees
        the same frames of speech, out of step with the motion."""
        ks = self.b.rand_clip.tolist()
        frac = 0.25 + 0.5 * torch.rand(len(ks), generator=self.rng)
        shifted = []
        for f, k in zip(frac.tolist(), ks, strict=True):
            c = self._per_clip[k][level]
            shifted.append(c.roll(max(1, round(f * len(c))), 0).T)
        return self.b.rand_layout.pack(shifted, level).transpose(1, 2).to(self.b.device)


class SpeechTrainer(Trainer):
    """``mrlib.training.trainer.Trainer`` with speech as the control signal.

    Overrides only the signal (:meth:`control_signal`: a :class:`SpeechSignal`) and what
    the checkpoint holds (``state_dict``, ``from_checkpoint``); the networks, losses,
    loop, logging, resume and Ctrl-C handling are the Trainer's.

    Args:
        data: a :class:`SpeechTrainingSet`.
        config: a ``TrainConfig`` (``mrlib.model.presets.speech_tutorial()``, ``speech_paper()``).
        random_audio: where random generations take their speech: ``"unpaired"`` (paper),
            ``"all"`` (paired and unpaired) or ``"paired"``; None (default): ``"paired"``
            with conditional critics (they hear paired audio only, see
            :meth:`SpeechSignal.critic_keep`), else ``"unpaired"`` (``"paired"`` when
            there is no unpaired audio).
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
                "(ModelConfig(film_joints=mrlib.representation.skeleton.UPPER_BODY_JOINTS))",
                stacklevel=2,
            )
        self.speech = data
        self.random_audio = random_audio
        super().__init__(data.motion, config, out_dir, body=body)

    def control_signal(self) -> SpeechSignal:
        return SpeechSignal(self.speech, self.batches, self.config, self.rng, self.random_audio)

    # -- checkpoints ---------------------------------------------------------------------------
    def state_dict(self) -> dict:
        state = super().state_dict()
        state["speech"] = {**self.speech.speech_state(), "random_audio": self.random_audio}
        return state

    @classmethod
    def _check_state(cls, path: Path, state: dict) -> None:
        if "speech" not in state:
            raise CheckpointError(path, "not a speech-conditioned checkpoint (no 'speech' key)")

    @classmethod
    def _data_from_state(cls, state: dict) -> SpeechTrainingSet:
        return SpeechTrainingSet.from_state(state)

    @classmethod
    def _init_from_state(cls, state: dict) -> dict:
        return {"random_audio": str(state["speech"]["random_audio"])}


def speech_train(
    data: SpeechTrainingSet | None,
    config: TrainConfig | None,
    out_dir: str | Path,
    *,
    resume: str | Path | None = None,
    random_audio: str | None = None,
    body=None,
    progress: bool = True,
    overwrite: bool = False,
) -> TrainResult:
    """Train a speech-conditioned model (or continue one); ``mrlib.training.trainer.train``
    for speech. ``data``, ``config`` and ``random_audio`` are ignored when resuming (the
    checkpoint holds them). ``overwrite`` replaces a run already in ``out_dir`` (refused
    otherwise). For a callback after every iteration, or to resume on another device:
    ``SpeechTrainer.start(..., device=...).fit(callback=...)``."""
    options = {"random_audio": random_audio}
    trainer = SpeechTrainer.start(
        data, config, out_dir, resume=resume, body=body, overwrite=overwrite, options=options
    )
    return trainer.fit(progress=progress, overwrite=overwrite)
