"""Training losses as pure functions: the paper's terms (Eq. 12-16; their weighted sum,
Eq. 11, is ``mrlib.training.objective``) and the terms mrlib adds.

Shapes: B batch, C channels, T frames. A batch may be padded ``(B, C, T_max)`` or packed
``(1, C, S)`` (``mrlib.model.pyramid.PackedLevels``); either way, ``weights (B, T)`` gives every
frame its weight in the mean: zero on padding, and ``1 / (frames of its sample * B)``
on valid frames, so a short clip counts as much as a long one (the paper's
``1/N sum_k`` in Eq. 15). ``mask_weights`` builds them from a padded batch's mask.

Units: joint and vertex positions in metres, velocities in metres per second at the
level's own frame rate ``fps_i = fps * T_i / T_L``. With these units the paper's weights
(adv 1, con 5, rec 50, smooth 5) give terms of similar size: a sliding foot at 0.3 m/s
costs 0.09 per contact frame, a walking swing foot (~3 m/s) with contact label 0 costs
9 * sig(0) = 0.06.
"""

from __future__ import annotations

from collections.abc import Callable

import torch

from mrlib.representation.features import FeatureNormalizer, root_velocity_to_trans, split_features
from mrlib.representation.rotations import sixd_to_matrix

__all__ = [
    "weighted_mean",
    "mask_weights",
    "contact_sigmoid",
    "critic_loss",
    "generator_adversarial_loss",
    "gradient_penalty",
    "wgan_gp_critic_loss",
    "mismatch_critic_loss",
    "wgan_gp_mismatch_critic_loss",
    "detail_statistics_loss",
    "reconstruction_loss",
    "contact_consistency_loss",
    "smoothness_loss",
    "backward_velocity",
    "interior_mask",
    "body_kinematics",
]


def weighted_mean(x: torch.Tensor, weights: torch.Tensor) -> torch.Tensor:
    """``sum_{b,t} weights[b, t] * mean(x[b, t, ...])``: ``x (B, T, ...)``, ``weights (B, T)``
    (summing to 1). Returns a scalar."""
    per_frame = x.reshape(x.shape[0], x.shape[1], -1).mean(-1)  # (B, T)
    return (per_frame * weights).sum()


def mask_weights(mask: torch.Tensor) -> torch.Tensor:
    """Weights ``(B, T)`` of a per-sample mean over the True frames of ``mask (B, T)``,
    averaged over samples."""
    m = mask.float()
    return m / (m.sum(1, keepdim=True).clamp_min(1) * m.shape[0])


def contact_sigmoid(c: torch.Tensor) -> torch.Tensor:
    """The paper's transformed sigmoid ``sig(x) = 1 / (1 + exp(5 - 10 x))``: ~0 for a
    contact label of 0, 0.5 at 0.5, ~1 at 1."""
    return torch.sigmoid(10 * c - 5)


def _frame_rate(fps: torch.Tensor | float, like: torch.Tensor, extra_dims: int) -> torch.Tensor:
    """``fps`` (a float, ``(B,)`` per sample or ``(B, T)`` per frame) shaped to broadcast
    against ``(B, T, *[1] * extra_dims)``."""
    f = torch.as_tensor(fps, dtype=like.dtype, device=like.device)
    if f.ndim == 1:
        f = f[:, None]
    return f.reshape(*f.shape, *([1] * extra_dims))


# -- adversarial (WGAN-GP, Arjovsky 2017 / Gulrajani 2017) ---------------------------------
def critic_loss(
    score_real: torch.Tensor, score_fake: torch.Tensor, w_real: torch.Tensor, w_fake: torch.Tensor
) -> torch.Tensor:
    """``E[D(fake)] - E[D(real)]`` (paper Eq. 12 without the penalty, Eq. 13). Scores are per-patch
    ``(B, T)``; a sequence's score is the mean of its patch scores (PatchGAN)."""
    return weighted_mean(score_fake, w_fake) - weighted_mean(score_real, w_real)


def generator_adversarial_loss(score_fake: torch.Tensor, weights: torch.Tensor) -> torch.Tensor:
    """``-E[D(fake)]``; ``score_fake (B, T)``."""
    return -weighted_mean(score_fake, weights)


def gradient_penalty(
    critic: Callable[[torch.Tensor], torch.Tensor],
    real: torch.Tensor,
    fake: torch.Tensor,
    weights: torch.Tensor,
    alpha: torch.Tensor,
) -> torch.Tensor:
    """``E[(||grad D(x~)|| - 1)^2]`` at ``x~ = alpha * real + (1 - alpha) * fake``.

    As in GANimator, the gradient of the *sum* of patch scores is taken and its norm is
    computed over channels frame by frame, ``(B, T)``, then averaged over valid frames.

    Args:
        critic: ``(B, C, T) -> (B, T)`` patch scores.
        real, fake: ``(B, C, T)``; ``weights (B, T)``; ``alpha`` in [0, 1], ``(B, 1, 1)``
            per sample (or ``(B, 1, T)`` per frame for packed batches).
    """
    x = (alpha * real + (1 - alpha) * fake.detach()).requires_grad_(True)
    score = critic(x)
    (grad,) = torch.autograd.grad((score * (weights > 0)).sum(), x, create_graph=True)
    norm = grad.norm(dim=1)  # (B, T)
    return weighted_mean((norm - 1) ** 2, weights)


def wgan_gp_critic_loss(
    critic,
    real: torch.Tensor,
    fake: torch.Tensor,
    weights: torch.Tensor,
    alpha: torch.Tensor,
    pad_index: torch.Tensor,
    pad_index_pair: torch.Tensor,
    cond_real: torch.Tensor | None = None,
    cond_fake: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Critic loss ``E[D(fake)] - E[D(real)]`` and gradient penalty of packed batches.

    Real and fake are scored in one critic forward on ``[real, fake]`` (concatenated along
    time, a packed batch of twice the samples); the penalty takes its own forward (a
    double backward through the real and fake halves would be wasted work).
    ``losses.critic_loss`` and ``losses.gradient_penalty`` are the reference.

    Args:
        critic: a ``PatchCritic``.
        real, fake: ``(1, C, S)`` packed with the same layout; ``weights (1, S)``.
        alpha: ``(1, 1, S)`` interpolation weight of each sample, spread over its frames.
        pad_index: the layout's reflect-pad index ``(1, 1, S + 2p)``.
        pad_index_pair: that of the layout repeated twice ``(1, 1, 2S + 2p)``.
        cond_real, cond_fake: ``(1, S, D)`` conditions of a conditional critic (the real
            clips' own, and those the fakes were generated with; the penalty's
            interpolates take the fakes'); None for an unconditional critic.
    """
    S = real.shape[-1]
    pair = torch.cat([real, fake], -1)
    both = None if cond_fake is None else torch.cat([cond_real, cond_fake], 1)
    scores = critic(pair, pad_index_pair, both)  # (1, 2S)

    def one(x: torch.Tensor) -> torch.Tensor:
        return critic(x, pad_index, cond_fake)

    gp = gradient_penalty(one, real, fake, weights, alpha)
    return critic_loss(scores[:, :S], scores[:, S:], weights, weights), gp


def wgan_gp_mismatch_critic_loss(
    critic,
    real: torch.Tensor,
    fake: torch.Tensor,
    weights: torch.Tensor,
    alpha: torch.Tensor,
    pad_index: torch.Tensor,
    pad_index_pair: torch.Tensor,
    conds: tuple[torch.Tensor, torch.Tensor, torch.Tensor],
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """:func:`wgan_gp_critic_loss` and :func:`mismatch_critic_loss` of a conditional critic
    from one critic forward on ``[real, fake]``: the two scores of a real clip in the
    mismatch term differ only in the condition, so their realism parts cancel and the
    mismatch term is ``E[<P c_wrong, h>] - E[<P c_own, h>]`` with the features ``h`` of the
    real half (``PatchCritic.split``): the same value and gradient without the critic's
    second pass over ``[real, real]``. Arguments as the two functions'; ``conds``: the
    real clips' own, the fakes' and the wrong conditions, ``(1, S, D)`` each. Returns
    ``(D, gp, mis)``."""
    cond_real, cond_fake, cond_wrong = conds
    S = real.shape[-1]
    score, h = critic.split(torch.cat([real, fake], -1), pad_index_pair)
    label = critic.projection(h, torch.cat([cond_real, cond_fake], 1))  # (1, 2S)
    scores = score + label
    wrong = critic.projection(h[..., :S], cond_wrong)  # (1, S)

    def one(x: torch.Tensor) -> torch.Tensor:
        return critic(x, pad_index, cond_fake)

    gp = gradient_penalty(one, real, fake, weights, alpha)
    d = critic_loss(scores[:, :S], scores[:, S:], weights, weights)
    return d, gp, critic_loss(label[:, :S], wrong, weights, weights)


def mismatch_critic_loss(
    critic,
    real: torch.Tensor,
    cond_own: torch.Tensor,
    cond_wrong: torch.Tensor,
    weights: torch.Tensor,
    pad_index_pair: torch.Tensor,
) -> torch.Tensor:
    """``E[D(real, wrong condition)] - E[D(real, own condition)]``: the real clips shown
    once more with conditions that are not theirs, scored as fakes (the "real data, wrong
    text" negatives of Reed et al., ICML 2016), in one critic forward on ``[real, real]``.

    Args:
        critic: a conditional ``PatchCritic``.
        real: ``(1, C, S)`` packed; ``weights (1, S)``.
        cond_own, cond_wrong: ``(1, S, D)`` the clips' own and wrong conditions.
        pad_index_pair: reflect-pad index of the layout repeated twice.
    """
    S = real.shape[-1]
    twice = torch.cat([real, real], -1)
    scores = critic(twice, pad_index_pair, torch.cat([cond_own, cond_wrong], 1))
    return critic_loss(scores[:, :S], scores[:, S:], weights, weights)


# -- detail statistics (beyond the paper) ----------------------------------------------------
def detail_statistics_loss(band_rms: torch.Tensor, target_rms: torch.Tensor) -> torch.Tensor:
    """``mean_{b, c} |rms_bc - target_bc|``: the per-channel RMS ``(B, C)`` of the detail a
    level adds to each random generation (``PackedLevels.level_band``) against the mean
    RMS of that band over the training clips of the label driving the sample's level,
    ``(B, C)``: a style as channel statistics (Gatys et al. 2016; Huang & Belongie 2017).
    ``LossWeights.detail``."""
    return (band_rms - target_rms).abs().mean()


# -- reconstruction ------------------------------------------------------------------------
def reconstruction_loss(
    pred: torch.Tensor, target: torch.Tensor, weights: torch.Tensor
) -> torch.Tensor:
    """L1 between ``pred`` and ``target (B, C, T)`` (paper Eq. 15): mean absolute error
    over the frames and channels of each clip, averaged over clips."""
    return weighted_mean((pred - target).abs().transpose(1, 2), weights)


# -- body-model terms ----------------------------------------------------------------------
def backward_velocity(pos: torch.Tensor, fps: torch.Tensor | float) -> torch.Tensor:
    """Backward-difference velocity ``v[t] = (p[t] - p[t-1]) * fps`` of ``pos (B, T, K, 3)``;
    ``v[0] = 0`` (give frame 0 of every sequence zero weight). ``fps`` a float, ``(B,)`` or
    ``(B, T)`` (per frame, for packed batches whose samples have different rates)."""
    f = _frame_rate(fps, pos, pos.ndim - 2)
    v = torch.zeros_like(pos)
    v[:, 1:] = (pos[:, 1:] - pos[:, :-1]) * (f[:, 1:] if f.shape[1] > 1 else f)
    return v


def contact_consistency_loss(
    foot_velocity: torch.Tensor,
    contacts: torch.Tensor,
    weights: torch.Tensor,
) -> torch.Tensor:
    """Paper Eq. 14: ``mean_{t, j} ||v_j^t||^2 * sig(c_j^t)``.

    Args:
        foot_velocity: ``(B, T, 6, 3)`` m/s of the contact vertices.
        contacts: ``(B, T, 6)`` predicted contact labels (unnormalised, ~[0, 1]).
        weights: ``(B, T)``, zero where the velocity is undefined (each sequence's first
            frame) and on padding.
    """
    sq = foot_velocity.pow(2).sum(-1)  # (B, T, 6)
    cost = sq * contact_sigmoid(contacts)
    return weighted_mean(cost, weights)


def smoothness_loss(joints: torch.Tensor, weights: torch.Tensor) -> torch.Tensor:
    """Paper Eq. 16: ``mean_t ||p_t - (p_{t-1} + p_t + p_{t+1}) / 3||_2`` with ``p_t`` all
    joint positions of frame t as one vector; ``joints (B, T, J, 3)`` metres.

    ``weights (B, T)`` must be zero on each sequence's first and last frame (their
    neighbours are missing) and on padding; see ``interior_mask``."""
    p = joints.flatten(2)  # (B, T, 3J)
    d = torch.zeros_like(p[..., 0])
    d[:, 1:-1] = (p[:, 1:-1] - (p[:, :-2] + p[:, 1:-1] + p[:, 2:]) / 3).norm(dim=-1)
    return weighted_mean(d, weights)


def interior_mask(mask: torch.Tensor, before: int = 1, after: int = 1) -> torch.Tensor:
    """Frames of ``mask (B, T)`` whose ``before`` predecessors and ``after`` successors are
    also in the mask."""
    out = mask.clone()
    for k in range(1, before + 1):
        out[:, :k] = False
        out[:, k:] &= mask[:, :-k]
    for k in range(1, after + 1):
        out[:, -k:] = False
        out[:, :-k] &= mask[:, k:]
    return out


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
        fps: frame rate of the level: a float, ``(B,)`` per sample or ``(B, T)`` per frame.
        body: a ``mrlib.representation.body.BodyModel`` (``forward(rotmat, trans, betas, vertex_ids)``).
    Returns:
        joints ``(B, T, 24, 3)``, foot vertices ``(B, T, 6, 3)`` (metres, world frame,
        ground-plane path integrated from the root velocity; in a packed batch each
        sample's path is offset by a constant, which velocities and the smoothness term
        do not see), contacts ``(B, T, 6)``.
    """
    feats = normalizer.denormalize(x.transpose(1, 2))  # (B, T, C)
    rot6d, root, contacts = split_features(feats)
    trans = root_velocity_to_trans(root, _frame_rate(fps, x, 1))  # (B, T, 3)
    out = body.forward(
        sixd_to_matrix(rot6d), trans, betas=betas, vertex_ids=list(body.foot_vertex_ids)
    )
    return out.joints, out.vertices, contacts
