"""The result of retargeting a BVH onto SMPL and how it is judged (``mrlib.io.retarget``).

``RetargetResult`` holds SMPL's motion and the fit's numbers. ``clip_errors`` measures
the clip: SMPL's joints against the source's (step 7) and the normalised error, the
source's bone lengths laid along SMPL's posed bones (step 9). ``implausible_joints``
names the joints whose angles no person holds, and ``warning_text`` is the
``RetargetWarning`` of a clip above ``RETARGET_WARN_CM`` or with such joints (step 10).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mrlib.io.bodyfit import smpl_forward_joints
from mrlib.io.jointmap import JointMap
from mrlib.io.proportions import leg_length
from mrlib.io.recognize import SkeletonMatch
from mrlib.io.transfer import WorldSource
from mrlib.representation.skeleton import JOINT_NAMES, NUM_JOINTS, PARENTS

__all__ = [
    "RETARGET_WARN_CM",
    "RetargetWarning",
    "RetargetResult",
    "clip_errors",
    "implausible_joints",
    "warning_text",
]

# A clip whose mean joint error (cm; normalised to SMPL's size when its motion is
# transferred by rotations) is above this is reported with a RetargetWarning
RETARGET_WARN_CM = 5.0

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
        size: the source's mapped bones, in metres at ``unit``, over SMPL's average
            body's (1: SMPL's size).
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
    size: float = float("nan")
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
            "retarget_source_size": _rounded(self.size, 4),
            "retarget_joint_error_cm": per_joint,
            **(
                {"retarget_implausible_joints": self.implausible_joints}
                if self.implausible_joints
                else {}
            ),
            **({"retarget_warning": self.warning} if self.warning else {}),
        }


def _rounded(x: float, digits: int) -> float | None:
    return round(float(x), digits) if np.isfinite(x) else None


def clip_errors(
    source: WorldSource,
    G: np.ndarray,
    J: np.ndarray,
    trans: np.ndarray,
    scale: float,
    leg_src: float,
    mode: str,
    delta: np.ndarray | None = None,
) -> dict[str, Any]:
    """Steps 7 and 9: the clip's errors and leg ratio, as the ``RetargetResult`` fields
    of those names, of SMPL's motion (global rotations ``G (T, 24, 3, 3)``, rest joints ``J``,
    translation ``trans``) against the source scaled by ``scale`` (``leg_src``: its leg
    length); ``mode`` says which of them the clip is judged by. ``delta``: the fitted
    pelvis offset (``(3,)`` metres, pelvis frame): where the source's root joint sits
    off SMPL's pelvis (CMU's ~10 cm above its hip joints) is a convention of the
    skeleton, not an error, so the pelvis is compared with the root moved by it."""
    s = source
    joints = smpl_forward_joints(G, J, trans)
    target = scale * s.Pw[:, s.src]  # (T, M, 3) where SMPL's joints should be
    shift = np.zeros((len(G), 3)) if delta is None else G[:, 0] @ np.asarray(delta, float)
    target[:, 0] = target[:, 0] + shift
    # 7. error: SMPL joints vs the scaled source joints. The joints of SMPL's forward
    # pass are this forward kinematics of the rest joints J(b) (tested against
    # body.forward); numpy avoids the skinning module's per-call overhead.
    err = np.linalg.norm(joints[:, s.placed] - target[:, s.placed], axis=-1)
    err = err * 100.0  # (T, M) cm
    leg_ratio = leg_length(J[None], None) / (scale * leg_src)
    # 9. the normalised error: the source's bone lengths laid along SMPL's posed bones,
    # in SMPL's size (scaled by leg length)
    k_norm = leg_length(J[None], None) / leg_src
    norm = _normalised_error(G, J, s.src, s.placed, s.Pw, shift / scale) * 100.0 * k_norm
    judged = err if mode == "positions" else norm
    joint_err = np.full(NUM_JOINTS, np.nan)
    joint_err[s.placed] = judged.mean(0)
    return {
        "error_mean_cm": float(judged.mean()),
        "error_max_cm": float(judged.max()),
        "joint_error_cm": joint_err,
        "error_normalised_cm": float(norm.mean()),
        "position_error_cm": float(err.mean()),
        "leg_ratio": float(leg_ratio),
    }


def _normalised_error(
    G: np.ndarray,
    J: np.ndarray,
    src: np.ndarray,
    placed: np.ndarray,
    Pw: np.ndarray,
    shift: np.ndarray | None = None,
) -> np.ndarray:
    """``(T, M)`` distances (Pw's unit) between the source joints ``Pw (T, Js, 3)`` and a
    skeleton with the source's bone lengths laid along SMPL's posed bones (global
    rotations ``G (T, 24, 3, 3)``, rest joints ``J``), from the source's pelvis down: each
    mapped joint hangs from its nearest mapped ancestor by the source's bone length, in
    the direction SMPL's body goes from one to the other. Proportions do not count; a
    pose that differs does, and so does a map that puts a joint where the source has
    another (the directions between them disagree). ``shift (T, 3)``: the source's root
    moved onto SMPL's pelvis (its fitted offset, Pw's unit)."""
    X = smpl_forward_joints(G, J, np.zeros((len(G), 3)))
    keep = {int(j) for j in placed}
    Y = {0: Pw[:, src[0]] + (0.0 if shift is None else shift)}
    out = []
    for k in sorted(keep):
        if k == 0:
            out.append(np.zeros(len(G)))
            continue
        a = PARENTS[k]
        while a not in keep and a > 0:
            a = PARENTS[a]
        w = X[:, k] - X[:, a]
        length = np.median(
            np.linalg.norm(
                Pw[:, src[k]] - Y[a] if a == 0 else Pw[:, src[k]] - Pw[:, src[a]], axis=-1
            )
        )
        Y[k] = Y[a] + length * w / np.maximum(np.linalg.norm(w, axis=-1, keepdims=True), 1e-12)
        out.append(np.linalg.norm(Y[k] - Pw[:, src[k]], axis=-1))
    return np.stack(out, 1)


def implausible_joints(poses: np.ndarray) -> dict[str, float]:
    """The SMPL joints whose median local rotation over the clip (``poses (T, 24, 3)``
    axis-angle) is beyond a person's (``_ANGLE_LIMITS``), with that median in degrees."""
    angles = np.degrees(np.median(np.linalg.norm(poses, axis=-1), axis=0))  # (24,)
    return {
        n: round(float(angles[JOINT_NAMES.index(n)]), 1)
        for n, limit in _ANGLE_LIMITS.items()
        if angles[JOINT_NAMES.index(n)] > limit
    }


def warning_text(r: RetargetResult, source, bound: float) -> str | None:
    """The RetargetWarning text for ``r`` when its error is above ``RETARGET_WARN_CM`` or
    its joint angles are not a person's."""
    if not (r.error_mean_cm > RETARGET_WARN_CM or r.implausible_joints):
        return None
    # the numbers of the meta (rounded alike), worst first, ties in joint order, so that
    # the joints named are the meta's worst whatever the last bits of the fit
    per = {
        JOINT_NAMES[j]: round(float(e), 3) for j, e in enumerate(r.joint_error_cm) if np.isfinite(e)
    }
    worst = sorted(per, key=lambda n: (-per[n], JOINT_NAMES.index(n)))[:3]
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
