"""Does a small pretrained speech encoder that a wheel ships help on real speech? The
Silero VAD model (``pip install silero-vad``: its TorchScript weights are in the wheel, no
download at run time) adds its speech probability, one channel, to the log-mel features;
everything else is ``bench/speech_beat2.py`` (the BEAT2 sample, per-utterance features,
``speech_demo``, training seeds 0-2, three held-out audios against a mismatched control)::

    python bench/experiments/speech_encoder.py            # log-mel + Silero VAD
    python bench/speech_beat2.py --per-utterance          # log-mel alone, the same protocol

Silero's module sets PyTorch to one thread when imported; this script runs on one
thread anyway.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

CHUNK = 512  # Silero's window at 16 kHz: 32 ms


def vad_probability(wav: np.ndarray, sr: int) -> tuple[np.ndarray, float]:
    """Silero's speech probability per 32 ms chunk and the chunks' rate."""
    from silero_vad import load_silero_vad

    model = vad_probability.model = getattr(vad_probability, "model", None) or load_silero_vad()
    model.reset_states()
    x = torch.as_tensor(np.asarray(wav, np.float32))
    n = len(x) // CHUNK
    with torch.no_grad():
        p = [float(model(x[k * CHUNK : (k + 1) * CHUNK], sr)) for k in range(n)]
    return np.asarray(p, np.float32), sr / CHUNK


def main() -> None:
    import mrlib.speech.features as F

    plain = F.log_mel_features

    def with_vad(wav, sr, **kw):
        feats = plain(wav, sr, **kw)  # (T_a, D) at 50 fps, frame k at 0.0125 + k / 50 s
        wav16 = F.resample_audio(np.asarray(wav, np.float32), sr, 16000) if sr != 16000 else wav
        p, rate = vad_probability(wav16, 16000)
        t_feat = F.FRAME_OFFSET_S + np.arange(len(feats)) / F.FEATURE_FPS
        t_vad = (np.arange(len(p)) + 0.5) / rate
        vad = np.interp(t_feat, t_vad, p) if len(p) else np.zeros(len(feats))
        return torch.cat([feats, torch.as_tensor(vad, dtype=feats.dtype)[:, None]], 1)

    F.log_mel_features = with_vad
    sys.argv = [sys.argv[0], "--per-utterance", *sys.argv[1:]]
    import speech_beat2

    speech_beat2.main()


if __name__ == "__main__":
    main()
