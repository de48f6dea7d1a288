"""Still pictures and GIFs of the body mesh (pyvista), and the conventions they share.

pyvista is imported only inside the functions (here and in ``mrlib.viz.player``), so
mrlib works without it; install the ``render`` extra (``pip install mrlib[render]``).

Off-screen rendering needs no display. On a headless Linux machine VTK renders through
EGL (or OSMesa); ``render_meshes`` selects EGL by setting
``VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow`` and ``PYVISTA_OFF_SCREEN=true`` when no
``DISPLAY`` is set (values you set yourself are kept; :func:`headless_defaults`).

The skin and contact colours set here are the notebook player's (``mrlib.viz.player``)
too. Every name is also reachable as ``mrlib.viz.render.<name>``.

Conventions: metres, Y up, bodies face +Z in their rest pose (``mrlib.representation.skeleton``).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image  # pillow: a dependency of matplotlib

from mrlib.errors import MotionValueError
from mrlib.progress import bar as progress_bar

__all__ = [
    "SKIN",
    "CONTACT_COLOUR",
    "evenly_spaced_frames",
    "headless_defaults",
    "crop_to_bodies",
    "render_meshes",
    "render_mesh_animation",
    "save_gif",
]

SKIN = (0.83, 0.70, 0.58)
CONTACT_COLOUR = (0.85, 0.1, 0.1)
STRIP_SPACING = 0.9  # metres between the frames of a render_meshes strip
RENDER_SCALE = 2  # render_meshes draws at this multiple of its size when it frames the bodies


def evenly_spaced_frames(num_frames: int, count: int = 5) -> list[int]:
    """``count`` frame indices spread over ``[0, num_frames)``, first and last included."""
    if num_frames < 1:
        raise MotionValueError("a clip needs at least one frame")
    return sorted(
        set(np.linspace(0, num_frames - 1, min(count, num_frames)).round().astype(int).tolist())
    )


def headless_defaults() -> None:
    """Off-screen EGL rendering where there is no display (module docstring)."""
    if not os.environ.get("DISPLAY") and os.name != "nt":
        os.environ.setdefault("PYVISTA_OFF_SCREEN", "true")
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")


# -- meshes (pyvista) ---------------------------------------------------------------------
def _coloured_rows_cols(img: np.ndarray, min_saturation: int = 25) -> tuple[np.ndarray, np.ndarray]:
    """The rows and columns of a render that hold coloured pixels (skin, contact markers):
    the white background and the grey floor have (almost) equal RGB channels."""
    rgb = img[..., :3].astype(np.int16)
    coloured = (rgb.max(-1) - rgb.min(-1)) > min_saturation  # (H, W)
    return np.flatnonzero(coloured.any(1)), np.flatnonzero(coloured.any(0))


def crop_to_bodies(image: np.ndarray, pad: int = 16, min_saturation: int = 25) -> np.ndarray:
    """Crop a ``render_meshes`` image ``(H, W, 3)`` uint8 to its coloured pixels (skin,
    contact markers) plus ``pad`` pixels: the white background and the grey floor have
    (almost) equal RGB channels and fall away. Returns the image unchanged when nothing
    is coloured."""
    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] < 3:
        raise MotionValueError(f"expected an (H, W, 3) image, got shape {img.shape}")
    rows, cols = _coloured_rows_cols(img, min_saturation)
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
    window_size: tuple[int, int] = (1200, 520),
    path: str | Path | None = None,
    frame_bodies: bool = True,
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
        window_size: ``(width, height)`` in pixels.
        path: also save the image there (PNG).
        frame_bodies: zoom so the bodies and the floor under their soles fill the
            picture (rendered at twice the size, cropped to the bodies, scaled back to
            ``window_size``); False keeps the camera's own, looser framing.
    Returns:
        ``(H, W, 3)`` uint8 RGB image.
    """
    headless_defaults()
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
        offsets[:, 0] = (np.arange(len(frames)) - (len(frames) - 1) / 2) * STRIP_SPACING - root[
            :, 0
        ]
        offsets[:, 2] = -root[:, 2]
        verts = verts + offsets[:, None, :].astype(np.float32)
    ground = float(verts[..., 1].min())

    faces = np.hstack([np.full((len(body.faces), 1), 3), body.faces]).ravel()
    scale = RENDER_SCALE if frame_bodies else 1
    pl = pv.Plotter(off_screen=True, window_size=[scale * int(v) for v in window_size])
    pl.set_background("white")
    for i, f in enumerate(frames):
        pl.add_mesh(pv.PolyData(verts[i], faces), color=SKIN, smooth_shading=True)
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
    for v in verts:  # a soft shadow under each body: where it stands on the floor
        x, z = (float(np.median(v[:, k])) for k in (0, 2))
        for r, a in ((0.32, 0.12), (0.22, 0.18)):
            disc = pv.Disc(
                center=(x, ground + 0.01, z), inner=0.0, outer=r, normal=(0, 1, 0), c_res=48
            )
            pl.add_mesh(disc, color=(0.35, 0.35, 0.35), opacity=a, lighting=False)
    pl.reset_camera_clipping_range()
    img = np.asarray(pl.screenshot(None, return_img=True))[..., :3].copy()
    pl.close()
    if frame_bodies:
        img = fit_to_bodies(img, window_size)
    if path is not None:  # PNG bytes in memory, published by the atomic writer
        import io

        from mrlib.io.outputs import write_bytes

        buf = io.BytesIO()
        Image.fromarray(img).save(buf, format="PNG")
        write_bytes(path, buf.getvalue(), overwrite=True)
    return img


def fit_to_bodies(image: np.ndarray, size: tuple[int, int], pad: float = 0.05) -> np.ndarray:
    """The part of a render that holds the bodies (coloured pixels: skin, contact markers)
    with a margin of ``pad`` of its height, widened or heightened to the aspect of
    ``size = (width, height)`` (around the bodies, white where it runs past the render)
    and scaled to that size. Unchanged but scaled when nothing is coloured."""
    img = np.asarray(image)
    w_out, h_out = int(size[0]), int(size[1])
    rows, cols = _coloured_rows_cols(img)
    if len(rows) == 0:
        r0, r1, c0, c1 = 0, img.shape[0], 0, img.shape[1]
    else:
        m = pad * (rows[-1] - rows[0] + 1)
        r0, r1 = rows[0] - m, rows[-1] + 1 + m
        c0, c1 = cols[0] - m, cols[-1] + 1 + m
        h, w = r1 - r0, c1 - c0
        if w / h < w_out / h_out:  # too narrow: widen around the centre
            c0, c1 = (c0 + c1) / 2 - h * w_out / h_out / 2, (c0 + c1) / 2 + h * w_out / h_out / 2
        else:  # too flat: heighten, keeping the floor under the soles in view
            extra = w * h_out / w_out - h
            r0, r1 = r0 - 0.6 * extra, r1 + 0.4 * extra
    r0, r1, c0, c1 = (int(round(v)) for v in (r0, r1, c0, c1))
    top, left = max(0, -r0), max(0, -c0)
    bottom, right = max(0, r1 - img.shape[0]), max(0, c1 - img.shape[1])
    padded = np.pad(img, ((top, bottom), (left, right), (0, 0)), constant_values=255)
    crop = padded[r0 + top : r1 + top, c0 + left : c1 + left]
    out = Image.fromarray(np.ascontiguousarray(crop)).resize(
        (w_out, h_out), Image.Resampling.LANCZOS
    )
    return np.asarray(out)[..., :3].copy()


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
        spacing: metres between the bodies of the row.
        progress: show a progress bar over the frames.
    Returns:
        The path written.
    """
    headless_defaults()
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
        steps = progress_bar(steps, desc=f"rendering {Path(path).name}", unit="frame", leave=False)
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


def save_gif(
    frames_or_animation: Any, path: str | Path, fps: float = 15.0, *, overwrite: bool = True
) -> Path:
    """Write a GIF from a list of ``(H, W, 3)`` uint8 images or a matplotlib animation,
    atomically and never through a symbolic link (``mrlib.io.outputs``; ``overwrite=False``
    refuses an existing file).

    Returns:
        The path written.
    """
    from mrlib.io.outputs import check_writable, write_bytes

    path = Path(path)
    if not (np.isfinite(fps) and fps > 0):
        raise MotionValueError(f"fps must be positive, got {fps}")
    check_writable(path, overwrite=overwrite)
    if hasattr(frames_or_animation, "save"):  # a matplotlib Animation
        import tempfile

        # the pillow writer wants a file name: render into a private folder, then publish
        with tempfile.TemporaryDirectory(prefix="mrlib-gif-") as tmp:
            scratch = Path(tmp) / "animation.gif"
            frames_or_animation.save(str(scratch), writer="pillow", fps=fps)
            data = scratch.read_bytes()
        return write_bytes(path, data, overwrite=overwrite)
    import imageio.v3 as iio

    images = [np.asarray(f) for f in frames_or_animation]
    if not images or any(im.ndim != 3 or im.shape[-1] not in (3, 4) for im in images):
        raise MotionValueError("save_gif needs a non-empty list of (H, W, 3) images")
    data = iio.imwrite("<bytes>", images, extension=".gif", duration=1000.0 / fps, loop=0)
    return write_bytes(path, data, overwrite=overwrite)
