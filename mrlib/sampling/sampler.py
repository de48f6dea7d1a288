"""Sampler settings: how a trained generator is sampled, passed to every generation call
(``mrlib.generate(model, "walk", sampler=Sampler(fine_noise=0.5))``) rather than kept on
the model. Training and reconstructions use none of them.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import numpy as np

from mrlib.errors import MotionValueError
from mrlib.representation.motion import MAX_FPS

__all__ = [
    "Sampler",
    "raw_sampler",
    "model_frames",
    "FINE_NOISE",
    "GUIDANCE",
    "CANDIDATES",
    "MAX_FINE_NOISE",
    "MAX_GUIDANCE",
    "MAX_CANDIDATES",
]

# Amplitude of the finest level's noise at sampling, as a share of its training sigma_L
# (the paper's sampler: 1). That noise, modulated by the fine label's FiLM parameters,
# carries the fine label's detail into a crossover; it also reaches the output as
# frame-to-frame jitter. On the Bandai walks, 0 made samples as smooth as the capture
# (jerk 1.51x -> 1.04x the clip's) at the same coverage and fidelity, but crossovers
# took the fine label's detail in 20 of 24 cases instead of 24 (docs/results.md,
# "Jitter and the finest level's noise").
FINE_NOISE = 1.0

# Label guidance at sampling: each level's condition vector pushed away from the mean of
# all labels, W + g (W - 1/K), which moves the FiLM embedding (linear in W) by g times its
# distance from the average label's. 0 is the paper's sampler. On the Bandai walks
# (two training seeds) 0.25 raised condition fidelity by 3.4-3.8 points at the same
# coverage and +0.01-0.02 global diversity; 1 by 6-7 points, but coverage at eps 1 fell
# to 58-72 % and raw foot skating rose by 23-26 points: the samples exaggerate their
# label and leave the training poses (docs/results.md, "Label guidance").
GUIDANCE = 0.0

MAX_GUIDANCE = MAX_FINE_NOISE = 10.0  # 1 already leaves the training poses

# Candidates per label sample, ranked by the model's critics (mrlib.sampling.ranking); 1 is
# the paper's sampler. Chosen on the development walks (docs/results.md, "Critic-ranked
# sampling"): 8 raised the lowest label's condition fidelity from 83 to 90-91 % and its
# coverage at eps 1, and lowered global diversity by 0.04-0.1; judged on held-out styles
# after. Each sample costs 8 generator passes and 8 critic passes (the clean-up once).
CANDIDATES = 8
MAX_CANDIDATES = 64


@dataclass(frozen=True)
class Sampler:
    """Settings of a draw.

    Attributes:
        fine_noise: scale of the finest level's noise (1: the paper's sampler; 0: the
            smoothest motion), in [0, ``MAX_FINE_NOISE``].
        guidance: how far each level's label mix is pushed away from the mean of all labels
            (0: off), in [0, ``MAX_GUIDANCE``]; ``W + g (W - 1/K)``.
        fix_contacts: plant the feet with the foot-contact clean-up
            (``mrlib.sampling.cleanup.cleanup_foot_contacts``, on the floor of the
            training clips); False for the generator's raw output (clean it yourself
            with other options: ``cleanup_foot_contacts(m, body, ...)``).
        fps: the frame rate of the output; None: the model's. The model draws at its own
            rate (the ``preview`` preset: 15 fps), and the raw draw is resampled to ``fps``
            (raised, or lowered for a model trained above its clips' rate) by cubic splines
            (``Motion.resample(fps, smooth=True)``) before the clean-up plants the feet at
            that rate (its jitter filter spans the same time as at the model's rate:
            ``JITTER_SIGMA`` model frames). ``length`` still counts the model's frames; the
            output lasts as long: ``round(length * fps / model.fps)`` frames. Used by
            ``mrlib.generate`` (``mrlib sample --fps``), the paths, loops, body parts,
            keyframes (their frames count at ``fps``) and continuations of
            ``mrlib.sampling.constraints``, and ``mrlib.restyle`` (None for these two: the
            given clip's rate).
        candidates: draws per label sample, of which the one the model's critics score
            highest is kept (``mrlib.sampling.ranking``; 1: the paper's sampler, every
            draw kept), in [1, ``MAX_CANDIDATES``]. Label samples of a model with critics
            (every checkpoint mrlib writes) only; speech samples and restyling draw once.
        match_contact_rate: True: label each foot vertex in contact on as many frames
            as the condition's training clips are (``mrlib.sampling.contact_labels``: the
            frames of highest contact output); False: where the output exceeds 0.5 (the
            paper's sampler); None (the default): as the model chose for the condition's
            main label when its training ended (``GenerativeModel.contact_at_rate``,
            ``mrlib.sampling.contact_choice``; 0.5 for a model without a choice). Label
            samples only (``mrlib.generate`` and the paths, keyframes, continuations,
            loops and body parts of ``mrlib.sampling.constraints``). The rate raised the
            slow walks' fidelity of the 30-fps ``demo`` models and lowered the happy
            walk's of the 15-fps ``preview`` models (docs/notes/2026-12-07-contact-rate.md).
    """

    fine_noise: float = FINE_NOISE
    guidance: float = GUIDANCE
    fix_contacts: bool = True
    fps: float | None = None
    candidates: int = CANDIDATES
    match_contact_rate: bool | None = None

    def __post_init__(self):
        for name, bound in (("fine_noise", MAX_FINE_NOISE), ("guidance", MAX_GUIDANCE)):
            v = getattr(self, name)
            if isinstance(v, (bool, np.bool_)) or not isinstance(v, numbers.Real):
                raise MotionValueError(f"{name} must be a number, got {v!r}")
            v = float(v)
            if not (math.isfinite(v) and 0 <= v <= bound):
                raise MotionValueError(f"{name} must be in [0, {bound:g}], got {v!r}")
            object.__setattr__(self, name, float(v))
        c = self.candidates
        if (
            isinstance(c, bool)
            or not isinstance(c, numbers.Integral)
            or not 1 <= c <= MAX_CANDIDATES
        ):
            raise MotionValueError(
                f"candidates must be a whole number in [1, {MAX_CANDIDATES}], got {c!r}"
            )
        object.__setattr__(self, "candidates", int(c))
        for name in ("fix_contacts", "match_contact_rate"):
            v = getattr(self, name)
            if v is None and name == "match_contact_rate":
                continue
            if not isinstance(v, (bool, np.bool_)):
                either = "True, False or None" if name == "match_contact_rate" else "True or False"
                raise MotionValueError(f"{name} must be {either}, got {v!r}")
            object.__setattr__(self, name, bool(v))
        if self.fps is not None:
            v = self.fps
            if (
                isinstance(v, (bool, np.bool_))
                or not isinstance(v, numbers.Real)
                or not (math.isfinite(v) and 0 < v <= MAX_FPS)
            ):
                raise MotionValueError(
                    f"fps must be a frame rate in (0, {MAX_FPS:g}] or None, got {v!r}"
                )
            object.__setattr__(self, "fps", float(v))


def raw_sampler(sampler: Sampler | None = None) -> Sampler:
    """``sampler``, or for None the paper's sampler, one draw per sample and no
    foot-contact clean-up (``Sampler(fix_contacts=False, candidates=1,
    match_contact_rate=False)``): what measurements
    of the generator itself draw by default (crossover evidence, the nearest-sequence
    strips; contacts cut at 0.5). Anything else is an ``ArgumentError``."""
    if sampler is None:
        return Sampler(fix_contacts=False, candidates=1, match_contact_rate=False)
    if not isinstance(sampler, Sampler):
        from mrlib.errors import ArgumentError, shown

        raise ArgumentError(f"sampler must be a mrlib.Sampler or None, got {shown(sampler)}")
    return sampler


def model_frames(seconds: float, model_fps: float, least: int = 2) -> int:
    """Frames a model at ``model_fps`` draws for ``seconds`` of motion: enough that the
    draw raised or lowered to any output rate ``fps`` (``Sampler.fps``) holds at least
    ``round(seconds * fps)`` frames, to which the command line and ``generate_on_path``
    cut it (``ceil``; ``round`` at the model's rate would give 64 frames at 30 fps for
    2.1 s of a 15-fps model)."""
    return max(least, math.ceil(seconds * model_fps - 1e-9))
