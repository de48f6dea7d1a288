"""Networks: skeleton-aware convolution, FiLM condition encoders, the per-level residual
generators and patch critics, and the coarse-to-fine multi-resolution generator.

Read top to bottom: masks, the skeleton conv, conv stacks, FiLM, one generator level,
one critic, the whole generator.

Shapes: B batch, C = 153 feature channels (``mrlib.representation.features``), T frames, D the
dimension of a condition (number of labels for one-hot labels, feature size for
speech), E the FiLM embedding size. Sequences are ``(B, C, T)``; conditions are
``(B, T, D)``. A batch of clips of different lengths is packed end to end into one
sequence (B = 1, see :class:`mrlib.model.pyramid.PackedLevels`); the layout's reflect-pad
indices keep every convolution inside its own clip.
"""

from __future__ import annotations

import math

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F

from mrlib.model.config import ModelConfig
from mrlib.model.pyramid import PackedLevels, resample_linear, resample_periodic
from mrlib.representation.features import NUM_FEATURES, channel_joint
from mrlib.representation.skeleton import NUM_JOINTS, PARENTS, graph_distances

__all__ = [
    "hidden_channel_joint",
    "skeleton_mask",
    "SkeletonConv1d",
    "ConvStack",
    "FiLM",
    "LevelGenerator",
    "PatchCritic",
    "MultiResGenerator",
    "build_generator",
    "build_critics",
]


# -- topology as data ---------------------------------------------------------------------
def hidden_channel_joint(width: int, num_joints: int = NUM_JOINTS) -> np.ndarray:
    """Owner joint of each channel of a hidden layer of about ``width`` channels: the
    width is rounded up to ``k * num_joints`` (as GANimator does) and channels are grouped
    joint-major, ``k`` per joint. Returns ``(k * num_joints,)`` int."""
    per_joint = max(1, math.ceil(width / num_joints))
    return np.repeat(np.arange(num_joints), per_joint)


def skeleton_mask(
    out_joint: np.ndarray, in_joint: np.ndarray, radius: int = 2, parents=PARENTS
) -> torch.Tensor:
    """``(C_out, C_in)`` bool: output channel o may read input channel i when their owner
    joints are at most ``radius`` hops apart on the kinematic tree (Aberman et al. 2020)."""
    near = graph_distances(parents) <= radius  # (J, J)
    return torch.from_numpy(near[np.ix_(out_joint, in_joint)])


# -- layers -------------------------------------------------------------------------------
class SkeletonConv1d(nn.Module):
    """Temporal convolution whose weight is masked by the skeleton (Aberman et al. 2020).

    ``weight (C_out, C_in, K)`` is zero outside the fixed ``mask (C_out, C_in, 1)`` (a
    buffer, never trained), so an output joint only mixes channels of its neighbourhood.
    ``mask=None`` gives an ordinary dense convolution. Padding is reflect, per sample
    (``PackedLevels.pad_index``).

    The masked entries are zeroed at initialisation and on loading a state dict, and
    their gradient is zeroed once per backward (a post-accumulate-grad hook), so they
    stay zero under Adam and the forward convolves with the weight as it is. Masking
    the weight at every call instead (``weight * mask``, the same numbers) cost a copy
    of it per call, and made training the ``demo`` preset on one CPU thread 9 % slower
    (``python bench/busy_machine.py --extras``).
    """

    def __init__(
        self, in_channels: int, out_channels: int, kernel_size: int, mask: torch.Tensor | None
    ):
        super().__init__()
        self.kernel_size = kernel_size
        self.pad = (kernel_size - 1) // 2
        self.weight = nn.Parameter(torch.empty(out_channels, in_channels, kernel_size))
        self.bias = nn.Parameter(torch.empty(out_channels))
        if mask is None:
            mask = torch.ones(out_channels, in_channels, dtype=torch.bool)
        self.register_buffer("mask", mask.to(torch.float32)[..., None], persistent=True)
        self.reset_parameters()
        if not bool(mask.all()):
            self.weight.register_post_accumulate_grad_hook(self._mask_grad)

    def _mask_grad(self, weight: torch.Tensor) -> None:
        weight.grad.mul_(self.mask)

    def _load_from_state_dict(self, state_dict, prefix, *args, **kwargs):
        super()._load_from_state_dict(state_dict, prefix, *args, **kwargs)
        with torch.no_grad():
            self.weight.mul_(self.mask)  # zero already in any checkpoint mrlib writes

    def reset_parameters(self) -> None:
        # PyTorch's default conv init (kaiming_uniform with a=sqrt(5)) has bound 1/sqrt(fan_in);
        # here fan_in counts only the unmasked inputs of each output channel.
        fan_in = self.mask[..., 0].sum(1).clamp_min(1) * self.kernel_size  # (C_out,)
        bound = 1 / fan_in.sqrt()
        with torch.no_grad():
            self.weight.uniform_(-1, 1).mul_(bound[:, None, None]).mul_(self.mask)
            self.bias.uniform_(-1, 1).mul_(bound)

    def forward(
        self, x: torch.Tensor, pad_index: torch.Tensor | None = None, circular: bool = False
    ) -> torch.Tensor:
        """``x (B, C_in, T)``, ``pad_index (B, 1, T + 2p)`` -> ``(B, C_out, T)``. Without
        ``pad_index`` every row of the batch is one sample, reflect-padded at its ends, or
        wrapped around with ``circular`` (a periodic signal: a seamless loop)."""
        if pad_index is None:
            mode = "circular" if circular else "reflect"
            xp = F.pad(x, (self.pad, self.pad), mode=mode)
        else:
            B, C, _ = x.shape
            xp = x.gather(2, pad_index.expand(B, C, -1))  # (B, C_in, T + 2p), reflect-padded
        return F.conv1d(xp, self.weight, self.bias)  # masked entries are zero (see above)

    def extra_repr(self) -> str:
        co, ci, k = self.weight.shape
        density = float(self.mask.mean())
        return f"{ci}, {co}, kernel_size={k}, mask_density={density:.2f}"


class ConvStack(nn.Module):
    """Skeleton convs with LeakyReLU between them; channel owners ``joints[0..n]``.

    ``joints[k]`` is the owner-joint array of the k-th activation (input first, output
    last). When ``dense_last`` the last layer is an ordinary conv (a critic's score has
    no joint).
    """

    def __init__(
        self,
        joints: list[np.ndarray],
        kernel_size: int,
        radius: int,
        slope: float,
        dense_last: bool = False,
    ):
        super().__init__()
        self.layers = nn.ModuleList()
        for k in range(len(joints) - 1):
            last = k == len(joints) - 2
            mask = (
                None if (last and dense_last) else skeleton_mask(joints[k + 1], joints[k], radius)
            )
            self.layers.append(
                SkeletonConv1d(len(joints[k]), len(joints[k + 1]), kernel_size, mask)
            )
        self.slope = slope
        self.pad = (kernel_size - 1) // 2

    def forward(
        self, x: torch.Tensor, pad_index: torch.Tensor | None = None, circular: bool = False
    ) -> torch.Tensor:
        for k, layer in enumerate(self.layers):
            x = layer(x, pad_index, circular)
            if k < len(self.layers) - 1:
                x = F.leaky_relu(x, self.slope)
        return x


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
    """One level: ``G_i(x, z, s) = g_i(FiLM_i(up(x) + z, s)) + up(x)`` (paper Eq. 5-6);
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


class PatchCritic(nn.Module):
    """WGAN critic D_i: a small fully convolutional skeleton-aware net (receptive field
    ``n_layers * (K - 1) + 1`` frames) that scores every temporal patch; no sigmoid.
    The score of a sequence is the mean of its patch scores (``mrlib.model.losses``).

    With ``cond_dim > 0`` the critic is conditional, by projection (Miyato & Koyama,
    ICLR 2018): ``D(x, c)_t = w * h(x)_t + <P c_t, h(x)_t>``, ``h`` the last hidden
    activation ``(C_h, T)``, ``P`` a linear map of the per-frame condition. The paper's
    critics are unconditional (``cond_dim = 0``); see ``ModelConfig.critic_condition``.

    With ``ModelConfig.critic_band == "detail"`` the projection takes ``h`` from a branch
    of its own (the critic's layers less its last hidden one) fed with the detail band
    ``x - box_K(x)`` (a K-frame moving average, reflect-padded per sample), so the label
    is judged on detail while ``w * h(x)`` still judges realism of the whole signal. A
    box of 5 frames keeps everything above about a tenth of the frame rate, where a
    walk's gait still lies.
    """

    def __init__(self, config: ModelConfig, cond_dim: int = 0):
        super().__init__()
        joints = [channel_joint()]
        joints += [hidden_channel_joint(w) for w in config.disc_hidden]
        joints.append(np.zeros(1, np.int64))
        self.body = ConvStack(
            joints, config.kernel_size, config.neighbour_radius, config.leaky_slope, dense_last=True
        )
        self.cond_dim = int(cond_dim)
        self.detail = None
        self.band = config.critic_band if self.cond_dim > 0 else "full"
        features = joints[-2]  # channels of the h that the projection reads
        if self.band == "detail":
            # the critic's layers less its last hidden one: cheaper, and the detail band
            # needs a short temporal reach only
            d_joints = joints[: max(2, len(joints) - 2)]
            self.detail = ConvStack(
                d_joints, config.kernel_size, config.neighbour_radius, config.leaky_slope
            )
            features = d_joints[-1]
        self.project = (
            nn.Linear(self.cond_dim, len(features), bias=False) if self.cond_dim > 0 else None
        )

    @property
    def receptive_field(self) -> int:
        return len(self.body.layers) * (self.body.pad * 2) + 1

    def forward(
        self,
        x: torch.Tensor,
        pad_index: torch.Tensor,
        cond: torch.Tensor | None = None,
    ) -> torch.Tensor:
        """``x (B, C, T)``, ``cond (B, T, D)`` (conditional critics only) -> per-frame
        patch scores ``(B, T)``."""
        if self.project is None:
            if cond is not None:
                raise ValueError("this critic is unconditional; do not pass a condition")
            return self.body(x, pad_index)[:, 0]
        if cond is None or cond.shape[-1] != self.cond_dim or cond.shape[1] != x.shape[-1]:
            got = None if cond is None else tuple(cond.shape)
            raise ValueError(
                f"conditional critic needs cond (B, {x.shape[-1]}, {self.cond_dim}), got {got}"
            )
        score, h = self.split(x, pad_index)
        return score + (self.project(cond).transpose(1, 2) * h).sum(1)

    def split(self, x: torch.Tensor, pad_index: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """A conditional critic's two terms before the condition: the realism score
        ``w * h(x)`` ``(B, T)`` and the features ``(B, F, T)`` the projection reads (of the
        detail band or ``h(x)`` itself, per ``critic_band``); ``forward`` is
        ``score + <P c_t, features_t>``. Each feature channel belongs to a joint
        (``hidden_channel_joint``), so the label term splits by body part."""
        layers = self.body.layers
        h = x
        for layer in layers[:-1]:
            h = F.leaky_relu(layer(h, pad_index), self.body.slope)
        score = layers[-1](h, pad_index)[:, 0]  # (B, T)
        if self.detail is not None:
            B, C, _ = x.shape
            xp = x.gather(2, pad_index.expand(B, C, -1))  # reflect-padded per sample
            band = x - F.avg_pool1d(xp, self.body.pad * 2 + 1, stride=1)
            h = F.leaky_relu(self.detail(band, pad_index), self.body.slope)
        return score, h


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


def build_critics(config: ModelConfig, cond_dim: int = 0) -> nn.ModuleList:
    """One patch critic per level; conditional (projection) when ``cond_dim > 0``."""
    return nn.ModuleList(PatchCritic(config, cond_dim) for _ in range(config.num_levels))
