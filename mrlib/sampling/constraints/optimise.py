"""Test-time optimisation of the noise maps with the networks frozen.

The generator maps noise maps ``z_i`` (one per level) and a condition to a motion. With
the networks frozen, a constraint expressed as a differentiable loss of the output can
be met by moving the noise: ``z_i = sigma_i * e_i`` with ``e_i`` optimised by Adam from
the seed's draw, plus a prior ``prior * mean(e_i^2)`` that keeps it a plausible draw.
The output stays on what the generator can produce, so it looks like the model's own
motion; what the model never learned (a turn, for a model of straight walks) stays out
of reach, which is why paths use bending by default (``mrlib.sampling.constraints.path``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass
from numbers import Integral, Real

import torch

from mrlib.errors import ArgumentError, MotionValueError, check_flag, shown
from mrlib.progress import bar as progress_bar
from mrlib.representation.features import ROOT_SLICE, ROT_SLICE, root_velocity_to_trans
from mrlib.representation.rotations import sixd_to_matrix

__all__ = [
    "optimise_noise",
    "decode",
    "frozen",
    "check_fit_steps",
    "MAX_FIT_STEPS",
    "NoiseFit",
    "check_noise_fit",
    "FIT_LR",
    "FIT_PRIOR",
]

# Adam steps of one noise fit: 10 x the largest default (the keyframes' 300; continuation
# 100, sharpening 50). Each step runs the generator forwards and back, ~10-50 ms on the
# CPU for a clip of seconds: 1e8 would run for weeks.
MAX_FIT_STEPS = 3000
FIT_LR = 0.05  # Adam's step size on the whitened noise
FIT_PRIOR = 1e-2  # weight of mean(e_i^2) (a draw of N(0, 1) has 1)


def check_fit_steps(steps, name: str = "steps", minimum: int = 0) -> int:
    """``steps`` as an int if it is a whole number in ``[minimum, MAX_FIT_STEPS]``, else a
    one-line ``MotionValueError`` naming ``name`` (the argument or flag) and the cap."""
    whole = isinstance(steps, Integral) or (
        isinstance(steps, Real) and math.isfinite(steps) and float(steps).is_integer()
    )
    if isinstance(steps, bool) or not whole or steps < minimum:
        raise MotionValueError(f"{name} must be an integer >= {minimum}, got {steps!r}")
    if steps > MAX_FIT_STEPS:
        raise MotionValueError(
            f"{name}: {int(steps)} Adam steps are more than the {MAX_FIT_STEPS} of one noise "
            f"fit (the defaults are 50-300 and take seconds); pass at most {MAX_FIT_STEPS}"
        )
    return int(steps)


@dataclass(frozen=True)
class NoiseFit:
    """How a constraint fits the noise: ``steps`` Adam steps (0: none), with a progress
    bar when ``progress``. (Whether the feet of the result are planted is the sampler's
    ``fix_contacts``, ``mrlib.Sampler``.)"""

    steps: int = 100
    progress: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "steps", check_fit_steps(self.steps))
        object.__setattr__(self, "progress", check_flag("NoiseFit.progress", self.progress))


def check_noise_fit(name: str, value) -> NoiseFit:
    """A :class:`NoiseFit` (for ``mrlib.sampling.arguments.checked``)."""
    if not isinstance(value, NoiseFit):
        raise ArgumentError(
            f"{name} must be a NoiseFit(steps=..., progress=...), got {shown(value)}"
        )
    return value


@contextmanager
def frozen(module: torch.nn.Module):
    """No gradients for ``module``'s parameters inside the block (restored after)."""
    flags = [p.requires_grad for p in module.parameters()]
    for p in module.parameters():
        p.requires_grad_(False)
    try:
        yield module
    finally:
        for p, f in zip(module.parameters(), flags, strict=True):
            p.requires_grad_(f)


def decode(model, x: torch.Tensor) -> dict[str, torch.Tensor]:
    """Differentiable view of generator output ``x (B, C, T)`` (normalised features):
    ``rotations (B, T, 24, 3, 3)`` (local, joint 0 global), ``trans (B, T, 3)`` (root
    translation integrated from the origin) and ``contacts (B, T, 6)``, the contact
    channels as generated."""
    f = model.normalizer.denormalize(x.transpose(1, 2))  # (B, T, C)
    B, T, _ = f.shape
    R = sixd_to_matrix(f[..., ROT_SLICE].reshape(B, T, 24, 6))
    trans = root_velocity_to_trans(f[..., ROOT_SLICE], model.fps)
    return {"rotations": R, "trans": trans, "contacts": f[..., ROOT_SLICE.stop :]}


def optimise_noise(
    model,
    noises: list[torch.Tensor],
    conds: list,
    loss_fn: Callable[[torch.Tensor], torch.Tensor],
    *,
    steps: int = 100,
    prior_centre: str = "zero",
    progress: bool = False,
) -> tuple[list[torch.Tensor], list[float]]:
    """Move the noise maps to lower ``loss_fn(x)`` of the output ``x (B, C, T_L)``.

    Args:
        model: a ``GenerativeModel`` (its generator stays frozen).
        noises: per level ``(B, 1, T_i)``, the starting draw (``mrlib.sampling.generation.draw_noise``).
        conds: per level conditions as ``MultiResGenerator.run_batch`` takes them.
        loss_fn: scalar loss of the generator's normalised output.
        steps: Adam iterations (step size ``FIT_LR``) on the whitened noise ``e_i``.
        prior_centre: ``"zero"``: a prior ``FIT_PRIOR * mean(e_i^2)`` (a draw of N(0, 1)
            has 1); ``"draw"``: ``mean((e_i - e_i0)^2)``, the distance from the starting
            draw instead. Adam scales each step to about ``FIT_LR`` whatever the
            gradient's size, so under ``"zero"`` noise that the loss
            does not need still shrinks towards 0 (a calmer, less diverse motion);
            ``"draw"`` leaves it where it was drawn.
    Returns:
        The optimised noise maps and the loss after each step.
    """
    steps = check_fit_steps(steps)
    gen = model.generator
    # each sample's noise whitened by its own scale
    scale = [z.detach().std(dim=(1, 2), keepdim=True).clamp_min(1e-6) for z in noises]
    eps = [
        (z.detach() / s).clone().requires_grad_(True) for z, s in zip(noises, scale, strict=True)
    ]
    if prior_centre not in ("zero", "draw"):
        raise ValueError(f"prior_centre must be 'zero' or 'draw', got {prior_centre!r}")
    centre = [e.detach().clone() if prior_centre == "draw" else 0.0 for e in eps]
    opt = torch.optim.Adam(eps, lr=FIT_LR)
    history = []
    with frozen(gen), torch.enable_grad():
        for _ in progress_bar(range(steps), desc="optimising noise", enabled=progress, leave=False):
            opt.zero_grad()
            x = gen.run_batch([e * s for e, s in zip(eps, scale, strict=True)], conds)
            reg = sum((e - c).pow(2).mean() for e, c in zip(eps, centre, strict=True)) / len(eps)
            loss = loss_fn(x) + FIT_PRIOR * reg
            loss.backward()
            opt.step()
            history.append(float(loss.detach()))
    return [(e * s).detach() for e, s in zip(eps, scale, strict=True)], history
