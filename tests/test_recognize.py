"""Skeleton recognition (mrlib.io.recognize) and retargeting of BVH files in the conventions
users bring, written here by mrlib itself (tests/rigs.py): Bandai Namco 1 and 2, CMU in
both common conversions, Mixamo, LaFAN1, 3ds Max Biped (two layouts), a generic game rig,
Character Creator (split hip, twist and share bones, 99 joints), DAZ Genesis (bend and
twist bones on the limbs) and Unreal's mannequin (a ground root with IK chains)."""

from __future__ import annotations

import re

import numpy as np
import pytest
import rigs

import mrlib
from mrlib.datasets.synthetic import synthetic_walk
from mrlib.errors import JointMapError
from mrlib.io import default_data_dir, load_motion
from mrlib.io.axes import UNITS
from mrlib.io.bvh import write_bvh
from mrlib.io.name_rules import is_helper, name_parts
from mrlib.io.retarget import retarget_bvh
from mrlib.representation.skeleton import JOINT_NAMES

BANDAI = default_data_dir() / "data"
needs_data = pytest.mark.skipif(not BANDAI.is_dir(), reason="Bandai Namco data not found")

# which map each convention ends up with, and a few joints it must get right
EXPECTED = {
    "bandai_namco_1": ("bandai_namco", {"left_elbow": "LowerArm_L", "right_foot": "Toes_R"}),
    "bandai_namco_2": ("bandai_namco", {"left_elbow": "LowerArm_L", "right_foot": "Toes_R"}),
    "cmu": ("cmu", {"left_elbow": "LeftForeArm", "left_collar": "LeftShoulder"}),
    "cmu_daz": (
        "recognised",
        {
            "left_collar": "LeftCollar",
            "left_shoulder": "LeftShoulder",
            "left_elbow": "LeftElbow",
            "right_wrist": "RightWrist",
            "left_hip": "LeftHip",
            "right_knee": "RightKnee",
            "left_foot": "LeftToe",
            "head": "Head",
        },
    ),
    "mixamo": (
        "recognised",
        {
            "pelvis": "mixamorig:Hips",
            "spine1": "mixamorig:Spine",
            "spine3": "mixamorig:Spine2",
            "head": "mixamorig:Head",
            "left_hand": "mixamorig:LeftHandMiddle1",
            "right_foot": "mixamorig:RightToeBase",
        },
    ),
    "lafan1": ("recognised", {"left_shoulder": "LeftArm", "right_ankle": "RightFoot"}),
    "biped": (
        "recognised",
        {
            "left_collar": "Bip01 L Clavicle",
            "left_elbow": "Bip01 L Forearm",
            "right_hip": "Bip01 R Thigh",
            "neck": "Bip01 Neck",
            "left_hand": "Bip01 L Finger2",
        },
    ),
    "generic": (
        "recognised",
        {"left_elbow": "LeftLowerArm", "right_knee": "RightLowerLeg", "spine3": "Chest"},
    ),
    "character_creator": (
        "recognised",
        {
            "pelvis": "CC_Base_Hip",  # legs and spine part at Pelvis and Waist below it
            "spine1": "CC_Base_Waist",
            "left_hip": "CC_Base_L_Thigh",
            "right_knee": "CC_Base_R_Calf",
            "left_foot": "CC_Base_L_ToeBase",
            "neck": "CC_Base_NeckTwist01",  # a twist bone on the way to the head
            "head": "CC_Base_Head",
            "left_collar": "CC_Base_L_Clavicle",
            "left_shoulder": "CC_Base_L_Upperarm",
            "left_elbow": "CC_Base_L_Forearm",
            "right_wrist": "CC_Base_R_Hand",
            "left_hand": "CC_Base_L_Mid1",
        },
    ),
    "daz_genesis": (
        "recognised",
        {
            "pelvis": "hip",
            "left_hip": "lThighBend",  # the twist bone is part of the thigh
            "left_knee": "lShin",
            "left_foot": "lToe",
            "right_shoulder": "rShldrBend",
            "right_elbow": "rForearmBend",
            "right_wrist": "rHand",
        },
    ),
    "unreal": (
        "recognised",
        {
            "pelvis": "pelvis",
            "left_hip": "thigh_l",
            "left_knee": "calf_l",
            "left_foot": "ball_l",
            "right_elbow": "lowerarm_r",
            "spine3": "spine_03",
        },
    ),
    "biped_pelvis": (
        "recognised",
        {"left_hip": "Bip001 L Thigh", "right_elbow": "Bip001 R Forearm", "head": "Bip001 Head"},
    ),
}


@pytest.fixture(scope="module")
def walk(default_body):
    return synthetic_walk("walk_happy", seconds=3.0, fps=30.0, body=default_body)


def _errors(m) -> tuple[float, float]:
    per_joint = m.meta["retarget_joint_error_cm"]
    return m.meta["retarget_error_mean_cm"], max(per_joint.values())


@pytest.mark.parametrize("convention", list(rigs.RIGS))
def test_every_convention_loads_without_a_map(convention, walk, default_body, tmp_path):
    rig = rigs.RIGS[convention]
    path = write_bvh(tmp_path / f"{convention}.bvh", rigs.write_rig(walk, rig, default_body))
    m = load_motion(path, body=default_body)
    map_name, pairs = EXPECTED[convention]
    assert m.meta["joint_map"] == map_name
    for smpl, src in pairs.items():
        assert m.meta["joint_map_pairs"][smpl] == src, smpl
    if map_name == "recognised":
        assert m.meta["joint_map_confidence"] >= 0.9
    mean, worst = _errors(m)
    assert mean < 3.0 and worst < 6.0, (mean, worst)
    assert m.meta["unit_m"] == pytest.approx(UNITS[rig.unit]) and m.meta["up_axis"] == rig.up
    assert m.num_frames == walk.num_frames and m.fps == pytest.approx(walk.fps)
    # the motion comes back: the root travels as the source's does
    travel = np.linalg.norm(m.trans[-1, [0, 2]] - m.trans[0, [0, 2]])
    src_travel = np.linalg.norm(walk.trans[-1, [0, 2]] - walk.trans[0, [0, 2]])
    assert travel == pytest.approx(src_travel, rel=0.05)


@needs_data
@pytest.mark.parametrize("clip", ["walk_happy_001", "bow_proud_001"])
def test_real_motion_on_every_convention(clip, default_body, tmp_path):
    source = load_motion(BANDAI / f"dataset-1_{clip}.bvh", body=default_body)
    for name, rig in rigs.RIGS.items():
        path = write_bvh(tmp_path / f"{name}.bvh", rigs.write_rig(source, rig, default_body))
        mean, worst = _errors(load_motion(path, body=default_body))
        assert mean < 3.0 and worst < 6.0, (name, mean, worst)


def test_names_mean_nothing_the_tree_and_the_pose_suffice(walk, default_body, tmp_path):
    rig = rigs.RIGS["mixamo"]
    anon = {row[0]: f"j{k:02d}" for k, row in enumerate(rig.joints)}
    rows = tuple((anon[n], None if p is None else anon[p], a) for n, p, a in rig.joints)
    bvh = rigs.write_rig(walk, rigs.Rig("anonymous", rows), default_body)
    m = load_motion(write_bvh(tmp_path / "anon.bvh", bvh), body=default_body)
    assert m.meta["joint_map"] == "recognised" and 0.6 <= m.meta["joint_map_confidence"] < 0.9
    # sides from the pose alone: the left elbow is the left elbow
    assert m.meta["joint_map_pairs"]["left_elbow"] == anon["mixamorig:LeftForeArm"]
    assert m.meta["joint_map_pairs"]["right_knee"] == anon["mixamorig:RightLeg"]
    mean, worst = _errors(m)
    assert mean < 3.0 and worst < 6.0


def test_a_non_humanoid_tree_is_refused_clearly(default_body, tmp_path):
    walk = synthetic_walk("walk_normal", seconds=1.0, fps=30.0, body=default_body)
    path = write_bvh(tmp_path / "dog.bvh", rigs.write_rig(walk, rigs.QUADRUPED, default_body))
    with pytest.raises(JointMapError, match="humanoid") as info:
        load_motion(path, body=default_body)
    assert str(path) in str(info.value) and "joint_map=" in str(info.value)
    # a plain chain has no pelvis at all
    chain = rigs.Rig(
        "chain",
        (("a", None, "pelvis"), ("b", "a", "spine1"), ("c", "b", "spine2"), ("d", "c", "spine3")),
    )
    path = write_bvh(tmp_path / "chain.bvh", rigs.write_rig(walk, chain, default_body))
    with pytest.raises(JointMapError, match="two legs and a spine"):
        load_motion(path, body=default_body)


def test_a_spine_shorter_than_smpls_shares_its_bend(walk, default_body, tmp_path):
    """The generic rig has two spine joints for SMPL's three: the unmapped one takes half
    the turn between its neighbours instead of staying straight."""
    path = write_bvh(tmp_path / "g.bvh", rigs.write_rig(walk, rigs.RIGS["generic"], default_body))
    m = load_motion(path, body=default_body)
    assert "spine2" not in m.meta["joint_map_pairs"]
    s2 = JOINT_NAMES.index("spine2")
    s3 = JOINT_NAMES.index("spine3")
    a2 = np.linalg.norm(m.poses[:, s2], axis=-1)
    a3 = np.linalg.norm(m.poses[:, s3], axis=-1)
    assert a2.mean() > 0.01 and np.allclose(a2, a3, atol=1e-6)  # an even split


def test_helper_bones_are_told_from_body_joints():
    for name in (
        "CC_Base_L_ThighTwist01",
        "CC_Base_R_KneeShareBone",
        "upperarm_twist_01_l",
        "lForearmTwist",
        "ik_hand_gun",
        "ik_foot_root",
        "LeftArmRoll",
    ):
        assert is_helper(name), name
    for name in ("CC_Base_L_Thigh", "lShin", "Hips", "mixamorig:LeftForeArm", "Bip01 L Toe0"):
        assert not is_helper(name), name


def test_a_split_hip_turns_with_the_legs_and_a_twisted_bone_with_its_twist(walk, default_body):
    """Character Creator's pelvis is its Hip (legs and spine part below it); SMPL's pelvis
    turns with the joint where the legs part. DAZ's thigh runs Bend -> Twist -> Shin: the
    hip turns with the twist bone, which carries the thigh's whole rotation."""
    from mrlib.io.rest_alignment import rotation_sources

    for convention, expect in (
        ("character_creator", {"pelvis": "CC_Base_Pelvis", "left_knee": "CC_Base_L_Calf"}),
        (
            "daz_genesis",
            {
                "pelvis": "pelvis",
                "left_hip": "lThighTwist",
                "left_knee": "lShin",
                "right_shoulder": "rShldrTwist",
                "right_elbow": "rForearmTwist",
            },
        ),
    ):
        bvh = rigs.write_rig(walk, rigs.RIGS[convention], default_body)
        r = retarget_bvh(bvh, body=default_body)
        src = r.joint_map.source_indices(bvh.skeleton.names)
        rot = rotation_sources(src, bvh.skeleton)
        for smpl, joint in expect.items():
            assert bvh.skeleton.names[rot[JOINT_NAMES.index(smpl)]] == joint, (convention, smpl)


def test_twist_share_toe_finger_and_face_bones_change_nothing(walk, default_body):
    """The same skeleton with and without Character Creator's extras (ground root, split
    hip, twist and share bones, toes, fingers, face) gives the same motion."""
    plain = [r for r in rigs.RIGS["character_creator"].joints if not rigs_extra(r[0])]
    assert len(plain) < len(rigs.RIGS["character_creator"].joints) - 60
    full = retarget_bvh(rigs.write_rig(walk, rigs.RIGS["character_creator"], default_body))
    bare_rig = rigs.Rig("bare", tuple(plain), rest="bone", position_channels=("CC_Base_Hip",))
    bare = retarget_bvh(rigs.write_rig(walk, bare_rig, default_body))
    assert full.joint_map.mapping == bare.joint_map.mapping
    np.testing.assert_allclose(full.poses, bare.poses, atol=1e-6)


def rigs_extra(name: str) -> bool:
    """Character Creator's joints beyond a plain humanoid's (twist, share, toes, fingers
    other than the middle one, face, ribs)."""
    twist = ("ThighTwist", "CalfTwist", "UpperarmTwist", "ForearmTwist")
    extras = twist + ("Share", "Toe1", "Thumb", "Index", "Ring", "Pinky", "Mid2", "Mid3")
    face = ("Facial", "Jaw", "Tongue", "Teeth", "Eye", "Ribs", "Breast")
    return any(e in name for e in extras + face)


@pytest.mark.parametrize(
    "name, side, core",
    [
        ("mixamorig:LeftUpLeg", "left", "upleg"),
        ("Bip01 L Thigh", "left", "thigh"),
        ("UpperArm_R", "right", "upperarm"),
        ("lhand", "left", "hand"),
        ("RThumb", "right", "thumb"),
        ("LHipJoint", "left", "hipjoint"),
        ("Spine1", None, "spine"),
        ("hand.L", "left", "hand"),
        ("DEF-forearm_r", "right", "forearm"),
        ("Hips", None, "hips"),
    ],
)
def test_name_parts(name, side, core):
    assert name_parts(name) == (side, core)


def test_recognition_is_reported(walk, default_body, tmp_path):
    from mrlib.io import read_bvh
    from mrlib.io.retarget import retarget_bvh

    path = write_bvh(tmp_path / "m.bvh", rigs.write_rig(walk, rigs.RIGS["lafan1"], default_body))
    r = retarget_bvh(read_bvh(path), body=default_body)
    text = r.recognition.report()
    assert "confidence" in text and "[x] legs: upper / lower bone" in text
    assert mrlib.load_motion(path).meta["joint_map_confidence"] == pytest.approx(
        r.recognition.confidence, abs=1e-3
    )


def test_info_prints_the_map_and_writes_it_for_editing(walk, default_body, tmp_path, capsys):
    from mrlib.app.cli import main

    path = write_bvh(tmp_path / "daz.bvh", rigs.write_rig(walk, rigs.RIGS["cmu_daz"], default_body))
    out_map = tmp_path / "map.json"
    assert main(["info", str(path), "--write-map", str(out_map)]) == 0
    text = capsys.readouterr().out
    assert "recognised as humanoid, confidence" in text
    rows = {line.split()[0]: line.split() for line in text.splitlines()[1:] if line[:2] == "  "}
    assert rows["left_elbow"][1] == "LeftElbow" and float(rows["left_elbow"][2]) < 3.0
    assert rows["spine1"][1] == "-"  # unmapped: follows its parent
    # edit the written map (drive SMPL's neck from lowerneck) and load with it
    import json

    data = json.loads(out_map.read_text())
    assert data["map"]["neck"] == "Neck"
    data["map"]["neck"] = "lowerneck"
    out_map.write_text(json.dumps(data))
    assert main(["info", str(path), "--joint-map", str(out_map)]) == 0
    text = capsys.readouterr().out
    assert re.search(r"meta\.joint_map +custom", text) and "lowerneck" in text
    assert "recognised as humanoid" not in text
