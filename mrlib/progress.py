"""Progress for long work: a live bar on a terminal or in a notebook, one line per task
in a log.

:func:`bar` is what every long loop of mrlib uses (training blocks, evaluation, clip
downloads, renders, constraint fits). Where the progress goes decides its form:

* a terminal (standard error is a TTY) or a Jupyter kernel: a tqdm bar, updated in place;
* anything else (a pipe, a file, CI's log: ``make demo 2>&1 | tee log``): no carriage-
  return updates at all; each task writes **one line when it ends**, with its count, its
  time and its last figures (``block 2/4 (levels 3-4): 400/400 in 51.2 s, D=-0.31 ...``),
  so a log holds one line per block instead of thousands of redraws.

``enabled=False`` (``--no-progress`` on the command line) shows nothing either way.
``MRLIB_PROGRESS=bar`` or ``=lines`` overrides the choice (``=off``: nothing).
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Iterable, Iterator
from typing import Any, TextIO

__all__ = ["bar", "LineProgress", "interactive"]


def interactive(stream: TextIO | None = None) -> bool:
    """Whether ``stream`` (default standard error) shows a live bar: a terminal or a
    Jupyter kernel's output."""
    stream = sys.stderr if stream is None else stream
    if type(stream).__module__.startswith("ipykernel"):
        return True
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):
        return False


class LineProgress:
    """The part of tqdm's interface mrlib uses, writing one line when the task ends
    (:meth:`close`) instead of redrawing a bar. Iterable like tqdm when given one. A task
    left by an exception (or a ``break``) writes no line: the error says what happened."""

    def __init__(self, iterable: Iterable | None = None, *, desc: str = "", total: float | None = None,
                 initial: float = 0, stream: TextIO | None = None, unit: str = "it",
                 **_ignored: Any) -> None:  # fmt: skip
        self.iterable = iterable
        if total is None and iterable is not None and hasattr(iterable, "__len__"):
            total = len(iterable)  # type: ignore[arg-type]
        self.desc, self.total, self.n, self.unit = desc.strip(), total, initial, unit
        self.initial = initial
        self.postfix = ""
        self.stream = stream
        self._t0 = time.perf_counter()
        self._closed = False

    def __iter__(self) -> Iterator:
        if self.iterable is None:
            raise TypeError("this progress line was not given an iterable")
        try:
            for item in self.iterable:
                yield item
                self.update(1)
        except BaseException:  # stopped early or failed: no line claims it finished
            self._closed = True
            raise
        self.close()

    def __enter__(self) -> LineProgress:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:  # the error says what happened; no line claims the task finished
            self._closed = True

    def __len__(self) -> int:
        return int(self.total or 0)

    def update(self, n: float = 1) -> None:
        self.n += n

    def set_postfix(self, ordered_dict: dict | None = None, refresh: bool = True, **kw) -> None:
        items = {**(ordered_dict or {}), **kw}
        self.postfix = ", ".join(f"{k}={v}" for k, v in items.items())

    def set_postfix_str(self, s: str = "", refresh: bool = True) -> None:
        self.postfix = str(s)

    def set_description(self, desc: str | None = None, refresh: bool = True) -> None:
        self.desc = (desc or "").strip()

    def refresh(self) -> None:
        pass

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        if self.n == self.initial and self.n != 0:
            return  # nothing happened in this task (a resumed block already done)
        seconds = time.perf_counter() - self._t0
        if self.total is None:
            count = _count(self.n)
        elif float(self.total).is_integer():
            count = f"{_count(self.n)}/{_count(self.total)}"
        else:  # a weighted total (the demo's work units): a share reads better
            count = f"{100 * self.n / self.total:.0f}%" if self.total else _count(self.n)
        line = f"{self.desc + ': ' if self.desc else ''}{count} in {seconds:.1f} s"
        if self.postfix:
            line += f", {self.postfix}"
        stream = sys.stderr if self.stream is None else self.stream
        try:
            print(line, file=stream, flush=True)
        except (OSError, ValueError):  # a closed or broken log never stops the work
            pass


def _count(x: float) -> str:
    return f"{x:.0f}" if float(x).is_integer() else f"{x:.1f}"


class _Off(LineProgress):
    def close(self) -> None:
        self._closed = True


def bar(iterable: Iterable | None = None, *, enabled: bool = True, **kwargs: Any):
    """A progress bar over ``iterable`` (or updated by hand, ``total=``): tqdm's where
    the output is live (:func:`interactive`), a :class:`LineProgress` otherwise, nothing
    shown when ``enabled`` is false. Keyword arguments are tqdm's (``desc``, ``total``,
    ``initial``, ``unit``, ``leave``, ``bar_format``, ...)."""
    mode = os.environ.get("MRLIB_PROGRESS", "").strip().lower()
    if not enabled or mode == "off":
        return _Off(iterable, **kwargs)
    if mode == "bar" or (mode != "lines" and interactive()):
        from tqdm.auto import tqdm

        return tqdm(iterable, **kwargs)
    return LineProgress(iterable, **kwargs)
