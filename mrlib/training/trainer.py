"""Block-wise adversarial training of the multi-resolution conditional GAN.

Levels are trained in blocks of two consecutive levels (paper Sec. 3.4, after GANimator
and Hinz et al. 2021); levels of earlier blocks are frozen. One *iteration* of a block is

1. ``n_critic`` critic steps. The fakes of all of them come from one batched, gradient-free
   generation (the generator does not change between critic steps, so this equals
   GANimator's one-generation-per-step in distribution). Each step scores real and fake
   clips of every level in the block and adds the gradient penalty (WGAN-GP).
2. one generator step on ``L = adv*L_adv + con*L_con + rec*L_rec + smooth*L_smooth``
   (paper Eq. 6), summed over the levels of the block. Reconstructions (every training
   clip with its fixed noise z* and its own label) and random generations (one per clip,
   90% of them mixing two labels at a random crossover level) run as one batch; the
   frozen levels' reconstructions are computed once per block.

Batches mix clips of different lengths, packed end to end (``mrlib.model.pyramid.PackedLevels``):
random generation b follows the pyramid of clip ``b mod N``, so reals and fakes line up
sample by sample.

Checkpoints (``mrlib.model.checkpoint``) hold everything needed to resume bit-exactly on CPU:
networks, optimizers, iteration, and the RNG states. Ctrl-C finishes the current
iteration, writes a checkpoint and returns.

This module is long (~1000 lines) on purpose: one :class:`Trainer` holds a run's fixed
batches, its condition hooks, one iteration, its checkpoints and its loop, and
``mrlib.speech.SpeechTrainer`` overrides pieces of each; the losses themselves are pure
functions in ``mrlib.model.losses``.
"""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import json
import os
import random
import signal
import threading
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from io import StringIO
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

from mrlib.errors import ClipTooShortError, MrlibError
from mrlib.io.outputs import OutputExistsError, RunLock, open_for_append, write_text
from mrlib.io.paths import cache_root
from mrlib.model.checkpoint import (
    CheckpointError,
    global_rng_state,
    load_checkpoint,
    reading,
    save_checkpoint,
    set_global_rng_state,
)
from mrlib.model.config import ConfigError, TrainConfig, config_from_json, config_to_json
from mrlib.model.losses import (
    backward_velocity,
    body_kinematics,
    contact_consistency_loss,
    detail_statistics_loss,
    foot_slide,
    generator_adversarial_loss,
    mismatch_critic_loss,
    reconstruction_loss,
    smoothness_loss,
    wgan_gp_critic_loss,
)
from mrlib.model.networks import MultiResGenerator, build_critics, build_generator
from mrlib.model.pyramid import PackedLevels, build_pyramid, noise_amplitudes, pyramid_lengths
from mrlib.model.trained import load_model
from mrlib.representation.features import NUM_FEATURES, FeatureNormalizer, split_features
from mrlib.threads import with_policy
from mrlib.training.data import TrainingSet

__all__ = [
    "train",
    "train_or_reuse",
    "train_cached",
    "train_cached_many",
    "model_cache_key",
    "Trainer",
    "TrainResult",
    "TrainRecord",
    "RandomDraw",
    "TrainingDivergedError",
    "make_adam",
    "RunExistsError",
    "check_run_folder",
    "RUN_FILES",
    "LOSS_NAMES",
]


class TrainingDivergedError(MrlibError, FloatingPointError):
    """A loss or a weight became NaN or infinite during training."""


LOSS_NAMES = ("D", "gp", "adv", "rec", "con", "smooth", "mis", "detail")
CSV_FIELDS = ["time_s", "block", "iteration", "level", *LOSS_NAMES]
RUN_FILES = ("checkpoint.pt", "checkpoint.pt.json", "losses.csv")  # what a run writes


class RunExistsError(OutputExistsError):
    """The output folder already holds another training run."""


def _same_file(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def check_run_folder(
    out_dir: str | Path, *, resume: str | Path | None = None, overwrite: bool = False
) -> None:
    """Refuse to start a run in ``out_dir`` when that would replace another run's files
    (:data:`RUN_FILES`): a new run needs a folder without them, a resumed run its
    checkpoint's own folder or one without them; ``overwrite=True`` allows both.

    Raises:
        RunExistsError: naming the folder, what it holds and the ways around.
    """
    out = Path(out_dir)
    present = [n for n in RUN_FILES if os.path.lexists(out / n)]
    if not present or overwrite:
        return
    held = ", ".join(present)
    if resume is None:
        raise RunExistsError(
            out,
            f"already holds a training run ({held}); continue it with --resume "
            f"{out / 'checkpoint.pt'}, replace it with --overwrite, or choose another --out",
        )
    if not _same_file(out / "checkpoint.pt", Path(resume)):
        raise RunExistsError(
            out,
            f"holds another run ({held}); a resumed run continues in its checkpoint's own "
            f"folder ({Path(resume).parent}) or in a new one (or pass --overwrite)",
        )


@dataclass
class TrainResult:
    """What :func:`train` returns."""

    checkpoint: Path
    log: Path
    interrupted: bool
    wall_time_s: float
    losses: dict[int, dict[str, float]]  # last logged losses per level (1-based)


@dataclass
class RandomDraw:
    """The control signals and noises of a batch of random generations, and how they were
    drawn (what :meth:`Trainer.draw_random` returns).

    Attributes:
        conds: per level ``(1, S_i, D)`` conditions (packed, ``mrlib.model.pyramid``).
        noises: per level ``(1, 1, S_i)`` noise ``z_i``.
        mixed: ``(B, L)`` bool, the levels each sample takes from its second condition.
        labels: ``(B, L)`` label index per level (label training).
        paired: ``(B, L)`` bool, speech from paired audio (speech training).
    """

    conds: list[torch.Tensor]
    noises: list[torch.Tensor]
    mixed: torch.Tensor
    labels: torch.Tensor | None = None
    paired: torch.Tensor | None = None


def _clip_lengths(name: str, length: int, L: int, factor: float, min_length: int) -> list[int]:
    try:
        return pyramid_lengths(length, L, factor, min_length=min_length)
    except ClipTooShortError as e:
        raise ClipTooShortError(f"clip '{name}': {e}") from None


def make_adam(params, lr: float, betas: tuple[float, float], device) -> torch.optim.Adam:
    """Adam with PyTorch's fused kernel where this torch has one for the device (CPU from
    torch 2.4 on, CUDA), else its default implementation. Fused, the step of all of a
    block's parameters is one kernel instead of a dozen small ones per tensor: on a
    2-core x86-64 VM, one thread, the ``demo`` preset trained 4 % faster than with the
    for-loop Adam (most in the coarse blocks, where the networks' work is least;
    ``python bench/busy_machine.py --extras``; foreach: 1 %). Its results differ from
    the for-loop's by float rounding (~1e-7 after 50 steps)."""
    params = list(params)
    if torch.device(device).type in ("cpu", "cuda"):
        try:
            return torch.optim.Adam(params, lr=lr, betas=betas, fused=True)
        except (RuntimeError, TypeError, ValueError):  # an older torch: no fused CPU kernel
            pass
    return torch.optim.Adam(params, lr=lr, betas=betas)


class Trainer:
    """Holds the networks, data pyramids, layouts and optimizers of one training run.

    Use :func:`train` unless you need step-level control (``step`` runs one iteration of
    the current block and returns its losses). Creating a trainer seeds torch's, numpy's
    and Python's global generators with ``config.seed`` (network initialisation); every
    random draw of training then comes from the trainer's own generator ``rng``.
    """

    def __init__(self, data: TrainingSet, config: TrainConfig, out_dir: str | Path, body=None):
        self.data = data
        self.config = config
        self.out_dir = Path(out_dir)
        self.resumed_from: Path | None = None  # the checkpoint this trainer continues
        self._claimed = False  # out_dir checked (check_run_folder) by an earlier fit
        self._saved = False
        self.device = torch.device(config.device)
        mc = config.model
        L = mc.num_levels
        self.rng = torch.Generator().manual_seed(config.seed)  # every random draw of training
        torch.manual_seed(config.seed)  # network initialisation
        np.random.seed(config.seed)
        random.seed(config.seed)
        from mrlib.representation.body import resolve_body

        body = resolve_body(body)
        self.body = body.to(self.device) if hasattr(body, "to") else body
        self.betas = torch.as_tensor(
            np.asarray(data.betas), dtype=torch.float32, device=self.device
        )
        norm = data.normalizer
        self.data_normalizer = FeatureNormalizer(
            norm.mean.to(self.device), norm.std.to(self.device)
        )

        # 1. pyramids, noise amplitudes, reconstruction noise --------------------------------
        pad = (mc.kernel_size - 1) // 2
        self.lengths = torch.tensor(
            [
                _clip_lengths(name, t, L, mc.scale_factor, pad + 1)
                for name, t in zip(data.names, data.lengths, strict=True)
            ]
        )  # (N, L)
        clips = data.normalized()
        pyramids = [build_pyramid(x, self.lengths[k].tolist()) for k, x in enumerate(clips)]
        self.sigma_clip = torch.stack([noise_amplitudes(p) for p in pyramids])  # (N, L)
        lab = torch.tensor(data.clip_labels)
        self.sigma = torch.stack(
            [self.sigma_clip[lab == k].mean(0) for k in range(data.num_labels)]
        )
        # Fixed reconstruction noise z*_1 of every clip (zero above level 1). "shared": a draw
        # of the random noise itself, N(0, sigma_1) shared by all channels (paper Sec. 3.2-3.4);
        # "full": N(0, 1) on every channel (GANimator's default, full_zstar=1).
        k0 = NUM_FEATURES if config.zstar == "full" else 1
        self.zstar = []
        for k in range(data.num_clips):
            z = torch.randn(k0, int(self.lengths[k, 0]), generator=self.rng)
            self.zstar.append(z if config.zstar == "full" else z * self.sigma_clip[k, 0])

        # 2. networks -------------------------------------------------------------------------
        self.cond_dim = data.num_labels
        self.generator: MultiResGenerator = build_generator(mc, self.cond_dim).to(self.device)
        critic_cond = self.cond_dim if mc.critic_condition else 0
        self.critics = build_critics(mc, critic_cond).to(self.device)
        labels_mismatch = (
            type(self).mismatched_real_conditions is Trainer.mismatched_real_conditions
        )
        if config.loss.mismatch and labels_mismatch and data.num_labels < 2:
            raise ConfigError("loss.mismatch needs at least two labels (a wrong one to show)")
        self.block = 0
        self.iteration = 0
        self.done = False
        self.opt_g: torch.optim.Adam | None = None
        self.opt_d: torch.optim.Adam | None = None

        # 3. fixed batch layouts (packed: samples end to end, see mrlib.model.pyramid) -------------
        N = data.num_clips
        self.N, self.B = N, N * config.samples_per_clip
        self.rand_clip = torch.arange(self.B) % N  # clip whose pyramid random sample b follows
        dev, gap = self.device, 2 * pad
        rand_table = self.lengths[self.rand_clip]
        packed = lambda table: PackedLevels.from_table(table, gap, dev)  # noqa: E731
        self.rec_layout = packed(self.lengths)
        self.rand_layout = packed(rand_table)
        self.g_layout = packed(torch.cat([self.lengths, rand_table]))  # [reconstructions; random]
        self.fake_layout = packed(rand_table.repeat(max(1, config.n_critic), 1))  # critic steps
        self.critic_layout = packed(rand_table.repeat(2, 1))  # [real; fake]
        self.real = [self.rec_layout.pack([p[i] for p in pyramids], i) for i in range(L)]
        self.real_rand = [
            self.rand_layout.pack([pyramids[k][i] for k in self.rand_clip], i) for i in range(L)
        ]
        self.clip_labels = lab
        self.rec_labels = lab[:, None].expand(N, L)  # (N, L)
        self.real_rand_conds = (
            self.label_conditions(
                lab[self.rand_clip][:, None].expand(self.B, L), self.rand_layout, L
            )
            if mc.critic_condition
            else None
        )  # a conditional critic sees every real clip with its own label
        fps_table = data.fps * self.lengths.double() / self.lengths[:, -1:].double()  # (N, L)
        rand_fps = fps_table[self.rand_clip].float()  # (B, L)
        self.rand_fps = [
            self.rand_layout.per_sample(rand_fps[:, i], i)[None] for i in range(L)
        ]  # (1, S_i)
        lay = self.rand_layout
        self.w_rec = [self.rec_layout.weights(i) for i in range(L)]
        self.w_rand = [lay.weights(i) for i in range(L)]
        self.w_vel = [lay.weights(i, lay.trimmed(i, start=1)) for i in range(L)]
        self.w_smooth = [lay.weights(i, lay.trimmed(i, start=1, end=1)) for i in range(L)]
        rl = self.rec_layout
        self.rec_fps = [rl.per_sample(fps_table[:, i].float(), i)[None] for i in range(L)]
        self.w_vel_rec = [rl.weights(i, rl.trimmed(i, start=1)) for i in range(L)]
        # loss.con_on_rec: the clips' own contact labels per level, (1, S_i, 6)
        self.real_contacts = (
            [
                split_features(self.data_normalizer.denormalize(r.transpose(1, 2)))[2]
                for r in self.real
            ]
            if config.loss.con_on_rec
            else None
        )
        # critic_contacts: frames without a predecessor, and the real clips as the critics
        # see them (features + foot slides), fixed for the whole run
        self.first_rand = [~lay.trimmed(i, start=1) for i in range(L)]
        self.real_critic = self.real_rand
        if config.model.critic_contacts:
            with torch.no_grad():
                self.real_critic = [self.critic_input(r, i) for i, r in enumerate(self.real_rand)]
        self.zstar_packed = self.rec_layout.pack(self.zstar, 0)  # (1, 1 or C, S_1)
        self._rec_cache: tuple[int, torch.Tensor] | None = None
        # loss.detail only: per label and level, the per-channel RMS of the detail the level
        # adds (mean over the label's clips), the targets of the term, (K, C) per level
        self.detail_rms: list[torch.Tensor] = []
        if config.loss.detail:
            lay = self.rec_layout
            rms = [lay.per_sample_rms(lay.level_band(r, i), i) for i, r in enumerate(self.real)]
            self.detail_rms = [
                torch.stack([r[lab == k].mean(0) for k in range(data.num_labels)]) for r in rms
            ]

    # -- conditions and noise --------------------------------------------------------------
    # The networks take any control signal (B, T_i, D) per level. These methods are the only
    # place where labels become conditions: a trainer for another signal (per-frame speech
    # features, mrlib.speech.SpeechTrainer) overrides them.
    def label_conditions(
        self, label_table: torch.Tensor, layout: PackedLevels, stop: int
    ) -> list[torch.Tensor]:
        """One-hot label conditions ``(1, S_i, K)`` of levels ``0..stop-1`` from a ``(B, L)``
        table of label indices (constant over each sample's frames)."""
        onehot = F.one_hot(label_table, self.cond_dim).float()  # (B, L, K)
        return [layout.per_sample(onehot[:, i], i)[None] for i in range(stop)]

    def rec_conditions(self, stop: int) -> list[torch.Tensor]:
        """Conditions of the reconstructions: every clip's own label at every level."""
        return self.label_conditions(self.rec_labels, self.rec_layout, stop)

    def draw_random(self, layout: PackedLevels, stop: int) -> RandomDraw:
        """Conditions ``[(1, S_i, K)]`` and noises ``[(1, 1, S_i)]`` of levels ``0..stop-1``
        for the random generations of a layout whose sample b follows clip ``b mod N``.

        Sample b's coarse label is its clip's. With probability ``mix_prob`` a second label
        (uniform) takes over from a random crossover level on (style-mixing
        regularisation, paper Sec. 4.3); reconstructions never mix. Noise
        ``z_i ~ N(0, sigma_i)`` with the sigma of the label in use at level i, shared by
        all channels."""
        L, K, batch = self.config.model.num_levels, self.cond_dim, layout.batch_size
        a = self.clip_labels[torch.arange(batch) % self.N]
        mix = torch.rand(batch, generator=self.rng) < self.config.mix_prob
        b = torch.randint(K, (batch,), generator=self.rng)
        cross = torch.randint(1, max(L, 2), (batch,), generator=self.rng)  # levels >= cross use b
        levels = torch.arange(L)[None]
        mixed = mix[:, None] & (levels >= cross[:, None])  # (B, L) levels driven by b
        table = torch.where(mixed, b[:, None], a[:, None])
        noises = []
        for i in range(stop):
            z = torch.randn(1, 1, layout.sizes[i], generator=self.rng).to(self.device)
            noises.append(z * layout.per_sample(self.sigma[table[:, i], i], i))
        conds = self.label_conditions(table, layout, stop)
        return RandomDraw(conds, noises, mixed, labels=table)

    def critic_keep(self, draw: RandomDraw) -> torch.Tensor:
        """``(B, L)`` 1 where a sample of ``draw`` is scored with its condition, else 0:
        with ``critic_mixed == "none"`` a style-mixed sample is scored without a label from
        its crossover level on."""
        if self.config.critic_mixed == "label":
            return torch.ones_like(draw.mixed, dtype=torch.float32)
        return (~draw.mixed).float()

    def critic_conditions(self, draw: RandomDraw, layout: PackedLevels) -> list[torch.Tensor]:
        """What a conditional critic sees with the fakes of ``draw`` on ``layout``: their
        conditions, zeroed where :meth:`critic_keep` is 0. The real clip that shares the
        sample's slot is then scored without its condition too: were only fakes ever
        unlabelled, the critic could tell them apart by the missing label alone (the
        projection term is outside the gradient penalty's reach), which we saw diverge."""
        keep = self.critic_keep(draw)
        if bool(keep.all()):
            return draw.conds
        return [
            c * layout.per_sample(keep[:, i], i)[None, :, None] for i, c in enumerate(draw.conds)
        ]

    def mismatched_real_conditions(self, level: int) -> torch.Tensor:
        """Conditions ``(1, S_i, D)`` that do *not* go with the real clips of the random
        layout at ``level`` (``loss.mismatch``): each clip with another label, uniform
        over the others."""
        K, B = self.cond_dim, self.B
        own = self.clip_labels[self.rand_clip]
        wrong = (own + torch.randint(1, K, (B,), generator=self.rng)) % K
        onehot = F.one_hot(wrong, K).float()
        return self.rand_layout.per_sample(onehot, level)[None].to(self.device)

    def detail_targets(self, draw: RandomDraw, level: int) -> torch.Tensor:
        """``(B, C)`` targets of the detail-statistics term: the mean RMS of the band
        ``level`` adds, over the training clips of the label driving each sample there."""
        return self.detail_rms[level].to(self.device)[draw.labels[:, level]]

    def critic_input(self, x: torch.Tensor, level: int, kinematics=None) -> torch.Tensor:
        """What a critic of ``level`` reads of ``x (1, C, S)`` in the random layout: ``x``,
        and with ``ModelConfig.critic_contacts`` its foot slides (``losses.foot_slide``)
        as 6 more channels. ``kinematics``: ``body_kinematics`` of ``x`` if at hand."""
        if not self.config.model.critic_contacts:
            return x
        fps = self.rand_fps[level]
        if kinematics is None:
            kinematics = body_kinematics(x, self.data_normalizer, fps, self.body, self.betas)
        _, feet, contacts = kinematics
        return torch.cat([x, foot_slide(feet, contacts, fps, self.first_rand[level])], 1)

    def _band_of(self, layout, level: int) -> Callable[[torch.Tensor], torch.Tensor] | None:
        """``x -> layout.level_band(x, level)`` for a critic that reads the level band."""
        if self.critics[level].band != "level":
            return None
        return lambda x: layout.level_band(x, level)

    def _band(self, layout, level: int, x: torch.Tensor) -> torch.Tensor | None:
        """The ``band`` argument of a critic call: None unless the critic reads it."""
        f = self._band_of(layout, level)
        return None if f is None else f(x)

    # -- blocks ------------------------------------------------------------------------------
    @property
    def block_levels(self) -> list[int]:
        return self.config.blocks[self.block]

    def start_block(self) -> None:
        """Freeze earlier levels, create this block's optimizers."""
        lo, hi = self.block_levels[0], self.block_levels[-1]
        for i, (g, d) in enumerate(zip(self.generator.levels, self.critics, strict=False)):
            g.requires_grad_(lo <= i <= hi)
            d.requires_grad_(lo <= i <= hi)
        c = self.config
        g_params = [p for i in self.block_levels for p in self.generator.levels[i].parameters()]
        d_params = [p for i in self.block_levels for p in self.critics[i].parameters()]
        self.opt_g = make_adam(g_params, c.lr, c.betas, self.device)
        self.opt_d = make_adam(d_params, c.lr, c.betas, self.device)
        self._rec_cache = None

    def _rec_noises(self, stop: int) -> list[torch.Tensor]:
        """z*_1 at level 1, zero above (paper Sec. 3.4)."""
        return [self.zstar_packed] + [
            self.zstar_packed.new_zeros(1, 1, s) for s in self.rec_layout.sizes[1:stop]
        ]

    def _rec_input(self, lo: int) -> torch.Tensor | None:
        """Frozen levels' reconstruction of every clip (output of level lo-1), cached."""
        if lo == 0:
            return None
        if self._rec_cache is None or self._rec_cache[0] != lo:
            with torch.no_grad():
                conds = self.rec_conditions(lo)
                x = self.generator.run(self.rec_layout, self._rec_noises(lo), conds, 0, lo)
            self._rec_cache = (lo, x)
        return self._rec_cache[1]

    # -- one iteration ---------------------------------------------------------------------
    def step(self) -> dict[int, dict[str, torch.Tensor]]:
        """One iteration (critic steps + one generator step) of the current block; returns
        the losses ``{level: {name: value}}`` (0-based levels)."""
        losses: dict[int, dict[str, torch.Tensor]] = {i: {} for i in self.block_levels}
        if self.config.n_critic > 0:
            self._critic_steps(losses)
        self._generator_step(losses)
        return losses

    def _critic_steps(self, losses: dict[int, dict[str, torch.Tensor]]) -> None:
        """``n_critic`` critic steps on WGAN-GP (+ the mismatch term); the fakes of all of
        them come from one gradient-free generation."""
        c, w, G = self.config, self.config.loss, self.generator
        hi = self.block_levels[-1]
        draw = self.draw_random(self.fake_layout, hi + 1)
        with torch.no_grad():
            fakes = G.run(self.fake_layout, draw.noises, draw.conds, 0, hi + 1, keep=True)
        if self.real_rand_conds is not None:
            conds = self.critic_conditions(draw, self.fake_layout)
            keep = self.critic_keep(draw)  # (n_critic * B, L)
        alphas = torch.rand(c.n_critic, self.B, generator=self.rng).to(self.device)
        for j in range(c.n_critic):
            self.opt_d.zero_grad(set_to_none=True)
            total = 0.0
            for i in self.block_levels:
                S = self.rand_layout.sizes[i]
                fake = fakes[i][..., j * S : (j + 1) * S]  # the j-th copy of the random layout
                alpha = self.rand_layout.per_sample(alphas[j], i)[None, None]  # (1, 1, S)
                cond_real = cond_fake = None
                if self.real_rand_conds is not None:
                    # a real clip is shown without its condition where its fake partner
                    # (same sample slot) is: both sides see the same kind of condition
                    k_j = self.rand_layout.per_sample(keep[j * self.B : (j + 1) * self.B, i], i)
                    cond_real = self.real_rand_conds[i] * k_j[None, :, None]
                    cond_fake = conds[i][:, j * S : (j + 1) * S]
                pad, pad_pair = (
                    self.rand_layout.pad_index(i, G.pad),
                    self.critic_layout.pad_index(i, G.pad),
                )
                fake = self.critic_input(fake, i)
                wl, gp = wgan_gp_critic_loss(
                    self.critics[i],
                    self.real_critic[i],
                    fake,
                    self.w_rand[i],
                    alpha,
                    pad,
                    pad_pair,
                    cond_real=cond_real,
                    cond_fake=cond_fake,
                    band_of=self._band_of(self.rand_layout, i),
                    band_of_pair=self._band_of(self.critic_layout, i),
                )
                total = total + wl + w.gp * gp
                losses[i]["D"], losses[i]["gp"] = wl.detach(), gp.detach()
                if w.mismatch:
                    wrong = self.mismatched_real_conditions(i) * k_j[None, :, None]
                    mis = mismatch_critic_loss(
                        self.critics[i],
                        self.real_critic[i],
                        cond_real,
                        wrong,
                        self.w_rand[i],
                        pad_pair,
                        self._band_of(self.critic_layout, i),
                    )
                    total = total + w.mismatch * mis
                    losses[i]["mis"] = mis.detach()
            total.backward()
            self.opt_d.step()

    def _generator_step(self, losses: dict[int, dict[str, torch.Tensor]]) -> None:
        """One generator step on ``L = adv*L_adv + con*L_con + rec*L_rec + smooth*L_smooth``
        (+ ``detail``) over the block's levels: reconstructions and random generations
        run as one batch."""
        c, w, G = self.config, self.config.loss, self.generator
        lo, hi = self.block_levels[0], self.block_levels[-1]
        self.opt_g.zero_grad(set_to_none=True)
        draw = self.draw_random(self.rand_layout, hi + 1)
        critic_conds = (
            None if self.real_rand_conds is None else self.critic_conditions(draw, self.rand_layout)
        )
        rec_conds = self.rec_conditions(hi + 1)
        rec_noises = self._rec_noises(hi + 1)
        x_in = None
        if lo > 0:
            with torch.no_grad():
                x_rand = G.run(self.rand_layout, draw.noises, draw.conds, 0, lo)
            x_in = torch.cat([self._rec_input(lo), x_rand], -1)
        all_noises, all_conds = [], []
        for i in range(hi + 1):
            zr, zn = rec_noises[i], draw.noises[i]
            zn = zn.expand(-1, zr.shape[1], -1)  # level 1: a "full" z*_1 has every channel
            all_noises.append(torch.cat([zr, zn], -1))
            all_conds.append(torch.cat([rec_conds[i], draw.conds[i]], 1))
        outs = G.run(self.g_layout, all_noises, all_conds, lo, hi + 1, x=x_in, keep=True)
        total = 0.0
        for k, i in enumerate(self.block_levels):
            cut = self.g_layout.split(i, self.N)
            out_rec, out_rand = outs[k][..., :cut], outs[k][..., cut:]
            terms = {"rec": reconstruction_loss(out_rec, self.real[i], self.w_rec[i])}
            need_con = w.con and i + 1 >= c.contact_from_level
            need_smooth = w.smooth and i + 1 >= c.smooth_start
            need_adv = c.n_critic > 0 and w.adv
            fps, kin = self.rand_fps[i], None
            if need_adv and c.model.critic_contacts:
                kin = body_kinematics(out_rand, self.data_normalizer, fps, self.body, self.betas)
            if need_adv:
                cond = None if critic_conds is None else critic_conds[i]
                seen = self.critic_input(out_rand, i, kin)
                score = self.critics[i](
                    seen,
                    self.rand_layout.pad_index(i, G.pad),
                    cond,
                    self._band(self.rand_layout, i, seen),
                )
                terms["adv"] = generator_adversarial_loss(score, self.w_rand[i])
            if w.detail and i > 0:
                lay = self.rand_layout
                rms = lay.per_sample_rms(lay.level_band(out_rand, i), i)  # (B, C)
                terms["detail"] = detail_statistics_loss(rms, self.detail_targets(draw, i))
            if need_con or need_smooth:
                if kin is None:
                    kin = body_kinematics(
                        out_rand, self.data_normalizer, fps, self.body, self.betas
                    )
                joints, feet, contacts = kin
                if need_con:
                    vel = backward_velocity(feet, fps)
                    terms["con"] = contact_consistency_loss(
                        vel, contacts, self.w_vel[i], w.con_norm
                    )
                    if w.con_on_rec:  # the clip's own contacts on its reconstruction
                        _, feet_r, _ = body_kinematics(
                            out_rec, self.data_normalizer, self.rec_fps[i], self.body, self.betas
                        )
                        terms["con"] = terms["con"] + contact_consistency_loss(
                            backward_velocity(feet_r, self.rec_fps[i]),
                            self.real_contacts[i],
                            self.w_vel_rec[i],
                            w.con_norm,
                        )
                if need_smooth:
                    terms["smooth"] = smoothness_loss(joints, self.w_smooth[i])
            for name, value in terms.items():
                total = total + getattr(w, name) * value
                losses[i][name] = value.detach()
        total.backward()
        self.opt_g.step()

    # -- checkpoints -------------------------------------------------------------------------
    def state_dict(self) -> dict:
        d = self.data
        return {
            "config": config_to_json(self.config),
            "labels": list(d.labels),
            "clip_labels": [int(k) for k in d.clip_labels],
            "clip_names": list(d.names),
            "fps": float(d.fps),
            "betas": torch.as_tensor(np.asarray(d.betas), dtype=torch.float32),
            "cond_dim": int(self.cond_dim),
            "normalizer": d.normalizer.state_dict(),
            "features": [f.detach().cpu().clone() for f in d.features],
            "lengths": self.lengths.clone(),
            "sigma_clip": self.sigma_clip.clone(),
            "sigma": self.sigma.clone(),
            "zstar": [z.clone() for z in self.zstar],
            "generator": {k: v.cpu() for k, v in self.generator.state_dict().items()},
            "critics": {k: v.cpu() for k, v in self.critics.state_dict().items()},
            "progress": {
                "block": int(self.block),
                "iteration": int(self.iteration),
                "done": bool(self.done),
            },
            "optim_g": None if self.opt_g is None else self.opt_g.state_dict(),
            "optim_d": None if self.opt_d is None else self.opt_d.state_dict(),
            "rng": {**global_rng_state(), "trainer": self.rng.get_state()},
        }

    @classmethod
    def from_checkpoint(
        cls,
        path: str | Path,
        out_dir: str | Path | None = None,
        body=None,
        device: str | None = None,
    ) -> Trainer:
        """Rebuild a trainer (data included) from a checkpoint to continue training."""
        state = load_checkpoint(path)
        with reading(path):
            config = config_from_json(state["config"])
            if device is not None:
                config = config.replace(device=device)
            data = TrainingSet.from_state(state)
            out = Path(path).parent if out_dir is None else out_dir
            trainer = cls(data, config, out, body=body)
            trainer.load_state_dict(state)
            trainer.resumed_from = Path(path)
        return trainer

    def load_state_dict(self, state: dict) -> None:
        if state["lengths"].shape != self.lengths.shape or not torch.equal(
            state["lengths"], self.lengths
        ):
            raise CheckpointError(None, "checkpoint pyramid lengths do not match the training data")
        self.zstar = [z.clone() for z in state["zstar"]]
        self.zstar_packed = self.rec_layout.pack(self.zstar, 0)
        self.generator.load_state_dict(state["generator"])
        self.critics.load_state_dict(state["critics"])
        p = state["progress"]
        self.block, self.iteration, self.done = (
            int(p["block"]),
            int(p["iteration"]),
            bool(p["done"]),
        )
        if not self.done and self.block < self.config.num_blocks:
            self.start_block()
            if state["optim_g"] is not None:
                self.opt_g.load_state_dict(state["optim_g"])
                self.opt_d.load_state_dict(state["optim_d"])
        set_global_rng_state(state["rng"])
        self.rng.set_state(state["rng"]["trainer"])

    def save(self, path: Path | None = None) -> Path:
        """Write the checkpoint; refuses (keeping the previous file) when a network holds
        a non-finite weight."""
        for name, net in (("generator", self.generator), ("critics", self.critics)):
            if not all(bool(torch.isfinite(p).all()) for p in net.parameters()):
                raise TrainingDivergedError(
                    f"the {name} has non-finite weights at block {self.block + 1}, iteration "
                    f"{self.iteration}; the checkpoint was not overwritten"
                )
        out = save_checkpoint(path or self.out_dir / "checkpoint.pt", self.state_dict())
        self._saved = True
        return out

    def _check_finite(self, losses: dict[int, dict[str, torch.Tensor]]) -> None:
        """Stop at the first non-finite loss, naming the level and the term."""
        values = [v.detach().reshape(()) for d in losses.values() for v in d.values()]
        if not values or bool(torch.isfinite(torch.stack(values)).all()):
            return
        bad = next(
            (i + 1, k) for i, d in losses.items() for k, v in d.items() if not torch.isfinite(v)
        )
        raise TrainingDivergedError(
            f"loss '{bad[1]}' of level {bad[0]} is not finite at block {self.block + 1}, "
            f"iteration {self.iteration + 1}; training stopped and the last checkpoint in "
            f"{self.out_dir} was kept. Check the clips (frame rate, units, NaN values) or "
            "lower the learning rate"
        )

    # -- the loop ----------------------------------------------------------------------------
    @with_policy
    def fit(
        self,
        progress: bool = True,
        callback: Callable[[Trainer, dict[int, dict[str, float]]], None] | None = None,
        *,
        overwrite: bool = False,
    ) -> TrainResult:
        """Train every remaining block; see :func:`train`. The output folder is locked
        while it runs (``mrlib.io.outputs.RunLock``: a second run there is refused) and
        checked first (:func:`check_run_folder`)."""
        with RunLock(self.out_dir):
            if not self._claimed:
                check_run_folder(self.out_dir, resume=self.resumed_from, overwrite=overwrite)
                if overwrite and self.resumed_from is None:
                    for name in RUN_FILES:  # a fresh start: nothing of the old run remains
                        if os.path.lexists(self.out_dir / name):
                            os.unlink(self.out_dir / name)
                self._claimed = True
            result = self._fit(progress, callback)
            ckpt = self.out_dir / "checkpoint.pt"
            if not self._saved and not _same_file(ckpt, self.resumed_from or ckpt):
                self.save()  # resumed from a finished run into another folder: copy it there
            return result

    def _fit(
        self,
        progress: bool,
        callback: Callable[[Trainer, dict[int, dict[str, float]]], None] | None,
    ) -> TrainResult:
        from tqdm.auto import tqdm

        c = self.config
        self.out_dir.mkdir(parents=True, exist_ok=True)
        log_path = self.out_dir / "losses.csv"
        self._prepare_log(log_path)
        t0 = time.perf_counter()
        last: dict[int, dict[str, float]] = {}
        stop = {"flag": False}
        old_handler = None
        if threading.current_thread() is threading.main_thread():

            def _on_sigint(signum, frame):
                # first Ctrl-C: finish this iteration, save, return; a second one stops at
                # once without saving (the last checkpoint stays the last consistent state)
                if stop["flag"]:
                    raise KeyboardInterrupt
                stop["flag"] = True

            old_handler = signal.signal(signal.SIGINT, _on_sigint)
        interrupted = False
        try:
            with open_for_append(log_path) as fh:  # never through a symbolic link
                writer = csv.DictWriter(fh, CSV_FIELDS)
                while self.block < c.num_blocks and not interrupted:
                    if self.opt_g is None:
                        self.start_block()
                    levels = self.block_levels
                    n_iter = c.block_iterations[self.block]
                    bar = tqdm(
                        total=n_iter,
                        initial=self.iteration,
                        disable=not progress,
                        leave=True,
                        desc=f"block {self.block + 1}/{c.num_blocks} "
                        f"(levels {levels[0] + 1}-{levels[-1] + 1})",
                    )
                    try:
                        while self.iteration < n_iter:
                            stop["in_step"] = True
                            losses = self.step()
                            self._check_finite(losses)
                            self.iteration += 1
                            stop["in_step"] = False
                            if self.iteration % c.log_every == 0 or self.iteration == n_iter:
                                last = {
                                    i + 1: {k: float(v) for k, v in d.items()}
                                    for i, d in losses.items()
                                }
                                t = time.perf_counter() - t0
                                for lv, d in last.items():
                                    writer.writerow(
                                        {
                                            "time_s": f"{t:.2f}",
                                            "block": self.block + 1,
                                            "iteration": self.iteration,
                                            "level": lv,
                                            **{k: f"{d[k]:.6g}" for k in d},
                                        }
                                    )
                                fh.flush()
                                top = last[levels[-1] + 1]
                                bar.set_postfix(
                                    {k: f"{v:.3g}" for k, v in top.items()}, refresh=False
                                )
                            bar.update(1)
                            if callback is not None:
                                callback(self, last)
                            if (
                                c.checkpoint_every
                                and self.iteration % c.checkpoint_every == 0
                                and self.iteration < n_iter
                            ):
                                self.save()
                            if stop["flag"]:
                                raise KeyboardInterrupt
                    except KeyboardInterrupt:
                        if stop.get("in_step"):
                            raise  # forced stop mid-iteration: nothing consistent to save
                        interrupted = True
                    finally:
                        bar.close()
                    if not interrupted:
                        self.block += 1
                        self.iteration = 0
                        self.opt_g = self.opt_d = None
                        self.done = self.block >= c.num_blocks
                    self.save()
        finally:
            if old_handler is not None:
                signal.signal(signal.SIGINT, old_handler)
        return TrainResult(
            self.out_dir / "checkpoint.pt", log_path, interrupted, time.perf_counter() - t0, last
        )

    def _prepare_log(self, path: Path) -> None:
        """Write the CSV's header and, when resuming, the rows of the run resumed from
        (the ``losses.csv`` beside its checkpoint) up to that checkpoint; rows logged after
        it are dropped (they will be logged again). Written atomically, never through a
        symbolic link."""
        keep = []
        source = None if self.resumed_from is None else self.resumed_from.parent / "losses.csv"
        if source is not None and source.is_file() and not source.is_symlink():
            with open(source, newline="") as fh:
                for r in csv.DictReader(fh):
                    try:
                        at = (int(r["block"]) - 1, int(r["iteration"]))
                    except (KeyError, TypeError, ValueError):
                        continue
                    if at <= (self.block, self.iteration):
                        keep.append(r)
        text = StringIO()
        w = csv.DictWriter(text, CSV_FIELDS, extrasaction="ignore")
        w.writeheader()
        w.writerows(keep)
        write_text(path, text.getvalue(), overwrite=True)


def train(
    data: TrainingSet | None,
    config: TrainConfig | None,
    out_dir: str | Path,
    *,
    resume: str | Path | None = None,
    body=None,
    device: str | None = None,
    progress: bool = True,
    callback: Callable[[Trainer, dict[int, dict[str, float]]], None] | None = None,
    overwrite: bool = False,
) -> TrainResult:
    """Train a model, or continue one.

    Args:
        data: the clips (ignored when resuming: the checkpoint holds them).
        config: a ``TrainConfig`` (e.g. ``mrlib.model.config.tutorial()``); ignored when resuming.
        out_dir: folder for ``checkpoint.pt`` (+ ``checkpoint.pt.json``) and ``losses.csv``.
        resume: a checkpoint to continue from, exactly where it stopped.
        body: body model for the contact and smoothness losses (default ``load_body_model()``).
        device: when resuming, continue on this device instead of the checkpoint's
            (the config's device otherwise).
        progress: show a tqdm bar per block with the latest losses.
        callback: called after every iteration with the trainer and the last logged losses
            ``{level: {name: value}}``; raising ``KeyboardInterrupt`` in it stops training
            like Ctrl-C (a checkpoint is written first).
        overwrite: replace a run already in ``out_dir`` (another run's files are refused
            otherwise, :func:`check_run_folder`; resuming in the checkpoint's own folder
            needs no flag).
    Returns:
        a :class:`TrainResult`; ``interrupted`` tells whether it stopped early.

    Raises:
        RunExistsError: ``out_dir`` holds another run (checked before any work).
        mrlib.io.outputs.RunLockedError: another process is training into ``out_dir``.
    """
    check_run_folder(out_dir, resume=resume, overwrite=overwrite)
    if resume is not None:
        trainer = Trainer.from_checkpoint(resume, out_dir=out_dir, body=body, device=device)
    else:
        if data is None or config is None:
            raise CheckpointError(None, "train() needs data and config unless resume is given")
        trainer = Trainer(data, config, out_dir, body=body)
    return trainer.fit(progress=progress, callback=callback, overwrite=overwrite)


@dataclass(frozen=True)
class TrainRecord:
    """How a model of :func:`train_or_reuse` came about."""

    checkpoint: Path
    wall_time_s: float  # training time of the run that wrote the checkpoint
    reused: bool  # True: an earlier, finished run with the same config and clips


def train_or_reuse(
    data: TrainingSet,
    config: TrainConfig,
    out_dir: str | Path,
    *,
    body=None,
    progress: bool = True,
):
    """Train with :func:`train` unless ``out_dir`` already holds a finished run with the
    same config (field for field, as saved next to the checkpoint) and the same clips;
    then load it. Notebooks and benchmarks use this so that a long run is not repeated
    on every execution. A run there that cannot be reused is not overwritten: its files
    move to ``out_dir/previous-<time>/``, with a warning saying why.

    Returns:
        ``(model, record)``: the ``GenerativeModel`` and a :class:`TrainRecord`; for a
        reused run the wall time is the last ``time_s`` of its ``losses.csv`` (the time
        of its last logged iteration, without the final checkpoint write).
    """
    out = Path(out_dir)
    ckpt, log = out / "checkpoint.pt", out / "losses.csv"
    meta = ckpt.with_suffix(".pt.json")
    why = None
    if ckpt.exists() and meta.exists() and log.exists():
        # Compare the JSON itself: a field missing from it means an older mrlib wrote the
        # run, whose defaults may differ from today's.
        saved, wanted = json.loads(meta.read_text()), json.loads(config_to_json(config))
        if saved == wanted:
            model = load_model(ckpt)
            if model.trained_levels == model.num_levels and model.clip_names == list(data.names):
                with open(log, newline="") as fh:
                    rows = list(csv.DictReader(fh))
                wall = float(rows[-1]["time_s"]) if rows else float("nan")
                return model, TrainRecord(ckpt, wall, True)
            why = "unfinished" if model.trained_levels < model.num_levels else "other clips"
        else:
            keys = sorted(k for k in saved.keys() | wanted.keys() if saved.get(k) != wanted.get(k))
            why = "another config: " + ", ".join(
                f"{k} {'missing' if k not in saved else 'differs'}" for k in keys
            )
    elif ckpt.exists():
        why = "no config or loss log beside it"
    if why is not None:
        stamp = time.strftime("previous-%Y%m%d-%H%M%S")
        keep, k = out / stamp, 1
        while keep.exists():
            keep, k = out / f"{stamp}-{k}", k + 1
        keep.mkdir()
        for f in (ckpt, meta, log):
            if f.exists():
                f.rename(keep / f.name)
        warnings.warn(
            f"{out} held a run that is not reused ({why}); moved it to {keep}", stacklevel=2
        )
    # what was worth keeping moved aside above; a loss log without its checkpoint is not
    res = train(data, config, out, body=body, progress=progress, overwrite=True)
    return load_model(res.checkpoint), TrainRecord(res.checkpoint, res.wall_time_s, False)


def model_cache_key(data: TrainingSet, config: TrainConfig) -> str:
    """A key naming one trained model: the SHA-256 of the config (as saved with the
    checkpoint), the clips' names, labels and frame rate, and their feature values.
    Two notebooks that train the same config on the same clips get the same key."""
    h = hashlib.sha256(config_to_json(config).encode())
    h.update(
        json.dumps([data.names, data.labels, list(map(int, data.clip_labels)), data.fps]).encode()
    )
    for f in data.features:
        h.update(np.ascontiguousarray(f.detach().cpu().numpy(), dtype=np.float32).tobytes())
    return h.hexdigest()


def train_cached(
    data: TrainingSet,
    config: TrainConfig,
    *,
    body=None,
    progress: bool = True,
    cache_dir: str | Path | None = None,
):
    """:func:`train_or_reuse` in a folder of mrlib's model cache named by
    :func:`model_cache_key`, so a model trained once (by one notebook, say) is loaded by
    every later call with the same config and clips instead of trained again.

    The cache is ``cache_dir``, else ``$MRLIB_CACHE_DIR/models``, else the user's cache
    folder (``~/.cache/mrlib/models`` on Linux); delete a folder there to retrain.

    Returns:
        ``(model, record)`` as :func:`train_or_reuse`.
    """
    root = Path(cache_dir) if cache_dir is not None else cache_root() / "models"
    out = root / model_cache_key(data, config)[:20]
    out.mkdir(parents=True, exist_ok=True)
    return train_or_reuse(data, config, out, body=body, progress=progress)


def _train_cached_in_worker(args) -> None:
    """One :func:`train_cached` in a worker process, on one torch thread."""
    data, config, cache_dir = args
    torch.set_num_threads(1)
    train_cached(data, config, progress=False, cache_dir=cache_dir)


def train_cached_many(
    sets: list[TrainingSet],
    config: TrainConfig,
    *,
    workers: int | None = None,
    body=None,
    cache_dir: str | Path | None = None,
) -> list:
    """:func:`train_cached` for several training sets (GANimator-mode: one model per
    clip), training the ones not in the cache side by side in ``workers`` processes of
    one torch thread each (default: one per usable CPU, ``mrlib.threads.usable_cpus``).
    Where the CPUs run two processes at full speed, two models train in the time of one;
    on this project's 2-core x86-64 VM (two vCPUs) notebook 05's four ``demo`` models took
    277 s side by side against 284 s one after another. On a busy machine pass
    ``workers=1``.

    Returns:
        ``[(model, record), ...]`` in the order of ``sets``, as :func:`train_cached`
        (``record.reused`` is false for the models trained by this call).
    """
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    from mrlib.threads import usable_cpus

    root = Path(cache_dir) if cache_dir is not None else cache_root() / "models"
    todo = [
        d for d in sets if not (root / model_cache_key(d, config)[:20] / "checkpoint.pt").exists()
    ]
    n = min(len(todo), workers if workers is not None else usable_cpus())
    if n > 1:
        ctx = multiprocessing.get_context("spawn")  # no forked torch thread pools
        with ProcessPoolExecutor(n, mp_context=ctx) as pool:
            list(pool.map(_train_cached_in_worker, [(d, config, root) for d in todo]))
    out = [train_cached(d, config, body=body, progress=False, cache_dir=root) for d in sets]
    trained = {id(d) for d in todo}
    return [
        (m, dataclasses.replace(r, reused=False) if id(d) in trained else r)
        for d, (m, r) in zip(sets, out, strict=True)
    ]
