"""Generate the synthetic co-speech set (espeak-ng speech + rule-based gestures).

    python tools/make_speech_samples.py --out outputs/speech_synthetic
    python tools/make_speech_samples.py --out outputs/speech_synthetic --check
    python tools/make_speech_samples.py --hello data_samples/speech/hello.wav

The default sizes follow the paper's co-speech experiment (Sec. 6: 16 paired sequences
and 27 unpaired audio files). The motion is built on Bandai Namco clips
($MRLIB_DATA_DIR, CC BY-NC 4.0): write it outside the repository, never commit it.
``--check`` measures, on the paired set, the lagged correlation between speech loudness
and hand speed and the beat alignment score, each next to a control (the same motion
against the audio of the next pair). ``--hello`` writes only a short espeak-ng
utterance (no motion), small enough to ship.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from mrlib.io import load_motion
from mrlib.representation.body import load_body_model
from mrlib.speech import (
    GestureParams,
    beat_alignment_score,
    detect_onsets,
    energy_envelope,
    hand_speed,
    load_audio,
    speech_motion_correlation,
    synthesize_speech,
    synthetic_corpus,
)

HELLO_TEXT = "Hello! This is a short example of synthetic speech for mrlib."


def check(pairs: list[tuple[Path, Path]]) -> None:
    """Print loudness/hand-speed correlation and beat alignment, each with its control."""
    body = load_body_model()
    data = []
    for wav_path, npz_path in pairs:
        wav, sr = load_audio(wav_path)
        motion = load_motion(npz_path)
        data.append((wav, sr, motion, hand_speed(motion, body), detect_onsets(wav, sr)))
    rows = []
    for k, (wav, sr, motion, speed, onsets) in enumerate(data):
        wav2, sr2, _, _, onsets2 = data[(k + 1) % len(data)]
        env = energy_envelope(wav, sr, motion.fps, motion.num_frames)
        env2 = np.resize(energy_envelope(wav2, sr2, motion.fps), motion.num_frames)
        c = speech_motion_correlation(env, motion, speed=speed)
        c2 = speech_motion_correlation(env2, motion, speed=speed)
        ba = beat_alignment_score(onsets, motion, speed=speed)
        ba2 = beat_alignment_score(onsets2, motion, speed=speed)
        rows.append((c.r, c.lag_s, c2.r, ba, ba2))
        print(
            f"{motion.name}: r = {c.r:.2f} (lag {c.lag_s:+.2f} s), control r = {c2.r:.2f}; "
            f"beat alignment {ba:.2f}, control {ba2:.2f}"
        )
    r, lag, r2, ba, ba2 = np.array(rows).T
    print(
        f"mean over {len(rows)} pairs: r = {r.mean():.3f} +- {r.std():.3f} "
        f"(min {r.min():.2f}), control r = {r2.mean():.3f}; mean lag {lag.mean():+.2f} s; "
        f"beat alignment {ba.mean():.3f}, control {ba2.mean():.3f}"
    )


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--out", type=Path, help="folder for the synthetic set (outside git)")
    ap.add_argument("--paired", type=int, default=16, help="paired clips (default 16)")
    ap.add_argument("--unpaired", type=int, default=27, help="speech-only clips (default 27)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--fps", type=float, default=25.0, help="motion frame rate (default 25)")
    ap.add_argument("--data-dir", type=Path, help="Bandai Namco dataset (default $MRLIB_DATA_DIR)")
    ap.add_argument("--check", action="store_true", help="measure speech/motion coupling")
    ap.add_argument("--hello", type=Path, help="write only a short espeak-ng utterance here")
    args = ap.parse_args(argv)

    if args.hello is not None:
        import soundfile

        args.hello.parent.mkdir(parents=True, exist_ok=True)
        wav = synthesize_speech(HELLO_TEXT, "en-us", 160)
        soundfile.write(str(args.hello), wav, 16000, subtype="PCM_16")
        print(f"wrote {args.hello}: {len(wav) / 16000:.2f} s")
        return
    if args.out is None:
        ap.error("--out is required (a folder outside the repository)")
    corpus = synthetic_corpus(
        args.paired,
        args.unpaired,
        args.out,
        seed=args.seed,
        data_dir=args.data_dir,
        fps=args.fps,
        params=GestureParams(),
    )
    print(
        f"wrote {len(corpus.paired)} paired and {len(corpus.unpaired)} unpaired clips "
        f"to {corpus.root} (manifest: {corpus.manifest})"
    )
    if args.check and corpus.paired:
        check(corpus.paired)


if __name__ == "__main__":
    sys.exit(main())
