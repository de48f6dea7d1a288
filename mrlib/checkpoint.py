"""Checkpoint files: a plain dict of tensors and Python scalars/strings/lists.

Written with ``torch.save`` to a temporary file in the same folder and moved into place
with ``os.replace`` (atomic: a crash never leaves a half-written checkpoint), read with
``torch.load(..., weights_only=True)`` (no pickled classes; safe to load from others).
The training config is stored as a JSON string under ``"config"`` and also written as
``<checkpoint>.json`` next to the file.

Keys (``FORMAT_VERSION`` 1)::

    format, version          "mrlib-checkpoint", 1
    config                   TrainConfig as JSON
    labels                   condition names, list[str]; clip_labels list[int] per clip
    clip_names, fps, betas   training clips' names, frame rate, body shape (10,)
    cond_dim                 size D of a condition vector
    normalizer               {"mean": (C,), "std": (C,)}
    features                 training clips, list of (T_k, C) unnormalised
    lengths                  (N, L) int: pyramid lengths of every clip
    sigma_clip, sigma        (N, L) noise amplitudes per clip; (K, L) per label (mean)
    zstar                    list of (1 or C, T_1,k) fixed reconstruction noise per clip
    generator, critics       state dicts
    progress                 {"block": int, "iteration": int, "done": bool}
    optim_g, optim_d         optimizer state dicts of the running block (or None)
    rng                      {"torch", "numpy", "python", "trainer"} RNG states
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import torch

from mrlib.errors import MotionFileError

__all__ = ["FORMAT", "FORMAT_VERSION", "save_checkpoint", "load_checkpoint", "CheckpointError"]

FORMAT = "mrlib-checkpoint"
FORMAT_VERSION = 1


class CheckpointError(MotionFileError):
    """A checkpoint file is missing, unreadable, or not an mrlib checkpoint."""


def save_checkpoint(path: str | Path, state: dict[str, Any]) -> Path:
    """Write ``state`` atomically to ``path`` (and its config to ``path.json``)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    state = {"format": FORMAT, "version": FORMAT_VERSION, **state}
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    torch.save(state, tmp)
    os.replace(tmp, path)
    if "config" in state:
        jtmp = path.with_name(f".{path.name}.json.tmp{os.getpid()}")
        jtmp.write_text(state["config"])
        os.replace(jtmp, path.with_suffix(path.suffix + ".json"))
    return path


def load_checkpoint(path: str | Path, map_location: str | torch.device = "cpu") -> dict[str, Any]:
    """Read a checkpoint with ``weights_only=True`` and check its format."""
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(path, "no such checkpoint file")
    try:
        state = torch.load(path, map_location=map_location, weights_only=True)
    except Exception as exc:  # torch raises several types for corrupt or unsafe files
        raise CheckpointError(path, f"cannot read checkpoint: {exc}") from exc
    if not isinstance(state, dict) or state.get("format") != FORMAT:
        raise CheckpointError(path, "not an mrlib checkpoint (missing 'format' key)")
    if state.get("version") != FORMAT_VERSION:
        raise CheckpointError(
            path,
            f"checkpoint version {state.get('version')} is not supported "
            f"(this mrlib reads version {FORMAT_VERSION})",
        )
    return state
