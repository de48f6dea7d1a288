"""Conditions: what drives each level of the generator (paper Sec. 3.1-3.2, 4.3).

The generator reads a control signal ``s`` at every level. For a label model that signal
is a mix of one-hot labels per level, the ``(L, K)`` matrix :meth:`Condition.weights`
returns: row ``i`` drives level ``i + 1`` (levels are 1-based here, level 1 the coarsest,
as in the paper). One value, :class:`Condition`, says which mix:

* ``Condition.label("walk_happy")``: the same label at every level (a plain string or
  index means this wherever a condition is taken);
* ``Condition.crossover("walk_normal", "walk_happy", level=4)``: the paper's style mixing
  (Sec. 4.3) at crossover level 4: levels ``1 .. level`` follow the first label,
  ``level+1 .. L`` the second, so the coarse motion comes from one label and the detail
  from the other (the crossover level of ``mrlib.evaluation.crossover`` and of training's
  random crossovers, :func:`crossover_table`);
* ``Condition.levels([("walk_normal", (1, 4)), ("walk_happy", (5, 8))])``: any
  assignment of labels to level ranges that covers every level once;
* ``Condition.blend("walk_normal", "walk_happy", 0.3)``: ``(1 - w) a + w b`` per level
  (the FiLM embedding is linear in ``s``, so this interpolates embeddings);
* ``Condition.parts({"upper": "walk_happy", "lower": "walk_sad"})``: a label per body
  part, the parts of samples of each label spliced into one motion
  (``mrlib.sampling.constraints.generate_parts`` takes it); it has no one label mix per
  level.

Training draws its random crossovers with :func:`crossover_table` (the same rule for a
batch of draws). Speech conditions are per-frame features rather than label weights
(``mrlib.speech``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import torch

from mrlib.errors import MotionValueError, is_whole

__all__ = ["Condition", "as_condition", "crossover_table", "label_weights"]

Label = str | int


def _check_label(label) -> Label:
    if isinstance(label, bool) or not isinstance(label, (str, int, np.integer)):
        raise MotionValueError(f"a label is a name or an index, got {label!r}")
    return label if isinstance(label, str) else int(label)


@dataclass(frozen=True)
class Condition:
    """Labels per level range, a blend of two labels, or a label per body part (see the
    module docstring).

    ``ranges`` holds ``(label, first, last)`` with 1-based inclusive levels, ``last`` None
    for "to the finest level"; ``blend_of`` holds ``(a, b, w)`` with ``w`` one weight or one
    per level; ``parts_of`` holds ``(part, label)`` pairs and ``in_step`` whether the
    other parts follow the gait of the part holding the pelvis. Build it with the class
    methods, not the fields.
    """

    ranges: tuple[tuple[Label, int, int | None], ...] = ()
    blend_of: tuple[Label, Label, tuple[float, ...]] | None = None
    parts_of: tuple[tuple[str | tuple, Label], ...] | None = None
    in_step: bool = False

    @classmethod
    def label(cls, label: Label) -> Condition:
        """One label at every level."""
        return cls(ranges=((_check_label(label), 1, None),))

    @classmethod
    def crossover(cls, coarse: Label, fine: Label, level: int) -> Condition:
        """``coarse`` at levels ``1 .. level``, ``fine`` at ``level+1 .. L`` (the crossover
        level, ``1 <= level <= L - 1``)."""
        if isinstance(level, bool) or not isinstance(level, (int, np.integer)) or level < 1:
            raise MotionValueError(f"a crossover level is a whole number >= 1, got {level!r}")
        level = int(level)
        return cls(ranges=((_check_label(coarse), 1, level), (_check_label(fine), level + 1, None)))

    @classmethod
    def levels(cls, assignment: Sequence[tuple[Label, tuple[int, int]]]) -> Condition:
        """Labels assigned to 1-based inclusive level ranges that together cover every
        level once: ``[("walk_normal", (1, 4)), ("walk_happy", (5, 8))]``."""
        try:
            if isinstance(assignment, (str, bytes)) or any(
                isinstance(r, (str, bytes)) for _, r in assignment
            ):  # "18" would unpack as (1, 8)
                raise TypeError
            ranges = tuple((_check_label(lab), lo, hi) for lab, (lo, hi) in assignment)
            if not all(is_whole(v) for _, lo, hi in ranges for v in (lo, hi)):
                raise TypeError
            ranges = tuple((lab, int(lo), int(hi)) for lab, lo, hi in ranges)
        except (TypeError, ValueError):
            raise MotionValueError(
                f"levels take [(label, (first, last)), ...], got {assignment!r}"
            ) from None
        if not ranges:
            raise MotionValueError("levels need at least one (label, (first, last)) pair")
        return cls(ranges=ranges)

    @classmethod
    def blend(cls, a: Label, b: Label, weight: float | Sequence[float]) -> Condition:
        """``(1 - w) a + w b`` at every level, ``w`` in [0, 1], one value or one per level."""
        try:
            if np.asarray(weight).dtype.kind not in "iuf":  # True, "0.5", []: not weights
                raise TypeError
            w = np.atleast_1d(np.asarray(weight, dtype=float)).reshape(-1)
        except (TypeError, ValueError):
            raise MotionValueError(
                f"blend weights must be numbers in [0, 1], got {weight!r}"
            ) from None
        if w.size == 0:
            raise MotionValueError("blend weights: give one weight, or one per level, got none")
        if not np.isfinite(w).all() or ((w < 0) | (w > 1)).any():
            raise MotionValueError(
                f"blend weights must be in [0, 1], got {np.asarray(weight).tolist()}; to "
                "exaggerate a label beyond its clips use the sampler's guidance"
            )
        return cls(blend_of=(_check_label(a), _check_label(b), tuple(float(x) for x in w)))

    @classmethod
    def parts(cls, assignment: Mapping, *, in_step: bool = False) -> Condition:
        """A label per body part, ``{"upper": "walk_happy", "lower": "walk_sad"}`` (a part:
        a name of ``mrlib.sampling.constraints.PARTS``, a joint name, or a tuple of joints;
        joints no part names go with the part holding the pelvis). ``in_step``: the other
        parts are taken from samples retimed to the gait of the part holding the pelvis,
        so that the arms swing in step with the legs
        (``mrlib.sampling.constraints.compose``)."""
        if not isinstance(assignment, Mapping) or not assignment:
            raise MotionValueError(
                "parts take a dict {part: label}, e.g. {'upper': 'walk_happy', 'lower': "
                f"'walk_sad'}}, got {assignment!r}"
            )
        pairs = []
        for part, label in assignment.items():
            if not isinstance(part, (str, tuple)):
                raise MotionValueError(f"a body part is a name or a tuple of joints, got {part!r}")
            pairs.append((part, _check_label(label)))
        if not isinstance(in_step, bool):
            raise MotionValueError(f"in_step must be True or False, got {in_step!r}")
        return cls(parts_of=tuple(pairs), in_step=in_step)

    def part_labels(self) -> dict:
        """``{part: label}`` of a body-part condition (:meth:`parts`)."""
        if self.parts_of is None:
            raise MotionValueError("not a body-part condition (Condition.parts)")
        return dict(self.parts_of)

    def weights(self, model) -> torch.Tensor:
        """``(L, K)`` label weights of this condition for ``model`` (its ``num_levels``,
        ``labels`` and ``label_index``): row ``i`` is the condition vector of level i+1."""
        if self.parts_of is not None:
            raise MotionValueError(
                "a body-part condition has no one label mix per level: each part's samples "
                "have their own (Condition.label of the part's label)"
            )
        L, K = model.num_levels, len(model.labels)
        W = torch.zeros(L, K)
        if self.blend_of is not None:
            a, b, w = self.blend_of
            wt = torch.tensor(w, dtype=torch.float32)
            if wt.numel() == 1:
                wt = wt.expand(L)
            if wt.numel() != L:
                raise MotionValueError(f"blend weights need 1 or {L} values, got {wt.numel()}")
            W[:, model.label_index(a)] += 1 - wt
            W[:, model.label_index(b)] += wt
            return W
        covered = np.zeros(L, int)
        for lab, lo, hi in self.ranges:
            if hi is None and lo > L:  # a crossover at the finest level or beyond
                raise MotionValueError(
                    f"crossover level {lo - 1}: this model's levels 1..{L} take a crossover "
                    f"level from 1 to {L - 1}"
                )
            hi = L if hi is None else hi
            if not 1 <= lo <= hi <= L:
                raise MotionValueError(
                    f"level range ({lo}, {hi}) must satisfy 1 <= lo <= hi <= {L}"
                )
            W[lo - 1 : hi, model.label_index(lab)] = 1
            covered[lo - 1 : hi] += 1
        if not (covered == 1).all():
            raise MotionValueError(
                f"level ranges must cover levels 1..{L} exactly once, coverage {covered.tolist()}"
            )
        return W

    def name(self, model) -> str:
        """The label a sample of this condition carries: the label's name for one label
        at every level, else the names of the labels in use joined by ``+``; for body
        parts ``"upper=walk_happy,lower=walk_sad"``."""
        if self.parts_of is not None:
            return ",".join(f"{p}={c}" for p, c in self.parts_of)
        W = self.weights(model)
        used = (W > 0).any(0).nonzero().flatten().tolist()
        # in the order they enter, coarse to fine; at one level the heavier first
        first = {k: int((W[:, k] > 0).nonzero()[0]) for k in used}
        used.sort(key=lambda k: (first[k], -float(W[first[k], k]), k))
        return "+".join(model.labels[k] for k in used)


def as_condition(value) -> Condition:
    """``value`` as a :class:`Condition`: a label name or index is ``Condition.label``."""
    if isinstance(value, Condition):
        return value
    if isinstance(value, (str, int, np.integer)) and not isinstance(value, bool):
        return Condition.label(value)
    raise MotionValueError(
        f"a condition is a label name, a label index or a mrlib.Condition, got {value!r}"
    )


def label_weights(model, condition) -> torch.Tensor:
    """``(L, K)`` label weights of ``condition`` (a label or a :class:`Condition`)."""
    return as_condition(condition).weights(model)


def crossover_table(
    coarse: torch.Tensor, fine: torch.Tensor, level: torch.Tensor, num_levels: int
) -> tuple[torch.Tensor, torch.Tensor]:
    """Crossovers of a batch (training's style mixing): sample ``b`` follows label
    ``coarse[b]`` below 0-based level ``level[b]`` and ``fine[b]`` from it on.

    Returns ``(table, fine_levels)``: ``(B, L)`` the label index of every level and
    ``(B, L)`` bool, True where a level follows ``fine``."""
    fine_levels = torch.arange(num_levels)[None] >= level[:, None]
    return torch.where(fine_levels, fine[:, None], coarse[:, None]), fine_levels
