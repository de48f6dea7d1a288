"""Tests for mrlib.render: off-screen meshes (pyvista) and stick figures (matplotlib)."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import numpy as np
import pytest

from mrlib.body import load_body_model
from mrlib.errors import MotionValueError
from mrlib.motion import Motion
from mrlib.render import (
    animate_skeleton,
    evenly_spaced_frames,
    plot_skeleton_strip,
    render_meshes,
    save_gif,
)

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

    from mrlib.render import render_mesh_animation
    from mrlib.synthetic import synthetic_walk

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
