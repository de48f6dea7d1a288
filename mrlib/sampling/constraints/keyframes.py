"""Keyframes, in-betweening and continuation.

A :class:`Keyframe` fixes a full or partial pose (some joints' rotations, the root
position) at one frame. :func:`generate_with_keyframes` meets keyframes in three steps:

1. **Noise.** The noise maps are optimised with the networks frozen
   (``mrlib.sampling.constraints.optimise``, :func:`keyframe_objective`) towards the keyframes'
   joint rotations and the distances between root keyframes, so the model's own motion
   comes close by itself, and towards a low jerk within ``STILL_S`` seconds of each
   keyframe: the finest levels' noise reaches the output as frame-to-frame jitter,
   which the fit takes out where a pop would show. The jerk is weighed twice: in the
   generator's normalised pose and root channels, and in the joint positions the body
   model gives them (``JOINT_JERK``), where the jitter shows: a small rotation jitter at
   the hip moves the foot by the leg's length, and the foot planting that follows
   (``clean``) corrects the feet by more the more they jitter.
2. **Placement.** The motion is turned about the vertical and moved on the ground
   (one rigid motion for the whole clip) to fit the root keyframes best.
3. **Exact fit.** What is left at each keyframe, a rotation per constrained joint and a
   root offset, is spread over the neighbouring frames with a quintic ease (zero
   velocity and acceleration at both ends): between two keyframes the residual eases
   from one keyframe's to the next's; before the first and after the last it eases to
   zero over ``blend_s`` seconds. Every keyframe then holds exactly, with no pop.

:func:`continue_motion` extends a given prefix: the noise is fitted to the prefix, the
prefix is kept as it is, and the generated rest takes the prefix's last pose and
velocity with a cubic Hermite ease over ``BLEND_S`` seconds.

The module is long because it also reads and writes keyframe files
(:func:`save_keyframes`, :func:`load_keyframes`): every array's header is checked
(shape, type, size) before its data is read, and every value (whole, in-range frames;
finite, bounded poses and translations) before a :class:`Keyframe` is made, so that a
damaged file is one ``MotionFileError`` naming it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import torch

from mrlib.errors import MotionValueError, check_count, check_number
from mrlib.representation.features import ROOT_SLICE
from mrlib.representation.motion import Motion
from mrlib.representation.skeleton import NUM_JOINTS
from mrlib.sampling.arguments import checked
from mrlib.sampling.constraints.common import fitted_motion, label_setup, pelvis_rest, planted
from mrlib.sampling.constraints.keyframe_files import Keyframe, check_keyframes
from mrlib.sampling.constraints.optimise import NoiseFit, check_noise_fit
from mrlib.sampling.sampler import Sampler

__all__ = [
    "align_to_keyframes",
    "apply_keyframes",
    "keyframe_errors",
    "keyframe_objective",
    "KeyframeFit",
    "generate_with_keyframes",
    "continue_motion",
]

BLEND_S = 1.0  # seconds over which a residual eases out before the first / after the last keyframe
STILL_S = 0.5  # the window on either side of a keyframe whose jerk the noise fit lowers
STILL = 5.0  # weight of that jerk in the noise fit (generate_with_keyframes)
# weight of the joint positions' mean squared jerk (over the model's training clips' mean
# jerk, squared) beside the normalised channels', within the jerk term
JOINT_JERK = 2e-3
# Adam steps of the noise fit (generate_with_keyframes). On the Bandai walks the preset's
# models met the jerk target at 150, but models trained with a larger learning rate
# (sharper labels) needed 300 at the partial keyframe (docs/results.md, "Keyframes").
FIT_STEPS = 300
CONTINUE_FIT = NoiseFit(steps=100)  # continue_motion's noise fit: 100 Adam steps


@dataclass(frozen=True)
class KeyframeFit(NoiseFit):
    """The noise fit of :func:`generate_with_keyframes`: a ``NoiseFit`` (``FIT_STEPS``
    Adam steps by default, 0 skips it; a progress bar) whose loss also weighs the jerk
    within ``STILL_S`` seconds of a keyframe by ``still`` (``STILL``; 0: the keyframes
    alone)."""

    steps: int = FIT_STEPS
    still: float = STILL

    def __post_init__(self) -> None:
        super().__post_init__()
        object.__setattr__(self, "still", check_number("KeyframeFit.still", self.still, low=0))


def _mat(aa: np.ndarray) -> np.ndarray:
    from mrlib.representation.rotations import axis_angle_to_matrix

    return axis_angle_to_matrix(torch.from_numpy(np.asarray(aa, np.float64))).numpy()


def _aa(R: np.ndarray) -> np.ndarray:
    from mrlib.representation.rotations import matrix_to_axis_angle

    return matrix_to_axis_angle(torch.from_numpy(np.asarray(R, np.float64))).numpy()


def _ease(u: np.ndarray) -> np.ndarray:
    """Quintic ease 0 -> 1 on [0, 1] with zero first and second derivatives at both ends."""
    u = np.clip(u, 0.0, 1.0)
    return u * u * u * (u * (6 * u - 15) + 10)


def _spread(T: int, frames: list[int], values: list[np.ndarray], width: float) -> np.ndarray:
    """``(T, D)`` field equal to ``values[k]`` at ``frames[k]``, eased between keyframes
    and out to zero over ``width`` frames beyond the first and last."""
    order = np.argsort(frames)
    f = np.asarray(frames)[order]
    v = np.asarray(values)[order]
    t = np.arange(T, dtype=np.float64)
    out = np.zeros((T, v.shape[1]))
    w = max(float(width), 1.0)
    before = t < f[0]
    out[before] = v[0] * _ease(1 - (f[0] - t[before]) / w)[:, None]
    after = t > f[-1]
    out[after] = v[-1] * _ease(1 - (t[after] - f[-1]) / w)[:, None]
    for k in range(len(f)):
        if k + 1 < len(f):
            seg = (t >= f[k]) & (t <= f[k + 1])
            s = _ease((t[seg] - f[k]) / max(f[k + 1] - f[k], 1))[:, None]
            out[seg] = (1 - s) * v[k] + s * v[k + 1]
        else:
            out[t == f[k]] = v[k]
    return out


def _check_frames(motion: Motion, keyframes: Sequence[Keyframe]) -> None:
    if not keyframes:
        raise MotionValueError("no keyframes given")
    bad = [kf.frame for kf in keyframes if kf.frame >= motion.num_frames]
    if bad:
        raise MotionValueError(
            f"keyframes at frames {bad} are beyond the motion's {motion.num_frames} frames "
            f"({motion.duration:.4g} s at {motion.fps:g} fps)"
        )
    frames = [kf.frame for kf in keyframes]
    if len(set(frames)) != len(frames):
        raise MotionValueError(f"two keyframes at the same frame: {sorted(frames)}")


@checked(keyframes=check_keyframes)
def align_to_keyframes(motion: Motion, keyframes: Sequence[Keyframe], body=None) -> Motion:
    """``motion`` turned about the vertical and moved on the ground (one rigid motion)
    to fit the root keyframes: with two or more, the best fit of their ground positions;
    with one, its position and (when it fixes joint 0) its heading; with none, the
    heading of the first keyframe that fixes joint 0."""
    from mrlib.representation.body import resolve_body
    from mrlib.sampling.constraints.path import heading_of, yaw_matrix

    body = resolve_body(body, shared=True)
    _check_frames(motion, keyframes)
    J0 = pelvis_rest(motion, body)
    pel = motion.trans.astype(np.float64) + J0
    roots = [kf for kf in keyframes if kf.trans is not None]
    oriented = [kf for kf in keyframes if kf.poses is not None and 0 in kf.joints]
    R0 = _mat(motion.poses[:, 0])

    def facing_change(kf: Keyframe) -> float:
        f_key = _mat(kf.poses[0])[[0, 2], 2]
        f_gen = R0[kf.frame][[0, 2], 2]
        return float(heading_of(f_key) - heading_of(f_gen))

    alpha, shift = 0.0, np.zeros(2)
    if len(roots) >= 2:
        P = np.stack([pel[kf.frame, [0, 2]] for kf in roots])
        Q = np.stack([kf.trans[[0, 2]] + J0[[0, 2]] for kf in roots])
        p, q = P - P.mean(0), Q - Q.mean(0)
        alpha = float(np.arctan2((q[:, 0] * p[:, 1] - q[:, 1] * p[:, 0]).sum(), (q * p).sum()))
        c = yaw_matrix(alpha)[[0, 2]][:, [0, 2]] @ P.mean(0)
        shift = Q.mean(0) - c
    elif roots:
        kf = roots[0]
        if kf.poses is not None and 0 in kf.joints:
            alpha = facing_change(kf)
        c = yaw_matrix(alpha)[[0, 2]][:, [0, 2]] @ pel[kf.frame, [0, 2]]
        shift = kf.trans[[0, 2]] + J0[[0, 2]] - c
    elif oriented:
        alpha = facing_change(oriented[0])
    Ry = yaw_matrix(alpha)
    new_pel = pel @ Ry.T
    new_pel[:, [0, 2]] += shift
    poses = motion.poses.copy()
    poses[:, 0] = _aa(Ry @ R0)
    return motion.replace(poses=poses, trans=new_pel - J0)


@checked(keyframes=check_keyframes)
def apply_keyframes(
    motion: Motion, keyframes: Sequence[Keyframe], *, blend_s: float = BLEND_S
) -> Motion:
    """``motion`` with every keyframe holding exactly, the residuals eased over the
    neighbouring frames (module docstring, step 3). Place the motion first
    (:func:`align_to_keyframes`) so that the residuals are small."""
    _check_frames(motion, keyframes)
    T = motion.num_frames
    width = blend_s * motion.fps
    R = _mat(motion.poses)  # (T, 24, 3, 3)
    poses = motion.poses.astype(np.float64).copy()
    for j in range(NUM_JOINTS):
        ks = [kf for kf in keyframes if kf.poses is not None and j in kf.joints]
        if not ks:
            continue
        res = [_aa(_mat(kf.poses[j]) @ R[kf.frame, j].T) for kf in ks]
        field = _spread(T, [kf.frame for kf in ks], res, width)  # (T, 3)
        poses[:, j] = _aa(_mat(field) @ R[:, j])
    trans = motion.trans.astype(np.float64).copy()
    ks = [kf for kf in keyframes if kf.trans is not None]
    if ks:
        res = [kf.trans - trans[kf.frame] for kf in ks]
        trans += _spread(T, [kf.frame for kf in ks], res, width)
    meta = dict(motion.meta, keyframes=sorted(kf.frame for kf in keyframes))
    return motion.replace(poses=poses, trans=trans, meta=meta)


@checked(keyframes=check_keyframes)
def keyframe_errors(motion: Motion, keyframes: Sequence[Keyframe]) -> dict[str, float]:
    """Largest error at the keyframes: ``rotation_deg`` (geodesic, over constrained
    joints) and ``trans_cm``."""
    _check_frames(motion, keyframes)
    rot, pos = 0.0, 0.0
    for kf in keyframes:
        if kf.poses is not None:
            j = list(kf.joints)
            D = _mat(kf.poses[j]) @ np.swapaxes(_mat(motion.poses[kf.frame, j]), -1, -2)
            cos = np.clip((np.trace(D, axis1=-2, axis2=-1) - 1) / 2, -1, 1)
            rot = max(rot, float(np.degrees(np.arccos(cos)).max()))
        if kf.trans is not None:
            pos = max(pos, 100 * float(np.linalg.norm(kf.trans - motion.trans[kf.frame])))
    return {"rotation_deg": rot, "trans_cm": pos}


# -- with a model ---------------------------------------------------------------------------
def _sixd(R: torch.Tensor) -> torch.Tensor:
    return R[..., :, :2].transpose(-1, -2).reshape(*R.shape[:-2], 6)


def _clips_jerk(model, body) -> float:
    """Mean joint jerk (m/s^3) of the model's training clips on ``body``."""
    from mrlib.metrics.plausibility import mean_jerk, motion_kinematics
    from mrlib.representation.features import features_to_motion

    clips = [features_to_motion(x, model.fps, betas=model.betas) for x in model.features]
    return float(np.mean([mean_jerk(motion_kinematics(m, body)[0], model.fps) for m in clips]))


@checked(keyframes=check_keyframes, length=check_count)
def keyframe_objective(
    model, keyframes: Sequence[Keyframe], length: int, still: float = STILL, body=None
):
    """The noise fit's loss of generator output ``x (1, C, length)`` (normalised): the
    squared 6D error of the keyframes' joint rotations (the root's own is placed
    afterwards), the error of the ground distance between consecutive root keyframes,
    and ``still`` times the jerk within ``STILL_S`` seconds of a keyframe: the mean
    squared third difference of the pose and root channels plus ``JOINT_JERK`` times the
    mean squared jerk of the joint positions on ``body`` over the training clips' mean
    jerk squared. None when there is nothing to fit: no joint rotation but the root's
    and fewer than two root keyframes (a lone root keyframe is placed afterwards)."""
    from mrlib.representation.body import resolve_body
    from mrlib.representation.rotations import axis_angle_to_matrix
    from mrlib.sampling.constraints.optimise import decode

    if not (np.isfinite(still) and still >= 0):
        raise MotionValueError(f"still must be a number >= 0, got {still!r}")
    posed = [kf for kf in keyframes if kf.poses is not None]
    roots = sorted((kf for kf in keyframes if kf.trans is not None), key=lambda k: k.frame)
    centre = np.arange(max(length - 3, 0)) + 1.5  # the frame each third difference is about
    near = np.zeros(len(centre), bool)
    for kf in keyframes:
        near |= np.abs(centre - kf.frame) <= STILL_S * model.fps
    near_t = torch.from_numpy(near).to(model.device)
    still = float(still) if near.any() else 0.0
    # nothing the generator must be moved for: a root keyframe alone is placed afterwards
    # (align_to_keyframes), and the jerk term by itself would fit the body to stillness
    if not (any(j > 0 for kf in posed for j in kf.joints) or len(roots) >= 2):
        return None
    if still > 0:
        body = resolve_body(body, shared=True)
        betas = torch.as_tensor(np.asarray(model.betas, np.float32))
        per_joint = JOINT_JERK * (model.fps**3 / _clips_jerk(model, body)) ** 2
    tgt = [
        (kf.frame, [j for j in kf.joints if j > 0],
         _sixd(axis_angle_to_matrix(torch.from_numpy(kf.poses))).float().to(model.device))
        for kf in posed
    ]  # fmt: skip
    gaps = [
        (a.frame, b.frame, float(np.linalg.norm((b.trans - a.trans)[[0, 2]])))
        for a, b in zip(roots, roots[1:], strict=False)
    ]

    def loss_fn(x: torch.Tensor) -> torch.Tensor:
        d = decode(model, x)
        loss = x.new_zeros(())
        for f, js, six in tgt:
            if js:
                loss = loss + (_sixd(d["rotations"][0, f, js]) - six[js]).pow(2).mean()
        for a, b, dist in gaps:
            step = d["trans"][0, b, [0, 2]] - d["trans"][0, a, [0, 2]]
            loss = loss + (step.norm() - dist).pow(2)
        if still > 0:
            y = x[:, : ROOT_SLICE.stop]  # pose and root channels, normalised
            jerk = y[..., 3:] - 3 * y[..., 2:-1] + 3 * y[..., 1:-2] - y[..., :-3]
            on = body.device
            J = body(d["rotations"][0].to(on), d["trans"][0].to(on), betas).joints  # (T, 24, 3) m
            dJ = J[3:] - 3 * J[2:-1] + 3 * J[1:-2] - J[:-3]
            joints = per_joint * dJ[near_t.to(on)].pow(2).sum(-1).mean().to(x.device)
            loss = loss + still * (jerk[..., near_t].pow(2).mean() + joints)
        return loss

    return loss_fn


@checked(keyframes=check_keyframes, length=check_count, fit=check_noise_fit)
def generate_with_keyframes(
    model,
    keyframes: Sequence[Keyframe],
    length: int,
    condition=None,
    *,
    seed: int | None = None,
    sampler=None,
    fit: NoiseFit = KeyframeFit(),
    body=None,
) -> Motion:
    """A motion of ``length`` frames under a condition (a label or a ``mrlib.Condition``;
    None: the first label) that holds ``keyframes`` (method: module docstring; residuals
    ease out over ``BLEND_S`` seconds). ``fit``: the noise fit (:class:`KeyframeFit`:
    ``FIT_STEPS`` Adam steps, the jerk weight ``still``; a plain ``NoiseFit`` weighs the
    jerk by ``STILL``). ``sampler``: a ``mrlib.Sampler`` (fine noise, guidance; ``fps``:
    the output's frame rate, at which the keyframes' frames count, the motion drawn and
    fitted at the model's and resampled by cubic splines before the feet are planted and
    the keyframes laid; its ``fix_contacts`` plants the feet before the exact fit).
    ``length`` counts the model's frames, as ``mrlib.generate``'s: the output has
    ``round(length * fps / model.fps)``."""
    from mrlib.representation.body import resolve_body

    sampler = Sampler() if sampler is None else sampler
    still = fit.still if isinstance(fit, KeyframeFit) else STILL
    body = resolve_body(body, shared=True)
    if length < 2:
        raise MotionValueError(f"length must be >= 2 frames, got {length}")
    fps = float(sampler.fps or model.fps)
    n_out = length if fps == model.fps else round(length * fps / model.fps)
    probe = Motion(np.zeros((n_out, NUM_JOINTS, 3)), np.zeros((n_out, 3)), fps)
    _check_frames(probe, keyframes)
    # the fit at the model's rate: each keyframe at its nearest model frame
    at_model = [replace(kf, frame=min(round(kf.frame * model.fps / fps), length - 1))
                for kf in keyframes]  # fmt: skip
    noises, conds, label, rate_of, record = label_setup(model, condition, length, seed, sampler)
    loss_fn = keyframe_objective(model, at_model, length, still, body)
    name = f"{label}_keyframes_seed{seed}"
    m = fitted_motion(model, noises, conds, label, name, loss_fn, fit, rate_of)
    m.meta["sampler"] = record
    m = planted(_raised(m, fps, n_out), sampler, body, model)
    m = align_to_keyframes(m, keyframes, body)
    return apply_keyframes(m, keyframes, blend_s=BLEND_S)


def _raised(m: Motion, fps: float, frames: int) -> Motion:
    """The model's motion ``m`` at ``fps`` with ``frames`` frames (cubic splines)."""
    if abs(fps - m.fps) < 1e-9 and frames == m.num_frames:
        return m
    return m.resample(fps, smooth=True, frames=frames)


@checked(fit=check_noise_fit)
def continue_motion(
    model,
    prefix: Motion,
    frames: int,
    condition=None,
    *,
    seed: int | None = None,
    sampler=None,
    fit: NoiseFit = CONTINUE_FIT,
    body=None,
) -> Motion:
    """``prefix`` followed by ``frames`` new frames in the model's style under a condition
    (a label or a ``mrlib.Condition``; None: the first label) (method: module docstring;
    the new frames ease in over ``BLEND_S`` seconds). ``fit``: the noise fit to the prefix
    (``NoiseFit``: Adam steps, 100 by default; a progress bar). ``sampler``: a
    ``mrlib.Sampler`` (fine noise, guidance; ``fps``: the output's frame rate, default the
    prefix's own, the model's for a prefix under ``MIN_SOURCE_FPS``; its ``fix_contacts``
    plants the feet of the new frames after the ease, the prefix held as it is:
    ``PlantOptions.hold``). The noise is fitted to the prefix resampled to the model's
    frame rate; the output holds the prefix at the output's rate (itself, frame for frame,
    when that is its own) and ``frames`` model frames more, as many at that rate as last as
    long (``round(frames * fps / model.fps)``). A prefix and
    ``frames`` longer together than ``MAX_SAMPLE_SECONDS`` are refused before."""
    from mrlib.representation.body import resolve_body
    from mrlib.representation.rotations import axis_angle_to_matrix
    from mrlib.sampling.constraints.optimise import decode
    from mrlib.sampling.generation import MAX_SAMPLE_SECONDS

    if not isinstance(prefix, Motion):
        raise MotionValueError(f"prefix must be a Motion, got {type(prefix).__name__}")
    K = prefix.resampled_frames(model.fps)
    if K + frames > MAX_SAMPLE_SECONDS * model.fps + 1:
        what = f"prefix {prefix.name!r}" if prefix.name else "prefix"
        raise MotionValueError(
            f"{what}: {prefix.num_frames} frames at {prefix.fps:g} fps are "
            f"{K} frames at the model's {model.fps:g} fps; with {frames} more, "
            f"{(K + frames) / model.fps:.4g} s is longer than the {MAX_SAMPLE_SECONDS:.0f} s "
            "mrlib generates in one sample; continue from the prefix's last seconds "
            "(prefix.slice) or ask for fewer frames"
        )
    from mrlib.model.trained import MIN_SOURCE_FPS
    from mrlib.sampling.constraints.common import sole_lift

    body = resolve_body(body, shared=True)
    sampler = Sampler() if sampler is None else sampler
    # the prefix's own rate, unless asked (or a rate no motion is written at: keyframes)
    own = prefix.fps if prefix.fps >= min(MIN_SOURCE_FPS, model.fps) else model.fps
    fps = float(sampler.fps or own)
    kept = prefix if abs(prefix.fps - fps) < 1e-6 else prefix.resample(fps)  # in the output
    if abs(prefix.fps - model.fps) > 1e-6:
        prefix = prefix.resample(model.fps)
    K = prefix.num_frames
    if K < 2 or frames < 1 or kept.num_frames < 2:
        raise MotionValueError(f"need a prefix of >= 2 frames and frames >= 1, got {K}, {frames}")
    T = K + int(frames)
    noises, conds, label, rate_of, record = label_setup(model, condition, T, seed, sampler)
    six = _sixd(axis_angle_to_matrix(torch.from_numpy(prefix.poses[:, 1:].astype(np.float64))))
    six = six.float().to(model.device)  # (K, 23, 6)
    # fitted and drawn on the model's body, the output on the prefix's: soles as high
    lift = sole_lift(body, model.betas, prefix.betas)
    height = torch.from_numpy((prefix.trans[:, 1] - lift).astype(np.float32)).to(model.device)
    speed = torch.from_numpy(
        np.linalg.norm(np.gradient(prefix.trans[:, [0, 2]], axis=0), axis=1).astype(np.float32)
    ).to(model.device)

    def loss_fn(x: torch.Tensor) -> torch.Tensor:
        d = decode(model, x)
        rot = (_sixd(d["rotations"][0, :K, 1:]) - six).pow(2).mean()
        tr = d["trans"][0, :K]
        sp = torch.linalg.vector_norm(tr[1:, [0, 2]] - tr[:-1, [0, 2]], dim=-1)
        root = (tr[:, 1] - height).pow(2).mean() + (sp - speed[1:]).pow(2).mean()
        return rot + root

    name = f"{prefix.name or 'prefix'}_continued"
    m = fitted_motion(model, noises, conds, label, name, loss_fn, fit, rate_of)
    m.meta["sampler"] = record
    m = m.replace(betas=prefix.betas, trans=m.trans + np.float32([0.0, lift, 0.0]))
    # the fit done: at the output's rate, the prefix as kept there, the new frames after it
    prefix, K = kept, kept.num_frames
    T = K + max(1, round(frames * fps / model.fps)) if fps != model.fps else T
    m = _raised(m, fps, T)  # the feet are planted after the ease, the prefix held
    anchors = [Keyframe(f, prefix.poses[f], (0,), prefix.trans[f]) for f in range(K)]
    m = align_to_keyframes(m, anchors, body)
    # keep the prefix; ease the rest from the prefix's last pose and velocity
    R = _mat(m.poses)
    Rp = _mat(prefix.poses)
    r1 = _aa(Rp[K - 1] @ np.swapaxes(R[K - 1], -1, -2))  # (24, 3)
    r0 = _aa(Rp[K - 2] @ np.swapaxes(R[K - 2], -1, -2))
    d1 = prefix.trans[K - 1] - m.trans[K - 1]
    d0 = prefix.trans[K - 2] - m.trans[K - 2]
    w = max(BLEND_S * fps, 1.0)
    u = np.clip((np.arange(T - K + 1)) / w, 0, 1)[:, None]  # frames K-1 .. T-1
    h00, h10 = 2 * u**3 - 3 * u**2 + 1, (u**3 - 2 * u**2 + u) * w
    poses = m.poses.astype(np.float64).copy()
    for j in range(NUM_JOINTS):
        field = h00 * r1[j] + h10 * (r1[j] - r0[j])
        poses[K - 1 :, j] = _aa(_mat(field) @ R[K - 1 :, j])
    trans = m.trans.astype(np.float64).copy()
    # on the ground the gap at the join stays and the prefix's velocity fades into the
    # model's, never back (fading the gap, or a velocity term that returns to zero, pulled
    # the root back over the blend when the model walks slower than the clip); the
    # height eases back to the model's
    gap = h00 * d1 + h10 * (d1 - d0)
    ease = (u - u**2 + u**3 / 3) * w  # its slope goes from 1 to 0, its value only grows
    gap[:, [0, 2]] = d1[[0, 2]] + ease * (d1 - d0)[[0, 2]]
    trans[K - 1 :] += gap
    poses[:K], trans[:K] = prefix.poses, prefix.trans
    contacts = m.contacts
    if contacts is not None:
        contacts = contacts.copy()
        if prefix.contacts is not None:
            contacts[:K] = prefix.contacts
        else:
            from mrlib.representation.contacts import foot_contacts

            contacts[:K] = foot_contacts(prefix, body)
    meta = dict(m.meta, prefix_frames=K)
    out = m.replace(poses=poses, trans=trans, contacts=contacts, meta=meta)
    if not sampler.fix_contacts or contacts is None:
        return out
    from mrlib.sampling.cleanup import cleanup_foot_contacts, jitter_at
    from mrlib.sampling.planting import PLANT_DEFAULTS

    # the prefix as it is; the corrections start from zero at the join, so the eased
    # frames after it are planted too
    jitter, held = jitter_at(fps, model.fps), replace(PLANT_DEFAULTS, hold=K)
    return cleanup_foot_contacts(out, body, jitter=jitter, options=held)
