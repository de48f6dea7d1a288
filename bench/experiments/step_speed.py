"""Training iterations per second of a label preset, block by block, on real clips, and
the same against another checkout of mrlib, alternating, so that both see the same
machine.

    python bench/experiments/step_speed.py                       # this checkout
    git worktree add /tmp/before <commit>
    python bench/experiments/step_speed.py --against /tmp/before --rounds 2

Per checkout and round, in a fresh process on one torch thread: a ``Trainer`` of the
preset (``demo``, 30 fps) on the five held-out Bandai walks (``bench/heldout.py``'s
``HELDOUT_STYLES``), each block started (``Trainer.start_block``) and stepped ``--steps``
times after one warm-up step. Printed per process: iterations/s per block (the best of
two timings) and the block budget's projected training time; then, with ``--against``,
the ratio of the projected times (the best round of each checkout).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent


def measure(preset: str, steps: int) -> dict:
    """In this process (mrlib from ``sys.path``): iterations/s per block."""
    import tempfile
    import time

    import torch

    torch.set_num_threads(1)
    import mrlib
    from mrlib.datasets.bandai import tutorial_clips
    from mrlib.model.presets import get_preset
    from mrlib.training.data import TrainingSet
    from mrlib.training.trainer import Trainer

    sys.path.insert(0, str(ROOT / "bench"))
    from heldout import HELDOUT_STYLES

    src = tutorial_clips([f"walk_{s}_001" for s in HELDOUT_STYLES], fetch=True)
    if src.synthetic:
        raise SystemExit(f"the Bandai clips are needed: {src.note}")
    cfg = get_preset(preset)
    body = mrlib.load_body_model()
    clips = [mrlib.load_motion(p, fps=cfg.fps) for p in src.paths]
    data = TrainingSet.from_motions(clips, body=body)
    with tempfile.TemporaryDirectory() as out:
        tr = Trainer(data, cfg, out, body=body)
        best = []
        for block in range(cfg.num_blocks):
            tr.block, tr.active = block, None
            tr.start_block()
            tr.step()
            times = []
            for _ in range(2):
                t = time.perf_counter()
                for _ in range(steps):
                    tr.step()
                times.append((time.perf_counter() - t) / steps)
            best.append(min(times))
    projected = sum(n * s for n, s in zip(cfg.block_iterations, best, strict=True))
    return {"mrlib": mrlib.__file__, "its": [1 / s for s in best], "projected_s": projected}


def run(checkout: Path, preset: str, steps: int) -> dict:
    code = (
        f"import sys, json; sys.path.insert(0, {str(checkout)!r}); "
        f"sys.path.insert(1, {str(HERE)!r}); import step_speed; "
        f"print(json.dumps(step_speed.measure({preset!r}, {steps})))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    res = json.loads(out.stdout.strip().splitlines()[-1])
    if not res["mrlib"].startswith(str(checkout)):
        raise SystemExit(f"{checkout}: imported mrlib from {res['mrlib']}")
    return res


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--preset", default="demo", help="label preset [demo]")
    p.add_argument("--steps", type=int, default=15, help="timed steps per block, twice [15]")
    p.add_argument("--rounds", type=int, default=1, help="processes per checkout [1]")
    p.add_argument("--against", type=Path, default=None, help="another checkout of mrlib")
    a = p.parse_args(argv)
    checkouts = [ROOT] + ([a.against.resolve()] if a.against else [])
    best: dict[Path, float] = {}
    for r in range(a.rounds):
        for c in checkouts:
            res = run(c, a.preset, a.steps)
            its = " / ".join(f"{v:.1f}" for v in res["its"])
            print(f"round {r}, {c}: it/s per block {its}; "
                  f"projected {res['projected_s']:.0f} s", flush=True)  # fmt: skip
            best[c] = min(best.get(c, float("inf")), res["projected_s"])
    if a.against:
        ratio = best[checkouts[1]] / best[ROOT]
        print(f"projected training time, {checkouts[1]} / this checkout: {ratio:.2f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
