"""Reference code of following a path by the noise alone, the alternative to bending that
``mrlib.sampling.constraints.path`` had as ``generate_on_path(..., method="optimise")``,
kept for ``bench/constraints.py --only path``, which measures it against the default.

The noise maps are moved with the networks frozen (``mrlib.sampling.constraints.optimise``)
until the pelvis follows the path at the condition's pace (or the path's times), with no
bending. A model trained on a few straight walks never turns by itself, so what the noise
can reach stays near its own walk: on the Bandai walks the pelvis stayed metres off a
circle or a figure-eight where bending keeps it within centimetres, at seconds per sample
(``docs/notes/2026-12-06-study-options.md``).

Not maintained as a claim: the benchmark imports it (``from experiments.path_optimise
import generate_on_path_optimised``, with ``bench/`` on the path as when a benchmark runs).
"""

from __future__ import annotations

import numpy as np
import torch

from mrlib.representation.body import resolve_body
from mrlib.representation.motion import Motion
from mrlib.sampling.constraints import NoiseFit, natural_pace, parse_path, path_seconds
from mrlib.sampling.constraints.common import fitted_motion, label_setup, pelvis_rest, planted
from mrlib.sampling.constraints.optimise import decode
from mrlib.sampling.sampler import Sampler

PATH_FIT = NoiseFit(steps=150)  # the fit of generate_on_path(..., steps=150)


def generate_on_path_optimised(
    model, path, condition=None, *, seconds: float | None = None, seed: int | None = None,
    fit: NoiseFit = PATH_FIT, sampler=None, body=None,
) -> Motion:  # fmt: skip
    """A motion of a label model that walks ``path`` (a ``GroundPath`` or a spec such as
    ``"circle:2"``) by the noise fit alone (module docstring; ``fit``: its Adam steps);
    ``seconds`` and ``sampler`` as ``generate_on_path``'s."""
    sampler = Sampler() if sampler is None else sampler
    path = parse_path(path)
    pace = None
    if seconds is None:
        seconds, pace = path_seconds(model, path, condition, sampler=sampler)
    length = max(2, round(seconds * model.fps))
    body = resolve_body(body, shared=True)
    noises, conds, label, _ = label_setup(model, condition, length, seed, sampler)
    t = np.arange(length) / model.fps
    if path.times is not None:
        s = path.arc_at_time(t)
    else:
        pace = pace or natural_pace(model, condition, sampler=sampler)
        s = pace * t
    xz = path.at(s)[0]
    # decoded translations start at the origin: ask for the path's steps from its start
    target = torch.from_numpy(xz - xz[0]).float().to(model.device)  # (T, 2)

    def loss_fn(x: torch.Tensor) -> torch.Tensor:
        return (decode(model, x)["trans"][0, :, [0, 2]] - target).pow(2).sum(-1).mean()

    m = fitted_motion(model, noises, conds, label, f"{label}_path_seed{seed}", loss_fn, fit)
    m = planted(m, sampler, body)
    # the path starts where the pelvis starts: move the motion there
    trans = m.trans.astype(np.float64).copy()
    trans[:, [0, 2]] += xz[0] - trans[0, [0, 2]] - pelvis_rest(m, body)[[0, 2]]
    return m.replace(trans=trans, meta=dict(m.meta, path={"name": path.name, "method": "optimise"}))
