"""The load follower mid-run (docs/notes/2026-12-04-threads.md, 2026-12-05 section).

Trains one block of the ``demo`` preset on ``data_samples/walk_happy.npz`` and
``walk_sad.npz`` at 15 fps for ``--seconds``, ticking ``mrlib.threads.load_follower``
after every iteration as ``Trainer.fit`` does; a CPU-bound busy loop joins at
``--join`` seconds and leaves at ``--leave``. Prints, every 3 s, iterations per second,
torch's thread count and the other processes' CPUs the follower last measured.

    python bench/experiments/follow_load.py [--block 3] [--seconds 45] [--join 12] [--leave 30]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # bench/: common.py

from common import ROOT, describe


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--block", type=int, default=3, help="0-based block to train [3]")
    ap.add_argument("--seconds", type=float, default=45.0)
    ap.add_argument("--join", type=float, default=12.0, help="the busy loop starts [12 s]")
    ap.add_argument("--leave", type=float, default=30.0, help="and stops [30 s]")
    a = ap.parse_args()
    import torch

    import mrlib
    from mrlib.threads import apply_policy, load_follower
    from mrlib.training.data import TrainingSet
    from mrlib.training.trainer import Trainer

    apply_policy()
    clips = [ROOT / "data_samples" / f"{n}.npz" for n in ("walk_happy", "walk_sad")]
    data = TrainingSet.from_files(clips, fps=15.0)
    tr = Trainer(data, mrlib.get_preset("demo"), "/tmp/mrlib-follow-load-unused")
    tr.block = a.block
    tr.start_block()
    follower = load_follower()
    if follower is None:
        sys.exit("no follower here: the thread count is set by the user, one CPU, or no /proc/stat")
    print(describe())
    print(f"start: {follower.threads} thread(s)", flush=True)
    t0 = tw = time.monotonic()
    busy, its = None, 0
    try:
        while time.monotonic() - t0 < a.seconds:
            tr.step()
            follower.tick()
            its += 1
            now = time.monotonic()
            if now - tw >= 3.0:
                others = follower.history[-1][1] if follower.history else float("nan")
                print(f"t = {now - t0:5.1f} s: {its / (now - tw):5.1f} it/s, "
                      f"{torch.get_num_threads()} thread(s), others {others:.2f} CPUs, "
                      f"busy loop {'on' if busy else 'off'}", flush=True)  # fmt: skip
                its, tw = 0, now
            if busy is None and now - t0 > a.join:
                busy = subprocess.Popen([sys.executable, "-c", "while True: pass"])
            if busy and now - t0 > a.leave:
                busy.kill()
                busy = False
    finally:
        if busy:
            busy.kill()
    return 0


if __name__ == "__main__":
    sys.exit(main())
