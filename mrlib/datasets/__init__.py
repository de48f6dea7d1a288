"""Data sets mrlib knows by name: the Bandai Namco Research Motion Dataset 1, fetched on
first use (``bandai``), and procedural synthetic clips (``synthetic``).
"""

from mrlib.datasets.bandai import (
    NOTEBOOK_CLIPS,
    DataFetchError,
    bandai_dir,
    fetch_bandai,
    tutorial_clips,
)
from mrlib.datasets.synthetic import synthetic_dataset, synthetic_walk, synthetic_wave

__all__ = [
    "tutorial_clips",
    "fetch_bandai",
    "bandai_dir",
    "NOTEBOOK_CLIPS",
    "DataFetchError",
    "synthetic_walk",
    "synthetic_wave",
    "synthetic_dataset",
]
