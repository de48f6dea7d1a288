"""The critics of the paper (Sec. 3.3): one patch critic ``D_i`` per level, scoring
every temporal patch of a sequence (its adversarial loss, WGAN-GP, is Eq. 12-13 in
``mrlib.training.objective``).
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F

from mrlib.model.config import ModelConfig
from mrlib.model.skeleton_conv import ConvStack, hidden_channel_joint
from mrlib.representation.features import channel_joint

__all__ = ["PatchCritic", "build_critics"]


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
        pad_index: torch.Tensor | None,
        cond: torch.Tensor | None = None,
    ) -> torch.Tensor:
        """``x (B, C, T)``, ``cond (B, T, D)`` (conditional critics only) -> per-frame
        patch scores ``(B, T)``. ``pad_index``: the packed layout's reflect padding
        (``PackedLevels.pad_index``); None: every row is one sample."""
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
        return score + self.projection(h, cond)

    def projection(self, h: torch.Tensor, cond: torch.Tensor) -> torch.Tensor:
        """A conditional critic's condition term ``<P c_t, h_t>`` ``(B, T)`` of features
        ``h (B, F, T)`` (from :meth:`split`) and conditions ``cond (B, T, D)``."""
        return (self.project(cond).transpose(1, 2) * h).sum(1)

    def split(
        self, x: torch.Tensor, pad_index: torch.Tensor | None
    ) -> tuple[torch.Tensor, torch.Tensor]:
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
            if pad_index is None:  # every row one sample, as the layers take it
                xp = F.pad(x, (self.body.pad, self.body.pad), mode="reflect")
            else:
                xp = x.gather(2, pad_index.expand(B, C, -1))  # reflect-padded per sample
            band = x - F.avg_pool1d(xp, self.body.pad * 2 + 1, stride=1)
            h = F.leaky_relu(self.detail(band, pad_index), self.body.slope)
        return score, h


def build_critics(config: ModelConfig, cond_dim: int = 0) -> nn.ModuleList:
    """One patch critic per level; conditional (projection) when ``cond_dim > 0``."""
    return nn.ModuleList(PatchCritic(config, cond_dim) for _ in range(config.num_levels))
