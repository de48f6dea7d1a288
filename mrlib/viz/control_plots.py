"""Pictures of condition control: the measurements of ``mrlib.evaluation.crossover`` and
``mrlib.evaluation.fidelity`` (:func:`plot_crossover_evidence`,
:func:`plot_nearest_sequence`, :func:`plot_condition_fidelity`) and the ground paths of
path following (:func:`plot_ground_paths`, ``mrlib.sampling.constraints``).

Like ``mrlib.viz.plots``, whose names these are too (``mrlib.viz.plots.plot_nearest_sequence``),
this module imports matplotlib only inside its functions; every function draws into given
Axes or a new figure and returns them.

Dimension letters (``mrlib`` glossary): N windows, K labels.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mrlib.errors import MotionValueError

__all__ = [
    "plot_crossover_evidence",
    "plot_nearest_sequence",
    "plot_condition_fidelity",
    "plot_ground_paths",
]


def plot_crossover_evidence(evidence: Any, axes: Any = None):
    """Bars per band of a ``mrlib.evaluation.crossover.CrossoverEvidence``: distance to the coarse
    label A and to the fine label B, with the per-sample values as dots. The bands have
    their own scales.

    Args:
        axes: two matplotlib Axes (low-pass, residual); a new figure when None.
    Returns:
        the two Axes; the legend (bar = mean, dot = one sample) is the figure's, under
        the panels.
    """
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    e = evidence
    if axes is None:
        _, axes = plt.subplots(1, 2, figsize=(9, 3.6), layout="constrained")
    axes = np.atleast_1d(axes)
    if len(axes) != 2:
        raise MotionValueError("plot_crossover_evidence needs two axes (one per band)")
    a, b = e.coarse_label, e.fine_label
    panels = (
        ("low", "low-pass band: per-frame NN distance", "expected: closer to A"),
        ("high", "residual band: RMS-profile distance", "expected: closer to B"),
    )
    for k, (ax, (key, title, note)) in enumerate(zip(axes, panels, strict=True)):
        vals = [getattr(e, f"{key}_to_coarse"), getattr(e, f"{key}_to_fine")]
        ax.bar([0, 1], vals, 0.6, color=["tab:blue", "tab:orange"])
        ps = e.per_sample[:, 2 * k : 2 * k + 2]
        jitter = np.linspace(-0.15, 0.15, len(ps)) if len(ps) > 1 else np.zeros(1)
        for j in range(2):
            ax.scatter(j + jitter, ps[:, j], s=7, color="k", zorder=3,
                       label="dot: one crossover sample" if j == 0 else None)  # fmt: skip
        ax.set_xticks([0, 1], [f"A = {a}\n(coarse, 1-{e.level})", f"B = {b}\n(fine)"])
        ax.set_title(f"{title}\n({note})", fontsize=9)
        # 6D rotation features (mrlib.metrics.windows.metric_features) have no physical unit
        ax.set_ylabel(f"distance to {e.reference}\n(6D-rotation feature units)")
    fig = axes[0].figure
    fig.suptitle(f"crossover at level {e.level}: bands split at {e.cutoff_hz:.1f} Hz", fontsize=10)
    # under the panels: a legend inside one of them would cover its bars or dots
    handles, labels = axes[0].get_legend_handles_labels()
    handles = [Patch(color="0.6"), *handles]
    labels = [f"bar: mean over {len(e.per_sample)} samples", *labels]
    constrained = type(fig.get_layout_engine()).__name__ == "ConstrainedLayoutEngine"
    loc = "outside lower center" if constrained else "lower center"
    fig.legend(handles, labels, loc=loc, ncol=2, fontsize=8, frameon=False)
    return axes


_STRIP_COLOURS = (
    "tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple",
    "tab:brown", "tab:pink", "tab:gray", "tab:olive", "tab:cyan",
)  # fmt: skip


def plot_nearest_sequence(strip: Any, axes: Any = None, *, title: str | None = None):
    """Two panels over generated time for a ``mrlib.evaluation.crossover.NearestSequenceStrip``: a
    colour band naming the nearest training sequence of every window, and where in that
    sequence the window is (start frame, seconds). Diagonal runs in the lower panel are
    stretches that follow one training clip.

    Args:
        strip: from ``mrlib.evaluation.crossover.nearest_sequence_strip``.
        axes: two matplotlib Axes (band, position); a new figure when None.
    Returns:
        the two Axes.
    """
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    if axes is None:
        _, axes = plt.subplots(
            2, 1, figsize=(9, 3.4), sharex=True, gridspec_kw={"height_ratios": [1, 3]}
        )
    axes = np.atleast_1d(axes)
    if len(axes) != 2:
        raise MotionValueError("plot_nearest_sequence needs two axes")
    fps = strip.fps if np.isfinite(strip.fps) else 1.0
    unit = "s" if np.isfinite(strip.fps) else "frames"
    K, N = len(strip.names), len(strip.index)
    colours = [_STRIP_COLOURS[k % len(_STRIP_COLOURS)] for k in range(K)]
    t = np.arange(N) / fps
    band, pos = axes
    band.imshow(
        strip.index[None],
        aspect="auto",
        cmap=ListedColormap(colours),
        vmin=-0.5,
        vmax=K - 0.5,
        interpolation="nearest",
        extent=(0, N / fps, 0, 1),
    )
    band.set_yticks([])
    band.tick_params(labelbottom=False)
    pos.set_xlim(0, N / fps)
    band.set_title(
        title or f"nearest training sequence of every {strip.window}-frame window", fontsize=10
    )
    for k in range(K):
        on = strip.index == k
        if on.any():
            pos.scatter(t[on], strip.start[on] / fps, s=6, color=colours[k])
    pos.set_xlabel(f"generated window start ({unit})")
    pos.set_ylabel(f"position in source ({unit})")
    shares = strip.shares()
    handles = [
        Patch(color=colours[k], label=f"{nm} [{lab}] {100 * shares[nm]:.0f}%")
        for k, (nm, lab) in enumerate(zip(strip.names, strip.labels, strict=True))
    ]
    pos.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    return axes


def plot_condition_fidelity(fidelity: Any, ax: Any = None):
    """The confusion matrix of a ``mrlib.evaluation.crossover.ConditionFidelity`` as an image, shares
    in %: rows the requested label, columns the label of the nearest training window."""
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=(4.6, 3.8))
    labels = fidelity.labels
    K = len(labels)
    ax.imshow(100 * fidelity.confusion, cmap="Blues", vmin=0, vmax=100)
    for i in range(K):
        for j in range(K):
            v = 100 * fidelity.confusion[i, j]
            ax.text(j, i, f"{v:.0f}", ha="center", va="center",
                    color="white" if v > 60 else "black", fontsize=9)  # fmt: skip
    ax.set_xticks(range(K), labels, rotation=30, ha="right")
    ax.set_yticks(range(K), labels)
    ax.set_xlabel("label of the nearest training window")
    ax.set_ylabel("requested label")
    ax.set_title(f"condition fidelity {100 * fidelity.overall:.1f}% (diagonal, %)", fontsize=10)
    return ax


def plot_ground_paths(
    path: Any, motions: Any, body: Any = None, ax: Any = None, *, title: str | None = None
):
    """Top-down view of a target path (dashed) and the pelvis tracks of ``motions``
    (a ``{name: Motion}`` dict or a list), with each motion's planted heels as dots; each
    legend entry gives ``mrlib.sampling.constraints.path_error``'s mean distance off the
    path, mean distance from the schedule and the share of the path walked.

    Args:
        path: a ``mrlib.sampling.constraints.GroundPath`` or a spec (``"circle:2"``).
        body: body model for the pelvis and feet (default: mrlib's).
    Returns:
        The Axes (x to the right, z up the page, metres, equal aspect), its legend
        under the plot.
    """
    import matplotlib.pyplot as plt

    from mrlib.metrics.plausibility import motion_kinematics
    from mrlib.sampling.constraints import parse_path, path_error

    path = parse_path(path)
    items = motions.items() if isinstance(motions, dict) else enumerate(motions)
    if ax is None:
        _, ax = plt.subplots(figsize=(6, 6))
    q = np.vstack([path.points, path.points[:1]]) if path.closed else path.points
    ax.plot(q[:, 0], q[:, 1], "k--", lw=1.2, label=f"target: {path.name}")
    for k, (name, m) in enumerate(items):
        joints, feet = motion_kinematics(m, body)
        colour = f"C{k}"
        err = path_error(m, path, body)
        ax.plot(joints[:, 0, 0], joints[:, 0, 2], color=colour, lw=1.5,
                label=f"{name}: {100 * err['lateral_mean_m']:.1f} cm off the path (mean), "
                      f"{100 * err['mean_m']:.0f} cm from its schedule, {err['progress']:.2f} "
                      f"{'laps' if path.closed else 'of the path'}")  # fmt: skip
        if m.contacts is not None:
            for v in (2, 5):  # heels
                down = m.contacts[:, v] > 0.5
                ax.plot(feet[down, v, 0], feet[down, v, 2], ".", ms=2, color=colour, alpha=0.5)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("z (m)")
    # below the axes and their x label (an offset in points, whatever the axes' height):
    # inside, a legend covers part of a path that fills the plot
    from matplotlib.transforms import offset_copy

    below = offset_copy(ax.transAxes, fig=ax.figure, y=-34, units="points")
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, 0.0), bbox_transform=below,
              frameon=False)  # fmt: skip
    if title:
        ax.set_title(title, fontsize=10)
    return ax
