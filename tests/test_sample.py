import dataclasses

import numpy as np
import pytest
import torch

from mrlib.datasets.synthetic import synthetic_walk
from mrlib.errors import MotionValueError
from mrlib.representation.features import features_to_motion
from mrlib.representation.motion import Motion
from mrlib.sampling.cleanup import cleanup_foot_contacts
from mrlib.sampling.conditions import Condition
from mrlib.sampling.generation import (
    generate,
    label_inputs,
    noise_amplitude,
    reconstruct,
    reconstruction_error,
    sample_features,
    training_floor,
)
from mrlib.sampling.sampler import FINE_NOISE, GUIDANCE, Sampler


@pytest.fixture(scope="module")
def model(normal_sad_model):
    """A plumbing model (two iterations per block): its samples mean nothing."""
    return normal_sad_model


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
    # no condition: the model's first label
    first = generate(model, seed=0)
    assert first.label == "walk_normal"
    assert np.array_equal(first.poses, generate(model, "walk_normal", seed=0).poses)


def test_one_return_type_per_call_shape(model):
    kw = dict(length=40, seed=3, sampler=Sampler(fix_contacts=False))
    one = generate(model, "walk_sad", **kw)
    assert isinstance(one, Motion)
    listed = generate(model, "walk_sad", num=1, **kw)  # num=1 is still a list
    assert isinstance(listed, list) and len(listed) == 1
    assert np.array_equal(listed[0].poses, one.poses)
    m, levels = generate(model, "walk_sad", levels=True, **kw)
    assert isinstance(m, Motion) and len(levels) == 4
    assert all(isinstance(lv, Motion) for lv in levels)
    pairs = generate(model, "walk_sad", num=2, levels=True, **kw)
    assert isinstance(pairs, list) and len(pairs) == 2
    assert all(isinstance(p, tuple) and len(p) == 2 and len(p[1]) == 4 for p in pairs)
    # a batch of two: the same samples up to float rounding (test_any_length_and_batches)
    assert np.abs(pairs[0][0].poses - one.poses).max() < 1e-3
    assert np.abs(pairs[0][1][0].poses - levels[0].poses).max() < 1e-3


def test_any_length_and_batches(model):
    ms = generate(model, "walk_normal", length=95, num=3, seed=2)
    assert isinstance(ms, list) and len(ms) == 3
    assert all(m.num_frames == 95 for m in ms)  # longer than any training clip
    assert not np.allclose(ms[0].poses, ms[1].poses)
    one = generate(model, "walk_normal", length=95, seed=2)
    assert isinstance(one, Motion)
    # batching does not change a sample: the same up to float rounding, which convolution
    # kernels chosen per batch size (and the foot IK after them) make ~1e-5 rad on some CPUs
    assert np.abs(one.poses - ms[0].poses).max() < 1e-3
    assert np.abs(ms[1].poses - ms[0].poses).max() > 0.1  # while the samples differ


def test_condition_per_level_range_crossover_and_blend(model):
    W = Condition.levels([("walk_normal", (1, 2)), ("walk_sad", (3, 4))]).weights(model)
    assert W.tolist() == [[1, 0], [1, 0], [0, 1], [0, 1]]
    assert torch.equal(Condition.crossover("walk_normal", "walk_sad", 2).weights(model), W)
    with pytest.raises(MotionValueError, match="exactly once"):
        Condition.levels([("walk_normal", (1, 2)), ("walk_sad", (2, 4))]).weights(model)
    with pytest.raises(MotionValueError, match="crossover level 4"):
        Condition.crossover("walk_normal", "walk_sad", 4).weights(model)
    W = Condition.blend("walk_normal", "walk_sad", [0.0, 0.25, 0.5, 1.0]).weights(model)
    assert torch.allclose(W[:, 1], torch.tensor([0.0, 0.25, 0.5, 1.0])) and torch.allclose(
        W.sum(1), torch.ones(4)
    )
    with pytest.raises(MotionValueError, match="blend weights"):
        Condition.blend("walk_normal", "walk_sad", 1.5)
    mixed = generate(model, Condition.crossover("walk_normal", "walk_sad", 2), seed=0)
    assert mixed.label == "walk_normal+walk_sad" and mixed.num_frames == 30
    pure = generate(model, "walk_normal", seed=0)
    assert not np.allclose(mixed.poses, pure.poses)
    # blend weight 0 at every level is the first label exactly
    b0 = generate(model, Condition.blend("walk_normal", "walk_sad", 0.0), seed=0)
    assert np.allclose(b0.poses, pure.poses, atol=1e-6) and b0.label == "walk_normal"
    # a blend carries both labels, the heavier first
    for w, want in ((0.5, "walk_normal+walk_sad"), (0.75, "walk_sad+walk_normal")):
        blend = Condition.blend("walk_normal", "walk_sad", w)
        assert blend.name(model) == want
    assert generate(model, blend, length=30, seed=0).label == "walk_sad+walk_normal"


def test_generate_levels(model):
    kw = dict(length=40, seed=0)
    m, levels = generate(
        model, "walk_normal", levels=True, sampler=Sampler(fix_contacts=False), **kw
    )
    assert len(levels) == 4 and levels[-1].num_frames == 40
    assert [lv.num_frames for lv in levels] == sorted(lv.num_frames for lv in levels)
    assert levels[0].fps == pytest.approx(10.0 * levels[0].num_frames / 40)
    assert np.allclose(levels[-1].poses, m.poses)
    # by default the feet are planted; the levels stay the generator's raw output
    clean, raw_levels = generate(model, "walk_normal", levels=True, **kw)
    assert "contact_cleanup" in clean.meta and "contact_cleanup" not in m.meta
    assert np.array_equal(raw_levels[-1].poses, levels[-1].poses)
    assert np.array_equal(clean.poses, generate(model, "walk_normal", **kw).poses)


def test_sampler_settings_are_checked_and_the_model_has_none(model):
    assert Sampler() == Sampler(FINE_NOISE, GUIDANCE, True)
    for bad in (-0.5, float("nan"), 11.0, "1"):
        with pytest.raises(MotionValueError, match="fine_noise"):
            Sampler(fine_noise=bad)
        with pytest.raises(MotionValueError, match="guidance"):
            Sampler(guidance=bad)
    with pytest.raises(MotionValueError, match="fix_contacts"):
        Sampler(fix_contacts="optimise")
    with pytest.raises(dataclasses.FrozenInstanceError):
        Sampler().fine_noise = 0.0
    assert not hasattr(model, "fine_noise") and not hasattr(model, "guidance")
    with pytest.raises(MotionValueError, match="mrlib.Sampler"):
        generate(model, "walk_sad", sampler={"fine_noise": 0.5})


def test_fine_noise_scales_only_the_finest_levels_noise(model):
    W = Condition.blend("walk_normal", "walk_sad", 0.25).weights(model)
    mix = (W * model.sigma.T).sum(1)  # each level's sigma of the label mix
    raw = Sampler(fix_contacts=False, candidates=1)  # the paper's sampler: fine noise 1
    assert torch.allclose(noise_amplitude(model, W, raw), mix)
    loud = generate(model, "walk_sad", seed=0, sampler=raw)
    amp = noise_amplitude(model, W, Sampler(fine_noise=0.5))
    assert torch.allclose(amp[:-1], mix[:-1]) and amp[-1] == pytest.approx(0.5 * mix[-1])
    sad = Condition.label("walk_sad").weights(model)
    lengths, amp, conds = label_inputs(model, sad, 36, raw)
    amp[-1] = 0.0  # the paper's sigmas with the finest level's zeroed by hand
    x = sample_features(model, conds, lengths, amp, seed=0)
    by_hand = features_to_motion(x[0].T, model.fps, betas=model.betas, normalizer=model.normalizer)
    one = Sampler(fine_noise=0.0, fix_contacts=False, candidates=1)  # one draw, as by hand
    quiet = generate(model, "walk_sad", seed=0, sampler=one)
    assert np.allclose(quiet.poses, by_hand.poses, atol=1e-6)
    assert np.abs(quiet.poses - loud.poses).max() > 1e-4  # the finest noise reaches the output


def test_guidance_pushes_each_levels_condition_away_from_the_label_mean(model):
    W = Condition.crossover("walk_sad", "walk_normal", 2).weights(model)
    raw = Sampler(fix_contacts=False)
    assert raw.guidance == GUIDANCE == 0.0
    lengths, amp, conds = label_inputs(model, W, 36, raw)
    assert all(torch.equal(c[0, 0], w) for c, w in zip(conds, W, strict=True))
    plain = generate(model, "walk_sad", seed=0, sampler=raw)
    guided = Sampler(guidance=0.5, fix_contacts=False)
    _, amp_g, conds_g = label_inputs(model, W, 36, guided)
    assert torch.equal(amp_g, amp)  # the noise keeps the label's own sigma
    for c, w in zip(conds_g, W, strict=True):
        # two labels: (1, 0) -> (1.25, -0.25), rows still summing to one
        assert torch.allclose(c[0, 0], w + 0.5 * (w - 0.5))
        assert c[0, 0].sum() == pytest.approx(1.0)
    pushed = generate(model, "walk_sad", seed=0, sampler=guided)
    assert np.abs(pushed.poses - plain.poses).max() > 1e-4
    again = generate(model, "walk_sad", seed=0, sampler=raw)  # nothing stays behind
    assert np.array_equal(again.poses, plain.poses)


def test_samples_record_the_sampler_settings_and_keep_them_in_npz(model, tmp_path):
    from mrlib.io import load_motion, save_motion

    ms = generate(model, Condition.blend("walk_normal", "walk_sad", 0.5), seed=7, num=2,
                  sampler=Sampler(guidance=0.25))  # fmt: skip
    rec = ms[1].meta["sampler"]
    assert rec["seed"] == 7 and rec["index"] == 1 and rec["guidance"] == 0.25
    assert rec["fine_noise"] == FINE_NOISE and rec["labels"] == model.labels
    assert rec["label_weights"] == [[0.5, 0.5]] * model.num_levels
    back = load_motion(save_motion(ms[1], tmp_path / "s.npz"))
    assert back.meta["sampler"] == rec


def test_training_floor_is_cached_beside_the_model_not_on_it(model):
    import gc
    import weakref

    from mrlib.sampling import generation

    floor = training_floor(model, [1])
    assert training_floor(model, [1]) == floor and model in generation._FLOORS
    assert not any("floor" in k for k in vars(model))
    clone = dataclasses.replace(model)  # a model of its own: its own cache entry
    training_floor(clone, [1])
    ref = weakref.ref(clone)
    del clone
    gc.collect()
    assert ref() is None  # the cache does not keep a model alive


def test_reconstruct_uses_the_fixed_noise(model):
    r1, levels = reconstruct(model, 1, levels=True)
    r2 = reconstruct(model, 1)
    assert r1.num_frames == 36 and r1.label == "walk_sad" and len(levels) == 4
    assert np.array_equal(r1.poses, r2.poses)  # deterministic
    assert np.array_equal(levels[-1].poses, r1.poses)
    assert reconstruction_error(model, 0) > 0
    with pytest.raises(MotionValueError):
        reconstruct(model, 5)


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
    """The clean-up: sliding feet planted (skating share of contact frames from 84 % to
    under a quarter of it) with the joints' jerk within 5 % of the input's (pinning each
    run, the paired contrast, adds over 15 %: ``tests/test_cleanup_studies.py``); given
    the floor, no foot vertex sinks more than ``FLOOR_SLACK`` below it.
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
    skate1, jerk1, _ = measure(smooth)
    assert skate1 < 0.25 * skate0, (skate0, skate1)
    assert jerk1 < 1.05 * jerk0, (jerk0, jerk1)
    on_floor = cleanup_foot_contacts(bad, body, floor=0.0)
    assert measure(on_floor)[2][..., 1].min() > -FLOOR_SLACK - 1e-3
    others = [j for j in range(24) if j not in (1, 2, 4, 5, 7, 8)]
    legs_only = cleanup_foot_contacts(bad, body, jitter=0)  # no jitter filter: legs alone
    assert np.allclose(legs_only.poses[:, others], bad.poses[:, others], atol=1e-5)
    with pytest.raises(MotionValueError):
        cleanup_foot_contacts(bad.replace(contacts=None), body)
    with pytest.raises(TypeError):
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
    assert time.perf_counter() - t < 5.0  # a per-frame optimisation takes minutes here


def test_samples_at_another_frame_rate(model):
    """Sampler(fps=...): the draw at the model's rate, raised by splines, then cleaned."""
    for bad in (0, -5.0, float("inf"), "30", True, 5000.0):
        with pytest.raises(MotionValueError, match="fps"):
            Sampler(fps=bad)
    length = 30
    low = generate(model, "walk_sad", length=length, seed=3, sampler=Sampler(fix_contacts=False))
    high = generate(
        model,
        "walk_sad",
        length=length,
        seed=3,
        sampler=Sampler(fps=3 * model.fps, fix_contacts=False),
    )
    assert high.fps == 3 * model.fps and high.num_frames == 3 * length  # as long as the draw
    assert high.meta["sampler"]["fps"] == 3 * model.fps and low.meta["sampler"]["fps"] == model.fps
    # the spline passes through the model's frames: every third frame is the draw itself
    np.testing.assert_allclose(high.trans[::3], low.trans, atol=1e-5)
    # the two frames after the draw's last continue its splines: no frame held
    assert np.linalg.norm(np.diff(high.trans[-4:], axis=0), axis=1).min() > 0
    cleaned = generate(model, "walk_sad", length=length, seed=3, sampler=Sampler(fps=3 * model.fps))
    assert cleaned.fps == 3 * model.fps and cleaned.contacts.shape == (high.num_frames, 6)
    # the clean-up's jitter filter spans the time of JITTER_SIGMA model frames
    from mrlib.sampling.cleanup import JITTER_SIGMA

    own = generate(model, "walk_sad", length=length, seed=3)
    assert own.meta["contact_cleanup"]["jitter_sigma"] == JITTER_SIGMA
    assert cleaned.meta["contact_cleanup"]["jitter_sigma"] == pytest.approx(3 * JITTER_SIGMA)


def test_smooth_resampling_raises_a_rate_without_bends():
    """Slerp and linear translation bend the motion at every input frame, which shows as
    jerk at the higher rate; the cubic spline goes through the same frames without them."""
    t = np.arange(16) / 10.0  # a 10-fps clip: a smooth swing and a curved root path
    poses = np.zeros((16, 24, 3), np.float32)
    poses[:, 1, 0] = 0.6 * np.sin(2 * np.pi * 0.7 * t)
    trans = np.stack([np.sin(t), 0.9 + 0.02 * np.cos(3 * t), t], -1).astype(np.float32)
    clip = Motion(poses=poses, trans=trans, betas=np.zeros(10, np.float32), fps=10.0)

    def jerk(m):
        return np.abs(np.diff(m.poses[:, 1, 0], 3)).mean() * m.fps**3

    lin, spline = clip.resample(40.0), clip.resample(40.0, smooth=True)
    assert lin.num_frames == spline.num_frames == 61
    np.testing.assert_allclose(spline.poses[::4], clip.poses, atol=1e-5)  # through the frames
    np.testing.assert_allclose(spline.trans[::4], clip.trans, atol=1e-5)
    exact = (
        0.6 * (2 * np.pi * 0.7) ** 3 * np.abs(np.cos(2 * np.pi * 0.7 * np.arange(61) / 40.0)).mean()
    )
    assert abs(jerk(spline) - exact) < 0.5 * exact < jerk(lin) - exact  # slerp: far more jerk
    assert clip.resample(10.0, smooth=True).num_frames == 16
