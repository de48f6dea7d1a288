import math

import numpy as np
import pytest
import torch

from mrlib.model.losses import (
    backward_velocity,
    body_kinematics,
    contact_consistency_loss,
    contact_sigmoid,
    critic_loss,
    generator_adversarial_loss,
    gradient_penalty,
    interior_mask,
    mask_weights,
    reconstruction_loss,
    smoothness_loss,
    weighted_mean,
)
from mrlib.representation.body import load_body_model
from mrlib.representation.features import FeatureNormalizer, motion_to_features
from mrlib.representation.motion import Motion
from mrlib.representation.rotations import axis_angle_to_matrix

g = torch.Generator().manual_seed(0)


@pytest.fixture(scope="module")
def body():
    return load_body_model()


def test_mask_weights_weigh_clips_equally():
    x = torch.tensor([[1.0, 1.0, 9.0], [3.0, 3.0, 3.0]])
    mask = torch.tensor([[True, True, False], [True, True, True]])
    w = mask_weights(mask)
    assert w.sum() == pytest.approx(1.0)
    assert weighted_mean(x, w) == pytest.approx(2.0)  # (1 + 3) / 2, padding ignored


def test_interior_mask():
    m = torch.tensor([[True, True, True, True, False]])
    assert interior_mask(m).tolist() == [[False, True, True, False, False]]
    assert interior_mask(m, 1, 0).tolist() == [[False, True, True, True, False]]


def test_contact_sigmoid_is_the_papers():
    c = torch.tensor([0.0, 0.5, 1.0])
    ref = 1 / (1 + torch.exp(5 - 10 * c))
    assert torch.allclose(contact_sigmoid(c), ref)
    assert contact_sigmoid(c)[1] == pytest.approx(0.5)


def test_contact_consistency_by_hand():
    v = torch.zeros(1, 3, 6, 3)
    v[0, 1, 0] = torch.tensor([3.0, 0.0, 4.0])  # 5 m/s, |v|^2 = 25
    c = torch.zeros(1, 3, 6)
    c[0, 1, 0] = 1.0
    w = mask_weights(torch.tensor([[False, True, True]]))
    expect = 25 * (1 / (1 + math.exp(-5))) / (2 * 6)  # mean over 2 valid frames x 6 vertices
    assert contact_consistency_loss(v, c, w).item() == pytest.approx(expect, rel=1e-6)
    c[0, 1, 0] = 0.0  # labelled not in contact: almost free
    assert contact_consistency_loss(v, c, w).item() < 0.01 * expect


def test_smoothness_zero_for_constant_velocity_and_by_hand():
    t = torch.arange(10.0)
    p = torch.zeros(1, 10, 24, 3)
    p[..., 0] = 0.1 * t[None, :, None]  # every joint moves at constant speed
    inner = lambda m: mask_weights(interior_mask(m))  # noqa: E731
    assert smoothness_loss(p, inner(torch.ones(1, 10, dtype=torch.bool))).item() == pytest.approx(
        0.0, abs=1e-7
    )
    q = torch.zeros(1, 5, 24, 3)
    q[0, 2, :, 1] = 0.3  # one frame pops up by 30 cm on all joints
    # frame 2: |0.3 - 0.1| = 0.2 per joint; frames 1, 3: 0.1 per joint; norm over 24 joints
    expect = (0.2 + 0.1 + 0.1) * math.sqrt(24) / 3
    assert smoothness_loss(q, inner(torch.ones(1, 5, dtype=torch.bool))).item() == pytest.approx(
        expect, rel=1e-5
    )
    # padding: a short sample's last valid frame (2) has no successor; only frame 1 is scored
    m = torch.tensor([[True, True, True, False, False]])
    assert smoothness_loss(q, inner(m)).item() == pytest.approx(0.1 * math.sqrt(24), rel=1e-5)


def test_reconstruction_is_masked_l1():
    a = torch.zeros(2, 3, 4)
    b = torch.ones(2, 3, 4)
    b[0, :, 2:] = 100.0  # padding of sample 0
    mask = torch.tensor([[True, True, False, False], [True, True, True, True]])
    assert reconstruction_loss(a, b, mask_weights(mask)).item() == pytest.approx(1.0)


def test_wgan_terms_signs():
    real = torch.full((2, 5), 2.0)
    fake = torch.full((2, 5), -1.0)
    m = mask_weights(torch.ones(2, 5, dtype=torch.bool))
    assert critic_loss(real, fake, m, m).item() == pytest.approx(-3.0)
    assert generator_adversarial_loss(fake, m).item() == pytest.approx(1.0)


@pytest.mark.parametrize("scale, expect", [(1.0, 0.0), (2.0, 1.0), (0.5, 0.25)])
def test_gradient_penalty_of_linear_critics(scale, expect):
    w = torch.randn(1, 7, 1, generator=g)
    w = scale * w / w.norm()
    critic = lambda x: (x * w).sum(1)  # per-frame score; its per-frame gradient is w
    real, fake = torch.randn(2, 7, 9, generator=g), torch.randn(2, 7, 9, generator=g)
    alpha = torch.rand(2, 1, 1, generator=g)
    gp = gradient_penalty(
        critic, real, fake, mask_weights(torch.ones(2, 9, dtype=torch.bool)), alpha
    )
    assert gp.item() == pytest.approx(expect, abs=1e-5)


def test_backward_velocity_per_sample_and_per_frame_fps():
    p = torch.zeros(2, 3, 1, 3)
    p[:, :, 0, 0] = torch.tensor([0.0, 1.0, 3.0])
    v = backward_velocity(p, torch.tensor([1.0, 10.0]))
    assert v[0, :, 0, 0].tolist() == [0.0, 1.0, 2.0]
    assert v[1, :, 0, 0].tolist() == [0.0, 10.0, 20.0]
    v = backward_velocity(p[:1], torch.tensor([[5.0, 1.0, 10.0]]))  # packed: a rate per frame
    assert v[0, :, 0, 0].tolist() == [0.0, 1.0, 20.0]
    assert backward_velocity(p, 2.0)[1, :, 0, 0].tolist() == [0.0, 2.0, 4.0]


def test_body_kinematics_matches_the_body_model(body):
    rng = np.random.default_rng(0)
    T = 12
    poses = rng.normal(size=(T, 24, 3)) * 0.3
    trans = np.cumsum(rng.normal(size=(T, 3)) * 0.02, 0) + [0.0, 0.9, 0.0]
    m = Motion(poses, trans, 30.0, contacts=np.zeros((T, 6)))
    feats = motion_to_features(m)
    norm = FeatureNormalizer.fit(feats)
    x = norm.normalize(feats).T[None]  # (1, C, T)
    joints, feet, contacts = body_kinematics(x, norm, 30.0, body)
    assert (
        joints.shape == (1, T, 24, 3) and feet.shape == (1, T, 6, 3) and contacts.shape == (1, T, 6)
    )
    t0 = torch.tensor(
        trans - [trans[0, 0], 0.0, trans[0, 2]], dtype=torch.float32
    )  # path starts at x=z=0
    ref = body.forward(
        axis_angle_to_matrix(torch.tensor(poses, dtype=torch.float32)),
        t0,
        vertex_ids=list(body.foot_vertex_ids),
    )
    assert torch.allclose(joints[0], ref.joints, atol=1e-4)
    assert torch.allclose(feet[0], ref.vertices, atol=1e-4)
    # differentiable end to end
    xr = x.clone().requires_grad_(True)
    j, f, c = body_kinematics(xr, norm, torch.tensor([30.0]), body)
    (f.sum() + j.sum()).backward()
    assert torch.isfinite(xr.grad).all() and xr.grad.abs().sum() > 0
