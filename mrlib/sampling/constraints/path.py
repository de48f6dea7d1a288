"""Root paths: make a generated motion walk a given ground-plane path.

A model trained on a few straight walks never turns by itself, so a path cannot come
from its noise alone (the noise fit measured against bending,
``bench/experiments/path_optimise.py``, stayed off its path). Bending separates what the
model is good at from what the path prescribes:

1. The generated pelvis ground track ``g(t)`` is split into its travel ``g_s(t)`` (a
   Gaussian low-pass of ``smooth_s`` seconds) and the sway ``g - g_s`` around it.
2. The travel is re-laid along the path by arc length: the pelvis goes to ``p(s(t))``
   plus the sway, turned by ``dtheta(t)``, the angle between the path's tangent there and
   the generated direction of travel; the body's global orientation turns by the same
   angle about the vertical. The pace is the motion's own (``s(t)`` its own travelled
   distance) unless the path carries times, which then set ``s(t)``.
3. The feet are planted again (``mrlib.sampling.cleanup``): turning the body while a foot is
   down would otherwise slide it.

Headings are angles about +Y with 0 along +Z and +90 degrees along +X (SMPL: facing +Z,
left at +X), so a path that turns left curves towards +X. Path files are read by
``mrlib.sampling.constraints.path_files``; how well a motion walks a path is measured by
``mrlib.sampling.constraints.path_measure``.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
from scipy.ndimage import gaussian_filter1d

from mrlib.errors import ArgumentError, MotionValueError, check_number, shown
from mrlib.representation.motion import Motion
from mrlib.sampling.arguments import checked
from mrlib.sampling.constraints.common import pelvis_rest, warn_past_the_end

__all__ = [
    "GroundPath",
    "parse_path",
    "MAX_PATH_SECONDS",
    "follow_path",
    "ground_track",
    "yaw_matrix",
    "heading_of",
]

MIN_TRAVEL_SPEED = 0.1  # m/s: slower than this, the direction of travel is not defined
# the longest motion generate_on_path makes in one piece: a 10-minute walk stays within
# the 1000 m a motion may span (mrlib.representation.motion.MAX_TRANSLATION_M)
MAX_PATH_SECONDS = 600.0
# what a path may hold: its coordinates (metres) and times (seconds)
MAX_PATH_COORD = 1e6
MAX_PATH_TIME = 1e7
PACE_WARNING = 1.3  # warn when a timed path asks for this times the motion's pace (or 1/x)


def yaw_matrix(theta: np.ndarray) -> np.ndarray:
    """``(..., 3, 3)`` rotations by ``theta`` radians about +Y (maps +Z to
    ``(sin theta, 0, cos theta)``)."""
    c, s = np.cos(theta), np.sin(theta)
    R = np.zeros(np.shape(theta) + (3, 3))
    R[..., 0, 0], R[..., 0, 2], R[..., 1, 1], R[..., 2, 0], R[..., 2, 2] = c, s, 1.0, -s, c
    return R


def heading_of(d: np.ndarray) -> np.ndarray:
    """Heading (radians) of ground directions ``(..., 2)`` given as (x, z)."""
    return np.arctan2(d[..., 0], d[..., 1])


@dataclass(frozen=True)
class GroundPath:
    """A path on the ground plane.

    Attributes:
        points: ``(N, 2)`` metres, (x, z) with Y up.
        times: ``(N,)`` seconds, strictly increasing, or None: the motion keeps its own
            pace along the path.
        closed: the last point joins the first (circles, figure-eights): a motion
            longer than one lap keeps going round.
        name: shown in plots and metadata.
    """

    points: np.ndarray
    times: np.ndarray | None = None
    closed: bool = False
    name: str = "path"
    _arc: np.ndarray = field(init=False, repr=False, compare=False)
    _heading: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        p = np.asarray(self.points, np.float64)
        if p.ndim != 2 or p.shape[1] != 2 or len(p) < 2 or not np.isfinite(p).all():
            if p.ndim == 2 and p.shape[1] == 2 and len(p) >= 2:
                got = "NaN or infinite values"
            else:
                got = f"an array of shape {p.shape}" if p.ndim else "one number"
            raise MotionValueError(
                "a path needs 2 or more points of 2 numbers each, (x, z) in metres, as an "
                f"array of N rows and 2 columns; got {got}"
            )
        if np.abs(p).max() > MAX_PATH_COORD:
            raise MotionValueError(
                f"path points must lie within {MAX_PATH_COORD:g} m of the origin, got "
                f"{np.abs(p).max():.3g} (another unit?)"
            )
        if self.closed and np.linalg.norm(p[-1] - p[0]) < 1e-9:
            p = p[:-1]  # the closing segment is implicit
        object.__setattr__(self, "points", p)
        q = np.vstack([p, p[:1]]) if self.closed else p
        seg = np.linalg.norm(np.diff(q, axis=0), axis=1)
        if (seg < 1e-9).any():
            raise MotionValueError("a path has two consecutive points at the same place")
        arc = np.concatenate([[0.0], np.cumsum(seg)])  # arc length at each point of q
        # vertex headings from central differences, unwrapped along the path
        if self.closed:
            d = np.roll(p, -1, axis=0) - np.roll(p, 1, axis=0)
            h = np.unwrap(heading_of(d))
            # back at the first point after a lap: the heading has turned by the winding
            h = np.append(h, h[-1] + (h[0] - h[-1] + np.pi) % (2 * np.pi) - np.pi)
        else:
            h = np.unwrap(heading_of(np.gradient(p, axis=0)))
        object.__setattr__(self, "_arc", arc)
        object.__setattr__(self, "_heading", h)
        if self.times is not None:
            t = np.asarray(self.times, np.float64).reshape(-1)
            if len(t) != len(self.points) or not np.isfinite(t).all() or (np.diff(t) <= 0).any():
                k = int(np.argmax(np.diff(t) <= 0)) + 1 if len(t) > 1 else 0
                why = (f"got {len(t)}" if len(t) != len(self.points) else "got NaN or infinite "
                       "values" if not np.isfinite(t).all() else f"time {k} ({t[k]:g} s) is not "
                       f"after time {k - 1} ({t[k - 1]:g} s)")  # fmt: skip
                raise MotionValueError(
                    f"path times must be {len(self.points)} strictly increasing seconds, one "
                    f"per point: {why}"
                )
            if np.abs(t).max() > MAX_PATH_TIME:
                raise MotionValueError(
                    f"path times must lie within {MAX_PATH_TIME:g} s, got {np.abs(t).max():.3g}"
                )
            object.__setattr__(self, "times", t)

    # -- geometry -------------------------------------------------------------------------
    @property
    def length(self) -> float:
        """Arc length in metres (one lap for a closed path)."""
        return float(self._arc[-1])

    @property
    def duration(self) -> float | None:
        """Seconds from the first to the last time, or None without times."""
        return None if self.times is None else float(self.times[-1] - self.times[0])

    def at(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Points ``(..., 2)`` and unwrapped headings ``(...)`` at arc lengths ``s``.
        A closed path wraps (headings keep turning lap after lap); an open one continues
        straight along its end tangents."""
        s = np.asarray(s, np.float64)
        q = np.vstack([self.points, self.points[:1]]) if self.closed else self.points
        L = self.length
        if self.closed:
            lap, u = np.divmod(s, L)
            turn = self._heading[-1] - self._heading[0]
            xz = np.stack([np.interp(u, self._arc, q[:, k]) for k in range(2)], -1)
            h = np.interp(u, self._arc, self._heading) + lap * turn
            return xz, h
        u = np.clip(s, 0.0, L)
        xz = np.stack([np.interp(u, self._arc, q[:, k]) for k in range(2)], -1)
        h = np.interp(u, self._arc, self._heading)
        extra = (s - u)[..., None]  # beyond either end: straight on
        xz = xz + extra * np.stack([np.sin(h), np.cos(h)], -1)
        return xz, h

    def arc_at_time(self, t: np.ndarray) -> np.ndarray:
        """Arc length reached at times ``t`` (seconds from the first time); needs times."""
        if self.times is None:
            raise MotionValueError(f"path {self.name!r} has no times")
        return np.interp(np.asarray(t) + self.times[0], self.times, self._arc[: len(self.times)])

    def distance(self, xz: np.ndarray) -> np.ndarray:
        """``(T,)`` distance of ground points ``(T, 2)`` to the path's polyline."""
        xz = np.asarray(xz, np.float64)
        q = np.vstack([self.points, self.points[:1]]) if self.closed else self.points
        a, b = q[:-1], q[1:]  # (S, 2) segments
        ab = b - a
        out = np.empty(len(xz))
        for i in range(0, len(xz), 512):
            x = xz[i : i + 512, None]  # (n, 1, 2)
            u = np.clip(((x - a) * ab).sum(-1) / (ab * ab).sum(-1), 0.0, 1.0)
            out[i : i + 512] = np.linalg.norm(x - (a + u[..., None] * ab), axis=-1).min(1)
        return out

    # -- presets --------------------------------------------------------------------------
    @classmethod
    def line(cls, length: float = 10.0, heading_deg: float = 0.0) -> GroundPath:
        """A straight line from the origin, ``heading_deg`` from +Z towards +X."""
        _check_size("length", length)
        h = np.radians(heading_deg)
        end = length * np.array([np.sin(h), np.cos(h)])
        return cls(np.stack([np.zeros(2), end]), name=f"line {length:g} m")

    @classmethod
    def circle(cls, radius: float = 2.0, left: bool = True, points: int = 256) -> GroundPath:
        """A circle through the origin, starting along +Z and turning left (towards
        +X) or right."""
        _check_size("radius", radius)
        phi = np.linspace(0, 2 * np.pi, points, endpoint=False)
        sx = 1.0 if left else -1.0
        xz = np.stack([sx * radius * (1 - np.cos(phi)), radius * np.sin(phi)], -1)
        return cls(xz, closed=True, name=f"circle r={radius:g} m")

    @classmethod
    def figure_eight(cls, radius: float = 2.0, points: int = 256) -> GroundPath:
        """Two circles of ``radius`` meeting at the origin: a left lap, then a right
        lap, with the tangent continuous where they meet."""
        _check_size("radius", radius)
        a = cls.circle(radius, True, points).points
        b = cls.circle(radius, False, points).points
        return cls(np.vstack([a, b]), closed=True, name=f"figure-eight r={radius:g} m")

    @classmethod
    def from_csv(cls, path: str | Path, closed: bool = False) -> GroundPath:
        """Columns ``x, z`` (metres) and optionally ``t`` (seconds), with or without a
        header row; ``#`` starts a comment (``mrlib.sampling.constraints.path_files``).

        Raises:
            MotionFileError: naming ``path``: not a regular file, larger than
                ``MAX_PATH_FILE_BYTES``, not UTF-8, rows of differing widths, a header that
                does not match the rows, more than ``MAX_PATH_POINTS`` points, or values
                that no path has (non-finite, beyond ``MAX_PATH_COORD`` / ``MAX_PATH_TIME``).
        """
        from mrlib.sampling.constraints.path_files import read_path_csv

        return read_path_csv(path, lambda p, t: cls(p, t, closed, name=Path(path).stem))


def _check_size(name: str, value: float) -> None:
    if not (np.isfinite(value) and value > 0):
        raise MotionValueError(f"{name} must be a positive number of metres, got {value:g}")


def check_path_spec(name: str, value: Any) -> Any:
    """A ground path: a ``GroundPath``, a spec such as ``"circle:2"`` or a CSV file."""
    import os

    if isinstance(value, (str, os.PathLike, GroundPath)):
        return value
    raise ArgumentError(
        f"{name} must be a GroundPath, a spec such as 'circle:2' or 'line:5', or a CSV "
        f"file, got {shown(value)}"
    )


@checked(spec=check_path_spec)
def parse_path(spec: str | Path | GroundPath) -> GroundPath:
    """A path from ``"circle:R"``, ``"circle-right:R"``, ``"eight:R"``, ``"line:L"``
    (metres; without a number, R is 2 and L 10: ``"circle"``) or a CSV file
    (:meth:`GroundPath.from_csv`)."""
    if isinstance(spec, GroundPath):
        return spec
    text = str(spec)
    kind, _, arg = text.partition(":")
    presets = {
        "circle": lambda v: GroundPath.circle(v, left=True),
        "circle-right": lambda v: GroundPath.circle(v, left=False),
        "eight": GroundPath.figure_eight,
        "figure-eight": GroundPath.figure_eight,
        "line": GroundPath.line,
    }
    if kind in presets and not Path(text).is_file():
        try:
            value = float(arg) if arg else (10.0 if kind == "line" else 2.0)
        except ValueError:
            raise MotionValueError(f"path {text!r}: '{arg}' is not a number of metres") from None
        try:
            return presets[kind](value)
        except MotionValueError as e:
            raise MotionValueError(f"path {text!r}: {e}") from None
    if Path(text).suffix.lower() in (".csv", ".txt") or Path(text).is_file():
        return GroundPath.from_csv(text)
    raise MotionValueError(
        f"unknown path {text!r}: use circle:R, circle-right:R, eight:R, line:L (metres) or a "
        "CSV file of x, z[, t]"
    )


# -- following ----------------------------------------------------------------------------
def _low_pass(x: np.ndarray, sigma: float) -> np.ndarray:
    """Gaussian low-pass of ``x (T, D)`` over time, ``sigma`` frames, with the ends
    extended by point reflection (``2 x[0] - x[k]``), so a walk at a steady pace keeps
    that pace up to its first and last frames (holding the ends, the travel would
    start and end at half speed and lag the pelvis there)."""
    n = min(len(x) - 1, int(4 * sigma) + 1)
    if n < 1:
        return gaussian_filter1d(x, sigma, axis=0, mode="nearest")
    head = 2 * x[0] - x[n:0:-1]
    tail = 2 * x[-1] - x[-2 : -n - 2 : -1]
    y = gaussian_filter1d(np.concatenate([head, x, tail]), sigma, axis=0, mode="nearest")
    return y[n : n + len(x)]


@checked()
def ground_track(motion: Motion, body=None, smooth_s: float = 0.5) -> dict[str, np.ndarray]:
    """The pelvis on the ground and its travel: ``pelvis (T, 2)``, ``travel (T, 2)``
    (low-passed, ``smooth_s`` seconds, the ends extended by point reflection), ``heading (T,)`` of travel (unwrapped; held
    where slower than ``MIN_TRAVEL_SPEED``), ``arc (T,)`` travelled distance and
    ``speed (T,)`` m/s."""
    from mrlib.representation.body import resolve_body

    body = resolve_body(body, shared=True)
    pel = motion.trans[:, [0, 2]].astype(np.float64) + pelvis_rest(motion, body)[[0, 2]]
    travel = _low_pass(pel, smooth_s * motion.fps)
    v = np.gradient(travel, axis=0) * motion.fps
    speed = np.linalg.norm(v, axis=1)
    moving = speed > MIN_TRAVEL_SPEED
    if moving.any():
        idx = np.where(moving, np.arange(len(v)), 0)
        np.maximum.accumulate(idx, out=idx)  # hold the last moving frame's direction
        first = int(np.argmax(moving))
        idx[:first] = first
        h = np.unwrap(heading_of(v[idx]))
    else:  # standing: the direction the pelvis faces
        from mrlib.representation.rotations import axis_angle_to_matrix

        R0 = axis_angle_to_matrix(torch.from_numpy(motion.poses[:, 0].astype(np.float64)))
        f = R0[:, [0, 2], 2].numpy()
        h = np.unwrap(heading_of(f))
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(travel, axis=0), axis=1))])
    return {"pelvis": pel, "travel": travel, "heading": h, "arc": arc, "speed": speed}


@checked(path=check_path_spec, jitter=lambda n, v: check_number(n, v, low=0, optional=True))
def follow_path(
    motion: Motion,
    path: GroundPath | str,
    *,
    smooth_s: float = 0.5,
    clean: bool = True,
    body=None,
    jitter: float | None = None,
) -> Motion:
    """``motion`` walking ``path`` (method: module docstring), starting at the path's
    first point.

    Args:
        motion: any motion (label or speech model output, a capture).
        path: a :class:`GroundPath` or a spec for :func:`parse_path`.
        smooth_s: low-pass of the travel, seconds (the sway of a step is kept).
        clean: plant the feet afterwards (``mrlib.sampling.cleanup.cleanup_foot_contacts``
            with ``keep_path``: the root keeps the path, the legs plant the feet; needs
            contact labels, skipped without them).
        jitter: the clean-up's jitter filter, frames (None: ``JITTER_SIGMA``; a model's
            sample raised to a higher rate spans the same time with proportionally more).
    Returns:
        The motion with new translation and global orientation; ``meta["path"]`` says
        which path and pace.
    """
    from mrlib.representation.body import resolve_body
    from mrlib.representation.rotations import axis_angle_to_matrix, matrix_to_axis_angle

    path = parse_path(path)
    body = resolve_body(body, shared=True)
    tr = ground_track(motion, body, smooth_s)
    own_pace = float(tr["arc"][-1] / max(motion.duration, 1e-9))
    if path.times is not None:
        t = np.arange(motion.num_frames) / motion.fps
        s = path.arc_at_time(t)
        asked = float((s[-1] - s[0]) / max(motion.duration, 1e-9))
        ratio = asked / max(own_pace, 1e-9)
        if not 1 / PACE_WARNING <= ratio <= PACE_WARNING:
            warnings.warn(
                f"path {path.name!r} asks for {asked:.2f} m/s but this motion travels at "
                f"{own_pace:.2f} m/s: the feet will slide (give a path without times to keep "
                "the motion's pace, or pick a faster / slower condition)",
                stacklevel=2,
            )
    else:
        s = tr["arc"]
        warn_past_the_end(path, float(s[-1] - s[0]), own_pace)
    target, h_path = path.at(s)
    dtheta = h_path - tr["heading"]
    Ry = yaw_matrix(dtheta)  # (T, 3, 3)
    sway = tr["pelvis"] - tr["travel"]  # (T, 2)
    sway3 = np.stack([sway[:, 0], np.zeros(len(sway)), sway[:, 1]], -1)
    new_pel = target + (Ry @ sway3[..., None])[:, [0, 2], 0]
    R0 = axis_angle_to_matrix(torch.from_numpy(motion.poses[:, 0].astype(np.float64))).numpy()
    poses = motion.poses.copy()
    poses[:, 0] = matrix_to_axis_angle(torch.from_numpy(Ry @ R0)).numpy()
    trans = motion.trans.astype(np.float64).copy()
    trans[:, [0, 2]] = new_pel - pelvis_rest(motion, body)[[0, 2]]
    meta = dict(
        motion.meta,
        path={
            "name": path.name,
            "length_m": round(path.length, 3),
            "pace_m_s": round(own_pace if path.times is None else asked, 3),
            "timed": path.times is not None,
        },
    )
    out = motion.replace(poses=poses, trans=trans, meta=meta)
    if clean and out.contacts is not None:
        from mrlib.sampling.cleanup import JITTER_SIGMA, cleanup_foot_contacts

        # the root stays on the path: the legs take the feet's ground corrections
        sigma = JITTER_SIGMA if jitter is None else float(jitter)
        out = cleanup_foot_contacts(out, body, keep_path=True, jitter=sigma)
    return out
