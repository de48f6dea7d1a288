import numpy as np
import pytest
import torch

from mrlib.errors import MotionValueError
from mrlib.representation.features import (
    CONTACT_SLICE,
    NUM_FEATURES,
    ROOT_SLICE,
    FeatureNormalizer,
    channel_joint,
    feature_layout,
    features_to_motion,
    motion_to_features,
    root_velocity_to_trans,
)
from mrlib.representation.motion import Motion
from mrlib.representation.rotations import axis_angle_to_matrix, geodesic_distance

rng = np.random.default_rng(1)


def _motion(T=50):
    poses = rng.normal(size=(T, 24, 3)) * 1.2
    trans = np.cumsum(rng.normal(size=(T, 3)) * 0.03, 0) + [0.3, 0.9, -1.0]
    return Motion(poses, trans, 30, contacts=rng.random((T, 6)) > 0.5)


def test_layout_covers_every_channel_once():
    rows = feature_layout()
    covered = np.zeros(NUM_FEATURES, int)
    for _, a, b in rows:
        covered[a:b] += 1
    assert NUM_FEATURES == 24 * 6 + 3 + 6 == 153 and (covered == 1).all()
    assert channel_joint().shape == (NUM_FEATURES,)


def test_round_trip_is_exact():
    m = _motion()
    x = motion_to_features(m)
    assert x.shape == (50, NUM_FEATURES) and x.dtype == torch.float32
    back = features_to_motion(x, m.fps, origin=m.trans[0, [0, 2]], betas=m.betas)
    R = lambda p: axis_angle_to_matrix(torch.from_numpy(p).double())  # noqa: E731
    assert geodesic_distance(R(back.poses), R(m.poses)).max() < 1e-5
    assert np.abs(back.trans - m.trans).max() < 1e-5
    assert (back.contacts == m.contacts).all()


def test_root_velocity_is_metres_per_second():
    T = 10
    trans = np.stack([np.arange(T) * 0.05, np.full(T, 0.9), np.zeros(T)], -1)  # 1.5 m/s at 30 fps
    m = Motion(np.zeros((T, 24, 3)), trans, 30, contacts=np.zeros((T, 6)))
    root = motion_to_features(m)[:, ROOT_SLICE]
    assert torch.allclose(root[:, 0], torch.full((T,), 1.5)) and torch.allclose(
        root[:, 1], torch.full((T,), 0.9)
    )
    # integration is differentiable
    r = root.clone().requires_grad_()
    root_velocity_to_trans(r, 30.0).sum().backward()
    assert r.grad is not None


def test_normalizer_round_trip_and_leaves_contacts():
    xs = [motion_to_features(_motion(40)) for _ in range(3)]
    norm = FeatureNormalizer.fit(xs)
    y = norm.normalize(xs[0])
    assert torch.allclose(norm.denormalize(y), xs[0], atol=1e-5)
    assert torch.equal(y[:, CONTACT_SLICE], xs[0][:, CONTACT_SLICE])
    allroot = torch.cat([norm.normalize(x) for x in xs])[:, ROOT_SLICE]
    assert allroot.mean(0).abs().max() < 1e-4
    again = FeatureNormalizer.from_state_dict(norm.state_dict())
    assert torch.equal(again.mean, norm.mean)


def test_bad_feature_shapes():
    with pytest.raises(MotionValueError, match="153"):
        features_to_motion(torch.zeros(10, 150), 30)
    with pytest.raises(MotionValueError, match="NaN"):
        features_to_motion(torch.full((10, 153), float("nan")), 30)
