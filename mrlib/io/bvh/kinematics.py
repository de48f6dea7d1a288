"""Euler angles and forward kinematics of BVH skeletons, vectorised over frames: the
rotation channels' angles to matrices and back (``euler_to_matrix``,
``matrix_to_euler``), a clip's local transforms (``bvh_local_transforms``) and global
rotations and positions (``forward_kinematics``, ``bvh_forward_kinematics``); and a
reference pose written before the motion, found by its joints' turns
(``without_reference_frame``). Conventions: ``mrlib.io.bvh``.
"""

from __future__ import annotations

import numpy as np

from mrlib.io.bvh.hierarchy import BVH

__all__ = [
    "euler_to_matrix",
    "matrix_to_euler",
    "bvh_local_transforms",
    "forward_kinematics",
    "bvh_forward_kinematics",
    "without_reference_frame",
    "ReferenceFrameWarning",
]

_AXIS = {"X": 0, "Y": 1, "Z": 2}


# ----------------------------------------------------------------------------------------
# Euler angles
# ----------------------------------------------------------------------------------------
def _axis_matrix(axis: int, angle: np.ndarray) -> np.ndarray:
    """``(...,)`` radians -> ``(..., 3, 3)`` rotation about one coordinate axis."""
    c, s = np.cos(angle), np.sin(angle)
    R = np.zeros(angle.shape + (3, 3))
    i, j = (axis + 1) % 3, (axis + 2) % 3
    R[..., axis, axis] = 1.0
    R[..., i, i] = c
    R[..., j, j] = c
    R[..., j, i] = s
    R[..., i, j] = -s
    return R


def euler_to_matrix(angles: np.ndarray, order: str, degrees: bool = True) -> np.ndarray:
    """Euler angles -> rotation matrices, composed left to right.

    Args:
        angles: ``(..., K)`` angles, ``K = len(order)``.
        order: axis letters, e.g. ``"ZXY"`` (any length; repeated axes allowed).
        degrees: whether ``angles`` are in degrees (BVH) or radians.

    Returns:
        ``(..., 3, 3)`` ``R = R_order[0](a0) @ R_order[1](a1) @ ...``.
    """
    angles = np.asarray(angles, dtype=np.float64)
    if angles.shape[-1] != len(order):
        raise ValueError(f"angles (..., {angles.shape[-1]}) do not match order '{order}'")
    if degrees:
        angles = np.deg2rad(angles)
    R = np.broadcast_to(np.eye(3), angles.shape[:-1] + (3, 3))
    for k, ax in enumerate(order.upper()):
        R = R @ _axis_matrix(_AXIS[ax], angles[..., k])
    return np.array(R)


def matrix_to_euler(R: np.ndarray, order: str, degrees: bool = True) -> np.ndarray:
    """Rotation matrices -> Tait-Bryan angles with ``R = R_i(a) @ R_j(b) @ R_k(c)``.

    Args:
        R: ``(..., 3, 3)`` rotation matrices.
        order: three distinct axis letters, e.g. ``"ZXY"``.
        degrees: return degrees (BVH) or radians.

    Returns:
        ``(..., 3)`` angles; the middle one is in ``[-90, 90]`` degrees. At gimbal lock
        (middle angle +-90) the last angle is set to 0.
    """
    order = order.upper()
    if len(order) != 3 or len(set(order)) != 3:
        raise ValueError(f"order must be three distinct axes, got '{order}'")
    i, j, k = (_AXIS[a] for a in order)
    s = 1.0 if (j - i) % 3 == 1 else -1.0  # +1 for cyclic orders (XYZ, YZX, ZXY)
    R = np.asarray(R, dtype=np.float64)
    cos_b = np.hypot(R[..., i, i], R[..., i, j])
    b = np.arctan2(s * R[..., i, k], cos_b)
    a = np.arctan2(-s * R[..., j, k], R[..., k, k])
    c = np.arctan2(-s * R[..., i, j], R[..., i, i])
    lock = cos_b < 1e-9  # R = R_i(a) R_j(+-90): read a from column j, set c = 0
    if np.any(lock):
        a = np.where(lock, np.arctan2(s * R[..., k, j], R[..., j, j]), a)
        c = np.where(lock, 0.0, c)
    out = np.stack([a, b, c], axis=-1)
    return np.rad2deg(out) if degrees else out


# ----------------------------------------------------------------------------------------
# Forward kinematics
# ----------------------------------------------------------------------------------------
def bvh_local_transforms(bvh: BVH) -> tuple[np.ndarray, np.ndarray]:
    """Per-frame local rotations and translations from the channel values.

    Returns:
        ``rot (T, J, 3, 3)``: joint frame -> parent frame.
        ``trans (T, J, 3)``: joint origin in the parent frame (the OFFSET, with the
        components that have position channels replaced by their values), file units.
    """
    sk = bvh.skeleton
    T, J = bvh.num_frames, sk.num_joints
    rot = np.empty((T, J, 3, 3))
    trans = np.broadcast_to(sk.offsets, (T, J, 3)).copy()
    start = 0
    for j, chans in enumerate(sk.channels):
        order = ""
        cols: list[int] = []
        for c, name in enumerate(chans):
            if name.endswith("position"):
                trans[:, j, _AXIS[name[0]]] = bvh.motion[:, start + c]
            else:
                order += name[0]
                cols.append(start + c)
        if order:
            rot[:, j] = euler_to_matrix(bvh.motion[:, cols], order)
        else:
            rot[:, j] = np.eye(3)
        start += len(chans)
    return rot, trans


def forward_kinematics(
    parents: tuple[int, ...] | list[int], rot: np.ndarray, trans: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Global rotations and positions from local ones, vectorised over frames.

    Args:
        parents: ``J`` parent indices (-1 for roots); parents precede children.
        rot: ``(T, J, 3, 3)`` local rotations (joint frame -> parent frame).
        trans: ``(T, J, 3)`` joint origins in the parent frame (world frame for roots).

    Returns:
        ``global_rot (T, J, 3, 3)`` joint frame -> world and ``positions (T, J, 3)``.
    """
    g_rot = np.empty_like(rot)
    pos = np.empty_like(trans)
    for j, p in enumerate(parents):
        if p < 0:
            g_rot[:, j] = rot[:, j]
            pos[:, j] = trans[:, j]
        else:
            g_rot[:, j] = g_rot[:, p] @ rot[:, j]
            pos[:, j] = pos[:, p] + np.einsum("tab,tb->ta", g_rot[:, p], trans[:, j])
    return g_rot, pos


def _forward_kinematics_naive(parents, rot, trans):
    """Frame-by-frame 4x4 reference for ``forward_kinematics`` (tests only)."""
    T, J = rot.shape[:2]
    g_rot = np.zeros_like(rot)
    pos = np.zeros_like(trans)
    for t in range(T):
        world = [None] * J
        for j in range(J):
            M = np.eye(4)
            M[:3, :3] = rot[t, j]
            M[:3, 3] = trans[t, j]
            world[j] = M if parents[j] < 0 else world[parents[j]] @ M
            g_rot[t, j] = world[j][:3, :3]
            pos[t, j] = world[j][:3, 3]
    return g_rot, pos


def bvh_forward_kinematics(bvh: BVH) -> tuple[np.ndarray, np.ndarray]:
    """``(global_rot (T, J, 3, 3), positions (T, J, 3))`` of a BVH in file units."""
    rot, trans = bvh_local_transforms(bvh)
    return forward_kinematics(bvh.skeleton.parents, rot, trans)


class ReferenceFrameWarning(UserWarning):
    """A BVH file's first frame was a reference pose, not motion, and was left out
    (:func:`without_reference_frame`)."""


def without_reference_frame(bvh: BVH) -> tuple[BVH, bool]:
    """``bvh`` without its first frame when that frame is a reference pose that the
    exporter put before the motion (Axis Neuron, the cgspeed conversions of the CMU
    captures): every rotation channel exactly 0 while the next frame's are not, and the
    turn of some joint from it to the next frame over 20 degrees and over twice the
    clip's other frame-to-frame turns (their 99th percentile, over the first 2000
    frames): a motion that leaves the zero pose smoothly is kept. Returns
    ``(bvh, dropped)``."""
    names = [c for chs in bvh.skeleton.channels for c in chs]
    rot = [i for i, c in enumerate(names) if c.endswith("rotation")]
    if bvh.num_frames < 3 or not rot:
        return bvh, False
    if np.abs(bvh.motion[0, rot]).max() > 0 or np.abs(bvh.motion[1, rot]).max() == 0:
        return bvh, False
    head = BVH(bvh.skeleton, bvh.motion[:2000], bvh.frame_time, source=bvh.source)
    R, _ = bvh_local_transforms(head)  # (T, J, 3, 3)
    cos = (np.einsum("tjab,tjab->tj", R[:-1], R[1:]) - 1) / 2  # of each joint's turn
    turn = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))).max(1)  # (T - 1,) the largest
    if not (turn[0] > 20 and turn[0] > 2 * np.percentile(turn[1:], 99)):
        return bvh, False
    return BVH(bvh.skeleton, bvh.motion[1:], bvh.frame_time, source=bvh.source), True
