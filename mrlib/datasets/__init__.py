"""Data sets mrlib knows by name: the Bandai Namco Research Motion Dataset 1, fetched on
first use (``bandai``), five files of the BEAT2 co-speech dataset, likewise (``beat2``),
and procedural synthetic clips (``synthetic``); ``fetching`` holds their shared download
machinery.
"""

from mrlib.datasets.bandai import (
    NOTEBOOK_CLIPS,
    DataFetchError,
    bandai_dir,
    fetch_bandai,
    tutorial_clips,
)
from mrlib.datasets.beat2 import beat2_dir, beat2_speech_folders, fetch_beat2
from mrlib.datasets.synthetic import synthetic_dataset, synthetic_walk, synthetic_wave

__all__ = [
    "tutorial_clips",
    "fetch_bandai",
    "bandai_dir",
    "NOTEBOOK_CLIPS",
    "DataFetchError",
    "beat2_dir",
    "fetch_beat2",
    "beat2_speech_folders",
    "synthetic_walk",
    "synthetic_wave",
    "synthetic_dataset",
]
