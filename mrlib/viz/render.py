"""Pictures of motion: posed meshes with pyvista, stick figures with matplotlib.

This is the only module that imports pyvista (lazily, inside the functions), so mrlib
works without it; install the ``render`` extra (``pip install mrlib[render]``).

Off-screen rendering needs no display. On a headless Linux machine VTK renders through
EGL (or OSMesa); ``render_meshes`` selects EGL by setting
``VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow`` and ``PYVISTA_OFF_SCREEN=true`` when no
``DISPLAY`` is set (values you set yourself are kept).

In a live JupyterLab, :func:`play_motion` shows a motion as a playable, rotatable 3D
view (pyvista's trame backend, ``pip install mrlib[notebooks]``); where no live frontend
exists (CI, an executed notebook read on GitHub, ``PYVISTA_JUPYTER_BACKEND=static``) it
shows a still picture instead.

The module is long because its three kinds of mesh picture (stills, GIFs and the
notebook player) share one set of conventions for posing, floor and camera, kept
together here.

Conventions: metres, Y up, bodies face +Z in their rest pose (``mrlib.representation.skeleton``).
Side views look along -X: Z (forward) is horizontal, Y vertical.
"""

from __future__ import annotations

import asyncio
import contextlib
import io
import os
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from mrlib.errors import MotionValueError
from mrlib.representation.skeleton import NUM_JOINTS, PARENTS

__all__ = [
    "crop_to_bodies",
    "render_meshes",
    "plot_skeleton_strip",
    "animate_skeleton",
    "save_gif",
    "render_mesh_animation",
    "evenly_spaced_frames",
    "live_3d",
    "MotionPlayer",
    "play_motion",
]

SKIN = (0.83, 0.70, 0.58)
CONTACT_COLOUR = (0.85, 0.1, 0.1)
_LEFT = {1, 4, 7, 10, 13, 16, 18, 20, 22}  # left-side joints, drawn in blue
_RIGHT = {2, 5, 8, 11, 14, 17, 19, 21, 23}


def evenly_spaced_frames(num_frames: int, count: int = 5) -> list[int]:
    """``count`` frame indices spread over ``[0, num_frames)``, first and last included."""
    if num_frames < 1:
        raise MotionValueError("a clip needs at least one frame")
    return sorted(
        set(np.linspace(0, num_frames - 1, min(count, num_frames)).round().astype(int).tolist())
    )


def _headless_defaults() -> None:
    if not os.environ.get("DISPLAY") and os.name != "nt":
        os.environ.setdefault("PYVISTA_OFF_SCREEN", "true")
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")


# -- meshes (pyvista) ---------------------------------------------------------------------
def crop_to_bodies(image: np.ndarray, pad: int = 16, min_saturation: int = 25) -> np.ndarray:
    """Crop a ``render_meshes`` image ``(H, W, 3)`` uint8 to its coloured pixels (skin,
    contact markers) plus ``pad`` pixels: the white background and the grey floor have
    (almost) equal RGB channels and fall away. Returns the image unchanged when nothing
    is coloured."""
    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] < 3:
        raise MotionValueError(f"expected an (H, W, 3) image, got shape {img.shape}")
    rgb = img[..., :3].astype(np.int16)
    coloured = (rgb.max(-1) - rgb.min(-1)) > min_saturation  # (H, W)
    rows, cols = np.flatnonzero(coloured.any(1)), np.flatnonzero(coloured.any(0))
    if len(rows) == 0:
        return img
    r0, r1 = max(0, rows[0] - pad), min(img.shape[0], rows[-1] + pad + 1)
    c0, c1 = max(0, cols[0] - pad), min(img.shape[1], cols[-1] + pad + 1)
    return img[r0:r1, c0:c1]


def render_meshes(
    motion: Any,
    body: Any = None,
    frames: Sequence[int] | None = None,
    *,
    layout: str = "strip",
    highlight_contacts: bool = True,
    contacts: np.ndarray | None = None,
    spacing: float = 0.9,
    window_size: tuple[int, int] = (1200, 520),
    colour: tuple[float, float, float] = SKIN,
    path: str | Path | None = None,
) -> np.ndarray:
    """Render the body mesh of ``motion`` at several frames, off-screen.

    Args:
        motion: a ``mrlib.Motion``.
        body: a ``BodyModel``; None loads the default body.
        frames: frame indices; default five evenly spaced frames.
        layout: ``"strip"`` — the frames side by side along X, each centred on its root
            (a comic strip, seen from the front-left); ``"path"`` — every frame at its
            real position, overlaid along the trajectory.
        highlight_contacts: draw a red sphere on each foot vertex that is in contact.
        contacts: ``(T, 6)`` labels to show; default ``motion.contacts``, else computed
            with ``mrlib.representation.contacts.foot_contacts``.
        spacing: distance between frames in the strip layout (metres).
        window_size: ``(width, height)`` in pixels.
        path: also save the image there (PNG).
    Returns:
        ``(H, W, 3)`` uint8 RGB image.
    """
    _headless_defaults()
    import pyvista as pv

    from mrlib.representation.body import resolve_body

    body = resolve_body(body)
    if layout not in ("strip", "path"):
        raise MotionValueError(f"layout must be 'strip' or 'path', got {layout!r}")
    T = motion.num_frames
    frames = evenly_spaced_frames(T) if frames is None else [int(f) for f in frames]
    if not frames or min(frames) < -T or max(frames) >= T:
        raise MotionValueError(f"frames {frames} out of range for a clip of {T} frames")
    verts = body.motion_vertices(motion, frames)  # (F, V, 3)
    if highlight_contacts and contacts is None:
        if motion.contacts is not None:
            contacts = motion.contacts
        elif T >= 2:
            from mrlib.representation.contacts import foot_contacts

            contacts = foot_contacts(motion, body)
    if contacts is not None:
        contacts = np.asarray(contacts)
        if contacts.shape != (T, 6):
            raise MotionValueError(f"contacts must have shape ({T}, 6), got {contacts.shape}")

    # Place the frames: a strip centres each frame on its root and lines them up on X.
    if layout == "strip":
        root = np.asarray(motion.trans, np.float64)[frames]
        offsets = np.zeros((len(frames), 3))
        offsets[:, 0] = (np.arange(len(frames)) - (len(frames) - 1) / 2) * spacing - root[:, 0]
        offsets[:, 2] = -root[:, 2]
        verts = verts + offsets[:, None, :].astype(np.float32)
    ground = float(verts[..., 1].min())

    faces = np.hstack([np.full((len(body.faces), 1), 3), body.faces]).ravel()
    pl = pv.Plotter(off_screen=True, window_size=list(window_size))
    pl.set_background("white")
    for i, f in enumerate(frames):
        pl.add_mesh(pv.PolyData(verts[i], faces), color=colour, smooth_shading=True)
        if highlight_contacts and contacts is not None:
            on = np.flatnonzero(contacts[f] > 0.5)
            if len(on):
                pts = verts[i, list(np.asarray(body.foot_vertex_ids)[on])]
                pl.add_mesh(
                    pv.PolyData(pts).glyph(geom=pv.Sphere(radius=0.025), scale=False, orient=False),
                    color=CONTACT_COLOUR,
                )
    # Camera: from the front-left and a little above, framing the bodies (not the floor).
    view = np.array([0.35, 0.25, 1.0]) if layout == "strip" else np.array([1.0, 0.6, 0.4])
    lo, hi = verts.reshape(-1, 3).min(0), verts.reshape(-1, 3).max(0)
    centre = (lo + hi) / 2
    pl.camera_position = [tuple(centre + view), tuple(centre), (0, 1, 0)]
    pl.reset_camera()
    pl.camera.zoom(1.35 if layout == "strip" else 1.2)
    size = max(hi[0] - lo[0], hi[2] - lo[2]) + 1.5
    plane = pv.Plane(
        center=(centre[0], ground, centre[2]), direction=(0, 1, 0), i_size=size, j_size=size
    )
    pl.add_mesh(plane, color=(0.9, 0.9, 0.9))
    pl.reset_camera_clipping_range()
    img = pl.screenshot(str(path) if path is not None else None, return_img=True)
    pl.close()
    return np.asarray(img)[..., :3].copy()


def render_mesh_animation(
    motions: Any,
    path: str | Path,
    body: Any = None,
    *,
    fps: float = 15.0,
    seconds: float | None = None,
    titles: Sequence[str] | None = None,
    spacing: float = 1.0,
    window_size: tuple[int, int] = (640, 400),
    highlight_contacts: bool = True,
    progress: bool = False,
) -> Path:
    """An animated GIF of the body mesh of one or more motions, side by side.

    Each body walks in place (its root's ground position is held at its slot of a row
    along X, ``spacing`` metres apart), so several clips of different speed stay in view.
    Contact vertices are drawn as red dots while in contact.

    Args:
        motions: a ``mrlib.Motion`` or a sequence of them (same frame rate).
        path: the ``.gif`` to write.
        body: a ``BodyModel``; None loads the default body.
        fps: frame rate of the GIF; the motions are sampled at that rate.
        seconds: length of the GIF (default: the shortest motion).
        titles: one caption per motion, written above it.
        progress: show a progress bar over the frames.
    Returns:
        The path written.
    """
    _headless_defaults()
    import pyvista as pv

    motions = [motions] if hasattr(motions, "poses") else list(motions)
    if not motions:
        raise MotionValueError("render_mesh_animation needs at least one motion")
    if titles is not None and len(titles) != len(motions):
        raise MotionValueError(f"{len(titles)} titles for {len(motions)} motions")
    if not (np.isfinite(fps) and fps > 0):
        raise MotionValueError(f"fps must be positive, got {fps}")
    from mrlib.representation.body import resolve_body

    body = resolve_body(body)
    src_fps = motions[0].fps
    duration = min(m.num_frames for m in motions) / src_fps
    if seconds is not None:
        duration = min(duration, float(seconds))
    n_out = max(1, int(duration * fps))
    idx = np.minimum(
        (np.arange(n_out) * src_fps / fps).round().astype(int), min(len(m) for m in motions) - 1
    )
    verts, contacts = [], []
    for k, m in enumerate(motions):
        v = body.motion_vertices(m, idx)  # (F, V, 3)
        v[..., 0] += (k - (len(motions) - 1) / 2) * spacing - np.asarray(m.trans)[idx, None, 0]
        v[..., 2] -= np.asarray(m.trans)[idx, None, 2]
        verts.append(v)
        c = m.contacts if m.contacts is not None else None
        if highlight_contacts and c is None and m.num_frames >= 2:
            from mrlib.representation.contacts import foot_contacts

            c = foot_contacts(m, body)
        contacts.append(None if c is None else np.asarray(c)[idx] > 0.5)
    ground = float(min(v[..., 1].min() for v in verts))
    faces = np.hstack([np.full((len(body.faces), 1), 3), body.faces]).ravel()
    foot = np.asarray(body.foot_vertex_ids)

    pl = pv.Plotter(off_screen=True, window_size=list(window_size))
    pl.set_background("white")
    meshes, dots = [], []
    for k, v in enumerate(verts):
        mesh = pv.PolyData(v[0].copy(), faces)
        pl.add_mesh(mesh, color=SKIN, smooth_shading=True)
        meshes.append(mesh)
        if contacts[k] is not None:
            pts = pv.PolyData(v[0, foot].copy())
            pl.add_mesh(pts, color=CONTACT_COLOUR, point_size=9, render_points_as_spheres=True)
            dots.append(pts)
        else:
            dots.append(None)
    # Camera: from the front-left and a little above, framing the bodies over the whole
    # clip (not the floor), then the floor and the captions.
    allv = np.concatenate([v.reshape(-1, 3) for v in verts])
    lo, hi = allv.min(0), allv.max(0)
    centre = (lo + hi) / 2
    pl.camera_position = [tuple(centre + np.array([0.25, 0.2, 1.0])), tuple(centre), (0, 1, 0)]
    pl.reset_camera(bounds=(lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]))
    pl.camera.zoom(1.0 if len(motions) == 1 else 1.2)
    pl.add_mesh(
        pv.Plane(
            center=(centre[0], ground, centre[2]),
            direction=(0, 1, 0),
            i_size=hi[0] - lo[0] + 1.0,
            j_size=hi[2] - lo[2] + 1.5,
        ),
        color=(0.9, 0.9, 0.9),
    )
    pl.reset_camera_clipping_range()
    if titles:  # above each body's head, where it walks in place
        slots = (np.arange(len(motions)) - (len(motions) - 1) / 2) * spacing
        above = np.stack([slots, np.full(len(motions), hi[1] + 0.12), np.zeros(len(motions))], 1)
        pl.add_point_labels(
            above,
            [str(t) for t in titles],
            font_size=12,
            text_color="black",
            shape=None,
            show_points=False,
            always_visible=True,
            justification_horizontal="center",
        )
    images = []
    steps = range(n_out)
    if progress:
        from tqdm.auto import tqdm

        steps = tqdm(steps, desc=f"rendering {Path(path).name}", unit="frame", leave=False)
    for t in steps:
        for k, v in enumerate(verts):
            meshes[k].points = v[t]
            if dots[k] is not None:
                p = v[t, foot].copy()
                p[~contacts[k][t], 1] = ground - 10.0  # hidden below the floor
                dots[k].points = p
        pl.render()
        images.append(np.asarray(pl.screenshot(return_img=True))[..., :3].copy())
    pl.close()
    return save_gif(images, path, fps=fps)


# -- a playable 3D view for notebooks (pyvista + trame) -----------------------------------------
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
    _headless_defaults()
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
        _headless_defaults()
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
        return self.widget._repr_mimebundle_(**kwargs)


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
    import imageio.v3 as iio

    picture = crop_to_bodies(
        render_meshes(motion, body, frames=evenly_spaced_frames(motion.num_frames, frames))
    )
    return Image(data=iio.imwrite("<bytes>", picture, extension=".png"), format="png")


# -- stick figures (matplotlib) --------------------------------------------------------------
def _check_joints(joints: np.ndarray) -> np.ndarray:
    j = np.asarray(joints, dtype=np.float64)
    if j.ndim != 3 or j.shape[1:] != (NUM_JOINTS, 3):
        raise MotionValueError(f"joints must have shape (T, 24, 3), got {j.shape}")
    return j


def _bone_colour(j: int) -> str:
    return "tab:blue" if j in _LEFT else "tab:red" if j in _RIGHT else "0.25"


def _draw_skeleton(ax: Any, xy: np.ndarray, **kw: Any) -> list:
    """Draw one skeleton ``(24, 2)`` (already projected); returns the Line2D artists."""
    lines = []
    for j, p in enumerate(PARENTS):
        if p < 0:
            continue
        (ln,) = ax.plot(xy[[p, j], 0], xy[[p, j], 1], color=_bone_colour(j), lw=2, **kw)
        lines.append(ln)
    return lines


def plot_skeleton_strip(
    joints: np.ndarray,
    frames: Sequence[int] | None = None,
    ax: Any = None,
    *,
    spacing: float = 0.7,
    keep_trajectory: bool = False,
    title: str | None = None,
):
    """Side view of the skeleton at several frames, as stick figures in a row.

    Args:
        joints: ``(T, 24, 3)`` joint positions (metres, Y up, e.g. ``BodyModel.motion_joints``).
        frames: frame indices; default eight evenly spaced frames.
        ax: a matplotlib Axes; a new figure when None.
        spacing: horizontal distance between figures when ``keep_trajectory`` is False.
        keep_trajectory: draw each figure at its real forward (Z) position instead.
    Returns:
        The Axes. Left limbs are blue, right limbs red.
    """
    import matplotlib.pyplot as plt

    j = _check_joints(joints)
    frames = evenly_spaced_frames(len(j), 8) if frames is None else [int(f) for f in frames]
    if ax is None:
        _, ax = plt.subplots(figsize=(max(4.0, 1.1 * len(frames)), 3.2))
    for i, f in enumerate(frames):
        xy = j[f][:, [2, 1]].copy()  # side view: forward (Z) horizontal, up (Y) vertical
        if not keep_trajectory:
            xy[:, 0] += i * spacing - j[f, 0, 2]
        _draw_skeleton(ax, xy)
    ax.axhline(j[frames][..., 1].min(), color="0.7", lw=1)
    ax.set_aspect("equal")
    ax.set_xlabel("forward (m)" if keep_trajectory else "frames")
    ax.set_ylabel("up (m)")
    if not keep_trajectory:
        ax.set_xticks([i * spacing for i in range(len(frames))], [str(f) for f in frames])
    if title:
        ax.set_title(title)
    return ax


def animate_skeleton(
    joints: np.ndarray, fps: float, *, follow: bool = True, title: str | None = None
):
    """A side-view and front-view animation of the skeleton.

    Show it in a notebook with ``IPython.display.HTML(anim.to_jshtml())`` or save it with
    :func:`save_gif`.

    Args:
        joints: ``(T, 24, 3)`` joint positions.
        fps: playback frames per second.
        follow: keep the root centred (the figure walks in place); otherwise the view
            covers the whole trajectory.
    Returns:
        ``matplotlib.animation.FuncAnimation``.
    """
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation

    j = _check_joints(joints)
    if not (np.isfinite(fps) and fps > 0):
        raise MotionValueError(f"fps must be positive, got {fps}")
    fig, axes = plt.subplots(1, 2, figsize=(7, 3.6))
    views = ((2, "side (forward, m)"), (0, "front (left, m)"))
    lo, hi = j[..., 1].min(), j[..., 1].max()
    artists = []
    for ax, (h, label) in zip(axes, views, strict=True):
        ax.set_aspect("equal")
        ax.set_xlabel(label)
        ax.axhline(lo, color="0.7", lw=1)
        ax.set_ylim(lo - 0.1, hi + 0.1)
        if follow:
            ax.set_xlim(-1.0, 1.0)
        else:
            ax.set_xlim(j[..., h].min() - 0.3, j[..., h].max() + 0.3)
        artists.append(_draw_skeleton(ax, np.zeros((NUM_JOINTS, 2))))
    if title:
        fig.suptitle(title)
    fig.tight_layout()

    def update(t: int):
        out = []
        for (h, _), lines in zip(views, artists, strict=True):
            xy = j[t][:, [h, 1]].copy()
            if follow:
                xy[:, 0] -= j[t, 0, h]
            k = 0
            for jj, p in enumerate(PARENTS):
                if p < 0:
                    continue
                lines[k].set_data(xy[[p, jj], 0], xy[[p, jj], 1])
                k += 1
            out += lines
        return out

    anim = FuncAnimation(fig, update, frames=len(j), interval=1000.0 / fps, blit=True)
    plt.close(fig)  # keep notebooks from also showing the empty first frame
    return anim


def save_gif(frames_or_animation: Any, path: str | Path, fps: float = 15.0) -> Path:
    """Write a GIF from a list of ``(H, W, 3)`` uint8 images or a matplotlib animation.

    Returns:
        The path written.
    """
    path = Path(path)
    if not (np.isfinite(fps) and fps > 0):
        raise MotionValueError(f"fps must be positive, got {fps}")
    if hasattr(frames_or_animation, "save"):  # a matplotlib Animation
        frames_or_animation.save(str(path), writer="pillow", fps=fps)
        return path
    import imageio.v2 as imageio

    images = [np.asarray(f) for f in frames_or_animation]
    if not images or any(im.ndim != 3 or im.shape[-1] not in (3, 4) for im in images):
        raise MotionValueError("save_gif needs a non-empty list of (H, W, 3) images")
    imageio.mimsave(path, images, duration=1000.0 / fps, loop=0)
    return path
