"""SMPL's kinematic tree, joint names and the foot vertices used for contact labels.

Conventions used throughout mrlib (stated once, here):

* Dimension letters: B batch, T frames, J joints (24 for SMPL), C channels, L levels.
* World frame: metres, **Y up**, the character faces +Z in its rest pose and its left
  is +X (SMPL's native mesh frame).
* Rotations are right-handed; axis-angle vectors are in radians.
* The 6D rotation representation (Zhou et al., CVPR 2019) is the first two **columns**
  of the rotation matrix, ``[R00, R10, R20, R01, R11, R21]``; see ``mrlib.representation.rotations``.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "JOINT_NAMES",
    "PARENTS",
    "NUM_JOINTS",
    "CONTACT_NAMES",
    "CONTACT_JOINTS",
    "NUM_CONTACTS",
    "UPPER_BODY_JOINTS",
    "SMPL_FOOT_VERTEX_IDS",
    "children",
    "graph_distances",
    "neighbourhood",
]

JOINT_NAMES: tuple[str, ...] = (
    "pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee",
    "spine2", "left_ankle", "right_ankle", "spine3", "left_foot", "right_foot",
    "neck", "left_collar", "right_collar", "head", "left_shoulder", "right_shoulder",
    "left_elbow", "right_elbow", "left_wrist", "right_wrist", "left_hand", "right_hand",
)  # fmt: skip
NUM_JOINTS = len(JOINT_NAMES)

# PARENTS[j] is the parent of joint j; the root (pelvis) has -1. Parents precede children.
PARENTS: tuple[int, ...] = (
    -1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21,
)  # fmt: skip

# Foot vertices whose velocity defines the contact labels, in feature-channel order.
CONTACT_NAMES: tuple[str, ...] = (
    "left_big_toe", "left_small_toe", "left_heel",
    "right_big_toe", "right_small_toe", "right_heel",
)  # fmt: skip
NUM_CONTACTS = len(CONTACT_NAMES)
# The joint each contact channel attaches to in skeleton-aware convolutions.
CONTACT_JOINTS: tuple[int, ...] = (10, 10, 7, 11, 11, 8)

# Vertex indices of the contact vertices on the real SMPL mesh (6890 vertices); these
# are the ids smplx uses for its extra foot keypoints ("LBigToe", ... "RHeel").
SMPL_FOOT_VERTEX_IDS: tuple[int, ...] = (3216, 3226, 3387, 6617, 6624, 6787)

# Joints the speech FiLM modulates by default: the spine above the pelvis, neck, head
# and both arms. The pelvis and legs are left to the generator.
UPPER_BODY_JOINTS: tuple[int, ...] = (3, 6, 9, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21, 22, 23)


def children(parents: tuple[int, ...] | list[int] = PARENTS) -> list[list[int]]:
    """Children lists of a tree given by its parent array."""
    out: list[list[int]] = [[] for _ in parents]
    for j, p in enumerate(parents):
        if p >= 0:
            out[p].append(j)
    return out


def graph_distances(parents: tuple[int, ...] | list[int] = PARENTS) -> np.ndarray:
    """All-pairs hop distances on the kinematic tree, ``(J, J)`` int array."""
    n = len(parents)
    adj = [[] for _ in range(n)]
    for j, p in enumerate(parents):
        if p >= 0:
            adj[j].append(p)
            adj[p].append(j)
    dist = np.full((n, n), -1, dtype=np.int64)
    for s in range(n):  # breadth-first search from every joint; J is tiny
        dist[s, s] = 0
        frontier = [s]
        while frontier:
            nxt = []
            for u in frontier:
                for v in adj[u]:
                    if dist[s, v] < 0:
                        dist[s, v] = dist[s, u] + 1
                        nxt.append(v)
            frontier = nxt
    return dist


def neighbourhood(radius: int = 2, parents: tuple[int, ...] | list[int] = PARENTS) -> np.ndarray:
    """Boolean ``(J, J)`` mask: ``mask[i, j]`` is True when joints i and j are at most
    ``radius`` hops apart on the tree (Aberman et al. 2020 use radius 2)."""
    return graph_distances(parents) <= radius
