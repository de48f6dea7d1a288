"""Typed errors raised at mrlib's public entry points.

Every error names the offending file (when there is one) and the problem, so that a
user sees ``BVHFormatError: walk.bvh, line 12: expected 'OFFSET', got 'OFSET'`` rather
than a traceback from deep inside numpy.
"""

from __future__ import annotations

import functools
import inspect
import math
from collections.abc import Callable, Iterable
from numbers import Integral, Real
from pathlib import Path
from typing import Any, TypeVar

F = TypeVar("F", bound=Callable[..., Any])

__all__ = [
    "is_whole",
    "check_count",
    "check_seed",
    "check_path",
    "check_optional_path",
    "check_number",
    "check_flag",
    "check_text",
    "check_choice",
    "check_list",
    "check_args",
    "check_fields",
    "shown",
    "MAX_SEED",
    "MrlibError",
    "ArgumentError",
    "MotionFileError",
    "BVHFormatError",
    "JointMapError",
    "MotionValueError",
    "UnsupportedFormatError",
    "ClipTooShortError",
    "BodyModelError",
]


class MrlibError(Exception):
    """Base class of every error mrlib raises on purpose."""


class MotionFileError(MrlibError, ValueError):
    """A motion file could not be read: missing keys, wrong shapes, bad values."""

    def __init__(self, path: str | Path | None, problem: str):
        self.path = None if path is None else Path(path)
        self.problem = problem
        where = f"{self.path}: " if self.path is not None else ""
        super().__init__(f"{where}{problem}")


class BVHFormatError(MotionFileError):
    """A BVH file is truncated or malformed."""


class JointMapError(MotionFileError):
    """A skeleton's joints cannot be mapped onto SMPL's."""


class UnsupportedFormatError(MotionFileError):
    """The file extension is not one mrlib can read or write."""


class MotionValueError(MrlibError, ValueError):
    """An in-memory motion or feature array has the wrong shape or non-finite values."""


class ArgumentError(MotionValueError, TypeError):
    """A public function was given an argument of the wrong type or an impossible value:
    the message names the function and argument, the value given and what is expected
    (a ``TypeError`` too, for callers that catch those)."""


class ClipTooShortError(MrlibError, ValueError):
    """A clip has fewer frames than the model or metric needs."""


class BodyModelError(MrlibError, ValueError):
    """A body model file is missing or does not look like SMPL."""


def shown(value: Any, limit: int = 60) -> str:
    """``value`` as an error message shows it: its ``repr`` on one line, cut to ``limit``
    characters, and its type (``'30' (str)``, ``[1, 2] (list)``)."""
    try:
        text = " ".join(repr(value).split())
    except Exception:  # a repr that fails is no reason to lose the real error
        text = f"<{type(value).__name__}>"
    if len(text) > limit:
        text = text[: limit - 3] + "..."
    if value is None or isinstance(value, bool):
        return text
    return f"{text} ({type(value).__name__})"


def is_whole(value: Any, *, integral_floats: bool = False) -> bool:
    """Whether ``value`` is a whole number: an int or numpy integer, never a bool (True is
    no count); with ``integral_floats`` also a finite real equal to one (``44100.0``)."""
    if isinstance(value, bool):  # (numpy's bool_ is neither Integral nor Real)
        return False
    if isinstance(value, Integral):
        return True
    return (
        integral_floats
        and isinstance(value, Real)
        and math.isfinite(value)
        and float(value) == int(value)
    )


def _bad(name: str, value: Any, expected: str) -> ArgumentError:
    return ArgumentError(f"{name} must be {expected}, got {shown(value)}")


def check_count(name: str, value: Any) -> int:
    """``value`` as an int if it is a positive integer, else an ``ArgumentError``."""
    if isinstance(value, bool) or not isinstance(value, Integral) or value < 1:
        raise _bad(name, value, "a positive integer")
    return int(value)


MAX_SEED = 2**32 - 1  # numpy's and torch's seeds are 32/64-bit unsigned


def check_seed(name: str, value: Any) -> int | None:
    """``value`` as an int if it is None or an integer in ``[0, MAX_SEED]``, else an
    ``ArgumentError`` (``1.5`` is refused, not run as 1; ``"7"`` is not a seed)."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, Integral) or not 0 <= value <= MAX_SEED:
        raise _bad(name, value, f"an integer in [0, {MAX_SEED}] or None")
    return int(value)


def check_path(name: str, value: Any) -> Path:
    """``value`` as a ``Path``: a ``str``, ``os.PathLike`` or ``bytes`` (decoded as the
    file system does), else an ``ArgumentError`` naming what was given."""
    import os

    if not isinstance(value, (str, bytes, os.PathLike)):
        raise _bad(name, value, "a file path (str or os.PathLike)")
    text = os.fsdecode(os.fspath(value))
    if not text:
        raise ArgumentError(f"{name} must be a file path, got an empty one")
    return Path(text)


def check_optional_path(name: str, value: Any) -> Path | None:
    """:func:`check_path`, or None."""
    return None if value is None else check_path(name, value)


def check_number(
    name: str,
    value: Any,
    *,
    low: float | None = None,
    high: float | None = None,
    open_low: bool = False,
    integer: bool = False,
    optional: bool = False,
) -> float | int | None:
    """``value`` as a float (an int with ``integer``) if it is a finite real number in
    ``[low, high]`` (``(low, high]`` with ``open_low``), or None with ``optional``; else an
    ``ArgumentError``. Text is no number (``"30"`` is refused, not parsed), nor is a bool."""
    if value is None and optional:
        return None
    kinds = Integral if integer else Real
    ok = not isinstance(value, bool) and isinstance(value, kinds) and math.isfinite(value)
    if ok and low is not None:
        ok = value > low if open_low else value >= low
    if ok and high is not None:
        ok = value <= high
    if not ok:
        what = "an integer" if integer else "a number"
        if low is not None and high is not None:
            what += f" in {'(' if open_low else '['}{low:g}, {high:g}]"
        elif low is not None:
            what += f" {'>' if open_low else '>='} {low:g}"
        elif high is not None:
            what += f" <= {high:g}"
        raise _bad(name, value, what + (" or None" if optional else ""))
    return int(value) if integer else float(value)


def check_flag(name: str, value: Any) -> bool:
    """``value`` if it is a bool (numpy's too), else an ``ArgumentError`` (``"no"`` is
    not False)."""
    if isinstance(value, bool) or (
        type(value).__module__ == "numpy" and type(value).__name__ in ("bool", "bool_")
    ):
        return bool(value)
    raise _bad(name, value, "True or False")


def check_text(name: str, value: Any, *, optional: bool = False) -> str | None:
    """``value`` if it is a non-empty ``str`` (or None with ``optional``)."""
    if value is None and optional:
        return None
    if not isinstance(value, str) or not value:
        raise _bad(name, value, "a non-empty string" + (" or None" if optional else ""))
    return value


def check_choice(name: str, value: Any, choices: Iterable[Any]) -> Any:
    """``value`` if it is one of ``choices`` (compared by type and value: ``1`` is not
    ``True``), else an ``ArgumentError`` listing them."""
    options = tuple(choices)
    for c in options:
        if type(value) is type(c) and value == c:
            return value
    raise _bad(name, value, "one of " + ", ".join(repr(c) for c in options))


def check_list(
    name: str, value: Any, item: Callable[[str, Any], Any], *, what: str = "a list"
) -> list:
    """``value`` as a list if it is a list, tuple or other non-text sequence (a generator
    is read once), each element passed through ``item(f"{name}[i]", element)``; a single
    str, bytes, mapping or non-iterable is an ``ArgumentError`` (``"clip.bvh"`` is not a
    list of paths)."""
    import os
    from collections.abc import Mapping

    if isinstance(value, (str, bytes, os.PathLike, Mapping)) or not isinstance(value, Iterable):
        raise _bad(name, value, what)
    return [item(f"{name}[{i}]", v) for i, v in enumerate(value)]


def check_fields(obj: Any, error: type[Exception] = ArgumentError) -> None:
    """Each field of the dataclass ``obj`` of the kind of its default: a bool, an integer
    (not a bool), a real number, text, a tuple or list, or the default's own class (a
    nested config); fields whose default is None are not checked. An ``error`` naming
    the field and the value otherwise (``TrainConfig(lr="x")`` is refused, not a
    ``TypeError`` from a comparison further on)."""
    import dataclasses

    for f in dataclasses.fields(obj):
        if f.default is not dataclasses.MISSING:
            default = f.default
        elif f.default_factory is not dataclasses.MISSING:
            default = f.default_factory()
        else:
            continue
        value = getattr(obj, f.name)
        if default is None:
            continue
        if isinstance(default, bool):
            ok, what = isinstance(value, bool), "True or False"
        elif isinstance(default, Integral):
            ok = isinstance(value, Integral) and not isinstance(value, bool)
            what = "an integer"
        elif isinstance(default, Real):
            ok = isinstance(value, Real) and not isinstance(value, bool)
            what = "a number"
        elif isinstance(default, str):
            ok, what = isinstance(value, str), "text"
        elif isinstance(default, (tuple, list)):
            ok, what = isinstance(value, (tuple, list)), "a tuple or list"
        else:
            ok, what = isinstance(value, type(default)), f"a {type(default).__name__}"
        if not ok:
            raise error(f"{type(obj).__name__}.{f.name} must be {what}, got {shown(value)}")


def check_args(**checks: Callable[[str, Any], Any]) -> Callable[[F], F]:
    """Decorator of a public function: each argument named in ``checks`` that the call
    gives passes through its check, ``check(name, value) -> value`` (what the function
    then receives; defaults are not checked), before the function runs. The checks name
    the argument as ``"<function>: <argument>"``. A call that does not fit the signature
    (an argument missing, unknown or given twice) is an ``ArgumentError`` as well."""

    def wrap(fn: F) -> F:
        sig = inspect.signature(fn)
        unknown = set(checks) - set(sig.parameters)
        if unknown:
            raise RuntimeError(f"check_args of {fn.__qualname__}: no argument {sorted(unknown)}")
        where = fn.__qualname__

        @functools.wraps(fn)
        def checked(*args: Any, **kwargs: Any) -> Any:
            try:
                bound = sig.bind(*args, **kwargs)
            except TypeError as e:
                raise ArgumentError(f"{where}(): {e}") from None
            given = bound.arguments
            for name, check in checks.items():
                if name in given:
                    given[name] = check(f"{where}: {name}", given[name])
            return fn(*bound.args, **bound.kwargs)

        return checked  # type: ignore[return-value]

    return wrap
