"""Poses on the rig, without Blender (plain Python, no numpy): the bridge writes a motion
as per-bone BVH rotations in the armature's axes (``RigMotion``); turning them into pose-bone
rotations and locations keyed at the scene's frames is quaternion algebra (w, x, y, z),
done here so that ``tests/test_blender_addon.py`` checks it outside Blender."""

from __future__ import annotations

import json
import math
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from .core import SetupError

RIG_MOTION_FORMAT = "mrlib-rig-motion"
Quat = tuple[float, float, float, float]
Vec = tuple[float, float, float]


def quat_mul(a: Sequence[float], b: Sequence[float]) -> Quat:
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    )


def quat_conj(q: Sequence[float]) -> Quat:
    return (q[0], -q[1], -q[2], -q[3])


def quat_normalized(q: Sequence[float]) -> Quat:
    n = math.sqrt(sum(c * c for c in q)) or 1.0
    return (q[0] / n, q[1] / n, q[2] / n, q[3] / n)


def quat_rotate(q: Sequence[float], v: Sequence[float]) -> Vec:
    w, x, y, z = quat_mul(quat_mul(q, (0.0, *v)), quat_conj(q))
    return (x, y, z)


def quat_from_matrix(m: Sequence[Sequence[float]]) -> Quat:
    """The unit quaternion of a 3x3 rotation matrix (rows), w >= 0."""
    (m00, m01, m02), (m10, m11, m12), (m20, m21, m22) = ((float(v) for v in r) for r in m)
    tr = m00 + m11 + m22
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        q = (0.25 * s, (m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s)
    elif m00 > m11 and m00 > m22:
        s = math.sqrt(1.0 + m00 - m11 - m22) * 2
        q = ((m21 - m12) / s, 0.25 * s, (m01 + m10) / s, (m02 + m20) / s)
    elif m11 > m22:
        s = math.sqrt(1.0 + m11 - m00 - m22) * 2
        q = ((m02 - m20) / s, (m01 + m10) / s, 0.25 * s, (m12 + m21) / s)
    else:
        s = math.sqrt(1.0 + m22 - m00 - m11) * 2
        q = ((m10 - m01) / s, (m02 + m20) / s, (m12 + m21) / s, 0.25 * s)
    q = quat_normalized(q)
    return q if q[0] >= 0 else (-q[0], -q[1], -q[2], -q[3])


def quat_to_matrix(q: Sequence[float]) -> list[list[float]]:
    w, x, y, z = quat_normalized(q)
    return [
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ]


def basis_from_local(local: Sequence[float], rest: Sequence[float]) -> Quat:
    """A pose bone's rotation (``matrix_basis``, in the bone's rest frame) from its BVH
    rotation as Blender's BVH exporter writes it.

    With ``R`` the bone's rest orientation in armature space (``bone.matrix_local``) and
    ``P`` its posed one (``pose_bone.matrix``), the exporter writes ``G = P R^-1`` of the
    root and ``G_parent^-1 G`` of every other bone (``io_anim_bvh.export_bvh``), all in the
    armature's axes. Since ``P = P_parent R_parent^-1 R B`` (``B``: the basis rotation),
    ``G_parent^-1 G = R B R^-1``, so ``B = R^-1 (G_parent^-1 G) R``: ``local`` and ``rest``
    are those two rotations as quaternions."""
    return quat_normalized(quat_mul(quat_mul(quat_conj(rest), local), rest))


def root_location(position: Sequence[float], head: Sequence[float], rest: Sequence[float]) -> Vec:
    """A parentless pose bone's location (in its rest frame) that puts its head at
    ``position`` (armature space): ``R^-1 (position - head_rest)``."""
    d = tuple(float(p) - float(h) for p, h in zip(position, head, strict=True))
    return quat_rotate(quat_conj(rest), d)


def continuous(quats: Iterable[Sequence[float]]) -> list[Quat]:
    """``quats`` with signs flipped so each is in the hemisphere of the one before (no
    spins through the long way when Blender interpolates the components)."""
    out: list[Quat] = []
    for q in quats:
        q = tuple(float(c) for c in q)
        if out and sum(a * b for a, b in zip(out[-1], q, strict=True)) < 0:
            q = tuple(-c for c in q)
        out.append(q)  # type: ignore[arg-type]
    return out


def key_frames(count: int, motion_fps: float, scene_fps: float, start: float = 1.0) -> list[float]:
    """Scene frames of ``count`` motion frames at ``motion_fps`` (fractional where the
    rates differ; the first at ``start``)."""
    if motion_fps <= 0 or scene_fps <= 0:
        raise SetupError(f"frame rates must be positive, got {motion_fps:g} and {scene_fps:g}")
    step = scene_fps / motion_fps
    return [start + i * step for i in range(count)]


@dataclass(frozen=True)
class RigMotion:
    """What the bridge's ``onto-rig`` writes: a motion as rotations of the rig's bones.

    Attributes:
        fps: frames per second of the motion.
        bones: the rig's bones in the file's order (every one the clip exported).
        parents: index of each bone's parent in ``bones`` (-1: none).
        rotations: bone -> ``T`` quaternions (w, x, y, z), the bone's BVH rotation
            relative to its parent, in the armature's axes (see ``basis_from_local``).
        mover: the bone that carries the motion's translation (the rig's root).
        positions: ``T`` positions of ``mover``'s head, armature space and units.
        mapped: the joint map used, SMPL joint -> bone.
        meta: the rest (label, source files, retargeting error, ...).
    """

    fps: float
    bones: tuple[str, ...]
    parents: tuple[int, ...]
    rotations: dict[str, list[Quat]]
    mover: str
    positions: list[Vec]
    mapped: dict[str, str]
    meta: dict

    @property
    def num_frames(self) -> int:
        return len(self.positions)

    @classmethod
    def from_json(cls, path: str | Path) -> RigMotion:
        path = Path(path)
        try:
            d = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError) as e:
            raise SetupError(f"{path}: cannot read the rig motion ({e})") from None
        if not isinstance(d, dict) or d.get("format") != RIG_MOTION_FORMAT:
            raise SetupError(f"{path}: not a rig motion written by the add-on's bridge")
        T = len(d["positions"])
        rots = {b: [tuple(q) for q in qs] for b, qs in d["rotations"].items()}
        short = [b for b, qs in rots.items() if len(qs) != T]
        if short:
            raise SetupError(f"{path}: bone {short[0]!r} has {len(rots[short[0]])} frames, not {T}")
        meta = {k: v for k, v in d.items() if k not in ("rotations", "positions")}
        return cls(
            fps=float(d["fps"]), bones=tuple(d["bones"]), parents=tuple(d["parents"]),
            rotations=rots, mover=d["mover"], positions=[tuple(p) for p in d["positions"]],
            mapped=dict(d.get("mapped", {})), meta=meta,
        )  # fmt: skip

    def missing_bones(self, names: Iterable[str]) -> list[str]:
        """The bones this motion drives that an armature with bones ``names`` lacks."""
        have = set(names)
        return [b for b in self.bones if b not in have and not is_dummy_root(b)]


def is_dummy_root(name: str) -> bool:
    """The root Blender's BVH exporter adds above an armature of several root bones."""
    return re.fullmatch(r"__\d+", name) is not None
