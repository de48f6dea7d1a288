"""Quality and time of a training budget on the demo's data (the four synthetic clips of
``data_samples/`` at 15 fps): how the ``preview`` preset was sized.

Trains the ``tutorial`` networks and losses with the given iterations per block and
critic steps, then prints the training time and the demo's headline figures (coverage,
condition fidelity, foot skating) beside the calibration rows:

    python bench/demo_budget.py                                   # the preview preset
    python bench/demo_budget.py --iterations 600 --n-critic 1
    python bench/demo_budget.py --iterations 400 --n-critic 2 --threads 2

Prints a Markdown table and appends a JSON row (with the machine) to
``bench/results/demo_budget.jsonl``.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time

from common import describe, set_threads, write_json


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--iterations", default=None, help="per block: N or N,N,N,N [demo preset]")
    ap.add_argument("--n-critic", type=int, default=None, help="critic steps [demo preset]")
    ap.add_argument("--gen-hidden", default=None, help="e.g. 48,96,96 [tutorial's]")
    ap.add_argument("--fps", type=float, default=15.0)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--samples", type=int, default=10, help="evaluation samples per label")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--lr", type=float, default=None, help="Adam learning rate [preset's]")
    ap.add_argument("--con", type=float, default=None, help="LossWeights.con [preset's]")
    ap.add_argument(
        "--clean",
        action="store_true",
        help="also score the samples after the foot-contact clean-up (mrlib.sampling.cleanup), with "
        "global diversity and penetration",
    )
    args = ap.parse_args(argv)

    import dataclasses

    import mrlib
    from mrlib.app.demo import DATA_SAMPLES, headline_table
    from mrlib.evaluation.evaluate import EvaluationSettings, evaluate_model
    from mrlib.model.presets import preview
    from mrlib.model.trained import load_model
    from mrlib.training.data import TrainingSet
    from mrlib.training.trainer import train

    set_threads(args.threads)  # explicit: mrlib's own calls keep it (mrlib.threads)
    print(describe(), flush=True)
    cfg = preview().replace(seed=args.seed, fps=args.fps)
    if args.iterations:
        its = tuple(int(v) for v in args.iterations.split(","))
        cfg = cfg.replace(block_iterations=its * cfg.num_blocks if len(its) == 1 else its)
    if args.n_critic is not None:
        cfg = cfg.replace(n_critic=args.n_critic)
    if args.gen_hidden:
        hidden = tuple(int(v) for v in args.gen_hidden.split(","))
        cfg = cfg.replace(model=dataclasses.replace(cfg.model, gen_hidden=hidden))
    if args.con is not None:
        cfg = cfg.replace(loss=dataclasses.replace(cfg.loss, con=args.con))
    if args.lr is not None:
        cfg = cfg.replace(lr=args.lr)
    body = mrlib.load_body_model()
    clips = [mrlib.load_motion(p, fps=args.fps) for p in sorted(DATA_SAMPLES.glob("*.npz"))]
    data = TrainingSet.from_motions(clips, body=body)
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        res = train(data, cfg, tmp, body=body, progress=False)
        train_s = time.perf_counter() - t0
        model = load_model(res.checkpoint)
    t0 = time.perf_counter()
    result = evaluate_model(
        model,
        settings=EvaluationSettings(num_samples=args.samples, seed=args.seed),
        body=body,
        progress=False,
        contacts="both" if args.clean else "raw",
    )
    eval_s = time.perf_counter() - t0
    methods = {d["method"]: d for d in result.summary()}
    summary = methods["ours (raw)" if args.clean else "ours"]  # the raw figures, as in the table
    row = {
        "iterations": list(cfg.block_iterations),
        "n_critic": cfg.n_critic,
        "gen_hidden": list(cfg.model.gen_hidden),
        "fps": args.fps,
        "threads": args.threads,
        "seed": args.seed,
        "lr": cfg.lr,
        "con": cfg.loss.con,
        "train_s": round(train_s, 1),
        "eval_s": round(eval_s, 1),
        **{
            k: round(summary[f"{k}_mean"], 2)
            for k in ("coverage_pct", "cond_fidelity_pct", "skate_pct", "skate_speed")
        },
    }
    print(
        f"iterations {cfg.block_iterations}, n_critic {cfg.n_critic}, gen_hidden "
        f"{cfg.model.gen_hidden}, {args.fps:g} fps, {args.threads} thread(s): training "
        f"{train_s:.0f} s, evaluation {eval_s:.0f} s\n"
    )
    print(headline_table(result))
    if args.clean:
        keys = (
            "coverage_pct",
            "global_div",
            "cond_fidelity_pct",
            "skate_pct",
            "skate_speed",
            "penetration_cm",
        )
        print("\n| | " + " | ".join(keys) + " |\n|---|" + "---:|" * len(keys))
        for d in result.summary():
            print(f"| {d['method']} | " + " | ".join(f"{d[k + '_mean']:.3f}" for k in keys) + " |")
    write_json("demo_budget", row, append=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
