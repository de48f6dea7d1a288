"""A training run's folder: what a run writes there, the check before a run starts, the
lock and the thread count a fit holds (:meth:`RunFolder.fitting`), what a run returns,
and the reuse of a finished run (the model cache of notebooks and benchmarks).

Nothing here builds networks or trains: :func:`mrlib.training.trainer.train` and the
``train_*`` functions beside it start a :class:`~mrlib.training.trainer.Trainer` and use
these pieces.
"""

from __future__ import annotations

import contextlib
import csv
import hashlib
import json
import os
import time
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from mrlib.io.outputs import OutputExistsError, RunLock
from mrlib.io.paths import cache_root
from mrlib.io.transaction import outside_transactions, put_back, with_note
from mrlib.model.config import TrainConfig, config_to_json
from mrlib.model.trained import load_model
from mrlib.threads import run_threads, usable_cpus
from mrlib.training.data import TrainingSet

__all__ = [
    "RUN_FILES",
    "RunExistsError",
    "RunAttempt",
    "RunFolder",
    "thread_count_of_fit",
    "resume_thread_count",
    "stage_run",
    "progress_text",
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
    from mrlib.io.outputs import OutputError, file_in_the_way

    blocker = out if os.path.lexists(out) and not os.path.isdir(out) else file_in_the_way(out)
    if blocker is not None:
        raise OutputError(blocker, "is a file, not a folder: choose another --out (out_dir)")
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


class RunAttempt:
    """What one ``Trainer.fit`` may change in its run folder, and how to undo it.

    Made before the folder is locked (it notes the folders the lock creates),
    :meth:`claim`-ed under the lock once the folder is checked: a fresh run over an old
    one (``--overwrite``) moves the old :data:`RUN_FILES` aside, and an existing loss
    log gets a second name (a hard link) before the run rewrites it. A run that fails
    before it writes its first checkpoint (:meth:`failed` with ``wrote=False``) puts
    everything back: the folder is as it was, byte for byte, and a folder it created
    is removed. Once a checkpoint is written, what was set aside is dropped.
    """

    def __init__(self, out_dir: str | Path):
        self.out = Path(out_dir)
        self.created: list[Path] = []  # the folders the run creates, deepest first
        p = self.out
        while not os.path.lexists(p) and p != p.parent:
            self.created.append(p)
            p = p.parent
        self.claimed = False
        self.present: set[str] = set()
        self.aside: dict[str, Path] = {}  # name -> its previous file under another name
        self.copies: dict[str, bytes] = {}  # name -> previous bytes (no hard links here)

    def claim(self, *, fresh: bool) -> None:
        """Note what the folder holds; ``fresh``: the run replaces it (moved aside)."""
        from mrlib.io.transaction import set_aside

        self.present = {n for n in RUN_FILES if os.path.lexists(self.out / n)}
        for name in sorted(self.present):
            path = self.out / name
            if fresh:  # nothing of the old run remains in the new run's way
                self.aside[name] = set_aside(path, move=True)
            elif name == "losses.csv" and path.is_file() and not path.is_symlink():
                keep = set_aside(path)  # the run rewrites it before its first checkpoint
                if keep is not None and os.path.lexists(path):
                    self.aside[name] = keep
                elif keep is not None:  # no hard links here: moved; keep its bytes instead
                    self.copies[name] = keep.read_bytes()
                    put_back(keep, path)
        self.claimed = True

    def drop(self) -> None:
        """A checkpoint was written: what was set aside is not needed any more."""
        for keep in self.aside.values():
            with contextlib.suppress(OSError):
                os.unlink(keep)
        self.aside.clear()
        self.copies.clear()

    def restore(self) -> None:
        """The run wrote no checkpoint: put the folder back as it was."""
        from mrlib.io.outputs import write_bytes

        for name in RUN_FILES:
            path = self.out / name
            with contextlib.suppress(OSError):
                if name in self.aside:
                    put_back(self.aside[name], path)
                elif name in self.copies:
                    write_bytes(path, self.copies[name], overwrite=True)
                elif name not in self.present and os.path.lexists(path):
                    os.unlink(path)  # written by this run
        self.aside.clear()
        self.copies.clear()

    def remove_created_folders(self) -> None:
        """Remove, when empty, the folders this run created (call after the lock's release)."""
        for folder in self.created:
            with contextlib.suppress(OSError):
                folder.rmdir()

    def failed(
        self,
        e: BaseException,
        *,
        wrote: str | None,
        earlier: str | None = None,
        resumed_from: Path | None = None,
    ) -> BaseException:
        """After a failed run (its lock released): keep or restore, and ``e`` with what
        was kept said at the end of its message. ``wrote``: the checkpoint this run wrote
        last (described), or None; ``earlier``: the run's checkpoint the folder held
        before (described: the one it resumed from, or an earlier fit's); ``resumed_from``:
        the checkpoint it resumed from when that lies in another folder."""
        if not self.claimed:  # refused before it started: nothing of ours to undo
            return e
        if wrote is not None:
            self.drop()
            note = f"training stopped; kept: {wrote}"
        else:
            self.restore()
            self.remove_created_folders()
            note = "training stopped before writing a checkpoint; "
            if earlier is not None:
                note += f"kept: {earlier}, {self.out} as it was"
            elif resumed_from is not None:
                note += f"nothing was written to {self.out} ({resumed_from} is unchanged)"
            else:
                note += f"nothing was kept ({self.out} is as it was before)"
        return with_note(e, note, self.out)


class RunFolder:
    """One trainer's run folder across its fits: the checkpoint it resumed from, whether
    an earlier fit checked the folder (:func:`check_run_folder`), and the checkpoints it
    wrote (what a failed fit says it kept)."""

    def __init__(self, out_dir: str | Path, resumed_from: Path | None = None):
        self.out = Path(out_dir)
        self.resumed_from = resumed_from  # the checkpoint the trainer continues
        self.claimed = False  # checked (check_run_folder) by an earlier fit
        self.saves = 0
        self.last_saved: str | None = None

    def saved(self, path: Path, where: str) -> None:
        """Note a checkpoint written at ``where`` (:func:`progress_text`)."""
        self.saves += 1
        self.last_saved = f"the checkpoint of {where} ({path})"

    @contextlib.contextmanager
    def fitting(self, overwrite: bool, where: str) -> Iterator[None]:
        """Around one fit: outside any output transaction of the caller (the run's files reach the disk as it goes),
        the folder locked (``mrlib.io.outputs.RunLock``: a second run there is refused)
        and checked first. A fit that fails before its first checkpoint leaves the folder
        as it was (:class:`RunAttempt`), and its error says what was kept. ``where``: the
        trainer's position now (:func:`progress_text`)."""
        attempt, saves, claiming = RunAttempt(self.out), self.saves, False
        ckpt, earlier, elsewhere = self.out / "checkpoint.pt", None, None
        if self.last_saved is not None:  # by an earlier fit
            earlier = self.last_saved
        elif self.resumed_from is not None and same_file(self.resumed_from, ckpt):
            earlier = f"the checkpoint it resumed from ({where})"
        elif self.resumed_from is not None:
            elsewhere = self.resumed_from
        try:
            with outside_transactions(), RunLock(self.out):
                claiming = not self.claimed
                if claiming:
                    check_run_folder(self.out, resume=self.resumed_from, overwrite=overwrite)
                # a fresh start moves the old run aside: nothing of it remains in the way
                attempt.claim(fresh=overwrite and claiming and self.resumed_from is None)
                self.claimed = True
                yield
        except BaseException as e:
            wrote = self.last_saved if self.saves > saves else None
            if wrote is None and claiming and attempt.claimed:
                self.claimed = False  # the folder is as it was: check it again next time
            err = attempt.failed(e, wrote=wrote, earlier=earlier, resumed_from=elsewhere)
            if err is e:
                raise
            raise err from e
        attempt.drop()


def thread_count_of_fit(recorded: int | None) -> int:
    """The torch thread count a fit runs on: the process's, unchanged; with a warning
    where it differs from ``recorded``, the count of the run it resumes (its weights may
    then differ from an uninterrupted run's by float rounding)."""
    n = torch.get_num_threads()
    if recorded is not None and n != recorded:
        warnings.warn(
            f"this run was started with {recorded} torch threads and continues with "
            f"{n}: its weights may differ (by float rounding) from an uninterrupted run's; "
            f"--threads {recorded} (mrlib.threads.use({recorded})) continues it exactly",
            RuntimeWarning,
            stacklevel=3,
        )
    return n


def resume_thread_count(recorded: int | None) -> int:
    """The count the command line resumes a run on (``mrlib.threads.run_threads``: the
    user's choice, else ``recorded``, else mrlib's default), with a warning where the
    recorded count is more than the CPUs usable here."""
    n, why = run_threads(recorded)
    if why == "resumed" and n > usable_cpus():
        warnings.warn(
            f"this run was started with {n} torch threads, more than the {usable_cpus()} "
            "CPUs usable here; it keeps that count so that it continues exactly "
            "(--threads N trades that for speed)",
            RuntimeWarning,
            stacklevel=3,
        )
    return n


def stage_run(tx, scratch: Path, out: Path, *, overwrite: bool) -> None:
    """Stage the run files trained in ``scratch`` (a ``tx.scratch_folder``) as ``out``'s
    in the output transaction ``tx``: the run takes its folder when ``tx`` ends, with
    the command's other files, or not at all."""
    from mrlib.io.transaction import make_folders

    make_folders(out)
    for name in RUN_FILES:
        if (Path(scratch) / name).is_file():
            tx.adopt(Path(scratch) / name, out / name, overwrite=overwrite)


def progress_text(trainer) -> str:
    """Where a trainer stands, as its checkpoint would record it: ``block B, iteration I``
    (1-based block; a block's end is its last iteration, not the next block's 0th)."""
    b, it = trainer.block, trainer.iteration
    if it == 0 and b > 0:
        return f"block {b}, iteration {trainer.config.block_iterations[b - 1]}"
    return f"block {b + 1}, iteration {it}"


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
