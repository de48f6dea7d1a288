"""Constraints (mrlib.sampling.constraints): paths, keyframes, continuation, loops, body parts.

Each constraint has a test that fails when the constraint is ignored. The models here
are plumbing models (two iterations per block): the tests check what the constraints
guarantee by construction; what they achieve with a trained model is measured by
``bench/constraints.py`` (docs/results.md)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import torch

from mrlib.datasets.synthetic import synthetic_walk
from mrlib.errors import ClipTooShortError, MotionFileError, MotionValueError
from mrlib.sampling import constraints as C
from mrlib.sampling.cleanup import contact_skating
from mrlib.sampling.conditions import Condition
from mrlib.sampling.generation import (
    generate,
    label_inputs,
    sample_features,
)
from mrlib.sampling.sampler import Sampler

RAW = Sampler(fix_contacts=False, candidates=1)  # the generator's raw output, one draw


@pytest.fixture(scope="module")
def clips(sad_wave_clips):
    return sad_wave_clips


@pytest.fixture(scope="module")
def model(sad_wave_model):
    return sad_wave_model


@pytest.fixture(scope="module")
def walk(body):
    """A straight synthetic walk along +Z, 20 s, with its contact labels."""
    from mrlib.representation.contacts import foot_contacts

    w = synthetic_walk("walk_happy", seconds=20.0, fps=30.0, body=body)
    return w.replace(contacts=foot_contacts(w, body))


def _turn_steps(aa: np.ndarray) -> np.ndarray:
    """Degrees turned from frame to frame by each joint of ``aa (T, J, 3)``."""
    from mrlib.representation.rotations import axis_angle_to_matrix, geodesic_distance

    R = axis_angle_to_matrix(torch.from_numpy(np.asarray(aa, np.float64)))
    return np.degrees(geodesic_distance(R[1:], R[:-1]).numpy())


def _steps(motion, body) -> np.ndarray:
    J = body.motion_joints(motion)
    return np.linalg.norm(np.diff(J, axis=0), axis=-1).mean(-1)  # (T - 1,)


# -- paths --------------------------------------------------------------------------------
def test_path_presets_have_the_right_shape():
    c = C.GroundPath.circle(2.0)
    assert c.length == pytest.approx(2 * np.pi * 2.0, rel=1e-3) and c.closed
    xz, h = c.at(np.array([0.0, c.length / 4, c.length / 2, 1.25 * c.length]))
    assert np.allclose(xz, [[0, 0], [2, 2], [4, 0], [2, 2]], atol=1e-3)
    assert np.allclose(np.degrees(h), [0, 90, 180, 450], atol=1.0)  # keeps turning lap after lap
    e = C.GroundPath.figure_eight(2.0)
    xz, h = e.at(np.array([e.length / 4, 3 * e.length / 4, e.length]))
    assert np.allclose(xz, [[4, 0], [-4, 0], [0, 0]], atol=1e-3)  # left lap, right lap, home
    assert abs(np.degrees(h[-1])) < 2.0  # no net turn after an eight
    line = C.parse_path("line:5")
    assert np.allclose(line.at(np.array([7.0]))[0], [[0, 7]])  # straight on past the end
    assert C.GroundPath.circle(1.0).distance(np.array([[1.0, 1.0], [1.0, 0.0]])) == pytest.approx(
        [0.0, 1.0], abs=1e-3
    )


def test_path_files_and_bad_specs(tmp_path):
    f = tmp_path / "p.csv"
    f.write_text("x,z,t\n0,0,0\n0,1,1\n1,2,2.5\n")
    p = C.parse_path(f)
    assert p.times is not None and p.duration == 2.5 and len(p.points) == 3
    assert C.GroundPath.from_csv(f).arc_at_time(np.array([1.0]))[0] == pytest.approx(1.0)
    # a spreadsheet's export in a locale that writes decimal commas
    (tmp_path / "semi.csv").write_text("x;z;t\n0;0;0\n0;1,5;1\n1,5;2;2,5\n")
    semi = C.parse_path(tmp_path / "semi.csv")
    assert np.allclose(semi.points, [[0, 0], [0, 1.5], [1.5, 2]]) and semi.duration == 2.5
    (tmp_path / "bad.csv").write_text("x,z\n0,0\n0,zz\n")
    with pytest.raises(MotionFileError, match="bad.csv"):
        C.parse_path(tmp_path / "bad.csv")
    for spec in ["circle:-1", "circle:x", "spiral:2"]:
        with pytest.raises(MotionValueError):
            C.parse_path(spec)
    with pytest.raises(MotionValueError, match="same place"):
        C.GroundPath(np.array([[0, 0], [0, 0], [1, 1]]))


@pytest.mark.parametrize("spec", ["circle:2", "eight:2"])
def test_a_walk_bent_onto_a_path_follows_it_with_feet_planted(walk, body, spec):
    raw = C.path_error(walk, spec, body)
    assert raw["mean_m"] > 3.0  # ignoring the path misses it by metres
    m = C.follow_path(walk, spec, body=body)
    err = C.path_error(m, spec, body)
    assert err["lateral_mean_m"] < 0.10 and err["lateral_max_m"] < 0.30, err
    # on schedule: the walk's own pace varies a little, a stall would be metres off
    assert err["mean_m"] < 0.25 and err["max_m"] < 0.60, err
    walked = C.ground_track(walk, body)["arc"][-1] / C.parse_path(spec).length
    assert err["progress"] == pytest.approx(walked, rel=0.05)  # the eight's crossing: no lobe jump
    assert contact_skating(m, body) <= contact_skating(walk, body) + 0.05
    # planting the feet leaves the root on the path: the legs take the corrections
    bent = C.follow_path(walk, spec, body=body, clean=False)
    np.testing.assert_allclose(m.trans[:, [0, 2]], bent.trans[:, [0, 2]], atol=1e-5)
    # it travels along the path: its heading is the tangent at the nearest path point
    path = C.parse_path(spec)
    grid, h = path.at(np.linspace(0, path.length, 4000, endpoint=False))
    track = C.ground_track(m, body)
    near = np.argmin(((track["travel"][:, None] - grid[None]) ** 2).sum(-1), axis=1)
    d = np.degrees(np.angle(np.exp(1j * (track["heading"] - h[near]))))
    assert np.median(np.abs(d)) < 10.0


def test_a_path_too_short_for_the_model_names_the_path_and_its_time(model, tmp_path):
    timed = tmp_path / "dash.csv"  # 3 m in 0.1 s
    np.savetxt(timed, np.c_[np.linspace(0, 3, 5), np.zeros(5), np.linspace(0, 0.1, 5)],
               delimiter=",")  # fmt: skip
    with pytest.raises(
        ClipTooShortError, match=r"path 'dash': 0\.1 s of motion \(from its times\)"
    ):
        C.generate_on_path(model, timed, "walk_sad", seed=0)
    with pytest.raises(ClipTooShortError, match=r"0\.05 s of motion \(as asked\).*at least"):
        C.generate_on_path(model, "circle:2", "walk_sad", seconds=0.05, seed=0)


def test_walking_past_the_end_of_an_open_path_warns(walk, body):
    walked = C.ground_track(walk, body)["arc"][-1]
    short = C.GroundPath(np.array([[0.0, 0.0], [0.0, walked / 2]]), name="short")
    with pytest.warns(UserWarning, match="'short' is .* m long, and this motion walks"):
        C.follow_path(walk, short, body=body, clean=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # its own length, and a closed path: no warning
        C.follow_path(walk, C.GroundPath(short.points * 2.02), body=body, clean=False)
        C.follow_path(walk, "circle:0.3", body=body, clean=False)


def test_a_timed_path_sets_the_pace_and_warns_when_it_is_far_from_the_motions(walk, body):
    own = C.ground_track(walk, body)["arc"][-1] / walk.duration
    pts = np.array([[0.0, 0.0], [0.0, 3 * own * walk.duration]])
    fast = C.GroundPath(pts, times=np.array([0.0, walk.duration]))  # three times its pace
    with pytest.warns(UserWarning, match="m/s"):
        m = C.follow_path(walk, fast, body=body, clean=False)
    assert C.ground_track(m, body)["arc"][-1] == pytest.approx(3 * own * walk.duration, rel=0.05)
    slow = C.GroundPath(pts * 0.95 / 3, times=np.array([0.0, walk.duration]))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # close to its own pace: no warning
        C.follow_path(walk, slow, body=body, clean=False)


def _stalled(m, seconds: float):
    """``m`` walking for ``seconds``, then standing still in its pose of that moment."""
    k = int(seconds * m.fps)
    held = lambda a: np.concatenate([a[:k], np.repeat(a[k - 1 : k], m.num_frames - k, 0)])  # noqa: E731
    return m.replace(poses=held(m.poses), trans=held(m.trans), contacts=None)


@pytest.mark.parametrize("spec", ["circle:2", "eight:2"])
def test_path_error_scores_a_walker_that_stalls(walk, body, spec):
    """A walker that stops after 3 s of 20 stays near the path (the nearest-point
    distance, ``lateral_*``, cannot tell), but it is metres behind its schedule for the
    rest of the walk and has walked a fraction of the path."""
    good = C.follow_path(walk, spec, body=body)
    stall = _stalled(good, 3.0)
    e_good, e_stall = C.path_error(good, spec, body), C.path_error(stall, spec, body)
    assert e_stall["lateral_mean_m"] < 0.10  # on the line all the time ...
    assert e_stall["mean_m"] > 1.0 and e_stall["mean_m"] > 5 * e_good["mean_m"], (e_stall, e_good)
    assert e_stall["progress"] < 0.2 * e_good["progress"]  # ... but it walked a sixth of it
    walked = C.ground_track(walk.slice(0, int(3.0 * walk.fps)), body)["arc"][-1]
    assert e_stall["progress"] == pytest.approx(walked / C.parse_path(spec).length, rel=0.1)


def test_path_error_follows_a_timed_paths_schedule(walk, body):
    """With times, the schedule is the path's: on time scores centimetres, the same walk
    against a path timed at twice its pace scores metres though it walks the same line."""
    own = C.ground_track(walk, body)["arc"][-1] / walk.duration
    end = np.array([0.0, own * walk.duration])
    timed = C.GroundPath(np.stack([np.zeros(2), end]), times=np.array([0.0, walk.duration]))
    m = C.follow_path(walk, timed, body=body)
    assert C.path_error(m, timed, body)["mean_m"] < 0.25
    hurried = C.GroundPath(timed.points * 2, times=timed.times)
    e = C.path_error(m, hurried, body)
    assert e["lateral_mean_m"] < 0.10 and e["mean_m"] > 3.0, e
    assert e["progress"] == pytest.approx(0.5, abs=0.05)


def test_generate_on_path_with_a_model(model, body):
    m = C.generate_on_path(model, "circle:2", "walk_sad", seconds=6.0, seed=0, body=body)
    assert m.num_frames == 60 and m.meta["path"]["name"].startswith("circle")
    assert C.path_error(m, "circle:2", body)["lateral_mean_m"] < 0.10


def test_an_open_path_without_a_length_is_walked_to_its_end(model, body):
    """Timed by the label's 10-s pace, a draw walks a little faster or slower: it is drawn
    longer and cut where it reaches the end (a closed path keeps its implied lap)."""
    import warnings

    pace = C.natural_pace(model, "walk_sad")
    path = C.GroundPath(np.array([[0.0, 0.0], [0.0, 4 * pace]]), name="four seconds")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # not past the end
        m = C.generate_on_path(model, path, "walk_sad", seed=1, body=body)
    assert C.path_error(m, path, body)["progress"] == pytest.approx(1.0, abs=0.05)
    seconds, _ = C.path_seconds(model, "circle:2", "walk_sad")
    lap = C.generate_on_path(model, "circle:2", "walk_sad", seed=1, body=body)
    assert lap.num_frames == max(2, round(seconds * model.fps))


# -- keyframes ----------------------------------------------------------------------------
def test_keyframes_hold_exactly_and_without_a_pop(walk, body, clips):
    m = walk.slice(0, 90)
    other = clips[1].resample(30.0)  # a wave: a pose the walk never has
    kfs = [
        C.Keyframe(45, other.poses[10], joints=("right_shoulder", "right_elbow")),  # 17, 19
        C.Keyframe(89, trans=m.trans[89] + [0.3, 0.0, 0.2]),
    ]
    before = C.keyframe_errors(m, kfs)
    assert before["rotation_deg"] > 30 and before["trans_cm"] > 30  # ignored: far off
    out = C.apply_keyframes(m, kfs)
    after = C.keyframe_errors(out, kfs)
    assert after["rotation_deg"] < 1e-3 and after["trans_cm"] < 1e-3
    # no pop: a keyframe written into its frame alone jumps; eased, the arm turns a
    # little every frame
    popped = m.poses.copy()
    popped[45, [17, 19]] = other.poses[10, [17, 19]]
    pop = _turn_steps(popped[:, [17, 19]]).max()
    eased = _turn_steps(out.poses[:, [17, 19]]).max()
    assert pop > 20.0 and eased < 0.25 * pop, (pop, eased)


def test_keyframes_round_trip_and_refuse_bad_input(tmp_path, walk):
    kfs = [C.Keyframe.from_motion(walk, 3, 0), C.Keyframe(5, walk.poses[9], joints=(0, "head"))]
    back = C.load_keyframes(C.save_keyframes(tmp_path / "kf.npz", kfs))
    assert [k.frame for k in back] == [0, 5] and back[1].joints == (0, 15) and back[1].trans is None
    assert np.allclose(back[0].trans, walk.trans[3])
    with pytest.raises(MotionValueError, match="constrains nothing"):
        C.Keyframe(3)
    with pytest.raises(MotionValueError, match="unknown joint"):
        C.Keyframe(3, walk.poses[0], joints=("tail",))
    with pytest.raises(MotionValueError, match="beyond"):
        C.apply_keyframes(walk.slice(0, 10), [C.Keyframe(12, trans=np.zeros(3))])
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(MotionFileError):
        C.load_keyframes(tmp_path / "junk.npz")


def test_generate_with_keyframes_meets_them(model, clips, body):
    walk = clips[0]
    kfs = [C.Keyframe.from_motion(walk, 0, 0), C.Keyframe.from_motion(walk, -1, 29, root=False)]
    m = C.generate_with_keyframes(model, kfs, 30, "walk_sad", seed=0, fit=C.KeyframeFit(steps=5),
                                  body=body)  # fmt: skip
    err = C.keyframe_errors(m, kfs)
    assert err["rotation_deg"] < 0.01 and err["trans_cm"] < 0.01
    raw = generate(model, "walk_sad", length=30, seed=0)
    assert C.keyframe_errors(raw, kfs)["rotation_deg"] > 5.0


def test_the_noise_fit_weighs_jitter_near_keyframes_only(model, clips):
    walk = clips[0]
    smooth = model.normalizer.normalize(model.features[0])[None].transpose(1, 2)  # (1, C, T)
    T = smooth.shape[-1]
    kfs = [
        C.Keyframe(0, walk.poses[0], joints=("right_elbow",)),
        C.Keyframe(T - 1, trans=walk.trans[5]),
    ]
    reach = C.keyframes.STILL_S * model.fps  # frames
    assert T > 4 * reach
    rng = np.random.default_rng(0)

    def jittered(frames):
        x = smooth.clone()
        x[0, :, frames] += (
            0.3 * torch.from_numpy(rng.normal(size=(x.shape[1], len(frames)))).float()
        )
        return x

    near = jittered([max(2, int(reach) // 2 + 1)])  # in the first keyframe's window, not on it
    far = jittered([T // 2])
    plain = C.keyframe_objective(model, kfs, T, still=0.0)
    weighted = C.keyframe_objective(model, kfs, T, still=C.keyframes.STILL)
    assert float(plain(near)) == pytest.approx(float(plain(far)), abs=1e-6)
    base = float(weighted(smooth) - plain(smooth))  # the clip's own jerk near the keyframes
    assert float(weighted(far) - plain(far)) == pytest.approx(base, abs=1e-6)  # far: nothing
    assert float(weighted(near) - plain(near)) > base + 0.1
    assert C.keyframe_objective(model, [C.Keyframe(5, trans=walk.trans[0])], T, still=0.0) is None
    with pytest.raises(MotionValueError, match="still"):
        C.keyframe_objective(model, kfs, T, still=-1.0)


def test_a_lone_root_keyframe_leaves_the_body_moving(model, clips):
    # nothing to fit the noise to: the jerk term alone would fit the body to stillness
    walk, T = clips[0], 40
    lone = [C.Keyframe(T // 2, trans=walk.trans[5])]
    assert C.keyframe_objective(model, lone, T) is None
    facing = [C.Keyframe(T // 2, walk.poses[5], joints=(0,), trans=walk.trans[5])]
    assert C.keyframe_objective(model, facing, T) is None
    free = generate(model, "walk_sad", length=T, seed=3)
    m = C.generate_with_keyframes(model, lone, T, "walk_sad", seed=3)
    assert m.poses.std(0).max() > 0.5 * free.poses.std(0).max()
    assert C.keyframe_errors(m, lone)["trans_cm"] < 0.5


def test_the_jerk_term_weighs_the_joints_jitter_too(model, clips, body, monkeypatch):
    walk = clips[0]
    smooth = model.normalizer.normalize(model.features[0])[None].transpose(1, 2)  # (1, C, T)
    T = smooth.shape[-1]
    kfs = [C.Keyframe(0, walk.poses[0], joints=("right_elbow",))]
    near, far = smooth.clone(), smooth.clone()
    f_near, f_far = int(C.keyframes.STILL_S * model.fps) // 2 + 1, T // 2
    near[0, :, f_near] += 0.3
    far[0, :, f_far] += 0.3
    with_joints = C.keyframe_objective(model, kfs, T, body=body)
    monkeypatch.setattr(C.keyframes, "JOINT_JERK", 0.0)
    channels_only = C.keyframe_objective(model, kfs, T, body=body)

    def added(fn, x):
        return float(fn(x) - fn(smooth))

    # the same jolt near the keyframe costs more once the joints' jerk is weighed;
    # far from it, neither term sees it
    assert added(with_joints, near) > 2 * added(channels_only, near) > 0
    assert added(with_joints, far) == pytest.approx(0.0, abs=1e-4)
    assert added(channels_only, far) == pytest.approx(0.0, abs=1e-4)


def test_continuation_keeps_the_prefix_and_joins_it_smoothly(model, clips, body):
    prefix = clips[0].slice(0, 20)
    m = C.continue_motion(model, prefix, 20, "walk_sad", seed=0, fit=C.NoiseFit(steps=5),
                          body=body)  # fmt: skip
    assert m.num_frames == 40 and np.array_equal(m.poses[:20], prefix.poses)
    assert np.allclose(m.trans[:20], prefix.trans)
    # the seam step is no larger than the generated part's own steps; gluing the raw
    # sample on (placed at the prefix's end) jumps
    steps = _steps(m, body)
    assert steps[19] <= np.percentile(steps[20:], 95) + 1e-6
    raw = generate(model, "walk_sad", length=20, seed=0)
    raw = raw.replace(trans=raw.trans - raw.trans[0] + prefix.trans[-1])
    glued = prefix.replace(
        poses=np.concatenate([prefix.poses, raw.poses]),
        trans=np.concatenate([prefix.trans, raw.trans]),
        contacts=None,
    )
    assert _steps(glued, body)[19] > 2 * steps[19]


def test_a_continuation_keeps_the_prefixs_body_on_its_floor(model, clips, body):
    """A prefix of another body shape: the output has its betas and its prefix frame for
    frame, and the new frames' root stands as much higher as that body's soles are lower
    than the model's (they were drawn on the model's body and came out with its betas,
    the new frames 14 cm off the floor for a tall clip). The two prefixes below stand
    alike, one on the model's body and one on a taller one."""
    shapes = [np.float32(np.eye(body.num_betas)[i] * s) for i in range(body.num_betas)
              for s in (-2.5, 2.5)]  # fmt: skip
    tall = max(shapes, key=lambda b: C.common.sole_lift(body, model.betas, b))
    lift = C.common.sole_lift(body, model.betas, tall)
    assert lift > 0.05
    same = clips[0].slice(0, 20).replace(betas=model.betas)
    prefix = same.replace(betas=tall, trans=same.trans + np.float32([0, lift, 0]))
    low = [body.motion_vertices(p)[..., 1].min(1) for p in (same, prefix)]
    assert np.allclose(low[0], low[1], atol=0.01)
    out = []
    for p in (same, prefix):
        m = C.continue_motion(model, p, 20, "walk_sad", seed=0, fit=C.NoiseFit(steps=5),
                              body=body, sampler=Sampler(fix_contacts=False))  # fmt: skip
        assert np.array_equal(m.betas, p.betas) and np.allclose(m.trans[:20], p.trans)
        out.append(m)
    assert np.allclose(out[1].poses, out[0].poses, atol=1e-4)
    assert np.allclose(out[1].trans[20:, 1] - out[0].trans[20:, 1], lift, atol=1e-3)


def test_a_continuation_of_a_faster_walk_never_walks_back(model, clips, body):
    """A prefix that covers ground faster than the model walks: after the join the eased
    root goes on forward (it slid back over the blend when the gap there was faded out).
    Raw: this prefix's feet slide (its root moves 3x as far as its steps), and planting
    the continuation's feet holds the root back from that slide."""
    prefix = clips[0].slice(0, 20)
    fast = prefix.replace(trans=prefix.trans * np.array([3.0, 1.0, 3.0]))
    m = C.continue_motion(model, fast, 20, "walk_sad", seed=0, fit=C.NoiseFit(steps=5),
                          body=body, sampler=Sampler(fix_contacts=False))  # fmt: skip
    heading = fast.trans[-1, [0, 2]] - fast.trans[0, [0, 2]]
    heading /= np.linalg.norm(heading)
    ahead = m.trans[19:, [0, 2]] @ heading  # from the prefix's last frame on
    assert ahead.min() >= ahead[0] - 0.02, ahead[:12]


def test_a_held_prefix_comes_back_as_it_is_and_the_rest_is_planted(body):
    """cleanup_foot_contacts with PlantOptions(hold=K), as a continuation plants its feet after the
    ease: the root drifting after frame K (an ease that slides the feet) is planted
    again from the join on, the first K frames untouched; without the hold the clean-up
    moves them too."""
    from mrlib.representation.contacts import foot_contacts
    from mrlib.sampling.cleanup import cleanup_foot_contacts
    from mrlib.sampling.planting import PlantOptions

    w = synthetic_walk("walk_sad", seconds=4.0, fps=30.0, body=body)
    K, trans = 60, w.trans.copy()
    trans[K:, 0] += np.linspace(0, 0.4, w.num_frames - K)  # 0.4 m over 2 s
    m = w.replace(trans=trans, contacts=foot_contacts(w, body))
    held = cleanup_foot_contacts(m, body, options=PlantOptions(hold=K))
    free = cleanup_foot_contacts(m, body)
    assert np.array_equal(held.poses[:K], m.poses[:K]) and np.array_equal(
        held.trans[:K], m.trans[:K]
    )
    assert np.abs(free.trans[:K] - m.trans[:K]).max() > 0.02  # the hold is what keeps them
    after = contact_skating(held.slice(K - 1), body)
    assert after < 0.5 * contact_skating(m.slice(K - 1), body)
    assert after < 1.2 * contact_skating(free.slice(K - 1), body)
    step = np.linalg.norm(np.diff(held.trans, axis=0), axis=1)
    assert step[K - 2 : K + 2].max() < 1.5 * np.median(step)  # no jump at the join


# -- loops --------------------------------------------------------------------------------
def test_circular_generation_is_periodic(model):
    W = Condition.label("walk_sad").weights(model)
    lengths, amp, conds = label_inputs(model, W, 40, Sampler())

    def wrap_ratio(circular: bool) -> np.ndarray:
        x = sample_features(model, conds, lengths, amp, seed=3, num_samples=8, circular=circular)
        step = (x[..., 1:] - x[..., :-1]).norm(dim=1)  # (B, T - 1)
        wrap = (x[..., 0] - x[..., -1]).norm(dim=1)  # (B,)
        return (wrap / step.median(dim=1).values).numpy()

    on, off = wrap_ratio(True), wrap_ratio(False)
    assert np.median(on) < 2.0 and np.median(off) > 2 * np.median(on), (on, off)


def test_periodic_upsampling_wraps_around():
    from mrlib.model.pyramid import resample_linear, resample_periodic

    t = torch.arange(12, dtype=torch.float64)
    x = torch.sin(2 * np.pi * t / 12)[None, None]
    up = resample_periodic(x, 16)[0, 0]
    exact = torch.sin(2 * np.pi * ((torch.arange(16) + 0.5) * 12 / 16 - 0.5) / 12)
    assert (up - exact).abs().max() < 0.05
    # the same as resampling three periods and keeping the middle one
    three = resample_linear(x.repeat(1, 1, 3), 48)[0, 0, 16:32]
    assert torch.allclose(up, three, atol=1e-12)
    assert not torch.allclose(resample_linear(x, 16)[0, 0], three, atol=1e-3)  # clamped ends


def test_constrained_samples_carry_their_condition_and_what_made_them(model, clips):
    """Loops, keyframes and continuations of a mix carry its name, as generate's
    samples do (they carried the finest level's label), and record their seed."""
    mix = Condition.crossover("walk_sad", "wave", 2)
    fit = C.NoiseFit(steps=1)
    made = [
        C.generate_loop(model, mix, 30, seed=4),
        C.generate_with_keyframes(
            model, [C.Keyframe.from_motion(clips[0], 0, 5)], 30, mix, seed=4, fit=fit
        ),  # fmt: skip
        C.continue_motion(model, clips[0].slice(0, 12), 10, mix, seed=4, fit=fit),
    ]
    for m in made:
        assert m.label == generate(model, mix, length=30, seed=4).label == "walk_sad+wave"
        assert m.meta["sampler"]["seed"] == 4 and m.meta["sampler"]["labels"] == model.labels


def test_generate_loop_tiles_seamlessly(model, body):
    m = C.generate_loop(model, "walk_sad", 40, seed=1, sampler=RAW)
    assert m.num_frames == 40 and len(m.meta["loop_offset"]) == 3
    two = C.tile_loop(m, 2)
    assert two.num_frames == 80 and np.allclose(two.poses[40:], two.poses[:40])
    seam = C.loop_seam(m, body)
    assert seam["seam"] < 2 * seam["median"]
    assert 0.0 <= seam["rank"] <= 1.0
    with pytest.raises(MotionValueError, match="not a loop"):
        C.tile_loop(generate(model, "walk_sad", length=20, seed=0), 2)


def test_loop_starts_at_its_calmest_frame(model, body):
    raw = C.generate_loop(model, "walk_sad", 40, seed=1, start="sample", sampler=RAW)
    calm = C.generate_loop(model, "walk_sad", 40, seed=1, sampler=RAW)
    k = calm.meta["loop_start"]
    assert 0 < k < 40  # this draw's calmest step is not the wrap itself
    # the same cycle, begun k frames later, and still one cycle's travel per cycle
    assert np.allclose(calm.poses, np.roll(raw.poses, -k, axis=0), atol=1e-6)
    assert np.allclose(calm.meta["loop_offset"], raw.meta["loop_offset"])
    assert np.allclose(C.tile_loop(calm, 2).trans[1:41] - C.tile_loop(raw, 2).trans[k + 1 : k + 41],
                       calm.trans[1] - raw.trans[k + 1], atol=1e-5)  # fmt: skip
    seams = [C.loop_seam(m, body) for m in (raw, calm)]
    J = body.motion_joints(C.tile_loop(calm, 2).slice(0, 41))
    steps = np.linalg.norm(np.diff(J, axis=0), axis=-1).mean(-1)
    assert seams[1]["seam"] == pytest.approx(steps.min(), rel=1e-5)
    assert seams[1]["seam"] < seams[0]["seam"]
    assert seams[1]["rank"] == 0.0  # the smallest step of the cycle
    with pytest.raises(MotionValueError, match="start must be"):
        C.generate_loop(model, "walk_sad", 40, start="first")


def test_loop_seam_ranks_the_wrap_among_the_loops_own_steps(walk, body):
    """A cut of a steady walk closed on itself jumps back to its first pose: the seam is
    larger than every step of its own (rank 1); a piece of a walk ending just before it
    starts again (one gait cycle) wraps with an ordinary step."""
    from mrlib.sampling.constraints.compose import gait_phase

    phase = gait_phase(walk, body)
    start = int(np.searchsorted(phase, phase[0] + 2 * np.pi))
    end = int(np.searchsorted(phase, phase[start] + 2 * np.pi))  # one cycle from start

    def closed(m):  # the next cycle goes on from the last step's ground velocity
        off = m.trans[-1] - m.trans[0] + m.trans[-1] - m.trans[-2]
        return m.replace(meta=dict(m.meta, loop_offset=off.tolist()))

    cycle = closed(walk.slice(start, end))
    half = closed(walk.slice(start, (start + end) // 2 + 2))  # half a cycle: legs swapped
    whole, cut = C.loop_seam(cycle, body), C.loop_seam(half, body)
    assert cut["rank"] == 1.0 and cut["seam"] > 2 * cut["p95"], cut
    assert whole["rank"] < 1.0 and whole["seam"] < whole["p95"], whole


def test_a_cleaned_loop_wraps_where_its_clean_up_went_on(model, body):
    """Planting the feet moves the root: the cleaned cycle's ``loop_offset`` is its own
    travel (middle of three cleaned cycles to the third's start), so the tiled loop
    steps from its last frame to where the clean-up of three cycles went on."""
    from mrlib.sampling.cleanup import cleanup_foot_contacts

    raw = C.generate_loop(model, "walk_sad", 40, seed=1, start="sample", sampler=RAW)
    loop = C.generate_loop(model, "walk_sad", 40, seed=1, start="sample")
    three = cleanup_foot_contacts(C.tile_loop(raw, 3), body)
    two = C.tile_loop(loop, 2)
    want = three.trans[80] - three.trans[79]  # the clean-up's own step across the seam
    assert np.allclose(two.trans[40] - two.trans[39], want, atol=1e-6)
    assert np.allclose(loop.poses, three.poses[40:80])


# -- body parts ---------------------------------------------------------------------------
def test_spliced_parts_take_each_group_from_its_own_label(model):
    parts = {"upper": "wave", "lower": "walk_sad"}
    m = C.generate_parts(model, parts, length=30, seed=2, sampler=RAW)
    wave = generate(model, "wave", length=30, seed=2, sampler=RAW)
    sad = generate(model, "walk_sad", length=30, seed=2, sampler=RAW)
    up, low = list(C.part_joints("upper")), list(C.part_joints("lower"))
    assert np.array_equal(m.poses[:, up], wave.poses[:, up])
    assert np.array_equal(m.poses[:, low], sad.poses[:, low])
    assert np.array_equal(m.trans, sad.trans)
    # in step: the legs (and root) are still the pelvis part's own sample, at its length
    step = C.generate_parts(model, Condition.parts(parts, in_step=True), length=30, seed=2,
                            sampler=RAW)  # fmt: skip
    assert step.num_frames == 30
    assert np.array_equal(step.poses[:, low], sad.poses[:, low])
    assert np.array_equal(step.trans, sad.trans)
    # by name, before anything is drawn (and on the command line, when its argument is read)
    msg = "'upper' and 'left_arm' overlap at left_collar, left_shoulder, left_elbow"
    with pytest.raises(MotionValueError, match=msg):
        C.generate_parts(model, {"upper": "wave", "left_arm": "walk_sad"}, length=30)
    with pytest.raises(MotionValueError, match=msg):
        C.parse_parts("upper=wave,left_arm=walk_sad")
    with pytest.raises(MotionValueError, match="unknown body part 'arms'"):
        C.parse_parts("upper=wave,arms=walk_sad")
    two = C.generate_parts(model, parts, length=30, seed=2, num=2, sampler=RAW)
    assert isinstance(two, list) and len(two) == 2 and two[0].label == "upper=wave,lower=walk_sad"
    assert np.abs(two[0].poses - m.poses).max() < 1e-3  # sample b: noise stream (seed, b)
    with pytest.raises(MotionValueError, match="generate_parts"):
        generate(model, Condition.parts(parts))
    with pytest.raises(MotionValueError, match="part=label"):
        C.parse_parts("upper")


def _normalised(model, motion) -> torch.Tensor:
    """``(1, C, T)`` a motion as the generator's normalised output."""
    from mrlib.representation.features import motion_to_features

    f = motion_to_features(motion).float()
    return model.normalizer.normalize(f).T[None]


def test_the_label_margin_is_zero_on_a_label_clip_and_not_under_another_label(model):
    from mrlib.representation.features import features_to_motion

    k = model.clip_labels.index(model.label_index("walk_sad"))
    clip = features_to_motion(model.features[k], model.fps, betas=model.betas)
    x = _normalised(model, clip)
    for part in ("upper", "lower"):
        own = C.label_margin_objective(model, {part: "walk_sad"})(x)
        other = C.label_margin_objective(model, {part: "wave"})(x)
        assert float(own) < 1e-3, part  # every window is the clip itself
        assert float(other) > C.MARGIN, part  # nearer walk_sad than wave by far
    with pytest.raises(MotionValueError, match="margin"):
        C.label_margin_objective(model, {"upper": "wave"}, margin=float("nan"))
    with pytest.raises(MotionValueError, match="unknown label"):
        C.label_margin_objective(model, {"upper": "jump"})


def _own_distance(model, motion, part: str, label: str) -> float:
    """Mean squared distance of a part's windows to their nearest window of the label's clip."""
    from mrlib.metrics.windows import metric_features, model_references, nearest_windows
    from mrlib.sampling.constraints.sharpen import part_columns

    _, labels, feats = model_references(model)
    cols = part_columns(part)
    ref = feats[labels.index(label)][:, cols]
    return float(nearest_windows(metric_features(motion)[:, cols], ref, 30, squared=True)[0].mean())


def test_the_noise_prior_centred_on_the_draw_leaves_unneeded_noise_alone(model):
    # a loss that asks nothing of the output: Adam still moves every noise value towards
    # 0 under the prior at 0, and none under the prior centred on the starting draw
    from mrlib.sampling.constraints.optimise import optimise_noise
    from mrlib.sampling.generation import check_conditions, draw_noise

    W = Condition.label("walk_sad").weights(model)
    lengths, amp, conds = label_inputs(model, W, 40, Sampler())
    noises = draw_noise(lengths, amp, 3, 2, model.device)
    cs = check_conditions(model, conds, lengths, 2)

    def nothing(x):
        return 0 * x.sum()

    kept, _ = optimise_noise(model, noises, cs, nothing, steps=10, prior_centre="draw")
    shrunk, _ = optimise_noise(model, noises, cs, nothing, steps=10)
    for z, k, s in zip(noises, kept, shrunk, strict=True):
        assert torch.allclose(k, z)
        if z.abs().max() > 0:
            assert float(s.abs().mean()) < 0.9 * float(z.abs().mean())
    with pytest.raises(ValueError, match="prior_centre"):
        optimise_noise(model, noises, cs, nothing, steps=1, prior_centre="mean")


def test_sharpened_parts_are_pulled_to_their_label_and_spliced_as_drawn(model):
    # the plumbing model's walk_sad samples have the wave's arms (every upper-body window
    # is nearer the wave clip): the fit pulls them towards the walk_sad clip
    parts = {"upper": "walk_sad", "lower": "wave"}
    up = list(C.part_joints("upper"))
    kw = dict(seed=2, num=2)
    plain = C.generate_sharpened(model, "walk_sad", ("upper",), 40, fit=C.Sharpening(0), **kw)
    sharp = C.generate_sharpened(model, "walk_sad", ("upper",), 40, fit=C.Sharpening(15), **kw)
    drawn = generate(model, "walk_sad", length=40, sampler=RAW, **kw)
    for a, b in zip(plain, drawn, strict=True):  # no steps: the sampler's own draw
        assert np.array_equal(a.poses, b.poses)
    for a, b in zip(plain, sharp, strict=True):
        gain = _own_distance(model, a, "upper", "walk_sad") - _own_distance(
            model, b, "upper", "walk_sad"
        )
        assert gain > 1.0  # of about 64
        assert b.meta["sampler"]["sharpen"]["steps"] == 15
    # the splice takes the upper body from the sample fitted on it alone
    one = C.generate_sharpened(model, "walk_sad", ("upper",), 40, seed=2, fit=C.Sharpening(15))
    m = C.generate_parts(model, parts, length=40, seed=2, sharpen=15, sampler=RAW)
    assert np.array_equal(m.poses[:, up], one.poses[:, up])
    for bad in (-1, 1.5, True):
        with pytest.raises(MotionValueError, match="sharpen"):
            C.generate_parts(model, parts, length=40, sharpen=bad)
        with pytest.raises(MotionValueError, match="steps"):
            C.Sharpening(steps=bad)


def test_phase_align_puts_the_arms_in_step_with_the_legs(body):
    # two procedural walks of different cadence (1.3 and 2.2 steps/s) and phase: the
    # spliced body's arms swing out of step with its legs unless retimed to them
    legs = synthetic_walk("walk_sad", seconds=6.0, fps=30.0, seed=0, body=body)
    arms = synthetic_walk("walk_happy", seconds=12.0, fps=30.0, seed=1, body=body)
    assert C.arm_leg_coordination(legs, body) > 0.8 and C.arm_leg_coordination(arms, body) > 0.8
    plain = C.splice_parts({"upper": arms, "lower": legs})
    in_step = C.splice_parts({"upper": arms, "lower": legs}, align=True, body=body)
    assert in_step.num_frames == plain.num_frames == legs.num_frames
    assert abs(C.arm_leg_coordination(plain, body)) < 0.3
    assert C.arm_leg_coordination(in_step, body) > 0.9
    low = list(C.part_joints("lower"))
    assert np.array_equal(in_step.poses[:, low], legs.poses[:, low])  # the legs are kept
    # retimed, the arms' gait phase follows the legs' (up to whole cycles)
    d = C.gait_phase(C.phase_align(arms, legs, body), body) - C.gait_phase(legs, body)
    assert np.abs(np.angle(np.exp(1j * d[15:-15]))).max() < 0.2
    # nothing to align: a body standing still, or a source with too few strides
    still = legs.replace(poses=np.repeat(legs.poses[:1], legs.num_frames, 0),
                         trans=np.repeat(legs.trans[:1], legs.num_frames, 0))  # fmt: skip
    assert C.gait_phase(still, body) is None
    assert C.phase_align(arms, still, body) is None
    assert C.phase_align(arms.slice(0, 60), legs, body) is None
    kept = C.splice_parts({"upper": arms, "lower": still}, align=True, body=body)
    assert np.array_equal(kept.poses, C.splice_parts({"upper": arms, "lower": still}).poses)


def test_parts_widget_guidance_reaches_the_parts(model, body, monkeypatch):
    pytest.importorskip("ipywidgets")
    import mrlib.viz.constraint_views as CV

    monkeypatch.setattr(
        CV, "render_meshes", lambda m, body, frames=None, **kw: np.zeros((8, 8, 3))
    )  # the real one takes seconds
    box, update = CV.interactive_parts(model, body=body, length=40)
    controls = {c.description: c for row in box.children[:-1] for c in row.children}
    assert controls["guidance"].value == 0.0
    plain = update()
    controls["guidance"].value = 0.5
    pushed = update()
    assert np.abs(pushed.poses - plain.poses).max() > 1e-4
    same = C.generate_parts(model, {"upper": "walk_sad", "lower": "wave"}, length=40, seed=0,
                            sampler=Sampler(guidance=0.5), body=body)  # fmt: skip
    assert np.allclose(same.poses, pushed.poses, atol=1e-5)


# -- command line -------------------------------------------------------------------------
def test_sample_cli_constraints(tmp_path, clips):
    from mrlib.app.cli import main
    from mrlib.io import save_motion

    files = [str(save_motion(c, tmp_path / f"{c.label}.npz")) for c in clips]
    run = tmp_path / "run"
    assert main(["train", *files, "--iterations", "1", "--levels", "2", "--no-progress",
                 "--out", str(run)]) == 0  # fmt: skip
    ckpt = str(run / "checkpoint.pt")
    out = tmp_path / "o"
    base = ["sample", ckpt, "--label", "walk_sad", "--out", str(out)]
    assert main([*base, "--path", "circle:1.5", "--seconds", "3"]) == 0
    assert main([*base, "--loop", "--seconds", "2"]) == 0
    kf = C.save_keyframes(tmp_path / "kf.npz", [C.Keyframe.from_motion(clips[0], 0, 0)])
    assert main([*base, "--keyframes", str(kf), "--seconds", "2"]) == 0
    assert main([*base, "--continue", files[0], "--seconds", "1"]) == 0
    assert main(["sample", ckpt, "--parts", "upper=wave,lower=walk_sad", "--out", str(out)]) == 0
    assert main(["sample", ckpt, "--in-step", "--out", str(out)]) == 1  # needs --parts
    assert main([*base, "--loop", "--seconds", "2", "--fps", "30"]) == 1  # label samples only
    rate = tmp_path / "rate"
    fps = [
        "sample",
        ckpt,
        "--label",
        "walk_sad",
        "--fps",
        "25",
        "--seconds",
        "2",
        "--out",
        str(rate),
    ]
    assert main(fps) == 0
    from mrlib.io import load_motion as _load

    assert _load(next(rate.glob("*.npz"))).fps == 25.0
    step = ["sample", ckpt, "--parts", "upper=wave,lower=walk_sad", "--in-step"]
    assert main([*step, "--out", str(tmp_path / "in_step")]) == 0
    sharp = tmp_path / "sharp"
    assert main([*step, "--sharpen", "3", "--no-progress", "--out", str(sharp)]) == 0
    assert main([*base, "--sharpen", "3"]) == 1  # needs --parts
    from mrlib.io import load_motion

    fit = load_motion(next(sharp.glob("*.npz"))).meta["sampler"]["sharpen"]
    assert fit["steps"] == 3 and fit["joints"] == [list(C.part_joints("lower"))]
    names = sorted(p.name for p in out.glob("*.npz"))
    assert len(names) == 5, names
    assert [sum(w in n for n in names) for w in ("path", "loop", "keyframes", "continued")] == [
        1
    ] * 4
    assert main([*base, "--keyframes", str(kf)]) == 1  # needs --seconds
    # --fit-steps reaches the noise fit: 0 steps is the library's unfitted in-between,
    # which the default (fitted) one is not
    from mrlib.model.trained import load_model

    bare = tmp_path / "bare"
    argv = [*base[:-1], str(bare), "--keyframes", str(kf), "--seconds", "2", "--fit-steps", "0"]
    assert main(argv) == 0
    got = load_motion(next(bare.glob("*.npz")))
    want = C.generate_with_keyframes(load_model(ckpt), C.load_keyframes(kf), got.num_frames,
                                     "walk_sad", seed=0, fit=C.KeyframeFit(steps=0))  # fmt: skip
    np.testing.assert_allclose(got.poses, want.poses, atol=1e-5)
    fitted = load_motion(next(p for p in out.glob("*.npz") if "keyframes" in p.name))
    assert np.abs(fitted.poses - got.poses).max() > 1e-3
    assert main([*base, "--loop", "--seconds", "2", "--fit-steps", "5"]) == 1
