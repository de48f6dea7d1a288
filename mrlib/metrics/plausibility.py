"""Physical plausibility of motion: foot skating, jitter, ground penetration, and how far
the speed distributions of generated motion are from the training data's.

Coverage and diversity (``mrlib.metrics.coverage``, ``mrlib.metrics.diversity``) compare
body poses only. A clip can be fully covered and look diverse while its feet slide, its
joints shake or it sinks into the floor; these measures report that, on joint and
foot-vertex *positions* of the posed body (``mrlib.representation.body``), in SI units.

Quantities, for motions at ``fps`` frames per second:

* **Foot skating.** Horizontal (x-z) speed of the six foot contact vertices
  (``mrlib.representation.skeleton.CONTACT_NAMES``) on the frames where each is labelled in contact,
  velocities by central differences (the ones ``mrlib.representation.contacts`` labels contacts with).
  Reported as the mean speed (m/s) and the share of contact vertex-frames faster than
  ``SKATE_SPEED_THRESHOLD``. Labels are the motion's own ``contacts`` when it has them
  (a generator's predicted labels), else computed with ``mrlib.representation.contacts.foot_contacts``;
  the report says which (``contacts_from_motion``). Computed labels mark a vertex as in
  contact only while its 3-D speed is below 0.25 m/s, so with them the measure cannot
  exceed that speed: it then reads the slow sliding of planted feet, and a foot that
  slides fast is counted as swinging instead. Generated clips should be scored with the
  generator's own labels.
* **Jitter.** Mean magnitude of the jerk of the 24 joint positions, the third finite
  difference times ``fps**3`` (m/s^3), and its ratio to the training data's.
* **Ground penetration.** Per frame, how far the lowest foot vertex is below the ground
  (0 when above), in cm; mean over frames and the share of frames deeper than
  ``PENETRATION_THRESHOLD``. Retargeted Bandai Namco clips do not stand on y = 0: the
  lowest foot vertices sit 0 to 3 cm above it, depending on the clip (the first
  percentile of the foot-vertex heights of the walk clips ranges from 0.0 to 2.2 cm),
  and generated motion inherits the height of its training clip. The ground is
  therefore estimated from the *reference* as the ``GROUND_PERCENTILE``-th percentile
  of its foot-vertex heights, and the same plane is used for the motion scored against
  it.
* **Distribution distances.** 1-D Wasserstein distances
  (``scipy.stats.wasserstein_distance``) between generated and reference per-frame
  values of the root's ground speed (m/s, x-z speed of ``trans``) and of the angular
  speed of the local joint rotations (rad/s, geodesic angle between consecutive frames
  times ``fps``), pooled over the joints of each group in ``JOINT_GROUPS``.

Thresholds (measured on the Bandai Namco walk clips, 30 takes, retargeted to the
default body, contacts from ``foot_contacts``): the contact vertices move at 0.049 m/s
on average while labelled in contact (mocap noise and skin roll; heel strike and toe-off
frames are the fast ones). Above 0.10 m/s lie 11 % of the contact vertex-frames (34 %
on walk_happy_002), above 0.15 m/s 4.4 % (at most 8 % on any take), above 0.20 m/s
1.4 %. ``SKATE_SPEED_THRESHOLD = 0.15`` m/s (half a centimetre per frame at 30 fps)
sits above that noise and well below the 0.25 m/s contact threshold. Penetration: with
the ground at the first percentile, the reference's lowest vertex goes at most 0.7 cm
below it on any of the 50 clips checked, so ``PENETRATION_THRESHOLD = 1 cm`` counts no
frame of real data.

Dimension letters (``mrlib`` glossary): T frames, J joints (24), K foot vertices (6),
B samples.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
import torch
from scipy.stats import wasserstein_distance

from mrlib.errors import ClipTooShortError, MotionValueError
from mrlib.representation.body import resolve_body
from mrlib.representation.contacts import (
    DEFAULT_CONTACT_THRESHOLD,
    contacts_from_velocity,
    finite_difference_velocity,
)
from mrlib.representation.motion import Motion
from mrlib.representation.rotations import axis_angle_to_matrix, geodesic_distance
from mrlib.representation.skeleton import NUM_CONTACTS, NUM_JOINTS

__all__ = [
    "SKATE_SPEED_THRESHOLD",
    "PENETRATION_THRESHOLD",
    "GROUND_PERCENTILE",
    "JOINT_GROUPS",
    "motion_kinematics",
    "horizontal_speed",
    "contact_foot_speeds",
    "foot_skating",
    "joint_jerk",
    "mean_jerk",
    "motion_contacts",
    "estimate_ground",
    "penetration_depth",
    "root_ground_speed",
    "joint_angular_speed",
    "speed_distances",
    "plausibility_report",
]

SKATE_SPEED_THRESHOLD = 0.15  # m/s; above real-data contact noise, see the module docstring
PENETRATION_THRESHOLD = 0.01  # m; no frame of real data goes this deep below its ground
GROUND_PERCENTILE = 1.0  # percentile of reference foot-vertex heights taken as the ground

# Joints whose local rotations make up each angular-speed distribution. The pelvis
# (global orientation) is left out: it carries the turning of the whole body.
JOINT_GROUPS: dict[str, tuple[int, ...]] = {
    "legs": (1, 2, 4, 5, 7, 8, 10, 11),  # hips, knees, ankles, feet
    "arms": (13, 14, 16, 17, 18, 19, 20, 21, 22, 23),  # collars to hands
    "spine": (3, 6, 9, 12, 15),  # spine1-3, neck, head
}


# ---------------------------------------------------------------------------------------
# Validation helpers
# ---------------------------------------------------------------------------------------
def _positions(x: Any, name: str, k: int | None = None) -> np.ndarray:
    """``(T, K, 3)`` float64 positions, validated."""
    if isinstance(x, torch.Tensor):
        x = x.detach().cpu().numpy()
    arr = np.asarray(x, dtype=np.float64)
    if arr.ndim != 3 or arr.shape[-1] != 3 or (k is not None and arr.shape[1] != k):
        want = f"(T, {k if k is not None else 'K'}, 3)"
        raise MotionValueError(f"{name} must have shape {want} (metres), got {arr.shape}")
    if not np.isfinite(arr).all():
        raise MotionValueError(f"{name} has NaN or inf values")
    return arr


def _check_fps(fps: float) -> float:
    if not (np.isfinite(fps) and fps > 0):
        raise MotionValueError(f"fps must be a positive number, got {fps}")
    return float(fps)


def _need_frames(name: str, T: int, n: int, what: str) -> None:
    if T < n:
        raise ClipTooShortError(f"{name} has {T} frames; {what} needs at least {n}")


def _as_motions(x: Any, name: str) -> list[Motion]:
    items = [x] if isinstance(x, Motion) else list(x) if isinstance(x, Iterable) else None
    if not items or not all(isinstance(m, Motion) for m in items):
        raise MotionValueError(f"{name} must be a Motion or a non-empty list of Motions")
    return items


# ---------------------------------------------------------------------------------------
# Kinematics
# ---------------------------------------------------------------------------------------
@torch.no_grad()
def motion_kinematics(motion: Motion, body: Any = None) -> tuple[np.ndarray, np.ndarray]:
    """Joint and foot-vertex positions of a clip on ``body``.

    Args:
        motion: poses ``(T, 24, 3)``, trans ``(T, 3)``, betas (padded or cut to the
            body's ``num_betas``).
        body: a ``mrlib.representation.body.BodyModel``; None loads the default body.
    Returns:
        ``joints (T, 24, 3)`` and ``feet (T, 6, 3)``, float64 numpy, metres; feet in
        ``CONTACT_NAMES`` order.
    """
    if not isinstance(motion, Motion):
        raise MotionValueError(f"expected a mrlib.Motion, got {type(motion).__name__}")
    body = resolve_body(body)
    R, trans, betas = body.motion_inputs(motion)
    out = body(R, trans, betas, vertex_ids=list(body.foot_vertex_ids))
    return (
        out.joints.cpu().numpy().astype(np.float64),
        out.vertices.cpu().numpy().astype(np.float64),
    )


def _central_velocity(x: np.ndarray, fps: float) -> np.ndarray:
    """``(T, ...)`` -> ``(T, ...)`` per second; central inside, one-sided at the ends
    (as ``mrlib.representation.contacts.finite_difference_velocity``)."""
    v = np.empty_like(x)
    v[1:-1] = (x[2:] - x[:-2]) * (fps / 2.0)
    v[0] = (x[1] - x[0]) * fps
    v[-1] = (x[-1] - x[-2]) * fps
    return v


def horizontal_speed(positions: Any, fps: float) -> np.ndarray:
    """Ground-plane (x-z) speed of points over time.

    Args:
        positions: ``(T, K, 3)`` metres, Y up; ``T >= 2``.
        fps: frames per second.
    Returns:
        ``(T, K)`` m/s, central differences (one-sided at the first and last frame).
    """
    p = _positions(positions, "positions")
    _need_frames("positions", len(p), 2, "a speed")
    v = _central_velocity(p[..., [0, 2]], _check_fps(fps))
    return np.linalg.norm(v, axis=-1)


# ---------------------------------------------------------------------------------------
# Foot skating
# ---------------------------------------------------------------------------------------
def contact_foot_speeds(feet: Any, contacts: Any, fps: float) -> np.ndarray:
    """Horizontal speeds of the foot vertices on the frames they are in contact.

    Args:
        feet: ``(T, 6, 3)`` foot-vertex positions (metres).
        contacts: ``(T, 6)`` labels; values above 0.5 count as contact.
        fps: frames per second.
    Returns:
        ``(N,)`` m/s, one value per contact vertex-frame (N may be 0).
    """
    p = _positions(feet, "feet", NUM_CONTACTS)
    c = np.asarray(contacts, dtype=np.float64)
    if c.shape != p.shape[:2]:
        raise MotionValueError(
            f"contacts must have shape {p.shape[:2]} to match feet, got {c.shape}"
        )
    return horizontal_speed(p, fps)[c > 0.5]


def foot_skating(
    feet: Any, contacts: Any, fps: float, threshold: float = SKATE_SPEED_THRESHOLD
) -> tuple[float, float]:
    """Foot skating of one clip: ``(mean speed m/s, share above threshold)`` over its
    contact vertex-frames; ``(0.0, 0.0)`` when no vertex is ever in contact.

    Args:
        feet: ``(T, 6, 3)`` foot-vertex positions; contacts: ``(T, 6)`` labels.
        threshold: m/s (default ``SKATE_SPEED_THRESHOLD``).
    """
    s = contact_foot_speeds(feet, contacts, fps)
    if len(s) == 0:
        return 0.0, 0.0
    return float(s.mean()), float((s > threshold).mean())


# ---------------------------------------------------------------------------------------
# Jitter
# ---------------------------------------------------------------------------------------
def joint_jerk(joints: Any, fps: float) -> np.ndarray:
    """Jerk magnitude of every joint: third finite difference times ``fps**3``.

    Args:
        joints: ``(T, J, 3)`` positions (metres); ``T >= 4``.
    Returns:
        ``(T - 3, J)`` m/s^3.
    """
    p = _positions(joints, "joints")
    _need_frames("joints", len(p), 4, "a jerk")
    return np.linalg.norm(np.diff(p, n=3, axis=0), axis=-1) * _check_fps(fps) ** 3


def mean_jerk(joints: Any, fps: float) -> float:
    """Mean jerk magnitude over frames and joints (m/s^3) of ``joints (T, J, 3)``."""
    return float(joint_jerk(joints, fps).mean())


# ---------------------------------------------------------------------------------------
# Ground penetration
# ---------------------------------------------------------------------------------------
def estimate_ground(feet: Any, percentile: float = GROUND_PERCENTILE) -> float:
    """Ground height (metres): a low percentile of foot-vertex heights.

    Args:
        feet: ``(T, K, 3)`` foot-vertex positions of the reference, or a list of such
            arrays (pooled).
        percentile: in [0, 100]; 0 is the lowest vertex ever.
    """
    arrays = [feet] if not isinstance(feet, (list, tuple)) else list(feet)
    if not arrays:
        raise MotionValueError("estimate_ground: no foot positions")
    if not 0 <= percentile <= 100:
        raise MotionValueError(f"percentile must be in [0, 100], got {percentile}")
    y = np.concatenate([_positions(a, "feet")[..., 1].reshape(-1) for a in arrays])
    return float(np.percentile(y, percentile))


def penetration_depth(feet: Any, ground: float = 0.0) -> np.ndarray:
    """How far the lowest foot vertex is below the ground, per frame.

    Args:
        feet: ``(T, K, 3)`` foot-vertex positions (metres, Y up).
        ground: ground height (metres).
    Returns:
        ``(T,)`` depth in metres, 0 where every vertex is at or above the ground.
    """
    p = _positions(feet, "feet")
    return np.maximum(ground - p[..., 1].min(axis=1), 0.0)


# ---------------------------------------------------------------------------------------
# Speed distributions
# ---------------------------------------------------------------------------------------
def root_ground_speed(trans: Any, fps: float) -> np.ndarray:
    """``(T, 3)`` root translation -> ``(T,)`` x-z speed in m/s (central differences)."""
    t = np.asarray(trans.detach().cpu() if isinstance(trans, torch.Tensor) else trans, np.float64)
    if t.ndim != 2 or t.shape[1] != 3:
        raise MotionValueError(f"trans must have shape (T, 3), got {t.shape}")
    return horizontal_speed(t[:, None, :], fps)[:, 0]


def joint_angular_speed(poses: Any, fps: float) -> np.ndarray:
    """Angular speed of every local joint rotation.

    Args:
        poses: ``(T, 24, 3)`` axis-angle (radians); ``T >= 2``.
    Returns:
        ``(T - 1, 24)`` rad/s: the geodesic angle between the rotations of consecutive
        frames, times ``fps``.
    """
    aa = torch.as_tensor(np.asarray(poses, np.float64))
    if aa.ndim != 3 or tuple(aa.shape[1:]) != (NUM_JOINTS, 3):
        raise MotionValueError(f"poses must have shape (T, 24, 3), got {tuple(aa.shape)}")
    _need_frames("poses", len(aa), 2, "an angular speed")
    R = axis_angle_to_matrix(aa)
    return geodesic_distance(R[:-1], R[1:]).numpy() * _check_fps(fps)


def _speed_samples(motions: Sequence[Motion], groups: Mapping[str, Sequence[int]]):
    root = np.concatenate([root_ground_speed(m.trans, m.fps) for m in motions])
    ang = [joint_angular_speed(m.poses, m.fps) for m in motions]
    per_group = {
        g: np.concatenate([a[:, list(j)].reshape(-1) for a in ang]) for g, j in groups.items()
    }
    return root, per_group


def speed_distances(
    motions: Any, references: Any, groups: Mapping[str, Sequence[int]] | None = None
) -> dict[str, float]:
    """1-D Wasserstein distances between the per-frame speeds of two sets of clips.

    Args:
        motions: a ``Motion`` or a list (values pooled over clips).
        references: a ``Motion`` or a list (pooled).
        groups: name -> joint indices (default ``JOINT_GROUPS``).
    Returns:
        ``{"w_root_speed": m/s, "w_angspeed_<group>": rad/s, ...}``.
    """
    groups = JOINT_GROUPS if groups is None else groups
    gen = _speed_samples(_as_motions(motions, "motions"), groups)
    ref = _speed_samples(_as_motions(references, "references"), groups)
    out = {"w_root_speed": float(wasserstein_distance(gen[0], ref[0]))}
    for g in groups:
        out[f"w_angspeed_{g}"] = float(wasserstein_distance(gen[1][g], ref[1][g]))
    return out


# ---------------------------------------------------------------------------------------
# Report
# ---------------------------------------------------------------------------------------
def motion_contacts(
    motion: Motion, feet: Any, threshold: float = DEFAULT_CONTACT_THRESHOLD
) -> tuple[np.ndarray, bool]:
    """The contact labels a clip is scored with, and whether they are its own.

    Args:
        motion: a clip; its ``contacts (T, 6)`` are used when present.
        feet: ``(T, 6, 3)`` its foot-vertex positions (``motion_kinematics``).
        threshold: m/s, for clips without labels: the labels of
            ``mrlib.representation.contacts.foot_contacts`` (vertex speed below ``threshold``, central
            differences, no height gate), computed here from ``feet``.
    Returns:
        ``(labels (T, 6) float32 in {0, 1}, taken from the motion)``.
    """
    if motion.contacts is not None:
        return motion.contacts, True
    p = _positions(feet, "feet", NUM_CONTACTS)
    if len(p) != motion.num_frames:
        raise MotionValueError(f"feet has {len(p)} frames, {motion!r} has {motion.num_frames}")
    _need_frames(f"{motion!r}", len(p), 2, "contact labels")
    vel = finite_difference_velocity(torch.from_numpy(p), motion.fps)
    return contacts_from_velocity(vel, threshold), False


def _kinematics_of(motions: list[Motion], given: Any, body: Any, name: str) -> list:
    if given is None:
        return [motion_kinematics(m, body) for m in motions]
    given = list(given)
    if len(given) != len(motions):
        raise MotionValueError(f"{name} has {len(given)} entries for {len(motions)} motions")
    for m, (joints, feet) in zip(motions, given, strict=True):
        if len(joints) != m.num_frames or len(feet) != m.num_frames:
            raise MotionValueError(f"{name}: frame counts do not match {m!r}")
    return given


def plausibility_report(
    motions: Any,
    references: Any,
    body: Any = None,
    *,
    skate_threshold: float = SKATE_SPEED_THRESHOLD,
    penetration_threshold: float = PENETRATION_THRESHOLD,
    ground_percentile: float = GROUND_PERCENTILE,
    kinematics: Sequence[tuple[np.ndarray, np.ndarray]] | None = None,
    reference_kinematics: Sequence[tuple[np.ndarray, np.ndarray]] | None = None,
) -> dict[str, float]:
    """Plausibility of ``motions`` next to the training clip(s) ``references``.

    Args:
        motions: a ``Motion`` or a list of them (e.g. B generated samples); frame values
            are pooled over all of them.
        references: the training clip(s) of the same content.
        body: ``BodyModel`` (default body when None).
        skate_threshold: m/s for ``skate_share``.
        penetration_threshold: metres for ``penetration_share``.
        ground_percentile: the ground height is estimated from ``references``
            (``estimate_ground`` at this percentile of their foot-vertex heights).
        kinematics, reference_kinematics: ``motion_kinematics(m, body)`` of every
            motion / reference, when already computed (saves the body forward).

    Returns:
        dict with

        * ``skate_speed`` (m/s) and ``skate_share``: mean horizontal speed of contact
          vertex-frames, share above ``skate_threshold``;
        * ``contact_share``: share of foot vertex-frames labelled in contact;
        * ``contacts_from_motion``: share of ``motions`` whose labels were their own
          (1.0) rather than computed by ``foot_contacts`` (0.0);
        * ``jerk`` and ``jerk_reference`` (m/s^3), ``jerk_ratio`` (motions / reference);
        * ``ground`` (m), ``penetration_cm`` (mean depth over frames, cm) and
          ``penetration_share`` (share of frames deeper than the threshold);
        * ``w_root_speed`` (m/s), ``w_angspeed_legs`` / ``_arms`` / ``_spine`` (rad/s).
    """
    gens = _as_motions(motions, "motions")
    refs = _as_motions(references, "references")
    if not (np.isfinite(skate_threshold) and skate_threshold > 0):
        raise MotionValueError(f"skate_threshold must be a positive speed, got {skate_threshold}")
    if not (np.isfinite(penetration_threshold) and penetration_threshold >= 0):
        raise MotionValueError(f"penetration_threshold must be >= 0, got {penetration_threshold}")
    for name, ms in (("motions", gens), ("references", refs)):
        for m in ms:
            _need_frames(f"{name}: {m!r}", m.num_frames, 4, "the plausibility report")
    body = resolve_body(body)

    ref_kin = _kinematics_of(refs, reference_kinematics, body, "reference_kinematics")
    ground = estimate_ground([f for _, f in ref_kin], ground_percentile)
    jerk_ref = float(
        np.concatenate(
            [joint_jerk(j, m.fps).ravel() for (j, _), m in zip(ref_kin, refs, strict=True)]
        ).mean()
    )

    kinematics = _kinematics_of(gens, kinematics, body, "kinematics")
    speeds, jerks, depths, contact_frames, own = [], [], [], [], []
    for m, (joints, feet) in zip(gens, kinematics, strict=True):
        c, is_own = motion_contacts(m, feet)
        speeds.append(contact_foot_speeds(feet, c, m.fps))
        contact_frames.append((np.asarray(c) > 0.5).mean())
        own.append(float(is_own))
        jerks.append(joint_jerk(joints, m.fps).ravel())
        depths.append(penetration_depth(feet, ground))
    s = np.concatenate(speeds)
    d = np.concatenate(depths)
    jerk = float(np.concatenate(jerks).mean())
    report = {
        "skate_speed": float(s.mean()) if len(s) else 0.0,
        "skate_share": float((s > skate_threshold).mean()) if len(s) else 0.0,
        "contact_share": float(np.mean(contact_frames)),
        "contacts_from_motion": float(np.mean(own)),
        "jerk": jerk,
        "jerk_reference": jerk_ref,
        "jerk_ratio": jerk / jerk_ref if jerk_ref > 0 else (float("inf") if jerk > 0 else 1.0),
        "ground": float(ground),
        "penetration_cm": float(d.mean() * 100.0),
        "penetration_share": float((d > penetration_threshold).mean()),
    }
    report.update(speed_distances(gens, refs))
    return report
