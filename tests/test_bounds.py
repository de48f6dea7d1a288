"""Work bounded before it starts: sample counts, seeds, level counts, sample lengths,
network sizes from checkpoints and npz arrays are checked before anything is allocated,
and the refusal names the flag or file, the limit and the way around it.

Each case that could blow up runs in a subprocess under a memory cap (RLIMIT_DATA, so a
regression fails there instead of swapping the machine) that reports its peak resident
memory and time; the issue's acceptance is < 1 GB and < 30 s before the error."""

from __future__ import annotations

import json
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest
import torch
from capped import PEAK_MB, SECONDS, run_capped, sparse_file  # noqa: E402

from mrlib.datasets.synthetic import synthetic_walk
from mrlib.io import save_motion
from mrlib.model.checkpoint import state_checksum
from mrlib.model.config import ModelConfig, TrainConfig
from mrlib.training.data import TrainingSet
from mrlib.training.trainer import train

TINY = TrainConfig(
    model=ModelConfig(num_levels=2, gen_hidden=(24,), disc_hidden=(24,)),
    block_iterations=(1,),
    n_critic=1,
    checkpoint_every=0,
)


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory) -> Path:
    data = TrainingSet.from_motions([synthetic_walk("walk_sad", seconds=2.0, fps=10.0)])
    return train(data, TINY, tmp_path_factory.mktemp("ckpt"), progress=False).checkpoint


def _with_config(src: Path, dst: Path, **model) -> Path:
    state = torch.load(src, weights_only=True)
    cfg = json.loads(state["config"])
    cfg["model"].update(model)
    state["config"] = json.dumps(cfg)
    state["checksum"] = state_checksum(state)  # a consistent file: the bound must catch it
    torch.save(state, dst)
    return dst


def _zip_bomb(path: Path, clip: Path, junk_mb: int) -> Path:
    """``clip`` plus an unused key ``junk`` of ``junk_mb`` MB of zeros (a few hundred KB
    compressed), streamed so that the test itself never holds it."""
    path.write_bytes(clip.read_bytes())
    header = {"descr": "|u1", "fortran_order": False, "shape": (junk_mb * 2**20,)}
    with zipfile.ZipFile(path, "a", zipfile.ZIP_DEFLATED, compresslevel=1) as z:
        with z.open("junk.npy", "w", force_zip64=True) as fh:
            np.lib.format.write_array_header_2_0(fh, header)
            chunk = bytes(2**20)
            for _ in range(junk_mb):
                fh.write(chunk)
    return path


def _forged_header(path: Path, clip: Path) -> Path:
    """``clip`` with a ``betas`` array whose header claims 8 GB (its data is 80 bytes)."""
    with np.load(clip) as z:
        data = {k: z[k] for k in z.files if k != "betas"}
    np.savez(path, **data)
    header = {"descr": "<f8", "fortran_order": False, "shape": (10**9,)}
    with zipfile.ZipFile(path, "a") as z, z.open("betas.npy", "w") as fh:
        np.lib.format.write_array_header_1_0(fh, header)
        fh.write(bytes(80))
    return path


def _cases(tmp: Path, ckpt: Path) -> dict[str, tuple[list[str], int, str]]:
    """name -> (argv, exit code, text the error must hold)."""
    clip = save_motion(synthetic_walk("walk_sad", seconds=2.4, fps=10.0), tmp / "clip.npz")
    slow = synthetic_walk("walk_sad", seconds=2.4, fps=10.0).replace(fps=0.001)
    slow_clip = save_motion(slow, tmp / "slow.npz")  # 24 frames lasting 6.7 hours
    bomb = _zip_bomb(tmp / "bomb.npz", clip, junk_mb=1100)
    forged = _forged_header(tmp / "forged.npz", clip)
    big = {
        "kernel 100001": {"kernel_size": 100001},
        "hidden 20000": {"gen_hidden": [20000]},
        "levels 1000": {"num_levels": 1000},
    }
    ckpts = {k: _with_config(ckpt, tmp / f"{k.replace(' ', '_')}.pt", **v) for k, v in big.items()}
    big_bvh = sparse_file(tmp / "take.bvh", b"HIERARCHY\nROOT Hips\n{\n", 2 * 2**30)
    frames = tmp / "easymocap"
    frames.mkdir()
    sparse_file(frames / "000000.json", b'[{"id": 0, "poses": [[', 2 * 2**30)
    sidecar = tmp / "labelled"
    sidecar.mkdir()
    save_motion(synthetic_walk("walk_sad", seconds=1.0, fps=10.0), sidecar / "clip.bvh")
    sparse_file(sidecar / "clip.json", b'{"content": 0, ', 2 * 2**30)
    joint_map = sparse_file(tmp / "map.json", b'{"pelvis": "Hips", ', 2 * 2**30)
    sample = ["sample", str(ckpt), "--out", str(tmp / "o")]
    train_ = ["train", str(clip), "--no-progress", "--out", str(tmp / "t")]
    return {
        "info of a 2 GB BVH": (["info", str(big_bvh)], 1, "more than the 256 MB"),
        "export of a 2 GB EasyMocap frame": (
            ["export", str(frames), str(tmp / "e.npz"), "--fps", "30"],
            1,
            "more than the 16 MB",
        ),
        "a 2 GB joint map": (["info", str(big_bvh), "--joint-map", str(joint_map)], 1, "MB"),
        # an optional sidecar that cannot be read gives no label; never read whole
        "a 2 GB label sidecar": (["info", str(sidecar / "clip.bvh")], 0, ""),
        "sample --num 0": ([*sample, "--num", "0"], 2, "--num: must be at least 1"),
        "sample --num -3": ([*sample, "--num", "-3"], 2, "--num: must be at least 1"),
        "sample --num 10**9": ([*sample, "--num", "1000000000"], 2, "--num: must be at most"),
        "sample --seed -1": ([*sample, "--seed", "-1"], 2, "--seed: must be in [0,"),
        "sample --seed 2**40": ([*sample, "--seed", str(2**40)], 2, "--seed: must be in [0,"),
        "train --seed -1": ([*train_, "--seed", "-1"], 2, "--seed: must be in [0,"),
        "train --levels 1000": ([*train_, "--levels", "1000"], 2, "--levels: must be in [1, 32]"),
        "train --levels 50": ([*train_, "--levels", "50"], 2, "--levels: must be in [1, 32]"),
        "train --levels 0": ([*train_, "--levels", "0"], 2, "--levels: must be in [1, 32]"),
        "sample --seconds 86400": ([*sample, "--seconds", "86400"], 2, "in (0, 600]"),
        "sample --seconds 700": ([*sample, "--seconds", "700"], 2, "join longer motion with"),
        "sample --seconds 500 --fps 1000": (
            [*sample, "--seconds", "500", "--fps", "1000"],
            1,
            "--num: 1 samples of 500000 frames",
        ),
        "sample --num 1000 --seconds 300": (
            [*sample, "--num", "1000", "--seconds", "300"],
            1,
            "--num: 1000 samples of 3000 frames",
        ),
        "sample --continue a 0.001 fps clip": (
            [*sample, "--continue", str(slow_clip), "--seconds", "2"],
            1,
            "--continue: the clip plus --seconds",
        ),
        **{
            f"sample a checkpoint with {k}": (
                ["sample", str(p), "--out", str(tmp / "o")],
                1,
                f"{p.name}: invalid checkpoint",
            )
            for k, p in ckpts.items()
        },
        "info of a zip bomb (unused key)": (["info", str(bomb)], 0, ""),
        "export of a zip bomb (unused key)": (["export", str(bomb), str(tmp / "b.bvh")], 0, ""),
        "info of a forged array header": (["info", str(forged)], 1, "'betas' holds 7629 MB"),
    }


def test_bounded_before_it_starts(checkpoint, tmp_path):
    cases = _cases(tmp_path, checkpoint)
    results = run_capped([argv for argv, _, _ in cases.values()])
    assert len(results) == len(cases)
    for (name, (_, code, message)), r in zip(cases.items(), results, strict=True):
        err = r["err"]
        assert r["code"] == code, f"{name}: exit {r['code']}, {err!r}"
        assert message in err and "Traceback" not in err, f"{name}: {err!r}"
        if code == 1:  # one line, no exception class
            assert err.startswith("error: ") and len(err.strip().splitlines()) == 1, name
            assert "Error:" not in err, f"{name}: {err!r}"
        assert r["s"] < SECONDS, f"{name}: {r['s']:.1f} s"
        assert r["peak_mb"] < PEAK_MB, f"{name}: peak {r['peak_mb']:.0f} MB"


def test_pyramid_of_many_levels_fails_at_once():
    from mrlib.errors import ClipTooShortError
    from mrlib.model.pyramid import pyramid_lengths

    for levels in (50, 1000):
        t = time.perf_counter()
        with pytest.raises(ClipTooShortError, match="fewer levels"):
            pyramid_lengths(240, levels)
        assert time.perf_counter() - t < 2


@pytest.mark.parametrize(
    "change, message",
    [
        ({"num_levels": 33}, "num_levels must be in"),
        ({"kernel_size": 100001}, "kernel_size must be in"),
        ({"gen_hidden": (20000,)}, "gen_hidden must have"),
        ({"disc_hidden": (24,) * 17}, "disc_hidden must have"),
    ],
)
def test_model_configs_are_bounded(change, message):
    from mrlib.model.config import ConfigError

    with pytest.raises(ConfigError, match=message):
        ModelConfig(**change)
