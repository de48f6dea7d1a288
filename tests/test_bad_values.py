"""Nonsense that used to be accepted: each kind refused (or, where old files make it
legitimate, warned about) in one line, by every entry point that meets it.

* absurd rotations and translations, from every reader and the ``Motion`` constructor;
* frame rates the BVH writer would write and mrlib's own reader refuse (one pair of
  bounds for both);
* options of one format given for a file of another (``--joint-map`` for an npz);
* a body part named twice, malformed joint maps, a cache folder that is a file;
* sampling, restyling or evaluating from an unfinished run (a warning) and evaluating a
  speech model with the label evaluation.

Checkpoints (a label listed twice, no checksum) and the wrong-type sweep are in
``test_bad_input.py`` and ``test_bad_arguments.py``.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
import torch

import mrlib
from mrlib.app.cli import main
from mrlib.datasets.synthetic import synthetic_walk
from mrlib.errors import JointMapError, MotionFileError, MotionValueError, MrlibError
from mrlib.io.bvh import (
    BVH,
    MAX_FRAME_TIME,
    MIN_FRAME_TIME,
    BVHFormatError,
    format_bvh,
    parse_bvh,
)
from mrlib.model.checkpoint import state_checksum
from mrlib.model.config import ModelConfig, TrainConfig
from mrlib.representation.motion import MAX_ROTATION_RAD, Motion
from mrlib.sampling.constraints import parse_parts

TINY = TrainConfig(
    model=ModelConfig(num_levels=2, gen_hidden=(24,), disc_hidden=(24,)),
    block_iterations=(3,),
    n_critic=1,
    checkpoint_every=0,
)


def _walk(seconds: float = 3.0, label: str = "walk_sad") -> Motion:
    return synthetic_walk(label, seconds=seconds, fps=10.0)


def _run(argv: list[str], capsys) -> tuple[int, str, str]:
    try:
        code = main(argv)
    except SystemExit as e:
        code = e.code
    out, err = capsys.readouterr()
    return code, out, err


# -- absurd values: the Motion constructor ------------------------------------------------
def _poses(value: float, joint: int = 3) -> np.ndarray:
    p = np.zeros((5, 24, 3))
    p[2, joint, 0] = value
    return p


MOTION_CASES = {
    "an axis-angle of 1e30 rad": (dict(poses=_poses(1e30)), "axis-angle of 1e+30 rad"),
    "an axis-angle just past the bound": (
        dict(poses=_poses(MAX_ROTATION_RAD * 1.01, joint=0)),
        "frame 2, joint 0",
    ),
    "a NaN rotation": (dict(poses=_poses(np.nan)), "NaN or inf"),
    "an infinite rotation": (dict(poses=_poses(np.inf)), "NaN or inf"),
    "a translation of 1e30 m": (dict(trans=np.full((5, 3), 1e30)), "wrong units"),
    "a translation of 1e5 m": (dict(trans=np.full((5, 3), 1e5)), "wrong units"),
    "fps as text": (dict(fps="30"), "fps must be a number, got '30' (str)"),
    "fps as a bool": (dict(fps=True), "fps must be a number"),
    "fps of 0": (dict(fps=0.0), "fps must be a number in"),
    "fps of 1e9": (dict(fps=1e9), "fps must be a number in"),
    "a label that is a number": (dict(label=3), "label must be a string or None"),
    "a name that is a list": (dict(name=["a"]), "name must be a string or None"),
    "meta that is text": (dict(meta="x"), "meta must be a dict"),
}


@pytest.mark.parametrize("case", list(MOTION_CASES))
def test_the_motion_constructor_refuses(case):
    change, message = MOTION_CASES[case]
    args = {**dict(poses=np.zeros((5, 24, 3)), trans=np.zeros((5, 3)), fps=30.0), **change}
    with pytest.raises(MotionValueError, match=re.escape(message)):
        Motion(**args)


def test_the_motion_constructor_keeps_unwrapped_angles():
    """Angles a capture unwraps past 2 pi are rotations still: only thousands of radians
    are refused."""
    m = Motion(poses=_poses(40 * np.pi), trans=np.zeros((5, 3)), fps=30.0)
    assert m.poses.max() == pytest.approx(40 * np.pi)


# -- absurd values: every reader names the file -------------------------------------------
def _npz(path: Path, **changes) -> Path:
    mrlib.save_motion(_walk(), path)
    with np.load(path) as z:
        data = {k: z[k] for k in z.files}
    for key, (index, value) in changes.items():
        data[key] = data[key].astype(np.float64)
        data[key][index] = value
    np.savez(path, **data)
    return path


def _easymocap(folder: Path, key: str, value: float) -> Path:
    folder.mkdir()
    for t in range(3):
        person = {"id": 0, "Rh": [[0.0, 0.0, 0.0]], "Th": [[0.0, 0.9, 0.0]],
                  "poses": [[0.0] * 72], "shapes": [[0.0] * 10]}  # fmt: skip
        if t == 1:
            person[key][0][0] = value
        (folder / f"{t:06d}.json").write_text(json.dumps([person]))
    return folder


def _bvh(path: Path, column: int, value: str) -> Path:
    """mrlib's BVH of a walk with one value of frame 2 replaced (column 0-2: the root's
    position in cm, 3-5 its rotation in degrees)."""
    mrlib.save_motion(_walk(), path)
    lines = path.read_text().splitlines()
    first = lines.index("MOTION") + 3
    row = lines[first + 1].split()
    row[column] = value
    lines[first + 1] = " ".join(row)
    path.write_text("\n".join(lines) + "\n")
    return path


READER_CASES = {
    "npz: a body joint's rotation of 1e30": (
        lambda p: _npz(p / "a.npz", poses=((1, 5), 1e30)),
        "'poses' holds an axis-angle of 1e+30 rad",
    ),
    "npz: the root's rotation of 1e30 (hidden by the turn to Y up)": (
        lambda p: _npz(p / "b.npz", poses=((1, 0), 1e30)),
        "'poses' holds an axis-angle of 1e+30 rad (frame 1, joint 0)",
    ),
    "npz: a rotation of 2000 rad": (
        lambda p: _npz(p / "c.npz", poses=((1, 7), 2000.0)),
        "more than 1000 rad",
    ),
    "npz: a translation of 1e30 m": (
        lambda p: _npz(p / "d.npz", trans=((1, 0), 1e30)),
        "wrong units",
    ),
    "easymocap: Rh of 1e30": (
        lambda p: _easymocap(p / "em1", "Rh", 1e30),
        "'Rh' holds an axis-angle of 1e+30 rad",
    ),
    "easymocap: poses of 1e30": (
        lambda p: _easymocap(p / "em2", "poses", 1e30),
        "'poses' holds an axis-angle of 1e+30 rad",
    ),
    "easymocap: Th of 1e30": (lambda p: _easymocap(p / "em3", "Th", 1e30), "wrong units"),
    "bvh: a rotation channel of 1e30 degrees": (
        lambda p: _bvh(p / "r.bvh", 4, "1e30"),
        "frame 2: a rotation channel holds 1e+30 degrees",
    ),
    "bvh: a root position of 1e30 cm": (lambda p: _bvh(p / "t.bvh", 0, "1e30"), "wrong units"),
}


@pytest.mark.parametrize("case", list(READER_CASES))
def test_absurd_values_are_refused_naming_the_file(case, tmp_path):
    make, message = READER_CASES[case]
    path = make(tmp_path)
    with pytest.raises(MotionFileError) as info:
        mrlib.load_motion(path, fps=30.0 if path.is_dir() else None)
    text = str(info.value)
    assert str(path) in text and message in text, text
    assert len(text.splitlines()) == 1


# -- frame rates: one pair of bounds for the BVH reader and writer ------------------------
@pytest.mark.parametrize("fps", [1e-4, 0.001, 0.0099])
def test_a_bvh_is_not_written_at_a_rate_the_reader_refuses(fps, tmp_path):
    clip = _walk(seconds=1.0).slice(0, 2).replace(fps=fps)
    dst = tmp_path / "slow.bvh"
    with pytest.raises(MotionFileError, match=r"slow.bvh: a motion at .* fps makes no BVH"):
        mrlib.save_motion(clip, dst)
    assert not dst.exists()
    assert mrlib.save_motion(clip, tmp_path / "slow.npz").exists()  # npz has no such bound


@pytest.mark.parametrize("fps", [1 / MAX_FRAME_TIME, 0.5, 30.0, 1 / MIN_FRAME_TIME])
def test_a_bvh_written_at_the_bounds_reads_back(fps, tmp_path):
    clip = _walk(seconds=1.0).slice(0, 2).replace(fps=fps)
    back = mrlib.load_motion(mrlib.save_motion(clip, tmp_path / "edge.bvh"))
    assert back.fps == pytest.approx(fps, rel=1e-6)


def test_the_writer_writes_only_what_the_reader_reads():
    """Over frame times from 1e-4 s to 1000 s: ``format_bvh`` either refuses or writes a
    file ``parse_bvh`` reads with the same frame time (to the 8 decimals written)."""
    from mrlib.io import smpl_to_bvh

    bvh = smpl_to_bvh(_walk(seconds=1.0).slice(0, 2))
    written = 0
    for ft in np.geomspace(1e-4, 1e3, 97):
        b = BVH(skeleton=bvh.skeleton, motion=bvh.motion, frame_time=float(ft), source="x")
        try:
            text = format_bvh(b)
        except BVHFormatError as e:
            assert "Frame Time" in str(e)
            assert not MIN_FRAME_TIME <= ft <= MAX_FRAME_TIME
            continue
        assert parse_bvh(text, source="x").frame_time == pytest.approx(ft, abs=5e-9)
        written += 1
    assert 40 < written < 97


# -- options of one format for a file of another ------------------------------------------
def _clips(tmp: Path) -> dict[str, Path]:
    return {
        "npz": mrlib.save_motion(_walk(), tmp / "clip.npz"),
        "bvh": mrlib.save_motion(_walk(), tmp / "clip.bvh"),
        "easymocap": _easymocap(tmp / "em", "Th", 0.0),
    }


OPTION_CASES = {
    "joint_map for an npz": ("npz", dict(joint_map="smpl"), "joint_map (--joint-map)"),
    "a joint map dict for an npz": ("npz", dict(joint_map={"pelvis": "a"}), "joint_map"),
    "joint_map for an EasyMocap folder": ("easymocap", dict(joint_map="smpl"), "joint_map"),
    "unit for an npz": ("npz", dict(unit=0.01), "unit=0.01 applies to BVH files only"),
    "person for an npz": ("npz", dict(person=1), "person=1 applies to EasyMocap folders"),
    "person for a BVH": ("bvh", dict(person=2), "person=2 applies to EasyMocap folders"),
}


@pytest.mark.parametrize("case", list(OPTION_CASES))
def test_an_option_of_another_format_is_refused(case, tmp_path):
    kind, options, message = OPTION_CASES[case]
    path = _clips(tmp_path)[kind]
    fps = 30.0 if kind == "easymocap" else None
    with pytest.raises(MotionFileError, match=re.escape(message)):
        mrlib.load_motion(path, fps, **options)


def test_a_joint_map_for_a_list_of_files_reaches_the_bvh_files_only(tmp_path):
    clips = _clips(tmp_path)
    data = mrlib.TrainingSet.from_files([clips["bvh"], clips["npz"]], joint_map="smpl")
    assert data.num_clips == 2
    with pytest.raises(MotionFileError, match="applies to BVH files only"):
        mrlib.TrainingSet.from_files([clips["npz"], clips["npz"]], joint_map="smpl")


def test_a_label_given_for_an_npz_is_its_label(tmp_path):
    path = _clips(tmp_path)["npz"]
    assert mrlib.load_motion(path, label="walk_new").label == "walk_new"
    assert mrlib.load_motion(path).label == "walk_sad"


# -- body parts, joint maps, the cache folder ---------------------------------------------
@pytest.mark.parametrize(
    "spec", ["upper=a,upper=b", "lower=a, lower = b", "upper=a,lower=b,upper=a"]
)
def test_a_part_named_twice_is_refused(spec):
    part = spec.split("=")[0].strip()
    with pytest.raises(MotionValueError, match=f"names the part '{part}' twice"):
        parse_parts(spec)


MAPS = {
    "a list": [1, 2],
    "text": "pelvis",
    "null": None,
    "a number as a joint": {"pelvis": 3},
    "an object as a joint": {"pelvis": {"a": 1}},
    "a list as a joint": {"pelvis": ["pelvis"]},
    "null as a joint": {"pelvis": None},
    "an empty joint name": {"pelvis": ""},
    "'map' is a list": {"map": ["pelvis"]},
    "'map' with a nested value": {"map": {"pelvis": ["x"]}},
    "'map' with unknown keys beside it": {"map": {"pelvis": "pelvis"}, "mapping": {}},
    "refit_torso as text": {"map": {"pelvis": "pelvis", "head": "head"}, "refit_torso": "yes"},
    "a name that is a list": {"name": [1], "map": {"pelvis": "pelvis"}},
    "an unknown SMPL joint": {"pelvis": "pelvis", "tail": "head"},
    "no pelvis": {"head": "head"},
    "a source joint used twice": {"pelvis": "pelvis", "head": "pelvis"},
    "the pelvis alone": {"pelvis": "pelvis"},
    "a source joint the file lacks": {"pelvis": "Hips", "head": "head"},
}


MAP_CASES = [(c, "file") for c in MAPS] + [
    (c, "dict") for c, m in MAPS.items() if isinstance(m, dict)
]


@pytest.mark.parametrize(("case", "given_as"), MAP_CASES)
def test_a_malformed_joint_map_is_one_line(case, given_as, tmp_path):
    bvh = mrlib.save_motion(_walk(seconds=1.0), tmp_path / "clip.bvh")
    spec = MAPS[case]
    if given_as == "file":
        spec = tmp_path / "map.json"
        spec.write_text(json.dumps(MAPS[case]))
    with pytest.raises(JointMapError) as info:
        mrlib.load_motion(bvh, joint_map=spec)
    text = str(info.value)
    assert len(text.splitlines()) == 1
    assert "map.json" in text or "clip.bvh" in text or given_as == "dict", text
    for internal in ("Error:", "Traceback", "unhashable", "object has no attribute"):
        assert internal not in text, text


@pytest.mark.parametrize(
    "content",
    [b"\x00\xff\xfe not text", b"[" * 100_000 + b"]" * 100_000, b"{oops", b""],
    ids=["not UTF-8", "nested 100000 deep", "not JSON", "empty"],
)
def test_a_joint_map_file_that_is_no_json_object_is_one_line(content, tmp_path):
    bvh = mrlib.save_motion(_walk(seconds=1.0), tmp_path / "clip.bvh")
    (tmp_path / "map.json").write_bytes(content)
    with pytest.raises(JointMapError, match="map.json: cannot read joint map: ") as info:
        mrlib.load_motion(bvh, joint_map=tmp_path / "map.json")
    assert len(str(info.value).splitlines()) == 1
    assert "Error" not in str(info.value) and "recursion" not in str(info.value)


@pytest.mark.parametrize("where", ["a file", "under a file"])
@pytest.mark.parametrize("action", ["where", "fetch"])
def test_data_refuses_a_cache_folder_that_cannot_be_one(
    where, action, tmp_path, monkeypatch, capsys
):
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    monkeypatch.setenv("MRLIB_DATA_DIR", str(tmp_path / "no_local_copy"))
    monkeypatch.setenv("MRLIB_CACHE_DIR", str(blocker if where == "a file" else blocker / "c"))
    code, out, err = _run(["data", action, "bandai"], capsys)
    assert code == 1 and out == ""
    assert err.startswith("error: mrlib's cache folder") and "a_file" in err, err
    assert "MRLIB_CACHE_DIR" in err and len(err.strip().splitlines()) == 1


def test_data_where_names_a_cache_folder_that_can_be_made(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("MRLIB_DATA_DIR", str(tmp_path / "no_local_copy"))
    monkeypatch.setenv("MRLIB_CACHE_DIR", str(tmp_path / "new" / "cache"))
    code, out, _ = _run(["data", "where", "bandai"], capsys)
    assert code == 0 and str(tmp_path / "new" / "cache") in out


# -- unfinished runs and speech models -----------------------------------------------------
@pytest.fixture(scope="module")
def unfinished(tmp_path_factory) -> Path:
    """A run stopped after iteration 1 of block 1's 3 (as Ctrl-C stops one)."""

    def stop(trainer, losses):
        if (trainer.block, trainer.iteration) == (0, 1):
            raise KeyboardInterrupt

    data = mrlib.TrainingSet.from_motions([_walk()])
    out = tmp_path_factory.mktemp("unfinished")
    res = mrlib.train(data, TINY, out, progress=False, callback=stop)
    assert res.interrupted
    return res.checkpoint


@pytest.mark.parametrize("command", ["sample", "restyle"])
def test_an_unfinished_run_samples_with_a_warning(command, unfinished, tmp_path, capsys):
    clip = mrlib.save_motion(_walk(), tmp_path / "clip.npz")
    argv = {
        "sample": ["sample", str(unfinished), "--raw"],
        "restyle": ["restyle", str(unfinished), str(clip), "--label", "walk_sad", "--level", "1"],
    }[command] + ["--out", str(tmp_path / "out")]
    code, _, err = _run(argv, capsys)
    assert code == 0, err
    warning = [line for line in err.splitlines() if line.startswith("warning:")]
    assert len(warning) == 1, err
    assert "unfinished run (stopped at block 1 of 1, iteration 1 of 3" in warning[0]
    assert f"mrlib train --resume {unfinished} --out {unfinished.parent}" in warning[0]


def test_a_finished_run_samples_without_one(unfinished, tmp_path, capsys):
    model = mrlib.load_model(unfinished)
    assert model.unfinished() == "block 1 of 1, iteration 1 of 3; no level trained"
    done = mrlib.train(None, None, unfinished.parent, resume=unfinished, progress=False)
    assert mrlib.load_model(done.checkpoint).unfinished() is None
    code, _, err = _run(["sample", str(done.checkpoint), "--raw", "--out", str(tmp_path)], capsys)
    assert code == 0 and "warning" not in err


def test_evaluate_refuses_a_speech_model_in_one_line(tmp_path, capsys):
    """A speech checkpoint's condition is audio (its width is not its one label's): the
    label evaluation is refused, saying what scores a speech model."""
    clips = [_walk(label="walk_sad"), _walk(label="walk_happy")]
    cfg = TINY.replace(block_iterations=(1,))
    run = mrlib.train(mrlib.TrainingSet.from_motions(clips), cfg, tmp_path / "r", progress=False)
    state = torch.load(run.checkpoint, weights_only=True)
    state.update(labels=["speech"], clip_labels=[0, 0])  # a 2-channel condition, one label
    state["checksum"] = state_checksum(state)
    torch.save(state, tmp_path / "speech.pt")
    code, _, err = _run(["evaluate", str(tmp_path / "speech.pt"), "--out", str(tmp_path)], capsys)
    assert code == 1 and len(err.strip().splitlines()) == 1, err
    assert "speech-conditioned model" in err and "evaluate_speech_sync" in err
    with pytest.raises(MrlibError, match="speech-conditioned"):
        mrlib.evaluate_model(mrlib.load_model(tmp_path / "speech.pt"))
