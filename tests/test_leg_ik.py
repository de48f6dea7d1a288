"""Two-bone leg IK of the foot-contact clean-up (``mrlib.sampling.leg_ik``)."""

from __future__ import annotations

import numpy as np
import pytest

from mrlib.sampling import leg_ik


def _knee_angles(T: int = 60) -> np.ndarray:
    """Interior knee angle per frame of a bent leg (hip at the origin, 0.82 m straight,
    the ankle 0.80 m from the hip) whose ankle target moves away from the hip, from its
    own place to 3.5 cm past the straight leg's reach: what the clean-up asks of a leg
    when a planted foot falls behind a root that keeps its path."""
    a = np.zeros((T, 3))
    b = np.tile([0.0, -0.4, 0.1], (T, 1))
    c = np.tile([0.0, -0.8, 0.0], (T, 1))
    t = np.stack([np.zeros(T), -np.linspace(0.80, 0.86, T), np.zeros(T)], 1)
    eye = np.tile(np.eye(3), (T, 1, 1))
    Ga, Gb = leg_ik.two_bone_ik(a, b, c, t, eye, eye, bend_axis=np.tile([1.0, 0, 0], (T, 1)))
    b1 = a + np.einsum("tij,tj->ti", Ga, b - a)
    c1 = b1 + np.einsum("tij,tj->ti", Gb, c - b)
    u, v = a - b1, c1 - b1
    cos = (u * v).sum(1) / np.linalg.norm(u, axis=1) / np.linalg.norm(v, axis=1)
    return np.arccos(np.clip(cos, -1, 1))


def test_the_knee_straightens_ever_slower_as_the_target_leaves_reach(monkeypatch):
    # the angle a knee needs grows ever faster as the ankle nears full reach; reached
    # softly, each frame's step is no larger than the one before
    steps = np.diff(_knee_angles())
    assert (steps > 0).all() and np.all(np.diff(steps) <= 1e-9)
    # reached exactly up to the clamp (SOFT_REACH 0), the knee snaps straight: the
    # largest step six times the first, then none
    monkeypatch.setattr(leg_ik, "SOFT_REACH", 0.0)
    hard = np.diff(_knee_angles())
    assert hard.max() > 4 * hard[0] and hard[-10:].max() < 1e-9


def test_soft_reach_is_the_target_within_reach_and_within_the_leg_beyond():
    d0, length = np.full(5, 0.70), np.full(5, 0.82)
    d = np.array([0.5, 0.70, 0.779, 0.82, 5.0])  # base: (1 - 0.05) * 0.82 = 0.779
    out = leg_ik.soft_reach(d, d0, length)
    assert out[:3] == pytest.approx(d[:3]) and (out[3:] <= length[3:]).all()
    assert out[4] == pytest.approx(0.82, abs=1e-6) and out[3] > 0.80
    # a leg already straighter than the soft zone's start is left its own reach
    assert leg_ik.soft_reach(np.array([0.80]), np.array([0.81]), np.array([0.82]))[0] == 0.80
