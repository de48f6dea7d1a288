"""Recognising a humanoid skeleton: a joint map from the tree, the bone lengths and the
joint names, for skeletons no shipped map fits.

The module is long because it is one algorithm, the seven numbered steps below, whose
functions share one view of the tree (``_Tree``) and one set of name rules; split, each
part would have to reach into the others' internals.

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

import re
from dataclasses import dataclass, field

import numpy as np

from mrlib.errors import JointMapError
from mrlib.io.jointmap import JointMap
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

_END = re.compile(r"(end|top|nub|tip|site|effector)$")
# helper bones: twist / roll / share (skinning helpers riding on a limb bone), IK and
# control targets; matched on the core of the name (``name_parts``)
_HELPER = re.compile(r"(twist|roll|share|helper|corrective)|^(ik|ctrl|ctl)")
_PREFIX = re.compile(r"^(mixamorig\d*|bip0*\d+|def|jnt|j|b|bn|cc base|rig|sk)\s+")
_SIDE_WORDS = {
    "left": "left",
    "l": "left",
    "lft": "left",
    "right": "right",
    "r": "right",
    "rt": "right",
}
# role -> words a name of that role contains (after the side marker is removed)
_ROLES = {
    "pelvis": ("hips", "hip", "pelvis", "root", "cog"),
    "spine": ("spine", "chest", "back", "torso", "abdomen", "waist", "belly"),
    "neck": ("neck",),
    "head": ("head",),
    "collar": ("clavicle", "collar", "shoulder"),
    "shoulder": ("upperarm", "arm", "shoulder", "shldr", "humerus"),
    "elbow": ("forearm", "lowerarm", "elbow"),
    "wrist": ("hand", "wrist"),
    "hand": ("finger", "index", "middle", "hand", "palm", "knuckle"),
    "hip": ("upleg", "thigh", "upperleg", "hip", "femur"),
    "knee": ("leg", "knee", "shin", "calf", "lowerleg"),
    "ankle": ("foot", "ankle"),
    "foot": ("toe", "ball", "toes"),
}
_ROLE_OF = {
    "pelvis": "pelvis", "spine1": "spine", "spine2": "spine", "spine3": "spine",
    "neck": "neck", "head": "head",
}  # fmt: skip
for _s in ("left", "right"):
    _ROLE_OF.update(
        {f"{_s}_{k}": k for k in ("collar", "shoulder", "elbow", "wrist", "hand", "hip", "knee")}
    )
    _ROLE_OF.update({f"{_s}_ankle": "ankle", f"{_s}_foot": "foot"})
_PART_WORDS = tuple(sorted({w for ws in _ROLES.values() for w in ws} | {"thumb", "fingers"}))


def name_parts(name: str) -> tuple[str | None, str]:
    """``(side, core)`` of a joint name: ``"left"``, ``"right"`` or None, and the rest in
    lower case without separators, namespace or rig prefix.

    ``"mixamorig:LeftUpLeg"`` -> ``("left", "upleg")``, ``"Bip01 L Thigh"`` -> ``("left",
    "thigh")``, ``"UpperArm_R"`` -> ``("right", "upperarm")``, ``"lhand"`` -> ``("left",
    "hand")``, ``"Spine1"`` -> ``(None, "spine")``.
    """
    n = str(name).split(":")[-1].split("|")[-1]
    n = re.sub(r"([a-z0-9])([A-Z])", r"\1 \2", n)  # camelCase -> words
    words = [w for w in re.split(r"[^A-Za-z0-9]+", n.lower()) if w]
    text = _PREFIX.sub("", " ".join(words) + " ").strip()
    words = [w for w in text.split() if not w.isdigit()]
    side = None
    rest = []
    for w in words:
        s = _SIDE_WORDS.get(w)
        if s is None and w.startswith(("left", "right")):
            s, w = ("left", w[4:]) if w.startswith("left") else ("right", w[5:])
        if s is not None and side is None:
            side = s
            if w in ("left", "right", "l", "r", "lft", "rt"):
                continue
        rest.append(w)
    core = re.sub(r"\d+", "", "".join(rest))
    if side is None and len(core) > 1 and core[0] in "lr" and core[1:].startswith(_PART_WORDS):
        side, core = ("left" if core[0] == "l" else "right"), core[1:]
    return side, core


def is_helper(name: str) -> bool:
    """Whether a joint name is a helper bone's: ``CC_Base_L_ThighTwist01``,
    ``upperarm_twist_01_l``, ``CC_Base_L_KneeShareBone``, ``ik_hand_gun``, ... (not a
    joint of the body's own chain, though it may sit on one)."""
    return bool(_HELPER.search(name_parts(name)[1]))


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


class _Tree:
    def __init__(self, names, parents, offsets):
        self.names = list(names)
        self.parents = list(parents)
        self.n = len(self.names)
        self.children = [[] for _ in range(self.n)]
        for j, p in enumerate(self.parents):
            if p >= 0:
                self.children[p].append(j)
        self.bone = np.linalg.norm(np.asarray(offsets, np.float64), axis=-1)  # to the parent
        self.parts = [name_parts(n) for n in self.names]
        self.helper = [bool(_HELPER.search(core)) for _, core in self.parts]
        end = [not self.children[j] and bool(_END.search(self.parts[j][1])) for j in range(self.n)]
        # a body joint below: a joint that is neither a helper nor an end marker
        body_below = [False] * self.n
        for j in reversed(range(self.n)):  # parents precede children in a BVH
            body_below[j] = any(
                body_below[c] or not (self.helper[c] or end[c]) for c in self.children[j]
            )
        # end markers, and helper joints with no body joint below them, are passed over
        # when following chains; a helper on the way to a body joint is part of its bone
        self.skip = [end[j] or (self.helper[j] and not body_below[j]) for j in range(self.n)]
        # longest chain (bone length) from each joint down to a leaf
        self.down = np.zeros(self.n)
        for j in reversed(range(self.n)):  # parents precede children in a BVH
            kids = [c for c in self.children[j] if not self.skip[c]]
            self.down[j] = max((self.bone[c] + self.down[c] for c in kids), default=0.0)
        self.depth = np.zeros(self.n, int)
        for j in range(self.n):
            if self.parents[j] >= 0:
                self.depth[j] = self.depth[self.parents[j]] + 1

    def reach(self, parent: int, child: int) -> float:
        return self.bone[child] + self.down[child]

    def long_children(self, j: int, length: float) -> list[int]:
        return [c for c in self.children[j] if not self.skip[c] and self.reach(j, c) >= length]

    def chain(self, start: int) -> list[int]:
        """``start`` and its descendants along the longest path (end markers dropped)."""
        out = [start]
        while True:
            kids = [c for c in self.children[out[-1]] if not self.skip[c]]
            if not kids:
                return out
            out.append(max(kids, key=lambda c: self.bone[c] + self.down[c]))

    def path(self, a: int, b: int) -> list[int]:
        """Joints from ancestor ``a`` down to ``b``, both included."""
        out = [b]
        while out[-1] != a:
            if self.parents[out[-1]] < 0:
                raise ValueError("not an ancestor")
            out.append(self.parents[out[-1]])
        return out[::-1]

    def long_forks(self, j: int, length: float) -> int:
        """Number of joints in the subtree of ``j`` (itself included) with two or more
        long branches (the chest with the arms; a leg has none)."""
        total, stack = 0, [j]
        while stack:
            k = stack.pop()
            total += len(self.long_children(k, length)) >= 2
            stack += [c for c in self.children[k] if not self.skip[c]]
        return total

    def first_fork(self, start: int, length: float) -> tuple[int | None, float]:
        """Down from ``start`` along single long branches: the first joint with two or
        more long branches and the bone length on the way there (None if none)."""
        j, way = start, 0.0
        while True:
            kids = self.long_children(j, length)
            if len(kids) >= 2:
                return j, way
            if not kids:
                return None, way
            j = kids[0]
            way += self.bone[j]

    def branches(self, j: int) -> int:
        """Number of long branches in the subtree of ``j``."""
        total, stack = 0, [j]
        while stack:
            k = stack.pop()
            kids = [c for c in self.children[k] if not self.skip[c]]
            if len(kids) >= 2:
                total += len(kids) - 1
            stack += kids
        return total


def _alike(tree: _Tree, a: int, b: int, parent: int) -> float:
    """How alike two branches are: 0 for the same length, growing with the ratio."""
    la, lb = tree.reach(parent, a), tree.reach(parent, b)
    return abs(np.log(max(la, 1e-9) / max(lb, 1e-9)))


def _pick_pair(tree: _Tree, kids: list[int], parent: int) -> tuple[int, int]:
    pairs = [(a, b) for i, a in enumerate(kids) for b in kids[i + 1 :]]
    return min(pairs, key=lambda p: _alike(tree, p[0], p[1], parent))


def _limb(
    tree: _Tree, start: int, roles: tuple[str, str, str]
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
        fits = sum(
            any(w in tree.parts[ch[i + r]][1] for w in _ROLES[role]) for r, role in enumerate(roles)
        )
        return (seg[i] + seg[i + 1]) / max(top, 1e-9) + 0.1 * fits

    k = max(range(len(seg) - 1), key=score)
    return ch, k, seg


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


def _torso(
    tree: _Tree, torso: list[int], chest_at: int, P: np.ndarray, hips: list[int], J: np.ndarray
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
    tree = _Tree(names, parents, offsets)
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
    new = _torso(tree, torso, torso.index(chest), P, hips, np.asarray(rest_joints, np.float64))
    for n in ("spine1", "spine2", "spine3", "neck"):
        m.pop(n, None)
    m.update({n: names[j] for n, j in new.items()})
    if m == dict(jmap.mapping):
        return jmap
    order = {n: m[n] for n in JOINT_NAMES if n in m}
    return JointMap(jmap.name, order, jmap.description + " (torso placed by its geometry)")


def _find_pelvis(tree: _Tree, long: float) -> tuple[int, int, tuple[int, int]]:
    """``(pelvis, first joint of the spine, the two legs' first joints)``: the joint
    nearest the root where two legs and a spine part, together (three long branches) or
    split (two long branches: one reaches a joint where the legs part, within half a
    leg's length, the other holds the chest)."""
    for j in sorted(range(tree.n), key=lambda j: tree.depth[j]):
        kids = tree.long_children(j, long)
        if len(kids) >= 3:
            # the spine branches again (the chest); the legs do not
            spine = max(kids, key=lambda c: (tree.long_forks(c, long), tree.branches(c)))
            return j, spine, _pick_pair(tree, [k for k in kids if k != spine], j)
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
    tree = _Tree(names, parents, offsets)
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
            a, b = _pick_pair(tree, longs, j)
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
    for name, j in _torso(tree, torso, torso.index(chest), P, hips, J).items():
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
    agree = [
        any(w in name_parts(src)[1] for w in _ROLES[_ROLE_OF[smpl]])
        for smpl, src in mapping.items()
    ]
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
    from mrlib.io.bvh import BVH, bvh_forward_kinematics, bvh_local_transforms

    sk = bvh.skeleton
    sub = np.unique(np.linspace(0, bvh.num_frames - 1, min(bvh.num_frames, 60)).round().astype(int))
    part = BVH(sk, bvh.motion[sub], bvh.frame_time, source=bvh.source)
    _, P = bvh_forward_kinematics(part)
    local, _ = bvh_local_transforms(part)
    hint = (
        "Pass joint_map={smpl_name: bvh_name, ...} (a dict or a JSON file; `mrlib info "
        "--write-map map.json` writes a start)."
    )
    try:
        match = match_skeleton(sk.names, sk.parents, sk.offsets, P, rest_joints, local)
    except JointMapError as e:
        raise JointMapError(
            bvh.source, f"no joint map fits this skeleton: {e.problem} {hint}"
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
