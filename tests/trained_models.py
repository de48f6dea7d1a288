"""Recipes of the small trained models behind the tests of trained-model claims.

The tests (``test_control.py``) train each recipe once per module with training seed 0
and one torch thread; ``tests/trained_test_matrix.py`` trains the same recipes over
training seeds x torch thread counts, and their untrained or ablated negatives, and
prints the tested quantities, so an assertion is committed only where its margin holds
over that matrix (``docs/results.md`` has it).

Each claim is asserted on an aggregate over several crossover cases (both label orders,
two crossover levels): one case of one model is a coin with a bias, a mean over cases
is what holds on another machine's float kernels.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np

from mrlib.datasets.synthetic import synthetic_walk, synthetic_wave
from mrlib.evaluation.crossover import CrossoverOptions, crossover_evidence
from mrlib.model.config import ModelConfig, TrainConfig
from mrlib.model.presets import tutorial
from mrlib.model.trained import load_model
from mrlib.training.data import TrainingSet
from mrlib.training.trainer import train

# -- recipe 1: synthetic clips, coarse levels decide the low band ------------------------
SYNTHETIC_PAIRS = (
    ("walk_sad", "wave"),
    ("wave", "walk_sad"),
    ("walk_sad", "walk_happy"),
    ("walk_happy", "walk_sad"),
)
SYNTHETIC_LEVEL = 2


def synthetic_config(seed: int = 0, iterations: int = 300) -> TrainConfig:
    """4 levels, 300 iterations per block at lr 1e-3 (~25 s on one thread)."""
    return TrainConfig(
        model=ModelConfig(num_levels=4, gen_hidden=(48, 48), disc_hidden=(24, 24)),
        block_iterations=(iterations, iterations),
        n_critic=1,
        lr=1e-3,
        checkpoint_every=0,
        seed=seed,
    )


def synthetic_clips(body):
    return [
        synthetic_walk("walk_sad", seconds=4.0, fps=10.0, body=body),
        synthetic_walk("walk_happy", seconds=4.0, fps=10.0, body=body),
        synthetic_wave(seconds=3.6, fps=10.0, body=body),
    ]


def low_band_log_ratios(
    model, pairs=SYNTHETIC_PAIRS, level=SYNTHETIC_LEVEL, sampler=None
) -> np.ndarray:
    """``log(low_to_fine / low_to_coarse)`` per pair: > 0 where the crossover's low-pass
    band is nearer the coarse label's samples (drawn with ``sampler``, default raw)."""
    out = []
    opts = CrossoverOptions(sampler=sampler)
    for a, b in pairs:
        e = crossover_evidence(model, a, b, level, num_samples=4, seed=0, options=opts)
        out.append(np.log(e.low_to_fine / e.low_to_coarse))
    return np.asarray(out)


# -- recipe 2: two Bandai walks, the tutorial losses, both halves of the crossover ---------
DETAIL_FILES = ("dataset-1_walk_angry_001.bvh", "dataset-1_walk_sad_001.bvh")
DETAIL_CASES = tuple(
    (a, b, level)
    for a, b in (("walk_angry", "walk_sad"), ("walk_sad", "walk_angry"))
    for level in (2, 3, 4)
)


def detail_config(seed: int = 0, iterations: int = 300, detail: float | None = None) -> TrainConfig:
    """The ``tutorial`` preset (its losses include the detail-statistics term) at 6 levels
    and ``iterations`` per block; ``detail`` overrides the term's weight (0: ablated)."""
    t = tutorial()
    loss = t.loss if detail is None else dataclasses.replace(t.loss, detail=float(detail))
    return t.replace(
        model=dataclasses.replace(t.model, num_levels=6),
        block_iterations=(iterations,) * 3,
        checkpoint_every=0,
        seed=seed,
        loss=loss,
    )


_SHARED: dict = {}


def shared_detail_model(data_dir: Path, body, tmp_path_factory):
    """The recipe-2 model at training seed 0, trained once per test process and shared by
    the test files that use it (``test_control.py``, ``test_restyle.py``: one xdist
    group, see the root ``conftest.py``)."""
    if "detail" not in _SHARED:
        out = tmp_path_factory.mktemp("detail_model")
        _SHARED["detail"] = train_recipe(
            detail_clips(data_dir, body), detail_config(seed=0), out, body
        )
    return _SHARED["detail"]


def detail_clips(data_dir: Path, body):
    import mrlib

    return [mrlib.load_motion(Path(data_dir) / "data" / f, fps=15.0) for f in DETAIL_FILES]


def band_log_ratios(model, cases=DETAIL_CASES, sampler=None) -> np.ndarray:
    """``(len(cases), 2)``: per case, ``log(low_to_fine / low_to_coarse)`` (> 0: the low
    band is nearer A) and ``log(high_to_coarse / high_to_fine)`` (> 0: the residual is
    nearer B); samples drawn with ``sampler`` (default raw)."""
    out = []
    opts = CrossoverOptions(sampler=sampler)
    for a, b, level in cases:
        e = crossover_evidence(model, a, b, level, num_samples=4, seed=0, options=opts)
        out.append(
            (np.log(e.low_to_fine / e.low_to_coarse), np.log(e.high_to_coarse / e.high_to_fine))
        )
    return np.asarray(out)


# -- recipe 3: the reconstruction term alone ---------------------------------------------------
def reconstruction_config(seed: int = 3, iterations: int = 40) -> TrainConfig:
    """3 levels, reconstruction only, lr 1e-2, 40 iterations per block (seconds)."""
    from mrlib.model.config import LossWeights

    return TrainConfig(
        model=ModelConfig(num_levels=3, gen_hidden=(24, 24), disc_hidden=(24, 24)),
        block_iterations=(iterations, iterations),
        n_critic=0,
        lr=1e-2,
        checkpoint_every=0,
        log_every=20,
        seed=seed,
        loss=LossWeights(adv=0.0, con=0.0, rec=50.0, smooth=0.0),
    )


def reconstruction_clips():
    return [
        synthetic_walk(s, seconds=sec, fps=10.0, seed=k)
        for k, (s, sec) in enumerate([("walk_normal", 2.0), ("walk_happy", 2.6), ("walk_sad", 2.3)])
    ]


def reconstruction_errors(model) -> np.ndarray:
    from mrlib.sampling.generation import reconstruction_error

    return np.asarray([reconstruction_error(model, k) for k in range(len(model.clip_names))])


# -- training ---------------------------------------------------------------------------------
def train_recipe(clips, cfg: TrainConfig, out: str | os.PathLike, body, threads: int = 1):
    """Train ``cfg`` on ``clips`` with ``threads`` torch threads (restored afterwards)
    and return the loaded model."""
    from mrlib.threads import policy

    with policy(threads):  # explicit, so training keeps it whatever mrlib's default
        res = train(TrainingSet.from_motions(clips, body=body), cfg, out, body=body, progress=False)
    return load_model(res.checkpoint)


# -- recipe 4: restyling unseen Bandai walks (mrlib.sampling.restyling) with the recipe-2 model --------
RESTYLE_FILES = tuple(
    f"dataset-1_{kind}_{style}_{take}.bvh"
    for style in ("angry", "sad")
    for kind, take in (("walk", "002"), ("walk-left", "001"), ("walk-right", "001"))
)
RESTYLE_LEVELS = (3, 4)  # of the recipe's 6: the clip keeps levels 1..k


def restyle_inputs(data_dir: Path) -> dict:
    """Takes the recipe-2 model never saw, at 15 fps: the second takes and the side walks
    of the two styles, by file name (their own label is ``walk_<style>``)."""
    import mrlib

    return {f: mrlib.load_motion(Path(data_dir) / "data" / f, fps=15.0) for f in RESTYLE_FILES}


def restyle_log_ratios(model, inputs: dict, levels=RESTYLE_LEVELS, sampler=None) -> np.ndarray:
    """``(P, 2)`` over the (input, level) cases, the target the label the input is not:
    ``log(d_own / d_target)``, where ``d_l`` is the distance of the residual profile of
    the input restyled towards label ``l`` to the target's profile (> 0: restyling
    towards the target brings the residual nearer the target than the paired negative,
    the input restyled with its own label, does), and 1 where the restyled residual's
    nearest label is the target. Restyles and references are drawn with ``sampler``
    (default: the raw output)."""
    from mrlib.evaluation.restyle_evidence import restyle_evidence, restyle_references
    from mrlib.sampling.restyling import restyle
    from mrlib.sampling.sampler import raw_sampler

    sampler = raw_sampler(sampler)

    out = []
    for name, clip in inputs.items():
        own = "walk_" + name.split("_")[2]
        (target,) = [lab for lab in model.labels if lab != own]
        for level in levels:
            ref = restyle_references(model, clip.num_frames, level, num_samples=4, sampler=sampler)
            ev = {
                lab: restyle_evidence(
                    model, restyle(model, clip, lab, level, seed=0, sampler=sampler), clip, ref
                )
                for lab in (own, target)
            }
            d = ev[own].residual_to_labels[target] / ev[target].residual_to_labels[target]
            out.append((np.log(d), float(ev[target].nearest_label == target)))
    return np.asarray(out)
