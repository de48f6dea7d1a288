"""Restyling unseen walks (``mrlib.sampling.restyling``) with a model of four Bandai walks.

Run from the repository root (the Bandai Namco clips are found as ``mrlib.datasets.bandai``
finds them)::

    python bench/restyle.py --seed 0          # trains or reuses the preview model (5-8 min)
    python bench/restyle.py --seed 1          # the second training seed
    python bench/restyle.py --seed 0 --iterations 2   # a nearly untrained model: the negative
    python bench/restyle.py --checkpoint ckpt.pt      # measure a given checkpoint
    python bench/restyle.py --seed 0 --guidance 0.5   # restyled with label guidance

Model: the ``preview`` preset trained on ``walk_{normal,happy,sad,angry}_001`` resampled
to 15 fps (``mrlib.model.presets.preview().fps``), through ``mrlib.training.trainer.train_cached``
(the same model as notebook 03's for seed 0, reused from mrlib's cache).

Inputs the model never saw: the second takes ``walk_{style}_002`` and the side walks
``walk-left_{style}_001`` / ``walk-right_{style}_001`` of the four styles (12 clips
with a label of the model: their own; ``walk_normal_002`` lasts 1.03 s, shorter than
the 1.33 s the 8-level pyramid needs at 15 fps, and is refused), and four walks of
other styles (no label of the model). Every input is restyled towards each label at
every level ``k`` (seed 0, without the foot clean-up) and measured with
``mrlib.evaluation.restyle_evidence.restyle_evidence``:

* **path**: mean ground distance of the restyled root from the input's (cm);
* **low band kept**: its low band (split at level k's Nyquist, as
  ``mrlib.evaluation.crossover.crossover_evidence`` splits) nearer the input's than any training
  clip's, share of (input, target) cases;
* **residual given**: its high-frequency residual's RMS profile nearest the target
  label's (4 pure samples per label), share of the (input, target != own label) pairs;
  the **paired negative**: the same input restyled with its own label, share of those
  pairs whose residual is nearest the (other) target all the same (chance: 1/4); and
  the input itself, unrestyled, likewise;
* **source share**: ``mrlib.evaluation.restyle_evidence.RestyleShares.source_share``, mean
  over cases.

Then the time per second of input, and that of a 120 s walk restyled at ``--level`` in
one pass. (The inversion measured here until 2026-12-06, ``restyle(..., invert=True)``,
did worse and was removed: ``docs/notes/2026-12-06-study-options.md``.)

The quantity of the trained-model test (``tests/test_restyle.py``, recipe 4 of
``tests/trained_models.py``) over training seeds x thread counts, and on the recipe
untrained, is ``python tests/trained_test_matrix.py --recipe restyle`` (formerly
``--matrix`` here).
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np
from common import add_iterations_arg, no_data, set_threads, with_iterations, write_json

import mrlib
from mrlib.datasets.synthetic import synthetic_walk
from mrlib.errors import ClipTooShortError
from mrlib.evaluation.restyle_evidence import (
    restyle_evidence,
    restyle_references,
    restyle_shares,
)
from mrlib.metrics.windows import metric_features
from mrlib.model.presets import get_preset
from mrlib.model.trained import load_model
from mrlib.sampling.restyling import restyle, restyle_lengths
from mrlib.training.data import TrainingSet
from mrlib.training.trainer import train_cached

STYLES = ("normal", "happy", "sad", "angry")
TRAIN = [f"walk_{s}_001" for s in STYLES]
LABELLED = (
    [f"walk_{s}_002" for s in STYLES]
    + [f"walk-left_{s}_001" for s in STYLES]
    + [f"walk-right_{s}_001" for s in STYLES]
)
OTHER = ["walk_tired_002", "walk_proud_002", "walk_old_002", "walk_active_002"]


def own_label(name: str) -> str | None:
    style = name.split("_")[1]
    return f"walk_{style}" if style in STYLES else None


def load(names: list[str]) -> dict[str, mrlib.Motion]:
    source = mrlib.datasets.bandai.tutorial_clips(names)
    if source.synthetic:
        no_data(f"the Bandai Namco clips are needed: {source.note}")
    return {n: mrlib.load_motion(p) for n, p in zip(names, source.paths, strict=True)}


def residual_nearest(model, motion, ref) -> str:
    """The label whose residual profile is nearest ``motion``'s (the input itself)."""
    from mrlib.metrics.bands import rms_profile, split_bands

    p = rms_profile(split_bands(metric_features(motion, contacts=False), model.fps,
                                ref.cutoff_hz)[1])  # fmt: skip
    return min(ref.label_profiles, key=lambda k: np.linalg.norm(p - ref.label_profiles[k]))


def sweep(model, inputs: dict, body, levels, sampler=None) -> list[dict]:
    """One row per (input, target, level); ``sampler``: the ``mrlib.Sampler`` that
    restyles (default: the raw output; the references are always the model's own raw
    samples)."""
    sampler = mrlib.Sampler(fix_contacts=False) if sampler is None else sampler
    rows = []
    for name, clip in inputs.items():
        src = clip.resample(model.fps)
        own = own_label(name)
        try:
            restyle_lengths(model, src.num_frames, name)
        except ClipTooShortError as e:
            print(f"refused: {e}")
            continue
        for k in levels:
            ref = restyle_references(model, src.num_frames, k, num_samples=4)
            itself = residual_nearest(model, src, ref)
            made = {
                lab: restyle(model, src, lab, k, seed=0, sampler=sampler, body=body)
                for lab in model.labels
            }
            evs = {lab: restyle_evidence(model, m, src, ref) for lab, m in made.items()}
            for lab, ev in evs.items():
                shares = restyle_shares(model, src, lab, levels=[k], seed=0, body=body,
                                        sampler=sampler)  # fmt: skip
                rows.append({
                    "input": name, "own": own, "target": lab, "level": k,
                    "cutoff_hz": ev.cutoff_hz, "path_cm": ev.trajectory_cm,
                    "low_holds": ev.low_holds, "nearest": ev.nearest_label,
                    "negative_nearest": evs[own].nearest_label if own else None,
                    "input_nearest": itself, "source_share": float(shares.source_share[0]),
                    "ms_per_s": 1000 * made[lab].meta["restyle"]["seconds"] / src.duration,
                })  # fmt: skip
    return rows


def pct(xs) -> str:
    xs = list(xs)
    return f"{100 * np.mean(xs):.0f}% ({sum(xs)}/{len(xs)})" if xs else "-"


def level_table(rows: list[dict], L: int) -> str:
    out = [
        "| k | cutoff Hz | path cm mean (max) | low band kept | residual given | "
        "paired negative | input itself | other styles: residual given | source share |",
        "|" + "---|" * 9,
    ]
    for k in sorted({r["level"] for r in rows}):
        rk = [r for r in rows if r["level"] == k]
        pos = [r for r in rk if r["own"] and r["target"] != r["own"]]
        oth = [r for r in rk if not r["own"]]
        path = [r["path_cm"] for r in rk]
        out.append(
            f"| {k} | {np.mean([r['cutoff_hz'] for r in rk]):.2f} | "
            f"{np.mean(path):.1f} ({np.max(path):.1f}) | {pct(r['low_holds'] for r in rk)} | "
            f"{pct(r['nearest'] == r['target'] for r in pos)} | "
            f"{pct(r['negative_nearest'] == r['target'] for r in pos)} | "
            f"{pct(r['input_nearest'] == r['target'] for r in pos)} | "
            f"{pct(r['nearest'] == r['target'] for r in oth)} | "
            f"{100 * np.mean([r['source_share'] for r in rk]):.0f}% |"
        )
    return "\n".join(out)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seed", type=int, default=0, help="training seed [0]")
    add_iterations_arg(p, "iterations per block (overrides the preview preset's; 2: untrained)")
    p.add_argument("--level", type=int, default=None, help="level of the 120 s restyle [L//2]")
    p.add_argument("--threads", type=int, default=1, help="torch intra-op threads [1]")
    p.add_argument("--guidance", type=float, default=None,
                   help="restyle with this Sampler guidance [mrlib's: 0]")  # fmt: skip
    p.add_argument("--json", type=Path, default=None, help="also write the rows here")
    p.add_argument("--checkpoint", type=Path, default=None,
                   help="measure this checkpoint instead of the cached preview model")  # fmt: skip
    a = p.parse_args(argv)
    set_threads(a.threads)  # explicit: mrlib's own calls keep it (mrlib.threads)

    body = mrlib.load_body_model()
    fps = get_preset("preview").fps
    clips = [c.resample(fps) for c in load(TRAIN).values()]
    data = TrainingSet.from_motions(clips, body=body)
    cfg, _ = with_iterations(get_preset("preview").replace(seed=a.seed), a.iterations)
    t = time.perf_counter()
    if a.checkpoint is not None:
        model, how = load_model(a.checkpoint), f"loaded {a.checkpoint}"
        cfg = model.config
    else:
        model, record = train_cached(data, cfg, body=body, progress=False)
        how = "reused" if record.reused else f"trained in {time.perf_counter() - t:.0f} s"
        how += f" ({record.checkpoint})"
    print(f"{data}\npreview preset, training seed {cfg.seed}, iterations {cfg.block_iterations}: "
          f"{how}", flush=True)  # fmt: skip
    L = model.num_levels
    level = L // 2 if a.level is None else a.level

    inputs = load(LABELLED + OTHER)
    t = time.perf_counter()
    sampler = mrlib.Sampler(fix_contacts=False)
    if a.guidance is not None:  # the restyles only: the references stay the model's own
        sampler = mrlib.Sampler(guidance=a.guidance, fix_contacts=False)
        print(f"restyling with guidance {a.guidance:g}")
    rows = sweep(model, inputs, body, range(1, L), sampler)
    print(f"\nrestyled {len(rows)} cases in {time.perf_counter() - t:.0f} s "
          f"({len(inputs)} inputs x {len(model.labels)} labels x {L - 1} levels)\n")  # fmt: skip
    print(level_table(rows, L) + "\n", flush=True)

    speed = [r["ms_per_s"] for r in rows]
    long_walk = synthetic_walk("walk_normal", seconds=120.0, fps=fps, body=body)
    t = time.perf_counter()
    restyle(model, long_walk, model.labels[0], level, seed=0,
            sampler=mrlib.Sampler(fix_contacts=False), body=body)  # fmt: skip
    long_ms = 1000 * (time.perf_counter() - t) / long_walk.duration
    print(f"direct route: median {statistics.median(speed):.1f} ms per second of input "
          f"(max {max(speed):.1f}); a 120 s clip in one pass: {long_ms:.1f} ms per "
          "second\n")  # fmt: skip

    if a.json is not None:
        summary = {"seed": a.seed, "iterations": list(cfg.block_iterations), "rows": rows}
        write_json("restyle", summary, a.json)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
