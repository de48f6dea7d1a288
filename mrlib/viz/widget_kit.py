"""The plumbing every interactive view of ``mrlib.viz.widgets`` and
``mrlib.viz.constraint_views`` shares: the status line and the busy state of a redraw
(:class:`Runner`), checked control values, the "3D player" toggle (:class:`Player3D`,
``mrlib.viz.player.play_motion``), and the parts each view is built from
(:func:`view_parts`, :func:`show_figure`, :func:`mesh_figure`, :func:`view_box`).

While a redraw runs the status line reads "drawing..." (:data:`BUSY`) and the controls
are disabled; then it reads what the picture shows. An invalid value (NaN, out of range)
is reported there and the last good picture stays.

A view's box (:func:`view_box`) also carries its latest picture as a PNG: where no
widget can be shown (GitHub, nbviewer, an exported notebook) the picture is, so a
notebook that draws a view before displaying it (``update()`` then ``display(box)``)
leaves that picture in its committed output.
"""

from __future__ import annotations

import base64
import html
import io
from collections.abc import Callable
from typing import Any

import numpy as np

from mrlib.errors import MotionValueError
from mrlib.representation.motion import Motion
from mrlib.viz.player import MotionPlayer, play_motion

__all__ = [
    "BUSY",
    "WIDE",
    "status_html",
    "checked",
    "view_arguments",
    "strict",
    "Runner",
    "Player3D",
    "wire",
    "status_widget",
    "view_parts",
    "show_figure",
    "mesh_figure",
    "view_box",
]

BUSY = "drawing..."
WIDE = {"description_width": "initial"}  # descriptions in full, never cut off
_COLOURS = {"busy": "#9a6700", "error": "#b3261e", "done": "inherit"}


def status_html(text: str, kind: str = "done") -> str:
    """The status line's HTML; ``kind`` is ``busy``, ``error`` or ``done`` (also its CSS
    class, ``mrlib-busy`` and so on, which the browser test reads)."""
    body = html.escape(text, quote=False)
    return f'<span class="mrlib-{kind}" style="color: {_COLOURS[kind]}">{body}</span>'


def view_arguments(**own: Callable[[str, Any], Any]) -> Callable:
    """Decorator of a view builder: its arguments checked before any control is built
    (``mrlib.sampling.arguments.checked``: ``model``, ``body``, ``frames``, ``length``,
    ``window``, ``seconds``, ``motion``... refused when of the wrong type or out of range,
    e.g. ``frames=0``), ``render`` a flag, and ``own`` checks; an ``ArgumentError`` (a
    ``MotionValueError``) like the views' other refusals."""
    import inspect

    from mrlib.errors import check_flag
    from mrlib.sampling.arguments import checked as sampling_checks

    def wrap(fn: Callable) -> Callable:
        flags = {"render": check_flag} if "render" in inspect.signature(fn).parameters else {}
        return sampling_checks(**flags, **own)(fn)

    return wrap


def checked(control: Any) -> float:
    """A numeric control's value, or a ``MotionValueError`` naming it when the value is
    not finite or outside the control's range (sliders clamp, but NaN passes through)."""
    value = float(control.value)
    lo, hi = float(control.min), float(control.max)
    if not (np.isfinite(value) and lo <= value <= hi):
        raise MotionValueError(
            f"{control.description} must be a number in [{lo:g}, {hi:g}], got {value}"
        )
    return value


def strict(cls: type) -> type:
    """``cls`` (an ipywidgets bounded numeric control: ``FloatSlider``, ``IntSlider``,
    ``BoundedIntText``) refusing, instead of clamping, a value outside ``[min, max]`` set
    from Python: a ``TraitError`` naming the control and its range, the value left as it
    was, and the message in the view's status line (``on_refused``, set by :func:`wire`).
    NaN passes, for :func:`checked` to report when the view redraws."""
    from traitlets import TraitError, validate

    class Strict(cls):
        on_refused: Callable[[str], None] | None = None

        @validate("value")
        def _validate_value(self, proposal: Any) -> Any:
            value = proposal["value"]
            if value == value and not self.min <= value <= self.max:  # NaN != NaN
                message = (
                    f"{self.description} must be a number in [{self.min:g}, {self.max:g}], "
                    f"got {value}"
                )
                if self.on_refused is not None:
                    self.on_refused(message)
                raise TraitError(message)
            return value

    Strict.__name__ = Strict.__qualname__ = cls.__name__
    return Strict


class Runner:
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
        self.status.value = status_html(busy, "busy")
        try:
            result, text = work()
        except ValueError as e:  # MotionValueError and the like: an invalid value
            self.status.value = status_html(f"not drawn: {e}{self._still()}", "error")
            raise
        except Exception as e:
            self.status.value = status_html(
                f"failed: {type(e).__name__}: {e}{self._still()}", "error"
            )
            raise
        finally:
            for c, d in zip(self.controls, was, strict=True):
                c.disabled = d
        self.text = text
        self.status.value = status_html(text)
        return result

    def refused(self, message: str) -> None:
        """Report a value a control refused (see :func:`strict`); the picture stays."""
        self.status.value = status_html(f"not drawn: {message}{self._still()}", "error")

    def _still(self) -> str:
        return f" (the picture still shows: {self.text})" if self.text else ""

    def on_change(self, work: Callable[[], tuple[Any, str]],
                  busy: Callable[[], str] = lambda: BUSY) -> Callable[..., None]:  # fmt: skip
        """An observer that redraws and leaves any error in the status line, the last
        good picture in place (a notebook would show an observer's traceback only in the
        kernel log, the page none)."""

        def changed(change: Any = None) -> None:
            if self.hold:
                return
            try:
                self.run(work, busy())
            except Exception:  # noqa: BLE001 - reported in the status line by run()
                pass

        return changed


class Player3D:
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


def wire(
    runner: Runner,
    player: Player3D,
    controls: list[Any],
    draw: Callable[[], tuple[Any, str]],
    busy: Callable[[], str],
) -> Callable[..., Any]:
    """Redraw (``draw``, through ``runner``) on every change of ``controls``, and open
    or close the 3D player when its toggle changes. Returns the view's ``update``: a
    redraw now, its result returned (and its error raised)."""
    for c in controls:
        c.observe(runner.on_change(draw, busy), names="value")
        if hasattr(c, "on_refused"):
            c.on_refused = runner.refused
    player.toggle.observe(
        runner.on_change(
            lambda: (player.show(), runner.text or "not drawn yet"),
            lambda: "opening the 3D view...",
        ),
        names="value",
    )

    def update(*_: Any) -> Any:
        return runner.run(draw, busy())

    return update


def status_widget(w: Any) -> Any:
    """A view's status line (an ``HTML`` widget of CSS class ``mrlib-status``)."""
    status = w.HTML(value=status_html("not drawn yet"))
    status.add_class("mrlib-status")
    return status


def view_parts(w: Any, controls: list[Any], body: Callable[[], Any], *,
               in_place: bool = True) -> tuple[Any, Any, Player3D, Runner]:  # fmt: skip
    """What every view has besides its controls: ``(out, status, player, runner)``, the
    ``Output`` its picture goes to, the status line, the "3D player" of ``body()`` and
    the runner of its redraws (which disables ``controls`` and the player's toggle while
    one runs)."""
    out = w.Output()
    status = status_widget(w)
    player = Player3D(w, body, in_place=in_place)
    runner = Runner(status, [*controls, player.toggle])
    return out, status, player, runner


def show_figure(out: Any, fig: Any) -> None:
    """Show the matplotlib figure ``fig`` in the ``Output`` widget ``out``, in place of
    what it showed, and close the figure."""
    import matplotlib.pyplot as plt
    from IPython.display import display

    with out:
        out.clear_output(wait=True)
        display(fig)
    png = io.BytesIO()
    fig.savefig(png, format="png", bbox_inches="tight")
    out.mrlib_png = png.getvalue()  # the view box's static picture (view_box)
    plt.close(fig)


def mesh_figure(image: np.ndarray, title: str) -> Any:
    """A figure of one mesh render ``(H, W, 3)`` under ``title``, axes off."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(10, 4))
    ax.imshow(image)
    ax.axis("off")
    ax.set_title(title, fontsize=10)
    return fig


def view_box(w: Any, rows: list[Any], out: Any) -> Any:
    """The ``VBox`` of a view's ``rows`` whose display data also holds the latest
    picture drawn into ``out`` (:func:`show_figure`) as ``image/png``: a front end with
    widgets shows the live view, one without (GitHub) the picture."""

    class ViewBox(w.VBox):
        def _repr_mimebundle_(self, **kwargs: Any) -> Any:
            data = super()._repr_mimebundle_(**kwargs)
            png = getattr(out, "mrlib_png", None)
            if png is not None and isinstance(data, dict):
                data = {**data, "image/png": base64.b64encode(png).decode("ascii")}
            return data

    return ViewBox(rows)
