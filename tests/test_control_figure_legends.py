"""Legends of the condition-control figures (notebook 03) sit outside the data they explain:
the crossover evidence's legend under its two panels, the restyle view's legends under
its ground-path and share plots, so no bar, dot or path is hidden behind one."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

from types import SimpleNamespace

import numpy as np
import pytest

import mrlib.viz.widgets as W
from mrlib.viz.control_plots import plot_crossover_evidence


def _overlap(a, b) -> bool:
    """Whether two display-space boxes share any area."""
    return a.x0 < b.x1 and b.x0 < a.x1 and a.y0 < b.y1 and b.y0 < a.y1


def _evidence(num_samples: int = 5) -> SimpleNamespace:
    rng = np.random.default_rng(0)
    return SimpleNamespace(
        coarse_label="walk_angry", fine_label="walk_sad", level=4, cutoff_hz=2.4,
        reference="pure samples", low_to_coarse=0.5, low_to_fine=1.4,
        high_to_coarse=0.22, high_to_fine=0.14, per_sample=rng.random((num_samples, 4)),
    )  # fmt: skip


def test_crossover_evidence_legend_says_what_bars_and_dots_are_and_covers_no_panel():
    axes = plot_crossover_evidence(_evidence(5))
    fig = axes[0].figure
    fig.canvas.draw()
    assert all(ax.get_legend() is None for ax in axes)  # none inside a panel
    assert len(fig.legends) == 1
    legend = fig.legends[0]
    texts = [t.get_text() for t in legend.get_texts()]
    assert texts == ["bar: mean over 5 samples", "dot: one crossover sample"]
    box = legend.get_window_extent()
    assert not any(_overlap(box, ax.get_window_extent()) for ax in axes)
    assert all("feature units" in ax.get_ylabel() for ax in axes)


def test_crossover_evidence_legend_also_in_given_axes_without_constrained_layout():
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2)
    plot_crossover_evidence(_evidence(3), axes)
    assert len(fig.legends) == 1 and "3 samples" in fig.legends[0].get_texts()[0].get_text()
    plt.close(fig)


@pytest.fixture
def captured(monkeypatch):
    """The restyle view's figure, kept instead of shown and closed."""
    figs = []
    monkeypatch.setattr(W, "show_figure", lambda out, fig: figs.append(fig))
    monkeypatch.setattr(W, "render_meshes", lambda m, body, frames=None, **kw: np.zeros((8, 8, 3)))
    return figs


def test_restyle_view_puts_its_legends_under_the_plots(sad_wave_model, sad_wave_clips, body,
                                                       captured):  # fmt: skip
    pytest.importorskip("ipywidgets")
    _, update = W.interactive_restyle(sad_wave_model, sad_wave_clips[0], body, frames=2,
                                      render=False)  # fmt: skip
    update()
    fig = captured[-1]
    fig.canvas.draw()
    with_legend = [ax for ax in fig.axes if ax.get_legend() is not None]
    assert len(with_legend) == 2  # the ground paths and the shares
    for ax in with_legend:
        legend, frame = ax.get_legend().get_window_extent(), ax.get_window_extent()
        assert legend.y1 <= frame.y0 + 1, ax.get_title()  # under the axes, not on the data
