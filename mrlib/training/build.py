"""What a training run builds before its first step, and the hooks that turn its control
signal into conditions.

:class:`TrainerBase` holds one run's fixed parts: the data pyramid of every clip and its
noise amplitudes, the reconstruction noise z*_1 (paper Sec. 3.4), the generator and the
critics, the packed batch layouts (``mrlib.model.pyramid.PackedLevels``: clips of
different lengths end to end; random generation b follows the pyramid of clip b,
so reals and fakes line up sample by sample) and each block's optimisers.
Its condition hooks (``rec_conditions``, ``draw_random``, ``critic_keep``, ...) are the
only place where labels become conditions; ``mrlib.speech.SpeechTrainer`` overrides them.

:class:`mrlib.training.trainer.Trainer` adds the steps (``mrlib.training.steps``), the
checkpoints and the loop (``mrlib.training.loop``).
"""

from __future__ import annotations

import random
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

from mrlib.errors import ClipTooShortError
from mrlib.model.config import TrainConfig
from mrlib.model.losses import body_kinematics
from mrlib.model.networks import MultiResGenerator, build_critics, build_generator
from mrlib.model.pyramid import PackedLevels, build_pyramid, noise_amplitudes, pyramid_lengths
from mrlib.representation.features import FeatureNormalizer
from mrlib.training.data import TrainingSet

__all__ = ["TrainerBase", "RandomDraw", "make_adam"]


@dataclass
class RandomDraw:
    """The control signals and noises of a batch of random generations, and how they were
    drawn (what :meth:`TrainerBase.draw_random` returns).

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


class TrainerBase:
    """The fixed parts of one training run (see the module's docstring): construction,
    condition hooks, and the start of each block. Creating one seeds torch's, numpy's and
    Python's global generators with ``config.seed`` (network initialisation); every random
    draw of training then comes from the trainer's own generator ``rng``."""

    def __init__(self, data: TrainingSet, config: TrainConfig, out_dir: str | Path, body=None):
        self.data = data
        self.config = config
        self.out_dir = Path(out_dir)
        self.resumed_from: Path | None = None  # the checkpoint this trainer continues
        self._claimed = False  # out_dir checked (check_run_folder) by an earlier fit
        self._saved = False
        self.threads: int | None = None  # the run's torch thread count, fixed by fit()
        self.device = torch.device(config.device)
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
        pyramids = self._build_levels()
        self._build_networks()
        self._build_layouts(pyramids)

    def _build_levels(self) -> list[list[torch.Tensor]]:
        """Every clip's pyramid (returned), its noise amplitudes, and its fixed
        reconstruction noise z*_1."""
        data, mc = self.data, self.config.model
        L, pad = mc.num_levels, (mc.kernel_size - 1) // 2
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
        # Fixed reconstruction noise z*_1 of every clip (zero above level 1): a draw of the
        # random noise itself, N(0, sigma_1) shared by all channels (paper Sec. 3.2-3.4).
        self.zstar = []
        for k in range(data.num_clips):
            z = torch.randn(1, int(self.lengths[k, 0]), generator=self.rng)
            self.zstar.append(z * self.sigma_clip[k, 0])
        return pyramids

    def _build_networks(self) -> None:
        """The generator and the critics (weights from the global generator, seeded)."""
        mc = self.config.model
        self.cond_dim = self.data.num_labels
        self.generator: MultiResGenerator = build_generator(mc, self.cond_dim).to(self.device)
        critic_cond = self.cond_dim if mc.critic_condition else 0
        self.critics = build_critics(mc, critic_cond).to(self.device)
        labels_mismatch = (
            type(self).mismatched_real_conditions is TrainerBase.mismatched_real_conditions
        )
        # the mismatch term shows real clips under a wrong label: with one label there is
        # none, and the term is left out (the config keeps its weight)
        self.use_mismatch = bool(self.config.loss.mismatch) and (
            not labels_mismatch or self.data.num_labels >= 2
        )
        self.block = 0
        self.iteration = 0
        self.done = False
        self.opt_g: torch.optim.Adam | None = None
        self.opt_d: torch.optim.Adam | None = None

    def _build_layouts(self, pyramids: list[list[torch.Tensor]]) -> None:
        """The fixed batch layouts (packed: samples end to end, see mrlib.model.pyramid),
        the real clips in them, and the frame weights of every loss."""
        data, config, mc = self.data, self.config, self.config.model
        L, pad = mc.num_levels, (mc.kernel_size - 1) // 2
        lab = torch.tensor(data.clip_labels)
        N = data.num_clips
        self.N, self.B = N, N  # one random generation per clip and step
        self.rand_clip = torch.arange(self.B)  # clip whose pyramid random sample b follows
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
        self.zstar_packed = self.rec_layout.pack(self.zstar, 0)  # (1, 1, S_1)
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

    # -- body model ------------------------------------------------------------------------
    def kinematics(self, x: torch.Tensor, fps: torch.Tensor):
        """``losses.body_kinematics`` of ``x (1, C, S)`` with this run's body and shape:
        joints, foot vertices, contacts."""
        return body_kinematics(x, self.data_normalizer, fps, self.body, self.betas)

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

    def rec_noises(self, stop: int) -> list[torch.Tensor]:
        """z*_1 at level 1, zero above (paper Sec. 3.4)."""
        return [self.zstar_packed] + [
            self.zstar_packed.new_zeros(1, 1, s) for s in self.rec_layout.sizes[1:stop]
        ]

    def rec_input(self, lo: int) -> torch.Tensor | None:
        """Frozen levels' reconstruction of every clip (output of level lo-1), cached."""
        if lo == 0:
            return None
        if self._rec_cache is None or self._rec_cache[0] != lo:
            with torch.no_grad():
                conds = self.rec_conditions(lo)
                x = self.generator.run(self.rec_layout, self.rec_noises(lo), conds, 0, lo)
            self._rec_cache = (lo, x)
        return self._rec_cache[1]
