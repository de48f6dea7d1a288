"""One training iteration of a block (paper Sec. 3.4): ``n_critic`` critic steps on
WGAN-GP (Eq. 7-8), then one generator step on Eq. 6, summed over the block's levels.

Each objective is written once, as a sum (:func:`critic_steps`, :func:`generator_step`);
every term in it is a pure function of ``mrlib.model.losses``, fed by the trainer's
fixed batches (``mrlib.training.build``):

* critic steps: the fakes of all of them come from one batched, gradient-free
  generation (the generator does not change between critic steps, so this equals
  GANimator's one-generation-per-step in distribution); each step scores real and fake
  clips of every level in the block and adds the gradient penalty;
* generator step: reconstructions (every training clip with its fixed noise z* and its
  own label) and random generations (one per clip, 90% of them mixing two labels at a
  random crossover level) run as one batch; the frozen levels' reconstructions are
  computed once per block.
"""

from __future__ import annotations

import torch

from mrlib.model.losses import (
    backward_velocity,
    contact_consistency_loss,
    detail_statistics_loss,
    generator_adversarial_loss,
    mismatch_critic_loss,
    reconstruction_loss,
    smoothness_loss,
    wgan_gp_critic_loss,
)
from mrlib.training.build import RandomDraw, TrainerBase

__all__ = ["critic_steps", "generator_step", "critic_terms", "generator_terms"]

Losses = dict[int, dict[str, torch.Tensor]]  # {level: {term: value}}, 0-based levels


# -- critics -------------------------------------------------------------------------------
def critic_steps(tr: TrainerBase, losses: Losses) -> None:
    """``n_critic`` critic steps, each one Adam step on the sum over the block's levels i of

        L_D,i = E[D_i(fake)] - E[D_i(real)] + gp * E[(||grad D_i(x~)||_2 - 1)^2]
                + mismatch * (E[D_i(real, wrong condition)] - E[D_i(real, own condition)])

    the paper's WGAN-GP critic loss (Eq. 7-8, ``LossWeights.gp``, GANimator's 1) and,
    beyond the paper, the mismatch term of conditional critics (``LossWeights.mismatch``,
    0 unless set; Reed et al. 2016). Records ``D``, ``gp`` and ``mis`` in ``losses``."""
    c, w, G = tr.config, tr.config.loss, tr.generator
    hi = tr.block_levels[-1]
    draw = tr.draw_random(tr.fake_layout, hi + 1)
    with torch.no_grad():
        fakes = G.run(tr.fake_layout, draw.noises, draw.conds, 0, hi + 1, keep=True)
    conds = None  # conditional critics: which fakes keep their condition, and what it is
    if tr.real_rand_conds is not None:
        conds = tr.critic_keep(draw), tr.critic_conditions(draw, tr.fake_layout)
    alphas = torch.rand(c.n_critic, tr.B, generator=tr.rng).to(tr.device)
    for j in range(c.n_critic):
        tr.opt_d.zero_grad(set_to_none=True)
        total = 0.0
        for i in tr.block_levels:
            t = critic_terms(tr, i, j, fakes[i], conds, alphas[j])
            # Eq. 7-8 (WGAN-GP), + the mismatch term
            total = total + (t["D"] + w.gp * t["gp"] + w.mismatch * t.get("mis", 0.0))
            losses[i].update({name: value.detach() for name, value in t.items()})
        total.backward()
        tr.opt_d.step()


def critic_terms(
    tr: TrainerBase,
    i: int,
    j: int,
    fakes: torch.Tensor,
    conds: tuple[torch.Tensor, list[torch.Tensor]] | None,
    alpha: torch.Tensor,
) -> dict[str, torch.Tensor]:
    """The terms of critic step ``j`` at level ``i``: ``D`` (critic loss) and ``gp``
    (gradient penalty) of ``losses.wgan_gp_critic_loss``, and ``mis``
    (``losses.mismatch_critic_loss``) when ``LossWeights.mismatch`` is on. ``fakes``: the
    level's fakes of all critic steps; ``conds``: ``critic_keep`` and
    ``critic_conditions`` of their draw (None for unconditional critics); ``alpha (B,)``
    the step's interpolation weights."""
    G, lay, pair = tr.generator, tr.rand_layout, tr.critic_layout
    S = lay.sizes[i]
    fake = fakes[..., j * S : (j + 1) * S]  # j-th copy of the random layout
    cond_real = cond_fake = None
    if conds is not None:
        # a real clip is shown without its condition where its fake partner (same sample
        # slot) is: both sides see the same kind of condition
        keep = lay.per_sample(conds[0][j * tr.B : (j + 1) * tr.B, i], i)[None, :, None]
        cond_real = tr.real_rand_conds[i] * keep
        cond_fake = conds[1][i][:, j * S : (j + 1) * S]
    d, gp = wgan_gp_critic_loss(
        tr.critics[i],
        tr.real_rand[i],
        fake,
        tr.w_rand[i],
        lay.per_sample(alpha, i)[None, None],  # (1, 1, S)
        lay.pad_index(i, G.pad),
        pair.pad_index(i, G.pad),
        cond_real=cond_real,
        cond_fake=cond_fake,
    )
    terms = {"D": d, "gp": gp}
    if tr.use_mismatch:
        terms["mis"] = mismatch_critic_loss(
            tr.critics[i],
            tr.real_rand[i],
            cond_real,
            tr.mismatched_real_conditions(i) * keep,
            tr.w_rand[i],
            pair.pad_index(i, G.pad),
        )
    return terms


# -- generator -----------------------------------------------------------------------------
def generator_step(tr: TrainerBase, losses: Losses) -> None:
    """One Adam step of the block's generator levels on the sum over those levels of the
    paper's Eq. 6,

        L = lambda_adv L_adv + lambda_con L_con + lambda_rec L_rec + lambda_smooth L_smooth

    (``LossWeights`` adv / con / rec / smooth, the paper's 1 / 5 / 50 / 5), plus, beyond
    the paper, ``detail * L_detail`` (``LossWeights.detail``, 0 unless set). A term that
    is off at a level (its weight 0, or smoothness below ``TrainConfig.smooth_start``;
    adversarial with ``n_critic = 0``; detail at level 1) is not
    computed and counts 0. Records each term computed in ``losses``."""
    w = tr.config.loss
    tr.opt_g.zero_grad(set_to_none=True)
    draw = tr.draw_random(tr.rand_layout, tr.block_levels[-1] + 1)
    critic_conds = None  # what conditional critics see with the random generations
    if tr.real_rand_conds is not None:
        critic_conds = tr.critic_conditions(draw, tr.rand_layout)
    outs = generator_outputs(tr, draw)
    total = 0.0
    for i, (out_rec, out_rand) in zip(tr.block_levels, outs, strict=True):
        cond = None if critic_conds is None else critic_conds[i]
        t = generator_terms(tr, i, out_rec, out_rand, draw, cond)
        # Eq. 6, + the detail-statistics term
        total = total + (
            w.adv * t.get("adv", 0.0)
            + w.con * t.get("con", 0.0)
            + w.rec * t["rec"]
            + w.smooth * t.get("smooth", 0.0)
            + w.detail * t.get("detail", 0.0)
        )
        losses[i].update({name: value.detach() for name, value in t.items()})
    total.backward()
    tr.opt_g.step()


def generator_outputs(tr: TrainerBase, draw: RandomDraw) -> list[tuple[torch.Tensor, torch.Tensor]]:
    """``(reconstructions, random generations)`` ``(1, C, S_i)`` of every level of the
    block, from one generator run on ``[reconstructions; random]``: every clip with its
    z* and its own condition, and the random generations of ``draw``. The levels below
    the block are frozen: their reconstructions come from the cache."""
    G, lo, hi = tr.generator, tr.block_levels[0], tr.block_levels[-1]
    rec_conds, rec_noises = tr.rec_conditions(hi + 1), tr.rec_noises(hi + 1)
    x_in = None
    if lo > 0:
        with torch.no_grad():
            x_rand = G.run(tr.rand_layout, draw.noises, draw.conds, 0, lo)
        x_in = torch.cat([tr.rec_input(lo), x_rand], -1)
    noises, conds = [], []
    for i in range(hi + 1):
        zr, zn = rec_noises[i], draw.noises[i]
        noises.append(torch.cat([zr, zn], -1))
        conds.append(torch.cat([rec_conds[i], draw.conds[i]], 1))
    outs = G.run(tr.g_layout, noises, conds, lo, hi + 1, x=x_in, keep=True)
    cuts = [tr.g_layout.split(i, tr.N) for i in tr.block_levels]
    return [(out[..., :cut], out[..., cut:]) for out, cut in zip(outs, cuts, strict=True)]


def generator_terms(
    tr: TrainerBase,
    i: int,
    out_rec: torch.Tensor,
    out_rand: torch.Tensor,
    draw: RandomDraw,
    critic_cond: torch.Tensor | None,
) -> dict[str, torch.Tensor]:
    """The terms of Eq. 6 in use at level ``i``, each from ``mrlib.model.losses``:
    ``rec`` (Eq. 10) on the reconstructions; ``adv`` (the generator's side of Eq. 7),
    ``con`` (Eq. 9), ``smooth`` (Eq. 11) and ``detail`` on the random generations
    ``out_rand`` of ``draw``, which a conditional critic sees with ``critic_cond``."""
    c, w, lay = tr.config, tr.config.loss, tr.rand_layout
    need_con = w.con
    need_smooth = w.smooth and i + 1 >= c.smooth_start
    need_adv = c.n_critic > 0 and w.adv
    fps = tr.rand_fps[i]
    terms = {"rec": reconstruction_loss(out_rec, tr.real[i], tr.w_rec[i])}
    if need_adv:
        pad = lay.pad_index(i, tr.generator.pad)
        score = tr.critics[i](out_rand, pad, critic_cond)
        terms["adv"] = generator_adversarial_loss(score, tr.w_rand[i])
    if w.detail and i > 0:
        rms = lay.per_sample_rms(lay.level_band(out_rand, i), i)  # (B, C)
        terms["detail"] = detail_statistics_loss(rms, tr.detail_targets(draw, i))
    if need_con or need_smooth:
        joints, feet, contacts = tr.kinematics(out_rand, fps)
        if need_con:
            vel = backward_velocity(feet, fps)
            terms["con"] = contact_consistency_loss(vel, contacts, tr.w_vel[i])
        if need_smooth:
            terms["smooth"] = smoothness_loss(joints, tr.w_smooth[i])
    return terms
