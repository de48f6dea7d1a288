"""Helpers the constraint modules share: joint ids from names, a label model's inputs
and outputs, the body's rest pelvis."""

from __future__ import annotations

import numpy as np
import torch

from mrlib.errors import MotionValueError
from mrlib.motion import Motion
from mrlib.skeleton import JOINT_NAMES, NUM_JOINTS

__all__ = ["joint_ids", "label_setup", "features_motion", "pelvis_rest"]


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


def label_setup(model, condition, conditions, blend, length: int, seed: int | None):
    """Noise maps ``[(1, 1, T_i)]`` (the draw ``generate`` makes for ``seed``), checked
    per-level conditions and the finest level's main label, for a label condition."""
    from mrlib.sample import check_conditions, draw_noise, label_inputs, label_weights

    W = label_weights(model, condition, conditions, blend)
    lengths, amp, conds = label_inputs(model, W, length)
    noises = draw_noise(lengths, amp, seed, 1, model.device)
    label = model.labels[int(W[-1].argmax())]
    return noises, check_conditions(model, conds, lengths), label


def features_motion(model, x: torch.Tensor, label: str | None, name: str) -> Motion:
    """Generator output ``(1, C, T)`` (normalised) -> Motion at the model's rate."""
    from mrlib.features import features_to_motion

    return features_to_motion(
        x[0].T.detach().cpu(), model.fps, betas=model.betas, normalizer=model.normalizer,
        label=label, name=name,
    )  # fmt: skip


def pelvis_rest(motion: Motion, body) -> np.ndarray:
    """``(3,)`` rest position of the pelvis for the motion's betas on ``body``."""
    from mrlib.io.bodyfit import rest_pelvis

    return rest_pelvis(body, motion.betas)
