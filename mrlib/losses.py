"""Training losses (paper Eq. 6-11) as pure functions on padded batches.

Shapes: B batch, C channels, T frames (padded), ``mask (B, T)`` bool marks valid frames.
Every mean is taken per sample over its valid frames, then over the batch, so a short
clip counts as much as a long one (the paper's ``1/N sum_k`` in Eq. 10).

Units: joint and vertex positions in metres, velocities in metres per second at the
level's own frame rate ``fps_i = fps * T_i / T_L``. With these units the paper's weights
(adv 1, con 5, rec 50, smooth 5) give terms of similar size: a sliding foot at 0.3 m/s
costs 0.09 per contact frame, a walking swing foot (~3 m/s) with contact label 0 costs
9 * sig(0) = 0.06.
"""

from __future__ import annotations

from collections.abc import Callable

import torch

from mrlib.features import FeatureNormalizer, root_velocity_to_trans, split_features
from mrlib.rotations import sixd_to_matrix

__all__ = [
    "masked_mean",
    "contact_sigmoid",
    "critic_loss",
    "generator_adversarial_loss",
    "gradient_penalty",
    "reconstruction_loss",
    "contact_consistency_loss",
    "smoothness_loss",
    "backward_velocity",
    "body_kinematics",
]


def masked_mean(x: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """``x (B, T, ...)`` averaged over valid frames and trailing dims per sample, then over
    the batch. ``mask (B, T)`` bool. Returns a scalar."""
    w = mask.to(x.dtype)
    per_frame = x.reshape(x.shape[0], x.shape[1], -1).mean(-1)  # (B, T)
    per_sample = (per_frame * w).sum(1) / w.sum(1).clamp_min(1)
    return per_sample.mean()


def contact_sigmoid(c: torch.Tensor) -> torch.Tensor:
    """The paper's transformed sigmoid ``sig(x) = 1 / (1 + exp(5 - 10 x))``: ~0 for a
    contact label of 0, 0.5 at 0.5, ~1 at 1."""
    return torch.sigmoid(10 * c - 5)


# -- adversarial (WGAN-GP, Arjovsky 2017 / Gulrajani 2017) ---------------------------------
def critic_loss(
    score_real: torch.Tensor,
    score_fake: torch.Tensor,
    mask_real: torch.Tensor,
    mask_fake: torch.Tensor,
) -> torch.Tensor:
    """``E[D(fake)] - E[D(real)]`` (paper Eq. 7 without the penalty). Scores are per-patch
    ``(B, T)``; a sequence's score is the mean of its patch scores (PatchGAN)."""
    return masked_mean(score_fake, mask_fake) - masked_mean(score_real, mask_real)


def generator_adversarial_loss(score_fake: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """``-E[D(fake)]``; ``score_fake (B, T)``."""
    return -masked_mean(score_fake, mask)


def gradient_penalty(
    critic: Callable[[torch.Tensor], torch.Tensor],
    real: torch.Tensor,
    fake: torch.Tensor,
    mask: torch.Tensor,
    alpha: torch.Tensor,
) -> torch.Tensor:
    """``E[(||grad D(x~)|| - 1)^2]`` at ``x~ = alpha * real + (1 - alpha) * fake``.

    As in GANimator, the gradient of the *sum* of patch scores is taken and its norm is
    computed over channels frame by frame, ``(B, T)``, then averaged over valid frames.

    Args:
        critic: ``(B, C, T) -> (B, T)`` patch scores.
        real, fake: ``(B, C, T)``; ``mask (B, T)``; ``alpha (B, 1, 1)`` in [0, 1].
    """
    x = (alpha * real + (1 - alpha) * fake.detach()).requires_grad_(True)
    score = critic(x)
    (grad,) = torch.autograd.grad((score * mask).sum(), x, create_graph=True)
    norm = grad.norm(dim=1)  # (B, T)
    return masked_mean((norm - 1) ** 2, mask)


# -- reconstruction ------------------------------------------------------------------------
def reconstruction_loss(
    pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor
) -> torch.Tensor:
    """L1 between ``pred`` and ``target (B, C, T)`` (paper Eq. 10): mean absolute error
    over valid frames and channels of each clip, averaged over clips."""
    return masked_mean((pred - target).abs().transpose(1, 2), mask)


# -- body-model terms ----------------------------------------------------------------------
def backward_velocity(pos: torch.Tensor, fps: torch.Tensor | float) -> torch.Tensor:
    """Backward-difference velocity ``v[t] = (p[t] - p[t-1]) * fps`` of ``pos (B, T, ..., 3)``;
    ``v[0] = 0`` (callers mask frame 0). ``fps`` a float or ``(B,)``."""
    fps = torch.as_tensor(fps, dtype=pos.dtype, device=pos.device)
    if fps.ndim:
        fps = fps.reshape(-1, *([1] * (pos.ndim - 1)))
    v = torch.zeros_like(pos)
    v[:, 1:] = (pos[:, 1:] - pos[:, :-1]) * fps
    return v


def contact_consistency_loss(
    foot_velocity: torch.Tensor, contacts: torch.Tensor, mask: torch.Tensor
) -> torch.Tensor:
    """Paper Eq. 9: ``mean_{t, j} ||v_j^t||^2 * sig(c_j^t)``.

    Args:
        foot_velocity: ``(B, T, 6, 3)`` m/s of the contact vertices.
        contacts: ``(B, T, 6)`` predicted contact labels (unnormalised, ~[0, 1]).
        mask: ``(B, T)`` frames where the velocity is defined (frame 0 excluded).
    """
    cost = foot_velocity.pow(2).sum(-1) * contact_sigmoid(contacts)  # (B, T, 6)
    return masked_mean(cost, mask)


def smoothness_loss(joints: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Paper Eq. 11: ``mean_t ||p_t - (p_{t-1} + p_t + p_{t+1}) / 3||_2`` with ``p_t`` all
    joint positions of frame t as one vector; ``joints (B, T, J, 3)`` metres. Only
    interior frames (both neighbours valid) count."""
    p = joints.flatten(2)  # (B, T, 3J)
    d = torch.zeros_like(p[..., 0])
    d[:, 1:-1] = (p[:, 1:-1] - (p[:, :-2] + p[:, 1:-1] + p[:, 2:]) / 3).norm(dim=-1)
    interior = mask.clone()
    interior[:, 0] = False
    interior[:, 1:] &= mask[:, :-1]  # previous frame valid
    interior[:, :-1] &= mask[:, 1:]  # next frame valid
    interior[:, -1] = False
    return masked_mean(d, interior)


def body_kinematics(
    x: torch.Tensor,
    normalizer: FeatureNormalizer,
    fps: torch.Tensor | float,
    body,
    betas: torch.Tensor | None = None,
):
    """Joint and foot-vertex positions of a batch of (normalised) feature sequences.

    Args:
        x: ``(B, C, T)`` normalised features.
        fps: frame rate of the level, a float or ``(B,)`` (per-sample when clips differ).
        body: a ``mrlib.body.BodyModel`` (``forward(rotmat, trans, betas, vertex_ids)``).
    Returns:
        joints ``(B, T, 24, 3)``, foot vertices ``(B, T, 6, 3)`` (metres, world frame,
        ground-plane path integrated from the root velocity), contacts ``(B, T, 6)``.
    """
    feats = normalizer.denormalize(x.transpose(1, 2))  # (B, T, C)
    rot6d, root, contacts = split_features(feats)
    fps_t = torch.as_tensor(fps, dtype=x.dtype, device=x.device)
    if fps_t.ndim:
        fps_t = fps_t.reshape(-1, 1, 1)
    trans = root_velocity_to_trans(root, fps_t)  # (B, T, 3)
    out = body.forward(
        sixd_to_matrix(rot6d), trans, betas=betas, vertex_ids=list(body.foot_vertex_ids)
    )
    return out.joints, out.vertices, contacts
