"""The argument checks the sampling functions share, by argument name.

Every public sampler (``generate``, ``restyle``, ``mrlib.sampling.constraints``) names its
arguments alike: ``model``, ``seed``, ``length``, ``body``, ``motion``, ... :func:`checked`
gives each function the checks of :data:`COMMON` for the arguments it has (plus its own),
through ``mrlib.errors.check_args``: an argument of the wrong type is an
``ArgumentError`` naming the function, the argument and the value, raised before any
work, never a ``TypeError`` or ``AttributeError`` from deep inside.

Values are checked for their type and for what holds without the model (a seed in
range, a positive length); what depends on the model (a label it knows, a level it has)
is checked where the model is at hand.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Mapping
from numbers import Integral, Real
from typing import Any

from mrlib.errors import (
    ArgumentError,
    check_args,
    check_count,
    check_flag,
    check_list,
    check_number,
    check_seed,
    shown,
)
from mrlib.model.trained import check_label_model
from mrlib.representation.body import check_body
from mrlib.representation.motion import check_motion, check_motions

__all__ = [
    "COMMON",
    "checked",
    "check_level_conditions",
    "check_blend",
    "check_fix_contacts",
    "check_parts",
    "optional_count",
    "optional_label",
    "non_negative",
    "steps",
]

CLEANUP_METHODS = ("ik", "optimise")


def optional_count(name: str, value: Any) -> int | None:
    """None or a positive integer."""
    return None if value is None else check_count(name, value)


def non_negative(name: str, value: Any) -> float:
    """A finite number >= 0."""
    return check_number(name, value, low=0)


def steps(name: str, value: Any) -> int:
    """An integer >= 0 (steps of a fit; 0: none)."""
    return check_number(name, value, low=0, integer=True)


def _label(name: str, value: Any) -> Any:
    if isinstance(value, str) or (isinstance(value, Integral) and not isinstance(value, bool)):
        return value
    raise ArgumentError(
        f"{name} must be a label name or index (a label is one of the model's labels), "
        f"got {shown(value)}"
    )


def optional_label(name: str, value: Any) -> Any:
    """None, a label name or a label index (the model says which it knows)."""
    return None if value is None else _label(name, value)


def check_level_conditions(name: str, value: Any) -> list | None:
    """None or a list of ``(label, (first_level, last_level))`` pairs."""
    if value is None:
        return None
    what = "a list of (label, (first_level, last_level)) pairs"

    def pair(n: str, item: Any) -> tuple:
        if not isinstance(item, (tuple, list)) or len(item) != 2:
            raise ArgumentError(f"{name} must be {what}; {n} is {shown(item)}")
        lab, levels = item
        ok = isinstance(levels, (tuple, list)) and len(levels) == 2
        if not ok or not all(isinstance(v, Integral) and not isinstance(v, bool) for v in levels):
            raise ArgumentError(f"{name} must be {what}; {n} has levels {shown(levels)}")
        return (_label(f"{n} label", lab), (int(levels[0]), int(levels[1])))

    return check_list(name, value, pair, what=what)


def check_blend(name: str, value: Any) -> tuple | None:
    """None or ``(label_a, label_b, w)`` with ``w`` a number or one number per level."""
    if value is None:
        return None
    what = "(label_a, label_b, weight) with a weight or one weight per level"
    if not isinstance(value, (tuple, list)) or len(value) != 3:
        raise ArgumentError(f"{name} must be {what}, got {shown(value)}")
    a, b, w = value
    if isinstance(w, (list, tuple)):
        check_list(f"{name} weights", w, _weight)
    elif not hasattr(w, "shape"):  # an array or tensor of weights: label_weights reads it
        _weight(f"{name} weight", w)
    return (_label(f"{name} label_a", a), _label(f"{name} label_b", b), w)


def _weight(name: str, value: Any) -> Any:
    if isinstance(value, bool) or not isinstance(value, Real):
        raise ArgumentError(f"{name} must be a number, got {shown(value)}")
    return value


def check_fix_contacts(name: str, value: Any) -> bool | str:
    """True, False or a clean-up method (``"ik"``, ``"optimise"``)."""
    if isinstance(value, str) and value in CLEANUP_METHODS:
        return value
    if isinstance(value, str) or not isinstance(value, bool):
        raise ArgumentError(
            f"{name} must be True, False or a method ({', '.join(map(repr, CLEANUP_METHODS))}), "
            f"got {shown(value)}"
        )
    return value


def check_parts(name: str, value: Any) -> Mapping:
    """A non-empty mapping ``{part: label}`` (a part: a name of ``PARTS``, a joint name, or
    a list of joints; ``mrlib.sampling.constraints.parse_parts`` reads the text form)."""
    if not isinstance(value, Mapping) or not value:
        hint = " (text such as 'upper=a,lower=b': parse_parts)" if isinstance(value, str) else ""
        raise ArgumentError(
            f"{name} must be a dict {{part: label}}, e.g. {{'upper': 'walk_happy', "
            f"'lower': 'walk_sad'}}{hint}, got {shown(value)}"
        )
    for part, label in value.items():
        if not isinstance(part, (str, tuple)):
            raise ArgumentError(
                f"{name} keys must be part names or tuples of joints, got {shown(part)}"
            )
        _label(f"{name}[{part!r}]", label)
    return value


# Checks by argument name: the same name means the same thing in every sampler.
COMMON: dict[str, Callable[[str, Any], Any]] = {
    "model": check_label_model,
    "motion": check_motion,
    "prefix": check_motion,
    "source": check_motion,
    "target": check_motion,
    "motions": check_motions,
    "condition": optional_label,
    "label": optional_label,
    "conditions": check_level_conditions,
    "blend": check_blend,
    "length": optional_count,
    "seed": check_seed,
    "num_samples": check_count,
    "fix_contacts": check_fix_contacts,
    "clean": check_flag,
    "progress": check_flag,
    "align": check_flag,
    "align_gait": check_flag,
    "invert": check_flag,
    "push": check_flag,
    "body": check_body,
    "steps": steps,
    "invert_steps": steps,
    "sharpen": steps,
    "seconds": lambda n, v: check_number(n, v, low=0, open_low=True, optional=True),
    "blend_s": non_negative,
    "smooth_s": non_negative,
    "still": non_negative,
    "margin": non_negative,
    "frames": check_count,
    "cycles": check_count,
    "window": check_count,
}


def checked(**own: Callable[[str, Any], Any]) -> Callable:
    """Decorator: ``mrlib.errors.check_args`` with the :data:`COMMON` check of every
    argument the function has, and ``own`` checks (which replace a common one)."""

    def wrap(fn: Callable) -> Callable:
        params = inspect.signature(fn).parameters
        checks = {k: v for k, v in COMMON.items() if k in params}
        checks.update(own)
        return check_args(**checks)(fn)

    return wrap
