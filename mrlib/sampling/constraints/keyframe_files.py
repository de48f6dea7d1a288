"""Keyframes as data: the :class:`Keyframe` (a full or partial pose, and optionally the
root, held at a frame) and its file format (:func:`save_keyframes`,
:func:`load_keyframes`: an npz read lazily, every array's header checked before its data,
bounded counts and values, one ``MotionFileError`` naming the file). How keyframes are
held, in-betweened and continued is in ``mrlib.sampling.constraints.keyframes``."""

from __future__ import annotations

import math
import zipfile
import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from mrlib.errors import (
    ArgumentError,
    MotionFileError,
    MotionValueError,
    check_flag,
    check_list,
    check_path,
    shown,
)
from mrlib.io.npz import read_npy_header
from mrlib.representation.motion import MAX_TRANSLATION_M, Motion
from mrlib.representation.skeleton import NUM_JOINTS
from mrlib.sampling.arguments import checked
from mrlib.sampling.constraints.common import joint_ids

__all__ = ["Keyframe", "save_keyframes", "load_keyframes", "MAX_KEYFRAMES"]


# a keyframe's axis-angle components beyond this are not radians (degrees, a unit error)
MAX_AXIS_ANGLE = 100.0
# the most keyframes one file may hold (each is checked, and held by the noise fit)
MAX_KEYFRAMES = 10_000
# the latest frame a keyframe may hold at: mrlib.representation.motion.MAX_FRAMES
MAX_KEYFRAME_FRAME = 5_000_000


def _frame_index(frame) -> int:
    """A keyframe's frame as an int in ``[0, MAX_KEYFRAME_FRAME]``: whole numbers only
    (1.7 is refused, not cut to 1)."""
    import operator

    if isinstance(frame, (bool, np.bool_)):
        raise MotionValueError(f"keyframe frame must be a whole number, got {frame!r}")
    try:
        f = operator.index(frame)
    except TypeError:
        v = float(frame) if isinstance(frame, (float, np.floating)) else math.nan
        if not (math.isfinite(v) and v.is_integer()):
            raise MotionValueError(
                f"keyframe frame must be a whole number, got {frame!r}"
            ) from None
        f = int(v)
    if not 0 <= f <= MAX_KEYFRAME_FRAME:
        raise MotionValueError(f"keyframe frame must be in [0, {MAX_KEYFRAME_FRAME}], got {f}")
    return f


def _bounded_values(
    name: str, value, shape: tuple[int, ...], limit: float, within: str, hint: str
) -> np.ndarray:
    """``value`` as a float64 array of ``shape`` (or as many values flat), finite and no
    component beyond ``limit``, else a ``MotionValueError``: "keyframe {name} must
    {within}" ({hint})."""
    words = {(NUM_JOINTS, 3): f"{NUM_JOINTS} joint rotations of 3 axis-angle values (SMPL)",
             (3,): "3 values, x, y and z in metres"}.get(shape, str(shape))  # fmt: skip
    try:
        a = np.asarray(value, np.float64)
    except (TypeError, ValueError):
        raise MotionValueError(f"keyframe {name} must be {words}, got {shown(value)}") from None
    if a.size == math.prod(shape):
        a = a.reshape(shape)
    if a.shape != shape:
        got = f"{' x '.join(map(str, a.shape))} values" if a.ndim else "one number"
        raise MotionValueError(f"keyframe {name} must be {words}, got {got}")
    if not np.isfinite(a).all():
        raise MotionValueError(f"keyframe {name} holds NaN or infinite values")
    if np.abs(a).max() > limit:
        raise MotionValueError(f"keyframe {name} must {within}, got {np.abs(a).max():.3g} ({hint})")
    return a


@dataclass(frozen=True)
class Keyframe:
    """A pose constraint at one frame.

    Attributes:
        frame: the output frame it holds at (0-based).
        poses: ``(24, 3)`` axis-angle (joint 0 the global orientation), or None.
        joints: which joints of ``poses`` are constrained (names or indices); None means
            all 24 when ``poses`` is given.
        trans: ``(3,)`` SMPL root translation in metres (Y up), or None: the root is free.
    """

    frame: int
    poses: np.ndarray | None = None
    joints: tuple[int, ...] | None = None
    trans: np.ndarray | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "frame", _frame_index(self.frame))
        if self.poses is None and self.trans is None:
            raise MotionValueError(f"keyframe at frame {self.frame} constrains nothing")
        if self.poses is not None:
            p = _bounded_values(
                f"at frame {self.frame}: poses", self.poses, (NUM_JOINTS, 3), MAX_AXIS_ANGLE,
                f"be axis-angle radians within +-{MAX_AXIS_ANGLE:g}", "degrees or another unit?",
            )  # fmt: skip
            object.__setattr__(self, "poses", p)
            joints = range(NUM_JOINTS) if self.joints is None else self.joints
            object.__setattr__(self, "joints", joint_ids(joints))
        elif self.joints is not None:
            raise MotionValueError("keyframe joints given without poses")
        if self.trans is not None:
            t = _bounded_values(
                f"at frame {self.frame}: trans", self.trans, (3,), MAX_TRANSLATION_M,
                f"lie within {MAX_TRANSLATION_M:g} m of the origin", "centimetres?",
            )  # fmt: skip
            object.__setattr__(self, "trans", t)

    @classmethod
    def from_motion(
        cls, motion: Motion, index: int, frame: int, joints=None, root: bool = True
    ) -> Keyframe:
        """Frame ``index`` of ``motion`` as a keyframe at output ``frame`` (``joints``:
        a subset; ``root``: also its translation)."""
        if not -motion.num_frames <= index < motion.num_frames:
            raise MotionValueError(f"frame {index} is outside {motion!r}")
        return cls(frame, motion.poses[index], joints, motion.trans[index] if root else None)


def check_keyframes(name: str, value: Any) -> list:
    """A list of ``mrlib.sampling.constraints.Keyframe``."""

    def one(n: str, v: Any) -> Any:
        if not isinstance(v, Keyframe):
            raise ArgumentError(f"{n} must be a Keyframe, got {shown(v)}")
        return v

    return check_list(name, value, one, what="a list of Keyframe")


@checked(path=check_path, keyframes=check_keyframes, overwrite=check_flag)
def save_keyframes(
    path: str | Path, keyframes: Sequence[Keyframe], *, overwrite: bool = True
) -> Path:
    """Write keyframes as ``.npz``: ``frames (K,)``, ``poses (K, 24, 3)``, ``joint_mask
    (K, 24)``, ``trans (K, 3)``, ``trans_mask (K,)`` (what ``mrlib sample --keyframes``
    reads); atomically, never through a symbolic link (``mrlib.io.outputs``)."""
    from mrlib.io.outputs import atomic_write

    K = len(keyframes)
    poses, jm = np.zeros((K, NUM_JOINTS, 3)), np.zeros((K, NUM_JOINTS), bool)
    trans, tm = np.zeros((K, 3)), np.zeros(K, bool)
    for k, kf in enumerate(keyframes):
        if kf.poses is not None:
            poses[k], jm[k, list(kf.joints)] = kf.poses, True
        if kf.trans is not None:
            trans[k], tm[k] = kf.trans, True
    arrays = {"frames": np.array([kf.frame for kf in keyframes], dtype=np.int64),
              "poses": poses, "joint_mask": jm, "trans": trans, "trans_mask": tm}  # fmt: skip
    # a file object: np.savez would append ".npz" to a path with another suffix
    return atomic_write(Path(path), lambda fh: np.savez(fh, **arrays), overwrite=overwrite)


MAX_KEYFRAME_FILE_BYTES = 64 * 2**20
_KEYFRAME_KEYS = ("frames", "poses", "joint_mask", "trans", "trans_mask")


def _keyframe_arrays(path: Path) -> dict[str, np.ndarray]:
    """The five arrays of a keyframe file, each header checked (shape, size) before its
    data is read; no pickles."""
    try:
        st = path.stat()
    except OSError as e:
        raise MotionFileError(path, f"cannot read: {e.strerror or e}") from None
    if not path.is_file():
        raise MotionFileError(path, "not a regular file")
    if st.st_size > MAX_KEYFRAME_FILE_BYTES:
        raise MotionFileError(
            path,
            f"{st.st_size / 2**20:.0f} MB is more than a keyframe file of {MAX_KEYFRAMES} "
            "keyframes needs; not a keyframe file",
        )
    if not zipfile.is_zipfile(path):
        raise MotionFileError(path, "not a keyframe file (an .npz written by save_keyframes)")
    out = {}
    with zipfile.ZipFile(path) as z:
        names = set(z.namelist())
        for key in _KEYFRAME_KEYS:
            member = f"{key}.npy"
            if member not in names:
                raise MotionFileError(
                    path, f"not a keyframe file: no '{key}' ({', '.join(_KEYFRAME_KEYS)})"
                )
            with z.open(member) as fh:
                shape, fortran, dtype = read_npy_header(fh)
                if dtype.hasobject or dtype.kind not in "biuf":
                    raise MotionFileError(path, f"'{key}' holds {dtype}, not numbers")
                if len(shape) == 0 or shape[0] > MAX_KEYFRAMES:
                    raise MotionFileError(
                        path,
                        f"'{key}' has shape {shape}: expected one row per keyframe, at most "
                        f"{MAX_KEYFRAMES} keyframes",
                    )
                size = int(np.prod(shape, dtype=object)) * dtype.itemsize
                if size > MAX_KEYFRAME_FILE_BYTES:
                    raise MotionFileError(path, f"'{key}' holds {size / 2**20:.0f} MB")
                count = int(np.prod(shape, dtype=object))
                data = np.frombuffer(fh.read(size), dtype=dtype, count=count)
            order = "F" if fortran else "C"
            out[key] = data.reshape(shape, order=order)
    return out


@checked(path=check_path)
def load_keyframes(path: str | Path) -> list[Keyframe]:
    """Keyframes written by :func:`save_keyframes` (no pickles are loaded).

    Raises:
        MotionFileError: naming ``path``: not such a file, arrays of the wrong shape or
            type, non-integer or out-of-range frames, non-finite or out-of-range values,
            more than ``MAX_KEYFRAMES`` keyframes.
    """
    path = Path(path)
    try:
        d = _keyframe_arrays(path)
    except MotionFileError:
        raise
    except (
        OSError,
        ValueError,
        EOFError,
        LookupError,
        ArithmeticError,
        RuntimeError,
        zipfile.BadZipFile,
        zlib.error,
    ) as e:
        # a damaged zip or array header: zipfile's, zlib's and numpy's errors
        raise MotionFileError(
            path, f"not a readable keyframe file ({type(e).__name__}: {e})"
        ) from None
    frames = d["frames"]
    K = len(frames)
    shapes = {
        "frames": (K,),
        "poses": (K, NUM_JOINTS, 3),
        "joint_mask": (K, NUM_JOINTS),
        "trans": (K, 3),
        "trans_mask": (K,),
    }
    for key, shape in shapes.items():
        if d[key].shape != shape:
            raise MotionFileError(
                path, f"'{key}' has shape {d[key].shape}; {K} keyframes need {shape}"
            )
    f64 = frames.astype(np.float64)
    if not np.isfinite(f64).all() or (f64 != np.round(f64)).any():
        raise MotionFileError(path, "'frames' must be whole numbers (output frame indices)")
    if K and not (0 <= f64.min() and f64.max() <= MAX_KEYFRAME_FRAME):
        raise MotionFileError(
            path,
            f"'frames' must lie in [0, {MAX_KEYFRAME_FRAME}], got {f64.min():g}..{f64.max():g}",
        )
    for key in ("joint_mask", "trans_mask"):
        if not np.isin(d[key], (0, 1)).all():
            raise MotionFileError(path, f"'{key}' must hold booleans (0 or 1)")
    out = []
    try:
        for k in range(K):
            joints = np.flatnonzero(d["joint_mask"][k])
            out.append(
                Keyframe(
                    int(f64[k]),
                    d["poses"][k].astype(np.float64) if len(joints) else None,
                    tuple(joints.tolist()) if len(joints) else None,
                    d["trans"][k].astype(np.float64) if d["trans_mask"][k] else None,
                )
            )
    except MotionValueError as e:
        raise MotionFileError(path, f"keyframe {k}: {e}") from None
    return out


# -- rotations (numpy, float64) ------------------------------------------------------------
