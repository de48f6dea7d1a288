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
import warnings
from pathlib import Path

import numpy as np

from mrlib.errors import (
    ArgumentError,
    BVHFormatError,
    MotionFileError,
    MotionValueError,
    MrlibError,
    UnsupportedFormatError,
    check_args,
    check_choice,
    check_flag,
    check_number,
    check_path,
    check_text,
    shown,
)
from mrlib.io.bvh.hierarchy import BVH, BVHSkeleton, frame_time_problem
from mrlib.io.bvh.kinematics import ReferenceFrameWarning, without_reference_frame
from mrlib.io.bvh.reader import parse_bvh, read_bvh
from mrlib.io.bvh.writer import format_bvh, write_bvh
from mrlib.io.export import smpl_to_bvh
from mrlib.io.jointmap import (
    JointMap,
    check_joint_map,
    detect_joint_map,
    load_joint_map,
    shipped_joint_maps,
)
from mrlib.io.npz import load_easymocap, load_npz, save_npz
from mrlib.io.outputs import OutputError, check_writable, write_text
from mrlib.io.paths import default_data_dir, read_text_bounded
from mrlib.io.retarget import calibrate_retarget, retarget_bvh
from mrlib.io.retarget_report import RetargetResult
from mrlib.io.transfer import RetargetOptions
from mrlib.representation.body import check_body
from mrlib.representation.motion import MAX_FPS, MAX_ROTATION_RAD, Motion

__all__ = [
    "default_data_dir",
    "load_motion",
    "save_motion",
    "joint_maps_for",
    "load_label",
    "load_bvh",
    "load_npz",
    "save_npz",
    "load_easymocap",
    "retarget_bvh",
    "calibrate_retarget",
    "RetargetOptions",
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
        body, up_axis, unit, **retarget_options: passed to ``retarget_bvh``
            (``options=RetargetOptions(...)``, ``warn``, or what ``calibrate_retarget``
            returns).
        label: ``"auto"`` reads a Bandai Namco JSON next to the file when there is one
            (``load_label``), None leaves it empty, a string sets it.

    Returns:
        A ``Motion`` named after the file stem, with ``meta``: ``source``, ``format``,
        the joint map, unit, up axis, scale, and the retargeting error (mean/max/per
        joint in cm).
    """
    path = Path(path)
    bvh, dropped = without_reference_frame(read_bvh(path))
    if dropped:
        warnings.warn(
            f"{path}: frame 1 is a reference pose (every rotation 0, then a jump to frame "
            "2), not motion: left out",
            ReferenceFrameWarning,
            stacklevel=2,
        )
    _check_angles(bvh, path)
    r = retarget_bvh(bvh, joint_map, body=body, up_axis=up_axis, unit=unit, **retarget_options)
    if label == "auto":
        label = None
        if path.with_suffix(".json").is_file():
            try:
                label = load_label(path)
            except MotionFileError:
                label = None  # a JSON that is not Bandai Namco metadata: no label
    meta = {"source": str(path), "format": "bvh", "bvh_frames": bvh.num_frames, **r.meta()}
    if dropped:
        meta["bvh_reference_frame_left_out"] = True
    trans = _root_on_the_floor(bvh, r, body, meta)
    motion = Motion(
        poses=r.poses,
        trans=trans,
        fps=_snap_fps(bvh.fps),
        betas=r.betas,
        label=label,
        name=path.stem,
        meta=meta,
    )
    return motion if fps is None else motion.resample(fps)


def _root_on_the_floor(bvh: BVH, r, body, meta: dict) -> np.ndarray:
    """The retargeted root translation; for a file without position channels, whose
    body's height is only its OFFSETs (often 0: the body would stand below the floor),
    moved vertically so the feet stand on ``y = 0`` as npz files without an up axis are
    (``meta["floor_shift_m"]``)."""
    if any(c.endswith("position") for chs in bvh.skeleton.channels for c in chs):
        return r.trans
    from mrlib.io.placement import FLOOR_TOLERANCE_M, floor_height

    height = floor_height(r.poses, r.trans, r.betas, bvh.fps, body)
    if height is None or abs(height) <= FLOOR_TOLERANCE_M:
        return r.trans
    meta["floor_shift_m"] = round(-height, 4)
    trans = np.array(r.trans, dtype=np.float64)
    trans[:, 1] -= height
    return trans.astype(np.asarray(r.trans).dtype)


def _check_angles(bvh: BVH, path: Path) -> None:
    """Refuse rotation channels beyond ``MAX_ROTATION_RAD`` (in degrees): a damaged file
    or wrong columns, not a rotation (the matrices of any number look like one)."""
    names = [c for chs in bvh.skeleton.channels for c in chs]
    cols = [i for i, c in enumerate(names) if c.endswith("rotation")]
    if not cols or not bvh.num_frames:
        return
    v = np.abs(bvh.motion[:, cols])
    limit = np.degrees(MAX_ROTATION_RAD)
    if v.max() > limit:
        frame, k = np.unravel_index(int(v.argmax()), v.shape)
        raise BVHFormatError(
            path,
            f"frame {frame + 1}: a rotation channel holds {v[frame, k]:.3g} degrees, more "
            f"than {limit:.0f}: not an angle (a damaged file?)",
        )


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


def _check_unit(name: str, value):
    if isinstance(value, str):
        return value
    return check_number(name, value, low=0, open_low=True)


def _format_options(path: Path, kind: str, joint_map, unit, person) -> None:
    """Refuse the options of one format given for a file of another (they would be
    ignored): ``joint_map``/``unit`` are BVH's, ``person`` EasyMocap's."""
    given = []
    if kind != "bvh":
        given += ["joint_map (--joint-map)"] * (joint_map is not None)
        given += [f"unit={unit!r}"] * (unit != "auto")
    if kind != "easymocap":
        given += [f"person={person!r}"] * (person != 0)
    if given:
        what = {"bvh": "a BVH file", "npz": "an .npz of SMPL parameters"}.get(
            kind, "an EasyMocap folder"
        )
        only = {"joint_map": "BVH files", "unit=": "BVH files", "person=": "EasyMocap folders"}
        first = given[0]
        applies = next(v for k, v in only.items() if first.startswith(k))
        raise MotionFileError(
            path, f"{first} applies to {applies} only, and this is {what}; leave it out"
        )


@check_args(
    path=check_path,
    fps=lambda n, v: check_number(n, v, low=0, high=MAX_FPS, open_low=True, optional=True),
    joint_map=check_joint_map,
    body=check_body,
    up_axis=lambda n, v: check_text(n, v, optional=True),
    unit=_check_unit,
    person=lambda n, v: check_number(n, v, low=0, integer=True),
    label=lambda n, v: check_text(n, v, optional=True),
)
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
        joint_map: BVH only (refused for other files): a shipped map name, JSON path
            or ``{smpl: bvh}`` dict.
        body: body model (default: mrlib's), used for the rest joints.
        up_axis: the source's up axis, ``x y z -x -y -z`` or ``"auto"``. Defaults: BVH
            ``"auto"`` (from the skeleton), npz the file's ``up_axis`` key, else told from
            the body (AMASS comes out ``"z"``, BEAT2 ``"y"``; ``mrlib.io.npz``), EasyMocap
            ``"auto"`` (from the body). npz files without the key and EasyMocap folders
            are also put on the floor (``meta["floor_shift_m"]``).
        unit: BVH only: metres per file unit or ``"auto"``.
        person: EasyMocap only: the person ``id`` to read.
        label: ``"auto"``: BVH files read a Bandai Namco JSON next to the file, npz
            files their own ``label`` key; None or a string replaces it.

    Arguments of the wrong type (``fps="30"``, ``path=123``) are an ``ArgumentError``
    naming the argument; an option of another format (``joint_map`` for an npz) is
    refused, not ignored.

    Raises:
        UnsupportedFormatError: unknown extension.
        MotionFileError: missing or malformed file (``BVHFormatError``,
            ``JointMapError`` for BVH problems), with the path and the problem.
    """
    if path.is_dir():
        _format_options(path, "easymocap", joint_map, unit, person)
        motion = load_easymocap(path, fps, person=person, up_axis=up_axis or "auto", body=body)
        return motion if label == "auto" else motion.replace(label=label)
    ext = path.suffix.lower()
    if ext not in SUPPORTED_EXTENSIONS:
        raise UnsupportedFormatError(
            path, f"unsupported file type '{ext}'; mrlib reads .bvh, .npz and EasyMocap folders"
        )
    if not path.is_file():
        raise MotionFileError(path, _not_a_file(path))
    _format_options(path, ext[1:], joint_map, unit, person)
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
        motion = load_npz(path, fps, up_axis=up_axis, body=body)
        return motion if label == "auto" else motion.replace(label=label)
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


def joint_maps_for(paths, joint_map) -> list:
    """Per file of ``paths``, the joint map to read it with: ``joint_map`` for BVH files,
    None for the others (SMPL parameters need none). A joint map given for files none of
    which is a BVH is refused (it would be ignored)."""
    files = [Path(os.fsdecode(os.fspath(p))) for p in paths]
    is_bvh = [f.suffix.lower() == ".bvh" for f in files]
    if joint_map is not None and files and not any(is_bvh):
        raise MotionFileError(
            files[0] if len(files) == 1 else None,
            "joint_map (--joint-map) applies to BVH files only, and "
            + ("this is not one" if len(files) == 1 else "none of these files is one")
            + "; leave it out",
        )
    return [joint_map if b else None for b in is_bvh]


@check_args(
    path=check_path,
    body=check_body,
    bvh_unit=lambda n, v: check_choice(n, v, ("cm", "m")),
    euler_order=lambda n, v: check_choice(n, v.upper() if isinstance(v, str) else v,
                                          ("XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX")),
    overwrite=check_flag,
)  # fmt: skip
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
    if not isinstance(motion, Motion):
        hint = ""
        if isinstance(motion, (str, os.PathLike)):
            hint = " (a file: load it with mrlib.load_motion first)"
        raise ArgumentError(
            f"save_motion wants a Motion, got {type(motion).__name__}: motion={shown(motion)}{hint}"
        )
    ext = path.suffix.lower()
    if ext not in (".npz", ".bvh", ".glb"):
        raise UnsupportedFormatError(
            path, f"unsupported file type '{ext}'; mrlib writes .bvh, .glb and .npz"
        )
    problem = frame_time_problem(float(f"{1.0 / motion.fps:.8f}")) if ext == ".bvh" else None
    if problem is not None:  # what mrlib's reader (and most others) would refuse
        raise MotionFileError(
            path,
            f"a motion at {motion.fps:g} fps makes no BVH: {problem}; resample it first "
            "(motion.resample(fps), or `mrlib export --fps`)",
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
        if isinstance(e, OutputError):  # it names the file and what became of it
            raise MotionFileError(e.path, e.problem) from e
        kept = "; the previous file is kept" if os.path.lexists(path) else ""
        raise MotionFileError(path, f"cannot write: {e.strerror or e}{kept}") from e
