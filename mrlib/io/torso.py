"""SMPL's torso on a source skeleton's spine, step 5 of recognition
(``mrlib.io.recognize``): SMPL's spine1..3 and neck go to the joints of the source's
pelvis-to-head chain nearest their own fraction of SMPL's arc length (``place_torso``,
a monotone assignment by dynamic programming), and ``refit_torso`` does the same for a
shipped joint map whose skeletons' spines differ (``JointMap.refit_torso``).
"""

from __future__ import annotations

import numpy as np

from mrlib.io.jointmap import JointMap
from mrlib.io.skeleton_tree import SkeletonTree
from mrlib.representation.skeleton import JOINT_NAMES

__all__ = ["place_torso", "refit_torso"]


def _torso_assignment(
    fr_src: np.ndarray,
    fr_smpl: list[float],
    lo: list[int],
    hi: list[int],
    usable: list[bool] | None = None,
):
    """Monotone assignment of SMPL torso joints (fractions ``fr_smpl``) to source chain
    positions ``1..len-2`` (fractions ``fr_src``; only the ``usable`` ones) or to
    nothing, position ``k`` of SMPL joint ``i`` within ``[lo[i], hi[i]]``; cost ``|fraction
    difference|``, or ``UNMAPPED`` for a joint left out. Returns one position per SMPL
    joint (-1: unmapped)."""
    unmapped = 0.08
    n, m = len(fr_smpl), len(fr_src)
    best = {(-1, 0): (0.0, [])}  # (last position used, SMPL joints done) -> (cost, picks)
    for i in range(n):
        nxt: dict = {}
        for (last, _), (cost, picks) in best.items():
            options = [(-1, unmapped)]
            for k in range(max(last + 1, lo[i]), min(hi[i], m - 2) + 1):
                if usable is None or usable[k]:
                    options.append((k, abs(fr_src[k] - fr_smpl[i])))
            for k, c in options:
                key = (k if k >= 0 else last, i + 1)
                cand = (cost + c, picks + [k])
                if key not in nxt or cand[0] < nxt[key][0]:
                    nxt[key] = cand
        best = nxt
    return min(best.values(), key=lambda v: v[0])[1]


def place_torso(
    tree: SkeletonTree,
    torso: list[int],
    chest_at: int,
    P: np.ndarray,
    hips: list[int],
    J: np.ndarray,
) -> dict[str, int]:
    """SMPL's spine1..3 and neck on the pelvis-to-head chain ``torso`` (step 5): ``{smpl
    name: source joint}``, those with no source joint near enough left out. Arc lengths
    start between the hips ``P[:, hips]`` (where the pelvis joint sits differs between
    rigs); a joint at its parent's place (a zero-length bone) marks no point of its own
    and is not used."""
    base = float(np.median(np.linalg.norm(P[:, torso[0]] - P[:, hips].mean(1), axis=-1)))
    seg = [base] + [tree.bone[torso[i]] for i in range(1, len(torso))]
    fr_src = np.cumsum(seg) / max(sum(seg), 1e-9)
    torso_names = ("pelvis", "spine1", "spine2", "spine3", "neck", "head")
    smpl_torso = [JOINT_NAMES.index(n) for n in torso_names]
    smpl_hips = J[[JOINT_NAMES.index("left_hip"), JOINT_NAMES.index("right_hip")]].mean(0)
    steps = [np.linalg.norm(J[smpl_torso[0]] - smpl_hips)]
    steps += [np.linalg.norm(J[b] - J[a]) for a, b in zip(smpl_torso, smpl_torso[1:], strict=False)]
    arc = np.cumsum(steps)
    fr_smpl = list(arc[1:5] / arc[-1])
    lo = [1, 1, 1, chest_at]
    hi = [chest_at, chest_at, chest_at, len(torso) - 2]
    usable = [seg[k] > 1e-3 * sum(seg) for k in range(len(torso))]
    picks = _torso_assignment(fr_src, fr_smpl, lo, hi, usable)
    names = ("spine1", "spine2", "spine3", "neck")
    return {n: torso[k] for n, k in zip(names, picks, strict=True) if k >= 0}


def refit_torso(jmap: JointMap, names, parents, offsets, positions, rest_joints) -> JointMap:
    """``jmap`` with SMPL's spine1..3 and neck placed on the source's own spine by its
    geometry (step 5), the other joints kept: a shipped map names the torso joints of one
    skeleton, another skeleton with the same names may have its spine joints elsewhere
    (CMU's chest joint, where the collars hang, sits a third of the way up from SMPL's
    spine3 to its collars). Returns ``jmap`` itself when the pelvis, head or chest is not
    mapped or nothing moves.

    Args:
        names, parents, offsets: the source skeleton; positions: ``(F, J, 3)`` joint
            positions of a few frames; rest_joints: ``(24, 3)`` SMPL's.
    """
    m = dict(jmap.mapping)
    need = ("pelvis", "head", "left_hip", "right_hip", "left_collar", "right_collar")
    if any(n not in m for n in need):
        return jmap
    tree = SkeletonTree(names, parents, offsets)
    idx = {n: list(names).index(m[n]) for n in need}
    try:
        torso = tree.path(idx["pelvis"], idx["head"])
    except ValueError:
        return jmap

    def up(j: int) -> list[int]:
        out = [j]
        while parents[out[-1]] >= 0:
            out.append(parents[out[-1]])
        return out

    a, b = up(idx["left_collar"]), set(up(idx["right_collar"]))
    chest = next(j for j in a if j in b)  # where the collars part
    if chest not in torso or chest == torso[0] or chest == torso[-1]:
        return jmap
    P = np.asarray(positions, np.float64)
    hips = [idx["left_hip"], idx["right_hip"]]
    new = place_torso(tree, torso, torso.index(chest), P, hips, np.asarray(rest_joints, np.float64))
    for n in ("spine1", "spine2", "spine3", "neck"):
        m.pop(n, None)
    m.update({n: names[j] for n, j in new.items()})
    if m == dict(jmap.mapping):
        return jmap
    order = {n: m[n] for n in JOINT_NAMES if n in m}
    return JointMap(jmap.name, order, jmap.description + " (torso placed by its geometry)")
