"""Sharper labels per body part: the noise fitted so that every window of a part is
nearer its own label's training clips than any other label's.

Condition fidelity per part (:func:`mrlib.sampling.constraints.part_fidelity`) asks of each
30-frame window of a part whether its nearest training window, on the part's joints,
has the part's label. At the `tutorial` budget a model draws some parts (the happy
walk's arms, the normal walk's legs) that are nearest another label's clip in a third of
their windows or more (``docs/results.md``, "Body parts"). With the networks frozen
(``mrlib.sampling.constraints.optimise``), the noise maps are moved to lower a hinge on that
nearest-neighbour decision,

    loss = mean over windows and parts of max(0, d_own - d_other + margin),

``d_own`` / ``d_other`` the mean per-frame squared distance of a generated window to
the nearest window of the part's own label's / of any other label's training clips, on
the features of ``mrlib.metrics.windows.metric_features`` (6D local rotations of the part's
joints, with the contact labels for a part with leg joints). A window nearer its own
label by ``margin`` costs nothing, and the fit's prior is centred on the sample's own
draw (``optimise_noise(..., prior_centre="draw")``: centred on 0, Adam shrinks the noise
no window needs and can still a motion), so the fit leaves a sample alone once it shows
its label and moves only the windows in doubt: classifier guidance (Dhariwal & Nichol 2021)
with the training clips' nearest-neighbour classifier, on the generator's own noise.
GenMM (Li et al. 2023) gets the same by construction, building each part from the
patches of its own example.

The loss and ``part_fidelity`` share their features, so that measure alone cannot judge
the fit; ``bench/constraints.py`` also classifies the parts by their joint positions,
which the fit never sees, and measures what the fit costs in diversity and coverage.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import torch

from mrlib.errors import (
    ArgumentError,
    MotionValueError,
    check_choice,
    check_flag,
    check_number,
    shown,
)
from mrlib.sampling.arguments import check_parts, checked

__all__ = [
    "MARGIN",
    "SHARPEN_STEPS",
    "Sharpening",
    "part_columns",
    "label_margin_objective",
    "sharpened_features",
    "generate_sharpened",
]

MARGIN = 0.5  # in mean per-frame squared distance of the metric features
SHARPEN_STEPS = 50  # Adam steps of the noise fit (docs/results.md, "Body parts")
_CHUNK = 4096  # reference windows compared at once


@dataclass(frozen=True)
class Sharpening:
    """The noise fit of :func:`generate_sharpened`: ``steps`` Adam steps (0: the plain
    draw), the hinge's ``margin`` and ``push`` (:func:`label_margin_objective`), and
    ``prior_centre`` (``mrlib.sampling.constraints.optimise.optimise_noise``: ``"draw"``
    leaves the noise the hinge does not need as drawn, ``"zero"`` shrinks it, which calms
    a motion and can still it altogether where few windows are in doubt,
    ``docs/results.md``); a progress bar when ``progress``."""

    steps: int = SHARPEN_STEPS
    margin: float = MARGIN
    push: bool = False
    prior_centre: str = "draw"
    progress: bool = False

    def __post_init__(self) -> None:
        from mrlib.sampling.constraints.optimise import check_fit_steps

        object.__setattr__(self, "steps", check_fit_steps(self.steps))
        object.__setattr__(self, "margin", check_number("Sharpening.margin", self.margin, low=0))
        object.__setattr__(self, "push", check_flag("Sharpening.push", self.push))
        object.__setattr__(self, "progress", check_flag("Sharpening.progress", self.progress))
        check_choice("Sharpening.prior_centre", self.prior_centre, ("draw", "zero"))


def _sharpening(name: str, value) -> Sharpening:
    if not isinstance(value, Sharpening):
        raise ArgumentError(f"{name} must be a Sharpening(steps=...), got {shown(value)}")
    return value


def part_columns(part) -> np.ndarray:
    """Columns of ``mrlib.metrics.windows.metric_features`` (23 joints x 6D, then 6 contact
    labels) that belong to a part (:func:`mrlib.sampling.constraints.part_joints`): its joints
    but the root, and the contact labels when the part holds the pelvis or a leg joint."""
    from mrlib.sampling.constraints.common import LOWER_BODY_JOINTS, part_joints

    joints = part_joints(part)
    js = [j for j in joints if j > 0]  # the metrics leave out the root joint
    cols = [np.arange(6 * (j - 1), 6 * j) for j in js]
    if 0 in joints or any(j in LOWER_BODY_JOINTS for j in js):
        cols.append(138 + np.arange(6))
    if not cols:
        raise MotionValueError(f"part {part!r} has no joint the metrics compare")
    return np.concatenate(cols)


def _windows(f: torch.Tensor, w: int) -> torch.Tensor:
    """``(..., T, D)`` -> ``(..., T - w + 1, w * D)``: every ``w``-frame window, frame-major."""
    return f.unfold(-2, w, 1).transpose(-1, -2).flatten(-2)


def _nearest(g: torch.Tensor, r: torch.Tensor) -> torch.Tensor:
    """``(N,)`` the smallest squared distance from each row of ``g (N, K)`` to a row of
    ``r (M, K)``, smooth everywhere (no square root)."""
    g2 = g.pow(2).sum(-1, keepdim=True)
    best = None
    for i in range(0, len(r), _CHUNK):
        rc = r[i : i + _CHUNK]
        d = (g2 - 2 * g @ rc.T + rc.pow(2).sum(-1)).clamp_min(0).min(-1).values
        best = d if best is None else torch.minimum(best, d)
    return best


@checked(parts=check_parts)
def label_margin_objective(
    model, parts: Mapping[str, str], *, margin: float = MARGIN, window: int = 30,
    push: bool = False,
):  # fmt: skip
    """The loss of generator output ``x (B, C, T)`` (normalised) that the fit lowers
    (module docstring): per part of ``parts`` (``{part: label}``), the mean over its
    windows of ``max(0, d_own - d_other + margin)``, averaged over the parts. It is 0
    for a motion whose every window is nearer its part's own label by ``margin``.
    ``push``: the gradient also flows through ``d_other``, pushing a window away from
    the other labels as well as pulling it to its own; off by default: on the Bandai
    walks it kept more diversity but made the samples jerkier and slide more than
    pulling alone (``docs/results.md``, "Body parts")."""
    from mrlib.metrics.windows import model_references
    from mrlib.representation.rotations import matrix_to_6d
    from mrlib.sampling.constraints.optimise import decode

    if not (np.isfinite(margin) and margin >= 0):
        raise MotionValueError(f"margin must be a number >= 0, got {margin!r}")
    _, labels, feats = model_references(model)
    if len(set(labels)) < 2:
        raise MotionValueError("sharpening a label needs a model of two labels or more")
    terms = []
    for part, label in parts.items():
        label = model.labels[model.label_index(label)]
        cols = part_columns(part)
        own, other = [], []
        for f, lab in zip(feats, labels, strict=True):
            if len(f) >= window:
                wins = _windows(torch.from_numpy(f[:, cols]).float(), window)
                (own if lab == label else other).append(wins)
        if not own or not other:
            raise MotionValueError(
                f"no training window of {window} frames for {part}={label} or for the other labels"
            )
        on = model.device  # the references live where the generator runs, made once
        terms.append(
            (torch.from_numpy(cols).to(on), torch.cat(own).to(on), torch.cat(other).to(on))
        )

    def loss_fn(x: torch.Tensor) -> torch.Tensor:
        if x.shape[-1] < window:
            raise MotionValueError(f"the motion has {x.shape[-1]} frames, fewer than {window}")
        d = decode(model, x)
        six = matrix_to_6d(d["rotations"][:, :, 1:]).flatten(2)  # (B, T, 138)
        f = torch.cat([six, d["contacts"].clamp(0, 1)], -1)  # as metric_features
        loss = x.new_zeros(())
        for cols, own, other in terms:
            g = _windows(f[..., cols], window).flatten(0, 1)
            d_own = _nearest(g, own) / window
            d_other = _nearest(g if push else g.detach(), other) / window
            loss = loss + torch.relu(d_own - d_other + margin).mean()
        return loss / len(terms)

    return loss_fn


def sharpened_features(
    model, noises, conds, parts: Mapping, fit: Sharpening = Sharpening()
) -> torch.Tensor:
    """Generator output ``(B, C, T)`` (normalised) for the noise maps ``noises`` and the
    checked per-level conditions ``conds`` (``mrlib.sampling.generation.draw_noise``,
    ``check_conditions``) after the fit ``fit`` towards ``parts`` (``{part: label}``)."""
    from mrlib.sampling.constraints.optimise import optimise_noise

    loss_fn = label_margin_objective(model, parts, margin=fit.margin, push=fit.push)
    noises, _ = optimise_noise(model, noises, conds, loss_fn, steps=fit.steps,
                               prior_centre=fit.prior_centre, progress=fit.progress)  # fmt: skip
    with torch.no_grad():
        return model.generator.run_batch(noises, conds)


def _part_names(name: str, value):
    """``generate_sharpened``'s parts: a list of part names (or of joint lists)."""
    from mrlib.errors import check_list

    return check_list(
        name, value, lambda n, v: v, what="a list of part names, e.g. ['upper', 'lower']"
    )


@checked(parts=_part_names, fit=_sharpening)
def generate_sharpened(
    model,
    condition: str | int,
    parts: Sequence[str] = ("upper", "lower"),
    length: int | None = None,
    *,
    seed: int | None = None,
    num: int | None = None,
    sampler=None,
    fit: Sharpening = Sharpening(),
):
    """Samples of label ``condition`` (the draw of ``mrlib.generate`` for ``seed`` and
    ``sampler``; the same samples when ``fit.steps`` is 0) after the noise fit ``fit``
    (:class:`Sharpening`: ``SHARPEN_STEPS`` Adam steps by default) towards ``condition``
    on each of ``parts`` (module docstring). ``sampler``: a ``mrlib.Sampler``; default
    the raw output with the generator's contact labels (``raw_sampler()``: one draw, no clean-up).
    Returns a ``Motion``, or with ``num=k`` a list of k, as ``mrlib.generate``."""
    from mrlib.representation.features import features_to_motions
    from mrlib.sampling.cleanup import cleanup_foot_contacts, jitter_at
    from mrlib.sampling.conditions import Condition
    from mrlib.sampling.constraints.common import part_joints
    from mrlib.sampling.generation import (
        check_conditions,
        draw_noise,
        generate,
        label_inputs,
        sampler_record,
        shaped_samples,
        training_floor,
    )
    from mrlib.sampling.sampler import raw_sampler

    sampler = raw_sampler(sampler)
    if fit.steps == 0:
        return generate(model, condition, length=length, seed=seed, num=num, sampler=sampler)
    num_samples = 1 if num is None else num
    W = Condition.label(condition).weights(model)
    lengths, amp, conds = label_inputs(model, W, length, sampler)
    noises = draw_noise(lengths, amp, seed, num_samples, model.device)
    conds = check_conditions(model, conds, lengths, num_samples)
    x = sharpened_features(model, noises, conds, {p: condition for p in parts}, fit)
    label = model.labels[model.label_index(condition)]
    names = [f"{label}_sharp_seed{seed}_{b}" for b in range(num_samples)]
    motions = features_to_motions(x.transpose(1, 2), model.fps, betas=model.betas,
                                  normalizer=model.normalizer, label=label, names=names)  # fmt: skip
    from mrlib.sampling.contact_labels import output_contacts, reads_at_rate

    if reads_at_rate(model, sampler, W):  # as generate reads them
        c = output_contacts(model, x, W)
        motions = [m.replace(contacts=c[b]) for b, m in enumerate(motions)]
    for b, m in enumerate(motions):  # as generate records it, and the fit
        m.meta["sampler"] = sampler_record(model, sampler, seed, b, W)
        m.meta["sampler"]["sharpen"] = {
            "joints": [list(part_joints(p)) for p in parts], "steps": fit.steps,
            "margin": fit.margin, "push": fit.push, "prior_centre": fit.prior_centre,
        }  # fmt: skip
    if sampler.fps is not None and sampler.fps != model.fps:  # as generate raises them
        motions = [m.resample(sampler.fps, smooth=True, keep_duration=True) for m in motions]
    if sampler.fix_contacts:  # as generate plants them
        floor = training_floor(model, [model.label_index(condition)])
        jitter = jitter_at(sampler.fps or model.fps, model.fps)
        motions = [cleanup_foot_contacts(m, floor=floor, jitter=jitter) for m in motions]
    return shaped_samples(motions, None, num)
