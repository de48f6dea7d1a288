"""The paper's training objective (Sec. 3.4) as pure functions of explicit tensors.

Equation numbers are the paper's (every line of an ``align`` numbered):

* Eq. 11, the generator's objective at level i,
  ``L = l_adv L_adv + l_con L_con + l_rec L_rec + l_smooth L_smooth``
  (:func:`generator_terms`, summed by :func:`generator_objective`);
* Eq. 12-13, the adversarial loss, trained as WGAN-GP: the critic minimises
  ``E[D_i(fake)] - E[D_i(real)] + gp * E[(||grad D_i(x~)||_2 - 1)^2]``
  (:func:`critic_terms`, summed by :func:`critic_objective`), the generator
  ``L_adv = -E[D_i(fake)]``;
* Eq. 14 ``L_con``, Eq. 15 ``L_rec``, Eq. 16 ``L_smooth``.

Every term is a function of ``mrlib.model.losses``; here they are put together for one
level, from the tensors of that level: the generator's outputs, the real clips, the frame
weights of each term (``mrlib.model.pyramid.PackedLevels.weights``), a critic and the
body model. Beyond the paper, and off unless their weight is set: the critics' mismatch
term (``LossWeights.mismatch``) and the detail-statistics term (``LossWeights.detail``).
``mrlib.training.trainer`` sums these over a block's levels and takes the Adam steps.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import torch

from mrlib.model.config import LossWeights, TrainConfig
from mrlib.model.losses import (
    backward_velocity,
    contact_consistency_loss,
    detail_statistics_loss,
    generator_adversarial_loss,
    reconstruction_loss,
    smoothness_loss,
    wgan_gp_critic_loss,
    wgan_gp_mismatch_critic_loss,
)

__all__ = [
    "LevelData",
    "Terms",
    "critic_terms",
    "critic_objective",
    "terms_on",
    "generator_terms",
    "generator_objective",
]

Terms = dict[str, torch.Tensor]  # {term name: scalar}, the names of losses.csv


@dataclass
class LevelData:
    """The fixed tensors of one level that its terms read (packed batches,
    ``mrlib.model.pyramid``; S frames of the random layout, S_rec of the reconstructions).

    Attributes:
        real: ``(1, C, S_rec)`` every training clip, for ``L_rec``.
        real_rand: ``(1, C, S)`` the real clip each random generation follows, for the critic.
        w_rec, w_rand: ``(1, S_rec)``, ``(1, S)`` frame weights of a per-sample mean.
        w_vel: ``(1, S)`` zero on each sample's first frame (no velocity there), for ``L_con``.
        w_smooth: ``(1, S)`` zero on each sample's first and last frame, for ``L_smooth``.
        fps: ``(1, S)`` frame rate of each frame (``fps_i = fps * T_i / T_L``).
    """

    real: torch.Tensor
    real_rand: torch.Tensor
    w_rec: torch.Tensor
    w_rand: torch.Tensor
    w_vel: torch.Tensor
    w_smooth: torch.Tensor
    fps: torch.Tensor


# -- critic -------------------------------------------------------------------------------
def critic_terms(
    critic: torch.nn.Module,
    real: torch.Tensor,
    fake: torch.Tensor,
    weights: torch.Tensor,
    alpha: torch.Tensor,
    pads: tuple[torch.Tensor, torch.Tensor],
    conds: tuple[torch.Tensor, torch.Tensor] | None = None,
    wrong: torch.Tensor | None = None,
) -> Terms:
    """The terms of one level's critic loss: ``D = E[D(fake)] - E[D(real)]`` and ``gp``
    (Eq. 12-13, ``losses.wgan_gp_critic_loss``), and ``mis``
    (``losses.mismatch_critic_loss``) when ``wrong`` is given (then all three from one
    critic pass, ``losses.wgan_gp_mismatch_critic_loss``).

    Args:
        critic: the level's ``PatchCritic``.
        real, fake: ``(1, C, S)`` packed with the same layout; ``weights (1, S)``.
        alpha: ``(1, 1, S)`` the penalty's interpolation weight of each sample.
        pads: the reflect-pad indices of the layout and of the layout twice ``[real; fake]``.
        conds: ``(cond_real, cond_fake)``, ``(1, S, D)`` each, for a conditional critic.
        wrong: ``(1, S, D)`` conditions that do not go with the real clips (mismatch term).
    """
    cond_real, cond_fake = (None, None) if conds is None else conds
    if wrong is not None:
        d, gp, mis = wgan_gp_mismatch_critic_loss(
            critic, real, fake, weights, alpha, *pads, (cond_real, cond_fake, wrong)
        )
        return {"D": d, "gp": gp, "mis": mis}
    d, gp = wgan_gp_critic_loss(
        critic, real, fake, weights, alpha, *pads, cond_real=cond_real, cond_fake=cond_fake
    )
    return {"D": d, "gp": gp}


def critic_objective(t: Terms, w: LossWeights) -> torch.Tensor:
    """One level's critic loss, Eq. 12-13 (WGAN-GP; ``w.gp``, GANimator's 1), plus the
    mismatch term ``w.mismatch * mis`` when it was computed."""
    return t["D"] + w.gp * t["gp"] + w.mismatch * t.get("mis", 0.0)


# -- generator ----------------------------------------------------------------------------
def terms_on(config: TrainConfig, level: int) -> frozenset[str]:
    """The terms of Eq. 11 (and ``detail``) computed at 0-based ``level`` besides ``rec``
    (always on): a term with weight 0 is not computed, nor ``adv`` without critic steps
    (``n_critic = 0``), ``smooth`` below ``TrainConfig.smooth_start``, ``detail`` at
    level 1 (it has no band of its own)."""
    w = config.loss
    on = {
        "adv": config.n_critic > 0 and bool(w.adv),
        "con": bool(w.con),
        "smooth": bool(w.smooth) and level + 1 >= config.smooth_start,
        "detail": bool(w.detail) and level > 0,
    }
    return frozenset(k for k, v in on.items() if v)


def generator_terms(
    out_rec: torch.Tensor,
    out_rand: torch.Tensor,
    lv: LevelData,
    on: frozenset[str],
    critic: Callable[[torch.Tensor], torch.Tensor] | None = None,
    kinematics: Callable | None = None,
    detail: tuple[Callable[[torch.Tensor], torch.Tensor], torch.Tensor] | None = None,
) -> Terms:
    """The terms of Eq. 11 in ``on`` (:func:`terms_on`) at one level: ``rec`` (Eq. 15) of
    the reconstructions ``out_rec``; ``adv`` (the generator's side of Eq. 12), ``con``
    (Eq. 14), ``smooth`` (Eq. 16) and ``detail`` of the random generations ``out_rand``.

    Args:
        out_rec, out_rand: ``(1, C, S_rec)``, ``(1, C, S)`` the generator's outputs.
        lv: the level's real clips, frame weights and frame rates.
        critic: ``x -> (1, S)`` patch scores of the level's critic (with the conditions
            it sees the random generations with), for ``adv``.
        kinematics: ``(x, fps) -> (joints, foot vertices, contacts)``
            (``losses.body_kinematics`` with the run's body), for ``con`` and ``smooth``.
        detail: ``(band_rms, targets)``: ``x -> (B, C)`` RMS of the band the level adds
            to each sample, and its ``(B, C)`` targets, for ``detail``.
    """
    terms = {"rec": reconstruction_loss(out_rec, lv.real, lv.w_rec)}
    if "adv" in on:
        terms["adv"] = generator_adversarial_loss(critic(out_rand), lv.w_rand)
    if "detail" in on:
        band_rms, targets = detail
        terms["detail"] = detail_statistics_loss(band_rms(out_rand), targets)
    if "con" in on or "smooth" in on:
        joints, feet, contacts = kinematics(out_rand, lv.fps)
        if "con" in on:
            vel = backward_velocity(feet, lv.fps)
            terms["con"] = contact_consistency_loss(vel, contacts, lv.w_vel)
        if "smooth" in on:
            terms["smooth"] = smoothness_loss(joints, lv.w_smooth)
    return terms


def generator_objective(t: Terms, w: LossWeights) -> torch.Tensor:
    """One level's generator loss, Eq. 11 with the ``LossWeights`` adv / con / rec /
    smooth (the paper's 1 / 5 / 50 / 5), plus ``w.detail * detail``; a term not
    computed counts 0."""
    return (
        w.adv * t.get("adv", 0.0)
        + w.con * t.get("con", 0.0)
        + w.rec * t["rec"]
        + w.smooth * t.get("smooth", 0.0)
        + w.detail * t.get("detail", 0.0)
    )
