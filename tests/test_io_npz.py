"""Tests for mrlib.io.npz: AMASS-style npz, mrlib's own npz, EasyMocap folders."""

import json

import numpy as np
import pytest
import torch

from mrlib.errors import MotionFileError, UnsupportedFormatError
from mrlib.io import load_motion, save_motion
from mrlib.io.axes import up_axis_rotation
from mrlib.io.bodyfit import default_body
from mrlib.io.npz import BodyModelWarning, load_easymocap, load_npz, save_npz
from mrlib.representation.motion import Motion
from mrlib.representation.rotations import (
    axis_angle_to_matrix,
    geodesic_distance,
    matrix_to_axis_angle,
)


@pytest.fixture(scope="module")
def body():
    return default_body()


def _motion(T=40, seed=0, contacts=False):
    rng = np.random.default_rng(seed)
    poses = rng.normal(size=(T, 24, 3)) * 0.4
    trans = np.cumsum(rng.normal(size=(T, 3)) * 0.02, 0) + [0.1, 0.9, -0.5]
    c = (rng.random((T, 6)) > 0.5).astype(np.float32) if contacts else None
    return Motion(poses, trans, 30.0, betas=rng.normal(size=10) * 0.5, contacts=c)


def _geodesic_max(a, b):
    Ra = axis_angle_to_matrix(torch.from_numpy(np.asarray(a, np.float64)))
    Rb = axis_angle_to_matrix(torch.from_numpy(np.asarray(b, np.float64)))
    return float(geodesic_distance(Ra, Rb).max())


def _to_world(poses_root, trans, J0, A):
    """Re-express Y-up SMPL parameters in a world rotated by A^T (the file's frame)."""
    G = axis_angle_to_matrix(torch.from_numpy(poses_root.astype(np.float64))).numpy()
    G2 = A.T @ G
    t2 = (trans.astype(np.float64) + J0) @ A - J0  # A^T (J0 + trans) - J0, row vectors
    return matrix_to_axis_angle(torch.from_numpy(G2)).numpy(), t2


def test_mrlib_npz_round_trip(tmp_path):
    m = _motion(contacts=True).replace(
        label="walk_happy", name="clip", meta={"source": "x", "err": 1.5}
    )
    path = save_motion(m, tmp_path / "clip.npz")
    with np.load(path) as z:
        assert z["poses"].shape == (40, 72) and str(z["up_axis"]) == "y"
        assert float(z["mocap_framerate"]) == 30.0
    back = load_motion(path)
    np.testing.assert_array_equal(back.poses, m.poses)
    np.testing.assert_array_equal(back.trans, m.trans)
    np.testing.assert_array_equal(back.betas, m.betas)
    np.testing.assert_array_equal(back.contacts, m.contacts)
    assert back.label == "walk_happy" and back.name == "clip" and back.fps == 30.0
    assert back.meta["err"] == 1.5 and back.meta["up_axis"] == "y"


def test_save_npz_keeps_other_suffixes(tmp_path):
    path = save_npz(_motion(T=3), tmp_path / "x.motion")
    assert path.exists() and not (tmp_path / "x.motion.npz").exists()
    assert load_npz(path).num_frames == 3


def test_amass_smplh_z_up(tmp_path, body):
    """An AMASS-style SMPL-H file in Z-up is truncated to 22 joints and rotated to Y-up
    so that every joint lands where the Z-up body had it, rotated."""
    m = _motion(T=20, seed=1)
    J0 = body.rest_joints(torch.tensor(m.betas)).double().numpy()[0]
    A = up_axis_rotation("z")
    root_z, trans_z = _to_world(m.poses[:, 0], m.trans, J0, A)
    rng = np.random.default_rng(2)
    poses156 = np.concatenate(
        [root_z, m.poses[:, 1:22].reshape(20, -1), rng.normal(size=(20, 90))], 1
    )
    betas16 = np.concatenate([m.betas, rng.normal(size=6)])
    np.savez(tmp_path / "amass.npz", poses=poses156, trans=trans_z, betas=betas16,
             mocap_framerate=np.array(60.0), gender=np.array("male"))  # fmt: skip
    with pytest.warns(BodyModelWarning, match="made for the male SMPL body"):
        back = load_motion(tmp_path / "amass.npz", body=body)
    assert back.meta["source_gender"] == "male"  # read on the neutral body, said so
    assert back.fps == 60.0 and back.meta["up_axis"] == "z" and back.meta["dropped_hand_pose"]
    np.testing.assert_allclose(back.betas, m.betas, atol=1e-6)  # first 10 of 16
    assert np.all(back.poses[:, 22:] == 0)  # SMPL's hand joints: no SMPL-H counterpart
    assert _geodesic_max(back.poses[:, :22], m.poses[:, :22]) < 1e-5
    np.testing.assert_allclose(back.trans, m.trans, atol=1e-5)
    # independent check: joints of the loaded motion == A @ joints of the Z-up parameters
    zup = Motion(
        np.concatenate([root_z[:, None], back.poses[:, 1:]], 1), trans_z, 60, betas=m.betas
    )
    np.testing.assert_allclose(body.motion_joints(back), body.motion_joints(zup) @ A.T, atol=1e-5)


def test_amass_smpl_frame_rate_key_and_resampling(tmp_path):
    m = _motion(T=61)
    np.savez(tmp_path / "a.npz", poses=m.poses.reshape(61, 72), trans=m.trans,
             mocap_frame_rate=np.array(60.0), up_axis=np.array("y"))  # fmt: skip
    assert load_motion(tmp_path / "a.npz").fps == 60.0
    half = load_motion(tmp_path / "a.npz", fps=30)
    assert half.fps == 30.0 and half.num_frames == 31
    np.testing.assert_allclose(half.trans, m.trans[::2], atol=1e-6)
    # an explicit up axis overrides the file's
    assert load_npz(tmp_path / "a.npz", up_axis="-z").meta["up_axis"] == "-z"


def test_missing_frame_rate_needs_fps(tmp_path):
    m = _motion(T=5)
    np.savez(tmp_path / "nofps.npz", poses=m.poses.reshape(5, 72), trans=m.trans)
    with pytest.raises(MotionFileError, match="mocap_framerate"):
        load_motion(tmp_path / "nofps.npz")
    got = load_motion(tmp_path / "nofps.npz", fps=25)
    assert got.fps == 25 and got.num_frames == 5


@pytest.mark.parametrize(
    "arrays, match",
    [
        ({"trans": None}, "missing key 'poses'"),
        ({"poses": np.zeros((5, 72))}, "missing key 'trans'"),
        ({"poses": np.zeros((5, 50)), "trans": np.zeros((5, 3))}, r"'poses' has shape \(5, 50\)"),
        (
            {"poses": np.zeros((5, 72)), "trans": np.zeros((4, 3))},
            r"'trans' must have shape \(5, 3\)",
        ),
        ({"poses": np.full((5, 72), np.nan), "trans": np.zeros((5, 3))}, "'poses' has NaN"),
        (
            {"poses": np.zeros((5, 72)), "trans": np.zeros((5, 3)), "betas": [np.inf]},
            "'betas' has NaN",
        ),
        (
            {"poses": np.zeros((5, 72)), "trans": np.zeros((5, 3)), "contacts": np.zeros((5, 2))},
            "'contacts'",
        ),
        (
            {"poses": np.zeros((5, 72)), "trans": np.zeros((5, 3)), "mocap_framerate": -1.0},
            "positive",
        ),
        ({"poses": np.zeros((5, 72)), "trans": np.zeros((5, 3)), "up_axis": "w"}, "up axis"),
        ({"poses": np.zeros((0, 72)), "trans": np.zeros((0, 3))}, "no frames"),
    ],
)
def test_bad_npz_names_the_key(tmp_path, arrays, match):
    data = {"mocap_framerate": 30.0} | {k: v for k, v in arrays.items() if v is not None}
    path = tmp_path / "bad.npz"
    np.savez(path, **data)
    with pytest.raises(MotionFileError, match=match) as info:
        load_motion(path, body=default_body())
    assert str(path) in str(info.value)


def test_not_an_npz(tmp_path):
    (tmp_path / "junk.npz").write_text("hello")  # not numpy's advice about pickles
    with pytest.raises(MotionFileError, match=r"is not an .npz archive \(neither a zip"):
        load_motion(tmp_path / "junk.npz")
    (tmp_path / "empty.npz").write_bytes(b"")
    with pytest.raises(MotionFileError, match="empty.npz: is empty"):
        load_motion(tmp_path / "empty.npz")
    with pytest.raises(UnsupportedFormatError):
        load_motion(tmp_path / "clip.pkl")


# -- EasyMocap ---------------------------------------------------------------------------------
def _write_easymocap(folder, m, body, up="-y", pose_width=72, extra_person=True):
    """Frames of ``m`` as EasyMocap writes them, in a world whose up is ``up``."""
    folder.mkdir()
    J0 = body.rest_joints(torch.tensor(m.betas)).double().numpy()[0]
    A = up_axis_rotation(up)
    G = A.T @ axis_angle_to_matrix(torch.from_numpy(m.poses[:, 0].astype(np.float64))).numpy()
    Rh = matrix_to_axis_angle(torch.from_numpy(G)).numpy()
    pelvis = (m.trans.astype(np.float64) + J0) @ A  # A^T (J0 + trans)
    Th = pelvis - G @ J0  # world pelvis = R(Rh) J0 + Th
    for t in range(m.num_frames):
        pose = np.concatenate([np.zeros(3), m.poses[t, 1:].reshape(-1)])[72 - pose_width :]
        people = [{"id": 0, "Rh": [Rh[t].tolist()], "Th": [Th[t].tolist()],
                   "poses": [pose.tolist()], "shapes": [m.betas.tolist()]}]  # fmt: skip
        if extra_person:
            people.insert(0, {"id": 1, "Rh": [[0, 0, 0]], "Th": [[1, 0, 0]],
                              "poses": [[0.0] * 72], "shapes": [[0.0] * 10]})  # fmt: skip
        (folder / f"{t:06d}.json").write_text(json.dumps(people))


@pytest.mark.parametrize("up, width", [("-y", 72), ("z", 69)])
def test_easymocap_folder(tmp_path, body, up, width):
    m = _motion(T=12, seed=3)
    m = m.replace(poses=m.poses * 0.5)
    _write_easymocap(tmp_path / "smpl", m, body, up=up, pose_width=width)
    back = load_motion(tmp_path / "smpl", fps=30, body=body)
    assert back.meta["format"] == "easymocap" and back.meta["up_axis"] == up
    assert back.num_frames == 12 and back.fps == 30 and back.name == "smpl"
    assert _geodesic_max(back.poses, m.poses) < 1e-5
    np.testing.assert_allclose(back.trans, m.trans, atol=1e-5)
    np.testing.assert_allclose(back.betas, m.betas, atol=1e-6)
    # the up axis can be given; a wrong one rotates the clip
    wrong = load_easymocap(tmp_path / "smpl", 30, up_axis="y", body=body)
    assert _geodesic_max(wrong.poses[:, :1], m.poses[:, :1]) > 0.5
    other = load_motion(tmp_path / "smpl", fps=30, person=1, body=body)
    np.testing.assert_allclose(other.poses, 0, atol=1e-6)


def test_easymocap_errors(tmp_path, body):
    m = _motion(T=3, seed=4)
    _write_easymocap(tmp_path / "ok", m, body, extra_person=False)
    with pytest.raises(MotionFileError, match="fps"):
        load_motion(tmp_path / "ok")
    with pytest.raises(MotionFileError, match="no person with id 2"):
        load_motion(tmp_path / "ok", fps=30, person=2)
    frame = tmp_path / "ok" / "000001.json"
    people = json.loads(frame.read_text())
    del people[0]["Th"]
    frame.write_text(json.dumps(people))
    with pytest.raises(MotionFileError, match="missing key 'Th'") as info:
        load_motion(tmp_path / "ok", fps=30)
    assert "000001.json" in str(info.value)
    people[0]["Th"] = [[0, float("nan"), 0]]
    frame.write_text(json.dumps(people))
    with pytest.raises(MotionFileError, match="'Th' has NaN"):
        load_motion(tmp_path / "ok", fps=30)
    (tmp_path / "empty").mkdir()
    with pytest.raises(MotionFileError, match="no \\*.json"):
        load_motion(tmp_path / "empty", fps=30)


def test_other_tools_pose_layouts_read_as_amass(tmp_path):
    """``poses (T, 24, 3)`` and the smplx package's ``global_orient`` / ``body_pose`` /
    ``transl`` (SMPL 69, SMPL-X 63 wide, also as (T, J, 3)) give the same motion as
    AMASS's ``poses (T, 72)``; the SMPL-X body drops SMPL's hand joints, saying so."""
    m = _motion(T=12, seed=3)
    common = {"mocap_framerate": 30.0, "up_axis": "y"}
    np.savez(tmp_path / "amass.npz", poses=m.poses.reshape(12, 72), trans=m.trans, **common)
    np.savez(tmp_path / "j3.npz", poses=m.poses, trans=m.trans, **common)
    np.savez(tmp_path / "smpl.npz", global_orient=m.poses[:, 0], body_pose=m.poses[:, 1:],
             transl=m.trans, **common)  # fmt: skip
    np.savez(tmp_path / "smplx.npz", global_orient=m.poses[:, :1],
             body_pose=m.poses[:, 1:22].reshape(12, 63), transl=m.trans[:, None], **common)  # fmt: skip
    ref = load_motion(tmp_path / "amass.npz")
    for name in ("j3", "smpl"):
        got = load_motion(tmp_path / f"{name}.npz")
        np.testing.assert_array_equal(got.poses, ref.poses)
        np.testing.assert_array_equal(got.trans, ref.trans)
    x = load_motion(tmp_path / "smplx.npz")
    assert x.meta["dropped_hand_pose"] and np.all(x.poses[:, 22:] == 0)
    np.testing.assert_array_equal(x.poses[:, :22], ref.poses[:, :22])


@pytest.mark.parametrize(
    "arrays, match",
    [
        ({"poses": np.tile(np.eye(3), (5, 24, 1, 1))}, "rotation matrices"),
        ({"poses": np.full((5, 72), 30.0)}, "degrees, not radians"),
        ({"poses": np.zeros((5, 72)), "trans": np.full((5, 3), 1500.0)}, "centimetres"),
        ({"global_orient": np.zeros((5, 3))}, "not the other"),
        ({"global_orient": np.zeros((5, 3)), "body_pose": np.zeros((5, 60))}, r"\(T, 69\)"),
    ],
)
def test_degrees_matrices_and_centimetres_are_named(tmp_path, arrays, match):
    data = {"mocap_framerate": 30.0, "trans": np.zeros((5, 3)), "up_axis": "y"} | arrays
    np.savez(tmp_path / "x.npz", **data)
    with pytest.raises(MotionFileError, match=match):
        load_motion(tmp_path / "x.npz")


def test_rate_keys_that_disagree_are_warned_about_and_bytes_read_as_text(tmp_path):
    m = _motion(T=5)
    np.savez(tmp_path / "x.npz", poses=m.poses.reshape(5, 72), trans=m.trans,
             mocap_framerate=30.0, mocap_frame_rate=60.0, gender=np.bytes_(b"female"),
             up_axis=np.bytes_(b"y"))  # fmt: skip
    with pytest.warns(UserWarning) as seen:
        got = load_motion(tmp_path / "x.npz")
    said = " ".join(str(w.message) for w in seen)
    assert got.fps == 30.0 and "'mocap_frame_rate' 60" in said
    assert "the female SMPL body" in said and "b'" not in said
