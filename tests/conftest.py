"""Shared fixtures.

``body`` / ``default_body``: the default body model, loaded once per session.
``plumbing_model``: a factory of small models trained for two iterations per block, whose
samples mean nothing; for tests of what sampling, conditions and measurements do with a
model, not of what a model learns.

``pinned_torch`` (autouse) pins what a test of a trained model depends on: one torch
thread, PyTorch's deterministic algorithms, and the global seeds, so a test sees the
same numbers on every run on one machine. A trained-model claim must also hold on
other machines, whose float kernels differ; ``tests/trained_test_matrix.py`` checks
each such claim over training seeds x thread counts before it is asserted.
"""

from __future__ import annotations

import random

import numpy as np
import pytest
import torch


@pytest.fixture(autouse=True)
def pinned_torch():
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    torch.use_deterministic_algorithms(True, warn_only=True)
    torch.manual_seed(0)
    np.random.seed(0)
    random.seed(0)
    yield
    torch.set_num_threads(threads)


@pytest.fixture(scope="session")
def default_body():
    """The default body model, loaded once per test session."""
    from mrlib.representation.body import load_body_model

    return load_body_model()


@pytest.fixture(scope="session")
def body(default_body):
    """The default body model (the same object as ``default_body``)."""
    return default_body


@pytest.fixture(scope="session")
def plumbing_model(tmp_path_factory, default_body):
    """``make(clips, name) -> GenerativeModel``: 4 levels of 24-channel networks, two
    iterations per block, one critic step; trained once per name and session."""
    from mrlib.model.config import ModelConfig, TrainConfig
    from mrlib.model.trained import load_model
    from mrlib.training.data import TrainingSet
    from mrlib.training.trainer import train

    cfg = TrainConfig(
        model=ModelConfig(num_levels=4, gen_hidden=(24, 24), disc_hidden=(24, 24)),
        block_iterations=(2, 2),
        n_critic=1,
        checkpoint_every=0,
    )
    made = {}

    def make(clips, name: str):
        if name not in made:
            torch.set_num_threads(1)
            out = tmp_path_factory.mktemp(f"plumbing_{name}")
            res = train(
                TrainingSet.from_motions(clips), cfg, out, body=default_body, progress=False
            )
            made[name] = load_model(res.checkpoint)
            # its choice of contact reading, on noise-like samples, could differ between
            # CPUs: the plumbing models read every label at 0.5, the paper's cut
            made[name].contact_at_rate = ()
        return made[name]

    make.config = cfg
    return make


@pytest.fixture(scope="session")
def sad_wave_clips(default_body):
    """Two synthetic clips at 10 fps: a sad walk (4 s) and a wave (3.6 s)."""
    from mrlib.datasets.synthetic import synthetic_walk, synthetic_wave

    return [
        synthetic_walk("walk_sad", seconds=4.0, fps=10.0, body=default_body),
        synthetic_wave(seconds=3.6, fps=10.0, body=default_body),
    ]


@pytest.fixture(scope="session")
def sad_wave_model(plumbing_model, sad_wave_clips):
    """A plumbing model of ``sad_wave_clips`` (two iterations per block): its samples
    mean nothing."""
    return plumbing_model(sad_wave_clips, "walk_sad_wave")


@pytest.fixture(scope="session")
def normal_sad_model(plumbing_model):
    """A plumbing model of a normal (3 s) and a sad (3.6 s) synthetic walk at 10 fps (two
    iterations per block): its samples mean nothing."""
    from mrlib.datasets.synthetic import synthetic_walk

    clips = [
        synthetic_walk(s, seconds=sec, fps=10.0)
        for s, sec in [("walk_normal", 3.0), ("walk_sad", 3.6)]
    ]
    return plumbing_model(clips, "walk_normal_sad")
