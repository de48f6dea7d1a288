"""Tests for mrlib.viz.plots: segmentation frame maps, PNN segmentation, coverage strips,
quality curves."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
import pytest

from mrlib import metrics as mt
from mrlib.errors import MotionValueError
from mrlib.viz.plots import (
    plot_coverage_strip,
    plot_quality_curve,
    plot_segmentation,
    segmentation_frame_map,
)


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


@pytest.fixture(scope="module")
def collage():
    """A reference of random frames and a generated clip glued from three of its windows."""
    rng = np.random.default_rng(0)
    ref = rng.normal(size=(80, 6))
    pieces = [(10, 50), (0, 35), (40, 80)]
    gen = np.concatenate([ref[a:b] for a, b in pieces])  # (115, 6)
    return ref, gen, pieces


def test_frame_map_of_the_pnn_segmentation_rebuilds_a_collage(collage):
    ref, gen, pieces = collage
    value, seg = mt.global_diversity(gen, ref, tmin=30, return_segmentation=True)
    assert value == pytest.approx(0.0, abs=1e-6)
    assert [(a, r) for a, _, r in seg] == [(0, 10), (40, 0), (75, 40)]
    frame_map = segmentation_frame_map(seg, len(gen), len(ref))
    assert frame_map.shape == (len(gen),) and frame_map.dtype == np.int64
    np.testing.assert_array_equal(ref[frame_map], gen)
    np.testing.assert_array_equal(frame_map[:40], np.arange(10, 50))


def test_frame_map_rejects_bad_tilings():
    with pytest.raises(MotionValueError, match="gaps"):
        segmentation_frame_map([(0, 10, 0), (12, 20, 0)], 20)  # gap
    with pytest.raises(MotionValueError, match="gaps"):
        segmentation_frame_map([(0, 10, 0), (8, 20, 0)], 20)  # overlap
    with pytest.raises(MotionValueError, match="covers frames"):
        segmentation_frame_map([(0, 10, 0)], 20)  # stops early
    with pytest.raises(MotionValueError, match="ends after"):
        segmentation_frame_map([(0, 25, 0)], 20)
    with pytest.raises(MotionValueError, match="outside"):
        segmentation_frame_map([(0, 20, 5)], 20, num_ref_frames=22)
    with pytest.raises(MotionValueError, match="triple"):
        segmentation_frame_map([(0, 20)], 20)
    with pytest.raises(MotionValueError, match="num_frames"):
        segmentation_frame_map([], 0)


def test_plot_segmentation_draws_one_diagonal_per_segment(collage):
    ref, gen, _ = collage
    _, seg = mt.global_diversity(gen, ref, tmin=30, return_segmentation=True)
    ax = plot_segmentation(seg, len(gen), len(ref))
    diagonals = [ln for ln in ax.lines if ln.get_linewidth() == 3.0]
    assert len(diagonals) == len(seg) == 3
    for ln, (a, b, r) in zip(diagonals, seg, strict=True):
        np.testing.assert_allclose(ln.get_xdata(), [a, b - 1])
        np.testing.assert_allclose(ln.get_ydata(), [r, r + b - a - 1])
    assert "3 segments" in ax.get_title()
    ax2 = plot_segmentation(seg, len(gen), len(ref), fps=10.0, title="x")
    np.testing.assert_allclose(ax2.lines[1].get_xdata(), [4.0, 7.4])  # frames 40..74 at 10 fps
    assert ax2.get_title() == "x" and ax2.get_xlabel().endswith("(s)")
    with pytest.raises(MotionValueError):
        plot_segmentation(seg, len(gen), 50)  # matched frames beyond a 50-frame reference
    with pytest.raises(MotionValueError, match="fps"):
        plot_segmentation(seg, len(gen), len(ref), fps=0.0)


def test_plot_coverage_strip_shows_the_profile_around_eps():
    profile = np.array([[0.5, 1.0, 3.0, 4.0], [0.1, 0.2, 0.3, 5.0]])
    ax = plot_coverage_strip(profile, eps=2.0, window=30, row_labels=["a", "b"])
    img = ax.images[0]
    np.testing.assert_array_equal(np.asarray(img.get_array()), profile)
    assert img.norm.vcenter == 2.0 and img.norm.vmin == 0.0 and img.norm.vmax == 4.0
    assert ax.figure.axes[1].get_label() == "<colorbar>"
    ticks = [t.get_text() for t in ax.get_yticklabels()]
    assert ticks == ["a (50%)", "b (75%)"]
    assert "62.5%" in ax.get_title() and "30-frame" in ax.get_xlabel()
    assert len(ax.figure.axes) == 2  # the colour bar
    # one row, all covered: the colour scale spans [0, 2 eps] whatever the values
    ax1 = plot_coverage_strip(np.full(10, 0.3), eps=1.5, colorbar=False)
    assert ax1.images[0].norm.vmax == 3.0 and len(ax1.figure.axes) == 1
    assert ax1.get_yticklabels()[0].get_text() == "sample 0 (100%)"


def test_plot_coverage_strip_validates_inputs():
    with pytest.raises(MotionValueError, match="eps"):
        plot_coverage_strip(np.ones(5), eps=0.0)
    with pytest.raises(MotionValueError, match="shape"):
        plot_coverage_strip(np.ones((2, 3, 4)), eps=1.0)
    with pytest.raises(MotionValueError, match="finite"):
        plot_coverage_strip(np.array([1.0, np.nan]), eps=1.0)
    with pytest.raises(MotionValueError, match="row labels"):
        plot_coverage_strip(np.ones((2, 4)), eps=1.0, row_labels=["one"])


def test_plot_quality_curve():
    ax = plot_quality_curve([0, 10, 20], [50, 90, 99.5], target=99, reached_at=20, label="cov")
    np.testing.assert_allclose(ax.lines[0].get_ydata(), [50, 90, 99.5])
    assert ax.lines[1].get_ydata()[0] == 99  # the target line
    assert ax.lines[2].get_xdata()[0] == 20  # reached
    with pytest.raises(MotionValueError):
        plot_quality_curve([0, 1], [1.0])


def _fake_result(jerk_top: float = 1.4):
    """An EvaluationResult with one model, its raw output and one calibration row over
    two sequences; the jerk ratio of the raw rows reaches ``jerk_top``."""
    from mrlib.evaluation.results import PLOT_COLUMNS, EvaluationResult, EvaluationSettings

    def row(method, kind, seq, base):
        vals = {k: base + i for i, k in enumerate(PLOT_COLUMNS)}
        return {"method": method, "kind": kind, "sequence": seq, "source": "", **vals}

    rows = [
        row("ours", "model", "a", 1.0),
        row("ours", "model", "b", 3.0),
        {**row("ours (raw)", "model", "a", 2.0), "jerk_ratio": jerk_top},
        {**row("ours (raw)", "model", "b", 2.0), "jerk_ratio": 0.8},
        row("calib: played twice", "calibration", "a", 0.5),
        row("calib: played twice", "calibration", "b", 0.5),
    ]
    return EvaluationResult(rows=rows, settings=EvaluationSettings(num_samples=1, eps=1.5))


def test_plot_evaluation_draws_the_table_statistics_with_labelled_axes_and_an_outside_legend():
    from mrlib.evaluation.results import PLOT_COLUMNS
    from mrlib.viz.plots import plot_evaluation

    res = _fake_result()
    fig = plot_evaluation(res)
    axes = fig.axes
    assert len(axes) == len(PLOT_COLUMNS)
    cov = axes[PLOT_COLUMNS.index("coverage_pct")]
    assert "eps = 1.5" in cov.get_title()
    summary = {d["method"]: d for d in res.summary()}
    for ax, key in zip(axes, PLOT_COLUMNS, strict=True):
        assert ax.get_ylabel(), key  # every panel says what its axis measures
        assert ax.get_legend() is None  # no legend over the data
        heights = [p.get_height() for p in ax.patches]
        want = [summary[m][f"{key}_mean"] for m in res.methods]
        np.testing.assert_allclose(heights, want)  # bars: the table's means
        whiskers = [c for c in ax.containers if type(c).__name__ == "ErrorbarContainer"]
        spans = [c.lines[2][0].get_segments()[0][:, 1] for c in whiskers]
        stds = [summary[m][f"{key}_std"] for m in res.methods]
        np.testing.assert_allclose([s[1] - s[0] for s in spans], 2 * np.array(stds))
    assert len(fig.legends) == 1
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert labels[:2] == ["ours", "ours (raw)"] and "mean ± std over sequences" in labels
    # the raw rows: the colour of their method, hatched; calibration grey
    ours, raw, calib = cov.patches
    assert raw.get_facecolor() == ours.get_facecolor() and raw.get_hatch() and not ours.get_hatch()
    assert calib.get_facecolor()[:3] == pytest.approx((0.6, 0.6, 0.6))


def test_plot_evaluation_jerk_axis_is_linear_unless_it_spans_decades():
    from mrlib.evaluation.results import PLOT_COLUMNS
    from mrlib.viz.plots import plot_evaluation

    k = PLOT_COLUMNS.index("jerk_ratio")
    assert plot_evaluation(_fake_result(1.4)).axes[k].get_yscale() == "linear"
    ax = plot_evaluation(_fake_result(150.0)).axes[k]
    assert ax.get_yscale() == "symlog"
    ticks = list(ax.get_yticks())
    assert ticks[:3] == [0.0, 0.5, 1.0] and 10 in ticks and 100 in ticks and ticks[-1] >= 150
    ax.figure.canvas.draw()
    texts = [t.get_text() for t in ax.get_yticklabels()]
    assert "100" in texts and not any("^" in t for t in texts)  # plain numbers, readable
