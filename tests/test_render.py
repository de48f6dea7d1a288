"""Tests for mrlib.viz.render: off-screen meshes (pyvista) and stick figures (matplotlib)."""

from __future__ import annotations

import base64

import matplotlib

matplotlib.use("Agg")

import importlib.util

import numpy as np
import pytest

from mrlib.errors import MotionValueError
from mrlib.representation.body import load_body_model
from mrlib.representation.motion import Motion
from mrlib.viz.meshes import evenly_spaced_frames, render_meshes, save_gif
from mrlib.viz.render import animate_skeleton, plot_skeleton_strip

pytest.importorskip("pyvista")


@pytest.fixture(scope="module")
def body():
    return load_body_model()


@pytest.fixture(scope="module")
def motion():
    T = 12
    t = np.arange(T) / 30.0
    poses = np.zeros((T, 24, 3), np.float32)
    poses[:, 1, 0] = 0.5 * np.sin(2 * np.pi * t)  # left hip swings
    poses[:, 16, 2] = -1.2  # left arm down
    poses[:, 17, 2] = 1.2
    return Motion(poses=poses, trans=np.zeros((T, 3)), fps=30.0)


def red_pixels(img: np.ndarray) -> int:
    r, g, b = (img[..., i].astype(int) for i in range(3))
    return int(((r > 150) & (g < 80) & (b < 80)).sum())


def test_render_meshes_draws_bodies_and_contacts(motion, body, tmp_path):
    contacts = np.ones((motion.num_frames, 6), np.float32)
    img = render_meshes(
        motion,
        body,
        frames=[0, 6],
        contacts=contacts,
        window_size=(320, 200),
        path=tmp_path / "a.png",
    )
    assert img.shape == (200, 320, 3) and img.dtype == np.uint8
    assert (tmp_path / "a.png").stat().st_size > 1000
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > 50  # shaded, not blank
    skin = (np.abs(img.astype(int) - [212, 178, 148]).sum(-1) < 90).sum()
    assert skin > 500  # the bodies are there
    assert red_pixels(img) > 5  # the contact spheres
    plain = render_meshes(
        motion, body, frames=[0, 6], highlight_contacts=False, window_size=(320, 200)
    )
    assert red_pixels(plain) == 0


def test_render_meshes_path_layout_and_default_contacts(motion, body):
    moving = motion.replace(trans=np.stack([np.zeros(12), np.zeros(12), np.arange(12) * 0.1], -1))
    img = render_meshes(moving, body, frames=[0, 11], layout="path", window_size=(240, 160))
    assert img.shape == (160, 240, 3)
    assert img.std() > 10


def test_render_meshes_rejects_bad_arguments(motion, body):
    with pytest.raises(MotionValueError, match="layout"):
        render_meshes(motion, body, layout="grid")
    with pytest.raises(MotionValueError, match="out of range"):
        render_meshes(motion, body, frames=[0, 99])
    with pytest.raises(MotionValueError, match="contacts"):
        render_meshes(motion, body, frames=[0], contacts=np.ones((3, 6)))


def test_evenly_spaced_frames():
    assert evenly_spaced_frames(100, 5) == [0, 25, 50, 74, 99]
    assert evenly_spaced_frames(3, 5) == [0, 1, 2]


def test_skeleton_strip_and_animation(motion, body, tmp_path):
    joints = body.motion_joints(motion)
    ax = plot_skeleton_strip(joints, frames=[0, 4, 8], title="walk")
    assert len(ax.lines) == 3 * 23 + 1  # 23 bones per figure and the ground line
    with pytest.raises(MotionValueError):
        plot_skeleton_strip(joints[:, :20])
    anim = animate_skeleton(joints[:4], fps=10)
    anim._func(2)  # draw one frame without a display
    out = save_gif(anim, tmp_path / "anim.gif", fps=10)
    import imageio.v2 as imageio

    assert len(imageio.mimread(out)) == 4
    frames = [np.full((20, 30, 3), v, np.uint8) for v in (0, 128, 255)]
    assert len(imageio.mimread(save_gif(frames, tmp_path / "flat.gif", fps=5))) == 3


def test_mesh_animation_moves_and_shows_contacts(body, tmp_path):
    """A walk animates (frames differ) with the bodies side by side; the frame count
    follows the GIF rate; red contact dots appear."""
    import imageio.v2 as imageio

    from mrlib.datasets.synthetic import synthetic_walk
    from mrlib.viz.meshes import render_mesh_animation

    walk = synthetic_walk("walk_happy", seconds=2.0, fps=30.0, body=body)
    out = render_mesh_animation(
        [walk, walk], tmp_path / "a.gif", body, fps=10.0, seconds=1.0, titles=["a", "b"],
        window_size=(320, 200),
    )  # fmt: skip
    frames = np.asarray(imageio.mimread(out))[..., :3].astype(int)
    assert frames.shape == (10, 200, 320, 3)
    assert np.abs(frames[0] - frames[5]).mean() > 0.5  # it moves
    red = (frames[..., 0] > 150) & (frames[..., 1] < 80) & (frames[..., 2] < 80)
    assert red.any()
    with pytest.raises(MotionValueError, match="titles"):
        render_mesh_animation([walk], tmp_path / "b.gif", body, titles=["a", "b"])
    with pytest.raises(MotionValueError, match="at least one"):
        render_mesh_animation([], tmp_path / "c.gif", body)


# -- the notebook player -----------------------------------------------------------------------
class _StubViewer:
    """Stands in for trame's viewer: counts the pushes to the page."""

    def __init__(self):
        self.updates = 0
        self.cameras = 0

    def update(self):
        self.updates += 1

    def push_camera(self):
        self.cameras += 1


@pytest.fixture
def stub_show(monkeypatch):
    """``Plotter.show`` returns a plain widget with a stub viewer: no trame server."""
    ipywidgets = pytest.importorskip("ipywidgets")
    import pyvista as pv

    view = ipywidgets.HTML()
    view.viewer = _StubViewer()
    monkeypatch.setattr(pv.Plotter, "show", lambda self, **kw: view)
    return view


@pytest.fixture(scope="module")
def walk(body):
    from mrlib.datasets.synthetic import synthetic_walk

    return synthetic_walk("walk_happy", seconds=2.0, fps=30.0, body=body)


def test_live_3d_needs_a_kernel_a_live_backend_and_no_ci(monkeypatch):
    import IPython
    import pyvista as pv

    from mrlib.viz.player import live_3d

    monkeypatch.delenv("CI", raising=False)
    monkeypatch.setattr(IPython, "get_ipython", lambda: None)
    assert not live_3d()  # plain Python, pytest
    kernel_shell = type("Shell", (), {"kernel": object()})()
    monkeypatch.setattr(IPython, "get_ipython", lambda: kernel_shell)
    monkeypatch.setattr(pv.global_theme, "_jupyter_backend", "client")
    assert live_3d() == (importlib.util.find_spec("trame_pyvista") is not None)
    monkeypatch.setattr(pv.global_theme, "_jupyter_backend", "static")
    assert not live_3d()
    monkeypatch.setattr(pv.global_theme, "_jupyter_backend", "client")
    monkeypatch.setenv("CI", "true")
    assert not live_3d()


def test_play_motion_without_a_live_frontend_shows_a_still_picture(walk, body):
    """The fallback of CI and of a notebook read on GitHub: a PNG strip (or a GIF)."""
    import imageio.v3 as iio
    from IPython.display import Image

    from mrlib.viz.player import play_motion

    still = play_motion(walk, body, live=False, frames=3)
    assert isinstance(still, Image) and still.format == "png"
    img = iio.imread(still.data)
    assert img.ndim == 3 and img.shape[1] > img.shape[0]  # a strip, wider than high
    skin = (np.abs(img[..., :3].astype(int) - [212, 178, 148]).sum(-1) < 90).sum()
    assert skin > 500
    gif = play_motion(walk.slice(0, 12), body, live=False, still="gif", window_size=(160, 120))
    assert gif.format == "gif" and len(iio.imread(gif.data, index=None)) > 1
    with pytest.raises(MotionValueError, match="still"):
        play_motion(walk, body, live=False, still="movie")


def test_motion_player_poses_each_frame_and_swaps_motions(walk, body, stub_show):
    from mrlib.viz.player import MotionPlayer

    player = MotionPlayer(walk, body, rate=10.0, window_size=(240, 160))
    assert player.widget.children[0] is stub_show
    assert player.frame.max == player.play.max == walk.num_frames - 1
    assert player.play.step == 3 and player.play.interval == 100  # 30 fps at 10 redraws/s
    before = stub_show.viewer.updates
    player.frame.value = 12
    assert stub_show.viewer.updates == before + 1
    assert np.allclose(player.mesh.points, player.vertices(12))
    assert np.abs(player.mesh.points[:, [0, 2]].mean(0)).max() < 0.3  # walks in place
    normals = player.mesh.point_data["Normals"]
    assert np.allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-4)
    assert player.clock.value == "0.40 s of 2.00 s"
    # contact spheres sit on the feet in contact, the others below the floor
    centres = player.dots.points.reshape(len(player._foot), -1, 3).mean(1)
    on_floor = centres[:, 1] > player._ground - 1.0
    assert np.array_equal(on_floor, player._contacts[12])
    with pytest.raises(MotionValueError, match="out of range"):
        player.show_frame(walk.num_frames)
    shorter = walk.slice(0, 20)
    player.frame.value = 15
    player.set_motion(shorter)
    assert player.frame.max == 19 and player.frame.value == 0
    assert stub_show.viewer.cameras == 1
    assert np.allclose(player.mesh.points, player.vertices(0))
    data = player._repr_mimebundle_()  # the live view, and a still for GitHub
    assert "application/vnd.jupyter.widget-view+json" in data
    assert base64.b64decode(data["image/png"])[:8] == b"\x89PNG\r\n\x1a\n"
    player.close()


def test_motion_player_draws_frames_asked_from_other_threads_on_its_own(walk, body, stub_show):
    """ipykernel hands widget messages to other threads; VTK must draw on the thread
    that made its context, so those frames are passed to the player's event loop, and
    only the newest one is drawn."""
    import asyncio
    import threading

    from mrlib.viz.player import MotionPlayer

    async def main():
        player = MotionPlayer(walk, body, window_size=(240, 160))
        drawn = []
        show = player.show_frame
        player.show_frame = lambda t: (drawn.append((t, threading.get_ident())), show(t))
        worker = threading.Thread(
            target=lambda: [setattr(player.frame, "value", t) for t in (3, 5, 9)]
        )
        worker.start()
        worker.join()
        assert drawn == []  # nothing drawn on the worker
        await asyncio.sleep(0.05)
        assert drawn == [(9, threading.get_ident())]
        assert np.allclose(player.mesh.points, player.vertices(9))
        player.close()

    asyncio.run(main())


def test_vertex_normals_point_out_of_a_closed_mesh():
    import pyvista as pv

    from mrlib.viz.player import vertex_normals

    sphere = pv.Sphere(radius=1.0, theta_resolution=16, phi_resolution=16).triangulate()
    v = np.asarray(sphere.points)
    f = sphere.faces.reshape(-1, 4)[:, 1:]
    n = vertex_normals(v, f)
    assert n.shape == v.shape and n.dtype == np.float32
    assert (np.sum(n * v, axis=1) > 0.95).all()  # a sphere's normals are its radii
    assert np.allclose(vertex_normals(np.zeros((3, 3)), np.array([[0, 1, 2]])), 0.0)


def test_render_meshes_frames_the_bodies(motion, body):
    """The bodies fill the picture (the camera's own framing left them in a third of it)."""

    def skin_extent(img):
        rgb = img.astype(int)
        skin = (rgb.max(-1) - rgb.min(-1) > 40) & (rgb[..., 0] > 120)  # skin, not the grey floor
        rows, cols = np.flatnonzero(skin.any(1)), np.flatnonzero(skin.any(0))
        return (rows[-1] - rows[0]) / img.shape[0], (cols[-1] - cols[0]) / img.shape[1]

    kw = dict(frames=[0, 3, 6, 9, 11], window_size=(480, 200))
    framed = skin_extent(render_meshes(motion, body, **kw))
    loose = skin_extent(render_meshes(motion, body, frame_bodies=False, **kw))
    assert min(framed) > 0.8, framed  # both ways: tall and wide
    assert min(loose) < 0.7, loose  # the negative: what the reader saw before
