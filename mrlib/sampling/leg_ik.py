"""Leg inverse kinematics for the foot-contact clean-up (``mrlib.sampling.cleanup``): the
two feet's joints and contact channels, contact runs and the two-bone (hip - knee -
ankle) IK by the law of cosines."""

from __future__ import annotations

import numpy as np

from mrlib.representation.skeleton import NUM_JOINTS, PARENTS

__all__ = ["contact_runs", "two_bone_ik", "soft_reach", "global_rotations", "LEGS", "SOFT_REACH"]

# (hip, knee, ankle) joint ids and contact channels of each foot
LEGS: tuple[tuple[tuple[int, int, int], tuple[int, int, int]], ...] = (
    ((1, 4, 7), (0, 1, 2)),
    ((2, 5, 8), (3, 4, 5)),
)
_EPS = 1e-6
# the last share of a leg's length (hip to ankle, straight) that IK reaches softly: a
# target further than that (and further than the leg's own pose) is approached
# exponentially, never reached, so the knee does not snap straight as a target passes
# out of reach (restyled walks at 120 fps: knees up to 20-24 rad/s, 9-11 raw). 0.05
# chosen on the development walks (0.02 left 11 rad/s), judged on the held-out styles.
SOFT_REACH = 0.05


def contact_runs(c: np.ndarray) -> np.ndarray:
    """``c (T,)`` bool -> ``(R, 2)`` inclusive ``[start, stop]`` frames of its True runs."""
    c = np.asarray(c, bool)
    d = np.diff(np.concatenate([[False], c, [False]]).astype(np.int8))
    return np.stack([np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1], 1)


def _normalise(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), _EPS)


def _axis_angle(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotation matrices ``(..., 3, 3)`` about unit ``axis (..., 3)`` by ``angle (...)``."""
    x, y, z = axis[..., 0], axis[..., 1], axis[..., 2]
    c, s = np.cos(angle), np.sin(angle)
    C = 1 - c
    return np.stack(
        [
            np.stack([c + x * x * C, x * y * C - z * s, x * z * C + y * s], -1),
            np.stack([y * x * C + z * s, c + y * y * C, y * z * C - x * s], -1),
            np.stack([z * x * C - y * s, z * y * C + x * s, c + z * z * C], -1),
        ],
        -2,
    )


def _angle(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    cos = (_normalise(u) * _normalise(v)).sum(-1)
    return np.arccos(np.clip(cos, -1.0, 1.0))


def soft_reach(d: np.ndarray, d0: np.ndarray, length: np.ndarray) -> np.ndarray:
    """The hip-ankle distance IK aims for when asked for ``d``: ``d`` itself up to
    ``base = max(d0, (1 - SOFT_REACH) length)`` (``d0`` the leg's own, ``length`` its
    straight length), beyond it ``base + room (1 - exp(-(d - base) / room))`` with
    ``room = length - base``: continuous with its slope, never above ``length``."""
    base = np.maximum(d0, (1.0 - SOFT_REACH) * length)
    room = np.maximum(length - base, _EPS)
    return np.where(d > base, base - room * np.expm1(-np.maximum(d - base, 0.0) / room), d)


def two_bone_ik(
    a: np.ndarray,
    b: np.ndarray,
    c: np.ndarray,
    t: np.ndarray,
    Ga: np.ndarray,
    Gb: np.ndarray,
    bend_axis: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """New global rotations of the upper and middle joint so the end joint reaches ``t``.

    Args:
        a, b, c: ``(T, 3)`` positions of hip, knee and ankle; t: ``(T, 3)`` targets.
        Ga, Gb: ``(T, 3, 3)`` global rotations of hip and knee.
        bend_axis: ``(T, 3)`` fallback bending axis where the leg is straight (no plane).
    Returns:
        ``(Ga', Gb')``.
    """
    lab = np.linalg.norm(b - a, axis=-1)
    lcb = np.linalg.norm(b - c, axis=-1)
    lat = np.clip(soft_reach(np.linalg.norm(t - a, axis=-1), np.linalg.norm(c - a, axis=-1),
                             lab + lcb), np.abs(lab - lcb) + 1e-4, lab + lcb - 1e-4)  # fmt: skip
    # 1. bend: set the angles at hip and knee for the wanted hip-ankle distance
    ac_ab_0 = _angle(c - a, b - a)
    ba_bc_0 = _angle(a - b, c - b)
    ac_ab_1 = np.arccos(np.clip((lcb**2 - lab**2 - lat**2) / (-2 * lab * lat), -1, 1))
    ba_bc_1 = np.arccos(np.clip((lat**2 - lab**2 - lcb**2) / (-2 * lab * lcb), -1, 1))
    axis0 = np.cross(c - a, b - a)
    straight = np.linalg.norm(axis0, axis=-1) < 1e-8
    axis0 = _normalise(np.where(straight[:, None], bend_axis, axis0))
    Ra = _axis_angle(axis0, ac_ab_1 - ac_ab_0)
    Rb = _axis_angle(axis0, ba_bc_1 - ba_bc_0)
    # positions after the bend (the hip rotation turns the whole leg about a)
    b1 = a + (Ra @ (b - a)[..., None])[..., 0]
    c1 = b1 + (Ra @ Rb @ (c - b)[..., None])[..., 0]
    # 2. swing: turn the leg about the hip so the ankle points at the target
    axis1 = np.cross(c1 - a, t - a)
    tiny = np.linalg.norm(axis1, axis=-1) < 1e-10
    axis1 = _normalise(np.where(tiny[:, None], axis0, axis1))
    Rs = _axis_angle(axis1, np.where(tiny, 0.0, _angle(c1 - a, t - a)))
    Ga1 = Rs @ Ra @ Ga
    Gb1 = Rs @ Ra @ Rb @ Gb
    return Ga1, Gb1


def global_rotations(R: np.ndarray) -> np.ndarray:
    G = np.empty_like(R)
    for j in range(NUM_JOINTS):  # joints, vectorised over frames
        p = PARENTS[j]
        G[:, j] = R[:, j] if p < 0 else G[:, p] @ R[:, j]
    return G
