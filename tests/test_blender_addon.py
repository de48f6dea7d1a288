"""The Blender add-on (``blender/mrlib_addon``): its bpy-free logic in plain Python, the
bridge that puts mrlib's motion onto a rig, the zip ``make blender-addon`` builds, and, where
a Blender is at hand, the whole add-on headless.

The headless test runs with ``MRLIB_BLENDER_PYTHON`` (a Python where ``import bpy`` works,
e.g. a venv outside the repository with PyPI's ``bpy==4.2.0``: docs/blender.md), else a
``blender`` executable on the PATH, else this interpreter if it imports ``bpy``; without any
of them it skips."""

from __future__ import annotations

import ast
import importlib.util
import json
import math
import os
import shutil
import subprocess
import sys
import textwrap
import time
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pytest
import torch

ROOT = Path(__file__).resolve().parent.parent
ADDON = ROOT / "blender" / "mrlib_addon"
sys.path.insert(0, str(ROOT / "blender"))

from mrlib_addon import core  # noqa: E402  (the add-on's bpy-free modules)
from mrlib_addon import rig as rig_math  # noqa: E402

A_Z_UP = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])  # Blender's Z up -> mrlib's Y up


def _bridge():
    spec = importlib.util.spec_from_file_location("mrlib_addon_bridge", ADDON / "bridge.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _random_rotations(rng, n: int) -> np.ndarray:
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return np.array([rig_math.quat_to_matrix(v) for v in q])


# -- no bpy -------------------------------------------------------------------------------------
def test_the_core_module_and_the_package_import_without_bpy():
    code = (
        "import sys; sys.path.insert(0, sys.argv[1]); import mrlib_addon, mrlib_addon.core, mrlib_addon.rig; "
        "assert 'bpy' not in sys.modules and 'torch' not in sys.modules; "
        "print(mrlib_addon.bl_info['blender'])"
    )
    out = subprocess.run(
        [sys.executable, "-c", code, str(ROOT / "blender")], capture_output=True, text=True
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "(3, 4, 0)"


# -- command lines --------------------------------------------------------------------------------
def test_train_arguments():
    args = core.train_args(
        ["/c/a.bvh", "/c/b.bvh"], ["walk sad", "happy"], "/out/model", preset="demo",
        iterations=5, levels=4, joint_map="/m.json", accept_retarget_error=True,
        overwrite=True, threads=2,
    )  # fmt: skip
    assert args == [
        "train", "/c/a.bvh", "/c/b.bvh", "--labels", "walk sad", "happy", "--preset", "demo",
        "--out", "/out/model", "--iterations", "5", "--levels", "4", "--joint-map", "/m.json",
        "--accept-retarget-error", "--overwrite", "--threads", "2",
    ]  # fmt: skip
    assert core.train_args(["a.bvh"], ["x"], "o", iterations=(3, 4))[-2:] == ["--iterations", "3,4"]
    assert core.mrlib_command("/py", "info", "x")[:3] == ["/py", "-m", "mrlib"]
    assert core.resume_args("/r/model/checkpoint.pt") == [
        "train", "--resume", "/r/model/checkpoint.pt", "--out", "/r/model",
    ]  # fmt: skip
    for bad in (
        lambda: core.train_args([], [], "o"),
        lambda: core.train_args(["a"], ["x", "y"], "o"),
        lambda: core.train_args(["a"], [" "], "o"),
        lambda: core.train_args(["a"], ["x"], "o", preset="huge"),
    ):
        with pytest.raises(core.SetupError):
            bad()


def test_the_arguments_parse_with_mrlibs_own_parser(tmp_path):
    from mrlib.app.cli import build_parser

    parser = build_parser()
    cond = core.Condition("crossover", coarse="walk_sad", fine="walk_happy", level=2, num_levels=4)
    args = parser.parse_args(core.sample_args("c.pt", tmp_path, cond, seconds=2, seed=3))
    assert args.crossover == [("walk_sad", (1, 2)), ("walk_happy", (3, 4))]
    assert (args.seconds, args.seed, args.num, args.overwrite) == (2.0, 3, 1, True)
    args = parser.parse_args(core.train_args(["a.bvh"], ["x"], tmp_path, iterations=2, levels=4))
    assert (args.labels, args.preset, args.iterations, args.levels) == (["x"], "demo", (2,), 4)
    blend = core.Condition("blend", coarse="a", fine="b", weight=0.25)
    args = parser.parse_args(core.sample_args("c.pt", tmp_path, blend, loop=True))
    assert (args.blend, args.loop) == (["a", "b", "0.25"], True)
    args = parser.parse_args(core.sample_args("c.pt", tmp_path, core.Condition(label="a"), path="p.csv"))  # fmt: skip
    assert (args.label, args.path) == ("a", "p.csv")
    label = core.Condition(label="a")
    args = parser.parse_args(core.sample_args("c.pt", tmp_path, label, seconds=1.6, keyframes="k.npz"))  # fmt: skip
    assert (str(args.keyframes), args.seconds, args.loop) == ("k.npz", 1.6, False)
    args = parser.parse_args(core.sample_args("c.pt", tmp_path, label, seconds=1, prefix="a.npz"))
    assert (str(args.prefix), args.seconds) == ("a.npz", 1.0)
    args = parser.parse_args(core.restyle_args("c.pt", "clip.bvh", "a", tmp_path, level=2, keep="detail"))  # fmt: skip
    assert (args.label, args.level, args.keep, str(args.clip)) == ("a", 2, "detail", "clip.bvh")
    assert args.up_axis is None  # mrlib's detection unless the rig's axis is given
    args = parser.parse_args(core.restyle_args("c.pt", "clip.bvh", "a", tmp_path, up_axis="z"))
    assert args.up_axis == "z"
    (tmp_path / "axes.json").write_text('{"up_axis": "-y"}')
    assert core.read_up_axis(tmp_path / "axes.json") == "-y"
    (tmp_path / "axes.json").write_text('{"up_axis": "up"}')
    with pytest.raises(core.SetupError, match="no up axis"):
        core.read_up_axis(tmp_path / "axes.json")


def test_conditions_are_checked_before_anything_runs():
    assert core.crossover_specs("a", "b", 3, 8) == ["a:1-3", "b:4-8"]
    assert core.Condition(label="").args() == []
    for cond in (
        core.Condition("crossover", coarse="a", fine="b", level=4, num_levels=4),
        core.Condition("crossover", coarse="a", fine="b", level=0, num_levels=4),
        core.Condition("crossover", coarse="a", fine="", level=1, num_levels=4),
        core.Condition("blend", coarse="a", fine="b", weight=1.5),
        core.Condition("nope"),
    ):
        with pytest.raises(core.SetupError):
            cond.args()
    with pytest.raises(core.SetupError, match="loop and a path"):
        core.sample_args("c", "o", core.Condition(label="a"), loop=True, path="p.csv")
    label = core.Condition(label="a")
    with pytest.raises(core.SetupError, match="a path and timeline keyframes cannot be combined"):
        core.sample_args("c", "o", label, seconds=1, path="p.csv", keyframes="k.npz")
    with pytest.raises(core.SetupError, match="keyframes and continuing the action"):
        core.sample_args("c", "o", label, seconds=1, keyframes="k.npz", prefix="a.npz")
    with pytest.raises(core.SetupError, match="keyframes need a length"):
        core.sample_args("c", "o", label, keyframes="k.npz")
    with pytest.raises(core.SetupError, match="continuing needs a length"):
        core.sample_args("c", "o", label, prefix="a.npz")


def test_timeline_keys_are_taken_from_the_start_frame():
    # keys at scene frames 1, 11.4 (a sub-frame key), 13 and 25 of an action exported from
    # frame 1, a motion starting at frame 11 of a 24-fps scene
    keys = core.timeline_keys([25.0, 1.0, 11.4, 13.0, 13.0], first=1, start=11, scene_fps=24)
    assert keys == [core.TimelineKey(10, 0.0), core.TimelineKey(12, 2 / 24), core.TimelineKey(24, 14 / 24)]  # fmt: skip
    assert core.keyframe_seconds(keys, 0.0, 24) == pytest.approx(15 / 24)
    assert core.keyframe_seconds(keys, 2.0, 24) == 2.0
    with pytest.raises(core.SetupError, match="at least 0.625 s"):
        core.keyframe_seconds(keys, 0.5, 24)
    with pytest.raises(core.SetupError, match="no keyframes at or after the start frame 30"):
        core.timeline_keys([1.0, 25.0], first=1, start=30, scene_fps=24)
    argv = core.keyframes_args("py", "rig.bvh", "m.pt", keys, "k.npz", joint_map="map.json")
    assert argv[2:] == ["keyframes", "rig.bvh", "m.pt", "--frames", "10,12,24",
                        "--times", "0.000000,0.083333,0.583333", "--out", "k.npz",
                        "--joint-map", "map.json"]  # fmt: skip
    with pytest.raises(core.SetupError):
        core.restyle_args("c", "clip", "", "o")


# -- progress and error lines -------------------------------------------------------------------
def test_progress_lines_as_mrlib_writes_them_are_read():
    import io

    from mrlib.progress import LineProgress

    buf = io.StringIO()
    with LineProgress(total=400, desc="block 2/4 (levels 3-4)", stream=buf) as bar:
        bar.update(400)
        bar.set_postfix(D=-0.31, gp=0.2)
    line = buf.getvalue().strip()
    e = core.parse_line(line)
    assert (e.kind, e.desc, e.fraction) == ("task", "block 2/4 (levels 3-4)", 0.5)
    assert e.seconds is not None and e.seconds >= 0
    e = core.parse_line("sampling: 3/3 in 0.4 s")
    assert (e.kind, e.desc, e.fraction) == ("task", "sampling", None)
    assert core.parse_line("45% in 3.0 s").kind == "task"


def test_error_and_warning_lines_are_read():
    e = core.parse_line("error: unknown label 'nope'; this model knows ['a', 'b']\n")
    assert (e.kind, e.text) == ("error", "unknown label 'nope'; this model knows ['a', 'b']")
    e = core.parse_line("mrlib sample: error: argument --seed: must be in [0, 4294967295], got -1")
    assert (e.kind, e.text) == ("error", "argument --seed: must be in [0, 4294967295], got -1")
    assert core.parse_line("warning: clip.bvh: retarget error 9 cm").kind == "warning"
    assert core.parse_line("training on 2 clips, labels ['a', 'b']").kind == "info"
    events = [core.parse_line("error: first"), core.parse_line("error: second")]
    assert core.error_text(events, 1, []) == "second"
    assert core.error_text([], 1, ["Traceback", "ValueError: x"]) == "ValueError: x"
    assert core.error_text([], 3, []) == "the command stopped with exit status 3"


def test_the_error_line_of_the_real_command_line_reaches_the_job(tmp_path):
    job = core.Job([sys.executable, "-m", "mrlib", "sample", str(tmp_path / "none.pt")])
    job.start().wait(timeout=120)
    assert job.returncode == 1 and not job.ok
    assert "none.pt" in job.error and not job.error.startswith("error:")


# -- child processes ----------------------------------------------------------------------------
_CHILD = textwrap.dedent(
    """
    import sys, time
    for k in (1, 2):
        print(f"block {k}/2 (levels {2 * k - 1}-{2 * k}): 10/10 in 0.1 s, D=0.1", file=sys.stderr, flush=True)
        time.sleep(0.05)
    print("done in 1 s -> x", flush=True)
    if sys.argv[1] == "fail":
        print("error: clip.bvh: no such file", file=sys.stderr)
        sys.exit(1)
    """
)


def test_a_job_reports_progress_and_success():
    job = core.Job([sys.executable, "-c", _CHILD, "ok"], name="train").start()
    fractions = []
    while not job.done:
        job.poll()
        fractions.append(job.fraction)
        time.sleep(0.01)
    assert job.ok and job.error is None and job.fraction == 1.0
    assert [e.fraction for e in job.events if e.kind == "task"] == [0.5, 1.0]
    assert fractions == sorted(fractions)
    assert job.events[-1].text == "done in 1 s -> x"


def test_a_failed_job_gives_the_one_line_error():
    job = core.Job([sys.executable, "-c", _CHILD, "fail"], name="train")
    assert job.wait(timeout=60) == 1
    assert job.error == "clip.bvh: no such file"


def test_a_job_whose_program_is_missing_is_a_setup_error(tmp_path):
    with pytest.raises(core.SetupError, match="cannot run"):
        core.Job([str(tmp_path / "no-python")]).start()


@pytest.mark.skipif(os.name == "nt", reason="POSIX signals")
def test_cancel_interrupts_the_child_and_it_stops_cleanly(tmp_path):
    marker = tmp_path / "stopped"
    child = textwrap.dedent(
        f"""
        import signal, sys, time
        # as mrlib's training does (a handler of its own): a parent that ignores SIGINT (a
        # job started in the background by a shell) would otherwise pass that on
        signal.signal(signal.SIGINT, signal.default_int_handler)
        print("started", flush=True)
        try:
            while True:
                time.sleep(0.05)
        except KeyboardInterrupt:  # as mrlib's training does: save, then exit 130
            open({str(marker)!r}, "w").write("saved")
            print("interrupted", file=sys.stderr)
            sys.exit(130)
        """
    )
    job = core.Job([sys.executable, "-c", child], grace=5.0).start()
    while not any(e.text == "started" for e in job.events):
        job.poll()
        time.sleep(0.01)
    t0 = time.monotonic()
    job.cancel()
    job.wait(timeout=30)
    assert time.monotonic() - t0 < 5
    assert job.cancelled and not job.ok and job.returncode == 130
    assert job.error == "mrlib: cancelled" and marker.read_text() == "saved"


@pytest.mark.skipif(os.name == "nt", reason="POSIX signals")
def test_cancel_terminates_a_child_that_ignores_the_interrupt():
    child = (
        "import signal, time; signal.signal(signal.SIGINT, signal.SIG_IGN); print('up', flush=True)\n"
        "while True: time.sleep(0.05)"
    )
    job = core.Job([sys.executable, "-c", child], grace=0.3).start()
    while not job.events:
        job.poll()
        time.sleep(0.01)
    job.cancel()
    job.wait(timeout=30)
    assert job.cancelled and job.returncode != 0


def test_a_pipeline_runs_its_steps_in_order_and_stops_at_a_failure(tmp_path):
    out = tmp_path / "a.txt"
    seen = []
    write = [sys.executable, "-c", f"open({str(out)!r}, 'w').write('1')"]
    read = lambda: [sys.executable, "-c", f"print(open({str(out)!r}).read())"]  # noqa: E731
    pipe = core.Pipeline(
        [core.Step("a", write), core.Step("b", read, after=lambda: seen.append("b"))]
    )
    assert pipe.wait(timeout=60) and pipe.fraction == 1.0 and seen == ["b"]
    fail = [sys.executable, "-c", "import sys; print('error: bad', file=sys.stderr); sys.exit(1)"]
    pipe = core.Pipeline(
        [core.Step("a", fail), core.Step("b", read, after=lambda: seen.append("x"))]
    )
    assert not pipe.wait(timeout=60)
    assert pipe.error == "bad" and seen == ["b"] and "failed" in pipe.status
    broken = core.Pipeline([core.Step("a", write, after=lambda: 1 / 0)])
    assert not broken.wait(timeout=60) and broken.error.startswith("a: ZeroDivisionError")


def test_the_child_does_not_inherit_blenders_python_settings():
    env = core.child_env({"PYTHONHOME": "/blender/python", "PYTHONPATH": "/x", "HOME": "/h"})
    assert "PYTHONHOME" not in env and "PYTHONPATH" not in env and env["HOME"] == "/h"
    assert env["MRLIB_PROGRESS"] == "lines" and env["PYTHONUNBUFFERED"] == "1"


def test_the_python_setting_takes_a_venv_folder_or_an_executable(tmp_path):
    venv = tmp_path / "repo" / ".venv"
    (venv / "bin").mkdir(parents=True)
    exe = venv / "bin" / "python"
    exe.write_text("#!/bin/sh\n")
    exe.chmod(0o755)
    assert core.resolve_python(str(venv)) == str(exe)
    assert core.resolve_python(str(tmp_path / "repo")) == str(exe)
    assert core.resolve_python(str(exe)) == str(exe)
    for bad in ("", str(tmp_path / "nothing"), str(tmp_path)):
        with pytest.raises(core.SetupError):
            core.resolve_python(bad)


# -- poses on the rig -----------------------------------------------------------------------------
def test_basis_rotations_invert_what_blenders_bvh_exporter_writes():
    """A random rig, posed by random basis rotations, written as the exporter does
    (``G = P R^-1`` in armature space, then ``G_parent^-1 G``): ``basis_from_local`` gives
    the basis rotations back, and ``root_location`` the root's location."""
    rng = np.random.default_rng(0)
    parents = [-1, 0, 1, 1, 3]
    R = _random_rotations(rng, 5)  # rest orientations (bone.matrix_local)
    heads = rng.normal(size=(5, 3))
    B = _random_rotations(rng, 5)  # the pose (matrix_basis rotations)
    loc = rng.normal(size=3)
    P = np.empty_like(R)
    for j, p in enumerate(parents):  # Blender: P = P_parent R_parent^-1 R B
        P[j] = R[j] @ B[j] if p < 0 else P[p] @ R[p].T @ R[j] @ B[j]
    G = P @ np.swapaxes(R, 1, 2)
    for j, p in enumerate(parents):
        L = G[j] if p < 0 else G[p].T @ G[j]
        q = rig_math.basis_from_local(rig_math.quat_from_matrix(L), rig_math.quat_from_matrix(R[j]))
        np.testing.assert_allclose(rig_math.quat_to_matrix(q), B[j], atol=1e-12)
    head_posed = heads[0] + R[0] @ loc  # the root's posed head
    back = rig_math.root_location(head_posed, heads[0], rig_math.quat_from_matrix(R[0]))
    np.testing.assert_allclose(back, loc, atol=1e-12)


def test_quaternion_helpers():
    rng = np.random.default_rng(1)
    for M in _random_rotations(rng, 20):
        q = rig_math.quat_from_matrix(M)
        assert q[0] >= 0 and math.isclose(sum(c * c for c in q), 1.0)
        np.testing.assert_allclose(rig_math.quat_to_matrix(q), M, atol=1e-12)
        v = rng.normal(size=3)
        np.testing.assert_allclose(rig_math.quat_rotate(q, v), M @ v, atol=1e-12)
    flipped = rig_math.continuous([(1, 0, 0, 0), (-0.99, -0.1, 0, 0), (0.98, 0.2, 0, 0)])
    assert all(q[0] > 0 for q in flipped)
    assert rig_math.key_frames(3, 15, 30, start=1) == [1, 3, 5]
    assert rig_math.key_frames(2, 30, 24, start=0) == [0, 0.8]


def test_a_rig_motion_file_is_read_and_checked(tmp_path):
    d = {
        "format": rig_math.RIG_MOTION_FORMAT, "fps": 15, "bones": ["__0", "hips", "leg"],
        "parents": [-1, 0, 1], "mover": "hips", "positions": [[0, 0, 1], [0, 0.1, 1]],
        "rotations": {b: [[1, 0, 0, 0]] * 2 for b in ("__0", "hips", "leg")},
        "mapped": {"pelvis": "hips"},
    }  # fmt: skip
    path = tmp_path / "m.json"
    path.write_text(json.dumps(d))
    m = rig_math.RigMotion.from_json(path)
    assert (m.num_frames, m.fps, m.mover) == (2, 15.0, "hips")
    assert m.missing_bones(["hips", "leg"]) == []  # the exporter's dummy root is no bone
    assert m.missing_bones(["hips"]) == ["leg"]
    d["rotations"]["leg"] = [[1, 0, 0, 0]]
    path.write_text(json.dumps(d))
    with pytest.raises(core.SetupError, match="frames"):
        rig_math.RigMotion.from_json(path)
    path.write_text("{}")
    with pytest.raises(core.SetupError, match="not a rig motion"):
        rig_math.RigMotion.from_json(path)


def test_joint_maps_paths_and_names(tmp_path):
    f = tmp_path / "map.json"
    f.write_text(json.dumps({"name": "custom", "map": {"pelvis": "Hips", "head": "Head"}}))
    mapping = core.read_joint_map(f)
    assert mapping == {"pelvis": "Hips", "head": "Head"}
    assert core.check_joint_map(mapping, ["Hips", "Spine"]) == ["Head"]
    f.write_text(json.dumps({"hip": "Hips"}))
    with pytest.raises(core.SetupError, match="not SMPL joints"):
        core.read_joint_map(f)
    assert core.path_csv([(0, 0), (1, 2)]) == "x,z\n0.000000,-0.000000\n1.000000,-2.000000\n"
    with pytest.raises(core.SetupError):
        core.path_csv([(0, 0)])
    assert core.bvh_unsafe_names(["Hips", "Left Arm", "a{b}", ""]) == ["Left Arm", "a{b}", ""]
    assert core.unique_stems(["walk sad", "walk/sad", "Walk_sad", ""]) == [
        "walk_sad", "walk_sad_2", "Walk_sad_3", "clip",
    ]  # fmt: skip
    assert core.split_labels(" a, b,,c ") == ["a", "b", "c"]


def test_a_sample_path_csv_is_read_by_mrlib(tmp_path):
    from mrlib.sampling.constraints.path import GroundPath

    f = tmp_path / "p.csv"
    f.write_text(core.path_csv([(0, 0), (1, 0), (1, 1)]))
    np.testing.assert_allclose(GroundPath.from_csv(f).points, [[0, 0], [1, 0], [1, -1]])


# -- the bridge (mrlib's Python) ---------------------------------------------------------------
@pytest.fixture(scope="module")
def walks():
    from mrlib.io import load_motion

    return [load_motion(ROOT / "data_samples" / f"{n}.npz") for n in ("walk_sad", "walk_happy")]


def _local_matrices(motion) -> np.ndarray:
    return _bridge()._aa_to_matrix(motion.poses.reshape(motion.num_frames, 24, 3).astype(float))


def test_the_bridge_puts_a_motion_onto_an_smpl_rig_exactly(walks, tmp_path):
    from mrlib.io import load_motion, save_motion

    sad, happy = walks
    rig = save_motion(sad, tmp_path / "rig.bvh")
    happy_npz = save_motion(happy, tmp_path / "happy.npz")
    out, bvh = tmp_path / "m.json", tmp_path / "onto.bvh"
    assert _bridge().main(["onto-rig", str(rig), str(happy_npz), "--out", str(out), "--bvh", str(bvh)]) == 0  # fmt: skip
    m = rig_math.RigMotion.from_json(out)
    assert (m.num_frames, m.fps, m.mover, len(m.mapped)) == (happy.num_frames, happy.fps, "pelvis", 24)  # fmt: skip
    back = load_motion(bvh)
    np.testing.assert_allclose(back.poses, happy.poses, atol=1e-5)
    np.testing.assert_allclose(back.trans, happy.trans, atol=1e-5)
    # the JSON's rotations are the same as the BVH's
    from mrlib.representation.skeleton import JOINT_NAMES

    q = np.array([m.rotations[n] for n in JOINT_NAMES]).transpose(1, 0, 2)  # (T, 24, 4)
    L = np.array([[rig_math.quat_to_matrix(v) for v in row] for row in q[:5]])
    np.testing.assert_allclose(L, _local_matrices(happy)[:5], atol=1e-6)


def test_the_bridge_inverts_mrlibs_reading_of_another_rig(walks, tmp_path):
    """A rig with its own names, Z up and in cm: the motion it gets reads back (with the
    calibration mrlib fitted to the rig's clip) as the motion given."""
    from mrlib.io import save_motion
    from mrlib.io.bvh import BVH, BVHSkeleton, read_bvh, write_bvh
    from mrlib.io.retarget import calibrate_retarget, retarget_bvh
    from mrlib.representation.skeleton import JOINT_NAMES

    sad, happy = walks
    smpl = read_bvh(save_motion(sad, tmp_path / "smpl.bvh"))
    names = tuple(f"Bone_{i:02d}" for i in range(len(smpl.skeleton.names)))
    # Z up: every offset and root position turned by A^T (Y up -> Z up)
    sk = smpl.skeleton
    values = smpl.motion.copy()
    values[:, :3] = values[:, :3] @ A_Z_UP  # the root's positions (rows: A^T x)
    rig = BVH(
        BVHSkeleton(names, sk.parents, sk.offsets @ A_Z_UP, sk.channels, sk.end_sites),
        values, smpl.frame_time,
    )  # fmt: skip
    # the rotations: R' = A^T R A, written back as the channels' Euler angles
    from mrlib.io.bvh.kinematics import bvh_local_transforms, matrix_to_euler

    rot, _ = bvh_local_transforms(smpl)
    rot = A_Z_UP.T @ rot @ A_Z_UP
    starts = sk.channel_starts()
    for j, chans in enumerate(sk.channels):
        order = "".join(c[0] for c in chans if c.endswith("rotation"))
        k = starts[j] + (3 if len(chans) == 6 else 0)
        values[:, k : k + 3] = matrix_to_euler(rot[:, j], order)
    rig_path = write_bvh(tmp_path / "rig.bvh", rig)
    jmap = tmp_path / "map.json"
    jmap.write_text(json.dumps({"name": "custom", "map": {s: names[smpl.skeleton.index(s)] for s in JOINT_NAMES}}))  # fmt: skip
    happy_npz = save_motion(happy, tmp_path / "happy.npz")
    out, bvh = tmp_path / "m.json", tmp_path / "onto.bvh"
    argv = ["onto-rig", str(rig_path), str(happy_npz), "--out", str(out), "--bvh", str(bvh), "--joint-map", str(jmap)]  # fmt: skip
    assert _bridge().main(argv) == 0
    m = rig_math.RigMotion.from_json(out)
    assert m.meta["up_axis"] == "z" and m.mover == "Bone_00"
    calib = calibrate_retarget([read_bvh(rig_path)], str(jmap), max_frames_per_clip=10**6)
    r = retarget_bvh(read_bvh(bvh), **calib, warn=False)
    G_back = _fk(_bridge()._aa_to_matrix(r.poses))
    G_want = _fk(_local_matrices(happy))
    assert np.abs(G_back - G_want).max() < 1e-4
    assert np.abs(r.trans - happy.trans).max() < 1e-4


def _fk(L: np.ndarray) -> np.ndarray:
    from mrlib.representation.skeleton import PARENTS

    G = np.empty_like(L)
    for j, p in enumerate(PARENTS):
        G[:, j] = L[:, j] if p < 0 else G[:, p] @ L[:, j]
    return G


def _onto_rig_and_back(rig_path, motion_npz, tmp_path, stem, joint_map=None):
    """The add-on's path: the bridge's ``onto-rig`` (as the add-on runs it), then the BVH
    it writes read by mrlib's own loader, as mrlib reads any clip of the rig."""
    from mrlib.io import load_motion

    out, bvh = tmp_path / f"{stem}.json", tmp_path / f"{stem}.bvh"
    argv = ["onto-rig", str(rig_path), str(motion_npz), "--out", str(out), "--bvh", str(bvh)]
    if joint_map is not None:
        argv += ["--joint-map", str(joint_map)]
    assert _bridge().main(argv) == 0
    return rig_math.RigMotion.from_json(out), load_motion(bvh)


@pytest.mark.parametrize("convention", ["mixamo", "character_creator"])
def test_the_retarget_onto_a_non_smpl_rig_keeps_smpls_joint_positions(
    convention, walks, body, tmp_path
):
    """A SMPL motion put onto a Mixamo-named and a Character
    Creator-named rig (``tests/rigs.py``: fingers, end joints; CC's root on the ground, split
    hip, twist, share and face bones, bone-aligned frames) reads back with mrlib's loader
    within 3 cm of the SMPL motion's joints. A wrong joint map (legs swapped) does not."""
    import rigs

    from mrlib.io import save_motion
    from mrlib.io.bvh import write_bvh
    from mrlib.io.retarget import RetargetWarning

    sad, happy = walks
    rig_path = write_bvh(tmp_path / "rig.bvh", rigs.write_rig(sad, rigs.RIGS[convention], body))
    happy_npz = save_motion(happy, tmp_path / "happy.npz")
    want = body.motion_joints(happy)

    with warnings.catch_warnings():
        warnings.simplefilter("error", RetargetWarning)  # read back without a complaint
        m, back = _onto_rig_and_back(rig_path, happy_npz, tmp_path, "onto")
    assert len(m.mapped) == 24 and back.num_frames == happy.num_frames
    err_cm = 100 * float(np.linalg.norm(body.motion_joints(back) - want, axis=-1).max())
    print(f"{convention}: max joint-position error {err_cm:.3f} cm")
    assert err_cm <= 3.0, f"{convention}: {err_cm:.2f} cm"

    # the legs' sides swapped in the map the bridge is given: far beyond the bound
    legs = [f"{s}_{j}" for s in ("left", "right") for j in ("hip", "knee", "ankle", "foot")]
    other = dict(zip(legs, legs[4:] + legs[:4], strict=True))
    swapped = {other.get(smpl, smpl): bone for smpl, bone in m.mapped.items()}
    jmap = tmp_path / "swapped.json"
    jmap.write_text(json.dumps({"name": "swapped", "map": swapped}))
    with pytest.warns(RetargetWarning, match="no person holds"):
        _, wrong = _onto_rig_and_back(rig_path, happy_npz, tmp_path, "wrong", jmap)
    wrong_cm = 100 * float(np.linalg.norm(body.motion_joints(wrong) - want, axis=-1).max())
    print(f"{convention}, legs swapped: {wrong_cm:.1f} cm")
    assert wrong_cm > 10.0


def test_the_bridge_reads_a_rig_and_its_keyframes(walks, tmp_path, plumbing_model, default_body, capsys):  # fmt: skip
    from mrlib import load_model
    from mrlib.io import load_motion, save_motion
    from mrlib.sampling.constraints import load_keyframes
    from mrlib.training.data import TrainingSet
    from mrlib.training.trainer import train

    sad = walks[0].resample(15)
    rig = save_motion(sad, tmp_path / "rig.bvh")
    bridge = _bridge()
    assert bridge.main(["read", str(rig), "--out", str(tmp_path / "rig.npz")]) == 0
    read = load_motion(tmp_path / "rig.npz")
    assert read.num_frames == sad.num_frames and np.abs(read.trans - sad.trans).max() < 1e-5
    torch.set_num_threads(1)
    ckpt = train(TrainingSet.from_motions(walks), plumbing_model.config, tmp_path / "model",
                 body=default_body, progress=False).checkpoint  # fmt: skip
    # BVH frames 4, 19, 20 held 0, 0.5 and 0.51 s in: the last two fall on one frame at
    # the rate `mrlib sample` writes (the clips', else the model's)
    model = load_model(ckpt)
    k = round(0.5 * (model.source_fps or model.fps))
    argv = ["keyframes", str(rig), str(ckpt), "--frames", "4,19,20", "--times", "0,0.5,0.51",
            "--out", str(tmp_path / "k.npz")]  # fmt: skip
    assert bridge.main(argv) == 0
    assert f"two keys on the output's frame {k} " in capsys.readouterr().err
    keys = load_keyframes(tmp_path / "k.npz")
    assert [kf.frame for kf in keys] == [0, k]
    assert np.abs(keys[1].poses - read.poses[20]).max() < 1e-6
    assert np.abs(keys[0].trans - read.trans[4]).max() < 1e-6
    assert bridge.main([*argv[:3], "--frames", "4,999", "--times", "0,1", *argv[-2:]]) == 1
    assert "frame 999 is outside its 120 frames" in capsys.readouterr().err


def test_the_bridge_error_is_one_line(tmp_path, capsys):
    assert _bridge().main(["onto-rig", str(tmp_path / "no.bvh"), "x.npz", "--out", str(tmp_path / "o.json")]) == 1  # fmt: skip
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and "no.bvh" in err[0]


# -- the zip ---------------------------------------------------------------------------------------
def test_the_zip_holds_the_addon_with_bl_info_and_its_registration(tmp_path):
    out = tmp_path / "addon.zip"
    run = subprocess.run(
        [sys.executable, str(ROOT / "tools" / "make_blender_addon.py"), "--out", str(out)],
        capture_output=True, text=True,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    with zipfile.ZipFile(out) as z:
        names = z.namelist()
        files = {n: z.read(n).decode() for n in names}
    assert all(n.startswith("mrlib_addon/") and n.endswith(".py") for n in names)
    expected = {"__init__", "core", "rig", "bridge", "props", "ops", "panel", "scene_io"}
    assert {Path(n).stem for n in names} == expected
    init = ast.parse(files["mrlib_addon/__init__.py"])
    info = next(
        ast.literal_eval(node.value)
        for node in init.body
        if isinstance(node, ast.Assign) and getattr(node.targets[0], "id", "") == "bl_info"
    )
    assert info["blender"] >= (3, 4, 0) and info["location"] == "View3D > Sidebar > mrlib"
    functions = {n.name for n in init.body if isinstance(n, ast.FunctionDef)}
    assert {"register", "unregister"} <= functions
    for module in ("props", "ops", "panel"):
        text = files[f"mrlib_addon/{module}.py"]
        assert "bpy.utils.register_class" in text and "def register" in text
    assert "import torch" not in "".join(files.values())
    # the same sources give the same bytes
    again = tmp_path / "again.zip"
    subprocess.run([sys.executable, str(ROOT / "tools" / "make_blender_addon.py"), "--out", str(again)], check=True, capture_output=True)  # fmt: skip
    assert out.read_bytes() == again.read_bytes()


def test_make_has_the_blender_addon_target():
    if shutil.which("make") is None:
        pytest.skip("no make")
    out = subprocess.run(["make", "-n", "blender-addon"], cwd=ROOT, capture_output=True, text=True)
    assert out.returncode == 0 and "tools/make_blender_addon.py" in out.stdout


# -- headless Blender ----------------------------------------------------------------------------
def _blender() -> list[str] | None:
    """How to run a script in Blender: ``MRLIB_BLENDER_PYTHON`` (a Python with the bpy
    module), a ``blender`` on the PATH, or this Python when it imports bpy."""
    py = os.environ.get("MRLIB_BLENDER_PYTHON")
    if py:
        return [py]
    exe = shutil.which("blender")
    if exe:
        return [exe, "-b", "--factory-startup", "--python-exit-code", "1", "--python"]
    if importlib.util.find_spec("bpy") is not None:
        return [sys.executable]
    return None


BLENDER = _blender()

# Runs inside Blender: installs the zip, points the add-on at this repository's Python,
# imports two walks as armatures, lists a motion file as a clip (then removes it), trains on
# the two armatures' actions, generates a crossover onto the first armature (Euler bones), a
# blended loop onto the second (quaternion bones), restyles the first one's action, holds
# poses keyed on the timeline, continues an action and walks a curve, then writes every
# bone's rotation relative to its parent (and every bone's head) per frame.
_BLENDER_SCRIPT = textwrap.dedent(
    """
    import builtins, json, math, os, sys
    import bpy, addon_utils
    from mathutils import Vector

    zip_path, mrlib_python, work, clip_a, clip_b, out_json = sys.argv[sys.argv.index("--") + 1:]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    addon_utils.enable("io_anim_bvh", default_set=True)
    import io_anim_bvh.import_bvh as ib  # Debian's Blender 3.4 opens with "rU" (Python 3.11)
    ib.open = lambda f, mode="r", *a, **k: builtins.open(f, mode.replace("U", ""), *a, **k)
    assert bpy.ops.preferences.addon_install(filepath=zip_path, overwrite=True) == {"FINISHED"}
    addon_utils.enable("mrlib_addon", default_set=True)
    prefs = bpy.context.preferences.addons["mrlib_addon"].preferences
    prefs.python, prefs.threads = mrlib_python, 1
    scene = bpy.context.scene
    scene.render.fps, scene.render.fps_base = 15, 1.0
    rigs = []
    for clip, name in ((clip_a, "walk_sad"), (clip_b, "walk_happy")):
        bpy.ops.import_anim.bvh(filepath=clip, global_scale=0.01, rotate_mode="NATIVE",
                                axis_forward="-Z", axis_up="Y")
        arm = bpy.context.active_object
        arm.name = "rig_" + name
        arm.animation_data.action.name = name
        rigs.append(arm)

    def select(objs):
        for o in bpy.context.view_layer.objects:
            o.select_set(o in objs)
        bpy.context.view_layer.objects.active = objs[0]

    # the two armatures' actions as clips; a motion file is listed too, then removed
    select(rigs)
    assert bpy.ops.mrlib.clip_add_selected() == {"FINISHED"}
    folder, name = os.path.split(clip_b)
    assert bpy.ops.mrlib.clip_add_files(directory=folder, files=[{"name": name}]) == {"FINISHED"}
    s = scene.mrlib
    res = {"listed": [[c.armature.name if c.armature else os.path.basename(c.filepath),
                       c.label] for c in s.clips]}
    s.clip_index = 2
    assert bpy.ops.mrlib.clip_remove() == {"FINISHED"}
    s.preset, s.iterations, s.levels, s.overwrite = "preview", 2, 4, True  # the scene's 15 fps
    s.out_dir = os.path.join(work, "run")
    res["clips"] = [[c.armature.name, c.action.name, c.label] for c in s.clips]
    res["train"] = sorted(bpy.ops.mrlib.train())
    res["checkpoint"], res["labels"], res["num_levels"] = s.checkpoint, s.labels, s.num_levels

    def dump(arm):
        action = arm.animation_data.action
        lo, hi = action.frame_range
        frames = []
        for f in range(int(lo), int(hi) + 1):
            scene.frame_set(f)
            G = {pb.name: pb.matrix.to_3x3() @ pb.bone.matrix_local.to_3x3().inverted()
                 for pb in arm.pose.bones}
            L = {pb.name: [list(r) for r in (G[pb.parent.name].inverted() @ G[pb.name]
                                              if pb.parent else G[pb.name])]
                 for pb in arm.pose.bones}
            frames.append({"local": L, "pelvis": list(arm.pose.bones["pelvis"].head),
                           "heads": {pb.name: list(pb.head) for pb in arm.pose.bones}})
        return {"action": action.name, "range": [lo, hi], "frames": frames,
                "modes": sorted({pb.rotation_mode for pb in arm.pose.bones})}

    select(rigs[:1])
    s.mode, s.coarse, s.fine, s.level, s.seconds, s.seed = "crossover", "walk_sad", "walk_happy", 2, 2.0, 3
    s.body_mesh = True
    import importlib.util  # Debian's Blender runs the system Python: its glTF importer may lack numpy
    res["numpy"] = importlib.util.find_spec("numpy") is not None
    before = set(bpy.data.objects)
    res["crossover"] = {"result": sorted(bpy.ops.mrlib.generate(action_name="crossover"))}
    res["crossover"].update(dump(rigs[0]))
    meshes = [o for o in bpy.data.objects if o not in before and o.type == "MESH"]
    res["body"] = [[len(o.data.vertices), [m.type for m in o.modifiers],
                    o.find_armature() is not None] for o in meshes]
    s.body_mesh = False
    for pb in rigs[1].pose.bones:
        pb.rotation_mode = "QUATERNION"
    select(rigs[1:])
    s.mode, s.coarse, s.fine, s.weight, s.loop, s.seed = "blend", "walk_sad", "walk_happy", 0.3, True, 1
    res["blend"] = {"result": sorted(bpy.ops.mrlib.generate(action_name="blend"))}
    res["blend"].update(dump(rigs[1]))
    select(rigs[:1])
    s.restyle_label, s.restyle_level, s.seed = "walk_happy", 2, 0
    res["restyle"] = {"result": sorted(bpy.ops.mrlib.restyle(action_name="restyle"))}
    res["restyle"].update(dump(rigs[0]))
    # poses keyed on the timeline: three of the first armature's walk, keyed in a new
    # action at frames 1, 12 and 24
    arm, walk = rigs[0], bpy.data.actions["walk_sad"]
    arm.animation_data.action, poses = walk, []
    for f in (5, 20, 35):
        scene.frame_set(f)
        poses.append({pb.name: (tuple(pb.rotation_euler), tuple(pb.location))
                      for pb in arm.pose.bones})
    arm.animation_data.action = bpy.data.actions.new("timeline")
    for f, pose in zip((1, 12, 24), poses):
        for pb in arm.pose.bones:
            pb.rotation_euler, pb.location = pose[pb.name]
            pb.keyframe_insert("rotation_euler", frame=f)
            pb.keyframe_insert("location", frame=f)
    res["timeline"] = dump(arm)
    select(rigs[:1])
    s.mode, s.label, s.seconds, s.seed, s.loop, s.hold_keys = "label", "walk_sad", 0.0, 2, False, True
    res["keys"] = {"result": sorted(bpy.ops.mrlib.generate(action_name="keys"))}
    res["keys"].update(dump(rigs[0]))
    # that action continued for one second
    s.label, s.seconds, s.seed, s.hold_keys, s.continue_action = "walk_happy", 1.0, 4, False, True
    res["continued"] = dump(rigs[0])
    res["continue"] = {"result": sorted(bpy.ops.mrlib.generate(action_name="continue"))}
    res["continue"].update(dump(rigs[0]))
    # a curve of the scene as the root's path: a 2 m line, then a quarter circle of 1 m
    pts = [(0.4 * i, 0.0) for i in range(6)] + [
        (2 + math.sin(a * math.pi / 16), 1 - math.cos(a * math.pi / 16)) for a in range(1, 9)]
    curve = bpy.data.curves.new("path", "CURVE")
    spline = curve.splines.new("POLY")
    spline.points.add(len(pts) - 1)
    for p, (x, y) in zip(spline.points, pts):
        p.co = (x, y, 0.0, 1.0)
    path_obj = bpy.data.objects.new("path", curve)
    scene.collection.objects.link(path_obj)
    to_arm = rigs[0].matrix_world.inverted()
    res["curve"] = [list((to_arm @ Vector((x, y, 0.0)))[:2]) for x, y in pts]
    s.continue_action, s.path_curve, s.seconds, s.seed = False, path_obj, 0.0, 5
    res["path"] = {"result": sorted(bpy.ops.mrlib.generate(action_name="path"))}
    res["path"].update(dump(rigs[0]))
    s.path_curve = None
    s.continue_action, s.loop, s.hold_keys = True, True, False
    try:
        res["two_controls"] = sorted(bpy.ops.mrlib.generate())
    except RuntimeError as e:
        res["two_controls"] = str(e).strip()
    s.label, s.mode, s.continue_action, s.loop = "no_such_label", "label", False, False
    try:  # an operator's error report is a RuntimeError when a script calls it
        res["bad_label"] = sorted(bpy.ops.mrlib.generate())
    except RuntimeError as e:
        res["bad_label"] = str(e).strip()
    json.dump(res, open(out_json, "w"))
    """
)


@pytest.mark.slow
@pytest.mark.skipif(
    BLENDER is None,
    reason="no Blender: set MRLIB_BLENDER_PYTHON to a Python with the bpy module "
    "(pip install bpy==4.2.0 in a venv outside the repository), or put blender on the PATH",
)
def test_the_addon_trains_and_generates_onto_armatures_headless(walks, tmp_path):
    from mrlib.io import load_motion, save_motion
    from mrlib.io.bodyfit import rest_joints_for
    from mrlib.representation.body import resolve_body
    from mrlib.representation.skeleton import JOINT_NAMES

    clips = [save_motion(w.resample(15), tmp_path / f"{w.label}.bvh") for w in walks]
    zip_path = tmp_path / "mrlib_addon.zip"
    subprocess.run([sys.executable, str(ROOT / "tools" / "make_blender_addon.py"), "--out", str(zip_path)], check=True, capture_output=True)  # fmt: skip
    script = tmp_path / "in_blender.py"
    script.write_text(_BLENDER_SCRIPT)
    work, out = tmp_path / "work", tmp_path / "result.json"
    home = tmp_path / "blender_home"  # Blender's user folders: nothing outside tmp_path
    env = dict(os.environ, HOME=str(home))
    for name in ("CONFIG", "SCRIPTS", "DATAFILES", "EXTENSIONS"):
        env[f"BLENDER_USER_{name}"] = str(home / name.lower())
    argv = [*BLENDER, str(script), "--", str(zip_path), sys.executable, str(work),
            *map(str, clips), str(out)]  # fmt: skip
    proc = subprocess.run(argv, capture_output=True, text=True, env=env, timeout=900)
    if not out.exists():
        pytest.fail(f"Blender failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    res = json.loads(out.read_text())
    assert res["listed"] == [["rig_walk_sad", "walk_sad"], ["rig_walk_happy", "walk_happy"], ["walk_happy.bvh", "walk_happy"]]  # fmt: skip
    assert res["clips"] == [["rig_walk_sad", "walk_sad", "walk_sad"], ["rig_walk_happy", "walk_happy", "walk_happy"]]  # fmt: skip
    assert res["train"] == ["FINISHED"] and res["num_levels"] == 4
    assert res["labels"] == "walk_sad,walk_happy"
    # the command line's one-line error, as the operator's error report
    assert res["bad_label"] == (
        "Error: mrlib: unknown label 'no_such_label'; this model knows ['walk_happy', 'walk_sad']"
    )

    ckpt = res["checkpoint"]
    restyle_clip = next((work / "run" / "restyled").glob("*/clip.bvh"))
    # the action is read in the up axis of the rig's calibration clip, as the transfer is
    from mrlib.io.bvh import read_bvh
    from mrlib.io.retarget import retarget_bvh

    rig_up = retarget_bvh(read_bvh(restyle_clip.parent / "rig.bvh"), None, warn=False).up_axis
    assert core.read_up_axis(restyle_clip.parent / "rig_axes.json") == rig_up
    cases = {
        "crossover": [
            "sample",
            ckpt,
            "--crossover",
            "walk_sad:1-2",
            "walk_happy:3-4",
            "--seconds",
            "2",
            "--seed",
            "3",
        ],  # fmt: skip
        "blend": [
            "sample",
            ckpt,
            "--blend",
            "walk_sad",
            "walk_happy",
            "0.3",
            "--loop",
            "--seconds",
            "2",
            "--seed",
            "1",
        ],  # fmt: skip
        "keys": [
            "sample",
            ckpt,
            "--label",
            "walk_sad",
            "--keyframes",
            str(next((work / "run" / "generated").glob("*/keys.npz"))),
            "--seconds",
            "1.6",
            "--seed",
            "2",
        ],  # fmt: skip
        "continue": [
            "sample",
            ckpt,
            "--label",
            "walk_happy",
            "--continue",
            str(next((work / "run" / "generated").glob("*/action.npz"))),
            "--seconds",
            "1",
            "--seed",
            "4",
        ],  # fmt: skip
        "path": [
            "sample",
            ckpt,
            "--label",
            "walk_happy",
            "--path",
            str(next((work / "run" / "generated").glob("*/path.csv"))),
            "--seed",
            "5",
        ],  # fmt: skip
        "restyle": [
            "restyle",
            ckpt,
            str(restyle_clip),
            "--label",
            "walk_happy",
            "--level",
            "2",
            "--seed",
            "0",
            "--up-axis",
            rig_up,
        ],  # fmt: skip
    }
    body = resolve_body(None, shared=True)
    for name, cli in cases.items():
        got = res[name]
        assert got["result"] == ["FINISHED"] and got["action"] == name
        ref_dir = tmp_path / f"ref_{name}"
        subprocess.run([sys.executable, "-m", "mrlib", *cli, "--threads", "1", "--out", str(ref_dir)], check=True, capture_output=True)  # fmt: skip
        (npz,) = ref_dir.glob("*.npz")
        ref = load_motion(npz)
        assert len(got["frames"]) == ref.num_frames
        L = np.array([[f["local"][n] for n in JOINT_NAMES] for f in got["frames"]])
        err = np.abs(A_Z_UP @ L @ A_Z_UP.T - _local_matrices(ref)).max()
        assert err < 1e-4, (name, err)
        pelvis = np.array([f["pelvis"] for f in got["frames"]]) @ A_Z_UP.T
        want = ref.trans + rest_joints_for(body, ref.betas)[0]
        perr = np.abs(pelvis - want).max()
        print(f"{name}: {len(L)} frames, rotations within {err:.1e}, pelvis within {perr:.1e} m")
        assert perr < 1e-4, (name, perr)
    assert res["crossover"]["modes"] != ["QUATERNION"] and res["blend"]["modes"] == ["QUATERNION"]
    # the optional body: one mesh of SMPL's 6890 vertices (the importer splits a few along
    # seams), skinned to its skeleton (the importer's bone shape is the other mesh)
    # (a Blender without numpy cannot import glTF: the action stands and a warning says so)
    skinned = [b for b in res["body"] if b[2]]
    if res["numpy"]:
        assert len(skinned) == 1 and 6890 <= skinned[0][0] < 7000 and skinned[0][1] == ["ARMATURE"], res["body"]  # fmt: skip
    else:
        assert res["body"] == [] and "the body mesh was not imported" in proc.stdout + proc.stderr
    assert res["two_controls"] == "Error: mrlib: a loop and continuing the action cannot be combined: choose one"  # fmt: skip

    def heads(frames):
        return np.array([[f["heads"][n] for n in JOINT_NAMES] for f in frames])

    # the poses keyed on the timeline are held on the armature, at their frames
    timeline, keys = res["timeline"], res["keys"]
    assert timeline["range"] == [1.0, 24.0] and keys["range"] == [1.0, 24.0]
    held = np.linalg.norm(heads(keys["frames"])[[0, 11, 23]] - heads(timeline["frames"])[[0, 11, 23]], axis=-1)  # fmt: skip
    print(f"keyframes held within {held.max() * 100:.2f} cm")
    assert held.max() < 0.01
    free = heads(res["crossover"]["frames"])[[0, 11, 23]] - heads(timeline["frames"])[[0, 11, 23]]
    assert np.linalg.norm(free, axis=-1).max() > 0.05  # what a sample not told of them does
    # a continued action starts as the action did
    before, after = heads(res["continued"]["frames"]), heads(res["continue"]["frames"])
    assert len(after) == len(before) + 15
    kept = np.linalg.norm(after[: len(before) // 2] - before[: len(before) // 2], axis=-1)
    print(f"continued action's first half within {kept.max() * 100:.2f} cm")
    assert kept.max() < 0.01
    # the root walks the scene's curve: its ground track against the curve's polyline
    curve = np.array(res["curve"])
    track = np.array([f["pelvis"][:2] for f in res["path"]["frames"]])
    a, b = curve[:-1], curve[1:]
    u = np.clip(np.einsum("tsk,sk->ts", track[:, None] - a, b - a) / ((b - a) ** 2).sum(-1), 0, 1)
    off = np.linalg.norm(track[:, None] - (a + u[..., None] * (b - a)), axis=-1).min(1)
    print(f"path: the root within {off.mean() * 100:.1f} cm of the curve on average, {off.max() * 100:.1f} cm at most; start {np.linalg.norm(track[0] - curve[0]) * 100:.1f} cm, end {np.linalg.norm(track[-1] - curve[-1]) * 100:.1f} cm from the curve's")  # fmt: skip
    assert off.max() < 0.05 and np.linalg.norm(track[0] - curve[0]) < 0.05
    assert np.linalg.norm(track[-1] - curve[-1]) < 0.15  # a mirrored or turned path: metres
