"""Training the multi-resolution GAN (paper Sec. 3.4). Read this file top to bottom:

1. :func:`train` makes a :class:`Trainer`, fresh or resumed (:meth:`Trainer.start`).
2. ``Trainer(data, config, out_dir)`` builds the run's state: the fixed batches (every
   clip's pyramid, packed; ``build``), the control signal (labels; ``signals``), the
   generator and the critics, where the schedule stands; each block brings its
   optimisers (:class:`BlockState`).
3. :meth:`Trainer.fit` holds the run folder (``run.RunFolder``: lock, thread count)
   around :func:`run_blocks`, the block loop: per block of two levels, freeze the levels
   below, new Adam optimisers, iterations until the block's budget, each logged to
   ``losses.csv``, a checkpoint every ``checkpoint_every`` iterations and at the block's
   end; the first Ctrl-C finishes the iteration, checkpoints and returns (``monitor``).
4. :meth:`Trainer.step`: :func:`critic_steps` (Adam steps on WGAN-GP, Eq. 12-13) and
   :func:`generator_step` (one Adam step on Eq. 11), summed over the block's levels from
   the pure terms of ``objective``.

Checkpoints are ``checkpoints``; at the end, the functions that train or reuse a model
(:func:`train_or_reuse`, :func:`train_cached`, :func:`train_cached_many`). Speech: a
``mrlib.speech.SpeechTrainer`` (module names are those of ``mrlib.training``).
"""

from __future__ import annotations

import dataclasses
import functools
import random
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch

from mrlib.errors import check_args, check_flag, check_optional_path, check_path
from mrlib.model.checkpoint import CheckpointError
from mrlib.model.config import TrainConfig
from mrlib.model.generator import MultiResGenerator
from mrlib.model.trained import load_model
from mrlib.representation.body import check_body
from mrlib.sampling.contact_choice import settle_contact_reading
from mrlib.threads import usable_cpus
from mrlib.training import build, checkpoints, objective
from mrlib.training.build import Batches, Kinematics, build_batches, build_networks, make_adam
from mrlib.training.data import TrainingSet, check_training_fps, instance_or_none
from mrlib.training.monitor import CtrlC, LossLog, block_bar, check_finite
from mrlib.training.run import (
    RunFolder,
    TrainRecord,
    TrainResult,
    cache_folder,
    check_run_folder,
    models_root,
    progress_text,
    reuse_finished_run,
    same_file,
    thread_count_of_fit,
)
from mrlib.training.signals import LabelSignal, RandomDraw

__all__ = ["train", "train_or_reuse", "train_cached", "train_cached_many", "Trainer"]

Losses = dict[int, dict[str, torch.Tensor]]  # {level: {term: value}}, 0-based levels


# -- 1. the entry point -------------------------------------------------------------------------
@check_args(
    data=instance_or_none(TrainingSet, "a TrainingSet (TrainingSet.from_motions / from_files)"),
    config=instance_or_none(TrainConfig, "a TrainConfig (e.g. mrlib.get_preset('demo'))"),
    out_dir=check_path,
    resume=check_optional_path,
    body=check_body,
    progress=check_flag,
    callback=lambda n, v: (
        v if v is None or callable(v) else instance_or_none(type(None), "a function")(n, v)
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
    progress: bool = True,
    callback: Callable[[Trainer, dict[int, dict[str, float]]], None] | None = None,
    overwrite: bool = False,
) -> TrainResult:
    """Train a model, or continue one.

    Args:
        data: the clips (ignored when resuming: the checkpoint holds them), at the
            config's frame rate when it sets one (``TrainConfig.fps``: build them with
            ``TrainingSet.from_files(paths, fps=config.fps)``).
        config: a ``TrainConfig`` (e.g. ``mrlib.model.presets.tutorial()``); ignored when resuming.
        out_dir: folder for ``checkpoint.pt`` (+ ``checkpoint.pt.json``) and ``losses.csv``.
        resume: a checkpoint to continue from, exactly where it stopped (on the
            checkpoint's device; ``Trainer.start(..., device=...)`` moves it).
        body: body model for the contact and smoothness losses (default ``load_body_model()``).
        progress: show a tqdm bar per block with the latest losses.
        callback: called after every iteration with the trainer and the last logged losses
            ``{level: {name: value}}``; raising ``KeyboardInterrupt`` in it stops training
            like Ctrl-C (a checkpoint is written first).
        overwrite: replace a run already in ``out_dir`` (another run's files are refused
            otherwise, ``mrlib.training.run.check_run_folder``; resuming in the
            checkpoint's own folder needs no flag).
    Returns:
        a :class:`TrainResult`; ``interrupted`` tells whether it stopped early.
    Raises:
        RunExistsError: ``out_dir`` holds another run (checked before any work).
        mrlib.io.outputs.RunLockedError: another process is training into ``out_dir``.
        ConfigError: ``config.fps`` is set and ``data`` is at another frame rate.
    """
    trainer = Trainer.start(data, config, out_dir, resume=resume, body=body, overwrite=overwrite)
    return trainer.fit(progress=progress, callback=callback, overwrite=overwrite)


# -- 2. the state of a run ------------------------------------------------------------------------
@dataclasses.dataclass
class BlockState:
    """The block being trained: its 0-based levels, its Adam optimisers, and the frozen
    levels' reconstruction of every clip (its input; from the block's first step on)."""

    levels: list[int]
    opt_g: torch.optim.Adam
    opt_d: torch.optim.Adam
    frozen: torch.Tensor | None = None


class Trainer:
    """The state of one training run: data and config; ``rng``, the generator of every
    random draw of training; ``kinematics`` (the body model); ``batches``, the fixed
    packed batches (``mrlib.training.build.Batches``); ``signal``, the conditions
    (``mrlib.training.signals``); ``generator`` and ``critics``; ``block``,
    ``iteration`` and ``done``, where the schedule stands; ``active``, the block being
    trained (None between blocks); ``folder``, the run folder's bookkeeping.

    Step-level control: :meth:`start_block`, then :meth:`step` (returns the losses).
    Creating a trainer seeds torch's, numpy's and Python's global generators.
    """

    def __init__(self, data: TrainingSet, config: TrainConfig, out_dir: str | Path, body=None):
        check_training_fps(data, config.fps)
        self.data, self.config, self.out_dir = data, config, Path(out_dir)
        self.device = torch.device(config.device)
        self.folder = RunFolder(self.out_dir)
        self.threads: int | None = None  # the run's torch thread count, fixed by fit()
        self.rng = torch.Generator().manual_seed(config.seed)  # every random draw of training
        torch.manual_seed(config.seed)  # network initialisation
        np.random.seed(config.seed)
        random.seed(config.seed)
        self.kinematics = Kinematics(data, body, self.device)
        self.batches: Batches = build_batches(data, config, self.rng, self.device)
        self.signal = self.control_signal()
        self.generator: MultiResGenerator
        self.generator, self.critics = build_networks(config.model, self.signal.dim, self.device)
        self.block, self.iteration, self.done = 0, 0, False
        self.active: BlockState | None = None
        self.contact_at_rate: tuple[str, ...] | None = None  # chosen when the run ends

    def control_signal(self) -> LabelSignal:
        """The conditions of this run: labels (a subclass returns its own signal, see
        ``mrlib.training.signals`` for what it provides)."""
        return LabelSignal(self.data, self.batches, self.config, self.rng)

    @classmethod
    def start(
        cls,
        data,
        config: TrainConfig | None,
        out_dir: str | Path,
        *,
        resume: str | Path | None = None,
        device: str | None = None,
        body=None,
        overwrite: bool = False,
        options: dict | None = None,
    ) -> Trainer:
        """A trainer for :meth:`fit`: fresh (``cls(data, config, out_dir, body=body,
        **options)``), or resumed from the checkpoint ``resume`` (``data``, ``config``
        and ``options`` ignored; ``device``: continue there instead of the checkpoint's
        device). The run folder is checked first (``check_run_folder``)."""
        check_run_folder(out_dir, resume=resume, overwrite=overwrite)
        if resume is not None:
            return cls.from_checkpoint(resume, out_dir=out_dir, body=body, device=device)
        if data is None or config is None:
            raise CheckpointError(None, "training needs data and config unless resume is given")
        return cls(data, config, out_dir, body=body, **(options or {}))

    @property
    def block_levels(self) -> list[int]:
        return self.config.blocks[self.block]

    def start_block(self) -> None:
        """Freeze the levels below the current block and create its optimisers."""
        levels, c = self.block_levels, self.config
        for i, (g, d) in enumerate(zip(self.generator.levels, self.critics, strict=False)):
            g.requires_grad_(levels[0] <= i <= levels[-1])
            d.requires_grad_(levels[0] <= i <= levels[-1])
        g_params = [p for i in levels for p in self.generator.levels[i].parameters()]
        d_params = [p for i in levels for p in self.critics[i].parameters()]
        opt_g = make_adam(g_params, c.lr, c.betas, self.device)
        self.active = BlockState(levels, opt_g, make_adam(d_params, c.lr, c.betas, self.device))

    # -- 3. the run ---------------------------------------------------------------------------
    def fit(
        self,
        progress: bool = True,
        callback: Callable[[Trainer, dict[int, dict[str, float]]], None] | None = None,
        *,
        overwrite: bool = False,
    ) -> TrainResult:
        """Train every remaining block (:func:`run_blocks`; see :func:`train`) on the
        process's torch thread count (recorded in the checkpoints; a resumed run on another
        count warns, a finished one has nothing to train); then a finished label model
        chooses each label's contact reading (``mrlib.sampling.contact_choice``)."""
        self.threads = thread_count_of_fit(None if self.done else self.threads)
        ckpt = self.out_dir / "checkpoint.pt"
        with self.folder.fitting(overwrite, progress_text(self)):
            result = run_blocks(self, progress, callback)
            checkpoints.record_contact_reading(self, progress)
            if self.folder.saves == 0 and not same_file(ckpt, self.folder.resumed_from or ckpt):
                self.save()  # resumed from a finished run into another folder: copy it there
        return result

    # -- 4. one iteration -----------------------------------------------------------------------
    def step(self) -> Losses:
        """One iteration of the current block: ``n_critic`` critic steps, then one
        generator step; returns the losses ``{level: {name: value}}`` (0-based levels)."""
        a, b, G, sig, c = self.active, self.batches, self.generator, self.signal, self.config
        if a.frozen is None and a.levels[0] > 0:  # the frozen levels' output, once per block
            lo = a.levels[0]
            with torch.no_grad():
                a.frozen = G.run(b.rec_layout, b.rec_noises(lo), sig.rec_conditions(lo), 0, lo)
        losses: Losses = {i: {} for i in a.levels}
        if c.n_critic > 0:
            losses = critic_steps(G, self.critics, a, b, sig, c, self.rng)
        with build.frozen(self.critics[i] for i in a.levels):  # their gradients would go unused
            for i, t in generator_step(G, self.critics, a, b, sig, c, self.kinematics).items():
                losses[i].update(t)
        return losses

    # -- checkpoints (mrlib.training.checkpoints) ------------------------------------------------
    def state_dict(self) -> dict:
        return checkpoints.trainer_state(self)

    def load_state_dict(self, state: dict) -> None:
        checkpoints.load_trainer_state(self, state)

    def save(self, path: Path | None = None) -> Path:
        """Write the checkpoint; refuses (keeping the previous file) when a network holds
        a non-finite weight."""
        return checkpoints.save_trainer(self, path)

    @classmethod
    def from_checkpoint(
        cls, path: str | Path, out_dir: str | Path | None = None, body=None, device=None
    ) -> Trainer:
        """Rebuild a trainer (data included) from a checkpoint to continue training. A
        subclass with state of its own (``mrlib.speech.SpeechTrainer``) supplies it
        through :meth:`_check_state`, :meth:`_data_from_state`, :meth:`_init_from_state`."""
        return checkpoints.trainer_from_checkpoint(cls, path, out_dir, body, device)

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


# -- 3. the block loop --------------------------------------------------------------------------
def run_blocks(tr: Trainer, progress: bool, callback: Callable | None) -> TrainResult:
    """Train every remaining block of ``tr`` from where it stands (paper Sec. 3.4: two
    consecutive levels at a time, the levels of earlier blocks frozen)."""
    c = tr.config
    log = LossLog(tr.out_dir, tr.folder.resumed_from, tr.block, tr.iteration)
    with log, CtrlC() as ctrl_c:
        while tr.block < c.num_blocks and not ctrl_c.pressed:
            if tr.active is None:
                tr.start_block()
            n_iter = c.block_iterations[tr.block]
            with block_bar(c, tr.block, tr.iteration, progress) as bar, ctrl_c.catch():
                while tr.iteration < n_iter:
                    with ctrl_c.step():  # a KeyboardInterrupt in here propagates, unsaved
                        losses = tr.step()
                        check_finite(losses, tr.block, tr.iteration, tr.out_dir)
                        tr.iteration += 1
                    if tr.iteration % c.log_every == 0 or tr.iteration == n_iter:
                        top = log.write(tr.block, tr.iteration, losses)
                        bar.set_postfix({k: f"{v:.3g}" for k, v in top.items()}, refresh=False)
                    bar.update(1)
                    if callback is not None:
                        callback(tr, log.last)
                    every = c.checkpoint_every
                    if every and tr.iteration % every == 0 and tr.iteration < n_iter:
                        tr.save()
                    if ctrl_c.pressed:
                        break
            if not ctrl_c.pressed:  # the block is done: on to the next
                tr.block, tr.iteration, tr.active = tr.block + 1, 0, None
                tr.done = tr.block >= c.num_blocks
            tr.save()
    ckpt = tr.out_dir / "checkpoint.pt"
    return TrainResult(ckpt, log.path, ctrl_c.pressed, log.elapsed(), log.last)


# -- 4. the steps -------------------------------------------------------------------------------
# G: the generator; a: the block being trained; b: the run's batches; signal: its conditions
def critic_steps(G, critics, a: BlockState, b: Batches, signal, config, rng) -> Losses:
    """``n_critic`` Adam steps of the block's critics, each on the sum over its levels of
    the critic loss (``objective.critic_terms``: WGAN-GP, Eq. 12-13, + the mismatch
    term). The fakes of all steps come from one batched, gradient-free generation (the
    generator does not change between critic steps: GANimator's one generation per
    step, in distribution). Returns ``D``, ``gp`` (and ``mis``) of the last step."""
    hi, lay, B = a.levels[-1], b.rand_layout, len(b.rand_clip)
    losses: Losses = {i: {} for i in a.levels}
    draw = signal.draw_random(b.fake_layout, hi + 1)
    with torch.no_grad():
        fakes = G.run(b.fake_layout, draw.noises, draw.conds, 0, hi + 1, keep=True)
    keep = cond_fake = None  # conditional critics: which fakes keep their condition, and it
    if signal.real_conds is not None:
        keep, cond_fake = signal.critic_keep(draw), signal.critic_conditions(draw, b.fake_layout)
    alphas = torch.rand(config.n_critic, B, generator=rng).to(b.device)
    for j in range(config.n_critic):
        a.opt_d.zero_grad(set_to_none=True)
        total = 0.0
        for i in a.levels:
            S = lay.sizes[i]
            fake = fakes[i][..., j * S : (j + 1) * S]  # the j-th copy of the random layout
            conds = wrong = None
            if keep is not None:
                # a real clip is shown without its condition where its fake partner (same
                # sample slot) is: both sides see the same kind of condition
                k = lay.per_sample(keep[j * B : (j + 1) * B, i], i)[None, :, None]
                conds = (signal.real_conds[i] * k, cond_fake[i][:, j * S : (j + 1) * S])
                if signal.mismatch:
                    wrong = signal.mismatched_real_conditions(i) * k
            alpha = lay.per_sample(alphas[j], i)[None, None]  # (1, 1, S)
            pads = (lay.pad_index(i, G.pad), b.critic_layout.pad_index(i, G.pad))
            real, w = b.levels[i].real_rand, b.levels[i].w_rand
            t = objective.critic_terms(critics[i], real, fake, w, alpha, pads, conds, wrong)
            total = total + objective.critic_objective(t, config.loss)
            losses[i].update({name: value.detach() for name, value in t.items()})
        total.backward()
        a.opt_d.step()
    return losses


def generator_step(G, critics, a: BlockState, b: Batches, signal, config, kinematics) -> Losses:
    """One Adam step of the block's generator levels on the sum over those levels of
    Eq. 11 (``objective.generator_terms``): ``L_rec`` of the reconstructions (every clip
    with its fixed noise z* and its own condition), the other terms of the random
    generations (one per clip; with ``mix_prob``, two conditions from a random crossover
    level on), both from one generator run (:func:`generator_outputs`)."""
    losses: Losses = {i: {} for i in a.levels}
    a.opt_g.zero_grad(set_to_none=True)
    draw = signal.draw_random(b.rand_layout, a.levels[-1] + 1)
    critic_conds = None  # what conditional critics see with the random generations
    if signal.real_conds is not None:
        critic_conds = signal.critic_conditions(draw, b.rand_layout)
    outs = generator_outputs(G, a, b, signal, draw)
    total = 0.0
    for i, (out_rec, out_rand) in zip(a.levels, outs, strict=True):
        lay, on = b.rand_layout, objective.terms_on(config, i)
        cond = None if critic_conds is None else critic_conds[i]
        critic = functools.partial(critics[i], pad_index=lay.pad_index(i, G.pad), cond=cond)
        detail = None  # the band level i adds, and its label's statistics
        if "detail" in on:
            detail = functools.partial(_band_rms, lay, i), signal.detail_targets(draw, i)
        lv = b.levels[i]
        t = objective.generator_terms(out_rec, out_rand, lv, on, critic, kinematics, detail)
        total = total + objective.generator_objective(t, config.loss)
        losses[i].update({name: value.detach() for name, value in t.items()})
    total.backward()
    a.opt_g.step()
    return losses


def _band_rms(layout, level: int, x: torch.Tensor) -> torch.Tensor:
    return layout.per_sample_rms(layout.level_band(x, level), level)  # (B, C)


def generator_outputs(G, a: BlockState, b: Batches, signal, draw: RandomDraw) -> list:
    """``(reconstructions, random generations)`` ``(1, C, S_i)`` of every level of the
    block, from one generator run on ``[reconstructions; random]``: every clip with its
    z* and its own condition, and the random generations of ``draw``. Below the block
    the levels are frozen: the reconstructions come from ``a.frozen``."""
    lo, hi = a.levels[0], a.levels[-1]
    rec_conds, rec_noises = signal.rec_conditions(hi + 1), b.rec_noises(hi + 1)
    x_in = None
    if lo > 0:
        with torch.no_grad():
            x_rand = G.run(b.rand_layout, draw.noises, draw.conds, 0, lo)
        x_in = torch.cat([a.frozen, x_rand], -1)
    noises = [torch.cat([zr, zn], -1) for zr, zn in zip(rec_noises, draw.noises, strict=True)]
    conds = [torch.cat([cr, cn], 1) for cr, cn in zip(rec_conds, draw.conds, strict=True)]
    outs = G.run(b.g_layout, noises, conds, lo, hi + 1, x=x_in, keep=True)
    cuts = [b.g_layout.split(i, b.num_clips) for i in a.levels]
    return [(out[..., :cut], out[..., cut:]) for out, cut in zip(outs, cuts, strict=True)]


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
    then load it (notebooks and benchmarks: a long run is not repeated on every
    execution). A run there that cannot be reused moves to ``out_dir/previous-<time>/``
    with a warning saying why (``mrlib.training.run.reuse_finished_run``).

    Returns:
        ``(model, record)``: the ``GenerativeModel`` and a :class:`TrainRecord`; for a
        reused run the wall time is the last ``time_s`` of its ``losses.csv`` (the time
        of its last logged iteration, without the final checkpoint write).
    """
    out = Path(out_dir)
    reused = reuse_finished_run(data, config, out)
    if reused is not None:  # a run from before models chose their contact reading chooses now
        settle_contact_reading(reused[0], checkpoint=reused[1].checkpoint)
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
    ``mrlib.training.run.model_cache_key``: a model trained once (by one notebook, say)
    is loaded by every later call with the same config and clips. The cache is
    ``cache_dir``, else ``$MRLIB_CACHE_DIR/models``, else the user's cache folder
    (``~/.cache/mrlib/models`` on Linux); delete a folder there to retrain.

    Returns ``(model, record)`` as :func:`train_or_reuse`."""
    out = cache_folder(models_root(cache_dir), data, config)
    out.mkdir(parents=True, exist_ok=True)
    return train_or_reuse(data, config, out, body=body, progress=progress)


def _train_cached_in_worker(args) -> None:  # one train_cached in a worker, on one thread
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
