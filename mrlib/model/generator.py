"""The generator of the paper (Sec. 3.2-3.3, Eq. 2-10): FiLM condition encoders
``S_i``, one residual level ``G_i``, and the pyramid of ``L`` levels run coarse to fine.

Read top to bottom: FiLM (Eq. 8-10), one level (Eq. 6-7; level 1 is Eq. 2-3), the
whole generator (Eq. 4-5). Equation numbers are those of the paper's LaTeX.

Shapes: B batch, C = 153 feature channels, T frames, D the dimension of a condition
(number of labels for one-hot labels, feature size for speech), E the FiLM embedding
size. Sequences are ``(B, C, T)``; conditions are ``(B, T, D)``.
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn as nn

from mrlib.model.config import ModelConfig
from mrlib.model.pyramid import PackedLevels, resample_linear, resample_periodic
from mrlib.model.skeleton_conv import ConvStack, hidden_channel_joint
from mrlib.representation.features import NUM_FEATURES, channel_joint

__all__ = ["FiLM", "LevelGenerator", "MultiResGenerator", "build_generator"]


class FiLM(nn.Module):
    """Condition encoder S_i: ``y = W s`` (a fully connected embedding of the control
    signal, ``E`` = 8 in the paper), ``gamma = 1 + f(y)``, ``delta = h(y)`` per channel
    and per frame, ``FiLM(u) = gamma * u + delta`` (Perez et al. 2018).

    ``f`` and ``h`` start near zero so an untrained encoder is close to the identity.
    ``channel_mask (C,)`` restricts which channels are modulated (others pass through).
    """

    def __init__(
        self,
        cond_dim: int,
        channels: int,
        embed_dim: int = 8,
        channel_mask: torch.Tensor | None = None,
    ):
        super().__init__()
        self.embed = nn.Linear(cond_dim, embed_dim)
        self.to_gamma = nn.Linear(embed_dim, channels)
        self.to_delta = nn.Linear(embed_dim, channels)
        for lin in (self.to_gamma, self.to_delta):
            nn.init.normal_(lin.weight, std=0.02)
            nn.init.zeros_(lin.bias)
        if channel_mask is None:
            channel_mask = torch.ones(channels)
        self.register_buffer(
            "channel_mask", channel_mask.float()[:, None], persistent=True
        )  # (C, 1)

    def params(self, cond: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``cond (B, T, D)`` -> ``gamma, delta (B, C, T)`` (``T = 1`` for a condition
        constant over time, broadcast over the frames)."""
        y = self.embed(cond)  # (B, T, E)
        gamma = 1 + self.to_gamma(y).transpose(1, 2) * self.channel_mask
        delta = self.to_delta(y).transpose(1, 2) * self.channel_mask
        return gamma, delta

    def forward(self, u: torch.Tensor, cond: torch.Tensor) -> torch.Tensor:
        """``u (B, C, T)``, ``cond (B, T, D)`` -> ``(B, C, T)``."""
        gamma, delta = self.params(cond)
        return gamma * u + delta


class LevelGenerator(nn.Module):
    """One level: ``G_i(x, z, s) = g_i(FiLM_i(up(x) + z, s)) + up(x)`` (paper Eq. 6-7);
    the caller passes ``x_up = up(x)`` (zeros at level 1, giving ``G_1 = g_1(S_1(z_1, s))``)."""

    def __init__(self, config: ModelConfig, cond_dim: int):
        super().__init__()
        io = channel_joint()
        joints = [io] + [hidden_channel_joint(w) for w in config.gen_hidden] + [io]
        self.body = ConvStack(
            joints, config.kernel_size, config.neighbour_radius, config.leaky_slope
        )
        mask = None
        if config.film_joints is not None:
            mask = torch.from_numpy(np.isin(io, np.asarray(config.film_joints)))
        self.film = FiLM(cond_dim, NUM_FEATURES, config.film_dim, mask)

    def modulate(self, u: torch.Tensor, cond) -> torch.Tensor:
        """``FiLM(u, s)``; ``cond`` is ``(B, T|1, D)``, or a list of ``(mask (C,), cond)``
        pairs whose masks partition the channels: each channel group is modulated by its
        own condition (body-part composition, ``mrlib.sampling.constraints``)."""
        if isinstance(cond, torch.Tensor):
            return self.film(u, cond)
        out = torch.zeros_like(u)
        for mask, c in cond:
            gamma, delta = self.film.params(c)
            out = out + mask[:, None] * (gamma * u + delta)
        return out

    def forward(
        self,
        x_up: torch.Tensor,
        z: torch.Tensor,
        cond,
        pad_index: torch.Tensor | None = None,
        circular: bool = False,
    ) -> torch.Tensor:
        """``x_up (B, C, T)``, ``z (B, 1|C, T)``, ``cond (B, T|1, D)`` (or per channel
        group, see :meth:`modulate`) -> ``(B, C, T)``; without ``pad_index`` each row of
        the batch is one sample (``circular``: periodic, see ``SkeletonConv1d``)."""
        return self.body(self.modulate(x_up + z, cond), pad_index, circular) + x_up


class MultiResGenerator(nn.Module):
    """``L`` level generators run coarse to fine; ``levels[i]`` is G_{i+1}."""

    def __init__(self, config: ModelConfig, cond_dim: int):
        super().__init__()
        self.config = config
        self.cond_dim = cond_dim
        self.levels = nn.ModuleList(
            LevelGenerator(config, cond_dim) for _ in range(config.num_levels)
        )
        self.pad = (config.kernel_size - 1) // 2

    def run(
        self,
        layout: PackedLevels,
        noises: list[torch.Tensor],
        conds: list[torch.Tensor],
        start: int = 0,
        stop: int | None = None,
        x: torch.Tensor | None = None,
        keep: bool = False,
    ) -> torch.Tensor | list[torch.Tensor]:
        """Levels ``start .. stop-1`` (0-based), coarse to fine.

        Args:
            layout: lengths of every sample at every level.
            noises: per level ``(B, 1|C, T_i)``, indexed by absolute level.
            conds: per level ``(B, T_i, D)``, indexed by absolute level.
            x: output of level ``start - 1`` ``(B, C, T_{start-1})``; None at level 0.
            keep: return every level's output, not only the last.
        Returns:
            ``(B, C, T_{stop-1})`` or the list of outputs of levels ``start..stop-1``.
        """
        stop = len(self.levels) if stop is None else stop
        outs = []
        for i in range(start, stop):
            if i == 0:
                B = noises[0].shape[0]
                x_up = noises[0].new_zeros(B, NUM_FEATURES, layout.sizes[0])
            else:
                x_up = layout.upsample(x, i)
            x = self.levels[i](x_up, noises[i], conds[i], layout.pad_index(i, self.pad))
            outs.append(x)
        return outs if keep else x

    def forward(
        self,
        layout: PackedLevels,
        noises: list[torch.Tensor],
        conds: list[torch.Tensor],
        keep: bool = False,
    ):
        """All levels; see :meth:`run`."""
        return self.run(layout, noises, conds, keep=keep)

    def run_batch(
        self,
        noises: list[torch.Tensor],
        conds: list,
        keep: bool = False,
        circular: bool = False,
    ) -> torch.Tensor | list[torch.Tensor]:
        """All levels for a batch of samples of equal length, one per row: the sampling
        path. Reflect padding is ``F.pad`` and upsampling ``F.interpolate`` (the linear
        interpolation :meth:`run` computes with gathers), so a sample matches the packed
        run to float rounding (~1e-6); a condition constant over time is passed as
        ``(B, 1, D)`` and its FiLM parameters are computed once per sample.

        Args:
            noises: per level ``(B, 1|C, T_i)``.
            conds: per level ``(B, T_i|1, D)``, or per level a list of ``(mask (C,),
                cond)`` pairs (one condition per channel group, see
                :meth:`LevelGenerator.modulate`).
            circular: treat every level as periodic (wrap-around padding and
                upsampling): the output loops seamlessly.
        Returns:
            ``(B, C, T_L)`` or the list of every level's output.
        """
        outs, x = [], None
        for i, level in enumerate(self.levels):
            z = noises[i]
            if i == 0:
                x_up = z.new_zeros(z.shape[0], NUM_FEATURES, z.shape[-1])
            elif circular:
                x_up = resample_periodic(x, z.shape[-1])
            else:
                x_up = resample_linear(x, z.shape[-1])
            x = level(x_up, z, conds[i], None, circular)
            outs.append(x)
        return outs if keep else x


def build_generator(config: ModelConfig, cond_dim: int) -> MultiResGenerator:
    return MultiResGenerator(config, cond_dim)
