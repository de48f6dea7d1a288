"""What a training checkpoint holds, and a trainer rebuilt from one.

A checkpoint (``mrlib.model.checkpoint``: a dict of tensors, lists and numbers, loadable
with ``weights_only=True``) holds the config, the training set (features, labels,
normaliser, body shape), the pyramid (lengths, noise amplitudes, z*_1), the generator's
and the critics' weights, where the schedule stands (block, iteration, done), the
current block's optimiser states, every RNG state and the run's torch thread count: a
run resumed from it continues bit-exactly on CPU. :class:`mrlib.training.trainer.Trainer`
calls these from ``state_dict``, ``load_state_dict``, ``save`` and ``from_checkpoint``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from mrlib.model.checkpoint import (
    CheckpointError,
    contact_choice,
    global_rng_state,
    load_checkpoint,
    reading,
    save_checkpoint,
    set_global_rng_state,
)
from mrlib.model.config import config_from_json, config_to_json
from mrlib.training.monitor import TrainingDivergedError
from mrlib.training.run import progress_text

__all__ = [
    "trainer_state",
    "load_trainer_state",
    "save_trainer",
    "trainer_from_checkpoint",
    "record_contact_reading",
]


def trainer_state(tr) -> dict:
    """The checkpoint of a ``Trainer`` ``tr`` (see the module's docstring)."""
    d, b, a = tr.data, tr.batches, tr.active
    return {
        "config": config_to_json(tr.config),
        "labels": list(d.labels),
        "clip_labels": [int(k) for k in d.clip_labels],
        "clip_names": list(d.names),
        "fps": float(d.fps),
        **({"clip_fps": [float(r) for r in d.source_fps]} if d.source_fps else {}),
        "betas": torch.as_tensor(np.asarray(d.betas), dtype=torch.float32),
        "cond_dim": int(tr.signal.dim),
        "normalizer": d.normalizer.state_dict(),
        "features": [f.detach().cpu().clone() for f in d.features],
        "lengths": b.lengths.clone(),
        "sigma_clip": b.sigma_clip.clone(),
        "sigma": tr.signal.sigma.clone(),
        "zstar": [z.clone() for z in b.zstar],
        "generator": {k: v.cpu() for k, v in tr.generator.state_dict().items()},
        "critics": {k: v.cpu() for k, v in tr.critics.state_dict().items()},
        "progress": {"block": int(tr.block), "iteration": int(tr.iteration), "done": bool(tr.done)},
        "optim_g": None if a is None else a.opt_g.state_dict(),
        "optim_d": None if a is None else a.opt_d.state_dict(),
        "rng": {**global_rng_state(), "trainer": tr.rng.get_state()},
        "threads": None if tr.threads is None else int(tr.threads),
        **({} if tr.contact_at_rate is None else {"contact_at_rate": list(tr.contact_at_rate)}),
    }


def load_trainer_state(tr, state: dict) -> None:
    """Put ``tr`` (built from the same data and config) where the checkpoint ``state``
    stands: weights, z*_1, schedule position, the block's optimisers, RNG states."""
    b = tr.batches
    if state["lengths"].shape != b.lengths.shape or not torch.equal(state["lengths"], b.lengths):
        raise CheckpointError(None, "checkpoint pyramid lengths do not match the training data")
    b.set_zstar(state["zstar"])
    tr.generator.load_state_dict(state["generator"])
    tr.critics.load_state_dict(state["critics"])
    p = state["progress"]
    tr.block, tr.iteration, tr.done = int(p["block"]), int(p["iteration"]), bool(p["done"])
    tr.contact_at_rate = contact_choice(state)
    if not tr.done and tr.block < tr.config.num_blocks:
        tr.start_block()
        if state["optim_g"] is not None:
            tr.active.opt_g.load_state_dict(state["optim_g"])
            tr.active.opt_d.load_state_dict(state["optim_d"])
    set_global_rng_state(state["rng"])
    tr.rng.set_state(state["rng"]["trainer"])
    recorded = state.get("threads")  # absent in checkpoints of earlier versions
    tr.threads = int(recorded) if isinstance(recorded, int) and recorded >= 1 else None


def save_trainer(tr, path: Path | None = None) -> Path:
    """Write ``tr``'s checkpoint (default ``out_dir/checkpoint.pt``); refuses, keeping the
    previous file, when a network holds a non-finite weight."""
    for name, net in (("generator", tr.generator), ("critics", tr.critics)):
        if not all(bool(torch.isfinite(p).all()) for p in net.parameters()):
            raise TrainingDivergedError(
                f"the {name} has non-finite weights at block {tr.block + 1}, iteration "
                f"{tr.iteration}; the checkpoint was not overwritten"
            )
    out = save_checkpoint(path or tr.out_dir / "checkpoint.pt", tr.state_dict())
    tr.folder.saved(out, progress_text(tr))  # what a failed fit says it kept
    return out


def trainer_from_checkpoint(cls, path: str | Path, out_dir, body, device):
    """A trainer of class ``cls`` (data included) rebuilt from the checkpoint ``path`` to
    continue training, in ``out_dir`` (default: the checkpoint's folder), on ``device``
    (default: the checkpoint's). A subclass with state of its own supplies it through
    ``cls._check_state``, ``cls._data_from_state`` and ``cls._init_from_state``."""
    state = load_checkpoint(path)
    with reading(path):
        cls._check_state(Path(path), state)
        config = config_from_json(state["config"])
        if device is not None:
            config = config.replace(device=device)
        data = cls._data_from_state(state)
        out = Path(path).parent if out_dir is None else out_dir
        trainer = cls(data, config, out, body=body, **cls._init_from_state(state))
        trainer.load_state_dict(state)
        trainer.folder.resumed_from = Path(path)
    return trainer


def record_contact_reading(tr, progress: bool) -> None:
    """When ``tr``'s run has finished a label model (a stopped run has not): each label's
    reading of the contact output (``mrlib.sampling.contact_choice``), kept in ``tr`` and
    saved."""
    speech = tr.signal.dim != len(tr.data.labels)  # (before building a model to ask it)
    if not tr.done or tr.contact_at_rate is not None or speech:
        return
    from mrlib.model.trained import model_from_trainer
    from mrlib.sampling.contact_choice import settle_contact_reading

    chosen = settle_contact_reading(model_from_trainer(tr), progress)
    if chosen is not None:
        tr.contact_at_rate = chosen
        tr.save()
