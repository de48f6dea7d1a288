"""Pictures of the evaluation metrics: which training frames a generated clip copies, how
well the training timeline is covered, and how quality evolves during training.

* :func:`plot_segmentation` draws the patched-nearest-neighbour (PNN) segmentation of
  ``mrlib.metrics.paper.global_diversity(..., return_segmentation=True)``: generated frames on
  the x axis, the training frames each segment is matched to on the y axis. A copy of
  the training clip is one long diagonal; a generator that recombines the clip shows
  many short diagonals that jump around.
* :func:`plot_coverage_strip` draws ``mrlib.metrics.paper.coverage_profile`` as a heat strip
  over the training timeline: for every training window (by its first frame), the
  distance to its nearest generated window, green below the coverage threshold ``eps``
  (covered) and red above it.
* :func:`plot_quality_curve` draws a quantity measured at checkpoints against training
  time, with its target (``bench/time_to_quality.py``).
* :func:`plot_crossover_evidence`, :func:`plot_nearest_sequence` and
  :func:`plot_condition_fidelity` draw the measurements of ``mrlib.evaluation.crossover``;
  :func:`plot_contacts` draws foot-contact labels over time.

Like ``mrlib.viz.render``, this module imports matplotlib only inside its functions; every
function draws into a given Axes or a new figure and returns the Axes.

Dimension letters (``mrlib`` glossary): T frames, B samples, N windows, K labels.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from mrlib.errors import MotionValueError
from mrlib.representation.skeleton import CONTACT_NAMES, NUM_CONTACTS

__all__ = [
    "segmentation_frame_map",
    "plot_segmentation",
    "plot_coverage_strip",
    "plot_quality_curve",
    "save_titled_image",
    "plot_crossover_evidence",
    "plot_nearest_sequence",
    "plot_condition_fidelity",
    "plot_contacts",
    "plot_evaluation",
    "plot_ground_paths",
]

# Colours of consecutive segments (tab10 without its grey, which reads as "missing").
_SEGMENT_COLOURS = (
    "tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple",
    "tab:brown", "tab:pink", "tab:olive", "tab:cyan",
)  # fmt: skip


def _check_int(name: str, value: Any, minimum: int = 1) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise MotionValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def segmentation_frame_map(
    segmentation: Sequence[tuple[int, int, int]], num_frames: int, num_ref_frames: int | None = None
) -> np.ndarray:
    """The training frame every generated frame is matched to, ``(T_gen,)`` int.

    Args:
        segmentation: ``(gen_start, gen_stop, ref_start)`` triples as returned by
            ``global_diversity(..., return_segmentation=True)``: generated frames
            ``[gen_start, gen_stop)`` copy training frames from ``ref_start`` on. They
            must tile ``[0, num_frames)`` in order, without gaps or overlaps.
        num_frames: ``T_gen``, frames of the generated clip.
        num_ref_frames: ``T_ref``; when given, every matched frame must lie in
            ``[0, T_ref)``.

    Returns:
        ``frame_map`` with ``frame_map[t] = ref_start + (t - gen_start)`` for the segment
        holding ``t``; ``reference[frame_map]`` is the nearest-neighbour "collage" of the
        generated clip.
    """
    T = _check_int("num_frames", num_frames)
    out = np.empty(T, dtype=np.int64)
    pos = 0
    for k, seg in enumerate(segmentation):
        try:
            a, b, r = (int(v) for v in seg)
        except (TypeError, ValueError):
            raise MotionValueError(
                f"segment {k} must be a (gen_start, gen_stop, ref_start) triple, got {seg!r}"
            ) from None
        if a != pos or b <= a:
            raise MotionValueError(
                f"segment {k} = {(a, b, r)} does not continue the tiling at frame {pos} "
                "(segments must be in order, non-empty, without gaps or overlaps)"
            )
        if r < 0 or (num_ref_frames is not None and r + (b - a) > num_ref_frames):
            raise MotionValueError(
                f"segment {k} = {(a, b, r)} matches training frames {r}..{r + b - a - 1}, "
                f"outside [0, {num_ref_frames if num_ref_frames is not None else 'T_ref'})"
            )
        if b > T:
            raise MotionValueError(f"segment {k} = {(a, b, r)} ends after frame {T}")
        out[a:b] = np.arange(r, r + b - a)
        pos = b
    if pos != T:
        raise MotionValueError(f"the segmentation covers frames [0, {pos}) of {T}")
    return out


def _new_axes(ax: Any, figsize: tuple[float, float]):
    if ax is not None:
        return ax
    import matplotlib.pyplot as plt

    _, ax = plt.subplots(figsize=figsize, layout="constrained")
    return ax


def plot_segmentation(
    segmentation: Sequence[tuple[int, int, int]],
    num_frames: int,
    num_ref_frames: int,
    ax: Any = None,
    *,
    fps: float | None = None,
    title: str | None = None,
):
    """Which training frames each segment of a generated clip copies (PNN).

    Args:
        segmentation: ``(gen_start, gen_stop, ref_start)`` triples tiling the generated
            clip (see :func:`segmentation_frame_map`).
        num_frames: ``T_gen``, frames of the generated clip.
        num_ref_frames: ``T_ref``, frames of the training clip.
        ax: a matplotlib Axes; a new figure when None.
        fps: label the axes in seconds instead of frames.
        title: default: the number of segments.

    Returns:
        The Axes. Segment k is a diagonal from ``(gen_start, ref_start)`` to
        ``(gen_stop - 1, ref_start + gen_stop - gen_start - 1)`` over a lightly shaded
        band of the generated frames it covers; the dotted lines mark the training clip.
    """
    T_ref = _check_int("num_ref_frames", num_ref_frames)
    segmentation_frame_map(segmentation, num_frames, T_ref)  # validates the tiling
    if fps is not None and not (np.isfinite(fps) and fps > 0):
        raise MotionValueError(f"fps must be a positive number, got {fps!r}")
    s = 1.0 / fps if fps is not None else 1.0
    ax = _new_axes(ax, (8.0, 3.6))
    for k, (a, b, r) in enumerate(segmentation):
        c = _SEGMENT_COLOURS[k % len(_SEGMENT_COLOURS)]
        ax.axvspan(a * s, b * s, color=c, alpha=0.10, lw=0)
        ax.plot(
            [a * s, (b - 1) * s], [r * s, (r + b - a - 1) * s], color=c, lw=3.0,
            solid_capstyle="round", label=f"gen {a}-{b - 1} <- train {r}-{r + b - a - 1}",
        )  # fmt: skip
    for y in (0, T_ref - 1):
        ax.axhline(y * s, color="0.5", lw=0.8, ls=":")
    unit = "s" if fps is not None else "frame"
    ax.set_xlim(0, num_frames * s)
    ax.set_ylim(-0.03 * T_ref * s, 1.03 * T_ref * s)
    ax.set_xlabel(f"generated clip ({unit})")
    ax.set_ylabel(f"training clip ({unit})")
    n = len(segmentation)
    ax.set_title(title if title is not None else f"nearest training segments ({n} segments)")
    return ax


def plot_coverage_strip(
    profile: Any,
    eps: float,
    ax: Any = None,
    *,
    window: int | None = None,
    row_labels: Sequence[str] | None = None,
    fps: float | None = None,
    title: str | None = None,
    colorbar: bool = True,
):
    """Heat strip of nearest-neighbour distances over the training timeline.

    Args:
        profile: ``(N,)`` or ``(B, N)``: for each of the ``N = T_ref - window + 1``
            training windows (by first frame), the distance to the closest window of a
            generated clip (``mrlib.metrics.paper.coverage_profile``); one row per sample.
        eps: the coverage threshold; windows closer than it are covered. The colour
            scale runs from green (0) through yellow (``eps``) to red (``2 eps`` and
            beyond).
        ax: a matplotlib Axes; a new figure when None.
        window: the window length ``T_c``, for the axis label.
        row_labels: one label per row; default ``"sample i"``. Each gets the row's
            coverage in percent appended.
        fps: label the timeline in seconds instead of frames.
        title: default: the mean coverage over the rows.
        colorbar: add a colour bar with ``eps`` marked.

    Returns:
        The Axes (its image is ``ax.images[0]``, holding the profile as given).
    """
    from matplotlib.colors import TwoSlopeNorm

    if not (np.isfinite(eps) and eps > 0):
        raise MotionValueError(f"eps must be a positive number, got {eps!r}")
    p = np.asarray(profile, dtype=np.float64)
    if p.ndim == 1:
        p = p[None]
    if p.ndim != 2 or p.shape[1] == 0 or p.shape[0] == 0:
        raise MotionValueError(f"profile must have shape (N,) or (B, N), got {np.shape(profile)}")
    if not np.isfinite(p).all() or (p < 0).any():
        raise MotionValueError("profile must hold finite, non-negative distances")
    if row_labels is not None and len(row_labels) != len(p):
        raise MotionValueError(f"got {len(row_labels)} row labels for {len(p)} rows")
    if fps is not None and not (np.isfinite(fps) and fps > 0):
        raise MotionValueError(f"fps must be a positive number, got {fps!r}")
    B, N = p.shape
    covered = (p < eps).mean(1)  # (B,)
    s = 1.0 / fps if fps is not None else 1.0
    ax = _new_axes(ax, (8.0, 0.9 + 0.32 * B))
    # A fixed scale (0 .. 2 eps) keeps strips comparable; farther windows saturate red.
    norm = TwoSlopeNorm(vmin=0.0, vcenter=eps, vmax=2.0 * eps)
    im = ax.imshow(
        p, aspect="auto", cmap="RdYlGn_r", norm=norm, interpolation="nearest",
        extent=(0, N * s, B - 0.5, -0.5),
    )  # fmt: skip
    labels = list(row_labels) if row_labels is not None else [f"sample {i}" for i in range(B)]
    ax.set_yticks(
        range(B), [f"{lab} ({100 * c:.0f}%)" for lab, c in zip(labels, covered, strict=True)]
    )
    unit = "s" if fps is not None else "frame"
    what = f"{window}-frame window" if window is not None else "window"
    ax.set_xlabel(f"training clip: first {unit} of each {what}")
    ax.set_title(
        title
        if title is not None
        else f"coverage {100 * covered.mean():.1f}% (green: nearest generated window < eps = {eps:g})"
    )
    if colorbar:
        extend = "max" if p.max() > 2.0 * eps else "neither"
        cb = ax.figure.colorbar(im, ax=ax, pad=0.01, fraction=0.04, extend=extend)
        cb.ax.axhline(eps, color="k", lw=1.5)
        cb.set_label("distance", fontsize=8)
    return ax


def plot_quality_curve(
    times: Any,
    values: Any,
    target: float | None = None,
    ax: Any = None,
    *,
    higher_is_better: bool = True,
    label: str | None = None,
    ylabel: str | None = None,
    reached_at: float | None = None,
):
    """A quality measure at training checkpoints against wall time, with its target.

    Args:
        times: ``(K,)`` training time of each checkpoint (seconds).
        values: ``(K,)`` the measure there.
        target: the target value, drawn as a dashed line; the side that fails it is
            shaded.
        higher_is_better: which side of ``target`` passes.
        label: legend entry of the curve.
        reached_at: mark the time the target (of all measures) was first met.

    Returns:
        The Axes.
    """
    t = np.asarray(times, dtype=np.float64)
    v = np.asarray(values, dtype=np.float64)
    if t.ndim != 1 or v.shape != t.shape or len(t) == 0:
        raise MotionValueError(
            f"times and values must be 1-D of the same non-zero length, got {t.shape}, {v.shape}"
        )
    ax = _new_axes(ax, (6.0, 3.4))
    ax.plot(t, v, "o-", ms=3, label=label)
    if target is not None:
        ax.axhline(target, color="k", ls="--", lw=1)
        lo, hi = ax.get_ylim()
        if higher_is_better:
            ax.axhspan(min(lo, target), target, color="tab:red", alpha=0.06, lw=0)
        else:
            ax.axhspan(target, max(hi, target), color="tab:red", alpha=0.06, lw=0)
        ax.set_ylim(lo, hi)
    if reached_at is not None:
        ax.axvline(reached_at, color="tab:green", lw=1.5)
    ax.set_xlabel("training time (s)")
    if ylabel:
        ax.set_ylabel(ylabel)
    ax.grid(alpha=0.3)
    return ax


def save_titled_image(img: np.ndarray, title: str, path: str | Path) -> Path:
    """Save an ``(H, W, 3)`` image (a render) as a PNG with ``title`` above it."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    img = np.asarray(img)
    if img.ndim != 3:
        raise MotionValueError(f"expected an (H, W, 3) image, got shape {img.shape}")
    h, w = img.shape[:2]
    fig = Figure(figsize=(w / 100, h / 100 + 0.4), dpi=100)
    ax = fig.add_axes((0, 0, 1, h / (h + 40)))
    ax.imshow(img)
    ax.axis("off")
    fig.suptitle(title, fontsize=12, y=0.99)
    fig.savefig(path)
    return Path(path)


# -- condition control (mrlib.evaluation.crossover) ------------------------------------------------------
def plot_crossover_evidence(evidence: Any, axes: Any = None):
    """Bars per band of a ``mrlib.evaluation.crossover.CrossoverEvidence``: distance to the coarse
    label A and to the fine label B, with the per-sample values as dots. The bands have
    their own scales.

    Args:
        axes: two matplotlib Axes (low-pass, residual); a new figure when None.
    Returns:
        the two Axes.
    """
    import matplotlib.pyplot as plt

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
            ax.scatter(j + jitter, ps[:, j], s=7, color="k", zorder=3)
        ax.set_xticks([0, 1], [f"A = {a}\n(coarse, 1-{e.level})", f"B = {b}\n(fine)"])
        ax.set_title(f"{title}\n({note})", fontsize=9)
        ax.set_ylabel(f"distance to {e.reference}")
    axes[0].figure.suptitle(
        f"crossover at level {e.level}: bands split at {e.cutoff_hz:.1f} Hz",
        fontsize=10,
    )
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


def plot_contacts(contacts: np.ndarray, fps: float, ax: Any = None, *, title: str | None = None):
    """Contact labels as six horizontal bars over time (seconds).

    Args:
        contacts: ``(T, 6)`` labels (values in [0, 1] are shaded).
        fps: frames per second.
        ax: a matplotlib Axes; a new figure when None.
    Returns:
        The Axes.
    """
    import matplotlib.pyplot as plt

    c = np.asarray(contacts, dtype=np.float32)
    if c.ndim != 2 or c.shape[1] != NUM_CONTACTS:
        raise MotionValueError(f"contacts must have shape (T, {NUM_CONTACTS}), got {c.shape}")
    if ax is None:
        _, ax = plt.subplots(figsize=(8, 2.4))
    T = len(c)
    ax.imshow(
        c.T,
        aspect="auto",
        interpolation="nearest",
        cmap="Greys",
        vmin=0,
        vmax=1,
        extent=(0, T / fps, NUM_CONTACTS - 0.5, -0.5),
    )
    ax.set_yticks(range(NUM_CONTACTS), [n.replace("_", " ") for n in CONTACT_NAMES])
    ax.axhline(2.5, color="tab:red", lw=0.8)  # left foot above, right foot below
    ax.set_xlabel("time (s)")
    if title:
        ax.set_title(title)
    return ax


def plot_evaluation(result: Any, path: str | Path | None = None):
    """Bars (mean over sequences) and dots (sequences) per method for the main metrics of
    a ``mrlib.evaluation.evaluate.EvaluationResult``; calibration rows in grey. Returns the
    matplotlib Figure; saved to ``path`` when given."""
    from matplotlib import colormaps
    from matplotlib.figure import Figure  # no pyplot: works headless, no global state

    from mrlib.evaluation.evaluate import CALIB_PREFIX, METRIC_COLUMNS, PLOT_COLUMNS

    methods = result.methods
    kinds = {r["method"]: r["kind"] for r in result.rows}
    headers = {k: h for k, h, _ in METRIC_COLUMNS}
    cmap = colormaps["tab10"]
    colors, model_i = [], 0
    for m in methods:
        if kinds[m] == "calibration":
            colors.append("0.6")
        else:
            colors.append(cmap(model_i % 10))
            model_i += 1
    fig = Figure(figsize=(16, 7.5), layout="constrained")
    axes = fig.subplots(2, 4)
    rng = np.random.default_rng(0)  # x jitter of the dots only
    x = np.arange(len(methods))
    for ax, key in zip(axes.ravel(), PLOT_COLUMNS, strict=True):
        for i, m in enumerate(methods):
            v = np.array([r.get(key, np.nan) for r in result.rows if r["method"] == m], float)
            v = v[np.isfinite(v)]
            if not len(v):
                continue
            ax.bar(i, v.mean(), color=colors[i], alpha=0.55, width=0.7)
            ax.scatter(i + rng.uniform(-0.18, 0.18, len(v)), v, s=14, color="k", zorder=3)
        ax.set_title(headers[key], fontsize=10)
        if key == "jerk_ratio":  # spans decades (a noisy bow: x100); 0 must stay visible
            ax.set_yscale("symlog", linthresh=1.0)
        ax.set_xticks(
            x,
            [m.replace(CALIB_PREFIX, "") for m in methods],
            rotation=35,
            ha="right",
            fontsize=8,
        )
        ax.grid(axis="y", alpha=0.3)
    if any(kinds[m] == "calibration" for m in methods):
        fig.suptitle("Methods (colour) and calibration rows (grey); dots: sequences", fontsize=11)
    if path is not None:
        fig.savefig(path, dpi=110)
    return fig


def plot_ground_paths(
    path: Any, motions: Any, body: Any = None, ax: Any = None, *, title: str | None = None
):
    """Top-down view of a target path (dashed) and the pelvis tracks of ``motions``
    (a ``{name: Motion}`` dict or a list), with each motion's planted heels as dots.

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
                label=f"{name}: {100 * err['mean_m']:.1f} cm mean, {100 * err['max_m']:.0f} cm max")  # fmt: skip
        if m.contacts is not None:
            for v in (2, 5):  # heels
                down = m.contacts[:, v] > 0.5
                ax.plot(feet[down, v, 0], feet[down, v, 2], ".", ms=2, color=colour, alpha=0.5)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("z (m)")
    # below the axes: inside, a legend covers part of a path that fills the plot
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.1), frameon=False)
    if title:
        ax.set_title(title, fontsize=10)
    return ax
