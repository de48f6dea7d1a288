"""Foot-contact clean-up: feet that stay put while labelled in contact, on the floor, with
motion that stays smooth (``cleanup_foot_contacts``); in closed form, vectorised over
frames, or by a per-frame optimisation (``method="optimise"``).

The paper refines predicted contacts by inverse kinematics (Sec. 3.4), as GANimator does
(Li et al., SIGGRAPH 2022), with a per-frame optimisation. Here the default
(``style="smooth"``) solves for the corrections of the whole clip at once, the
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

``style="pin"`` is the clean-up before it (:func:`plant_feet`): every contact vertex
pinned to its mean position over its run, eased in and out over ``BLEND_S`` seconds,
the root taking the common correction low-passed over ``ROOT_SMOOTH_S``. It plants
harder but steps the feet's velocity at the blends, changes the leg angles more and
leaves feet under the floor. ``bench/cleanup_natural.py`` measures both on the Bandai
walks (coverage, skating, jerk, penetration).
"""

from __future__ import annotations

import inspect

import numpy as np
import torch

from mrlib.errors import MotionValueError
from mrlib.representation.body import resolve_body
from mrlib.representation.motion import Motion
from mrlib.representation.rotations import (
    axis_angle_to_6d,
    axis_angle_to_matrix,
    matrix_to_axis_angle,
    sixd_to_axis_angle,
)
from mrlib.sampling.leg_ik import (
    BLEND_S,
    ROOT_SMOOTH_S,
    contact_runs,
)
from mrlib.sampling.planting import (
    plant_feet,
    plant_feet_smooth,
    smooth_foot_offsets,
)
from mrlib.threads import with_policy

__all__ = [
    "remove_jitter",
    "JITTER_SIGMA",
    "contact_skating",
    "contact_floor",
    "cleanup_foot_contacts",
    "LEG_JOINTS",
    "FLOOR_PERCENTILE",
]


# -- clean-up of a Motion ------------------------------------------------------------------
LEG_JOINTS = (1, 2, 4, 5, 7, 8, 10, 11)  # hips, knees, ankles, feet
# Gaussian sigma, in frames, of the jitter filter that opens the smooth clean-up. The
# finest level's noise reaches a sample as frame-to-frame jitter (FINE_NOISE); half a
# frame keeps 73 % of the amplitude at a quarter of the frame rate and 29 % at the
# Nyquist rate. On the demo preset's Bandai walks (two training seeds) it took the cleaned
# samples' jerk from 1.24 / 1.15x the training clips' to 0.96 / 0.88x with coverage at
# eps 1 up by 0.0-2.1 points and condition fidelity within 0.1 (bench/cleanup_natural.py).
JITTER_SIGMA = 0.5


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


def _cleanup_ik(
    motion: Motion, body, blend: int, passes: int = 2, move_root: bool = True,
    root_smooth: float = 0.0,
) -> Motion:  # fmt: skip
    if motion.contacts is None:
        raise MotionValueError("motion has no contact labels to clean up")
    body = resolve_body(body)
    R, trans, betas = body.motion_inputs(motion)
    ids = list(body.foot_vertex_ids)
    Rn, tn = R.double().cpu().numpy(), trans.double().cpu().numpy()
    on = dict(device=body.device, dtype=body.dtype)  # a body on an accelerator stays there
    for _ in range(passes):  # each pass re-poses the feet on the planted ones' means
        with torch.no_grad():
            out = body.forward(
                torch.from_numpy(Rn).to(**on), torch.from_numpy(tn).to(**on), betas, vertex_ids=ids
            )
        J, F = out.joints.double().cpu().numpy(), out.vertices.double().cpu().numpy()
        Rn, offset, info = plant_feet(
            Rn, J, F, motion.contacts, blend, move_root=move_root, root_smooth=root_smooth
        )
        tn = tn + offset
    poses = matrix_to_axis_angle(torch.from_numpy(Rn)).numpy().astype(np.float32)
    meta = dict(
        motion.meta,
        contact_cleanup={
            "method": "ik",
            "blend": blend,
            "move_root": move_root,
            "root_smooth": round(float(root_smooth), 3),
            **info,
        },  # fmt: skip
    )
    return motion.replace(poses=poses, trans=tn.astype(np.float32), meta=meta)


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


def _cleanup_smooth(
    motion: Motion, body, *, move_root: bool, floor_clamp: bool, floor_percentile: float,
    floor: float | None = None, passes: int = 1, jitter: float = JITTER_SIGMA, **kw,
) -> Motion:  # fmt: skip
    if motion.contacts is None:
        raise MotionValueError("motion has no contact labels to clean up")
    motion = remove_jitter(motion, jitter)
    body = resolve_body(body)
    R, trans, betas = body.motion_inputs(motion)
    ids = list(body.foot_vertex_ids)
    Rn, tn = R.double().cpu().numpy(), trans.double().cpu().numpy()
    on = dict(device=body.device, dtype=body.dtype)
    c = np.asarray(motion.contacts) > 0.5
    floor = floor if floor_clamp else None
    for _ in range(passes):
        with torch.no_grad():
            out = body.forward(
                torch.from_numpy(Rn).to(**on), torch.from_numpy(tn).to(**on), betas, vertex_ids=ids
            )
        J, F = out.joints.double().cpu().numpy(), out.vertices.double().cpu().numpy()
        if floor is None and floor_clamp:
            floor = contact_floor(F, c, floor_percentile)
        Rn, offset, info = plant_feet_smooth(
            Rn, J, F, c, motion.fps, floor=floor, move_root=move_root, **kw
        )
        tn = tn + offset
    poses = matrix_to_axis_angle(torch.from_numpy(Rn)).numpy().astype(np.float32)
    meta = dict(
        motion.meta,
        contact_cleanup={"method": "ik", "style": "smooth", "move_root": move_root,
                         "jitter_sigma": float(jitter),
                         "floor": None if floor is None else round(floor, 4),
                         **{k: round(float(v), 3) for k, v in kw.items()}, **info},
    )  # fmt: skip
    return motion.replace(poses=poses, trans=tn.astype(np.float32), meta=meta)


@with_policy
def cleanup_foot_contacts(
    motion: Motion,
    body=None,
    iterations: int = 150,
    lr: float = 0.02,
    weight_reg: float = 1e-2,
    weight_smooth: float = 1.0,
    *,
    method: str = "ik",
    blend: int | None = None,
    move_root: bool = True,
    root_smooth_s: float = ROOT_SMOOTH_S,
    style: str = "smooth",
    floor: float | None = None,
    floor_clamp: bool = True,
    floor_percentile: float = FLOOR_PERCENTILE,
    jitter: float = JITTER_SIGMA,
    **options,
) -> Motion:
    """Plant feet during predicted contacts (the paper's IK post-processing, Sec. 3.4).

    ``method="ik"`` (default), ``style="smooth"`` (default): frame-to-frame jitter is
    filtered out first (:func:`remove_jitter`, a Gaussian of ``jitter`` frames; 0 keeps
    the motion's own), then the root and each leg's
    ankle move by the smooth offsets of :func:`smooth_foot_offsets` (one sparse
    least-squares solve per axis: contact vertices held still, the corrections of least
    jerk, the root before the legs; the body lifted onto the floor and never far below
    it), analytic two-bone leg IK taking each ankle by its offset. ``floor`` is the
    height (m) planted feet rest at, when known (``generate`` passes its training
    clips', ``mrlib.sampling.generation.training_floor``); None estimates it from the
    motion (``contact_floor`` at ``floor_percentile``); ``floor_clamp=False`` leaves
    heights alone. ``move_root=False`` keeps the root path (the legs take everything).
    Further keyword ``options`` go to :func:`smooth_foot_offsets` (``smooth_s``,
    ``pin_weight``, ``leg_hold_s``, ...). Milliseconds per clip.

    ``style="pin"``: the clean-up before (:func:`plant_feet`): every contact vertex is
    pinned to its mean position over each contact run, eased in and out over ``blend``
    frames (default ``BLEND_S`` seconds); the root takes the planted feet's common
    correction, low-passed over ``root_smooth_s`` seconds (``move_root``), and two-bone
    leg IK the rest, the foot turning as a rigid body so that all its planted vertices
    hold. It plants harder but steps the feet's velocity at the blends (jerk), changes
    the leg angles more (coverage) and leaves feet under the floor
    (``bench/cleanup_natural.py``).

    ``method="optimise"``: for every contact vertex and every run of frames labelled in
    contact, the target is the vertex's mean position over the run (as GANimator does);
    axis-angle offsets of the leg joints (hips, knees, ankles, feet) are then optimised
    with Adam (``iterations``, ``lr``) to reach the targets, with a small penalty on the
    offsets (``weight_reg``) and on their frame-to-frame change (``weight_smooth``).
    It leaves the root trajectory untouched.
    """
    if method not in ("ik", "optimise"):
        raise MotionValueError(f"method must be 'ik' or 'optimise', got {method!r}")
    if style not in ("smooth", "pin"):
        raise MotionValueError(f"style must be 'smooth' or 'pin', got {style!r}")
    known = set(inspect.signature(smooth_foot_offsets).parameters) - {
        "feet", "contacts", "fps", "floor", "move_root"
    }  # fmt: skip
    unknown = sorted(set(options) - known)
    if unknown or (options and (method, style) != ("ik", "smooth")):
        raise MotionValueError(
            f"unknown options {unknown or sorted(options)}: only method='ik', style='smooth' "
            f"takes more, namely {sorted(known)}"
        )
    if method == "ik" and style == "smooth":
        return _cleanup_smooth(
            motion, body, move_root=move_root, floor=floor, floor_clamp=floor_clamp,
            floor_percentile=floor_percentile, jitter=jitter, **options,
        )  # fmt: skip
    if method == "ik":
        frames = max(1, round(BLEND_S * motion.fps)) if blend is None else int(blend)
        return _cleanup_ik(
            motion, body, frames, move_root=move_root, root_smooth=root_smooth_s * motion.fps
        )
    if motion.contacts is None:
        raise MotionValueError("motion has no contact labels to clean up")
    body = resolve_body(body)
    ids = list(body.foot_vertex_ids)
    R, trans, betas = body.motion_inputs(motion)
    with torch.no_grad():
        p0 = body.forward(R, trans, betas, vertex_ids=ids).vertices  # (T, 6, 3)
    c = np.asarray(motion.contacts) > 0.5
    target = p0.clone()
    active = torch.zeros(c.shape, dtype=torch.bool, device=p0.device)
    for v in range(c.shape[1]):
        for s, e in contact_runs(c[:, v]).tolist():
            if e > s:
                target[s : e + 1, v] = p0[s : e + 1, v].mean(0)
                active[s : e + 1, v] = True
    if not active.any():
        return motion.replace()
    legs = list(LEG_JOINTS)
    delta = torch.zeros(len(p0), len(legs), 3, device=R.device, dtype=R.dtype, requires_grad=True)
    opt = torch.optim.Adam([delta], lr=lr)
    for _ in range(iterations):
        opt.zero_grad()
        Rn = R.clone()
        Rn[:, legs] = R[:, legs] @ axis_angle_to_matrix(delta)
        p = body.forward(Rn, trans, betas, vertex_ids=ids).vertices
        err = ((p - target) ** 2).sum(-1)[active].mean()
        loss = (
            err
            + weight_reg * delta.pow(2).mean()
            + weight_smooth * (delta[1:] - delta[:-1]).pow(2).mean()
        )
        loss.backward()
        opt.step()
    with torch.no_grad():
        Rn = R.clone()
        Rn[:, legs] = R[:, legs] @ axis_angle_to_matrix(delta)
        poses = matrix_to_axis_angle(Rn).cpu().numpy()
    meta = dict(motion.meta, contact_cleanup={"iterations": iterations})
    return motion.replace(poses=poses, meta=meta)
