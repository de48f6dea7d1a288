"""Public motion data that mrlib's notebooks, tests and benchmarks use, fetched on first use.

The `Bandai Namco Research Motion Dataset 1
<https://github.com/BandaiNamcoResearchInc/Bandai-Namco-Research-Motiondataset>`_
(CC BY-NC 4.0: attribution, non-commercial use) holds 174 labelled BVH clips: 17 kinds
of motion in up to 15 styles, each with a JSON file of its labels. mrlib does not
redistribute it. Where the clips come from, first match wins:

1. a folder of the dataset already on disk: ``$MRLIB_DATA_DIR`` when it is set and names
   an existing folder, else (when it is unset) ``../shared/data/bandai-namco-motion-1``
   beside the repository (an offline mirror);
2. mrlib's cache (``$MRLIB_CACHE_DIR``, default the user's cache folder,
   ``~/.cache/mrlib`` on Linux), filled on demand with `pooch
   <https://www.fatiando.org/pooch>`_ from the dataset's repository at a pinned commit
   (``BANDAI_REF``); every file is checked against the SHA-256 in
   ``mrlib/assets/bandai_registry.txt`` before it is kept. ``$MRLIB_DATA_URL`` replaces
   the download prefix up to and including the commit (a mirror, or a local server).

Every download is bounded (a size cap from the registry, ``TIMEOUT_S`` of silence,
``file_deadline`` in all; ``mrlib.datasets.fetching``, shared with ``beat2``).

``mrlib data fetch bandai`` fetches the clips the notebooks use ahead of time
(``--all``: the whole dataset, 40 MB). :func:`tutorial_clips` is what the notebooks
call: the Bandai clips when they can be had, else the synthetic clips of
``data_samples/`` with a one-line note saying so.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from mrlib.datasets import fetching
from mrlib.datasets.fetching import (
    TIMEOUT_S,
    DataFetchError,
    FetchHints,
    FetchLimits,
    file_deadline,
    registry_rows,
)
from mrlib.io.paths import DATA_DIR_ENV, SHARED_DATA_DIR, cache_root

__all__ = [
    "BANDAI_REF",
    "BANDAI_URL",
    "NOTEBOOK_CLIPS",
    "DataFetchError",
    "bandai_registry",
    "bandai_sizes",
    "download_cap",
    "CappedDownloader",
    "bandai_local_dir",
    "bandai_cache_dir",
    "bandai_dir",
    "fetch_bandai",
    "bandai_clip",
    "ClipSource",
    "tutorial_clips",
]

BANDAI_REPO = "BandaiNamcoResearchInc/Bandai-Namco-Research-Motiondataset"
BANDAI_REF = "74ead3ba1ae4696404e6086233779f60de8bf9ef"  # 2023-07-04, "Add Citation Information"
BANDAI_URL = f"https://raw.githubusercontent.com/{BANDAI_REPO}/{BANDAI_REF}"
BANDAI_SUBDIR = "dataset/Bandai-Namco-Research-Motiondataset-1"
DATA_URL_ENV = "MRLIB_DATA_URL"
ATTRIBUTION = (
    "Bandai Namco Research Motion Dataset 1 (c) Bandai Namco Research Inc., CC BY-NC 4.0 "
    "(https://creativecommons.org/licenses/by-nc/4.0/): attribution required, "
    "non-commercial use only; licence text in {license}"
)
DATA_SAMPLES = Path(__file__).resolve().parents[2] / "data_samples"
_REGISTRY = Path(__file__).resolve().parents[1] / "assets" / "bandai_registry.txt"
# the cap of a file the registry gives no size for (a registry of an older mrlib)
CAP_BY_SUFFIX = {".bvh": 16 * 2**20, ".json": 64 * 2**10, ".txt": 64 * 2**10}
CAP_OTHER = 1 * 2**20
HINTS = FetchHints(DATA_URL_ENV, DATA_DIR_ENV, "mrlib data fetch bandai")

# The clips the notebooks load: the four walks they train on, second takes and other
# contents for the calibration rows, and the resting poses of the speech notebook.
NOTEBOOK_CLIPS = tuple(
    [f"walk_{s}_{t}" for s in ("normal", "happy", "sad", "angry") for t in ("001", "002")]
    + ["walk_active_001"]
    + [f"bow_{s}_001" for s in ("normal", "happy", "sad", "angry")]
    + ["bye_sad_001", "byebye_sad_001", "guide_sad_001"]
)


def bandai_registry() -> dict[str, str]:
    """``{relative path: "sha256:<hex>"}`` of every file mrlib can fetch (paths relative
    to the dataset folder: ``data/<clip>.bvh``, ``data/<clip>.json``, ``cfg/*.txt``,
    ``LICENSE``)."""
    return fetching.registry_hashes(registry_rows(_REGISTRY))


def bandai_sizes(registry: dict[str, str] | None = None) -> dict[str, int]:
    """``{relative path: size in bytes}`` of the files :func:`bandai_registry` lists (the
    registry's third column); with ``registry``, of the files whose hash there is the one
    the size belongs to (another file's size is no cap for it)."""
    return fetching.registry_sizes(registry_rows(_REGISTRY), registry)


def download_cap(name: str, sizes: dict[str, int] | None = None) -> int:
    """The most bytes a download of ``name`` may bring: its size in the registry, else a
    generous cap for its kind of file (``CAP_BY_SUFFIX``)."""
    sizes = bandai_sizes() if sizes is None else sizes
    if name in sizes:
        return sizes[name]
    return CAP_BY_SUFFIX.get(Path(name).suffix, CAP_OTHER)


def bandai_local_dir() -> Path | None:
    """The dataset folder already on disk, or ``None``: ``$MRLIB_DATA_DIR`` when the
    variable is set (a folder that does not exist means none, so
    ``MRLIB_DATA_DIR=/nonexistent`` tries the cache and the download as a fresh clone
    would), else the ``../shared`` mirror beside the repository if it exists."""
    env = os.environ.get(DATA_DIR_ENV)
    cand = Path(env).expanduser() if env else SHARED_DATA_DIR  # a set variable alone decides
    return cand if (cand / "data").is_dir() else None


def bandai_cache_dir() -> Path:
    """Where fetched files are kept: ``<cache_root()>/bandai-namco-motion-1``."""
    return cache_root() / "bandai-namco-motion-1"


def bandai_dir() -> Path:
    """The folder to read Bandai clips from: the local copy when there is one, else the
    cache (which holds what has been fetched so far; see :func:`fetch_bandai`)."""
    return bandai_local_dir() or bandai_cache_dir()


def _clip_files(names: Iterable[str], registry: dict[str, str]) -> list[str]:
    files = []
    for name in names:
        stem = re.sub(r"\.(bvh|json)$", "", str(name))
        stem = stem if stem.startswith("dataset-1_") else f"dataset-1_{stem}"
        found = [f"data/{stem}.bvh", f"data/{stem}.json"]
        if found[0] not in registry:
            raise DataFetchError(
                f"{name}: not a clip of the Bandai Namco dataset 1 (names look like "
                "'walk_happy_001'; `mrlib data list bandai` lists them)"
            )
        files += found
    return files


def _base_url() -> str:
    prefix = os.environ.get(DATA_URL_ENV) or BANDAI_URL
    return f"{prefix.rstrip('/')}/{BANDAI_SUBDIR}/"


class CappedDownloader(fetching.CappedDownloader):
    """``mrlib.datasets.fetching.CappedDownloader`` whose messages name the Bandai
    dataset's ways around (``$MRLIB_DATA_URL``, ``$MRLIB_DATA_DIR``)."""

    def __init__(self, name: str, cap: int, deadline: float, *, timeout: float | None = None):
        timeout = TIMEOUT_S if timeout is None else timeout
        super().__init__(name, cap, deadline, hints=HINTS, timeout=timeout)


def fetch_bandai(
    clips: Iterable[str] | None = NOTEBOOK_CLIPS, *, everything: bool = False, progress=True
) -> Path:
    """Make sure the named clips (and the licence and label names) are in the cache,
    downloading what is missing; returns the cache folder.

    Args:
        clips: clip names as ``"walk_happy_001"`` or ``"dataset-1_walk_happy_001"``;
            default the clips the notebooks use.
        everything: fetch the whole dataset (40 MB) instead.
        progress: a progress bar per download.

    Raises:
        DataFetchError: one line naming the file, the URL and what to do.
    """
    registry = bandai_registry()
    sizes = bandai_sizes(registry)
    cache = bandai_cache_dir()
    wanted = ["LICENSE", "cfg/content_label.txt", "cfg/style_label.txt"]
    wanted += list(registry) if everything else _clip_files(clips or (), registry)
    first = not (cache / "LICENSE").exists()
    limits = FetchLimits(lambda f: download_cap(f, sizes), TIMEOUT_S, file_deadline)
    fetched = fetching.fetch_files(
        wanted, registry=registry, cache=cache, base_url=_base_url(), limits=limits,
        hints=HINTS, desc="Bandai Namco clips", progress=progress,
    )  # fmt: skip
    if fetched and first:
        print(ATTRIBUTION.format(license=cache / "LICENSE"), flush=True)
    return cache


def bandai_clip(name: str, *, fetch: bool = True) -> Path:
    """The BVH file of one clip (``"walk_happy_001"``), from the local copy or the cache,
    fetched first when it is in neither and ``fetch`` is true."""
    registry = bandai_registry()
    rel = _clip_files([name], registry)[0]
    local = bandai_local_dir()
    if local is not None and (local / rel).is_file():
        return local / rel
    cache = bandai_cache_dir()
    if fetch:
        fetch_bandai([name])
    return cache / rel


@dataclass(frozen=True)
class ClipSource:
    """Clips for a notebook: ``paths`` to load with ``mrlib.load_motion``; ``synthetic``
    is true when they are ``data_samples/`` stand-ins, ``note`` says where they came
    from; ``data_dir`` is the Bandai folder (``None`` for stand-ins)."""

    paths: list[Path]
    synthetic: bool
    note: str
    data_dir: Path | None = None


def tutorial_clips(clips: Iterable[str], *, fetch: bool = True) -> ClipSource:
    """The Bandai clips ``clips`` (e.g. ``["walk_normal_001", "walk_happy_001"]``) from the
    local copy or the cache (fetched with the other notebook clips when missing), or,
    when they cannot be had, the synthetic clips of ``data_samples/`` in their place: one
    per requested clip, the same label where a sample has it (``walk_happy_001`` ->
    ``walk_happy.npz``), the remaining samples after that. Prints one line saying which."""
    clips = list(clips)
    registry = bandai_registry()
    rels = _clip_files(clips, registry)[::2]
    local = bandai_local_dir()
    if local is not None and all((local / r).is_file() for r in rels):
        return ClipSource(
            [local / r for r in rels], False, f"Bandai Namco clips from {local}", local
        )
    why = None
    if fetch:
        try:
            cache = fetch_bandai(list(dict.fromkeys(list(NOTEBOOK_CLIPS) + clips)))
            return ClipSource(
                [cache / r for r in rels], False, f"Bandai Namco clips from {cache}", cache
            )
        except DataFetchError as exc:
            why = str(exc)
    samples = sorted(DATA_SAMPLES.glob("*.npz"))
    by_label = {p.stem: p for p in samples}
    chosen: list[Path] = []
    for c in clips:
        m = re.fullmatch(r"(?:dataset-1_)?([a-z-]+)_([a-z-]+)_\d+", c)
        p = by_label.get(f"{m.group(1)}_{m.group(2)}") if m else None
        if p is not None and p not in chosen:
            chosen.append(p)
    chosen += [p for p in samples if p not in chosen][: max(0, len(clips) - len(chosen))]
    note = (
        "no Bandai Namco data (" + (why or "fetching is off") + "): using the synthetic "
        f"clips of data_samples/ instead ({', '.join(p.stem for p in chosen)}); figures are "
        "from synthetic motion"
    )
    print(note, flush=True)
    return ClipSource(chosen, True, note, None)
