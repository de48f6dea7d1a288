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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from mrlib.body import resolve_body
from mrlib.io.bvh import BVH, BVHSkeleton, matrix_to_euler
from mrlib.io.retarget import UNITS, up_axis_rotation
from mrlib.rotations import axis_angle_to_matrix
from mrlib.skeleton import JOINT_NAMES, NUM_JOINTS, PARENTS

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

RIGS: dict[str, Rig] = {
    # Bandai Namco Research Motion Dataset 1: 6 channels on every joint, bone-aligned frames
    "bandai_namco_1": _rig("bandai_namco_1", BANDAI_ROWS, rest="bone", position_channels="all"),
    # dataset 2: rotations only below the hips, another Euler order
    "bandai_namco_2": _rig(
        "bandai_namco_2", BANDAI_ROWS, rest="bone", order="YXZ", position_channels=("Hips",)
    ),
    # CMU, the common BVH conversion (31 joints, units of 1/0.45 inch)
    "cmu": _rig(
        "cmu",
        [
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
        ],
        unit="cmu",
    ),
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
    "mixamo": _rig(
        "mixamo",
        [
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
            (
                "mixamorig:{S}HandIndex1",
                "mixamorig:{S}Hand",
                ("offset", "{side}_wrist", (0.1, 0.0, 0.02)),
            ),
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
            (
                "mixamorig:{S}Toe_End",
                "mixamorig:{S}ToeBase",
                ("offset", "{side}_foot", (0.0, 0.0, 0.06)),
            ),
        ],
    ),
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


def write_rig(motion, rig: Rig, body=None) -> BVH:
    """``motion`` (a ``mrlib.Motion``) on ``rig``: a BVH in the rig's conventions."""
    body = resolve_body(body, shared=True)
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
    children = {i: [c for c, p in enumerate(parents) if p == i] for i in range(len(names))}
    # rest orientation of every joint frame, in mrlib's world
    O = np.empty((len(names), 3, 3))
    for i in range(len(names)):
        if rig.rest == "tpose":
            O[i] = A
        else:
            kids = children[i]
            if kids:
                O[i] = _bone_frame(rest[kids[0]] - rest[i])
            else:
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
    Rw = Gd @ O[None]  # joint frame -> mrlib world
    at = np.stack(
        [
            np.broadcast_to(rest[i], (T, 3)) if d < 0 else pos[:, d] + G[:, d] @ (rest[i] - Jr[d])
            for i, d in enumerate(driver)
        ],
        1,
    )  # (T, Jrig, 3) metres, mrlib world
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
