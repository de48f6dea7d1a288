"""Reading and writing motion: BVH (retargeted to SMPL), AMASS-style npz, EasyMocap.

Entry points:

* ``load_motion(path, fps=None, ...)`` -> ``Motion``, by extension: ``.bvh`` (parsed and
  retargeted onto SMPL, see ``mrlib.io.retarget``), ``.npz`` (AMASS-style or mrlib's own,
  see ``mrlib.io.npz``), or a folder of EasyMocap per-frame JSON files.
* ``save_motion(motion, path)``: ``.npz`` (AMASS-style keys plus ``up_axis="y"``,
  contacts and label) or ``.bvh`` on SMPL's skeleton (``mrlib.io.export.smpl_to_bvh``:
  cm, ``ZXY`` Euler angles, ROOT with 6 channels, joints with 3). Reading either back
  gives the same poses and translation.
* ``load_label(path)``: the ``"<content>_<style>"`` label of a Bandai Namco clip from its
  JSON metadata (``{"content": i, "style": j}``) and the dataset's ``cfg/*_label.txt``.

Everything returned is in mrlib's conventions (``mrlib.representation.skeleton``): metres, Y up.
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

from mrlib.errors import (
    MotionFileError,
    MotionValueError,
    MrlibError,
    UnsupportedFormatError,
    check_path,
)
from mrlib.io.bvh import BVH, BVHSkeleton, format_bvh, parse_bvh, read_bvh, write_bvh
from mrlib.io.export import smpl_to_bvh
from mrlib.io.jointmap import JointMap, detect_joint_map, load_joint_map, shipped_joint_maps
from mrlib.io.npz import load_easymocap, load_npz, save_npz
from mrlib.io.outputs import check_writable, write_text
from mrlib.io.paths import default_data_dir, read_text_bounded
from mrlib.io.retarget import calibrate_retarget, retarget_bvh
from mrlib.io.retarget_report import RetargetResult
from mrlib.representation.motion import Motion

__all__ = [
    "default_data_dir",
    "load_motion",
    "save_motion",
    "load_label",
    "load_bvh",
    "load_npz",
    "save_npz",
    "load_easymocap",
    "retarget_bvh",
    "calibrate_retarget",
    "smpl_to_bvh",
    "RetargetResult",
    "JointMap",
    "load_joint_map",
    "detect_joint_map",
    "shipped_joint_maps",
    "BVH",
    "BVHSkeleton",
    "read_bvh",
    "parse_bvh",
    "write_bvh",
    "SUPPORTED_EXTENSIONS",
]

SUPPORTED_EXTENSIONS = (".bvh", ".npz")


def _snap_fps(fps: float) -> float:
    """1/frame_time is rarely an exact integer (30.00003 for 0.0333333 s): snap rates
    within 1e-4 (relative) of an integer; 29.97 stays 29.97."""
    r = round(fps)
    return float(r) if r > 0 and abs(fps - r) < 1e-4 * fps else float(fps)


def load_label(path: str | Path, *, cfg_dir: str | Path | None = None) -> str:
    """The label of a Bandai Namco clip, e.g. ``"walk_happy"``.

    Args:
        path: the clip's ``.json`` metadata (``{"content": i, "style": j}``) or the
            ``.bvh`` next to it.
        cfg_dir: folder with ``content_label.txt`` and ``style_label.txt`` (line i is
            the name of index i, e.g. ``dataset-1_walk``); default: a ``cfg`` folder
            next to the file or one level up (the dataset's layout).

    Raises:
        MotionFileError: missing or malformed JSON, no label files, index out of range.
    """
    path = Path(path).with_suffix(".json")
    try:
        meta = json.loads(read_text_bounded(path, 2**20, "a label sidecar", MotionFileError))
    except json.JSONDecodeError as e:
        raise MotionFileError(path, f"cannot read label metadata: {e}") from None
    if not isinstance(meta, dict) or not all(
        isinstance(meta.get(k), int) for k in ("content", "style")
    ):
        raise MotionFileError(path, 'expected {"content": <int>, "style": <int>}')
    cands = (
        [Path(cfg_dir)]
        if cfg_dir is not None
        else [path.parent / "cfg", path.parent.parent / "cfg"]
    )
    cfg = next((c for c in cands if (c / "content_label.txt").is_file()), None)
    if cfg is None:
        raise MotionFileError(
            path, f"no content_label.txt/style_label.txt in {[str(c) for c in cands]}"
        )
    parts = []
    for key in ("content", "style"):
        file = cfg / f"{key}_label.txt"
        try:
            names = [
                ln.strip() for ln in file.read_text(encoding="utf-8").splitlines() if ln.strip()
            ]
        except OSError as e:
            raise MotionFileError(file, f"cannot read: {e}") from None
        i = meta[key]
        if not 0 <= i < len(names):
            raise MotionFileError(
                path, f"'{key}': {i} is out of range for {file} ({len(names)} names)"
            )
        parts.append(re.sub(r"^dataset-\d+_", "", names[i]))
    return "_".join(parts)


def load_bvh(
    path: str | Path,
    fps: float | None = None,
    *,
    joint_map=None,
    body=None,
    up_axis: str = "auto",
    unit: str | float = "auto",
    label: str | None = "auto",
    **retarget_options,
) -> Motion:
    """Read a BVH file and retarget it onto SMPL (``mrlib.io.retarget.retarget_bvh``).

    Args:
        path: the ``.bvh`` file.
        fps: resample to this rate (default: the file's).
        joint_map: see ``retarget_bvh`` (None: detected from the joint names).
        body, up_axis, unit, **retarget_options: passed to ``retarget_bvh``.
        label: ``"auto"`` reads a Bandai Namco JSON next to the file when there is one
            (``load_label``), None leaves it empty, a string sets it.

    Returns:
        A ``Motion`` named after the file stem, with ``meta``: ``source``, ``format``,
        the joint map, unit, up axis, scale, and the retargeting error (mean/max/per
        joint in cm).
    """
    path = Path(path)
    bvh = read_bvh(path)
    r = retarget_bvh(bvh, joint_map, body=body, up_axis=up_axis, unit=unit, **retarget_options)
    if label == "auto":
        label = None
        if path.with_suffix(".json").is_file():
            try:
                label = load_label(path)
            except MotionFileError:
                label = None  # a JSON that is not Bandai Namco metadata: no label
    meta = {"source": str(path), "format": "bvh", "bvh_frames": bvh.num_frames, **r.meta()}
    motion = Motion(
        poses=r.poses,
        trans=r.trans,
        fps=_snap_fps(bvh.fps),
        betas=r.betas,
        label=label,
        name=path.stem,
        meta=meta,
    )
    return motion if fps is None else motion.resample(fps)


def _not_a_file(path: Path) -> str:
    """Why ``path``, which is not a regular file (after following links), cannot be read."""
    if path.is_symlink():
        try:
            target = os.readlink(path)
        except OSError:
            target = "?"
        if not path.exists():
            return f"is a broken symbolic link (to {target})"
        return f"is a symbolic link to {target}, which is not a regular file"
    if not os.path.lexists(path):
        return "no such file"
    import stat

    mode = path.lstat().st_mode
    kind = (
        "a named pipe (FIFO)"
        if stat.S_ISFIFO(mode)
        else "a socket"
        if stat.S_ISSOCK(mode)
        else "a device"
        if stat.S_ISCHR(mode) or stat.S_ISBLK(mode)
        else "something other than a file"
    )
    return f"is {kind}, not a regular file; mrlib reads regular files only"


def load_motion(
    path: str | Path,
    fps: float | None = None,
    *,
    joint_map=None,
    body=None,
    up_axis: str | None = None,
    unit: str | float = "auto",
    person: int = 0,
    label: str | None = "auto",
) -> Motion:
    """Read a motion file into a ``Motion`` (metres, Y up), choosing the reader by type.

    Args:
        path: ``.bvh``, ``.npz``, or a folder of EasyMocap per-frame JSON files.
        fps: resample to this rate. Required for EasyMocap folders, which store no rate:
            there it *is* the capture rate (nothing is resampled).
        joint_map: BVH only: a shipped map name, JSON path or ``{smpl: bvh}`` dict.
        body: body model (default: mrlib's), used for the rest joints.
        up_axis: the source's up axis, ``x y z -x -y -z`` or ``"auto"``. Defaults: BVH
            ``"auto"`` (from the skeleton), npz the file's ``up_axis`` key or ``"z"``
            (AMASS), EasyMocap ``"auto"`` (from the body's orientation).
        unit: BVH only: metres per file unit or ``"auto"``.
        person: EasyMocap only: the person ``id`` to read.
        label: BVH only: ``"auto"`` reads a Bandai Namco JSON next to the file.

    Raises:
        UnsupportedFormatError: unknown extension.
        MotionFileError: missing or malformed file (``BVHFormatError``,
            ``JointMapError`` for BVH problems), with the path and the problem.
    """
    path = check_path("path", path)
    if path.is_dir():
        return load_easymocap(path, fps, person=person, up_axis=up_axis or "auto", body=body)
    ext = path.suffix.lower()
    if ext not in SUPPORTED_EXTENSIONS:
        raise UnsupportedFormatError(
            path, f"unsupported file type '{ext}'; mrlib reads .bvh, .npz and EasyMocap folders"
        )
    if not path.is_file():
        raise MotionFileError(path, _not_a_file(path))
    try:
        if ext == ".bvh":
            return load_bvh(
                path,
                fps,
                joint_map=joint_map,
                body=body,
                up_axis=up_axis or "auto",
                unit=unit,
                label=label,
            )
        return load_npz(path, fps, up_axis=up_axis, body=body)
    except MotionFileError:
        raise
    except MotionValueError as e:  # the values read make no motion (bounds, NaN, shapes)
        raise MotionFileError(path, str(e)) from e
    except MrlibError:
        raise
    except (ArithmeticError, LookupError, TypeError, ValueError, OSError, RuntimeError) as e:
        # the readers check what they expect; whatever else a damaged file trips over is
        # still reported as this file's problem, never as numpy's or zlib's
        raise MotionFileError(path, f"cannot read ({type(e).__name__}: {e})") from e
    except MemoryError as e:
        raise MotionFileError(path, "too large to read into memory") from e


def save_motion(
    motion: Motion,
    path: str | Path,
    *,
    body=None,
    bvh_unit: str = "cm",
    euler_order: str = "ZXY",
    overwrite: bool = True,
) -> Path:
    """Write ``motion`` to ``.npz`` (``save_npz``), ``.bvh`` (``smpl_to_bvh``: SMPL's
    skeleton for ``motion.betas``, ``bvh_unit`` cm or m, ``euler_order`` rotations) or
    ``.glb`` (``mrlib.io.gltf.save_glb``: the skinned body mesh with the animation).

    Every format is written atomically and never through a symbolic link
    (``mrlib.io.outputs``): a failed write leaves an earlier file as it was.
    ``overwrite=False`` refuses an existing file (before any work).

    Raises:
        UnsupportedFormatError: any other extension.
        OutputExistsError: ``path`` exists and ``overwrite`` is False.
        OutputError: ``path`` is a symbolic link or not a regular file.
        MotionFileError: the write failed (a missing folder, a full disk).
    """
    path = check_path("path", path)
    if not isinstance(motion, Motion):
        raise MotionValueError(f"save_motion wants a Motion, got {type(motion).__name__}")
    ext = path.suffix.lower()
    if ext not in (".npz", ".bvh", ".glb"):
        raise UnsupportedFormatError(
            path, f"unsupported file type '{ext}'; mrlib writes .bvh, .glb and .npz"
        )
    check_writable(path, overwrite=overwrite)
    try:
        if ext == ".npz":
            return save_npz(motion, path, overwrite=overwrite)
        if ext == ".glb":
            from mrlib.io.gltf import save_glb

            return save_glb(motion, path, body=body, overwrite=overwrite)
        bvh = smpl_to_bvh(motion, body=body, unit=bvh_unit, order=euler_order)
        return write_text(path, format_bvh(bvh), overwrite=overwrite)
    except OSError as e:
        kept = "; the previous file is kept" if os.path.lexists(path) else ""
        raise MotionFileError(path, f"cannot write: {e.strerror or e}{kept}") from e
