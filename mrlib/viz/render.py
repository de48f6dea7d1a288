"""Pictures of motion: posed meshes with pyvista, stick figures with matplotlib.

The mesh pictures are in two modules, whose names this one hands on so that
``mrlib.viz.render.<name>`` reaches every picture: ``mrlib.viz.meshes`` (stills and
GIFs rendered off-screen: :func:`render_meshes`, :func:`render_mesh_animation`,
:func:`crop_to_bodies`, :func:`save_gif`) and ``mrlib.viz.player`` (:func:`play_motion`
and :class:`MotionPlayer`, a playable 3D view in a live JupyterLab, a still picture
elsewhere). pyvista and matplotlib are imported only inside functions, so mrlib works
without them (the ``render`` and ``notebooks`` extras).

This module draws the stick figures (matplotlib): :func:`plot_skeleton_strip` and
:func:`animate_skeleton`.

Conventions: metres, Y up, bodies face +Z in their rest pose (``mrlib.representation.skeleton``).
Side views look along -X: Z (forward) is horizontal, Y vertical.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from mrlib.errors import MotionValueError
from mrlib.representation.skeleton import NUM_JOINTS, PARENTS
from mrlib.viz.meshes import (
    evenly_spaced_frames,
)

__all__ = [
    "plot_skeleton_strip",
    "animate_skeleton",
]

_LEFT = {1, 4, 7, 10, 13, 16, 18, 20, 22}  # left-side joints, drawn in blue
_RIGHT = {2, 5, 8, 11, 14, 17, 19, 21, 23}


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
