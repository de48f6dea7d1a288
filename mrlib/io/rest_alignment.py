"""Rest-pose alignment, step 3 of retargeting a BVH onto SMPL (``mrlib.io.retarget``).

One constant rotation ``C_j`` per mapped SMPL joint makes ``R'_{src(j)}(t) @ C_j`` SMPL's
global rotation. ``solve_offsets`` finds them from the source's bone directions in its
joints' frames (``source_directions``): Wahba's problem, solved by SVD (``_solve_offset``);
where one direction leaves the twist about a bone free, the knee's or elbow's hinge axis
(``hinge_axes``) or the closed form (local rotations closest to identity over the clip)
sets it. ``rotation_sources`` says which source joint turns each SMPL joint (a split hip,
helper bones); ``is_smpl_rest`` tells a skeleton whose rest pose is SMPL's own.
"""

from __future__ import annotations

import numpy as np

from mrlib.io.bvh.hierarchy import BVHSkeleton
from mrlib.io.jointmap import mapped_targets
from mrlib.io.name_rules import is_helper
from mrlib.representation.rotations import axis_rotation, kabsch_rotation, rotation_between, skew
from mrlib.representation.skeleton import JOINT_NAMES, NUM_JOINTS, PARENTS

__all__ = [
    "source_directions",
    "solve_offsets",
    "hinge_axes",
    "rotation_sources",
    "is_smpl_rest",
]


# Bone directions spreading less than this (second over first singular value of their
# weighted outer products: about 10 deg between two equal bones) fix no turn about their
# mean: nearly parallel bones (a chest whose collars and neck all point up) are one
# direction, their twist left to the data term
_SPREAD = 0.03


def _solve_offset(pairs: list[tuple[np.ndarray, np.ndarray, float]], M: np.ndarray) -> np.ndarray:
    """Rest alignment ``C`` of one joint.

    Args:
        pairs: ``(d, a, w)``: SMPL rest bone direction ``d`` should map to source local
            bone direction ``a`` (``C d = a``) with weight ``w``. Weighting by the product
            of the bone lengths makes this the Procrustes fit of the child joints'
            positions.
        M: ``(3, 3)`` ``sum_t G_parent(t)^T R'_src(t)``: the local rotation is
            ``M_t C``, and ``tr(M C)`` is largest when it is closest to identity.
    """
    if pairs:
        H = sum(w * np.outer(d, a) for d, a, w in pairs)
        sv = np.linalg.svd(H, compute_uv=False)
        if len(pairs) >= 2 and sv[1] > _SPREAD * sv[0]:
            return kabsch_rotation(H)
        # One direction (or all parallel): exact swing, twist from the data term.
        d = sum(w * d for d, _, w in pairs)
        a = sum(w * a for _, a, w in pairs)
        d, a = d / np.linalg.norm(d), a / np.linalg.norm(a)
        C0 = rotation_between(d, a)
        N = M @ C0  # maximise tr(N R_d(theta))
        theta = np.arctan2(np.trace(N @ skew(d)), np.trace(N) - d @ N @ d)
        return C0 @ axis_rotation(d, theta)
    return kabsch_rotation(M)


# A joint with no bone direction to match gets the rotation that keeps it closest, on
# average, to its parent's orientation - except the head: SMPL's neck->head bone leans
# ~20 deg forward of the face's vertical axis while most skeletons' is straight, so
# aligning that bone tilts the neck back, and a head following the neck would look up.
# The head is instead kept, on average, in the orientation of the chest (spine3).
_ORIENTATION_REFERENCE = {JOINT_NAMES.index("head"): JOINT_NAMES.index("spine3")}


def source_directions(
    src: np.ndarray, Rw: np.ndarray, Pw: np.ndarray, rot: np.ndarray | None = None
) -> dict[int, list[tuple[int, np.ndarray, float]]]:
    """Per mapped SMPL joint j: ``(k, a, l)`` for each nearest mapped descendant k with a
    source bone of non-zero length: ``a`` the mean unit direction of the bone in the
    frame of the source joint that turns j (``rot[j]``, default ``src[j]``), ``l`` its
    median length (Pw's unit)."""
    rot = src if rot is None else rot
    out: dict[int, list[tuple[int, np.ndarray, float]]] = {}
    for j in np.flatnonzero(src >= 0):
        RsT = np.swapaxes(Rw[:, rot[j]], -1, -2)  # (T, 3, 3) world -> source local
        out[int(j)] = []
        for k in mapped_targets(j, src):
            v = (RsT @ (Pw[:, src[k]] - Pw[:, src[j]])[..., None])[..., 0]  # (T, 3)
            n = np.linalg.norm(v, axis=-1)
            length = float(np.median(n))
            if length < 1e-6:
                continue  # zero-length source bone (CMU's collars): no direction
            a = (v / np.maximum(n, 1e-12)[:, None]).mean(0)
            out[int(j)].append((k, a / np.linalg.norm(a), length))
    return out


def solve_offsets(
    J: np.ndarray,
    src: np.ndarray,
    Rw: np.ndarray,
    dirs: dict[int, list],
    rot: np.ndarray | None = None,
    hinges: dict[int, tuple[np.ndarray, np.ndarray]] | None = None,
) -> np.ndarray:
    """Rest alignment ``C (24, 3, 3)`` (identity where unmapped) for rest joints ``J``.

    Args:
        J: ``(24, 3)`` SMPL rest joints.
        src: ``(24,)`` source joint per SMPL joint (-1: unmapped).
        Rw: ``(T, Js, 3, 3)`` source global rotations in mrlib's frame (a subset of
            frames is enough: only sums over frames are used).
        dirs: ``source_directions`` output.
        rot: ``(24,)`` the source joint whose rotation turns each SMPL joint (default
            ``src``; ``rotation_sources``).
        hinges: ``hinge_axes`` output: the twist of a limb joint with one bone
            direction is set by its knee's or elbow's hinge axis.
    """
    rot = src if rot is None else rot
    T = len(Rw)
    G = np.empty((T, NUM_JOINTS, 3, 3))
    C_all = np.broadcast_to(np.eye(3), (NUM_JOINTS, 3, 3)).copy()
    for j in range(NUM_JOINTS):
        p = PARENTS[j]
        Gp = np.broadcast_to(np.eye(3), (T, 3, 3)) if p < 0 else G[:, p]
        if src[j] < 0:
            G[:, j] = Gp  # identity local rotation
            continue
        Rs = Rw[:, rot[j]]
        pairs = []
        for k, a, length in dirs[j]:
            d = J[k] - J[j]
            dn = np.linalg.norm(d)
            pairs.append((d / dn, a, dn * length))
        if len(pairs) == 1 and hinges and j in hinges:
            axis, h_src = hinges[j]
            d = pairs[0][0]
            h = axis - (axis @ d) * d  # the hinge axis square to SMPL's bone
            pairs.append((h / np.linalg.norm(h), h_src, 0.5 * pairs[0][2]))
        ref = _ORIENTATION_REFERENCE.get(j) if not pairs else None
        Gref = G[:, ref] if ref is not None else Gp
        M = (np.swapaxes(Gref, -1, -2) @ Rs).sum(0)  # sum_t Gref^T Rs
        C_all[j] = _solve_offset(pairs, M)
        G[:, j] = Rs @ C_all[j]
    return C_all


# Knees and elbows are hinges. SMPL's rest pose (a T-pose, palms down) bends the knees
# about +X (the shin swings back) and the elbows about -Y (left) and +Y (right: the
# forearm swings forward). Seen in the source, the hinge axis is where the cross product
# of the upper and lower bone points on average over the clip; it fixes the twist about
# its one bone of the hip and the knee, the shoulder and the elbow, which one bone
# direction leaves free (the ankle, a joint of two axes, is left to the closed form).
_HINGES = {
    JOINT_NAMES.index(f"{side}_{j}"): (tuple(f"{side}_{n}" for n in chain), axis)
    for side, sign in (("left", -1.0), ("right", 1.0))
    for joints, chain, axis in (
        (("hip", "knee"), ("hip", "knee", "ankle"), np.array([1.0, 0.0, 0.0])),
        (("shoulder", "elbow"), ("shoulder", "elbow", "wrist"), np.array([0.0, sign, 0.0])),
    )
    for j in joints
}
_HINGE_MIN = 0.1  # |mean cross product| below this (about 6 deg of mean flexion): no axis
_HINGE_STEADY = 0.8  # |mean cross product| / mean |cross product| below this: no axis


def hinge_axes(
    src: np.ndarray, rot: np.ndarray, Rw: np.ndarray, Pw: np.ndarray
) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """Per hip, knee, shoulder and elbow whose limb is mapped: ``(SMPL's hinge axis at
    rest, the source's hinge axis in the frame of the source joint turning it)``; left
    out when the limb barely bends in the clip, or bends about no steady axis."""
    out = {}
    for j, (chain, axis) in _HINGES.items():
        a, b, c = (src[JOINT_NAMES.index(n)] for n in chain)
        if min(a, b, c) < 0 or src[j] < 0:
            continue
        u, v = Pw[:, b] - Pw[:, a], Pw[:, c] - Pw[:, b]  # (T, 3) upper and lower bone
        u = u / np.maximum(np.linalg.norm(u, axis=-1, keepdims=True), 1e-12)
        v = v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)
        h = np.einsum("tji,tj->ti", Rw[:, rot[j]], np.cross(u, v))  # (T, 3) source local
        mean = h.mean(0)
        # an axis that holds over the clip: bent enough, and the same way in most frames
        steady = np.linalg.norm(mean) / max(np.linalg.norm(h, axis=-1).mean(), 1e-12)
        if np.linalg.norm(mean) >= _HINGE_MIN and steady >= _HINGE_STEADY:
            out[j] = (axis, mean / np.linalg.norm(mean))
    return out


def rotation_sources(src: np.ndarray, sk: BVHSkeleton) -> np.ndarray:
    """``(24,)`` the source joint whose rotation turns each mapped SMPL joint: its own,
    except (a) SMPL's pelvis on a split hip (legs and spine under a common joint, parting
    at different joints below it: Character Creator's Hip -> Pelvis / Waist) turns with
    the joint where the legs part, and (b) a joint whose bone runs through helper joints
    (DAZ's ThighBend -> ThighTwist -> Shin) turns with the last of them, which carries
    the bone's whole rotation."""
    rot = src.copy()
    parents = sk.parents

    def up(j: int) -> list[int]:
        out = [j]
        while parents[out[-1]] >= 0:
            out.append(parents[out[-1]])
        return out

    hips = [src[JOINT_NAMES.index(n)] for n in ("left_hip", "right_hip")]
    if src[0] >= 0 and min(hips) >= 0:
        a, b = up(hips[0]), set(up(hips[1]))
        fork = next(j for j in a if j in b)  # the lowest common ancestor
        others = [src[k] for k in mapped_targets(0, src) if src[k] not in hips]
        if fork != src[0] and not any(fork in up(o) for o in others):
            rot[0] = fork
    for j in np.flatnonzero(src >= 0):
        kids = mapped_targets(int(j), src)
        if j == 0 or len(kids) != 1:
            continue
        way = up(src[kids[0]])[1:]
        if src[j] not in way:
            continue
        way = way[: way.index(src[j])]  # joints strictly between, child side first
        if way and all(is_helper(sk.names[w]) for w in way):
            rot[j] = way[0]
    return rot


def is_smpl_rest(sk: BVHSkeleton, src: np.ndarray, A: np.ndarray, J: np.ndarray) -> bool:
    """Whether the BVH's rest offsets point the way SMPL's T-pose bones do (within ~25
    deg), i.e. its joint frames are SMPL's rest frames."""
    for j in range(1, NUM_JOINTS):
        u = A @ sk.offsets[src[j]]
        v = J[j] - J[PARENTS[j]]
        nu, nv = np.linalg.norm(u), np.linalg.norm(v)
        if nu == 0 or nv == 0:
            continue
        if u @ v < 0.9 * nu * nv:
            return False
    return True
