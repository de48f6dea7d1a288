"""Units and up axes: the world-frame conversions mrlib's readers share.

mrlib's world is in metres with Y up. ``up_axis_rotation`` turns a world whose up is
another axis into it, and ``change_up_axis`` re-expresses SMPL parameters captured in
such a world (AMASS's Z up, ``mrlib.io.npz``). For a BVH (``mrlib.io.retarget``, step 2)
``file_unit`` picks the file's unit among ``UNITS`` by its bone lengths, and
``source_up_axis`` takes the world axis closest to the mean feet-to-head vector.
"""

from __future__ import annotations

import numpy as np

from mrlib.representation.skeleton import JOINT_NAMES

__all__ = [
    "UNITS",
    "up_axis_rotation",
    "detect_up_axis",
    "change_up_axis",
    "file_unit",
    "source_up_axis",
]

# Candidate file units (metres per file unit) for automatic detection. "cmu" is the unit
# of the CMU database's ASF/AMC files and of their common BVH conversion: 1/0.45 inch.
UNITS: dict[str, float] = {"m": 1.0, "cmu": 0.0254 / 0.45, "inch": 0.0254, "cm": 0.01, "mm": 0.001}

_AXES = ("x", "y", "z", "-x", "-y", "-z")


def up_axis_rotation(axis: str) -> np.ndarray:
    """``(3, 3)`` rotation taking a world whose up is ``axis`` to mrlib's Y-up world.

    ``axis`` is one of ``x y z -x -y -z``. ``"z"`` is a -90 deg turn about X (AMASS:
    ``(x, y, z) -> (x, z, -y)``); ``"-y"`` is 180 deg about X (camera frames).
    """
    a = str(axis).lower()
    c = {
        "y": np.eye(3),
        "z": [[1, 0, 0], [0, 0, 1], [0, -1, 0]],
        "-z": [[1, 0, 0], [0, 0, -1], [0, 1, 0]],
        "-y": [[1, 0, 0], [0, -1, 0], [0, 0, -1]],
        "x": [[0, -1, 0], [1, 0, 0], [0, 0, 1]],
        "-x": [[0, 1, 0], [-1, 0, 0], [0, 0, 1]],
    }.get(a)
    if c is None:
        raise ValueError(f"up axis must be one of {_AXES}, got {axis!r}")
    return np.asarray(c, dtype=np.float64)


def detect_up_axis(up_vectors: np.ndarray) -> str:
    """The signed world axis closest to the mean of ``(..., 3)`` "up" vectors."""
    v = np.asarray(up_vectors, dtype=np.float64).reshape(-1, 3).mean(0)
    i = int(np.argmax(np.abs(v)))
    return ("-" if v[i] < 0 else "") + "xyz"[i]


def change_up_axis(
    global_orient: np.ndarray, trans: np.ndarray, rest_pelvis: np.ndarray, axis: str
) -> tuple[np.ndarray, np.ndarray]:
    """Re-express SMPL parameters captured in an ``axis``-up world in mrlib's Y-up world.

    SMPL rotates about the pelvis joint, so rotating the world by ``A`` changes the
    translation by more than ``A``: ``G' = A G`` and ``trans' = A (J_pelvis + trans) - J_pelvis``.

    Args:
        global_orient: ``(T, 3, 3)`` pelvis rotations.
        trans: ``(T, 3)`` SMPL translations.
        rest_pelvis: ``(3,)`` the body's rest pelvis position for the clip's betas.
        axis: the source up axis (``"z"`` for AMASS).

    Returns:
        ``(global_orient (T, 3, 3), trans (T, 3))`` in the Y-up frame.
    """
    A = up_axis_rotation(axis)
    J0 = np.asarray(rest_pelvis, dtype=np.float64)
    return A @ global_orient, (np.asarray(trans, np.float64) + J0) @ A.T - J0


def file_unit(unit: str | float, smpl_lengths: np.ndarray, source_lengths: np.ndarray) -> float:
    """Metres per file unit: ``unit`` (a name in ``UNITS`` or a number), or for
    ``"auto"`` the candidate of ``UNITS`` that makes the source's bones closest in total
    length to SMPL's (``source_lengths`` in file units, ``smpl_lengths`` in metres: the
    same mapped bones)."""
    if unit == "auto":
        guess = smpl_lengths.sum() / max(source_lengths.sum(), 1e-12)
        return min(UNITS.values(), key=lambda u: abs(np.log(u / guess)))
    if isinstance(unit, str):
        if unit not in UNITS:
            raise ValueError(
                f"unit must be 'auto', one of {sorted(UNITS)} or a number, got {unit!r}"
            )
        return UNITS[unit]
    unit_m = float(unit)
    if not (np.isfinite(unit_m) and unit_m > 0):
        raise ValueError(f"unit must be a positive number of metres, got {unit!r}")
    return unit_m


def source_up_axis(src: np.ndarray, P: np.ndarray) -> str:
    """The up axis of a source whose joints are at ``P (T, Js, 3)`` (file axes), ``src``
    ``(24,)`` its joint per SMPL joint (-1: unmapped): the world axis closest to the mean
    vector from the feet (the ankles, else the pelvis) to the highest mapped joint of the
    torso; ``"y"`` when no torso joint above the pelvis is mapped."""
    top = next(
        (
            src[JOINT_NAMES.index(n)]
            for n in ("head", "neck", "spine3", "spine2", "spine1")
            if src[JOINT_NAMES.index(n)] >= 0
        ),
        None,
    )
    feet = [
        src[JOINT_NAMES.index(n)]
        for n in ("left_ankle", "right_ankle")
        if src[JOINT_NAMES.index(n)] >= 0
    ]
    bottom = P[:, feet].mean(1) if feet else P[:, src[0]]
    return detect_up_axis(P[:, top] - bottom) if top is not None else "y"
