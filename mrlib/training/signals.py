"""The control signal of training: where labels become the conditions the networks see.

The networks take any control signal ``(B, T_i, D)`` per level. A *signal* is the object
the trainer's steps ask for conditions; :class:`LabelSignal` is the one of label training
(one-hot labels, style mixing, paper Sec. 4.3), ``mrlib.speech.train.SpeechSignal`` the
one of speech (paper Sec. 6). What a new control signal must provide (subclass
:class:`LabelSignal`, override what differs, and return it from the trainer's
``control_signal``):

* ``dim``: the condition size D (the networks are built for it);
* :meth:`~LabelSignal.rec_conditions`: the conditions of the reconstructions, each clip
  with its own;
* :meth:`~LabelSignal.draw_random`: conditions and noises of a batch of random
  generations (a :class:`RandomDraw`);
* for conditional critics: ``real_conds`` (each real clip's own conditions) and
  :meth:`~LabelSignal.critic_keep` (which fakes the critic sees with their condition);
  with ``LossWeights.mismatch``: ``mismatch`` and
  :meth:`~LabelSignal.mismatched_real_conditions`.

Every random draw comes from the trainer's generator ``rng``, in the order the steps ask.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
import torch.nn.functional as F

from mrlib.model.config import TrainConfig
from mrlib.model.pyramid import PackedLevels
from mrlib.sampling.conditions import crossover_table
from mrlib.training.build import Batches
from mrlib.training.data import TrainingSet

__all__ = ["RandomDraw", "LabelSignal"]


@dataclass
class RandomDraw:
    """The control signals and noises of a batch of random generations, and how they were
    drawn (what :meth:`LabelSignal.draw_random` returns).

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


class LabelSignal:
    """Labels as the control signal: a one-hot label per sample and level.

    Attributes:
        dim: K, the number of labels.
        sigma: ``(K, L)`` noise amplitudes per label (mean over its clips).
        real_conds: conditional critics: per level ``(1, S_i, K)``, every real clip of the
            random layout with its own label; None for unconditional critics.
        mismatch: whether the critics' mismatch term is computed (``LossWeights.mismatch``
            set, and at least two labels: with one there is no wrong label to show).
        detail_rms: ``LossWeights.detail`` only: per level ``(K, C)``, the per-channel RMS
            of the detail the level adds (mean over the label's clips), the targets of
            the detail-statistics term.
    """

    def __init__(self, data: TrainingSet, b: Batches, config: TrainConfig, rng: torch.Generator):
        self.b, self.config, self.rng = b, config, rng
        L = config.model.num_levels
        lab = torch.tensor(data.clip_labels)
        self.dim = data.num_labels
        self.clip_labels = lab
        self.sigma = torch.stack([b.sigma_clip[lab == k].mean(0) for k in range(self.dim)])
        self.rec_labels = lab[:, None].expand(b.num_clips, L)  # (N, L)
        B = len(b.rand_clip)
        self.real_conds = (
            self.label_conditions(lab[b.rand_clip][:, None].expand(B, L), b.rand_layout, L)
            if config.model.critic_condition
            else None
        )
        self.mismatch = bool(config.loss.mismatch) and self.dim >= 2
        self.detail_rms: list[torch.Tensor] = []
        if config.loss.detail:
            lay = b.rec_layout
            rms = [
                lay.per_sample_rms(lay.level_band(lv.real, i), i) for i, lv in enumerate(b.levels)
            ]
            self.detail_rms = [
                torch.stack([r[lab == k].mean(0) for k in range(self.dim)]) for r in rms
            ]

    def label_conditions(
        self, label_table: torch.Tensor, layout: PackedLevels, stop: int
    ) -> list[torch.Tensor]:
        """One-hot label conditions ``(1, S_i, K)`` of levels ``0..stop-1`` from a ``(B, L)``
        table of label indices (constant over each sample's frames)."""
        onehot = F.one_hot(label_table, self.dim).float()  # (B, L, K)
        return [layout.per_sample(onehot[:, i], i)[None] for i in range(stop)]

    def rec_conditions(self, stop: int) -> list[torch.Tensor]:
        """Conditions of the reconstructions: every clip's own label at every level."""
        return self.label_conditions(self.rec_labels, self.b.rec_layout, stop)

    def draw_random(self, layout: PackedLevels, stop: int) -> RandomDraw:
        """Conditions ``[(1, S_i, K)]`` and noises ``[(1, 1, S_i)]`` of levels ``0..stop-1``
        for the random generations of a layout whose sample b follows clip ``b mod N``.

        Sample b's coarse label is its clip's. With probability ``mix_prob`` a second label
        (uniform) takes over from a random crossover level on (style-mixing
        regularisation, paper Sec. 4.3); reconstructions never mix. Noise
        ``z_i ~ N(0, sigma_i)`` with the sigma of the label in use at level i, shared by
        all channels."""
        L, K, batch = self.config.model.num_levels, self.dim, layout.batch_size
        a = self.clip_labels[torch.arange(batch) % self.b.num_clips]
        mix = torch.rand(batch, generator=self.rng) < self.config.mix_prob
        b = torch.randint(K, (batch,), generator=self.rng)
        cross = torch.randint(1, max(L, 2), (batch,), generator=self.rng)  # levels >= cross use b
        table, from_b = crossover_table(a, torch.where(mix, b, a), cross, L)
        mixed = mix[:, None] & from_b  # (B, L) levels driven by b
        noises = []
        for i in range(stop):
            z = torch.randn(1, 1, layout.sizes[i], generator=self.rng).to(self.b.device)
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
        K, rand_clip = self.dim, self.b.rand_clip
        own = self.clip_labels[rand_clip]
        wrong = (own + torch.randint(1, K, (len(rand_clip),), generator=self.rng)) % K
        onehot = F.one_hot(wrong, K).float()
        return self.b.rand_layout.per_sample(onehot, level)[None].to(self.b.device)

    def detail_targets(self, draw: RandomDraw, level: int) -> torch.Tensor:
        """``(B, C)`` targets of the detail-statistics term: the mean RMS of the band
        ``level`` adds, over the training clips of the label driving each sample there."""
        return self.detail_rms[level].to(self.b.device)[draw.labels[:, level]]
