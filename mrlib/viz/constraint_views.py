"""Interactive views of the constraints for notebooks (ipywidgets): path following,
body parts and in-betweening (``mrlib.sampling.constraints``). Each regenerates on every
change of its controls and shows the result with a status line and a "3D player" toggle,
as the views of ``mrlib.viz.widgets`` do (the plumbing they share is
``mrlib.viz.widget_kit``'s); every name is also reachable as
``mrlib.viz.widgets.<name>``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from mrlib.errors import ArgumentError, MotionValueError, check_number, check_text, shown
from mrlib.representation.body import resolve_body
from mrlib.representation.motion import Motion, check_motion
from mrlib.sampling.arguments import steps
from mrlib.sampling.conditions import Condition
from mrlib.sampling.sampler import GUIDANCE, Sampler
from mrlib.viz.meshes import crop_to_bodies, evenly_spaced_frames, render_meshes
from mrlib.viz.widget_kit import (
    BUSY,
    WIDE,
    checked,
    mesh_figure,
    show_figure,
    strict,
    view_arguments,
    view_box,
    view_parts,
    wire,
)

__all__ = ["interactive_path", "interactive_parts", "interactive_inbetween"]


def _seconds(name: str, value: Any) -> float:
    return check_number(name, value, low=0, open_low=True)


def _clips(name: str, value: Any) -> dict:
    if not isinstance(value, dict) or not value:
        raise ArgumentError(
            f"{name} must be a dict {{name: Motion}} of one clip or more, got {shown(value)}"
        )
    for key, m in value.items():
        check_motion(f"{name}[{key!r}]", m)
    return value


@view_arguments(label=lambda n, v: check_text(n, v, optional=True), seconds=_seconds)
def interactive_path(
    model: Any, body: Any = None, *, label: str | None = None, seconds: float = 20.0
) -> tuple[Any, Callable[[], Motion]]:
    """An ipywidgets UI for path following: path preset and size, label and seed; every
    change regenerates and redraws the top-down plot of target and generated paths
    (``mrlib.viz.control_plots.plot_ground_paths``), the status line the pelvis's
    distance to the path, the share of it walked and the distance from an even pace
    along it (``mrlib.sampling.constraints.path_error``).

    Returns:
        ``(widget, update)``; ``update()`` regenerates and returns the Motion.
    """
    import ipywidgets as w
    import matplotlib.pyplot as plt

    from mrlib.sampling.constraints import generate_on_path, path_error
    from mrlib.viz.control_plots import plot_ground_paths

    body = resolve_body(body, shared=True)
    kind = w.Dropdown(options=["circle", "circle-right", "eight", "line"], value="circle",
                      description="path", style=WIDE)  # fmt: skip
    size = strict(w.FloatSlider)(value=2.0, min=0.5, max=10.0, step=0.5, description="size (m)",
                         continuous_update=False, style=WIDE)  # fmt: skip
    lab = w.Dropdown(options=list(model.labels), value=label or model.labels[0],
                     description="label", style=WIDE)  # fmt: skip
    seed = strict(w.BoundedIntText)(value=0, min=0, max=2**31 - 1, description="seed", style=WIDE)
    controls = [kind, size, lab, seed]
    out, status, player, runner = view_parts(w, controls, lambda: body, in_place=False)

    def draw() -> tuple[Motion, str]:
        spec = f"{kind.value}:{checked(size):g}"
        s = int(checked(seed))
        m = generate_on_path(model, spec, lab.value, seconds=seconds, seed=s, body=body)
        fig, ax = plt.subplots(figsize=(6, 7))
        plot_ground_paths(spec, {lab.value: m}, body, ax)
        fig.tight_layout()
        show_figure(out, fig)
        player.show(m)
        e = path_error(m, spec, body)
        walked = f"{e['progress']:.2f} {'laps' if kind.value != 'line' else 'of the path'}"
        return m, (f"'{lab.value}' on {spec} (seed {s}): the pelvis "
                   f"{100 * e['lateral_mean_m']:.1f} cm from the path on average, "
                   f"{100 * e['lateral_max_m']:.0f} cm at most; {walked} walked, "
                   f"{100 * e['mean_m']:.0f} cm from an even pace on average")  # fmt: skip

    update = wire(runner, player, controls, draw, lambda: BUSY)
    rows = [w.HBox([kind, size]), w.HBox([lab, seed]), w.HBox([player.toggle]),
            w.VBox([status, out, player.out])]  # fmt: skip
    return view_box(w, rows, out), update


@view_arguments()
def interactive_parts(
    model: Any, body: Any = None, *, frames: int = 5, length: int | None = None
) -> tuple[Any, Callable[[], Motion]]:
    """An ipywidgets UI for body-part composition: a label for the upper body, one for
    the lower body, the seed and this view's ``mrlib.Sampler`` label ``guidance``
    (``mrlib.sampling.generation.guided_weights``: above 0 each part keeps its label more
    often, at some distance from the training motion); every change
    regenerates and shows a mesh render of ``frames`` frames, titled (and the status line
    too) with each part's condition fidelity (``mrlib.sampling.constraints.part_fidelity``).
    "arms in step" retimes the upper body to the legs' gait
    (``Condition.parts(..., in_step=True)``); "sharpen" fits the noise so that each part
    shows its label (``generate_parts(..., sharpen=SHARPEN_STEPS)``)."""
    import ipywidgets as w

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
    in_step = w.Checkbox(
        value=False, description="arms in step with the legs", indent=False,
        layout=w.Layout(width="auto"), style=WIDE,
        tooltip="retime the upper body's sample to the legs' gait phase, so that the arms "
        "swing in step with the legs (Condition.parts(..., in_step=True))",
    )  # fmt: skip
    sharpen = w.Checkbox(
        value=False, description="sharpen each part's label (takes seconds)", indent=False,
        layout=w.Layout(width="auto"), style=WIDE,
        tooltip=f"fit each part's noise ({SHARPEN_STEPS} steps, seconds per redraw) so that "
        "its windows are nearer its own label's training clips than any other label's",
    )  # fmt: skip
    seed = strict(w.BoundedIntText)(value=0, min=0, max=2**31 - 1, description="seed", style=WIDE)
    guidance = strict(w.FloatSlider)(
        value=GUIDANCE, min=0.0, max=max(1.0, GUIDANCE), step=0.05,
        description="guidance", continuous_update=False, style=WIDE,
    )  # fmt: skip
    controls = [upper, lower, in_step, sharpen, seed, guidance]
    out, status, player, runner = view_parts(w, controls, lambda: body)

    def draw() -> tuple[Motion, str]:
        parts = {"upper": upper.value, "lower": lower.value}
        s, g = int(checked(seed)), checked(guidance)
        aligned = bool(in_step.value)
        m = generate_parts(model, Condition.parts(parts, in_step=aligned), length=length,
                           seed=s, sampler=Sampler(guidance=g), body=body,
                           sharpen=SHARPEN_STEPS if sharpen.value else 0)  # fmt: skip
        windows = min(len(m), int(model.lengths[:, -1].min())) >= 30
        fid = part_fidelity([m], model, parts) if windows else {}
        coordination = arm_leg_coordination(m, body)
        image = crop_to_bodies(render_meshes(m, body, frames=evenly_spaced_frames(len(m), frames)))
        how = ", ".join(["splice"] + ["arms in step"] * aligned + ["sharpened"] * sharpen.value)
        kept = ", ".join(f"{p} {100 * f:.0f}%" for p, f in fid.items())
        title = (f"upper body {upper.value}, lower body {lower.value} ({how}, seed {s})"
                 + (f"; windows keeping their part's label: {kept}" if kept else "")
                 + f"; arm-leg coordination {coordination:.2f}")  # fmt: skip
        fig = mesh_figure(image, title)
        show_figure(out, fig)
        player.show(m)
        return m, title

    def busy() -> str:
        return BUSY + (" (sharpening: several seconds)" if sharpen.value else "")

    update = wire(runner, player, controls, draw, busy)
    rows = [w.HBox([upper, lower]), w.HBox([in_step]), w.HBox([seed, guidance]),
            w.HBox([sharpen, player.toggle]), w.VBox([status, out, player.out])]  # fmt: skip
    return view_box(w, rows, out), update


@view_arguments(
    clips=_clips, steps=lambda n, v: None if v is None else steps(n, v), seconds=_seconds
)
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

    from mrlib.sampling.constraints import (
        Keyframe,
        KeyframeFit,
        generate_with_keyframes,
        keyframe_errors,
    )

    body = resolve_body(body, shared=True)
    names = list(clips)
    a = w.Dropdown(options=names, value=names[0], description="from clip", style=WIDE)
    fa = strict(w.IntSlider)(value=0, min=0, max=clips[names[0]].num_frames - 1, description="frame",
                     continuous_update=False, style=WIDE)  # fmt: skip
    b = w.Dropdown(options=names, value=names[-1], description="to clip", style=WIDE)
    fb = strict(w.IntSlider)(value=clips[names[-1]].num_frames - 1, min=0,
                     max=clips[names[-1]].num_frames - 1, description="frame",
                     continuous_update=False, style=WIDE)  # fmt: skip
    lab = w.Dropdown(options=list(model.labels), value=model.labels[0], description="between",
                     style=WIDE)  # fmt: skip
    seed = strict(w.BoundedIntText)(value=0, min=0, max=2**31 - 1, description="seed", style=WIDE)
    controls = [a, fa, b, fb, lab, seed]
    out, status, player, runner = view_parts(w, controls, lambda: body)
    N = max(2, round(seconds * model.fps))

    def clip_of(choice: Any) -> Motion:
        if choice.value not in clips:  # an option added from Python
            raise MotionValueError(
                f"{choice.description}: unknown clip {choice.value!r}; known: {names}"
            )
        return clips[choice.value]

    def clamp(slider: Any, choice: Any) -> None:
        if choice.value not in clips:
            return  # the redraw reports it
        clip = clips[choice.value]
        runner.hold += 1  # one redraw, by the clip's own observer, not two
        try:
            slider.max = clip.num_frames - 1
            slider.value = min(slider.value, slider.max)
        finally:
            runner.hold -= 1

    def draw() -> tuple[Motion, str]:
        i, j, s = int(checked(fa)), int(checked(fb)), int(checked(seed))
        kfs = [
            Keyframe.from_motion(clip_of(a), i, 0),
            Keyframe.from_motion(clip_of(b), j, N - 1, root=False),
        ]
        fit = KeyframeFit() if steps is None else KeyframeFit(steps=steps)
        m = generate_with_keyframes(model, kfs, N, lab.value, seed=s, body=body, fit=fit)
        shown = [0, N // 4, N // 2, 3 * N // 4, N - 1]
        image = crop_to_bodies(render_meshes(m, body, frames=shown))
        title = f"{a.value}[{i}] -> {lab.value} -> {b.value}[{j}] (seed {s})"
        fig = mesh_figure(image, f"{title}: frames {shown}, keyframes first and last")
        show_figure(out, fig)
        player.show(m)
        e = keyframe_errors(m, kfs)
        return m, f"{title}; keyframe error {e['rotation_deg']:.3f} deg, {e['trans_cm']:.3f} cm"

    a.observe(lambda change: clamp(fa, a), names="value")
    b.observe(lambda change: clamp(fb, b), names="value")
    update = wire(runner, player, controls, draw,
                  lambda: BUSY + " (fitting the noise to the keyframes)")  # fmt: skip
    rows = [w.HBox([a, fa]), w.HBox([b, fb]), w.HBox([lab, seed, player.toggle]),
            w.VBox([status, out, player.out])]  # fmt: skip
    return view_box(w, rows, out), update
