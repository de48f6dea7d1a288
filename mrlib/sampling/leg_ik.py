"""Leg inverse kinematics for the foot-contact clean-up (``mrlib.sampling.cleanup``): the
two feet's joints and contact channels, contact runs, the two-bone (hip - knee - ankle)
IK by the law of cosines, and the rigid transform of a foot that keeps its pinned
vertices on their targets."""

from __future__ import annotations

import numpy as np

from mrlib.representation.skeleton import NUM_JOINTS, PARENTS

__all__ = [
    "contact_runs",
    "pin_corrections",
    "two_bone_ik",
    "foot_transform",
    "global_rotations",
    "LEGS",
    "BLEND_S",
    "ROOT_SMOOTH_S",
]

# (hip, knee, ankle) joint ids and contact channels of each foot
LEGS: tuple[tuple[tuple[int, int, int], tuple[int, int, int]], ...] = (
    ((1, 4, 7), (0, 1, 2)),
    ((2, 5, 8), (3, 4, 5)),
)
_EPS = 1e-6
BLEND_S = 2 / 15  # seconds over which a planted foot eases in and out (4 frames at 30 fps)
ROOT_SMOOTH_S = 0.1  # Gaussian sigma (s) of the root's share of the correction


def contact_runs(c: np.ndarray) -> np.ndarray:
    """``c (T,)`` bool -> ``(R, 2)`` inclusive ``[start, stop]`` frames of its True runs."""
    c = np.asarray(c, bool)
    d = np.diff(np.concatenate([[False], c, [False]]).astype(np.int8))
    return np.stack([np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1], 1)


def pin_corrections(
    pos: np.ndarray, contact: np.ndarray, blend: int = 4, floor: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """How far a contact point must move to stay planted: ``((T, 3), (T,))``.

    In every contact run, and on the frame either side of it, the point is pinned to its
    mean position over the run (not below height ``floor`` when given); over the next
    ``blend`` frames the correction of that edge frame fades out with a smoothstep
    weight. Returns the corrections (weight included) and the weights.
    """
    pos = np.asarray(pos, np.float64)
    T = len(pos)
    runs = contact_runs(contact)
    if len(runs) == 0:
        return np.zeros_like(pos), np.zeros(T)
    idx = np.arange(T)
    run_of = np.full(T, -1)
    for r, (s, e) in enumerate(runs):  # runs, not frames
        run_of[s : e + 1] = r
    means = np.stack([pos[s : e + 1].mean(0) for s, e in runs])  # (R, 3)
    if floor is not None:
        means[:, 1] = np.maximum(means[:, 1], floor)
    inside = run_of >= 0
    # the nearest contact frame before and after every frame
    prev_c = np.maximum.accumulate(np.where(inside, idx, -1))
    next_c = np.minimum.accumulate(np.where(inside, idx, T)[::-1])[::-1]
    d_prev = np.where(prev_c >= 0, idx - prev_c, T + 1)
    d_next = np.where(next_c < T, next_c - idx, T + 1)
    before = d_prev <= d_next
    near = np.clip(np.where(before, prev_c, next_c), 0, T - 1)
    dist = np.minimum(d_prev, d_next)
    # The run and the frame either side of it sit on the run's mean (so the velocity of
    # the run's end frames, a central difference, is zero too); further out, the
    # correction of that edge frame fades with a smoothstep, so the foot eases into and
    # out of its planted position.
    edge = np.clip(np.where(dist <= 1, idx, np.where(before, near + 1, near - 1)), 0, T - 1)
    corr = means[run_of[near]] - pos[edge]
    x = np.clip(1.0 - (dist - 1) / (blend + 1.0), 0.0, 1.0) if blend > 0 else (dist <= 1) * 1.0
    w = x * x * (3 - 2 * x)
    return w[:, None] * corr, w


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
    lat = np.clip(np.linalg.norm(t - a, axis=-1), np.abs(lab - lcb) + 1e-4, lab + lcb - 1e-4)
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


def foot_transform(
    points: np.ndarray,
    targets: np.ndarray,
    weights: np.ndarray,
    prior: float = 1e-3,
    floor: float | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per frame, the rigid motion of a foot that brings its pinned points onto their
    targets: ``x -> R (x - c) + d``.

    ``c`` and ``d`` are the ``weights``-weighted centres of the points and of their
    targets, so the pinned points land on their targets' mean; ``R`` is the weighted
    Procrustes (Kabsch) rotation of the points about those centres. Points that are not
    pinned enter with weight ``prior`` and the target "where the translation takes them"
    (lifted to ``floor`` when that would put them below it): they keep the rotation near
    the identity and settle it where the pinned points leave it free (one point, or the
    turn about the line of two).

    Args:
        points, targets: ``(T, K, 3)``; weights: ``(T, K)`` in [0, 1].
    Returns:
        ``R (T, 3, 3)``, ``c (T, 3)``, ``d (T, 3)`` (``R = I``, ``c = d = 0`` on frames
        without a pinned point).
    """
    P, w = np.asarray(points, np.float64), np.asarray(weights, np.float64)
    sw = w.sum(1, keepdims=True)  # (T, 1)
    pinned = sw[:, 0] > 1e-9
    c = (w[..., None] * P).sum(1) / np.maximum(sw, 1e-12)
    d = (w[..., None] * np.asarray(targets)).sum(1) / np.maximum(sw, 1e-12)
    free = P + (d - c)[:, None]  # unpinned points follow the translation
    if floor is not None:
        free[..., 1] = np.maximum(free[..., 1], floor)
    Q = np.where(w[..., None] > 1e-9, targets, free)
    a = w + prior  # (T, K)
    ca = (a[..., None] * P).sum(1) / a.sum(1, keepdims=True)
    qa = (a[..., None] * Q).sum(1) / a.sum(1, keepdims=True)
    H = np.einsum("tk,tki,tkj->tij", a, P - ca[:, None], Q - qa[:, None])  # sum a p q^T
    U, _, Vt = np.linalg.svd(H)
    V, Ut = np.swapaxes(Vt, -1, -2), np.swapaxes(U, -1, -2)
    D = np.broadcast_to(np.eye(3), H.shape).copy()
    D[:, 2, 2] = np.where(np.linalg.det(V @ Ut) < 0, -1.0, 1.0)
    R = V @ D @ Ut  # (T, 3, 3): R (p - ca) ~ q - qa
    R = np.where(pinned[:, None, None], R, np.eye(3))
    return R, np.where(pinned[:, None], c, 0.0), np.where(pinned[:, None], d, 0.0)


def global_rotations(R: np.ndarray) -> np.ndarray:
    G = np.empty_like(R)
    for j in range(NUM_JOINTS):  # joints, vectorised over frames
        p = PARENTS[j]
        G[:, j] = R[:, j] if p < 0 else G[:, p] @ R[:, j]
    return G
