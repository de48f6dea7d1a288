"""Deprecated: moved to :mod:`mrlib.speech` (``synthetic`` for the synthetic set, ``data``
for the folder loaders). Import from ``mrlib.speech`` instead."""

import warnings

from mrlib.speech.data import (  # noqa: F401
    AUDIO_EXTENSIONS,
    MOTION_EXTENSIONS,
    SpeechClip,
    SpeechMotionPair,
    load_paired_folder,
    load_unpaired_folder,
)
from mrlib.speech.synthetic import *  # noqa: F401,F403
from mrlib.speech.synthetic import J  # noqa: F401

warnings.warn(
    "mrlib.speech_data is deprecated and will be removed; import from mrlib.speech",
    DeprecationWarning,
    stacklevel=2,
)
