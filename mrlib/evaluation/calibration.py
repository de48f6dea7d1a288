"""Calibration rows: motions built from the data and scored like a generator, to read an
evaluation's numbers against.

The metrics alone are hard to read: a periodic clip (a walk) is covered by anything
walk-like, and an under-trained generator scores more "diverse" than a second real take.
``calibration_rows`` builds comparison motions, scored by ``mrlib.evaluation.evaluate`` with the
same code and settings as the generators:

* ``played twice``: the training clip twice in a row, the second copy continuing the
  root path (coverage 100 %, global diversity ~0: a perfect copy);
* ``frozen first frame``: the first frame held for ``length_factor`` times the clip's
  length (no motion at all; coverage ~0 because its computed contact labels say both
  feet are always down: on the rotation channels alone a frozen walk frame can lie
  within ``eps`` of every window);
* ``other take`` / ``other style``: another real recording of the same content (same
  style, another take; or another style), when one exists. A second take is not
  always the closer one: actors vary a style between takes;
* ``different content``: a real clip of other content (a bow against a walk).

For Bandai Namco clips (``dataset-1_<content>_<style>_<take>``) the real counterparts
are found by name in ``$MRLIB_DATA_DIR`` (``find_bandai_counterparts``).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from mrlib.errors import ClipTooShortError, MotionValueError
from mrlib.io import default_data_dir, load_motion
from mrlib.representation.motion import Motion
from mrlib.representation.rotations import axis_angle_to_matrix, matrix_to_axis_angle

__all__ = [
    "PLAYED_TWICE",
    "FROZEN",
    "OTHER_TAKE",
    "OTHER_STYLE",
    "DIFFERENT_CONTENT",
    "CALIBRATION_METHODS",
    "play_twice",
    "freeze_first_frame",
    "parse_bandai_name",
    "find_bandai_counterparts",
    "load_counterparts",
    "calibration_rows",
    "CalibrationOptions",
]

# Names of the calibration rows, in the order they are reported.
PLAYED_TWICE = "played twice"
FROZEN = "frozen first frame"
OTHER_TAKE = "other take"
OTHER_STYLE = "other style"
DIFFERENT_CONTENT = "different content"
CALIBRATION_METHODS = (PLAYED_TWICE, FROZEN, OTHER_TAKE, OTHER_STYLE, DIFFERENT_CONTENT)


def _yaw_matrix(angle: float) -> np.ndarray:
    """Rotation about +Y by ``angle`` radians, ``(3, 3)``; maps +Z to (sin, 0, cos)."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _heading(root_orient: np.ndarray) -> np.ndarray:
    """``(T, 3)`` axis-angle of the pelvis -> ``(T,)`` yaw (radians) of its +Z axis."""
    R = axis_angle_to_matrix(torch.from_numpy(np.asarray(root_orient, np.float64))).numpy()
    fwd = R[:, :, 2]  # (T, 3): the body's forward direction
    return np.arctan2(fwd[:, 0], fwd[:, 2])


def play_twice(motion: Motion) -> Motion:
    """The clip followed by a copy of itself that continues its root path.

    The copy is turned about the vertical axis and shifted on the ground so that its
    first frame is where the clip would be one frame after its last: heading (pelvis
    yaw) and ground position extrapolated from the last two frames. A walk keeps walking
    instead of jumping back to its start, and a clip moving along a circle continues on
    it exactly. Heights are kept. Contact labels, when present, are repeated.

    Args:
        motion: ``poses (T, 24, 3)``, ``trans (T, 3)``; ``T >= 2``.
    Returns:
        a ``Motion`` of ``2 T`` frames named ``"<name> x2"``.
    """
    T = motion.num_frames
    if T < 2:
        raise ClipTooShortError(f"{motion!r}: playing a clip twice needs at least 2 frames")
    # Frame T extrapolates the last frame: its heading turns on by the last frame's yaw
    # change, its position moves on by the last step turned by that change. The copy is
    # the rigid motion (yaw about +Y, then a shift) that takes frame 0 there.
    yaw = _heading(motion.poses[:, 0])
    turn = float(yaw[-1] - yaw[-2])
    Ry = _yaw_matrix(float(yaw[-1] - yaw[0]) + turn)
    R0 = axis_angle_to_matrix(torch.from_numpy(motion.poses[:, 0].astype(np.float64)))
    poses2 = motion.poses.astype(np.float64).copy()
    poses2[:, 0] = matrix_to_axis_angle(torch.from_numpy(Ry) @ R0).numpy()
    tr = motion.trans.astype(np.float64)
    step = _yaw_matrix(turn) @ (tr[-1] - tr[-2])
    anchor = np.array([tr[-1, 0] + step[0], tr[0, 1], tr[-1, 2] + step[2]])
    trans2 = (tr - tr[0]) @ Ry.T + anchor  # (T, 3); Ry keeps heights
    contacts = None if motion.contacts is None else np.concatenate([motion.contacts] * 2)
    return motion.replace(
        poses=np.concatenate([motion.poses, poses2.astype(np.float32)]),
        trans=np.concatenate([motion.trans, trans2.astype(np.float32)]),
        contacts=contacts,
        name=f"{motion.name or 'clip'} x2",
        meta=dict(motion.meta, calibration=PLAYED_TWICE),
    )


def freeze_first_frame(motion: Motion, length: int | None = None) -> Motion:
    """The first frame held still for ``length`` frames (default ``2 T``); no contact
    labels (computed ones are all 1: nothing moves)."""
    n = 2 * motion.num_frames if length is None else length
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise MotionValueError(f"length must be a positive integer, got {length!r}")
    return motion.replace(
        poses=np.repeat(motion.poses[:1], n, axis=0),
        trans=np.repeat(motion.trans[:1], n, axis=0),
        contacts=None,
        name=f"{motion.name or 'clip'} frame 0",
        meta=dict(motion.meta, calibration=FROZEN),
    )


_BANDAI = re.compile(
    r"^(?:(?P<prefix>dataset-\d+)_)?(?P<content>[A-Za-z0-9-]+)_(?P<style>[A-Za-z0-9-]+)_(?P<take>\d+)$"
)


def parse_bandai_name(name: str) -> dict[str, str] | None:
    """``"dataset-1_walk_happy_001"`` (or ``"walk_happy_001"``) -> ``{"prefix":
    "dataset-1", "content": "walk", "style": "happy", "take": "001"}``; None when the
    name does not follow the Bandai Namco pattern."""
    m = _BANDAI.match(Path(str(name)).stem)
    if m is None:
        return None
    d = m.groupdict()
    d["prefix"] = d["prefix"] or ""
    return d


def find_bandai_counterparts(
    name: str,
    data_dir: str | Path | None = None,
    *,
    different_content: str | None = None,
    other_style: str = "normal",
) -> dict[str, Path]:
    """Real clips to calibrate against, found by Bandai Namco file names.

    Args:
        name: the training clip, e.g. ``"dataset-1_walk_happy_001"``.
        data_dir: the dataset folder (with a ``data/`` subfolder) or the folder of BVH
            files; default ``default_data_dir()``.
        different_content: content of the ``"different content"`` clip; default
            ``"bow"`` (``"walk"`` when the clip is a bow).
        other_style: preferred style of the ``"other style"`` clip (the first other
            style in alphabetical order when it is the clip's own or missing).

    Returns:
        ``{"other take": path, "other style": path, "different content": path}``, only
        the entries that exist: another take of the same content and style (lowest take
        number), the same content in another style (same take number when there is
        one), and the other content in the ``"normal"`` style. Empty when the name is
        not a Bandai Namco name or the folder is missing.
    """
    ref = parse_bandai_name(name)
    root = Path(data_dir) if data_dir is not None else default_data_dir()
    folder = root / "data" if (root / "data").is_dir() else root
    if ref is None or not folder.is_dir():
        return {}
    clips = []
    for p in sorted(folder.glob("*.bvh")):
        d = parse_bandai_name(p.stem)
        if d is not None and d["prefix"] == ref["prefix"]:
            clips.append((d, p))

    def pick(cands: list, prefer_take: str | None = None) -> Path | None:
        if not cands:
            return None
        same = [c for c in cands if c[0]["take"] == prefer_take]
        return sorted(same or cands, key=lambda c: (int(c[0]["take"]), c[1].name))[0][1]

    out: dict[str, Path] = {}
    take = pick(
        [c for c in clips if (c[0]["content"], c[0]["style"]) == (ref["content"], ref["style"])
         and c[0]["take"] != ref["take"]]
    )  # fmt: skip
    if take is not None:
        out[OTHER_TAKE] = take
    styles = sorted(
        {c[0]["style"] for c in clips if c[0]["content"] == ref["content"]} - {ref["style"]}
    )
    if styles:
        style = other_style if other_style in styles else styles[0]
        out[OTHER_STYLE] = pick(
            [c for c in clips if c[0]["content"] == ref["content"] and c[0]["style"] == style],
            ref["take"],
        )
    content = different_content or ("walk" if ref["content"] == "bow" else "bow")
    other = [c for c in clips if c[0]["content"] == content]
    if other:
        normal = [c for c in other if c[0]["style"] == "normal"]
        out[DIFFERENT_CONTENT] = pick(normal or other, "001")
    return out


def calibration_rows(
    reference: Motion,
    others: Mapping[str, Motion] | None = None,
    length_factor: float = 2.0,
) -> dict[str, Motion]:
    """Comparison motions for one training clip.

    Args:
        reference: the training clip.
        others: real clips by row name (``"other take"``, ``"other style"``,
            ``"different content"``, or any name), e.g. loaded from the paths of
            ``find_bandai_counterparts``; used as they are.
        length_factor: the frozen frame lasts ``round(length_factor * T)`` frames.

    Returns:
        ``{"played twice": ..., "frozen first frame": ..., **others}``.
    """
    if not isinstance(reference, Motion):
        raise MotionValueError(f"reference must be a Motion, got {type(reference).__name__}")
    if not (np.isfinite(length_factor) and length_factor > 0):
        raise MotionValueError(f"length_factor must be positive, got {length_factor}")
    rows = {
        PLAYED_TWICE: play_twice(reference),
        FROZEN: freeze_first_frame(reference, max(1, round(length_factor * reference.num_frames))),
    }
    for key, m in (others or {}).items():
        if not isinstance(m, Motion):
            raise MotionValueError(f"others[{key!r}] must be a Motion, got {type(m).__name__}")
        rows[key] = m
    return rows


def load_counterparts(
    label: str, reference: Motion, data_dir: Any, body: Any, notes: list[str]
) -> dict[str, Motion]:
    """The real clips of :func:`find_bandai_counterparts` for ``reference``, loaded and
    at its frame rate; what could not be found is said in ``notes``."""
    name = reference.name or Path(str(reference.meta.get("source", ""))).stem
    paths = find_bandai_counterparts(name, data_dir) if name else {}
    if not paths:
        notes.append(
            f"{label}: no real calibration clips (reference {name!r} is not a Bandai Namco "
            f"name, or {data_dir or default_data_dir()} is missing)"
        )
        return {}
    out = {}
    for key, p in paths.items():
        m = load_motion(p, body=body)
        out[key] = m.resample(reference.fps) if abs(m.fps - reference.fps) > 1e-6 else m
    return out


@dataclass(frozen=True)
class CalibrationOptions:
    """Which calibration rows ``mrlib.evaluation.evaluate.evaluate`` adds.

    Attributes:
        enabled: add the calibration rows (:func:`calibration_rows`) at all.
        others: the real clips beside the built rows: ``"auto"`` finds other takes /
            styles / contents of Bandai Namco references in ``data_dir``
            (:func:`find_bandai_counterparts`); None uses none; or label -> {row name:
            Motion}.
        data_dir: the Bandai Namco folder for ``"auto"`` (default ``default_data_dir()``).
    """

    enabled: bool = True
    others: str | Mapping[str, Mapping[str, Motion]] | None = "auto"
    data_dir: str | Path | None = None

    def others_of(
        self, label: str, reference: Motion, body: Any, notes: list[str]
    ) -> dict[str, Motion]:
        """The real clips to score beside the built rows of ``reference`` (``label``);
        for ``"auto"``, what could not be found is said in ``notes``."""
        if self.others == "auto":
            return load_counterparts(label, reference, self.data_dir, body, notes)
        if self.others is None:
            return {}
        return dict(self.others.get(label, {}))
