"""A playable, rotatable 3D view of a motion for notebooks (pyvista + trame).

In a live JupyterLab, :func:`play_motion` shows a motion as a playable, rotatable 3D
view (pyvista's trame backend, ``pip install mrlib[notebooks]``); where no live frontend
exists (CI, an executed notebook read on GitHub, ``PYVISTA_JUPYTER_BACKEND=static``) it
shows a still picture instead (``mrlib.viz.meshes``, whose colours the player shares).
Every name is also reachable as ``mrlib.viz.render.<name>``.
"""

from __future__ import annotations

import asyncio
import base64
import contextlib
import io
import os
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from mrlib.errors import MotionValueError
from mrlib.viz.meshes import (
    CONTACT_COLOUR,
    SKIN,
    crop_to_bodies,
    evenly_spaced_frames,
    headless_defaults,
    render_mesh_animation,
    render_meshes,
)

__all__ = ["live_3d", "vertex_normals", "MotionPlayer", "play_motion"]


def live_3d() -> bool:
    """Whether :func:`play_motion` can show a live 3D view here: an IPython kernel, the
    trame backend installed (``trame_pyvista``), pyvista's Jupyter backend not
    ``"static"`` or ``"none"`` (``PYVISTA_JUPYTER_BACKEND``, ``pv.set_jupyter_backend``)
    and no ``CI`` variable set. A kernel run by ``nbclient``/``nbmake`` has no frontend to
    talk to; the Makefile's ``test`` target sets the backend to ``static`` for it."""
    import importlib.util

    if os.environ.get("CI", "").strip().lower() not in ("", "0", "false", "no"):
        return False
    try:
        from IPython import get_ipython
    except ImportError:
        return False
    shell = get_ipython()
    if shell is None or getattr(shell, "kernel", None) is None:
        return False
    if importlib.util.find_spec("trame_pyvista") is None:
        return False
    headless_defaults()
    import pyvista as pv

    backend = pv.global_theme.jupyter_backend
    return backend is None or str(backend).lower() not in ("static", "none")


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit normals ``(V, 3)`` of a triangle mesh at its vertices: the area-weighted mean
    of the normals of the faces ``(F, 3)`` around each vertex (a vertex in no face gets
    zero)."""
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64)
    face_n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])  # 2 x area
    n = np.stack(
        [np.bincount(f.ravel(), np.repeat(face_n[:, k], 3), minlength=len(v)) for k in range(3)], 1
    )
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return (n / np.where(length > 0, length, 1.0)).astype(np.float32)


def _no_wasm_download() -> None:
    """trame-vtklocal, which trame-pyvista installs, fetches VTK's WebAssembly build from
    the internet whenever a trame server starts, and fails where there is no network.
    The player draws with vtk.js and on the server and needs none of it: an empty folder
    stands in for the build (a ``VTK_WASM_DIR_OVERRIDE`` you set yourself is kept)."""
    if not os.environ.get("VTK_WASM_DIR_OVERRIDE"):
        import tempfile

        empty = Path(tempfile.gettempdir()) / "mrlib-no-vtk-wasm"
        empty.mkdir(exist_ok=True)
        os.environ["VTK_WASM_DIR_OVERRIDE"] = str(empty)


class MotionPlayer:
    """A playable, rotatable 3D view of one motion for a live notebook: the body mesh in
    a pyvista plotter shown through trame (drag to orbit, scroll to zoom), with a play
    button and a frame slider (ipywidgets) under it. :meth:`set_motion` swaps the motion
    inside the same view. Prefer :func:`play_motion`, which shows a still picture where
    no live frontend exists.

    Each frame's mesh is posed on demand (one SMPL forward pass), so a long clip costs no
    memory up front; playback advances ``fps / rate`` frames per step so that it keeps
    real time at about ``rate`` redraws per second.

    Attributes:
        widget: the ``ipywidgets.VBox`` shown (the 3D view, then the controls).
        frame, play: the frame slider and the play button (linked in the browser).
        plotter, mesh: the pyvista plotter and the body's ``PolyData``.
    """

    def __init__(
        self,
        motion: Any,
        body: Any = None,
        *,
        in_place: bool = True,
        rate: float = 12.0,
        window_size: tuple[int, int] = (720, 440),
        highlight_contacts: bool = True,
        jupyter_backend: str = "client",
    ) -> None:
        headless_defaults()
        import ipywidgets as w
        import pyvista as pv

        from mrlib.representation.body import resolve_body

        if not (np.isfinite(rate) and rate > 0):
            raise MotionValueError(f"rate must be positive, got {rate}")
        self.body = resolve_body(body, shared=True)
        self.in_place = bool(in_place)
        self.rate = float(rate)
        self.highlight_contacts = bool(highlight_contacts)
        self._foot = np.asarray(self.body.foot_vertex_ids)
        self._load(motion)
        v0 = self.vertices(0)
        faces = np.hstack([np.full((len(self.body.faces), 1), 3), self.body.faces]).ravel()

        self.plotter = pv.Plotter(notebook=True, off_screen=True, window_size=list(window_size))
        self.plotter.set_background("white")
        self._tris = np.asarray(self.body.faces, np.int64)
        self.mesh = pv.PolyData(v0.copy(), faces)
        self.mesh.point_data.active_normals = vertex_normals(v0, self._tris)
        # Smooth from these normals, set with the points every frame, and contact dots as
        # small sphere meshes: pyvista's smooth-shading filter and points drawn as spheres
        # left vertex buffers half-updated in trame's views (VTK errors in the notebook).
        self.plotter.add_mesh(self.mesh, color=SKIN, smooth_shading=False, interpolation="gouraud")
        ball = pv.Sphere(radius=0.025, theta_resolution=10, phi_resolution=10)
        self._ball = np.asarray(ball.points, np.float32)  # (B, 3) around the origin
        tri = ball.faces.reshape(-1, 4)[:, 1:]
        n, B = len(self._foot), len(self._ball)
        balls = np.concatenate([np.column_stack([np.full(len(tri), 3), tri + k * B])
                                for k in range(n)])  # fmt: skip
        self.dots = pv.PolyData(self._dot_points(v0, 0), balls.ravel())
        self.plotter.add_mesh(self.dots, color=CONTACT_COLOUR)
        self.floor = self._floor_mesh()
        self.plotter.add_mesh(self.floor, color=(0.9, 0.9, 0.9))
        self._frame_camera()

        self.frame = w.IntSlider(value=0, min=0, description="frame", continuous_update=True,
                                 style={"description_width": "initial"})  # fmt: skip
        self.play = w.Play(value=0, min=0, tooltip="play / pause the motion")
        w.jslink((self.play, "value"), (self.frame, "value"))
        self.clock = w.Label()
        self._set_ranges()
        # VTK draws with the OpenGL context of the thread that made it, this one, where
        # the kernel's event loop (and trame's server) runs; ipykernel hands widget
        # messages to other threads, so their updates are passed back here.
        self._owner = threading.get_ident()
        try:
            self._loop: asyncio.AbstractEventLoop | None = asyncio.get_running_loop()
        except RuntimeError:
            self._loop = None
        self._wanted: int | None = None  # the newest frame asked for from another thread
        self.frame.observe(lambda change: self._frame_asked(int(change["new"])), names="value")
        _no_wasm_download()
        with contextlib.redirect_stdout(io.StringIO()):  # trame-vtklocal prints its folder
            self.view = self.plotter.show(jupyter_backend=jupyter_backend, return_viewer=True)
        self.widget = w.VBox([self.view, w.HBox([self.play, self.frame, self.clock])])
        self.show_frame(0)

    # the motion ------------------------------------------------------------------------
    def _load(self, motion: Any) -> None:
        T = motion.num_frames
        if T < 1:
            raise MotionValueError("a clip needs at least one frame")
        self.motion = motion
        contacts = None
        if self.highlight_contacts:
            if motion.contacts is not None:
                contacts = np.asarray(motion.contacts) > 0.5
            elif T >= 2:
                from mrlib.representation.contacts import foot_contacts

                contacts = np.asarray(foot_contacts(motion, self.body)) > 0.5
        self._contacts = contacts
        # the floor and the camera from a few frames (posing every frame costs time)
        sample = self.vertices(evenly_spaced_frames(T, 16))
        self._ground = float(sample[..., 1].min())
        joints = self.body.motion_joints(motion).astype(np.float64)  # (T, 24, 3)
        if self.in_place:
            joints[..., [0, 2]] -= np.asarray(motion.trans, np.float64)[:, None][..., [0, 2]]
        lo = np.minimum(joints.reshape(-1, 3).min(0), sample.reshape(-1, 3).min(0))
        hi = np.maximum(joints.reshape(-1, 3).max(0), sample.reshape(-1, 3).max(0))
        self._bounds = (lo, hi)

    def vertices(self, frames: int | Sequence[int]) -> np.ndarray:
        """The mesh at ``frames`` as shown: ``(V, 3)`` for one frame, ``(F, V, 3)`` for a
        list (held at the origin on the ground plane when ``in_place``)."""
        one = np.ndim(frames) == 0
        idx = [int(frames)] if one else [int(f) for f in frames]
        v = self.body.motion_vertices(self.motion, idx)  # (F, V, 3)
        if self.in_place:
            root = np.asarray(self.motion.trans, np.float32)[idx]
            v[..., 0] -= root[:, None, 0]
            v[..., 2] -= root[:, None, 2]
        return v[0] if one else v

    def _floor_mesh(self) -> Any:
        import pyvista as pv

        lo, hi = self._bounds
        centre = (lo + hi) / 2
        return pv.Plane(center=(centre[0], self._ground, centre[2]), direction=(0, 1, 0),
                        i_size=hi[0] - lo[0] + 1.5, j_size=hi[2] - lo[2] + 1.5)  # fmt: skip

    def _frame_camera(self) -> None:
        lo, hi = self._bounds
        centre = (lo + hi) / 2
        view = np.array([0.35, 0.25, 1.0])  # from the front-left, a little above
        self.plotter.camera_position = [tuple(centre + view), tuple(centre), (0, 1, 0)]
        self.plotter.reset_camera(bounds=(lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]))
        self.plotter.reset_camera_clipping_range()

    def _set_ranges(self) -> None:
        T, fps = self.motion.num_frames, float(self.motion.fps)
        step = max(1, round(fps / self.rate))
        self.play.value = 0
        self.frame.value = 0
        self.frame.max = self.play.max = T - 1
        self.play.step = step
        self.play.interval = max(1, round(1000.0 * step / fps))

    def _refresh(self, camera: bool = False) -> None:
        viewer = getattr(self.view, "viewer", None)  # trame: push the scene to the page
        if viewer is not None:
            viewer.update()
            if camera:
                viewer.push_camera()
        else:
            self.plotter.render()

    def _dot_points(self, v: np.ndarray, t: int) -> np.ndarray:
        """The contact spheres' points at frame ``t`` (body vertices ``v``): one sphere on
        each foot vertex in contact, the others hidden below the floor."""
        centres = v[self._foot].copy()
        if self._contacts is None:
            centres[:, 1] = self._ground - 10.0
        else:
            centres[~self._contacts[t], 1] = self._ground - 10.0
        return (centres[:, None, :] + self._ball[None]).reshape(-1, 3)

    def _here(self) -> bool:
        return self._loop is None or threading.get_ident() == self._owner

    def _frame_asked(self, t: int) -> None:
        if self._here():
            self.show_frame(t)
            return
        # from another thread: draw the newest frame asked for, once, on the owner's loop
        first = self._wanted is None
        self._wanted = t
        if first:
            self._loop.call_soon_threadsafe(self._show_wanted)

    def _show_wanted(self) -> None:
        t, self._wanted = self._wanted, None
        if t is not None:
            self.show_frame(t)

    # public ----------------------------------------------------------------------------
    def show_frame(self, t: int) -> None:
        """Pose the body at frame ``t`` and redraw."""
        T = self.motion.num_frames
        if not 0 <= t < T:
            raise MotionValueError(f"frame {t} out of range for a clip of {T} frames")
        v = self.vertices(t)
        self.mesh.points = v
        self.mesh.point_data.active_normals = vertex_normals(v, self._tris)
        self.dots.points = self._dot_points(v, t)
        self.clock.value = (
            f"{t / float(self.motion.fps):.2f} s of {T / float(self.motion.fps):.2f} s"
        )
        self._refresh()

    def set_motion(self, motion: Any) -> None:
        """Show ``motion`` in this view instead (the slider and floor follow it; called
        from another thread, it happens on the view's own thread soon after)."""
        if not self._here():
            self._loop.call_soon_threadsafe(self.set_motion, motion)
            return
        self._load(motion)
        self.floor.points = self._floor_mesh().points
        self._frame_camera()
        self._set_ranges()
        self.show_frame(0)
        self._refresh(camera=True)

    def close(self) -> None:
        """Close the plotter and the widgets (on the view's own thread)."""
        if not self._here():
            self._loop.call_soon_threadsafe(self.close)
            return
        self.play.playing = False
        self.widget.close()
        self.plotter.close()

    def _repr_mimebundle_(self, **kwargs: Any) -> Any:
        """The live view, and a still picture of the motion (:func:`still_picture`) for
        a front end without widgets (GitHub shows the still)."""
        data = self.widget._repr_mimebundle_(**kwargs)
        if isinstance(data, dict):
            png = still_picture(self.motion, self.body)
            data = {**data, "image/png": base64.b64encode(png).decode("ascii")}
        return data


def still_picture(motion: Any, body: Any = None, frames: int = 5) -> bytes:
    """A PNG of ``frames`` evenly spaced frames of ``motion`` (``render_meshes``),
    cropped to the bodies."""
    import imageio.v3 as iio

    picture = crop_to_bodies(
        render_meshes(motion, body, frames=evenly_spaced_frames(motion.num_frames, frames))
    )
    return iio.imwrite("<bytes>", picture, extension=".png")


def play_motion(
    motion: Any,
    body: Any = None,
    *,
    live: bool | None = None,
    still: str = "strip",
    frames: int = 5,
    in_place: bool = True,
    rate: float = 12.0,
    window_size: tuple[int, int] = (720, 440),
) -> Any:
    """Show ``motion`` in a notebook: in a live JupyterLab a :class:`MotionPlayer`
    (rotate, zoom, play, scrub), elsewhere a still picture that any notebook viewer shows.

    Args:
        motion: a ``mrlib.Motion``.
        body: a ``BodyModel``; None uses the shared default body.
        live: force the live view (True) or the still picture (False); default
            :func:`live_3d`.
        still: the picture without a live view: ``"strip"`` — a PNG of ``frames``
            evenly spaced frames (``render_meshes``); ``"gif"`` — an animated GIF of the
            whole motion (``render_mesh_animation``; seconds to render).
        in_place: the live view holds the body at the origin (True) or lets it walk
            its path over a floor that covers it (False).
        rate: redraws per second of the live view's playback.
    Returns:
        A :class:`MotionPlayer` or an ``IPython.display.Image``; either displays as a
        cell's last expression.
    """
    from IPython.display import Image

    from mrlib.representation.body import resolve_body

    if still not in ("strip", "gif"):
        raise MotionValueError(f"still must be 'strip' or 'gif', got {still!r}")
    body = resolve_body(body, shared=True)
    if live is None:
        live = live_3d()
    if live:
        return MotionPlayer(motion, body, in_place=in_place, rate=rate, window_size=window_size)
    if still == "gif":
        import tempfile

        with tempfile.TemporaryDirectory() as tmp:
            path = render_mesh_animation(motion, Path(tmp) / "motion.gif", body,
                                         fps=min(15.0, float(motion.fps)),
                                         window_size=window_size)  # fmt: skip
            return Image(data=path.read_bytes(), format="gif")
    return Image(data=still_picture(motion, body, frames), format="png")
