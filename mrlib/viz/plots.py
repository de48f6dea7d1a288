"""Pictures of the evaluation metrics: which training frames a generated clip copies, how
well the training timeline is covered, and how quality evolves during training.

* :func:`plot_segmentation` draws the patched-nearest-neighbour (PNN) segmentation of
  ``mrlib.metrics.diversity.global_diversity(..., return_segmentation=True)``: generated frames on
  the x axis, the training frames each segment is matched to on the y axis. A copy of
  the training clip is one long diagonal; a generator that recombines the clip shows
  many short diagonals that jump around.
* :func:`plot_coverage_strip` draws ``mrlib.metrics.coverage.coverage_profile`` as a heat strip
  over the training timeline: for every training window (by its first frame), the
  distance to its nearest generated window, green below the coverage threshold ``eps``
  (covered) and red above it.
* :func:`plot_quality_curve` draws a quantity measured at checkpoints against training
  time, with its target (``bench/time_to_quality.py``).
* :func:`plot_contacts` draws foot-contact labels over time, :func:`plot_evaluation` the
  table of ``mrlib.evaluation.evaluate``.
* :func:`plot_crossover_evidence`, :func:`plot_nearest_sequence`,
  :func:`plot_condition_fidelity` (the measurements of ``mrlib.evaluation.crossover``) and
  :func:`plot_ground_paths` are drawn by ``mrlib.viz.control_plots`` and reachable here.

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
    "save_figure",
    "save_titled_image",
    "plot_contacts",
    "plot_evaluation",
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
            generated clip (``mrlib.metrics.coverage.coverage_profile``); one row per sample.
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
        cb.set_label("mean per-frame feature distance (no unit)", fontsize=8)
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


def save_figure(fig: Any, path: str | Path, *, overwrite: bool = True, **kwargs: Any) -> Path:
    """``fig.savefig`` into ``path`` atomically and never through a symbolic link
    (``mrlib.io.outputs``); the format follows the suffix (PNG without one)."""
    from mrlib.io.outputs import atomic_write

    path = Path(path)
    fmt = path.suffix[1:].lower() or "png"
    return atomic_write(path, lambda fh: fig.savefig(fh, format=fmt, **kwargs), overwrite=overwrite)


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
    return save_figure(fig, path)


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


# y-axis label (with units) of each panel of plot_evaluation.
_EVALUATION_AXES = {
    "coverage_pct": "% of training windows within eps",
    "global_div": "PNN cost (feature distance / frame)",
    "local_div": "nearest-window distance (feature dist.)",
    "skate_pct": "% of contact vertex-frames sliding",
    "jerk_ratio": "mean jerk / training clip's (x)",
    "penetration_cm": "mean depth below floor (cm)",
    "w_root_speed": "W1 to training root speed (m/s)",
    "w_angspeed_legs": "W1 to training leg speed (rad/s)",
}
RAW_SUFFIX = " (raw)"  # evaluate_model(contacts="both"): the raw output beside the cleaned


def _method_styles(methods: list[str], kinds: dict[str, str]) -> dict[str, dict[str, Any]]:
    """Bar style per method: a tab10 colour per model, the colour of its cleaned method
    and a hatch for ``"<method> (raw)"``, grey for calibration rows."""
    from matplotlib import colormaps

    out: dict[str, dict[str, Any]] = {}
    n = 0
    for m in methods:
        base = m.removesuffix(RAW_SUFFIX)
        if kinds[m] == "calibration":
            out[m] = {"facecolor": "0.6", "edgecolor": "0.6", "hatch": ""}
        elif m != base and base in out:
            out[m] = {**out[base], "edgecolor": "0.25", "hatch": "///"}
        else:
            c = colormaps["tab10"](n % 10)
            out[m], n = {"facecolor": c, "edgecolor": c, "hatch": ""}, n + 1
    return {m: {**st, "alpha": 0.55} for m, st in out.items()}


def _readable_log_axis(ax: Any, top: float) -> None:
    """A symlog y axis (0 stays visible) with ticks at 0, 0.5, 1, 2, 5, 10, ... up to
    ``top``, written as plain numbers."""
    from matplotlib.ticker import FixedLocator, FuncFormatter, NullLocator

    ax.set_yscale("symlog", linthresh=1.0, linscale=0.6)
    ticks = [0.0, 0.5, 1.0]
    k = 0
    while ticks[-1] < top:
        ticks.append([2, 5, 10][k % 3] * 10 ** (k // 3))
        k += 1
    ax.yaxis.set_major_locator(FixedLocator(ticks))
    ax.yaxis.set_minor_locator(NullLocator())
    ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))


def plot_evaluation(result: Any, path: str | Path | None = None, *, overwrite: bool = True):
    """The main metrics of a ``mrlib.evaluation.results.EvaluationResult`` per method, in
    the statistics of its Markdown table: bars the mean over sequences, whiskers ± the
    (population) standard deviation over sequences, dots the sequences. Models in
    colour (``"<method> (raw)"`` hatched in its method's colour), calibration rows in
    grey; the legend sits below the panels. The jerk ratio gets a symmetric-log axis
    (with ticks at 0, 0.5, 1, 2, 5, ...) only when it spans more than 20x. Returns the
    matplotlib Figure; saved to ``path`` when given (an existing file is replaced only
    with ``overwrite``)."""
    from matplotlib.figure import Figure  # no pyplot: works headless, no global state
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    from mrlib.evaluation.results import CALIB_PREFIX, METRIC_COLUMNS, PLOT_COLUMNS

    methods = result.methods
    kinds = {r["method"]: r["kind"] for r in result.rows}
    headers = {k: h for k, h, _ in METRIC_COLUMNS}
    styles = _method_styles(methods, kinds)
    fig = Figure(figsize=(16, 8.2), layout="constrained")
    axes = fig.subplots(2, 4)
    rng = np.random.default_rng(0)  # x jitter of the dots only
    x = np.arange(len(methods))
    for ax, key in zip(axes.ravel(), PLOT_COLUMNS, strict=True):
        top = 0.0
        for i, m in enumerate(methods):
            v = np.array([r.get(key, np.nan) for r in result.rows if r["method"] == m], float)
            v = v[np.isfinite(v)]
            if not len(v):
                continue
            ax.bar(i, v.mean(), width=0.7, **styles[m])
            lo, hi = v.mean() - v.std(), v.mean() + v.std()
            if key.endswith("_pct"):  # a share: the whisker stops at what is possible
                lo, hi = max(lo, 0.0), min(hi, 100.0)
            yerr = [[v.mean() - lo], [hi - v.mean()]]
            ax.errorbar(i, v.mean(), yerr=yerr, color="0.2", capsize=3, lw=1, zorder=2)
            ax.scatter(i + rng.uniform(-0.18, 0.18, len(v)), v, s=14, color="k", zorder=3)
            top = max(top, float(v.max()), float(hi))
        title = headers[key]
        if key == "coverage_pct":
            title += f" (eps = {result.settings.eps:g})"
        ax.set_title(title, fontsize=10)
        ax.set_ylabel(_EVALUATION_AXES.get(key, headers[key]), fontsize=8)
        if key == "jerk_ratio" and top > 20.0:  # a noisy clip can be x100: 0 must stay visible
            _readable_log_axis(ax, top)
        ax.set_xticks(
            x,
            [m.replace(CALIB_PREFIX, "") for m in methods],
            rotation=35,
            ha="right",
            fontsize=8,
        )
        ax.grid(axis="y", alpha=0.3)
    handles = [Patch(label=m, **styles[m]) for m in methods if kinds[m] != "calibration"]
    if any(kinds[m] == "calibration" for m in methods):
        grey = styles[next(m for m in methods if kinds[m] == "calibration")]
        handles.append(Patch(label="calibration rows (real or built motion)", **grey))
    handles += [
        Line2D([], [], color="0.2", marker="_", ms=10, label="mean ± std over sequences"),
        Line2D([], [], color="k", marker="o", ms=4, lw=0, label="one sequence"),
    ]
    fig.legend(
        handles=handles,
        loc="outside lower center",
        ncols=min(len(handles), 5),
        fontsize=9,
        frameon=False,
    )
    if path is not None:
        save_figure(fig, path, dpi=110, overwrite=overwrite)
    return fig
