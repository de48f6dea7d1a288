"""What the benchmarks share: the machine, the data, torch threads, result files and the
Bandai ``tutorial`` model that several of them measure.

The scripts run from the repository root as ``python bench/<name>.py``, which puts
``bench/`` on ``sys.path``, so they ``import common`` (``bench/experiments/`` scripts add
``bench/`` to the path first). Importing this module loads the standard library only:
``--help`` stays quick and the speed benchmarks' child processes are not made heavier;
torch and mrlib are imported inside the functions that need them.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "bench" / "results"
TUTORIAL_CLIPS = ("walk_normal_001", "walk_happy_001", "walk_sad_001", "walk_angry_001")
TUTORIAL_RUNS = ROOT / "outputs" / "condition_control"
# tutorial_run() of bench/condition_control.py's defaults: what the checkpoint readers load
TUTORIAL_CHECKPOINT = TUTORIAL_RUNS / "tutorial_seed0_detail100_mismatch0" / "checkpoint.pt"


# -- the machine ------------------------------------------------------------------------------
def machine() -> dict:
    """The machine a figure was measured on: CPU model, logical CPUs, the CPUs this process
    may use (its affinity mask), Python, platform and architecture, numpy's version and
    torch's with its intra-op thread count at the time of the call."""
    cpu = platform.processor()
    try:
        lines = Path("/proc/cpuinfo").read_text().splitlines()
        cpu = next(
            (ln.split(":", 1)[1].strip() for ln in lines if ln.startswith("model name")), cpu
        )
    except OSError:
        pass
    try:
        usable = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        usable = os.cpu_count()
    out = {"cpu": cpu or "unknown", "logical_cpus": os.cpu_count(), "usable_cpus": usable,
           "python": platform.python_version(), "platform": platform.platform(),
           "arch": platform.machine()}  # fmt: skip
    import numpy
    import torch

    out.update(numpy=numpy.__version__, torch=torch.__version__)
    out["torch_threads"] = torch.get_num_threads()
    return out


def describe(m: dict | None = None) -> str:
    """:func:`machine` (or ``m``) on one line, to print above a table of timings."""
    m = m or machine()
    return (f"{m['cpu']}, {m['logical_cpus']} logical CPUs ({m['usable_cpus']} usable); "
            f"torch {m['torch']} on {m['torch_threads']} thread(s); Python {m['python']}; "
            f"{m['platform']}")  # fmt: skip


def set_threads(n: int | None = None) -> int:
    """Torch's intra-op thread count through mrlib's policy (``mrlib.threads.use``):
    ``n`` explicitly, so mrlib's own calls keep it; ``None``: mrlib's default. Returns it."""
    from mrlib.threads import use

    return use(n)


# -- results ----------------------------------------------------------------------------------
def write_json(name: str, payload: dict, path: Path | None = None, append: bool = False) -> Path:
    """Write ``payload`` with the time (``utc``) and :func:`machine` first, replacing any
    keys of those names, to ``path``, by default ``bench/results/<name>.json``; with
    ``append``, as one line at the end of ``bench/results/<name>.jsonl`` (a row per run).
    Values JSON does not know (numpy scalars) are written as floats. Returns the path."""
    record = {"utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), "machine": machine()}
    record.update((k, v) for k, v in payload.items() if k not in record)
    path = Path(path) if path is not None else RESULTS / (name + (".jsonl" if append else ".json"))
    path.parent.mkdir(parents=True, exist_ok=True)
    if append:
        with path.open("a") as f:
            f.write(json.dumps(record, default=float) + "\n")
    else:
        path.write_text(json.dumps(record, indent=1, default=float) + "\n")
    return path


# -- data -------------------------------------------------------------------------------------
def no_data(message: str):
    """Stop for want of data: the message on stderr, exit code 2."""
    print(f"error: {message}", file=sys.stderr)
    raise SystemExit(2)


def bandai_dir(required: bool = True) -> Path:
    """The Bandai Namco Research Motion Dataset 1 folder, as mrlib finds it
    (``mrlib.datasets.bandai.bandai_dir``: ``$MRLIB_DATA_DIR``, else the ``../shared`` mirror,
    else mrlib's cache of fetched clips). With ``required``, exits (code 2) when it holds
    no clip."""
    from mrlib.datasets.bandai import bandai_dir as find

    folder = find()
    if required and not any((folder / "data").glob("*.bvh")):
        no_data(f"no Bandai Namco clips in {folder / 'data'}: set MRLIB_DATA_DIR to the "
                "dataset's folder or fetch the clips with `mrlib data fetch bandai`")  # fmt: skip
    return folder


def bandai_clips(names) -> list[Path]:
    """The BVH files of the Bandai clips ``names`` (``walk_happy_001``, with or without the
    ``dataset-1_`` prefix); exits (code 2) naming the first one missing."""
    folder = bandai_dir() / "data"
    paths = [folder / f"dataset-1_{n.removeprefix('dataset-1_')}.bvh" for n in names]
    for p in paths:
        if not p.is_file():
            no_data(f"{p} not found: set MRLIB_DATA_DIR or `mrlib data fetch bandai --all`")
    return paths


# -- the tutorial model -------------------------------------------------------------------------
def tutorial_run(cfg, preset: str = "tutorial", suffix: str = "") -> Path:
    """The run folder of a model of ``bench/condition_control.py`` with config ``cfg``, which
    the other benchmarks reuse: ``<preset>_seed<S>_detail<D>_mismatch<M><suffix>``."""
    name = f"{preset}_seed{cfg.seed}_detail{cfg.loss.detail:g}_mismatch{cfg.loss.mismatch:g}"
    return TUTORIAL_RUNS / (name + suffix)


def trained_model(cfg, clips, out: Path, note: str | None = None):
    """``(model, record, body)``: ``cfg`` trained on the Bandai ``clips`` in ``out``, or the
    finished run there loaded if it has the same config and clips
    (``mrlib.training.trainer.train_or_reuse``). ``note`` is printed under the training set before."""
    import mrlib
    from mrlib.training.data import TrainingSet
    from mrlib.training.trainer import train_or_reuse

    paths = bandai_clips(clips)
    body = mrlib.load_body_model()
    data = TrainingSet.from_motions([mrlib.load_motion(p) for p in paths], body=body)
    if note is not None:
        print(f"{data}\n{note}", flush=True)
    model, record = train_or_reuse(data, cfg, out, body=body)
    return model, record, body


def add_contact_reading_args(ap: argparse.ArgumentParser, prefix: str = "") -> None:
    """``--match-contact-rate`` / ``--cut-contacts`` into ``match_contact_rate`` (True /
    False; None, the default: as each model chose), as ``mrlib evaluate`` takes them."""
    reading = ap.add_mutually_exclusive_group()
    reading.add_argument("--match-contact-rate", action="store_const", const=True, default=None,
                         help=f"{prefix}every label's contact labels at its contact rate "
                              "[the model's choice]")  # fmt: skip
    reading.add_argument("--cut-contacts", dest="match_contact_rate", action="store_const",
                         const=False, help=f"{prefix}every label's contact labels cut at 0.5 "
                                           "(the paper's) [the model's choice]")  # fmt: skip


def add_iterations_arg(ap: argparse.ArgumentParser, help: str) -> None:
    """``--iterations N[,N...]``: one count for every block, or one per block."""
    ap.add_argument("--iterations", type=lambda v: tuple(int(n) for n in v.split(",")),
                    default=None, metavar="N[,N...]", help=help)  # fmt: skip


def with_iterations(cfg, iterations: tuple[int, ...] | None):
    """``cfg`` with ``--iterations`` applied, and the suffix of its run folder's name
    (``_it1600``, ``_it3200-3200-800-800``; empty for the preset's own budget)."""
    if iterations is None:
        return cfg, ""
    its = iterations * cfg.num_blocks if len(iterations) == 1 else iterations
    suffix = "_it" + "-".join(str(n) for n in iterations)
    return cfg.replace(block_iterations=its, checkpoint_every=0), suffix


def add_checkpoint_arg(ap: argparse.ArgumentParser) -> None:
    """``--checkpoint``: the model to measure, by default :data:`TUTORIAL_CHECKPOINT`."""
    ap.add_argument("--checkpoint", type=Path, default=TUTORIAL_CHECKPOINT)


def checkpoint_model(ap: argparse.ArgumentParser, path: Path):
    """``(model, body)`` of ``--checkpoint`` on one torch thread; a usage error if missing."""
    if not path.is_file():
        ap.error(f"{path} not found: run bench/condition_control.py first or pass --checkpoint")
    set_threads(1)
    import mrlib
    from mrlib.model.trained import load_model

    return load_model(path), mrlib.load_body_model()
