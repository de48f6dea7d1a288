"""Tests for mrlib.metrics.plausibility: exact values on constructed trajectories, invariants, and
the behaviour on real Bandai Namco clips (clean, noisy, frozen)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from mrlib.errors import ClipTooShortError, MotionValueError
from mrlib.io.paths import default_data_dir
from mrlib.metrics import plausibility as pl
from mrlib.representation.contacts import foot_contacts
from mrlib.representation.motion import Motion

DATA_DIR = default_data_dir()
needs_data = pytest.mark.skipif(
    not (DATA_DIR / "data").is_dir(), reason="Bandai-Namco data not found (MRLIB_DATA_DIR)"
)


def still_motion(T: int = 40, fps: float = 30.0) -> Motion:
    rng = np.random.default_rng(0)
    pose = rng.normal(scale=0.2, size=(1, 24, 3))
    return Motion(poses=np.repeat(pose, T, 0), trans=np.tile([0.1, 0.9, -0.3], (T, 1)), fps=fps)


# -- exact values on constructed trajectories ----------------------------------------------
def test_horizontal_speed_ignores_height_and_is_exact_for_linear_paths():
    t = np.arange(20) / 30.0
    p = np.stack([0.3 * t, 5.0 * np.sin(7 * t), -0.4 * t], -1)[:, None, :]  # (T, 1, 3)
    np.testing.assert_allclose(pl.horizontal_speed(p, 30.0), 0.5, rtol=1e-12)


def test_contact_speeds_take_only_contact_frames():
    T, fps = 30, 30.0
    feet = np.zeros((T, 6, 3))
    feet[:, 0, 0] = np.arange(T) * 0.01  # vertex 0 slides at 0.3 m/s
    feet[:, 1, 2] = np.arange(T) * 0.002  # vertex 1 at 0.06 m/s
    c = np.zeros((T, 6))
    c[:10, 0] = 1
    c[:, 1] = 1
    s = pl.contact_foot_speeds(feet, c, fps)
    assert len(s) == 10 + T
    mean, share = pl.foot_skating(feet, c, fps, threshold=0.15)
    np.testing.assert_allclose(mean, (10 * 0.3 + T * 0.06) / (10 + T))
    np.testing.assert_allclose(share, 10 / (10 + T))
    assert pl.foot_skating(feet, np.zeros((T, 6)), fps) == (0.0, 0.0)
    with pytest.raises(MotionValueError, match="contacts must have shape"):
        pl.contact_foot_speeds(feet, c[:, :4], fps)
    with pytest.raises(MotionValueError, match=r"\(T, 6, 3\)"):
        pl.contact_foot_speeds(feet[:, :4], c[:, :4], fps)


def test_jerk_of_a_cubic_is_six_times_its_coefficient():
    fps = 30.0
    t = np.arange(12) / fps
    a = np.array([0.5, -2.0, 1.0])
    joints = (t[:, None] ** 3 * a)[:, None, :] + np.array([0.0, 1.0, 0.0])  # (T, 1, 3)
    jerk = pl.joint_jerk(joints, fps)
    assert jerk.shape == (9, 1)
    np.testing.assert_allclose(jerk, 6 * np.linalg.norm(a), rtol=1e-6)
    # constant velocity and constant acceleration have no jerk
    np.testing.assert_allclose(
        pl.mean_jerk((t[:, None] ** 2)[:, :, None] * [1, 2, 3], fps), 0, atol=1e-8
    )
    with pytest.raises(ClipTooShortError):
        pl.joint_jerk(joints[:3], fps)


def test_ground_and_penetration_depth():
    feet = np.zeros((4, 6, 3))
    feet[..., 1] = 0.05
    feet[1, 2, 1] = 0.03  # 2 cm below a ground at 5 cm
    feet[3, :, 1] = 0.07  # floating: no penetration
    np.testing.assert_allclose(pl.penetration_depth(feet, 0.05), [0, 0.02, 0, 0], atol=1e-15)
    assert pl.estimate_ground(feet, 0.0) == pytest.approx(0.03)
    assert pl.estimate_ground([feet, feet - 1.0], 0.0) == pytest.approx(-0.97)
    assert 0.03 < pl.estimate_ground(feet, 5.0) <= 0.05
    with pytest.raises(MotionValueError, match="percentile"):
        pl.estimate_ground(feet, 120.0)


def test_root_and_angular_speeds_of_uniform_motion():
    T, fps, omega = 25, 30.0, 1.7  # rad/s about a fixed axis
    t = np.arange(T) / fps
    axis = np.array([1.0, 2.0, -2.0]) / 3.0
    poses = np.zeros((T, 24, 3))
    poses[:, 5] = (omega * t)[:, None] * axis
    trans = np.stack([0.6 * t, np.full(T, 0.9), 0.8 * t], -1)
    np.testing.assert_allclose(pl.root_ground_speed(trans, fps), 1.0, rtol=1e-12)
    w = pl.joint_angular_speed(poses, fps)
    assert w.shape == (T - 1, 24)
    np.testing.assert_allclose(w[:, 5], omega, rtol=1e-6)
    np.testing.assert_allclose(np.delete(w, 5, axis=1), 0.0, atol=1e-7)


def test_speed_distances_are_zero_for_the_same_clip_and_grow_with_speed():
    T, fps = 60, 30.0
    t = np.arange(T) / fps
    rng = np.random.default_rng(1)
    poses = np.cumsum(rng.normal(scale=0.05, size=(T, 24, 3)), 0)
    m = Motion(poses=poses, trans=np.stack([t, np.ones(T), 0 * t], -1), fps=fps)
    d = pl.speed_distances(m, [m, m])
    assert set(d) == {"w_root_speed", "w_angspeed_legs", "w_angspeed_arms", "w_angspeed_spine"}
    assert all(v == pytest.approx(0, abs=1e-9) for v in d.values())
    faster = m.replace(trans=m.trans * [1.5, 1, 1])  # 1.5 m/s instead of 1 m/s
    assert pl.speed_distances(faster, m)["w_root_speed"] == pytest.approx(0.5, rel=1e-6)
    with pytest.raises(MotionValueError, match="non-empty list of Motions"):
        pl.speed_distances([], m)


def test_motion_contacts_match_foot_contacts(body):
    T = 40
    t = np.arange(T) / 30.0
    poses = np.zeros((T, 24, 3), np.float32)
    poses[:, 1, 0] = 0.6 * np.sin(2 * np.pi * t) - 0.3  # left leg swings, right one stands
    m = Motion(poses=poses, trans=np.zeros((T, 3)), fps=30.0)
    _, feet = pl.motion_kinematics(m, body)
    c, own = pl.motion_contacts(m, feet)
    assert not own
    np.testing.assert_array_equal(c, foot_contacts(m, body))
    assert c[:, 3:].all() and not c[:, :3].all()
    c2, own2 = pl.motion_contacts(m.replace(contacts=np.zeros((T, 6))), feet)
    assert own2 and not c2.any()


def test_still_motion_is_perfectly_plausible(body):
    m = still_motion()
    joints, feet = pl.motion_kinematics(m, body)
    assert joints.shape == (40, 24, 3) and feet.shape == (40, 6, 3)
    assert pl.mean_jerk(joints, m.fps) == 0.0
    rep = pl.plausibility_report(m, m, body)
    assert rep["jerk"] == 0.0 and rep["jerk_ratio"] == 1.0
    assert rep["skate_speed"] == 0.0 and rep["contact_share"] == 1.0
    assert rep["contacts_from_motion"] == 0.0 and rep["w_root_speed"] == 0.0
    # ground at the lowest vertex: nothing below it
    rep0 = pl.plausibility_report(m, m, body, ground_percentile=0.0)
    assert rep0["penetration_cm"] == 0.0 and rep0["penetration_share"] == 0.0
    # lowering the clip by 3 cm against its own ground: every frame penetrates
    low = m.replace(trans=m.trans - [0, 0.03, 0])
    rep_low = pl.plausibility_report(low, m, body, ground_percentile=0.0)
    assert rep_low["penetration_cm"] == pytest.approx(3.0, abs=1e-4)
    assert rep_low["penetration_share"] == 1.0


def test_report_validates_inputs(body):
    m = still_motion()
    with pytest.raises(MotionValueError, match="Motion"):
        pl.plausibility_report(np.zeros((10, 24, 3)), m, body)
    with pytest.raises(ClipTooShortError, match="at least 4"):
        pl.plausibility_report(m.slice(0, 3), m, body)
    with pytest.raises(MotionValueError, match="skate_threshold"):
        pl.plausibility_report(m, m, body, skate_threshold=0.0)
    with pytest.raises(MotionValueError, match="kinematics has 2 entries"):
        pl.plausibility_report(m, m, body, kinematics=[pl.motion_kinematics(m, body)] * 2)


# -- real data --------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def walk(body):
    from mrlib.io import load_motion

    m = load_motion(DATA_DIR / "data" / "dataset-1_walk_happy_001.bvh", body=body)
    return m.replace(contacts=foot_contacts(m, body))


def with_noise(m: Motion, sigma: float, seed: int = 0) -> Motion:
    """Per-frame Gaussian noise (radians) on every local rotation: high-frequency jitter."""
    rng = np.random.default_rng(seed)
    return m.replace(poses=m.poses + rng.normal(scale=sigma, size=m.poses.shape).astype(np.float32))


@needs_data
def test_real_walk_has_little_foot_skating_under_its_own_contacts(walk, body):
    rep = pl.plausibility_report(walk, walk, body)
    assert rep["contacts_from_motion"] == 1.0
    assert 0.2 < rep["contact_share"] < 0.7
    # mocap noise and heel/toe roll: a few cm/s, a few percent above the threshold
    assert rep["skate_speed"] < 0.1
    assert rep["skate_share"] < 0.12
    assert rep["jerk_ratio"] == 1.0 and 50 < rep["jerk"] < 500  # m/s^3
    assert all(rep[k] == 0.0 for k in rep if k.startswith("w_"))
    # the ground estimate sits a little above y = 0 and nothing penetrates it by 1 cm
    assert 0.0 < rep["ground"] < 0.04
    assert rep["penetration_share"] == 0.0 and rep["penetration_cm"] < 0.05


@needs_data
def test_noise_raises_jitter_and_foot_skating(walk, body):
    clean = pl.plausibility_report(walk, walk, body)
    noisy = pl.plausibility_report(with_noise(walk, 0.01), walk, body)
    assert noisy["jerk_ratio"] > 3.0
    assert noisy["skate_speed"] > 3 * clean["skate_speed"]
    assert noisy["skate_share"] > 0.5
    assert noisy["w_angspeed_legs"] > 0.05 and noisy["w_angspeed_arms"] > 0.05
    # with labels recomputed from the noisy clip, skating still goes up (capped by the
    # 0.25 m/s contact threshold, see the module docstring)
    relabelled = pl.plausibility_report(with_noise(walk, 0.01).replace(contacts=None), walk, body)
    assert relabelled["contacts_from_motion"] == 0.0
    assert relabelled["skate_speed"] > 1.5 * clean["skate_speed"]
    assert relabelled["skate_share"] > 3 * clean["skate_share"]
    # more noise, more jitter
    assert (
        pl.plausibility_report(with_noise(walk, 0.03), walk, body)["jerk_ratio"]
        > noisy["jerk_ratio"]
    )


@needs_data
def test_frozen_real_frame_has_zero_jitter_and_misses_the_speed_distribution(walk, body):
    T = 2 * walk.num_frames
    frozen = walk.replace(
        poses=np.repeat(walk.poses[:1], T, 0), trans=np.repeat(walk.trans[:1], T, 0), contacts=None
    )
    rep = pl.plausibility_report(frozen, walk, body)
    assert rep["jerk"] == 0.0 and rep["jerk_ratio"] == 0.0
    assert rep["skate_speed"] == 0.0 and rep["contact_share"] == 1.0
    # W1 to a point mass at 0 is the mean of the reference's speeds
    ref_speed = pl.root_ground_speed(walk.trans, walk.fps).mean()
    assert rep["w_root_speed"] == pytest.approx(ref_speed, rel=1e-6)
    assert rep["w_root_speed"] > 1.0  # a walk at more than 1 m/s


@needs_data
def test_sinking_a_real_clip_is_reported_as_penetration(walk, body):
    sunk = walk.replace(trans=walk.trans - np.array([0, 0.05, 0], np.float32))
    rep = pl.plausibility_report(sunk, walk, body)
    assert rep["penetration_share"] > 0.9
    assert 3.0 < rep["penetration_cm"] < 5.5


def test_motion_kinematics_uses_the_motion_betas(body):
    m = still_motion(10)
    tall = m.replace(betas=np.r_[2.0, np.zeros(9)].astype(np.float32))
    j0, _ = pl.motion_kinematics(m, body)
    j1, _ = pl.motion_kinematics(tall, body)
    assert not np.allclose(j0, j1)
    # matches the body's own conveniences
    np.testing.assert_allclose(j1, body.motion_joints(tall), atol=1e-6)
    with pytest.raises(MotionValueError, match="Motion"):
        pl.motion_kinematics(torch.zeros(3), body)


def test_angular_speed_is_invariant_to_the_axis_angle_branch():
    # the same rotations written with angle > pi (another axis-angle of the same matrix)
    T, fps = 12, 30.0
    rng = np.random.default_rng(3)
    poses = rng.normal(scale=0.5, size=(T, 24, 3))
    ang = np.linalg.norm(poses, axis=-1, keepdims=True)
    flipped = poses - poses / ang * 2 * np.pi  # rotation by (angle - 2 pi): same matrix
    np.testing.assert_allclose(
        pl.joint_angular_speed(flipped, fps), pl.joint_angular_speed(poses, fps), atol=1e-6
    )
