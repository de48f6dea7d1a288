"""The :class:`Trainer` of the multi-resolution conditional GAN, and :func:`train`.

One run, from construction to the last checkpoint, in four modules:

* ``mrlib.training.build``: what the run builds first (pyramids, noise, networks,
  packed batch layouts, each block's optimisers) and the hooks that turn labels into
  conditions (:class:`~mrlib.training.build.TrainerBase`, which the Trainer extends);
* ``mrlib.training.steps``: one iteration, the paper's objectives as sums of pure loss
  functions (``n_critic`` WGAN-GP critic steps, Eq. 7-8; one generator step, Eq. 6);
* ``mrlib.training.loop``: the block loop, the loss log, Ctrl-C;
* ``mrlib.training.run``: the run folder, what a run returns, and the model cache.

Here: the Trainer itself (one iteration, checkpoints that resume bit-exactly on CPU:
networks, optimizers, iteration and the RNG states; the locked run), :func:`train`, and
the functions that train or reuse a model (:func:`train_or_reuse`, :func:`train_cached`,
:func:`train_cached_many`). ``mrlib.speech.SpeechTrainer`` subclasses the Trainer.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch

from mrlib.errors import (
    ArgumentError,
    check_args,
    check_flag,
    check_optional_path,
    check_path,
    shown,
)
from mrlib.io.outputs import RunLock
from mrlib.io.transaction import outside_transactions
from mrlib.model.checkpoint import (
    CheckpointError,
    global_rng_state,
    load_checkpoint,
    reading,
    save_checkpoint,
    set_global_rng_state,
)
from mrlib.model.config import TrainConfig, config_from_json, config_to_json
from mrlib.model.trained import check_device, load_model
from mrlib.representation.body import check_body
from mrlib.threads import policy, run_threads, usable_cpus
from mrlib.training.build import TrainerBase
from mrlib.training.data import TrainingSet
from mrlib.training.loop import TrainingDivergedError, run_blocks
from mrlib.training.run import (
    RunAttempt,
    TrainRecord,
    TrainResult,
    cache_folder,
    check_run_folder,
    models_root,
    progress_text,
    reuse_finished_run,
    same_file,
)
from mrlib.training.steps import critic_steps, generator_step

__all__ = [
    "train",
    "train_or_reuse",
    "train_cached",
    "train_cached_many",
    "Trainer",
]


class Trainer(TrainerBase):
    """Holds the networks, data pyramids, layouts and optimizers of one training run.

    Use :func:`train` unless you need step-level control (``step`` runs one iteration of
    the current block and returns its losses). Creating a trainer seeds torch's, numpy's
    and Python's global generators with ``config.seed`` (network initialisation); every
    random draw of training then comes from the trainer's own generator ``rng``.
    """

    # -- one iteration ---------------------------------------------------------------------
    def step(self) -> dict[int, dict[str, torch.Tensor]]:
        """One iteration (critic steps + one generator step, ``mrlib.training.steps``) of
        the current block; returns the losses ``{level: {name: value}}`` (0-based levels)."""
        losses: dict[int, dict[str, torch.Tensor]] = {i: {} for i in self.block_levels}
        if self.config.n_critic > 0:
            critic_steps(self, losses)
        generator_step(self, losses)
        return losses

    # -- checkpoints -------------------------------------------------------------------------
    def state_dict(self) -> dict:
        d = self.data
        return {
            "config": config_to_json(self.config),
            "labels": list(d.labels),
            "clip_labels": [int(k) for k in d.clip_labels],
            "clip_names": list(d.names),
            "fps": float(d.fps),
            "betas": torch.as_tensor(np.asarray(d.betas), dtype=torch.float32),
            "cond_dim": int(self.cond_dim),
            "normalizer": d.normalizer.state_dict(),
            "features": [f.detach().cpu().clone() for f in d.features],
            "lengths": self.lengths.clone(),
            "sigma_clip": self.sigma_clip.clone(),
            "sigma": self.sigma.clone(),
            "zstar": [z.clone() for z in self.zstar],
            "generator": {k: v.cpu() for k, v in self.generator.state_dict().items()},
            "critics": {k: v.cpu() for k, v in self.critics.state_dict().items()},
            "progress": {
                "block": int(self.block),
                "iteration": int(self.iteration),
                "done": bool(self.done),
            },
            "optim_g": None if self.opt_g is None else self.opt_g.state_dict(),
            "optim_d": None if self.opt_d is None else self.opt_d.state_dict(),
            "rng": {**global_rng_state(), "trainer": self.rng.get_state()},
            "threads": None if self.threads is None else int(self.threads),
        }

    @classmethod
    def from_checkpoint(
        cls,
        path: str | Path,
        out_dir: str | Path | None = None,
        body=None,
        device: str | None = None,
    ) -> Trainer:
        """Rebuild a trainer (data included) from a checkpoint to continue training.
        A subclass with state of its own (``mrlib.speech.SpeechTrainer``) supplies it
        through :meth:`_check_state`, :meth:`_data_from_state` and :meth:`_init_from_state`."""
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
            trainer.resumed_from = Path(path)
        return trainer

    @classmethod
    def _check_state(cls, path: Path, state: dict) -> None:
        """Refuse a checkpoint of another kind (a label checkpoint: any)."""

    @classmethod
    def _data_from_state(cls, state: dict) -> TrainingSet:
        return TrainingSet.from_state(state)

    @classmethod
    def _init_from_state(cls, state: dict) -> dict:
        """Keyword arguments of the constructor that the checkpoint holds."""
        return {}

    def load_state_dict(self, state: dict) -> None:
        if state["lengths"].shape != self.lengths.shape or not torch.equal(
            state["lengths"], self.lengths
        ):
            raise CheckpointError(None, "checkpoint pyramid lengths do not match the training data")
        self.zstar = [z.clone() for z in state["zstar"]]
        self.zstar_packed = self.rec_layout.pack(self.zstar, 0)
        self.generator.load_state_dict(state["generator"])
        self.critics.load_state_dict(state["critics"])
        p = state["progress"]
        self.block, self.iteration, self.done = (
            int(p["block"]),
            int(p["iteration"]),
            bool(p["done"]),
        )
        if not self.done and self.block < self.config.num_blocks:
            self.start_block()
            if state["optim_g"] is not None:
                self.opt_g.load_state_dict(state["optim_g"])
                self.opt_d.load_state_dict(state["optim_d"])
        set_global_rng_state(state["rng"])
        self.rng.set_state(state["rng"]["trainer"])
        recorded = state.get("threads")  # absent in checkpoints of earlier versions
        self.threads = int(recorded) if isinstance(recorded, int) and recorded >= 1 else None

    def save(self, path: Path | None = None) -> Path:
        """Write the checkpoint; refuses (keeping the previous file) when a network holds
        a non-finite weight."""
        for name, net in (("generator", self.generator), ("critics", self.critics)):
            if not all(bool(torch.isfinite(p).all()) for p in net.parameters()):
                raise TrainingDivergedError(
                    f"the {name} has non-finite weights at block {self.block + 1}, iteration "
                    f"{self.iteration}; the checkpoint was not overwritten"
                )
        out = save_checkpoint(path or self.out_dir / "checkpoint.pt", self.state_dict())
        self._saved = True
        self._saves = getattr(self, "_saves", 0) + 1  # what a failed fit says it kept:
        self._last_saved = f"the checkpoint of {progress_text(self)} ({out})"
        return out

    # -- the run -------------------------------------------------------------------------------
    def fit(
        self,
        progress: bool = True,
        callback: Callable[[Trainer, dict[int, dict[str, float]]], None] | None = None,
        *,
        overwrite: bool = False,
    ) -> TrainResult:
        """Train every remaining block (``mrlib.training.loop``); see :func:`train`. The
        output folder is locked while it runs (``mrlib.io.outputs.RunLock``: a second run
        there is refused) and checked first (:func:`check_run_folder`). The run keeps one
        torch thread count from start to end (``mrlib.threads.run_threads``: the user's
        choice, else the count recorded by the run it resumes, else mrlib's default), and
        records it in its checkpoints."""
        n, why = run_threads(self.threads)
        if why == "user" and self.threads is not None and n != self.threads:
            warnings.warn(
                f"this run was started with {self.threads} torch threads and continues with "
                f"{n}: its weights may differ (by float rounding) from an uninterrupted run's; "
                f"--threads {self.threads} continues it exactly",
                RuntimeWarning,
                stacklevel=2,
            )
        elif why == "resumed" and n > usable_cpus():
            warnings.warn(
                f"this run was started with {n} torch threads, more than the {usable_cpus()} "
                "CPUs usable here; it keeps that count so that it continues exactly "
                "(--threads N trades that for speed)",
                RuntimeWarning,
                stacklevel=2,
            )
        self.threads = n
        # a run that fails before its first checkpoint leaves the folder as it was
        # (mrlib.training.run.RunAttempt); its files reach the disk as it goes, outside
        # any output transaction of the caller
        attempt, saves, claiming = RunAttempt(self.out_dir), getattr(self, "_saves", 0), False
        ckpt, earlier, elsewhere = self.out_dir / "checkpoint.pt", None, None
        if getattr(self, "_last_saved", None) is not None:  # by an earlier fit
            earlier = self._last_saved
        elif self.resumed_from is not None and same_file(self.resumed_from, ckpt):
            earlier = f"the checkpoint it resumed from ({progress_text(self)})"
        elif self.resumed_from is not None:
            elsewhere = self.resumed_from
        try:
            with policy(n), outside_transactions(), RunLock(self.out_dir):
                claiming = not self._claimed
                if claiming:
                    check_run_folder(self.out_dir, resume=self.resumed_from, overwrite=overwrite)
                # a fresh start moves the old run aside: nothing of it remains in the way
                attempt.claim(fresh=overwrite and claiming and self.resumed_from is None)
                self._claimed = True
                result = run_blocks(self, progress, callback)
                if not self._saved and not same_file(ckpt, self.resumed_from or ckpt):
                    self.save()  # resumed from a finished run into another folder: copy it there
        except BaseException as e:
            wrote = self._last_saved if getattr(self, "_saves", 0) > saves else None
            if wrote is None and claiming and attempt.claimed:
                self._claimed = False  # the folder is as it was: check it again next time
            err = attempt.failed(e, wrote=wrote, earlier=earlier, resumed_from=elsewhere)
            if err is e:
                raise
            raise err from e
        attempt.drop()
        return result


def _instance(kind: type, what: str):
    def check(name: str, value):
        if value is None or isinstance(value, kind):
            return value
        raise ArgumentError(f"{name} must be {what} or None, got {shown(value)}")

    return check


@check_args(
    data=_instance(TrainingSet, "a TrainingSet (TrainingSet.from_motions / from_files)"),
    config=_instance(TrainConfig, "a TrainConfig (e.g. mrlib.get_preset('demo'))"),
    out_dir=check_path,
    resume=check_optional_path,
    body=check_body,
    device=lambda n, v: None if v is None else check_device(n, v),
    progress=check_flag,
    callback=lambda n, v: (
        v if v is None or callable(v) else _instance(type(None), "a function")(n, v)
    ),
    overwrite=check_flag,
)
def train(
    data: TrainingSet | None,
    config: TrainConfig | None,
    out_dir: str | Path,
    *,
    resume: str | Path | None = None,
    body=None,
    device: str | None = None,
    progress: bool = True,
    callback: Callable[[Trainer, dict[int, dict[str, float]]], None] | None = None,
    overwrite: bool = False,
) -> TrainResult:
    """Train a model, or continue one.

    Args:
        data: the clips (ignored when resuming: the checkpoint holds them).
        config: a ``TrainConfig`` (e.g. ``mrlib.model.config.tutorial()``); ignored when resuming.
        out_dir: folder for ``checkpoint.pt`` (+ ``checkpoint.pt.json``) and ``losses.csv``.
        resume: a checkpoint to continue from, exactly where it stopped.
        body: body model for the contact and smoothness losses (default ``load_body_model()``).
        device: when resuming, continue on this device instead of the checkpoint's
            (the config's device otherwise).
        progress: show a tqdm bar per block with the latest losses.
        callback: called after every iteration with the trainer and the last logged losses
            ``{level: {name: value}}``; raising ``KeyboardInterrupt`` in it stops training
            like Ctrl-C (a checkpoint is written first).
        overwrite: replace a run already in ``out_dir`` (another run's files are refused
            otherwise, :func:`check_run_folder`; resuming in the checkpoint's own folder
            needs no flag).
    Returns:
        a :class:`TrainResult`; ``interrupted`` tells whether it stopped early.

    Raises:
        RunExistsError: ``out_dir`` holds another run (checked before any work).
        mrlib.io.outputs.RunLockedError: another process is training into ``out_dir``.
    """
    check_run_folder(out_dir, resume=resume, overwrite=overwrite)
    if resume is not None:
        trainer = Trainer.from_checkpoint(resume, out_dir=out_dir, body=body, device=device)
    else:
        if data is None or config is None:
            raise CheckpointError(None, "train() needs data and config unless resume is given")
        trainer = Trainer(data, config, out_dir, body=body)
    return trainer.fit(progress=progress, callback=callback, overwrite=overwrite)


# -- trained once, reused after (notebooks and benchmarks) -------------------------------------
def train_or_reuse(
    data: TrainingSet,
    config: TrainConfig,
    out_dir: str | Path,
    *,
    body=None,
    progress: bool = True,
):
    """Train with :func:`train` unless ``out_dir`` already holds a finished run with the
    same config (field for field, as saved next to the checkpoint) and the same clips;
    then load it. Notebooks and benchmarks use this so that a long run is not repeated
    on every execution. A run there that cannot be reused is not overwritten: its files
    move to ``out_dir/previous-<time>/``, with a warning saying why
    (``mrlib.training.run.reuse_finished_run``).

    Returns:
        ``(model, record)``: the ``GenerativeModel`` and a :class:`TrainRecord`; for a
        reused run the wall time is the last ``time_s`` of its ``losses.csv`` (the time
        of its last logged iteration, without the final checkpoint write).
    """
    out = Path(out_dir)
    reused = reuse_finished_run(data, config, out)
    if reused is not None:
        return reused
    # what was worth keeping moved aside; a loss log without its checkpoint is not
    res = train(data, config, out, body=body, progress=progress, overwrite=True)
    return load_model(res.checkpoint), TrainRecord(res.checkpoint, res.wall_time_s, False)


def train_cached(
    data: TrainingSet,
    config: TrainConfig,
    *,
    body=None,
    progress: bool = True,
    cache_dir: str | Path | None = None,
):
    """:func:`train_or_reuse` in a folder of mrlib's model cache named by
    :func:`model_cache_key`, so a model trained once (by one notebook, say) is loaded by
    every later call with the same config and clips instead of trained again.

    The cache is ``cache_dir``, else ``$MRLIB_CACHE_DIR/models``, else the user's cache
    folder (``~/.cache/mrlib/models`` on Linux); delete a folder there to retrain.

    Returns:
        ``(model, record)`` as :func:`train_or_reuse`.
    """
    out = cache_folder(models_root(cache_dir), data, config)
    out.mkdir(parents=True, exist_ok=True)
    return train_or_reuse(data, config, out, body=body, progress=progress)


def _train_cached_in_worker(args) -> None:
    """One :func:`train_cached` in a worker process, on one torch thread."""
    data, config, cache_dir = args
    torch.set_num_threads(1)
    train_cached(data, config, progress=False, cache_dir=cache_dir)


def train_cached_many(
    sets: list[TrainingSet],
    config: TrainConfig,
    *,
    workers: int | None = None,
    body=None,
    cache_dir: str | Path | None = None,
) -> list:
    """:func:`train_cached` for several training sets (GANimator-mode: one model per
    clip), training the ones not in the cache side by side in ``workers`` processes of
    one torch thread each (default: one per usable CPU, ``mrlib.threads.usable_cpus``).
    Where the CPUs run two processes at full speed, two models train in the time of one;
    on this project's 2-core x86-64 VM (two vCPUs) notebook 05's four ``demo`` models took
    277 s side by side against 284 s one after another. On a busy machine pass
    ``workers=1``.

    Returns:
        ``[(model, record), ...]`` in the order of ``sets``, as :func:`train_cached`
        (``record.reused`` is false for the models trained by this call).
    """
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    from mrlib.threads import usable_cpus

    root = models_root(cache_dir)
    todo = [d for d in sets if not (cache_folder(root, d, config) / "checkpoint.pt").exists()]
    n = min(len(todo), workers if workers is not None else usable_cpus())
    if n > 1:
        ctx = multiprocessing.get_context("spawn")  # no forked torch thread pools
        with ProcessPoolExecutor(n, mp_context=ctx) as pool:
            list(pool.map(_train_cached_in_worker, [(d, config, root) for d in todo]))
    out = [train_cached(d, config, body=body, progress=False, cache_dir=root) for d in sets]
    trained = {id(d) for d in todo}
    return [
        (m, dataclasses.replace(r, reused=False) if id(d) in trained else r)
        for d, (m, r) in zip(sets, out, strict=True)
    ]
