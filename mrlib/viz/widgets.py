"""Interactive views for notebooks (ipywidgets): the label crossover, with a mesh render
and the nearest-sequence strip of every generated sample, and the restyling of a clip.
The views of the constraints (path following, body parts, in-betweening) are in
``mrlib.viz.constraint_views``; their names are reachable from here too
(``mrlib.viz.widgets.interactive_path``).

The measurements behind the views are ``mrlib.evaluation.crossover``'s and
``mrlib.evaluation.restyle_evidence``'s, their pictures ``mrlib.viz.plots``' and
``mrlib.viz.render``'s; these modules only wire them to controls, with the plumbing the
views share in ``mrlib.viz.widget_kit``.

Every view has a status line under its controls. While a redraw runs it reads
"drawing..." and the controls are disabled (some redraws fit noise for seconds); then it
reads what the picture shows, updated on every redraw. An invalid value (NaN, out of
range) is reported there and the last good picture stays. The "3D player" toggle shows
the current sample playable and rotatable (``mrlib.viz.render.play_motion``: pyvista's trame
backend in a live JupyterLab, an animated GIF where there is none).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from mrlib.errors import MotionValueError, check_text
from mrlib.evaluation.crossover import check_crossover_level, crossover_blend
from mrlib.evaluation.fidelity import (
    NearestSequenceStrip,
    nearest_sequence_strip,
    reference_features,
)
from mrlib.representation.body import resolve_body
from mrlib.representation.motion import Motion
from mrlib.sampling.generation import generate
from mrlib.sampling.sampler import FINE_NOISE, GUIDANCE, Sampler
from mrlib.viz.control_plots import plot_nearest_sequence
from mrlib.viz.meshes import crop_to_bodies, evenly_spaced_frames, render_meshes
from mrlib.viz.widget_kit import (
    BUSY,
    WIDE,
    checked,
    show_figure,
    strict,
    view_arguments,
    view_box,
    view_parts,
    wire,
)

__all__ = [
    "CrossoverView",
    "interactive_crossover",
    "crossover_title",
    "RestyleView",
    "interactive_restyle",
]


@dataclass
class CrossoverView:
    """What one call of the interactive view made."""

    motion: Motion
    weights: np.ndarray  # (L, K) per-level label weights used (mrlib.Condition.weights)
    strip: NearestSequenceStrip
    image: np.ndarray | None  # (H, W, 3) mesh render, None when rendering is off
    title: str


def crossover_title(coarse: str, fine: str, weight: float, level: int, levels: int,
                    seed: int) -> str:  # fmt: skip
    """The title of a crossover: ``coarse`` at levels ``1..level``, at the finer ones
    ``(1 - weight) * coarse + weight * fine``. One label when the two agree or the weight
    is 0 (nothing of ``fine`` reaches the sample)."""
    if coarse == fine or weight == 0.0:
        return f"'{coarse}' at every level (seed {seed})"
    mix = fine if weight == 1.0 else f"{1 - weight:.2f} {coarse} + {weight:.2f} {fine}"
    return (f"coarse '{coarse}' at levels 1-{level}, fine '{mix}' at levels "
            f"{level + 1}-{levels} (seed {seed})")  # fmt: skip


# -- the views ---------------------------------------------------------------------------------
@view_arguments(
    coarse=lambda n, v: check_text(n, v, optional=True),
    fine=lambda n, v: check_text(n, v, optional=True),
)
def interactive_crossover(
    model: Any,
    body: Any = None,
    *,
    frames: int = 5,
    length: int | None = None,
    window: int = 30,
    render: bool = True,
    coarse: str | None = None,
    fine: str | None = None,
    level: int | None = None,
) -> tuple[Any, Callable[[], CrossoverView]]:
    """An ipywidgets UI for label crossover.

    Controls: *coarse* label (levels ``1..i``), *fine* label (levels ``i+1..L``), the
    crossover level ``i``, the seed, and *fine weight* ``w`` in [0, 1]: the fine levels get
    the condition ``(1 - w) * coarse + w * fine`` (FiLM is linear in the condition, so this
    interpolates the two labels' embeddings; ``mrlib.Condition.blend``), the coarse
    levels stay pure. ``w = 1`` is the plain crossover of the paper, ``w = 0`` the coarse
    label alone; one number per control keeps the UI readable (per-level weights are
    available through ``generate(model, Condition.blend(a, b, [w_1, ..., w_L]))``).
    *fine noise* and *guidance* are this view's ``mrlib.Sampler`` settings (the paper's
    sampler at first): a lower fine noise is smoother and carries less of the fine
    label's detail; guidance above 0 exaggerates the labels
    (``mrlib.sampling.generation.guided_weights``).

    Every change regenerates the sample and redraws, into an ``Output`` widget, a mesh
    render of ``frames`` frames (``mrlib.viz.render.render_meshes``) titled with the labels
    and the nearest-sequence strip (``mrlib.viz.control_plots.plot_nearest_sequence``); the
    status line shows the title (:func:`crossover_title`) and the share of each label
    among the nearest windows.

    Args:
        model: a ``GenerativeModel`` with at least two levels.
        body: body model for rendering (default ``load_body_model()`` when rendering).
        frames: mesh snapshots per render.
        length: frames per sample; default the longest training clip.
        window: window of the nearest-sequence strip.
        render: draw the mesh view (off: only the strip, e.g. without pyvista).
        coarse, fine, level: initial control values (default: the first label, the
            last label, ``L // 2``).
    Returns:
        ``(widget, update)``: the ``VBox`` to display and the callback; ``update()``
        regenerates with the current control values and returns a :class:`CrossoverView`
        (an invalid control value raises ``MotionValueError``, also shown in the status).
    """
    import ipywidgets as w
    import matplotlib.pyplot as plt

    L = model.num_levels
    if L < 2:
        raise MotionValueError("a crossover needs a model with at least two levels")
    if len(model.labels) < 1:
        raise MotionValueError("the model has no labels")
    if render:
        body = resolve_body(body)
    length = int(model.lengths[:, -1].max()) if length is None else int(length)
    references = reference_features(model)  # computed once, reused by every update
    labels = list(model.labels)

    first = [model.labels[model.label_index(x)] for x in (coarse or labels[0], fine or labels[-1])]
    level = max(1, L // 2) if level is None else check_crossover_level(model, level)
    coarse = w.Dropdown(options=labels, value=first[0], description="coarse", style=WIDE)
    fine = w.Dropdown(options=labels, value=first[1], description="fine", style=WIDE)
    level = strict(w.IntSlider)(value=level, min=1, max=L - 1, description="crossover i",
                        continuous_update=False, style=WIDE)  # fmt: skip
    seed = strict(w.BoundedIntText)(value=0, min=0, max=2**31 - 1, description="seed", style=WIDE)
    weight = strict(w.FloatSlider)(value=1.0, min=0.0, max=1.0, step=0.05, description="fine weight",
                           continuous_update=False, style=WIDE)  # fmt: skip
    noise = strict(w.FloatSlider)(
        value=FINE_NOISE, min=0.0, max=max(1.0, FINE_NOISE), step=0.1,
        description="fine noise", continuous_update=False, style=WIDE,
    )  # fmt: skip
    guidance = strict(w.FloatSlider)(
        value=GUIDANCE, min=0.0, max=max(1.0, GUIDANCE), step=0.05,
        description="guidance", continuous_update=False, style=WIDE,
    )  # fmt: skip
    controls = [coarse, fine, level, seed, weight, noise, guidance]
    out, status, player, runner = view_parts(w, controls, lambda: resolve_body(body, shared=True))

    def draw() -> tuple[CrossoverView, str]:
        a, b = coarse.value, fine.value
        i, s, wt = int(checked(level)), int(checked(seed)), checked(weight)
        fine_noise, g = checked(noise), checked(guidance)
        blend = crossover_blend(model, a, b, i, wt)
        W = blend.weights(model).numpy()
        sampler = Sampler(fine_noise=fine_noise, guidance=g)
        motion = generate(model, blend, length=length, seed=s, sampler=sampler)
        strip = nearest_sequence_strip(motion, references, window)
        title = crossover_title(a, b, wt, i, L, s)
        image = None
        if render:
            frame_ids = evenly_spaced_frames(len(motion), frames)
            image = crop_to_bodies(render_meshes(motion, body, frames=frame_ids))
        fig = plt.figure(figsize=(10, 6.4 if render else 3.4))
        ratios = [4, 0.5, 2] if render else [0.5, 2]  # (mesh view,) band, positions
        grid = fig.add_gridspec(len(ratios), 1, height_ratios=ratios)
        axs = [fig.add_subplot(g) for g in grid]
        if render:
            axs[0].imshow(image)
            axs[0].axis("off")
            axs[0].set_title(title, fontsize=10)
            axs = axs[1:]
        axs[1].sharex(axs[0])
        plot_nearest_sequence(strip, axs, title=None if render else title)
        fig.tight_layout()
        show_figure(out, fig)
        player.show(motion)
        shares = ", ".join(f"{k} {100 * v:.0f}%" for k, v in strip.label_shares().items())
        view = CrossoverView(motion=motion, weights=W, strip=strip, image=image, title=title)
        return view, f"{title}; nearest-window labels: {shares}"

    update = wire(runner, player, controls, draw, lambda: BUSY)
    rows = [w.HBox([coarse, fine]), w.HBox([level, weight]), w.HBox([seed, noise, guidance]),
            status, out, player.toggle, player.out]  # fmt: skip
    return view_box(w, rows, out), update


@dataclass
class RestyleView:
    """What one call of :func:`interactive_restyle` made."""

    motion: Motion  # the restyled clip
    source: Motion  # the input at the model's frame rate
    label_sample: Motion  # the target label's own sample, same seed and length
    shares: Any  # mrlib.evaluation.restyle_evidence.RestyleShares over every level
    image: np.ndarray | None  # (H, W, 3) mesh renders, None when rendering is off
    title: str


@view_arguments(label=lambda n, v: check_text(n, v, optional=True))
def interactive_restyle(
    model: Any, motion: Motion, body: Any = None, *, frames: int = 5, render: bool = True,
    label: str | None = None, level: int | None = None,
) -> tuple[Any, Callable[[], RestyleView]]:  # fmt: skip
    """An ipywidgets UI for restyling a clip (``mrlib.sampling.restyling.restyle``).

    Controls: the target *label*, the *level* ``k``, what to *keep* of the clip (its
    ``coarse`` levels ``1..k``, the label adding the detail; or its ``detail``, the label
    giving levels ``1..k``) and the seed. Every change redraws the input, the
    restyled clip and the target label's own sample (same seed and length) side by side
    as mesh renders of ``frames`` frames (off with ``render=False``), their paths on the
    ground, and per level the share of the result that is the input's and the label's
    (``mrlib.evaluation.restyle_evidence.restyle_shares``: nearness of its poses to the
    input's and to the label sample's), the current level marked; the status line says
    the same in words.

    Returns:
        ``(widget, update)``; ``update()`` redraws and returns a :class:`RestyleView`.
    """
    import ipywidgets as w
    import matplotlib.pyplot as plt

    from mrlib.evaluation.restyle_evidence import restyle_shares
    from mrlib.sampling.restyling import KEEP, restyle, restyle_level

    if render:
        body = resolve_body(body)
    shared_body = resolve_body(body, shared=True)
    source = motion.resample(model.fps) if abs(motion.fps - model.fps) > 1e-6 else motion
    labels = list(model.labels)
    L = model.num_levels
    first = model.labels[model.label_index(label or labels[0])]
    lab = w.Dropdown(options=labels, value=first, description="label", style=WIDE)
    lvl = strict(w.IntSlider)(value=restyle_level(model, level), min=1, max=L - 1, description="level k",
                      continuous_update=False, style=WIDE)  # fmt: skip
    keep = w.ToggleButtons(
        options=list(KEEP), value="coarse", description="keep", style=WIDE,
        tooltips=["the clip's levels 1..k, the label's detail on top",
                  "the label's levels 1..k, the clip's detail on top"],
    )  # fmt: skip
    seed = strict(w.BoundedIntText)(value=0, min=0, max=2**31 - 1, description="seed", style=WIDE)
    controls = [lab, lvl, keep, seed]
    out, status, player, runner = view_parts(w, controls, lambda: shared_body)
    cache: dict[tuple, Any] = {}

    def draw() -> tuple[RestyleView, str]:
        k, s = int(checked(lvl)), int(checked(seed))
        m = restyle(model, source, lab.value, k, keep=keep.value, seed=s, body=shared_body)
        key = (lab.value, keep.value, s)
        if key not in cache:
            shares = restyle_shares(model, source, lab.value, keep=keep.value, seed=s,
                                    body=shared_body)  # fmt: skip
            cache[key] = (shares.label_sample, shares)
        sample, shares = cache[key]
        share = float(shares.source_share[k - 1])
        path_cm = 100 * np.linalg.norm(m.trans[:, [0, 2]] - source.trans[:, [0, 2]], 1).mean()
        low, high = f"1-{k}", f"{k + 1}-{L}"
        mine, theirs = (low, high) if keep.value == "coarse" else (high, low)
        title = (f"{source.name or 'input'} at levels {mine}, "
                 f"'{lab.value}' at levels {theirs} (seed {s})")  # fmt: skip
        clips = {"input": source, "restyled": m, f"'{lab.value}' sample": sample}
        image = None
        rows = len(clips) if render else 0
        fig = plt.figure(figsize=(11, 2.3 * rows + 3.2))
        grid = fig.add_gridspec(rows + 1, 2, height_ratios=[2.3] * rows + [3.2])
        if render:
            ids = evenly_spaced_frames(len(source), frames)
            images = [crop_to_bodies(render_meshes(c, body, frames=ids)) for c in clips.values()]
            for r, (name, img) in enumerate(zip(clips, images, strict=True)):
                ax = fig.add_subplot(grid[r, :])
                ax.imshow(img)
                ax.axis("off")
                ax.set_title(name, fontsize=10)
            image = images[1]
        ax = fig.add_subplot(grid[rows, 0])
        for name, c in clips.items():
            if name != f"'{lab.value}' sample":
                ax.plot(c.trans[:, 0], c.trans[:, 2], label=name)
        ax.set(xlabel="x (m)", ylabel="z (m)", title="root on the ground")
        ax.set_aspect("equal", adjustable="datalim")
        below = dict(
            fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.18), ncol=2, frameon=False
        )  # under the axes: inside, a legend hides a path or a bar
        ax.legend(**below)
        ax = fig.add_subplot(grid[rows, 1])
        ks = np.asarray(shares.levels)
        ax.bar(ks, 100 * shares.source_share, color="tab:blue", label="input")
        ax.bar(ks, 100 * (1 - shares.source_share), bottom=100 * shares.source_share,
               color="tab:orange", label=f"'{lab.value}'")  # fmt: skip
        ax.axvline(k, color="k", lw=1, ls="--")
        ax.set(xlabel="level k", ylabel="share (%)", ylim=(0, 100), xticks=ks,
               title=f"how much input, how much label (keep {keep.value})")  # fmt: skip
        ax.legend(**below)
        fig.suptitle(title, fontsize=10)
        fig.tight_layout()
        show_figure(out, fig)
        player.show(m)
        view = RestyleView(m, source, sample, shares, image, title)
        return view, (f"{title}; at level {k} the result is {100 * share:.0f}% input, "
                      f"{100 * (1 - share):.0f}% label; its root {path_cm:.1f} cm from the "
                      "input's on average")  # fmt: skip

    update = wire(runner, player, controls, draw, lambda: BUSY)
    rows = [w.HBox([lab, lvl]), w.HBox([keep, seed]), w.HBox([player.toggle]),
            w.VBox([status, out, player.out])]  # fmt: skip
    return view_box(w, rows, out), update
