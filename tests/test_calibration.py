"""Tests for mrlib.evaluation.calibration: the clip played twice, the frozen frame, Bandai names and
their real counterparts, and the calibration rows."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from mrlib.errors import ClipTooShortError, MotionValueError
from mrlib.evaluation import calibration as cal
from mrlib.io.paths import default_data_dir
from mrlib.representation.motion import Motion
from mrlib.representation.rotations import axis_angle_to_matrix

DATA_DIR = default_data_dir()
needs_data = pytest.mark.skipif(
    not (DATA_DIR / "data").is_dir(), reason="Bandai-Namco data not found (MRLIB_DATA_DIR)"
)


def turning_walk(T: int = 60, fps: float = 30.0, yaw_rate: float = 0.8, speed: float = 1.2):
    """A body gliding along a circular arc, facing along it; legs swing (for contacts)."""
    t = np.arange(T) / fps
    yaw = yaw_rate * t
    poses = np.zeros((T, 24, 3), np.float32)
    poses[:, 0, 1] = yaw
    poses[:, 1, 0] = 0.4 * np.sin(2 * np.pi * t)
    poses[:, 2, 0] = -0.4 * np.sin(2 * np.pi * t)
    x = speed / yaw_rate * (1 - np.cos(yaw))  # integral of speed * sin(yaw)
    z = speed / yaw_rate * np.sin(yaw)  # integral of speed * cos(yaw)
    return Motion(poses=poses, trans=np.stack([x, np.full(T, 0.9), z], -1), fps=fps, name="arc")


def test_play_twice_repeats_the_poses_and_continues_the_path():
    m = turning_walk()
    T = m.num_frames
    tw = cal.play_twice(m)
    assert tw.num_frames == 2 * T and tw.name == "arc x2"
    np.testing.assert_array_equal(tw.poses[:T], m.poses)
    np.testing.assert_array_equal(tw.poses[T:, 1:], m.poses[:, 1:])  # body poses unchanged
    np.testing.assert_allclose(tw.trans[T:, 1], m.trans[:, 1])  # heights kept
    # the path continues: the copy's first step and its heading follow on smoothly
    step = np.linalg.norm(np.diff(tw.trans[:, [0, 2]], axis=0), axis=1)
    np.testing.assert_allclose(step, 1.2 / 30, rtol=1e-3)
    yaw = cal._heading(tw.poses[:, 0])
    dyaw = np.diff(np.unwrap(yaw))
    np.testing.assert_allclose(dyaw, 0.8 / 30, atol=1e-5)
    # and lies on the same circle: it is the arc continued for another T frames
    np.testing.assert_allclose(tw.trans, turning_walk(2 * T).trans, atol=1e-5)
    # contact labels are repeated when present
    c = (np.arange(T * 6).reshape(T, 6) % 3 == 0).astype(np.float32)
    np.testing.assert_array_equal(cal.play_twice(m.replace(contacts=c)).contacts, np.r_[c, c])
    with pytest.raises(ClipTooShortError):
        cal.play_twice(m.slice(0, 1))


def test_freeze_first_frame():
    m = turning_walk(20)
    f = cal.freeze_first_frame(m)
    assert f.num_frames == 40 and f.contacts is None
    np.testing.assert_array_equal(f.poses, np.repeat(m.poses[:1], 40, 0))
    np.testing.assert_array_equal(f.trans, np.repeat(m.trans[:1], 40, 0))
    assert cal.freeze_first_frame(m, 7).num_frames == 7
    with pytest.raises(MotionValueError):
        cal.freeze_first_frame(m, 0)


def test_parse_bandai_name():
    assert cal.parse_bandai_name("dataset-1_walk-back_not-confident_002") == {
        "prefix": "dataset-1",
        "content": "walk-back",
        "style": "not-confident",
        "take": "002",
    }
    assert cal.parse_bandai_name("walk_happy_001.bvh")["prefix"] == ""
    assert cal.parse_bandai_name("walk_happy") is None
    assert cal.parse_bandai_name("my clip") is None


def test_find_bandai_counterparts_by_name(tmp_path):
    names = [
        "walk_happy_001", "walk_happy_003", "walk_happy_002", "walk_angry_001",
        "walk_normal_002", "walk_normal_001", "bow_happy_001", "bow_normal_001",
        "run_normal_001",
    ]  # fmt: skip
    (tmp_path / "data").mkdir()
    for n in names:
        (tmp_path / "data" / f"dataset-1_{n}.bvh").touch()
    (tmp_path / "data" / "dataset-2_walk_happy_009.bvh").touch()  # another dataset: ignored
    found = cal.find_bandai_counterparts("dataset-1_walk_happy_001", tmp_path)
    stems = {k: p.stem for k, p in found.items()}
    assert stems == {
        "other take": "dataset-1_walk_happy_002",
        "other style": "dataset-1_walk_normal_001",
        "different content": "dataset-1_bow_normal_001",
    }
    # a bow is compared with a walk; no other take of bow_normal exists
    stems = {
        k: p.stem
        for k, p in cal.find_bandai_counterparts("dataset-1_bow_normal_001", tmp_path).items()
    }
    assert stems == {
        "other style": "dataset-1_bow_happy_001",
        "different content": "dataset-1_walk_normal_001",
    }
    # the normal style falls back to another style, preferring the same take number
    found = cal.find_bandai_counterparts("dataset-1_walk_normal_002", tmp_path / "data")
    assert found["other take"].stem == "dataset-1_walk_normal_001"
    assert found["other style"].stem == "dataset-1_walk_angry_001"  # alphabetical
    assert (
        cal.find_bandai_counterparts(
            "dataset-1_run_normal_001", tmp_path, different_content="walk"
        )["different content"].stem
        == "dataset-1_walk_normal_001"
    )
    assert cal.find_bandai_counterparts("my clip", tmp_path) == {}
    assert cal.find_bandai_counterparts("walk_happy_001", tmp_path / "missing") == {}


def test_calibration_rows_keys_and_lengths():
    m = turning_walk(40)
    other = turning_walk(50, yaw_rate=0.2)
    rows = cal.calibration_rows(m, {"other style": other}, length_factor=1.5)
    assert list(rows) == ["played twice", "frozen first frame", "other style"]
    assert rows["played twice"].num_frames == 80
    assert rows["frozen first frame"].num_frames == 60
    assert rows["other style"] is other
    with pytest.raises(MotionValueError):
        cal.calibration_rows(m, {"x": np.zeros(3)})
    with pytest.raises(MotionValueError):
        cal.calibration_rows(m, length_factor=0)


@needs_data
def test_real_counterparts_of_walk_happy():
    found = cal.find_bandai_counterparts("dataset-1_walk_happy_001", DATA_DIR)
    assert {k: p.stem for k, p in found.items()} == {
        "other take": "dataset-1_walk_happy_002",
        "other style": "dataset-1_walk_normal_001",
        "different content": "dataset-1_bow_normal_001",
    }


def test_heading_of_a_yaw_rotation():
    yaw = np.array([0.0, 0.5, -2.0])
    aa = np.zeros((3, 3))
    aa[:, 1] = yaw
    np.testing.assert_allclose(cal._heading(aa), yaw, atol=1e-12)
    R = axis_angle_to_matrix(torch.from_numpy(aa))
    np.testing.assert_allclose(R[:, :, 2][:, 0].numpy(), np.sin(yaw), atol=1e-12)
