"""A source skeleton's bones against SMPL's, for retargeting (``mrlib.io.retarget``).

``source_bones`` measures the source's mapped bones (step 1); ``compared_joints`` picks
the joints that mark a point of their own, the ones whose positions are compared with
SMPL's (step 7). Leg length (hip to ankle) and the arm-to-leg ratio tell whether SMPL's
shape space can reach the source at all (``reaches_source``, step 8) and scale the root
and the normalised error when it cannot (steps 8, 9).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mrlib.io.jointmap import mapped_targets
from mrlib.representation.skeleton import JOINT_NAMES

__all__ = [
    "ARM_LEG_RANGE",
    "LEG_NAMES",
    "SourceBones",
    "source_bones",
    "compared_joints",
    "leg_length",
    "leg_range",
    "arm_leg",
    "source_leg_length",
    "reaches_source",
]

# The body fit is given up for a transfer by rotations (mrlib.io.retarget, step 8) when
# the source's legs are longer or shorter than any SMPL body's within the shape bound, or
# when its arms are more than a factor ARM_LEG_RANGE longer or shorter, relative to its
# legs, than those of SMPL's mean body (people measured: 0.89-0.95 of it; a stylised
# character with arms x1.2 and legs x0.7: 1.53 - the shape space reaches such a body, but
# its fit trades the feet for the head and torso, and foot contacts move by frames)
ARM_LEG_RANGE = 1.3

LEG_NAMES = {f"{s}_{j}" for s in ("left", "right") for j in ("hip", "knee", "ankle", "foot")}


@dataclass(frozen=True)
class SourceBones:
    """The source's mapped bones: each SMPL joint ``j`` to its nearest mapped descendant
    ``k`` (``pairs``), with the median length of the source bone between them over the
    clip (``lengths``, file units); ``kept`` marks those of non-zero length."""

    pairs: list[tuple[int, int]]
    lengths: np.ndarray
    kept: np.ndarray

    @property
    def kept_pairs(self) -> list[tuple[int, int]]:
        return [p for p, ok in zip(self.pairs, self.kept, strict=True) if ok]

    @property
    def kept_lengths(self) -> np.ndarray:
        return self.lengths[self.kept]

    def smpl_lengths(self, J: np.ndarray) -> np.ndarray:
        """The lengths of the kept bones in SMPL's rest joints ``J (24, 3)``."""
        return np.array([np.linalg.norm(J[k] - J[j]) for j, k in self.kept_pairs])


def source_bones(src: np.ndarray, P: np.ndarray) -> SourceBones:
    """The bones of a source whose joints are at ``P (T, Js, 3)``, mapped by ``src``
    ``(24,)`` (source joint per SMPL joint, -1: unmapped)."""
    mapped = np.flatnonzero(src >= 0)
    pairs = [(j, k) for j in mapped for k in mapped_targets(j, src)]
    src_len = np.array(
        [np.median(np.linalg.norm(P[:, src[k]] - P[:, src[j]], axis=-1)) for j, k in pairs]
    )
    keep = src_len > 1e-6 * max(src_len.max(initial=0.0), 1e-12)
    return SourceBones(pairs, src_len, keep)


def compared_joints(src: np.ndarray, bones: SourceBones, J_tmpl: np.ndarray) -> np.ndarray:
    """The mapped SMPL joints whose positions are compared with the source's ("placed").

    Not those at their mapped ancestor's place (CMU's collars, at the chest: they turn,
    they mark no point), nor a hand joint much nearer to or farther from the wrist, in
    forearm lengths, than SMPL's (CMU's HandIndex1, at 4 cm: SMPL's hand joint is at the
    knuckles, 11 cm) - the bound recognition maps a hand joint within
    (``mrlib.io.recognize``). ``J_tmpl``: SMPL's mean rest joints.
    """
    mapped = np.flatnonzero(src >= 0)
    src_len = bones.lengths
    bone = {k: length for (_, k), length in zip(bones.pairs, src_len, strict=True)}
    unplaced = {k for k, length in bone.items() if length <= 1e-3 * max(src_len.max(), 1e-12)}
    for side in ("left", "right"):
        e, w, h = (JOINT_NAMES.index(f"{side}_{n}") for n in ("elbow", "wrist", "hand"))
        if min(src[[e, w, h]]) >= 0 and w in bone and h in bone:
            want = np.linalg.norm(J_tmpl[h] - J_tmpl[w]) / np.linalg.norm(J_tmpl[w] - J_tmpl[e])
            if not 0.5 * want <= bone[h] / max(bone[w], 1e-12) <= 2.0 * want:
                unplaced.add(h)
    return np.array([j for j in mapped if j not in unplaced])


def leg_length(P: np.ndarray, src: np.ndarray | None) -> float:
    """Hip-to-ankle length (thigh + shin, mean of the legs mapped, median over frames) of
    the source joints ``P (T, Js, 3)`` mapped by ``src``, or of SMPL joints
    ``(T, 24, 3)`` (``src`` None); NaN when no leg is mapped."""
    out = []
    for side in ("left", "right"):
        idx = [JOINT_NAMES.index(f"{side}_{j}") for j in ("hip", "knee", "ankle")]
        if src is not None:
            if (src[idx] < 0).any():
                continue
            idx = list(src[idx])
        thigh = np.linalg.norm(P[:, idx[0]] - P[:, idx[1]], axis=-1)
        shin = np.linalg.norm(P[:, idx[1]] - P[:, idx[2]], axis=-1)
        out.append(float(np.median(thigh + shin)))
    return float(np.mean(out)) if out else float("nan")


def leg_range(J0: np.ndarray, D: np.ndarray, bound: float) -> tuple[float, float]:
    """Shortest and longest hip-to-ankle length (metres) of SMPL bodies with every beta
    within ``bound`` (the length is close to linear in the betas)."""
    L0 = leg_length(J0[None], None)
    grad = [leg_length((J0 + D[..., i])[None], None) - L0 for i in range(D.shape[-1])]
    reach = bound * float(np.abs(grad).sum())
    return L0 - reach, L0 + reach


def arm_leg(P: np.ndarray, src: np.ndarray | None) -> float:
    """Arm length (shoulder to wrist) over leg length (hip to ankle), both sides, of the
    joints ``P (T, Js, 3)`` mapped by ``src`` (or SMPL's ``(T, 24, 3)``, ``src`` None);
    NaN when a limb joint is not mapped."""
    total = {}
    for limb, joints in (
        ("arm", ("shoulder", "elbow", "wrist")),
        ("leg", ("hip", "knee", "ankle")),
    ):
        idx = np.array([JOINT_NAMES.index(f"{s}_{j}") for s in ("left", "right") for j in joints])
        if src is not None:
            if (src[idx] < 0).any():
                return float("nan")
            idx = src[idx]
        idx = idx.reshape(2, 3)
        d = np.linalg.norm(P[:, idx[:, 1:]] - P[:, idx[:, :-1]], axis=-1)  # (T, 2, 2)
        total[limb] = float(np.median(d.sum((1, 2))))
    return total["arm"] / max(total["leg"], 1e-12)


def source_leg_length(
    Pw: np.ndarray, src: np.ndarray, bones: SourceBones, unit_m: float, J_tmpl: np.ndarray
) -> float:
    """The source's hip-to-ankle length in metres, unscaled (``Pw (T, Js, 3)``: its joints
    in metres); with no leg mapped, SMPL's mean body's scaled by the mapped bones' total
    length over SMPL's."""
    leg_src = leg_length(Pw, src)
    if not np.isfinite(leg_src):  # SMPL's size over the source's, by the mapped bones
        smpl_len = sum(np.linalg.norm(J_tmpl[k] - J_tmpl[j]) for j, k in bones.kept_pairs)
        ratio = unit_m * bones.kept_lengths.sum() / smpl_len if smpl_len > 0 else 1.0
        leg_src = leg_length(J_tmpl[None], None) * ratio
    return leg_src


def reaches_source(
    Pw: np.ndarray,
    src: np.ndarray,
    leg_src: float,
    J_tmpl: np.ndarray,
    D: np.ndarray,
    shape_bound: float,
) -> bool:
    """Whether SMPL's shape space (rest joints ``J_tmpl + D b``, every beta within
    ``shape_bound``) reaches the source: its legs (``leg_src``, metres) within the range
    of lengths, its arms relative to its legs within ``ARM_LEG_RANGE`` of SMPL's mean
    body's (NaN, no arms mapped, counts as in range)."""
    ratio = arm_leg(Pw, src) / arm_leg(J_tmpl[None], None)
    lo, hi = leg_range(J_tmpl, D, shape_bound)
    return lo <= leg_src <= hi and not abs(np.log(ratio)) > np.log(ARM_LEG_RANGE)
