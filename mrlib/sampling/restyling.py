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
they were trained on. :func:`coarse_gap` measures how far (the per-frame distance from
the clip's level-k frames to the nearest level-k frame of the training clips, over how
far the training clips are from one another), and ``invert=True`` fits the coarse
levels' noise (``mrlib.sampling.constraints.optimise``, the networks frozen, under the target
label) so that their level-k output comes as close to the clip's level k as the model
can make it, and uses that output instead. It costs about 2 s per clip where the
direct route costs milliseconds, and on the unseen Bandai clips measured (walks, side
walks, a bow and a wave; coarse gaps 0.7-2.1) it kept less of the clip (its low band
1.4-4 times further from the clip's) and gave the label as often, once in a while one pair
more: the direct route is the default.

:func:`restyle_evidence` measures a result against the three claims (the path kept, the
low band nearer the clip's than any training clip's, the residual nearest the target
label's); :func:`restyle_shares` how much of the result is the clip's and how much the
label's, level by level. Measured figures: ``docs/notes/2026-12-04-restyle.md``.

``mrlib.sampling.restyling`` is this module, and calling it calls :func:`restyle`
(``mrlib.restyle(model, "clip.bvh", "walk_sad")``); its other names are reached as
usual (``mrlib.sampling.restyling.coarse_gap``, ``from mrlib.sampling.restyling import restyle_evidence``).
The module is long because the measures live beside the method they measure: the
bench, the tests and the widget share them.

Dimension letters (``mrlib`` glossary): T frames, C feature channels, D metric channels,
L levels, K labels.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import torch

from mrlib.errors import ClipTooShortError, MotionValueError
from mrlib.metrics.bands import lowpass, rms_profile, split_bands
from mrlib.metrics.paper import frame_distances, metric_features
from mrlib.model.networks import MultiResGenerator
from mrlib.model.pyramid import level_fps, pyramid_lengths, resample_linear
from mrlib.representation.features import (
    CONTACT_SLICE,
    NUM_FEATURES,
    ROOT_SLICE,
    features_to_motion,
    motion_to_features,
)
from mrlib.representation.motion import Motion
from mrlib.representation.rotations import matrix_to_6d, sixd_to_matrix
from mrlib.threads import with_policy

__all__ = [
    "KEEP",
    "INVERT_STEPS",
    "RESTYLE_LEVELS_ABOVE",
    "restyle",
    "restyle_level",
    "restyle_lengths",
    "CoarseGap",
    "coarse_gap",
    "RestyleReferences",
    "restyle_references",
    "RestyleEvidence",
    "restyle_evidence",
    "RestyleShares",
    "restyle_shares",
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
REFERENCE_SEED = 1_000_003  # the label references share no noise with the restyled clips
_GROUND = [ROOT_SLICE.start, ROOT_SLICE.start + 2]  # vx, vz: the root's ground velocity


# -- checks --------------------------------------------------------------------------------
def _label_model(model: Any) -> Any:
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


def _at_model_rate(model: Any, motion: Motion | str | Path, resample: bool = True) -> Motion:
    if isinstance(motion, (str, Path)):
        from mrlib.io import load_motion

        motion = load_motion(motion)
    if not isinstance(motion, Motion):
        raise MotionValueError(
            f"restyle takes a Motion or a motion file, got {type(motion).__name__}"
        )
    if resample and abs(motion.fps - model.fps) > 1e-6:
        motion = motion.resample(model.fps)
    return motion


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


# -- yaw of the features -------------------------------------------------------------------
def _yaw_matrices(theta: np.ndarray) -> np.ndarray:
    """``(..., 3, 3)`` rotations by ``theta`` about +Y (+Z turns towards +X)."""
    c, s = np.cos(theta), np.sin(theta)
    R = np.zeros(np.shape(theta) + (3, 3))
    R[..., 0, 0], R[..., 0, 2], R[..., 1, 1], R[..., 2, 0], R[..., 2, 2] = c, s, 1.0, -s, c
    return R


def _headings(f: np.ndarray) -> np.ndarray:
    """``(T,)`` facing of the pelvis (radians about +Y, 0 along +Z) of features ``(T, C)``."""
    R = sixd_to_matrix(torch.from_numpy(np.asarray(f[:, :6], np.float64))).numpy()
    return np.arctan2(R[:, 0, 2], R[:, 2, 2])


def _mean_heading(headings: np.ndarray) -> float:
    return float(np.arctan2(np.sin(headings).mean(), np.cos(headings).mean()))


def _turn(f: np.ndarray, theta: float | np.ndarray, ground: bool = True) -> np.ndarray:
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


def _training_heading(model: Any) -> float:
    return _mean_heading(np.concatenate([_headings(np.asarray(x)) for x in model.features]))


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
            :func:`coarse_gap`).
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
    model = _label_model(model)
    if keep not in KEEP:
        raise MotionValueError(f"keep must be one of {KEEP}, got {keep!r}")
    if invert and keep != "coarse":
        raise MotionValueError("invert fits the coarse levels to the clip: keep='coarse' only")
    if invert and (isinstance(invert_steps, bool) or int(invert_steps) < 1):
        raise MotionValueError(f"invert_steps must be a positive integer, got {invert_steps!r}")
    k = restyle_level(model, level)
    lab = model.label_index(label)
    motion = _at_model_rate(model, motion, resample=False)
    source = _at_model_rate(model, motion)
    name = source.name or "clip"
    T = source.num_frames
    lengths = restyle_lengths(model, T, name)
    L = model.num_levels
    body = resolve_body(body, shared=True)

    f_in = motion_to_features(source, body).double().numpy()  # (T, C)
    turn = _training_heading(model) - _mean_heading(_headings(f_in)) if align else 0.0
    f_in = _turn(f_in, turn)
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
    dyaw = np.unwrap(np.angle(np.exp(1j * (_headings(f_in) - _headings(out)))))
    out = _turn(out, lowpass(dyaw[:, None], model.fps, cutoff)[:, 0], ground=False)
    out = _turn(out, -turn)

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


# -- how far the clip is from the coarse levels --------------------------------------------
@dataclass(frozen=True)
class CoarseGap:
    """How far a clip's level-k version is from the training clips' level-k versions.

    ``distance``: mean over the clip's level-k frames of the RMS per channel (normalised
    pose and root channels) to the nearest level-k frame of any training clip;
    ``spread``: the same for each training clip against the others, averaged (how far
    the training clips are from one another; NaN with one clip); ``ratio``: the two's
    quotient. Below 1 the clip is nearer the training data than its clips are to each
    other; well above 1 the fine levels see input unlike anything they were trained on
    (where ``restyle(..., invert=True)`` may help; the module docstring says what it did
    on the clips measured)."""

    level: int
    distance: float
    spread: float
    ratio: float
    nearest_clip: str


def _level_frames(model: Any, f: np.ndarray, n: int) -> np.ndarray:
    """Normalised pose and root channels of features ``(T, C)`` at ``n`` frames, ``(n, D)``."""
    x = model.normalizer.normalize(torch.as_tensor(np.asarray(f), dtype=torch.float32))
    x = resample_linear(x.T[None].cpu(), int(n))[0].T
    return x[:, : CONTACT_SLICE.start].double().numpy()


def coarse_gap(
    model: Any, motion: Motion | str | Path, level: int | None = None, *, align: bool = True,
    body: Any = None,
) -> CoarseGap:  # fmt: skip
    """How far ``motion`` is from what the coarse levels ``1..level`` produce
    (:class:`CoarseGap`), taking the training clips' level-k versions as that: the coarse
    levels reconstruct them (the training's reconstruction loss) and their samples stay
    near them."""
    from mrlib.representation.body import resolve_body

    model = _label_model(model)
    k = restyle_level(model, level)
    source = _at_model_rate(model, motion)
    lengths = restyle_lengths(model, source.num_frames, source.name or "the clip")
    f = motion_to_features(source, resolve_body(body, shared=True)).double().numpy()
    if align:
        f = _turn(f, _training_heading(model) - _mean_heading(_headings(f)))
    D = CONTACT_SLICE.start
    x = _level_frames(model, f, lengths[k - 1])
    refs = [
        _level_frames(model, np.asarray(c), int(model.lengths[n, k - 1]))
        for n, c in enumerate(model.features)
    ]
    per_clip = np.stack([frame_distances(x, r).min(1) for r in refs])  # (N, T_k)
    distance = float(per_clip.min(0).mean() / np.sqrt(D))
    nearest = model.clip_names[int(np.bincount(per_clip.argmin(0), minlength=len(refs)).argmax())]
    spreads = []
    for n, r in enumerate(refs):
        others = [q for j, q in enumerate(refs) if j != n]
        if others:
            d = np.min([frame_distances(r, q).min(1) for q in others], 0)
            spreads.append(d.mean() / np.sqrt(D))
    spread = float(np.mean(spreads)) if spreads else float("nan")
    return CoarseGap(k, distance, spread, distance / spread if spreads else float("nan"), nearest)


# -- measuring a restyled clip -------------------------------------------------------------
@dataclass(frozen=True)
class RestyleReferences:
    """What a restyled clip of ``length`` frames at level ``level`` is compared with:
    the band split's ``cutoff_hz`` (level k's Nyquist frequency), the low bands of the
    training clips and the mean residual RMS profile ``(D,)`` of every label's pure
    samples (or training clips). Built by :func:`restyle_references`."""

    level: int
    length: int
    cutoff_hz: float
    clip_names: tuple[str, ...]
    clip_lows: list[np.ndarray] = field(repr=False)
    label_profiles: dict[str, np.ndarray] = field(repr=False)
    reference: str = "samples"


def restyle_references(
    model: Any, length: int, level: int | None = None, *, num_samples: int = 4,
    seed: int = REFERENCE_SEED, reference: str = "samples",
) -> RestyleReferences:  # fmt: skip
    """The references of :func:`restyle_evidence` for clips of ``length`` frames at the
    model's rate restyled at ``level``: per label, ``num_samples`` pure samples of that
    length (``reference="samples"``, as ``mrlib.evaluation.crossover.crossover_evidence``) or its
    training clips (``"clips"``)."""
    from mrlib.metrics.paper import model_references
    from mrlib.sampling.generation import generate

    model = _label_model(model)
    k = restyle_level(model, level)
    lengths = restyle_lengths(model, int(length))
    cutoff = level_fps(model.fps, lengths)[k - 1] / 2
    if reference not in ("samples", "clips"):
        raise MotionValueError(f"reference must be 'samples' or 'clips', got {reference!r}")
    names, clip_labels, feats = model_references(model, contacts=False)
    lows = [split_bands(f, model.fps, cutoff)[0] for f in feats]
    profiles = {}
    for lab in model.labels:
        if reference == "samples":
            ms = generate(model, lab, length=int(length), seed=seed, num_samples=num_samples,
                          fix_contacts=False)  # fmt: skip
            refs = [metric_features(m, contacts=False) for m in ([ms] if num_samples == 1 else ms)]
        else:
            refs = [f for f, cl in zip(feats, clip_labels, strict=True) if cl == lab]
        profiles[lab] = np.mean(
            [rms_profile(split_bands(r, model.fps, cutoff)[1]) for r in refs], 0
        )
    return RestyleReferences(k, int(length), float(cutoff), tuple(names), lows, profiles, reference)


@dataclass(frozen=True)
class RestyleEvidence:
    """A restyled clip against the three claims.

    ``trajectory_cm``: mean ground distance between the restyled and the source root
    (SMPL translation, same body); ``low_to_source`` / ``low_to_clips``: mean per-frame
    nearest-neighbour distance of the restyled clip's low band (6D local rotations below
    ``cutoff_hz``) to the source's low band and to each training clip's;
    ``residual_to_labels``: distance of its residual's RMS profile to each label's."""

    label: str
    level: int
    cutoff_hz: float
    trajectory_cm: float
    low_to_source: float
    low_to_clips: dict[str, float]
    residual_to_labels: dict[str, float]

    @property
    def low_holds(self) -> bool:
        """The low band is nearer the source's than any training clip's."""
        return self.low_to_source < min(self.low_to_clips.values())

    @property
    def nearest_label(self) -> str:
        """The label whose residual profile is nearest the restyled clip's."""
        return min(self.residual_to_labels, key=self.residual_to_labels.get)

    @property
    def high_holds(self) -> bool:
        """The residual is nearest the target label's."""
        return self.nearest_label == self.label


def restyle_evidence(
    model: Any, restyled: Motion, source: Motion | str | Path,
    references: RestyleReferences | None = None,
) -> RestyleEvidence:  # fmt: skip
    """Measure ``restyled`` (a result of :func:`restyle`, best without the foot clean-up)
    against its ``source`` clip; ``references`` from :func:`restyle_references` (built
    for the restyled clip's length and level when None)."""
    info = restyled.meta.get("restyle", {})
    source = _at_model_rate(model, source)
    if source.num_frames != restyled.num_frames:
        raise MotionValueError(
            f"the source has {source.num_frames} frames at {model.fps:g} fps, the restyled "
            f"clip {restyled.num_frames}: not a restyling of it"
        )
    ref = references or restyle_references(model, restyled.num_frames, info.get("level"))
    if ref.length != restyled.num_frames or info.get("level", ref.level) != ref.level:
        raise MotionValueError(
            f"references for {ref.length} frames at level {ref.level}, a restyled clip of "
            f"{restyled.num_frames} frames at level {info.get('level')}"
        )
    lab = restyled.label if restyled.label in ref.label_profiles else info.get("label")
    if lab not in ref.label_profiles:
        raise MotionValueError(f"the restyled clip's label {lab!r} is not one of the model's")
    d = np.linalg.norm(restyled.trans[:, [0, 2]] - source.trans[:, [0, 2]], axis=1)
    low, high = split_bands(metric_features(restyled, contacts=False), model.fps, ref.cutoff_hz)
    src_low = split_bands(metric_features(source, contacts=False), model.fps, ref.cutoff_hz)[0]
    p = rms_profile(high)
    return RestyleEvidence(
        label=lab,
        level=ref.level,
        cutoff_hz=ref.cutoff_hz,
        trajectory_cm=float(100 * d.mean()),
        low_to_source=_nn(low, src_low),
        low_to_clips={n: _nn(low, c) for n, c in zip(ref.clip_names, ref.clip_lows, strict=True)},
        residual_to_labels={k: float(np.linalg.norm(p - v)) for k, v in ref.label_profiles.items()},
    )


def _nn(x: np.ndarray, ref: np.ndarray) -> float:
    """Mean over the frames of ``x`` of the distance to the nearest frame of ``ref``."""
    return float(frame_distances(x, ref).min(1).mean())


# -- how much clip, how much label ---------------------------------------------------------
@dataclass(frozen=True)
class RestyleShares:
    """Per level ``k``: the mean per-frame nearest-neighbour distance of the restyled
    clip's poses (6D local rotations) to the source clip's (``to_source``) and to the
    target label's own sample (``to_label``; same seed and length), and the source's
    share ``to_label / (to_source + to_label)``: 1 when the result is the source, 0 when
    it is the label's sample, 0.5 halfway."""

    label: str
    keep: str
    levels: tuple[int, ...]
    to_source: np.ndarray
    to_label: np.ndarray

    @property
    def source_share(self) -> np.ndarray:
        return self.to_label / np.maximum(self.to_source + self.to_label, 1e-12)

    def to_markdown(self) -> str:
        rows = [
            "| level k | to source | to label | source share | label share |",
            "|---|---|---|---|---|",
        ]
        for k, a, b, s in zip(self.levels, self.to_source, self.to_label, self.source_share,
                              strict=True):  # fmt: skip
            rows.append(f"| {k} | {a:.3f} | {b:.3f} | {100 * s:.0f}% | {100 * (1 - s):.0f}% |")
        return "\n".join(rows)


def restyle_shares(
    model: Any, motion: Motion | str | Path, label: str | int, *, keep: str = "coarse",
    seed: int = 0, levels: Any = None, body: Any = None, label_sample: Motion | None = None,
) -> RestyleShares:  # fmt: skip
    """How much of a restyling is the clip's and how much the label's, at every level
    (``levels``, default ``1..L-1``): :class:`RestyleShares` of ``restyle(model, motion,
    label, k, keep=keep, seed=seed, fix_contacts=False)``. ``label_sample``: the label's
    own sample to compare with (default ``generate(model, label, length=T, seed=seed)``
    without the foot clean-up)."""
    from mrlib.sampling.generation import generate

    model = _label_model(model)
    source = _at_model_rate(model, motion)
    levels = tuple(range(1, model.num_levels)) if levels is None else tuple(levels)
    ks = [restyle_level(model, k) for k in levels]
    tag = model.labels[model.label_index(label)]
    if label_sample is None:
        label_sample = generate(model, tag, length=source.num_frames, seed=seed, fix_contacts=False)
    src = metric_features(source, contacts=False)
    lab = metric_features(label_sample, contacts=False)
    to_src, to_lab = [], []
    for k in ks:
        r = restyle(model, source, tag, k, keep=keep, seed=seed, fix_contacts=False, body=body)
        x = metric_features(r, contacts=False)
        to_src.append(_nn(x, src))
        to_lab.append(_nn(x, lab))
    return RestyleShares(tag, keep, tuple(ks), np.asarray(to_src), np.asarray(to_lab))
