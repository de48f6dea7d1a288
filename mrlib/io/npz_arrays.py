"""The arrays of an SMPL-parameter ``.npz`` as ``mrlib.io.npz.load_npz`` reads them: each
checked (real numbers, finite, its shape), with the layouts other tools write.

Poses come as AMASS does, ``poses (T, 72 | 156 | 165)``, or ``(T, J, 3)`` with the same
``3 J``, or as the ``smplx`` package names its parameters (and many pose estimators write
them): ``global_orient (T, 3)`` and ``body_pose (T, 69)`` (SMPL) or ``(T, 63)`` (SMPL-H,
SMPL-X: the 21 body joints), either also as ``(T, J, 3)``, with ``transl`` for ``trans``.
Axis-angle in degrees, rotation matrices and translations in centimetres are refused,
saying so.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from mrlib.errors import MotionFileError
from mrlib.representation.motion import MAX_TRANSLATION_M
from mrlib.representation.skeleton import NUM_JOINTS

__all__ = ["POSE_WIDTHS", "FPS_KEYS", "POSE_KEYS", "body_poses", "root_translation", "frame_rate"]

# Pose vector widths and the body model they come from.
POSE_WIDTHS = {72: "SMPL", 156: "SMPL-H", 165: "SMPL-X"}
FPS_KEYS = ("mocap_framerate", "mocap_frame_rate", "fps")
POSE_KEYS = ("poses", "global_orient", "body_pose", "trans", "transl")
# body_pose widths of the smplx package's parameters: SMPL's 23 joints, SMPL-H / SMPL-X's 21
_BODY_POSE_WIDTHS = {69: "SMPL", 63: "SMPL-X / SMPL-H body"}
# The median angle of a body's joint rotations is a few tenths of a radian; above pi
# (no axis-angle needs more) the numbers are degrees.
_DEGREES_MEDIAN_RAD = np.pi


def finite(path, key: str, arr: np.ndarray) -> np.ndarray:
    if not np.isfinite(arr).all():
        bad = np.argwhere(~np.isfinite(arr.reshape(len(arr), -1) if arr.ndim else arr[None]))[0, 0]
        raise MotionFileError(path, f"'{key}' has NaN or inf values (first at index {bad})")
    return arr


def array(path, data, key: str, ndim: int | None = None) -> np.ndarray:
    if key not in data:
        raise MotionFileError(path, f"missing key '{key}' (keys: {sorted(data.keys())})")
    raw = np.asarray(data[key])
    if raw.dtype.kind not in "biuf":
        raise MotionFileError(path, f"'{key}' must hold real numbers, got dtype {raw.dtype}")
    arr = raw.astype(np.float64)
    if ndim is not None and arr.ndim != ndim:
        raise MotionFileError(path, f"'{key}' must have {ndim} dimensions, got shape {arr.shape}")
    return finite(path, key, arr)


def text_value(data, key: str, path=None) -> str | None:
    if key not in data:
        return None
    v = np.asarray(data[key])
    if v.size == 0:
        return None
    if v.dtype.kind not in "SUiuf":
        raise MotionFileError(path, f"'{key}' must be text, got an array of {v.dtype}")
    item = v.item() if v.ndim == 0 else v.reshape(-1)[0]
    if isinstance(item, bytes):
        return item.decode("utf-8", errors="replace")
    return str(item)


def _rows(path, data, key: str, widths) -> np.ndarray:
    """``key`` as ``(T, width)``: given so, or as ``(T, J, 3)`` with ``3 J`` a width."""
    a = array(path, data, key)
    if a.ndim >= 3 and a.shape[-2:] == (3, 3):
        raise MotionFileError(
            path,
            f"'{key}' has shape {a.shape}: rotation matrices; mrlib reads axis-angle "
            "(convert them, e.g. with scipy's Rotation.from_matrix(...).as_rotvec())",
        )
    if a.ndim == 3 and a.shape[2] == 3 and 3 * a.shape[1] in widths:
        a = a.reshape(len(a), -1)
    if a.ndim != 2 or a.shape[1] not in widths:
        expected = " or ".join(f"(T, {w})" for w in widths)
        raise MotionFileError(
            path, f"'{key}' has shape {a.shape}; expected {expected} axis-angle (or (T, J, 3))"
        )
    return a


def body_poses(path: Path, data) -> tuple[np.ndarray, str]:
    """``(T, 24, 3)`` SMPL axis-angle (radians) and what the file held (``"SMPL"``,
    ``"SMPL-H"``, ...): SMPL's hand joints 22, 23 zero where the file's model has
    fingers there instead (the caller records that)."""
    if "poses" in data or not ("global_orient" in data and "body_pose" in data):
        if "poses" not in data and ("global_orient" in data or "body_pose" in data):
            raise MotionFileError(
                path, "has one of 'global_orient' / 'body_pose' but not the other, and no 'poses'"
            )
        poses = _rows(path, data, "poses", POSE_WIDTHS)
        kind = POSE_WIDTHS[poses.shape[1]]
    else:
        root = _rows(path, data, "global_orient", (3,))
        body = _rows(path, data, "body_pose", _BODY_POSE_WIDTHS)
        if len(root) != len(body):
            raise MotionFileError(
                path, f"'global_orient' has {len(root)} frames, 'body_pose' {len(body)}"
            )
        poses = np.concatenate([root, body], axis=1)
        kind = _BODY_POSE_WIDTHS[body.shape[1]]
    T = len(poses)
    if T == 0:
        raise MotionFileError(path, "'poses' has no frames")
    if poses.shape[1] != 72:  # 22 joints shared with SMPL; its hand joints set to zero
        poses = np.concatenate([poses[:, :66], np.zeros((T, 6))], axis=1)
    poses = poses.reshape(T, NUM_JOINTS, 3)
    _check_radians(path, poses)
    return poses, kind


def _check_radians(path, poses: np.ndarray) -> None:
    angles = np.linalg.norm(poses[:, 1:22], axis=-1)
    moved = angles[angles > 1e-6]
    if moved.size and np.median(moved) > _DEGREES_MEDIAN_RAD:
        raise MotionFileError(
            path,
            f"the joint rotations have a median angle of {np.median(moved):.3g} rad, more than "
            "pi: degrees, not radians? (axis-angle poses are radians: np.radians(poses))",
        )


def root_translation(path: Path, data, T: int) -> np.ndarray:
    """``(T, 3)`` metres from ``trans`` (or the ``smplx`` package's ``transl``)."""
    key = "trans" if "trans" in data or "transl" not in data else "transl"
    if key not in data:
        raise MotionFileError(
            path, f"missing key 'trans' (the root translation; keys: {sorted(data.keys())})"
        )
    trans = array(path, data, key)
    if trans.ndim == 3 and trans.shape[1] == 1:
        trans = trans[:, 0]
    if trans.shape != (T, 3):
        raise MotionFileError(
            path, f"'{key}' must have shape ({T}, 3) like the poses, got {trans.shape}"
        )
    far = np.abs(trans).max()
    if far > MAX_TRANSLATION_M:
        raise MotionFileError(
            path,
            f"'{key}' reaches {far:.3g} m from the origin (more than {MAX_TRANSLATION_M:g} m): "
            "wrong units? SMPL translations are metres (centimetres or millimetres here?)",
        )
    return trans


def frame_rate(path: Path, data) -> tuple[str, float] | None:
    """``(key, frames per second)`` of the file's first rate key, None without one; a
    second rate key that disagrees is warned about."""
    found = [k for k in FPS_KEYS if k in data]
    if not found:
        return None
    rates = {}
    for k in found:
        values = array(path, data, k).reshape(-1)
        if values.size == 0:
            raise MotionFileError(path, f"'{k}' is empty")
        rates[k] = float(values[0])
        if not rates[k] > 0:
            raise MotionFileError(path, f"'{k}' must be positive, got {rates[k]}")
    key = found[0]
    others = {k: r for k, r in rates.items() if abs(r - rates[key]) > 1e-6 * rates[key]}
    if others:
        warnings.warn(
            f"{path}: '{key}' says {rates[key]:g} fps, "
            + ", ".join(f"'{k}' {r:g}" for k, r in others.items())
            + f"; read at {rates[key]:g} fps (the first of {', '.join(FPS_KEYS)})",
            UserWarning,
            stacklevel=4,
        )
    return key, rates[key]
