"""Tests for mrlib.metrics.coverage, .diversity and .windows: the fast metrics against
their naive oracles, invariants, and error handling. Inputs are small and seeded."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from mrlib.errors import ClipTooShortError, MotionValueError
from mrlib.metrics import oracles
from mrlib.metrics import windows as win
from mrlib.metrics.coverage import condition_fidelity, coverage, coverage_profile
from mrlib.metrics.diversity import global_diversity, local_diversity
from mrlib.metrics.windows import frame_distances, metric_features, reconstruction_error
from mrlib.representation.motion import Motion


def smooth_motion(T: int, seed: int, contacts: bool = True) -> Motion:
    """A clip with smoothly varying random joint rotations (moderate angles)."""
    rng = np.random.default_rng(seed)
    knots = rng.normal(scale=0.5, size=(T // 10 + 2, 24, 3))
    t = np.linspace(0, len(knots) - 1, T)
    i = np.minimum(t.astype(int), len(knots) - 2)
    w = (t - i)[:, None, None]
    poses = (1 - w) * knots[i] + w * knots[i + 1]
    c = (rng.random((T, 6)) < 0.5).astype(np.float32) if contacts else None
    return Motion(poses=poses, trans=rng.normal(size=(T, 3)), fps=30.0, contacts=c)


def patchwork(ref: np.ndarray, L: int, rng: np.random.Generator, noise: float) -> np.ndarray:
    """A clip made of random pieces of ``ref`` plus noise: PNN has several segments."""
    pieces, n = [], 0
    while n < L:
        k = int(rng.integers(1, min(12, len(ref)) + 1))
        s = int(rng.integers(0, len(ref) - k + 1))
        pieces.append(ref[s : s + k])
        n += k
    out = np.concatenate(pieces)[:L]
    return out + noise * rng.normal(size=out.shape)


def check_segmentation(seg, L, Lr, tmin):
    """Segments tile [0, L), each at least tmin frames, reference window in range."""
    assert seg[0][0] == 0 and seg[-1][1] == L
    for (a, b, r), nxt in zip(seg, seg[1:] + [None], strict=True):
        assert b - a >= tmin
        assert 0 <= r and r + (b - a) <= Lr
        if nxt is not None:
            assert nxt[0] == b


def segmentation_cost(g, r, seg, squared=False):
    D = oracles.frame_distances_naive(g, r, squared)
    return sum(D[a + m, s + m] for a, b, s in seg for m in range(b - a)) / len(g)


# ---------------------------------------------------------------------------------------
# features
# ---------------------------------------------------------------------------------------
def test_metric_features_shapes_and_root_excluded():
    m = smooth_motion(20, 0)
    f = metric_features(m)
    assert f.shape == (20, 23 * 6 + 6) and f.dtype == np.float64
    assert metric_features(m, contacts=False).shape == (20, 138)
    assert metric_features(m.replace(contacts=None)).shape == (20, 138)
    assert metric_features(m, kind="rotmat").shape == (20, 23 * 9 + 6)
    np.testing.assert_array_equal(f[:, -6:], m.contacts)
    # the root orientation and translation do not enter the features
    moved = m.replace(poses=m.poses.copy(), trans=m.trans + 5.0)
    moved.poses[:, 0] += 1.0
    np.testing.assert_allclose(metric_features(moved), f)
    # zero rotation -> identity columns
    still = Motion(poses=np.zeros((3, 24, 3)), trans=np.zeros((3, 3)), fps=30.0)
    np.testing.assert_allclose(
        metric_features(still).reshape(3, 23, 6), np.tile([1.0, 0, 0, 0, 1, 0], (3, 23, 1))
    )
    # 6D is the first two columns of the matrix
    R = metric_features(m, kind="rotmat", contacts=False).reshape(20, 23, 3, 3)
    sixd = f[:, :138].reshape(20, 23, 6)
    np.testing.assert_allclose(sixd[..., :3], R[..., :, 0], atol=1e-12)
    np.testing.assert_allclose(sixd[..., 3:], R[..., :, 1], atol=1e-12)


def test_metric_features_passthrough_and_errors():
    x = np.random.default_rng(0).normal(size=(7, 5)).astype(np.float32)
    np.testing.assert_allclose(metric_features(x), x)
    np.testing.assert_allclose(metric_features(torch.from_numpy(x)), x)
    with pytest.raises(MotionValueError, match=r"\(T, D\)"):
        metric_features(np.zeros((3, 4, 5)))
    with pytest.raises(MotionValueError, match="NaN"):
        metric_features(np.full((3, 4), np.nan))
    with pytest.raises(MotionValueError, match="kind"):
        metric_features(smooth_motion(5, 0), kind="quat")
    with pytest.raises(MotionValueError, match="channels"):
        local_diversity(np.zeros((20, 4)), np.zeros((20, 5)))


def test_metrics_accept_motion_directly():
    m = smooth_motion(40, 1)
    f = metric_features(m)
    assert local_diversity(m, m, window=5) == pytest.approx(local_diversity(f, f, window=5))


def test_frame_distances_match_naive():
    rng = np.random.default_rng(1)
    x, y = rng.normal(size=(13, 6)), rng.normal(size=(9, 6)) + 3.0
    for squared in (False, True):
        np.testing.assert_allclose(
            frame_distances(x, y, squared),
            oracles.frame_distances_naive(x, y, squared),
            rtol=1e-10,
            atol=1e-10,
        )


# ---------------------------------------------------------------------------------------
# window metrics vs oracles
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("chunk", [None, 64])
def test_window_metrics_match_naive(monkeypatch, chunk):
    if chunk is not None:  # tiny blocks: exercises the block seams
        monkeypatch.setattr(win, "_CHUNK_ELEMS", chunk)
    rng = np.random.default_rng(2)
    for trial in range(40):
        D = int(rng.integers(1, 6))
        ref = rng.normal(size=(int(rng.integers(8, 40)), D))
        gen = patchwork(ref, int(rng.integers(8, 40)), rng, noise=0.3 * (trial % 3))
        w = int(rng.integers(1, 8))
        squared = bool(trial % 2)
        prof = coverage_profile(gen, ref, w, squared)
        np.testing.assert_allclose(
            prof, oracles.window_nn_naive(ref, gen, w, squared), rtol=1e-9, atol=1e-7
        )
        eps = float(np.median(prof)) + 1e-6  # about half covered
        assert coverage(gen, ref, w, eps, squared) == oracles.coverage_naive(
            gen, ref, w, eps, squared
        )
        assert local_diversity(gen, ref, w, squared) == pytest.approx(
            oracles.local_diversity_naive(gen, ref, w, squared), rel=1e-9, abs=1e-7
        )


def test_coverage_of_a_list_is_the_mean_and_accepts_iterables():
    rng = np.random.default_rng(3)
    ref = rng.normal(size=(50, 4))
    gens = [patchwork(ref, 60, rng, noise=s) for s in (0.0, 0.5, 1.0)]
    per = [coverage(g, ref, 10, eps=1.0) for g in gens]
    assert len(set(per)) > 1
    assert coverage(gens, ref, 10, eps=1.0) == pytest.approx(np.mean(per))
    assert coverage(iter(gens), ref, 10, eps=1.0) == pytest.approx(np.mean(per))
    assert coverage(gens, ref, 10, eps=1.0) == pytest.approx(
        oracles.coverage_naive(gens, ref, 10, eps=1.0)
    )
    assert local_diversity(gens, ref, 5) == pytest.approx(
        oracles.local_diversity_naive(gens, ref, 5)
    )
    # several thresholds at once: the same numbers as one call per threshold
    many = coverage(gens, ref, 10, eps=(1.0, 0.5, 1e9))
    assert many == {e: coverage(gens, ref, 10, eps=e) for e in (1.0, 0.5, 1e9)}
    with pytest.raises(MotionValueError, match="eps"):
        coverage(gens, ref, 10, eps=(1.0, -1.0))


# ---------------------------------------------------------------------------------------
# global diversity vs oracles
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("chunk", [None, 50])
def test_global_diversity_matches_naive_dp(monkeypatch, chunk):
    if chunk is not None:
        monkeypatch.setattr(win, "_CHUNK_ELEMS", chunk)
    rng = np.random.default_rng(4)
    n_feasible = 0
    for trial in range(60):
        D = int(rng.integers(1, 5))
        Lr = int(rng.integers(4, 40))
        L = int(rng.integers(4, 60))
        tmin = int(rng.integers(1, 8))
        squared = bool(trial % 2)
        ref = rng.normal(size=(Lr, D))
        gen = patchwork(ref, L, rng, noise=0.2) if trial % 3 else rng.normal(size=(L, D))
        try:
            want, _ = oracles.global_diversity_naive(gen, ref, tmin, squared)
        except ClipTooShortError:
            with pytest.raises(ClipTooShortError):
                global_diversity(gen, ref, tmin, squared)
            continue
        n_feasible += 1
        got, seg = global_diversity(gen, ref, tmin, squared, return_segmentation=True)
        assert got == pytest.approx(want, rel=1e-9, abs=1e-7)
        check_segmentation(seg, L, Lr, tmin)
        assert segmentation_cost(gen, ref, seg, squared) == pytest.approx(got, rel=1e-9, abs=1e-7)
    assert n_feasible > 40


def test_naive_dp_matches_enumeration_and_short_segments_suffice():
    """The naive DP against listing every segmentation; and restricting segments to
    tmin..2*tmin-1 frames gives the same optimum (a longer one splits at no cost)."""
    rng = np.random.default_rng(5)
    for _ in range(12):
        tmin = int(rng.integers(2, 5))
        ref = rng.normal(size=(int(rng.integers(2 * tmin, 14)), 2))
        gen = patchwork(ref, int(rng.integers(tmin, 17)), rng, noise=0.3)
        want = oracles.global_diversity_enumerate(gen, ref, tmin)
        assert oracles.global_diversity_naive(gen, ref, tmin)[0] == pytest.approx(want)
        assert oracles.global_diversity_enumerate(
            gen, ref, tmin, max_len=2 * tmin - 1
        ) == pytest.approx(want)
        assert global_diversity(gen, ref, tmin) == pytest.approx(want, abs=1e-7)


def test_global_diversity_list_returns_mean_and_segmentations():
    rng = np.random.default_rng(6)
    ref = rng.normal(size=(40, 3))
    gens = [patchwork(ref, 45, rng, 0.1), rng.normal(size=(50, 3))]
    v, segs = global_diversity(gens, ref, 5, return_segmentation=True)
    assert len(segs) == 2
    assert v == pytest.approx(
        np.mean([oracles.global_diversity_naive(g, ref, 5)[0] for g in gens]), abs=1e-7
    )


# ---------------------------------------------------------------------------------------
# identities
# ---------------------------------------------------------------------------------------
def test_identity_shift_and_noise():
    ref = metric_features(smooth_motion(120, 7))
    assert coverage(ref, ref) == 1.0
    assert local_diversity(ref, ref) < 1e-6
    v, seg = global_diversity(ref, ref, return_segmentation=True)
    assert v < 1e-6 and seg == [(0, 120, 0)]
    # cropped: a single segment at the crop offset
    v, seg = global_diversity(ref[17:100], ref, return_segmentation=True)
    assert v < 1e-6 and seg == [(0, 83, 17)]
    # rolled: two segments, the second matched to the start of the reference
    v, seg = global_diversity(np.roll(ref, -45, axis=0), ref, return_segmentation=True)
    assert v < 1e-6 and seg == [(0, 75, 45), (75, 120, 0)]
    # ... and only the reference windows across the seam (frames 44 and 45) are missing
    prof = coverage_profile(np.roll(ref, -45, axis=0), ref)
    assert prof[:16].max() < 1e-6 and prof[45:].max() < 1e-6 and prof[16:45].min() > 1e-3
    # white noise covers nothing and is far from everything
    noise = np.random.default_rng(0).normal(size=(240, ref.shape[1]))
    assert coverage(noise, ref) == 0.0
    assert global_diversity(noise, ref) > 2.0
    # a different clip scores in between
    other = metric_features(smooth_motion(240, 8))
    assert 0 < local_diversity(other, ref) < local_diversity(noise, ref)


def test_reconstruction_error():
    rng = np.random.default_rng(9)
    a, b = rng.normal(size=(10, 4)), rng.normal(size=(10, 4))
    assert reconstruction_error(a, a) == 0.0
    assert reconstruction_error(a, b) == pytest.approx(np.linalg.norm(a - b, axis=1).mean())
    assert reconstruction_error(a, b, squared=True) == pytest.approx(((a - b) ** 2).sum(1).mean())
    with pytest.raises(MotionValueError, match="equal lengths"):
        reconstruction_error(a, b[:9])


def test_condition_fidelity():
    fa = metric_features(smooth_motion(90, 10))
    fb = metric_features(smooth_motion(90, 11))
    refs = {"happy": fa, "angry": fb}
    assert condition_fidelity([(fa[10:80], "happy"), (fb, "angry")], refs) == 1.0
    assert condition_fidelity([(fa[10:80], "angry")], refs) == 0.0
    # half of each clip from each label: about half of the windows go each way
    mixed = np.concatenate([fa[:60], fb[:60]])
    share = condition_fidelity([(mixed, "happy")], refs)
    assert 0.3 < share < 0.7
    m = smooth_motion(60, 10).replace(label="happy")
    assert (
        condition_fidelity([m], {"happy": smooth_motion(90, 10), "angry": smooth_motion(90, 11)})
        == 1.0
    )
    with pytest.raises(MotionValueError, match="no reference"):
        condition_fidelity([(fa, "sad")], refs)


def test_errors_on_short_clips_and_bad_arguments():
    x = np.zeros((20, 3))
    with pytest.raises(ClipTooShortError, match="tmin"):
        global_diversity(x[:10], x, tmin=15)
    with pytest.raises(ClipTooShortError, match="reference"):
        global_diversity(x, x[:10], tmin=15)
    with pytest.raises(ClipTooShortError, match="no segmentation"):
        global_diversity(np.zeros((31, 3)), np.zeros((30, 3)), tmin=30)
    with pytest.raises(ClipTooShortError, match="window"):
        coverage(x[:5], x, window=10)
    with pytest.raises(MotionValueError, match="eps"):
        coverage(x, x, window=5, eps=0.0)
    with pytest.raises(MotionValueError, match="window"):
        local_diversity(x, x, window=0)
    with pytest.raises(MotionValueError, match="no generated"):
        coverage([], x, window=5)
