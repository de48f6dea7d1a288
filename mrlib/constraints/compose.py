"""Body-part composition: different conditions for different joint groups.

``method="splice"`` (default): one motion per condition with the same noise, each
group's joint rotations taken from its own (the root and the contact labels from the
group holding the pelvis). It works across models too (:func:`splice_parts`: upper
body from a speech model, legs from a label model).

``method="film"``: one generator pass, each group's channels modulated by its own
condition's FiLM parameters at every level (``LevelGenerator.modulate``; the
channel-to-joint map of the skeleton-aware convolutions says which channels are a
group's: the root displacement belongs to the pelvis, each contact label to its foot).
The networks see the whole body, so a part's label leaks into its neighbours through the
convolutions: on the Bandai walks the parts kept their labels less often than spliced
ones (``docs/results.md``, ``bench/constraints.py``), hence the default.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import torch

from mrlib.constraints.common import joint_ids
from mrlib.errors import MotionValueError
from mrlib.motion import Motion
from mrlib.skeleton import JOINT_NAMES, NUM_JOINTS, UPPER_BODY_JOINTS

__all__ = [
    "PARTS",
    "part_joints",
    "parse_parts",
    "generate_parts",
    "splice_parts",
    "part_fidelity",
]

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
    return joint_ids(part)


def parse_parts(spec: str) -> dict[str, str]:
    """``"upper=walk_happy,lower=walk_sad"`` -> ``{"upper": "walk_happy", ...}``."""
    out = {}
    for item in str(spec).split(","):
        part, eq, cond = item.partition("=")
        if not eq or not part.strip() or not cond.strip():
            raise MotionValueError(f"--parts expects part=label[,part=label...], got {spec!r}")
        out[part.strip()] = cond.strip()
    return out


def _groups(parts: Mapping) -> list[tuple[tuple[int, ...], object]]:
    """``[(joints, condition)]`` covering every joint once; joints no part names join
    the part holding the pelvis, or else the first part."""
    if not parts:
        raise MotionValueError("give at least one part=condition")
    groups = [(set(part_joints(p)), c) for p, c in parts.items()]
    seen: set[int] = set()
    for js, _ in groups:
        if js & seen:
            raise MotionValueError(f"body parts overlap at joints {sorted(js & seen)}")
        seen |= js
    rest = set(range(NUM_JOINTS)) - seen
    if rest:
        k = next((i for i, (js, _) in enumerate(groups) if 0 in js), 0)
        groups[k][0].update(rest)
    return [(tuple(sorted(js)), c) for js, c in groups]


def _channel_masks(groups) -> list[torch.Tensor]:
    from mrlib.features import channel_joint

    owner = channel_joint()
    return [torch.from_numpy(np.isin(owner, js).astype(np.float32)) for js, _ in groups]


def generate_parts(
    model,
    parts: Mapping[str, str],
    length: int | None = None,
    *,
    seed: int | None = None,
    num_samples: int = 1,
    method: str = "splice",
    fix_contacts: bool = True,
    body=None,
):
    """A label model's motion with each body part under its own label (method: module
    docstring), e.g. ``parts={"upper": "walk_happy", "lower": "walk_sad"}``.

    Returns:
        ``Motion`` (label ``"upper=walk_happy,lower=walk_sad"``) or a list.
    """
    from mrlib.features import features_to_motions
    from mrlib.sample import (
        cleanup_foot_contacts,
        generate,
        guided_weights,
        label_inputs,
        label_weights,
        noise_amplitude,
        sample_features,
    )

    if method not in ("film", "splice"):
        raise MotionValueError(f"method must be 'film' or 'splice', got {method!r}")
    groups = _groups(parts)
    tag = ",".join(f"{p}={c}" for p, c in parts.items())
    if method == "splice":
        motions = {
            c: generate(
                model, c, length=length, seed=seed, num_samples=num_samples, fix_contacts=False
            )  # fmt: skip
            for _, c in groups
        }
        out = []
        for b in range(num_samples):
            pick = {c: (ms if isinstance(ms, Motion) else ms[b]) for c, ms in motions.items()}
            out.append(
                splice_parts({js: pick[c] for js, c in groups}, name=f"{tag}_seed{seed}_{b}")
            )
    else:
        Ws = [label_weights(model, c) for _, c in groups]
        lengths, _, _ = label_inputs(model, Ws[0], length)
        amp = torch.stack([noise_amplitude(model, W) for W in Ws]).mean(0)
        masks = _channel_masks(groups)
        Gs = [guided_weights(model, W) for W in Ws]
        conds = [
            [(m, G[i].expand(1, lengths[i], -1)) for m, G in zip(masks, Gs, strict=True)]
            for i in range(model.num_levels)
        ]
        x = sample_features(model, conds, lengths, amp, seed=seed, num_samples=num_samples)
        names = [f"{tag}_seed{seed}_{b}" for b in range(num_samples)]
        out = features_to_motions(x.transpose(1, 2), model.fps, betas=model.betas,
                                  normalizer=model.normalizer, label=tag, names=names)  # fmt: skip
    if fix_contacts:
        out = [cleanup_foot_contacts(m, body) for m in out]
    for m in out:
        m.label = tag
        m.meta["parts"] = {p: c for p, c in parts.items()}
    return out[0] if num_samples == 1 else out


def splice_parts(parts: Mapping, name: str | None = None) -> Motion:
    """One motion from several: ``{part: Motion}`` (parts as :func:`part_joints` takes
    them, or joint-id tuples), each part's joint rotations from its motion; the root
    translation and contact labels from the motion of the part holding the pelvis. The
    motions are cut to the shortest and must share a frame rate."""
    groups = _groups(parts)
    motions = [m for _, m in groups]
    fps = {m.fps for m in motions}
    if len(fps) != 1:
        raise MotionValueError(f"motions to splice need one frame rate, got {sorted(fps)}")
    T = min(m.num_frames for m in motions)
    base = next(m for js, m in groups if 0 in js)
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


def part_fidelity(
    motions: Sequence[Motion], model, parts: Mapping[str, str], window: int = 30
) -> dict[str, float]:
    """Condition fidelity measured on each part alone: the share of a part's windows
    whose nearest training window (on that part's joint rotations; the lower body also
    on the contact labels) belongs to the part's own label."""
    from mrlib.fidelity import model_references
    from mrlib.metrics import condition_fidelity, metric_features

    _, labels, feats = model_references(model)
    out = {}
    for part, cond in parts.items():
        js = [j for j in part_joints(part) if j > 0]  # the metrics leave out the root joint
        cols = np.concatenate([np.arange(6 * (j - 1), 6 * j) for j in js])
        with_contacts = 0 in part_joints(part) or any(j in LOWER_BODY_JOINTS for j in js)
        if with_contacts:
            cols = np.concatenate([cols, 138 + np.arange(6)])
        refs = {
            lab: np.concatenate(
                [f[:, cols] for f, lb in zip(feats, labels, strict=True) if lb == lab]
            )
            for lab in dict.fromkeys(labels)
        }
        gen = [(metric_features(m)[:, cols], cond) for m in motions]
        out[part] = condition_fidelity(gen, refs, window=window)
    return out
