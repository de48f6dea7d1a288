"""Restyle a clip of one's own: keep its coarse motion, add a learned label's detail (or
the reverse).

The pyramid of a trained model splits motion by temporal resolution: level ``k`` runs at
``fps_k = fps * T_k / T_L`` and holds what varies slower than its Nyquist frequency
``fps_k / 2``; levels ``k+1..L`` add the rest, each a residual on the upsampled level
below (paper Eq. 6-7). :func:`restyle` feeds a clip that is not the model's own into
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
within a stride) stays. Integrated, that velocity still wanders off the clip's path: its
high band's integral is not bounded (at ``k = 2``, worst frames 16 cm off on unseen
Bandai walks with the demo model of the four walks, 66 cm with the demo model of the
synthetic clips). So the root is then laid on the clip's ground path by time
(:func:`relay_root_path`): the clip's path plus the generated path's sway about it (the
part of their difference above the cutoff), eased in and out over ``PATH_EASE_S`` at the
ends and scaled down where it goes beyond ``PATH_SWAY_M`` (3 cm). The result starts and
ends where the clip does (at the same times) and never leaves its path by more than the
bound, at any frame rate of the clip. The result comes back at the clip's own frame rate
and frame count (``Sampler.fps``: another rate): the model's output is resampled by cubic
splines, then laid on the clip's path and its feet planted at that rate. The facing (yaw of
the pelvis) is corrected by the low band of the per-frame yaw difference. With
``keep="detail"`` both bands of the ground velocity come from the clip, so the root
travels as the clip's. The root height is generated like any other channel (the label's
bob). The foot clean-up (``Sampler.fix_contacts``) runs with ``keep_path=True``
(``mrlib.sampling.cleanup.cleanup_foot_contacts``): it may lift the root onto the floor
but leaves its ground path alone, the legs taking what the planted feet need; the
clean-up that moves the root took it up to 1.9 m (four walks' model) and 5.3 m
(synthetic model) off the clip's path at ``k = 2``, where the generated feet skate
against the clip's travel (``bench/restyle_path.py``). The result has the clip's body
shape (``betas``).

**Not inverted.** The clip itself stands at level ``k``; when it is far from anything the
coarse levels produce (``coarse_gap``, ``mrlib.evaluation.restyle_evidence``), the fine
levels see input unlike their training. Fitting the coarse levels' noise to the clip
first and restyling the model's own version of it was measured and did worse: on the
unseen Bandai clips it kept less of the clip (its low band 1.4-4 times further from the
clip's) and gave the label as often, once in a while one pair more, at about 2 s per
clip (``docs/notes/2026-12-04-restyle.md``, ``docs/notes/2026-12-06-study-options.md``).

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
from mrlib.metrics.bands import check_split_level, lowpass
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

__all__ = [
    "KEEP",
    "PATH_SWAY_M",
    "RESTYLE_LEVELS_ABOVE",
    "relay_root_path",
    "restyle",
    "restyle_level",
    "restyle_lengths",
]

KEEP = ("coarse", "detail")  # what of the clip survives: its coarse levels, or its detail
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
    return check_split_level(
        level, L, "restyle level",
        f"the clip keeps levels 1..k, the label makes k+1..{L}; keep='detail' the reverse",
    )  # fmt: skip


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


# -- the root's ground path ------------------------------------------------------------------
PATH_SWAY_M = 0.03  # m: the farthest the restyled root's ground path leaves the clip's
PATH_EASE_S = 0.25  # s: over this at each end the sway eases in from (out to) zero
SWAY_WINDOW_S = 1.0  # s: the sway is scaled down by its largest excursion over about this


def _bounded_sway(d: np.ndarray, fps: float, sway: float) -> np.ndarray:
    """``d (T, 2)`` scaled down where it goes beyond ``sway`` (m): by a gain that follows
    the largest excursion within about ``SWAY_WINDOW_S`` (a maximum filter, then a
    Gaussian), so the sway keeps its shape, only smaller; a last per-frame clamp makes
    the bound exact."""
    from scipy.ndimage import gaussian_filter1d, maximum_filter1d

    if sway <= 0:
        return np.zeros_like(d)
    r = np.linalg.norm(d, axis=1)
    w = max(1, round(SWAY_WINDOW_S * fps))
    env = gaussian_filter1d(maximum_filter1d(r, 2 * w + 1, mode="nearest"), w / 2, mode="nearest")
    d = d * np.minimum(1.0, sway / np.maximum(env, 1e-12))[:, None]
    r = np.linalg.norm(d, axis=1)
    return d * np.minimum(1.0, sway / np.maximum(r, 1e-12))[:, None]


def relay_root_path(
    trans: np.ndarray, path: np.ndarray, fps: float, cutoff_hz: float, sway: float = PATH_SWAY_M
) -> np.ndarray:
    """Root translation ``trans (T, 3)`` laid on the ground path of ``path (T, 3)`` (the
    clip's, frame by frame at the same times): ``path``'s x and z plus the sway of
    ``trans`` about it, i.e. the part of their difference above ``cutoff_hz`` (the
    label's detail: the speed's rise and fall within a stride, the pelvis's side to side),
    eased in and out over ``PATH_EASE_S`` at both ends and scaled down where it goes
    beyond ``sway`` m (:func:`_bounded_sway`). The height is ``trans``'s. So the result
    starts and ends on ``path`` and never leaves it by more than ``sway``, whatever the
    generated velocities integrate to; ``sway=0`` gives ``path``'s ground path."""
    trans = np.asarray(trans, np.float64)
    path = np.asarray(path, np.float64)
    if trans.shape != path.shape or trans.ndim != 2 or trans.shape[1] != 3:
        raise MotionValueError(
            f"relay_root_path needs two (T, 3) translations, got {trans.shape} and {path.shape}"
        )
    T = len(trans)
    d = trans[:, [0, 2]] - path[:, [0, 2]]
    # at a rate that cannot hold cutoff_hz (under 2 cutoff_hz fps) there is no sway to keep
    d = d - lowpass(d, fps, cutoff_hz) if T > 1 and cutoff_hz < fps / 2 else np.zeros_like(d)
    n = max(1, min(round(PATH_EASE_S * fps), T // 4))
    ramp = np.sin(0.5 * np.pi * np.arange(n) / n) ** 2  # 0 at the end frame itself
    w = np.ones(T)
    w[:n] = ramp
    w[T - n :] = np.minimum(w[T - n :], ramp[::-1])
    out = trans.copy()
    out[:, [0, 2]] = path[:, [0, 2]] + _bounded_sway(d * w[:, None], fps, float(sway))
    return out


# -- the generator, level by level ---------------------------------------------------------
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


# -- restyle -------------------------------------------------------------------------------
def _clip(name: str, value: Any) -> Any:
    import os

    if isinstance(value, (Motion, str, os.PathLike)):
        return value
    raise ArgumentError(f"{name} must be a Motion or a motion file, got {shown(value)}")


@checked(model=check_model, motion=_clip, keep=lambda n, v: check_choice(n, v, KEEP))
def restyle(
    model: Any,
    motion: Motion | str | Path,
    label: str | int,
    level: int | None = None,
    *,
    keep: str = "coarse",
    seed: int | None = None,
    align: bool = True,
    sampler: Any = None,
    body: Any = None,
) -> Motion:
    """``motion`` restyled towards ``label`` (method: module docstring).

    Args:
        model: a label-conditioned ``mrlib.sampling.generation.GenerativeModel``.
        motion: the clip, a ``Motion`` or a file ``mrlib.io.load_motion`` reads; any
            length the pyramid can hold (:func:`restyle_lengths`), any frame rate (it is
            resampled to the model's, and the result back to the clip's). A long clip
            runs in one pass.
        label: the target label (name or index).
        level: ``k`` in ``1..L-1``: the clip's levels ``1..k`` are kept (``keep="coarse"``)
            or replaced by the label's (``keep="detail"``); default ``L - 2``
            (:func:`restyle_level`).
        keep: ``"coarse"`` or ``"detail"``.
        seed: the noise of the label's levels (None: a fresh draw).
        align: turn the clip to the training clips' mean facing first (and back after).
        sampler: a ``mrlib.Sampler``: the fine noise and guidance of the label's levels,
            the output's frame rate (``fps``; None: the clip's own), and whether the feet
            are planted (``fix_contacts``,
            ``mrlib.sampling.cleanup.cleanup_foot_contacts`` with ``keep_path=True``: the
            root keeps the clip's ground path; False for the raw result).
        body: body model for the contact labels of a clip that has none and for the
            clean-up (default: mrlib's).
    Returns:
        A ``Motion`` at the clip's frame rate with the clip's number of frames (drawn at
        the model's rate and resampled by cubic splines, ``Motion.resample(smooth=True)``,
        before the feet are planted; ``Sampler(fps=model.fps)``: at the model's rate with
        the clip's number of frames there), its label the target label, its root on the clip's ground path (within
        ``PATH_SWAY_M``, exactly at the first and last frame); ``meta["restyle"]``
        records how it was made.
    """
    from mrlib.representation.body import resolve_body
    from mrlib.sampling.cleanup import cleanup_foot_contacts, jitter_at
    from mrlib.sampling.conditions import Condition
    from mrlib.sampling.generation import (
        check_conditions,
        draw_noise,
        guided_weights,
        noise_amplitude,
    )
    from mrlib.sampling.sampler import Sampler

    t0 = time.perf_counter()
    sampler = Sampler() if sampler is None else sampler
    model = check_label_model(model)
    if keep not in KEEP:
        raise MotionValueError(f"keep must be one of {KEEP}, got {keep!r}")
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

    W = Condition.label(lab).weights(model)
    G = guided_weights(W, sampler)
    conds = check_conditions(model, [G[i].expand(1, n, -1) for i, n in enumerate(lengths)], lengths)
    noises = draw_noise(lengths, noise_amplitude(model, W, sampler), seed, 1, dev)
    if keep == "coarse":
        y = _run_levels(model, x_k, k, L, noises, conds)
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
    # drawn at the model's rate; out at the clip's (or the sampler's) by cubic splines,
    # before the root is laid on the clip's path and the feet are planted at that rate
    fps = float(motion.fps if sampler.fps is None else sampler.fps)
    path = motion if abs(fps - motion.fps) < 1e-6 else motion.resample(fps)
    if m.num_frames != path.num_frames or abs(fps - model.fps) > 1e-6:
        m = m.resample(fps, smooth=True, frames=path.num_frames)
    trans = relay_root_path(m.trans, path.trans, fps, cutoff)
    m = m.replace(trans=trans.astype(m.trans.dtype))
    if keep == "detail":
        from mrlib.representation.contacts import foot_contacts

        m = m.replace(contacts=foot_contacts(m, body))
    m.meta["restyle"] = {
        "source": str(source.meta.get("source", name)), "source_fps": float(motion.fps),
        "label": tag, "level": k, "keep": keep, "seed": seed, "align_deg": float(np.degrees(turn)),
        "cutoff_hz": float(cutoff), "path_sway_m": PATH_SWAY_M, "fine_noise": sampler.fine_noise,
        "guidance": sampler.guidance, "seconds": time.perf_counter() - t0,
    }  # fmt: skip
    if sampler.fix_contacts:  # its jitter filter spans the same time as at the model's rate
        m = cleanup_foot_contacts(m, body, keep_path=True, jitter=jitter_at(fps, model.fps))
    return m
