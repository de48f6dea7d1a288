"""Time to quality: CPU training time until generated motion meets a stated target.

Run from the repository root::

    python bench/time_to_quality.py                       # both sets, tutorial preset
    python bench/time_to_quality.py --set one --max-minutes 10 --eval-every 50
    python bench/time_to_quality.py --set four --iterations 400,400,400,3000 --fix-contacts

Two fixed training sets of Bandai Namco clips (``$MRLIB_DATA_DIR``):

* ``one``: ``dataset-1_walk_happy_001`` (213 frames at 30 fps), one model;
* ``four``: ``dataset-1_walk_{normal,happy,sad,angry}_001``, one model with four labels.

Training is the ordinary ``mrlib.training.trainer.train`` (preset ``--preset``, ``tutorial`` by
default) with a callback that, every ``--eval-every`` iterations and at the end of every
block, pauses the clock, takes the current generator (``mrlib.sampling.generation.model_from_trainer``),
draws ``--samples`` clips of twice each training clip's length with fixed seeds and scores
them with ``mrlib.evaluation.evaluate.score_motions`` (the Table-1 protocol of ``mrlib evaluate``).
The global RNG state is saved and restored around each evaluation, so training follows
the same trajectory as without the callback. *Training time* is wall time from the call
to ``train`` (networks and data pyramids included) to the checkpoint, minus the time
spent evaluating; BVH loading and retargeting are reported separately.

**The target.** A checkpoint passes when, for *every* training clip:

1. **coverage >= 99 %** (``T_c = 30``, ``eps = 2.0``; mean over the samples);
2. **reconstruction error <= the clip's one-frame step**: the mean per-frame distance
   between the reconstruction (``mrlib.sampling.generation.reconstruct``) and the clip, on the metric
   features (23 local joint rotations in 6D + 6 contact labels), is at most the mean
   distance between consecutive frames of the clip itself, i.e. the error of playing the
   clip one frame (33 ms) late. On the four walks this bound is 0.36 (sad, slow) to
   0.78 (angry, fast). It is a noise-level bound: it sits far below the calibration
   rows that are different motion (another take: local diversity 0.9-2.3, a frozen
   frame 1.7-2.5) and is reached only by a reconstruction that follows the clip frame
   by frame, contact labels included (one wrong contact label alone costs 1.0 on that
   frame);
3. **local diversity <= the "other take" row**: the generated 15-frame windows are on
   average no farther from their nearest training window than the windows of a second
   real recording of the same style (``dataset-1_walk_<style>_002``) are. Samples that
   wander further from the data than a real retake are not counted as good;
4. **foot skating <= the training clip's + ``--skate-margin`` points** (default 5):
   share of contact vertex-frames sliding faster than 0.15 m/s
   (``mrlib.metrics.plausibility``), generated clips with the generator's own contact labels,
   the training clip with labels computed from its foot speeds. The margin is the
   take-to-take spread of real data: on the four walks the training take and its
   second take differ by 0.7 to 3.2 points (walk_sad: 6.1 vs 2.9 %), and over the 30
   Bandai walk takes the share is 4.4 % on average and at most 8 %. The share of
   frames labelled in contact must also be at least half the training clip's: a
   generator that labels no contact at all would otherwise pass with 0 % skating.

The training time at the first passing checkpoint is compared with GANimator's published
schedule (Li et al., SIGGRAPH 2022: 15,000 iterations per two-level block, 5 critic steps
per generator step, one model per clip) on this 2-core machine: 7.3 hours for the
213-frame clip, from the naive GANimator-style step of ``bench/train_speed.py`` times
15,000 iterations for each of the paper's four blocks. The ratio is taken against
that figure. When ``bench/results/train_speed.json`` holds single-clip naive timings of
all four blocks, the projection from those is reported next to it (it depends on that
run's load and clip). For the ``four`` set the ratio is against one such run, though
GANimator-mode needs one run per clip.

Results are printed as tables and written to ``bench/results/time_to_quality.json``
(with the load average during the run: on a shared machine the times are upper bounds).
Torch runs with ``--threads`` intra-op threads (default 1: on 2 busy cores the
tutorial networks trained faster with one thread than with two).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch
from common import (
    RESULTS,
    ROOT,
    bandai_clips,
    bandai_dir,
    describe,
    no_data,
    set_threads,
    write_json,
)

SETS = {
    "one": ("dataset-1_walk_happy_001",),
    "four": (
        "dataset-1_walk_normal_001",
        "dataset-1_walk_happy_001",
        "dataset-1_walk_sad_001",
        "dataset-1_walk_angry_001",
    ),
}
GANIMATOR_ITERS_PER_BLOCK = 15000  # GANimator's num_iters for each two-level block
GANIMATOR_BLOCKS = 4  # the paper's L = 8 levels in blocks of two
GANIMATOR_HOURS_213 = 7.3  # projected on this 2-core machine, see the module docstring


@dataclass(frozen=True)
class Targets:
    """The quality target every training clip must meet."""

    coverage_pct: float = 99.0  # coverage >= this
    recon_step_factor: float = 1.0  # recon error <= factor * the clip's one-frame step
    skate_margin_pct: float = 5.0  # skating share <= training clip's + this (points)
    # local diversity <= the "other take" row's (no parameter)


# -- data and thresholds ---------------------------------------------------------------------
def load_clips(names, body):
    """Loaded and retargeted clips, by name."""
    from mrlib.io import load_motion

    return {n: load_motion(p, body=body) for n, p in zip(names, bandai_clips(names), strict=True)}


def clip_thresholds(name, ref, body, settings, targets: Targets) -> dict:
    """The per-clip bounds of the target, and the calibration rows they come from."""
    from mrlib import metrics as mt
    from mrlib.evaluation.calibration import find_bandai_counterparts
    from mrlib.evaluation.evaluate import score_motions
    from mrlib.io import load_motion
    from mrlib.metrics import plausibility as pl

    kin = pl.motion_kinematics(ref, body)
    labels, _ = pl.motion_contacts(ref, kin[1])
    feats = mt.metric_features(ref.replace(contacts=labels), kind=settings.feature_kind)
    step = mt.reconstruction_error(feats[1:], feats[:-1])  # the clip one frame late
    others = find_bandai_counterparts(name, bandai_dir())
    if "other take" not in others:
        no_data(f"no second take of {name} in {bandai_dir()}")
    take = load_motion(others["other take"], body=body)
    own = score_motions([ref], ref, settings=settings, body=body)
    other = score_motions([take], ref, settings=settings, body=body)
    return {
        "frames": ref.num_frames,
        "one_frame_step": step,
        "recon_max": targets.recon_step_factor * step,
        "other_take": others["other take"].stem,
        "other_take_local_div": other["local_div"],
        "other_take_coverage_pct": other["coverage_pct"],
        "other_take_skate_pct": other["skate_pct"],
        "local_div_max": other["local_div"],
        "train_skate_pct": own["skate_pct"],
        "skate_max_pct": own["skate_pct"] + targets.skate_margin_pct,
        "train_contact_share": own["contact_share"],
    }


# -- evaluation at checkpoints ---------------------------------------------------------------
def score_checkpoint(
    model, refs, thresholds, settings, body, targets: Targets, fix_contacts: bool = False
) -> dict:
    """Metrics of the current generator on every clip, and whether each meets the target
    (samples cleaned up by foot-contact IK when ``fix_contacts``)."""
    from mrlib.evaluation.evaluate import score_motions
    from mrlib.sampling.cleanup import cleanup_foot_contacts
    from mrlib.sampling.generation import generate, reconstruct, training_floor
    from mrlib.sampling.sampler import Sampler

    names = list(refs)
    multi = refs if len(refs) > 1 else None
    out = {}
    for k, name in enumerate(names):
        ref, th = refs[name], thresholds[name]
        label = model.labels[model.clip_labels[k]]
        length = round(settings.length_factor * ref.num_frames)
        gen = generate(
            model, label, length=length, seed=settings.seed, num=settings.num_samples,
            sampler=Sampler(fix_contacts=False), body=body,
        )  # fmt: skip
        if fix_contacts:  # a clean-up method of its own: the raw samples cleaned as generate would
            floor = training_floor(model, [model.clip_labels[k]], body)
            if fix_contacts == "optimise":  # the per-frame optimisation (reference code)
                from experiments.cleanup_studies import cleanup_optimised

                gen = [cleanup_optimised(m, body) for m in gen]
            else:
                gen = [cleanup_foot_contacts(m, body, floor=floor) for m in gen]
        row = score_motions(
            gen, ref, settings=settings, body=body, label=name, all_references=multi,
            reconstruction=reconstruct(model, k),
        )  # fmt: skip
        ok = {
            "coverage": row["coverage_pct"] >= targets.coverage_pct,
            "recon": row["recon_error"] <= th["recon_max"],
            "local_div": row["local_div"] <= th["local_div_max"],
            # a generator that labels (almost) no contacts cannot show skating: not a pass
            "skating": row["skate_pct"] <= th["skate_max_pct"]
            and row["contact_share"] >= 0.5 * th["train_contact_share"],
        }
        keep = ("coverage_pct", "global_div", "local_div", "recon_error", "cond_fidelity_pct",
                "skate_pct", "contact_share", "jerk_ratio", "penetration_pct")  # fmt: skip
        out[name] = {**{k2: float(row[k2]) for k2 in keep}, "ok": ok, "pass": all(ok.values())}
    return out


class CheckpointEvaluator:
    """``train`` callback: evaluates every ``every`` iterations and at block ends, keeps
    the training clock, stops at the target (unless ``full``) or after ``max_s``."""

    def __init__(
        self, refs, thresholds, settings, body, targets, every, max_s, full, t_start,
        fix_contacts=False,
    ):  # fmt: skip
        self.refs, self.thresholds, self.settings = refs, thresholds, settings
        self.body, self.targets = body, targets
        self.every, self.max_s, self.full = every, max_s, full
        self.t_start = t_start
        self.fix_contacts = fix_contacts
        self.eval_s = 0.0
        self.checkpoints: list[dict] = []
        self.reached: dict | None = None

    def train_time(self) -> float:
        return time.perf_counter() - self.t_start - self.eval_s

    def __call__(self, trainer, losses) -> None:
        cfg = trainer.config
        n_block = cfg.block_iterations[trainer.block]
        done_before = sum(cfg.block_iterations[: trainer.block])
        it = done_before + trainer.iteration
        block_end = trainer.iteration == n_block
        t_train = self.train_time()
        over = self.max_s is not None and t_train >= self.max_s
        if it % self.every == 0 or block_end or over:
            self.evaluate(trainer, it, t_train, block_end)
        if (self.reached is not None and not self.full) or over:
            raise KeyboardInterrupt  # train() writes a checkpoint and returns

    def evaluate(self, trainer, it, t_train, block_end) -> None:
        from mrlib.model.trained import model_from_trainer

        t0 = time.perf_counter()
        np_state = np.random.get_state()
        with torch.random.fork_rng(devices=[]):  # building a generator draws initial weights
            model = model_from_trainer(trainer)
            clips = score_checkpoint(
                model, self.refs, self.thresholds, self.settings, self.body, self.targets,
                self.fix_contacts,
            )  # fmt: skip
        np.random.set_state(np_state)
        dt = time.perf_counter() - t0
        self.eval_s += dt
        cp = {
            "iteration": it,
            "block": trainer.block + 1,
            "block_end": block_end,
            "train_s": t_train,
            "eval_s": dt,
            "loadavg": os.getloadavg(),
            "pass": all(c["pass"] for c in clips.values()),
            "clips": clips,
        }
        self.checkpoints.append(cp)
        print(format_checkpoint(cp, self.thresholds), flush=True)
        if cp["pass"] and self.reached is None:
            self.reached = cp


# -- reporting -------------------------------------------------------------------------------
def worst(cp: dict, thresholds: dict) -> dict:
    """Worst clip per criterion: lowest coverage, highest reconstruction error over the
    one-frame step, highest local diversity over the other take's, highest skating share
    minus the training clip's (points)."""
    c = cp["clips"]
    return {
        "coverage": min(v["coverage_pct"] for v in c.values()),
        "recon": max(v["recon_error"] / thresholds[n]["one_frame_step"] for n, v in c.items()),
        "local": max(v["local_div"] / thresholds[n]["local_div_max"] for n, v in c.items()),
        "skate": max(v["skate_pct"] - thresholds[n]["train_skate_pct"] for n, v in c.items()),
    }


HEADER = (
    f"{'iter':>6} {'blk':>3} {'train s':>8} {'cov% min':>8} {'recon/step':>11} "
    f"{'local/take':>10} {'skate +pts':>10} {'load':>5}  pass"
)


def format_checkpoint(cp: dict, thresholds: dict) -> str:
    w = worst(cp, thresholds)
    return (
        f"{cp['iteration']:>6} {cp['block']:>3} {cp['train_s']:>8.1f} {w['coverage']:>8.1f} "
        f"{w['recon']:>11.2f} {w['local']:>10.2f} {w['skate']:>+10.1f} "
        f"{cp['loadavg'][0]:>5.1f}  {'yes' if cp['pass'] else 'no'}"
    )


def plot_curves(results: list[dict], targets: Targets, path: Path) -> Path:
    """The four criteria (worst clip) against training time, one line per set."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from mrlib.viz.plots import plot_quality_curve

    panels = (
        ("coverage", "coverage % (worst clip)", targets.coverage_pct, True),
        ("recon", "recon. error / one-frame step", targets.recon_step_factor, False),
        ("local", "local div. / other take", 1.0, False),
        ("skate", "skating - training (points)", targets.skate_margin_pct, False),
    )
    fig, axs = plt.subplots(1, 4, figsize=(18, 3.6), layout="constrained")
    for r in results:
        cps = r["checkpoints"]
        if not cps:
            continue
        t = [cp["train_s"] for cp in cps]
        ws = [worst(cp, r["thresholds"]) for cp in cps]
        reached = r["reached"]["train_s"] if r["reached"] else None
        for ax, (key, ylabel, target, higher) in zip(axs, panels, strict=True):
            plot_quality_curve(
                t, [w[key] for w in ws], target, ax, higher_is_better=higher,
                label=f"{r['set']} ({len(r['clips'])} clips)", ylabel=ylabel, reached_at=reached,
            )  # fmt: skip
    axs[0].legend(fontsize=8)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def ganimator_projection() -> tuple[float, dict | None]:
    """Hours of GANimator's schedule for one clip on this machine: the stated projection
    for the 213-frame clip (the ratio is taken against it), and, when
    ``bench/results/train_speed.json`` has single-clip naive timings of all four blocks,
    the projection from those (measured under that run's load, on its clip)."""
    path = RESULTS / "train_speed.json"
    measured = None
    try:
        d = json.loads(path.read_text())
        rows = [r for r in d["rows"] if r["impl"] == "naive" and r["clips"] == 1]
        naive = {r["block"]: r["s_per_it"] for r in rows}
        if len(naive) == GANIMATOR_BLOCKS:
            measured = {
                "hours": GANIMATOR_ITERS_PER_BLOCK * sum(naive.values()) / 3600,
                "s_per_it": [naive[b] for b in sorted(naive)],
                "frames": rows[0].get("frames"),
                "loadavg_at_end": d.get("meta", {}).get("loadavg_at_end"),
                "source": str(path.relative_to(ROOT)),
            }
    except (OSError, KeyError, ValueError, TypeError):
        pass
    return GANIMATOR_HOURS_213, measured


def git_commit() -> str:
    try:
        return subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True
        ).stdout.strip()
    except OSError:
        return ""


# -- one set ---------------------------------------------------------------------------------
def run_set(key: str, args, body, targets: Targets, out_root: Path) -> dict:
    from mrlib.evaluation.results import EvaluationSettings
    from mrlib.model.config import config_to_json
    from mrlib.model.presets import training_config
    from mrlib.training.data import TrainingSet
    from mrlib.training.trainer import train

    names = SETS[key]
    print(f"\n== set '{key}': {', '.join(names)}")
    t0 = time.perf_counter()
    clips = load_clips(names, body)
    data = TrainingSet.from_motions(list(clips.values()), body=body)
    load_s = time.perf_counter() - t0
    settings = EvaluationSettings(num_samples=args.samples, seed=args.seed)
    thresholds = {n: clip_thresholds(n, m, body, settings, targets) for n, m in clips.items()}
    for n, th in thresholds.items():
        print(
            f"   {n}: {th['frames']} frames; recon <= {th['recon_max']:.3f} (one-frame step), "
            f"local div <= {th['local_div_max']:.2f} ({th['other_take']}), skating <= "
            f"{th['skate_max_pct']:.1f} % (training clip {th['train_skate_pct']:.1f} %)"
        )
    cfg = training_config(args.preset, args.iterations, args.levels, args.seed)
    if len(names) == 1:
        cfg = cfg.replace(mix_prob=0.0)  # one label: nothing to mix (as `mrlib train --per-clip`)
    cfg = cfg.replace(checkpoint_every=0)
    print(
        f"   preset {args.preset}: {cfg.model.num_levels} levels, blocks "
        f"{list(cfg.block_iterations)}, n_critic {cfg.n_critic}; {args.samples} samples per "
        f"clip at each evaluation{f' after the foot-contact clean-up ({args.fix_contacts})' if args.fix_contacts else ''}; "
        f"data loaded in {load_s:.1f} s"
    )
    print(HEADER)
    t_start = time.perf_counter()
    cb = CheckpointEvaluator(
        clips, thresholds, settings, body, targets, args.eval_every,
        None if args.max_minutes is None else 60 * args.max_minutes, args.full_schedule, t_start,
        args.fix_contacts,
    )  # fmt: skip
    res = train(data, cfg, out_root / key, body=body, progress=False, callback=cb)
    total_train = time.perf_counter() - t_start - cb.eval_s
    hours, measured = ganimator_projection()
    reached = cb.reached
    out = {
        "set": key,
        "clips": list(names),
        "frames": [m.num_frames for m in clips.values()],
        "load_s": load_s,
        "config": json.loads(config_to_json(cfg)),
        "thresholds": thresholds,
        "checkpoints": cb.checkpoints,
        "train_s_total": total_train,
        "eval_s_total": cb.eval_s,
        "iterations_total": sum(cfg.block_iterations),
        "fix_contacts": args.fix_contacts or False,
        "stopped": "target" if reached is not None and not args.full_schedule
        else "max-minutes" if res.interrupted else "schedule end",
        "reached": None if reached is None else {
            "train_s": reached["train_s"], "iteration": reached["iteration"],
            "block": reached["block"],
        },
        "ganimator_hours": hours,
        "ganimator_measured": measured,
        "ratio": None if reached is None else hours * 3600 / reached["train_s"],
    }  # fmt: skip
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument(
        "--set", choices=["one", "four", "both"], default="both",
        help="one: walk_happy_001 alone; four: walk_{normal,happy,sad,angry}_001 [default: both]",
    )  # fmt: skip
    p.add_argument("--preset", default="tutorial", choices=["tutorial", "paper"])
    p.add_argument(
        "--iterations", default=None, metavar="N[,N...]",
        help="iterations per block, overriding the preset (one value or one per block)",
    )  # fmt: skip
    p.add_argument("--levels", type=int, default=None, help="pyramid levels (overrides the preset)")
    p.add_argument(
        "--max-minutes", type=float, default=None,
        help="stop training after this much training time per set (default: the schedule)",
    )  # fmt: skip
    p.add_argument(
        "--eval-every", type=int, default=100,
        help="iterations between evaluations (also at every block end) [default: 100]",
    )  # fmt: skip
    p.add_argument(
        "--samples", type=int, default=10,
        help="generated clips per training clip at each evaluation [default: 10]",
    )  # fmt: skip
    p.add_argument(
        "--skate-margin", type=float, default=Targets.skate_margin_pct,
        help="allowed skating share above the training clip's, in points [default: 5]",
    )  # fmt: skip
    p.add_argument(
        "--full-schedule", action="store_true",
        help="keep training (and evaluating) after the target is met",
    )  # fmt: skip
    p.add_argument(
        "--fix-contacts", nargs="?", const="optimise", default=False, metavar="METHOD",
        help="score samples after the foot-contact clean-up: 'optimise' (the per-frame "
        "optimisation of experiments/cleanup_studies.py, as the README's figures were "
        "measured; the default with no METHOD) or 'ik' (mrlib.sampling.cleanup)",
    )  # fmt: skip
    p.add_argument("--threads", type=int, default=1, help="torch intra-op threads [default: 1]")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--runs", type=Path, default=None, help="checkpoint folder (default: a temp dir)"
    )
    p.add_argument("--out", type=Path, default=RESULTS / "time_to_quality.json")
    args = p.parse_args(argv)
    if args.iterations is not None:
        try:
            args.iterations = tuple(int(v) for v in args.iterations.split(","))
        except ValueError:
            p.error(f"--iterations wants integers, got {args.iterations!r}")
    if args.eval_every < 1 or args.samples < 1 or args.threads < 1:
        p.error("--eval-every, --samples and --threads must be positive")
    set_threads(args.threads)  # explicit: mrlib's own calls keep it (mrlib.threads)
    print(describe(), flush=True)
    import tempfile

    import mrlib

    body = mrlib.load_body_model()
    targets = Targets(skate_margin_pct=args.skate_margin)
    keys = ["one", "four"] if args.set == "both" else [args.set]
    meta = {
        "threads": args.threads,
        "commit": git_commit(),
        "date": time.strftime("%Y-%m-%d %H:%M:%S"),
        "loadavg_at_start": os.getloadavg(),
        "targets": asdict(targets),
        "argv": sys.argv[1:] if argv is None else list(argv),
    }
    with tempfile.TemporaryDirectory(prefix="mrlib_ttq_") as tmp:
        runs = args.runs if args.runs is not None else Path(tmp)
        results = [run_set(k, args, body, targets, runs) for k in keys]
    meta["loadavg_at_end"] = os.getloadavg()

    print("\n| set | clips (frames) | target reached at (training time) | iterations | "
          "GANimator projection | ratio | load avg (1 min) during run |")  # fmt: skip
    print("|---|---|---:|---:|---:|---:|---|")
    for r in results:
        loads = [cp["loadavg"][0] for cp in r["checkpoints"]] or [math.nan]
        if r["reached"] is None:
            when = f"not reached ({r['stopped']}, {r['train_s_total'] / 60:.1f} min trained)"
            it, ratio = "–", "–"
        else:
            when = f"{r['reached']['train_s']:.0f} s ({r['reached']['train_s'] / 60:.1f} min)"
            it, ratio = str(r["reached"]["iteration"]), f"{r['ratio']:.1f}x"
        print(
            f"| {r['set']} | {', '.join(str(f) for f in r['frames'])} | {when} | {it} | "
            f"{r['ganimator_hours']:.1f} h | {ratio} | {min(loads):.1f}-{max(loads):.1f} |"
        )
    measured = results[0]["ganimator_measured"]
    if measured is not None:
        print(
            f"GANimator projection from {measured['source']} (clip of {measured['frames']} "
            f"frames, load {measured['loadavg_at_end']}): {measured['hours']:.1f} h"
        )
    write_json("time_to_quality", {"meta": meta, "sets": results}, args.out)
    png = plot_curves(results, targets, args.out.with_suffix(".png"))
    print(f"\nwrote {args.out} and {png.name}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
