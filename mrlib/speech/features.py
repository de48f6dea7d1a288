"""Per-frame speech features at 50 fps: WavLM hidden states, or a log-mel fallback that
needs no weights.

Both produce ``(T_a, D)`` float32 tensors on the frame grid of ``mrlib.speech.audio``
(400-sample windows, 320-sample hop at 16 kHz: ``T_a = (N - 400) // 320 + 1`` frames,
frame k centred at ``k / 50 + 12.5 ms``), so everything downstream is agnostic of which
one is used.

* **WavLM** (Chen et al., "WavLM: Large-Scale Self-Supervised Pre-Training for Full
  Stack Speech Processing", IEEE JSTSP 2022), the features of the paper (Sec. 6), through
  ``transformers.WavLMModel``. Weights are read from disk only: a folder saved by
  ``save_pretrained`` / downloaded with ``huggingface-cli``, ``$MRLIB_WAVLM_PATH``, or the
  Hugging Face cache. The default layer is the middle one (6 of 12 for
  ``microsoft/wavlm-base-plus``): layer-wise probing of self-supervised speech models
  (Pasad et al., "Layer-wise analysis of a self-supervised speech representation
  model", ASRU 2021) finds phonetic and prosodic information peaking in the middle
  layers, while the last layers specialise to the pre-training target. ``layer="mean"``
  averages all hidden states instead (an untrained version of SUPERB's weighted sum).
* **log-mel** fallback: ``n_mels`` log mel-band energies (HTK mel scale, 0-8 kHz, Hann
  window, 512-point FFT), the log frame energy, and a cheap autocorrelation pitch track
  (voicing strength and log2 F0 / 100 Hz, 0 where unvoiced) -- ``n_mels + 3`` channels,
  computed with ``torch.fft``; no torchaudio or librosa.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import os
from dataclasses import dataclass
from pathlib import Path

import torch

from mrlib.errors import MotionValueError, MrlibError, is_whole
from mrlib.speech.audio import (
    FEATURE_FPS,
    FRAME_OFFSET_S,
    HOP,
    SAMPLE_RATE,
    WINDOW,
    check_waveform,
    frame_signal,
    load_audio,
    log_mel_spectrogram,
    num_feature_frames,
    resample_audio,
)

__all__ = [
    "WAVLM_PATH_ENV",
    "WAVLM_DEFAULT_ID",
    "SpeechModelError",
    "autocorrelation_pitch",
    "log_mel_features",
    "log_mel_channel_names",
    "load_wavlm",
    "wavlm_features",
    "SpeechFeatureConfig",
    "SpeechFeatureExtractor",
]

WAVLM_PATH_ENV = "MRLIB_WAVLM_PATH"
WAVLM_DEFAULT_ID = "microsoft/wavlm-base-plus"


class SpeechModelError(MrlibError, ValueError):
    """Speech model weights are missing or unusable."""


# -- log-mel fallback ----------------------------------------------------------------------
def autocorrelation_pitch(
    wav: torch.Tensor,
    *,
    hop: int = HOP,
    window: int = WINDOW,
    f_min: float = 60.0,
    f_max: float = 400.0,
    sr: int = SAMPLE_RATE,
) -> tuple[torch.Tensor, torch.Tensor]:
    """A cheap pitch track on the feature frame grid.

    For every frame centre ``k hop + window / 2`` the normalised autocorrelation
    ``r(l) / r(0)`` of a 40 ms Hann-windowed excerpt (two periods at 50 Hz, so the
    lowest pitches are seen twice) is searched for its maximum over lags
    ``sr / f_max .. sr / f_min``; the lag gives F0, the peak value the voicing
    strength (1 for a pure periodic signal, near 0 for noise). No octave-error
    correction or smoothing: it is a feature, not a pitch tracker.

    Returns:
        ``f0 (T,)`` in Hz and ``voicing (T,)`` in [0, 1].
    """
    T = num_feature_frames(len(wav), window, hop)
    long = int(round(0.04 * sr))
    centre = hop * torch.arange(T) + window // 2
    start = centre - long // 2
    pad_l = int(max(0, -int(start.min()))) if T else 0
    padded = torch.nn.functional.pad(wav.float(), (pad_l, long))
    idx = (start + pad_l)[:, None] + torch.arange(long)[None]  # (T, long)
    x = padded[idx]
    # the excerpt's mean off before the window: after it, a DC offset of a few thousandths
    # left a Hann-shaped bump that outweighed the periods (voicing and F0 of 16-19 % of
    # frames moved by an offset 28 dB under the speech)
    x = (x - x.mean(-1, keepdim=True)) * torch.hann_window(long, periodic=False)
    n_fft = 2 ** math.ceil(math.log2(2 * long))
    spec = torch.fft.rfft(x, n=n_fft)
    r = torch.fft.irfft(spec.real**2 + spec.imag**2, n=n_fft)[:, :long]  # (T, long)
    # unbias: a windowed excerpt has fewer overlapping samples at larger lags
    w = torch.hann_window(long, periodic=False)
    wr = torch.fft.irfft(torch.fft.rfft(w, n=n_fft).abs() ** 2, n=n_fft)[:long]
    r = r / wr.clamp_min(1e-6) * wr[0]
    lo, hi = int(sr // f_max), int(math.ceil(sr / f_min))
    seg = r[:, lo : hi + 1] / r[:, :1].clamp_min(1e-12)
    peak, arg = seg.max(-1)
    f0 = sr / (arg + lo).float()
    return f0, peak.clamp(0, 1)


def log_mel_channel_names(n_mels: int = 80) -> list[str]:
    """Names of the ``n_mels + 3`` log-mel feature channels, in order."""
    return [f"mel_{i:02d}" for i in range(n_mels)] + ["log_energy", "voicing", "log2_f0"]


def log_mel_features(
    wav, sr: int = SAMPLE_RATE, *, n_mels: int = 80, pitch: bool = True
) -> torch.Tensor:
    """The weight-free speech features: ``wav (N,)`` -> ``(T_a, n_mels + 3)`` at 50 fps
    (``(T_a, n_mels + 1)`` with ``pitch=False``).

    Channels (``log_mel_channel_names``): ``n_mels`` log mel energies; the log of the
    frame's mean square (Hann-windowed); voicing strength in [0, 1]; ``log2(F0 / 100
    Hz)`` times voicing (so unvoiced frames read ~0 rather than a random pitch).
    """
    wav = check_waveform(wav, sr)
    if sr != SAMPLE_RATE:
        wav = check_waveform(resample_audio(wav, sr, SAMPLE_RATE), SAMPLE_RATE)
    x = torch.from_numpy(wav)
    mel = log_mel_spectrogram(x, n_mels)  # (T, n_mels)
    frames = frame_signal(x) * torch.hann_window(WINDOW, periodic=False)
    energy = torch.log(frames.pow(2).mean(-1) + 1e-10)[:, None]  # (T, 1)
    feats = [mel, energy]
    if pitch:
        f0, voicing = autocorrelation_pitch(x)
        feats += [voicing[:, None], (torch.log2(f0 / 100.0) * voicing)[:, None]]
    return torch.cat(feats, -1).float()


# -- WavLM ---------------------------------------------------------------------------------
def _missing_weights_message(tried: list[str]) -> str:
    return (
        "WavLM weights not found (looked in: " + "; ".join(tried) + "). mrlib never "
        "downloads at run time. On a machine with internet access run "
        f"'huggingface-cli download {WAVLM_DEFAULT_ID} --local-dir wavlm-base-plus' "
        "(or in Python: WavLMModel.from_pretrained("
        f"'{WAVLM_DEFAULT_ID}').save_pretrained('wavlm-base-plus')), copy the folder here "
        f"and set {WAVLM_PATH_ENV}=/path/to/wavlm-base-plus or pass its path; "
        "or use the weight-free features: SpeechFeatureConfig(kind='logmel')."
    )


def load_wavlm(path: str | Path | None = None, device: str | torch.device = "cpu"):
    """Load a ``transformers.WavLMModel`` from local files only, in eval mode.

    Resolution: ``path`` (a folder with ``config.json`` and the weights), else
    ``$MRLIB_WAVLM_PATH``, else the Hugging Face cache entry of ``microsoft/wavlm-base-plus``.

    Returns:
        ``(model, do_normalize)``: whether inputs are standardised per utterance, read
        from the folder's ``preprocessor_config.json`` when there is one, else
        Hugging Face's rule (models with layer-norm feature extractors, e.g. WavLM
        Large, expect it; group-norm ones such as Base+ do not).
    Raises:
        SpeechModelError: no weights where they were looked for (the message says how
            to get them), or transformers is not installed.
    """
    try:
        from transformers import WavLMModel
        from transformers.utils import logging as hf_logging
    except ImportError:
        raise SpeechModelError(
            "WavLM features need the transformers package: pip install 'mrlib[speech]', "
            "or use SpeechFeatureConfig(kind='logmel')"
        ) from None
    tried: list[str] = []
    if path is None and os.environ.get(WAVLM_PATH_ENV):
        path = os.environ[WAVLM_PATH_ENV]
        tried_label = f"${WAVLM_PATH_ENV}={path}"
    else:
        tried_label = str(path) if path is not None else ""
    if path is not None:
        p = Path(path).expanduser()
        tried.append(tried_label)
        if not (p / "config.json").is_file():
            why = "no such folder" if not p.exists() else "no config.json in it"
            raise SpeechModelError(_missing_weights_message([f"{tried_label} ({why})"]))
        source = str(p)
    else:
        tried.append(f"the Hugging Face cache ({WAVLM_DEFAULT_ID})")
        source = WAVLM_DEFAULT_ID
    verbosity = hf_logging.get_verbosity()
    hf_logging.set_verbosity_error()
    hf_logging.disable_progress_bar()
    try:
        model = WavLMModel.from_pretrained(source, local_files_only=True)
    except (OSError, ValueError) as e:
        raise SpeechModelError(_missing_weights_message(tried) + f"\n(cause: {e})") from None
    finally:
        hf_logging.set_verbosity(verbosity)
        hf_logging.enable_progress_bar()
    do_normalize = model.config.feat_extract_norm == "layer"
    if path is not None:
        pre = Path(source) / "preprocessor_config.json"
    else:
        from huggingface_hub import try_to_load_from_cache

        cached = try_to_load_from_cache(WAVLM_DEFAULT_ID, "preprocessor_config.json")
        pre = Path(cached) if isinstance(cached, str) else None
    if pre is not None and pre.is_file():
        import json

        do_normalize = bool(json.loads(pre.read_text()).get("do_normalize", do_normalize))
    return model.to(device).eval(), do_normalize


def _select_layer(hidden_states: tuple[torch.Tensor, ...], layer: int | str) -> torch.Tensor:
    if layer == "mean":
        return torch.stack(hidden_states).mean(0)
    return hidden_states[int(layer)]


@torch.no_grad()
def wavlm_features(
    model,
    wav,
    sr: int = SAMPLE_RATE,
    *,
    layer: int | str = 6,
    do_normalize: bool = False,
    chunk_seconds: float | None = 30.0,
    context_seconds: float = 2.0,
) -> torch.Tensor:
    """WavLM hidden states of one utterance: ``wav (N,)`` -> ``(T_a, H)`` float32 at 50
    fps, ``T_a = (N - 400) // 320 + 1``.

    Args:
        model: a ``transformers.WavLMModel`` (``load_wavlm``).
        layer: index into ``hidden_states`` (0 = the input to the first transformer
            layer, ``num_hidden_layers`` = the last), or ``"mean"`` (all of them).
        do_normalize: standardise the waveform first (zero mean, unit variance).
        chunk_seconds: run long clips in chunks of this length (self-attention memory
            grows with the square of the length), each seeing ``context_seconds`` of
            audio on both sides that is then dropped; None: one pass.
    """
    wav = check_waveform(wav, sr)
    if sr != SAMPLE_RATE:
        wav = check_waveform(resample_audio(wav, sr, SAMPLE_RATE), SAMPLE_RATE)
    n_layers = model.config.num_hidden_layers
    if layer != "mean" and not (isinstance(layer, int) and 0 <= layer <= n_layers):
        raise SpeechModelError(
            f"layer must be 'mean' or an int in [0, {n_layers}] for this model, got {layer!r}"
        )
    x = torch.from_numpy(wav)
    if do_normalize:
        x = (x - x.mean()) / (x.var() + 1e-7).sqrt()
    dev = next(model.parameters()).device
    T = num_feature_frames(len(x))

    def run(seg: torch.Tensor) -> torch.Tensor:
        out = model(seg[None].to(dev), output_hidden_states=True)
        return _select_layer(out.hidden_states, layer)[0].float().cpu()  # (T_seg, H)

    if chunk_seconds is None or T <= int(chunk_seconds * FEATURE_FPS):
        return run(x)
    core = max(1, int(chunk_seconds * FEATURE_FPS))
    ctx = int(context_seconds * FEATURE_FPS)
    pieces = []
    for f0 in range(0, T, core):
        f1 = min(T, f0 + core)
        a, b = max(0, f0 - ctx), min(T, f1 + ctx)  # frames fed to the model
        feats = run(x[a * HOP : (b - 1) * HOP + WINDOW])  # frame i <-> global frame a + i
        pieces.append(feats[f0 - a : f1 - a])
    return torch.cat(pieces)


# -- the front end -------------------------------------------------------------------------
MAX_MELS = 114  # 115 bands over a 512-point spectrum at 16 kHz leave one band empty
MIN_CHUNK_SECONDS = 1.0  # a WavLM pass per chunk: shorter chunks only add passes


@dataclass(frozen=True)
class SpeechFeatureConfig:
    """Which speech features to compute; saved with a speech-conditioned model.

    Attributes:
        kind: ``"wavlm"`` (the paper's) or ``"logmel"`` (no weights needed).
        wavlm_path: folder of WavLM weights; None: ``$MRLIB_WAVLM_PATH`` or the HF cache.
        layer: WavLM hidden state to use (int) or ``"mean"``.
        n_mels: log-mel bands of the fallback.
        pitch: add voicing and log F0 to the fallback.
        chunk_seconds: WavLM chunk length for long clips (None: one pass).
        per_utterance: standardise every dimension over each utterance (its mean and
            s.d. over the clip), so that a voice louder, higher or recorded on another
            microphone than the training speaker's reaches the model on the same scale;
            what is left is how the speech changes within the utterance.
    """

    kind: str = "wavlm"
    wavlm_path: str | None = None
    layer: int | str = 6  # middle layer of WavLM Base+ (see the module docstring)
    n_mels: int = 80
    pitch: bool = True
    chunk_seconds: float | None = 30.0
    per_utterance: bool = False

    def __post_init__(self):
        if self.kind not in ("wavlm", "logmel"):
            raise MotionValueError(f"kind must be 'wavlm' or 'logmel', got {self.kind!r}")
        if self.layer != "mean" and not (is_whole(self.layer) and self.layer >= 0):
            raise MotionValueError(f"layer must be a layer number or 'mean', got {self.layer!r}")
        if not (is_whole(self.n_mels) and 1 <= self.n_mels <= MAX_MELS):
            raise MotionValueError(
                f"n_mels must be a whole number in [1, {MAX_MELS}] (more bands than the "
                f"512-point spectrum fills), got {self.n_mels!r}"
            )
        c = self.chunk_seconds
        if c is not None and not (
            isinstance(c, numbers.Real) and math.isfinite(c) and c >= MIN_CHUNK_SECONDS
        ):
            raise MotionValueError(
                f"chunk_seconds must be None (one pass) or at least {MIN_CHUNK_SECONDS:g} s, "
                f"got {c!r}"
            )

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> SpeechFeatureConfig:
        return cls(**d)


class SpeechFeatureExtractor:
    """Turns audio into ``(T_a, D)`` features at ``fps`` = 50 frames per second.

    Attributes:
        config: the :class:`SpeechFeatureConfig`.
        fps: 50.0; ``frame_offset_s``: 0.0125, the time of frame 0's centre.
        dim: D (WavLM's hidden size, or ``n_mels + 3`` / ``n_mels + 1``).

    The WavLM model is loaded on first use (so building a log-mel extractor, or a
    WavLM one that is never called, needs no weights).
    """

    fps: float = FEATURE_FPS
    frame_offset_s: float = FRAME_OFFSET_S

    def __init__(self, config: SpeechFeatureConfig | None = None, device="cpu", **overrides):
        config = config if config is not None else SpeechFeatureConfig()
        self.config = dataclasses.replace(config, **overrides) if overrides else config
        self.device = torch.device(device)
        self._model = None
        self._do_normalize = False

    def __repr__(self) -> str:
        c = self.config
        what = f"layer={c.layer!r}" if c.kind == "wavlm" else f"n_mels={c.n_mels}"
        return f"SpeechFeatureExtractor(kind={c.kind!r}, {what}, fps={self.fps:g})"

    def _wavlm(self):
        if self._model is None:
            self._model, self._do_normalize = load_wavlm(self.config.wavlm_path, self.device)
        return self._model

    @property
    def dim(self) -> int:
        c = self.config
        if c.kind == "logmel":
            return c.n_mels + (3 if c.pitch else 1)
        return int(self._wavlm().config.hidden_size)

    def __call__(self, wav, sr: int = SAMPLE_RATE) -> torch.Tensor:
        """``wav (N,)`` (or ``(N, channels)``) at ``sr`` -> ``(T_a, D)`` float32."""
        c = self.config
        if c.kind == "logmel":
            x = log_mel_features(wav, sr, n_mels=c.n_mels, pitch=c.pitch)
        else:
            x = wavlm_features(
                self._wavlm(),
                wav,
                sr,
                layer=c.layer,
                do_normalize=self._do_normalize,
                chunk_seconds=c.chunk_seconds,
            )
        if c.per_utterance:
            std = x.std(0, keepdim=True) if len(x) > 1 else torch.ones_like(x[:1])
            x = (x - x.mean(0, keepdim=True)) / std.clamp_min(1e-3)
        return x

    def from_file(self, path: str | Path) -> torch.Tensor:
        """Features of an audio file (``load_audio``: mono, 16 kHz)."""
        wav, sr = load_audio(path)
        return self(wav, sr)
