"""The ``Motion`` container: a clip of SMPL parameters plus what belongs to it.

A ``Motion`` is what mrlib reads from files, what the generator returns, and what gets
exported. Arrays are numpy, float32, in the conventions of ``mrlib.representation.skeleton``
(metres, Y up, axis-angle in radians).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import roma
import torch

from mrlib.errors import ClipTooShortError, MotionValueError
from mrlib.representation.skeleton import NUM_CONTACTS, NUM_JOINTS

__all__ = ["Motion", "NUM_BETAS"]

NUM_BETAS = 10


# Plausibility bounds: a frame rate or a root translation beyond these is a unit or
# parsing error (a BVH "Frame Time: 1e-300", millimetres read as metres), not motion.
# Module constants, read at every check: raise them for a capture that really is longer.
MAX_FPS = 1000.0
MAX_TRANSLATION_M = 1000.0
MAX_FRAMES = 5_000_000  # ~46 h at 30 fps: more is an fps typo, and would not fit in memory


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
        betas = np.asarray(self.betas, dtype=np.float32).reshape(-1)
        if not np.isfinite(betas).all():
            raise MotionValueError("Motion.betas has NaN or inf values")
        self.betas = betas
        if not (np.isfinite(self.fps) and 0 < self.fps <= MAX_FPS):
            raise MotionValueError(
                f"Motion.fps must be a number in (0, {MAX_FPS:g}], got {self.fps}"
            )
        self.fps = float(self.fps)
        if self.contacts is not None:
            c = _as_array("contacts", self.contacts, (NUM_CONTACTS,), "foot contact labels")
            if len(c) != T:
                raise MotionValueError(f"Motion.contacts has {len(c)} frames, poses has {T}")
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
        sl = slice(start, stop)
        if len(range(*sl.indices(self.num_frames))) == 0:
            raise ClipTooShortError(f"slice [{start}:{stop}] of {self!r} is empty")
        return self.replace(
            poses=self.poses[sl],
            trans=self.trans[sl],
            contacts=None if self.contacts is None else self.contacts[sl],
        )

    def resample(self, fps: float) -> Motion:
        """Resample to ``fps``: rotations by slerp, translation linearly, contact labels
        by nearest frame. The first frame is kept; the last output frame is the last
        one not after the input's end."""
        if not (np.isfinite(fps) and 0 < fps <= MAX_FPS):
            raise MotionValueError(f"target fps must be in (0, {MAX_FPS:g}], got {fps}")
        if abs(fps - self.fps) < 1e-9:
            return self.replace()
        T = self.num_frames
        n_out = int(np.floor((T - 1) * fps / self.fps + 1e-9)) + 1
        if n_out > MAX_FRAMES:
            raise MotionValueError(
                f"resampling {T} frames from {self.fps:g} to {fps:g} fps would make {n_out} "
                f"frames (more than {MAX_FRAMES}); choose a lower fps"
            )
        t = np.arange(n_out) * (self.fps / fps)  # positions in input frames
        return self.at_frames(t).replace(fps=float(fps))

    def at_frames(self, t) -> Motion:
        """The motion at fractional frame positions ``t`` (a 1-D array, clipped to the
        clip): rotations by slerp between the neighbouring frames, translation linearly,
        contact labels from the nearer frame. Same frame rate; ``len(t)`` frames."""
        t = np.asarray(t, np.float64).reshape(-1)
        if t.size == 0 or not np.isfinite(t).all():
            raise MotionValueError("at_frames needs a non-empty array of finite frame positions")
        T = self.num_frames
        t = np.clip(t, 0, T - 1)
        i0 = np.clip(np.floor(t).astype(np.int64), 0, T - 1)
        i1 = np.clip(i0 + 1, 0, T - 1)
        w = t - i0
        aa = torch.from_numpy(self.poses.astype(np.float64))
        q0 = roma.rotvec_to_unitquat(aa[i0])
        q1 = roma.rotvec_to_unitquat(aa[i1])
        q1 = torch.where((q0 * q1).sum(-1, keepdim=True) < 0, -q1, q1)  # shortest arc
        wt = torch.from_numpy(w)[:, None, None]
        q = _slerp(q0, q1, wt)
        poses = roma.unitquat_to_rotvec(q).numpy().astype(np.float32)
        trans = (1 - w)[:, None] * self.trans[i0] + w[:, None] * self.trans[i1]
        contacts = None
        if self.contacts is not None:
            contacts = self.contacts[np.where(w < 0.5, i0, i1)]
        return self.replace(poses=poses, trans=trans, contacts=contacts)


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
