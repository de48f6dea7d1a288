"""Test skeletons in the conventions users bring: a SMPL motion written onto another rig's
joint names, tree, rest pose, channel order, unit and up axis.

Nothing here is copied from a file of those conventions: each rig is described by which
SMPL joint (or point between two SMPL joints) every one of its joints sits at, and the
BVH is written by mrlib's own writer. The motion drives each rig joint with the global
rotation of the SMPL joint whose body segment it sits on, so the rig's forward kinematics
reproduce the SMPL joints wherever the rig has one.

A rig is a list of ``(name, parent name, anchor)`` rows; ``anchor`` is a SMPL joint name,
``("lerp", a, b, f)`` (the point ``f`` of the way from SMPL joint ``a`` to ``b``, on ``a``'s
segment), or ``("offset", j, (x, y, z))`` (metres from SMPL joint ``j`` in the body's rest
frame, on ``j``'s segment: end markers, fingers, thumbs).

A rig may also have a body of its own (``Rig.geometry``: the rest offsets of another
skeleton, e.g. a CMU subject's; ``Rig.proportions``: body parts scaled, a stylised
character's big head and short legs; ``Rig.arms_down``: an A-pose at rest). Its joints
then keep their bone lengths and rest layout, and its limbs turn as the SMPL motion's do:
a limb bone points, in every frame, where the SMPL bone it sits on points; the root
travels as SMPL's pelvis, scaled with the legs. Such a rig reproduces the motion's joint
angles and foot contacts, not its joint positions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from mrlib.io.axes import UNITS, up_axis_rotation
from mrlib.io.bvh import BVH, BVHSkeleton, matrix_to_euler
from mrlib.representation.body import resolve_body
from mrlib.representation.rotations import axis_angle_to_matrix, kabsch_rotation, rotation_between
from mrlib.representation.skeleton import JOINT_NAMES, NUM_JOINTS, PARENTS

J = {n: i for i, n in enumerate(JOINT_NAMES)}


@dataclass(frozen=True)
class Rig:
    name: str
    joints: tuple  # (name, parent or None, anchor)
    unit: str = "cm"  # "m", "cm", "inch", "cmu"
    up: str = "y"  # the file's up axis
    order: str = "ZXY"  # Euler order of every rotation channel
    rest: str = "tpose"  # "tpose" (joint frames world-aligned at rest) or "bone" (x along the bone)
    # joints with position channels: "root", "all" (Bandai: 6 channels on every joint), or
    # a tuple of joint names
    position_channels: str | tuple = "root"
    # a body of its own (module docstring): (name, (x, y, z)) rest offsets in file units and
    # axes, (group, factor) bone length scales (groups: head, torso, arms, legs), and the
    # arms lowered at rest by this many degrees
    geometry: tuple = ()
    proportions: tuple = ()
    arms_down: float = 0.0
    fps: float | None = None  # written at this frame rate (the motion resampled)


def _sides(rows):
    """Mirror rows written for the left side (``{S}`` / ``{s}`` / ``{LR}`` placeholders)."""
    out = []
    for row in rows:
        if "{" not in str(row):
            out.append(row)
            continue
        for side, short, lr, smpl in (("Left", "L", "l", "left"), ("Right", "R", "r", "right")):

            def fill(x, side=side, short=short, lr=lr, smpl=smpl):
                if isinstance(x, str):
                    return x.format(S=side, s=short, lr=lr, side=smpl)
                if isinstance(x, tuple):
                    return tuple(fill(v) for v in x)
                return x

            out.append(tuple(fill(v) for v in row))
    return out


def _mirror_offsets(rows):
    """Offsets written for the left side flipped in x on the right side."""
    out = []
    for name, parent, anchor in rows:
        if isinstance(anchor, tuple) and anchor[0] == "offset" and anchor[1].startswith("right"):
            x, y, z = anchor[2]
            anchor = ("offset", anchor[1], (-x, y, z))
        out.append((name, parent, anchor))
    return out


def _rig(name, rows, **kw) -> Rig:
    return Rig(name, tuple(_mirror_offsets(_sides(rows))), **kw)


# Bandai Namco's skeleton, the same in both of its datasets (they differ in channels)
BANDAI_ROWS = [
    ("joint_Root", None, ("ground", "pelvis")),
    ("Hips", "joint_Root", "pelvis"),
    ("Spine", "Hips", "spine2"),
    ("Chest", "Spine", "spine3"),
    ("Neck", "Chest", "neck"),
    ("Head", "Neck", "head"),
    ("Shoulder_{s}", "Chest", "{side}_collar"),
    ("UpperArm_{s}", "Shoulder_{s}", "{side}_shoulder"),
    ("LowerArm_{s}", "UpperArm_{s}", "{side}_elbow"),
    ("Hand_{s}", "LowerArm_{s}", "{side}_wrist"),
    ("UpperLeg_{s}", "Hips", "{side}_hip"),
    ("LowerLeg_{s}", "UpperLeg_{s}", "{side}_knee"),
    ("Foot_{s}", "LowerLeg_{s}", "{side}_ankle"),
    ("Toes_{s}", "Foot_{s}", "{side}_foot"),
]

# CMU's 31-joint skeleton (the common BVH conversion): where its joints sit on SMPL
CMU_ROWS = [
    ("Hips", None, "pelvis"),
    ("{lr}hipjoint", "Hips", ("lerp", "pelvis", "{side}_hip", 0.0)),
    ("{S}UpLeg", "{lr}hipjoint", "{side}_hip"),
    ("{S}Leg", "{S}UpLeg", "{side}_knee"),
    ("{S}Foot", "{S}Leg", "{side}_ankle"),
    ("{S}ToeBase", "{S}Foot", "{side}_foot"),
    ("LowerBack", "Hips", ("lerp", "pelvis", "spine1", 0.0)),
    ("Spine", "LowerBack", "spine2"),
    ("Spine1", "Spine", "spine3"),
    ("Neck", "Spine1", ("lerp", "spine3", "neck", 0.5)),
    ("Neck1", "Neck", "neck"),
    ("Head", "Neck1", "head"),
    ("{S}Shoulder", "Spine1", "{side}_collar"),
    ("{S}Arm", "{S}Shoulder", "{side}_shoulder"),
    ("{S}ForeArm", "{S}Arm", "{side}_elbow"),
    ("{S}Hand", "{S}ForeArm", "{side}_wrist"),
    ("{S}FingerBase", "{S}Hand", ("lerp", "{side}_wrist", "{side}_hand", 0.4)),
    ("{S}HandIndex1", "{S}FingerBase", "{side}_hand"),
    ("{s}Thumb", "{S}Hand", ("offset", "{side}_wrist", (0.03, 0.0, 0.03))),
]

# Mixamo: namespaced names, fingers, end joints
MIXAMO_ROWS = [
    ("mixamorig:Hips", None, "pelvis"),
    ("mixamorig:Spine", "mixamorig:Hips", "spine1"),
    ("mixamorig:Spine1", "mixamorig:Spine", "spine2"),
    ("mixamorig:Spine2", "mixamorig:Spine1", "spine3"),
    ("mixamorig:Neck", "mixamorig:Spine2", "neck"),
    ("mixamorig:Head", "mixamorig:Neck", "head"),
    ("mixamorig:HeadTop_End", "mixamorig:Head", ("offset", "head", (0.0, 0.18, 0.0))),
    ("mixamorig:{S}Shoulder", "mixamorig:Spine2", "{side}_collar"),
    ("mixamorig:{S}Arm", "mixamorig:{S}Shoulder", "{side}_shoulder"),
    ("mixamorig:{S}ForeArm", "mixamorig:{S}Arm", "{side}_elbow"),
    ("mixamorig:{S}Hand", "mixamorig:{S}ForeArm", "{side}_wrist"),
    (
        "mixamorig:{S}HandThumb1",
        "mixamorig:{S}Hand",
        ("offset", "{side}_wrist", (0.03, -0.01, 0.03)),
    ),
    (
        "mixamorig:{S}HandThumb2",
        "mixamorig:{S}HandThumb1",
        ("offset", "{side}_wrist", (0.055, -0.01, 0.045)),
    ),
    ("mixamorig:{S}HandIndex1", "mixamorig:{S}Hand", ("offset", "{side}_wrist", (0.1, 0.0, 0.02))),
    (
        "mixamorig:{S}HandIndex2",
        "mixamorig:{S}HandIndex1",
        ("offset", "{side}_wrist", (0.135, 0.0, 0.02)),
    ),
    ("mixamorig:{S}HandMiddle1", "mixamorig:{S}Hand", "{side}_hand"),
    (
        "mixamorig:{S}HandMiddle2",
        "mixamorig:{S}HandMiddle1",
        ("offset", "{side}_hand", (0.04, 0.0, 0.0)),
    ),
    (
        "mixamorig:{S}HandMiddle3",
        "mixamorig:{S}HandMiddle2",
        ("offset", "{side}_hand", (0.07, 0.0, 0.0)),
    ),
    ("mixamorig:{S}UpLeg", "mixamorig:Hips", "{side}_hip"),
    ("mixamorig:{S}Leg", "mixamorig:{S}UpLeg", "{side}_knee"),
    ("mixamorig:{S}Foot", "mixamorig:{S}Leg", "{side}_ankle"),
    ("mixamorig:{S}ToeBase", "mixamorig:{S}Foot", "{side}_foot"),
    ("mixamorig:{S}Toe_End", "mixamorig:{S}ToeBase", ("offset", "{side}_foot", (0.0, 0.0, 0.06))),
]


def _fingers(prefix: str, parent: str, names: tuple[str, ...], joints: int) -> list:
    """Finger chains on the left hand (mirrored by ``_sides``): thumb to little finger,
    ``joints`` per finger, laid out from the wrist along +X."""
    rows = []
    spread = (0.035, 0.02, 0.0, -0.02, -0.038)  # metres along Z, thumb to little finger
    start = (0.025, 0.09, 0.095, 0.09, 0.08)  # metres along X from the wrist
    step = (0.025, 0.035, 0.037, 0.033, 0.025)
    for f, name in enumerate(names):
        up = parent
        for k in range(joints):
            x = start[f] + k * step[f]
            y = -0.012 * (f == 0)
            row = (f"{prefix}{name}{k + 1}", up, ("offset", "{side}_wrist", (x, y, spread[f])))
            rows.append(row)
            up = row[0]
    return rows


CC_ROWS = [
    ("RL_BoneRoot", None, ("ground", "pelvis")),
    ("CC_Base_Hip", "RL_BoneRoot", "pelvis"),
    ("CC_Base_Pelvis", "CC_Base_Hip", ("offset", "pelvis", (0.0, -0.015, 0.0))),
    ("CC_Base_{s}_Thigh", "CC_Base_Pelvis", "{side}_hip"),
    ("CC_Base_{s}_Calf", "CC_Base_{s}_Thigh", "{side}_knee"),
    ("CC_Base_{s}_Foot", "CC_Base_{s}_Calf", "{side}_ankle"),
    ("CC_Base_{s}_ToeBase", "CC_Base_{s}_Foot", "{side}_foot"),
    *[
        (
            f"CC_Base_{{s}}_{toe}Toe1",
            "CC_Base_{s}_ToeBase",
            ("offset", "{side}_foot", (x, -0.01, 0.03)),
        )
        for toe, x in (
            ("Big", -0.02),
            ("Index", -0.005),
            ("Mid", 0.01),
            ("Ring", 0.022),
            ("Pinky", 0.034),
        )
    ],
    ("CC_Base_{s}_ThighTwist01", "CC_Base_{s}_Thigh", ("lerp", "{side}_hip", "{side}_knee", 0.0)),
    (
        "CC_Base_{s}_ThighTwist02",
        "CC_Base_{s}_ThighTwist01",
        ("lerp", "{side}_hip", "{side}_knee", 0.5),
    ),
    ("CC_Base_{s}_CalfTwist01", "CC_Base_{s}_Calf", ("lerp", "{side}_knee", "{side}_ankle", 0.0)),
    (
        "CC_Base_{s}_CalfTwist02",
        "CC_Base_{s}_CalfTwist01",
        ("lerp", "{side}_knee", "{side}_ankle", 0.5),
    ),
    ("CC_Base_{s}_KneeShareBone", "CC_Base_{s}_Calf", ("offset", "{side}_knee", (0.0, 0.0, 0.05))),
    ("CC_Base_Waist", "CC_Base_Hip", ("lerp", "pelvis", "spine1", 0.6)),
    ("CC_Base_Spine01", "CC_Base_Waist", "spine2"),
    ("CC_Base_Spine02", "CC_Base_Spine01", "spine3"),
    ("CC_Base_NeckTwist01", "CC_Base_Spine02", "neck"),
    ("CC_Base_NeckTwist02", "CC_Base_NeckTwist01", ("lerp", "neck", "head", 0.5)),
    ("CC_Base_Head", "CC_Base_NeckTwist02", "head"),
    ("CC_Base_FacialBone", "CC_Base_Head", ("offset", "head", (0.0, 0.02, 0.02))),
    ("CC_Base_JawRoot", "CC_Base_FacialBone", ("offset", "head", (0.0, -0.02, 0.03))),
    ("CC_Base_Tongue01", "CC_Base_JawRoot", ("offset", "head", (0.0, -0.03, 0.05))),
    ("CC_Base_Tongue02", "CC_Base_Tongue01", ("offset", "head", (0.0, -0.03, 0.065))),
    ("CC_Base_Tongue03", "CC_Base_Tongue02", ("offset", "head", (0.0, -0.03, 0.08))),
    ("CC_Base_Teeth02", "CC_Base_JawRoot", ("offset", "head", (0.0, -0.04, 0.085))),
    ("CC_Base_Teeth01", "CC_Base_FacialBone", ("offset", "head", (0.0, -0.01, 0.09))),
    ("CC_Base_UpperJaw", "CC_Base_FacialBone", ("offset", "head", (0.0, 0.0, 0.07))),
    ("CC_Base_{s}_Eye", "CC_Base_FacialBone", ("offset", "head", (0.032, 0.05, 0.08))),
    ("CC_Base_{s}_Clavicle", "CC_Base_Spine02", "{side}_collar"),
    ("CC_Base_{s}_Upperarm", "CC_Base_{s}_Clavicle", "{side}_shoulder"),
    (
        "CC_Base_{s}_UpperarmTwist01",
        "CC_Base_{s}_Upperarm",
        ("lerp", "{side}_shoulder", "{side}_elbow", 0.0),
    ),
    (
        "CC_Base_{s}_UpperarmTwist02",
        "CC_Base_{s}_UpperarmTwist01",
        ("lerp", "{side}_shoulder", "{side}_elbow", 0.5),
    ),
    ("CC_Base_{s}_Forearm", "CC_Base_{s}_Upperarm", "{side}_elbow"),
    (
        "CC_Base_{s}_ForearmTwist01",
        "CC_Base_{s}_Forearm",
        ("lerp", "{side}_elbow", "{side}_wrist", 0.0),
    ),
    (
        "CC_Base_{s}_ForearmTwist02",
        "CC_Base_{s}_ForearmTwist01",
        ("lerp", "{side}_elbow", "{side}_wrist", 0.5),
    ),
    (
        "CC_Base_{s}_ElbowShareBone",
        "CC_Base_{s}_Forearm",
        ("offset", "{side}_elbow", (0.0, 0.0, -0.04)),
    ),
    ("CC_Base_{s}_Hand", "CC_Base_{s}_Forearm", "{side}_wrist"),
    *_fingers("CC_Base_{s}_", "CC_Base_{s}_Hand", ("Thumb", "Index", "Mid", "Ring", "Pinky"), 3),
    ("CC_Base_{s}_RibsTwist", "CC_Base_Spine02", ("offset", "spine3", (0.07, 0.06, 0.06))),
    ("CC_Base_{s}_Breast", "CC_Base_{s}_RibsTwist", ("offset", "spine3", (0.09, 0.04, 0.13))),
]

DAZ_ROWS = [
    ("hip", None, "pelvis"),
    ("pelvis", "hip", ("offset", "pelvis", (0.0, -0.02, 0.0))),
    ("{lr}ThighBend", "pelvis", "{side}_hip"),
    ("{lr}ThighTwist", "{lr}ThighBend", ("lerp", "{side}_hip", "{side}_knee", 0.45)),
    ("{lr}Shin", "{lr}ThighTwist", "{side}_knee"),
    ("{lr}Foot", "{lr}Shin", "{side}_ankle"),
    ("{lr}Metatarsals", "{lr}Foot", ("lerp", "{side}_ankle", "{side}_foot", 0.5)),
    ("{lr}Toe", "{lr}Metatarsals", "{side}_foot"),
    ("abdomenLower", "hip", ("lerp", "pelvis", "spine1", 0.7)),
    ("abdomenUpper", "abdomenLower", "spine2"),
    ("chestLower", "abdomenUpper", "spine3"),
    ("chestUpper", "chestLower", ("lerp", "spine3", "neck", 0.4)),
    ("neckLower", "chestUpper", "neck"),
    ("neckUpper", "neckLower", ("lerp", "neck", "head", 0.5)),
    ("head", "neckUpper", "head"),
    ("{lr}Eye", "head", ("offset", "head", (0.03, 0.05, 0.08))),
    ("{lr}Collar", "chestUpper", "{side}_collar"),
    ("{lr}ShldrBend", "{lr}Collar", "{side}_shoulder"),
    ("{lr}ShldrTwist", "{lr}ShldrBend", ("lerp", "{side}_shoulder", "{side}_elbow", 0.5)),
    ("{lr}ForearmBend", "{lr}ShldrTwist", "{side}_elbow"),
    ("{lr}ForearmTwist", "{lr}ForearmBend", ("lerp", "{side}_elbow", "{side}_wrist", 0.5)),
    ("{lr}Hand", "{lr}ForearmTwist", "{side}_wrist"),
    *_fingers("{lr}", "{lr}Hand", ("Thumb", "Index", "Mid", "Ring", "Pinky"), 3),
]

UNREAL_ROWS = [
    ("root", None, ("ground", "pelvis")),
    ("pelvis", "root", "pelvis"),
    ("spine_01", "pelvis", "spine1"),
    ("spine_02", "spine_01", "spine2"),
    ("spine_03", "spine_02", "spine3"),
    ("neck_01", "spine_03", "neck"),
    ("head", "neck_01", "head"),
    ("clavicle_{lr}", "spine_03", "{side}_collar"),
    ("upperarm_{lr}", "clavicle_{lr}", "{side}_shoulder"),
    ("lowerarm_{lr}", "upperarm_{lr}", "{side}_elbow"),
    ("hand_{lr}", "lowerarm_{lr}", "{side}_wrist"),
    ("upperarm_twist_01_{lr}", "upperarm_{lr}", ("lerp", "{side}_shoulder", "{side}_elbow", 0.5)),
    ("lowerarm_twist_01_{lr}", "lowerarm_{lr}", ("lerp", "{side}_elbow", "{side}_wrist", 0.6)),
    ("thigh_{lr}", "pelvis", "{side}_hip"),
    ("calf_{lr}", "thigh_{lr}", "{side}_knee"),
    ("foot_{lr}", "calf_{lr}", "{side}_ankle"),
    ("ball_{lr}", "foot_{lr}", "{side}_foot"),
    ("thigh_twist_01_{lr}", "thigh_{lr}", ("lerp", "{side}_hip", "{side}_knee", 0.5)),
    ("calf_twist_01_{lr}", "calf_{lr}", ("lerp", "{side}_knee", "{side}_ankle", 0.5)),
    ("ik_foot_root", "root", ("ground", "pelvis")),
    ("ik_foot_{lr}", "ik_foot_root", ("offset", "{side}_ankle", (0.0, 0.0, 0.0))),
    ("ik_hand_root", "root", ("ground", "pelvis")),
    ("ik_hand_gun", "ik_hand_root", ("offset", "right_wrist", (0.0, 0.0, 0.0))),
    ("ik_hand_{lr}", "ik_hand_gun", ("offset", "{side}_wrist", (0.0, 0.0, 0.0))),
]

BIPED_PELVIS_ROWS = [
    ("Bip001", None, "pelvis"),
    ("Bip001 Footsteps", "Bip001", ("ground", "pelvis")),
    ("Bip001 Pelvis", "Bip001", "pelvis"),
    ("Bip001 {s} Thigh", "Bip001 Pelvis", "{side}_hip"),
    ("Bip001 {s} Calf", "Bip001 {s} Thigh", "{side}_knee"),
    ("Bip001 {s} Foot", "Bip001 {s} Calf", "{side}_ankle"),
    ("Bip001 {s} Toe0", "Bip001 {s} Foot", "{side}_foot"),
    ("Bip001 Spine", "Bip001 Pelvis", ("lerp", "pelvis", "spine1", 0.5)),
    ("Bip001 Spine1", "Bip001 Spine", "spine2"),
    ("Bip001 Spine2", "Bip001 Spine1", "spine3"),
    ("Bip001 Neck", "Bip001 Spine2", "neck"),
    ("Bip001 Head", "Bip001 Neck", "head"),
    ("Bip001 Ponytail1", "Bip001 Head", ("offset", "head", (0.0, 0.05, -0.1))),
    ("Bip001 {s} Clavicle", "Bip001 Neck", "{side}_collar"),
    ("Bip001 {s} UpperArm", "Bip001 {s} Clavicle", "{side}_shoulder"),
    ("Bip001 {s} Forearm", "Bip001 {s} UpperArm", "{side}_elbow"),
    ("Bip001 {s} Hand", "Bip001 {s} Forearm", "{side}_wrist"),
    ("Bip001 {s} Finger0", "Bip001 {s} Hand", ("offset", "{side}_wrist", (0.03, -0.01, 0.03))),
    ("Bip001 {s} Finger2", "Bip001 {s} Hand", "{side}_hand"),
]

# Rest offsets (file units, Y up, T-pose) of two motion-capture subjects on CMU's skeleton
CMU_GEOMETRY = (
    ("lhipjoint", (0.0, 0.0, 0.0)), ("LeftUpLeg", (1.65, -1.80, 0.80)),
    ("LeftLeg", (2.50, -6.87, 0.0)), ("LeftFoot", (2.54, -6.98, 0.0)),
    ("LeftToeBase", (0.16, -0.44, 1.99)), ("rhipjoint", (0.0, 0.0, 0.0)),
    ("RightUpLeg", (-1.61, -1.80, 0.80)), ("RightLeg", (-2.44, -6.70, 0.0)),
    ("RightFoot", (-2.44, -6.70, 0.0)), ("RightToeBase", (-0.21, -0.57, 2.02)),
    ("LowerBack", (0.0, 0.0, 0.0)), ("Spine", (-0.02, 2.24, -0.04)),
    ("Spine1", (0.05, 2.19, -0.19)), ("Neck", (0.0, 0.0, 0.0)),
    ("Neck1", (-0.12, 1.43, 0.28)), ("Head", (0.18, 1.46, -0.33)),
    ("LeftShoulder", (0.0, 0.0, 0.0)), ("LeftArm", (3.28, 0.86, 0.05)),
    ("LeftForeArm", (4.97, 0.0, 0.0)), ("LeftHand", (3.36, 0.0, 0.0)),
    ("LeftFingerBase", (0.0, 0.0, 0.0)), ("LeftHandIndex1", (0.80, 0.0, 0.0)),
    ("LThumb", (0.0, 0.0, 0.0)), ("RightShoulder", (0.0, 0.0, 0.0)),
    ("RightArm", (-3.24, 1.02, 0.35)), ("RightForeArm", (-5.22, 0.0, 0.0)),
    ("RightHand", (-3.37, 0.0, 0.0)), ("RightFingerBase", (0.0, 0.0, 0.0)),
    ("RightHandIndex1", (-0.62, 0.0, 0.0)), ("RThumb", (0.0, 0.0, 0.0)),
)  # fmt: skip
XIA_GEOMETRY = (
    ("lhipjoint", (0.0, 0.0, 0.0)), ("LeftUpLeg", (1.36, -1.79, 0.84)),
    ("LeftLeg", (2.45, -6.73, 0.0)), ("LeftFoot", (2.56, -7.04, 0.0)),
    ("LeftToeBase", (0.16, -0.43, 2.32)), ("rhipjoint", (0.0, 0.0, 0.0)),
    ("RightUpLeg", (-1.31, -1.79, 0.84)), ("RightLeg", (-2.54, -6.99, 0.0)),
    ("RightFoot", (-2.57, -7.06, 0.0)), ("RightToeBase", (-0.16, -0.45, 2.36)),
    ("LowerBack", (0.0, 0.0, 0.0)), ("Spine", (0.03, 2.04, -0.19)),
    ("Spine1", (0.06, 2.05, -0.04)), ("Neck", (0.0, 0.0, 0.0)),
    ("Neck1", (-0.05, 1.75, 0.17)), ("Head", (0.10, 1.76, -0.12)),
    ("LeftShoulder", (0.0, 0.0, 0.0)), ("LeftArm", (3.36, 1.20, -0.31)),
    ("LeftForeArm", (4.98, 0.0, 0.0)), ("LeftHand", (3.48, 0.0, 0.0)),
    ("LeftFingerBase", (0.0, 0.0, 0.0)), ("LeftHandIndex1", (0.72, 0.0, 0.0)),
    ("LThumb", (0.0, 0.0, 0.0)), ("RightShoulder", (0.0, 0.0, 0.0)),
    ("RightArm", (-3.14, 1.37, -0.40)), ("RightForeArm", (-5.24, 0.0, 0.0)),
    ("RightHand", (-3.44, 0.0, 0.0)), ("RightFingerBase", (0.0, 0.0, 0.0)),
    ("RightHandIndex1", (-0.62, 0.0, 0.0)), ("RThumb", (0.0, 0.0, 0.0)),
)  # fmt: skip

RIGS: dict[str, Rig] = {
    # Bandai Namco Research Motion Dataset 1: 6 channels on every joint, bone-aligned frames
    "bandai_namco_1": _rig("bandai_namco_1", BANDAI_ROWS, rest="bone", position_channels="all"),
    # dataset 2: rotations only below the hips, another Euler order
    "bandai_namco_2": _rig(
        "bandai_namco_2", BANDAI_ROWS, rest="bone", order="YXZ", position_channels=("Hips",)
    ),
    # CMU, the common BVH conversion (31 joints, units of 1/0.45 inch)
    "cmu": _rig("cmu", CMU_ROWS, unit="cmu"),
    # CMU, the other widely mirrored conversion: other names, "LeftShoulder" is the upper arm
    "cmu_daz": _rig(
        "cmu_daz",
        [
            ("Hips", None, "pelvis"),
            ("{s}HipJoint", "Hips", ("lerp", "pelvis", "{side}_hip", 0.0)),
            ("{S}Hip", "{s}HipJoint", "{side}_hip"),
            ("{S}Knee", "{S}Hip", "{side}_knee"),
            ("{S}Ankle", "{S}Knee", "{side}_ankle"),
            ("{S}Toe", "{S}Ankle", "{side}_foot"),
            ("lowerback", "Hips", ("lerp", "pelvis", "spine1", 0.0)),
            ("Chest", "lowerback", "spine2"),
            ("Chest2", "Chest", "spine3"),
            ("lowerneck", "Chest2", ("lerp", "spine3", "neck", 0.5)),
            ("Neck", "lowerneck", "neck"),
            ("Head", "Neck", "head"),
            ("{S}Collar", "Chest2", "{side}_collar"),
            ("{S}Shoulder", "{S}Collar", "{side}_shoulder"),
            ("{S}Elbow", "{S}Shoulder", "{side}_elbow"),
            ("{S}Wrist", "{S}Elbow", "{side}_wrist"),
            ("{lr}hand", "{S}Wrist", ("lerp", "{side}_wrist", "{side}_hand", 0.4)),
            ("{s}Fingers", "{lr}hand", "{side}_hand"),
            ("{s}Thumb", "{S}Wrist", ("offset", "{side}_wrist", (0.03, 0.0, 0.03))),
        ],
        order="XYZ",
        up="z",
    ),
    # Mixamo: namespaced names, fingers, end joints
    "mixamo": _rig("mixamo", MIXAMO_ROWS),
    # Ubisoft LaFAN1: 22 joints, bone-aligned rest pose, ZYX channels
    "lafan1": _rig(
        "lafan1",
        [
            ("Hips", None, "pelvis"),
            ("{S}UpLeg", "Hips", "{side}_hip"),
            ("{S}Leg", "{S}UpLeg", "{side}_knee"),
            ("{S}Foot", "{S}Leg", "{side}_ankle"),
            ("{S}Toe", "{S}Foot", "{side}_foot"),
            ("Spine", "Hips", "spine1"),
            ("Spine1", "Spine", "spine2"),
            ("Spine2", "Spine1", "spine3"),
            ("Neck", "Spine2", "neck"),
            ("Head", "Neck", "head"),
            ("{S}Shoulder", "Spine2", "{side}_collar"),
            ("{S}Arm", "{S}Shoulder", "{side}_shoulder"),
            ("{S}ForeArm", "{S}Arm", "{side}_elbow"),
            ("{S}Hand", "{S}ForeArm", "{side}_wrist"),
        ],
        order="ZYX",
        rest="bone",
    ),
    # 3ds Max Biped: "Bip01 L Thigh", clavicles under the neck, thighs under the spine,
    # Z up, inches
    "biped": _rig(
        "biped",
        [
            ("Bip01", None, "pelvis"),
            ("Bip01 Pelvis", "Bip01", "pelvis"),
            ("Bip01 Spine", "Bip01 Pelvis", ("lerp", "pelvis", "spine1", 0.5)),
            ("Bip01 {s} Thigh", "Bip01 Spine", "{side}_hip"),
            ("Bip01 {s} Calf", "Bip01 {s} Thigh", "{side}_knee"),
            ("Bip01 {s} Foot", "Bip01 {s} Calf", "{side}_ankle"),
            ("Bip01 {s} Toe0", "Bip01 {s} Foot", "{side}_foot"),
            ("Bip01 {s} Toe0Nub", "Bip01 {s} Toe0", ("offset", "{side}_foot", (0.0, 0.0, 0.05))),
            ("Bip01 Spine1", "Bip01 Spine", "spine2"),
            ("Bip01 Spine2", "Bip01 Spine1", "spine3"),
            ("Bip01 Neck", "Bip01 Spine2", "neck"),
            ("Bip01 Head", "Bip01 Neck", "head"),
            ("Bip01 HeadNub", "Bip01 Head", ("offset", "head", (0.0, 0.17, 0.0))),
            ("Bip01 {s} Clavicle", "Bip01 Neck", "{side}_collar"),
            ("Bip01 {s} UpperArm", "Bip01 {s} Clavicle", "{side}_shoulder"),
            ("Bip01 {s} Forearm", "Bip01 {s} UpperArm", "{side}_elbow"),
            ("Bip01 {s} Hand", "Bip01 {s} Forearm", "{side}_wrist"),
            (
                "Bip01 {s} Finger0",
                "Bip01 {s} Hand",
                ("offset", "{side}_wrist", (0.03, -0.01, 0.03)),
            ),
            ("Bip01 {s} Finger2", "Bip01 {s} Hand", "{side}_hand"),
            (
                "Bip01 {s} Finger2Nub",
                "Bip01 {s} Finger2",
                ("offset", "{side}_hand", (0.07, 0.0, 0.0)),
            ),
        ],
        unit="inch",
        up="z",
        order="ZXY",
    ),
    # a generic game rig: Left/Right + UpperArm/LowerArm, two spine joints, metres, XYZ
    "generic": _rig(
        "generic",
        [
            ("Hips", None, "pelvis"),
            ("Spine", "Hips", ("lerp", "pelvis", "spine2", 0.6)),
            ("Chest", "Spine", "spine3"),
            ("Neck", "Chest", "neck"),
            ("Head", "Neck", "head"),
            ("{S}Shoulder", "Chest", "{side}_collar"),
            ("{S}UpperArm", "{S}Shoulder", "{side}_shoulder"),
            ("{S}LowerArm", "{S}UpperArm", "{side}_elbow"),
            ("{S}Hand", "{S}LowerArm", "{side}_wrist"),
            ("{S}UpperLeg", "Hips", "{side}_hip"),
            ("{S}LowerLeg", "{S}UpperLeg", "{side}_knee"),
            ("{S}Foot", "{S}LowerLeg", "{side}_ankle"),
            ("{S}Toes", "{S}Foot", "{side}_foot"),
        ],
        unit="m",
        order="XYZ",
    ),
    # Reallusion Character Creator / iClone: a root on the ground, a split hip (Hip ->
    # Pelvis for the legs, Hip -> Waist for the spine), twist and share bones on every
    # limb, two neck twist bones on the way to the head, toes, fingers, face, 98 joints
    "character_creator": _rig(
        "character_creator", CC_ROWS, rest="bone", position_channels=("CC_Base_Hip",)
    ),
    # DAZ Genesis: a split hip, bend and twist bones *on* the limb chains, Y up, cm
    "daz_genesis": _rig("daz_genesis", DAZ_ROWS, order="ZYX"),
    # Unreal's mannequin: a root on the ground with IK target chains beside the pelvis,
    # twist leaves, Z up, bone-aligned frames
    "unreal": _rig(
        "unreal", UNREAL_ROWS, up="z", rest="bone", order="XYZ", position_channels=("pelvis",)
    ),
    # 3ds Max Biped, the other layout: thighs under the pelvis, a footsteps node at the root
    "biped_pelvis": _rig("biped_pelvis", BIPED_PELVIS_ROWS, unit="inch", up="z"),
}

# Mixamo's rig with a stylised character's proportions (the motion's joint angles, not
# its joint positions: SMPL's shape space cannot reach them)
STYLISED = _rig(
    "stylised",
    MIXAMO_ROWS,
    proportions=(("head", 1.6), ("legs", 0.7), ("arms", 1.2), ("torso", 1.3)),
)

# Motion-capture skeletons with their own subjects' bone lengths, at 120 fps: CMU's
# (offsets of the common conversion, as in tests/test_retarget.py) and the 31-joint
# skeleton of Xia et al.'s style dataset (CMU's names and layout, another subject;
# offsets rounded to 0.01). Their rest layout is CMU's, their motion SMPL's.
MOCAP: dict[str, Rig] = {
    "cmu_mocap": _rig("cmu_mocap", CMU_ROWS, unit="cmu", geometry=CMU_GEOMETRY, fps=120.0),
    "xia_mocap": _rig("xia_mocap", CMU_ROWS, unit="cmu", geometry=XIA_GEOMETRY, fps=120.0),
}

# Not humanoid: a four-legged animal (the matcher must refuse it).
QUADRUPED = Rig(
    "quadruped",
    (
        ("Root", None, "pelvis"),
        ("Tail", "Root", ("offset", "pelvis", (0.0, 0.0, -0.3))),
        ("HindLeg_L", "Root", ("offset", "pelvis", (0.1, -0.1, 0.0))),
        ("HindKnee_L", "HindLeg_L", ("offset", "pelvis", (0.1, -0.35, 0.0))),
        ("HindPaw_L", "HindKnee_L", ("offset", "pelvis", (0.1, -0.6, 0.0))),
        ("HindLeg_R", "Root", ("offset", "pelvis", (-0.1, -0.1, 0.0))),
        ("HindKnee_R", "HindLeg_R", ("offset", "pelvis", (-0.1, -0.35, 0.0))),
        ("HindPaw_R", "HindKnee_R", ("offset", "pelvis", (-0.1, -0.6, 0.0))),
        ("Spine", "Root", ("offset", "pelvis", (0.0, 0.0, 0.3))),
        ("Chest", "Spine", ("offset", "pelvis", (0.0, 0.0, 0.6))),
        ("Neck", "Chest", ("offset", "pelvis", (0.0, 0.1, 0.75))),
        ("Head", "Neck", ("offset", "pelvis", (0.0, 0.15, 0.9))),
        ("FrontLeg_L", "Chest", ("offset", "pelvis", (0.1, -0.1, 0.6))),
        ("FrontKnee_L", "FrontLeg_L", ("offset", "pelvis", (0.1, -0.35, 0.6))),
        ("FrontPaw_L", "FrontKnee_L", ("offset", "pelvis", (0.1, -0.6, 0.6))),
        ("FrontLeg_R", "Chest", ("offset", "pelvis", (-0.1, -0.1, 0.6))),
        ("FrontKnee_R", "FrontLeg_R", ("offset", "pelvis", (-0.1, -0.35, 0.6))),
        ("FrontPaw_R", "FrontKnee_R", ("offset", "pelvis", (-0.1, -0.6, 0.6))),
    ),
)


def _anchor_point(anchor, Jr: np.ndarray) -> tuple[np.ndarray, int]:
    """Rest position (metres, mrlib frame) of an anchor and the SMPL joint that drives it."""
    if isinstance(anchor, str):
        return Jr[J[anchor]], J[anchor]
    kind = anchor[0]
    if kind == "lerp":
        a, b, f = J[anchor[1]], J[anchor[2]], anchor[3]
        return (1 - f) * Jr[a] + f * Jr[b], a
    if kind == "offset":
        j = J[anchor[1]]
        return Jr[j] + np.asarray(anchor[2], np.float64), j
    if kind == "ground":
        j = J[anchor[1]]
        return np.array([Jr[j, 0], 0.0, Jr[j, 2]]), -1
    raise ValueError(anchor)


def _bone_frame(direction: np.ndarray) -> np.ndarray:
    """A rotation whose x axis is ``direction`` (a bone-aligned joint frame)."""
    x = direction / max(np.linalg.norm(direction), 1e-9)
    helper = np.array([0.0, 0.0, 1.0]) if abs(x[2]) < 0.9 else np.array([0.0, 1.0, 0.0])
    z = np.cross(x, helper)
    z /= np.linalg.norm(z)
    y = np.cross(z, x)
    return np.stack([x, y, z], 1)


GROUPS = ("head", "torso", "arms", "legs")  # the body parts Rig.proportions scales
_GROUP = {
    **{n: "legs" for n in JOINT_NAMES if n.endswith(("_hip", "_knee", "_ankle", "_foot"))},
    **{n: "arms" for n in JOINT_NAMES if n.endswith(("_shoulder", "_elbow", "_wrist", "_hand"))},
    **{n: "head" for n in ("neck", "head")},
}
# joints whose rest layout is a convention of the rig (a limb's rest direction): turned to
# follow SMPL's bone; the others (pelvis, spine, head) keep the rig's anatomy
_LIMB_DRIVERS = {J[n] for n in JOINT_NAMES if n.endswith(("_collar",)) or n in _GROUP} - {
    J["neck"],
    J["head"],
}


def _reshape(rig: Rig, rest: np.ndarray, driver, parents, names, A: np.ndarray):
    """A rig's own rest points ``(Jrig, 3)`` (metres, mrlib's frame) and, per joint, the
    rotation ``Q`` turning its rest bones onto the SMPL bones they sit on (limbs only)."""
    k = UNITS[rig.unit]
    out = rest.copy()
    scale = dict(rig.proportions)
    geometry = dict(rig.geometry)
    for i, p in enumerate(parents):
        if p < 0:
            continue
        if names[i] in geometry:
            out[i] = out[p] + A @ np.asarray(geometry[names[i]], np.float64) * k
            continue
        # a bone belongs to its parent's body part; a bone ending at a hip to the legs
        d = driver[i] if driver[i] >= 0 and JOINT_NAMES[driver[i]].endswith("_hip") else driver[p]
        f = scale.get(_GROUP.get(JOINT_NAMES[d], "torso"), 1.0) if d >= 0 else 1.0
        out[i] = out[p] + f * (rest[i] - rest[p])
    if rig.arms_down:
        for i, p in enumerate(parents):
            d, dp = driver[i], driver[p] if p >= 0 else -1
            if d < 0 or not JOINT_NAMES[d].endswith("_shoulder") or dp == d:
                continue
            sign = -1.0 if out[i, 0] > 0 else 1.0  # left arm (+X) turns down about -Z
            a = np.deg2rad(rig.arms_down) * sign
            R = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
            below = [i]
            for c in range(i + 1, len(parents)):
                if parents[c] in below:
                    below.append(c)
            out[below[1:]] = (out[below[1:]] - out[i]) @ R.T + out[i]
    Q = np.broadcast_to(np.eye(3), (len(names), 3, 3)).copy()
    for i in range(len(names)):
        if driver[i] not in _LIMB_DRIVERS:
            continue
        kids = [c for c, p in enumerate(parents) if p == i]
        H = np.zeros((3, 3))
        for c in kids:
            u, v = out[c] - out[i], rest[c] - rest[i]
            if np.linalg.norm(u) > 1e-6 and np.linalg.norm(v) > 1e-6:
                H += np.outer(u / np.linalg.norm(u), v / np.linalg.norm(v))
        if not H.any():
            Q[i] = Q[parents[i]] if parents[i] >= 0 else np.eye(3)
        elif np.linalg.matrix_rank(H, tol=1e-6) >= 2:
            Q[i] = kabsch_rotation(H)
        else:
            u, v = np.linalg.svd(H)[0][:, 0], np.linalg.svd(H)[2][0]
            Q[i] = rotation_between(u, v)
    return out, Q


def write_rig(motion, rig: Rig, body=None) -> BVH:
    """``motion`` (a ``mrlib.Motion``) on ``rig``: a BVH in the rig's conventions."""
    body = resolve_body(body, shared=True)
    if rig.fps is not None and rig.fps != motion.fps:
        motion = motion.resample(rig.fps)
    betas = torch.as_tensor(np.asarray(motion.betas, np.float32))[None]
    Jr = body.rest_joints(betas)[0].double().numpy()  # (24, 3) rest, metres
    R = axis_angle_to_matrix(torch.from_numpy(motion.poses.astype(np.float64))).numpy()
    T = motion.num_frames
    G = np.empty_like(R)  # SMPL global rotations
    pos = np.empty((T, NUM_JOINTS, 3))
    for j in range(NUM_JOINTS):
        p = PARENTS[j]
        G[:, j] = R[:, j] if p < 0 else G[:, p] @ R[:, j]
        pos[:, j] = Jr[j] + motion.trans if p < 0 else pos[:, p] + G[:, p] @ (Jr[j] - Jr[p])
    names = [row[0] for row in rig.joints]
    parents = [-1 if row[1] is None else names.index(row[1]) for row in rig.joints]
    rest, driver = zip(*(_anchor_point(row[2], Jr) for row in rig.joints), strict=True)
    rest = np.stack(rest)
    A = up_axis_rotation(rig.up)  # file world -> mrlib world
    k = 1.0 / UNITS[rig.unit]  # file units per metre
    reshaped = bool(rig.geometry or rig.proportions or rig.arms_down)
    Q = np.broadcast_to(np.eye(3), (len(names), 3, 3))
    if reshaped:
        if rig.position_channels != "root" or driver[0] < 0:
            raise ValueError("a rig with a body of its own needs a root on the pelvis")
        anchors = rest
        rest, Q = _reshape(rig, anchors, driver, parents, names, A)
        # the root travels as the pelvis, scaled with the legs; the feet keep their height
        feet = [i for i, d in enumerate(driver) if d >= 0 and JOINT_NAMES[d].endswith("_ankle")]
        legs = dict(rig.proportions).get("legs", 1.0)
        lift = legs * (anchors[feet, 1].min() - anchors[0, 1]) - (rest[feet, 1].min() - rest[0, 1])
    children = {i: [c for c, p in enumerate(parents) if p == i] for i in range(len(names))}
    # rest orientation of every joint frame, in mrlib's world
    O = np.empty((len(names), 3, 3))
    for i in range(len(names)):
        if rig.rest == "tpose":
            O[i] = A
        else:
            kids = [c for c in children[i] if np.linalg.norm(rest[c] - rest[i]) > 1e-6]
            if kids:
                O[i] = _bone_frame(rest[kids[0]] - rest[i])
            else:  # a leaf, or only zero-length bones below (twist bones at their joint)
                O[i] = O[parents[i]] if parents[i] >= 0 else np.eye(3)
    offsets = np.zeros((len(names), 3))
    for i, p in enumerate(parents):
        if p >= 0:
            offsets[i] = O[p].T @ (rest[i] - rest[p]) * k
        else:
            offsets[i] = A.T @ rest[i] * k
    # motion: the global rotation of a rig joint is its driver's times its rest frame, its
    # position its anchor point carried by the driver
    eye = np.broadcast_to(np.eye(3), (T, 3, 3))
    Gd = np.stack([eye if d < 0 else G[:, d] for d in driver], 1)  # (T, Jrig, 3, 3)
    Rw = Gd @ (Q @ O)[None]  # joint frame -> mrlib world
    at = np.stack(
        [
            np.broadcast_to(rest[i], (T, 3)) if d < 0 else pos[:, d] + G[:, d] @ (rest[i] - Jr[d])
            for i, d in enumerate(driver)
        ],
        1,
    )  # (T, Jrig, 3) metres, mrlib world
    if reshaped:
        at[:, 0] = legs * at[:, 0] + np.array([0.0, lift, 0.0])
    local = np.empty_like(Rw)
    for i, p in enumerate(parents):
        local[:, i] = (A.T @ Rw[:, i]) if p < 0 else np.swapaxes(Rw[:, p], -1, -2) @ Rw[:, i]
    euler = matrix_to_euler(local, rig.order)  # (T, Jrig, 3)
    rot_ch = tuple(f"{a}rotation" for a in rig.order)
    pos_ch = ("Xposition", "Yposition", "Zposition")
    channels, cols = [], []
    for i, p in enumerate(parents):
        pc = rig.position_channels
        has_pos = p < 0 or pc == "all" or (isinstance(pc, tuple) and names[i] in pc)
        channels.append((pos_ch + rot_ch) if has_pos else rot_ch)
        if has_pos:
            if p < 0:
                cols.append((at[:, i] @ A) * k)  # world -> file axes (A^T x, row-wise)
            else:  # in the parent's frame: the offset, or a translation under a static root
                rel = at[:, i] - at[:, p]
                cols.append(np.einsum("tji,tj->ti", Rw[:, p], rel) * k)
        cols.append(euler[:, i])
    ends = []
    for i in range(len(names)):
        if not children[i]:
            ends.append((i, np.array([0.0, 0.0, 0.0]) if rig.rest == "bone" else np.zeros(3)))
    sk = BVHSkeleton(
        names=tuple(names),
        parents=tuple(parents),
        offsets=offsets,
        channels=tuple(channels),
        end_sites=tuple(ends),
    )
    return BVH(sk, np.concatenate(cols, 1), 1.0 / motion.fps, source=f"{rig.name} rig")


def rig_joint_positions(motion, rig: Rig, body=None) -> dict[str, np.ndarray]:
    """Where each rig joint should be, ``{name: (T, 3)}`` metres in mrlib's world."""
    from mrlib.io.bvh import bvh_forward_kinematics

    bvh = write_rig(motion, rig, body)
    _, P = bvh_forward_kinematics(bvh)
    P = P * UNITS[rig.unit] @ up_axis_rotation(rig.up).T
    return {n: P[:, i] for i, n in enumerate(bvh.skeleton.names)}


# ----------------------------------------------------------------------------------------
# Fidelity of a transfer: joint angles and foot contacts
# ----------------------------------------------------------------------------------------
LIMB_JOINTS = tuple(
    J[f"{s}_{j}"]
    for s in ("left", "right")
    for j in ("hip", "knee", "ankle", "shoulder", "elbow", "wrist")
)
_FEET = tuple(J[f"{s}_{j}"] for s in ("left", "right") for j in ("ankle", "foot"))


def limb_angle_error(a, b) -> np.ndarray:
    """``(T, 12)`` angle (degrees) between the local rotations of the limb joints (hips,
    knees, ankles, shoulders, elbows, wrists) of two motions of the same length."""
    Ra = axis_angle_to_matrix(torch.from_numpy(a.poses[:, list(LIMB_JOINTS)]).double())
    Rb = axis_angle_to_matrix(torch.from_numpy(b.poses[:, list(LIMB_JOINTS)]).double())
    cos = ((Ra.transpose(-1, -2) @ Rb).diagonal(dim1=-2, dim2=-1).sum(-1) - 1) / 2
    return np.degrees(np.arccos(np.clip(cos.numpy(), -1.0, 1.0)))


def joint_contacts(P: np.ndarray, fps: float, threshold: float = 0.3) -> np.ndarray:
    """``(T, 4)`` foot contacts (left ankle, left toe, right ankle, right toe) of SMPL-ordered
    joints ``P (T, 24, 3)``: the joint moves slower than ``threshold`` leg lengths per
    second (0.3: SMPL's 0.25 m/s), whatever the body's size."""
    leg = np.mean(
        [
            np.median(
                np.linalg.norm(P[:, J[f"{s}_hip"]] - P[:, J[f"{s}_knee"]], axis=-1)
                + np.linalg.norm(P[:, J[f"{s}_knee"]] - P[:, J[f"{s}_ankle"]], axis=-1)
            )
            for s in ("left", "right")
        ]
    )
    speed = np.linalg.norm(np.gradient(P[:, list(_FEET)], axis=0), axis=-1) * fps / leg
    return speed < threshold


def rig_smpl_joints(bvh: BVH, rig: Rig, joint_map) -> np.ndarray:
    """``(T, 24, 3)`` the rig's joints that ``joint_map`` maps onto SMPL (metres, mrlib's
    frame; unmapped SMPL joints take the rig's root)."""
    from mrlib.io.bvh import bvh_forward_kinematics

    _, P = bvh_forward_kinematics(bvh)
    P = P * UNITS[rig.unit] @ up_axis_rotation(rig.up).T
    return P[:, np.maximum(joint_map.source_indices(bvh.skeleton.names), 0)]


def contact_timing(ref: np.ndarray, test: np.ndarray, frames: int = 1) -> tuple[float, int]:
    """Share of the contacts of ``ref (T, C)`` (runs of True on a channel) that ``test``
    has too, starting and ending within ``frames`` frames; and the number of contacts."""

    def runs(c):
        out = []
        for ch in range(c.shape[1]):
            d = np.diff(np.concatenate([[0], c[:, ch].astype(int), [0]]))
            out += [
                (ch, a, b)
                for a, b in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1), strict=True)
            ]
        return out

    got = runs(test)
    want = runs(ref)
    hit = sum(
        any(c == ch and abs(a - a2) <= frames and abs(b - b2) <= frames for c, a2, b2 in got)
        for ch, a, b in want
    )
    return hit / max(len(want), 1), len(want)
