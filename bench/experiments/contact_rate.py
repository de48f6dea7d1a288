"""How many frames the samples of a ``bench/heldout.py`` model label in contact, against
the label's training clip (docs/notes/2026-12-07-contact-rate.md).

    python bench/experiments/contact_rate.py --split heldout --seed 1
    python bench/experiments/contact_rate.py --split dev --seed 1 --preset preview

Per label of the cached model (trained there first when missing), over ``--samples`` raw
draws of twice the clip (the default sampler's best of 8, no clean-up): the share of frames
in contact per foot vertex, mean over the six vertices and its range, for the training
clip, for the samples with the generator's contact output cut at 0.5 (the paper's) and
with ``mrlib.sampling.contact_labels`` (each vertex at the label's rate); and the share of
contact outputs inside ``CONTACT_BAND``, where the generator is unsure.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # bench/: common.py

from common import describe, set_threads
from heldout import split_model


def shares(c: np.ndarray) -> str:
    """``(..., T, 6)`` labels -> 'mean (min-max)' % of frames in contact per vertex."""
    per = 100 * c.reshape(-1, c.shape[-1]).mean(0)
    return f"{per.mean():.1f} ({per.min():.1f}-{per.max():.1f})"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--split", choices=["heldout", "fresh", "dev"], default="heldout")
    p.add_argument("--seed", type=int, default=0, help="training seed [0]")
    p.add_argument("--preset", choices=["demo", "preview"], default="demo")
    p.add_argument("--contact-weight", type=float, default=None,
                   help="the contact consistency weight, as bench/heldout.py [the preset's]")  # fmt: skip
    p.add_argument("--samples", type=int, default=20)
    p.add_argument("--threads", type=int, default=None)
    a = p.parse_args(argv)
    set_threads(a.threads)
    print(describe(), flush=True)

    import mrlib
    from mrlib.model.presets import get_preset
    from mrlib.sampling.conditions import Condition
    from mrlib.sampling.contact_labels import (
        CONTACT_BAND,
        condition_contact_rates,
        label_contact_rates,
        rate_matched_contacts,
    )
    from mrlib.sampling.generation import label_inputs, sample_ranked
    from mrlib.sampling.sampler import Sampler

    body = mrlib.load_body_model()
    base = get_preset(a.preset)
    if a.contact_weight is not None:
        base = base.replace(loss=dataclasses.replace(base.loss, con=a.contact_weight))
    model, _, _ = split_model(a.split, a.seed, body, base)
    rates = label_contact_rates(model)
    sampler = Sampler()
    lo, hi = CONTACT_BAND
    print(f"\n`{a.preset}` model of the {a.split} split, training seed {a.seed}, {a.samples} raw "
          f"draws per label (best of {sampler.candidates}) of twice the clip: % of frames in "
          "contact, mean over the six foot vertices (range)\n")  # fmt: skip
    print(f"| label | clip | samples, cut at 0.5 | samples, at the label's rate | "
          f"outputs in ({lo:g}, {hi:g}) % |\n|---|---|---|---|---:|")  # fmt: skip
    for k, label in enumerate(model.labels):
        W = Condition.label(label).weights(model)
        n = 2 * max(len(x) for x, c in zip(model.features, model.clip_labels, strict=True)
                    if c == k)  # fmt: skip
        lengths, amp, conds = label_inputs(model, W, n, sampler)
        out = sample_ranked(model, conds, lengths, amp, 0, a.samples, sampler.candidates)[-1]
        x = model.normalizer.denormalize(out.transpose(1, 2))[..., -6:].double().numpy()
        matched = rate_matched_contacts(x, condition_contact_rates(model, W))
        unsure = 100 * np.mean((x > lo) & (x < hi))
        clip = np.broadcast_to(rates[k], (1, 6))
        print(f"| {label} | {shares(clip)} | {shares(x > 0.5)} | {shares(matched)} | "
              f"{unsure:.1f} |")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
