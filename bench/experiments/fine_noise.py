"""Jitter against the finest level's noise: ``Sampler.fine_noise`` on a trained model.

For each ``--fine`` value, ``--samples`` samples per label of twice the label's training
clip (seed 0, one torch thread) from a checkpoint (default: the `tutorial` model of
``bench/condition_control.py``), raw and after the foot-contact clean-up. Prints the
mean joint jerk over the label's own training clip's (raw, cleaned), and for the cleaned
samples coverage (eps 2 and 1), global and local diversity against the label's clip,
condition fidelity and the skating share. Crossover figures at each value:
``python bench/condition_control.py --fine-noise F``.

    python bench/experiments/fine_noise.py [--checkpoint ckpt.pt] [--fine 1,0.5,0] [--samples 5]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # bench/: common.py

from common import add_checkpoint_arg, checkpoint_model
from label_clips import LabelClips

from mrlib.sampling.sampler import Sampler


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_checkpoint_arg(ap)
    ap.add_argument("--fine", default="1,0.5,0", help="fine_noise values [1,0.5,0]")
    ap.add_argument("--samples", type=int, default=5, help="samples per label [5]")
    a = ap.parse_args()
    model, body = checkpoint_model(ap, a.checkpoint)
    clips = LabelClips(model, body)
    print(f"{a.checkpoint}: {a.samples} samples per label, twice the label's clip\n")
    print("| fine_noise | jerk raw | jerk cleaned | coverage eps 2 / 1 % | global div. | "
          "local div. | cond. fidelity % | skating raw / cleaned % |")  # fmt: skip
    print("|---:|---:|---:|---:|---:|---:|---:|---:|")
    for fine in (float(x) for x in a.fine.split(",")):
        r = clips.measure(model, a.samples, Sampler(fine_noise=fine))
        print(f"| {fine:g} | {r['jerk_raw']:.2f} | {r['jerk_clean']:.2f} | "
              f"{100 * r['coverage']:.1f} / {100 * r['coverage_eps1']:.1f} | "
              f"{r['global_div']:.3f} | {r['local_div']:.3f} | {100 * r['fidelity']:.1f} | "
              f"{100 * r['skating_raw']:.1f} / {100 * r['skating_clean']:.1f} |", flush=True)  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
