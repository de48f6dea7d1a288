import pytest
import torch
import torch.nn.functional as F

from mrlib.errors import ClipTooShortError
from mrlib.model.pyramid import (
    PackedLevels,
    build_pyramid,
    level_fps,
    noise_amplitudes,
    pyramid_lengths,
    resample_linear,
)

g = torch.Generator().manual_seed(0)


def test_pyramid_lengths_follow_the_scale_factor():
    lengths = pyramid_lengths(300, 8, 4 / 3)
    assert len(lengths) == 8 and lengths[-1] == 300
    assert all(a < b for a, b in zip(lengths, lengths[1:], strict=False))
    for i, n in enumerate(lengths):
        assert abs(n - 300 / (4 / 3) ** (7 - i)) <= 1  # T_i ~ T / F^(L-i)
    assert lengths[0] == 40


def test_pyramid_lengths_stay_increasing_for_short_clips_and_reject_too_short():
    lengths = pyramid_lengths(12, 6, 4 / 3)
    assert all(a < b for a, b in zip(lengths, lengths[1:], strict=False))
    with pytest.raises(ClipTooShortError):
        pyramid_lengths(8, 8, 4 / 3)


def test_level_fps():
    assert level_fps(30.0, [15, 20, 30]) == [15.0, 20.0, 30.0]


def test_resample_linear_matches_interpolate_and_keeps_constants():
    x = torch.randn(2, 5, 17, generator=g)
    assert torch.equal(
        resample_linear(x, 23), F.interpolate(x, size=23, mode="linear", align_corners=False)
    )
    c = torch.full((1, 3, 10), 2.5)
    assert torch.allclose(resample_linear(c, 31), torch.full((1, 3, 31), 2.5))


def _layout(table, gap=4):
    return PackedLevels.from_table(torch.tensor(table), gap)


def test_pack_unpack_round_trip_and_offsets():
    lay = _layout([[4, 6], [7, 9], [5, 8]])
    assert lay.batch_size == 3 and lay.num_levels == 2
    assert lay.sizes == [4 + 7 + 5 + 12, 6 + 9 + 8 + 12]
    assert lay.offsets[1].tolist() == [0, 10, 23]
    clips = [torch.randn(3, n, generator=g) for n in (6, 9, 8)]
    x = lay.pack(clips, 1)
    assert x.shape == (1, 3, lay.sizes[1])
    assert all(torch.equal(a, b) for a, b in zip(lay.unpack(x, 1), clips, strict=True))
    assert lay.valid[1].sum() == 23 and lay.split(1, 2) == 23
    assert (
        lay.per_sample(torch.tensor([1.0, 2.0, 3.0]), 0).tolist()
        == [1.0] * 8 + [2.0] * 11 + [3.0] * 9
    )


def test_packed_upsampling_equals_per_sample_interpolate():
    """The packed version against the naive per-sample oracle."""
    lay = _layout([[7, 10], [12, 16], [9, 30]])
    clips = [torch.randn(4, n, generator=g) for n in (7, 12, 9)]
    y = lay.upsample(lay.pack(clips, 0), 1)
    assert y.shape == (1, 4, lay.sizes[1])
    for c, out in zip(clips, lay.unpack(y, 1), strict=True):
        ref = F.interpolate(c[None], size=out.shape[-1], mode="linear", align_corners=False)[0]
        assert torch.allclose(out, ref, atol=1e-6)


def test_packed_downsampling_and_level_band_equal_per_sample_interpolate():
    lay = _layout([[7, 10], [12, 16], [9, 30]])
    clips = [torch.randn(4, n, generator=g) for n in (10, 16, 30)]
    x = lay.pack(clips, 1)
    down, band = lay.downsample(x, 1), lay.level_band(x, 1)
    assert down.shape == (1, 4, lay.sizes[0]) and band.shape == x.shape
    for c, d, h in zip(clips, lay.unpack(down, 0), lay.unpack(band, 1), strict=True):
        ref = F.interpolate(c[None], size=d.shape[-1], mode="linear", align_corners=False)
        assert torch.allclose(d, ref[0], atol=1e-6)
        up = F.interpolate(ref, size=c.shape[-1], mode="linear", align_corners=False)[0]
        assert torch.allclose(h, c - up, atol=1e-6)
    # a constant and a straight line survive the round trip in the interior, so their
    # level band is (close to) zero there; fast detail is kept
    t = torch.arange(30.0)
    slow = lay.pack([torch.ones(1, 10), torch.ones(1, 16), (0.1 * t)[None]], 1)
    inner = lay.unpack(lay.level_band(slow, 1), 1)[2][0, 3:-3]
    assert inner.abs().max() < 1e-5
    fast = lay.pack([torch.zeros(1, 10), torch.zeros(1, 16), torch.cos(torch.pi * t)[None]], 1)
    assert lay.unpack(lay.level_band(fast, 1), 1)[2].abs().mean() > 0.5
    coarse = lay.pack([c[:, :n] for c, n in zip(clips, (7, 12, 9), strict=True)], 0)
    assert torch.equal(lay.level_band(coarse, 0), coarse)  # level 1 owns all of it


def test_per_sample_rms_ignores_gap_frames():
    lay = _layout([[5], [8]])
    clips = [torch.randn(3, n, generator=g) for n in (5, 8)]
    x = lay.pack(clips, 0)
    x[..., lay.valid[0][0] == 0] = 100.0  # junk in the gaps
    ref = torch.stack([c.pow(2).mean(-1).sqrt() for c in clips])
    assert torch.allclose(lay.per_sample_rms(x, 0), ref, atol=1e-6)


def test_packed_reflect_padding_equals_per_sample_f_pad():
    lay = _layout([[6], [9], [4]])
    clips = [torch.randn(3, n, generator=g) for n in (6, 9, 4)]
    x = lay.pack(clips, 0)
    idx = lay.pad_index(0, 2)
    xp = x.gather(2, idx.expand(1, 3, -1))  # (1, 3, S + 4)
    for b, c in enumerate(clips):
        o, n = int(lay.offsets[0][b]), c.shape[-1]
        ref = F.pad(c[None], (2, 2), mode="reflect")[0]
        assert torch.equal(xp[0, :, o : o + n + 4], ref)  # padded position u is centre u - 2
    with pytest.raises(ClipTooShortError):
        _layout([[2]]).pad_index(0, 2)
    with pytest.raises(Exception, match="gap"):
        _layout([[9], [9]], gap=2).pad_index(0, 2)  # two samples need a gap of 2p


def test_packed_weights_make_per_sample_means():
    lay = _layout([[2], [4]])
    w = lay.weights(0)
    assert w.sum().item() == pytest.approx(1.0)
    x = lay.pack([torch.full((1, 2), 1.0), torch.full((1, 4), 3.0)], 0)
    assert (x[0, 0] * w[0]).sum().item() == pytest.approx(2.0)  # (1 + 3) / 2
    inner = lay.trimmed(0, start=1, end=1)
    assert inner.sum() == 0 + 2
    assert lay.weights(0, inner)[0, lay.offsets[0][1] + 1].item() == pytest.approx(
        0.25
    )  # 1 / (2 * B)


def test_data_pyramid_and_noise_amplitudes():
    x = torch.randn(6, 40, generator=g)
    lengths = pyramid_lengths(40, 4, 4 / 3)
    pyr = build_pyramid(x, lengths)
    assert [p.shape for p in pyr] == [(6, n) for n in lengths]
    assert torch.equal(pyr[-1], x)
    amps = noise_amplitudes(pyr)
    assert amps.shape == (4,)
    # level 1 against zeros is the RMS of the coarsest level; level i the RMS residual
    assert torch.isclose(amps[0], pyr[0].pow(2).mean().sqrt())
    up = F.interpolate(pyr[1][None], size=lengths[2], mode="linear", align_corners=False)[0]
    assert torch.isclose(amps[2], (pyr[2] - up).pow(2).mean().sqrt())
    # a smooth signal needs little detail at fine levels
    smooth = torch.sin(torch.linspace(0, 3, 40))[None].repeat(6, 1)
    a = noise_amplitudes(build_pyramid(smooth, lengths))
    assert (a[1:] < 0.1 * a[0]).all()
