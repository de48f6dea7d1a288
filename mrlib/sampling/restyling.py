"""Restyle a clip of one's own: keep its coarse motion, add a learned label's detail (or
the reverse).

The pyramid of a trained model splits motion by temporal resolution: level ``k`` runs at
``fps_k = fps * T_k / T_L`` and holds what varies slower than its Nyquist frequency
``fps_k / 2``; levels ``k+1..L`` add the rest, each a residual on the upsampled level
below (paper Eq. 5-6). :func:`restyle` feeds a clip that is not the model's own into
that chain:

- ``keep="coarse"`` (default): the clip is resampled to the model's frame rate, turned
  into the model's normalised features and taken down the pyramid to level ``k`` with
  the pyramid's own linear resampling (``mrlib.model.pyramid.build_pyramid``). That level-k
  clip stands in for the generator's level-k output; levels ``k+1..L`` then run as in
  sampling, under the target label and their own noise (a seed, drawn as
  ``mrlib.sampling.generation.generate`` draws it for the same length). A small ``k`` keeps little
  of the clip (its path, its rhythm), a large one keeps nearly all of it.
- ``keep="detail"``: the reverse. Levels ``1..k`` are generated under the label, at the
  clip's pyramid lengths, and the clip's residual above level ``k`` (the clip minus its
  level-k version upsampled again) is added to the label's level-k output upsampled.

**Where the clip faces.** The features hold the root's global orientation and its
ground-plane velocity in world axes, so a model trained on clips that all walk along +Z
has never seen a walk along +X. The clip is first turned about the vertical so that its
mean facing direction is the training clips' mean facing direction, restyled there, and
turned back (``align=True``; a rigid turn, exact in the features).

**Root travel and facing follow the clip.** The restyled clip's ground-plane root
velocity takes its low band from the clip (below the Nyquist frequency of level ``k``,
the zero-phase low-pass of ``mrlib.metrics.bands.lowpass``): the generated velocity ``v``
becomes ``v + lowpass(v_clip - v)``, so the label's detail (the speed's rise and fall
within a stride) stays and the path integrates to the clip's up to a bounded wobble.
The facing (yaw of the pelvis) is corrected the same way, by the low band of the
per-frame yaw difference. With ``keep="detail"`` both bands of the ground velocity come
from the clip, so the root travels exactly as the clip's. The root height is generated
like any other channel. The result starts where the clip starts and has the clip's body
shape (``betas``).

**Inversion.** The direct route puts the clip itself at level ``k``; when the clip is
far from anything the coarse levels produce, the fine levels see input unlike anything
they were trained on. ``coarse_gap`` (``mrlib.evaluation.restyle_evidence``) measures
how far (the per-frame distance from the clip's level-k frames to the nearest level-k
frame of the training clips, over how far the training clips are from one another),
and ``invert=True`` fits the coarse levels' noise (``mrlib.sampling.constraints.optimise``,
the networks frozen, under the target label) so that their level-k output comes as close
to the clip's level k as the model can make it, and uses that output instead. It costs
about 2 s per clip where the direct route costs milliseconds, and on the unseen Bandai
clips measured (walks, side walks, a bow and a wave; coarse gaps 0.7-2.1) it kept less
of the clip (its low band 1.4-4 times further from the clip's) and gave the label as
often, once in a while one pair more: the direct route is the default.

The measures of a result are ``mrlib.evaluation.restyle_evidence``'s (evaluation sits
above sampling): ``restyle_evidence`` against the three claims (the path kept, the low
band nearer the clip's than any training clip's, the residual nearest the target
label's), ``restyle_shares`` how much of the result is the clip's and how much the
label's, level by level. Measured figures: ``docs/notes/2026-12-04-restyle.md``.

``mrlib.restyle`` is :func:`restyle` (``mrlib.restyle(model, "clip.bvh", "walk_sad")``).

Dimension letters (``mrlib`` glossary): T frames, C feature channels, D metric channels,
L levels, K labels.
"""

from __future__ import annotations

import time
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import torch

from mrlib.errors import (
    ArgumentError,
    ClipTooShortError,
    MotionValueError,
    check_choice,
    shown,
)
from mrlib.metrics.bands import lowpass
from mrlib.model.networks import MultiResGenerator
from mrlib.model.pyramid import level_fps, pyramid_lengths, resample_linear
from mrlib.model.trained import check_model
from mrlib.representation.features import (
    NUM_FEATURES,
    ROOT_SLICE,
    features_to_motion,
    motion_to_features,
)
from mrlib.representation.motion import Motion
from mrlib.representation.rotations import matrix_to_6d, sixd_to_matrix
from mrlib.sampling.arguments import checked
from mrlib.threads import with_policy

__all__ = [
    "KEEP",
    "INVERT_STEPS",
    "RESTYLE_LEVELS_ABOVE",
    "restyle",
    "restyle_level",
    "restyle_lengths",
]

KEEP = ("coarse", "detail")  # what of the clip survives: its coarse levels, or its detail
INVERT_STEPS = 200  # Adam steps of the coarse noise fit (invert=True)
INVERT_LR = 0.05
INVERT_PRIOR = 1e-3  # weight of mean(e_i^2) on the whitened noise (1e-2 kept less of clips)
# The default level k is this many levels below the finest (k = 6 of 8): on the demo model
# of four Bandai walks, the lowest k at which the residual took the target label's detail
# in >= 80 % of (unseen clip, other label) pairs on both training seeds (82 % and 82 %;
# at k = 4, 61 % and 58 %); lower k give more of the label and less of the clip
# (docs/notes/2026-12-04-restyle.md).
RESTYLE_LEVELS_ABOVE = 2
_GROUND = [ROOT_SLICE.start, ROOT_SLICE.start + 2]  # vx, vz: the root's ground velocity


# -- checks --------------------------------------------------------------------------------
def check_label_model(model: Any) -> Any:
    """``model`` if it is a label-conditioned ``GenerativeModel``, else a clear error."""
    if hasattr(model, "feature_config") and hasattr(model, "model"):
        raise MotionValueError(
            "restyle needs a label-conditioned model; this is a speech-conditioned one "
            "(its condition is audio, not a label: use mrlib.speech.generate_from_audio)"
        )
    gen = getattr(model, "generator", None)
    if gen is None or not hasattr(model, "labels"):
        raise MotionValueError(
            f"restyle needs a mrlib.sampling.generation.GenerativeModel, got {type(model).__name__}"
        )
    if int(gen.cond_dim) != len(model.labels):
        raise MotionValueError(
            "restyle needs a label-conditioned model; this one's condition has "
            f"{gen.cond_dim} channels for {len(model.labels)} label(s) (a speech model?)"
        )
    if model.num_levels < 2:
        raise MotionValueError("restyle needs a model with at least two levels")
    return model


def restyle_level(model: Any, level: int | None) -> int:
    """``level`` checked against ``model`` (an integer in ``1..L-1``); None gives the
    default, ``L - 2`` (``RESTYLE_LEVELS_ABOVE`` below the finest)."""
    L = model.num_levels
    if level is None:
        return max(1, L - RESTYLE_LEVELS_ABOVE)
    if isinstance(level, bool) or not isinstance(level, (int, np.integer)):
        raise MotionValueError(f"restyle level must be an integer, got {level!r}")
    if not 1 <= level <= L - 1:
        raise MotionValueError(
            f"restyle level must be in 1..{L - 1} (the clip keeps levels 1..k, the label "
            f"makes k+1..{L}; keep='detail' the reverse), got {level}"
        )
    return int(level)


def at_model_rate(model: Any, motion: Motion | str | Path, resample: bool = True) -> Motion:
    """``motion`` (or the file it names) as a ``Motion``, resampled to the model's frame
    rate unless ``resample`` is False. A clip longer than ``MAX_SAMPLE_SECONDS`` at that
    rate (a long one, or a few frames at a tiny frame rate) is refused before any
    resampling."""
    if isinstance(motion, (str, Path)):
        from mrlib.io import load_motion

        motion = load_motion(motion)
    if not isinstance(motion, Motion):
        raise MotionValueError(
            f"restyle takes a Motion or a motion file, got {type(motion).__name__}"
        )
    check_restyle_length(model, motion)
    if resample and abs(motion.fps - model.fps) > 1e-6:
        motion = motion.resample(model.fps)
    return motion


def check_restyle_length(model: Any, motion: Motion) -> int:
    """The frames ``motion`` has at the model's frame rate, or a ``MotionValueError``
    when that is longer than ``MAX_SAMPLE_SECONDS`` (computed, not resampled)."""
    from mrlib.sampling.generation import MAX_SAMPLE_SECONDS

    frames = motion.resampled_frames(model.fps)
    if frames > MAX_SAMPLE_SECONDS * model.fps + 1:
        name = motion.meta.get("source", motion.name or "the clip")
        raise MotionValueError(
            f"{name}: {motion.num_frames} frames at {motion.fps:g} fps are {frames} frames "
            f"({frames / model.fps:.4g} s) at the model's {model.fps:g} fps, longer than the "
            f"{MAX_SAMPLE_SECONDS:.0f} s mrlib restyles in one pass; cut it into pieces, or "
            "check its frame rate"
        )
    return frames


def restyle_lengths(model: Any, frames: int, name: str = "the clip") -> list[int]:
    """``[T_1, ..., T_L]`` of a clip of ``frames`` frames at the model's frame rate, or a
    ``ClipTooShortError`` that says how long a clip this model needs."""
    mc = model.config.model
    pad = (mc.kernel_size - 1) // 2

    def lengths(n: int) -> list[int] | None:
        try:
            return pyramid_lengths(n, mc.num_levels, mc.scale_factor, min_length=pad + 1)
        except ClipTooShortError:
            return None

    out = lengths(int(frames)) if frames >= 2 else None
    if out is None:
        lo, hi = 2, 4
        while lengths(hi) is None:  # the shortest clip the pyramid holds: double, bisect
            lo, hi = hi, 2 * hi
        while lo < hi:
            mid = (lo + hi) // 2
            lo, hi = (lo, mid) if lengths(mid) is not None else (mid + 1, hi)
        raise ClipTooShortError(
            f"{name} is too short to restyle: {frames} frames at the model's {model.fps:g} fps "
            f"({frames / model.fps:.2f} s); its {mc.num_levels}-level pyramid needs at least "
            f"{hi} frames ({hi / model.fps:.2f} s)"
        )
    return out


# -- yaw of the features (also mrlib.evaluation.restyle_evidence's) -------------------------
def _yaw_matrices(theta: np.ndarray) -> np.ndarray:
    """``(..., 3, 3)`` rotations by ``theta`` about +Y (+Z turns towards +X)."""
    c, s = np.cos(theta), np.sin(theta)
    R = np.zeros(np.shape(theta) + (3, 3))
    R[..., 0, 0], R[..., 0, 2], R[..., 1, 1], R[..., 2, 0], R[..., 2, 2] = c, s, 1.0, -s, c
    return R


def headings(f: np.ndarray) -> np.ndarray:
    """``(T,)`` facing of the pelvis (radians about +Y, 0 along +Z) of features ``(T, C)``."""
    R = sixd_to_matrix(torch.from_numpy(np.asarray(f[:, :6], np.float64))).numpy()
    return np.arctan2(R[:, 0, 2], R[:, 2, 2])


def mean_heading(headings: np.ndarray) -> float:
    """The circular mean of facing angles (radians)."""
    return float(np.arctan2(np.sin(headings).mean(), np.cos(headings).mean()))


def turn_about_vertical(
    f: np.ndarray, theta: float | np.ndarray, ground: bool = True
) -> np.ndarray:
    """Features ``(T, C)`` turned about the vertical by ``theta`` (a number or ``(T,)``):
    the pelvis orientation and, with ``ground``, the ground velocity."""
    f = np.array(f, np.float64)
    Ry = _yaw_matrices(np.broadcast_to(np.asarray(theta, np.float64), (len(f),)))
    R = sixd_to_matrix(torch.from_numpy(f[:, :6])).numpy()
    f[:, :6] = matrix_to_6d(torch.from_numpy(Ry @ R)).numpy()
    if ground:
        vx, vz = f[:, _GROUND[0]].copy(), f[:, _GROUND[1]].copy()
        f[:, _GROUND[0]] = Ry[:, 0, 0] * vx + Ry[:, 0, 2] * vz
        f[:, _GROUND[1]] = Ry[:, 2, 0] * vx + Ry[:, 2, 2] * vz
    return f


def training_heading(model: Any) -> float:
    """The mean facing of the model's training clips (radians about +Y)."""
    return mean_heading(np.concatenate([headings(np.asarray(x)) for x in model.features]))


# -- the generator, level by level ---------------------------------------------------------
class _Levels(torch.nn.Module):
    """The first ``k`` level generators of a model as a generator of their own (what
    ``mrlib.sampling.constraints.optimise.optimise_noise`` runs while it fits the coarse noise)."""

    run_batch = MultiResGenerator.run_batch

    def __init__(self, generator: MultiResGenerator, k: int) -> None:
        super().__init__()
        self.levels = generator.levels[:k]


def _run_levels(model: Any, x: torch.Tensor | None, start: int, stop: int, noises, conds):
    """Levels ``start..stop-1`` (0-based) on ``x``, the output of level ``start - 1``
    (None at level 0): ``(1, C, T_{stop-1})``."""
    gen = model.generator
    with torch.inference_mode():
        for i in range(start, stop):
            n = noises[i].shape[-1]
            x_up = noises[i].new_zeros(1, NUM_FEATURES, n) if x is None else resample_linear(x, n)
            x = gen.levels[i](x_up, noises[i], conds[i])
    return x


def _fit_coarse(model: Any, target: torch.Tensor, noises, conds, steps: int, progress: bool):
    """Noise of levels ``1..k`` fitted so that level ``k`` comes close to ``target
    (1, C, T_k)``; returns that output and the RMS error before and after the fit.

    Each level's noise is fitted per channel, starting from the seed's draw on every
    channel (sampling shares one map over the channels): one map per level was too
    few to follow a clip (on the demo model, walk_sad_002 at level 4: RMS 0.32 -> 0.19
    in 200 steps against 0.32 -> 0.05 per channel)."""
    from mrlib.sampling.constraints.optimise import optimise_noise

    k = len(noises)
    view = SimpleNamespace(generator=_Levels(model.generator, k))
    noises = [z.expand(-1, target.shape[1], -1).clone() for z in noises]

    def loss_fn(x: torch.Tensor) -> torch.Tensor:
        return (x - target).pow(2).mean()

    with torch.no_grad():
        before = float(loss_fn(view.generator.run_batch(noises, conds)).sqrt())
    fitted, _ = optimise_noise(view, noises, conds, loss_fn, steps=int(steps), lr=INVERT_LR,
                               prior=INVERT_PRIOR, progress=progress)  # fmt: skip
    with torch.no_grad():
        out = view.generator.run_batch(fitted, conds)
    return out, before, float(loss_fn(out).sqrt())


# -- restyle -------------------------------------------------------------------------------
def _clip(name: str, value: Any) -> Any:
    import os

    if isinstance(value, (Motion, str, os.PathLike)):
        return value
    raise ArgumentError(f"{name} must be a Motion or a motion file, got {shown(value)}")


@checked(model=check_model, motion=_clip, keep=lambda n, v: check_choice(n, v, KEEP))
@with_policy
def restyle(
    model: Any,
    motion: Motion | str | Path,
    label: str | int,
    level: int | None = None,
    *,
    keep: str = "coarse",
    seed: int | None = None,
    invert: bool = False,
    invert_steps: int = INVERT_STEPS,
    align: bool = True,
    fix_contacts: bool | str = True,
    body: Any = None,
    progress: bool = False,
) -> Motion:
    """``motion`` restyled towards ``label`` (method: module docstring).

    Args:
        model: a label-conditioned ``mrlib.sampling.generation.GenerativeModel``.
        motion: the clip, a ``Motion`` or a file ``mrlib.io.load_motion`` reads; any
            length the pyramid can hold (:func:`restyle_lengths`), any frame rate (it is
            resampled to the model's). A long clip runs in one pass.
        label: the target label (name or index).
        level: ``k`` in ``1..L-1``: the clip's levels ``1..k`` are kept (``keep="coarse"``)
            or replaced by the label's (``keep="detail"``); default ``L - 2``
            (:func:`restyle_level`).
        keep: ``"coarse"`` or ``"detail"``.
        seed: the noise of the label's levels (None: a fresh draw).
        invert: ``keep="coarse"`` only: fit the coarse levels' noise to the clip
            (``invert_steps`` Adam steps) and run the fine levels on the model's own
            level-k output instead of the clip's (for clips far from the training data,
            ``mrlib.evaluation.restyle_evidence.coarse_gap``).
        align: turn the clip to the training clips' mean facing first (and back after).
        fix_contacts: plant the feet (``mrlib.sampling.generation.cleanup_foot_contacts``; a method
            name, or False for the raw result).
        body: body model for the contact labels of a clip that has none and for the
            clean-up (default: mrlib's).
    Returns:
        A ``Motion`` at the model's frame rate with the clip's number of frames there,
        its label the target label; ``meta["restyle"]`` records how it was made.
    """
    from mrlib.representation.body import resolve_body
    from mrlib.sampling.cleanup import cleanup_foot_contacts
    from mrlib.sampling.generation import (
        check_conditions,
        draw_noise,
        guided_weights,
        label_weights,
        noise_amplitude,
    )

    t0 = time.perf_counter()
    model = check_label_model(model)
    if keep not in KEEP:
        raise MotionValueError(f"keep must be one of {KEEP}, got {keep!r}")
    if invert and keep != "coarse":
        raise MotionValueError("invert fits the coarse levels to the clip: keep='coarse' only")
    if invert:
        from mrlib.sampling.constraints.optimise import check_fit_steps

        invert_steps = check_fit_steps(invert_steps, "invert_steps", minimum=1)
    k = restyle_level(model, level)
    lab = model.label_index(label)
    motion = at_model_rate(model, motion, resample=False)
    source = at_model_rate(model, motion)
    name = source.name or "clip"
    T = source.num_frames
    lengths = restyle_lengths(model, T, name)
    L = model.num_levels
    body = resolve_body(body, shared=True)

    f_in = motion_to_features(source, body).double().numpy()  # (T, C)
    turn = training_heading(model) - mean_heading(headings(f_in)) if align else 0.0
    f_in = turn_about_vertical(f_in, turn)
    dev = model.device
    x = model.normalizer.normalize(torch.from_numpy(f_in).float()).T[None].to(dev)  # (1, C, T)
    x_k = resample_linear(x, lengths[k - 1])

    W = label_weights(model, condition=lab)
    G = guided_weights(model, W)
    conds = check_conditions(model, [G[i].expand(1, n, -1) for i, n in enumerate(lengths)], lengths)
    noises = draw_noise(lengths, noise_amplitude(model, W), seed, 1, dev)
    fit = None
    if keep == "coarse":
        start = x_k
        if invert:
            start, before, after = _fit_coarse(model, x_k, noises[:k], conds[:k],
                                               invert_steps, progress)  # fmt: skip
            fit = {"steps": int(invert_steps), "rms_before": before, "rms_after": after}
        y = _run_levels(model, start, k, L, noises, conds)
    else:
        y_k = _run_levels(model, None, 0, k, noises, conds)
        y = resample_linear(y_k, T) + (x - resample_linear(x_k, T))
    out = model.normalizer.denormalize(y[0].T.double().cpu()).numpy()  # (T, C)

    cutoff = level_fps(model.fps, lengths)[k - 1] / 2
    if keep == "coarse":
        out[:, _GROUND] += lowpass(f_in[:, _GROUND] - out[:, _GROUND], model.fps, cutoff)
    else:
        out[:, _GROUND] = f_in[:, _GROUND]
    dyaw = np.unwrap(np.angle(np.exp(1j * (headings(f_in) - headings(out)))))
    out = turn_about_vertical(out, lowpass(dyaw[:, None], model.fps, cutoff)[:, 0], ground=False)
    out = turn_about_vertical(out, -turn)

    tag = model.labels[lab]
    m = features_to_motion(
        torch.from_numpy(out).float(), model.fps, betas=source.betas,
        origin=source.trans[0, [0, 2]], label=tag,
        name=f"{name}_restyled_{tag}_{keep}{k}",
    )  # fmt: skip
    if keep == "detail":
        from mrlib.representation.contacts import foot_contacts

        m = m.replace(contacts=foot_contacts(m, body))
    m.meta["restyle"] = {
        "source": str(source.meta.get("source", name)), "source_fps": float(motion.fps),
        "label": tag, "level": k, "keep": keep, "seed": seed, "align_deg": float(np.degrees(turn)),
        "cutoff_hz": float(cutoff), "invert": fit, "fine_noise": float(model.fine_noise),
        "guidance": float(model.guidance), "seconds": time.perf_counter() - t0,
    }  # fmt: skip
    if fix_contacts:
        method = fix_contacts if isinstance(fix_contacts, str) else "ik"
        m = cleanup_foot_contacts(m, body, method=method)
    return m
