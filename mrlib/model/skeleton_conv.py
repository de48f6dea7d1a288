"""Skeleton-aware convolution (Aberman et al. 2020), the building block of the paper's
generators ``g_i`` and critics ``D_i`` (Sec. 3.3): which channels may read which
(owner joints a few hops apart on the kinematic tree), the masked 1-D convolution, and
a stack of them.

Shapes: B batch, C = 153 feature channels (``mrlib.representation.features``), T frames.
Sequences are ``(B, C, T)``. A batch of clips of different lengths is packed end to end
into one sequence (B = 1, see :class:`mrlib.model.pyramid.PackedLevels`); the layout's
reflect-pad indices keep every convolution inside its own clip.
"""

from __future__ import annotations

import math

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F

from mrlib.representation.skeleton import NUM_JOINTS, PARENTS, graph_distances

__all__ = ["hidden_channel_joint", "skeleton_mask", "SkeletonConv1d", "ConvStack"]


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
