"""Label guidance away from one other label instead of the mean of all labels: does a
part that the mean-guided sampler leaves short (the normal walk's legs) gain when its
condition is pushed away from the label it is mistaken for?

For each label ``a`` and each reference ``r`` (``mean``, or each other label ``b``),
``--samples`` samples of twice the longest training clip (seed 0, one torch thread, feet
planted as in ``generate``) under the per-level weights ``W_a + g (W_a - W_r)``: for
``mean`` that is ``Sampler(guidance=g)``, for a label ``b`` the blend ``(b, a, 1 + g)``
(a negative weight on ``b``, the FiLM embedding being linear in the condition; a weight
``Condition.blend`` refuses, so the condition is built from its field). Prints the part's fidelity (``mrlib.sampling.constraints.part_fidelity``, the measure
of body-part composition) per label and reference.

    python bench/experiments/guidance_away.py --checkpoint RUN/checkpoint.pt [--part lower] [--guidance 0.5]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # bench/: common.py

from common import add_checkpoint_arg, checkpoint_model

from mrlib.sampling.cleanup import cleanup_foot_contacts
from mrlib.sampling.conditions import Condition
from mrlib.sampling.constraints import part_fidelity
from mrlib.sampling.generation import generate
from mrlib.sampling.sampler import Sampler


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_checkpoint_arg(ap)
    ap.add_argument("--part", choices=["upper", "lower"], default="lower", help="[lower]")
    ap.add_argument("--guidance", type=float, default=0.5, help="g [0.5]")
    ap.add_argument("--samples", type=int, default=10, help="samples per case [10]")
    a = ap.parse_args()
    model, body = checkpoint_model(ap, a.checkpoint)
    length = 2 * int(model.lengths[:, -1].max())
    labs = model.labels
    print(f"{a.checkpoint}: {a.part} fidelity, g = {a.guidance:g}, {a.samples} samples\n")
    print(f"| label | away from the mean | {' | '.join(f'away from {b}' for b in labs)} |")
    print("|---|---:|" + "---:|" * len(labs))
    for lab in labs:
        cells = []
        for ref in ["mean", *labs]:
            if ref == lab:
                cells.append("")
                continue
            if ref == "mean":
                cond, sampler = lab, Sampler(guidance=a.guidance, fix_contacts=False)
            else:
                cond = Condition(blend_of=(ref, lab, (1 + a.guidance,)))
                sampler = Sampler(fix_contacts=False)
            ms = generate(model, cond, length=length, seed=0, num=a.samples, sampler=sampler)
            ms = [cleanup_foot_contacts(m, body) for m in ms]
            f = part_fidelity(ms, model, {a.part: lab})[a.part]
            cells.append(f"{100 * f:.1f} %")
        print(f"| {lab} | {' | '.join(cells)} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
