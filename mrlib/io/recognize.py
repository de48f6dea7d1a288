"""Recognising a humanoid skeleton: a joint map from the tree, the bone lengths and the
joint names, for skeletons no shipped map fits.

The steps below share one view of the tree (``mrlib.io.skeleton_tree.SkeletonTree``) and
one set of name rules (``mrlib.io.name_rules``: sides, helper joints, end markers, the
words of each role); step 5 lives in ``mrlib.io.torso``, which also refits a shipped
map's torso (``refit_torso``). This module finds the pelvis, chest and limbs and judges
the result.

A humanoid tree, whatever its names, has a *pelvis* where two legs and the spine part, a
*chest* on the spine where two arms part from the way to the head, and five long chains
to the feet, the hands and the head. ``match_skeleton`` finds them in numbered steps:

1. **Chains.** Bone lengths come from the rest offsets (they do not depend on the pose).
   End markers (leaf joints named ``end``, ``top``, ``nub``, ``tip``, ``site``) and
   helper joints (``twist``, ``roll``, ``share`` bones, ``ik`` and ``ctrl`` targets) with
   nothing but helpers below them are passed over; a helper joint *on* a chain (a
   ``NeckTwist`` under the head, a ``ThighTwist`` between thigh and shin) is part of the
   bone it sits on (:func:`is_helper`).
2. **Pelvis.** The joint nearest the root with three long branches (each at least a
   sixth of the tree's longest chain): the two most alike are the legs, the one that
   branches again is the spine. Or a *split hip*: a joint with two long branches, one
   leading (within half a leg's length) to a joint where the two legs part, the other
   to the spine (Character Creator's ``Hip`` -> ``Pelvis`` (legs) and ``Waist`` (spine),
   or a lower and an upper body under a common root); the common joint is the pelvis.
3. **Chest.** Down the spine, the first joint with two long branches that are alike: the
   arms; its remaining branch leads to the head.
4. **Limbs.** On each leg and arm (helper joints on the chain merged into their bone)
   the two longest consecutive bones are thigh and shin,
   upper arm and forearm: the hip, knee and ankle, the shoulder, elbow and wrist (the
   collar before it); the toe and the hand joint are the joints after the ankle and the
   wrist as far from them, in shin and forearm lengths, as SMPL's (the toe base, not a
   mid-foot joint; a knuckle, not a finger base at the wrist).
5. **Torso.** SMPL's spine1..3 and neck go to the joints of the pelvis-to-head chain
   nearest their own fraction of SMPL's arc length (dynamic programming: in order, one
   SMPL joint per source joint, spine3 at or below the chest and the neck at or above
   it; a joint at its parent's place marks no point and is not used); a SMPL joint with
   no source joint near enough stays unmapped, and retargeting spreads the rotation over
   it (``mrlib.io.retarget``). ``refit_torso`` does the same for a shipped map.
6. **Sides** from the names (``Left``, ``L``, ``_l``, ``.L``, ...), else from the pose:
   with up from the feet to the head and forward along the feet, left is ``up x
   forward`` (SMPL's convention: facing +Z, left at +X).
7. **Confidence**: the share of plausibility checks passed (limb ratios, left/right
   symmetry, arm / leg / torso proportions, an upright trunk over the clip), weighted
   0.7, plus the share of mapped joints whose names agree with their role, 0.3. Below
   ``MIN_CONFIDENCE`` the skeleton is refused, and so is a trunk that is upright over
   the feet in none of the sampled frames (a four-legged tree).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mrlib.errors import JointMapError
from mrlib.io.jointmap import JointMap
from mrlib.io.name_rules import fits_role, is_helper, name_fits_joint, name_parts
from mrlib.io.skeleton_tree import SkeletonTree
from mrlib.io.torso import place_torso, refit_torso
from mrlib.representation.skeleton import JOINT_NAMES

__all__ = [
    "MIN_CONFIDENCE",
    "SkeletonMatch",
    "name_parts",
    "is_helper",
    "match_skeleton",
    "refit_torso",
]

MIN_CONFIDENCE = 0.6


@dataclass(frozen=True)
class SkeletonMatch:
    """What :func:`match_skeleton` found.

    Attributes:
        joint_map: SMPL joint -> source joint (SMPL joints with no counterpart left out).
        confidence: in [0, 1] (module docstring, step 7).
        checks: ``(what, passed, detail)`` for every plausibility check.
        name_agreement: share of mapped joints whose source name fits their role.
    """

    joint_map: JointMap
    confidence: float
    checks: tuple[tuple[str, bool, str], ...] = field(default=())
    name_agreement: float = 0.0

    def report(self) -> str:
        """The map and the checks, one line each."""
        lines = [f"recognised as humanoid, confidence {self.confidence:.2f}"]
        for what, ok, detail in self.checks:
            lines.append(f"  [{'x' if ok else ' '}] {what}: {detail}")
        lines.append(f"  names agree with their role: {100 * self.name_agreement:.0f}%")
        return "\n".join(lines)


def _limb(
    tree: SkeletonTree, start: int, roles: tuple[str, str, str]
) -> tuple[list[int], int, list[float]]:
    """The chain from ``start`` (helper joints on it merged into their bone), the index
    ``k`` of its upper bone (chain[k] -> chain[k + 1] -> chain[k + 2]) and the chain's
    bone lengths (``seg[i]``: chain[i] -> chain[i + 1]). The upper bone starts the two
    longest consecutive bones, with a bonus for names that fit ``roles`` (a long collar
    and a short forearm, as CMU's, are a near tie on lengths alone)."""
    full = tree.chain(start)
    ch = [j for i, j in enumerate(full) if i == 0 or not tree.helper[j]]
    if len(ch) < 3:
        raise JointMapError(None, f"the limb at '{tree.names[start]}' has fewer than 3 joints")
    at = {j: i for i, j in enumerate(full)}
    seg = [
        float(sum(tree.bone[c] for c in full[at[a] + 1 : at[b] + 1]))
        for a, b in zip(ch, ch[1:], strict=False)
    ]
    top = max(seg[i] + seg[i + 1] for i in range(len(seg) - 1))

    def score(i: int) -> float:
        fits = sum(fits_role(tree.parts[ch[i + r]][1], role) for r, role in enumerate(roles))
        return (seg[i] + seg[i + 1]) / max(top, 1e-9) + 0.1 * fits

    k = max(range(len(seg) - 1), key=score)
    return ch, k, seg


def _find_pelvis(tree: SkeletonTree, long: float) -> tuple[int, int, tuple[int, int]]:
    """``(pelvis, first joint of the spine, the two legs' first joints)``: the joint
    nearest the root where two legs and a spine part, together (three long branches) or
    split (two long branches: one reaches a joint where the legs part, within half a
    leg's length, the other holds the chest)."""
    for j in sorted(range(tree.n), key=lambda j: tree.depth[j]):
        kids = tree.long_children(j, long)
        if len(kids) >= 3:
            # the spine branches again (the chest); the legs do not
            spine = max(kids, key=lambda c: (tree.long_forks(c, long), tree.branches(c)))
            return j, spine, tree.pick_pair([k for k in kids if k != spine], j)
        if len(kids) != 2:
            continue
        best = None
        for a, b in (kids, kids[::-1]):  # a: towards the legs, b: the spine
            fork, way = tree.first_fork(a, long)
            if fork is None or not tree.long_forks(b, long):
                continue
            legs = tree.long_children(fork, long)
            if len(legs) != 2 or any(tree.long_forks(c, long) for c in legs):
                continue  # three branches there (a hip of its own), or arms with a head
            way += tree.bone[a]
            if way > 0.5 * min(tree.reach(fork, c) for c in legs):
                continue  # the arms part far up the spine; the legs near the hip
            if best is None or way < best[0]:
                best = (way, b, (legs[0], legs[1]))
        if best is not None:
            return j, best[1], best[2]
    raise JointMapError(None, "no joint where two legs and a spine part: not a humanoid tree")


def match_skeleton(
    names,
    parents,
    offsets,
    positions: np.ndarray,
    rest_joints: np.ndarray,
    local_rotations: np.ndarray | None = None,
) -> SkeletonMatch:
    """Recognise a humanoid source skeleton (method: module docstring).

    Args:
        names, parents, offsets: the source skeleton (``offsets (J, 3)`` in file units).
        positions: ``(F, J, 3)`` joint positions of a few frames of the clip (any unit and
            axes; used for sides and the upright check).
        rest_joints: ``(24, 3)`` SMPL rest joints (fractions along SMPL's torso and the
            wrist-to-hand distance).
        local_rotations: ``(F, J, 3, 3)`` of the same frames (optional): a leaf that
            never turns against its parent is an end marker, whatever its name.
    Returns:
        A :class:`SkeletonMatch`.
    Raises:
        JointMapError: the tree has no pelvis with two legs and a spine, or no chest with
            two arms and a head.
    """
    tree = SkeletonTree(names, parents, offsets)
    P = np.asarray(positions, np.float64)
    still = None
    if local_rotations is not None:
        Rl = np.asarray(local_rotations, np.float64)
        still = np.abs(Rl - Rl[:1]).max(axis=(0, 2, 3)) < 1e-4  # (J,)
    size = max(tree.down[j] for j in range(tree.n) if tree.parents[j] < 0)
    if size <= 0:
        raise JointMapError(None, "the skeleton has no bone of non-zero length")
    # 2. pelvis: nearest the root with three long branches, or a split hip
    pelvis, spine_child, leg_kids = _find_pelvis(tree, size / 6)
    # 3. chest: down the spine, the first joint with two alike long branches
    chest, arm_kids, head_child = None, None, None
    for j in tree.chain(spine_child):
        longs = tree.long_children(j, size / 6)
        others = [c for c in tree.children[j] if not tree.skip[c]]
        if len(longs) >= 2 and len(others) >= 3:
            a, b = tree.pick_pair(longs, j)
            rest = [c for c in others if c not in (a, b)]
            chest, arm_kids = j, (a, b)
            head_child = max(rest, key=lambda c: tree.reach(j, c))
            break
    if chest is None:
        raise JointMapError(
            None, "no joint on the spine where two arms part from the neck: not a humanoid tree"
        )
    # 4. limbs
    legs, arms = {}, {}
    for store, starts, roles in (
        (legs, leg_kids, ("hip", "knee", "ankle")),
        (arms, arm_kids, ("shoulder", "elbow", "wrist")),
    ):
        for s in starts:
            store[s] = _limb(tree, s, roles)
    # 5. torso: pelvis .. chest .. head along the chain; arc lengths start between the
    # hips (where the pelvis joint sits differs between rigs). The head is the joint named
    # so; without names, a head-top marker is a leaf that never turns against its parent.
    head_chain = tree.chain(head_child)
    named = [i for i, j in enumerate(head_chain) if tree.parts[j][1] == "head"]
    if named:  # a joint called "head" is the head, whatever follows it
        head_chain = head_chain[: named[-1] + 1]
    elif still is not None and len(head_chain) >= 2 and still[head_chain[-1]]:
        head_chain = head_chain[:-1]
    torso = tree.path(pelvis, chest) + head_chain
    hips = [ch[k] for ch, k, _ in legs.values()]
    J = np.asarray(rest_joints, np.float64)
    mapping = {"pelvis": tree.names[pelvis], "head": tree.names[torso[-1]]}
    for name, j in place_torso(tree, torso, torso.index(chest), P, hips, J).items():
        mapping[name] = tree.names[j]
    # 6. sides: names, else the pose
    up_f = P[:, torso[-1]] - P[:, pelvis]  # (F, 3)
    foot_dirs = []
    for ch, k, _ in legs.values():
        if len(ch) > k + 3:
            foot_dirs.append(P[:, ch[k + 3]] - P[:, ch[k + 2]])
    fwd_f = np.mean(foot_dirs, 0) if foot_dirs else None

    def side_of(start: int, chain: list[int]) -> str | None:
        votes = [tree.parts[j][0] for j in chain if tree.parts[j][0]]
        if votes:
            return max(set(votes), key=votes.count)
        if fwd_f is None:
            return None
        left = np.cross(up_f, fwd_f)  # (F, 3)
        rel = P[:, start] - P[:, pelvis]
        return "left" if np.median((rel * left).sum(-1)) > 0 else "right"

    checks: list[tuple[str, bool, str]] = []
    for label, store, roles in (
        ("legs", legs, ("hip", "knee", "ankle")),
        ("arms", arms, ("shoulder", "elbow", "wrist")),
    ):
        starts = list(store)
        sides = [side_of(s, store[s][0]) for s in starts]
        if sides[0] == sides[1] or None in sides:
            raise JointMapError(
                None, f"cannot tell the left from the right {label} (names and pose disagree)"
            )
        for s, side in zip(starts, sides, strict=True):
            ch, k, lseg = store[s]
            for i, role in enumerate(roles):
                if k + i < len(ch):
                    mapping[f"{side}_{role}"] = tree.names[ch[k + i]]
            if label == "arms" and k >= 1:
                mapping[f"{side}_collar"] = tree.names[ch[k - 1]]
            # the hand (toe) joint: on the chain after the wrist (ankle), as far from it,
            # in forearm (shin) lengths, as SMPL's; a foot without one takes the next joint
            mid, end, tip = roles[1:] + (("hand",) if label == "arms" else ("foot",))
            a, b, c = (JOINT_NAMES.index(f"{side}_{r}") for r in (mid, end, tip))
            want = np.linalg.norm(J[c] - J[b]) / np.linalg.norm(J[b] - J[a])
            dist = np.cumsum(lseg[k + 2 :]) / max(lseg[k + 1], 1e-9)
            if len(dist):
                best = int(np.argmin(np.abs(dist - want)))
                if 0.5 * want <= dist[best] <= 2.0 * want:
                    mapping[f"{side}_{tip}"] = tree.names[ch[k + 3 + best]]
                elif label == "legs":
                    mapping[f"{side}_{tip}"] = tree.names[ch[k + 3]]
    # 7. plausibility and names
    for label, store in (("legs", legs), ("arms", arms)):
        ratios, lengths = [], []
        for _, k, lseg in store.values():
            a, b = lseg[k], lseg[k + 1]
            ratios.append(a / max(b, 1e-9))
            lengths.append(a + b)
        ok = all(0.6 <= r <= 1.7 for r in ratios)
        checks.append(
            (f"{label}: upper / lower bone", ok, " and ".join(f"{r:.2f}" for r in ratios))
        )
        sym = abs(np.log(lengths[0] / max(lengths[1], 1e-9)))
        checks.append((f"{label}: left / right length", sym < 0.15, f"{np.exp(sym):.2f}"))
    leg_len = np.mean([sg[k] + sg[k + 1] for _, k, sg in legs.values()])
    arm_len = np.mean([sg[k] + sg[k + 1] for _, k, sg in arms.values()])
    base = float(np.median(np.linalg.norm(P[:, pelvis] - P[:, hips].mean(1), axis=-1)))
    torso_len = base + sum(tree.bone[torso[i]] for i in range(1, len(torso)))
    # wide enough for stylised characters (long arms, short legs, a big head), narrow
    # enough to tell a humanoid from a long-armed or long-bodied animal
    checks.append(
        ("arm / leg length", 0.45 <= arm_len / leg_len <= 1.5, f"{arm_len / leg_len:.2f}")
    )
    checks.append(
        ("torso / leg length", 0.45 <= torso_len / leg_len <= 2.2, f"{torso_len / leg_len:.2f}")
    )
    # upright over the clip: the trunk points away from the feet
    ankles = [P[:, ch[k + 2]] for ch, k, _ in legs.values()]
    down_f = np.mean(ankles, 0) - P[:, pelvis]
    cos = (up_f * -down_f).sum(-1) / np.maximum(
        np.linalg.norm(up_f, axis=-1) * np.linalg.norm(down_f, axis=-1), 1e-9
    )
    upright = float(np.mean(cos > np.cos(np.radians(45))))
    if upright == 0.0:
        raise JointMapError(
            None,
            "the way from the pelvis to the head never points away from the feet in the clip "
            "(legs under a level spine: a four-legged tree, not a humanoid one)",
        )
    checks.append(
        ("trunk upright over the feet", upright >= 0.7, f"{100 * upright:.0f}% of frames")
    )
    agree = [name_fits_joint(src, smpl) for smpl, src in mapping.items()]
    names_ok = float(np.mean(agree)) if agree else 0.0
    confidence = 0.7 * float(np.mean([ok for _, ok, _ in checks])) + 0.3 * names_ok
    jmap = JointMap(
        "recognised",
        {k: mapping[k] for k in JOINT_NAMES if k in mapping},
        "recognised from the tree, bone lengths and names (mrlib.io.recognize)",
    )
    return SkeletonMatch(jmap, confidence, tuple(checks), names_ok)


def recognise_bvh(bvh, rest_joints: np.ndarray, min_confidence: float = MIN_CONFIDENCE):
    """:func:`match_skeleton` for a parsed BVH (``mrlib.io.bvh.BVH``): the pose of up to
    60 frames spread over the clip; refuses below ``min_confidence``.

    Raises:
        JointMapError: not recognised as humanoid (the error names the file and says why,
            with the checks that failed).
    """
    from mrlib.io.bvh.hierarchy import BVH
    from mrlib.io.bvh.kinematics import bvh_forward_kinematics, bvh_local_transforms

    sk = bvh.skeleton
    sub = np.unique(np.linspace(0, bvh.num_frames - 1, min(bvh.num_frames, 60)).round().astype(int))
    part = BVH(sk, bvh.motion[sub], bvh.frame_time, source=bvh.source)
    _, P = bvh_forward_kinematics(part)
    local, _ = bvh_local_transforms(part)
    hint = (
        "Pass a joint map {smpl_name: bvh_name, ...} (--joint-map map.json, joint_map= in "
        "Python; `mrlib info --write-map map.json` writes a start)."
    )
    try:
        match = match_skeleton(sk.names, sk.parents, sk.offsets, P, rest_joints, local)
    except JointMapError as e:
        raise JointMapError(
            bvh.source, f"no joint map fits this skeleton: {e.problem.rstrip('.')}. {hint}"
        ) from None
    if match.confidence < min_confidence:
        failed = [f"{w} ({d})" for w, ok, d in match.checks if not ok]
        raise JointMapError(
            bvh.source,
            f"no joint map fits this skeleton: it does not look humanoid enough (confidence "
            f"{match.confidence:.2f} < {min_confidence}; failed: {', '.join(failed) or 'none'}; "
            f"names agree with their role for {100 * match.name_agreement:.0f}% of joints). {hint}",
        )
    return match
