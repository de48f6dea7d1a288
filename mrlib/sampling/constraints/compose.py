"""Body-part composition: different conditions for different joint groups.

A splice: one motion per condition with the same noise, each group's joint rotations
taken from its own (the root and the contact labels from the group holding the pelvis).
It works across models too (:func:`splice_parts`: upper body from a speech model, legs
from a label model).

Each part of a splice keeps its own sample's timing, so arms and legs drawn at two
cadences swing out of step; ``align_gait`` retimes the other parts to the gait of the
part holding the pelvis (:func:`gait_phase`: the phase of the ankles' stride from the
analytic signal, Hilbert transform; :func:`arm_leg_coordination` measures the result).

The alternative measured against it, one generator pass with each group's channels
modulated by its own condition (FiLM), kept the parts' labels less often on the Bandai
walks: ``bench/experiments/film_parts.py``, ``docs/notes/2026-12-06-study-options.md``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace

import numpy as np
import torch

from mrlib.errors import ArgumentError, MotionValueError, check_text, shown
from mrlib.representation.motion import Motion
from mrlib.representation.skeleton import JOINT_NAMES, NUM_JOINTS
from mrlib.sampling.arguments import check_parts, checked
from mrlib.sampling.conditions import Condition
from mrlib.sampling.constraints.common import (
    disjoint_parts,
)
from mrlib.sampling.sampler import Sampler

__all__ = [
    "generate_parts",
    "splice_parts",
    "gait_phase",
    "phase_align",
    "arm_leg_coordination",
    "part_fidelity",
]


def _motion_parts(name: str, value):
    """``splice_parts``'s ``{part or joints: Motion}``."""
    from mrlib.errors import ArgumentError, shown
    from mrlib.representation.motion import check_motion

    if not isinstance(value, Mapping) or not value:
        raise ArgumentError(f"{name} must be a dict {{part or joints: Motion}}, got {shown(value)}")
    for part, m in value.items():
        check_motion(f"{name}[{part!r}]", m)
    return value


def _groups(parts: Mapping) -> list[tuple[tuple[int, ...], object]]:
    """``[(joints, condition)]`` covering every joint once; joints no part names join
    the part holding the pelvis, or else the first part."""
    if not parts:
        raise MotionValueError("give at least one part=condition")
    groups = list(zip(disjoint_parts(list(parts)), parts.values(), strict=True))
    rest = set(range(NUM_JOINTS)) - set().union(*(js for js, _ in groups))
    if rest:
        k = next((i for i, (js, _) in enumerate(groups) if 0 in js), 0)
        groups[k][0].update(rest)
    return [(tuple(sorted(js)), c) for js, c in groups]


def _part_condition(name: str, value) -> Condition:
    """``generate_parts``'s parts: a dict ``{part: label}`` or a ``Condition.parts``."""
    if isinstance(value, Condition):
        if value.parts_of is None:
            raise ArgumentError(
                f"{name} must be a dict {{part: label}} or a Condition.parts(...), got a "
                f"condition of no body parts: {value!r}"
            )
        return value
    return Condition.parts(check_parts(name, value))


def _sharpening(name: str, value):
    """``generate_parts``'s ``sharpen``: Adam steps (0: off) or a ``Sharpening``."""
    from mrlib.sampling.constraints.optimise import check_fit_steps
    from mrlib.sampling.constraints.sharpen import Sharpening

    if isinstance(value, Sharpening):
        return value
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ArgumentError(
            f"{name} must be Adam steps (an integer, 0: off) or a Sharpening(...), got "
            f"{shown(value)}"
        )
    return Sharpening(steps=check_fit_steps(value, "sharpen (steps)"))


@checked(parts=_part_condition, sharpen=_sharpening)
def generate_parts(
    model,
    parts: Mapping | Condition,
    *,
    length: int | None = None,
    seed: int | None = None,
    num: int | None = None,
    sampler=None,
    sharpen=0,
    body=None,
):
    """A label model's motion with each body part under its own label (a splice: module
    docstring): ``parts={"upper": "walk_happy", "lower": "walk_sad"}``, or
    ``Condition.parts({...}, in_step=True)``, whose ``in_step`` takes each other part
    from a sample retimed to the gait of the part holding the pelvis (:func:`phase_align`),
    so the arms swing in step with the legs; it costs some of the part's own label where
    the labels' cadences differ (``docs/results.md``, "Body parts").

    Args:
        length, seed, num: as ``mrlib.generate`` (every part's samples are the draws of
            ``seed``).
        sampler: a ``mrlib.Sampler``: the draws' fine noise and guidance, the output's
            frame rate (``fps``: each draw raised as ``mrlib.generate`` raises it; None:
            the model's); its ``fix_contacts`` plants the feet of the spliced motion.
        sharpen: Adam steps of the noise fit that moves each part's windows nearer its
            own label's training clips than any other's, or a ``Sharpening`` (its margin,
            a progress bar; ``mrlib.sampling.constraints.sharpen``); ``SHARPEN_STEPS`` is
            the benchmarked length, 0 is off; 50 steps take seconds per sample where a
            draw takes milliseconds (``docs/results.md``, "Body parts").
    Returns:
        A ``Motion`` (label ``"upper=walk_happy,lower=walk_sad"``), or with ``num=k`` a
        list of k, as ``mrlib.generate``.
    """
    from mrlib.sampling.cleanup import cleanup_foot_contacts, jitter_at
    from mrlib.sampling.constraints.sharpen import generate_sharpened
    from mrlib.sampling.generation import shaped_samples

    sampler = Sampler() if sampler is None else sampler
    fit = _sharpening("generate_parts: sharpen", sharpen)  # the default too
    raw = replace(sampler, fix_contacts=False)
    count = 1 if num is None else num
    labels = parts.part_labels()
    align_gait = parts.in_step
    groups = _groups(labels)
    tag = parts.name(model)

    def draw(c, n):
        own = [js for js, cc in groups if cc == c]  # the parts this sample gives
        return generate_sharpened(model, c, own, n, seed=seed, num=count, sampler=raw, fit=fit)

    base_c = next(c for js, c in groups if 0 in js)
    motions = {base_c: draw(base_c, length)}
    first = motions[base_c][0]
    T = round(first.num_frames * model.fps / first.fps)  # the model's frames (Sampler.fps)
    for _, c in groups:
        if c in motions:
            continue
        # retimed to the pelvis part's gait (align_gait), a sample of a label that
        # walks slower needs more frames to cover as many strides
        n = _frames_to_cover(model, base_c, c, T, body) if align_gait else length
        motions[c] = draw(c, n)
    out = []
    for b in range(count):
        pick = {js: motions[c][b] for js, c in groups}
        out.append(splice_parts(pick, name=f"{tag}_seed{seed}_{b}", align=align_gait,
                                body=body))  # fmt: skip
    if sampler.fix_contacts:  # its jitter filter spans the same time at any output rate
        out = [cleanup_foot_contacts(m, body, jitter=jitter_at(m.fps, model.fps))
               for m in out]  # fmt: skip
    for m in out:
        m.label = tag
        m.meta["parts"] = dict(labels)
    return shaped_samples(out, None, num)


# Gait phase (gait_phase): the legs' stride signal is the difference of the two ankles'
# forward offsets from the pelvis, in the body's own frame, smoothed over GAIT_SMOOTH_S
# seconds; a motion walks when that signal's standard deviation is at least GAIT_MIN_M.
GAIT_SMOOTH_S = 0.1
GAIT_MIN_M = 0.05


def _stride_signal(motion: Motion, body=None) -> np.ndarray:
    """``(T,)`` left minus right ankle forward offset from the pelvis (m), body frame."""
    from scipy.ndimage import gaussian_filter1d

    rel = _forward_offsets(motion, body)
    f = rel[:, JOINT_NAMES.index("left_ankle")] - rel[:, JOINT_NAMES.index("right_ankle")]
    return gaussian_filter1d(f - f.mean(), GAIT_SMOOTH_S * motion.fps, mode="nearest")


def body_frame_joints(motion: Motion, body=None) -> np.ndarray:
    """``(T, 24, 3)`` joint positions relative to the pelvis (m), in the body's own frame
    (the root orientation undone: SMPL's body faces +z)."""
    from mrlib.metrics.plausibility import motion_kinematics
    from mrlib.representation.rotations import axis_angle_to_matrix

    J = motion_kinematics(motion, body)[0]
    R = axis_angle_to_matrix(torch.as_tensor(motion.poses[:, 0], dtype=torch.float64)).numpy()
    return np.einsum("tji,tkj->tki", R, J - J[:, :1])  # R^T (J - pelvis)


def _forward_offsets(motion: Motion, body=None) -> np.ndarray:
    """``(T, 24)`` each joint's forward offset from the pelvis (m) in the body's frame."""
    return body_frame_joints(motion, body)[..., 2]


@checked()
def arm_leg_coordination(motion: Motion, body=None) -> float:
    """How much the arms swing in step with the legs: the correlation over time of each
    wrist's forward offset from the pelvis with the opposite ankle's, averaged over the
    two sides (1: in step, as in a walk; 0: unrelated; the Bandai walks' clips 0.44-0.95)."""
    f = _forward_offsets(motion, body)
    f = f - f.mean(0)
    n = JOINT_NAMES.index

    def corr(a: str, b: str) -> float:
        x, y = f[:, n(a)], f[:, n(b)]
        den = np.sqrt((x * x).sum() * (y * y).sum())
        return float((x * y).sum() / den) if den > 0 else 0.0

    return 0.5 * (corr("left_wrist", "right_ankle") + corr("right_wrist", "left_ankle"))


@checked()
def gait_phase(motion: Motion, body=None) -> np.ndarray | None:
    """``(T,)`` the gait phase of ``motion`` in radians, unwrapped and non-decreasing:
    the angle of the analytic signal (Hilbert transform) of its stride signal, the
    ankles' forward offsets from the pelvis (module constants). None when the motion
    does not walk (stride signal below ``GAIT_MIN_M``)."""
    from scipy.signal import hilbert

    f = _stride_signal(motion, body)
    if f.size < 8 or f.std() < GAIT_MIN_M:
        return None
    phase = np.unwrap(np.angle(hilbert(f)))
    return np.maximum.accumulate(phase)


def _frames_to_cover(model, base, other, frames: int, body=None) -> int:
    """Frames of a sample of label ``other`` that, retimed to the gait of ``frames``
    frames of label ``base`` (:func:`phase_align`), do not run out of strides: by the
    cadences of the model's training clips, the strides of ``base`` at half as many
    again plus one cycle of ``other`` for the start; twice ``frames`` where a label's
    clips do not walk."""
    from mrlib.representation.features import features_to_motion

    def rate(label) -> float | None:  # radians of gait phase per frame
        k = model.label_index(label)
        rates = []
        for x, lab in zip(model.features, model.clip_labels, strict=True):
            if lab == k:
                m = features_to_motion(x, model.fps, betas=model.betas)
                ph = gait_phase(m, body)
                if ph is not None and ph[-1] > ph[0]:
                    rates.append((ph[-1] - ph[0]) / m.num_frames)
        return float(np.median(rates)) if rates else None

    ra, rb = rate(base), rate(other)
    if ra is None or rb is None:
        return 2 * frames
    return int(np.ceil(1.5 * frames * max(1.0, ra / rb) + 2 * np.pi / rb))


@checked()
def phase_align(source: Motion, target: Motion, body=None) -> Motion | None:
    """``source`` retimed to ``target``'s gait: ``target.num_frames`` frames of it,
    frame ``t`` at the source time whose gait phase is ``target``'s at ``t`` (within
    the source's first cycle at the start), so that a part taken from ``source`` (the
    arms) swings in step with ``target``'s legs. None when either does not walk, or
    when ``source`` has too few cycles to follow ``target`` to its end."""
    if source.fps != target.fps:
        raise MotionValueError(
            f"phase_align needs one frame rate, got {source.fps} and {target.fps}"
        )
    ps, pt = gait_phase(source, body), gait_phase(target, body)
    if ps is None or pt is None:
        return None
    # the target's phase on the source's branch, offset by whole cycles so that the
    # start falls in the source's first cycle
    want = pt + 2 * np.pi * np.ceil((ps[0] - pt[0]) / (2 * np.pi))
    if want[-1] > ps[-1]:
        return None
    frames = np.arange(source.num_frames, dtype=np.float64)
    keep = np.concatenate([[True], np.diff(ps) > 0])  # strictly increasing for interp
    return source.at_frames(np.interp(want, ps[keep], frames[keep]))


@checked(parts=_motion_parts, name=lambda n, v: check_text(n, v, optional=True))
def splice_parts(
    parts: Mapping, name: str | None = None, *, align: bool = False, body=None
) -> Motion:
    """One motion from several: ``{part: Motion}`` (parts as :func:`part_joints` takes
    them, or joint-id tuples), each part's joint rotations from its motion; the root
    translation and contact labels from the motion of the part holding the pelvis. The
    motions must share a frame rate. ``align``: each other part's motion is first
    retimed to the gait of the pelvis part's (:func:`phase_align`; left as it is where
    either does not walk or it has too few cycles), so its arms swing with those legs.
    The motions are then cut to the shortest."""
    groups = _groups(parts)
    motions = [m for _, m in groups]
    fps = {m.fps for m in motions}
    if len(fps) != 1:
        raise MotionValueError(f"motions to splice need one frame rate, got {sorted(fps)}")
    base = next(m for js, m in groups if 0 in js)
    if align:
        aligned = []
        for js, m in groups:
            moved = None if 0 in js else phase_align(m, base, body)
            aligned.append((js, m if moved is None else moved))
        groups = aligned
    T = min(m.num_frames for _, m in groups)
    poses = base.poses[:T].copy()
    for js, m in groups:
        poses[:, list(js)] = m.poses[:T, list(js)]
    return base.replace(
        poses=poses,
        trans=base.trans[:T].copy(),
        contacts=None if base.contacts is None else base.contacts[:T].copy(),
        name=name or base.name,
        meta=dict(base.meta),
    )


@checked(parts=check_parts)
def part_fidelity(
    motions: Sequence[Motion], model, parts: Mapping[str, str], window: int = 30
) -> dict[str, float]:
    """Condition fidelity measured on each part alone: the share of a part's windows
    whose nearest training window (on that part's joint rotations; the lower body also
    on the contact labels) belongs to the part's own label."""
    from mrlib.metrics.coverage import condition_fidelity
    from mrlib.metrics.windows import metric_features, model_references
    from mrlib.sampling.constraints.sharpen import part_columns

    _, labels, feats = model_references(model)
    out = {}
    for part, cond in parts.items():
        cols = part_columns(part)
        refs = {
            lab: np.concatenate(
                [f[:, cols] for f, lb in zip(feats, labels, strict=True) if lb == lab]
            )
            for lab in dict.fromkeys(labels)
        }
        gen = [(metric_features(m)[:, cols], cond) for m in motions]
        out[part] = condition_fidelity(gen, refs, window=window)
    return out
