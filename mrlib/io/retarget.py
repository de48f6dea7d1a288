"""Retargeting a BVH skeleton onto SMPL: ``retarget_bvh`` and ``calibrate_retarget``.

``retarget_bvh`` runs the steps below in order; their pieces live in modules of their
own: ``mrlib.io.axes`` (units and up axes, step 2), ``mrlib.io.proportions`` (the
source's bones, the joints compared, leg and arm lengths: steps 1, 7, 8),
``mrlib.io.rest_alignment`` (step 3), ``mrlib.io.transfer`` (SMPL's rotations, the fit
and the root: steps 3-6, 8), ``mrlib.io.bodyfit`` (the body's side of step 5) and
``mrlib.io.retarget_report`` (the result, its errors and warning: steps 7, 9, 10).

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
   SVD, each bone weighted by its lengths: a Procrustes fit of the child joints). When a
   joint has only one such direction, the free twist about that bone is the one that
   keeps the joint's local rotation closest to identity on average over the clip (closed
   form) - except for hips, knees, shoulders and elbows once the shape is fitted: there
   the twist puts SMPL's knee or elbow hinge axis on the source's (the mean cross
   product of the limb's two bones over the clip, ``rest_alignment.hinge_axes``), so the
   limbs' local rotations are the source's even when a clip holds its arms turned
   throughout; when a joint has none (SMPL's feet and head, and the wrists when the
   source ends there) the whole ``C_j`` is chosen that way (the head relative to the
   chest: ``rest_alignment._ORIENTATION_REFERENCE``). Directions that barely spread (a
   chest whose collars and neck all point up) count as one. The source's own rest pose
   is never used, so skeletons whose rest pose is not a T-pose (Bandai Namco: every bone
   along +X) work.
4. Unmapped SMPL joints (e.g. spine1 for Bandai Namco, the hands) get an identity local
   rotation: they move rigidly with their parent, and the parent's ``C`` already aims
   the rigid chain at the next mapped joint.
5. Body shape: for fixed global rotations SMPL's joints are linear in the rest joints,
   which are linear in ``betas`` (``J(b) = J_0 + D b``); the betas (and optionally a
   uniform scale ``s`` of the source, and ``delta`` of step 6) minimising the mean
   squared joint error plus a ridge term are a bounded linear least-squares problem.
   Steps 3 and 5 alternate (the alignment depends on SMPL's rest directions) until the
   betas settle.
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
   ``proportions.ARM_LEG_RANGE`` times longer or shorter, relative to the legs, than
   SMPL's mean body's (a stylised character) - the body fit is not run: SMPL's mean
   shape takes the rotations of steps 3-6 and the root travels as the source's scaled by
   leg length (``s = SMPL's hip-to-ankle length / the source's``, the pelvis offset
   fitted to the legs), so the joint angles and the foot contacts are the source's. The
   decision looks at the source alone: a wrong map, whose fit fails, stays in positions
   and is reported.
9. Normalised error, both modes: the source's bone lengths laid along SMPL's posed
   bones, from the source's pelvis down, against the source's joints, scaled to SMPL's
   size by leg length (cm). Proportions do not count; a pose that differs does, and so
   does a map that puts a joint where the source has another. It is the error a clip
   transferred by rotations is judged by.
10. Never silently wrong: a clip whose error (positions, or normalised for rotations) is
    above ``RETARGET_WARN_CM``, or whose SMPL joint angles no person holds (median over
    the clip beyond ``retarget_report._ANGLE_LIMITS``: legs swapped by a map fit every
    position with the hips turned 175 deg), is reported with a ``RetargetWarning``
    naming the clip, its worst joints, the shape bounds reached and what to do; ``mrlib
    train`` refuses it unless given ``--accept-retarget-error``.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from mrlib.errors import ArgumentError, JointMapError, MotionFileError, shown
from mrlib.io.axes import (
    UNITS,
    file_unit,
    source_up_axis,
    up_axis_rotation,
)
from mrlib.io.bodyfit import default_body, joint_shape_basis
from mrlib.io.bvh.hierarchy import BVH
from mrlib.io.bvh.kinematics import bvh_forward_kinematics, without_reference_frame
from mrlib.io.jointmap import JointMap, detect_joint_map, load_joint_map, validate_map
from mrlib.io.proportions import compared_joints, source_bones
from mrlib.io.recognize import SkeletonMatch, recognise_bvh
from mrlib.io.retarget_report import (
    RetargetResult,
    RetargetWarning,
    clip_errors,
    implausible_joints,
    warning_text,
)
from mrlib.io.torso import refit_torso
from mrlib.io.transfer import (
    RetargetOptions,
    fit_rest_and_shape,
    local_poses,
    root_by_leg_length,
    shape_fit,
    smpl_motion,
    transfer_mode,
    world_source,
)

__all__ = [
    "RetargetOptions",
    "retarget_bvh",
    "calibrate_retarget",
]


# A mean joint error beyond this (1 km) is no fit at all but garbage in the file: refused,
# where errors of a wrong map (tens of cm) load with a RetargetWarning.
MAX_RETARGET_ERROR_CM = 1e5


def retarget_bvh(
    bvh: BVH,
    joint_map: str | Path | Mapping[str, str] | JointMap | None = None,
    *,
    body=None,
    up_axis: str = "auto",
    unit: str | float = "auto",
    options: RetargetOptions | None = None,
    warn: bool = True,
) -> RetargetResult:
    """Retarget a BVH clip onto the SMPL skeleton (method: module docstring).

    Args:
        bvh: a parsed BVH.
        joint_map: a ``JointMap``, shipped map name, JSON path or ``{smpl: bvh}`` dict;
            ``None`` detects it from the joint names.
        body: a body model (``mrlib.representation.body``); default: the one mrlib ships.
        up_axis: the source's up axis (``x y z -x -y -z``) or ``"auto"``.
        unit: metres per file unit, a name in ``mrlib.io.axes.UNITS``, or ``"auto"``.
        options: what the fit fits, holds fixed and its knobs (``RetargetOptions``:
            betas, rest alignment, scale, pelvis offset, shape ridge and bound, transfer
            mode, hinge twist); None: the defaults.
        warn: issue a ``RetargetWarning`` when the error is above ``RETARGET_WARN_CM``
            (the result's ``warning`` holds its text either way).

    Returns:
        A ``RetargetResult``.

    Raises:
        JointMapError: the skeleton cannot be mapped.
    """
    if bvh.num_frames == 0:
        raise MotionFileError(bvh.source, "the BVH has no frames")
    options = RetargetOptions() if options is None else options
    if not isinstance(options, RetargetOptions):
        raise ArgumentError(f"options must be a RetargetOptions, got options={shown(options)}")
    sk = bvh.skeleton
    body = default_body() if body is None else body
    J_tmpl, D = joint_shape_basis(body)
    jmap, recognition = _joint_map_for(bvh, joint_map, J_tmpl)
    if joint_map is None and recognition is None and jmap.refit_torso and options.offsets is None:
        # a shipped map's torso, and the same map with the torso placed by this
        # skeleton's geometry (torso.refit_torso): the one that fits better
        alt = _torso_by_geometry(bvh, jmap, J_tmpl)
        if alt is not jmap:
            same = dict(body=body, up_axis=up_axis, unit=unit, options=options, warn=False)
            fits = [retarget_bvh(bvh, m, **same) for m in (jmap, alt)]
            best = min(fits, key=lambda r: r.error_mean_cm)
            if best.warning and warn:
                warnings.warn(best.warning, RetargetWarning, stacklevel=2)
            _warn_unit(best, bvh.source, unit, warn)
            return best
    src = validate_map(jmap, sk.names, sk.parents, bvh.source)

    # 1. source forward kinematics (file units and axes), its mapped bones and the joints
    # whose positions are compared with SMPL's
    R, P = bvh_forward_kinematics(bvh)  # (T, Js, 3, 3), (T, Js, 3)
    bones = source_bones(src, P)
    placed = compared_joints(src, bones, J_tmpl)
    # 2. units and axes
    unit_m = file_unit(unit, bones.smpl_lengths(J_tmpl), bones.kept_lengths)
    size = unit_m * bones.kept_lengths.sum() / max(bones.smpl_lengths(J_tmpl).sum(), 1e-12)
    up_axis = source_up_axis(src, P) if up_axis == "auto" else up_axis
    A = up_axis_rotation(up_axis)
    # 3.-5. what the fit is given and what it fits; the source in mrlib's frame
    fit = shape_fit(sk, jmap, src, A, unit_m, J_tmpl, D, options)
    source = world_source(src, sk, placed, A @ R, unit_m * (P @ A.T), options.hinge_twist)
    # 8. by positions, or by rotations when SMPL's shape space cannot reach the source
    mode, leg_src = transfer_mode(options.transfer, source, bones, unit_m, J_tmpl, D, fit)
    if mode == "rotations":
        fit = fit.by_rotations(keep_betas=options.betas is not None)
    # 3.-5. rest alignment and body shape; 8. by rotations, the root scaled by leg length
    b, C_all, s_fit, delta = fit_rest_and_shape(source, J_tmpl, D, fit, mode)
    if mode == "rotations":
        s_fit, delta = root_by_leg_length(source, J_tmpl, D, b, C_all, leg_src, fit)
    # 6. SMPL's global rotations, translation and poses
    J, scale_used = J_tmpl + D @ b, float(s_fit)
    G, trans = smpl_motion(source, J, C_all, scale_used, delta)
    poses = local_poses(G)
    # 7., 9. the errors; 10. joint angles no person holds, and the warning
    result = RetargetResult(
        poses=poses, trans=trans, betas=b, offsets=C_all, joint_map=jmap, unit=unit_m,
        up_axis=up_axis, scale=scale_used, pelvis_offset=delta, recognition=recognition,
        mode=mode, betas_at_bound=fit.at_bound(b), implausible_joints=implausible_joints(poses),
        size=float(size),
        **clip_errors(source, G, J, trans, scale_used, leg_src, mode, delta),
    )  # fmt: skip
    if not result.error_mean_cm <= MAX_RETARGET_ERROR_CM:  # NaN included
        raise MotionFileError(
            bvh.source,
            f"cannot retarget onto SMPL: the fitted joints lie {result.error_mean_cm:.3g} cm "
            "from the file's on average, no body's skeleton or motion (a damaged file, or "
            "values in the wrong columns?)",
        )
    text = warning_text(result, bvh.source, options.shape_bound)
    if text is not None:
        result = replace(result, warning=text)
        if warn:
            warnings.warn(text, RetargetWarning, stacklevel=2)
    _warn_unit(result, bvh.source, unit, warn)
    return result


# A skeleton read at the guessed unit this much larger or smaller than SMPL's average
# body (a 2.3 m or a 1.3 m person) may have been read at the wrong unit: a 0.9 m child
# written in centimetres is nearer in size to an adult written in inches.
UNIT_SIZE_WARN = 4 / 3


def _warn_unit(r: RetargetResult, source, unit, warn: bool) -> None:
    """A ``RetargetWarning`` when the unit was guessed (``unit="auto"``) and the skeleton
    comes out more than ``UNIT_SIZE_WARN`` times larger or smaller than SMPL's average."""
    guessed = warn and isinstance(unit, str) and unit == "auto" and np.isfinite(r.size)
    if not guessed or 1 / UNIT_SIZE_WARN <= r.size <= UNIT_SIZE_WARN:
        return
    name = next((k for k, v in UNITS.items() if v == r.unit), f"{r.unit:g} m")
    warnings.warn(
        f"{source}: read in unit '{name}' ({r.unit:g} m, the unit its bone lengths "
        f"suggest), the skeleton is {r.size:.2f}x the size of SMPL's average body; if the "
        "person is not that size, give the file's unit (unit= 'm', 'cm', 'mm', 'inch', "
        "'cmu' or metres per unit in Python, --unit on the command line)",
        RetargetWarning,
        stacklevel=3,
    )


def _joint_map_for(
    bvh: BVH, joint_map: str | Path | Mapping[str, str] | JointMap | None, J_tmpl: np.ndarray
) -> tuple[JointMap, SkeletonMatch | None]:
    """The joint map, and how it was recognised (None: given, or a shipped map): the one
    given, else the shipped map the joint names fit, else the one recognised from the
    skeleton's tree and pose (``mrlib.io.recognize``; ``J_tmpl``: SMPL's rest joints)."""
    if joint_map is not None:
        return load_joint_map(joint_map), None
    try:
        return detect_joint_map(bvh.skeleton.names, source=bvh.source), None
    except JointMapError:
        recognition = recognise_bvh(bvh, J_tmpl)
        return recognition.joint_map, recognition


def _torso_by_geometry(bvh: BVH, jmap: JointMap, J_tmpl: np.ndarray) -> JointMap:
    """``jmap`` with SMPL's spine and neck placed by the skeleton's geometry on at most 30
    frames (``mrlib.io.recognize.refit_torso``), or ``jmap`` itself when that places them
    where it does."""
    sk = bvh.skeleton
    few = np.unique(np.linspace(0, bvh.num_frames - 1, min(bvh.num_frames, 30)).round())
    _, P_few = bvh_forward_kinematics(BVH(sk, bvh.motion[few.astype(int)], bvh.frame_time))
    return refit_torso(jmap, sk.names, sk.parents, sk.offsets, P_few, J_tmpl)


def calibrate_retarget(
    bvhs: Sequence[BVH],
    joint_map: str | Path | Mapping[str, str] | JointMap | None = None,
    *,
    max_frames_per_clip: int = 240,
    **retarget_kwargs: Any,
) -> dict[str, Any]:
    """One retargeting calibration for several clips of the same skeleton.

    ``retarget_bvh`` fits the rest alignment, betas and pelvis offset per clip (they
    only use sums over frames), so clips of one actor get slightly different ones. This
    fits them once on frames pooled from all ``bvhs`` (up to ``max_frames_per_clip``
    evenly spaced frames of each) and returns keyword arguments that make
    ``retarget_bvh`` (or ``mrlib.io.load_bvh``) reuse them::

        calib = calibrate_retarget([read_bvh(p) for p in paths])
        motions = [load_bvh(p, **calib) for p in paths]

    ``retarget_kwargs`` are passed to ``retarget_bvh`` (``body``, ``up_axis``, ``unit``,
    ``options``, ``warn``).

    Returns:
        ``{"joint_map", "unit", "up_axis", "options"}``: ``options`` is the
        ``RetargetOptions`` given (or the defaults) with the fitted ``offsets``,
        ``betas``, ``pelvis_offset`` and ``scale`` held fixed.

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
        b = without_reference_frame(b)[0]  # as load_bvh reads it
        n = min(b.num_frames, max_frames_per_clip)
        parts.append(
            b.motion[np.unique(np.linspace(0, b.num_frames - 1, n).round().astype(np.int64))]
        )
    pooled = BVH(first, np.concatenate(parts), bvhs[0].frame_time, source=f"{len(bvhs)} clips")
    r = retarget_bvh(pooled, joint_map, **retarget_kwargs)
    given = retarget_kwargs.get("options") or RetargetOptions()
    fitted = replace(
        given, offsets=r.offsets, betas=r.betas, pelvis_offset=r.pelvis_offset, scale=r.scale
    )
    return {"joint_map": r.joint_map, "unit": r.unit, "up_axis": r.up_axis, "options": fitted}
