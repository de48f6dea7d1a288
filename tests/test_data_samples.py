"""data_samples/ must be exactly what tools/make_data_samples.py produces."""

from pathlib import Path

import numpy as np
import pytest

from mrlib.datasets.synthetic import STYLES, synthetic_dataset
from mrlib.io import load_motion

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def regenerated():
    return {m.label: m for m in synthetic_dataset()}


@pytest.mark.parametrize("label", [*STYLES, "wave"])
def test_samples_match_the_generator(label, regenerated):
    m = load_motion(ROOT / "data_samples" / f"{label}.npz")
    g = regenerated[label]
    assert m.label == label and m.fps == g.fps and m.num_frames == g.num_frames
    assert np.allclose(m.poses, g.poses, atol=1e-5) and np.allclose(m.trans, g.trans, atol=1e-5)


def test_walks_move_forward_and_wave_stays(regenerated):
    for label, m in regenerated.items():
        speed = np.linalg.norm(np.diff(m.trans[:, [0, 2]], axis=0), axis=1).mean() * m.fps
        if label.startswith("walk"):
            assert 0.3 < speed < 2.5 and m.trans[-1, 2] > m.trans[0, 2] + 2.0
        else:
            assert speed < 0.05
