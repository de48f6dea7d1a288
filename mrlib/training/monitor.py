"""What watches the training loop (``mrlib.training.trainer.run_blocks``): the loss log
``losses.csv`` (:class:`LossLog`), the progress bar of a block (:func:`block_bar`), Ctrl-C
(:class:`CtrlC`: the first one finishes the iteration, then the loop writes a checkpoint
and returns) and the stop at the first non-finite loss (:func:`check_finite`).
"""

from __future__ import annotations

import contextlib
import csv
import signal
import threading
import time
from collections.abc import Iterator
from io import StringIO
from pathlib import Path

import torch

from mrlib.errors import MrlibError
from mrlib.io.outputs import open_for_append, write_text
from mrlib.progress import bar as progress_bar

__all__ = [
    "LossLog",
    "CtrlC",
    "block_bar",
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

Losses = dict[int, dict[str, torch.Tensor]]  # {level: {term: value}}, 0-based levels


class LossLog:
    """``losses.csv`` of a run (a context manager: the file is open inside it): one row
    per logged iteration and level (1-based), seconds since the log was opened, and the
    last logged losses ``{level: {name: value}}`` (1-based levels) in :attr:`last`. A
    resumed run's log starts with the rows of the run it resumes (:func:`prepare_log`)."""

    def __init__(self, out_dir: Path, resumed_from: Path | None, block: int, iteration: int):
        out_dir.mkdir(parents=True, exist_ok=True)
        self.path = out_dir / "losses.csv"
        prepare_log(self.path, resumed_from, block, iteration)
        self.t0 = time.perf_counter()
        self.last: dict[int, dict[str, float]] = {}
        self._files = contextlib.ExitStack()

    def __enter__(self) -> LossLog:
        self.fh = self._files.enter_context(open_for_append(self.path))  # no symbolic link
        self.writer = csv.DictWriter(self.fh, CSV_FIELDS)
        return self

    def __exit__(self, *exc) -> None:
        self._files.close()

    def elapsed(self) -> float:
        return time.perf_counter() - self.t0

    def write(self, block: int, iteration: int, losses: Losses) -> dict[str, float]:
        """Log the losses of ``iteration`` (1-based) of 0-based ``block``; returns those of
        the block's finest level (for the progress bar)."""
        self.last = {i + 1: {k: float(v) for k, v in d.items()} for i, d in losses.items()}
        t = self.elapsed()
        for lv, d in self.last.items():
            self.writer.writerow(
                {
                    "time_s": f"{t:.2f}",
                    "block": block + 1,
                    "iteration": iteration,
                    "level": lv,
                    **{k: f"{d[k]:.6g}" for k in d},
                }
            )
        self.fh.flush()
        return self.last[max(losses) + 1]


class CtrlC:
    """Ctrl-C during training (a context manager; the handler is installed in the main
    thread only, and restored on exit). The first Ctrl-C sets :attr:`pressed`: the loop
    finishes the iteration, writes a checkpoint and returns. A second one raises
    ``KeyboardInterrupt`` at once; inside a step (:meth:`step`) it propagates without a
    checkpoint (the last one stays the last consistent state). A ``KeyboardInterrupt``
    between steps (a callback's) counts as the first (:meth:`catch`)."""

    def __init__(self):
        self.pressed = False
        self.in_step = False
        self._old = None

    def __enter__(self) -> CtrlC:
        if threading.current_thread() is threading.main_thread():
            self._old = signal.signal(signal.SIGINT, self._on_sigint)
        return self

    def __exit__(self, *exc) -> None:
        if self._old is not None:
            signal.signal(signal.SIGINT, self._old)

    def _on_sigint(self, signum, frame) -> None:
        if self.pressed:
            raise KeyboardInterrupt
        self.pressed = True

    @contextlib.contextmanager
    def step(self) -> Iterator[None]:
        """Around one iteration: an interrupt inside it is not caught by :meth:`catch`."""
        self.in_step = True
        yield
        self.in_step = False

    @contextlib.contextmanager
    def catch(self) -> Iterator[None]:
        """Around a block's iterations: a ``KeyboardInterrupt`` between steps stops them."""
        try:
            yield
        except KeyboardInterrupt:
            if self.in_step:
                raise  # forced stop mid-iteration: nothing consistent to save
            self.pressed = True


def block_bar(config, block: int, iteration: int, enabled: bool):
    """The progress bar of 0-based ``block`` (``mrlib.progress.bar``), at ``iteration``."""
    levels = config.blocks[block]
    return progress_bar(
        total=config.block_iterations[block],
        initial=iteration,
        enabled=enabled,
        leave=True,
        desc=f"block {block + 1}/{config.num_blocks} (levels {levels[0] + 1}-{levels[-1] + 1})",
    )


def check_finite(losses: Losses, block: int, iteration: int, out_dir: Path) -> None:
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
