"""Writing motion for other tools: SMPL as BVH (Blender, MotionBuilder, ...).

``smpl_to_bvh`` writes SMPL's own skeleton, so a BVH importer reproduces SMPL's joint
positions exactly (``tests/test_export.py`` re-imports it in Blender where Blender is
installed).
"""

from __future__ import annotations

import numpy as np
import torch

from mrlib.io.bodyfit import rest_joints_for
from mrlib.io.bvh.hierarchy import BVH, BVHSkeleton
from mrlib.io.bvh.kinematics import matrix_to_euler
from mrlib.representation.body import resolve_body
from mrlib.representation.rotations import axis_angle_to_matrix
from mrlib.representation.skeleton import JOINT_NAMES, NUM_JOINTS, PARENTS

__all__ = ["smpl_to_bvh"]

_BVH_UNITS = {"cm": 100.0, "m": 1.0}


def smpl_to_bvh(motion, *, body=None, unit: str = "cm", order: str = "ZXY") -> BVH:
    """A BVH of ``motion`` on SMPL's skeleton (the inverse of the ``"smpl"`` joint map).

    * Joints are SMPL's 24, named as in ``mrlib.representation.skeleton.JOINT_NAMES``; the rest pose is
      the body's T-pose for ``motion.betas`` (``OFFSET = J_k - J_parent``), so every
      joint's local frame is world-aligned at rest and its rotation channels are exactly
      SMPL's local rotation.
    * ``pelvis`` is the ROOT with 6 channels (``X/Y/Zposition`` = the pelvis position
      ``J_pelvis + trans``, then the three rotations); every other joint has 3 rotation
      channels; leaves (head, feet, hands) end in an ``End Site``.
    * Euler ``order`` (default ``ZXY``: ``R = Rz Rx Ry``), angles in degrees.
    * ``unit`` ``"cm"`` (default, the usual BVH unit: import into Blender with scale
      0.01) or ``"m"``. The world is mrlib's: Y up, facing +Z, which is what Blender's
      BVH importer expects by default.

    Args:
        motion: a ``mrlib.Motion``.
        body: body model for the rest joints (default: mrlib's).
        unit: ``"cm"`` or ``"m"``.
        order: any of the six Tait-Bryan orders (``"XYZ"``, ``"ZXY"``, ...).

    Returns:
        A ``BVH`` (write it with ``mrlib.io.bvh.write_bvh``).
    """
    if unit not in _BVH_UNITS:
        raise ValueError(f"unit must be one of {sorted(_BVH_UNITS)}, got {unit!r}")
    order = order.upper()
    k = _BVH_UNITS[unit]
    J = rest_joints_for(resolve_body(body, shared=True), motion.betas)  # (24, 3) metres
    par = np.array(PARENTS)
    offsets = np.concatenate([J[:1], J[1:] - J[par[1:]]]) * k
    rot_ch = tuple(f"{a}rotation" for a in order)
    channels = (("Xposition", "Yposition", "Zposition") + rot_ch,) + (rot_ch,) * (NUM_JOINTS - 1)
    leaves = [j for j in range(NUM_JOINTS) if j not in par]
    ends = tuple(
        (j, k * (J[j] - J[PARENTS[j]]) * (1.0 if JOINT_NAMES[j] == "head" else 0.5)) for j in leaves
    )
    skeleton = BVHSkeleton(
        names=JOINT_NAMES, parents=PARENTS, offsets=offsets, channels=channels, end_sites=ends
    )
    T = motion.num_frames
    euler = np.empty((T, NUM_JOINTS, 3))  # degrees
    for a in range(0, T, 8192):  # in pieces: the float64 temporaries of a few MB at a time
        aa = torch.from_numpy(motion.poses[a : a + 8192].astype(np.float64))
        euler[a : a + 8192] = matrix_to_euler(axis_angle_to_matrix(aa).numpy(), order)
    root = (motion.trans.astype(np.float64) + J[0]) * k
    values = np.concatenate([root, euler.reshape(T, -1)], axis=1)  # (T, 3 + 72)
    return BVH(
        skeleton=skeleton, motion=values, frame_time=1.0 / motion.fps, source=str(motion.name)
    )
