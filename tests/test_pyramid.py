import pytest
import torch
import torch.nn.functional as F

from mrlib.errors import ClipTooShortError
from mrlib.pyramid import (
    RaggedLevels,
    build_pyramid,
    level_fps,
    noise_amplitudes,
    pad_stack,
    pyramid_lengths,
    reflect_pad_index,
    resample_linear,
    resample_linear_ragged,
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


def test_ragged_resampling_equals_per_sample_interpolate():
    """The batched, padded version against the naive per-sample oracle."""
    lin = torch.tensor([7, 12, 9])
    lout = torch.tensor([10, 16, 30])
    x = torch.randn(3, 4, 12, generator=g)
    y = resample_linear_ragged(x, lin, lout)
    assert y.shape == (3, 4, 30)
    for b in range(3):
        ref = F.interpolate(
            x[b : b + 1, :, : lin[b]], size=int(lout[b]), mode="linear", align_corners=False
        )
        assert torch.allclose(y[b : b + 1, :, : lout[b]], ref, atol=1e-6)


def test_ragged_resampling_ignores_padding():
    lin, lout = torch.tensor([5, 8]), torch.tensor([7, 11])
    x = torch.randn(2, 3, 8, generator=g)
    x2 = x.clone()
    x2[0, :, 5:] = 1e6  # garbage after sample 0's end
    assert torch.equal(
        resample_linear_ragged(x, lin, lout)[0, :, :7],
        resample_linear_ragged(x2, lin, lout)[0, :, :7],
    )


def test_reflect_pad_index_matches_f_pad_per_sample():
    lengths = torch.tensor([6, 9])
    x = torch.randn(2, 3, 9, generator=g)
    idx = reflect_pad_index(lengths, 9, 2)
    xp = x.gather(2, idx.expand(2, 3, -1))
    for b in range(2):
        n = int(lengths[b])
        ref = F.pad(x[b : b + 1, :, :n], (2, 2), mode="reflect")
        assert torch.equal(xp[b : b + 1, :, : n + 4], ref)
    with pytest.raises(ClipTooShortError):
        reflect_pad_index(torch.tensor([2]), 2, 2)


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


def test_pad_stack_and_ragged_levels():
    clips = [torch.randn(3, n, generator=g) for n in (5, 9)]
    x, lengths = pad_stack(clips)
    assert x.shape == (2, 3, 9) and lengths.tolist() == [5, 9]
    assert torch.equal(x[0, :, :5], clips[0])
    table = torch.tensor([[4, 5, 7], [6, 8, 11]])
    lay = RaggedLevels.from_table(table)
    assert lay.sizes == [6, 8, 11] and lay.batch_size == 2 and not lay.uniform
    assert lay.masks[2].sum(1).tolist() == [7, 11]
    y = lay.upsample(torch.randn(2, 3, 8, generator=g), 2)
    assert y.shape == (2, 3, 11)
    sub = lay.select(slice(1, 2))
    assert sub.sizes == [6, 8, 11] and sub.uniform
