"""Clips load upright and on the floor with no option: an npz without an ``up_axis`` key
(AMASS is Z up, BEAT2 and most SMPL-X tools Y up) has its axis told from the body, and
its feet are put on ``y = 0``; a clip whose axis cannot be told is refused in one line.
Every format is checked the same way: head above pelvis above ankles, the lowest foot
vertex in contact within 2 cm of the floor."""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pytest
import torch

import mrlib
from mrlib.errors import MotionFileError
from mrlib.io.axes import up_axis_rotation
from mrlib.io.bodyfit import rest_pelvis
from mrlib.io.placement import stance
from mrlib.representation.rotations import axis_angle_to_matrix, matrix_to_axis_angle

BEAT2 = Path(
    os.environ.get(
        "MRLIB_BEAT2_SAMPLE",
        Path(__file__).resolve().parents[2] / "shared" / "data" / "beat2-sample",
    )
)
AXES = ["z", "y", "-z", "x", "-x", "-y"]


def _assert_upright(m, body) -> None:
    u = stance(m, body)
    assert u["head_above_pelvis"] > 0.99 and u["pelvis_above_ankles"] > 0.99, u
    assert u["floor_cm"] <= 2.0, u


def _in_world(m, axis: str, body, lift: float = 0.0):
    """``m`` (Y up) as poses / trans of a world whose up is ``axis``, its feet ``lift``
    metres off that world's floor (the inverse of ``mrlib.io.axes.change_up_axis``)."""
    A = up_axis_rotation(axis)
    G = axis_angle_to_matrix(torch.from_numpy(m.poses[:, 0].astype(np.float64))).numpy()
    J0 = rest_pelvis(body, m.betas)
    trans = m.trans.astype(np.float64) + np.array([0.0, lift, 0.0])
    poses = m.poses.astype(np.float64).copy()
    poses[:, 0] = matrix_to_axis_angle(torch.from_numpy(A.T @ G)).numpy()
    return poses, (trans + J0) @ A - J0


def _write(path, poses, trans, fps, width=72, **extra) -> Path:
    T = len(poses)
    flat = poses.reshape(T, 72)
    if width > 72:  # SMPL-H / SMPL-X: the 22 shared joints, then hands (and face) at zero
        flat = np.concatenate([flat[:, :66], np.zeros((T, width - 66))], axis=1)
    np.savez(path, poses=flat, trans=trans, betas=np.zeros(16), mocap_frame_rate=fps, **extra)
    return path


@pytest.fixture(scope="module")
def walk(default_body):
    from mrlib.datasets.synthetic import synthetic_walk

    return synthetic_walk("walk_happy", seconds=3.0, fps=30.0, body=default_body)


@pytest.mark.parametrize("width", [72, 156, 165])
@pytest.mark.parametrize("axis", AXES)
def test_an_npz_without_up_axis_loads_upright_and_on_the_floor(walk, body, tmp_path, axis, width):
    poses, trans = _in_world(walk, axis, body, lift=0.3)  # feet 30 cm up, as SMPL-X's do
    m = mrlib.load_motion(_write(tmp_path / "clip.npz", poses, trans, 30.0, width))
    assert m.meta["up_axis"] == axis and m.meta["up_axis_reason"].startswith("told from the body")
    assert m.meta["floor_shift_m"] == pytest.approx(-0.3, abs=0.02)
    _assert_upright(m, body)
    # the same motion as written: rotations and the path (up to the floor's few mm)
    hands = slice(0, 22) if width > 72 else slice(None)
    np.testing.assert_allclose(m.poses[:, hands], walk.poses[:, hands], atol=1e-4)
    np.testing.assert_allclose(m.trans, walk.trans, atol=0.02)


def test_the_up_axis_key_and_the_option_win_over_the_body(walk, body, tmp_path):
    poses, trans = _in_world(walk, "z", body)
    path = _write(tmp_path / "declared.npz", poses, trans, 30.0, up_axis="z")
    m = mrlib.load_motion(path)
    assert m.meta["up_axis_reason"] == "the file's up_axis key" and "floor_shift_m" not in m.meta
    wrong = mrlib.load_motion(path, up_axis="y")  # as told, even when it lies the body down
    assert wrong.meta["up_axis_reason"] == "as given"
    assert stance(wrong, body)["head_above_pelvis"] < 0.5
    # mrlib's own files (up_axis="y") round-trip untouched
    own = mrlib.load_motion(mrlib.save_motion(walk, tmp_path / "own.npz"))
    np.testing.assert_array_equal(own.trans, walk.trans.astype(np.float32))


def test_a_clip_whose_axis_cannot_be_told_is_refused_in_one_line(walk, body, tmp_path):
    """A body tumbling head over heels: no axis is up on average."""
    poses = walk.poses.astype(np.float64).copy()
    T = len(poses)
    angle = np.linspace(0, 2 * np.pi, T, endpoint=False)
    poses[:, 0] = np.stack([angle, np.zeros(T), np.zeros(T)], 1)  # a turn about X
    path = _write(tmp_path / "tumble.npz", poses, walk.trans, 30.0)
    with pytest.raises(MotionFileError, match="cannot tell the up axis") as e:
        mrlib.load_motion(path)
    assert "\n" not in str(e.value) and "--up-axis" in str(e.value)
    mrlib.load_motion(path, up_axis="y")  # told, it loads


@pytest.mark.skipif(not (BEAT2 / "2_scott_0_1_1.npz").is_file(), reason="no BEAT2 sample here")
def test_the_beat2_sample_loads_upright_with_no_option(body):
    m = mrlib.load_motion(BEAT2 / "2_scott_0_1_1.npz")
    assert m.meta["up_axis"] == "y" and m.meta["dropped_hand_pose"]
    assert m.meta["floor_shift_m"] < -0.1  # SMPL-X's placement floats mrlib's body
    _assert_upright(m, body)


@pytest.mark.parametrize("rig", ["biped_pelvis", "mixamo"])  # Z up in inches; Y up in cm
def test_a_bvh_loads_upright_and_on_the_floor(walk, body, tmp_path, rig):
    import rigs

    from mrlib.io.bvh import write_bvh

    path = write_bvh(tmp_path / f"{rig}.bvh", rigs.write_rig(walk, rigs.RIGS[rig], body))
    _assert_upright(mrlib.load_motion(path, body=body), body)


@pytest.mark.parametrize("up", ["-y", "z"])
def test_an_easymocap_folder_loads_upright_and_on_the_floor(walk, body, tmp_path, up):
    """EasyMocap's world is a camera's frame: its floor is anywhere (here 1.4 m below
    the camera, Y down); the feet are put on y = 0."""
    from test_io_npz import _write_easymocap

    lifted = walk.replace(trans=walk.trans + np.array([0.0, -1.4, 0.0], np.float32))
    _write_easymocap(tmp_path / "cam", lifted.slice(0, 60), body, up=up, extra_person=False)
    m = mrlib.load_motion(tmp_path / "cam", fps=30.0, body=body)
    assert m.meta["up_axis"] == up and m.meta["floor_shift_m"] == pytest.approx(1.4, abs=0.02)
    _assert_upright(m, body)


@pytest.mark.skipif(not (BEAT2 / "2_scott_0_1_1.npz").is_file(), reason="no BEAT2 sample here")
def test_beat2_files_as_they_come_train_a_speech_model(tmp_path, capsys):
    """npz + WAV whose audio runs 0.6 s past the motion, no conversion and no option."""
    from mrlib.app.cli import main

    paired = tmp_path / "paired"
    paired.mkdir()
    for name in ("2_scott_0_1_1.npz", "2_scott_0_1_1.wav"):
        (paired / name).symlink_to(BEAT2 / name)
    assert main(["info", str(paired / "2_scott_0_1_1.npz")]) == 0
    out = capsys.readouterr().out
    assert re.search(r"meta\.up_axis +y\n", out) and "told from the body" in out
    args = ["train-speech", str(paired), "--unpaired", str(BEAT2 / "unpaired"), "--preset",
            "speech_demo", "--iterations", "1", "--out", str(tmp_path / "run"), "--no-progress"]  # fmt: skip
    assert main(args) == 0
    assert (tmp_path / "run" / "checkpoint.pt").is_file()
