"""Tests for mrlib.io.bvh: parser, Euler angles, forward kinematics, writer."""

from pathlib import Path

import numpy as np
import pytest

from mrlib.errors import BVHFormatError, MotionFileError
from mrlib.io.bvh import (
    bvh_forward_kinematics,
    bvh_local_transforms,
    euler_to_matrix,
    format_bvh,
    forward_kinematics,
    matrix_to_euler,
    parse_bvh,
    read_bvh,
    write_bvh,
)
from mrlib.io.bvh.kinematics import _forward_kinematics_naive

# A root with 6 channels in ZXY order, a joint with 3 rotation channels in XYZ order and
# one with a channel subset (only Yrotation) - plus End Sites.
SMALL = """HIERARCHY
ROOT Hips
{
\tOFFSET 0 0 0
\tCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
\tJOINT Spine
\t{
\t\tOFFSET 0 10 0
\t\tCHANNELS 3 Xrotation Yrotation Zrotation
\t\tEnd Site
\t\t{
\t\t\tOFFSET 0 5 0
\t\t}
\t}
\tJOINT Leg {
\t\tOFFSET 2 -1 0
\t\tCHANNELS 1 Yrotation
\t\tEnd Site { OFFSET 0 -8 0 }
\t}
}
MOTION
Frames: 2
Frame Time: 0.04
1 2 3 0 0 0 0 0 0 0
0 100 0 90 0 0 0 0 90 45
"""


def test_parse_small():
    b = parse_bvh(SMALL)
    sk = b.skeleton
    assert sk.names == ("Hips", "Spine", "Leg")
    assert sk.parents == (-1, 0, 0)
    assert sk.channels[1] == ("Xrotation", "Yrotation", "Zrotation")
    assert sk.channels[2] == ("Yrotation",)
    assert sk.num_channels == 10
    np.testing.assert_array_equal(sk.channel_starts(), [0, 6, 9])
    assert [j for j, _ in sk.end_sites] == [1, 2]
    np.testing.assert_allclose(sk.end_sites[1][1], [0, -8, 0])
    assert b.motion.shape == (2, 10) and b.fps == pytest.approx(25.0)


def test_fk_hand_computed():
    b = parse_bvh(SMALL)
    g, p = bvh_forward_kinematics(b)
    # frame 0: no rotation, root at (1, 2, 3)
    np.testing.assert_allclose(p[0], [[1, 2, 3], [1, 12, 3], [3, 1, 3]], atol=1e-12)
    # frame 1: root at (0,100,0) rotated 90 deg about Z: local +Y -> world -X, +X -> +Y.
    np.testing.assert_allclose(p[1, 1], [-10, 100, 0], atol=1e-9)
    np.testing.assert_allclose(p[1, 2], [1, 102, 0], atol=1e-9)  # offset (2,-1,0) -> (1,2,0)
    # Spine: Xrot 0, Yrot 0, Zrot 90 -> global = Rz(90) @ Rz(90) = Rz(180)
    Rz = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])
    np.testing.assert_allclose(g[1, 1], np.diag([-1.0, -1, 1]), atol=1e-12)
    # Leg has a single Yrotation channel (45 deg)
    r = np.deg2rad(45)
    Ry45 = np.array([[np.cos(r), 0, np.sin(r)], [0, 1, 0], [-np.sin(r), 0, np.cos(r)]])
    np.testing.assert_allclose(g[1, 2], Rz @ Ry45, atol=1e-12)


def test_position_channels_replace_offset():
    text = SMALL.replace("CHANNELS 1 Yrotation", "CHANNELS 2 Yrotation Xposition")
    text = text.replace("0 0 0 0 0 0 0\n", "0 0 0 0 0 0 0 7\n", 1)
    text = text.replace("0 90 45\n", "0 90 45 2\n")
    rot, trans = bvh_local_transforms(parse_bvh(text))
    np.testing.assert_allclose(trans[0, 2], [7, -1, 0])  # X replaced, Y and Z kept
    np.testing.assert_allclose(trans[:, 1], [[0, 10, 0]] * 2)


@pytest.mark.parametrize("order", ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"])
def test_euler_round_trip(order):
    rng = np.random.default_rng(1)
    ang = rng.uniform(-180, 180, size=(500, 3))
    ang[:5, 1] = [90, -90, 89.9999999, -90, 90]  # gimbal lock
    R = euler_to_matrix(ang, order)
    np.testing.assert_allclose(
        R @ np.swapaxes(R, -1, -2), np.broadcast_to(np.eye(3), R.shape), atol=1e-12
    )
    back = matrix_to_euler(R, order)
    assert np.all(np.abs(back[:, 1]) <= 90 + 1e-9)
    np.testing.assert_allclose(euler_to_matrix(back, order), R, atol=1e-10)


def test_euler_composition_order():
    # "ZX" means Rz @ Rx: rotate X first in the child's frame
    R = euler_to_matrix(np.array([90.0, 90.0]), "ZX")
    np.testing.assert_allclose(R @ [0, 1, 0], [0, 0, 1], atol=1e-12)  # Rx: y->z, Rz keeps z
    np.testing.assert_allclose(R @ [0, 0, 1], [1, 0, 0], atol=1e-12)  # Rx: z->-y, Rz: -y->x


def test_fk_matches_naive():
    rng = np.random.default_rng(2)
    parents = (-1, 0, 1, 1, 0, 4)
    rot = euler_to_matrix(rng.uniform(-180, 180, (7, 6, 3)), "ZXY")
    trans = rng.normal(size=(7, 6, 3))
    g, p = forward_kinematics(parents, rot, trans)
    g0, p0 = _forward_kinematics_naive(parents, rot, trans)
    np.testing.assert_allclose(g, g0, atol=1e-12)
    np.testing.assert_allclose(p, p0, atol=1e-12)


def test_write_read_round_trip(tmp_path):
    b = parse_bvh(SMALL)
    path = write_bvh(tmp_path / "x.bvh", b)
    b2 = read_bvh(path)
    assert b2.skeleton.names == b.skeleton.names and b2.skeleton.channels == b.skeleton.channels
    np.testing.assert_allclose(b2.motion, b.motion, atol=1e-6)
    np.testing.assert_allclose(b2.skeleton.offsets, b.skeleton.offsets)
    assert b2.frame_time == pytest.approx(b.frame_time)
    assert format_bvh(b2) == format_bvh(b)


def _lines(text):
    return text.splitlines()


@pytest.mark.parametrize(
    "mutate, line, match",
    [
        # truncated inside the hierarchy
        (lambda t: "\n".join(_lines(t)[:9]), 9, "truncated hierarchy"),
        # truncated frame data
        (
            lambda t: "\n".join(_lines(t)[:-1]),
            22,  # the line that declares the frames; where the file ends is said after
            r"'Frames: 2' but the file ends at line 24 after 1 frame lines \(truncated",
        ),
        # more frame lines than declared
        (lambda t: t + "0 0 0 0 0 0 0 0 0 0\n", 26, "more frame lines than declared"),
        # wrong number of values on a frame line
        (
            lambda t: t.replace("1 2 3 0 0 0 0 0 0 0", "1 2 3 0 0 0 0 0 0"),
            24,
            "expected 10 values in frame 1.*got 9",
        ),
        # a non-numeric value
        (lambda t: t.replace("0 100 0 90", "0 abc 0 90"), 25, "value 2 is not a number: 'abc'"),
        # NaN in the frames
        (lambda t: t.replace("0 100 0 90", "0 nan 0 90"), 25, "value 2 is not finite"),
        # misspelt keyword
        (
            lambda t: t.replace("\tOFFSET 0 10 0", "\tOFSET 0 10 0"),
            8,
            "expected 'OFFSET', got 'OFSET'",
        ),
        # unknown channel name
        (
            lambda t: t.replace("Xrotation Yrotation Zrotation", "Xrotation Yrotation Wrotation"),
            9,
            "channel name",
        ),
        # non-numeric offset
        (lambda t: t.replace("OFFSET 2 -1 0", "OFFSET 2 x 0"), 16, "expected a number for OFFSET"),
        # missing MOTION section
        (lambda t: t[: t.index("MOTION")], 20, "expected a 'MOTION' section"),
        # bad Frames header
        (lambda t: t.replace("Frames: 2", "Frame: 2"), 22, "expected 'Frames: <number>'"),
        (lambda t: t.replace("Frame Time: 0.04", "Frame Time: 0"), 23, "must be seconds per frame"),
        (lambda t: t.replace("Frame Time: 0.04", "Frame Time: 1e-300"), 23, "between 0.001"),
        (lambda t: t.replace("Frame Time: 0.04", "Frame Time: 1e300"), 23, "and 100"),
        # no HIERARCHY keyword
        (lambda t: t.replace("HIERARCHY", "HIERARCHIE"), 1, "expected 'HIERARCHY'"),
        (lambda t: "", 1, "empty"),
    ],
)
def test_malformed_raises_with_line(mutate, line, match):
    with pytest.raises(BVHFormatError, match=match) as info:
        parse_bvh(mutate(SMALL), source="bad.bvh")
    msg = str(info.value)
    assert msg.startswith("bad.bvh: ") and f"line {line}:" in msg, msg
    assert isinstance(info.value, MotionFileError)


def test_missing_file_is_typed(tmp_path):
    with pytest.raises(BVHFormatError, match="cannot read"):
        read_bvh(tmp_path / "nope.bvh")


def test_writer_reorders_joints_depth_first():
    # joints stored breadth first (as SMPL orders them): the text must still pair each
    # joint with its own frame values
    from mrlib.io.bvh import BVH, BVHSkeleton

    names = ("root", "a", "b", "a1", "b1")
    parents = (-1, 0, 0, 1, 2)
    offsets = np.array([[0, 0, 0], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0]], float)
    ch = (("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation"),)
    ch += (("Zrotation", "Xrotation", "Yrotation"),) * 4
    rng = np.random.default_rng(0)
    motion = rng.uniform(-90, 90, size=(3, 18))
    b = BVH(BVHSkeleton(names, parents, offsets, ch), motion, 0.1)
    b2 = parse_bvh(format_bvh(b))
    assert b2.skeleton.names == ("root", "a", "a1", "b", "b1")
    _, p = bvh_forward_kinematics(b)
    _, p2 = bvh_forward_kinematics(b2)
    np.testing.assert_allclose(p2[:, [0, 1, 3, 2, 4]], p, atol=1e-5)


def test_a_reference_pose_before_the_motion_is_left_out(tmp_path):
    """Exporters such as Axis Neuron write a zero pose at the origin as frame 1; the
    motion starts at frame 2. That frame is left out, with a warning; a clip that leaves
    the zero pose smoothly keeps it."""
    import warnings

    from mrlib.io import load_bvh, load_motion, save_motion
    from mrlib.io.bvh import BVH, ReferenceFrameWarning

    walk = load_motion(Path(__file__).resolve().parents[1] / "data_samples" / "walk_sad.npz")
    plain = save_motion(walk, tmp_path / "walk.bvh")
    b = read_bvh(plain)
    ref = BVH(b.skeleton, np.concatenate([np.zeros_like(b.motion[:1]), b.motion]), b.frame_time)
    write_bvh(tmp_path / "ref.bvh", ref)
    with pytest.warns(ReferenceFrameWarning, match="frame 1 is a reference pose"):
        got = load_bvh(tmp_path / "ref.bvh")
    want = load_bvh(plain)
    assert got.num_frames == want.num_frames == walk.num_frames
    assert got.meta["bvh_reference_frame_left_out"] is True
    np.testing.assert_allclose(got.poses, want.poses, atol=1e-5)
    # the same zero pose easing into the motion over a second is motion: kept
    ease = np.linspace(0.0, 1.0, 31)[:, None] * b.motion[:1]
    smooth = BVH(b.skeleton, np.concatenate([ease, b.motion[1:]]), b.frame_time)
    write_bvh(tmp_path / "smooth.bvh", smooth)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ReferenceFrameWarning)
        kept = load_bvh(tmp_path / "smooth.bvh")
    assert kept.num_frames == len(smooth.motion)
    assert "bvh_reference_frame_left_out" not in kept.meta


def _walk_bvh(tmp_path, body=None):
    """A synthetic walk written as an SMPL-named BVH in centimetres: (path, its text)."""
    from mrlib.datasets.synthetic import synthetic_walk
    from mrlib.io import save_motion

    walk = synthetic_walk("walk_normal", seconds=2.0, fps=30.0, body=body)
    path = save_motion(walk, tmp_path / "walk.bvh", body=body, bvh_unit="cm")
    return path, path.read_text()


def test_byte_order_mark_crlf_and_decimal_commas_are_read(tmp_path):
    from mrlib.io import load_motion

    path, text = _walk_bvh(tmp_path)
    ref = load_motion(path)
    head, motion = text.split("MOTION\n")
    variants = {
        "bom_crlf": "\ufeff" + text.replace("\n", "\r\n"),
        "comma": head + "MOTION\n" + motion.replace(".", ","),  # a locale's decimal comma
    }
    for name, t in variants.items():
        (tmp_path / f"{name}.bvh").write_text(t, encoding="utf-8", newline="")
        got = load_motion(tmp_path / f"{name}.bvh")
        assert got.fps == ref.fps and got.num_frames == ref.num_frames, name
        np.testing.assert_allclose(got.poses, ref.poses, atol=1e-6, err_msg=name)
        np.testing.assert_allclose(got.trans, ref.trans, atol=1e-6, err_msg=name)


def test_a_root_without_position_channels_stands_on_the_floor(tmp_path):
    """Its height is only its OFFSET (0 here): the body is put with its feet on y = 0 as
    an npz without an up axis is, not 0.9 m below the floor; with position channels the
    file's height is kept."""
    from mrlib.io import load_motion
    from mrlib.io.placement import stance

    path, text = _walk_bvh(tmp_path)
    lines, out, in_motion = text.splitlines(), [], False
    for i, ln in enumerate(lines):
        if ln.strip().startswith("CHANNELS 6") and not out[-2].strip().startswith("JOINT"):
            ln = ln.replace("CHANNELS 6 Xposition Yposition Zposition", "CHANNELS 3")
            out[-1] = out[-1].split("OFFSET")[0] + "OFFSET 0 0 0"
        if in_motion and i > lines.index("MOTION") + 2:
            ln = " ".join(ln.split()[3:])
        in_motion = in_motion or ln == "MOTION"
        out.append(ln)
    (tmp_path / "no_root_position.bvh").write_text("\n".join(out) + "\n")
    ref = load_motion(path)
    got = load_motion(tmp_path / "no_root_position.bvh")
    assert "floor_shift_m" in got.meta and "floor_shift_m" not in ref.meta
    assert got.meta["floor_shift_m"] > 0.5  # lifted from below the floor
    assert stance(got)["floor_cm"] < 1.0
    np.testing.assert_allclose(got.poses, ref.poses, atol=1e-5)


def test_a_guessed_unit_that_makes_an_odd_sized_person_is_warned_about(tmp_path):
    """A 0.55-scale person written in centimetres is nearer an adult in inches: read so,
    with a warning naming the unit and the size; given the unit, read right, no warning."""
    import dataclasses
    import warnings

    from mrlib.io import load_motion
    from mrlib.io.bvh import read_bvh
    from mrlib.io.bvh.writer import write_bvh
    from mrlib.io.retarget_report import RetargetWarning

    path, _ = _walk_bvh(tmp_path)
    bvh = read_bvh(path)
    small = dataclasses.replace(bvh.skeleton, offsets=bvh.skeleton.offsets * 0.55)
    motion = bvh.motion.copy()
    motion[:, :3] *= 0.55  # the root's position channels come first
    write_bvh(tmp_path / "child.bvh", dataclasses.replace(bvh, skeleton=small, motion=motion))
    with pytest.warns(RetargetWarning, match=r"unit 'inch'.*1\.\d\dx the size.*--unit"):
        guessed = load_motion(tmp_path / "child.bvh")
    assert guessed.meta["unit_m"] == pytest.approx(0.0254)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RetargetWarning)
        given = load_motion(tmp_path / "child.bvh", unit="cm")
    assert given.meta["unit_m"] == 0.01
    with warnings.catch_warnings():
        warnings.simplefilter("error", RetargetWarning)
        assert load_motion(path).meta["retarget_source_size"] == pytest.approx(1.0, abs=0.1)
