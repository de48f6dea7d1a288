"""Checkpoint files: a plain dict of tensors and Python scalars/strings/lists.

Written with ``torch.save`` to a temporary file in the same folder and moved into place
(``mrlib.io.outputs.atomic_write``: a crash never leaves a half-written checkpoint, and a
symbolic link in its place is refused, not followed), read with
``torch.load(..., weights_only=True)`` (no pickled classes; safe to load from others).
The training config is stored as a JSON string under ``"config"`` and also written as
``<checkpoint>.json`` next to the file.

Keys (``FORMAT_VERSION`` 1)::

    format, version          "mrlib-checkpoint", 1
    config                   TrainConfig as JSON
    labels                   condition names, list[str]; clip_labels list[int] per clip
    clip_names, fps, betas   training clips' names, frame rate, body shape (10,)
    clip_fps                 each clip's own rate before resampling to fps (optional;
                             ``clip_rates``)
    cond_dim                 size D of a condition vector
    normalizer               {"mean": (C,), "std": (C,)}
    features                 training clips, list of (T_k, C) unnormalised
    lengths                  (N, L) int: pyramid lengths of every clip
    sigma_clip, sigma        (N, L) noise amplitudes per clip; (K, L) per label (mean)
    zstar                    list of (1, T_1,k) fixed reconstruction noise per clip
    generator, critics       state dicts
    progress                 {"block": int, "iteration": int, "done": bool}
    optim_g, optim_d         optimizer state dicts of the running block (or None)
    rng                      {"torch", "numpy", "python", "trainer"} RNG states
    threads                  torch thread count the run trains with (kept on resume;
                             absent in checkpoints written before it was recorded)
    contact_at_rate          labels whose samples read contacts at the label's rate,
                             list[str], chosen when training ends
                             (``mrlib.sampling.contact_choice``; absent before)
    checksum                 SHA-256 of everything above (``state_checksum``), checked
                             on load: a flipped byte is reported, not loaded

Checkpoints written before 2026-12-01 have no ``checksum`` (same version 1), so one
without it still loads, with a :class:`CheckpointWarning` (it may be one of those, or a
file whose checksum was taken out). Labels listed twice are refused.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import pickle
import random
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import torch

from mrlib.errors import MotionFileError, MrlibError
from mrlib.io.outputs import OutputWriteError, atomic_write, write_text
from mrlib.io.transaction import make_folders, output_transaction
from mrlib.representation.motion import MAX_FPS

__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "save_checkpoint",
    "load_checkpoint",
    "check_checkpoint_file",
    "state_checksum",
    "clip_rates",
    "contact_choice",
    "reading",
    "CheckpointError",
    "CheckpointWarning",
    "global_rng_state",
    "set_global_rng_state",
]

FORMAT = "mrlib-checkpoint"
FORMAT_VERSION = 1


class CheckpointError(MotionFileError):
    """A checkpoint file is missing, unreadable, or not an mrlib checkpoint."""


class CheckpointWarning(UserWarning):
    """A checkpoint loads but cannot be checked (it has no checksum)."""


def _digest(h: Any, value: Any) -> None:
    if isinstance(value, torch.Tensor):
        t = value.detach().cpu().contiguous()
        h.update(f"T{t.dtype}{tuple(t.shape)}".encode())
        h.update(t.reshape(-1).view(torch.uint8).numpy().tobytes())
    elif isinstance(value, dict):
        h.update(f"D{len(value)}".encode())
        for k in sorted(value, key=repr):
            h.update(repr(k).encode())
            _digest(h, value[k])
    elif isinstance(value, (list, tuple)):
        h.update(f"L{len(value)}".encode())
        for v in value:
            _digest(h, v)
    else:
        h.update(f"V{value!r}".encode())


def state_checksum(state: dict[str, Any]) -> str:
    """SHA-256 (hex) of a checkpoint's content: keys, tensor dtypes, shapes and bytes,
    and every other value; the ``checksum`` entry itself is left out."""
    h = hashlib.sha256()
    _digest(h, {k: v for k, v in state.items() if k != "checksum"})
    return h.hexdigest()


def save_checkpoint(path: str | Path, state: dict[str, Any], *, overwrite: bool = True) -> Path:
    """Write ``state`` atomically to ``path`` (and its config to ``path.json``), with a
    checksum of its content, through ``mrlib.io.outputs``: both files in one
    ``output_transaction`` (both written, or neither); a failed write (full disk, file
    size limit, interruption) leaves the previous files as they were and removes the
    temporary files, and the error says whether there was a previous checkpoint; a
    symbolic link at ``path`` is refused, never followed; ``overwrite=False`` refuses an
    existing file."""
    path = Path(path)
    make_folders(path.parent)
    state = {"format": FORMAT, "version": FORMAT_VERSION, **state}
    state["checksum"] = state_checksum(state)
    meta = path.with_name(path.name + ".json")
    had = os.path.lexists(path)
    try:
        with output_transaction():
            atomic_write(path, lambda fh: torch.save(state, fh), overwrite=overwrite)
            if "config" in state:
                write_text(meta, state["config"], overwrite=overwrite)
        return path
    except OutputWriteError as exc:
        failed, why, cause = exc.path, exc.strerror or exc.problem, exc
    except MrlibError:
        raise
    except (OSError, RuntimeError) as exc:  # RuntimeError: torch's zip writer, a short write
        failed, cause = path, exc
        why = "the write failed part-way (disk full, or a file size limit?)"
        if isinstance(exc, OSError):
            why = exc.strerror or str(exc)
    what = "config" if failed == meta else "checkpoint"
    kept = "the previous one is kept" if had else "nothing was written"
    raise CheckpointError(failed, f"could not write the {what}: {why}; {kept}") from cause


@contextlib.contextmanager
def reading(path: str | Path) -> Iterator[None]:
    """Report whatever goes wrong while building a model or trainer from a checkpoint's
    content (a missing key, a bad config, tensors of the wrong shape) as a
    :class:`CheckpointError` naming ``path``."""
    try:
        yield
    except CheckpointError as e:
        if e.path is None:
            raise CheckpointError(Path(path), e.problem) from e
        raise
    except MrlibError as e:  # a config that does not validate, and the like
        raise CheckpointError(Path(path), f"invalid checkpoint: {e}") from e
    except KeyError as e:
        raise CheckpointError(Path(path), f"incomplete checkpoint: missing {e}") from e
    except (TypeError, ValueError, RuntimeError, AttributeError, IndexError) as e:
        first = str(e).splitlines()[0] if str(e) else type(e).__name__
        raise CheckpointError(Path(path), f"inconsistent checkpoint: {first}") from e


def check_checkpoint_file(path: str | Path) -> Path:
    """``path`` if it is a file, else a :class:`CheckpointError` (a folder, or nothing)."""
    path = Path(path)
    if path.is_dir():
        hint = " (a run folder: its checkpoint.pt)" if (path / "checkpoint.pt").is_file() else ""
        raise CheckpointError(path, f"is a folder, not a checkpoint file{hint}")
    if not path.is_file():
        raise CheckpointError(path, "no such checkpoint file")
    return path


def load_checkpoint(path: str | Path, map_location: str | torch.device = "cpu") -> dict[str, Any]:
    """Read a checkpoint with ``weights_only=True`` and check its format."""
    path = check_checkpoint_file(path)
    with open(path, "rb") as fh:
        head = fh.read(2)
    if not head.startswith((b"PK", b"\x80")):  # torch.save's zip, or an old pickle
        raise CheckpointError(
            path, "not a PyTorch checkpoint (neither a zip archive nor a pickle): not mrlib's"
        )
    try:
        with warnings.catch_warnings():  # torch's advice on files mrlib never writes
            warnings.filterwarnings("ignore", message="Detected pickle protocol")
            state = torch.load(path, map_location=map_location, weights_only=True)
    except pickle.UnpicklingError as exc:  # what weights_only refuses: classes, code
        raise CheckpointError(
            path,
            "refused: the file holds Python objects other than tensors and plain values "
            "(mrlib checkpoints never do); it is not loaded, since unpickling it could run code",
        ) from exc
    except Exception as exc:  # torch raises several types for corrupt files
        raise CheckpointError(path, _unreadable(path)) from exc
    if not isinstance(state, dict) or state.get("format") != FORMAT:
        raise CheckpointError(path, "not an mrlib checkpoint (missing 'format' key)")
    if "checksum" not in state:
        warnings.warn(
            f"{path}: the checkpoint has no checksum, so damage or an edit cannot be "
            "detected (mrlib writes one since 2026-12-01: an older file, or one changed "
            "by hand); resuming training writes a checked one",
            CheckpointWarning,
            stacklevel=2,
        )
    elif state["checksum"] != state_checksum(state):
        raise CheckpointError(
            path, "checksum mismatch: the file is corrupt (changed after it was written)"
        )
    if state.get("version") != FORMAT_VERSION:
        raise CheckpointError(
            path,
            f"checkpoint version {state.get('version')} is not supported "
            f"(this mrlib reads version {FORMAT_VERSION})",
        )
    _check_labels(path, state)
    return state


def contact_choice(state: dict[str, Any]) -> tuple[str, ...] | None:
    """The labels the checkpoint reads at their contact rate (``contact_at_rate``, checked
    on load against its labels), None where it records no choice."""
    chosen = state.get("contact_at_rate")
    return None if chosen is None else tuple(map(str, chosen))


def clip_rates(state: dict[str, Any]) -> list[float] | None:
    """The training clips' own frame rates (``clip_fps``, written since 2026-12-06): one
    finite rate in (0, ``MAX_FPS``] per clip, else None (older checkpoints, or values that
    are not rates: the key is a record, never a reason to refuse a model)."""
    rates = state.get("clip_fps")
    n = len(state.get("clip_names", ()))
    if not isinstance(rates, (list, tuple)) or len(rates) != n or n == 0:
        return None
    try:
        out = [float(r) for r in rates]
    except (TypeError, ValueError):
        return None
    return out if all(np.isfinite(r) and 0 < r <= MAX_FPS for r in out) else None


def _unreadable(path: Path) -> str:
    """Why torch could not read ``path``, in mrlib's words (torch's own messages name
    its zip reader's internals, or are a bare key such as '101')."""
    import zipfile

    try:
        size = path.stat().st_size
        names = zipfile.ZipFile(path).namelist() if zipfile.is_zipfile(path) else None
    except (OSError, zipfile.BadZipFile, ValueError):
        size, names = None, None
    if size == 0:
        return (
            "cannot read checkpoint: the file is empty; pass the checkpoint.pt a training run wrote"
        )
    if names and all(n.endswith(".npy") for n in names):
        return (
            "not a checkpoint: it is a NumPy .npz archive (a motion or data file?); pass the "
            "checkpoint.pt a training run wrote"
        )
    return (
        "cannot read checkpoint: the file is truncated or damaged, or is no PyTorch checkpoint "
        "(retrain, or take an earlier copy of the checkpoint.pt a training run wrote)"
    )


def _check_labels(path: Path, state: dict[str, Any]) -> None:
    """The checkpoint's ``labels``, where present, are distinct names (a label names one
    condition: a second 'walk_sad' would make two conditions of one name), and the labels
    it reads at their contact rate (``contact_at_rate``) are among them."""
    if "labels" not in state:
        return  # reported as missing where it is needed
    labels = state["labels"]
    if not isinstance(labels, (list, tuple)) or not all(isinstance(x, str) and x for x in labels):
        raise CheckpointError(path, "invalid checkpoint: 'labels' must be a list of label names")
    twice = sorted({x for x in labels if labels.count(x) > 1})
    if twice:
        raise CheckpointError(
            path,
            f"invalid checkpoint: label {twice[0]!r} is listed twice in 'labels' "
            f"({list(labels)}); each label names one condition",
        )
    chosen = state.get("contact_at_rate")
    if chosen is not None and (
        not isinstance(chosen, (list, tuple))
        or not all(isinstance(x, str) and x in labels for x in chosen)
    ):
        raise CheckpointError(
            path, "invalid checkpoint: 'contact_at_rate' must be a list of the model's labels"
        )


def global_rng_state() -> dict:
    """The states of torch's, numpy's and Python's global generators (and CUDA's), as
    tensors, lists and numbers that a checkpoint can hold."""
    np_state = np.random.get_state()
    state = {
        "torch": torch.get_rng_state(),
        "numpy": [
            np_state[0],
            torch.from_numpy(np_state[1].astype(np.int64)),
            *map(float, np_state[2:]),
        ],
        "python": list(random.getstate()),
    }
    if torch.cuda.is_available():
        state["cuda"] = torch.cuda.get_rng_state_all()
    return state


def set_global_rng_state(state: dict) -> None:
    """Restore what :func:`global_rng_state` returned."""
    torch.set_rng_state(state["torch"])
    n = state["numpy"]
    np.random.set_state((n[0], n[1].numpy().astype(np.uint32), int(n[2]), int(n[3]), float(n[4])))
    py = state["python"]
    random.setstate((py[0], tuple(py[1]), py[2]))
    if "cuda" in state and torch.cuda.is_available():
        torch.cuda.set_rng_state_all(state["cuda"])
