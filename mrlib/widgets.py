"""Interactive views for notebooks (ipywidgets): the label crossover, with a mesh render
and the nearest-sequence strip of every generated sample.

The measurements behind the views are ``mrlib.control``'s, their pictures
``mrlib.plots``' and ``mrlib.render``'s; this module only wires them to controls.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
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

__all__ = [
    "CrossoverView",
    "interactive_crossover",
    "interactive_path",
    "interactive_parts",
    "interactive_inbetween",
]


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
    are available through ``generate(blend=(a, b, [w_1, ..., w_L]))``). *fine noise* sets
    the sampler's ``fine_noise`` for this view (the model itself is left as it is): lower
    is smoother and carries less of the fine label's detail; *guidance* its ``guidance``
    (``mrlib.sample.guided_weights``): above 0 the labels are exaggerated.

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
    noise = w.FloatSlider(
        value=float(model.fine_noise), min=0.0, max=max(1.0, float(model.fine_noise)), step=0.1,
        description="fine noise", continuous_update=False,
    )  # fmt: skip
    guidance = w.FloatSlider(
        value=float(model.guidance), min=0.0, max=max(1.0, float(model.guidance)), step=0.05,
        description="guidance", continuous_update=False,
    )  # fmt: skip
    out = w.Output()
    status = w.HTML()

    def update(*_: Any) -> CrossoverView:
        a, b, i, wt = coarse.value, fine.value, int(level.value), float(weight.value)
        blend = crossover_blend(model, a, b, i, wt)
        W = label_weights(model, blend=blend).numpy()
        # a view of the model with this UI's sampler settings; it shares the networks
        sampler = replace(model, fine_noise=float(noise.value), guidance=float(guidance.value))
        motion = generate(sampler, blend=blend, length=length, seed=int(seed.value))
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

    for c in (coarse, fine, level, seed, weight, noise, guidance):
        c.observe(lambda change: update(), names="value")
    box = w.VBox(
        [
            w.HBox([coarse, fine]),
            w.HBox([level, weight]),
            w.HBox([seed, noise, guidance]),
            status,
            out,
        ]
    )
    return box, update


def interactive_path(
    model: Any, body: Any = None, *, label: str | None = None, seconds: float = 20.0
) -> tuple[Any, Callable[[], Motion]]:
    """An ipywidgets UI for path following: path preset and size, label, seed and
    method (``bend`` / ``optimise``); every change regenerates and redraws the top-down
    plot of target and generated paths (``mrlib.plots.plot_ground_paths``).

    Returns:
        ``(widget, update)``; ``update()`` regenerates and returns the Motion.
    """
    import ipywidgets as w
    import matplotlib.pyplot as plt
    from IPython.display import display

    from mrlib.constraints import generate_on_path
    from mrlib.plots import plot_ground_paths

    body = resolve_body(body, shared=True)
    kind = w.Dropdown(options=["circle", "circle-right", "eight", "line"], value="circle",
                      description="path")  # fmt: skip
    size = w.FloatSlider(value=2.0, min=0.5, max=10.0, step=0.5, description="size (m)",
                         continuous_update=False)  # fmt: skip
    lab = w.Dropdown(
        options=list(model.labels), value=label or model.labels[0], description="label"
    )
    seed = w.BoundedIntText(value=0, min=0, max=2**31 - 1, description="seed")
    method = w.ToggleButtons(options=["bend", "optimise"], value="bend", description="method")
    out = w.Output()

    def update(*_: Any) -> Motion:
        spec = f"{kind.value}:{size.value:g}"
        m = generate_on_path(model, spec, lab.value, seconds=seconds, seed=int(seed.value),
                             method=method.value, body=body)  # fmt: skip
        fig, ax = plt.subplots(figsize=(6, 6))
        plot_ground_paths(spec, {f"{lab.value} ({method.value})": m}, body, ax)
        with out:
            out.clear_output(wait=True)
            display(fig)
        plt.close(fig)
        return m

    for c in (kind, size, lab, seed, method):
        c.observe(lambda change: update(), names="value")
    return w.VBox([w.HBox([kind, size]), w.HBox([lab, seed]), method, out]), update


def interactive_parts(
    model: Any, body: Any = None, *, frames: int = 5, length: int | None = None
) -> tuple[Any, Callable[[], Motion]]:
    """An ipywidgets UI for body-part composition: a label for the upper body, one for
    the lower body, the method (``splice`` / ``film``), the seed and the sampler's label
    ``guidance`` for this view (``mrlib.sample.guided_weights``: above 0 each part keeps
    its label more often, at some distance from the training motion); every change
    regenerates and shows a mesh render of ``frames`` frames, titled with each part's
    condition fidelity (``mrlib.constraints.part_fidelity``). "sharpen" fits the noise so
    that each part shows its label (``generate_parts(..., sharpen=SHARPEN_STEPS)``)."""
    import ipywidgets as w
    import matplotlib.pyplot as plt
    from IPython.display import display

    from mrlib.constraints import SHARPEN_STEPS, arm_leg_coordination, generate_parts, part_fidelity

    body = resolve_body(body, shared=True)
    labels = list(model.labels)
    upper = w.Dropdown(options=labels, value=labels[0], description="upper body")
    lower = w.Dropdown(options=labels, value=labels[-1], description="lower body")
    method = w.ToggleButtons(options=["splice", "film"], value="splice", description="method")
    in_step = w.Checkbox(value=False, description="splice: arms in step with the legs")
    sharpen = w.Checkbox(value=False, description="sharpen each part's label (seconds)")
    seed = w.BoundedIntText(value=0, min=0, max=2**31 - 1, description="seed")
    guidance = w.FloatSlider(
        value=float(model.guidance), min=0.0, max=max(1.0, float(model.guidance)), step=0.05,
        description="guidance", continuous_update=False,
    )  # fmt: skip
    out = w.Output()

    def update(*_: Any) -> Motion:
        parts = {"upper": upper.value, "lower": lower.value}
        sampler = replace(model, guidance=float(guidance.value))  # shares the networks
        m = generate_parts(sampler, parts, length, seed=int(seed.value), method=method.value,
                           align_gait=bool(in_step.value), body=body,
                           sharpen=SHARPEN_STEPS if sharpen.value else 0)  # fmt: skip
        windows = min(len(m), int(model.lengths[:, -1].min())) >= 30
        fid = part_fidelity([m], model, parts) if windows else {}
        coordination = arm_leg_coordination(m, body)
        image = crop_to_bodies(render_meshes(m, body, frames=evenly_spaced_frames(len(m), frames)))
        fig, ax = plt.subplots(figsize=(10, 4))
        ax.imshow(image)
        ax.axis("off")
        kept = ", ".join(f"{p} {100 * f:.0f}%" for p, f in fid.items())
        ax.set_title(
            f"upper body {upper.value}, lower body {lower.value} ({method.value}"
            + (", sharpened)" if sharpen.value else ")")
            + (f"; windows keeping their part's label: {kept}" if kept else "")
            + f"; arm-leg coordination {coordination:.2f}",
            fontsize=10,
        )
        with out:
            out.clear_output(wait=True)
            display(fig)
        plt.close(fig)
        return m

    for c in (upper, lower, method, in_step, sharpen, seed, guidance):
        c.observe(lambda change: update(), names="value")
    rows = [w.HBox([upper, lower]), w.HBox([method, in_step]), w.HBox([seed, guidance]),
            w.HBox([sharpen]), out]  # fmt: skip
    return w.VBox(rows), update


def interactive_inbetween(
    model: Any, clips: dict[str, Motion], body: Any = None, *, seconds: float = 4.0,
    steps: int | None = None,
) -> tuple[Any, Callable[[], Motion]]:  # fmt: skip
    """An ipywidgets UI for in-betweening: a start frame of one clip and an end pose
    of another (clip and frame pickers), the label of what lies between and the seed;
    every change regenerates (``mrlib.constraints.generate_with_keyframes``, with
    ``steps`` of noise fit: default its own) and shows the mesh at the two keyframes and
    between them."""
    import ipywidgets as w
    import matplotlib.pyplot as plt
    from IPython.display import display

    from mrlib.constraints import Keyframe, generate_with_keyframes, keyframe_errors

    body = resolve_body(body, shared=True)
    names = list(clips)
    a = w.Dropdown(options=names, value=names[0], description="from clip")
    fa = w.IntSlider(value=0, min=0, max=clips[names[0]].num_frames - 1, description="frame",
                     continuous_update=False)  # fmt: skip
    b = w.Dropdown(options=names, value=names[-1], description="to clip")
    fb = w.IntSlider(value=clips[names[-1]].num_frames - 1, min=0,
                     max=clips[names[-1]].num_frames - 1, description="frame",
                     continuous_update=False)  # fmt: skip
    lab = w.Dropdown(options=list(model.labels), value=model.labels[0], description="between")
    seed = w.BoundedIntText(value=0, min=0, max=2**31 - 1, description="seed")
    out = w.Output()
    status = w.HTML()
    N = max(2, round(seconds * model.fps))

    def clamp(slider: Any, clip: Motion) -> None:
        slider.max = clip.num_frames - 1
        slider.value = min(slider.value, slider.max)

    def update(*_: Any) -> Motion:
        kfs = [
            Keyframe.from_motion(clips[a.value], int(fa.value), 0),
            Keyframe.from_motion(clips[b.value], int(fb.value), N - 1, root=False),
        ]
        fit = {} if steps is None else {"steps": steps}
        m = generate_with_keyframes(model, kfs, N, lab.value, seed=int(seed.value), body=body,
                                    **fit)  # fmt: skip
        shown = [0, N // 4, N // 2, 3 * N // 4, N - 1]
        image = crop_to_bodies(render_meshes(m, body, frames=shown))
        fig, ax = plt.subplots(figsize=(10, 4))
        ax.imshow(image)
        ax.axis("off")
        ax.set_title(f"{a.value}[{fa.value}] -> {lab.value} -> {b.value}[{fb.value}]: "
                     f"frames {shown}, keyframes first and last", fontsize=10)  # fmt: skip
        with out:
            out.clear_output(wait=True)
            display(fig)
        plt.close(fig)
        e = keyframe_errors(m, kfs)
        status.value = f"keyframe error: {e['rotation_deg']:.3f} deg, {e['trans_cm']:.3f} cm"
        return m

    a.observe(lambda change: clamp(fa, clips[a.value]), names="value")
    b.observe(lambda change: clamp(fb, clips[b.value]), names="value")
    for c in (a, fa, b, fb, lab, seed):
        c.observe(lambda change: update(), names="value")
    return w.VBox([w.HBox([a, fa]), w.HBox([b, fb]), w.HBox([lab, seed]), status, out]), update
