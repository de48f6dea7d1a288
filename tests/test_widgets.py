"""Tests for mrlib.viz.widgets, driven as a person drives them (control values set, the
callbacks they trigger) on a plumbing model: the busy state of a redraw, the status line
(its title kept current, invalid values reported there), labels in full, controls that do
nothing disabled, and the 3D player following the sample."""

from __future__ import annotations

import html
import re

import matplotlib

matplotlib.use("Agg")

import numpy as np
import pytest

import mrlib.viz.constraint_views as CV
import mrlib.viz.widget_kit as K
import mrlib.viz.widgets as W
from mrlib.errors import MotionValueError

ipywidgets = pytest.importorskip("ipywidgets")


@pytest.fixture(scope="module")
def model(sad_wave_model):
    return sad_wave_model


@pytest.fixture(autouse=True)
def quick_render(monkeypatch):
    """Mesh renders take seconds; a blank picture stands in."""
    blank = lambda m, body, frames=None, **kw: np.zeros((8, 8, 3))
    monkeypatch.setattr(W, "render_meshes", blank)
    monkeypatch.setattr(CV, "render_meshes", blank)


def controls_of(box) -> dict:
    """Every control of a view by its description, wherever it sits in the box."""
    found, todo = {}, [box]
    while todo:
        w = todo.pop()
        todo += list(getattr(w, "children", ()))
        if getattr(w, "description", ""):
            found[w.description] = w
    return found


def status_of(box) -> str:
    """The status line's HTML."""
    return next(w for w in _walk(box) if "mrlib-status" in w._dom_classes).value


def text_of(box) -> str:
    """The status line as a person reads it."""
    return html.unescape(re.sub("<[^>]+>", "", status_of(box)))


def _walk(box):
    todo = [box]
    while todo:
        w = todo.pop()
        todo += list(getattr(w, "children", ()))
        yield w


def test_crossover_title():
    assert W.crossover_title("a", "b", 1.0, 2, 4, 0) == (
        "coarse 'a' at levels 1-2, fine 'b' at levels 3-4 (seed 0)"
    )
    assert "fine '0.20 a + 0.80 b'" in W.crossover_title("a", "b", 0.8, 2, 4, 0)
    # one label: the same on both sides, or nothing of the fine one left
    assert W.crossover_title("wave", "wave", 0.8, 2, 4, 3) == "'wave' at every level (seed 3)"
    assert W.crossover_title("a", "b", 0.0, 2, 4, 1) == "'a' at every level (seed 1)"


def test_crossover_shows_drawing_with_controls_disabled_then_the_current_title(
    model, body, monkeypatch
):
    seen = []
    generate = W.generate

    def watched(*args, **kw):  # what the page shows while the sample is made
        seen.append((status_of(box), [c.disabled for c in controls.values()]))
        return generate(*args, **kw)

    monkeypatch.setattr(W, "generate", watched)
    box, update = W.interactive_crossover(model, body, frames=2, window=10)
    controls = controls_of(box)
    assert "not drawn yet" in text_of(box)
    update()
    assert "drawing..." in seen[-1][0] and all(seen[-1][1])
    assert not any(c.disabled for c in controls.values())  # restored
    assert "coarse 'walk_sad' at levels 1-2, fine 'wave' at levels 3-4 (seed 0)" in text_of(box)
    assert "nearest-window labels" in text_of(box)
    # a change redraws through the control's observer; the status follows every redraw
    controls["seed"].value = 4
    assert len(seen) == 2 and "(seed 4)" in text_of(box)
    controls["coarse"].value = "wave"  # coarse = fine: one label, not '0.00 wave + 1.00 wave'
    assert "'wave' at every level (seed 4)" in text_of(box)
    controls["fine weight"].value = 0.8
    assert "'wave' at every level" in text_of(box)


def test_a_drawn_view_carries_its_picture_for_front_ends_without_widgets(model, body):
    """Before the first draw a view's display data is the widget alone; after it, the
    latest picture as a PNG too (what GitHub shows of a committed notebook)."""
    import base64

    box, update = W.interactive_crossover(model, body, frames=2, window=10)
    assert "image/png" not in box._repr_mimebundle_()
    update()
    data = box._repr_mimebundle_()
    assert "application/vnd.jupyter.widget-view+json" in data
    assert base64.b64decode(data["image/png"])[:8] == b"\x89PNG\r\n\x1a\n"


def test_invalid_values_are_reported_and_the_last_picture_stays(model, body):
    box, update = W.interactive_crossover(model, body, frames=2, window=10)
    controls = controls_of(box)
    first = update()
    drawn = status_of(box)
    controls["fine weight"].value = float("nan")  # sliders clamp, but NaN passes
    assert "mrlib-error" in status_of(box)
    shown = text_of(box)
    assert "not drawn: fine weight must be a number in [0, 1], got nan" in shown
    assert first.title in shown  # says what the picture still shows
    assert not any(c.disabled for c in controls.values())
    with pytest.raises(MotionValueError, match="fine weight"):
        update()  # called directly, the error is raised as well
    controls["fine weight"].value = 1.0
    assert status_of(box) == drawn  # the same picture again
    controls["guidance"].max = 5.0
    controls["guidance"].min = 2.0  # clamps the value into range: a valid redraw
    assert "mrlib-done" in status_of(box)


def test_parts_labels_in_full_and_arms_in_step(model, body, monkeypatch):
    import mrlib.sampling.constraints

    calls = []
    generate_parts = mrlib.sampling.constraints.generate_parts

    def recorded(model, parts, **kw):
        calls.append(parts)
        return generate_parts(model, parts, **kw)

    monkeypatch.setattr(mrlib.sampling.constraints, "generate_parts", recorded)
    box, update = CV.interactive_parts(model, body=body, length=40)
    controls = controls_of(box)
    in_step = controls["arms in step with the legs"]
    sharpen = controls["sharpen each part's label (takes seconds)"]
    for box_ in (in_step, sharpen):
        assert box_.style.description_width == "initial" and box_.layout.width == "auto"
        assert not box_.indent and len(box_.tooltip) > 40
    in_step.value = True
    assert calls[-1].in_step is True
    assert "(splice, arms in step, seed 0)" in text_of(box)
    assert not in_step.disabled  # the redraw's restore leaves it enabled
    in_step.value = False
    assert calls[-1].in_step is False and "(splice, seed 0)" in text_of(box)


def test_path_status_and_busy_text(model, body, monkeypatch):
    import mrlib.sampling.constraints

    seen = []
    on_path = mrlib.sampling.constraints.generate_on_path

    def watched(*args, **kw):
        seen.append(status_of(box))
        return on_path(*args, **kw)

    monkeypatch.setattr(mrlib.sampling.constraints, "generate_on_path", watched)
    box, update = CV.interactive_path(model, body, seconds=3.0)
    controls = controls_of(box)
    update()
    assert seen[-1].endswith("drawing...</span>")
    assert "'walk_sad' on circle:2 (seed 0): the pelvis" in text_of(box)
    assert "cm from the path on average" in text_of(box)
    controls["seed"].value = 1
    assert seen[-1].endswith("drawing...</span>")
    assert "(seed 1)" in text_of(box)


def test_inbetween_changing_clip_redraws_once(model, body, sad_wave_clips, monkeypatch):
    import mrlib.sampling.constraints

    calls = []
    with_keyframes = mrlib.sampling.constraints.generate_with_keyframes

    def counted(*args, **kw):
        calls.append(kw)
        return with_keyframes(*args, **kw)

    monkeypatch.setattr(mrlib.sampling.constraints, "generate_with_keyframes", counted)
    clips = {c.label: c for c in sad_wave_clips}
    box, update = CV.interactive_inbetween(model, clips, body, seconds=2.0, steps=0)
    controls = controls_of(box)
    update()
    assert "walk_sad[0] -> walk_sad -> wave[35] (seed 0); keyframe error" in text_of(box)
    n = len(calls)
    controls["from clip"].value = "wave"  # the frame slider is clamped: one redraw
    assert len(calls) == n + 1
    assert "wave[0] -> walk_sad -> wave[" in text_of(box)


def test_the_3d_player_follows_the_sample(model, body, monkeypatch):
    shown = []
    monkeypatch.setattr(K, "play_motion", lambda m, body, **kw: shown.append((m, kw)) or "still")
    box, update = W.interactive_crossover(model, body, frames=2, window=10)
    controls = controls_of(box)
    view = update()
    assert shown == []  # off until asked for
    controls["3D player"].value = True
    assert shown[-1][0] is view.motion and shown[-1][1]["still"] == "gif"
    assert "(seed 0)" in text_of(box)  # the status of the picture, not "opening..."
    controls["seed"].value = 2
    assert shown[-1][0] is not view.motion and len(shown) == 2  # the new sample
    controls["3D player"].value = False
    controls["seed"].value = 3
    assert len(shown) == 2  # off: nothing drawn


def _build(name, model, body, clips):
    if name == "crossover":
        return W.interactive_crossover(model, body, frames=2, window=10)
    if name == "restyle":
        return W.interactive_restyle(model, clips[0], body, frames=2, render=False)
    if name == "path":
        return CV.interactive_path(model, body, seconds=2.0)
    if name == "parts":
        return CV.interactive_parts(model, body=body, length=40)
    return CV.interactive_inbetween(model, {c.label: c for c in clips}, body, seconds=2.0, steps=0)


BUILDERS = ["crossover", "restyle", "path", "parts", "inbetween"]


# the builders' own arguments, each refused before a control is built (frames <= 0 made
# views that drew nothing; a path for the model a view that failed on first use)
BAD_ARGUMENTS = [
    ("crossover", "frames", 0),
    ("crossover", "frames", -3),
    ("crossover", "frames", 2.5),
    ("crossover", "frames", "5"),
    ("crossover", "length", 0),
    ("crossover", "window", 0),
    ("crossover", "render", "no"),
    ("crossover", "model", "runs/x/checkpoint.pt"),
    ("restyle", "frames", 0),
    ("restyle", "frames", -1),
    ("restyle", "motion", "clip.bvh"),
    ("restyle", "label", 3.5),
    ("path", "seconds", 0),
    ("path", "seconds", float("nan")),
    ("path", "body", "smpl.pkl"),
    ("parts", "frames", 0),
    ("parts", "length", -5),
    ("inbetween", "seconds", -1.0),
    ("inbetween", "steps", -1),
    ("inbetween", "clips", []),
]


@pytest.mark.parametrize(("view", "arg", "value"), BAD_ARGUMENTS)
def test_a_view_refuses_a_bad_argument_up_front(view, arg, value, model, body, sad_wave_clips):
    clips = {c.label: c for c in sad_wave_clips}
    args = {
        "crossover": (W.interactive_crossover, dict(model=model, body=body, frames=2)),
        "restyle": (W.interactive_restyle, dict(model=model, motion=sad_wave_clips[0], body=body)),
        "path": (CV.interactive_path, dict(model=model, body=body)),
        "parts": (CV.interactive_parts, dict(model=model, body=body)),
        "inbetween": (CV.interactive_inbetween, dict(model=model, clips=clips, body=body)),
    }
    build, kwargs = args[view]
    with pytest.raises(MotionValueError, match=f"{build.__name__}: {arg} must be") as info:
        build(**{**kwargs, arg: value})
    assert repr(value) in str(info.value)


class TestInvalidValuesFromPython:
    """Every view: a NaN in a numeric control, or a label option the model does not
    have, shows its problem in the status line and keeps the last good picture; the
    controls stay usable and a good value draws again."""

    @pytest.fixture
    def view(self, request, model, body, sad_wave_clips):
        box, update = _build(request.param, model, body, sad_wave_clips)
        update()
        assert "mrlib-done" in status_of(box)
        return box, status_of(box)

    @pytest.mark.parametrize("view", BUILDERS, indirect=True)
    def test_nan_in_each_float_control(self, view):
        box, drawn = view
        floats = [c for c in controls_of(box).values() if isinstance(c, ipywidgets.FloatSlider)]
        for c in floats:
            good = c.value
            c.value = float("nan")
            assert "mrlib-error" in status_of(box), c.description
            shown = text_of(box)
            assert f"{c.description} must be a number in" in shown and "got nan" in shown
            assert "the picture still shows" in shown
            assert not c.disabled
            c.value = good
            assert status_of(box) == drawn, c.description

    @pytest.mark.parametrize("view", BUILDERS, indirect=True)
    def test_out_of_range_from_python_is_refused_not_clamped(self, view):
        """ipywidgets would clamp ``slider.value = 5`` to the maximum without a word; the
        views' controls refuse it (a TraitError naming the control and its range), keep
        their value and say so in the status line."""
        from traitlets import TraitError

        box, drawn = view
        numeric = [c for c in controls_of(box).values() if hasattr(c, "on_refused")]
        assert numeric
        for c in numeric:
            good = c.value
            with pytest.raises(TraitError, match=re.escape(f"{c.description} must be a number in")):
                c.value = c.max + 1
            assert c.value == good, c.description
            shown = text_of(box)
            assert "mrlib-error" in status_of(box) and "the picture still shows" in shown
            c.value = c.min if good != c.min else c.max
            c.value = good
            assert status_of(box) == drawn, c.description

    @pytest.mark.parametrize("view", BUILDERS, indirect=True)
    def test_an_added_label_option(self, view):
        box, drawn = view
        dropdowns = [
            c
            for c in controls_of(box).values()
            if isinstance(c, ipywidgets.Dropdown) and "walk_sad" in c.options
        ]
        for c in dropdowns:
            good = c.value
            c.options = [*c.options, "no_such_label"]
            c.value = good
            c.value = "no_such_label"
            assert "mrlib-error" in status_of(box), c.description
            assert "the picture still shows" in text_of(box)
            c.value = good
            assert "mrlib-done" in status_of(box), c.description
