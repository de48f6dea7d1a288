"""The block loop of training: blocks of two consecutive levels (paper Sec. 3.4, after
GANimator and Hinz et al. 2021), levels of earlier blocks frozen; per block, iterations
(``Trainer.step``) until its budget, with the loss log ``losses.csv``, checkpoints every
``checkpoint_every`` iterations and at the end of each block, and Ctrl-C handling: the
first Ctrl-C finishes the current iteration, writes a checkpoint and returns.

:meth:`mrlib.training.trainer.Trainer.fit` runs :func:`run_blocks` with the run folder
locked.
"""

from __future__ import annotations

import csv
import signal
import threading
import time
from collections.abc import Callable
from io import StringIO
from pathlib import Path

import torch

from mrlib.errors import MrlibError
from mrlib.io.outputs import open_for_append, write_text
from mrlib.progress import bar as progress_bar
from mrlib.training.run import TrainResult

__all__ = [
    "run_blocks",
    "check_finite",
    "prepare_log",
    "TrainingDivergedError",
    "LOSS_NAMES",
    "CSV_FIELDS",
]


class TrainingDivergedError(MrlibError, FloatingPointError):
    """A loss or a weight became NaN or infinite during training."""


LOSS_NAMES = ("D", "gp", "adv", "rec", "con", "smooth", "mis", "detail")
CSV_FIELDS = ["time_s", "block", "iteration", "level", *LOSS_NAMES]


def run_blocks(trainer, progress: bool, callback: Callable[..., None] | None) -> TrainResult:
    """Train every remaining block of ``trainer`` (a ``mrlib.training.trainer.Trainer``)
    from where it stands; see ``mrlib.training.trainer.train``."""
    tr, c = trainer, trainer.config
    tr.out_dir.mkdir(parents=True, exist_ok=True)
    log_path = tr.out_dir / "losses.csv"
    prepare_log(log_path, tr.resumed_from, tr.block, tr.iteration)
    t0 = time.perf_counter()
    last: dict[int, dict[str, float]] = {}
    stop = {"flag": False}
    old_handler = None
    if threading.current_thread() is threading.main_thread():

        def _on_sigint(signum, frame):
            # first Ctrl-C: finish this iteration, save, return; a second one stops at
            # once without saving (the last checkpoint stays the last consistent state)
            if stop["flag"]:
                raise KeyboardInterrupt
            stop["flag"] = True

        old_handler = signal.signal(signal.SIGINT, _on_sigint)
    interrupted = False
    try:
        with open_for_append(log_path) as fh:  # never through a symbolic link
            writer = csv.DictWriter(fh, CSV_FIELDS)
            while tr.block < c.num_blocks and not interrupted:
                if tr.opt_g is None:
                    tr.start_block()
                levels = tr.block_levels
                n_iter = c.block_iterations[tr.block]
                bar = progress_bar(
                    total=n_iter,
                    initial=tr.iteration,
                    enabled=progress,
                    leave=True,
                    desc=f"block {tr.block + 1}/{c.num_blocks} "
                    f"(levels {levels[0] + 1}-{levels[-1] + 1})",
                )
                try:
                    while tr.iteration < n_iter:
                        stop["in_step"] = True
                        losses = tr.step()
                        check_finite(losses, tr.block, tr.iteration, tr.out_dir)
                        tr.iteration += 1
                        stop["in_step"] = False
                        if tr.iteration % c.log_every == 0 or tr.iteration == n_iter:
                            last = {
                                i + 1: {k: float(v) for k, v in d.items()}
                                for i, d in losses.items()
                            }
                            t = time.perf_counter() - t0
                            for lv, d in last.items():
                                writer.writerow(
                                    {
                                        "time_s": f"{t:.2f}",
                                        "block": tr.block + 1,
                                        "iteration": tr.iteration,
                                        "level": lv,
                                        **{k: f"{d[k]:.6g}" for k in d},
                                    }
                                )
                            fh.flush()
                            top = last[levels[-1] + 1]
                            bar.set_postfix({k: f"{v:.3g}" for k, v in top.items()}, refresh=False)
                        bar.update(1)
                        if callback is not None:
                            callback(tr, last)
                        if (
                            c.checkpoint_every
                            and tr.iteration % c.checkpoint_every == 0
                            and tr.iteration < n_iter
                        ):
                            tr.save()
                        if stop["flag"]:
                            raise KeyboardInterrupt
                except KeyboardInterrupt:
                    if stop.get("in_step"):
                        raise  # forced stop mid-iteration: nothing consistent to save
                    interrupted = True
                finally:
                    bar.close()
                if not interrupted:
                    tr.block += 1
                    tr.iteration = 0
                    tr.opt_g = tr.opt_d = None
                    tr.done = tr.block >= c.num_blocks
                tr.save()
    finally:
        if old_handler is not None:
            signal.signal(signal.SIGINT, old_handler)
    return TrainResult(
        tr.out_dir / "checkpoint.pt", log_path, interrupted, time.perf_counter() - t0, last
    )


def check_finite(
    losses: dict[int, dict[str, torch.Tensor]], block: int, iteration: int, out_dir: Path
) -> None:
    """Stop at the first non-finite loss of iteration ``iteration + 1`` of block
    ``block + 1``, naming the level and the term.

    Raises:
        TrainingDivergedError: what and where, and what to check.
    """
    values = [v.detach().reshape(()) for d in losses.values() for v in d.values()]
    if not values or bool(torch.isfinite(torch.stack(values)).all()):
        return
    bad = next((i + 1, k) for i, d in losses.items() for k, v in d.items() if not torch.isfinite(v))
    raise TrainingDivergedError(
        f"loss '{bad[1]}' of level {bad[0]} is not finite at block {block + 1}, "
        f"iteration {iteration + 1} in {out_dir}; check the clips (frame rate, units, "
        "NaN values) or lower the learning rate"  # Trainer.fit adds what was kept
    )


def prepare_log(path: Path, resumed_from: Path | None, block: int, iteration: int) -> None:
    """Write the CSV's header and, when resuming from the checkpoint ``resumed_from``, the
    rows of the run resumed from (the ``losses.csv`` beside its checkpoint) up to that
    checkpoint (``block``, ``iteration``); rows logged after it are dropped (they will be
    logged again). Written atomically, never through a symbolic link."""
    keep = []
    source = None if resumed_from is None else resumed_from.parent / "losses.csv"
    if source is not None and source.is_file() and not source.is_symlink():
        with open(source, newline="") as fh:
            for r in csv.DictReader(fh):
                try:
                    at = (int(r["block"]) - 1, int(r["iteration"]))
                except (KeyError, TypeError, ValueError):
                    continue
                if at <= (block, iteration):
                    keep.append(r)
    text = StringIO()
    w = csv.DictWriter(text, CSV_FIELDS, extrasaction="ignore")
    w.writeheader()
    w.writerows(keep)
    write_text(path, text.getvalue(), overwrite=True)
