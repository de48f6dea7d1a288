"""Downloads of public data into mrlib's cache, shared by the data sets mrlib fetches by
name (``bandai``, ``beat2``): a registry of SHA-256 hashes and sizes per file (in
``mrlib/assets/``), `pooch <https://www.fatiando.org/pooch>`_ to fetch and check each
file, :class:`CappedDownloader` to bound every download, and one-line
:class:`DataFetchError` s that name the file, the URL and the way around.

Every download is bounded: it is stopped (and its temporary file removed) as soon as the
body passes the size the registry gives for the file, a server that sends nothing for
``TIMEOUT_S`` seconds is reported at once (no second try), and a file that has not
arrived within :func:`file_deadline` seconds (a server that trickles) is given up.
"""

from __future__ import annotations

import re
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

from mrlib.errors import MrlibError
from mrlib.io.paths import CACHE_ENV
from mrlib.progress import bar as progress_bar

__all__ = [
    "DataFetchError",
    "FetchHints",
    "TIMEOUT_S",
    "MIN_RATE",
    "registry_rows",
    "registry_hashes",
    "registry_sizes",
    "file_deadline",
    "CappedDownloader",
    "FetchLimits",
    "cached_ok",
    "fetch_files",
]

# seconds a server may stay silent (connecting, before the headers, between reads of the
# body): one that never answers is reported after this, not tried again
TIMEOUT_S = 10.0
MIN_RATE = 100_000  # bytes a second: a file slower than this (plus 20 s) is given up
CHUNK = 64 * 1024
STALE_TEMP_S = 15 * 60  # a temporary file this old in the cache is a killed download's


class DataFetchError(MrlibError, OSError):
    """A dataset file could not be fetched (no network, a bad file, an unwritable cache)."""


@dataclass(frozen=True)
class FetchHints:
    """What a failed download's message offers as the way around: ``url_env`` (a mirror
    prefix), ``dir_env`` (a local copy) and ``command`` (fetch again)."""

    url_env: str
    dir_env: str
    command: str

    @property
    def retry(self) -> str:
        return (
            f"run `{self.command}` again later, set ${self.url_env} to another mirror, or "
            f"${self.dir_env} to a downloaded copy"
        )


def registry_rows(path: Path) -> list[list[str]]:
    """The rows of a registry file: ``<relative path> sha256:<hex> [<size>]``, ``#``
    comments and blank lines skipped."""
    rows = Path(path).read_text().splitlines()
    return [line.split() for line in rows if line.strip() and not line.startswith("#")]


def registry_hashes(rows: list[list[str]]) -> dict[str, str]:
    """``{relative path: "sha256:<hex>"}`` of the rows."""
    return {row[0]: row[1] for row in rows}


def registry_sizes(rows: list[list[str]], registry: dict[str, str] | None = None) -> dict[str, int]:
    """``{relative path: size in bytes}`` of the rows that give one; with ``registry``, of
    the files whose hash there is the one the size belongs to (another file's size is no
    cap for it)."""
    rows = [row for row in rows if len(row) > 2]
    return {r[0]: int(r[2]) for r in rows if registry is None or registry.get(r[0]) == r[1]}


def file_deadline(cap: int) -> float:
    """Seconds a download of at most ``cap`` bytes may take in all: 20 s plus the time
    it takes at ``MIN_RATE``."""
    return 20.0 + cap / MIN_RATE


class CappedDownloader:
    """A pooch downloader (``downloader(url, output_file, pooch)``) of one file that
    stops as soon as the body passes ``cap`` bytes (a ``Content-Length`` above it is
    refused before the body is read), reports a server silent for ``timeout`` seconds
    at once, and gives up a file that has not arrived within ``deadline`` seconds. Its
    refusals are ``DataFetchError`` (pooch neither retries them nor keeps the temporary
    file); a dropped connection is a ``requests`` error, which pooch retries. ``hints``
    name the ways around in its messages."""

    def __init__(
        self, name: str, cap: int, deadline: float, *, hints: FetchHints, timeout: float = TIMEOUT_S
    ) -> None:
        self.name, self.cap, self.deadline = name, int(cap), float(deadline)
        self.hints, self.timeout = hints, float(timeout)

    def __call__(self, url: str, output_file, pooch=None, check_only: bool = False) -> None:
        import requests

        start = time.monotonic()
        try:
            with requests.get(url, stream=True, timeout=(self.timeout, self.timeout)) as r:
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
                                f"stopped and nothing kept; {self.hints.retry}"
                            )
                        fh.write(chunk)
        except DataFetchError:
            raise
        except Exception as exc:
            if isinstance(exc, requests.exceptions.Timeout) or re.search(
                r"timed? ?out", str(exc), re.IGNORECASE
            ):
                raise DataFetchError(
                    f"{url}: download failed (no answer within {self.timeout:g} s); "
                    f"{self.hints.retry}"
                ) from None
            if isinstance(exc, (requests.RequestException, OSError)):
                raise
            # urllib3's own (a connection dropped mid-body): what pooch retries
            raise requests.exceptions.ConnectionError(f"{type(exc).__name__}: {exc}") from exc

    def _too_big(self, url: str, what: str) -> DataFetchError:
        return DataFetchError(
            f"{url}: {what} the {self.cap} bytes mrlib's registry gives for {self.name}, so "
            f"the download was stopped and nothing kept; a mirror set in "
            f"${self.hints.url_env} may serve other files: unset it or point it at a copy of "
            "the dataset, then fetch again"
        )


@dataclass(frozen=True)
class FetchLimits:
    """The bounds of every download of one fetch: ``cap(path)``, the most bytes the file
    at a registry path may have; ``timeout``, the seconds a server may stay silent; and
    ``deadline(cap)``, the seconds a file of at most ``cap`` bytes may take in all."""

    cap: Callable[[str], int]
    timeout: float = TIMEOUT_S
    deadline: Callable[[int], float] = file_deadline


def _remove_stale_temporaries(folders: Iterable[Path]) -> None:
    """Remove the temporary files a killed download left in the cache (pooch's
    ``tmp********``), once they are older than any download may take."""
    for folder in folders:
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


def _causes(timeout: float) -> tuple[tuple[str, str], ...]:
    return (
        (
            r"resolve|Name or service not known|nodename nor servname|getaddrinfo",
            "host not found: no network?",
        ),
        (r"Connection refused", "connection refused"),
        (r"timed? ?out", f"no answer within {timeout:g} s"),
        (r"Connection reset|RemoteDisconnected|aborted", "connection dropped"),
        (r"SSL|certificate", "TLS error"),
    )


def _reason(exc: BaseException, timeout: float = TIMEOUT_S) -> str:
    """The cause of a failed download in a few words (HTTP status, refused, no network)."""
    text = " ".join(str(exc).split())
    status = getattr(getattr(exc, "response", None), "status_code", None)
    if status is not None:
        return f"HTTP {status}"
    for pattern, words in _causes(timeout):
        if re.search(pattern, text, re.IGNORECASE):
            return words
    return re.sub(r"\(Caused by .*", "", text).strip()[:160] or type(exc).__name__


def cached_ok(path: Path, digest: str) -> bool:
    """A cached file counts when it exists with the registry's hash; a file that fails
    the check is fetched again (pooch replaces it atomically)."""
    if not path.is_file():
        return False
    import pooch

    return pooch.file_hash(str(path)) == digest.split(":", 1)[-1]


def fetch_files(
    files: Iterable[str],
    *,
    registry: dict[str, str],
    cache: Path,
    base_url: str,
    limits: FetchLimits,
    hints: FetchHints,
    desc: str,
    progress=True,
) -> list[str]:
    """Download into ``cache`` those of ``files`` (registry paths) that are not there with
    the registry's hash, each from ``base_url + path``, bounded by ``limits``
    (``limits.cap(path)`` bytes, ``limits.timeout``, ``limits.deadline(cap)``); returns
    the paths downloaded (none: all cached). ``desc`` names the files on the progress
    bar, ``hints`` the ways around in the messages.

    Raises:
        DataFetchError: one line naming the file, the URL and what to do; a file whose
            SHA-256 does not match is not kept.
    """
    import pooch

    missing = [f for f in dict.fromkeys(files) if not cached_ok(cache / f, registry[f])]
    if not missing:
        return []
    _remove_stale_temporaries(dict.fromkeys([cache, *((cache / f).parent for f in missing)]))
    pooch.get_logger().setLevel("WARNING")  # mrlib's own bar and messages say it instead
    store = pooch.create(path=cache, base_url=base_url, registry=registry, retry_if_failed=1)
    show = bool(progress) and len(missing) > 1
    bar = progress_bar(missing, desc=desc, unit="file", enabled=show, leave=False)
    around = (
        f"check the network, set ${hints.url_env} to a mirror, or ${hints.dir_env} to a "
        "downloaded copy"
    )
    timeout = limits.timeout
    for f in bar:
        url = store.get_url(f)
        c = limits.cap(f)
        downloader = CappedDownloader(f, c, limits.deadline(c), hints=hints, timeout=timeout)
        try:
            store.fetch(f, downloader=downloader)
        except DataFetchError:
            raise  # the downloader's own: one line already
        except ValueError as exc:  # pooch: hash mismatch (the download is not kept)
            raise DataFetchError(
                f"{url}: the file's SHA-256 does not match mrlib's registry, so it was not "
                f"kept ({str(exc).splitlines()[0][:120]}); a mirror set in ${hints.url_env} "
                "may serve other files: unset it, or fetch again"
            ) from None
        except PermissionError as exc:
            raise DataFetchError(
                f"{cache}: cannot write the cache ({exc.strerror or exc}); set "
                f"${CACHE_ENV} to a writable folder, or ${hints.dir_env} to a copy of the dataset"
            ) from None
        except Exception as exc:  # OSError, requests' errors (connection, HTTP status, timeout)
            raise DataFetchError(
                f"{url}: download failed ({_reason(exc, timeout)}); {around}"
            ) from None
    return missing
