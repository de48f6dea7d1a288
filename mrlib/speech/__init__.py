"""Co-speech gestures (paper, Sec. 6): speech in, per-level conditions of the
multi-resolution GAN, training, generation from audio, and measures of how motion follows
speech. Everything of speech lives in this package and is imported from here.

Pipeline::

    wav, sr = load_audio("talk.wav")                    # mono, 16 kHz
    extractor = SpeechFeatureExtractor()                # WavLM (or kind="logmel")
    data = SpeechTrainingSet.from_folders("talks/paired", "talks/unpaired", extractor)
    result = speech_train(data, mrlib.model.presets.speech_tutorial(), "runs/speech")
    model = load_speech_model(result.checkpoint)
    motion = generate_from_audio(model, "new_talk.wav", seed=0)
    sync = evaluate_speech_sync(model, [(wav, sr), ...])

Modules, in the order data flows: ``audio`` (I/O, resampling, spectra, energy envelope,
onsets), ``features`` (WavLM and the log-mel fallback), ``align`` (motion frame rate,
levels, residuals, normalisation), ``data`` (folders of paired and unpaired clips, the
training set, ``split_pair``), ``split`` (a training set with the utterances held out of
it), ``train`` (the trainer), ``sample`` (generation from audio),
``evaluate`` (hand speed, lagged correlation, beat alignment, synchrony of a model);
``beat2`` (a training set, or a split, from the BEAT2 files of ``mrlib.datasets.beat2`` in
one call); ``synthetic`` makes a labelled-synthetic co-speech set with eSpeak NG (``espeak``) and
rule-based gestures (``gestures``). The public names of ``audio``, ``features``,
``align``, ``sample`` and ``evaluate`` are all re-exported here; of the other modules,
their entry points.
"""

from mrlib.model.config import SPEECH_NUM_LEVELS
from mrlib.model.presets import speech_paper, speech_tutorial
from mrlib.speech import align, audio, evaluate, features, sample
from mrlib.speech.align import *  # noqa: F403 (its __all__, below)
from mrlib.speech.audio import *  # noqa: F403 (its __all__, below)
from mrlib.speech.beat2 import BEAT2_HELD_OUT, beat2_split, beat2_training_set
from mrlib.speech.data import (
    SPEECH_LABEL,
    SpeechClip,
    SpeechMotionPair,
    SpeechTrainingSet,
    load_paired_folder,
    load_unpaired_folder,
    split_pair,
)
from mrlib.speech.espeak import SpeechSynthesisError
from mrlib.speech.evaluate import *  # noqa: F403 (its __all__, below)
from mrlib.speech.features import *  # noqa: F403 (its __all__, below)
from mrlib.speech.gestures import GestureParams, load_base_motions, standing_base
from mrlib.speech.sample import *  # noqa: F403 (its __all__, below)
from mrlib.speech.split import HeldOutSpeech, SpeechSplit
from mrlib.speech.synthetic import (
    SyntheticCorpus,
    espeak_available,
    make_synthetic_pair,
    synthesize_speech,
    synthetic_corpus,
    synthetic_split,
)
from mrlib.speech.train import RANDOM_AUDIO, SpeechDraw, SpeechTrainer, speech_train

__all__ = [
    *audio.__all__,
    *features.__all__,
    # alignment
    "SPEECH_NUM_LEVELS",
    *align.__all__,
    # data
    "SPEECH_LABEL",
    "SpeechClip",
    "SpeechMotionPair",
    "load_paired_folder",
    "load_unpaired_folder",
    "SpeechTrainingSet",
    "HeldOutSpeech",
    "SpeechSplit",
    "split_pair",
    "BEAT2_HELD_OUT",
    "beat2_training_set",
    "beat2_split",
    # training
    "speech_paper",
    "speech_tutorial",
    "RANDOM_AUDIO",
    "SpeechDraw",
    "SpeechTrainer",
    "speech_train",
    # generation
    *sample.__all__,
    # evaluation
    *evaluate.__all__,
    # synthetic data
    "SpeechSynthesisError",
    "espeak_available",
    "synthesize_speech",
    "GestureParams",
    "standing_base",
    "load_base_motions",
    "make_synthetic_pair",
    "SyntheticCorpus",
    "synthetic_corpus",
    "synthetic_split",
]
