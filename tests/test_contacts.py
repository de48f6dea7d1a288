"""Tests for mrlib.representation.contacts: finite differences, foot-vertex velocity, contact labels."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import numpy as np
import pytest
import torch

from mrlib.errors import ClipTooShortError, MotionValueError
from mrlib.io.paths import default_data_dir
from mrlib.representation.body import load_body_model
from mrlib.representation.contacts import (
    DEFAULT_CONTACT_THRESHOLD,
    finite_difference_velocity,
    foot_contacts,
    foot_vertex_positions,
    foot_vertex_velocity,
)
from mrlib.representation.motion import Motion
from mrlib.representation.rotations import axis_angle_to_matrix
from mrlib.viz.plots import plot_contacts

LEFT_HIP, LEFT_KNEE = 1, 4


@pytest.fixture(scope="module")
def body():
    return load_body_model()


def swinging_left_leg(T: int = 60, fps: float = 30.0, amplitude: float = 0.6) -> Motion:
    """The right leg stands still; the left hip swings back and forth (0.5 Hz) with the
    knee bent, so the left foot is in the air."""
    t = np.arange(T) / fps
    poses = np.zeros((T, 24, 3), np.float32)
    poses[:, LEFT_HIP, 0] = amplitude * np.sin(2 * np.pi * 0.5 * t) - 0.3
    poses[:, LEFT_KNEE, 0] = 0.6
    return Motion(poses=poses, trans=np.zeros((T, 3)), fps=fps)


def test_finite_difference_is_exact_for_linear_motion():
    t = torch.arange(10, dtype=torch.float64)
    x = torch.stack([2.0 * t, -t, 0.5 * t], -1)[:, None, :].expand(10, 4, 3)  # (T, 4, 3)
    v = finite_difference_velocity(x, fps=30.0)
    torch.testing.assert_close(
        v, torch.tensor([60.0, -30.0, 15.0], dtype=torch.float64).expand(10, 4, 3)
    )


def test_finite_difference_central_inside_one_sided_at_ends():
    x = torch.tensor([0.0, 1.0, 4.0, 9.0, 16.0])[:, None, None]  # t^2 at fps 1
    v = finite_difference_velocity(x, fps=1.0)[:, 0, 0]
    torch.testing.assert_close(v, torch.tensor([1.0, 2.0, 4.0, 6.0, 7.0]))
    with pytest.raises(ClipTooShortError):
        finite_difference_velocity(x[:1], fps=1.0)


def test_velocity_of_a_translating_body(body):
    B, T = 2, 8
    R = torch.eye(3).expand(B, T, 24, 3, 3)
    speed = torch.tensor([0.0, 1.5])  # m/s along +Z for the second sequence
    trans = (torch.arange(T) / 30.0)[None, :, None] * torch.stack(
        [torch.zeros(2), torch.zeros(2), speed], -1
    )[:, None, :]
    v = foot_vertex_velocity(body, R, trans, fps=30.0)
    assert v.shape == (B, T, 6, 3)
    torch.testing.assert_close(v[0], torch.zeros(T, 6, 3), atol=1e-5, rtol=0)
    torch.testing.assert_close(
        v[1], torch.tensor([0.0, 0.0, 1.5]).expand(T, 6, 3), atol=1e-4, rtol=0
    )


def test_velocity_is_differentiable_with_per_sequence_betas(body):
    g = torch.Generator().manual_seed(0)
    R = axis_angle_to_matrix(torch.randn(2, 5, 24, 3, generator=g) * 0.3).requires_grad_(True)
    trans = torch.randn(2, 5, 3, generator=g, requires_grad=True)
    betas = torch.zeros(2, 10, requires_grad=True)
    v = foot_vertex_velocity(body, R, trans, 30.0, betas=betas)
    assert v.shape == (2, 5, 6, 3)
    v.square().sum().backward()
    assert R.grad.abs().sum() > 0 and trans.grad.abs().sum() > 0 and betas.grad.abs().sum() > 0
    # positions agree with the body's forward on the contact vertices
    pos = foot_vertex_positions(body, R, trans, betas)
    ref = body(R, trans, vertex_ids=body.foot_vertex_ids).vertices
    torch.testing.assert_close(pos, ref)


def test_contacts_of_still_and_sliding_bodies(body):
    T = 10
    still = Motion(poses=np.zeros((T, 24, 3)), trans=np.zeros((T, 3)), fps=30)
    c = foot_contacts(still, body)
    assert c.shape == (T, 6) and c.dtype == np.float32
    assert (c == 1).all()
    trans = np.zeros((T, 3))
    trans[:, 2] = np.arange(T) / 30.0  # 1 m/s
    assert (foot_contacts(still.replace(trans=trans), body) == 0).all()
    # just under / just over the threshold
    slow = trans * (0.9 * DEFAULT_CONTACT_THRESHOLD)
    fast = trans * (1.1 * DEFAULT_CONTACT_THRESHOLD)
    assert (foot_contacts(still.replace(trans=slow), body) == 1).all()
    assert (foot_contacts(still.replace(trans=fast), body) == 0).all()


def test_contacts_follow_the_swinging_foot(body):
    m = swinging_left_leg()
    c = foot_contacts(m, body)
    assert (c[:, 3:] == 1).all()  # the standing right foot
    assert c[:, :3].mean() < 0.4  # the swinging left foot is mostly moving
    # it is "in contact" only near the turning points of the swing (speed ~ 0)
    t = np.arange(len(c)) / m.fps
    hip_speed = np.abs(np.cos(2 * np.pi * 0.5 * t))
    assert hip_speed[c[:, 2] == 1].max() < 0.5


def test_threshold_and_height_gate(body):
    m = swinging_left_leg()
    n = [foot_contacts(m, body, threshold=th).sum() for th in (0.05, 0.25, 1.0, 5.0)]
    assert n == sorted(n) and n[0] < n[-1]
    assert (foot_contacts(m, body, threshold=100.0) == 1).all()
    gated = foot_contacts(m, body, threshold=100.0, max_height=0.05)
    assert (gated[:, 3:] == 1).all() and gated[:, :3].mean() < 0.5  # the lifted foot
    with pytest.raises(MotionValueError, match="threshold"):
        foot_contacts(m, body, threshold=0.0)
    with pytest.raises(ClipTooShortError):
        foot_contacts(m.slice(0, 1), body)


def test_shape_errors(body):
    R = torch.eye(3).expand(4, 24, 3, 3)
    with pytest.raises(MotionValueError, match="trans"):
        foot_vertex_velocity(body, R, torch.zeros(5, 3), 30.0)
    with pytest.raises(MotionValueError, match="rotmat"):
        foot_vertex_velocity(body, torch.eye(3).expand(4, 23, 3, 3), torch.zeros(4, 3), 30.0)
    with pytest.raises(MotionValueError, match="fps"):
        foot_vertex_velocity(body, R, torch.zeros(4, 3), 0.0)


def test_plot_contacts():
    c = (np.random.default_rng(0).random((90, 6)) > 0.5).astype(np.float32)
    ax = plot_contacts(c, fps=30, title="walk")
    assert len(ax.get_yticks()) == 6
    assert ax.get_xlim() == (0.0, 3.0)
    with pytest.raises(MotionValueError):
        plot_contacts(c[:, :5], fps=30)


# -- real data: Bandai-Namco walking clips -------------------------------------------------
DATA_DIR = default_data_dir()


def rising_edges(c: np.ndarray) -> np.ndarray:
    return np.flatnonzero((c[1:] > 0.5) & (c[:-1] < 0.5)) + 1


@pytest.mark.skipif(not DATA_DIR.is_dir(), reason="Bandai-Namco data not found (MRLIB_DATA_DIR)")
@pytest.mark.parametrize("style", ["normal", "tired"])
def test_contacts_alternate_on_a_real_walk(body, style):
    from mrlib.io import load_motion

    motion = load_motion(DATA_DIR / "data" / f"dataset-1_walk_{style}_001.bvh", body=body)
    c = foot_contacts(motion, body)
    left, right = c[:, :3].max(1), c[:, 3:].max(1)
    assert 0.35 < left.mean() < 0.75 and 0.35 < right.mean() < 0.75
    assert np.maximum(left, right).mean() > 0.85  # walking: a foot is almost always down
    # heel strikes: left and right interleave
    strikes = sorted(
        [(t, "L") for t in rising_edges(c[:, 2])] + [(t, "R") for t in rising_edges(c[:, 5])]
    )
    assert sum(s == "L" for _, s in strikes) >= 3 and sum(s == "R" for _, s in strikes) >= 3
    alternating = np.mean([a[1] != b[1] for a, b in zip(strikes[:-1], strikes[1:], strict=True)])
    assert alternating >= 0.8
