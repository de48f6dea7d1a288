"""Audio in, simple signals out: reading, mono mixdown, resampling to 16 kHz, the energy
envelope at a motion frame rate, spectral-flux onset strength and onsets.

Waveforms are float32 numpy arrays ``(N,)`` in [-1, 1] at ``SAMPLE_RATE`` (16 kHz, what
WavLM was trained on) unless a function takes ``sr`` explicitly. Frame conventions shared
by every speech feature in mrlib (WavLM's convolutional front end fixes them):

* window ``WINDOW = 400`` samples (25 ms), hop ``HOP = 320`` samples (20 ms): 50 fps;
* a clip of ``N >= 400`` samples has ``(N - 400) // 320 + 1`` frames;
* frame ``k`` covers samples ``[320 k, 320 k + 400)``, its centre is at
  ``k / 50 + FRAME_OFFSET_S`` seconds with ``FRAME_OFFSET_S = 12.5 ms``.
"""

from __future__ import annotations

import numbers
from math import gcd
from pathlib import Path

import numpy as np
import torch
from scipy.ndimage import gaussian_filter1d
from scipy.signal import find_peaks, resample_poly

from mrlib.errors import ClipTooShortError, MotionFileError, MotionValueError, is_whole

__all__ = [
    "as_float_samples",
    "check_rate",
    "SAMPLE_RATE",
    "HOP",
    "WINDOW",
    "FEATURE_FPS",
    "FRAME_OFFSET_S",
    "MIN_INPUT_RATE",
    "MAX_AUDIO_SECONDS",
    "AudioFileError",
    "audio_duration",
    "check_audio_seconds",
    "load_audio",
    "to_mono",
    "resample_audio",
    "check_waveform",
    "num_feature_frames",
    "frame_signal",
    "fit_audio_length",
    "mel_filterbank",
    "log_mel_spectrogram",
    "energy_envelope",
    "onset_strength",
    "detect_onsets",
]

SAMPLE_RATE = 16_000
HOP = 320
WINDOW = 400
FEATURE_FPS = SAMPLE_RATE / HOP  # 50.0
FRAME_OFFSET_S = WINDOW / 2 / SAMPLE_RATE  # 0.0125 s: centre of frame 0
# Below this rate speech loses the 4-8 kHz band that WavLM (trained on 16 kHz) expects;
# upsampling cannot restore it, so such files are refused rather than silently degraded.
MIN_INPUT_RATE = 8_000
# One utterance: its features, conditions and the motion generated for it are held whole
# (~1.5 GB for 10 minutes). Longer recordings are refused from their header, before reading.
MAX_AUDIO_SECONDS = 600.0


class AudioFileError(MotionFileError):
    """An audio file is missing, unreadable, or unsuitable (rate, length)."""


# -- reading and resampling ---------------------------------------------------------------
MAX_CHANNELS = 8  # a 2-D array with at most this many rows and more columns is (channels, N)


def as_float_samples(wav) -> np.ndarray:
    """Samples as float32 in [-1, 1]: integer PCM (what ``scipy.io.wavfile.read``
    returns) scaled by its type's range (unsigned 8-bit about 128), floats as they are;
    ``(channels, N)`` (torchaudio's layout) turned to ``(N, channels)``."""
    a = np.asarray(wav)
    if a.dtype.kind == "b" or a.dtype.kind not in "iuf":
        raise MotionValueError(f"audio samples must be numbers, got {a.dtype} values")
    if a.dtype.kind in "iu":
        info = np.iinfo(a.dtype)
        mid = (int(info.max) + int(info.min) + 1) / 2  # 128 for uint8, 0 for signed
        a = (a.astype(np.float64) - mid) / (int(info.max) + 1 - mid)
    if a.ndim == 2 and a.shape[0] <= MAX_CHANNELS < a.shape[1]:
        a = a.T
    return a.astype(np.float32)


def to_mono(wav: np.ndarray) -> np.ndarray:
    """Average the channels: ``(N,)``, ``(N, channels)`` or ``(channels, N)`` (up to
    ``MAX_CHANNELS``) -> ``(N,)`` float32; integer PCM scaled to [-1, 1]."""
    wav = as_float_samples(wav)
    if wav.ndim == 2:
        wav = wav.mean(axis=1)
    if wav.ndim != 1:
        raise MotionValueError(f"audio must be (N,) or (N, channels), got shape {wav.shape}")
    return wav


def check_rate(sr, what: str = "sr") -> int:
    """``sr`` as a whole number of Hz from ``MIN_INPUT_RATE`` on, else a ``MotionValueError``."""
    if not is_whole(sr, integral_floats=True) or sr < MIN_INPUT_RATE:
        raise MotionValueError(
            f"{what} must be the sample rate in Hz, a whole number from {MIN_INPUT_RATE} on, "
            f"got {sr!r}"
        )
    return int(sr)


def resample_audio(wav: np.ndarray, sr_in: int, sr_out: int = SAMPLE_RATE) -> np.ndarray:
    """Polyphase resampling ``(N,)`` -> ``(round(N * sr_out / sr_in),)`` float32
    (``scipy.signal.resample_poly`` with its default Kaiser anti-aliasing filter)."""
    sr_in, sr_out = int(sr_in), int(sr_out)
    if sr_in <= 0 or sr_out <= 0:
        raise MotionValueError(f"sample rates must be positive, got {sr_in} -> {sr_out}")
    wav = np.asarray(wav, dtype=np.float32)
    if sr_in == sr_out:
        return wav
    g = gcd(sr_in, sr_out)
    return resample_poly(wav, sr_out // g, sr_in // g).astype(np.float32)


def check_waveform(wav, sr: int, *, min_samples: int = WINDOW, what: str = "audio") -> np.ndarray:
    """Validate a waveform in memory: 1-D (or ``(N, channels)``, mixed down), finite,
    at least ``min_samples`` long. Returns ``(N,)`` float32."""
    if isinstance(wav, torch.Tensor):
        wav = wav.detach().cpu().numpy()
    wav = to_mono(wav)
    if not np.isfinite(wav).all():
        raise MotionValueError(f"{what} has NaN or inf samples")
    if len(wav) < min_samples:
        raise ClipTooShortError(
            f"{what} has {len(wav)} samples ({len(wav) / sr * 1000:.1f} ms at {sr} Hz); "
            f"speech features need at least {min_samples} samples at {sr} Hz "
            f"({min_samples / sr * 1000:.0f} ms)"
        )
    return wav


def _soundfile(path: Path):
    try:
        import soundfile
    except ImportError:
        raise AudioFileError(
            path, "reading audio needs the soundfile package: pip install 'mrlib[speech]'"
        ) from None
    return soundfile


def check_audio_seconds(seconds: float, what: object, max_seconds: float | None) -> None:
    """Refuse ``seconds`` of audio over ``max_seconds`` (None: no limit), naming the
    limit and the way around it."""
    if max_seconds is not None and not seconds <= max_seconds:
        msg = (
            f"audio is {seconds:.0f} s long, more than the {max_seconds:.0f} s mrlib "
            "conditions on at once (the whole utterance's features and motion are held in "
            f"memory); cut it into pieces of at most {max_seconds:.0f} s (e.g. `sox in.wav "
            f"part.wav trim 0 {max_seconds:.0f} : newfile : restart`) and use one per run"
        )
        if isinstance(what, Path):
            raise AudioFileError(what, msg)
        raise MotionValueError(f"{what}: {msg}")


def audio_duration(path: str | Path) -> float:
    """Seconds of audio in ``path``, from its header only (nothing is decoded).

    Raises:
        AudioFileError: no such file, or a header libsndfile cannot read.
    """
    path = Path(path)
    if not path.is_file():
        raise AudioFileError(
            path, "a folder, not an audio file" if path.is_dir() else "no such file"
        )
    soundfile = _soundfile(path)
    try:
        info = soundfile.info(str(path))
    except Exception as e:  # soundfile raises its own LibsndfileError / RuntimeError
        raise AudioFileError(path, f"cannot read audio: {e}") from None
    if not info.samplerate or info.samplerate <= 0:
        raise AudioFileError(path, "the header gives no sample rate")
    return float(info.frames) / float(info.samplerate)


HEADER_BYTES = 44  # a canonical WAV header: more bytes than this and no samples is a bad header


def load_audio(
    path: str | Path,
    sr: int = SAMPLE_RATE,
    *,
    min_seconds: float = 0.1,
    max_seconds: float | None = MAX_AUDIO_SECONDS,
) -> tuple[np.ndarray, int]:
    """Read an audio file (anything libsndfile reads: wav, flac, ogg), mix it down to
    mono and resample it to ``sr``.

    Returns:
        ``(wav (N,) float32, sr)``.
    Raises:
        AudioFileError: no such file, unreadable, a rate below ``MIN_INPUT_RATE``, no
            samples, shorter than ``min_seconds`` or (from the header, before anything
            is decoded) longer than ``max_seconds`` (None: no limit).
    """
    path = Path(path)
    check_audio_seconds(audio_duration(path), path, max_seconds)
    soundfile = _soundfile(path)
    try:
        data, sr_in = soundfile.read(str(path), dtype="float32", always_2d=True)
    except Exception as e:  # soundfile raises its own LibsndfileError / RuntimeError
        raise AudioFileError(path, f"cannot read audio: {e}") from None
    if sr_in < MIN_INPUT_RATE:
        raise AudioFileError(
            path,
            f"sample rate {sr_in} Hz is below {MIN_INPUT_RATE} Hz; speech features need "
            f"{SAMPLE_RATE} Hz audio (resample the recording, not this file)",
        )
    if len(data) == 0:
        extra = path.stat().st_size - HEADER_BYTES
        raise AudioFileError(
            path,
            "the file has no samples"
            + (
                f" by its header, though {extra} bytes follow it: a recording that was not "
                "finalised? Write it again with a tool that fixes the header (sox, ffmpeg)"
                if extra > 1024
                else ""
            ),
        )
    wav = resample_audio(to_mono(data), sr_in, sr)
    if not np.isfinite(wav).all():
        raise AudioFileError(path, "audio has NaN or inf samples")
    check_audio_seconds(len(wav) / sr, path, max_seconds)  # a header that undercounted
    if len(wav) < min_seconds * sr:
        raise AudioFileError(
            path, f"audio is {len(wav) / sr:.3f} s long; need at least {min_seconds:g} s"
        )
    return wav, sr


# -- framing ------------------------------------------------------------------------------
def num_feature_frames(num_samples: int, window: int = WINDOW, hop: int = HOP) -> int:
    """Frames of a clip of ``num_samples`` samples: ``(N - window) // hop + 1`` (0 if
    shorter than one window) -- the count WavLM's front end produces."""
    return 0 if num_samples < window else (num_samples - window) // hop + 1


def frame_signal(wav: torch.Tensor, window: int = WINDOW, hop: int = HOP) -> torch.Tensor:
    """Overlapping frames ``(..., N)`` -> ``(..., T, window)``, frame k = samples
    ``[k hop, k hop + window)`` (no padding, so T = ``num_feature_frames``)."""
    return wav.unfold(-1, window, hop)


# -- energy and onsets ---------------------------------------------------------------------
# -- spectra ---------------------------------------------------------------------------------
def _hz_to_mel(f):
    return 2595.0 * np.log10(1.0 + np.asarray(f, np.float64) / 700.0)  # HTK


def _mel_to_hz(m):
    return 700.0 * (10.0 ** (np.asarray(m, np.float64) / 2595.0) - 1.0)


def mel_filterbank(
    n_mels: int, n_fft: int = 512, sr: int = SAMPLE_RATE, f_min: float = 0.0, f_max=None
) -> torch.Tensor:
    """Triangular mel filters on the HTK mel scale ``m = 2595 log10(1 + f / 700)``,
    ``(n_fft // 2 + 1, n_mels)``, unit peak (no area normalisation)."""
    f_max = sr / 2 if f_max is None else f_max
    if not 0 <= f_min < f_max <= sr / 2:
        raise MotionValueError(f"need 0 <= f_min < f_max <= sr/2, got {f_min}, {f_max}")
    edges = _mel_to_hz(np.linspace(_hz_to_mel(f_min), _hz_to_mel(f_max), n_mels + 2))
    freqs = np.linspace(0, sr / 2, n_fft // 2 + 1)[:, None]  # (F, 1)
    lo, mid, hi = edges[None, :-2], edges[None, 1:-1], edges[None, 2:]
    up = (freqs - lo) / (mid - lo)
    down = (hi - freqs) / (hi - mid)
    return torch.from_numpy(np.clip(np.minimum(up, down), 0, None)).float()


def log_mel_spectrogram(
    wav: torch.Tensor,
    n_mels: int = 80,
    *,
    hop: int = HOP,
    window: int = WINDOW,
    n_fft: int = 512,
    sr: int = SAMPLE_RATE,
) -> torch.Tensor:
    """``wav (N,)`` at ``sr`` -> natural-log mel energies ``(T, n_mels)``; frame k covers
    samples ``[k hop, k hop + window)`` (Hann window, zero-padded to ``n_fft``)."""
    frames = frame_signal(wav.float(), window, hop)  # (T, window)
    spec = torch.fft.rfft(frames * torch.hann_window(window, periodic=False), n=n_fft)
    power = spec.real**2 + spec.imag**2  # (T, n_fft // 2 + 1)
    return torch.log(power @ mel_filterbank(n_mels, n_fft, sr) + 1e-10)


def fit_audio_length(wav: np.ndarray, num_samples: int) -> np.ndarray:
    """``wav (N,)`` or ``(N, channels)`` cut or repeated (from its start) to
    ``num_samples`` samples."""
    wav = np.asarray(wav, np.float32)
    if num_samples < 1 or len(wav) == 0:
        raise MotionValueError(f"need a non-empty waveform and num_samples >= 1, got {num_samples}")
    reps = -(-num_samples // len(wav))
    return np.tile(wav, (reps,) + (1,) * (wav.ndim - 1))[:num_samples]  # along time only


def energy_envelope(
    wav: np.ndarray,
    sr: int,
    fps: float,
    num_frames: int | None = None,
    *,
    floor_db: float = -60.0,
) -> np.ndarray:
    """Loudness of the speech at a motion frame rate.

    Frame j (at time ``j / fps``) is the RMS of the signal under a Hann window of
    ``2 / fps`` seconds centred on that time (two motion frames: wide enough to remove
    the pitch ripple, narrow enough to keep syllables apart at 25-30 fps), in dB
    relative to the loudest frame of the clip and floored at ``floor_db``.

    Args:
        wav: ``(N,)`` waveform at ``sr``.
        fps: output frame rate (the motion's).
        num_frames: output length (default ``floor(duration * fps) + 1``, every frame
            time inside the clip); frames past the end of the audio read silence.
    Returns:
        ``(num_frames,)`` float32 in ``[floor_db, 0]`` dB.
    """
    sr = check_rate(sr)
    wav = check_waveform(wav, sr, min_samples=1)
    if not fps > 0:
        raise MotionValueError(f"fps must be positive, got {fps}")
    n = len(wav)
    if num_frames is None:
        num_frames = int(np.floor((n - 1) / sr * fps)) + 1
    if (
        isinstance(num_frames, bool)
        or not isinstance(num_frames, numbers.Integral)
        or num_frames < 1
    ):
        raise MotionValueError(
            f"num_frames must be a whole number >= 1 or None, got {num_frames!r}"
        )
    half = max(1, int(round(sr / fps)))
    win = np.hanning(2 * half + 1)
    win /= win.sum()
    power = np.convolve(wav.astype(np.float64) ** 2, win, mode="same")  # (N,)
    idx = np.round(np.arange(num_frames) / fps * sr).astype(np.int64)
    inside = idx < n
    ms = np.zeros(num_frames)
    ms[inside] = power[idx[inside]]
    if ms.max() <= 1e-12:  # digital silence: nothing to be relative to
        return np.full(num_frames, floor_db, np.float32)
    db = 10 * np.log10(np.maximum(ms, 1e-12) / ms.max())
    return np.maximum(db, floor_db).astype(np.float32)


def onset_strength(wav: np.ndarray, sr: int = SAMPLE_RATE, *, hop_s: float = 0.01) -> np.ndarray:
    """Spectral flux of a 40-band log-mel spectrogram (25 ms windows, ``hop_s`` hop):
    ``flux[t] = sum_b max(0, M[t, b] - M[t-1, b])`` (Bello et al., "A tutorial on onset
    detection in music signals", IEEE TSALP 2005, Sec. III-B), frame t centred at
    ``t * hop_s + 12.5 ms``. Returns ``(T,)`` float32, ``flux[0] = 0``."""
    wav = check_waveform(wav, sr, min_samples=int(0.025 * sr))
    if sr != SAMPLE_RATE:
        wav, sr = resample_audio(wav, sr, SAMPLE_RATE), SAMPLE_RATE
    hop = int(round(hop_s * sr))
    mel = log_mel_spectrogram(torch.from_numpy(wav), n_mels=40, hop=hop)  # (T, 40)
    # dB-like compression: a floor 80 dB under the clip's peak keeps silence from
    # producing flux out of numerical noise
    mel = torch.maximum(mel, mel.max() - 80 / (10 / np.log(10)))
    diff = (mel[1:] - mel[:-1]).clamp_min(0).sum(-1)
    return torch.cat([torch.zeros(1), diff]).numpy().astype(np.float32)


def detect_onsets(
    wav: np.ndarray,
    sr: int = SAMPLE_RATE,
    *,
    min_interval_s: float = 0.12,
    threshold: float = 0.3,
    min_energy_db: float = -35.0,
) -> np.ndarray:
    """Speech onsets (syllable and word starts) as times in seconds, ``(K,)`` float64.

    Peaks of the spectral flux (``onset_strength``, smoothed with a 10 ms Gaussian)
    that are at least ``min_interval_s`` apart and higher than ``threshold`` times the
    clip's 95th flux percentile, kept only where the next 50 ms are louder than
    ``min_energy_db`` (re the clip's peak: breaths and noise in pauses do not count)
    and, on average, no more than 3 dB quieter than the 50 ms before (an abrupt end of
    sound also makes spectral flux, but it is an offset). The parameters suit read
    speech at normal rates (3-6 syllables per second); they are not tuned to any data
    set.
    """
    wav = check_waveform(wav, sr, min_samples=int(0.025 * sr))
    if sr != SAMPLE_RATE:
        wav, sr = resample_audio(wav, sr, SAMPLE_RATE), SAMPLE_RATE
    hop_s = 0.01
    flux = gaussian_filter1d(onset_strength(wav, sr, hop_s=hop_s).astype(np.float64), 1.0)
    ref = np.percentile(flux, 95)
    if ref <= 0:
        return np.zeros(0)
    peaks, _ = find_peaks(
        flux, height=threshold * ref, distance=max(1, int(round(min_interval_s / hop_s)))
    )
    times = peaks * hop_s + 0.0125
    env = energy_envelope(wav, sr, 1 / hop_s, len(flux) + 10)  # frame j at j * hop_s
    w = int(round(0.05 / hop_s))
    keep = []
    for t in times:
        j = int(round(t / hop_s))
        after, before = env[j : j + w + 1], env[max(0, j - w) : j]
        rising = len(before) == 0 or after.mean() >= before.mean() - 3.0
        keep.append(after.max() >= min_energy_db and rising)
    return times[np.asarray(keep, bool)] if len(times) else np.zeros(0)
