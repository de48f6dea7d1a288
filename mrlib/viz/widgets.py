"""Interactive views for notebooks (ipywidgets): the label crossover, with a mesh render
and the nearest-sequence strip of every generated sample; path following; body parts;
in-betweening.

The measurements behind the views are ``mrlib.evaluation.crossover``'s, their pictures
``mrlib.viz.plots``' and ``mrlib.viz.render``'s; this module only wires them to controls.

Every view has a status line under its controls. While a redraw runs it reads
"drawing..." and the controls are disabled (some redraws fit noise for seconds); then it
reads what the picture shows, updated on every redraw. An invalid value (NaN, out of
range) is reported there and the last good picture stays. The "3D player" toggle shows
the current sample playable and rotatable (``mrlib.viz.render.play_motion``: pyvista's trame
backend in a live JupyterLab, an animated GIF where there is none).

The module is long because each of the four views wires its own controls; the plumbing
they share (the busy state, the status line, the 3D player) comes first.
"""

from __future__ import annotations

import html
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from mrlib.errors import MotionValueError
from mrlib.evaluation.crossover import check_crossover_level, crossover_blend
from mrlib.evaluation.fidelity import (
    NearestSequenceStrip,
    nearest_sequence_strip,
    reference_features,
)
from mrlib.representation.body import resolve_body
from mrlib.representation.motion import Motion
from mrlib.sampling.generation import generate, label_weights
from mrlib.viz.plots import plot_nearest_sequence
from mrlib.viz.render import (
    MotionPlayer,
    crop_to_bodies,
    evenly_spaced_frames,
    play_motion,
    render_meshes,
)

__all__ = [
    "CrossoverView",
    "interactive_crossover",
    "interactive_path",
    "interactive_parts",
    "interactive_inbetween",
    "crossover_title",
    "RestyleView",
    "interactive_restyle",
]

BUSY = "drawing..."
WIDE = {"description_width": "initial"}  # descriptions in full, never cut off
_COLOURS = {"busy": "#9a6700", "error": "#b3261e", "done": "inherit"}


@dataclass
class CrossoverView:
    """What one call of the interactive view made."""

    motion: Motion
    weights: (
        np.ndarray
    )  # (L, K) per-level label weights used (mrlib.sampling.generation.label_weights)
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


# -- plumbing shared by the views ------------------------------------------------------------
def _status_html(text: str, kind: str = "done") -> str:
    """The status line's HTML; ``kind`` is ``busy``, ``error`` or ``done`` (also its CSS
    class, ``mrlib-busy`` and so on, which the browser test reads)."""
    body = html.escape(text, quote=False)
    return f'<span class="mrlib-{kind}" style="color: {_COLOURS[kind]}">{body}</span>'


def _checked(control: Any) -> float:
    """A numeric control's value, or a ``MotionValueError`` naming it when the value is
    not finite or outside the control's range (sliders clamp, but NaN passes through)."""
    value = float(control.value)
    lo, hi = float(control.min), float(control.max)
    if not (np.isfinite(value) and lo <= value <= hi):
        raise MotionValueError(
            f"{control.description} must be a number in [{lo:g}, {hi:g}], got {value}"
        )
    return value


class _Runner:
    """Runs a view's redraws: "drawing..." and disabled controls while one runs (each
    control's own disabled state restored after, whatever happens), then the redraw's
    status text, or the error with the last good picture left in place."""

    def __init__(self, status: Any, controls: list[Any]) -> None:
        self.status = status
        self.controls = controls
        self.text = ""  # what the last good picture shows
        self.hold = 0  # > 0: value changes do not redraw (a control being adjusted)

    def run(self, work: Callable[[], tuple[Any, str]], busy: str = BUSY) -> Any:
        was = [c.disabled for c in self.controls]
        for c in self.controls:  # first, so that the page never shows busy and enabled
            c.disabled = True
        self.status.value = _status_html(busy, "busy")
        try:
            result, text = work()
        except ValueError as e:  # MotionValueError and the like: an invalid value
            still = f" (the picture still shows: {self.text})" if self.text else ""
            self.status.value = _status_html(f"not drawn: {e}{still}", "error")
            raise
        except Exception as e:
            self.status.value = _status_html(f"failed: {type(e).__name__}: {e}", "error")
            raise
        finally:
            for c, d in zip(self.controls, was, strict=True):
                c.disabled = d
        self.text = text
        self.status.value = _status_html(text)
        return result

    def on_change(self, work: Callable[[], tuple[Any, str]],
                  busy: Callable[[], str] = lambda: BUSY) -> Callable[..., None]:  # fmt: skip
        """An observer that redraws and leaves an invalid value's error in the status line
        (a notebook shows no traceback for it)."""

        def changed(change: Any = None) -> None:
            if self.hold:
                return
            try:
                self.run(work, busy())
            except ValueError:
                pass  # reported in the status line

        return changed


class _Player3D:
    """The "3D player" toggle of a view and the output it shows the player in; the
    player follows every redraw while the toggle is on."""

    def __init__(self, w: Any, body: Callable[[], Any], *, in_place: bool = True) -> None:
        self.toggle = w.ToggleButton(
            value=False, description="3D player", icon="cube", layout=w.Layout(width="auto"),
            tooltip="show the current sample playable and rotatable: drag to orbit, the "
            "play button and slider for time (a live JupyterLab with pyvista's trame "
            "backend; an animated GIF elsewhere)",
        )  # fmt: skip
        self.out = w.Output()
        self.body = body
        self.in_place = in_place
        self.motion: Motion | None = None
        self.player: MotionPlayer | None = None

    def show(self, motion: Motion | None = None) -> None:
        from IPython.display import display

        if motion is not None:
            self.motion = motion
        if not self.toggle.value or self.motion is None:
            self.close()
            return
        if self.player is not None:
            self.player.set_motion(self.motion)
            return
        view = play_motion(self.motion, self.body(), still="gif", in_place=self.in_place)
        self.player = view if isinstance(view, MotionPlayer) else None
        with self.out:
            self.out.clear_output(wait=True)
            display(view)

    def close(self) -> None:
        if self.player is not None:
            self.player.close()
            self.player = None
        self.out.clear_output()


def _wire(runner: _Runner, player: _Player3D, controls: list[Any],
          draw: Callable[[], tuple[Any, str]], busy: Callable[[], str]) -> None:  # fmt: skip
    for c in controls:
        c.observe(runner.on_change(draw, busy), names="value")
    player.toggle.observe(
        runner.on_change(
            lambda: (player.show(), runner.text or "not drawn yet"),
            lambda: "opening the 3D view...",
        ),
        names="value",
    )


def _status_widget(w: Any) -> Any:
    status = w.HTML(value=_status_html("not drawn yet"))
    status.add_class("mrlib-status")
    return status


# -- the views ---------------------------------------------------------------------------------
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
    interpolates the two labels' embeddings; see ``mrlib.sampling.generation.label_weights``), the
    coarse levels stay pure. ``w = 1`` is the plain crossover of the paper, ``w = 0`` the
    coarse label alone; one number per control keeps the UI readable (per-level weights
    are available through ``generate(blend=(a, b, [w_1, ..., w_L]))``). *fine noise* sets
    the sampler's ``fine_noise`` for this view (the model itself is left as it is): lower
    is smoother and carries less of the fine label's detail; *guidance* its ``guidance``
    (``mrlib.sampling.generation.guided_weights``): above 0 the labels are exaggerated.

    Every change regenerates the sample and redraws, into an ``Output`` widget, a mesh
    render of ``frames`` frames (``mrlib.viz.render.render_meshes``) titled with the labels and the
    nearest-sequence strip (``mrlib.viz.plots.plot_nearest_sequence``); the status line shows
    the title (:func:`crossover_title`) and the share of each label among the nearest
    windows.

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
    coarse = w.Dropdown(options=labels, value=first[0], description="coarse", style=WIDE)
    fine = w.Dropdown(options=labels, value=first[1], description="fine", style=WIDE)
    level = w.IntSlider(value=level, min=1, max=L - 1, description="crossover i",
                        continuous_update=False, style=WIDE)  # fmt: skip
    seed = w.BoundedIntText(value=0, min=0, max=2**31 - 1, description="seed", style=WIDE)
    weight = w.FloatSlider(value=1.0, min=0.0, max=1.0, step=0.05, description="fine weight",
                           continuous_update=False, style=WIDE)  # fmt: skip
    noise = w.FloatSlider(
        value=float(model.fine_noise), min=0.0, max=max(1.0, float(model.fine_noise)), step=0.1,
        description="fine noise", continuous_update=False, style=WIDE,
    )  # fmt: skip
    guidance = w.FloatSlider(
        value=float(model.guidance), min=0.0, max=max(1.0, float(model.guidance)), step=0.05,
        description="guidance", continuous_update=False, style=WIDE,
    )  # fmt: skip
    out = w.Output()
    status = _status_widget(w)
    player = _Player3D(w, lambda: resolve_body(body, shared=True))
    controls = [coarse, fine, level, seed, weight, noise, guidance]
    runner = _Runner(status, [*controls, player.toggle])

    def draw() -> tuple[CrossoverView, str]:
        a, b = coarse.value, fine.value
        i, s, wt = int(_checked(level)), int(_checked(seed)), _checked(weight)
        fine_noise, g = _checked(noise), _checked(guidance)
        blend = crossover_blend(model, a, b, i, wt)
        W = label_weights(model, blend=blend).numpy()
        # a view of the model with this UI's sampler settings; it shares the networks
        sampler = replace(model, fine_noise=fine_noise, guidance=g)
        motion = generate(sampler, blend=blend, length=length, seed=s)
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
        with out:
            out.clear_output(wait=True)
            display(fig)
        plt.close(fig)
        player.show(motion)
        shares = ", ".join(f"{k} {100 * v:.0f}%" for k, v in strip.label_shares().items())
        view = CrossoverView(motion=motion, weights=W, strip=strip, image=image, title=title)
        return view, f"{title}; nearest-window labels: {shares}"

    def update(*_: Any) -> CrossoverView:
        return runner.run(draw)

    _wire(runner, player, controls, draw, lambda: BUSY)
    box = w.VBox(
        [
            w.HBox([coarse, fine]),
            w.HBox([level, weight]),
            w.HBox([seed, noise, guidance]),
            status,
            out,
            player.toggle,
            player.out,
        ]
    )
    return box, update


def interactive_path(
    model: Any, body: Any = None, *, label: str | None = None, seconds: float = 20.0
) -> tuple[Any, Callable[[], Motion]]:
    """An ipywidgets UI for path following: path preset and size, label, seed and
    method (``bend`` / ``optimise``); every change regenerates and redraws the top-down
    plot of target and generated paths (``mrlib.viz.plots.plot_ground_paths``), the status
    line the pelvis's distance to the path.

    Returns:
        ``(widget, update)``; ``update()`` regenerates and returns the Motion.
    """
    import ipywidgets as w
    import matplotlib.pyplot as plt
    from IPython.display import display

    from mrlib.sampling.constraints import generate_on_path, path_error
    from mrlib.viz.plots import plot_ground_paths

    body = resolve_body(body, shared=True)
    kind = w.Dropdown(options=["circle", "circle-right", "eight", "line"], value="circle",
                      description="path", style=WIDE)  # fmt: skip
    size = w.FloatSlider(value=2.0, min=0.5, max=10.0, step=0.5, description="size (m)",
                         continuous_update=False, style=WIDE)  # fmt: skip
    lab = w.Dropdown(options=list(model.labels), value=label or model.labels[0],
                     description="label", style=WIDE)  # fmt: skip
    seed = w.BoundedIntText(value=0, min=0, max=2**31 - 1, description="seed", style=WIDE)
    method = w.ToggleButtons(
        options=["bend", "optimise"], value="bend", description="method", style=WIDE,
        tooltips=["bend the model's own walk onto the path (fast)",
                  "fit the noise, networks frozen (a few seconds)"],
    )  # fmt: skip
    out = w.Output()
    status = _status_widget(w)
    player = _Player3D(w, lambda: body, in_place=False)
    controls = [kind, size, lab, seed, method]
    runner = _Runner(status, [*controls, player.toggle])

    def draw() -> tuple[Motion, str]:
        spec = f"{kind.value}:{_checked(size):g}"
        s = int(_checked(seed))
        m = generate_on_path(model, spec, lab.value, seconds=seconds, seed=s,
                             method=method.value, body=body)  # fmt: skip
        fig, ax = plt.subplots(figsize=(6, 7))
        plot_ground_paths(spec, {f"{lab.value} ({method.value})": m}, body, ax)
        fig.tight_layout()
        with out:
            out.clear_output(wait=True)
            display(fig)
        plt.close(fig)
        player.show(m)
        e = path_error(m, spec, body)
        return m, (f"'{lab.value}' on {spec} ({method.value}, seed {s}): the pelvis "
                   f"{100 * e['mean_m']:.1f} cm from the path on average, "
                   f"{100 * e['max_m']:.0f} cm at most")  # fmt: skip

    def busy() -> str:
        return BUSY + (" (fitting the noise: a few seconds)" if method.value == "optimise" else "")

    def update(*_: Any) -> Motion:
        return runner.run(draw, busy())

    _wire(runner, player, controls, draw, busy)
    rows = [w.HBox([kind, size]), w.HBox([lab, seed]), w.HBox([method, player.toggle]),
            w.VBox([status, out, player.out])]  # fmt: skip
    return w.VBox(rows), update


def interactive_parts(
    model: Any, body: Any = None, *, frames: int = 5, length: int | None = None
) -> tuple[Any, Callable[[], Motion]]:
    """An ipywidgets UI for body-part composition: a label for the upper body, one for
    the lower body, the method (``splice`` / ``film``), the seed and the sampler's label
    ``guidance`` for this view (``mrlib.sampling.generation.guided_weights``: above 0 each part keeps
    its label more often, at some distance from the training motion); every change
    regenerates and shows a mesh render of ``frames`` frames, titled (and the status line
    too) with each part's condition fidelity (``mrlib.sampling.constraints.part_fidelity``).
    "arms in step" retimes a splice's upper body to the legs' gait (``align_gait``; film
    has nothing to retime, so it is disabled there); "sharpen" fits the noise so that
    each part shows its label (``generate_parts(..., sharpen=SHARPEN_STEPS)``)."""
    import ipywidgets as w
    import matplotlib.pyplot as plt
    from IPython.display import display

    from mrlib.sampling.constraints import (
        SHARPEN_STEPS,
        arm_leg_coordination,
        generate_parts,
        part_fidelity,
    )

    body = resolve_body(body, shared=True)
    labels = list(model.labels)
    upper = w.Dropdown(options=labels, value=labels[0], description="upper body", style=WIDE)
    lower = w.Dropdown(options=labels, value=labels[-1], description="lower body", style=WIDE)
    method = w.ToggleButtons(
        options=["splice", "film"], value="splice", description="method", style=WIDE,
        tooltips=["each part's joints from its own label's sample",
                  "one generator run, each part's channels modulated by its own label"],
    )  # fmt: skip
    in_step = w.Checkbox(
        value=False, description="arms in step with the legs (splice)", indent=False,
        layout=w.Layout(width="auto"), style=WIDE,
        tooltip="splice only: retime the upper body's sample to the legs' gait phase, so "
        "that the arms swing in step with the legs (align_gait); film makes one sample, "
        "with nothing to retime",
    )  # fmt: skip
    sharpen = w.Checkbox(
        value=False, description="sharpen each part's label (takes seconds)", indent=False,
        layout=w.Layout(width="auto"), style=WIDE,
        tooltip=f"fit each part's noise ({SHARPEN_STEPS} steps, seconds per redraw) so that "
        "its windows are nearer its own label's training clips than any other label's",
    )  # fmt: skip
    seed = w.BoundedIntText(value=0, min=0, max=2**31 - 1, description="seed", style=WIDE)
    guidance = w.FloatSlider(
        value=float(model.guidance), min=0.0, max=max(1.0, float(model.guidance)), step=0.05,
        description="guidance", continuous_update=False, style=WIDE,
    )  # fmt: skip
    out = w.Output()
    status = _status_widget(w)
    player = _Player3D(w, lambda: body)
    controls = [upper, lower, method, in_step, sharpen, seed, guidance]
    runner = _Runner(status, [*controls, player.toggle])

    def film_has_no_step(change: Any = None) -> None:
        in_step.disabled = method.value == "film"

    method.observe(film_has_no_step, names="value")  # before the redraw's observer
    film_has_no_step()

    def draw() -> tuple[Motion, str]:
        parts = {"upper": upper.value, "lower": lower.value}
        s, g = int(_checked(seed)), _checked(guidance)
        aligned = bool(in_step.value) and method.value == "splice"
        sampler = replace(model, guidance=g)  # shares the networks
        m = generate_parts(sampler, parts, length, seed=s, method=method.value,
                           align_gait=aligned, body=body,
                           sharpen=SHARPEN_STEPS if sharpen.value else 0)  # fmt: skip
        windows = min(len(m), int(model.lengths[:, -1].min())) >= 30
        fid = part_fidelity([m], model, parts) if windows else {}
        coordination = arm_leg_coordination(m, body)
        image = crop_to_bodies(render_meshes(m, body, frames=evenly_spaced_frames(len(m), frames)))
        how = ", ".join([method.value] + ["arms in step"] * aligned + ["sharpened"] * sharpen.value)
        kept = ", ".join(f"{p} {100 * f:.0f}%" for p, f in fid.items())
        title = (f"upper body {upper.value}, lower body {lower.value} ({how}, seed {s})"
                 + (f"; windows keeping their part's label: {kept}" if kept else "")
                 + f"; arm-leg coordination {coordination:.2f}")  # fmt: skip
        fig, ax = plt.subplots(figsize=(10, 4))
        ax.imshow(image)
        ax.axis("off")
        ax.set_title(title, fontsize=10)
        with out:
            out.clear_output(wait=True)
            display(fig)
        plt.close(fig)
        player.show(m)
        return m, title

    def busy() -> str:
        return BUSY + (" (sharpening: several seconds)" if sharpen.value else "")

    def update(*_: Any) -> Motion:
        return runner.run(draw, busy())

    _wire(runner, player, controls, draw, busy)
    rows = [w.HBox([upper, lower]), w.HBox([method, in_step]), w.HBox([seed, guidance]),
            w.HBox([sharpen, player.toggle]), w.VBox([status, out, player.out])]  # fmt: skip
    return w.VBox(rows), update


def interactive_inbetween(
    model: Any, clips: dict[str, Motion], body: Any = None, *, seconds: float = 4.0,
    steps: int | None = None,
) -> tuple[Any, Callable[[], Motion]]:  # fmt: skip
    """An ipywidgets UI for in-betweening: a start frame of one clip and an end pose
    of another (clip and frame pickers), the label of what lies between and the seed;
    every change regenerates (``mrlib.sampling.constraints.generate_with_keyframes``, with
    ``steps`` of noise fit: default its own) and shows the mesh at the two keyframes and
    between them; the status line the error at the keyframes."""
    import ipywidgets as w
    import matplotlib.pyplot as plt
    from IPython.display import display

    from mrlib.sampling.constraints import Keyframe, generate_with_keyframes, keyframe_errors

    body = resolve_body(body, shared=True)
    names = list(clips)
    a = w.Dropdown(options=names, value=names[0], description="from clip", style=WIDE)
    fa = w.IntSlider(value=0, min=0, max=clips[names[0]].num_frames - 1, description="frame",
                     continuous_update=False, style=WIDE)  # fmt: skip
    b = w.Dropdown(options=names, value=names[-1], description="to clip", style=WIDE)
    fb = w.IntSlider(value=clips[names[-1]].num_frames - 1, min=0,
                     max=clips[names[-1]].num_frames - 1, description="frame",
                     continuous_update=False, style=WIDE)  # fmt: skip
    lab = w.Dropdown(options=list(model.labels), value=model.labels[0], description="between",
                     style=WIDE)  # fmt: skip
    seed = w.BoundedIntText(value=0, min=0, max=2**31 - 1, description="seed", style=WIDE)
    out = w.Output()
    status = _status_widget(w)
    player = _Player3D(w, lambda: body)
    controls = [a, fa, b, fb, lab, seed]
    runner = _Runner(status, [*controls, player.toggle])
    N = max(2, round(seconds * model.fps))

    def clamp(slider: Any, clip: Motion) -> None:
        runner.hold += 1  # one redraw, by the clip's own observer, not two
        try:
            slider.max = clip.num_frames - 1
            slider.value = min(slider.value, slider.max)
        finally:
            runner.hold -= 1

    def draw() -> tuple[Motion, str]:
        i, j, s = int(_checked(fa)), int(_checked(fb)), int(_checked(seed))
        kfs = [
            Keyframe.from_motion(clips[a.value], i, 0),
            Keyframe.from_motion(clips[b.value], j, N - 1, root=False),
        ]
        fit = {} if steps is None else {"steps": steps}
        m = generate_with_keyframes(model, kfs, N, lab.value, seed=s, body=body, **fit)
        shown = [0, N // 4, N // 2, 3 * N // 4, N - 1]
        image = crop_to_bodies(render_meshes(m, body, frames=shown))
        title = f"{a.value}[{i}] -> {lab.value} -> {b.value}[{j}] (seed {s})"
        fig, ax = plt.subplots(figsize=(10, 4))
        ax.imshow(image)
        ax.axis("off")
        ax.set_title(f"{title}: frames {shown}, keyframes first and last", fontsize=10)
        with out:
            out.clear_output(wait=True)
            display(fig)
        plt.close(fig)
        player.show(m)
        e = keyframe_errors(m, kfs)
        return m, f"{title}; keyframe error {e['rotation_deg']:.3f} deg, {e['trans_cm']:.3f} cm"

    def update(*_: Any) -> Motion:
        return runner.run(draw, BUSY + " (fitting the noise to the keyframes)")

    a.observe(lambda change: clamp(fa, clips[a.value]), names="value")
    b.observe(lambda change: clamp(fb, clips[b.value]), names="value")
    _wire(runner, player, controls, draw,
          lambda: BUSY + " (fitting the noise to the keyframes)")  # fmt: skip
    rows = [w.HBox([a, fa]), w.HBox([b, fb]), w.HBox([lab, seed, player.toggle]),
            w.VBox([status, out, player.out])]  # fmt: skip
    return w.VBox(rows), update


@dataclass
class RestyleView:
    """What one call of :func:`interactive_restyle` made."""

    motion: Motion  # the restyled clip
    source: Motion  # the input at the model's frame rate
    label_sample: Motion  # the target label's own sample, same seed and length
    shares: Any  # mrlib.sampling.restyling.RestyleShares over every level
    image: np.ndarray | None  # (H, W, 3) mesh renders, None when rendering is off
    title: str


def interactive_restyle(
    model: Any, motion: Motion, body: Any = None, *, frames: int = 5, render: bool = True,
    label: str | None = None, level: int | None = None,
) -> tuple[Any, Callable[[], RestyleView]]:  # fmt: skip
    """An ipywidgets UI for restyling a clip (``mrlib.sampling.restyling.restyle``).

    Controls: the target *label*, the *level* ``k``, what to *keep* of the clip (its
    ``coarse`` levels ``1..k``, the label adding the detail; or its ``detail``, the label
    giving levels ``1..k``), the seed and *invert* (fit the coarse noise to the clip,
    seconds per redraw; ``keep="coarse"`` only). Every change redraws the input, the
    restyled clip and the target label's own sample (same seed and length) side by side
    as mesh renders of ``frames`` frames (off with ``render=False``), their paths on the
    ground, and per level the share of the result that is the input's and the label's
    (``mrlib.sampling.restyling.restyle_shares``: nearness of its poses to the input's and to the
    label sample's), the current level marked; the status line says the same in words.

    Returns:
        ``(widget, update)``; ``update()`` redraws and returns a :class:`RestyleView`.
    """
    import ipywidgets as w
    import matplotlib.pyplot as plt
    from IPython.display import display

    from mrlib.sampling.restyling import KEEP, restyle, restyle_level, restyle_shares

    if render:
        body = resolve_body(body)
    shared_body = resolve_body(body, shared=True)
    source = motion.resample(model.fps) if abs(motion.fps - model.fps) > 1e-6 else motion
    labels = list(model.labels)
    L = model.num_levels
    first = model.labels[model.label_index(label or labels[0])]
    lab = w.Dropdown(options=labels, value=first, description="label", style=WIDE)
    lvl = w.IntSlider(value=restyle_level(model, level), min=1, max=L - 1, description="level k",
                      continuous_update=False, style=WIDE)  # fmt: skip
    keep = w.ToggleButtons(
        options=list(KEEP), value="coarse", description="keep", style=WIDE,
        tooltips=["the clip's levels 1..k, the label's detail on top",
                  "the label's levels 1..k, the clip's detail on top"],
    )  # fmt: skip
    seed = w.BoundedIntText(value=0, min=0, max=2**31 - 1, description="seed", style=WIDE)
    invert = w.Checkbox(
        value=False, description="invert (fit the coarse noise; seconds)", indent=False,
        layout=w.Layout(width="auto"), style=WIDE,
        tooltip="fit the coarse levels' noise to the clip and restyle the model's own "
        "version of it (for clips far from the training data; keep=coarse only)",
    )  # fmt: skip
    out = w.Output()
    status = _status_widget(w)
    player = _Player3D(w, lambda: shared_body)
    controls = [lab, lvl, keep, seed, invert]
    runner = _Runner(status, [*controls, player.toggle])
    cache: dict[tuple, Any] = {}

    def detail_has_no_inversion(change: Any = None) -> None:
        invert.disabled = keep.value == "detail"

    keep.observe(detail_has_no_inversion, names="value")  # before the redraw's observer
    detail_has_no_inversion()

    def draw() -> tuple[RestyleView, str]:
        from mrlib.sampling.generation import generate

        k, s = int(_checked(lvl)), int(_checked(seed))
        inv = bool(invert.value) and keep.value == "coarse"
        m = restyle(model, source, lab.value, k, keep=keep.value, seed=s, invert=inv,
                    body=shared_body)  # fmt: skip
        key = (lab.value, keep.value, s)
        if key not in cache:
            sample = generate(model, lab.value, length=source.num_frames, seed=s,
                              fix_contacts=False)  # fmt: skip
            shares = restyle_shares(model, source, lab.value, keep=keep.value, seed=s,
                                    body=shared_body, label_sample=sample)  # fmt: skip
            cache[key] = (sample, shares)
        sample, shares = cache[key]
        share = float(shares.source_share[k - 1])
        path_cm = 100 * np.linalg.norm(m.trans[:, [0, 2]] - source.trans[:, [0, 2]], 1).mean()
        low, high = f"1-{k}", f"{k + 1}-{L}"
        mine, theirs = (low, high) if keep.value == "coarse" else (high, low)
        title = (f"{source.name or 'input'} at levels {mine}{' (inverted)' * inv}, "
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
        ax.legend(fontsize=8)
        ax = fig.add_subplot(grid[rows, 1])
        ks = np.asarray(shares.levels)
        ax.bar(ks, 100 * shares.source_share, color="tab:blue", label="input")
        ax.bar(ks, 100 * (1 - shares.source_share), bottom=100 * shares.source_share,
               color="tab:orange", label=f"'{lab.value}'")  # fmt: skip
        ax.axvline(k, color="k", lw=1, ls="--")
        ax.set(xlabel="level k", ylabel="share (%)", ylim=(0, 100), xticks=ks,
               title=f"how much input, how much label (keep {keep.value})")  # fmt: skip
        ax.legend(fontsize=8, loc="lower right")
        fig.suptitle(title, fontsize=10)
        fig.tight_layout()
        with out:
            out.clear_output(wait=True)
            display(fig)
        plt.close(fig)
        player.show(m)
        view = RestyleView(m, source, sample, shares, image, title)
        return view, (f"{title}; at level {k} the result is {100 * share:.0f}% input, "
                      f"{100 * (1 - share):.0f}% label; its root {path_cm:.1f} cm from the "
                      "input's on average")  # fmt: skip

    def busy() -> str:
        inv = invert.value and keep.value == "coarse"
        return BUSY + (" (fitting the coarse noise: a few seconds)" if inv else "")

    def update(*_: Any) -> RestyleView:
        return runner.run(draw, busy())

    _wire(runner, player, controls, draw, busy)
    rows = [w.HBox([lab, lvl]), w.HBox([keep, seed]), w.HBox([invert, player.toggle]),
            w.VBox([status, out, player.out])]  # fmt: skip
    return w.VBox(rows), update
