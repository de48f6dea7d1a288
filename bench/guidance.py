"""Label guidance on a trained model: ``GenerativeModel.guidance`` against fidelity and
closeness to the training motion.

For each ``--guidance`` value, ``--samples`` samples per label of twice the label's
training clip (seed 0, one torch thread) from a checkpoint (default: the `tutorial`
model of ``bench/condition_control.py``). Prints, averaged over the labels: condition
fidelity of the whole body and of the upper and lower body alone
(``mrlib.constraints.part_fidelity``, the measure of body-part composition), coverage of
the label's clip (eps 2 and 1), global and local diversity against it, and the raw
samples' joint jerk (over the label's clip's) and foot skating; the figures except
jerk and skating are of the cleaned samples.

    python bench/guidance.py [--checkpoint ckpt.pt] [--guidance 0,0.25,0.5,1] [--samples 5]
"""

from __future__ import annotations

import argparse

import numpy as np
from tutorial_checkpoint import add_checkpoint_arg, load

from mrlib.constraints import part_fidelity
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
    ap.add_argument("--guidance", default="0,0.25,0.5,1", help="values [0,0.25,0.5,1]")
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
    print("| guidance | fidelity % whole / upper / lower | worst part % | coverage eps 2 / 1 % "
          "| global div. | local div. | raw jerk | raw skating % |")  # fmt: skip
    print("|---:|---|---:|---:|---:|---:|---:|---:|")
    for g in (float(x) for x in a.guidance.split(",")):
        model.guidance = g
        rows, worst = [], 1.0
        for lab in model.labels:
            raw = generate(model, lab, length=2 * train[lab].num_frames, seed=0,
                           num_samples=a.samples, fix_contacts=False)  # fmt: skip
            clean = [cleanup_foot_contacts(m, body) for m in raw]
            f = [metric_features(m) for m in clean]
            part = part_fidelity(clean, model, {"upper": lab, "lower": lab})
            worst = min(worst, *part.values())
            rows.append([
                condition_fidelity([(h, lab) for h in f], refs), part["upper"], part["lower"],
                coverage(f, refs[lab]), coverage(f, refs[lab], eps=1.0),
                global_diversity(f, refs[lab]), local_diversity(f, refs[lab]),
                np.mean([jerk(m) for m in raw]) / own[lab], np.mean([skate(m) for m in raw]),
            ])  # fmt: skip
        r = np.mean(rows, 0)
        print(f"| {g:g} | {100 * r[0]:.1f} / {100 * r[1]:.1f} / {100 * r[2]:.1f} | "
              f"{100 * worst:.1f} | {100 * r[3]:.1f} / {100 * r[4]:.1f} | {r[5]:.3f} | "
              f"{r[6]:.3f} | {r[7]:.2f} | {100 * r[8]:.1f} |", flush=True)  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
