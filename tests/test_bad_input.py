"""The bad-input sweep, one case per row: every file the API reads, every flag the CLI
takes. The API raises an ``MrlibError`` naming the file (never a numpy, zlib or torch
exception); the CLI prints one ``error:`` line (exit 1) or a usage error (exit 2),
never a traceback."""

from __future__ import annotations

import io
import json
import zipfile
from pathlib import Path

import numpy as np
import pytest
import torch

from mrlib.app.cli import main
from mrlib.datasets.synthetic import synthetic_walk
from mrlib.errors import MrlibError
from mrlib.io import load_motion, save_motion
from mrlib.model.checkpoint import (
    CheckpointError,
    CheckpointWarning,
    load_checkpoint,
    state_checksum,
)
from mrlib.model.config import ModelConfig, TrainConfig
from mrlib.model.trained import load_model
from mrlib.sampling.conditions import Condition
from mrlib.sampling.constraints.path import parse_path
from mrlib.sampling.generation import generate
from mrlib.sampling.restyling import restyle
from mrlib.training.data import TrainingSet
from mrlib.training.trainer import Trainer, train

SAMPLE_CLIP = Path(__file__).resolve().parents[1] / "data_samples" / "walk_sad.npz"
GOOD_BVH_HEAD = """HIERARCHY
ROOT Hips
{
OFFSET 0 0 0
CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
End Site
{
OFFSET 0 10 0
}
}
MOTION
"""


def _npz(path: Path, **overrides) -> Path:
    m = synthetic_walk("walk_sad", seconds=3.0, fps=10.0)
    path = save_motion(m.replace(label="walk_sad"), path)
    if overrides:
        with np.load(path) as z:
            d = {k: z[k] for k in z.files}
        d.update(overrides)
        np.savez(path, **d)
    return path


def _deep_bvh(path: Path, depth: int = 1000) -> Path:
    parts = ["HIERARCHY\nROOT r\n{\nOFFSET 0 0 0\nCHANNELS 3 Xrotation Yrotation Zrotation\n"]
    for i in range(depth):
        parts.append(f"JOINT j{i}\n{{\nOFFSET 0 1 0\nCHANNELS 3 Xrotation Yrotation Zrotation\n")
    parts.append("}\n" * (depth + 1) + "MOTION\nFrames: 0\nFrame Time: 0.04\n")
    path.write_text("".join(parts))
    return path


def _corrupt_deflate(path: Path) -> Path:
    m = synthetic_walk("walk_sad", seconds=1.0, fps=10.0)
    buf = io.BytesIO()
    np.savez_compressed(buf, poses=m.poses.reshape(len(m), -1), trans=m.trans, mocap_framerate=10.0)
    raw = bytearray(buf.getvalue())
    start = raw.find(b"poses.npy") + 60  # inside the deflate stream of 'poses'
    raw[start : start + 40] = bytes(40)
    path.write_bytes(bytes(raw))
    return path


def _bvh_frame_time(path: Path, dt: str) -> Path:
    path.write_text(GOOD_BVH_HEAD + f"Frames: 1\nFrame Time: {dt}\n0 0 0 0 0 0\n")
    return path


def _renamed_npy(path: Path) -> Path:
    np.save(path.with_suffix(".npy"), np.zeros((3, 72)))
    path.with_suffix(".npy").rename(path)
    return path


def _truncated(path: Path) -> Path:
    raw = _npz(path).read_bytes()
    path.write_bytes(raw[: len(raw) // 2])
    return path


LOAD_CASES = {
    "bvh nested 1000 joints deep": (lambda p: _deep_bvh(p / "deep.bvh"), "nested more than"),
    ".npy renamed .npz": (lambda p: _renamed_npy(p / "array.npz"), "not an .npz archive"),
    "truncated .npz": (lambda p: _truncated(p / "half.npz"), "cannot read npz"),
    "corrupt deflate stream": (lambda p: _corrupt_deflate(p / "deflate.npz"), "cannot read npz"),
    "npz label is an empty array": (lambda p: _npz(p / "l.npz", label=np.array([])), None),
    "npz label is numbers of a struct": (
        lambda p: _npz(p / "l2.npz", label=np.zeros(2, dtype=[("a", "f4")])),
        "'label' must be text",
    ),
    "npz meta_json is a JSON list": (
        lambda p: _npz(p / "m.npz", meta_json=np.str_("[1, 2]")),
        "must be a JSON object",
    ),
    "npz meta_json is not JSON": (
        lambda p: _npz(p / "m2.npz", meta_json=np.str_("{oops")),
        "not valid JSON",
    ),
    "npz translations of 1e30 m": (
        lambda p: _npz(p / "far.npz", trans=np.full((30, 3), 1e30)),
        "wrong units",
    ),
    "npz complex poses": (
        lambda p: _npz(p / "c.npz", poses=np.zeros((30, 72), complex)),
        "real numbers",
    ),
    "npz fps of 1e300": (lambda p: _npz(p / "f.npz", mocap_framerate=1e300), "fps must be"),
    "npz fps is an empty array": (
        lambda p: _npz(p / "f2.npz", mocap_framerate=np.array([])),
        "is empty",
    ),
    "bvh Frame Time 1e-300": (lambda p: _bvh_frame_time(p / "t1.bvh", "1e-300"), "Frame Time"),
    "bvh Frame Time 1e300": (lambda p: _bvh_frame_time(p / "t2.bvh", "1e300"), "Frame Time"),
    "bvh Frame Time nan": (lambda p: _bvh_frame_time(p / "t3.bvh", "nan"), "Frame Time"),
    "a folder named .npz": (lambda p: (p / "dir.npz").mkdir() or (p / "dir.npz"), None),
    "a missing file": (lambda p: p / "missing.npz", "no such file"),
    "an unknown extension": (lambda p: (p / "clip.fbx").write_text("x") and p / "clip.fbx", ".fbx"),
}


@pytest.mark.parametrize("case", list(LOAD_CASES))
def test_load_motion_raises_an_mrlib_error_naming_the_file(case, tmp_path):
    make, message = LOAD_CASES[case]
    path = make(tmp_path)
    try:
        m = load_motion(path)
    except MrlibError as e:
        assert Path(path).name in str(e), str(e)
        if message:
            assert message in str(e), str(e)
        return
    assert message is None, f"{case}: loaded without error"
    assert np.isfinite(m.poses).all() and np.isfinite(m.trans).all()


def test_a_one_frame_clip_is_refused_naming_the_file(tmp_path):
    m = synthetic_walk("walk_sad", seconds=1.0, fps=10.0)
    path = save_motion(m.slice(0, 1), tmp_path / "one_frame.npz")
    with pytest.raises(MrlibError, match="one_frame"):
        TrainingSet.from_files([path])


# -- checkpoints --------------------------------------------------------------------------
TINY = TrainConfig(
    model=ModelConfig(num_levels=2, gen_hidden=(24,), disc_hidden=(24,)),
    block_iterations=(1,),
    n_critic=1,
    checkpoint_every=0,
)


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory):
    data = TrainingSet.from_motions([synthetic_walk("walk_sad", seconds=2.0, fps=10.0)])
    out = tmp_path_factory.mktemp("ckpt")
    return train(data, TINY, out, progress=False).checkpoint


def _rewrite(src: Path, dst: Path, change) -> Path:
    """``src`` changed by ``change`` and saved with a checksum of the changed content (a
    damaged file that still passes the checksum: what the checks behind it must catch)."""
    state = torch.load(src, weights_only=True)
    change(state)
    state["checksum"] = state_checksum(state)
    torch.save(state, dst)
    return dst


CHECKPOINT_CASES = {
    "missing config": (lambda s: s.pop("config"), "missing 'config'"),
    "config is not JSON": (lambda s: s.update(config="{oops"), "inconsistent checkpoint"),
    "config with unknown fields": (
        lambda s: s.update(config=json.dumps({**json.loads(s["config"]), "bogus": 1})),
        "invalid checkpoint",
    ),
    "generator weights of the wrong shape": (
        lambda s: s["generator"].update({k: torch.zeros(1) for k in list(s["generator"])[:1]}),
        "inconsistent checkpoint",
    ),
    "missing labels": (lambda s: s.pop("labels"), "missing 'labels'"),
    "a label listed twice": (
        lambda s: s.update(labels=[s["labels"][0]] * 2),
        "'walk_sad' is listed twice",
    ),
    "labels that are numbers": (
        lambda s: s.update(labels=[7]),
        "'labels' must be a list of label names",
    ),
    "a contact choice that is a string": (
        lambda s: s.update(contact_at_rate="walk_sad"),
        "'contact_at_rate' must be a list of the model's labels",
    ),
    "a contact choice of an unknown label": (
        lambda s: s.update(contact_at_rate=["walk_giant"]),
        "'contact_at_rate' must be a list of the model's labels",
    ),
}


@pytest.mark.parametrize("case", list(CHECKPOINT_CASES))
def test_a_damaged_checkpoint_is_a_checkpoint_error(case, checkpoint, tmp_path):
    change, message = CHECKPOINT_CASES[case]
    path = _rewrite(checkpoint, tmp_path / "bad.pt", change)
    for load in (load_model, Trainer.from_checkpoint):
        with pytest.raises(CheckpointError, match=message) as info:
            load(path)
        assert "bad.pt" in str(info.value)


def test_a_checkpoint_without_its_checksum_loads_with_a_warning(checkpoint, tmp_path):
    """Checkpoints of version 1 written before checksums (2026-12-01) have none: one
    without is loaded, but never silently (a file whose checksum was taken out looks the
    same)."""
    state = torch.load(checkpoint, weights_only=True)
    del state["checksum"]
    path = tmp_path / "unchecked.pt"
    torch.save(state, path)
    for load in (load_model, Trainer.from_checkpoint):
        with pytest.warns(CheckpointWarning, match="unchecked.pt: the checkpoint has no checksum"):
            load(path)


def test_a_zip_that_is_not_a_checkpoint(tmp_path):
    path = tmp_path / "zip.pt"
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("x", "y")
    with pytest.raises(CheckpointError, match="cannot read checkpoint"):
        load_checkpoint(path)


@pytest.mark.parametrize("content", [b"", b'{"seed": 0}', bytes(range(256)) * 4])
def test_a_file_that_is_no_pytorch_checkpoint_says_so(tmp_path, content):
    path = tmp_path / "x.pt"
    path.write_bytes(content)
    with pytest.raises(CheckpointError, match="not a PyTorch checkpoint"):
        load_checkpoint(path)


# -- the command line -----------------------------------------------------------------------
def _cli_cases(tmp: Path, ckpt: Path, clip: Path) -> dict[str, tuple[list[str], int, str]]:
    (tmp / "a_file").write_text("x")
    return {
        "sample --seconds nan": (["sample", str(ckpt), "--seconds", "nan"], 2, "--seconds"),
        "sample --seconds inf": (["sample", str(ckpt), "--seconds", "inf"], 2, "--seconds"),
        "sample --seconds 0": (["sample", str(ckpt), "--seconds", "0"], 2, "--seconds"),
        "sample --seconds 0.1": (  # one frame: shorter than the model draws, said in seconds
            ["sample", str(ckpt), "--seconds", "0.1", "--out", str(tmp / "short")],
            1,
            "shorter than this model draws: at least",
        ),
        "sample --fine-noise -1": (["sample", str(ckpt), "--fine-noise", "-1"], 2, "--fine-noise"),
        "sample --loop --candidates 2": (
            ["sample", str(ckpt), "--loop", "--candidates", "2"],
            1,
            "--candidates applies to label",
        ),
        "sample --up-axis z": (["sample", str(ckpt), "--up-axis", "z"], 1, "applies to --continue"),
        "sample --wavlm": (
            ["sample", str(ckpt), "--wavlm", str(tmp)],
            1,
            "--wavlm applies to --audio",
        ),
        "train-speech --wavlm": (  # the default features are log-mel: the folder is unused
            ["train-speech", str(tmp), "--wavlm", str(tmp), "--out", str(tmp / "sp")],
            1,
            "--wavlm applies with --features wavlm",
        ),
        "sample --label twice": (
            ["sample", str(ckpt), "--label", "a", "--label", "b"],
            2,
            "--label: given twice",
        ),
        "evaluate --tight-eps 3": (
            ["evaluate", str(ckpt), "--tight-eps", "3", "--samples", "1"],
            1,
            "tight_eps (--tight-eps) 3 is looser than eps (--eps) 2",
        ),
        "sample --guidance nan": (["sample", str(ckpt), "--guidance", "nan"], 2, "--guidance"),
        "sample --candidates 0": (["sample", str(ckpt), "--candidates", "0"], 2, "--candidates"),
        "sample --candidates 2.5": (
            ["sample", str(ckpt), "--candidates", "2.5"],
            2,
            "--candidates",
        ),
        "restyle --candidates 2": (  # a restyle draws once
            ["restyle", str(ckpt), str(clip), "--label", "walk_sad", "--candidates", "2"],
            2,
            "--candidates",
        ),
        "evaluate --fine-noise x": (
            ["evaluate", str(ckpt), "--fine-noise", "x"],
            2,
            "--fine-noise",
        ),
        "sample --blend abc": (
            ["sample", str(ckpt), "--blend", "walk_sad", "walk_sad", "abc", "--out", str(tmp)],
            1,
            "--blend",
        ),
        "sample --out under a file": (
            ["sample", str(ckpt), "--out", str(tmp / "a_file" / "o")],
            1,
            "a_file",
        ),
        "sample --out under /proc": (["sample", str(ckpt), "--out", "/proc/mrlib-x"], 1, "/proc"),
        "sample --out a file": (
            ["sample", str(ckpt), "--out", str(tmp / "a_file")],
            1,
            "a_file: is a file, not a folder",
        ),
        "evaluate --out a file": (  # refused before anything is drawn
            ["evaluate", str(ckpt), "--samples", "1", "--out", str(tmp / "a_file")],
            1,
            "a_file: is a file, not a folder",
        ),
        "train --out a file": (
            ["train", str(clip), "--iterations", "1", "--out", str(tmp / "a_file")],
            1,
            "a_file",
        ),
        "sample --device bogus": (["sample", str(ckpt), "--device", "bogus"], 2, "bogus"),
        "sample --fit-steps -1": (["sample", str(ckpt), "--fit-steps", "-1"], 2, "--fit-steps"),
        "sample --sharpen -1": (["sample", str(ckpt), "--sharpen", "-1"], 2, "--sharpen"),
        "export to a missing folder": (
            ["export", str(clip), str(tmp / "no" / "dir" / "x.bvh")],
            1,
            "no/dir",
        ),
        "export under /sys": (["export", str(clip), "/sys/mrlib-x.npz"], 1, "/sys"),
        "export --fps 1e9": (["export", str(clip), str(tmp / "x.npz"), "--fps", "1e9"], 2, "--fps"),
        "train --fps nan": (["train", str(clip), "--fps", "nan", "--out", str(tmp)], 2, "--fps"),
        "train --fps 0": (["train", str(clip), "--fps", "0", "--out", str(tmp)], 2, "frame rate"),
        "evaluate --samples 0": (["evaluate", str(ckpt), "--samples", "0"], 2, "--samples"),
        "train --lr 0": (["train", str(clip), "--lr", "0", "--out", str(tmp)], 2, "--lr"),
        "train --lr nan": (["train", str(clip), "--lr", "nan", "--out", str(tmp)], 2, "--lr"),
        "train a clip too short for the levels": (
            ["train", str(clip), "--levels", "20", "--out", str(tmp)],
            1,
            "clip 'walk_sad_seed0': a clip of 30 frames",
        ),
        "train --out under a file": (
            [
                "train",
                str(clip),
                "--iterations",
                "1",
                "--levels",
                "2",
                "--no-progress",
                "--out",
                str(tmp / "a_file" / "o"),
            ],
            1,
            "a_file",
        ),
        "train --resume of a non-checkpoint": (
            ["train", "--resume", str(clip), "--out", str(tmp)],
            1,
            "clip.npz",
        ),
        "info of a missing file": (["info", str(tmp / "nope.bvh")], 1, "nope.bvh"),
        "sample --parts naming a part twice": (
            ["sample", str(ckpt), "--parts", "upper=walk_sad,upper=wave"],
            2,
            "names the part 'upper' twice",
        ),
        "export of an npz with --joint-map": (
            ["export", str(clip), str(tmp / "j.bvh"), "--joint-map", "cmu"],
            1,
            "joint_map (--joint-map) applies to BVH files only",
        ),
        "info of an npz with --joint-map": (
            ["info", str(clip), "--joint-map", "smpl"],
            1,
            "joint_map (--joint-map) applies to BVH files only",
        ),
        "train on npz clips with --joint-map": (
            ["train", str(clip), "--joint-map", "cmu", "--out", str(tmp / "jm")],
            1,
            "applies to BVH files only",
        ),
        "export at 0.005 fps to BVH": (  # 3 s at 0.005 fps: one frame left, refused
            ["export", str(clip), str(tmp / "slow.bvh"), "--fps", "0.005"],
            1,
            "would leave 1 frame, no motion",
        ),
    }


def test_cli_sweep(checkpoint, tmp_path, capsys):
    clip = _npz(tmp_path / "clip.npz")
    for case, (argv, code, message) in _cli_cases(tmp_path, checkpoint, clip).items():
        try:
            got = main(argv)
        except SystemExit as e:
            got = e.code
        err = capsys.readouterr().err
        assert got == code, f"{case}: exit {got}, stderr {err!r}"
        assert "Traceback" not in err, case
        assert message in err, f"{case}: {err!r}"


def test_cli_fine_noise_reaches_the_sampler(checkpoint, tmp_path):
    from mrlib.io import load_motion
    from mrlib.sampling.sampler import FINE_NOISE

    default_value = f"{FINE_NOISE:g}"
    poses = {}
    for value in (default_value, "0" if FINE_NOISE else "1"):
        out = tmp_path / value
        argv = ["sample", str(checkpoint), "--raw", "--fine-noise", value, "--out", str(out)]
        assert main(argv) == 0
        poses[value] = load_motion(next(out.glob("*.npz"))).poses
    default = tmp_path / "default"
    assert main(["sample", str(checkpoint), "--raw", "--out", str(default)]) == 0
    assert np.array_equal(load_motion(next(default.glob("*.npz"))).poses, poses[default_value])
    a, b = poses.values()
    assert np.abs(a - b).max() > 1e-4


def test_cli_evaluate_names_its_sampler_settings(tmp_path, capsys):
    # clips long enough for the metrics' windows (59 frames)
    data = TrainingSet.from_motions([synthetic_walk("walk_sad", seconds=6.5, fps=10.0)])
    checkpoint = train(data, TINY, tmp_path / "run", progress=False).checkpoint
    argv = ["evaluate", str(checkpoint), "--samples", "1", "--no-calibration",
            "--fine-noise", "0.5", "--guidance", "0.25", "--candidates", "2",
            "--match-contact-rate", "--out", str(tmp_path / "eval")]  # fmt: skip
    assert main(argv) == 0
    said = (
        "sampler: fine_noise=0.5, guidance=0.25, candidates=2, contact labels: at each label's rate"
    )
    assert said in capsys.readouterr().out
    # a second evaluation into the same folder replaces nothing without --overwrite, and
    # is refused before it samples
    table = (tmp_path / "eval" / "evaluation.csv").read_bytes()
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "evaluation" in err and "--overwrite" in err, err
    assert len(err.strip().splitlines()) == 1
    assert (tmp_path / "eval" / "evaluation.csv").read_bytes() == table
    assert main([*argv, "--overwrite"]) == 0
    # the paper's distance: rotation matrices, no contact labels
    assert main([*argv[:-1], str(tmp_path / "paper"), "--features", "paper"]) == 0
    saved = json.loads((tmp_path / "paper" / "evaluation_settings.json").read_text())
    assert (saved["feature_kind"], saved["contact_features"]) == ("rotmat", False), saved
    assert saved["match_contact_rate"] is True, saved


def test_cli_guidance_reaches_the_sampler(checkpoint, tmp_path, monkeypatch):
    import mrlib.sampling.generation

    seen, plain = [], mrlib.sampling.generation.guided_weights

    def spy(W, sampler):
        seen.append(sampler.guidance)
        return plain(W, sampler)

    monkeypatch.setattr(mrlib.sampling.generation, "guided_weights", spy)
    assert main(["sample", str(checkpoint), "--raw", "--out", str(tmp_path / "a")]) == 0
    argv = ["sample", str(checkpoint), "--raw", "--guidance", "0.5", "--out", str(tmp_path / "b")]
    assert main(argv) == 0
    assert seen == [mrlib.sampling.sampler.GUIDANCE, 0.5]


def test_cli_candidates_reach_the_sampler(checkpoint, tmp_path, monkeypatch):
    import mrlib.sampling.generation

    seen, plain = [], mrlib.sampling.generation.sample_ranked

    def spy(*args):
        seen.append(args[-1])
        return plain(*args)

    monkeypatch.setattr(mrlib.sampling.generation, "sample_ranked", spy)
    assert main(["sample", str(checkpoint), "--raw", "--out", str(tmp_path / "a")]) == 0
    argv = ["sample", str(checkpoint), "--raw", "--candidates", "3", "--out", str(tmp_path / "b")]
    assert main(argv) == 0
    assert seen == [mrlib.sampling.sampler.CANDIDATES, 3]


def test_cli_contact_reading_reaches_the_sampler(checkpoint, tmp_path, capsys):
    from mrlib.model.trained import load_model

    assert load_model(checkpoint).contact_at_rate == ()  # its clip is too short to choose
    checkpoint = _rewrite(
        checkpoint, tmp_path / "chose.pt", lambda s: s.update(contact_at_rate=["walk_sad"])
    )
    out = {}
    for name, extra in (("a", []), ("b", ["--match-contact-rate"]), ("c", ["--cut-contacts"])):
        argv = ["sample", str(checkpoint), "--raw", "--seed", "2", *extra]
        assert main([*argv, "--out", str(tmp_path / name)]) == 0
        out[name] = load_motion(sorted((tmp_path / name).glob("*.npz"))[0])
    assert load_model(checkpoint).contact_at_rate == ("walk_sad",)
    assert out["a"].meta["sampler"]["match_contact_rate"] is True  # the model's choice
    assert out["b"].meta["sampler"]["match_contact_rate"] is True
    assert out["c"].meta["sampler"]["match_contact_rate"] is False
    np.testing.assert_array_equal(out["a"].poses, out["b"].poses)  # the same draw
    np.testing.assert_array_equal(out["b"].poses, out["c"].poses)
    capsys.readouterr()
    argv = ["sample", str(checkpoint), "--match-contact-rate", "--cut-contacts"]
    with pytest.raises(SystemExit):
        main([*argv, "--out", str(tmp_path / "d")])
    assert "not allowed with" in capsys.readouterr().err


API_CASES = {
    "length=10**9": (lambda m: generate(m, "walk_sad", length=10**9), "longer than the 600 s"),
    "length=0": (lambda m: generate(m, "walk_sad", length=0), "length must be a positive"),
    "length=2.5": (lambda m: generate(m, "walk_sad", length=2.5), "length must be a positive"),
    "seed='abc'": (lambda m: generate(m, "walk_sad", seed="abc"), "seed must be an integer"),
    "seed=1.5": (lambda m: generate(m, "walk_sad", seed=1.5), "seed must be an integer"),
    "seed=-1": (lambda m: generate(m, "walk_sad", seed=-1), "seed must be an integer"),
    "num=2.5": (lambda m: generate(m, "walk_sad", num=2.5), "num must be a positive"),
    "num=0": (lambda m: generate(m, "walk_sad", num=0), "num must be a positive"),
    "num x length": (
        lambda m: generate(m, "walk_sad", length=5000, num=100),
        "generate them in smaller batches",
    ),
    "condition=True": (lambda m: generate(m, True), "must be a label name or index"),
    "condition=a dict": (lambda m: generate(m, {"walk_sad": 1}), "must be a label name or index"),
    "condition=unknown index": (lambda m: generate(m, 7), "label index 7 out of range"),
    "blend weight 50": (
        lambda m: generate(m, Condition.blend("walk_sad", "walk_sad", 50.0)),
        r"blend weights must be in \[0, 1\]",
    ),
    "path line:-5": (lambda m: parse_path("line:-5"), "length must be a positive"),
    "save_motion(None, ...)": (
        lambda m: save_motion(None, "never.npz"),
        "save_motion wants a Motion, got NoneType",
    ),
    "load_motion(None)": (lambda m: load_motion(None), "must be a file path"),
    "save_motion(motion, None)": (
        lambda m: save_motion(synthetic_walk("walk_sad", seconds=1.0, fps=10.0), None),
        "must be a file path",
    ),
    # the issue's cases; tests/test_bad_arguments.py sweeps every public function
    "load_model(123)": (lambda m: load_model(123), "load_model: path must be a file path"),
    "generate('path/to/model.pt')": (
        lambda m: generate("path/to/model.pt", "walk_sad"),
        r"load it first: model = mrlib.load_model\('path/to/model.pt'\)",
    ),
    "restyle(..., seed='1')": (
        lambda m: restyle(m, synthetic_walk("walk_sad", seconds=3.0, fps=10.0), 0, seed="1"),
        r"restyle: seed must be an integer .*, got '1' \(str\)",
    ),
    "load_motion(path, fps='30')": (
        lambda m: load_motion(SAMPLE_CLIP, fps="30"),
        r"load_motion: fps must be a number .*, got '30' \(str\)",
    ),
}


@pytest.mark.parametrize("case", list(API_CASES))
def test_api_refuses_nonsense_with_an_mrlib_error(case, checkpoint, tmp_path, monkeypatch):
    """The API cases of the bad-input sweep: each an MrlibError naming the argument, before
    any work (nothing written, nothing allocated for a 10**9-frame request)."""
    monkeypatch.chdir(tmp_path)
    call, message = API_CASES[case]
    model = load_model(checkpoint)
    with pytest.raises(MrlibError, match=message):
        call(model)
    assert not any(tmp_path.iterdir())


def test_bytes_paths_are_read_like_str_paths(tmp_path):
    clip = save_motion(synthetic_walk("walk_sad", seconds=1.0, fps=10.0), tmp_path / "a.npz")
    back = load_motion(bytes(clip))
    assert back.num_frames == 10 and back.label == "walk_sad"


def test_resuming_a_finished_run_says_so_and_changes_nothing(checkpoint, capsys):
    before = checkpoint.read_bytes()
    argv = ["train", "--resume", str(checkpoint), "--out", str(checkpoint.parent), "--no-progress"]
    assert main(argv) == 0
    assert "the run is already complete" in capsys.readouterr().out
    assert checkpoint.read_bytes() == before
