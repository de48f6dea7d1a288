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

Every download is bounded: it is stopped (and its temporary file removed) as soon as the
body passes the size the registry gives for the file, a server that sends nothing for
``TIMEOUT_S`` seconds is reported at once (no second try), and a file that has not
arrived within ``file_deadline`` seconds (a server that trickles) is given up.

``mrlib data fetch bandai`` fetches the clips the notebooks use ahead of time
(``--all``: the whole dataset, 40 MB). :func:`tutorial_clips` is what the notebooks
call: the Bandai clips when they can be had, else the synthetic clips of
``data_samples/`` with a one-line note saying so.
"""

from __future__ import annotations

import os
import re
import time
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from mrlib.errors import MrlibError
from mrlib.io.paths import CACHE_ENV, DATA_DIR_ENV, SHARED_DATA_DIR, cache_root
from mrlib.progress import bar as progress_bar

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
# seconds a server may stay silent (connecting, before the headers, between reads of the
# body): one that never answers is reported after this, not tried again
TIMEOUT_S = 10.0
MIN_RATE = 100_000  # bytes a second: a file slower than this (plus 20 s) is given up
CHUNK = 64 * 1024
# the cap of a file the registry gives no size for (a registry of an older mrlib)
CAP_BY_SUFFIX = {".bvh": 16 * 2**20, ".json": 64 * 2**10, ".txt": 64 * 2**10}
CAP_OTHER = 1 * 2**20
STALE_TEMP_S = 15 * 60  # a temporary file this old in the cache is a killed download's

# The clips the notebooks load: the four walks they train on, second takes and other
# contents for the calibration rows, and the resting poses of the speech notebook.
NOTEBOOK_CLIPS = tuple(
    [f"walk_{s}_{t}" for s in ("normal", "happy", "sad", "angry") for t in ("001", "002")]
    + ["walk_active_001"]
    + [f"bow_{s}_001" for s in ("normal", "happy", "sad", "angry")]
    + ["bye_sad_001", "byebye_sad_001", "guide_sad_001"]
)


class DataFetchError(MrlibError, OSError):
    """A dataset file could not be fetched (no network, a bad file, an unwritable cache)."""


def _registry_rows() -> list[list[str]]:
    rows = _REGISTRY.read_text().splitlines()
    return [line.split() for line in rows if line.strip() and not line.startswith("#")]


def bandai_registry() -> dict[str, str]:
    """``{relative path: "sha256:<hex>"}`` of every file mrlib can fetch (paths relative
    to the dataset folder: ``data/<clip>.bvh``, ``data/<clip>.json``, ``cfg/*.txt``,
    ``LICENSE``)."""
    return {row[0]: row[1] for row in _registry_rows()}


def bandai_sizes(registry: dict[str, str] | None = None) -> dict[str, int]:
    """``{relative path: size in bytes}`` of the files :func:`bandai_registry` lists (the
    registry's third column); with ``registry``, of the files whose hash there is the one
    the size belongs to (another file's size is no cap for it)."""
    rows = [row for row in _registry_rows() if len(row) > 2]
    return {r[0]: int(r[2]) for r in rows if registry is None or registry.get(r[0]) == r[1]}


def download_cap(name: str, sizes: dict[str, int] | None = None) -> int:
    """The most bytes a download of ``name`` may bring: its size in the registry, else a
    generous cap for its kind of file (``CAP_BY_SUFFIX``)."""
    sizes = bandai_sizes() if sizes is None else sizes
    if name in sizes:
        return sizes[name]
    return CAP_BY_SUFFIX.get(Path(name).suffix, CAP_OTHER)


def file_deadline(cap: int) -> float:
    """Seconds a download of at most ``cap`` bytes may take in all: 20 s plus the time
    it takes at ``MIN_RATE``."""
    return 20.0 + cap / MIN_RATE


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


_RETRY = (
    f"run `mrlib data fetch bandai` again later, set ${DATA_URL_ENV} to another mirror, or "
    f"${DATA_DIR_ENV} to a downloaded copy"
)


class CappedDownloader:
    """A pooch downloader (``downloader(url, output_file, pooch)``) of one file that
    stops as soon as the body passes ``cap`` bytes (a ``Content-Length`` above it is
    refused before the body is read), reports a server silent for ``TIMEOUT_S`` seconds
    at once, and gives up a file that has not arrived within ``deadline`` seconds. Its
    refusals are ``DataFetchError`` (pooch neither retries them nor keeps the temporary
    file); a dropped connection is a ``requests`` error, which pooch retries."""

    def __init__(self, name: str, cap: int, deadline: float) -> None:
        self.name, self.cap, self.deadline = name, int(cap), float(deadline)

    def __call__(self, url: str, output_file, pooch=None, check_only: bool = False) -> None:
        import requests

        start = time.monotonic()
        try:
            with requests.get(url, stream=True, timeout=(TIMEOUT_S, TIMEOUT_S)) as r:
                r.raise_for_status()
                length = r.headers.get("Content-Length", "").strip()
                if length.isdigit() and int(length) > self.cap:
                    raise self._too_big(url, f"the server announces {int(length)} bytes, more than")
                read1 = getattr(r.raw, "read1", None)  # one recv a call: a trickle is seen
                if read1 is not None:
                    chunks = iter(lambda: read1(CHUNK, decode_content=True), b"")
                else:  # pragma: no cover - urllib3 < 2
                    chunks = r.iter_content(CHUNK)
                got = 0
                with open(output_file, "wb") as fh:
                    for chunk in chunks:
                        got += len(chunk)
                        if got > self.cap:
                            raise self._too_big(url, "the body ran past")
                        if time.monotonic() - start > self.deadline:
                            raise DataFetchError(
                                f"{url}: {got} of {self.cap} bytes in {self.deadline:.0f} s "
                                f"(slower than {MIN_RATE // 1000} KB/s), so the download was "
                                f"stopped and nothing kept; {_RETRY}"
                            )
                        fh.write(chunk)
        except DataFetchError:
            raise
        except Exception as exc:
            if isinstance(exc, requests.exceptions.Timeout) or re.search(
                r"timed? ?out", str(exc), re.IGNORECASE
            ):
                raise DataFetchError(
                    f"{url}: download failed (no answer within {TIMEOUT_S:g} s); {_RETRY}"
                ) from None
            if isinstance(exc, (requests.RequestException, OSError)):
                raise
            # urllib3's own (a connection dropped mid-body): what pooch retries
            raise requests.exceptions.ConnectionError(f"{type(exc).__name__}: {exc}") from exc

    def _too_big(self, url: str, what: str) -> DataFetchError:
        return DataFetchError(
            f"{url}: {what} the {self.cap} bytes mrlib's registry gives for {self.name}, so "
            f"the download was stopped and nothing kept; a mirror set in "
            f"${DATA_URL_ENV} may serve other files: unset it or point it at a copy of the "
            "dataset, then fetch again"
        )


def _remove_stale_temporaries(cache: Path) -> None:
    """Remove the temporary files a killed download left in the cache (pooch's
    ``tmp********``), once they are older than any download may take."""
    for folder in (cache, cache / "data", cache / "cfg"):
        try:
            entries = list(folder.iterdir())
        except OSError:
            continue
        for p in entries:
            try:
                if (
                    re.fullmatch(r"tmp[a-z0-9_]{8}", p.name)
                    and p.is_file()
                    and time.time() - p.stat().st_mtime > STALE_TEMP_S
                ):
                    p.unlink()
            except OSError:
                pass


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
    import pooch

    registry = bandai_registry()
    sizes = bandai_sizes(registry)
    cache = bandai_cache_dir()
    wanted = ["LICENSE", "cfg/content_label.txt", "cfg/style_label.txt"]
    wanted += list(registry) if everything else _clip_files(clips or (), registry)
    wanted = list(dict.fromkeys(wanted))
    missing = [f for f in wanted if not _cached_ok(cache / f, registry[f])]
    if not missing:
        return cache
    first = not (cache / "LICENSE").exists()
    _remove_stale_temporaries(cache)
    pooch.get_logger().setLevel("WARNING")  # mrlib's own bar and messages say it instead
    store = pooch.create(path=cache, base_url=_base_url(), registry=registry, retry_if_failed=1)
    show = bool(progress) and len(missing) > 1
    bar = progress_bar(missing, desc="Bandai Namco clips", unit="file", enabled=show, leave=False)
    for f in bar:
        url = store.get_url(f)
        cap = download_cap(f, sizes)
        try:
            store.fetch(f, downloader=CappedDownloader(f, cap, file_deadline(cap)))
        except DataFetchError:
            raise  # the downloader's own: one line already
        except ValueError as exc:  # pooch: hash mismatch (the download is not kept)
            raise DataFetchError(
                f"{url}: the file's SHA-256 does not match mrlib's registry, so it was not "
                f"kept ({str(exc).splitlines()[0][:120]}); a mirror set in ${DATA_URL_ENV} "
                "may serve other files: unset it, or fetch again"
            ) from None
        except PermissionError as exc:
            raise DataFetchError(
                f"{cache}: cannot write the cache ({exc.strerror or exc}); set "
                f"${CACHE_ENV} to a writable folder, or ${DATA_DIR_ENV} to a copy of the dataset"
            ) from None
        except OSError as exc:
            raise DataFetchError(
                f"{url}: download failed ({_reason(exc)}); check the network, set "
                f"${DATA_URL_ENV} to a mirror, or ${DATA_DIR_ENV} to a downloaded copy"
            ) from None
        except Exception as exc:  # requests' errors (connection, HTTP status, timeout)
            raise DataFetchError(
                f"{url}: download failed ({_reason(exc)}); check the network, set "
                f"${DATA_URL_ENV} to a mirror, or ${DATA_DIR_ENV} to a downloaded copy"
            ) from None
    if first:
        print(ATTRIBUTION.format(license=cache / "LICENSE"), flush=True)
    return cache


_CAUSES = (
    (
        r"resolve|Name or service not known|nodename nor servname|getaddrinfo",
        "host not found: no network?",
    ),
    (r"Connection refused", "connection refused"),
    (r"timed? ?out", f"no answer within {TIMEOUT_S:g} s"),
    (r"Connection reset|RemoteDisconnected|aborted", "connection dropped"),
    (r"SSL|certificate", "TLS error"),
)


def _reason(exc: BaseException) -> str:
    """The cause of a failed download in a few words (HTTP status, refused, no network)."""
    text = " ".join(str(exc).split())
    status = getattr(getattr(exc, "response", None), "status_code", None)
    if status is not None:
        return f"HTTP {status}"
    for pattern, words in _CAUSES:
        if re.search(pattern, text, re.IGNORECASE):
            return words
    return re.sub(r"\(Caused by .*", "", text).strip()[:160] or type(exc).__name__


def _cached_ok(path: Path, digest: str) -> bool:
    """A cached file counts when it exists with the registry's size-independent hash; a
    file that fails the check is fetched again (pooch replaces it atomically)."""
    if not path.is_file():
        return False
    import pooch

    return pooch.file_hash(str(path)) == digest.split(":", 1)[-1]


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
