"""Retargeting a BVH skeleton onto SMPL, and the world-frame conversions mrlib's readers share.

The module is long because its ten steps share one function's state (``retarget_bvh``);
the pieces of each step follow it, and the body's side lives in ``mrlib.io.bodyfit``.

The BVH's joints are matched to SMPL's by a *joint map* (SMPL joint name -> BVH joint
name, ``mrlib.io.jointmap``). A BVH whose joint names are SMPL's own (what
``mrlib.io.save_motion`` writes) is read back exactly.

Method, in numbered steps (``retarget_bvh``):

1. Forward kinematics of the source: global rotations ``R_s(t)`` and positions ``P_s(t)``.
   The rotation that turns a SMPL joint is its source joint's, except where a bone runs
   through helper joints (DAZ's ``ThighBend -> ThighTwist -> Shin``: the last of them
   carries the whole turn) and on a split hip (Character Creator's ``Hip`` over
   ``Pelvis`` (legs) and ``Waist`` (spine): SMPL's pelvis turns with ``Pelvis``).
2. Units and axes: the file unit is the candidate (m, cm, mm, inch, CMU's 1/0.45 inch)
   that makes the mapped bones closest in length to SMPL's; the up axis is the world
   axis closest to the mean feet-to-head vector. Both can be overridden. A rotation ``A``
   then brings the source into mrlib's frame (metres, Y up): ``R'_s = A R_s``,
   ``P'_s = unit * A P_s``. The heading is left as captured.
3. Rest-pose alignment: one constant rotation ``C_j`` per mapped SMPL joint so that
   ``G_j(t) = R'_{src(j)}(t) @ C_j`` is SMPL's global rotation. ``C_j`` maps SMPL's rest
   bone directions (to the next mapped joint down each branch) onto the source bone
   directions expressed in the source joint's local frame (Wahba's problem, solved by
   SVD, each bone weighted by its lengths: a Procrustes fit of the child joints). When
   a joint has only one such direction, the free twist about that bone is the one that
   keeps the joint's local rotation closest to identity on average over the clip
   (closed form) - except for hips, knees, shoulders and elbows once the shape is
   fitted: there the twist puts SMPL's knee or elbow hinge axis on the source's (the
   mean cross product of the limb's two bones over the clip, ``_hinge_axes``), so the
   limbs' local rotations are the source's even when a clip holds its arms turned
   throughout; when a joint has none (SMPL's feet and head, and the wrists when the
   source ends there) the whole ``C_j`` is chosen that way (the head relative to the
   chest, see ``_ORIENTATION_REFERENCE``). Directions that barely spread (a chest whose
   collars and neck all point up) count as one. The source's own rest pose is never
   used, so skeletons whose rest pose is not a T-pose (Bandai Namco: every bone along
   +X) work.
4. Unmapped SMPL joints (e.g. spine1 for Bandai Namco, the hands) get an identity local
   rotation: they move rigidly with their parent, and the parent's ``C`` already aims
   the rigid chain at the next mapped joint.
5. Body shape: for fixed global rotations SMPL's joints are linear in the rest joints,
   which are linear in ``betas`` (``J(b) = J_0 + D b``); the betas (and optionally a
   uniform scale ``s`` of the source, and ``delta`` of step 6) minimising the mean
   squared joint error plus a
   ridge term are a bounded linear least-squares problem. Steps 3 and 5 alternate
   (the alignment depends on SMPL's rest directions) until the betas settle.
6. Local rotations ``L_j = G_parent^T G_j`` become the axis-angle poses; the translation
   makes SMPL's pelvis follow the (scaled) source hips, up to a constant offset ``delta``
   in the pelvis frame fitted with the shape in step 5:
   ``trans = s P'_hips + G_pelvis delta - J_pelvis(b)``.
7. Error report: SMPL's joint positions (the joints of the body model's forward pass,
   i.e. forward kinematics of ``J(b)``) versus the source's mapped joints ``s P'_src``:
   mean and max over frames and mapped joints, in cm. What keeps it above zero is
   where the two skeletons put "the same" joint (spine segments, neck, shoulders) -
   differences the body's shape space can only partly absorb. Joints that mark no point
   of their own are not compared: one at its mapped ancestor's place (CMU's collars),
   a hand joint far nearer to the wrist than SMPL's (CMU's HandIndex1). A shipped map
   flagged ``refit_torso`` (CMU's: its subjects' spines differ) is also fitted with
   SMPL's spine and neck placed by the skeleton's geometry; the better fit is kept.
8. Transfer by rotations. When SMPL's shape space cannot reach the source - legs longer
   or shorter than any body's within ``shape_bound``, or arms more than
   ``ARM_LEG_RANGE`` times longer or shorter, relative to the legs, than SMPL's mean
   body's (a stylised character) - the body fit is not run: SMPL's mean shape takes the
   rotations of steps 3-6 and the root travels as the source's scaled by leg length
   (``s = SMPL's hip-to-ankle length / the source's``, the pelvis offset fitted to the
   legs), so the joint angles and the foot contacts are the source's. The decision looks
   at the source alone: a wrong map, whose fit fails, stays in positions and is reported.
9. Normalised error, both modes: the source's bone lengths laid along SMPL's posed
   bones, from the source's pelvis down, against the source's joints, scaled to SMPL's
   size by leg length (cm). Proportions do not count; a pose that differs does, and so
   does a map that puts a joint where the source has another. It is the error a clip
   transferred by rotations is judged by.
10. Never silently wrong: a clip whose error (positions, or normalised for rotations) is
    above ``RETARGET_WARN_CM``, or whose SMPL joint angles no person holds (median over
    the clip beyond ``_ANGLE_LIMITS``: legs swapped by a map fit every position with
    the hips turned 175 deg), is reported with a ``RetargetWarning`` naming the clip,
    its worst joints, the shape bounds reached and what to do; ``mrlib train`` refuses
    it unless given ``--accept-retarget-error``.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from mrlib.errors import JointMapError, MotionFileError
from mrlib.io.bodyfit import (
    default_body,
    fit_shape_scale,
    fit_smpl_offsets,
    joint_shape_basis,
    rest_joints_for,
    rest_pelvis,
    smpl_forward_joints,
)
from mrlib.io.bvh import BVH, BVHSkeleton, bvh_forward_kinematics
from mrlib.io.jointmap import (
    JOINT_MAP_DIR,
    SMPL_JOINT_MAP,
    JointMap,
    detect_joint_map,
    load_joint_map,
    mapped_targets,
    shipped_joint_maps,
    validate_map,
)
from mrlib.io.recognize import SkeletonMatch, is_helper, recognise_bvh, refit_torso
from mrlib.representation.body import (
    fit_betas as betas_of_length,  # retarget_bvh has a fit_betas flag
)
from mrlib.representation.rotations import (
    axis_rotation,
    kabsch_rotation,
    matrix_to_axis_angle_numpy,
    rotation_between,
    skew,
)
from mrlib.representation.skeleton import JOINT_NAMES, NUM_JOINTS, PARENTS

__all__ = [
    "JointMap",
    "RetargetResult",
    "RetargetWarning",
    "RETARGET_WARN_CM",
    "JOINT_MAP_DIR",
    "UNITS",
    "load_joint_map",
    "shipped_joint_maps",
    "detect_joint_map",
    "up_axis_rotation",
    "detect_up_axis",
    "change_up_axis",
    "retarget_bvh",
    "calibrate_retarget",
    "default_body",
    "rest_pelvis",
    "rest_joints_for",
]

# Candidate file units (metres per file unit) for automatic detection. "cmu" is the unit
# of the CMU database's ASF/AMC files and of their common BVH conversion: 1/0.45 inch.
UNITS: dict[str, float] = {"m": 1.0, "cmu": 0.0254 / 0.45, "inch": 0.0254, "cm": 0.01, "mm": 0.001}

_AXES = ("x", "y", "z", "-x", "-y", "-z")

# A clip whose mean joint error (cm; normalised to SMPL's size when its motion is
# transferred by rotations) is above this is reported with a RetargetWarning
RETARGET_WARN_CM = 5.0
# The body fit is given up for a transfer by rotations (module docstring, step 8) when the
# source's legs are longer or shorter than any SMPL body's within the shape bound, or when
# its arms are more than a factor ARM_LEG_RANGE longer or shorter, relative to its legs,
# than those of SMPL's mean body (people measured: 0.89-0.95 of it; a stylised character
# with arms x1.2 and legs x0.7: 1.53 - the shape space reaches such a body, but its fit
# trades the feet for the head and torso, and foot contacts move by frames)
ARM_LEG_RANGE = 1.3


# Median local rotation (degrees, over the clip) beyond which a joint's pose is not a
# person's: a map that swaps the legs fits the joint positions (the body turned round
# with its legs crossed over) but not these (measured on the 174 Bandai Namco and 10 CMU
# and Xia clips: medians at most spine 28, neck and head 46, hips 55, knees 60, ankles 58,
# collars 53, wrists 50 deg)
_ANGLE_LIMITS = {
    **{n: 60.0 for n in ("spine1", "spine2", "spine3")},
    **{n: 90.0 for n in ("neck", "head")},
    **{f"{s}_{j}": a for s in ("left", "right") for j, a in (
        ("hip", 120.0), ("knee", 150.0), ("ankle", 100.0), ("foot", 90.0),
        ("collar", 90.0), ("wrist", 120.0), ("hand", 90.0),
    )},
}  # fmt: skip


class RetargetWarning(UserWarning):
    """A clip was retargeted with a joint error above ``RETARGET_WARN_CM``: its motion on
    SMPL may be wrong (a wrong joint map, unit or up axis, or a skeleton SMPL cannot
    follow). The message names the clip, its worst joints and what to do."""


# ----------------------------------------------------------------------------------------
# Up axes
# ----------------------------------------------------------------------------------------
def up_axis_rotation(axis: str) -> np.ndarray:
    """``(3, 3)`` rotation taking a world whose up is ``axis`` to mrlib's Y-up world.

    ``axis`` is one of ``x y z -x -y -z``. ``"z"`` is a -90 deg turn about X (AMASS:
    ``(x, y, z) -> (x, z, -y)``); ``"-y"`` is 180 deg about X (camera frames).
    """
    a = str(axis).lower()
    c = {
        "y": np.eye(3),
        "z": [[1, 0, 0], [0, 0, 1], [0, -1, 0]],
        "-z": [[1, 0, 0], [0, 0, -1], [0, 1, 0]],
        "-y": [[1, 0, 0], [0, -1, 0], [0, 0, -1]],
        "x": [[0, -1, 0], [1, 0, 0], [0, 0, 1]],
        "-x": [[0, 1, 0], [-1, 0, 0], [0, 0, 1]],
    }.get(a)
    if c is None:
        raise ValueError(f"up axis must be one of {_AXES}, got {axis!r}")
    return np.asarray(c, dtype=np.float64)


def detect_up_axis(up_vectors: np.ndarray) -> str:
    """The signed world axis closest to the mean of ``(..., 3)`` "up" vectors."""
    v = np.asarray(up_vectors, dtype=np.float64).reshape(-1, 3).mean(0)
    i = int(np.argmax(np.abs(v)))
    return ("-" if v[i] < 0 else "") + "xyz"[i]


def change_up_axis(
    global_orient: np.ndarray, trans: np.ndarray, rest_pelvis: np.ndarray, axis: str
) -> tuple[np.ndarray, np.ndarray]:
    """Re-express SMPL parameters captured in an ``axis``-up world in mrlib's Y-up world.

    SMPL rotates about the pelvis joint, so rotating the world by ``A`` changes the
    translation by more than ``A``: ``G' = A G`` and ``trans' = A (J_pelvis + trans) - J_pelvis``.

    Args:
        global_orient: ``(T, 3, 3)`` pelvis rotations.
        trans: ``(T, 3)`` SMPL translations.
        rest_pelvis: ``(3,)`` the body's rest pelvis position for the clip's betas.
        axis: the source up axis (``"z"`` for AMASS).

    Returns:
        ``(global_orient (T, 3, 3), trans (T, 3))`` in the Y-up frame.
    """
    A = up_axis_rotation(axis)
    J0 = np.asarray(rest_pelvis, dtype=np.float64)
    return A @ global_orient, (np.asarray(trans, np.float64) + J0) @ A.T - J0


# ----------------------------------------------------------------------------------------
# Retargeting
# ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class RetargetResult:
    """Output of ``retarget_bvh``.

    Attributes:
        poses: ``(T, 24, 3)`` SMPL axis-angle, radians, Y-up world.
        trans: ``(T, 3)`` SMPL translation, metres.
        betas: ``(B,)`` fitted shape (zeros when the body has no shape space or
            ``fit_betas=False``).
        offsets: ``(24, 3, 3)`` rest alignment ``C_j`` (identity where unmapped); pass it
            back as ``offsets=`` to retarget other clips of the same skeleton identically.
        joint_map: the map used.
        unit: metres per file unit.
        up_axis: the source's up axis.
        scale: uniform scale applied to the source (after units) to fit the body.
        pelvis_offset: ``(3,)`` offset of SMPL's pelvis from the source hips, in the
            pelvis frame, metres: ``trans = s P'_hips + G_pelvis delta - J_pelvis``.
        error_mean_cm, error_max_cm: the clip's joint error over frames and mapped
            joints, cm: positions of SMPL's joints against the source's when ``mode`` is
            ``"positions"``, the normalised error when it is ``"rotations"`` (step 9).
        joint_error_cm: ``(24,)`` mean of that error per SMPL joint, NaN where unmapped
            (or where the source joint marks no point of its own).
        recognition: how the map was found when no shipped map fitted
            (``mrlib.io.recognize``), else None.
        mode: ``"positions"`` (SMPL's shape fitted to the source's joints) or
            ``"rotations"`` (the motion transferred by rotations, step 8).
        error_normalised_cm: mean normalised error (step 9), both modes.
        position_error_cm: mean joint position error against the source scaled by
            ``scale`` (what ``error_mean_cm`` is in positions mode), both modes.
        betas_at_bound: indices of the fitted betas that reached ``shape_bound``.
        leg_ratio: SMPL's leg length (hip to ankle, for the fitted betas) over the
            source's (scaled).
        implausible_joints: SMPL joints whose median local rotation over the clip is
            beyond a person's (``_ANGLE_LIMITS``), with that median in degrees.
        warning: the ``RetargetWarning`` text when the error is above
            ``RETARGET_WARN_CM``, else None.
    """

    poses: np.ndarray
    trans: np.ndarray
    betas: np.ndarray
    offsets: np.ndarray
    joint_map: JointMap
    unit: float
    up_axis: str
    scale: float
    pelvis_offset: np.ndarray
    error_mean_cm: float
    error_max_cm: float
    joint_error_cm: np.ndarray = field(repr=False)
    recognition: SkeletonMatch | None = field(default=None, repr=False)
    mode: str = "positions"
    error_normalised_cm: float = float("nan")
    position_error_cm: float = float("nan")
    betas_at_bound: tuple[int, ...] = ()
    leg_ratio: float = float("nan")
    implausible_joints: dict[str, float] = field(default_factory=dict, repr=False)
    warning: str | None = field(default=None, repr=False)

    def meta(self) -> dict[str, Any]:
        """JSON-friendly summary for ``Motion.meta``."""
        per_joint = {
            JOINT_NAMES[j]: round(float(e), 3)
            for j, e in enumerate(self.joint_error_cm)
            if np.isfinite(e)
        }
        extra = {}
        if self.recognition is not None:
            extra["joint_map_confidence"] = round(self.recognition.confidence, 3)
            extra["joint_map_report"] = self.recognition.report()
        return {
            "joint_map": self.joint_map.name,
            **extra,
            "joint_map_pairs": dict(self.joint_map.mapping),
            "unit_m": self.unit,
            "up_axis": self.up_axis,
            "scale": self.scale,
            "pelvis_offset_m": [round(float(v), 5) for v in self.pelvis_offset],
            "retarget_mode": self.mode,
            "retarget_error_mean_cm": self.error_mean_cm,
            "retarget_error_max_cm": self.error_max_cm,
            "retarget_error_normalised_cm": _rounded(self.error_normalised_cm, 3),
            "retarget_position_error_cm": _rounded(self.position_error_cm, 3),
            "retarget_betas_at_bound": list(self.betas_at_bound),
            "retarget_leg_ratio": _rounded(self.leg_ratio, 4),
            "retarget_joint_error_cm": per_joint,
            **(
                {"retarget_implausible_joints": self.implausible_joints}
                if self.implausible_joints
                else {}
            ),
            **({"retarget_warning": self.warning} if self.warning else {}),
        }


# Bone directions spreading less than this (second over first singular value of their
# weighted outer products: about 10 deg between two equal bones) fix no turn about their
# mean: nearly parallel bones (a chest whose collars and neck all point up) are one
# direction, their twist left to the data term
_SPREAD = 0.03


def _rounded(x: float, digits: int) -> float | None:
    return round(float(x), digits) if np.isfinite(x) else None


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


def _source_directions(
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


def _solve_offsets(
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
        dirs: ``_source_directions`` output.
        rot: ``(24,)`` the source joint whose rotation turns each SMPL joint (default
            ``src``; ``_rotation_sources``).
        hinges: ``_hinge_axes`` output: the twist of a limb joint with one bone
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


def _hinge_axes(
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


# SMPL's torso chain, pelvis to head: an unmapped joint on it takes a share of the turn
# between its mapped neighbours (a source spine with fewer joints than SMPL's)
_TORSO_CHAIN = tuple(
    JOINT_NAMES.index(n) for n in ("pelvis", "spine1", "spine2", "spine3", "neck", "head")
)


def _spread(Ga: np.ndarray, Gb: np.ndarray, n: int) -> list[np.ndarray]:
    """Global rotations of ``n`` joints between ``Ga`` and ``Gb`` ``(T, 3, 3)`` that share
    the turn ``Ga^T Gb`` evenly: ``Ga exp(k / (n + 1) log(Ga^T Gb))``, k = 1..n."""
    rel = matrix_to_axis_angle_numpy(np.swapaxes(Ga, -1, -2) @ Gb)  # (T, 3)
    angle = np.linalg.norm(rel, axis=-1, keepdims=True)
    axis = rel / np.maximum(angle, 1e-12)
    out = []
    for k in range(1, n + 1):
        th = angle[:, 0] * k / (n + 1)
        K = np.zeros(rel.shape[:-1] + (3, 3))
        K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -axis[:, 2], axis[:, 1], -axis[:, 0]
        K = K - np.swapaxes(K, -1, -2)
        s, c = np.sin(th)[:, None, None], np.cos(th)[:, None, None]
        out.append(Ga @ (np.eye(3) + s * K + (1 - c) * K @ K))  # Rodrigues
    return out


def _smpl_globals(
    C: np.ndarray,
    src: np.ndarray,
    Rw: np.ndarray,
    spread: bool = True,
    rot: np.ndarray | None = None,
) -> np.ndarray:
    """SMPL global rotations ``(T, 24, 3, 3)``: ``R'_rot(j) C_j`` where mapped (``rot``
    defaults to ``src``); an unmapped joint of the torso chain between two mapped ones
    shares the turn between them (``spread``), any other unmapped joint keeps its
    parent's (identity local rotation)."""
    rot = src if rot is None else rot
    T = len(Rw)
    G = np.empty((T, NUM_JOINTS, 3, 3))
    done = np.zeros(NUM_JOINTS, bool)
    for j in range(NUM_JOINTS):
        if src[j] >= 0:
            G[:, j] = Rw[:, rot[j]] @ C[j]
            done[j] = True
    if spread:
        chain = _TORSO_CHAIN
        k = 0
        while k < len(chain):
            if src[chain[k]] >= 0:
                k += 1
                continue
            first = k
            while k < len(chain) and src[chain[k]] < 0:
                k += 1
            if first == 0 or k == len(chain):
                continue  # no mapped joint on one side: identity below
            run = chain[first:k]
            for j, Gj in zip(
                run, _spread(G[:, chain[first - 1]], G[:, chain[k]], len(run)), strict=True
            ):
                G[:, j] = Gj
                done[j] = True
    for j in range(NUM_JOINTS):
        if not done[j]:
            G[:, j] = np.eye(3) if PARENTS[j] < 0 else G[:, PARENTS[j]]
    return G


def retarget_bvh(
    bvh: BVH,
    joint_map: str | Path | Mapping[str, str] | JointMap | None = None,
    *,
    body=None,
    up_axis: str = "auto",
    unit: str | float = "auto",
    fit_betas: bool = True,
    betas: np.ndarray | None = None,
    offsets: np.ndarray | None = None,
    scale: float | str = "auto",
    pelvis_offset: bool | np.ndarray = True,
    shape_ridge: float = 1e-5,
    shape_bound: float = 3.0,
    transfer: str = "auto",
    warn: bool = True,
    hinge_twist: bool = True,
) -> RetargetResult:
    """Retarget a BVH clip onto the SMPL skeleton (method: module docstring).

    Args:
        bvh: a parsed BVH.
        joint_map: a ``JointMap``, shipped map name, JSON path or ``{smpl: bvh}`` dict;
            ``None`` detects it from the joint names.
        body: a body model (``mrlib.representation.body``); default: the one mrlib ships.
        up_axis: the source's up axis (``x y z -x -y -z``) or ``"auto"``.
        unit: metres per file unit, a name in ``UNITS``, or ``"auto"``.
        fit_betas: fit SMPL's shape to the source skeleton's proportions.
        betas: use these betas instead of fitting.
        offsets: ``(24, 3, 3)`` rest alignment from an earlier call on the same skeleton.
        scale: uniform scale applied to the source after unit conversion. ``"auto"``:
            1 when betas are fitted (the capture keeps its metric size, so speeds and
            strides stay true and the body's shape takes up the difference), fitted by
            least squares otherwise; ``"fit"``: always fitted; or a number.
        pelvis_offset: fit a constant offset ``delta`` (pelvis frame) between SMPL's
            pelvis and the source hips (skeletons disagree on where the pelvis joint
            is: CMU's root sits ~10 cm above its hip joints, SMPL's level with them);
            False pins SMPL's pelvis to the hips; or a fixed ``(3,)`` offset in metres.
        shape_ridge: ridge weight of the betas fit, per mean squared joint error in m^2
            (at 1e-5 one unit of beta costs as much as 3 mm of RMS joint error).
        shape_bound: bound on each fitted beta (keeps the body plausible).
        transfer: ``"positions"`` (fit SMPL's shape to the source's joints),
            ``"rotations"`` (transfer the motion by rotations onto SMPL's mean shape,
            the root scaled by leg length) or ``"auto"``: positions unless SMPL's shape
            space cannot reach the source's proportions (step 8).
        warn: issue a ``RetargetWarning`` when the error is above ``RETARGET_WARN_CM``
            (the result's ``warning`` holds its text either way).
        hinge_twist: set the twist of hips, knees, shoulders and elbows by the knee and
            elbow hinge axes (step 3); False keeps the closed form there too (mrlib's
            retargeting before 2026-12: the same joint positions, the limbs' local
            rotations twisted by the clip's average).

    Returns:
        A ``RetargetResult``.

    Raises:
        JointMapError: the skeleton cannot be mapped.
    """
    sk = bvh.skeleton
    if bvh.num_frames == 0:
        raise MotionFileError(bvh.source, "the BVH has no frames")
    body = default_body() if body is None else body
    J_tmpl, D = joint_shape_basis(body)
    recognition = None
    if joint_map is not None:
        jmap = load_joint_map(joint_map)
    else:
        try:
            jmap = detect_joint_map(sk.names, source=bvh.source)
        except JointMapError:
            recognition = recognise_bvh(bvh, J_tmpl)
            jmap = recognition.joint_map
        if recognition is None and jmap.refit_torso and offsets is None:
            # a shipped map's torso, and the same map with the torso placed by this
            # skeleton's geometry (recognize.refit_torso): the one that fits better
            few = np.unique(np.linspace(0, bvh.num_frames - 1, min(bvh.num_frames, 30)).round())
            _, P_few = bvh_forward_kinematics(BVH(sk, bvh.motion[few.astype(int)], bvh.frame_time))
            alt = refit_torso(jmap, sk.names, sk.parents, sk.offsets, P_few, J_tmpl)
            if alt is not jmap:
                options = dict(
                    body=body, up_axis=up_axis, unit=unit, fit_betas=fit_betas, betas=betas,
                    scale=scale, pelvis_offset=pelvis_offset, shape_ridge=shape_ridge,
                    shape_bound=shape_bound, transfer=transfer, warn=False,
                    hinge_twist=hinge_twist,
                )  # fmt: skip
                fits = [retarget_bvh(bvh, m, **options) for m in (jmap, alt)]
                best = min(fits, key=lambda r: r.error_mean_cm)
                if best.warning and warn:
                    warnings.warn(best.warning, RetargetWarning, stacklevel=2)
                return best
    src = validate_map(jmap, sk.names, sk.parents, bvh.source)
    mapped = np.flatnonzero(src >= 0)

    # 1. source forward kinematics (file units, file axes)
    R, P = bvh_forward_kinematics(bvh)  # (T, Js, 3, 3), (T, Js, 3)
    T = bvh.num_frames

    # bone pairs (SMPL joint j -> nearest mapped descendant k) and their source lengths
    pairs = [(j, k) for j in mapped for k in mapped_targets(j, src)]
    src_len = np.array(
        [np.median(np.linalg.norm(P[:, src[k]] - P[:, src[j]], axis=-1)) for j, k in pairs]
    )
    keep = src_len > 1e-6 * max(src_len.max(initial=0.0), 1e-12)
    len_pairs = [p for p, ok in zip(pairs, keep, strict=True) if ok]
    # Joints whose position is compared with SMPL's ("placed"): not those at their mapped
    # ancestor's place (CMU's collars, at the chest: they turn, they mark no point), nor
    # a hand joint much nearer to or farther from the wrist, in forearm lengths, than
    # SMPL's (CMU's HandIndex1, at 4 cm: SMPL's hand joint is at the knuckles, 11 cm) -
    # the bound recognition maps a hand joint within (mrlib.io.recognize)
    bone = {k: length for (_, k), length in zip(pairs, src_len, strict=True)}
    unplaced = {k for k, length in bone.items() if length <= 1e-3 * max(src_len.max(), 1e-12)}
    for side in ("left", "right"):
        e, w, h = (JOINT_NAMES.index(f"{side}_{n}") for n in ("elbow", "wrist", "hand"))
        if min(src[[e, w, h]]) >= 0 and w in bone and h in bone:
            want = np.linalg.norm(J_tmpl[h] - J_tmpl[w]) / np.linalg.norm(J_tmpl[w] - J_tmpl[e])
            if not 0.5 * want <= bone[h] / max(bone[w], 1e-12) <= 2.0 * want:
                unplaced.add(h)
    placed = np.array([j for j in mapped if j not in unplaced])

    # 2. units and axes
    if unit == "auto":
        smpl_len = np.array([np.linalg.norm(J_tmpl[k] - J_tmpl[j]) for j, k in len_pairs])
        guess = smpl_len.sum() / max(src_len[keep].sum(), 1e-12)
        unit_m = min(UNITS.values(), key=lambda u: abs(np.log(u / guess)))
    elif isinstance(unit, str):
        if unit not in UNITS:
            raise ValueError(
                f"unit must be 'auto', one of {sorted(UNITS)} or a number, got {unit!r}"
            )
        unit_m = UNITS[unit]
    else:
        unit_m = float(unit)
        if not (np.isfinite(unit_m) and unit_m > 0):
            raise ValueError(f"unit must be a positive number of metres, got {unit!r}")
    if up_axis == "auto":
        top = next(
            (
                src[JOINT_NAMES.index(n)]
                for n in ("head", "neck", "spine3", "spine2", "spine1")
                if src[JOINT_NAMES.index(n)] >= 0
            ),
            None,
        )
        feet = [
            src[JOINT_NAMES.index(n)]
            for n in ("left_ankle", "right_ankle")
            if src[JOINT_NAMES.index(n)] >= 0
        ]
        bottom = P[:, feet].mean(1) if feet else P[:, src[0]]
        up_axis = detect_up_axis(P[:, top] - bottom) if top is not None else "y"
    A = up_axis_rotation(up_axis)
    Rw = A @ R  # (T, Js, 3, 3) source joint frame -> mrlib world
    Pw = unit_m * (P @ A.T)  # (T, Js, 3) metres, Y up

    # 3.-5. rest alignment, shape, scale and pelvis offset. The alignment depends on the
    # shape (SMPL's rest bone directions); for fixed rotations the joints are linear in
    # (betas, scale, offset): alternate the two until the betas settle.
    B = D.shape[-1]
    # An SMPL-named skeleton whose rest pose is SMPL's T-pose (mrlib's own export) is
    # read exactly: its local rotations are SMPL's, C_j = A^T (identity when Y up).
    smpl_named = jmap is SMPL_JOINT_MAP and _is_smpl_rest(sk, src, A, J_tmpl)
    if betas is not None:
        b, fit_b = betas_of_length(betas, B, np.float64), False
    elif smpl_named and fit_betas:
        # SMPL-named skeleton (mrlib's export): its offsets are SMPL rest joints, solve exactly
        b, fit_b = fit_smpl_offsets(sk, src, unit_m, J_tmpl, D, A), False
    else:
        b, fit_b = np.zeros(B), fit_betas and bool(np.any(D))
    fixed_C = None
    if offsets is not None:
        fixed_C = np.asarray(offsets, dtype=np.float64).reshape(NUM_JOINTS, 3, 3)
    elif smpl_named:
        fixed_C = np.broadcast_to(A.T, (NUM_JOINTS, 3, 3))
    if scale == "auto":
        fixed_s = 1.0 if (fit_b or smpl_named) else None
    elif scale == "fit":
        fixed_s = None
    else:
        fixed_s = float(scale)
    if isinstance(pelvis_offset, bool):
        fixed_delta = None if (pelvis_offset and not smpl_named) else np.zeros(3)
    else:
        fixed_delta = np.asarray(pelvis_offset, dtype=np.float64).reshape(3)
    Q = Pw - Pw[:, src[:1]]  # (T, Js, 3) source joints relative to the hips, metres
    rot = _rotation_sources(src, sk)
    # Offsets and shape are solved on at most 240 evenly spaced frames (sums over frames).
    sub = np.unique(np.linspace(0, T - 1, min(T, 240)).round().astype(np.int64))
    dirs = _source_directions(src, Rw[sub], Pw[sub], rot)
    hinges = _hinge_axes(src, rot, Rw[sub], Pw[sub]) if hinge_twist else {}
    # 8. a transfer by rotations when SMPL's shape space cannot reach the source's size or
    # proportions (decided on the source alone, so that a wrong map, whose fit fails,
    # stays in positions and is reported)
    if transfer not in ("auto", "positions", "rotations"):
        raise ValueError(f"transfer must be 'auto', 'positions' or 'rotations', got {transfer!r}")
    leg_src = _leg_length(Pw, src)  # metres, unscaled (NaN: no leg mapped)
    if not np.isfinite(leg_src):  # SMPL's size over the source's, by the mapped bones
        smpl_len = sum(np.linalg.norm(J_tmpl[k] - J_tmpl[j]) for j, k in len_pairs)
        ratio = unit_m * src_len[keep].sum() / smpl_len if smpl_len > 0 else 1.0
        leg_src = _leg_length(J_tmpl[None], None) * ratio
    arm_leg = _arm_leg(Pw, src) / _arm_leg(J_tmpl[None], None)
    lo, hi = _leg_range(J_tmpl, D, shape_bound)
    # NaN (no arms mapped) counts as in range
    human = lo <= leg_src <= hi and not abs(np.log(arm_leg)) > np.log(ARM_LEG_RANGE)
    mode = "positions"
    if transfer == "rotations" or (transfer == "auto" and fit_b and fixed_s == 1.0 and not human):
        mode, fit_b = "rotations", False
        b = np.zeros(B) if betas is None else b
    s_fit, delta = (fixed_s or 1.0), (np.zeros(3) if fixed_delta is None else fixed_delta)
    # The hinge axes set the limbs' twist once the shape is known: a joint's position
    # does not depend on the twist of the bone above it, so the fit takes the closed form
    for _ in range(4 if fit_b else 1):
        J = J_tmpl + D @ b  # (24, 3) rest joints for these betas
        C_all = fixed_C if fixed_C is not None else _solve_offsets(J, src, Rw[sub], dirs, rot)
        if mode == "rotations" or not (fit_b or fixed_s is None or fixed_delta is None):
            break
        G = _smpl_globals(C_all, src, Rw[sub], rot=rot)
        b_new, s_fit, delta = fit_shape_scale(
            G, J_tmpl, D, Q[sub], src, placed, b, fit_b, fixed_s, fixed_delta,
            shape_ridge, shape_bound,
        )  # fmt: skip
        change = np.abs(b_new - b).max(initial=0.0)
        b = b_new
        if change < 1e-4:
            break
    J = J_tmpl + D @ b
    if fixed_C is None:
        C_all = _solve_offsets(J, src, Rw[sub], dirs, rot, hinges)
    at_bound = tuple(int(i) for i in np.flatnonzero(fit_b & (np.abs(b) >= shape_bound * 0.999)))

    def fitted(scale_used, b, C_all, delta) -> tuple:
        J = J_tmpl + D @ b
        G = _smpl_globals(C_all, src, Rw, rot=rot)
        trans = scale_used * Pw[:, src[0]] + G[:, 0] @ delta - J[0]
        joints = smpl_forward_joints(G, J, trans)
        # 7. error: SMPL joints vs the scaled source joints. The joints of SMPL's forward
        # pass are this forward kinematics of the rest joints J(b) (tested against
        # body.forward); numpy avoids the skinning module's per-call overhead.
        err = np.linalg.norm(joints[:, placed] - scale_used * Pw[:, src[placed]], axis=-1)
        leg_ratio = _leg_length(J[None], None) / (scale_used * leg_src)
        return G, trans, err * 100.0, leg_ratio  # (T, M) cm

    if mode == "rotations":
        # the root travels as the source's, scaled by leg length (the feet keep their
        # contacts); SMPL's pelvis offset is fitted to the legs alone
        k = _leg_length(J[None], None) / leg_src
        G_sub = _smpl_globals(C_all, src, Rw[sub], rot=rot)
        legs = np.array([j for j in placed if j == 0 or JOINT_NAMES[j] in _LEG_NAMES])
        _, _, delta = fit_shape_scale(
            G_sub, J_tmpl, D, Q[sub], src, legs, b, False, k, fixed_delta,
            shape_ridge, shape_bound,
        )  # fmt: skip
        s_fit = k
    G, trans, err, leg_ratio = fitted(float(s_fit), b, C_all, delta)
    scale_used = float(s_fit)

    # 6. local rotations (the translation is fitted() 's: SMPL's pelvis at the scaled
    # source hips, + G_pelvis delta)
    L = G.copy()
    for j in range(1, NUM_JOINTS):
        L[:, j] = np.swapaxes(G[:, PARENTS[j]], -1, -2) @ G[:, j]
    poses = matrix_to_axis_angle_numpy(L)

    # 9. the normalised error: the source's bone lengths laid along SMPL's posed bones,
    # in SMPL's size (scaled by leg length)
    k_norm = _leg_length(J[None], None) / leg_src
    norm = _normalised_error(G, J, src, placed, Pw) * 100.0 * k_norm  # (T, M) cm
    judged = err if mode == "positions" else norm
    joint_err = np.full(NUM_JOINTS, np.nan)
    joint_err[placed] = judged.mean(0)
    result = RetargetResult(
        poses=poses,
        trans=trans,
        betas=b,
        offsets=C_all,
        joint_map=jmap,
        unit=unit_m,
        up_axis=up_axis,
        scale=scale_used,
        pelvis_offset=delta,
        error_mean_cm=float(judged.mean()),
        error_max_cm=float(judged.max()),
        joint_error_cm=joint_err,
        recognition=recognition,
        mode=mode,
        error_normalised_cm=float(norm.mean()),
        position_error_cm=float(err.mean()),
        betas_at_bound=at_bound,
        leg_ratio=float(leg_ratio),
    )
    angles = np.degrees(np.median(np.linalg.norm(poses, axis=-1), axis=0))  # (24,)
    odd = {
        n: round(float(angles[JOINT_NAMES.index(n)]), 1)
        for n, limit in _ANGLE_LIMITS.items()
        if angles[JOINT_NAMES.index(n)] > limit
    }
    result = replace(result, implausible_joints=odd)
    text = _warning_text(result, bvh.source, shape_bound)
    if text is not None:
        result = replace(result, warning=text)
        if warn:
            warnings.warn(text, RetargetWarning, stacklevel=2)
    return result


_LEG_NAMES = {f"{s}_{j}" for s in ("left", "right") for j in ("hip", "knee", "ankle", "foot")}


def _leg_length(P: np.ndarray, src: np.ndarray | None) -> float:
    """Hip-to-ankle length (thigh + shin, mean of the legs mapped, median over frames) of
    the source joints ``P (T, Js, 3)`` mapped by ``src``, or of SMPL joints
    ``(T, 24, 3)`` (``src`` None); NaN when no leg is mapped."""
    out = []
    for side in ("left", "right"):
        idx = [JOINT_NAMES.index(f"{side}_{j}") for j in ("hip", "knee", "ankle")]
        if src is not None:
            if (src[idx] < 0).any():
                continue
            idx = list(src[idx])
        thigh = np.linalg.norm(P[:, idx[0]] - P[:, idx[1]], axis=-1)
        shin = np.linalg.norm(P[:, idx[1]] - P[:, idx[2]], axis=-1)
        out.append(float(np.median(thigh + shin)))
    return float(np.mean(out)) if out else float("nan")


def _leg_range(J0: np.ndarray, D: np.ndarray, bound: float) -> tuple[float, float]:
    """Shortest and longest hip-to-ankle length (metres) of SMPL bodies with every beta
    within ``bound`` (the length is close to linear in the betas)."""
    L0 = _leg_length(J0[None], None)
    grad = [_leg_length((J0 + D[..., i])[None], None) - L0 for i in range(D.shape[-1])]
    reach = bound * float(np.abs(grad).sum())
    return L0 - reach, L0 + reach


def _arm_leg(P: np.ndarray, src: np.ndarray | None) -> float:
    """Arm length (shoulder to wrist) over leg length (hip to ankle), both sides, of the
    joints ``P (T, Js, 3)`` mapped by ``src`` (or SMPL's ``(T, 24, 3)``, ``src`` None);
    NaN when a limb joint is not mapped."""
    total = {}
    for limb, joints in (
        ("arm", ("shoulder", "elbow", "wrist")),
        ("leg", ("hip", "knee", "ankle")),
    ):
        idx = np.array([JOINT_NAMES.index(f"{s}_{j}") for s in ("left", "right") for j in joints])
        if src is not None:
            if (src[idx] < 0).any():
                return float("nan")
            idx = src[idx]
        idx = idx.reshape(2, 3)
        d = np.linalg.norm(P[:, idx[:, 1:]] - P[:, idx[:, :-1]], axis=-1)  # (T, 2, 2)
        total[limb] = float(np.median(d.sum((1, 2))))
    return total["arm"] / max(total["leg"], 1e-12)


def _rotation_sources(src: np.ndarray, sk: BVHSkeleton) -> np.ndarray:
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


def _normalised_error(
    G: np.ndarray, J: np.ndarray, src: np.ndarray, placed: np.ndarray, Pw: np.ndarray
) -> np.ndarray:
    """``(T, M)`` distances (Pw's unit) between the source joints ``Pw (T, Js, 3)`` and a
    skeleton with the source's bone lengths laid along SMPL's posed bones (global
    rotations ``G (T, 24, 3, 3)``, rest joints ``J``), from the source's pelvis down: each
    mapped joint hangs from its nearest mapped ancestor by the source's bone length, in
    the direction SMPL's body goes from one to the other. Proportions do not count; a
    pose that differs does, and so does a map that puts a joint where the source has
    another (the directions between them disagree)."""
    X = smpl_forward_joints(G, J, np.zeros((len(G), 3)))
    keep = {int(j) for j in placed}
    Y = {0: Pw[:, src[0]]}
    out = []
    for k in sorted(keep):
        if k == 0:
            out.append(np.zeros(len(G)))
            continue
        a = PARENTS[k]
        while a not in keep and a > 0:
            a = PARENTS[a]
        w = X[:, k] - X[:, a]
        length = np.median(np.linalg.norm(Pw[:, src[k]] - Pw[:, src[a]], axis=-1))
        Y[k] = Y[a] + length * w / np.maximum(np.linalg.norm(w, axis=-1, keepdims=True), 1e-12)
        out.append(np.linalg.norm(Y[k] - Pw[:, src[k]], axis=-1))
    return np.stack(out, 1)


def _warning_text(r: RetargetResult, source, bound: float) -> str | None:
    """The RetargetWarning text for ``r`` when its error is above ``RETARGET_WARN_CM`` or
    its joint angles are not a person's."""
    if not (r.error_mean_cm > RETARGET_WARN_CM or r.implausible_joints):
        return None
    per = {JOINT_NAMES[j]: e for j, e in enumerate(r.joint_error_cm) if not np.isnan(e)}
    worst = sorted(per, key=per.get, reverse=True)[:3]
    what = (
        "mean joint error"
        if r.mode == "positions"
        else "mean joint error normalised to SMPL's size (motion transferred by rotations)"
    )
    above = "above" if r.error_mean_cm > RETARGET_WARN_CM else "below"
    odd = (
        " Joint angles no person holds (median over the clip): "
        + ", ".join(f"{n} {a:.0f} deg" for n, a in r.implausible_joints.items())
        + "."
        if r.implausible_joints
        else ""
    )
    pinned = (
        f" The body fit reached the shape bound (+-{bound:g}) on betas {list(r.betas_at_bound)}."
        if r.betas_at_bound
        else ""
    )
    return (
        f"{source}: retargeted onto SMPL with a {what} of {r.error_mean_cm:.1f} cm "
        f"({above} {RETARGET_WARN_CM:g} cm; joint map '{r.joint_map.name}'); worst joints: "
        + ", ".join(f"{n} {per[n]:.1f} cm" for n in worst)
        + f".{odd}{pinned} Check the map: `mrlib info {source} --write-map map.json`, edit "
        "it and pass it back with `--joint-map map.json` (joint_map= in Python); `mrlib "
        "train` refuses this clip unless given --accept-retarget-error."
    )


def calibrate_retarget(
    bvhs: Sequence[BVH],
    joint_map: str | Path | Mapping[str, str] | JointMap | None = None,
    *,
    max_frames_per_clip: int = 240,
    **options: Any,
) -> dict[str, Any]:
    """One retargeting calibration for several clips of the same skeleton.

    ``retarget_bvh`` fits the rest alignment, betas and pelvis offset per clip (they
    only use sums over frames), so clips of one actor get slightly different ones. This
    fits them once on frames pooled from all ``bvhs`` (up to ``max_frames_per_clip``
    evenly spaced frames of each) and returns keyword arguments that make
    ``retarget_bvh`` (or ``mrlib.io.load_bvh``) reuse them::

        calib = calibrate_retarget([read_bvh(p) for p in paths])
        motions = [load_bvh(p, **calib) for p in paths]

    Returns:
        ``{"joint_map", "offsets", "betas", "pelvis_offset", "unit", "up_axis", "scale"}``.

    Raises:
        MotionFileError: the clips do not share one skeleton (joint names and channels).
    """
    if not bvhs:
        raise ValueError("calibrate_retarget needs at least one clip")
    first = bvhs[0].skeleton
    for b in bvhs[1:]:
        if b.skeleton.names != first.names or b.skeleton.channels != first.channels:
            raise MotionFileError(b.source, f"skeleton differs from {bvhs[0].source}'s")
    parts = []
    for b in bvhs:
        n = min(b.num_frames, max_frames_per_clip)
        parts.append(
            b.motion[np.unique(np.linspace(0, b.num_frames - 1, n).round().astype(np.int64))]
        )
    pooled = BVH(first, np.concatenate(parts), bvhs[0].frame_time, source=f"{len(bvhs)} clips")
    r = retarget_bvh(pooled, joint_map, **options)
    return {
        "joint_map": r.joint_map,
        "offsets": r.offsets,
        "betas": r.betas,
        "pelvis_offset": r.pelvis_offset,
        "unit": r.unit,
        "up_axis": r.up_axis,
        "scale": r.scale,
    }


def _is_smpl_rest(sk: BVHSkeleton, src: np.ndarray, A: np.ndarray, J: np.ndarray) -> bool:
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
