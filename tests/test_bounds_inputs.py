"""Work bounded up front for inputs whose size is not a flag (issue #39): a long audio
file for ``sample --audio``, a path whose length or times imply hours of motion for
``sample --path`` without ``--seconds``, a training clip far longer than a training run
can take. Each is refused before anything is generated or resampled, in under a second,
with the limit and the way around it in the message."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest
from capped import PEAK_MB, run_capped  # noqa: E402

from mrlib.datasets.synthetic import synthetic_walk
from mrlib.errors import MrlibError
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
SECONDS = 1.0


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory) -> Path:
    data = TrainingSet.from_motions([synthetic_walk("walk_sad", seconds=2.0, fps=10.0)])
    return train(data, TINY, tmp_path_factory.mktemp("ckpt"), progress=False).checkpoint


def _long_wav(path: Path, seconds: float) -> Path:
    """``seconds`` of 8 kHz 8-bit silence (the smallest rate mrlib reads: 8 KB a second)."""
    import soundfile

    with soundfile.SoundFile(path, "w", 8000, 1, subtype="PCM_U8") as f:
        block = np.zeros(8000 * 60, np.float32)
        for _ in range(int(seconds // 60)):
            f.write(block)
    return path


def _csv(path: Path, rows: list[tuple[float, ...]], header: str = "x,z,t") -> Path:
    path.write_text(header + "\n" + "\n".join(",".join(f"{v:g}" for v in r) for r in rows) + "\n")
    return path


def _cases(tmp: Path, ckpt: Path) -> dict[str, tuple[list[str], str]]:
    """name -> (argv, text the one-line error must hold)."""
    wav = _long_wav(tmp / "talk.wav", 11 * 60)
    timed = _csv(tmp / "slow.csv", [(0, 0, 0), (1, 0, 50_000), (2, 0, 100_000)])
    slow_clip = synthetic_walk("walk_sad", seconds=2.4, fps=10.0).replace(fps=0.001)
    slow = save_motion(slow_clip, tmp / "slow.npz")  # 24 frames lasting 6.7 hours
    sample = ["sample", str(ckpt), "--out", str(tmp / "o")]
    return {
        "sample --audio of 11 minutes": (
            [*sample, "--audio", str(wav)],
            "more than the 600 s mrlib conditions on at once",
        ),
        "sample --path CSV with times to 1e5 s": (
            [*sample, "--path", str(timed)],
            "--path",
        ),
        "sample --path line:1e6 (its length at the pace)": (
            [*sample, "--path", "line:1e6"],
            "pass a shorter --seconds",
        ),
        "sample --path eight:1e9": (
            [*sample, "--path", "eight:1e9"],
            "path 'eight:1e9': path points",
        ),
        "sample --path eight:1e4": ([*sample, "--path", "eight:1e4"], "pass a shorter --seconds"),
        "train on a 6.7-hour clip": (
            ["train", str(slow), "--fps", "30", "--no-progress", "--out", str(tmp / "t")],
            "more than the 18000 a training clip may have",
        ),
    }


def test_refused_up_front(checkpoint, tmp_path):
    """Every case in one child under the memory cap of ``capped``: one line, the limit
    named, nothing written, < 1 s and < 1 GB peak before the error."""
    cases = _cases(tmp_path, checkpoint)
    results = run_capped([argv for argv, _ in cases.values()])
    assert len(results) == len(cases)
    for (name, (_, message)), r in zip(cases.items(), results, strict=True):
        err = r["err"]
        assert r["code"] == 1, f"{name}: exit {r['code']}, {err!r}"
        assert err.startswith("error: ") and len(err.strip().splitlines()) == 1, f"{name}: {err!r}"
        assert message in err and "Traceback" not in err, f"{name}: {err!r}"
        assert r["s"] < SECONDS, f"{name}: {r['s']:.2f} s"
        assert r["peak_mb"] < PEAK_MB, f"{name}: peak {r['peak_mb']:.0f} MB"
    assert not (tmp_path / "o").exists() or not any((tmp_path / "o").iterdir())
    assert not (tmp_path / "t" / "checkpoint.pt").exists()


def test_long_audio_refused_from_the_header(tmp_path):
    from mrlib.speech.audio import AudioFileError, audio_duration, load_audio

    wav = _long_wav(tmp_path / "talk.wav", 11 * 60)
    assert audio_duration(wav) == pytest.approx(660.0)
    t = time.perf_counter()
    with pytest.raises(AudioFileError, match=r"talk\.wav: audio is 660 s long.*cut it into"):
        load_audio(wav)
    assert time.perf_counter() - t < SECONDS
    wav2, sr = load_audio(wav, max_seconds=None)  # the limit can be lifted by the caller
    assert len(wav2) == 660 * sr


def test_long_waveform_refused_by_the_api():
    from mrlib.speech.sample import _read_audio

    with pytest.raises(MrlibError, match="the audio array: audio is 700 s long"):
        _read_audio(np.zeros(700 * 16000, np.float32), 16000)


def test_generate_on_path_bounds_the_implied_length(checkpoint):
    from mrlib.model.trained import load_model
    from mrlib.sampling.constraints import generate_on_path, path_seconds

    model = load_model(checkpoint)
    seconds, pace = path_seconds(model, "eight:1e4", "walk_sad")
    assert seconds > 600 and pace is not None
    t = time.perf_counter()
    with pytest.raises(MrlibError, match=r"figure-eight.*longer than the 600 s"):
        generate_on_path(model, "eight:1e4", "walk_sad")
    with pytest.raises(MrlibError, match=r"\(as asked\) is longer than the 600 s"):
        generate_on_path(model, "circle:2", "walk_sad", seconds=7200)
    assert time.perf_counter() - t < 2 * SECONDS
