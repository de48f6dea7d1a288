"""The ``Motion`` container: a clip of SMPL parameters plus what belongs to it.

A ``Motion`` is what mrlib reads from files, what the generator returns, and what gets
exported. Arrays are numpy, float32, in the conventions of ``mrlib.representation.skeleton``
(metres, Y up, axis-angle in radians).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from numbers import Integral
from typing import Any

import numpy as np
import roma
import torch

from mrlib.errors import ArgumentError, ClipTooShortError, MotionValueError, shown
from mrlib.representation.skeleton import NUM_CONTACTS, NUM_JOINTS

__all__ = ["Motion", "NUM_BETAS", "check_motion", "check_motions"]

NUM_BETAS = 10


# Plausibility bounds: a frame rate or a root translation beyond these is a unit or
# parsing error (a BVH "Frame Time: 1e-300", millimetres read as metres), not motion.
# Module constants, read at every check: raise them for a capture that really is longer.
MAX_FPS = 1000.0
MAX_TRANSLATION_M = 1000.0
# An axis-angle's length is its angle: a few times pi where a capture unwraps its angles;
# thousands of radians are a damaged file or wrong units, not a rotation.
MAX_ROTATION_RAD = 1000.0
MAX_FRAMES = 5_000_000  # ~46 h at 30 fps: more is an fps typo, and would not fit in memory
# frames a resampling may make beyond the clip's own (a 24-frame clip at 0.001 fps is 6.7 h:
# at 30 fps, 690,000 frames): 55 minutes at 30 fps, 100 s at 1000 fps. A clip of this many
# frames takes ~10 s and ~1 GB to write as BVH; mrlib samples and restyles 600 s at most.
MAX_RESAMPLE_FRAMES = 100_000
_CHUNK = 32_768  # frames interpolated at a time (a few KB of temporaries each)


def _as_array(name: str, value: Any, shape_tail: tuple[int, ...], what: str) -> np.ndarray:
    raw = np.asarray(value)
    if raw.dtype.kind not in "biuf":
        raise MotionValueError(f"Motion.{name} must hold real numbers, got dtype {raw.dtype}")
    with np.errstate(over="ignore"):
        arr = raw.astype(np.float32)
    if arr.ndim != 1 + len(shape_tail) or tuple(arr.shape[1:]) != shape_tail:
        want = "(T, " + ", ".join(map(str, shape_tail)) + ")"
        raise MotionValueError(f"Motion.{name} must have shape {want} ({what}), got {arr.shape}")
    if not np.isfinite(arr).all():
        bad = np.argwhere(~np.isfinite(arr.reshape(len(arr), -1)))[0, 0]
        raise MotionValueError(f"Motion.{name} has NaN or inf values (first at frame {bad})")
    return arr


@dataclass
class Motion:
    """A clip of SMPL motion.

    Attributes:
        poses: ``(T, 24, 3)`` axis-angle per joint in radians; ``poses[:, 0]`` is the
            global orientation of the pelvis.
        trans: ``(T, 3)`` root translation in metres (SMPL's ``transl``), Y up.
        fps: frames per second.
        betas: ``(num_betas,)`` body shape coefficients (zeros: the mean shape).
        contacts: optional ``(T, 6)`` foot-contact labels in {0, 1}, channel order
            ``mrlib.representation.skeleton.CONTACT_NAMES``.
        label: optional condition name (e.g. ``"walk_happy"``).
        name: optional clip name, usually the file stem.
        meta: free-form provenance (source file, retargeting error, ...).
    """

    poses: np.ndarray
    trans: np.ndarray
    fps: float
    betas: np.ndarray = field(default_factory=lambda: np.zeros(NUM_BETAS, np.float32))
    contacts: np.ndarray | None = None
    label: str | None = None
    name: str | None = None
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if isinstance(self.poses, torch.Tensor):
            self.poses = self.poses.detach().cpu().numpy()
        poses = np.asarray(self.poses)
        if poses.dtype.kind not in "biuf":
            raise MotionValueError(f"Motion.poses must hold real numbers, got dtype {poses.dtype}")
        with np.errstate(over="ignore"):
            poses = poses.astype(np.float32)
        if poses.ndim == 2 and poses.shape[1] == NUM_JOINTS * 3:
            poses = poses.reshape(len(poses), NUM_JOINTS, 3)
        self.poses = _as_array("poses", poses, (NUM_JOINTS, 3), "axis-angle per SMPL joint")
        T = len(self.poses)
        if T == 0:
            raise ClipTooShortError("Motion has no frames")
        check_rotations("Motion.poses", self.poses)
        if isinstance(self.trans, torch.Tensor):
            self.trans = self.trans.detach().cpu().numpy()
        self.trans = _as_array("trans", self.trans, (3,), "root translation in metres")
        if len(self.trans) != T:
            raise MotionValueError(f"Motion.trans has {len(self.trans)} frames, poses has {T}")
        far = np.abs(self.trans).max()
        if far > MAX_TRANSLATION_M:
            raise MotionValueError(
                f"Motion.trans reaches {far:.3g} m from the origin (more than "
                f"{MAX_TRANSLATION_M:g} m): wrong units? (BVH: pass unit=...; for a real "
                "capture that long, raise mrlib.representation.motion.MAX_TRANSLATION_M)"
            )
        try:
            betas = np.asarray(self.betas, dtype=np.float32)
        except (TypeError, ValueError):
            raise ArgumentError(f"Motion.betas must be numbers, got {shown(self.betas)}") from None
        if betas.ndim > 1 and betas.size != betas.shape[-1]:  # (1, NB) is one shape
            raise MotionValueError(f"Motion.betas must be one shape (NB,), got {betas.shape}")
        betas = betas.reshape(-1)
        if not np.isfinite(betas).all():
            raise MotionValueError("Motion.betas has NaN or inf values")
        self.betas = betas
        fps = self.fps
        if isinstance(fps, (bool, str, bytes)) or not isinstance(
            fps, (int, float, np.integer, np.floating)
        ):
            raise ArgumentError(f"Motion.fps must be a number, got {shown(fps)}")
        if not (np.isfinite(fps) and 0 < fps <= MAX_FPS):
            raise MotionValueError(f"Motion.fps must be a number in (0, {MAX_FPS:g}], got {fps}")
        self.fps = float(fps)
        for key in ("label", "name"):
            if getattr(self, key) is not None and not isinstance(getattr(self, key), str):
                raise ArgumentError(
                    f"Motion.{key} must be a string or None, got {shown(getattr(self, key))}"
                )
        if not isinstance(self.meta, dict):
            raise ArgumentError(f"Motion.meta must be a dict, got {shown(self.meta)}")
        if self.contacts is not None:
            c = _as_array("contacts", self.contacts, (NUM_CONTACTS,), "foot contact labels")
            if len(c) != T:
                raise MotionValueError(f"Motion.contacts has {len(c)} frames, poses has {T}")
            if c.size and not (c.min() >= 0 and c.max() <= 1):
                raise MotionValueError(
                    f"Motion.contacts are labels in [0, 1] (1: in contact), got values from "
                    f"{c.min():g} to {c.max():g}"
                )
            self.contacts = c

    # -- basic properties -------------------------------------------------------------
    @property
    def num_frames(self) -> int:
        return len(self.poses)

    def __len__(self) -> int:
        return self.num_frames

    @property
    def duration(self) -> float:
        """Length in seconds."""
        return self.num_frames / self.fps

    def __repr__(self) -> str:
        extra = f", label={self.label!r}" if self.label else ""
        name = f"{self.name!r}, " if self.name else ""
        return f"Motion({name}{self.num_frames} frames @ {self.fps:g} fps{extra})"

    def replace(self, **changes: Any) -> Motion:
        """A copy with some fields replaced (``dataclasses.replace``)."""
        return dataclasses.replace(self, **changes)

    # -- editing ----------------------------------------------------------------------
    def slice(self, start: int, stop: int | None = None) -> Motion:
        """Frames ``[start, stop)`` as a new ``Motion``."""
        for key, value in (("start", start), ("stop", stop)):
            if value is not None and (isinstance(value, bool) or not isinstance(value, Integral)):
                raise ArgumentError(f"Motion.slice: {key} must be an integer, got {shown(value)}")
        sl = slice(start, stop)
        if len(range(*sl.indices(self.num_frames))) == 0:
            raise ClipTooShortError(f"slice [{start}:{stop}] of {self!r} is empty")
        return self.replace(
            poses=self.poses[sl],
            trans=self.trans[sl],
            contacts=None if self.contacts is None else self.contacts[sl],
        )

    def resampled_frames(self, fps: float) -> int:
        """The number of frames :meth:`resample` would give at ``fps``, computed without
        resampling (what a caller checks against its own bound first)."""
        if not isinstance(fps, (int, float, np.integer, np.floating)) or isinstance(fps, bool):
            raise ArgumentError(f"Motion.resample: fps must be a number, got {shown(fps)}")
        if not (np.isfinite(fps) and 0 < fps <= MAX_FPS):
            raise MotionValueError(f"target fps must be in (0, {MAX_FPS:g}], got {fps}")
        if abs(fps - self.fps) < 1e-9:
            return self.num_frames
        last = (self.num_frames - 1) * (float(fps) / self.fps)
        if not last < 2**62:  # a frame rate of 1e-300: as many as no bound allows
            return 2**62
        return int(np.floor(last + 1e-9)) + 1

    def resample(
        self, fps: float, *, smooth: bool = False, keep_duration: bool = False,
        frames: int | None = None,
    ) -> Motion:  # fmt: skip
        """Resample to ``fps``: rotations by slerp, translation linearly, contact labels
        by nearest frame. The first frame is kept; the last output frame is the last
        one not after the input's end. A resampling that would make more than
        ``MAX_RESAMPLE_FRAMES`` frames (and more than the clip has) is refused before
        anything is allocated.

        ``smooth=True`` interpolates rotations (unit quaternions) and translation with
        cubic splines instead (:meth:`at_frames`): raising a generated clip's rate, slerp
        bends the motion at every input frame, which shows as jerk at the higher rate;
        the spline passes through the same frames without the bends. ``meta["source_fps"]``
        keeps the first rate the motion had (the one it was read at).

        ``keep_duration=True`` (with ``smooth``, clips of 4 frames or more): as many frames
        as the clip lasts at ``fps``, ``round(T * fps / self.fps)`` (150 frames at 15 fps
        give 300 at 30, not 299), the last ones continued by the splines less than one
        input frame past the last (what ``mrlib.generate`` returns at ``Sampler.fps``).
        ``frames`` (with ``smooth``, clips of 4 frames or more): exactly that many, continued
        the same way where the clip ends first (a restyled clip at its input's frame count:
        ``mrlib.restyle``)."""
        n_out = self.resampled_frames(fps)
        if abs(fps - self.fps) < 1e-9 and frames in (None, self.num_frames):
            return self.replace()
        T = self.num_frames
        extend = (keep_duration or frames is not None) and smooth and T >= 4
        if frames is not None:
            ok = isinstance(frames, (int, np.integer)) and frames >= 2
            if not (extend and ok and (frames - 1) * self.fps / fps <= T):
                raise MotionValueError(
                    f"resample(frames={frames!r}) needs smooth=True, a clip of 4 frames or "
                    f"more (this one: {T}) and 2 to {int(np.floor(T * fps / self.fps + 1e-9)) + 1}"
                    f" frames at {fps:g} fps (ending within one input frame of its end)"
                )
            n_out = int(frames)
        elif extend:
            n_out = max(n_out, int(round(T * float(fps) / self.fps)))
        if n_out < 2 <= T:  # 8 s at 0.001 fps: one pose "lasting" 1000 s, the motion lost
            raise MotionValueError(
                f"resampling {self.name or 'the clip'} ({T} frames, {self.duration:.4g} s) "
                f"from {self.fps:g} to {fps:g} fps would leave {n_out} frame, no motion; "
                f"choose {self.fps / (T - 1):.4g} fps or more"
            )
        if n_out > max(MAX_RESAMPLE_FRAMES, T):
            raise MotionValueError(
                f"resampling {self.name or 'the clip'} ({T} frames, {self.duration:.4g} s) "
                f"from {self.fps:g} to {fps:g} fps would make {n_out} frames, more than the "
                f"{MAX_RESAMPLE_FRAMES} mrlib resamples to; choose a lower fps, cut the clip "
                "into pieces, or check its frame rate"
            )
        t = np.arange(n_out) * (self.fps / fps)  # positions in input frames
        # the rate it was captured at stays known (a model trained on resampled clips
        # records it: GenerativeModel.source_fps)
        meta = {**self.meta, "source_fps": float(self.meta.get("source_fps", self.fps))}
        if extend and t[-1] > T - 1:  # the splines continued past the last frame
            nearest = np.floor(t + 0.5).astype(np.int64)  # as at_frames: halves go up
            out = self._spline_at(t, np.clip(nearest, 0, T - 1))
        else:
            out = self.at_frames(t, smooth=smooth)
        return out.replace(fps=float(fps), meta=meta)

    def at_frames(self, t, *, smooth: bool = False) -> Motion:
        """The motion at fractional frame positions ``t`` (a 1-D array, clipped to the
        clip): rotations by slerp between the neighbouring frames, translation linearly,
        contact labels from the nearer frame. Same frame rate; ``len(t)`` frames.
        ``smooth=True``: rotations and translation by cubic splines through every frame
        (quaternions kept on one hemisphere, then normalised; clips of under 4 frames by
        slerp)."""
        try:
            t = np.asarray(t, np.float64).reshape(-1)
        except (TypeError, ValueError):
            raise ArgumentError(
                f"Motion.at_frames: t must be frame positions, got {shown(t)}"
            ) from None
        if t.size == 0 or not np.isfinite(t).all():
            raise MotionValueError("at_frames needs a non-empty array of finite frame positions")
        T = self.num_frames
        t = np.clip(t, 0, T - 1)
        i0 = np.clip(np.floor(t).astype(np.int64), 0, T - 1)
        i1 = np.clip(i0 + 1, 0, T - 1)
        w = t - i0
        if smooth and T >= 4:
            return self._spline_at(t, np.where(w < 0.5, i0, i1))
        quats = roma.rotvec_to_unitquat(torch.from_numpy(self.poses.astype(np.float64)))
        poses = np.empty((len(t), NUM_JOINTS, 3), np.float32)
        for a in range(0, len(t), _CHUNK):  # in pieces: temporaries stay small
            b = min(a + _CHUNK, len(t))
            q0, q1 = quats[i0[a:b]], quats[i1[a:b]]
            q1 = torch.where((q0 * q1).sum(-1, keepdim=True) < 0, -q1, q1)  # shortest arc
            q = _slerp(q0, q1, torch.from_numpy(w[a:b])[:, None, None])
            poses[a:b] = roma.unitquat_to_rotvec(q).numpy()
        trans = (1 - w)[:, None] * self.trans[i0] + w[:, None] * self.trans[i1]
        contacts = None
        if self.contacts is not None:
            contacts = self.contacts[np.where(w < 0.5, i0, i1)]
        return self.replace(poses=poses, trans=trans, contacts=contacts)

    def _spline_at(self, t: np.ndarray, nearest: np.ndarray) -> Motion:
        from scipy.interpolate import CubicSpline

        q = roma.rotvec_to_unitquat(torch.from_numpy(self.poses.astype(np.float64))).numpy()
        flip = np.cumprod(np.where((q[1:] * q[:-1]).sum(-1) < 0, -1.0, 1.0), axis=0)
        q[1:] *= flip[..., None]  # each frame on the hemisphere of the one before
        frames = np.arange(self.num_frames, dtype=np.float64)
        qt = CubicSpline(frames, q, axis=0)(t)
        qt /= np.linalg.norm(qt, axis=-1, keepdims=True)
        poses = roma.unitquat_to_rotvec(torch.from_numpy(qt)).numpy().astype(np.float32)
        trans = CubicSpline(frames, np.asarray(self.trans, np.float64), axis=0)(t)
        contacts = None if self.contacts is None else self.contacts[nearest]
        return self.replace(poses=poses, trans=trans.astype(self.trans.dtype), contacts=contacts)


def check_rotations(what: str, poses: np.ndarray) -> None:
    """Refuse axis-angle ``poses (..., 3)`` (radians) longer than ``MAX_ROTATION_RAD``:
    degrees or garbage read as radians, not a rotation."""
    angles = np.linalg.norm(np.asarray(poses, np.float64).reshape(-1, 3), axis=-1)
    if angles.size and angles.max() > MAX_ROTATION_RAD:
        i = int(angles.argmax())
        frame, joint = divmod(i, NUM_JOINTS) if np.ndim(poses) == 3 else (i, 0)
        where = f"frame {frame}, joint {joint}" if np.ndim(poses) == 3 else f"row {i}"
        raise MotionValueError(
            f"{what} holds an axis-angle of {angles[i]:.3g} rad ({where}), more than "
            f"{MAX_ROTATION_RAD:g} rad: not a rotation (degrees, or a damaged file?)"
        )


def check_motion(name: str, value: Any) -> Motion:
    """``value`` if it is a :class:`Motion`, else an ``ArgumentError`` (a file path: load
    it with ``mrlib.load_motion`` first)."""
    if isinstance(value, Motion):
        return value
    hint = ""
    if isinstance(value, str) or hasattr(value, "__fspath__"):
        hint = " (a file: load it first with mrlib.load_motion)"
    raise ArgumentError(f"{name} must be a mrlib.Motion{hint}, got {shown(value)}")


def check_motions(name: str, value: Any) -> list[Motion]:
    """``value`` as a list if it is a list or tuple of :class:`Motion` (not one Motion)."""
    from mrlib.errors import check_list

    return check_list(name, value, check_motion, what="a list of mrlib.Motion")


def _slerp(q0: torch.Tensor, q1: torch.Tensor, w: torch.Tensor) -> torch.Tensor:
    """Spherical interpolation of unit quaternions ``(..., 4)`` with weights broadcast
    to ``(..., 1)``; ``q0`` and ``q1`` are on the same hemisphere."""
    dot = (q0 * q1).sum(-1, keepdim=True).clamp(-1.0, 1.0)
    theta = torch.acos(dot)
    sin = torch.sin(theta)
    small = sin < 1e-6
    a = torch.where(small, 1 - w, torch.sin((1 - w) * theta) / torch.where(small, 1, sin))
    b = torch.where(small, w, torch.sin(w * theta) / torch.where(small, 1, sin))
    q = a * q0 + b * q1
    return q / q.norm(dim=-1, keepdim=True)
