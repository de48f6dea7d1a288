"""Which speech / gesture measures real capture can judge: the BEAT2 sample's own motion
scored against its own audio and against the same speaker's other recordings (cut or
repeated to its length). A measure that does not rank the own audio first on real
motion cannot judge a model on this data.

Run from the repository root, with the sample in ``../shared/data/beat2-sample`` or
``$MRLIB_BEAT2_SAMPLE``::

    python bench/speech_measures_real.py            # seconds

Prints one row per audio: the energy / hand-speed r (best lag within 0.3 s), beat
alignment, phrase lift (phrase loudness / wrist height r), the share of frames talking
and the wrists' speed talking over in pauses, at the sample's motion resampled to 25 fps.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from common import ROOT


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    default = os.environ.get("MRLIB_BEAT2_SAMPLE", ROOT.parent / "shared/data/beat2-sample")
    ap.add_argument("--sample", type=Path, default=Path(default))
    ap.add_argument("--fps", type=float, default=25.0)
    a = ap.parse_args()
    clip = a.sample / "2_scott_0_1_1.npz"
    if not clip.is_file():
        raise SystemExit(f"no BEAT2 sample at {a.sample} (set MRLIB_BEAT2_SAMPLE)")

    import soundfile

    import mrlib
    from mrlib.speech.audio import detect_onsets, energy_envelope, fit_audio_length
    from mrlib.speech.evaluate import (
        beat_alignment_score,
        hand_speed,
        lagged_correlation,
        phrase_loudness,
        speech_motion_correlation,
        speech_pause_ratio,
        voice_activity,
        wrist_lift,
    )

    m = mrlib.load_motion(clip, fps=a.fps)
    wav, sr = soundfile.read(clip.with_suffix(".wav"), dtype="float32")
    audios = {"own audio": wav}
    for p in sorted((a.sample / "unpaired").glob("*.wav")):
        audios[p.stem] = fit_audio_length(soundfile.read(p, dtype="float32")[0], len(wav))
    T, v, lift = m.num_frames, hand_speed(m), wrist_lift(m)
    lag = int(round(0.3 * m.fps))
    print(f"{clip.name}: {m.duration:.1f} s at {m.fps:g} fps, mean wrist speed {v.mean():.3f} m/s")
    print("\n| audio | energy / hand-speed r | beat alignment | phrase lift | talking | "
          "wrist speed talking / pauses |\n|---|---:|---:|---:|---:|---:|")  # fmt: skip
    for name, w in audios.items():
        r = speech_motion_correlation(energy_envelope(w, sr, m.fps, T), m, speed=v).r
        beat = beat_alignment_score(detect_onsets(w, sr), m, speed=v)
        phrase = lagged_correlation(phrase_loudness(w, sr, m.fps, T), lift, m.fps, lag).r
        talk = voice_activity(w, sr, m.fps, T)
        ratio = speech_pause_ratio(talk, v)
        print(f"| {name} | {r:.3f} | {beat:.3f} | {phrase:.3f} | {talk.mean():.0%} | {ratio:.2f} |")


if __name__ == "__main__":
    main()
