"""The reference clean-ups of ``bench/experiments/cleanup_studies.py`` (the pinning
clean-up, the default before 2026-12-05, and the per-frame optimisation), which the
benchmarks measure against ``mrlib.sampling.cleanup``: that they do what the benchmarks
say they do, and the paired contrast of the library's clean-up test (pinning adds jerk)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from mrlib.datasets.synthetic import synthetic_walk
from mrlib.errors import MotionValueError
from mrlib.metrics.plausibility import foot_skating, mean_jerk, motion_kinematics
from mrlib.representation.contacts import foot_contacts
from mrlib.sampling.cleanup import cleanup_foot_contacts, contact_skating
from mrlib.sampling.leg_ik import contact_runs


def _load_studies():
    path = Path(__file__).resolve().parents[1] / "bench" / "experiments" / "cleanup_studies.py"
    spec = importlib.util.spec_from_file_location("cleanup_studies", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


S = _load_studies()


def _skating_walk():
    """A synthetic walk whose contact frames slide: leg rotations get slow random offsets."""
    m = synthetic_walk("walk_normal", seconds=2.0, fps=30.0)
    rng = np.random.default_rng(0)
    poses = m.poses.copy()
    drift = np.cumsum(rng.normal(size=(m.num_frames, 4, 3)) * 0.02, 0)
    poses[:, [1, 2, 4, 5]] += drift.astype(np.float32)
    return m.replace(poses=poses)


@pytest.mark.parametrize(
    "clean, kw",
    [
        ("pinned", {}),
        ("pinned", {"move_root": False}),
        ("optimised", {"iterations": 60}),
    ],
)
def test_the_pinning_cleanups_reduce_skating(body, clean, kw):
    """On a walk whose legs drift: contact vertices slow down, only the legs (and the
    root) change."""
    fn = S.cleanup_pinned if clean == "pinned" else S.cleanup_optimised
    m = synthetic_walk("walk_normal", seconds=2.0, fps=30.0)
    contacts = foot_contacts(m, body)
    bad = _skating_walk().replace(contacts=contacts)
    before = contact_skating(bad, body)
    fixed = fn(bad, body, **kw)
    after = contact_skating(fixed, body)
    assert after < (0.3 if clean == "pinned" else 0.5) * before, (before, after)
    if clean == "pinned" and kw.get("move_root", True):
        # the root takes the planted feet's common correction: never more than the
        # farthest a contact vertex strays from its run's mean (+ the lift to the floor)
        feet = motion_kinematics(bad, body)[1]
        stray = max(
            np.linalg.norm(feet[s : e + 1, v] - feet[s : e + 1, v].mean(0), axis=-1).max()
            for v in range(6)
            for s, e in contact_runs(contacts[:, v] > 0.5)
        )
        shift = np.linalg.norm(fixed.trans - bad.trans, axis=-1).max()
        assert 0 < shift < stray + 0.01, (shift, stray)
    else:
        assert np.allclose(fixed.trans, bad.trans)  # the root path is kept
    legs = (1, 2, 4, 5, 7, 8) if clean == "pinned" else (1, 2, 4, 5, 7, 8, 10, 11)
    others = [j for j in range(24) if j not in legs]
    assert np.allclose(fixed.poses[:, others], bad.poses[:, others], atol=1e-5)
    with pytest.raises(MotionValueError):
        fn(m.replace(contacts=None), body)


def test_pinning_holds_a_lone_contact_vertex_and_keeps_bone_lengths(body):
    """One toe in contact over a run: after the pinning clean-up it stands still on the
    ground plane where it was on average, and the leg's bones keep their lengths."""
    bad = _skating_walk()
    real = foot_contacts(synthetic_walk("walk_normal", seconds=2.0, fps=30.0), body)
    v = 3  # the right big toe, over one of its stance phases
    # how far a run's correction reaches: the blend, the pinned edge frame, and the
    # root's smoothing (a Gaussian cut at 3 sigma)
    reach = round(S.BLEND_S * 30) + 1 + int(np.ceil(3 * S.ROOT_SMOOTH_S * 30))
    runs = contact_runs(real[:, v] > 0.5)
    s, e = next((s, e) for s, e in runs if s > reach + 4 and e - s >= 4)
    contacts = np.zeros((bad.num_frames, 6), np.float32)
    contacts[s : e + 1, v] = 1
    fixed = S.cleanup_pinned(bad.replace(contacts=contacts), body)
    ids = list(body.foot_vertex_ids)
    before = body.motion_vertices(bad)[:, ids]
    after = body.motion_vertices(fixed)[:, ids]
    pinned = after[s : e + 1, v][:, [0, 2]]  # on the ground plane
    # it stays put: within 5 mm, the step of a foot sliding at the skating threshold
    # (0.15 m/s) in one frame at 30 fps; most frames within 1 mm
    assert np.abs(pinned - pinned.mean(0)).max() < 5e-3
    assert np.median(np.abs(pinned - pinned.mean(0))) < 1e-3
    assert np.abs(pinned.mean(0) - before[s : e + 1, v][:, [0, 2]].mean(0)).max() < 2e-3
    far = slice(0, s - reach)
    assert np.abs(after[far] - before[far]).max() < 1e-4  # away from the run nothing moves
    jb, ja = body.motion_joints(bad), body.motion_joints(fixed)
    for p, c in ((2, 5), (5, 8)):
        assert np.allclose(
            np.linalg.norm(ja[:, c] - ja[:, p], axis=-1),
            np.linalg.norm(jb[:, c] - jb[:, p], axis=-1),
            atol=1e-4,
        )


def test_pinning_adds_the_jerk_the_smooth_cleanup_does_not(body):
    """The paired contrast of ``tests/test_sample.py``'s clean-up test: on a walk whose
    root wanders (planted feet slide at 0.1-0.2 m/s), both plant the feet (skating under
    a quarter of the input's), but pinning each run adds over 15 % to the joints' jerk
    where the library's clean-up stays within 5 %."""
    m = synthetic_walk("walk_normal", seconds=4.0, fps=30.0)
    t = np.arange(m.num_frames) / 30.0
    trans = m.trans.copy()
    trans[:, 0] += 0.05 * np.sin(2 * np.pi * 0.7 * t)
    trans[:, 2] += 0.04 * np.sin(2 * np.pi * 1.1 * t + 1)
    trans[:, 1] -= 0.015
    bad = m.replace(trans=trans.astype(np.float32), contacts=foot_contacts(m, body))

    def measure(x):
        joints, feet = motion_kinematics(x, body)
        return foot_skating(feet, x.contacts, x.fps)[1], mean_jerk(joints, x.fps)

    skate0, jerk0 = measure(bad)
    skate1, jerk1 = measure(cleanup_foot_contacts(bad, body))
    skate2, jerk2 = measure(S.cleanup_pinned(bad, body))
    assert skate1 < 0.25 * skate0 and skate2 < 0.25 * skate0, (skate0, skate1, skate2)
    assert jerk1 < 1.05 * jerk0, (jerk0, jerk1)
    assert jerk2 > 1.15 * jerk0, (jerk0, jerk2)
