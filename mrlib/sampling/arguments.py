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
from numbers import Integral
from typing import Any

from mrlib.errors import (
    ArgumentError,
    check_args,
    check_count,
    check_flag,
    check_number,
    check_seed,
    shown,
)
from mrlib.model.trained import check_label_model
from mrlib.representation.body import check_body
from mrlib.representation.motion import check_motion, check_motions
from mrlib.sampling.conditions import Condition
from mrlib.sampling.sampler import Sampler

__all__ = [
    "COMMON",
    "checked",
    "check_condition",
    "check_sampler",
    "check_parts",
    "optional_count",
    "optional_label",
    "non_negative",
    "steps",
]


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


def check_condition(name: str, value: Any) -> Any:
    """None, a label name or index, or a ``mrlib.Condition`` (``mrlib.sampling.conditions``)."""
    if value is None or isinstance(value, Condition):
        return value
    if isinstance(value, str) or (isinstance(value, Integral) and not isinstance(value, bool)):
        return value
    raise ArgumentError(
        f"{name} must be a label name or index, or a mrlib.Condition (Condition.crossover, "
        f"Condition.levels, Condition.blend), got {shown(value)}"
    )


def check_sampler(name: str, value: Any) -> Sampler | None:
    """None or a ``mrlib.Sampler``."""
    if value is None or isinstance(value, Sampler):
        return value
    raise ArgumentError(
        f"{name} must be a mrlib.Sampler (e.g. Sampler(fine_noise=0.5, guidance=0.25, "
        f"fix_contacts=False)) or None, got {shown(value)}"
    )


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
    "condition": check_condition,
    "label": optional_label,
    "length": optional_count,
    "seed": check_seed,
    "num_samples": check_count,
    "num": optional_count,
    "sampler": check_sampler,
    "levels": check_flag,
    "clean": check_flag,
    "progress": check_flag,
    "align": check_flag,
    "align_gait": check_flag,
    "push": check_flag,
    "body": check_body,
    "steps": steps,
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
