"""Condition control of a label preset on four Bandai walks (the figures of ``tutorial``).

Run from the repository root (``$MRLIB_DATA_DIR`` points at the Bandai Namco dataset)::

    python bench/condition_control.py                    # tutorial, seed 0 (~18-32 min CPU)
    python bench/condition_control.py --seed 2 --detail 200
    python bench/condition_control.py --iterations 20    # smoke test, meaningless numbers

Training set: ``dataset-1_walk_{normal,happy,sad,angry}_001`` at 30 fps, one label per
clip read from the dataset's JSON files. The run goes to ``--out`` and a finished run of
the same configuration and clips there is reused (``mrlib.training.trainer.train_or_reuse``).

Printed, for the trained model:

* **condition fidelity** of single-label samples (``condition_fidelity_of_model``, 10
  samples per label of twice the longest clip; the target is >= 90 %);
* **crossover evidence** for every ordered label pair at crossover levels 2 and 4
  (``crossover_evidence``, 6 samples per case): is the low-pass band nearer the coarse
  label A, and the high-frequency residual nearer the fine label B?
* **coverage** of each training clip at eps 2 and 1 (``coverage_per_sequence``, 20
  samples of twice the clip's length).

The figures are also written to ``<out>/condition_control.json``.

A smoke run (``--iterations 2``, a nearly untrained model) prints fidelity 25 % (chance),
coverage 0 %, the low band from A in 11 of 24 cases and the residual from B in 20: the
fine levels make a sample's residual even before training, so the residual half alone
says little; a trained model without ``LossWeights.detail`` takes it from A instead (B
in 11 of 24). Read the two halves together, and with the fidelity.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

from common import (
    TUTORIAL_CLIPS,
    add_iterations_arg,
    bandai_clips,
    set_threads,
    trained_model,
    tutorial_run,
    with_iterations,
    write_json,
)

from mrlib.evaluation import crossover as control
from mrlib.evaluation import fidelity
from mrlib.model.presets import get_preset
from mrlib.sampling.sampler import FINE_NOISE, GUIDANCE, Sampler

LEVELS = (2, 4)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--preset", default="tutorial", choices=["tutorial", "paper"])
    p.add_argument("--seed", type=int, default=0, help="training seed [0]")
    p.add_argument(
        "--detail", type=float, default=None, help="LossWeights.detail (overrides the preset)"
    )
    p.add_argument("--mismatch", type=float, default=None, help="LossWeights.mismatch (overrides)")
    p.add_argument("--con", type=float, default=None, help="LossWeights.con (overrides)")
    p.add_argument("--lr", type=float, default=None, help="Adam learning rate (overrides)")
    p.add_argument(
        "--mix-prob", type=float, default=None,
        help="TrainConfig.mix_prob, the share of generations that mix two labels (overrides)",
    )  # fmt: skip
    add_iterations_arg(p, "iterations per block, one value for all blocks or one per block")
    p.add_argument(
        "--fine-noise", type=float, default=None,
        help="sample with this Sampler fine_noise [default: mrlib's]",
    )  # fmt: skip
    p.add_argument(
        "--guidance", type=float, default=None,
        help="sample with this Sampler guidance [default: mrlib's]",
    )  # fmt: skip
    p.add_argument("--device", default="cpu")
    p.add_argument("--threads", type=int, default=1, help="torch intra-op threads [1]")
    p.add_argument(
        "--out", type=Path, default=None, help="run folder [outputs/condition_control/...]"
    )
    a = p.parse_args(argv)
    set_threads(a.threads)  # explicit: mrlib's own calls keep it (mrlib.threads)
    bandai_clips(TUTORIAL_CLIPS)  # exits before anything else when the data is missing

    cfg = get_preset(a.preset).replace(seed=a.seed, device=a.device)
    loss = cfg.loss
    if a.detail is not None:
        loss = dataclasses.replace(loss, detail=a.detail)
    if a.mismatch is not None:
        loss = dataclasses.replace(loss, mismatch=a.mismatch)
    if a.con is not None:
        loss = dataclasses.replace(loss, con=a.con)
    cfg = cfg.replace(loss=loss)
    if a.lr is not None:
        cfg = cfg.replace(lr=a.lr)
    if a.mix_prob is not None:
        cfg = cfg.replace(mix_prob=a.mix_prob)
    cfg, it_suffix = with_iterations(cfg, a.iterations)
    suffix = ""
    if a.con is not None:
        suffix += f"_con{a.con:g}"
    if a.lr is not None:
        suffix += f"_lr{a.lr:g}"
    if a.mix_prob is not None:
        suffix += f"_mix{a.mix_prob:g}"
    run = tutorial_run(cfg, a.preset, suffix + it_suffix)
    name, out = run.name, a.out or run

    note = f"preset {a.preset}, seed {a.seed}, {loss}\nrun folder {out}"
    model, record, _ = trained_model(cfg, TUTORIAL_CLIPS, out, note=note)
    how = "reused a finished run" if record.reused else "trained"
    sampler = Sampler(
        fine_noise=FINE_NOISE if a.fine_noise is None else a.fine_noise,
        guidance=GUIDANCE if a.guidance is None else a.guidance,
        fix_contacts=False,
    )
    print(f"sampling with fine_noise={sampler.fine_noise:g}, guidance={sampler.guidance:g}")
    print(f"{how}: {record.wall_time_s:.0f} s of training", flush=True)

    t = time.perf_counter()
    fid = fidelity.condition_fidelity_of_model(model, num_samples=10, seed=0, sampler=sampler)
    print("\n" + fid.to_markdown() + "\n")
    cases = [
        control.crossover_evidence(
            model,
            ca,
            fi,
            lv,
            num_samples=6,
            seed=0,
            options=control.CrossoverOptions(sampler=sampler),
        )  # fmt: skip
        for ca in model.labels
        for fi in model.labels
        if ca != fi
        for lv in LEVELS
    ]
    print(control.evidence_table(cases) + "\n")
    low, high, both = (
        sum(getattr(e, k) for e in cases) for k in ("low_holds", "high_holds", "holds")
    )
    cov = {
        eps: fidelity.coverage_per_sequence(
            model, num_samples=20, length_factor=2.0, seed=0, eps=eps, sampler=sampler
        )
        for eps in (2.0, 1.0)
    }
    for eps, c in cov.items():
        print(
            f"coverage eps {eps:g}: "
            + ", ".join(f"{k.replace('dataset-1_', '')} {100 * v:.1f}%" for k, v in c.items())
        )
    print(
        f"\nRESULT {name}: condition fidelity {100 * fid.overall:.1f}%; crossovers at levels "
        f"{LEVELS} of {len(cases) // len(LEVELS)} ordered pairs: low band from A in {low} of "
        f"{len(cases)}, residual from B in {high}, both in {both}; min coverage eps 2 "
        f"{100 * min(cov[2.0].values()):.1f}%, eps 1 {100 * min(cov[1.0].values()):.1f}% "
        f"(evaluation {time.perf_counter() - t:.0f} s)"
    )
    result = {
        "preset": a.preset,
        "seed": a.seed,
        "loss": dataclasses.asdict(loss),
        "iterations": a.iterations,
        "train_s": record.wall_time_s,
        "reused": record.reused,
        "fine_noise": sampler.fine_noise,
        "guidance": sampler.guidance,
        "fidelity": fid.overall,
        "fidelity_per_label": fid.per_label,
        "crossover": [
            {
                "coarse": e.coarse_label,
                "fine": e.fine_label,
                "level": e.level,
                "low_to_coarse": e.low_to_coarse,
                "low_to_fine": e.low_to_fine,
                "high_to_coarse": e.high_to_coarse,
                "high_to_fine": e.high_to_fine,
            }
            for e in cases
        ],
        "counts": {"cases": len(cases), "low": low, "high": high, "both": both},
        "coverage": {f"{eps:g}": c for eps, c in cov.items()},
    }
    tag = "" if a.fine_noise is None else f"_fine{a.fine_noise:g}"
    tag += "" if a.guidance is None else f"_guidance{a.guidance:g}"
    write_json("condition_control", result, Path(out) / f"condition_control{tag}.json")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
