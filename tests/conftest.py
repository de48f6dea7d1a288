"""Shared fixtures.

``pinned_torch`` (autouse) pins what a test of a trained model depends on: one torch
thread, PyTorch's deterministic algorithms, and the global seeds, so a test sees the
same numbers on every run on one machine. A trained-model claim must also hold on
other machines, whose float kernels differ; ``bench/trained_test_matrix.py`` checks
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
    from mrlib.body import load_body_model

    return load_body_model()
