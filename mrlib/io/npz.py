"""SMPL parameter files: AMASS-style ``.npz`` (read and write) and EasyMocap output folders.

AMASS-style npz keys (https://amass.is.tue.mpg.de/):

* ``poses`` ``(T, 72)`` SMPL, ``(T, 156)`` SMPL-H or ``(T, 165)`` SMPL-X axis-angle. The
  first 22 joints (pelvis ... right wrist) are the same in all three. SMPL's joints 22 and
  23 (``left_hand``, ``right_hand``) have no counterpart in SMPL-H/SMPL-X, which replace
  them by finger joints: they are set to **zero rotation** and the fingers are dropped
  (``Motion.meta["dropped_hand_pose"]`` says so). Also read: ``poses (T, J, 3)``, and
  the ``smplx`` package's ``global_orient`` / ``body_pose`` / ``transl``
  (``mrlib.io.npz_arrays``); degrees, rotation matrices and centimetres are refused.
* ``trans`` ``(T, 3)`` metres; ``betas`` (any length; the first 10 are kept, since the
  shape spaces of different body models do not correspond anyway);
  ``mocap_framerate`` or ``mocap_frame_rate`` (frames per second).
* ``up_axis``: not an AMASS key; mrlib's own files store ``up_axis="y"``. Files without
  it come Z up (AMASS) or Y up (BEAT2, most SMPL-X tools), so their axis is **told from
  the body** (:func:`detect_npz_up_axis`): the world direction of the pelvis's own up
  axis and of the pelvis-to-head vector, averaged over the clip, must agree on one
  signed axis by a clear margin, else the file is refused in one line naming
  ``up_axis=`` / ``--up-axis``. A clip that lies or crawls on every frame points its
  body along the floor, so it is read standing: give its ``up_axis``. The rotation to mrlib's Y-up frame is applied to the
  global orientation and to the translation (about the body's rest pelvis:
  ``mrlib.io.axes.change_up_axis``).
* The floor: files without ``up_axis`` place the body as *their* body model does
  (SMPL-X's pelvis sits lower than SMPL's), so their feet can float or sink on mrlib's
  body. They are moved vertically so that the feet stand on ``y = 0``: the median
  height of the lowest foot vertex over the frames with a foot in contact
  (``meta["floor_shift_m"]`` records the move; mrlib's own files are left as written).

mrlib's npz (``save_npz``) uses the same keys with ``poses (T, 72)``, ``up_axis="y"`` and
optionally ``contacts (T, 6)``, ``label``, ``name`` and ``meta_json``.

EasyMocap writes one JSON file per frame, each a list of people
``{"id", "Rh" (1, 3), "Th" (1, 3), "poses" (1, 72 or 69), "shapes" (1, 10)}``; its body
is posed with a zero root rotation and then moved rigidly:
``v_world = R(Rh) v + Th``. In SMPL's convention that is a global orientation
``R(Rh) R(poses[:3])`` and a translation ``R(Rh) J_pelvis + Th - J_pelvis``.
"""

from __future__ import annotations

import json
import re
import warnings
import zipfile
import zlib
from pathlib import Path
from typing import Any

import numpy as np
import torch

from mrlib.errors import MotionFileError, MotionValueError
from mrlib.io.axes import change_up_axis, up_axis_rotation
from mrlib.io.bodyfit import default_body, rest_pelvis
from mrlib.io.npz_arrays import (
    FPS_KEYS,
    POSE_KEYS,
    POSE_WIDTHS,
    body_poses,
    frame_rate,
    root_translation,
)
from mrlib.io.npz_arrays import array as _array
from mrlib.io.npz_arrays import text_value as _text_value
from mrlib.io.outputs import atomic_write
from mrlib.io.paths import read_text_bounded
from mrlib.io.placement import FLOOR_TOLERANCE_M, detect_npz_up_axis, floor_height
from mrlib.representation.motion import NUM_BETAS, Motion, check_rotations
from mrlib.representation.rotations import axis_angle_to_matrix, matrix_to_axis_angle
from mrlib.representation.skeleton import NUM_CONTACTS, NUM_JOINTS

__all__ = [
    "load_npz",
    "save_npz",
    "load_easymocap",
    "read_npy_header",
    "POSE_WIDTHS",
    "BodyModelWarning",
]


class BodyModelWarning(UserWarning):
    """A motion file was made for another SMPL body than mrlib's neutral one (its
    ``gender`` key): its shape parameters are read on the neutral body."""


_USED_KEYS = frozenset(
    (
        *POSE_KEYS,
        "betas",
        *FPS_KEYS,
        "up_axis",
        "contacts",
        "label",
        "name",
        "meta_json",
        "gender",
    )  # fmt: skip
)
# The most one array of an npz may hold, uncompressed: 4 hours of SMPL-X poses at 30 fps
# in float64. Checked before the array is read, from the zip's record and the array's own
# header, so a small file that inflates to gigabytes (a zip bomb) is refused, not read.
MAX_ARRAY_BYTES = 256 * 2**20


def read_npy_header(fh) -> tuple[tuple[int, ...], bool, np.dtype]:
    """Shape, Fortran order and dtype from the header of an ``.npy`` stream (an npz member), without
    reading its data: what a size or type check needs before the array is loaded."""
    version = np.lib.format.read_magic(fh)
    read = (
        np.lib.format.read_array_header_1_0
        if version == (1, 0)
        else np.lib.format.read_array_header_2_0
    )
    return read(fh)


MAX_FRAME_JSON_BYTES = 16 * 2**20  # one EasyMocap frame (a few KB per person)


def _read_used_keys(path: Path, z) -> dict[str, Any]:
    """The arrays of ``z`` (an open ``NpzFile``) that mrlib reads, each checked against
    ``MAX_ARRAY_BYTES`` first; other keys are listed (value None), never read."""
    data: dict[str, Any] = {}
    names = set(z.zip.namelist())
    for key in z.files:
        if key not in _USED_KEYS:
            data[key] = None
            continue
        member = f"{key}.npy" if f"{key}.npy" in names else key
        size = z.zip.getinfo(member).file_size
        with z.zip.open(member) as fh:
            shape, _, dtype = read_npy_header(fh)
        size = max(size, int(np.prod(shape, dtype=object)) * dtype.itemsize)
        if size > MAX_ARRAY_BYTES:
            raise MotionFileError(
                path,
                f"'{key}' holds {size / 2**20:.0f} MB uncompressed, more than the "
                f"{MAX_ARRAY_BYTES // 2**20} MB mrlib reads per array; split the clip or "
                "store fewer frames",
            )
        data[key] = z[key]
    return data


def _to_y_up(poses, trans, betas, up_axis, body) -> tuple[np.ndarray, np.ndarray]:
    """Rotate SMPL parameters from an ``up_axis``-up world to mrlib's Y-up world."""
    if up_axis == "y":
        return poses, trans
    body = default_body() if body is None else body
    G = axis_angle_to_matrix(torch.from_numpy(poses[:, 0])).numpy()
    G, trans = change_up_axis(G, trans, rest_pelvis(body, betas), up_axis)
    poses = poses.copy()
    poses[:, 0] = matrix_to_axis_angle(torch.from_numpy(G)).numpy()
    return poses, trans


def _check_axis(path, axis: str) -> str:
    try:
        up_axis_rotation(axis)
    except ValueError as e:
        raise MotionFileError(path, str(e)) from None
    return str(axis).lower()


def load_npz(
    path: str | Path,
    fps: float | None = None,
    *,
    up_axis: str | None = None,
    body=None,
) -> Motion:
    """Read an AMASS-style or mrlib npz (see the module docstring for the keys).

    Args:
        path: the ``.npz`` file.
        fps: resample to this frame rate (the file's own rate is used when None); if the
            file has no frame-rate key, ``fps`` is required and taken as its rate.
        up_axis: the file's up axis (``x y z -x -y -z``), overriding its ``up_axis`` key;
            ``"auto"`` or None on a file without the key: told from the body
            (:func:`detect_npz_up_axis`; ``meta["up_axis_reason"]`` says how).
        body: body model for the rest pelvis used by the up-axis conversion (default:
            mrlib's); only needed for files that are not Y up.

    Returns:
        A ``Motion`` named after the file stem; ``meta`` has ``source``, ``format``,
        ``up_axis`` and, for SMPL-H/SMPL-X, ``dropped_hand_pose``.

    Raises:
        MotionFileError: unreadable file, missing keys, wrong shapes, NaN values.
    """
    path = Path(path)
    try:
        with open(path, "rb") as f:
            head = f.read(6)
        if not head:
            raise MotionFileError(path, "is empty")
        if not head.startswith((b"PK", b"\x93NUMPY")):
            raise MotionFileError(path, "is not an .npz archive (neither a zip nor a numpy file)")
        z = np.load(path, allow_pickle=False)
        if not isinstance(z, np.lib.npyio.NpzFile):
            raise MotionFileError(path, "not an .npz archive (a single .npy array?)")
        with z:
            data = _read_used_keys(path, z)
    except MotionFileError:
        raise
    except IsADirectoryError:
        raise MotionFileError(path, "is a folder, not an .npz file") from None
    except FileNotFoundError:
        raise MotionFileError(path, "no such file") from None
    except (
        OSError,
        ValueError,
        EOFError,
        zipfile.BadZipFile,
        zlib.error,
        KeyError,
        RuntimeError,
    ) as e:
        raise MotionFileError(path, f"cannot read npz ({type(e).__name__}: {e})") from None
    poses, kind = body_poses(path, data)
    T = len(poses)
    meta: dict[str, Any] = {"source": str(path), "format": f"npz ({kind} poses)"}
    if kind != "SMPL":  # SMPL's hand joints 22, 23: zero where the model has fingers
        meta["dropped_hand_pose"] = True
    trans = root_translation(path, data, T)
    betas = np.zeros(NUM_BETAS)
    if "betas" in data:
        b = _array(path, data, "betas").reshape(-1)
        betas = b[:NUM_BETAS]
    found = frame_rate(path, data)
    file_fps = None if found is None else found[0]
    if found is not None:
        rate = found[1]
    elif fps is None:
        raise MotionFileError(
            path,
            "missing key 'mocap_framerate' (or 'mocap_frame_rate'): give the rate with --fps on "
            "the command line, fps= in Python",
        )
    else:
        rate = float(fps)
    gender = (_text_value(data, "gender", path) or "neutral").strip().lower()
    if gender not in ("neutral", ""):
        meta["source_gender"] = gender
        warnings.warn(
            f"{path}: made for the {gender} SMPL body; mrlib reads its shape (betas) on "
            "its neutral body, so its proportions and foot height may differ",
            BodyModelWarning,
            stacklevel=3,
        )
    declared = _text_value(data, "up_axis")
    _check_rotations(path, "'poses'", poses)  # before the turn to Y up hides the root's
    if up_axis is not None and str(up_axis).lower() != "auto":
        axis, why = _check_axis(path, up_axis), "as given"
    elif declared is not None and up_axis is None:
        axis, why = _check_axis(path, declared), "the file's up_axis key"
    else:
        axis, why = detect_npz_up_axis(poses, trans, betas, body, source=path)
    meta["up_axis"] = axis
    meta["up_axis_reason"] = why
    poses, trans = _to_y_up(poses, trans, betas, axis, body)
    if declared is None:  # placed by another body model: stand the feet on y = 0
        height = floor_height(poses, trans, betas, rate, body)
        if height is not None and abs(height) > FLOOR_TOLERANCE_M:
            trans = trans.copy()
            trans[:, 1] -= height
            meta["floor_shift_m"] = round(-height, 4)
    contacts = None
    if "contacts" in data:
        contacts = _array(path, data, "contacts", ndim=2)
        if contacts.shape != (T, NUM_CONTACTS):
            raise MotionFileError(
                path, f"'contacts' must have shape ({T}, {NUM_CONTACTS}), got {contacts.shape}"
            )
    if "meta_json" in data:
        try:
            extra = json.loads(_text_value(data, "meta_json", path) or "{}")
        except (json.JSONDecodeError, RecursionError):
            raise MotionFileError(path, "'meta_json' is not valid JSON") from None
        if not isinstance(extra, dict):
            raise MotionFileError(
                path, f"'meta_json' must be a JSON object, got {type(extra).__name__}"
            )
        meta = {**extra, **meta}
    try:
        motion = Motion(
            poses=poses,
            trans=trans,
            fps=rate,
            betas=betas,
            contacts=contacts,
            label=_text_value(data, "label", path),
            name=_text_value(data, "name", path) or path.stem,
            meta=meta,
        )
    except MotionValueError as e:
        raise MotionFileError(path, str(e)) from None
    return motion if fps is None or file_fps is None else motion.resample(fps)


def save_npz(motion: Motion, path: str | Path, *, overwrite: bool = True) -> Path:
    """Write ``motion`` as an AMASS-style npz with ``up_axis="y"`` (mrlib's frame).

    The file is written atomically and never through a symbolic link
    (``mrlib.io.outputs.atomic_write``); ``overwrite=False`` refuses an existing file.

    Keys: ``poses (T, 72)``, ``trans (T, 3)``, ``betas``, ``mocap_framerate``,
    ``up_axis``, ``gender="neutral"``, and when present ``contacts (T, 6)``, ``label``,
    ``name``, ``meta_json`` (``Motion.meta`` as JSON, non-JSON values as strings).
    """
    path = Path(path)
    out: dict[str, Any] = {
        "poses": motion.poses.reshape(motion.num_frames, NUM_JOINTS * 3).astype(np.float32),
        "trans": motion.trans.astype(np.float32),
        "betas": np.asarray(motion.betas, dtype=np.float32),
        "mocap_framerate": np.float64(motion.fps),
        "up_axis": np.str_("y"),
        "gender": np.str_("neutral"),
    }
    if motion.contacts is not None:
        out["contacts"] = motion.contacts.astype(np.float32)
    if motion.label is not None:
        out["label"] = np.str_(motion.label)
    if motion.name is not None:
        out["name"] = np.str_(motion.name)
    if motion.meta:
        out["meta_json"] = np.str_(json.dumps(motion.meta, default=str))
    # a file object: np.savez would append ".npz" to other suffixes
    return atomic_write(path, lambda f: np.savez(f, **out), overwrite=overwrite)


def _natural_key(p: Path):
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", p.name)]


def load_easymocap(
    folder: str | Path,
    fps: float,
    *,
    person: int = 0,
    up_axis: str = "auto",
    body=None,
) -> Motion:
    """Read an EasyMocap SMPL output folder (one JSON file per frame).

    Args:
        folder: the folder of per-frame ``*.json`` files (sorted by the numbers in
            their names).
        fps: the capture frame rate (EasyMocap stores none); required.
        person: the ``id`` of the person to read (every frame must contain them).
        up_axis: the world's up axis. EasyMocap's world is the camera frame for
            monocular capture (**Y down**, ``"-y"``) and the calibration board's frame
            for multi-view capture (often ``"z"``). The default ``"auto"`` picks the
            signed axis closest to the body's mean up direction (the pelvis's rest Y
            axis), which is right for anyone mostly upright.
        body: body model for the rest pelvis (default: mrlib's).

    Returns:
        A ``Motion`` named after the folder; ``meta["up_axis"]`` records the axis used.

    Raises:
        MotionFileError: no JSON files, unreadable JSON, the person missing from a frame,
            missing keys (named) or wrong shapes.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise MotionFileError(folder, "EasyMocap input must be a folder of per-frame JSON files")
    files = sorted(folder.glob("*.json"), key=_natural_key)
    if not files:
        raise MotionFileError(
            folder,
            "a folder is read as EasyMocap output (one JSON file per frame), but it has no "
            "*.json files; give a motion file (.bvh, .npz) instead",
        )
    if fps is None or not (np.isfinite(fps) and fps > 0):
        raise MotionFileError(folder, "EasyMocap files store no frame rate: pass fps=")
    Rh, Th, poses, shapes = [], [], [], []
    for f in files:
        try:
            data = json.loads(
                read_text_bounded(f, MAX_FRAME_JSON_BYTES, "one frame's JSON", MotionFileError)
            )
        except json.JSONDecodeError as e:
            raise MotionFileError(f, f"cannot read JSON: {e}") from None
        people = data.get("annots", data) if isinstance(data, dict) else data
        if isinstance(people, dict):
            people = [people]
        who = [p for p in people if isinstance(p, dict) and int(p.get("id", 0)) == person]
        if not who:
            raise MotionFileError(f, f"no person with id {person} in this frame")
        p = who[0]
        Rh.append(_vector(f, p, "Rh", (3,)))
        Th.append(_vector(f, p, "Th", (3,)))
        pose = _vector(f, p, "poses", None)
        if pose.size == 69:
            pose = np.concatenate([np.zeros(3), pose])
        elif pose.size != 72:
            if pose.size < 66:
                raise MotionFileError(f, f"'poses' has {pose.size} values; expected 72 or 69")
            pose = np.concatenate([pose[:66], np.zeros(6)])  # SMPL-H layout: hands dropped
        poses.append(pose.reshape(NUM_JOINTS, 3))
        shapes.append(
            _vector(f, p, "shapes", None)[:NUM_BETAS] if "shapes" in p else np.zeros(NUM_BETAS)
        )
    Rh, Th, poses = np.stack(Rh), np.stack(Th), np.stack(poses)
    _check_rotations(folder, "'Rh'", Rh)
    _check_rotations(folder, "'poses'", poses)
    betas = np.mean(np.stack([np.pad(s, (0, NUM_BETAS - len(s))) for s in shapes]), axis=0)
    body = default_body() if body is None else body
    J0 = rest_pelvis(body, betas)
    R_h = axis_angle_to_matrix(torch.from_numpy(Rh)).numpy()
    G = R_h @ axis_angle_to_matrix(torch.from_numpy(poses[:, 0])).numpy()  # (T, 3, 3)
    trans = R_h @ J0 + Th - J0  # SMPL's transl for EasyMocap's rigid (Rh, Th)
    poses[:, 0] = matrix_to_axis_angle(torch.from_numpy(G)).numpy()  # in EasyMocap's world
    if up_axis == "auto":
        axis, why = detect_npz_up_axis(poses, trans, betas, body, source=folder)
    else:
        axis, why = _check_axis(folder, up_axis), "as given"
    G, trans = change_up_axis(G, trans, J0, axis)
    poses[:, 0] = matrix_to_axis_angle(torch.from_numpy(G)).numpy()
    meta = {"source": str(folder), "format": "easymocap", "up_axis": axis,
            "up_axis_reason": why, "person": person}  # fmt: skip
    # EasyMocap's world is a camera's frame, whose floor is anywhere: feet on y = 0
    height = floor_height(poses, trans, betas, float(fps), body)
    if height is not None and abs(height) > FLOOR_TOLERANCE_M:
        trans = trans.copy()
        trans[:, 1] -= height
        meta["floor_shift_m"] = round(-height, 4)
    try:
        return Motion(
            poses=poses, trans=trans, fps=float(fps), betas=betas, name=folder.name, meta=meta
        )
    except MotionValueError as e:
        raise MotionFileError(folder, str(e)) from None


def _check_rotations(path: Path, what: str, poses: np.ndarray) -> None:
    """Axis-angle of a file refused, naming the file, beyond ``MAX_ROTATION_RAD``."""
    try:
        check_rotations(what, poses)
    except MotionValueError as e:
        raise MotionFileError(path, str(e)) from None


def _vector(path: Path, person: dict, key: str, size: tuple[int, ...] | None) -> np.ndarray:
    if key not in person:
        raise MotionFileError(path, f"missing key '{key}' for person {person.get('id', 0)}")
    try:
        v = np.asarray(person[key], dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise MotionFileError(path, f"'{key}' is not numeric") from None
    if size is not None and v.shape != size:
        raise MotionFileError(
            path, f"'{key}' must have {size[0]} values (shape (1, {size[0]})), got {v.size}"
        )
    if not np.isfinite(v).all():
        raise MotionFileError(path, f"'{key}' has NaN or inf values")
    return v
