"""Time to generate one-minute motions, raw and with the foot-contact clean-up.

Networks of the ``tutorial`` preset (its weights barely trained: speed does not depend
on them) on the four synthetic clips of ``data_samples/`` at 30 fps, so a one-minute
sample has 1800 frames. Prints the time per call for 1, 8 and 64 samples in one batch,
raw, and the clean-up of a one-minute synthetic walk (contacts labelled from its own
motion) with the analytic IK (``method="ik"``, the default) against the per-frame
optimisation it replaces (``method="optimise"``), as a ratio measured in the same run:

    python bench/sample_speed.py [--threads 1] [--repeats 3] [--checkpoint ckpt.pt]

Writes ``bench/results/sample_speed.json``.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _best(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--checkpoint", type=Path, default=None, help="a trained model [train one]")
    args = ap.parse_args(argv)

    import torch

    import mrlib
    import mrlib.synthetic
    from mrlib.config import tutorial
    from mrlib.data import TrainingSet
    from mrlib.demo import DATA_SAMPLES
    from mrlib.sample import cleanup_foot_contacts, generate, load_model
    from mrlib.train import train

    torch.set_num_threads(args.threads)
    body = mrlib.load_body_model()
    with tempfile.TemporaryDirectory() as tmp:
        ckpt = args.checkpoint
        if ckpt is None:
            clips = [mrlib.load_motion(p) for p in sorted(DATA_SAMPLES.glob("*.npz"))]
            cfg = tutorial().replace(block_iterations=(2, 2, 2, 2), checkpoint_every=0)
            ckpt = train(
                TrainingSet.from_motions(clips, body=body), cfg, tmp, body=body, progress=False
            ).checkpoint
        model = load_model(ckpt)
    T = round(60 * model.fps)
    label = model.labels[0]
    rows = {}
    generate(model, label, length=T, seed=0)  # warm-up
    for n in (1, 8, 64):
        rows[f"generate {n} x 1 min (raw), s per call"] = _best(
            lambda n=n: generate(model, label, length=T, seed=0, num_samples=n), args.repeats
        )
    # a one-minute walk with contacts labelled from its own motion (a barely trained
    # model predicts few contacts, which would leave the clean-up nothing to do)
    m = mrlib.synthetic.synthetic_walk("walk_normal", seconds=60.0, fps=model.fps, body=body)
    m = m.replace(contacts=mrlib.foot_contacts(m, body))
    ik = _best(lambda: cleanup_foot_contacts(m, body, method="ik"), args.repeats)
    opt = _best(lambda: cleanup_foot_contacts(m, body, method="optimise"), 1)
    rows["clean-up of 1 min, analytic IK, s"] = ik
    rows["clean-up of 1 min, per-frame optimisation, s"] = opt
    rows["generate 1 x 1 min + IK clean-up, s"] = _best(
        lambda: generate(model, label, length=T, seed=0, fix_contacts=True), args.repeats
    )
    print(
        f"{T} frames at {model.fps:g} fps, {args.threads} torch thread(s), {platform.processor() or platform.machine()}\n"
    )
    print("| what | seconds |\n|---|---:|")
    for k, v in rows.items():
        print(f"| {k} | {v:.3f} |")
    print(
        f"\nanalytic IK is {opt / ik:.0f}x faster than the per-frame optimisation (same clip, same run)"
    )
    out = ROOT / "bench" / "results"
    out.mkdir(parents=True, exist_ok=True)
    (out / "sample_speed.json").write_text(
        json.dumps({"frames": T, "threads": args.threads, **rows}, indent=2)
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
