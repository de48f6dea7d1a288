"""Where data is read from, and output paths built from names that come from files.

:func:`default_data_dir` finds the Bandai Namco dataset that the real-data tests,
notebooks and benchmarks use (``$MRLIB_DATA_DIR``).

A clip's name and label come from its file (the npz ``name`` / ``label`` keys, a BVH's
JSON sidecar, a file stem) and end up in output paths: ``<out>/<clip name>/`` for
``mrlib train --per-clip``, ``<out>/<label>_seed0_0.npz`` for ``mrlib sample``. A name such
as ``/etc/x``, ``../../x`` or ``a/b`` must not decide where a file is written, so every such
name passes through :func:`safe_component` (the original stays in the metadata), and every
output path through :func:`inside`.
"""

from __future__ import annotations

import hashlib
import os
import re
import unicodedata
from collections.abc import Iterable
from pathlib import Path

from mrlib.errors import MrlibError

__all__ = [
    "DATA_DIR_ENV",
    "default_data_dir",
    "CACHE_ENV",
    "cache_root",
    "folder_problem",
    "UnsafePathError",
    "safe_component",
    "unique_components",
    "inside",
    "read_bytes_bounded",
    "read_text_bounded",
]

DATA_DIR_ENV = "MRLIB_DATA_DIR"
# An offline mirror of the dataset beside the repository (``../shared/...``), if any.
SHARED_DATA_DIR = Path(__file__).resolve().parents[3] / "shared" / "data" / "bandai-namco-motion-1"

MAX_COMPONENT = 80  # characters of a sanitised name, before its hash suffix
_ALLOWED = re.compile(r"[^A-Za-z0-9._+=-]+")


def default_data_dir(data_dir: str | Path | None = None) -> Path:
    """The Bandai Namco dataset folder: ``data_dir`` when given, else ``$MRLIB_DATA_DIR``,
    else ``../shared/data/bandai-namco-motion-1`` beside the repository. The folder may
    not exist; callers say so with their own error. ``mrlib.datasets.bandai`` fetches the
    clips into a cache when neither exists."""
    if data_dir is not None:
        return Path(data_dir).expanduser()
    env = os.environ.get(DATA_DIR_ENV)
    if env:
        return Path(env).expanduser()
    return SHARED_DATA_DIR


CACHE_ENV = "MRLIB_CACHE_DIR"


def folder_problem(path: str | Path) -> str | None:
    """Why ``path`` can be no folder (it exists and is not one, or a folder above it is a
    file), or None when it is one or can be made."""
    p = Path(path)
    if p.exists() and not p.is_dir():
        return f"{p} exists and is not a folder"
    for above in p.parents:
        if os.path.lexists(above):
            if not above.is_dir():
                return f"{above} is a file, not a folder, so {p} cannot be made"
            break
    return None


def cache_root() -> Path:
    """mrlib's cache folder: ``$MRLIB_CACHE_DIR``, else the user's cache folder
    (``~/.cache/mrlib`` on Linux, as ``platformdirs`` says elsewhere). Fetched data
    (``mrlib.datasets.bandai``) and shared trained models (``mrlib.training.trainer.train_cached``) live
    here."""
    root = os.environ.get(CACHE_ENV)
    if root:
        return Path(root).expanduser()
    import platformdirs  # a dependency of pooch

    return Path(platformdirs.user_cache_dir("mrlib"))


class UnsafePathError(MrlibError, ValueError):
    """An output path would leave the output folder."""


def safe_component(name: object, fallback: str = "unnamed") -> str:
    """``name`` as one safe file-name component.

    Letters, digits and ``. _ + = -`` are kept (after Unicode NFKD folding to ASCII);
    every other run of characters, path separators, NUL and control characters among
    them, becomes ``_``; leading dots are dropped (no ``..``, no hidden files). A name
    that had to change, or is longer than ``MAX_COMPONENT``, gets a short hash of the
    original appended, so distinct names stay distinct. Empty results become
    ``fallback``.
    """
    text = str(name)
    folded = unicodedata.normalize("NFKD", text).encode("ascii", "ignore").decode("ascii")
    out = _ALLOWED.sub("_", folded).lstrip("._").rstrip("_") or fallback
    changed = out != text
    if len(out) > MAX_COMPONENT:
        out, changed = out[:MAX_COMPONENT].rstrip("._"), True
    if changed:
        digest = hashlib.sha1(text.encode("utf-8", "surrogatepass")).hexdigest()[:8]
        out = f"{out}-{digest}"
    return out


def unique_components(names: Iterable[object], fallback: str = "unnamed") -> list[str]:
    """:func:`safe_component` of every name, with ``-2``, ``-3``, ... appended to repeats
    (compared case-insensitively, for case-insensitive file systems)."""
    out: list[str] = []
    seen: set[str] = set()
    for name in names:
        base = safe_component(name, fallback)
        cand, k = base, 1
        while cand.lower() in seen:
            k += 1
            cand = f"{base}-{k}"
        seen.add(cand.lower())
        out.append(cand)
    return out


def inside(root: str | Path, path: str | Path) -> Path:
    """``path`` if it lies in ``root`` (both resolved, symbolic links followed), else
    :class:`UnsafePathError`."""
    root_r = Path(root).resolve()
    path_r = Path(path).resolve()
    if path_r != root_r and root_r not in path_r.parents:
        raise UnsafePathError(f"{path}: refusing to write outside the output folder {root}")
    return Path(path)


def read_bytes_bounded(
    path: str | Path, max_bytes: int, error, too_big: str, unreadable: str = "cannot read file"
) -> bytes:
    """The bytes of ``path``, refused from its size before a byte is read when it is over
    ``max_bytes``: a multi-GB file where a few MB are expected costs a ``stat``, not the
    file. ``error(path, problem)`` builds the exception (the reader's own ``MrlibError``
    subclass), with ``"<size> MB is more than the <too_big>"`` for a file too large and
    ``"<unreadable>: <the system's reason>"`` for one that cannot be read."""
    path = Path(path)
    try:
        size = path.stat().st_size
        if size > max_bytes:
            raise error(path, f"{size / 2**20:.0f} MB is more than the {too_big}")
        return path.read_bytes()
    except OSError as e:
        raise error(path, f"{unreadable}: {e.strerror or e}") from None


def read_text_bounded(path: str | Path, max_bytes: int, what: str, error, **kw) -> str:
    """The text of ``path`` (UTF-8, newlines as ``Path.read_text`` gives them; ``kw``
    passes ``errors=``), bounded as :func:`read_bytes_bounded`; ``what`` names the file
    kind in the message."""
    too_big = f"{max_bytes / 2**20:g} MB mrlib reads from {what}; cut it into shorter files"
    text = read_bytes_bounded(path, max_bytes, error, too_big).decode("utf-8", **kw)
    if "\r" in text:  # universal newlines, as text mode reads them
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    return text
