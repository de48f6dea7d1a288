"""Real co-speech capture: five files of the BEAT2 dataset, from a local copy or fetched
on first use.

`BEAT2 <https://huggingface.co/datasets/H-Liu1997/BEAT2>`_ (Liu et al., "EMAGE: Towards
Unified Holistic Co-Speech Gesture Generation via Expressive Masked Audio Gesture
Modeling", CVPR 2024; built on BEAT, ECCV 2022; CC BY-NC 4.0: attribution, non-commercial
use) pairs speech with SMPL-X motion capture. mrlib does not redistribute it. Its registry
(``mrlib/assets/beat2_registry.txt``: SHA-256 and size per file) holds five files of
speaker 2 ("scott"), by their paths under the host's ``beat_english_v2.0.0/``:
``smplxflame_30/2_scott_0_1_1.npz`` (motion, 30 fps, Y up) with
``wave16k/2_scott_0_1_1.wav`` (16 kHz speech), and ``wave16k/2_scott_0_{2_2,3_3,4_4}.wav``
(speech with no motion: unpaired). Where each file comes from, first match wins:

1. a local copy: ``$MRLIB_BEAT2_DIR`` when it is set (a folder that does not exist, or
   holds none of the five files, means none), else ``../shared/data/beat2-sample``
   beside the repository. Either the host's layout (``smplxflame_30/``, ``wave16k/``,
   also under ``beat_english_v2.0.0/``) or the sample's: ``<stem>.npz`` and
   ``<stem>.wav`` side by side, audio-only recordings in ``unpaired/``;
2. mrlib's cache (``$MRLIB_CACHE_DIR``, default ``~/.cache/mrlib`` on Linux; folder
   ``beat2``), filled on demand with pooch from ``BEAT2_URL`` +
   ``/beat_english_v2.0.0/<registry path>``, each download bounded and checked as in
   ``mrlib.datasets.fetching``. ``$MRLIB_BEAT2_URL`` replaces the prefix up to and
   including the revision (a mirror, or a local server).

**Not verified against the real host** (it could not be reached from where this was
written): the URL layout, ``https://huggingface.co/datasets/H-Liu1997/BEAT2/resolve/
<revision>/beat_english_v2.0.0/{smplxflame_30/<stem>.npz,wave16k/<stem>.wav}``, and the
revision: ``BEAT2_REF`` is the branch ``main``, to be pinned to a commit hash once
checked. The registry's hashes and sizes are those of the offline sample; that the host
serves the same bytes has not been checked (a mismatch is refused, nothing kept). Only
these five files (speaker 2) have known hashes, so only they can be fetched: other
speakers or more minutes need BEAT2 downloaded by hand and read with
``mrlib.speech.SpeechTrainingSet.from_folders``.

:func:`beat2_speech_folders` lays the files out as ``SpeechTrainingSet.from_folders``
reads them (links in the cache, no copies); ``mrlib.speech.beat2_training_set`` makes
the training set in one call. ``mrlib data fetch|where|list beat2`` on the command line.
"""

from __future__ import annotations

import hashlib
import os
import re
from collections.abc import Iterable
from pathlib import Path

from mrlib.datasets import fetching
from mrlib.datasets.fetching import DataFetchError, FetchHints, FetchLimits, registry_rows
from mrlib.io.paths import CACHE_ENV, cache_root

__all__ = [
    "BEAT2_REF",
    "BEAT2_URL",
    "BEAT2_DIR_ENV",
    "BEAT2_URL_ENV",
    "beat2_registry",
    "beat2_sizes",
    "beat2_clips",
    "beat2_local_dir",
    "beat2_cache_dir",
    "beat2_dir",
    "fetch_beat2",
    "beat2_files",
    "beat2_speech_folders",
]

BEAT2_REPO = "H-Liu1997/BEAT2"
# UNVERIFIED: a branch, not a commit. Pin it to the commit hash whose files match
# mrlib/assets/beat2_registry.txt once that has been checked against the host.
BEAT2_REF = "main"
BEAT2_URL = f"https://huggingface.co/datasets/{BEAT2_REPO}/resolve/{BEAT2_REF}"
BEAT2_SUBDIR = "beat_english_v2.0.0"
MOTION_DIR, AUDIO_DIR = "smplxflame_30", "wave16k"
BEAT2_DIR_ENV = "MRLIB_BEAT2_DIR"
BEAT2_URL_ENV = "MRLIB_BEAT2_URL"
SHARED_BEAT2_DIR = Path(__file__).resolve().parents[3] / "shared" / "data" / "beat2-sample"
ATTRIBUTION = (
    "BEAT2 (Liu et al., EMAGE, CVPR 2024; BEAT, ECCV 2022), CC BY-NC 4.0 "
    "(https://creativecommons.org/licenses/by-nc/4.0/): attribution required, "
    "non-commercial use only; files in {cache}"
)
_REGISTRY = Path(__file__).resolve().parents[1] / "assets" / "beat2_registry.txt"
CAP_OTHER = 64 * 2**20  # the cap of a file the registry gives no size for
HINTS = FetchHints(BEAT2_URL_ENV, BEAT2_DIR_ENV, "mrlib data fetch beat2")
# what mrlib.speech's folder readers read (mrlib.speech.data's AUDIO_/MOTION_EXTENSIONS)
_READ_SUFFIXES = (".wav", ".flac", ".npz", ".bvh")


def beat2_registry() -> dict[str, str]:
    """``{relative path: "sha256:<hex>"}`` of every file mrlib can fetch (paths relative
    to ``beat_english_v2.0.0/``: ``smplxflame_30/<stem>.npz``, ``wave16k/<stem>.wav``)."""
    return fetching.registry_hashes(registry_rows(_REGISTRY))


def beat2_sizes(registry: dict[str, str] | None = None) -> dict[str, int]:
    """``{relative path: size in bytes}`` of the registry's files (see ``bandai_sizes``)."""
    return fetching.registry_sizes(registry_rows(_REGISTRY), registry)


def beat2_clips(registry: dict[str, str] | None = None) -> dict[str, tuple[str, ...]]:
    """``{stem: its registry paths}``, motion first: ``("smplxflame_30/<stem>.npz",
    "wave16k/<stem>.wav")`` for a paired clip, the wav alone for an unpaired one."""
    out: dict[str, list[str]] = {}
    for rel in beat2_registry() if registry is None else registry:
        out.setdefault(Path(rel).stem, []).append(rel)
    return {s: tuple(sorted(f, key=lambda r: not r.startswith(MOTION_DIR))) for s, f in out.items()}


def _stem(name: object, clips: dict[str, tuple[str, ...]]) -> str:
    stem = re.sub(r"\.(npz|wav)$", "", Path(str(name)).name)
    if stem not in clips:
        raise DataFetchError(
            f"{name}: not a BEAT2 clip mrlib can fetch (its registry has speaker 2's "
            f"{', '.join(clips)} only; `mrlib data list beat2` lists them)"
        )
    return stem


def _files_of(stems: Iterable[object] | None, registry: dict[str, str]) -> list[str]:
    if stems is None:
        return list(registry)
    clips = beat2_clips(registry)
    return list(dict.fromkeys(f for s in stems for f in clips[_stem(s, clips)]))


def _local_file(root: Path, rel: str) -> Path | None:
    """``rel`` (a registry path) in a local copy laid out as the host (also under
    ``beat_english_v2.0.0/``) or as the sample (flat; audio-only clips in ``unpaired/``)."""
    folder, name = rel.split("/", 1)
    cands = [root / rel, root / BEAT2_SUBDIR / rel, root / name]
    if folder == AUDIO_DIR:
        cands.append(root / "unpaired" / name)
    return next((p for p in cands if p.is_file()), None)


def beat2_local_dir() -> Path | None:
    """The local copy, or ``None``: ``$MRLIB_BEAT2_DIR`` when the variable is set (a
    folder that does not exist, or holds none of the registry's files, means none), else
    ``../shared/data/beat2-sample`` beside the repository if it exists."""
    env = os.environ.get(BEAT2_DIR_ENV)
    cand = Path(env).expanduser() if env else SHARED_BEAT2_DIR  # a set variable alone decides
    if not cand.is_dir():
        return None
    return cand if any(_local_file(cand, rel) for rel in beat2_registry()) else None


def beat2_cache_dir() -> Path:
    """Where fetched files are kept: ``<cache_root()>/beat2``, in the host's layout."""
    return cache_root() / "beat2"


def beat2_dir() -> Path:
    """The folder BEAT2 files are read from: the local copy when there is one, else the
    cache (which holds what has been fetched so far; see :func:`fetch_beat2`)."""
    return beat2_local_dir() or beat2_cache_dir()


def _base_url() -> str:
    prefix = os.environ.get(BEAT2_URL_ENV) or BEAT2_URL
    return f"{prefix.rstrip('/')}/{BEAT2_SUBDIR}/"


def _fetch(files: list[str], registry: dict[str, str], progress) -> Path:
    sizes = beat2_sizes(registry)
    cache = beat2_cache_dir()
    first = not any((cache / f).is_file() for f in registry)
    limits = FetchLimits(lambda f: sizes.get(f, CAP_OTHER))
    fetched = fetching.fetch_files(
        files, registry=registry, cache=cache, base_url=_base_url(), limits=limits,
        hints=HINTS, desc="BEAT2 files", progress=progress,
    )  # fmt: skip
    if fetched and first:
        print(ATTRIBUTION.format(cache=cache), flush=True)
    return cache


def fetch_beat2(stems: Iterable[str] | None = None, *, progress=True) -> Path:
    """Make sure the files of ``stems`` (``"2_scott_0_1_1"``; default: all five files
    of the registry, 13 MB) are in the cache, downloading what is missing; returns the
    cache folder (host layout: ``smplxflame_30/``, ``wave16k/``). The local copy is not
    consulted: this fills the cache.

    Raises:
        DataFetchError: one line naming the file, the URL and what to do; a stem that is
            not in the registry.
    """
    registry = beat2_registry()
    return _fetch(_files_of(stems, registry), registry, progress)


def beat2_files(
    stems: Iterable[str] | None = None, *, fetch: bool = True, progress=True
) -> dict[str, Path]:
    """``{registry path: file}`` for the files of ``stems`` (default all): each from the
    local copy when it has it, else from the cache, fetched first when ``fetch``.

    Raises:
        DataFetchError: a file in neither place (``fetch=False``), or a failed download.
    """
    registry = beat2_registry()
    wanted = _files_of(stems, registry)
    local = beat2_local_dir()
    found = {rel: _local_file(local, rel) if local is not None else None for rel in wanted}
    missing = [rel for rel, p in found.items() if p is None]
    cache = beat2_cache_dir()
    if missing and fetch:
        _fetch(missing, registry, progress)
    for rel in missing:
        if not fetching.cached_ok(cache / rel, registry[rel]):
            raise DataFetchError(
                f"{rel}: not in the local copy (${BEAT2_DIR_ENV}: {local or 'none'}) nor in "
                f"the cache {cache}; run `mrlib data fetch beat2`"
            )
        found[rel] = cache / rel
    return {rel: p for rel, p in found.items() if p is not None}


def _as_is(folder: Path, files: dict[str, Path]) -> bool:
    """Whether ``folder`` already holds exactly ``files`` ({name: file}) among the files
    the speech folder readers read."""
    if any(p.parent != folder or p.name != name for name, p in files.items()):
        return False
    have = {p.name for p in folder.iterdir() if p.suffix.lower() in _READ_SUFFIXES}
    return have == set(files)


def _link_folder(folder: Path, files: dict[str, Path]) -> Path:
    """``folder`` holding a link named ``name`` to each file (a symbolic link, else a
    hard link) and nothing else: what is there already is kept when it is right."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        for p in folder.iterdir():
            if p.name not in files and (p.is_symlink() or p.is_file()):
                p.unlink()
        for name, target in files.items():
            p = folder / name
            if p.exists() and os.path.samefile(p, target):
                continue
            if p.is_symlink() or p.exists():
                p.unlink()
            try:
                p.symlink_to(target.resolve())
            except OSError:
                os.link(target, p)
    except OSError as exc:
        raise DataFetchError(
            f"{folder}: cannot make the folder of links to the BEAT2 files "
            f"({exc.strerror or exc}); set ${CACHE_ENV} to a writable folder"
        ) from None
    return folder


def beat2_speech_folders(
    stems: Iterable[str] | None = None, *, fetch: bool = True, progress=True
) -> tuple[Path | None, Path | None]:
    """``(paired_dir, unpaired_dir)`` for ``mrlib.speech.SpeechTrainingSet.from_folders``:
    ``<stem>.npz`` + ``<stem>.wav`` of every clip of ``stems`` (default all) that has
    motion, and the ``.wav`` of every clip that has none; ``None`` for a kind the stems
    hold none of. The local copy's own folders when they hold exactly those files (the
    sample, all stems); else folders of links to the files (local or fetched; see
    :func:`beat2_files`) under the cache's ``speech-folders/``, never copies.

    Raises:
        DataFetchError: an unknown stem, a failed download, an unwritable cache.
    """
    registry = beat2_registry()
    clips = beat2_clips(registry)
    chosen = list(clips) if stems is None else list(dict.fromkeys(_stem(s, clips) for s in stems))
    files = beat2_files(chosen, fetch=fetch, progress=progress)
    paired: dict[str, Path] = {}
    unpaired: dict[str, Path] = {}
    for s in chosen:
        wav = files[f"{AUDIO_DIR}/{s}.wav"]
        motion = files.get(f"{MOTION_DIR}/{s}.npz")
        if motion is not None:
            paired.update({f"{s}.npz": motion, f"{s}.wav": wav})
        else:
            unpaired[f"{s}.wav"] = wav
    local = beat2_local_dir()
    if (
        local is not None
        and (paired or unpaired)
        and (not paired or _as_is(local, paired))
        and (not unpaired or _as_is(local / "unpaired", unpaired))
    ):
        return (local if paired else None), (local / "unpaired" if unpaired else None)
    key = "\n".join(f"{n} {p.resolve()}" for n, p in sorted({**paired, **unpaired}.items()))
    root = beat2_cache_dir() / "speech-folders" / hashlib.sha1(key.encode()).hexdigest()[:12]
    return (
        _link_folder(root / "paired", paired) if paired else None,
        _link_folder(root / "unpaired", unpaired) if unpaired else None,
    )
