"""Quality of the foot-contact clean-up on a trained model's samples: skating and jerk.

For ``--samples`` seeds per label of a checkpoint (default: the `tutorial` model of
``bench/condition_control.py``), prints the mean joint jerk over the training clips'
mean jerk, the share of contact vertex-frames sliding faster than the skating threshold
and the mean contact-foot speed, for the raw samples, the pinning clean-up as it was
before the root's correction was low-passed (root correction frame by frame, blend 2/15 s:
``experiments/cleanup_studies.py``'s ``cleanup_pinned``), and the defaults
(``cleanup_foot_contacts``); the training clips on the last row.

    python bench/cleanup_quality.py [--checkpoint ckpt.pt] [--samples 2] [--frames 400]
"""

from __future__ import annotations

import argparse

import numpy as np
from common import add_checkpoint_arg, checkpoint_model
from experiments.cleanup_studies import cleanup_pinned

from mrlib.metrics.plausibility import foot_skating, mean_jerk, motion_kinematics
from mrlib.representation.features import features_to_motion
from mrlib.sampling.cleanup import cleanup_foot_contacts
from mrlib.sampling.generation import generate
from mrlib.sampling.sampler import Sampler


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_checkpoint_arg(ap)
    ap.add_argument("--samples", type=int, default=2, help="seeds per label [2]")
    ap.add_argument("--frames", type=int, default=400, help="frames at 30 fps per sample [400]")
    a = ap.parse_args()
    model, body = checkpoint_model(ap, a.checkpoint)
    fps = model.fps
    train = [features_to_motion(x, fps, betas=model.betas) for x in model.features]
    jerk0 = np.mean([mean_jerk(motion_kinematics(m, body)[0], fps) for m in train])

    def row(name, ms):
        jr, share, speed = [], [], []
        for m in ms:
            J, F = motion_kinematics(m, body)
            jr.append(mean_jerk(J, fps) / jerk0)
            sp, sh = foot_skating(F, m.contacts, fps)
            share.append(sh)
            speed.append(sp)
        print(f"| {name} | {np.mean(jr):.2f} | {100 * np.mean(share):.1f} | {np.mean(speed):.3f} |")

    n = max(2, round(a.frames * fps / 30))
    raw = [generate(model, lab, length=n, seed=s, sampler=Sampler(fix_contacts=False))
           for lab in model.labels for s in range(a.samples)]  # fmt: skip
    print(f"{a.checkpoint}: {len(raw)} samples of {n} frames at {fps:g} fps\n")
    print(
        "| samples | jerk / training | skating % | contact-foot speed m/s |\n|---|---:|---:|---:|"
    )
    row("raw", raw)
    old = [cleanup_pinned(m, body, blend=max(1, round(2 / 15 * fps)), root_smooth_s=0.0)
           for m in raw]  # fmt: skip
    row("cleaned, root frame by frame, blend 2/15 s", old)
    row("cleaned, defaults", [cleanup_foot_contacts(m, body) for m in raw])
    row("training clips", train)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
