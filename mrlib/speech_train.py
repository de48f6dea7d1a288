"""Deprecated: moved to :mod:`mrlib.speech` (``train``, ``sample``, ``evaluate``, ``data``;
the presets to :mod:`mrlib.config`). Import from ``mrlib.speech`` instead."""

import warnings

from mrlib.config import speech_paper, speech_tutorial  # noqa: F401
from mrlib.speech.audio import fit_audio_length  # noqa: F401
from mrlib.speech.data import SPEECH_LABEL, SpeechTrainingSet  # noqa: F401
from mrlib.speech.evaluate import (  # noqa: F401
    SyncResult,
    evaluate_speech_sync,
    phrase_loudness,
    wrist_lift,
)
from mrlib.speech.sample import (  # noqa: F401
    SpeechModel,
    audio_conditions,
    generate_from_audio,
    is_speech_checkpoint,
    load_speech_model,
    speech_model_from_trainer,
)
from mrlib.speech.train import (  # noqa: F401
    RANDOM_AUDIO,
    SpeechDraw,
    SpeechTrainer,
    residual_operators,
    speech_train,
)

warnings.warn(
    "mrlib.speech_train is deprecated and will be removed; import from mrlib.speech",
    DeprecationWarning,
    stacklevel=2,
)
