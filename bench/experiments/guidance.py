"""Label guidance on a trained model: ``Sampler.guidance`` against fidelity and
closeness to the training motion.

For each ``--guidance`` value, ``--samples`` samples per label of twice the label's
training clip (seed 0, one torch thread) from a checkpoint (default: the `tutorial`
model of ``bench/condition_control.py``). Prints, averaged over the labels: condition
fidelity of the whole body and of the upper and lower body alone
(``mrlib.sampling.constraints.part_fidelity``, the measure of body-part composition), coverage of
the label's clip (eps 2 and 1), global and local diversity against it, and the raw
samples' joint jerk (over the label's clip's) and foot skating; the figures except
jerk and skating are of the cleaned samples.

    python bench/experiments/guidance.py [--checkpoint ckpt.pt] [--guidance 0,0.25,0.5,1] [--samples 5]
    python bench/experiments/guidance.py --guidance 0 --noise-scale 1,0.75,0.5 [--noise-levels coarse]

``--noise-scale`` multiplies the sampling noise's sigma (every level, or with
``--noise-levels coarse`` level 1 only), a truncation of the noise as in BigGAN (Brock et
al. 2019): each value is measured at every guidance value.
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
    ap.add_argument("--guidance", default="0,0.25,0.5,1", help="values [0,0.25,0.5,1]")
    ap.add_argument("--samples", type=int, default=5, help="samples per label [5]")
    ap.add_argument("--noise-scale", default="1", help="factors on the noise sigma [1]")
    ap.add_argument("--noise-levels", choices=["all", "coarse"], default="all",
                    help="levels whose noise --noise-scale scales [all]")  # fmt: skip
    a = ap.parse_args()
    model, body = checkpoint_model(ap, a.checkpoint)
    clips = LabelClips(model, body)
    print(f"{a.checkpoint}: {a.samples} samples per label, twice the label's clip\n")
    print("| guidance | noise scale | fidelity % whole / upper / lower | worst part % "
          "| coverage eps 2 / 1 % | global div. | local div. | raw jerk | raw skating % |")  # fmt: skip
    print("|---:|---:|---|---:|---:|---:|---:|---:|---:|")
    sigma = model.sigma.clone()
    grid = [(float(g), float(t)) for g in a.guidance.split(",") for t in a.noise_scale.split(",")]
    for g, t in grid:
        model.sigma = sigma.clone()
        if a.noise_levels == "all":
            model.sigma *= t
        else:
            model.sigma[:, 0] *= t
        r = clips.measure(model, a.samples, Sampler(guidance=g))
        print(f"| {g:g} | {t:g} | {100 * r['fidelity']:.1f} / {100 * r['upper']:.1f} / "
              f"{100 * r['lower']:.1f} | {100 * r['worst_part']:.1f} | "
              f"{100 * r['coverage']:.1f} / {100 * r['coverage_eps1']:.1f} | "
              f"{r['global_div']:.3f} | {r['local_div']:.3f} | {r['jerk_raw']:.2f} | "
              f"{100 * r['skating_raw']:.1f} |", flush=True)  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
