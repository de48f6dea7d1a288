"""Path files: the CSV a :class:`mrlib.sampling.constraints.GroundPath` is read from
(``GroundPath.from_csv``), with every check a hand-written or damaged file needs: size,
encoding, header, row widths, bounded counts, one ``MotionFileError`` naming the file. How
a path is followed is in ``mrlib.sampling.constraints.path``."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from mrlib.errors import MotionFileError, MotionValueError
from mrlib.io.paths import read_text_bounded

__all__ = ["read_path_csv", "MAX_PATH_FILE_BYTES", "MAX_PATH_POINTS"]

MAX_PATH_FILE_BYTES = 8 * 2**20  # what a path file may hold: its size and its points
MAX_PATH_POINTS = 100_000


def read_path_csv(path: str | Path, build: Callable[[np.ndarray, np.ndarray | None], Any]):
    """``build(points (N, 2), times (N,) or None)`` of the CSV file ``path``: columns
    ``x, z`` (metres) and optionally ``t`` (seconds), with or without a header row,
    separated by commas, spaces or tabs, or by semicolons with decimal commas (``1,5;2``,
    as spreadsheets write in many locales); ``#`` starts a comment.

    Raises:
        MotionFileError: naming ``path``: not a regular file, larger than
            ``MAX_PATH_FILE_BYTES``, not UTF-8, rows of differing widths, a header that
            does not match the rows, more than ``MAX_PATH_POINTS`` points, or values that
            ``build`` refuses (its ``MotionValueError``).
    """
    path = Path(path)
    if not path.is_file():
        raise MotionFileError(path, "no such file" if not path.exists() else "not a regular file")
    what = f"a path file (at most {MAX_PATH_POINTS} points)"
    try:
        text = read_text_bounded(path, MAX_PATH_FILE_BYTES, what, MotionFileError)
    except UnicodeDecodeError as e:
        raise MotionFileError(path, f"not UTF-8 text (byte {e.start})") from None
    try:
        return build(*_columns(path, text.removeprefix("\ufeff")))
    except MotionFileError:
        raise
    except MotionValueError as e:
        raise MotionFileError(path, str(e)) from None
    except (ValueError, ArithmeticError, LookupError) as e:  # anything the checks missed
        raise MotionFileError(path, f"cannot read ({type(e).__name__}: {e})") from None


def _columns(path: Path, text: str) -> tuple[np.ndarray, np.ndarray | None]:
    rows = []
    for no, line in enumerate(text.splitlines(), 1):
        line = line.split("#")[0].strip()
        if line and ";" in line:  # a spreadsheet's export where commas mark decimals
            rows.append((no, [v.strip().replace(",", ".") for v in line.split(";") if v.strip()]))
        elif line:
            rows.append((no, line.replace(",", " ").split()))
    header = None
    if rows and not all(_is_number(v) for v in rows[0][1]):
        header_line, header = rows[0][0], [h.strip().lower() for h in rows[0][1]]
        rows = rows[1:]
        bad = [h for h in header if h not in ("x", "z", "t")]
        if bad or len(set(header)) != len(header) or not {"x", "z"} <= set(header):
            raise MotionFileError(
                path,
                f"line {header_line}: the header needs columns x and z (and t), got {header}",
            )
    if len(rows) > MAX_PATH_POINTS:
        raise MotionFileError(
            path, f"{len(rows)} points, more than the {MAX_PATH_POINTS} a path may have"
        )
    width = len(header) if header else (len(rows[0][1]) if rows else 2)
    if width not in (2, 3):
        raise MotionFileError(path, f"expected 2 or 3 columns (x, z[, t]), got {width}")
    values = []
    for no, vals in rows:
        if len(vals) != width:
            raise MotionFileError(
                path, f"line {no}: {len(vals)} values, expected {width} (x, z[, t])"
            )
        try:
            values.append([float(v) for v in vals])
        except ValueError:
            raise MotionFileError(
                path, f"line {no}: expected numbers in columns x, z[, t], got {vals}"
            ) from None
    if len(values) < 2:
        raise MotionFileError(path, "expected at least 2 rows of x, z[, t] (metres, seconds)")
    data = np.array(values, np.float64)
    cols = header or ["x", "z", "t"][:width]
    x, z = data[:, cols.index("x")], data[:, cols.index("z")]
    return np.stack([x, z], -1), (data[:, cols.index("t")] if "t" in cols else None)


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True
