"""Helpers the constraint modules share: joint ids from names, the named body parts,
a label model's inputs and outputs, the body's rest pelvis."""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np
import torch

from mrlib.errors import MotionValueError, check_args, check_text
from mrlib.representation.motion import Motion
from mrlib.representation.skeleton import JOINT_NAMES, NUM_JOINTS, UPPER_BODY_JOINTS

__all__ = [
    "LOWER_BODY_JOINTS",
    "PARTS",
    "part_joints",
    "parse_parts",
    "joint_ids",
    "label_setup",
    "planted",
    "features_motion",
    "fitted_motion",
    "pelvis_rest",
    "sole_lift",
    "warn_past_the_end",
]

# An open path walked further than its length by more than this (metres, or share of
# the length, whichever is more) warns: past its end the motion goes straight on.
PAST_THE_END_M, PAST_THE_END_SHARE = 1.0, 0.1


def joint_ids(joints) -> tuple[int, ...]:
    """Sorted unique SMPL joint ids of joint names and/or indices."""
    out = []
    for j in joints:
        if isinstance(j, str):
            if j not in JOINT_NAMES:
                raise MotionValueError(f"unknown joint {j!r}; SMPL joints: {list(JOINT_NAMES)}")
            out.append(JOINT_NAMES.index(j))
        else:
            if not 0 <= int(j) < NUM_JOINTS:
                raise MotionValueError(f"joint index {j} is not in [0, {NUM_JOINTS})")
            out.append(int(j))
    return tuple(sorted(set(out)))


LOWER_BODY_JOINTS: tuple[int, ...] = tuple(
    j for j in range(NUM_JOINTS) if j not in UPPER_BODY_JOINTS
)
PARTS: dict[str, tuple[int, ...]] = {
    "upper": UPPER_BODY_JOINTS,
    "lower": LOWER_BODY_JOINTS,
    "left_arm": tuple(JOINT_NAMES.index(n) for n in ("left_collar", "left_shoulder", "left_elbow", "left_wrist", "left_hand")),
    "right_arm": tuple(JOINT_NAMES.index(n) for n in ("right_collar", "right_shoulder", "right_elbow", "right_wrist", "right_hand")),
}  # fmt: skip


def part_joints(part: str | Sequence) -> tuple[int, ...]:
    """Joint ids of a named part (``PARTS``: upper, lower, left_arm, right_arm) or of a
    list of joint names / ids."""
    if isinstance(part, str):
        if part in PARTS:
            return PARTS[part]
        if part in JOINT_NAMES:
            return (JOINT_NAMES.index(part),)
        raise MotionValueError(f"unknown body part {part!r}: use {sorted(PARTS)} or joint names")
    if not isinstance(part, Sequence) or isinstance(part, bytes):
        from mrlib.errors import ArgumentError, shown

        raise ArgumentError(
            f"a body part must be a name ({sorted(PARTS)}, a joint name) or a list of joint "
            f"names or indices, got {shown(part)}"
        )
    return joint_ids(part)


def disjoint_parts(parts) -> list[set[int]]:
    """The joint ids of each of ``parts`` (names or joint lists, :func:`part_joints`), or
    a ``MotionValueError`` naming the first two parts that share a joint, and the joints."""
    groups = [set(part_joints(p)) for p in parts]
    seen: dict[int, object] = {}
    for js, part in zip(groups, parts, strict=True):
        both = sorted(js & seen.keys())
        if both:
            names = ", ".join(JOINT_NAMES[j] for j in both)
            raise MotionValueError(
                f"body parts {seen[both[0]]!r} and {part!r} overlap at {names}: give each "
                "joint to one part (joints no part names go with the pelvis's part)"
            )
        seen.update(dict.fromkeys(js, part))
    return groups


@check_args(spec=check_text)
def parse_parts(spec: str) -> dict[str, str]:
    """``"upper=walk_happy,lower=walk_sad"`` -> ``{"upper": "walk_happy", ...}``; a part
    named twice, an unknown part and parts that share a joint are refused (the second
    would silently replace the first)."""
    out: dict[str, str] = {}
    for item in str(spec).split(","):
        part, eq, cond = item.partition("=")
        if not eq or not part.strip() or not cond.strip():
            raise MotionValueError(f"--parts expects part=label[,part=label...], got {spec!r}")
        part = part.strip()
        if part in out:
            raise MotionValueError(
                f"--parts names the part '{part}' twice ({part}={out[part]}, "
                f"{part}={cond.strip()}); give each part one label"
            )
        out[part] = cond.strip()
    disjoint_parts(list(out))
    return out


def label_setup(model, condition, length: int, seed: int | None, sampler):
    """Noise maps ``[(1, 1, T_i)]`` (the draw ``generate`` makes for ``seed``), checked
    per-level conditions, the label a sample carries (``Condition.name``: ``a+b`` for a
    mix), the condition's weights ``W (L, K)`` where the sampler matches the contact rate
    (else None) and what made the sample (``meta["sampler"]``, as ``generate`` records
    it), for a label condition (a label or a ``mrlib.Condition``; None: the first label)
    under ``sampler``."""
    from mrlib.sampling.conditions import as_condition
    from mrlib.sampling.contact_labels import reads_at_rate
    from mrlib.sampling.generation import check_conditions, draw_noise, label_inputs, sampler_record

    cond = as_condition(0 if condition is None else condition)
    W = cond.weights(model)
    lengths, amp, conds = label_inputs(model, W, length, sampler)
    noises = draw_noise(lengths, amp, seed, 1, model.device)
    rate_of = W if reads_at_rate(model, sampler, W) else None
    record = sampler_record(model, sampler, seed, 0, W)
    return noises, check_conditions(model, conds, lengths), cond.name(model), rate_of, record


def planted(motion: Motion, sampler, body=None, model=None) -> Motion:
    """``motion`` with its feet planted (``mrlib.sampling.cleanup``) when the sampler's
    ``fix_contacts`` asks for it and the motion has contact labels; the jitter filter
    spans the same time as at the rate of ``model`` (when given) at the motion's."""
    if not sampler.fix_contacts or motion.contacts is None:
        return motion
    from mrlib.sampling.cleanup import cleanup_foot_contacts, jitter_at

    jitter = jitter_at(motion.fps, motion.fps if model is None else model.fps)
    return cleanup_foot_contacts(motion, body, jitter=jitter)


def features_motion(model, x: torch.Tensor, label: str | None, name: str, rate_of=None) -> Motion:
    """Generator output ``(1, C, T)`` (normalised) -> Motion at the model's rate; its
    contact labels at the rate of the condition ``rate_of`` (``W``) when given
    (``mrlib.sampling.contact_labels``), else cut at 0.5."""
    from mrlib.representation.features import features_to_motion

    m = features_to_motion(
        x[0].T.detach().cpu(), model.fps, betas=model.betas, normalizer=model.normalizer,
        label=label, name=name,
    )  # fmt: skip
    if rate_of is None:
        return m
    from mrlib.sampling.contact_labels import output_contacts

    return m.replace(contacts=output_contacts(model, x, rate_of)[0])


def pelvis_rest(motion: Motion, body) -> np.ndarray:
    """``(3,)`` rest position of the pelvis for the motion's betas on ``body``."""
    from mrlib.io.bodyfit import rest_pelvis

    return rest_pelvis(body, motion.betas)


def sole_lift(body, betas_from, betas_to) -> float:
    """Metres to raise a root translation of a body of shape ``betas_from`` so that the
    same poses on shape ``betas_to`` have their soles (the lowest foot vertex in the rest
    pose) as high: positive when ``betas_to`` stands taller. None: the mean shape."""
    ids = list(body.foot_vertex_ids)
    with torch.no_grad():
        soles = [float(body.rest_vertices(b)[ids, 1].min()) for b in (betas_from, betas_to)]
    return soles[0] - soles[1]


def fitted_motion(
    model, noises, conds, label: str | None, name: str, loss_fn, fit, rate_of=None
) -> Motion:
    """The model's (raw) motion for ``noises`` after ``fit.steps`` of noise optimisation
    against ``loss_fn`` (``mrlib.sampling.constraints.optimise``; none when the steps are
    0 or ``loss_fn`` is None; ``fit``: a ``NoiseFit``); ``rate_of``: as
    :func:`features_motion`."""
    if fit.steps > 0 and loss_fn is not None:
        from mrlib.sampling.constraints.optimise import optimise_noise

        noises, _ = optimise_noise(
            model, noises, conds, loss_fn, steps=fit.steps, progress=fit.progress
        )
    with torch.no_grad():
        x = model.generator.run_batch(noises, conds)
    return features_motion(model, x, label, name, rate_of)


def warn_past_the_end(path, walked: float, pace: float) -> None:
    """A warning when an open ``path`` (a ``GroundPath``) is walked ``walked`` metres,
    beyond its length by more than ``PAST_THE_END_M`` / ``PAST_THE_END_SHARE``."""
    over = walked - path.length
    if path.closed or over <= max(PAST_THE_END_M, PAST_THE_END_SHARE * path.length):
        return
    warnings.warn(
        f"path {path.name!r} is {path.length:.1f} m long, and this motion walks "
        f"{walked:.1f} m at its pace of {pace:.2f} m/s: past the end it goes straight on "
        f"(give about {path.length / max(pace, 1e-9):.1f} s, or a longer path)",
        stacklevel=3,
    )
