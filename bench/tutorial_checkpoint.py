"""The checkpoint the model-measuring benchmarks read: by default the Bandai `tutorial`
model that ``bench/condition_control.py`` trains (seed 0), or any ``--checkpoint``."""

from __future__ import annotations

import argparse
from pathlib import Path

import torch

import mrlib
from mrlib.sample import GenerativeModel, load_model

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = ROOT / "outputs/condition_control/tutorial_seed0_detail100_mismatch0/checkpoint.pt"


def add_checkpoint_arg(ap: argparse.ArgumentParser) -> None:
    ap.add_argument("--checkpoint", type=Path, default=DEFAULT)


def load(ap: argparse.ArgumentParser, path: Path) -> tuple[GenerativeModel, object]:
    """``(model, body)`` on one torch thread; a missing checkpoint is a usage error."""
    if not path.is_file():
        ap.error(f"{path} not found: run bench/condition_control.py first or pass --checkpoint")
    torch.set_num_threads(1)
    return load_model(path), mrlib.load_body_model()
