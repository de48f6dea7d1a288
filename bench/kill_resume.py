"""``kill -9`` during ``mrlib train`` at random moments, then ``--resume``: is the result
the same as an uninterrupted run?

Trains a small model (3 levels, a checkpoint every iteration, so many kills land inside
a checkpoint write) from the command line, SIGKILLs it after a random delay, resumes
with ``--resume`` until done, and compares the final checkpoint's weights with those of
an uninterrupted run, bit for bit (CPU). Also checks after every kill that the
checkpoint on disk loads (checksum included):

    python bench/kill_resume.py --trials 20

Prints one line per trial and the count of identical results.
"""

from __future__ import annotations

import argparse
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _train_cmd(clip: Path, out: Path, resume: bool) -> list[str]:
    cmd = [sys.executable, "-m", "mrlib.app.cli", "train", "--no-progress", "--out", str(out)]
    if resume:
        return cmd + ["--resume", str(out / "checkpoint.pt")]
    return cmd + [
        str(clip),
        "--levels",
        "3",
        "--iterations",
        "30,30",
        "--seed",
        "1",
        "--checkpoint-every",
        "1",
    ]


def _weights(path: Path):
    from mrlib.model.checkpoint import load_checkpoint

    state = load_checkpoint(path)
    return state["generator"], state["critics"], state["progress"]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--trials", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0, help="seed of the kill times")
    args = ap.parse_args(argv)

    import torch

    from mrlib.datasets.synthetic import synthetic_walk
    from mrlib.io import save_motion

    env = dict(os.environ, OMP_NUM_THREADS="1")
    rng = random.Random(args.seed)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        clip = save_motion(synthetic_walk("walk_sad", seconds=3.0, fps=10.0), tmp / "clip.npz")
        ref_out = tmp / "reference"
        t0 = time.perf_counter()
        subprocess.run(_train_cmd(clip, ref_out, False), check=True, env=env, capture_output=True)
        full_s = time.perf_counter() - t0
        ref = _weights(ref_out / "checkpoint.pt")
        same = writes = 0
        for k in range(args.trials):
            out = tmp / f"trial{k}"
            delay = rng.uniform(0.3 * full_s, 0.9 * full_s)
            proc = subprocess.Popen(
                _train_cmd(clip, out, False),
                env=env,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
            time.sleep(delay)
            proc.send_signal(signal.SIGKILL)
            proc.wait()
            ok_after_kill = (out / "checkpoint.pt").is_file()
            mid_write = out.is_dir() and any(".tmp" in f.name for f in out.iterdir())
            writes += mid_write
            if ok_after_kill:
                _weights(out / "checkpoint.pt")  # loads, checksum included
                done = subprocess.run(
                    _train_cmd(clip, out, True), env=env, capture_output=True, text=True
                )
                if done.returncode != 0:
                    print(f"trial {k}: resume failed: {done.stderr.strip()[-300:]}")
                    continue
            else:  # killed before the first checkpoint: start again
                subprocess.run(
                    _train_cmd(clip, out, False), check=True, env=env, capture_output=True
                )
            g, c, p = _weights(out / "checkpoint.pt")
            identical = all(torch.equal(g[n], ref[0][n]) for n in g) and all(
                torch.equal(c[n], ref[1][n]) for n in c
            )
            same += identical and p["done"]
            left = [f.name for f in out.iterdir() if ".tmp" in f.name]
            print(
                f"trial {k}: killed after {delay:.2f} s{' during a checkpoint write' if mid_write else ''}, "
                f"checkpoint {'there' if ok_after_kill else 'not yet written'}, "
                f"resumed to the end: {'identical' if identical else 'DIFFERENT'}; temporary files left: {left or 'none'}",
                flush=True,
            )
    print(
        f"\n{same} of {args.trials} resumed runs identical to the uninterrupted one, {writes} "
        f"killed during a checkpoint write (uninterrupted run {full_s:.1f} s)"
    )
    return 0 if same == args.trials else 1


if __name__ == "__main__":
    sys.exit(main())
