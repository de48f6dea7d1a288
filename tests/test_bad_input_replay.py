"""Cases of the bad-input sweep found by replaying it with inputs nobody had tried, one
class a test (each case a row):

- a file given as a checkpoint that torch cannot read (empty, truncated, plain text, a
  zip of something else, a motion ``.npz``): one ``error:`` line naming the file, never
  torch's zip-reader internals nor an ``IndexError`` of the error path itself;
- an empty or blank option value (``--out ""``, ``--path ""``, an empty file name):
  a usage error, never "the current folder" or "no path";
- a file name with a newline or another control character: the error stays one line;
- ``OMP_NUM_THREADS`` / ``MKL_NUM_THREADS`` above the 4 x usable CPUs that ``--threads``
  may ask for: capped, with one warning;
- a resampling that leaves one frame of a clip (8 s at 0.001 fps): refused, not a still
  pose "lasting" 1000 s;
- ``evaluate --samples 1000000000`` (and the Python API's ``num_samples`` /
  ``length_factor``): refused before anything is drawn."""

from __future__ import annotations

import zipfile
from pathlib import Path

import pytest
import torch

from mrlib import threads
from mrlib.app.cli import main
from mrlib.datasets.synthetic import synthetic_walk
from mrlib.errors import MrlibError
from mrlib.evaluation.evaluate import evaluate
from mrlib.evaluation.results import MAX_EVAL_SAMPLES, EvaluationSettings
from mrlib.io import save_motion
from mrlib.model.config import ModelConfig, TrainConfig
from mrlib.training.data import TrainingSet
from mrlib.training.trainer import train

TINY = TrainConfig(
    model=ModelConfig(num_levels=2, gen_hidden=(24,), disc_hidden=(24,)),
    block_iterations=(1,),
    n_critic=1,
    checkpoint_every=0,
)
INTERNAL = ("miniz", "enforce fail", "hasRecord", "PytorchStreamReader", "IndexError", "Error:")


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory):
    data = TrainingSet.from_motions([synthetic_walk("walk_sad", seconds=2.0, fps=10.0)])
    return train(data, TINY, tmp_path_factory.mktemp("ckpt"), progress=False).checkpoint


@pytest.fixture(scope="module")
def clip(tmp_path_factory) -> Path:
    m = synthetic_walk("walk_sad", seconds=3.0, fps=10.0)
    return save_motion(m, tmp_path_factory.mktemp("clip") / "clip.npz")


def _run(argv: list[str], capsys) -> tuple[int, str]:
    try:
        code = main([str(a) for a in argv])
    except SystemExit as e:
        code = e.code
    return code, capsys.readouterr().err


def _unreadable(kind: str, tmp: Path, clip: Path) -> Path:
    path = tmp / f"{kind}.pt"
    if kind == "empty":
        path.write_bytes(b"")
    elif kind == "truncated":
        torch.save({"weights": torch.zeros(5000)}, path)
        path.write_bytes(path.read_bytes()[:3000])
    elif kind == "text":
        path.write_text("hello\n")
    elif kind == "foreign zip":
        with zipfile.ZipFile(path, "w") as z:
            z.writestr("a/b.txt", "x")
    else:  # a motion .npz given as the checkpoint
        path.write_bytes(clip.read_bytes())
    return path


@pytest.mark.parametrize("kind", ["empty", "truncated", "text", "foreign zip", "motion npz"])
@pytest.mark.parametrize("command", ["sample", "evaluate"])
def test_an_unreadable_checkpoint_is_one_mrlib_line(kind, command, clip, tmp_path, capsys):
    bad = _unreadable(kind, tmp_path, clip)
    out = tmp_path / "out"
    code, err = _run([command, bad, "--out", out, "--no-progress"], capsys)
    assert code == 1, err
    assert err.count("\n") == 1 and err.startswith(f"error: {bad}: "), err
    assert not any(word in err for word in INTERNAL), err
    assert "checkpoint" in err and not out.exists()


@pytest.mark.parametrize(
    "argv, flag",
    [
        (["sample", "{ckpt}", "--out", ""], "--out"),
        (["sample", "{ckpt}", "--path", "", "--out", "{tmp}/o"], "--path"),
        (["sample", "{ckpt}", "--label", "  ", "--out", "{tmp}/o"], "--label"),
        (["restyle", "{ckpt}", "{clip}", "--label", "walk_sad", "--out", ""], "--out"),
        (["evaluate", "{ckpt}", "--out", " "], "--out"),
        (["train", "{clip}", "--labels", "", "--out", "{tmp}/o"], "--labels"),
        (["export", "", "{tmp}/o.npz"], "src"),
        (["export", "{clip}", ""], "dst"),
        (["info", ""], "path"),
    ],
)
def test_an_empty_option_value_is_a_usage_error(argv, flag, checkpoint, clip, tmp_path, capsys):
    fill = dict(ckpt=checkpoint, clip=clip, tmp=tmp_path)
    before = set(Path.cwd().iterdir())
    code, err = _run([a.format(**fill) for a in argv], capsys)
    assert code == 2, err
    assert f"argument {flag}: wants a value" in err, err
    assert set(Path.cwd().iterdir()) == before  # nothing written to the current folder


@pytest.mark.parametrize(
    "name, shown",
    [
        ("new\nline.npz", "new\\nline"),
        ("tab\there.npz", "tab\\there"),
        ("e\x1b[31m.npz", "e\\x1b[31m"),
    ],
)
def test_an_error_naming_a_file_with_a_control_character_is_one_line(name, shown, tmp_path, capsys):
    code, err = _run(["info", tmp_path / name], capsys)
    assert code == 1
    assert err.count("\n") == 1 and err.startswith("error: ") and shown in err, err


def test_a_bom_is_skipped_and_what_follows_judged(tmp_path, capsys):
    bvh = tmp_path / "bom.bvh"
    bvh.write_bytes(b"\xef\xbb\xbfHIERARCHY\nROOT Hips\n")
    code, err = _run(["info", bvh], capsys)
    assert code == 1 and err.count("\n") == 1 and "truncated hierarchy" in err, err
    assert "ufeff" not in err, err


@pytest.fixture
def fresh_policy(monkeypatch):
    for name in threads.ENV_VARS:
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setattr(threads, "_state", threads._State())
    monkeypatch.setattr(threads, "_warned", set())
    monkeypatch.setattr(threads, "usable_cpus", lambda: 2)
    before = torch.get_num_threads()
    yield monkeypatch
    torch.set_num_threads(before)


@pytest.mark.parametrize("name", threads.ENV_VARS)
@pytest.mark.parametrize("value", ["10000", "100000", "9", "10000,2"])
def test_an_environment_count_above_the_cap_is_capped(fresh_policy, name, value):
    fresh_policy.setenv(name, value)
    with pytest.warns(UserWarning, match=f"{name}=.*more than the 8 mrlib runs here"):
        n = threads.use()
    assert 1 <= n <= 8 and torch.get_num_threads() == n
    threads.use()  # warned once, not at every call


@pytest.mark.parametrize("value", ["8", "2", "4,2"])
def test_an_environment_count_within_the_cap_is_kept(fresh_policy, value, recwarn):
    fresh_policy.setenv("OMP_NUM_THREADS", value)
    assert threads.use() == torch.get_num_threads()
    assert not [w for w in recwarn if "mrlib runs here" in str(w.message)]


@pytest.mark.parametrize("fps", [0.001, 1e-300, 0.1])
def test_a_resampling_that_leaves_one_frame_is_refused(fps, clip, tmp_path, capsys):
    m = synthetic_walk("walk_sad", seconds=8.0, fps=30.0)
    with pytest.raises(MrlibError, match="would leave 1 frame, no motion; choose 0.1255 fps"):
        m.resample(fps)
    assert m.resample(0.126).num_frames == 2
    out = tmp_path / "slow.npz"
    code, err = _run(["export", clip, out, "--fps", str(fps)], capsys)
    assert code == 1 and "no motion" in err and not out.exists(), err


@pytest.mark.parametrize(
    "settings, match",
    [
        (dict(num_samples=10**9), "num_samples \\(--samples\\): 1000000000"),
        (dict(num_samples=MAX_EVAL_SAMPLES + 1), "more than the 1000"),
        (dict(length_factor=1e6), "length_factor: 1e\\+06"),
    ],
)
def test_evaluation_sizes_are_bounded(settings, match):
    with pytest.raises(MrlibError, match=match):
        EvaluationSettings(**settings)


def test_evaluation_frames_are_bounded_before_drawing():
    ref = synthetic_walk("walk_sad", seconds=30.0, fps=30.0)  # 900 frames

    def never(label, length, seed):
        raise AssertionError("drew a sample")

    with pytest.raises(MrlibError, match="more than the 1000000 mrlib scores per sequence"):
        evaluate({"m": never}, {"walk_sad": ref}, EvaluationSettings(num_samples=1000))


def test_cli_evaluate_refuses_a_billion_samples(checkpoint, tmp_path, capsys):
    code, err = _run(
        ["evaluate", checkpoint, "--samples", "1000000000", "--out", tmp_path / "e"], capsys
    )
    assert code == 1 and err.count("\n") == 1 and "--samples" in err, err
    assert not (tmp_path / "e").exists()


@pytest.mark.parametrize("flag", ["--fine-noise", "--guidance"])
@pytest.mark.parametrize("value", ["1e30", "11", "inf"])
def test_sampler_settings_beyond_their_bound_are_usage_errors(flag, value, capsys):
    """A value past the sampler's bound names the flag (it blamed units or NaN before)."""
    from mrlib.app.cli import main

    with pytest.raises(SystemExit):
        main(["sample", "model.pt", flag, value])
    err = capsys.readouterr().err
    assert flag in err and "\n" not in err.strip().splitlines()[-1]


def test_the_sampler_bounds_hold_in_python_too():
    from mrlib.errors import MotionValueError
    from mrlib.sampling.sampler import MAX_FINE_NOISE, MAX_GUIDANCE, Sampler

    for name, bound in (("fine_noise", MAX_FINE_NOISE), ("guidance", MAX_GUIDANCE)):
        with pytest.raises(MotionValueError, match=f"{name} must be in"):
            Sampler(**{name: bound * 10})


def test_write_map_on_a_skeleton_no_map_fits_writes_a_template(tmp_path, capsys):
    import json

    bvh = tmp_path / "odd.bvh"
    bvh.write_text(
        "HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 3 Zrotation Xrotation Yrotation\n"
        " End Site\n {\n OFFSET 0 1 0\n }\n}\nMOTION\nFrames: 1\nFrame Time: 0.0333\n0 0 0\n"
    )
    code, err = _run(["info", bvh, "--write-map", tmp_path / "map.json"], capsys)
    assert code == 1 and "no joint map fits" in err, err
    data = json.loads((tmp_path / "map.json").read_text())
    assert "Hips" in data["description"] and set(data["map"]) >= {"pelvis", "left_ankle"}
