"""Exports for other tools: glTF binary read back (always) and BVH / GLB re-imported in
headless Blender (where a ``blender`` executable is installed, e.g. Debian's package)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import roma
import torch

from mrlib.datasets.synthetic import synthetic_walk
from mrlib.io import load_motion, save_motion
from mrlib.io.gltf import read_glb, save_glb
from mrlib.representation.skeleton import JOINT_NAMES, NUM_JOINTS


@pytest.fixture(scope="module")
def motion(default_body):
    m = synthetic_walk("walk_sad", seconds=2.0, fps=25.0, body=default_body)
    return m.replace(betas=np.linspace(-1.0, 1.0, 10).astype(np.float32))


def _glb_pose(g: dict) -> tuple[np.ndarray, np.ndarray]:
    """World joint positions ``(T, J, 3)`` and skinning transforms ``(T, J, 4, 4)`` of a
    read-back GLB, by forward kinematics over its nodes (nothing of mrlib's)."""
    names, parents = g["joint_names"], g["parents"]
    T = len(g["times"])
    q = np.stack([g["rotation"][n] for n in names], 1)  # (T, J, 4)
    R = roma.unitquat_to_rotmat(torch.as_tensor(q, dtype=torch.float64)).numpy()
    local = np.tile(np.eye(4), (T, len(names), 1, 1))
    local[..., :3, :3] = R
    local[..., :3, 3] = g["rest_translation"]
    for n, t in g["translation"].items():
        local[:, names.index(n), :3, 3] = t
    world = np.empty_like(local)
    for j, p in enumerate(parents):  # parents come before children in SMPL's order
        world[:, j] = local[:, j] if p < 0 else world[:, p] @ local[:, j]
    return world[..., :3, 3], world @ g["inverse_bind"]


def test_glb_reads_back_with_the_skeleton_frames_and_rate(motion, default_body, tmp_path):
    path = save_glb(motion, tmp_path / "walk.glb", body=default_body)
    g = read_glb(path)
    assert g["joint_names"] == list(JOINT_NAMES) and len(g["parents"]) == NUM_JOINTS
    assert len(g["times"]) == motion.num_frames
    assert 1.0 / np.diff(g["times"]).mean() == pytest.approx(motion.fps, rel=1e-5)
    assert g["extras"]["fps"] == motion.fps
    assert len(g["vertices"]) == default_body.num_vertices
    assert g["faces"].max() < len(g["vertices"])
    # the animated skeleton is the body model's, joint for joint
    joints, skinning = _glb_pose(g)
    ref = default_body.motion_joints(motion)
    assert np.abs(joints - ref).max() < 1e-4  # metres: float32 storage
    # and the skinned mesh is the body's mesh (the 4 largest weights per vertex)
    frames = [0, motion.num_frames // 2]
    W = np.zeros((len(g["vertices"]), NUM_JOINTS))
    rows = np.repeat(np.arange(len(W)), g["skin_joints"].shape[1])
    np.add.at(W, (rows, g["skin_joints"].astype(int).ravel()), g["skin_weights"].ravel())
    vh = np.concatenate([g["vertices"], np.ones((len(g["vertices"]), 1))], 1)
    skinned = np.einsum("vj,fjab,vb->fva", W, skinning[frames], vh)[..., :3]
    verts = default_body.motion_vertices(motion, frames)
    err = np.linalg.norm(skinned - verts, axis=-1)
    assert np.median(err) < 1e-4 and err.max() < 0.01, (np.median(err), err.max())


def test_glb_is_reachable_from_save_motion_and_the_cli(motion, default_body, tmp_path):
    from mrlib.app.cli import main

    save_motion(motion, tmp_path / "a.npz")
    assert main(["export", str(tmp_path / "a.npz"), str(tmp_path / "a.glb")]) == 0
    g = read_glb(tmp_path / "a.glb")
    assert len(g["times"]) == motion.num_frames
    with pytest.raises(Exception, match="writes"):
        save_motion(motion, tmp_path / "a.fbx")
    with pytest.raises(Exception, match="cannot read|unsupported"):
        load_motion(tmp_path / "a.glb")


# -- Blender -----------------------------------------------------------------------------
BLENDER = shutil.which("blender")
needs_blender = pytest.mark.skipif(
    BLENDER is None,
    reason="Blender is not installed (Debian: apt-get install blender); the re-import "
    "checks need a real Blender",
)

# Runs inside Blender: import one file, write the world position of every bone head at
# every key frame. Debian bookworm's Blender 3.4 BVH add-on opens files with mode "rU",
# which Python 3.11 removed: the script hands that call a plain "r".
_BLENDER_SCRIPT = textwrap.dedent(
    """
    import builtins, json, sys
    import bpy
    src, out, fps = sys.argv[sys.argv.index("--") + 1:]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.fps, scene.render.fps_base = int(round(float(fps))), 1.0
    if src.endswith(".bvh"):
        import io_anim_bvh.import_bvh as ib
        ib.open = lambda f, mode="r", *a, **k: builtins.open(f, mode.replace("U", ""), *a, **k)
        bpy.ops.import_anim.bvh(filepath=src, global_scale=0.01, rotate_mode="NATIVE",
                                axis_forward="-Z", axis_up="Y")
    else:
        bpy.ops.import_scene.gltf(filepath=src)
    arm = next(o for o in scene.objects if o.type == "ARMATURE")
    lo, hi = arm.animation_data.action.frame_range
    res = {"names": [b.name for b in arm.pose.bones], "frames": [],
           "meshes": [len(o.data.vertices) for o in scene.objects if o.type == "MESH"]}
    for f in range(int(lo), int(hi) + 1):
        scene.frame_set(f)
        res["frames"].append([list(arm.matrix_world @ b.head) for b in arm.pose.bones])
    json.dump(res, open(out, "w"))
    """
)


def _blender_joints(path, fps: float, tmp_path) -> dict:
    script = tmp_path / "reimport.py"
    script.write_text(_BLENDER_SCRIPT)
    out = tmp_path / "reimport.json"
    env = dict(os.environ)
    # Blender's glTF add-on imports numpy: lend it this interpreter's
    env["PYTHONPATH"] = os.pathsep.join(p for p in sys.path if "site-packages" in p)
    cmd = [BLENDER, "-b", "--factory-startup", "--python-use-system-env", "--python", str(script)]
    proc = subprocess.run(
        [*cmd, "--", str(path), str(out), str(fps)],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    if not out.exists():
        pytest.fail(
            f"Blender did not import {path.name}:\n{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}"
        )
    res = json.loads(out.read_text())
    P = np.array(res["frames"])  # Blender: Z up, -Y forward
    P = np.stack([P[..., 0], P[..., 2], -P[..., 1]], -1)
    res["joints"] = P[:, [res["names"].index(n) for n in JOINT_NAMES]]
    return res


@needs_blender
@pytest.mark.parametrize("order", ["ZXY", "XYZ"])
def test_blender_reimports_the_bvh_export_within_a_millimetre(
    motion, default_body, tmp_path, order
):
    path = save_motion(motion, tmp_path / "walk.bvh", body=default_body, euler_order=order)
    res = _blender_joints(path, motion.fps, tmp_path)
    ref = default_body.motion_joints(motion)
    assert res["joints"].shape == ref.shape
    assert np.linalg.norm(res["joints"] - ref, axis=-1).max() < 1e-3


@needs_blender
def test_blender_imports_the_glb_with_its_mesh_and_animation(motion, default_body, tmp_path):
    path = save_glb(motion, tmp_path / "walk.glb", body=default_body)
    res = _blender_joints(path, motion.fps, tmp_path)
    assert res["meshes"] == [default_body.num_vertices]
    ref = default_body.motion_joints(motion)
    assert res["joints"].shape == ref.shape
    assert np.linalg.norm(res["joints"] - ref, axis=-1).max() < 1e-3


def test_sample_writes_a_glb_per_sample_on_request(motion, tmp_path):
    from mrlib.app.cli import main

    clip = save_motion(motion.replace(label="sad"), tmp_path / "sad.npz")
    run = tmp_path / "run"
    argv = ["train", str(clip), "--iterations", "1", "--levels", "2", "--no-progress"]
    assert main([*argv, "--out", str(run)]) == 0
    out = tmp_path / "samples"
    assert (
        main(["sample", str(run / "checkpoint.pt"), "--glb", "--seconds", "1", "--out", str(out)])
        == 0
    )
    (glb,) = out.glob("*.glb")
    assert {p.suffix for p in out.iterdir()} == {".npz", ".bvh", ".glb"}
    assert len(read_glb(glb)["times"]) == load_motion(glb.with_suffix(".npz")).num_frames
