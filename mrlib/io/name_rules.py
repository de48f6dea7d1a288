"""The name rules of skeleton recognition (``mrlib.io.recognize``): what a joint's name
says whatever the rig's naming scheme - its side and its core (``name_parts``), whether it
is a helper bone (``is_helper``) or an end marker (``is_end_marker``), and whether it
fits a role on the body (``fits_role``, ``name_fits_joint``).

End markers are leaf joints named ``end``, ``top``, ``nub``, ``tip``, ``site``, ``effector``;
helper joints are ``twist``, ``roll``, ``share`` bones and ``ik`` and ``ctrl`` targets
(matched on the core of the name). Sides come from ``Left``, ``L``, ``_l``, ``.L``, ...
"""

from __future__ import annotations

import re

__all__ = [
    "name_parts",
    "is_helper",
    "is_helper_core",
    "is_end_marker",
    "fits_role",
    "name_fits_joint",
]

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
    return is_helper_core(name_parts(name)[1])


def is_helper_core(core: str) -> bool:
    """Whether the core of a name (``name_parts(name)[1]``) is a helper bone's."""
    return bool(_HELPER.search(core))


def is_end_marker(core: str) -> bool:
    """Whether the core of a leaf joint's name marks an end (``"headtop"``, ``"end"``,
    ``"handnub"``): a point, not a body joint."""
    return bool(_END.search(core))


def fits_role(core: str, role: str) -> bool:
    """Whether the core of a name holds a word of ``role`` (``"hip"``, ``"knee"``,
    ``"wrist"``, ...; the keys of the role table)."""
    return any(w in core for w in _ROLES[role])


def name_fits_joint(name: str, smpl_joint: str) -> bool:
    """Whether a source joint's ``name`` fits the role of the SMPL joint it is mapped to
    (``"LeftUpLeg"`` for ``"left_hip"``)."""
    return fits_role(name_parts(name)[1], _ROLE_OF[smpl_joint])
