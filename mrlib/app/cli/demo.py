"""``mrlib demo``: the end-to-end demo on the bundled data (``mrlib.app.demo``)."""

from __future__ import annotations

import argparse
from pathlib import Path

from mrlib.app.cli.common import (
    add_command,
    parse_positive,
    parse_seed,
    preset_choices,
    preset_help,
    progress_option,
)


def add_demo(sub) -> argparse.ArgumentParser:
    p = add_command(
        sub,
        "demo",
        "end-to-end demo on the bundled data (train, sample, crossover, evaluate)",
        "Load the synthetic clips in data_samples/, retarget a Bandai Namco BVH if "
        "MRLIB_DATA_DIR points at the dataset, train (the 'preview' preset: a few minutes on two "
        "CPU cores), sample every label and a coarse/fine crossover, evaluate, and write renders, "
        "animated previews, exports and summary.md to --out.",
        more=preset_help("labels"),
    )
    p.add_argument(
        "--out", type=Path, default=Path("outputs"), help="folder of the results [default: outputs]"
    )
    p.add_argument(
        "--preset",
        default="preview",
        choices=preset_choices("labels"),
        help="training schedule, one of the presets listed below [default: preview]",
    )
    p.add_argument(
        "--quick", action="store_true", help="smoke-test budget (seconds; results not meaningful)"
    )
    p.add_argument(
        "--iterations",
        type=parse_positive,
        default=None,
        help="iterations per block (overrides the preset)",
    )
    p.add_argument(
        "--samples",
        type=parse_positive,
        default=10,
        help="evaluation samples per label [default: 10]",
    )
    p.add_argument("--seed", type=parse_seed, default=0)
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace an earlier demo run in --out (refused without it)",
    )
    progress_option(p)
    return p


def cmd_demo(args) -> int:
    from mrlib.app.demo import run_demo

    run_demo(
        args.out,
        preset=args.preset,
        quick=args.quick,
        iterations=args.iterations,
        samples=args.samples,
        seed=args.seed,
        overwrite=args.overwrite,
        progress=not args.no_progress,
    )
    return 0
