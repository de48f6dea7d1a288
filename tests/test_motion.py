import numpy as np
import pytest
import torch

from mrlib.errors import ClipTooShortError, MotionValueError
from mrlib.representation.motion import Motion
from mrlib.representation.rotations import axis_angle_to_matrix, geodesic_distance

rng = np.random.default_rng(0)


def _motion(T=30, fps=30.0):
    return Motion(
        rng.normal(size=(T, 24, 3)) * 0.5, np.cumsum(rng.normal(size=(T, 3)) * 0.01, 0), fps
    )


def test_shapes_and_defaults():
    m = _motion()
    assert m.poses.dtype == np.float32 and m.poses.shape == (30, 24, 3)
    assert m.betas.shape == (10,) and m.contacts is None
    assert len(m) == 30 and m.duration == pytest.approx(1.0)
    # (T, 72) flat poses are accepted too
    assert Motion(m.poses.reshape(30, 72), m.trans, 30).poses.shape == (30, 24, 3)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"poses": np.zeros((5, 23, 3))}, "poses must have shape"),
        ({"trans": np.zeros((4, 3))}, "trans has 4 frames"),
        ({"fps": 0}, r"fps must be a number in \(0, 1000\]"),
        ({"fps": 1e300}, "fps must be a number"),
        ({"fps": float("nan")}, "fps must be a number"),
        ({"trans": np.full((5, 3), 1e30)}, "wrong units"),
        ({"poses": np.zeros((5, 24, 3), complex)}, "real numbers"),
        ({"poses": np.full((5, 24, 3), np.nan)}, "NaN or inf"),
        ({"contacts": np.zeros((5, 5))}, "contacts must have shape"),
    ],
)
def test_bad_input_raises_typed_errors(kwargs, match):
    args = {"poses": np.zeros((5, 24, 3)), "trans": np.zeros((5, 3)), "fps": 30} | kwargs
    with pytest.raises(MotionValueError, match=match):
        Motion(**args)


def test_empty_and_empty_slice():
    with pytest.raises(ClipTooShortError):
        Motion(np.zeros((0, 24, 3)), np.zeros((0, 3)), 30)
    with pytest.raises(ClipTooShortError):
        _motion().slice(10, 10)


@pytest.mark.parametrize(
    "T, fps, want", [(150, 30, 300), (150, 60, 600), (150, 24, 240), (7, 12, 6), (31, 45, 93)]
)
def test_resample_keeping_the_duration(T, fps, want):
    """``keep_duration``: a clip's duration at the new rate (150 frames at 15 fps: 300 at
    30, where the endpoint rule gives 299), the frames up to the last input frame as
    without it, and the ones past it continuing the spline."""
    t = np.arange(T) / 15.0
    poses = np.zeros((T, 24, 3))
    poses[:, 1, 0] = 0.5 * np.sin(2 * np.pi * 0.7 * t)  # one smooth joint angle
    contacts = (np.arange(T)[:, None] + np.arange(6)) % 3 == 0  # labels that change often
    m = Motion(poses, np.stack([t, 0 * t, 0.3 * t], 1), 15.0, contacts=contacts.astype(float))
    plain, kept = m.resample(fps, smooth=True), m.resample(fps, smooth=True, keep_duration=True)
    assert kept.num_frames == want and kept.fps == fps
    assert np.array_equal(kept.poses[: len(plain)], plain.poses)
    assert np.array_equal(kept.contacts[: len(plain)], plain.contacts)
    tk = np.arange(want) / fps  # past the end: the motion continued, no held frame
    assert np.allclose(kept.poses[:, 1, 0], 0.5 * np.sin(2 * np.pi * 0.7 * tk), atol=2e-3)
    assert np.allclose(kept.trans[:, 0], tk, atol=1e-5)
    # slerp (smooth=False) is never asked to reach past the last frame
    assert m.resample(fps, keep_duration=True).num_frames == plain.num_frames


def test_resample_keeps_endpoints_and_is_smooth():
    m = _motion(T=31)
    up = m.resample(60)
    assert up.num_frames == 61 and up.fps == 60
    R = lambda p: axis_angle_to_matrix(torch.from_numpy(p).double())  # noqa: E731
    # every other frame of the upsampled clip is an original frame
    assert geodesic_distance(R(up.poses[::2]), R(m.poses)).max() < 1e-5
    # a midpoint lies between its neighbours on the geodesic
    d_ab = geodesic_distance(R(m.poses[:-1]), R(m.poses[1:]))
    d_am = geodesic_distance(R(m.poses[:-1]), R(up.poses[1::2]))
    assert torch.allclose(d_am, d_ab / 2, atol=1e-4)
    down = m.resample(25)
    assert down.num_frames == 26 and np.allclose(down.trans[0], m.trans[0])
