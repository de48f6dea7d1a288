"""Co-speech gestures (paper, Sec. 6): speech in, per-level conditions of the
multi-resolution GAN, training, generation from audio, and measures of how motion follows
speech. Everything of speech lives in this package and is imported from here.

Pipeline::

    wav, sr = load_audio("talk.wav")                    # mono, 16 kHz
    extractor = SpeechFeatureExtractor()                # WavLM (or kind="logmel")
    data = SpeechTrainingSet.from_folders("talks/paired", "talks/unpaired", extractor)
    result = speech_train(data, mrlib.model.config.speech_tutorial(), "runs/speech")
    model = load_speech_model(result.checkpoint)
    motion = generate_from_audio(model, "new_talk.wav", seed=0)
    sync = evaluate_speech_sync(model, [(wav, sr), ...])

Modules, in the order data flows: ``audio`` (I/O, resampling, spectra, energy envelope,
onsets), ``features`` (WavLM and the log-mel fallback), ``align`` (motion frame rate,
levels, residuals, normalisation), ``data`` (folders of paired and unpaired clips, the
training set), ``train`` (the trainer), ``sample`` (generation from audio),
``evaluate`` (hand speed, lagged correlation, beat alignment, synchrony of a model);
``beat2`` (a training set from the BEAT2 files of ``mrlib.datasets.beat2`` in one call);
``synthetic`` makes a labelled-synthetic co-speech set with eSpeak NG (``espeak``) and
rule-based gestures (``gestures``).
"""

from mrlib.model.config import SPEECH_NUM_LEVELS, speech_paper, speech_tutorial
from mrlib.speech.align import (
    SpeechNormalizer,
    align_to_levels,
    downsample_levels,
    interpolate_to_fps,
    level_lengths,
    levels_to_residuals,
    motion_frames_for_audio,
    residuals_to_levels,
    speech_conditions,
    stack_conditions,
)
from mrlib.speech.audio import (
    FEATURE_FPS,
    FRAME_OFFSET_S,
    HOP,
    SAMPLE_RATE,
    WINDOW,
    AudioFileError,
    detect_onsets,
    energy_envelope,
    fit_audio_length,
    load_audio,
    log_mel_spectrogram,
    mel_filterbank,
    num_feature_frames,
    onset_strength,
    resample_audio,
    to_mono,
)
from mrlib.speech.beat2 import BEAT2_HELD_OUT, beat2_training_set
from mrlib.speech.data import (
    SPEECH_LABEL,
    SpeechClip,
    SpeechMotionPair,
    SpeechTrainingSet,
    load_paired_folder,
    load_unpaired_folder,
)
from mrlib.speech.espeak import SpeechSynthesisError
from mrlib.speech.evaluate import (
    LaggedCorrelation,
    SyncResult,
    beat_alignment_score,
    evaluate_speech_sync,
    hand_speed,
    lagged_correlation,
    motion_beats,
    phrase_loudness,
    speech_motion_correlation,
    wrist_lift,
)
from mrlib.speech.features import (
    WAVLM_PATH_ENV,
    SpeechFeatureConfig,
    SpeechFeatureExtractor,
    SpeechModelError,
    autocorrelation_pitch,
    load_wavlm,
    log_mel_channel_names,
    log_mel_features,
    wavlm_features,
)
from mrlib.speech.gestures import GestureParams, load_base_motions, standing_base
from mrlib.speech.sample import (
    SpeechModel,
    audio_conditions,
    generate_from_audio,
    generate_levels_from_audio,
    generate_many_from_audio,
    is_speech_checkpoint,
    load_speech_model,
    speech_model_from_trainer,
)
from mrlib.speech.synthetic import (
    SyntheticCorpus,
    espeak_available,
    make_synthetic_pair,
    synthesize_speech,
    synthetic_corpus,
)
from mrlib.speech.train import RANDOM_AUDIO, SpeechDraw, SpeechTrainer, speech_train

__all__ = [
    # audio
    "SAMPLE_RATE",
    "HOP",
    "WINDOW",
    "FEATURE_FPS",
    "FRAME_OFFSET_S",
    "AudioFileError",
    "load_audio",
    "to_mono",
    "resample_audio",
    "fit_audio_length",
    "num_feature_frames",
    "mel_filterbank",
    "log_mel_spectrogram",
    "energy_envelope",
    "onset_strength",
    "detect_onsets",
    # features
    "WAVLM_PATH_ENV",
    "SpeechModelError",
    "autocorrelation_pitch",
    "log_mel_features",
    "log_mel_channel_names",
    "load_wavlm",
    "wavlm_features",
    "SpeechFeatureConfig",
    "SpeechFeatureExtractor",
    # alignment
    "SPEECH_NUM_LEVELS",
    "interpolate_to_fps",
    "downsample_levels",
    "align_to_levels",
    "levels_to_residuals",
    "level_lengths",
    "residuals_to_levels",
    "SpeechNormalizer",
    "speech_conditions",
    "motion_frames_for_audio",
    "stack_conditions",
    # data
    "SPEECH_LABEL",
    "SpeechClip",
    "SpeechMotionPair",
    "load_paired_folder",
    "load_unpaired_folder",
    "SpeechTrainingSet",
    "BEAT2_HELD_OUT",
    "beat2_training_set",
    # training
    "speech_paper",
    "speech_tutorial",
    "RANDOM_AUDIO",
    "SpeechDraw",
    "SpeechTrainer",
    "speech_train",
    # generation
    "SpeechModel",
    "load_speech_model",
    "speech_model_from_trainer",
    "is_speech_checkpoint",
    "audio_conditions",
    "generate_from_audio",
    "generate_many_from_audio",
    "generate_levels_from_audio",
    # evaluation
    "hand_speed",
    "motion_beats",
    "LaggedCorrelation",
    "lagged_correlation",
    "speech_motion_correlation",
    "beat_alignment_score",
    "wrist_lift",
    "phrase_loudness",
    "SyncResult",
    "evaluate_speech_sync",
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
]
