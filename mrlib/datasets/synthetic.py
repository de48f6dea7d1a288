"""Procedural, labelled SMPL motion that mrlib generates itself.

These clips are what ``data_samples/`` holds and what the demo trains on when no motion
capture is at hand: walks in a few styles and an in-place wave, built from a handful of
sinusoids per joint (a textbook gait model, not captured data). They are *synthetic*:
good for smoke tests, demos and tutorials, not for judging motion quality.

Angles follow the conventions of ``mrlib.representation.skeleton`` (Y up, facing +Z, left = +X). The
pelvis translation is derived from the feet: the root moves so that the lower foot does
not slide, which gives stride-consistent speed without tuning.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from mrlib.representation.motion import Motion
from mrlib.representation.rotations import axis_angle_to_matrix, matrix_to_axis_angle
from mrlib.representation.skeleton import JOINT_NAMES

__all__ = ["GaitStyle", "STYLES", "synthetic_walk", "synthetic_wave", "synthetic_dataset"]

J = {name: i for i, name in enumerate(JOINT_NAMES)}


@dataclass(frozen=True)
class GaitStyle:
    """Parameters of the procedural gait (angles in degrees, frequency in steps per second)."""

    step_rate: float = 1.8  # steps per second (two steps per gait cycle)
    hip_swing: float = 22.0
    knee_bend: float = 35.0
    arm_swing: float = 18.0
    elbow_bend: float = 15.0
    arm_down: float = 72.0  # shoulder abduction from the T-pose towards the body
    spine_lean: float = 3.0  # forward lean (positive) of the whole spine chain
    head_pitch: float = 0.0  # positive looks down
    bounce: float = 4.0  # extra knee flexion at mid-stance, gives a vertical bounce
    sway: float = 3.0  # pelvis roll


STYLES: dict[str, GaitStyle] = {
    "walk_normal": GaitStyle(),
    "walk_happy": GaitStyle(step_rate=2.2, hip_swing=26, knee_bend=42, arm_swing=32, elbow_bend=35,
                            arm_down=62, spine_lean=-2, head_pitch=-8, bounce=10, sway=5),
    "walk_sad": GaitStyle(step_rate=1.3, hip_swing=14, knee_bend=25, arm_swing=6, elbow_bend=8,
                          arm_down=80, spine_lean=12, head_pitch=25, bounce=1, sway=2),
}  # fmt: skip


def _rotx(a):
    return np.stack([a, np.zeros_like(a), np.zeros_like(a)], -1)


def _roty(a):
    return np.stack([np.zeros_like(a), a, np.zeros_like(a)], -1)


def _rotz(a):
    return np.stack([np.zeros_like(a), np.zeros_like(a), a], -1)


def _compose(*aas: np.ndarray) -> np.ndarray:
    """Axis-angle of R_1 @ R_2 @ ... for ``(T, 3)`` inputs."""
    R = axis_angle_to_matrix(torch.from_numpy(np.asarray(aas[0], np.float64)))
    for aa in aas[1:]:
        R = R @ axis_angle_to_matrix(torch.from_numpy(np.asarray(aa, np.float64)))
    return matrix_to_axis_angle(R).numpy()


def _anchor_root(poses: np.ndarray, fps: float, body, left_stance: np.ndarray) -> np.ndarray:
    """Translation that keeps the stance foot planted: the root moves by minus the
    horizontal velocity of the stance foot (``left_stance`` (T,) bool says which), and
    the lowest foot vertex touches y=0."""
    rot = axis_angle_to_matrix(torch.from_numpy(poses).float())
    with torch.no_grad():
        out = body(rot, torch.zeros(len(poses), 3), vertex_ids=list(body.foot_vertex_ids))
    feet = out.vertices.numpy()  # (T, 6, 3)
    left, right = feet[:, :3], feet[:, 3:]
    lower_left = np.asarray(left_stance, bool)
    stance = np.where(lower_left[:, None, None], left, right).mean(1)  # (T, 3)
    step = np.zeros_like(stance)
    step[1:] = stance[1:] - stance[:-1]
    # a switch of stance foot is not motion of the foot: reuse the previous step there
    switch = np.r_[False, lower_left[1:] != lower_left[:-1]]
    for t in np.flatnonzero(switch):
        step[t] = step[t - 1]
    trans = np.zeros((len(poses), 3))
    trans[:, [0, 2]] = -np.cumsum(step[:, [0, 2]], 0)
    trans[:, 1] = -feet[:, :, 1].min(1)
    return trans.astype(np.float32)


def synthetic_walk(
    style: str | GaitStyle = "walk_normal",
    seconds: float = 8.0,
    fps: float = 30.0,
    seed: int = 0,
    body=None,
) -> Motion:
    """A procedural walk along +Z in one of ``STYLES`` (or a custom ``GaitStyle``).

    ``seed`` adds small smooth random variation of amplitudes, so two takes of the same
    style differ slightly, as two captures would.
    """
    from mrlib.representation.body import resolve_body

    name = style if isinstance(style, str) else "walk_custom"
    s = STYLES[style] if isinstance(style, str) else style
    body = resolve_body(body)
    rng = np.random.default_rng(seed)
    T = int(round(seconds * fps))
    t = np.arange(T) / fps
    wobble = lambda: 1 + 0.08 * np.sin(2 * np.pi * rng.uniform(0.05, 0.2) * t + rng.uniform(0, 6.3))  # noqa: E731
    phase = np.pi * s.step_rate * t + rng.uniform(0, 2 * np.pi)  # one gait cycle = 2 steps
    d = np.deg2rad
    poses = np.zeros((T, 24, 3))
    for side, sgn in (("left", 1.0), ("right", -1.0)):
        ph = phase + (0 if sgn > 0 else np.pi)
        # hip: forward swing is a negative rotation about +X (the leg points down, -Y)
        poses[:, J[f"{side}_hip"]] = _rotx(-d(s.hip_swing) * np.sin(ph) * wobble())
        # the leg swings forward while cos(ph) > 0: the knee flexes then (peaking a little
        # before mid-swing) and slightly at mid-stance (cos(ph) = -1), which makes the bounce
        swing = np.clip(np.cos(ph + 0.3), 0, None) ** 1.5
        knee = d(s.knee_bend) * swing + d(s.bounce) * np.clip(-np.cos(ph), 0, None) ** 2
        poses[:, J[f"{side}_knee"]] = _rotx(knee * wobble())
        # toes up (a negative rotation about +X) while the foot swings through
        poses[:, J[f"{side}_ankle"]] = _rotx(-d(12) * swing + d(5) * np.sin(ph + 0.8))
        # arms: lowered from the T-pose, swinging opposite to the leg of the same side
        down = _rotz(-sgn * d(s.arm_down) * np.ones(T))
        swing_arm = _rotx(d(s.arm_swing) * np.sin(ph) * wobble())
        poses[:, J[f"{side}_shoulder"]] = _compose(swing_arm, down)
        elbow = d(s.elbow_bend) * (1 + 0.3 * np.sin(ph))
        poses[:, J[f"{side}_elbow"]] = _roty(-sgn * elbow)
    lean = d(s.spine_lean) / 3
    for j in ("spine1", "spine2", "spine3"):
        poses[:, J[j]] = _rotx(np.full(T, lean) + d(1.5) * np.sin(2 * phase))
    poses[:, J["neck"]] = _rotx(np.full(T, d(s.head_pitch) / 2))
    poses[:, J["head"]] = _rotx(np.full(T, d(s.head_pitch) / 2))
    # pelvis: a little roll with the steps and yaw with the stride
    poses[:, 0] = _compose(_roty(d(4) * np.sin(phase)), _rotz(d(s.sway) * np.sin(phase)))
    # the left leg is in stance while it moves backwards, i.e. while cos(phase) < 0
    trans = _anchor_root(poses, fps, body, left_stance=np.cos(phase) < 0)
    return Motion(
        poses,
        trans,
        fps,
        label=name,
        name=f"{name}_seed{seed}",
        meta={"source": "mrlib.datasets.synthetic", "synthetic": True},
    )


def synthetic_wave(seconds: float = 8.0, fps: float = 30.0, seed: int = 0, body=None) -> Motion:
    """Standing in place, waving the right hand, with slow weight shifts."""
    from mrlib.representation.body import resolve_body

    body = resolve_body(body)
    rng = np.random.default_rng(seed)
    T = int(round(seconds * fps))
    t = np.arange(T) / fps
    d = np.deg2rad
    f = rng.uniform(1.6, 2.0)  # waves per second
    poses = np.zeros((T, 24, 3))
    poses[:, J["left_shoulder"]] = _rotz(np.full(T, -d(75)))
    poses[:, J["left_elbow"]] = _roty(np.full(T, -d(10)))
    # right upper arm out to the side and a little forward, forearm up (a negative
    # rotation about +Z for the right arm), waving about the elbow
    raise_ = _rotz(np.full(T, d(10)) + d(5) * np.sin(2 * np.pi * 0.3 * t))
    poses[:, J["right_shoulder"]] = _compose(_roty(np.full(T, -d(20))), raise_)
    poses[:, J["right_elbow"]] = _compose(
        _rotz(np.full(T, -d(95))), _rotx(d(25) * np.sin(2 * np.pi * f * t))
    )
    poses[:, J["right_wrist"]] = _rotz(d(10) * np.sin(2 * np.pi * f * t + 0.5))
    shift = d(3) * np.sin(2 * np.pi * rng.uniform(0.15, 0.3) * t)
    poses[:, 0] = _rotz(shift)
    poses[:, J["left_hip"]] = _rotz(-shift)
    poses[:, J["right_hip"]] = _rotz(-shift)
    poses[:, J["head"]] = _roty(d(10) * np.sin(2 * np.pi * 0.2 * t))
    trans = np.zeros((T, 3), np.float32)
    rot = axis_angle_to_matrix(torch.from_numpy(poses).float())
    with torch.no_grad():
        feet = body(rot, torch.zeros(T, 3), vertex_ids=list(body.foot_vertex_ids)).vertices.numpy()
    trans[:, 1] = -feet[:, :, 1].min(1)
    return Motion(
        poses,
        trans,
        fps,
        label="wave",
        name=f"wave_seed{seed}",
        meta={"source": "mrlib.datasets.synthetic", "synthetic": True},
    )


def synthetic_dataset(
    seconds: float = 8.0, fps: float = 30.0, seed: int = 0, body=None
) -> list[Motion]:
    """The labelled set in ``data_samples/``: three walk styles and a wave."""
    clips = [synthetic_walk(name, seconds, fps, seed, body) for name in STYLES]
    return clips + [synthetic_wave(seconds, fps, seed, body)]
