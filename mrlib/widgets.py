"""Interactive views for notebooks (ipywidgets): the label crossover, with a mesh render
and the nearest-sequence strip of every generated sample.

The measurements behind the views are ``mrlib.control``'s, their pictures
``mrlib.plots``' and ``mrlib.render``'s; this module only wires them to controls.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from mrlib.body import resolve_body
from mrlib.control import (
    NearestSequenceStrip,
    check_crossover_level,
    crossover_blend,
    nearest_sequence_strip,
    reference_features,
)
from mrlib.errors import MotionValueError
from mrlib.motion import Motion
from mrlib.plots import plot_nearest_sequence
from mrlib.render import crop_to_bodies, evenly_spaced_frames, render_meshes
from mrlib.sample import generate, label_weights

__all__ = ["CrossoverView", "interactive_crossover"]


@dataclass
class CrossoverView:
    """What one call of the interactive view made."""

    motion: Motion
    weights: np.ndarray  # (L, K) per-level label weights used (mrlib.sample.label_weights)
    strip: NearestSequenceStrip
    image: np.ndarray | None  # (H, W, 3) mesh render, None when rendering is off
    title: str


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
    interpolates the two labels' embeddings; see ``mrlib.sample.label_weights``), the
    coarse levels stay pure. ``w = 1`` is the plain crossover of the paper, ``w = 0`` the
    coarse label alone; one number per control keeps the UI readable (per-level weights
    are available through ``generate(blend=(a, b, [w_1, ..., w_L]))``).

    Every change regenerates the sample and redraws, into an ``Output`` widget, a mesh
    render of ``frames`` frames (``mrlib.render_meshes``) titled with the labels and the
    nearest-sequence strip (``mrlib.plots.plot_nearest_sequence``).

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
        regenerates with the current control values and returns a :class:`CrossoverView`.
    """
    import ipywidgets as w
    import matplotlib.pyplot as plt
    from IPython.display import display

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
    coarse = w.Dropdown(options=labels, value=first[0], description="coarse")
    fine = w.Dropdown(options=labels, value=first[1], description="fine")
    level = w.IntSlider(
        value=level, min=1, max=L - 1, description="crossover i", continuous_update=False
    )
    seed = w.BoundedIntText(value=0, min=0, max=2**31 - 1, description="seed")
    weight = w.FloatSlider(
        value=1.0, min=0.0, max=1.0, step=0.05, description="fine weight", continuous_update=False
    )
    out = w.Output()
    status = w.HTML()

    def update(*_: Any) -> CrossoverView:
        a, b, i, wt = coarse.value, fine.value, int(level.value), float(weight.value)
        blend = crossover_blend(model, a, b, i, wt)
        W = label_weights(model, blend=blend).numpy()
        motion = generate(model, blend=blend, length=length, seed=int(seed.value))
        strip = nearest_sequence_strip(motion, references, window)
        fine_txt = b if wt == 1.0 else f"{1 - wt:.2f} {a} + {wt:.2f} {b}"
        title = f"coarse '{a}' at levels 1-{i}, fine '{fine_txt}' at levels {i + 1}-{L} (seed {seed.value})"
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
        with out:
            out.clear_output(wait=True)
            display(fig)
        plt.close(fig)
        shares = ", ".join(f"{k} {100 * v:.0f}%" for k, v in strip.label_shares().items())
        status.value = f"nearest-window labels: {shares}"
        return CrossoverView(motion=motion, weights=W, strip=strip, image=image, title=title)

    for c in (coarse, fine, level, seed, weight):
        c.observe(lambda change: update(), names="value")
    box = w.VBox([w.HBox([coarse, fine]), w.HBox([level, weight]), seed, status, out])
    return box, update
