"""Foot-contact clean-up: feet that stay put while labelled in contact, on the floor, with
motion that stays smooth (``cleanup_foot_contacts``); in closed form, vectorised over
frames.

The paper refines predicted contacts by inverse kinematics (Sec. 3.4), as GANimator does
(Li et al., SIGGRAPH 2022), with a per-frame optimisation. Here the clean-up solves for
the corrections of the whole clip at once, the
least-squares form of Kovar et al.'s footskate clean-up (SCA 2002: the root first, then
the legs, corrections blended in and out) with the blends replaced by a smoothness term,
as in spacetime motion editing (Gleicher, SIGGRAPH 1998; Lee and Shin, SIGGRAPH 1999):

1. **Offsets** (:func:`smooth_foot_offsets`). A root offset ``r(t)`` and one offset
   ``l_f(t)`` per foot (the foot moves rigidly with its ankle) minimise, per axis, one
   quadratic energy: the ground speed of every contact vertex while labelled in contact
   (``PIN_WEIGHT``), the jerk of the corrections weighted by the joints each one moves
   (24 for the root, 3 for a leg; time scale ``SMOOTH_S``), and their size, the legs'
   dearer than the root's (``ROOT_HOLD_S``, ``LEG_HOLD_S``): a single planted foot is
   held by moving the whole body, which changes no joint angle (the pose features of
   the coverage metric leave the root out), and the legs take only the difference
   between two planted feet. Sparse, banded, one factorisation: milliseconds.
2. **The floor** (:func:`_vertical`). Vertically, the lowest vertex of each planted foot
   is pulled onto the floor (``FLOOR_WEIGHT``) and no vertex may go more than
   ``FLOOR_SLACK`` below it (stiff springs on an active set): the root takes the slow
   part, a leg, dearer (``LIFT_HOLD_S``), the brief dips of its own foot. The floor is
   where the training clips' planted feet rest (``generate`` passes it,
   ``mrlib.sampling.generation.training_floor``), else estimated from the clip
   (:func:`contact_floor`).
3. **Two-bone IK** (hip - knee - ankle, law of cosines) takes each ankle by its leg's
   offset, the foot keeping its global orientation; bone lengths are kept.

The clean-up before it pinned every contact run to its mean position and eased it in
and out; it planted harder but stepped the feet's velocity at the blends, changed the
leg angles more and left feet under the floor. It, and the per-frame optimisation of
the leg joints, are kept as reference code in ``bench/experiments/cleanup_studies.py``;
``bench/cleanup_natural.py`` measures them on the Bandai walks (coverage, skating, jerk,
penetration; ``docs/notes/2026-12-06-study-options.md``).
"""

from __future__ import annotations

from dataclasses import fields

import numpy as np
import torch

from mrlib.errors import MotionValueError
from mrlib.representation.body import resolve_body
from mrlib.representation.motion import Motion
from mrlib.representation.rotations import (
    axis_angle_to_6d,
    matrix_to_axis_angle,
    sixd_to_axis_angle,
)
from mrlib.sampling.leg_ik import contact_runs
from mrlib.sampling.planting import PLANT_DEFAULTS, PlantOptions, move_ankles, smooth_foot_offsets

__all__ = [
    "remove_jitter",
    "JITTER_SIGMA",
    "jitter_at",
    "contact_skating",
    "contact_floor",
    "cleanup_foot_contacts",
    "FLOOR_PERCENTILE",
]


# -- clean-up of a Motion ------------------------------------------------------------------
# Gaussian sigma, in frames, of the jitter filter that opens the smooth clean-up. The
# finest level's noise reaches a sample as frame-to-frame jitter (FINE_NOISE); half a
# frame keeps 73 % of the amplitude at a quarter of the frame rate and 29 % at the
# Nyquist rate. On the preview preset's Bandai walks (two training seeds) it took the cleaned
# samples' jerk from 1.24 / 1.15x the training clips' to 0.96 / 0.88x with coverage at
# eps 1 up by 0.0-2.1 points and condition fidelity within 0.1 (bench/cleanup_natural.py).
JITTER_SIGMA = 0.5


def jitter_at(fps: float, model_fps: float) -> float:
    """The jitter filter's sigma, in frames at ``fps``, for a model's output drawn at
    ``model_fps`` and resampled: ``JITTER_SIGMA`` model frames, the same time at any rate."""
    return JITTER_SIGMA * float(fps) / float(model_fps)


def remove_jitter(motion: Motion, sigma: float = JITTER_SIGMA) -> Motion:
    """``motion`` with its joint rotations (as 6D, Zhou et al. 2019, continuous where
    axis-angle wraps) and root path low-passed over time by a Gaussian of ``sigma``
    frames (edges held); 0 returns it unchanged. Contact labels are kept."""
    sigma = float(sigma)
    if not (np.isfinite(sigma) and sigma >= 0):
        raise MotionValueError(f"jitter sigma must be a number of frames >= 0, got {sigma!r}")
    if sigma == 0 or motion.num_frames < 2:
        return motion
    from scipy.ndimage import gaussian_filter1d

    x = axis_angle_to_6d(torch.from_numpy(motion.poses.astype(np.float64))).numpy()
    x = gaussian_filter1d(x, sigma, axis=0, mode="nearest")
    poses = sixd_to_axis_angle(torch.from_numpy(x)).numpy().astype(motion.poses.dtype)
    trans = gaussian_filter1d(motion.trans.astype(np.float64), sigma, axis=0, mode="nearest")
    return motion.replace(poses=poses, trans=trans.astype(motion.trans.dtype))


def contact_skating(motion: Motion, body=None) -> float:
    """Mean speed (m/s) of the contact vertices on frames labelled in contact (both the
    frame and its predecessor): 0 for perfectly planted feet."""
    body = resolve_body(body)
    if motion.contacts is None:
        raise MotionValueError("motion has no contact labels")
    with torch.no_grad():
        R, t, b = body.motion_inputs(motion)
        p = body.forward(R, t, b, vertex_ids=list(body.foot_vertex_ids)).vertices  # (T, 6, 3)
    v = (p[1:] - p[:-1]).norm(dim=-1) * motion.fps  # (T-1, 6)
    c = torch.as_tensor(motion.contacts > 0.5)
    both = c[1:] & c[:-1]
    return float(v[both].mean()) if both.any() else 0.0


FLOOR_PERCENTILE = 50.0  # of the lowest contact vertex's height: the floor a clip stands on


def contact_floor(
    feet: np.ndarray | list[np.ndarray],
    contacts: np.ndarray | list[np.ndarray],
    percentile: float = FLOOR_PERCENTILE,
) -> float | None:
    """The height (m) planted feet rest at: a percentile (the median by default) of the
    lowest vertex labelled in contact, over the frames that have one, pooled over clips.
    ``feet (T, 6, 3)``, ``contacts (T, 6)`` (> 0.5 is contact), or lists of them. None
    when no vertex is ever in contact. On the Bandai walks it lies 0.4 to 0.5 cm above
    the evaluation's ground (the first percentile of all foot-vertex heights)."""
    feet = [feet] if not isinstance(feet, (list, tuple)) else list(feet)
    contacts = [contacts] if not isinstance(contacts, (list, tuple)) else list(contacts)
    lows = []
    for F, c in zip(feet, contacts, strict=True):
        c = np.asarray(c) > 0.5
        y = np.asarray(F, np.float64)[..., 1]
        lows.append(np.where(c, y, np.inf).min(1)[c.any(1)])
    low = np.concatenate(lows) if lows else np.zeros(0)
    return float(np.percentile(low, percentile)) if len(low) else None


def cleanup_foot_contacts(
    motion: Motion,
    body=None,
    *,
    floor: float | None = None,
    floor_clamp: bool = True,
    jitter: float = JITTER_SIGMA,
    move_root: bool = True,
    keep_path: bool = False,
    options: PlantOptions = PLANT_DEFAULTS,
) -> Motion:
    """Plant feet during predicted contacts (the paper's IK post-processing, Sec. 3.4).

    Frame-to-frame jitter is filtered out first (:func:`remove_jitter`, a Gaussian of
    ``jitter`` frames; 0 keeps the motion's own), then the root and each leg's ankle move
    by the smooth offsets of :func:`smooth_foot_offsets` (one sparse least-squares solve
    per axis: contact vertices held still, the corrections of least jerk, the root before
    the legs; the body lifted onto the floor and never far below it), analytic two-bone
    leg IK taking each ankle by its offset. ``floor`` is the height (m) planted feet rest
    at, when known (``generate`` passes its training clips',
    ``mrlib.sampling.generation.training_floor``); None estimates it from the motion
    (``contact_floor`` at ``FLOOR_PERCENTILE``); ``floor_clamp=False`` leaves heights
    alone. ``move_root=False`` keeps the root path (the legs take everything).
    ``keep_path=True`` keeps the root's ground path (x, z) exactly, jitter filter
    included, and lets the root move vertically only (onto the floor; not with
    ``move_root=False``): the legs take the feet's ground corrections. For a motion
    whose path is given, as ``mrlib.sampling.restyling.restyle``'s (the clip's).
    ``options``: the solve's knobs (:class:`mrlib.sampling.planting.PlantOptions`:
    ``smooth_s``, ``pin_weight``, ``leg_hold_s``, ...; ``hold=K``: the first K frames come
    back as they are and the corrections start from zero after them, a given prefix the
    rest continues, ``mrlib.sampling.constraints.continue_motion``). Milliseconds per clip.
    """
    if motion.contacts is None:
        raise MotionValueError("motion has no contact labels to clean up")
    given = motion
    ground = motion.trans[:, [0, 2]].copy()
    motion = remove_jitter(motion, jitter)
    if keep_path:  # the jitter filter leaves the ground path as it is
        trans = motion.trans.copy()
        trans[:, [0, 2]] = ground
        motion = motion.replace(trans=trans)
    body = resolve_body(body)
    R, trans, betas = body.motion_inputs(motion)
    ids = list(body.foot_vertex_ids)
    Rn, tn = R.double().cpu().numpy(), trans.double().cpu().numpy()
    on = dict(device=body.device, dtype=body.dtype)
    c = np.asarray(motion.contacts) > 0.5
    floor = floor if floor_clamp else None
    with torch.no_grad():
        out = body.forward(
            torch.from_numpy(Rn).to(**on), torch.from_numpy(tn).to(**on), betas, vertex_ids=ids
        )
    J, F = out.joints.double().cpu().numpy(), out.vertices.double().cpu().numpy()
    if floor is None and floor_clamp:
        floor = contact_floor(F, c, FLOOR_PERCENTILE)
    offset, legs = smooth_foot_offsets(
        F, c, motion.fps, floor=floor, move_root=move_root, ground_root=not keep_path,
        options=options,
    )  # fmt: skip
    Rn, tn = move_ankles(Rn, J, legs), tn + offset
    k = max(0, min(int(options.hold), motion.num_frames))
    runs = sum(len(contact_runs(c[:, v])) for v in range(6))
    poses = matrix_to_axis_angle(torch.from_numpy(Rn)).numpy().astype(np.float32)
    poses[:k], tn[:k] = given.poses[:k], given.trans[:k]  # as given, jitter filter included
    changed = {
        f.name: round(float(getattr(options, f.name)), 3)
        for f in fields(options)
        if getattr(options, f.name) != f.default
    }
    meta = dict(
        motion.meta,
        contact_cleanup={"method": "ik", "style": "smooth", "move_root": move_root,
                         "keep_path": bool(keep_path),
                         "jitter_sigma": float(jitter),
                         "floor": None if floor is None else round(floor, 4),
                         **changed, "runs": int(runs)},
    )  # fmt: skip
    return motion.replace(poses=poses, trans=tn.astype(np.float32), meta=meta)
