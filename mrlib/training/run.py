"""A training run's folder: what a run writes there, the check before a run starts, what
a run returns, and the reuse of a finished run (the model cache of notebooks and
benchmarks).

Nothing here builds networks or trains: :func:`mrlib.training.trainer.train` and the
``train_*`` functions beside it start a :class:`~mrlib.training.trainer.Trainer` and use
these pieces.
"""

from __future__ import annotations

import csv
import hashlib
import json
import os
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mrlib.io.outputs import OutputExistsError
from mrlib.io.paths import cache_root
from mrlib.model.config import TrainConfig, config_to_json
from mrlib.model.trained import load_model
from mrlib.training.data import TrainingSet

__all__ = [
    "RUN_FILES",
    "RunExistsError",
    "check_run_folder",
    "same_file",
    "TrainResult",
    "TrainRecord",
    "reuse_finished_run",
    "model_cache_key",
    "models_root",
    "cache_folder",
]

RUN_FILES = ("checkpoint.pt", "checkpoint.pt.json", "losses.csv")  # what a run writes


class RunExistsError(OutputExistsError):
    """The output folder already holds another training run."""


def same_file(a: Path, b: Path) -> bool:
    """Whether ``a`` and ``b`` name the same existing file."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def check_run_folder(
    out_dir: str | Path, *, resume: str | Path | None = None, overwrite: bool = False
) -> None:
    """Refuse to start a run in ``out_dir`` when that would replace another run's files
    (:data:`RUN_FILES`): a new run needs a folder without them, a resumed run its
    checkpoint's own folder or one without them; ``overwrite=True`` allows both.

    Raises:
        RunExistsError: naming the folder, what it holds and the ways around.
    """
    out = Path(out_dir)
    present = [n for n in RUN_FILES if os.path.lexists(out / n)]
    if not present or overwrite:
        return
    held = ", ".join(present)
    if resume is None:
        raise RunExistsError(
            out,
            f"already holds a training run ({held}); continue it with --resume "
            f"{out / 'checkpoint.pt'}, replace it with --overwrite, or choose another --out",
        )
    if not same_file(out / "checkpoint.pt", Path(resume)):
        raise RunExistsError(
            out,
            f"holds another run ({held}); a resumed run continues in its checkpoint's own "
            f"folder ({Path(resume).parent}) or in a new one (or pass --overwrite)",
        )


@dataclass
class TrainResult:
    """What :func:`mrlib.training.trainer.train` returns."""

    checkpoint: Path
    log: Path
    interrupted: bool
    wall_time_s: float
    losses: dict[int, dict[str, float]]  # last logged losses per level (1-based)


@dataclass(frozen=True)
class TrainRecord:
    """How a model of :func:`mrlib.training.trainer.train_or_reuse` came about."""

    checkpoint: Path
    wall_time_s: float  # training time of the run that wrote the checkpoint
    reused: bool  # True: an earlier, finished run with the same config and clips


def reuse_finished_run(data: TrainingSet, config: TrainConfig, out_dir: str | Path):
    """``(model, record)`` of the finished run in ``out_dir`` when it has the same config
    (field for field, as saved next to the checkpoint) and the same clips; else None,
    after moving a run there that cannot be reused to ``out_dir/previous-<time>/`` with a
    warning saying why (attributed to the caller of ``train_or_reuse``). For a reused run
    the wall time is the last ``time_s`` of its ``losses.csv``."""
    out = Path(out_dir)
    ckpt, log = out / "checkpoint.pt", out / "losses.csv"
    meta = ckpt.with_suffix(".pt.json")
    why = None
    if ckpt.exists() and meta.exists() and log.exists():
        # Compare the JSON itself: a field missing from it means an older mrlib wrote the
        # run, whose defaults may differ from today's.
        saved, wanted = json.loads(meta.read_text()), json.loads(config_to_json(config))
        if saved == wanted:
            model = load_model(ckpt)
            if model.trained_levels == model.num_levels and model.clip_names == list(data.names):
                with open(log, newline="") as fh:
                    rows = list(csv.DictReader(fh))
                wall = float(rows[-1]["time_s"]) if rows else float("nan")
                return model, TrainRecord(ckpt, wall, True)
            why = "unfinished" if model.trained_levels < model.num_levels else "other clips"
        else:
            keys = sorted(k for k in saved.keys() | wanted.keys() if saved.get(k) != wanted.get(k))
            why = "another config: " + ", ".join(
                f"{k} {'missing' if k not in saved else 'differs'}" for k in keys
            )
    elif ckpt.exists():
        why = "no config or loss log beside it"
    if why is not None:
        stamp = time.strftime("previous-%Y%m%d-%H%M%S")
        keep, k = out / stamp, 1
        while keep.exists():
            keep, k = out / f"{stamp}-{k}", k + 1
        keep.mkdir()
        for f in (ckpt, meta, log):
            if f.exists():
                f.rename(keep / f.name)
        warnings.warn(
            f"{out} held a run that is not reused ({why}); moved it to {keep}", stacklevel=3
        )
    return None


def model_cache_key(data: TrainingSet, config: TrainConfig) -> str:
    """A key naming one trained model: the SHA-256 of the config (as saved with the
    checkpoint), the clips' names, labels and frame rate, and their feature values.
    Two notebooks that train the same config on the same clips get the same key."""
    h = hashlib.sha256(config_to_json(config).encode())
    h.update(
        json.dumps([data.names, data.labels, list(map(int, data.clip_labels)), data.fps]).encode()
    )
    for f in data.features:
        h.update(np.ascontiguousarray(f.detach().cpu().numpy(), dtype=np.float32).tobytes())
    return h.hexdigest()


def models_root(cache_dir: str | Path | None = None) -> Path:
    """The model cache: ``cache_dir``, else ``$MRLIB_CACHE_DIR/models``, else the user's
    cache folder (``~/.cache/mrlib/models`` on Linux)."""
    return Path(cache_dir) if cache_dir is not None else cache_root() / "models"


def cache_folder(root: Path, data: TrainingSet, config: TrainConfig) -> Path:
    """The run folder of ``config`` trained on ``data`` in the model cache ``root``."""
    return root / model_cache_key(data, config)[:20]
