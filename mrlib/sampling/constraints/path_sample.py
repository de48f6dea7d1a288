"""A label model's motion on a ground path: its natural pace, how long a walk of a path
lasts, and the walk itself (generated, then bent onto the path by
``mrlib.sampling.constraints.path.follow_path``)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from mrlib.errors import ClipTooShortError, MotionValueError, check_number
from mrlib.representation.motion import Motion
from mrlib.sampling.arguments import checked
from mrlib.sampling.constraints.path import (
    MAX_PATH_SECONDS,
    MIN_TRAVEL_SPEED,
    GroundPath,
    check_path_spec,
    follow_path,
    ground_track,
    parse_path,
)
from mrlib.sampling.generation import MAX_SAMPLE_SECONDS
from mrlib.sampling.sampler import Sampler, model_frames

__all__ = ["natural_pace", "path_seconds", "generate_on_path", "OVERDRAW"]

# An open path walked at its implied length is drawn this much longer and cut at its end:
# a draw's pace differs from the 10-s sample's that timed it by a few per cent to a tenth.
OVERDRAW = 1.25


@checked()
def natural_pace(model, condition=None, *, seed: int = 0, sampler=None) -> float:
    """Ground speed (m/s) of the model's own motion under a condition (a label or a
    ``mrlib.Condition``): the travel speed of a 10 s raw sample drawn with the
    ``sampler``'s fine noise and guidance."""
    from mrlib.sampling.generation import generate

    n = max(2, round(10 * model.fps))
    raw = replace(sampler or Sampler(), fix_contacts=False)
    m = generate(model, condition, length=n, seed=seed, sampler=raw)
    return float(ground_track(m)["arc"][-1] / m.duration)


@checked(path=check_path_spec)
def path_seconds(
    model, path: GroundPath | str, condition=None, *, sampler=None
) -> tuple[float, float | None]:
    """How long a walk of ``path`` lasts without an explicit length: the path's times,
    else its length at the condition's own pace (:func:`natural_pace`, returned too;
    None for a timed path)."""
    path = parse_path(path)
    if path.times is not None:
        return float(path.duration), None
    pace = natural_pace(model, condition, sampler=sampler)
    return float(path.length / max(pace, MIN_TRAVEL_SPEED)), pace


@checked(
    path=check_path_spec,
    max_seconds=lambda n, v: check_number(n, v, low=0, open_low=True, optional=True),
)
def generate_on_path(
    model,
    path: GroundPath | str,
    condition=None,
    *,
    seconds: float | None = None,
    seed: int | None = None,
    sampler=None,
    body=None,
    max_seconds: float | None = MAX_PATH_SECONDS,
) -> Motion:
    """A motion of a label model that walks ``path``: generated, then bent onto it
    (:func:`follow_path`).

    Args:
        path: a :class:`GroundPath` or a spec (``"circle:2"``, ``"eight:2"``, a CSV).
        condition: a label or a ``mrlib.Condition`` (None: the first label).
        seconds: length; default: the path's times, else one lap of a closed path at
            the condition's own pace (:func:`natural_pace`), or an open path walked to
            its end (drawn ``OVERDRAW`` times that long and cut where it gets there).
        sampler: a ``mrlib.Sampler``: the draw's fine noise and guidance, the output's
            frame rate (``fps``; None: the model's; ``seconds`` and the path's times are
            kept), and whether the feet are planted after the bend (``fix_contacts``,
            ``mrlib.sampling.cleanup``).
        max_seconds: refuse (before generating) a walk longer than this, given or
            implied by the path (None: no limit).
    """
    from mrlib.sampling.generation import generate

    path = parse_path(path)
    implied = seconds is None
    if implied:
        seconds, _ = path_seconds(model, path, condition, sampler=sampler)
    if not (np.isfinite(seconds) and seconds > 0):
        raise MotionValueError(f"seconds must be a positive number, got {seconds}")
    if not implied:
        how = "as asked"
    elif path.times is not None:
        how = "from its times"
    else:
        how = f"{path.length:.0f} m at the condition's pace"
    if max_seconds is not None and seconds > max_seconds:
        raise MotionValueError(
            f"path {path.name!r}: {seconds:.0f} s of motion ({how}) is longer than the "
            f"{max_seconds:.0f} s generated in one piece; give a shorter length (seconds=, "
            "--seconds) or a shorter path, and join pieces with continue_motion (--continue)"
        )
    # an open path at the length its pace implies: drawn longer, cut where the walk
    # reaches the path's end (this draw's pace is not the 10-s sample's it was timed by)
    cut = implied and not path.closed and path.times is None
    drawn = min(seconds * OVERDRAW, MAX_SAMPLE_SECONDS) if cut else seconds
    sampler, length = sampler or Sampler(), model_frames(drawn, model.fps)
    try:
        m = generate(model, condition, length=length, seed=seed,
                     sampler=replace(sampler, fix_contacts=False))  # fmt: skip
    except ClipTooShortError as e:  # a path timed faster than anyone walks, or seconds=0.1
        raise ClipTooShortError(
            f"path {path.name!r}: {seconds:.3g} s of motion ({how}): {e}"
        ) from None
    m = m.slice(0, min(m.num_frames, max(2, round(drawn * m.fps))))  # seconds at its rate
    if cut:
        arc = ground_track(m, body)["arc"]
        m = m.slice(
            0, max(2, min(m.num_frames, int(np.searchsorted(arc - arc[0], path.length)) + 1))
        )
    # at sampler.fps the raw draw is already raised; the clean-up's filter spans the same time
    from mrlib.sampling.cleanup import jitter_at

    jitter = jitter_at(m.fps, model.fps)
    return follow_path(m, path, clean=sampler.fix_contacts, body=body, jitter=jitter)
