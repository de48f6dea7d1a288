"""The speech side of co-speech gesture synthesis (paper, Sec. 6): audio to the per-level
conditions of the multi-resolution GAN, and measures of how motion follows speech.

Pipeline for one clip::

    wav, sr = load_audio("talk.wav")                    # mono, 16 kHz
    extractor = SpeechFeatureExtractor()                # WavLM (or kind="logmel")
    feats = extractor(wav, sr)                          # (T_a, D) at 50 fps
    norm = SpeechNormalizer.fit([feats, ...])           # over all training audio
    conds = speech_conditions(feats, extractor.fps, motion_fps=25, lengths=lengths,
                              normalizer=norm, offset_s=extractor.frame_offset_s)
    # conds: [(T_1, D), ..., (T_L, D)], L = 10; s_1 absolute, s_i residual for i > 1

Modules: ``audio`` (I/O, resampling, energy envelope, onsets), ``features`` (WavLM and
the log-mel fallback), ``align`` (levels, residuals, normalisation, batching),
``evaluate`` (hand speed, lagged correlation, beat alignment).
"""

from mrlib.speech.align import (
    SPEECH_NUM_LEVELS,
    SpeechNormalizer,
    align_to_levels,
    downsample_levels,
    interpolate_to_fps,
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
    load_audio,
    num_feature_frames,
    onset_strength,
    resample_audio,
    to_mono,
)
from mrlib.speech.evaluate import (
    LaggedCorrelation,
    beat_alignment_score,
    hand_speed,
    lagged_correlation,
    motion_beats,
    speech_motion_correlation,
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
    log_mel_spectrogram,
    mel_filterbank,
    wavlm_features,
)

__all__ = [
    "SAMPLE_RATE",
    "HOP",
    "WINDOW",
    "FEATURE_FPS",
    "FRAME_OFFSET_S",
    "SPEECH_NUM_LEVELS",
    "WAVLM_PATH_ENV",
    "AudioFileError",
    "SpeechModelError",
    "load_audio",
    "to_mono",
    "resample_audio",
    "num_feature_frames",
    "energy_envelope",
    "onset_strength",
    "detect_onsets",
    "mel_filterbank",
    "log_mel_spectrogram",
    "autocorrelation_pitch",
    "log_mel_features",
    "log_mel_channel_names",
    "load_wavlm",
    "wavlm_features",
    "SpeechFeatureConfig",
    "SpeechFeatureExtractor",
    "interpolate_to_fps",
    "downsample_levels",
    "align_to_levels",
    "levels_to_residuals",
    "residuals_to_levels",
    "SpeechNormalizer",
    "speech_conditions",
    "motion_frames_for_audio",
    "stack_conditions",
    "hand_speed",
    "motion_beats",
    "LaggedCorrelation",
    "lagged_correlation",
    "speech_motion_correlation",
    "beat_alignment_score",
]
