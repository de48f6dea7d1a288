"""Retargeting a BVH skeleton onto SMPL, and the world-frame conversions mrlib's readers share.

The BVH's joints are matched to SMPL's by a *joint map* (SMPL joint name -> BVH joint
name, ``mrlib.io.jointmap``). A BVH whose joint names are SMPL's own (what
``mrlib.io.save_motion`` writes) is read back exactly.

Method, in numbered steps (``retarget_bvh``):

1. Forward kinematics of the source: global rotations ``R_s(t)`` and positions ``P_s(t)``.
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
   (closed form); when it has none (SMPL's feet and head, and the wrists when the
   source ends there) the whole ``C_j`` is chosen that way (the head relative to the
   chest, see ``_ORIENTATION_REFERENCE``). The source's own rest pose is never used, so
   skeletons whose rest pose is not a T-pose (Bandai Namco: every bone along +X) work.
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
   differences the body's shape space can only partly absorb.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from mrlib.body import fit_betas as betas_of_length  # retarget_bvh has a fit_betas flag
from mrlib.errors import JointMapError, MotionFileError
from mrlib.io.bodyfit import (  # noqa: F401  (part of this module's API before they moved)
    default_body,
    fit_shape_scale,
    fit_smpl_offsets,
    joint_shape_basis,
    rest_joints_for,
    rest_pelvis,
    smpl_forward_joints,
)
from mrlib.io.bvh import BVH, BVHSkeleton, bvh_forward_kinematics
from mrlib.io.jointmap import (  # noqa: F401  (part of this module's API before they moved)
    JOINT_MAP_DIR,
    SMPL_JOINT_MAP,
    JointMap,
    detect_joint_map,
    load_joint_map,
    mapped_targets,
    shipped_joint_maps,
    validate_map,
)
from mrlib.io.recognize import SkeletonMatch, recognise_bvh
from mrlib.rotations import (
    axis_rotation,
    kabsch_rotation,
    matrix_to_axis_angle_numpy,
    rotation_between,
    skew,
)
from mrlib.skeleton import JOINT_NAMES, NUM_JOINTS, PARENTS

__all__ = [
    "JointMap",
    "RetargetResult",
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
        error_mean_cm, error_max_cm: joint position error over frames and mapped joints.
        joint_error_cm: ``(24,)`` mean error per SMPL joint, NaN where unmapped.
        recognition: how the map was found when no shipped map fitted
            (``mrlib.io.recognize``), else None.
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
            "retarget_error_mean_cm": self.error_mean_cm,
            "retarget_error_max_cm": self.error_max_cm,
            "retarget_joint_error_cm": per_joint,
        }


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
        if len(pairs) >= 2 and sv[1] > 1e-3 * sv[0]:
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
    src: np.ndarray, Rw: np.ndarray, Pw: np.ndarray
) -> dict[int, list[tuple[int, np.ndarray, float]]]:
    """Per mapped SMPL joint j: ``(k, a, l)`` for each nearest mapped descendant k with a
    source bone of non-zero length: ``a`` the mean unit direction of the bone in the
    source joint's local frame, ``l`` its median length (Pw's unit)."""
    out: dict[int, list[tuple[int, np.ndarray, float]]] = {}
    for j in np.flatnonzero(src >= 0):
        RsT = np.swapaxes(Rw[:, src[j]], -1, -2)  # (T, 3, 3) world -> source local
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
    J: np.ndarray, src: np.ndarray, Rw: np.ndarray, dirs: dict[int, list]
) -> np.ndarray:
    """Rest alignment ``C (24, 3, 3)`` (identity where unmapped) for rest joints ``J``.

    Args:
        J: ``(24, 3)`` SMPL rest joints.
        src: ``(24,)`` source joint per SMPL joint (-1: unmapped).
        Rw: ``(T, Js, 3, 3)`` source global rotations in mrlib's frame (a subset of
            frames is enough: only sums over frames are used).
        dirs: ``_source_directions`` output.
    """
    T = len(Rw)
    G = np.empty((T, NUM_JOINTS, 3, 3))
    C_all = np.broadcast_to(np.eye(3), (NUM_JOINTS, 3, 3)).copy()
    for j in range(NUM_JOINTS):
        p = PARENTS[j]
        Gp = np.broadcast_to(np.eye(3), (T, 3, 3)) if p < 0 else G[:, p]
        if src[j] < 0:
            G[:, j] = Gp  # identity local rotation
            continue
        Rs = Rw[:, src[j]]
        pairs = []
        for k, a, length in dirs[j]:
            d = J[k] - J[j]
            dn = np.linalg.norm(d)
            pairs.append((d / dn, a, dn * length))
        ref = _ORIENTATION_REFERENCE.get(j) if not pairs else None
        Gref = G[:, ref] if ref is not None else Gp
        M = (np.swapaxes(Gref, -1, -2) @ Rs).sum(0)  # sum_t Gref^T Rs
        C_all[j] = _solve_offset(pairs, M)
        G[:, j] = Rs @ C_all[j]
    return C_all


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
    C: np.ndarray, src: np.ndarray, Rw: np.ndarray, spread: bool = True
) -> np.ndarray:
    """SMPL global rotations ``(T, 24, 3, 3)``: ``R'_src(j) C_j`` where mapped; an unmapped
    joint of the torso chain between two mapped ones shares the turn between them
    (``spread``), any other unmapped joint keeps its parent's (identity local rotation)."""
    T = len(Rw)
    G = np.empty((T, NUM_JOINTS, 3, 3))
    done = np.zeros(NUM_JOINTS, bool)
    for j in range(NUM_JOINTS):
        if src[j] >= 0:
            G[:, j] = Rw[:, src[j]] @ C[j]
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
) -> RetargetResult:
    """Retarget a BVH clip onto the SMPL skeleton (method: module docstring).

    Args:
        bvh: a parsed BVH.
        joint_map: a ``JointMap``, shipped map name, JSON path or ``{smpl: bvh}`` dict;
            ``None`` detects it from the joint names.
        body: a body model (``mrlib.body``); default: the one mrlib ships.
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
    # Offsets and shape are solved on at most 240 evenly spaced frames (sums over frames).
    sub = np.unique(np.linspace(0, T - 1, min(T, 240)).round().astype(np.int64))
    dirs = _source_directions(src, Rw[sub], Pw[sub])
    s_fit, delta = (fixed_s or 1.0), (np.zeros(3) if fixed_delta is None else fixed_delta)
    for _ in range(4 if fit_b else 1):
        J = J_tmpl + D @ b  # (24, 3) rest joints for these betas
        C_all = fixed_C if fixed_C is not None else _solve_offsets(J, src, Rw[sub], dirs)
        if not (fit_b or fixed_s is None or fixed_delta is None):
            break
        G = _smpl_globals(C_all, src, Rw[sub])
        b_new, s_fit, delta = fit_shape_scale(
            G, J_tmpl, D, Q[sub], src, mapped, b, fit_b, fixed_s, fixed_delta,
            shape_ridge, shape_bound,
        )  # fmt: skip
        change = np.abs(b_new - b).max(initial=0.0)
        b = b_new
        if change < 1e-4:
            break
    J = J_tmpl + D @ b
    if fit_b and fixed_C is None:
        C_all = _solve_offsets(J, src, Rw[sub], dirs)
    scale_used = float(s_fit)
    Pw = scale_used * Pw
    G = _smpl_globals(C_all, src, Rw)

    # 6. local rotations; translation: SMPL's pelvis at the source hips (+ G_pelvis delta)
    L = G.copy()
    for j in range(1, NUM_JOINTS):
        L[:, j] = np.swapaxes(G[:, PARENTS[j]], -1, -2) @ G[:, j]
    poses = matrix_to_axis_angle_numpy(L)
    trans = Pw[:, src[0]] + G[:, 0] @ delta - J[0]

    # 7. error: SMPL joints vs the scaled source joints. The joints of SMPL's forward pass
    # are this forward kinematics of the rest joints J(b) (tested against body.forward);
    # numpy avoids the skinning module's per-call overhead.
    joints = smpl_forward_joints(G, J, trans)
    err = np.linalg.norm(joints[:, mapped] - Pw[:, src[mapped]], axis=-1) * 100.0  # (T, M) cm
    joint_err = np.full(NUM_JOINTS, np.nan)
    joint_err[mapped] = err.mean(0)
    return RetargetResult(
        poses=poses,
        trans=trans,
        betas=b,
        offsets=C_all,
        joint_map=jmap,
        unit=unit_m,
        up_axis=up_axis,
        scale=scale_used,
        pelvis_offset=delta,
        error_mean_cm=float(err.mean()),
        error_max_cm=float(err.max()),
        joint_error_cm=joint_err,
        recognition=recognition,
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
