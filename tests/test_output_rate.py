"""A model trained at a lower rate than its clips records the clips' rate, and the command
line writes its samples at that rate unless told otherwise (``GenerativeModel.source_fps``,
``mrlib sample --fps``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mrlib.app.cli import main
from mrlib.datasets.synthetic import synthetic_walk
from mrlib.io import load_motion, save_motion
from mrlib.model.checkpoint import clip_rates, load_checkpoint, save_checkpoint
from mrlib.model.trained import load_model
from mrlib.training.data import TrainingSet

TRAIN = ["--iterations", "1", "--levels", "2", "--no-progress", "--fps", "15"]


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    """A run trained by the CLI at 15 fps on two 30-fps clips (seconds)."""
    root = tmp_path_factory.mktemp("rate")
    clips = [
        save_motion(synthetic_walk(style, seconds=2.4, fps=30.0, seed=k), root / f"{style}.npz")
        for k, style in enumerate(("walk_sad", "walk_happy"))
    ]
    assert main(["train", *map(str, clips), *TRAIN, "--out", str(root / "run")]) == 0
    return root / "run"


def test_resampling_keeps_the_rate_a_motion_was_read_at():
    m = synthetic_walk("walk_sad", seconds=1.0, fps=30.0)
    assert "source_fps" not in m.meta
    assert m.resample(15).meta["source_fps"] == 30.0
    assert m.resample(15).resample(10).meta["source_fps"] == 30.0
    data = TrainingSet.from_motions([m.resample(15), synthetic_walk("walk_happy", 1.0, fps=24.0)], fps=15)  # fmt: skip
    assert data.fps == 15 and data.source_fps == [30.0, 24.0]


def test_the_model_records_its_clips_rate(run):
    model = load_model(run / "checkpoint.pt")
    assert model.fps == 15 and model.clip_fps == [30.0, 30.0] and model.source_fps == 30.0


def test_samples_come_at_the_clips_rate_unless_asked(run, tmp_path, capsys):
    ckpt = str(run / "checkpoint.pt")
    assert main(["sample", ckpt, "--seconds", "2", "--out", str(tmp_path / "a"), "--no-progress"]) == 0  # fmt: skip
    assert "samples at 30 fps, the training clips' rate" in capsys.readouterr().out
    (npz,) = (tmp_path / "a").glob("*.npz")
    m = load_motion(npz)
    assert m.fps == 30.0 and m.num_frames == 60  # 30 model frames (2 s) raised to 30 fps
    argv = ["sample", ckpt, "--seconds", "2", "--fps", "15", "--out", str(tmp_path / "b"), "--no-progress"]  # fmt: skip
    assert main(argv) == 0
    assert load_motion(next((tmp_path / "b").glob("*.npz"))).fps == 15.0


def test_a_model_at_a_higher_rate_than_its_clips_samples_at_theirs(tmp_path, capsys):
    """24-fps captures trained at 30 fps (the ``demo`` preset's rate) come back at 24 fps."""
    clips = [
        save_motion(synthetic_walk(style, seconds=2.4, fps=24.0, seed=k), tmp_path / f"{style}.npz")
        for k, style in enumerate(("walk_sad", "walk_happy"))
    ]
    argv = ["train", *map(str, clips), *TRAIN[:-1], "30", "--out", str(tmp_path / "run")]
    assert main(argv) == 0
    ckpt = tmp_path / "run" / "checkpoint.pt"
    model = load_model(ckpt)
    assert model.fps == 30 and model.clip_fps == [24.0, 24.0] and model.source_fps == 24.0
    argv = ["sample", str(ckpt), "--seconds", "2", "--out", str(tmp_path / "s"), "--no-progress"]
    assert main(argv) == 0
    assert "samples at 24 fps, the training clips' rate" in capsys.readouterr().out
    m = load_motion(next((tmp_path / "s").glob("*.npz")))
    assert m.fps == 24.0 and m.num_frames == 48  # 60 model frames (2 s) lowered to 24 fps


def test_a_checkpoint_without_the_record_samples_at_the_models_rate(run, tmp_path):
    state = load_checkpoint(run / "checkpoint.pt")
    del state["clip_fps"]
    old = tmp_path / "old.pt"
    save_checkpoint(old, state)
    assert load_model(old).source_fps is None
    assert main(["sample", str(old), "--seconds", "2", "--out", str(tmp_path / "s"), "--no-progress"]) == 0  # fmt: skip
    assert load_motion(next((tmp_path / "s").glob("*.npz"))).fps == 15.0


@pytest.mark.parametrize(
    "value", [None, "30", [30.0], [30.0, float("nan")], [30.0, -1.0], [30.0, 1e6], [30.0, "x"]]
)
def test_rates_that_are_not_rates_are_ignored(value):
    state = {"clip_names": ["a", "b"], "clip_fps": value}
    assert clip_rates(state) is None
    assert clip_rates({"clip_names": ["a", "b"], "clip_fps": [30, 24.0]}) == [30.0, 24.0]
    assert np.isfinite(clip_rates({"clip_names": ["a"], "clip_fps": [15]})[0])


def test_keyframes_a_second_apart_are_no_rate_to_write_samples_at(run, tmp_path):
    state = load_checkpoint(run / "checkpoint.pt")
    for rates, want in (([1.0, 1.0], None), ([1.0, 30.0], 30.0), ([12.0, 12.0], 12.0)):
        state["clip_fps"] = rates
        path = save_checkpoint(tmp_path / f"r{rates[-1]:g}.pt", state)
        assert load_model(path).source_fps == want


@pytest.mark.parametrize(
    "flags, frames",
    [
        (["--path", "line:1", "--seconds", "2"], 60),  # 30 model frames raised to 30 fps
        (["--parts", "upper=walk_sad,lower=walk_happy", "--seconds", "2"], 60),
        (["--loop", "--seconds", "2"], 60),  # a cycle of 30 frames, 60 at 30 fps
    ],
)
def test_path_loop_and_part_samples_come_at_the_clips_rate(run, tmp_path, capsys, flags, frames):
    ckpt = str(run / "checkpoint.pt")
    out = tmp_path / "a"
    assert main(["sample", ckpt, *flags, "--out", str(out), "--no-progress"]) == 0
    assert "samples at 30 fps, the training clips' rate" in capsys.readouterr().out
    m = load_motion(next(out.glob("*.npz")))
    assert m.fps == 30.0 and m.num_frames == frames
    assert main(["sample", ckpt, *flags, "--fps", "15", "--out", str(tmp_path / "b"), "--no-progress"]) == 0  # fmt: skip
    m = load_motion(next((tmp_path / "b").glob("*.npz")))
    assert m.fps == 15.0 and m.num_frames == frames // 2


@pytest.mark.parametrize(
    "flags, seconds, frames",
    [
        ([], 2.1, 63),  # 31.5 frames of the 15-fps model: 63 at 30 fps, not 64
        (["--fps", "60"], 1.5, 90),
        (["--fps", "100", "--path", "line:3"], 2.03, 203),
        (["--continue", "PREFIX", "--fit-steps", "2"], 2.1, 72 + 63),
    ],
)
def test_seconds_count_at_the_output_rate(run, tmp_path, flags, seconds, frames):
    flags = [str(run.parent / "walk_sad.npz") if f == "PREFIX" else f for f in flags]
    argv = ["sample", str(run / "checkpoint.pt"), *flags, "--seconds", str(seconds)]
    assert main([*argv, "--out", str(tmp_path / "a"), "--no-progress"]) == 0
    assert load_motion(next((tmp_path / "a").glob("*.npz"))).num_frames == frames


def test_continuations_and_keyframes_come_at_the_clips_rate(run, tmp_path, capsys):
    from mrlib.sampling.constraints import Keyframe, keyframe_errors, save_keyframes

    ckpt = str(run / "checkpoint.pt")
    prefix = load_motion(run.parent / "walk_sad.npz")  # a 30-fps clip of 72 frames
    out = tmp_path / "a"
    argv = ["sample", ckpt, "--continue", str(run.parent / "walk_sad.npz"), "--seconds", "1",
            "--fit-steps", "2", "--out", str(out), "--no-progress"]  # fmt: skip
    assert main(argv) == 0
    assert "continued at 30 fps, the prefix's rate" in capsys.readouterr().out
    m = load_motion(next(out.glob("*.npz")))
    # the prefix frame for frame, then 15 model frames (1 s) at 30 fps
    assert m.fps == 30.0 and m.num_frames == prefix.num_frames + 30
    np.testing.assert_allclose(m.poses[: prefix.num_frames], prefix.poses, atol=1e-6)
    # a 60-fps prefix comes back at 60 fps (the clips' rate is 30), frame for frame
    fast = save_motion(prefix.resample(60.0, smooth=True), tmp_path / "p60.npz")
    argv60 = [*argv[:3], str(fast), *argv[4:-3], "--out", str(tmp_path / "a60"), "--no-progress"]
    assert main(argv60) == 0
    m60, p60 = load_motion(next((tmp_path / "a60").glob("*.npz"))), load_motion(fast)
    assert m60.fps == 60.0 and m60.num_frames == p60.num_frames + 60  # 1 s more
    np.testing.assert_allclose(m60.poses[: p60.num_frames], p60.poses, atol=1e-6)
    # keyframes at frames of 30 fps: frame 50 of 60 (2 s)
    keys = [Keyframe.from_motion(prefix, 0, 0), Keyframe.from_motion(prefix, 50, 50)]
    save_keyframes(tmp_path / "k.npz", keys)
    argv = ["sample", ckpt, "--keyframes", str(tmp_path / "k.npz"), "--seconds", "2",
            "--fit-steps", "2", "--out", str(tmp_path / "b"), "--no-progress"]  # fmt: skip
    assert main(argv) == 0
    assert "--keyframes count frames at this rate" in capsys.readouterr().out
    m = load_motion(next((tmp_path / "b").glob("*.npz")))
    assert m.fps == 30.0 and m.num_frames == 60
    err = keyframe_errors(m, keys)
    assert err["rotation_deg"] < 0.01 and err["trans_cm"] < 0.01
    assert main([*argv[:-3], "--fps", "15", "--out", str(tmp_path / "c"), "--no-progress"]) == 1
    assert "beyond the motion's 30 frames (2 s at 15 fps)" in capsys.readouterr().err


def test_a_loop_raised_to_the_clips_rate_still_joins(run):
    from mrlib.representation.body import resolve_body
    from mrlib.sampling.constraints import generate_loop, loop_seam
    from mrlib.sampling.sampler import Sampler

    model, body = load_model(run / "checkpoint.pt"), resolve_body(None, shared=True)
    raw = Sampler(fix_contacts=False)
    kw = dict(seed=0, start="sample", body=body)
    low = generate_loop(model, "walk_sad", 20, sampler=raw, **kw)
    high = generate_loop(model, "walk_sad", 20, sampler=Sampler(fix_contacts=False, fps=30.0), **kw)
    assert (low.fps, low.num_frames, high.fps, high.num_frames) == (15.0, 20, 30.0, 40)
    # the same cycle: every second raised frame is a model frame
    np.testing.assert_allclose(high.poses[::2], low.poses, atol=1e-4)
    np.testing.assert_allclose(high.trans[::2], low.trans, atol=1e-5)
    np.testing.assert_allclose(high.meta["loop_offset"], low.meta["loop_offset"], atol=1e-5)
    # the step across the seam is no larger than the cycle's others at the new rate
    calm = generate_loop(model, "walk_sad", 20, seed=0, body=body, sampler=Sampler(fps=30.0))
    assert loop_seam(calm, body)["seam"] <= loop_seam(calm, body)["p95"]
