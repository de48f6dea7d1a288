"""``mrlib evaluate``: score a trained model like the paper's Table 1."""

from __future__ import annotations

import argparse
from pathlib import Path

from mrlib.app.cli.common import (
    add_command,
    device_option,
    overwrite_option,
    parse_positive,
    parse_seed,
    progress_option,
    sampler_from_args,
    sampler_options,
    warn_unfinished,
)
from mrlib.errors import MrlibError
from mrlib.evaluation.results import contact_reading


def add_evaluate(sub) -> argparse.ArgumentParser:
    p = add_command(
        sub,
        "evaluate",
        "score a trained model like the paper's Table 1",
        "Draw samples of 2x the training length with fixed seeds and score them against each "
        "training clip: coverage, global (PNN) and local diversity, reconstruction error, "
        "condition fidelity, foot skating, jitter, penetration and speed distributions, next to "
        "calibration rows (the clip played twice, a frozen frame, other real takes when the clips "
        "are Bandai Namco ones). Writes CSV, Markdown and a plot to --out and prints the table.",
        [
            "mrlib evaluate runs/samples/checkpoint.pt --samples 20",
            "mrlib evaluate runs/walks/checkpoint.pt --baseline runs/ganimator_mode "
            "--out outputs/table1",
        ],
    )
    p.add_argument("checkpoint", type=Path, help="a trained model (a run's checkpoint.pt)")
    p.add_argument(
        "--samples", type=parse_positive, default=200, help="samples per sequence [default: 200]"
    )
    p.add_argument("--eps", type=float, default=2.0, help="coverage threshold [default: 2.0]")
    p.add_argument(
        "--tight-eps",
        type=float,
        default=1.0,
        help="a tighter coverage threshold reported beside it [default: 1.0; at 2.0 a frozen "
        "frame of a slow clip can cover it]",
    )
    p.add_argument("--seed", type=parse_seed, default=0)
    p.add_argument(
        "--features",
        choices=["mrlib", "paper"],
        default="mrlib",
        help="the frame features every window distance uses: mrlib's (23 local rotations in "
        "6D + the 6 foot-contact labels) or the paper's (23 local rotation matrices, no "
        "contact labels; its distances have another scale, so choose --eps and --tight-eps "
        "for it) [default: mrlib]",
    )
    p.add_argument(
        "--baseline",
        type=Path,
        default=None,
        help="a folder of single-clip checkpoints (*/checkpoint.pt) to compare against, "
        "e.g. from `mrlib train --per-clip`",
    )
    p.add_argument("--baseline-name", default="GANimator-mode")
    p.add_argument("--no-calibration", action="store_true", help="leave out the calibration rows")
    sampler_options(p)
    p.add_argument(
        "--raw",
        action="store_true",
        help="score only the raw samples (default: the foot-contact cleaned ones, and the "
        "raw ones beside them as 'ours (raw)', and '<baseline name> (raw)' with --baseline)",
    )
    device_option(p)
    p.add_argument(
        "--out",
        type=Path,
        default=Path("outputs/evaluation"),
        help="folder of the tables, settings and plot [default: outputs/evaluation]",
    )
    overwrite_option(p, "replace evaluation files already in --out")
    progress_option(p)
    return p


EVALUATION_FILES = (
    "evaluation.csv",
    "evaluation_summary.csv",
    "evaluation.md",
    "evaluation_settings.json",
    "evaluation.png",
)


def cmd_evaluate(args) -> int:
    from mrlib.evaluation.evaluate import (
        CalibrationOptions,
        EvaluationSettings,
        evaluate_model,
        model_references,
    )
    from mrlib.evaluation.results import FEATURE_SETS
    from mrlib.io.outputs import check_writable
    from mrlib.io.transaction import output_transaction, when_written
    from mrlib.model.trained import load_model
    from mrlib.viz.plots import plot_evaluation

    for name in EVALUATION_FILES:  # refused before the samples are drawn
        check_writable(Path(args.out) / name, overwrite=args.overwrite)
    model = load_model(args.checkpoint, device=args.device)
    if model.generator.cond_dim != len(model.labels):
        raise MrlibError(
            f"{args.checkpoint} is a speech-conditioned model: `mrlib evaluate` scores label "
            "models; score how its gestures follow speech with mrlib.speech."
            "evaluate_speech_sync (bench/speech_sync.py runs it on held-out utterances)"
        )
    sampler = sampler_from_args(args)
    warn_unfinished(model, args.checkpoint)
    baselines = None
    if args.baseline is not None:
        per_key = {}
        refs = model_references(model)
        for path in sorted(args.baseline.glob("*/checkpoint.pt")):
            # the baselines sample as the model does (guidance moves no one-label model)
            m = load_model(path, device=args.device)
            for key in refs:
                if key in m.clip_names or key in m.labels:
                    per_key[key] = m
        if not per_key:
            raise MrlibError(
                f"no baseline checkpoint in {args.baseline} matches this model's clips"
            )
        missing = [key for key in refs if key not in per_key]
        if missing:
            raise MrlibError(
                f"no baseline checkpoint in {args.baseline} has the clip(s) {missing}: a "
                "baseline needs a model for every clip of this model (mrlib train "
                "--per-clip on the same clips)"
            )
        baselines = {args.baseline_name: per_key}
    result = evaluate_model(
        model,
        baselines,
        settings=EvaluationSettings(
            num_samples=args.samples,
            eps=args.eps,
            tight_eps=args.tight_eps,
            seed=args.seed,
            **FEATURE_SETS[args.features],
            fine_noise=sampler.fine_noise,
            guidance=sampler.guidance,
            candidates=sampler.candidates,
            match_contact_rate=sampler.match_contact_rate,
        ),  # fmt: skip
        calibration=CalibrationOptions(enabled=not args.no_calibration),
        contacts="raw" if args.raw else "both",
        progress=not args.no_progress,
    )
    with output_transaction():  # the five files, or (one fails) none of them
        result.save(args.out, overwrite=args.overwrite)
        plot_evaluation(result, Path(args.out) / "evaluation.png", overwrite=args.overwrite)
        when_written(lambda: print(f"\nwrote {args.out}/"))
    print(
        f"sampler: fine_noise={sampler.fine_noise:g}, guidance={sampler.guidance:g}, "
        f"candidates={sampler.candidates}, contact labels: {contact_reading(model, sampler)}\n"
    )
    print(result.to_markdown())
    return 0
