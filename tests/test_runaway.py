"""Runaway work bounded: no small input makes mrlib run for minutes or fill the memory
before it finishes or fails with one line that names the limit and the way around.

- downloads: a mirror that streams an endless body (or announces one), one that never
  answers and one that trickles, each served on 127.0.0.1; the download stops at the
  registry's size or the timeout, and nothing is left in the cache;
- ``--threads N`` / ``use(N)``: counts above 4 x the usable CPUs are refused;
- iteration counts (``--fit-steps``, ``--sharpen``, the Python entry points' ``steps``):
  refused above ``MAX_FIT_STEPS`` up front;
- frame rates and lengths: a clip whose resampling to the model's or training rate
  would make more frames than mrlib's bounds is refused before anything is resampled.

The command-line cases run in a child under the memory cap of ``capped``."""

from __future__ import annotations

import http.server
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from capped import PEAK_MB, run_capped, run_capped_python  # noqa: E402

from mrlib.datasets import bandai as datasets
from mrlib.datasets.bandai import DataFetchError
from mrlib.datasets.synthetic import synthetic_walk
from mrlib.errors import MrlibError
from mrlib.io import save_motion
from mrlib.model.config import ModelConfig, TrainConfig
from mrlib.representation.motion import Motion
from mrlib.training.data import TrainingSet
from mrlib.training.trainer import train

PREFIX = "/" + datasets.BANDAI_SUBDIR + "/"
FAST_S = 5.0  # each case: its one-line error within this
TINY = TrainConfig(
    model=ModelConfig(num_levels=2, gen_hidden=(24,), disc_hidden=(24,)),
    block_iterations=(1,),
    n_critic=1,
    checkpoint_every=0,
)


# -- downloads ------------------------------------------------------------------------------
class _Mirror:
    """A server on 127.0.0.1 whose every GET is answered by ``behaviour``: "endless" (a
    body with no length that never ends), "huge" (a Content-Length of 1 TB), "silent"
    (the connection accepted, nothing ever sent) or "trickle" (a byte every 0.3 s)."""

    def __init__(self, behaviour: str):
        self.stop, self.sent = threading.Event(), [0]
        outer = self

        class Handler(http.server.BaseHTTPRequestHandler):
            protocol_version = "HTTP/1.0"

            def do_GET(self):  # noqa: N802 (http.server's name)
                try:
                    if behaviour == "silent":
                        outer.stop.wait(30)
                        return
                    self.send_response(200)
                    if behaviour == "huge":
                        self.send_header("Content-Length", str(10**12))
                    self.end_headers()
                    block = b"x" * 65536 if behaviour in ("endless", "huge") else b"x"
                    while not outer.stop.is_set():
                        self.wfile.write(block)
                        outer.sent[0] += len(block)
                        if behaviour == "trickle":
                            outer.stop.wait(0.3)
                except OSError:
                    pass  # the client hung up: what a capped download does

            def log_message(self, *args):
                pass

        self.httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.httpd.daemon_threads = True
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}/{datasets.BANDAI_REF}"
        threading.Thread(target=self.httpd.serve_forever, daemon=True).start()

    def close(self):
        self.stop.set()
        self.httpd.shutdown()
        self.httpd.server_close()


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """An empty cache and no local dataset: what a fresh clone has."""
    monkeypatch.setenv("MRLIB_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv("MRLIB_DATA_DIR", str(tmp_path / "no-such-folder"))
    return tmp_path / "cache" / "bandai-namco-motion-1"


def _fetch_from(behaviour: str, monkeypatch) -> tuple[str, float, str, int]:
    srv = _Mirror(behaviour)
    try:
        monkeypatch.setenv("MRLIB_DATA_URL", srv.url)
        t = time.perf_counter()
        with pytest.raises(DataFetchError) as err:
            datasets.fetch_bandai(["walk_happy_001"], progress=False)
        return str(err.value), time.perf_counter() - t, srv.url, srv.sent[0]
    finally:
        srv.close()


def _files(cache: Path) -> list[Path]:
    return [p for p in cache.rglob("*") if p.is_file()] if cache.exists() else []


def test_the_registry_gives_every_files_size():
    reg, sizes = datasets.bandai_registry(), datasets.bandai_sizes()
    assert set(sizes) == set(reg) and all(s > 0 for s in sizes.values())
    assert datasets.download_cap("LICENSE") == sizes["LICENSE"]
    assert datasets.download_cap("data/unknown.bvh", {}) == datasets.CAP_BY_SUFFIX[".bvh"]


@pytest.mark.parametrize("behaviour", ["endless", "huge"])
def test_an_endless_body_stops_at_the_registry_size(cache, monkeypatch, behaviour):
    msg, seconds, url, sent = _fetch_from(behaviour, monkeypatch)
    cap = datasets.bandai_sizes()["LICENSE"]  # the first file fetched
    assert "\n" not in msg and url in msg and f"the {cap} bytes" in msg, msg
    assert "MRLIB_DATA_URL" in msg
    assert seconds < FAST_S
    assert _files(cache) == []  # no temporary file left behind
    if behaviour == "huge":
        assert "announces 1000000000000 bytes" in msg  # refused from the header


def test_a_silent_server_fails_after_one_timeout(cache, monkeypatch):
    assert datasets.TIMEOUT_S <= 20  # one try of at most 20 s, not two of 30
    monkeypatch.setattr(datasets, "TIMEOUT_S", 1.0)
    msg, seconds, url, _ = _fetch_from("silent", monkeypatch)
    assert "\n" not in msg and url in msg and "no answer within 1 s" in msg, msg
    assert "mrlib data fetch bandai" in msg and "MRLIB_DATA_URL" in msg
    assert seconds < 1.0 + FAST_S / 2  # one try: no second one
    assert _files(cache) == []


def test_a_trickling_server_is_given_up_at_the_deadline(cache, monkeypatch):
    monkeypatch.setattr(datasets, "file_deadline", lambda cap: 1.0)
    msg, seconds, url, _ = _fetch_from("trickle", monkeypatch)
    assert "\n" not in msg and url in msg and "KB/s" in msg and "nothing kept" in msg, msg
    assert seconds < FAST_S
    assert _files(cache) == []


def test_a_stale_temporary_in_the_cache_is_removed(cache, monkeypatch):
    import os

    (cache / "data").mkdir(parents=True)
    old, new = cache / "data" / "tmpab_cd123", cache / "data" / "tmpzz_zz999"
    for p in (old, new):
        p.write_bytes(b"x" * 1000)
    os.utime(old, (time.time() - 3600, time.time() - 3600))
    monkeypatch.setenv("MRLIB_DATA_URL", "http://127.0.0.1:9/nothing-listens")
    with pytest.raises(DataFetchError):
        datasets.fetch_bandai(["walk_happy_001"], progress=False)
    assert not old.exists() and new.exists()  # a running download's is kept


# -- the cases of the command line and of the Python API, each under the memory cap -------
@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory) -> Path:
    data = TrainingSet.from_motions([synthetic_walk("walk_sad", seconds=2.0, fps=10.0)])
    return train(data, TINY, tmp_path_factory.mktemp("ckpt"), progress=False).checkpoint


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict[str, Path]:
    from mrlib.sampling.constraints import Keyframe, save_keyframes

    tmp = tmp_path_factory.mktemp("clips")
    clip = synthetic_walk("walk_sad", seconds=2.4, fps=10.0)
    long = Motion(np.zeros((4000, 24, 3)), np.zeros((4000, 3)), 10.0, name="long")
    return {
        "clip": save_motion(clip, tmp / "clip.npz"),
        "slow": save_motion(clip.replace(fps=0.001), tmp / "slow.npz"),  # 24 frames, 6.7 h
        "long": save_motion(long, tmp / "long.npz"),  # 400 s: 400,000 frames at 1000 fps
        "keys": save_keyframes(tmp / "keys.npz", [Keyframe(0, clip.poses[0])]),
        "out": tmp / "out",
    }


def _cli_cases(ckpt: Path, f: dict[str, Path]) -> dict[str, tuple[list[str], str]]:
    """name -> (argv, text the one-line error must hold)."""
    ck, clip, slow, out = str(ckpt), str(f["clip"]), str(f["slow"]), str(f["out"])
    sample = ["sample", ck, "--out", out]
    resamples = "more than the 100000 mrlib resamples to"
    steps = "Adam steps are more than the 3000 of one noise fit"
    return {
        "info of a 0.001 fps clip at --fps 30": (["info", slow, "--fps", "30"], resamples),
        "export of it at --fps 30": (["export", slow, f"{out}.bvh", "--fps", "30"], resamples),
        "info of 400 s at --fps 1000": (["info", str(f["long"]), "--fps", "1000"], resamples),
        "restyle a 0.001 fps clip": (
            ["restyle", ck, slow, "--label", "walk_sad", "--out", out],
            "longer than the 600 s mrlib restyles",
        ),
        "sample --keyframes --fit-steps 1e8": (
            [*sample, "--keyframes", str(f["keys"]), "--seconds", "2", "--fit-steps", "1e8"],
            f"--fit-steps: 100000000 {steps}",
        ),
        "sample --continue --fit-steps 10**7": (
            [*sample, "--continue", clip, "--seconds", "2", "--fit-steps", "10000000"],
            f"--fit-steps: 10000000 {steps}",
        ),
        "sample --parts --sharpen 1e8": (
            [*sample, "--parts", "upper=walk_sad,lower=walk_sad", "--sharpen", "100000000"],
            f"--sharpen: 100000000 {steps}",
        ),
        "info --threads 10000": (["info", clip, "--threads", "10000"], "threads: 10000 is more"),
        "sample --threads 1e5": ([*sample, "--threads", "1e5"], "threads: 100000 is more than"),
        "data fetch from an endless mirror": (
            ["data", "fetch", "bandai", "--clips", "walk_sad_001"],
            f"the {datasets.bandai_sizes()['LICENSE']} bytes mrlib's registry gives",
        ),
    }


def test_the_command_line_refuses_runaway_work(checkpoint, files, tmp_path, monkeypatch):
    """Every case in one child under the memory cap: one line, the limit named, < 5 s
    and < 1 GB before the error, nothing written."""
    monkeypatch.setenv("MRLIB_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv("MRLIB_DATA_DIR", str(tmp_path / "no-such-folder"))
    monkeypatch.setenv("MRLIB_PROGRESS", "off")
    cases = _cli_cases(checkpoint, files)
    srv = _Mirror("endless")
    try:
        monkeypatch.setenv("MRLIB_DATA_URL", srv.url)
        results = run_capped([argv for argv, _ in cases.values()])
    finally:
        srv.close()
    assert len(results) == len(cases)
    for (name, (_, message)), r in zip(cases.items(), results, strict=True):
        err = "\n".join(line.rsplit("\r", 1)[-1] for line in r["err"].split("\n"))  # as shown
        assert r["code"] == 1, f"{name}: exit {r['code']}, {err!r}"
        assert err.startswith("error: ") and len(err.strip().splitlines()) == 1, f"{name}: {err!r}"
        assert message in err and "Traceback" not in err, f"{name}: {err!r}"
        assert r["s"] < FAST_S, f"{name}: {r['s']:.2f} s"
        assert r["peak_mb"] < PEAK_MB, f"{name}: peak {r['peak_mb']:.0f} MB"
    assert not files["out"].exists() and not Path(f"{files['out']}.bvh").exists()
    assert _files(tmp_path / "cache") == []


SETUP = """
import numpy as np
import mrlib
from mrlib.datasets.synthetic import synthetic_walk
from mrlib.io import load_motion
from mrlib.model.trained import load_model
from mrlib.representation.motion import Motion
from mrlib.sampling.constraints import (
    KeyframeFit, NoiseFit, Sharpening, continue_motion, generate_parts, generate_sharpened,
    generate_with_keyframes,
)
from mrlib.sampling.constraints.optimise import optimise_noise
from mrlib.sampling.restyling import restyle
from mrlib.training.data import TrainingSet
model = load_model({ckpt!r})
clip = synthetic_walk("walk_sad", seconds=2.4, fps=10.0)
slow = clip.replace(fps=0.001)  # 24 frames lasting 6.7 hours
"""

API_CASES = {
    # frame rates and lengths, refused before anything is resampled
    "restyle(a 0.001 fps clip)": (
        "restyle(model, slow, 'walk_sad')",
        "MotionValueError: mrlib.datasets.synthetic: 24 frames at 0.001 fps are 230001 frames",
    ),
    "restyle(a 0.001 fps file)": ("restyle(model, {slow!r}, 'walk_sad')", "longer than the 600 s"),
    "load_motion(fps=30)": (
        "load_motion({slow!r}, fps=30)",
        "more than the 100000 mrlib resamples",
    ),
    "Motion.resample of a 0.001 fps clip": ("slow.resample(30.0)", "would make 690001 frames"),
    "Motion.resample at fps 1e-300": (
        "Motion(clip.poses, clip.trans, 1e-300).resample(30.0)",
        "more than the 100000 mrlib resamples",
    ),
    "TrainingSet of a 0.001 fps clip": (
        "TrainingSet.from_motions([slow], fps=30)",
        "690001 frames at 30 fps, more than the 18000 a training clip may have",
    ),
    "continue_motion(a 0.001 fps prefix)": (
        "continue_motion(model, slow, 20)",
        "longer than the 600 s mrlib generates in one sample",
    ),
    # iteration counts, refused up front
    "generate_with_keyframes(steps=1e8)": (
        "generate_with_keyframes(model, [], 20, fit=KeyframeFit(steps=10**8))",
        "steps: 100000000 Adam steps",
    ),
    "continue_motion(steps=1e8)": (
        "continue_motion(model, clip, 20, fit=NoiseFit(steps=10**8))",
        "the 3000",
    ),
    "generate_sharpened(steps=1e8)": (
        "generate_sharpened(model, 'walk_sad', fit=Sharpening(steps=10**8))",
        "steps: 100000000 Adam steps",
    ),
    "generate_parts(sharpen=1e8)": (
        "generate_parts(model, {{'upper': 'walk_sad', 'lower': 'walk_sad'}}, sharpen=10**8)",
        "sharpen (steps): 100000000 Adam steps",
    ),
    "optimise_noise(steps=1e8)": (
        "optimise_noise(model, [], [], None, steps=10**8)",
        "steps: 100000000 Adam steps",
    ),
    "use(10000)": ("mrlib.threads.use(10000)", "threads: 10000 is more than"),
}


def test_the_python_api_refuses_runaway_work(checkpoint, files):
    fill = {"slow": str(files["slow"])}
    setup = SETUP.format(ckpt=str(checkpoint))
    results = run_capped_python(setup, [code.format(**fill) for code, _ in API_CASES.values()])
    assert len(results) == len(API_CASES)
    for (name, (_, message)), r in zip(API_CASES.items(), results, strict=True):
        err = r["error"]
        assert err is not None and message in err and "\n" not in err, f"{name}: {err!r}"
        assert r["s"] < FAST_S, f"{name}: {r['s']:.2f} s"
        assert r["peak_mb"] < PEAK_MB, f"{name}: peak {r['peak_mb']:.0f} MB"


# -- what stays allowed ---------------------------------------------------------------------
def test_thread_counts_up_to_four_per_cpu_work(monkeypatch):
    import torch

    from mrlib import threads
    from mrlib.app.cli import main

    before = torch.get_num_threads()
    cpus = threads.usable_cpus()
    for n in (1, cpus, 4 * cpus):  # the policy and torch's count restored after each
        with threads.policy(n):
            assert torch.get_num_threads() == n
    with pytest.raises(MrlibError, match=rf"more than the {4 * cpus} .*--threads N"):
        threads.use(4 * cpus + 1)  # refused before anything is set
    assert torch.get_num_threads() == before
    monkeypatch.setattr("mrlib.app.cli._cmd_info", lambda args: 0)
    assert main(["info", "x.npz", "--threads", str(cpus)]) == 0


def test_fit_steps_up_to_the_cap_are_taken():
    from mrlib.sampling.constraints.keyframes import FIT_STEPS
    from mrlib.sampling.constraints.optimise import MAX_FIT_STEPS, check_fit_steps

    assert MAX_FIT_STEPS >= 10 * FIT_STEPS
    assert check_fit_steps(MAX_FIT_STEPS) == MAX_FIT_STEPS
    assert check_fit_steps(np.int64(5)) == 5 and check_fit_steps(100.0) == 100
    with pytest.raises(MrlibError, match="integer >= 1"):
        check_fit_steps(0, minimum=1)
    with pytest.raises(MrlibError, match="integer >= 0"):
        check_fit_steps(2.5)


def test_resampling_in_pieces_gives_the_same_motion(monkeypatch):
    import mrlib.representation.motion as motion

    clip = synthetic_walk("walk_happy", seconds=2.0, fps=30.0)
    whole = clip.resample(47.0)
    monkeypatch.setattr(motion, "_CHUNK", 7)
    pieces = clip.resample(47.0)
    assert pieces.num_frames == whole.num_frames == clip.resampled_frames(47.0)
    np.testing.assert_array_equal(pieces.poses, whole.poses)
    np.testing.assert_array_equal(pieces.trans, whole.trans)


def test_resampling_to_many_frames_from_many_frames_is_taken():
    """The cap is on what resampling adds: a long clip may be resampled to about its own
    length, and any clip down."""
    from mrlib.representation.motion import MAX_RESAMPLE_FRAMES

    n = MAX_RESAMPLE_FRAMES + 10
    big = Motion(np.zeros((n, 24, 3)), np.zeros((n, 3)), 100.0)
    assert big.resampled_frames(99.0) < n and big.resampled_frames(101.0) > n
    with pytest.raises(MrlibError, match="mrlib resamples to"):
        big.resample(101.0)
    assert big.resample(10.0).num_frames == (n - 1) // 10 + 1


def test_the_training_bound_matches_the_commands():
    from mrlib.app.cli.train import MAX_TRAIN_CLIP_FRAMES as cli
    from mrlib.training.data import MAX_TRAIN_CLIP_FRAMES as api

    assert cli == api
