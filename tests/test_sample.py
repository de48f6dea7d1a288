import numpy as np
import pytest
import torch

from mrlib.datasets.synthetic import synthetic_walk
from mrlib.errors import MotionValueError
from mrlib.model.trained import FINE_NOISE, GUIDANCE
from mrlib.representation.features import features_to_motion
from mrlib.representation.motion import Motion
from mrlib.sampling.cleanup import cleanup_foot_contacts, contact_skating
from mrlib.sampling.generation import (
    generate,
    generate_levels,
    generate_many,
    label_inputs,
    label_weights,
    noise_amplitude,
    reconstruct,
    reconstruct_levels,
    reconstruction_error,
    sample_features,
)


@pytest.fixture(scope="module")
def model(plumbing_model):
    """A plumbing model (two iterations per block): its samples mean nothing."""
    clips = [
        synthetic_walk(s, seconds=sec, fps=10.0)
        for s, sec in [("walk_normal", 3.0), ("walk_sad", 3.6)]
    ]
    return plumbing_model(clips, "walk_normal_sad")


def test_loaded_model_metadata(model):
    assert model.labels == ["walk_normal", "walk_sad"]
    assert model.num_levels == 4 and model.trained_levels == 4 and model.fps == 10.0
    assert model.lengths[:, -1].tolist() == [30, 36]
    assert not any(p.requires_grad for p in model.generator.parameters())


def test_generate_by_label_name_and_index(model):
    m = generate(model, "walk_sad", seed=0)
    assert isinstance(m, Motion) and m.num_frames == 36 and m.label == "walk_sad" and m.fps == 10.0
    assert m.contacts.shape == (36, 6) and np.isfinite(m.poses).all()
    m1 = generate(model, 1, seed=0)
    assert np.array_equal(m.poses, m1.poses)  # index 1 is walk_sad; same seed, same motion
    m2 = generate(model, "walk_sad", seed=1)
    assert not np.allclose(m.poses, m2.poses)  # the noise matters
    with pytest.raises(MotionValueError, match="unknown label"):
        generate(model, "walk_proud")


def test_any_length_and_batches(model):
    ms = generate_many(model, "walk_normal", length=95, num_samples=3, seed=2)
    assert isinstance(ms, list) and len(ms) == 3
    assert all(m.num_frames == 95 for m in ms)  # longer than any training clip
    assert not np.allclose(ms[0].poses, ms[1].poses)
    one = generate(model, "walk_normal", length=95, seed=2)
    assert isinstance(one, Motion)  # one type whatever the arguments
    # batching does not change a sample: the same up to float rounding, which convolution
    # kernels chosen per batch size (and the foot IK after them) make ~1e-5 rad on some CPUs
    assert np.abs(one.poses - ms[0].poses).max() < 1e-3
    assert np.abs(ms[1].poses - ms[0].poses).max() > 0.1  # while the samples differ


def test_condition_per_level_range_and_blend(model):
    W = label_weights(model, conditions=[("walk_normal", (1, 2)), ("walk_sad", (3, 4))])
    assert W.tolist() == [[1, 0], [1, 0], [0, 1], [0, 1]]
    with pytest.raises(MotionValueError, match="exactly once"):
        label_weights(model, conditions=[("walk_normal", (1, 2)), ("walk_sad", (2, 4))])
    with pytest.raises(MotionValueError, match="exactly one"):
        label_weights(model, "walk_sad", conditions=[("walk_normal", (1, 4))])
    W = label_weights(model, blend=("walk_normal", "walk_sad", [0.0, 0.25, 0.5, 1.0]))
    assert torch.allclose(W[:, 1], torch.tensor([0.0, 0.25, 0.5, 1.0])) and torch.allclose(
        W.sum(1), torch.ones(4)
    )
    mixed = generate(model, conditions=[("walk_normal", (1, 2)), ("walk_sad", (3, 4))], seed=0)
    assert mixed.label == "walk_normal+walk_sad" and mixed.num_frames == 30
    pure = generate(model, "walk_normal", seed=0)
    assert not np.allclose(mixed.poses, pure.poses)
    # blend weight 0 at every level is the first label exactly
    b0 = generate(model, blend=("walk_normal", "walk_sad", 0.0), seed=0)
    assert np.allclose(b0.poses, pure.poses, atol=1e-6)


def test_generate_levels(model):
    kw = dict(length=40, seed=0)
    m, levels = generate_levels(model, "walk_normal", fix_contacts=False, **kw)
    assert len(levels) == 4 and levels[-1].num_frames == 40
    assert [lv.num_frames for lv in levels] == sorted(lv.num_frames for lv in levels)
    assert levels[0].fps == pytest.approx(10.0 * levels[0].num_frames / 40)
    assert np.allclose(levels[-1].poses, m.poses)
    # by default the feet are planted; the levels stay the generator's raw output
    clean, raw_levels = generate_levels(model, "walk_normal", **kw)
    assert "contact_cleanup" in clean.meta and "contact_cleanup" not in m.meta
    assert np.array_equal(raw_levels[-1].poses, levels[-1].poses)
    assert np.array_equal(clean.poses, generate(model, "walk_normal", **kw).poses)


def test_fine_noise_scales_only_the_finest_levels_noise(model):
    W = label_weights(model, blend=("walk_normal", "walk_sad", 0.25))
    mix = (W * model.sigma.T).sum(1)  # each level's sigma of the label mix
    assert model.fine_noise == FINE_NOISE
    try:
        model.fine_noise = 1.0  # the paper's sampler
        assert torch.allclose(noise_amplitude(model, W), mix)
        loud = generate(model, "walk_sad", seed=0, fix_contacts=False)
        model.fine_noise = 0.5
        amp = noise_amplitude(model, W)
        assert torch.allclose(amp[:-1], mix[:-1]) and amp[-1] == pytest.approx(0.5 * mix[-1])
        lengths, amp, conds = label_inputs(model, label_weights(model, "walk_sad"), 36)
        amp[-1] = 0.0  # the paper's sigmas with the finest level's zeroed by hand
        x = sample_features(model, conds, lengths, amp, seed=0)
        by_hand = features_to_motion(
            x[0].T, model.fps, betas=model.betas, normalizer=model.normalizer
        )
        model.fine_noise = 0.0
        quiet = generate(model, "walk_sad", seed=0, fix_contacts=False)
        assert np.allclose(quiet.poses, by_hand.poses, atol=1e-6)
        assert np.abs(quiet.poses - loud.poses).max() > 1e-4  # the finest noise reaches the output
        for bad in (-0.5, float("nan")):
            model.fine_noise = bad
            with pytest.raises(MotionValueError, match="fine_noise"):
                generate(model, "walk_sad", seed=0)
    finally:
        model.fine_noise = FINE_NOISE


def test_guidance_pushes_each_levels_condition_away_from_the_label_mean(model):
    W = label_weights(model, conditions=[("walk_sad", (1, 2)), ("walk_normal", (3, 4))])
    assert model.guidance == GUIDANCE == 0.0
    lengths, amp, conds = label_inputs(model, W, 36)
    assert all(torch.equal(c[0, 0], w) for c, w in zip(conds, W, strict=True))
    plain = generate(model, "walk_sad", seed=0, fix_contacts=False)
    try:
        model.guidance = 0.5
        _, amp_g, conds_g = label_inputs(model, W, 36)
        assert torch.equal(amp_g, amp)  # the noise keeps the label's own sigma
        for c, w in zip(conds_g, W, strict=True):
            # two labels: (1, 0) -> (1.25, -0.25), rows still summing to one
            assert torch.allclose(c[0, 0], w + 0.5 * (w - 0.5))
            assert c[0, 0].sum() == pytest.approx(1.0)
        pushed = generate(model, "walk_sad", seed=0, fix_contacts=False)
        assert np.abs(pushed.poses - plain.poses).max() > 1e-4
        model.guidance = 0.0
        again = generate(model, "walk_sad", seed=0, fix_contacts=False)
        assert np.array_equal(again.poses, plain.poses)
        for bad in (-0.1, float("inf")):
            model.guidance = bad
            with pytest.raises(MotionValueError, match="guidance"):
                generate(model, "walk_sad", seed=0)
    finally:
        model.guidance = GUIDANCE


def test_samples_record_the_sampler_settings_and_keep_them_in_npz(model, tmp_path):
    from mrlib.io import load_motion, save_motion

    try:
        model.guidance = 0.25
        ms = generate_many(model, blend=("walk_normal", "walk_sad", 0.5), seed=7, num_samples=2)
    finally:
        model.guidance = GUIDANCE
    rec = ms[1].meta["sampler"]
    assert rec["seed"] == 7 and rec["index"] == 1 and rec["guidance"] == 0.25
    assert rec["fine_noise"] == model.fine_noise and rec["labels"] == model.labels
    assert rec["label_weights"] == [[0.5, 0.5]] * model.num_levels
    back = load_motion(save_motion(ms[1], tmp_path / "s.npz"))
    assert back.meta["sampler"] == rec


def test_reconstruct_uses_the_fixed_noise(model):
    r1, levels = reconstruct_levels(model, 1)
    r2 = reconstruct(model, 1)
    assert r1.num_frames == 36 and r1.label == "walk_sad" and len(levels) == 4
    assert np.array_equal(r1.poses, r2.poses)  # deterministic
    assert reconstruction_error(model, 0) > 0
    with pytest.raises(MotionValueError):
        reconstruct(model, 5)


def _skating_walk():
    """A synthetic walk whose contact frames slide: leg rotations get slow random offsets."""
    m = synthetic_walk("walk_normal", seconds=2.0, fps=30.0)
    rng = np.random.default_rng(0)
    poses = m.poses.copy()
    drift = np.cumsum(rng.normal(size=(m.num_frames, 4, 3)) * 0.02, 0)
    poses[:, [1, 2, 4, 5]] += drift.astype(np.float32)
    return m.replace(poses=poses)


@pytest.mark.parametrize(
    "method, kw",
    [
        ("ik", {"style": "pin"}),
        ("ik", {"style": "pin", "move_root": False}),
        ("optimise", {"iterations": 60}),
    ],
)
def test_foot_contact_cleanup_reduces_skating(body, method, kw):
    """The pinning clean-ups (``style="pin"``, ``method="optimise"``) on a walk whose
    legs drift: contact vertices slow down, only the legs (and the root) change."""
    from mrlib.representation.contacts import foot_contacts

    m = synthetic_walk("walk_normal", seconds=2.0, fps=30.0)
    contacts = foot_contacts(m, body)
    bad = _skating_walk().replace(contacts=contacts)
    before = contact_skating(bad, body)
    fixed = cleanup_foot_contacts(bad, body, method=method, **kw)
    after = contact_skating(fixed, body)
    assert after < (0.3 if method == "ik" else 0.5) * before, (before, after)
    if method == "ik" and kw.get("move_root", True):
        # the root takes the planted feet's common correction: never more than the
        # farthest a contact vertex strays from its run's mean (+ the lift to the floor)
        from mrlib.metrics.plausibility import motion_kinematics
        from mrlib.sampling.leg_ik import contact_runs

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
    legs = (1, 2, 4, 5, 7, 8) if method == "ik" else (1, 2, 4, 5, 7, 8, 10, 11)
    others = [j for j in range(24) if j not in legs]
    assert np.allclose(fixed.poses[:, others], bad.poses[:, others], atol=1e-5)
    with pytest.raises(MotionValueError):
        cleanup_foot_contacts(m.replace(contacts=None), body, method=method)


def test_ik_cleanup_pins_a_lone_contact_vertex_and_keeps_bone_lengths(body):
    """``style="pin"``, one toe in contact over a run: after the clean-up it stands still
    on the ground plane where it was on average, and the leg's bones keep their lengths."""
    from mrlib.representation.contacts import foot_contacts
    from mrlib.sampling.leg_ik import BLEND_S, ROOT_SMOOTH_S, contact_runs

    bad = _skating_walk()
    real = foot_contacts(synthetic_walk("walk_normal", seconds=2.0, fps=30.0), body)
    v = 3  # the right big toe, over one of its stance phases
    # how far a run's correction reaches: the blend, the pinned edge frame, and the
    # root's smoothing (a Gaussian cut at 3 sigma)
    reach = round(BLEND_S * 30) + 1 + int(np.ceil(3 * ROOT_SMOOTH_S * 30))
    runs = contact_runs(real[:, v] > 0.5)
    s, e = next((s, e) for s, e in runs if s > reach + 4 and e - s >= 4)
    contacts = np.zeros((bad.num_frames, 6), np.float32)
    contacts[s : e + 1, v] = 1
    fixed = cleanup_foot_contacts(bad.replace(contacts=contacts), body, style="pin")
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


def _sliding_walk(body, sink: float = 0.015):
    """A synthetic walk whose root wanders (about 0.1-0.2 m/s on the ground, so planted
    feet slide as a model's samples do) and sinks ``sink`` m, with the clean walk's
    contact labels."""
    from mrlib.representation.contacts import foot_contacts

    m = synthetic_walk("walk_normal", seconds=4.0, fps=30.0)
    t = np.arange(m.num_frames) / 30.0
    trans = m.trans.copy()
    trans[:, 0] += 0.05 * np.sin(2 * np.pi * 0.7 * t)
    trans[:, 2] += 0.04 * np.sin(2 * np.pi * 1.1 * t + 1)
    trans[:, 1] -= sink
    return m.replace(trans=trans.astype(np.float32), contacts=foot_contacts(m, body))


def test_smooth_cleanup_plants_feet_without_adding_jerk(body):
    """The default clean-up (``style="smooth"``): sliding feet planted (skating share of
    contact frames from 84 % to under a quarter of it) with the joints' jerk within 5 %
    of the input's, where pinning each run (``style="pin"``, the paired contrast) adds
    over 15 %; given the floor, no foot vertex sinks more than ``FLOOR_SLACK`` below it.
    """
    from mrlib.metrics.plausibility import foot_skating, mean_jerk, motion_kinematics
    from mrlib.sampling.planting import FLOOR_SLACK

    bad = _sliding_walk(body)

    def measure(m):
        joints, feet = motion_kinematics(m, body)
        return foot_skating(feet, m.contacts, m.fps)[1], mean_jerk(joints, m.fps), feet

    skate0, jerk0, feet0 = measure(bad)
    assert skate0 > 0.5 and feet0[..., 1].min() < -0.01  # the input slides and sinks
    smooth = cleanup_foot_contacts(bad, body)
    pinned = cleanup_foot_contacts(bad, body, style="pin")
    skate1, jerk1, _ = measure(smooth)
    skate2, jerk2, _ = measure(pinned)
    assert skate1 < 0.25 * skate0 and skate2 < 0.25 * skate0, (skate0, skate1, skate2)
    assert jerk1 < 1.05 * jerk0, (jerk0, jerk1)
    assert jerk2 > 1.15 * jerk0, (jerk0, jerk2)
    on_floor = cleanup_foot_contacts(bad, body, floor=0.0)
    assert measure(on_floor)[2][..., 1].min() > -FLOOR_SLACK - 1e-3
    others = [j for j in range(24) if j not in (1, 2, 4, 5, 7, 8)]
    legs_only = cleanup_foot_contacts(bad, body, jitter=0)  # no jitter filter: legs alone
    assert np.allclose(legs_only.poses[:, others], bad.poses[:, others], atol=1e-5)
    with pytest.raises(MotionValueError):
        cleanup_foot_contacts(bad, body, no_such_option=1)


def test_jitter_filter_takes_out_frame_noise_and_keeps_the_motion(body):
    """``remove_jitter`` (the smooth clean-up's first step): frame-to-frame noise on a
    walk loses a third of its jerk while the walk itself moves by a few hundredths of a
    radian; sigma 0 is the identity; a paired contrast: the noise is what it removes."""
    from mrlib.metrics.plausibility import mean_jerk, motion_kinematics
    from mrlib.sampling.cleanup import remove_jitter

    walk = synthetic_walk("walk_normal", seconds=3.0, fps=15.0)
    rng = np.random.default_rng(0)
    noisy = walk.replace(poses=walk.poses + rng.normal(0, 0.03, walk.poses.shape).astype("f4"))

    def jerk(m):
        return mean_jerk(motion_kinematics(m, body)[0], m.fps)

    assert jerk(noisy) > 2 * jerk(walk)  # the noise dominates the jerk
    assert jerk(remove_jitter(noisy)) < 0.75 * jerk(noisy)  # 0.65 measured
    kept = remove_jitter(walk)
    assert np.abs(kept.poses - walk.poses).max() < 0.05 and kept.contacts is walk.contacts
    assert remove_jitter(noisy, 0) is noisy
    with pytest.raises(MotionValueError, match="jitter"):
        remove_jitter(walk, -1)


def test_ik_cleanup_of_a_one_minute_clip_is_vectorised(body):
    """1800 frames: the clean-up loops over runs and joints, not frames, so it is quick
    enough to run by default (the speed target itself lives in bench/sample_speed.py)."""
    import time

    m = synthetic_walk("walk_normal", seconds=60.0, fps=30.0)
    from mrlib.representation.contacts import foot_contacts

    m = m.replace(contacts=foot_contacts(m, body))
    t = time.perf_counter()
    cleanup_foot_contacts(m, body)
    assert time.perf_counter() - t < 5.0  # the optimising method takes minutes here
