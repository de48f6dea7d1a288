import dataclasses

import numpy as np
import pytest
import torch

from mrlib.model.config import ConfigError, ModelConfig
from mrlib.model.critic import PatchCritic, build_critics
from mrlib.model.generator import FiLM, LevelGenerator, build_generator
from mrlib.model.pyramid import PackedLevels
from mrlib.model.skeleton_conv import SkeletonConv1d, hidden_channel_joint, skeleton_mask
from mrlib.representation.features import NUM_FEATURES, channel_joint
from mrlib.representation.skeleton import UPPER_BODY_JOINTS, graph_distances

TINY = ModelConfig(num_levels=3, gen_hidden=(24, 48, 48), disc_hidden=(24, 48, 48))
DIST = graph_distances()
IO = channel_joint()
C = NUM_FEATURES


def _pad(T, p=2):
    """Reflect-pad index of one sequence of T frames."""
    return PackedLevels.from_table([[T]], gap=0).pad_index(0, p)


def test_hidden_channels_round_up_to_joint_groups():
    owner = hidden_channel_joint(128)
    assert (
        len(owner) == 144 and (np.bincount(owner) == 6).all()
    )  # GANimator: 128 -> 144 for 24 joints


def test_skeleton_mask_is_a_buffer_and_respects_distance():
    conv = SkeletonConv1d(C, 48, 5, skeleton_mask(hidden_channel_joint(48), IO, 2))
    assert "mask" in dict(conv.named_buffers()) and "mask" not in dict(conv.named_parameters())
    m = conv.mask[..., 0].bool().numpy()
    expect = DIST[np.ix_(hidden_channel_joint(48), IO)] <= 2
    assert (m == expect).all()
    assert (conv.weight.detach()[~conv.mask.expand_as(conv.weight).bool()] == 0).all()


def _joint_jacobian(fn, in_owner, out_owner, T=21):
    """(J_out, J_in) bool: does any output channel of joint a depend on an input channel of
    joint b (autograd, one backward per output joint)."""
    x = torch.randn(1, len(in_owner), T, requires_grad=True)
    y = fn(x)
    dep = np.zeros((24, 24), bool)
    for a in range(24):
        sel = torch.from_numpy(out_owner == a)
        if not sel.any():
            continue
        (g,) = torch.autograd.grad(y[:, sel].sum(), x, retain_graph=True)
        per_channel = g.abs().sum((0, 2)).numpy() > 0
        for b in range(24):
            dep[a, b] = per_channel[in_owner == b].any()
    return dep


def test_one_skeleton_conv_only_reads_the_neighbourhood():
    torch.manual_seed(0)
    out_owner = hidden_channel_joint(48)
    conv = SkeletonConv1d(C, len(out_owner), 5, skeleton_mask(out_owner, IO, 2))
    dep = _joint_jacobian(lambda x: conv(x, _pad(x.shape[-1])), IO, out_owner)
    assert (dep == (DIST <= 2)).all()


def test_generator_level_is_local_on_the_skeleton():
    """Four radius-2 convs: an output joint depends exactly on joints within 8 hops, so the
    left hand (22) cannot move the left foot (10), 12 hops away; the FiLM layer and the
    residual are per channel and keep it that way."""
    torch.manual_seed(0)
    level = LevelGenerator(TINY, cond_dim=3)
    cond = torch.zeros(1, 21, 3)
    cond[..., 1] = 1
    z = torch.zeros(1, 1, 21)
    dep = _joint_jacobian(lambda x: level(x, z, cond, _pad(21)), IO, IO)
    assert (dep == (DIST <= 8)).all()
    assert DIST[22, 10] == 12 and not dep[10, 22]
    # finite-difference check of the same fact on the full output
    x = torch.randn(1, C, 21)
    x2 = x.clone()
    x2[:, torch.from_numpy(IO == 22)] += 5.0
    with torch.no_grad():
        y, y2 = level(x, z, cond, _pad(21)), level(x2, z, cond, _pad(21))
    foot = torch.from_numpy(IO == 10)
    assert torch.equal(y[:, foot], y2[:, foot])
    assert not torch.equal(y[:, torch.from_numpy(IO == 20)], y2[:, torch.from_numpy(IO == 20)])


def test_temporal_receptive_fields():
    torch.manual_seed(0)
    critic = PatchCritic(TINY)
    assert critic.receptive_field == 17
    x = torch.randn(1, C, 60, requires_grad=True)
    s = critic(x, _pad(60))
    assert s.shape == (1, 60)
    (g,) = torch.autograd.grad(s[0, 30], x)
    touched = (g.abs().sum(1)[0] > 0).nonzero().flatten()
    assert touched.min() == 22 and touched.max() == 38  # 17 frames around frame 30


def test_film_identity_at_init_and_channel_mask():
    torch.manual_seed(0)
    film = FiLM(4, C, 8)
    cond = torch.eye(4)[None, :, :].repeat(2, 5, 1)[:, :7]  # (2, 7, 4)
    gamma, delta = film.params(cond)
    assert gamma.shape == (2, C, 7) and (gamma - 1).abs().max() < 0.2 and delta.abs().max() < 0.2
    mask = torch.from_numpy(np.isin(IO, UPPER_BODY_JOINTS))
    film_m = FiLM(4, C, 8, channel_mask=mask)
    gamma, delta = film_m.params(cond)
    assert (gamma[:, ~mask] == 1).all() and (delta[:, ~mask] == 0).all()
    assert (gamma[:, mask] != 1).any()


def test_film_changes_the_output_when_the_condition_changes():
    torch.manual_seed(0)
    level = LevelGenerator(TINY, cond_dim=3)
    x, z = torch.randn(1, C, 32), torch.randn(1, 1, 32)
    a, b = torch.zeros(1, 32, 3), torch.zeros(1, 32, 3)
    a[..., 0], b[..., 2] = 1, 1
    with torch.no_grad():
        ya, yb = level(x, z, a, _pad(32)), level(x, z, b, _pad(32))
    assert (ya - yb).abs().max() > 1e-4
    # a per-frame condition modulates frame by frame (receptive field: 8 frames each side)
    c = a.clone()
    c[:, 16:] = b[:, 16:]
    with torch.no_grad():
        yc = level(x, z, c, _pad(32))
    assert torch.equal(yc[..., :8], ya[..., :8]) and torch.equal(yc[..., 25:], yb[..., 25:])
    assert not torch.equal(yc[..., 8:25], ya[..., 8:25])


def test_film_joints_config_restricts_modulation():
    cfg = ModelConfig(
        num_levels=2, gen_hidden=(24,), disc_hidden=(24,), film_joints=UPPER_BODY_JOINTS
    )
    level = LevelGenerator(cfg, cond_dim=5)
    m = level.film.channel_mask[:, 0].bool().numpy()
    assert (m == np.isin(IO, UPPER_BODY_JOINTS)).all()


def test_shapes_through_every_level_with_packed_batch():
    torch.manual_seed(0)
    gen = build_generator(TINY, cond_dim=2)
    table = torch.tensor([[9, 12, 16], [12, 16, 21]])
    lay = PackedLevels.from_table(table, gap=4)
    noises = [torch.randn(1, C, lay.sizes[0])] + [torch.randn(1, 1, s) for s in lay.sizes[1:]]
    conds = [torch.rand(1, s, 2) for s in lay.sizes]
    outs = gen.run(lay, noises, conds, keep=True)
    assert [o.shape for o in outs] == [(1, C, s) for s in lay.sizes]
    # each sample of the packed batch equals that sample generated alone
    for b in range(2):
        solo = PackedLevels.from_table(table[b : b + 1], gap=0)
        sl = [
            slice(int(lay.offsets[i][b]), int(lay.offsets[i][b]) + int(table[b, i]))
            for i in range(3)
        ]
        n_b = [n[..., sl[i]] for i, n in enumerate(noises)]
        c_b = [c[:, sl[i]] for i, c in enumerate(conds)]
        alone = gen.run(solo, n_b, c_b, keep=True)
        for i in range(3):
            assert torch.allclose(outs[i][..., sl[i]], alone[i], atol=1e-5)
    # levels can be run in two halves (frozen levels, then a block)
    mid = gen.run(lay, noises, conds, 0, 2)
    top = gen.run(lay, noises, conds, 2, 3, x=mid)
    assert torch.allclose(top, outs[-1])


def test_batched_sampling_path_equals_the_packed_run():
    """run_batch (equal-length samples, one per row, F.pad / F.interpolate) gives what the
    packed training path gives, with time-constant conditions passed once per sample."""
    torch.manual_seed(0)
    gen = build_generator(TINY, cond_dim=2)
    lengths = [9, 12, 16]
    table = torch.tensor([lengths, lengths])
    lay = PackedLevels.from_table(table, gap=4)
    z = [torch.randn(2, 1, n) for n in lengths]
    label = torch.tensor([[1.0, 0.0], [0.3, 0.7]])  # (B, D), constant over time
    conds_b = [label[:, None] for _ in lengths]  # (B, 1, D)
    packed = gen.run(
        lay,
        [lay.pack(list(zi), i) for i, zi in enumerate(z)],
        [lay.pack([c.T.expand(-1, n) for c in label[:, None]], i).transpose(1, 2)
         for i, n in enumerate(lengths)],
        keep=True,
    )  # fmt: skip
    batched = gen.run_batch(z, conds_b, keep=True)
    for i in range(3):
        assert batched[i].shape == (2, C, lengths[i])
        assert torch.allclose(torch.stack(lay.unpack(packed[i], i)), batched[i], atol=1e-5)
    # per-frame conditions give the same as the constant ones repeated over time
    per_frame = [label[:, None].expand(-1, n, -1) for n in lengths]
    assert torch.allclose(gen.run_batch(z, per_frame), batched[-1], atol=1e-6)


def test_critics_score_patches_without_sigmoid():
    critics = build_critics(TINY)
    assert len(critics) == 3
    x = torch.randn(2, C, 20) * 10
    s = critics[0](x, _pad(20).expand(2, -1, -1))
    assert s.shape == (2, 20)
    assert s.abs().max() > 1 or s.min() < 0  # unbounded scores


@pytest.mark.parametrize("radius", [1, 2])
def test_mask_density_shrinks_with_radius(radius):
    m = skeleton_mask(hidden_channel_joint(24), hidden_channel_joint(24), radius)
    assert m.float().mean() == pytest.approx(float((DIST <= radius).mean()))


def test_conditional_critic_is_a_projection_of_the_last_hidden_layer():
    torch.manual_seed(0)
    critic = PatchCritic(TINY, cond_dim=3)
    x = torch.randn(2, C, 20)
    pad = _pad(20).expand(2, -1, -1)
    a = torch.eye(3)[0].expand(2, 20, 3)
    b = torch.eye(3)[2].expand(2, 20, 3)
    sa, sb = critic(x, pad, a), critic(x, pad, b)
    assert sa.shape == (2, 20) and not torch.allclose(sa, sb)
    # the label enters linearly: D(x, (a + b) / 2) is the mean of the two scores
    assert torch.allclose(critic(x, pad, (a + b) / 2), (sa + sb) / 2, atol=1e-5)
    # with the projection zeroed it is the unconditional critic
    with torch.no_grad():
        critic.project.weight.zero_()
    plain = PatchCritic(TINY)
    plain.load_state_dict({k: v for k, v in critic.state_dict().items() if "project" not in k})
    assert torch.allclose(critic(x, pad, a), plain(x, pad), atol=1e-6)
    with pytest.raises(ValueError, match="needs cond"):
        critic(x, pad)
    with pytest.raises(ValueError, match="unconditional"):
        plain(x, pad, a)
    assert len(build_critics(TINY, cond_dim=3)) == 3


def test_detail_band_critic_judges_the_label_on_detail_only():
    torch.manual_seed(0)
    cfg = dataclasses.replace(TINY, critic_band="detail")
    critic = PatchCritic(cfg, cond_dim=3)
    assert critic.detail is not None and critic.project.in_features == 3
    x = torch.randn(1, C, 40)
    pad = _pad(40)
    a, b = torch.eye(3)[0].expand(1, 40, 3), torch.eye(3)[2].expand(1, 40, 3)
    sa, sb = critic(x, pad, a), critic(x, pad, b)
    assert not torch.allclose(sa, sb)
    assert torch.allclose(critic(x, pad, (a + b) / 2), (sa + sb) / 2, atol=1e-5)
    # an offset of every channel moves only the unconditional score: the label term
    # sees x - box(x), which an offset leaves unchanged
    y = x + 3 * torch.randn(1, C, 1)
    assert not torch.allclose(critic(y, pad, a), sa, atol=1e-3)
    assert torch.allclose(critic(y, pad, a) - critic(y, pad, b), sa - sb, atol=1e-4)
    # a full-band conditional critic's label term does see the offset
    full = PatchCritic(TINY, cond_dim=3)
    assert full.detail is None
    d_x = full(x, pad, a) - full(x, pad, b)
    assert not torch.allclose(full(y, pad, a) - full(y, pad, b), d_x, atol=1e-3)
    # no branch without a condition; bad values are refused
    assert PatchCritic(cfg).detail is None
    for bad in ("high", "level"):  # "level" was a study option, removed
        with pytest.raises(ConfigError, match="critic_band"):
            ModelConfig(critic_band=bad)


@pytest.mark.parametrize("band", ["full", "detail"])
def test_critic_split_gives_the_two_terms_forward_adds(band):
    torch.manual_seed(0)
    critic = PatchCritic(dataclasses.replace(TINY, critic_band=band), cond_dim=3)
    x = torch.randn(2, C, 30)
    pad = _pad(30).expand(2, -1, -1)
    c = torch.softmax(torch.randn(2, 30, 3), -1)
    score, feats = critic.split(x, pad)
    assert score.shape == (2, 30) and feats.shape[::2] == (2, 30)
    # one joint per feature channel, as the skeleton-aware layers assign them
    assert len(hidden_channel_joint(feats.shape[1])) == feats.shape[1]
    label = (critic.project(c).transpose(1, 2) * feats).sum(1)
    assert torch.allclose(critic(x, pad, c), score + label, atol=1e-5)


def test_masked_weights_stay_zero_through_training_and_loading():
    """The forward uses the weight as it is: its masked entries must stay zero, so their
    gradient is masked (once per backward) and a loaded state dict is masked too."""
    torch.manual_seed(0)
    conv = SkeletonConv1d(C, 48, 5, skeleton_mask(hidden_channel_joint(48), IO, 2))
    off = ~conv.mask.expand_as(conv.weight).bool()
    opt = torch.optim.Adam(conv.parameters(), lr=0.1)
    x = torch.randn(2, C, 30)
    for _ in range(3):
        opt.zero_grad()
        conv(x).square().sum().backward()
        conv(x).sum().backward()  # a second backward accumulates: still masked
        assert (conv.weight.grad[off] == 0).all() and (conv.weight.grad[~off] != 0).any()
        opt.step()
    assert (conv.weight.detach()[off] == 0).all()
    expected = torch.nn.functional.conv1d(
        torch.nn.functional.pad(x, (2, 2), mode="reflect"), conv.weight * conv.mask, conv.bias
    )
    assert torch.equal(conv(x), expected)
    state = {k: v.clone() for k, v in conv.state_dict().items()}
    state["weight"] = torch.randn_like(state["weight"])
    conv.load_state_dict(state)
    assert (conv.weight.detach()[off] == 0).all()
    assert torch.equal(conv.weight.detach()[~off], state["weight"][~off])
    dense = SkeletonConv1d(C, 8, 5, None)
    dense(x).sum().backward()
    assert (dense.weight.grad != 0).all()
