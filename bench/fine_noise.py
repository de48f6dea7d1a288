"""Jitter against the finest level's noise: ``GenerativeModel.fine_noise`` on a trained model.

For each ``--fine`` value, ``--samples`` samples per label of twice the label's training
clip (seed 0, one torch thread) from a checkpoint (default: the `tutorial` model of
``bench/condition_control.py``), raw and after the foot-contact clean-up. Prints the
mean joint jerk over the label's own training clip's (raw, cleaned), and for the cleaned
samples coverage (eps 2 and 1), global and local diversity against the label's clip,
condition fidelity and the skating share. Crossover figures at each value:
``python bench/condition_control.py --fine-noise F``.

    python bench/fine_noise.py [--checkpoint ckpt.pt] [--fine 1,0.5,0] [--samples 5]
"""

from __future__ import annotations

import argparse

import numpy as np
from tutorial_checkpoint import add_checkpoint_arg, load

from mrlib.features import features_to_motion
from mrlib.footik import cleanup_foot_contacts
from mrlib.metrics import (
    condition_fidelity,
    coverage,
    global_diversity,
    local_diversity,
    metric_features,
)
from mrlib.plausibility import foot_skating, mean_jerk, motion_kinematics
from mrlib.sample import generate


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_checkpoint_arg(ap)
    ap.add_argument("--fine", default="1,0.5,0", help="fine_noise values [1,0.5,0]")
    ap.add_argument("--samples", type=int, default=5, help="samples per label [5]")
    a = ap.parse_args()
    model, body = load(ap, a.checkpoint)
    fps = model.fps
    train = {
        model.labels[model.clip_labels[k]]: features_to_motion(x, fps, betas=model.betas)
        for k, x in enumerate(model.features)
    }
    refs = {lab: metric_features(m) for lab, m in train.items()}

    def jerk(m):
        return mean_jerk(motion_kinematics(m, body)[0], fps)

    def skate(m):
        return foot_skating(motion_kinematics(m, body)[1], m.contacts, fps)[1]

    own = {lab: jerk(m) for lab, m in train.items()}
    print(f"{a.checkpoint}: {a.samples} samples per label, twice the label's clip\n")
    print("| fine_noise | jerk raw | jerk cleaned | coverage eps 2 / 1 % | global div. | "
          "local div. | cond. fidelity % | skating raw / cleaned % |")  # fmt: skip
    print("|---:|---:|---:|---:|---:|---:|---:|---:|")
    for fine in (float(x) for x in a.fine.split(",")):
        model.fine_noise = fine
        rows = []
        for lab in model.labels:
            raw = generate(model, lab, length=2 * train[lab].num_frames, seed=0,
                           num_samples=a.samples, fix_contacts=False)  # fmt: skip
            clean = [cleanup_foot_contacts(m, body) for m in raw]
            f = [metric_features(m) for m in clean]
            rows.append([
                np.mean([jerk(m) for m in raw]) / own[lab],
                np.mean([jerk(m) for m in clean]) / own[lab],
                coverage(f, refs[lab]), coverage(f, refs[lab], eps=1.0),
                global_diversity(f, refs[lab]), local_diversity(f, refs[lab]),
                condition_fidelity([(g, lab) for g in f], refs),
                np.mean([skate(m) for m in raw]), np.mean([skate(m) for m in clean]),
            ])  # fmt: skip
        r = np.mean(rows, 0)
        print(f"| {fine:g} | {r[0]:.2f} | {r[1]:.2f} | {100 * r[2]:.1f} / {100 * r[3]:.1f} | "
              f"{r[4]:.3f} | {r[5]:.3f} | {100 * r[6]:.1f} | {100 * r[7]:.1f} / {100 * r[8]:.1f} |",
              flush=True)  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
