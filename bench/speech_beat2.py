"""Co-speech gestures on real recorded speech: the BEAT2 sample, paired + unpaired.

Run from the repository root, with the sample in ``../shared/data/beat2-sample`` or
``$MRLIB_BEAT2_SAMPLE`` (one paired clip of speaker 2 and three unpaired recordings)::

    python bench/speech_beat2.py                     # speech_demo, seeds 0-2 (~15 min CPU)
    python bench/speech_beat2.py --seeds 0 --preset speech_demo

Training set (``mrlib.speech.beat2_split``): the paired clip but its last ``--tail``
seconds (63.5 s; its audio runs 0.6 s past the motion and is cut) and two unpaired
recordings; ``2_scott_0_4_4`` is held out. Each trained model (one per training seed) is
driven by three audios it never heard: the paired clip's last seconds (whose captured
motion is the reference row), the held-out recording of the same speaker, and another
speaker (a synthetic eSpeak NG voice reading corpus sentences, 40 s: the sample has one
speaker only). ``evaluate_speech_sync`` scores
every (audio, seed) run with its own audio and with the next audio's (the mismatched
control, cut or repeated to length); the real clip's own row is the reference. Printed:
the phrase lift (phrase loudness / wrist height r) own vs control, the wrists' speed
talking / in pauses, and the mean wrist speed against the real clip's.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

from common import ROOT, describe, set_threads


def _another_speaker(seconds: float) -> object:
    import numpy as np

    from mrlib.speech.synthetic import SENTENCES, synthetic_utterance

    parts, total, k = [], 0.0, 0
    while total < seconds:
        wav, _ = synthetic_utterance(SENTENCES[k % len(SENTENCES)], "en-gb+m3", seed=900 + k)
        parts.append(wav)
        total += len(wav) / 16000
        k += 1
    return np.concatenate(parts)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    default = os.environ.get("MRLIB_BEAT2_SAMPLE", ROOT.parent / "shared/data/beat2-sample")
    ap.add_argument("--sample", type=Path, default=Path(default))
    ap.add_argument("--preset", default="speech_demo")
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--tail", type=float, default=15.0, help="seconds held out (default 15)")
    ap.add_argument(
        "--per-utterance", action="store_true", help="standardise features per utterance"
    )
    ap.add_argument("--threads", type=int, default=None)
    ap.add_argument("--out", type=Path, default=ROOT / "outputs" / "speech_beat2")
    a = ap.parse_args()
    clip = a.sample / "2_scott_0_1_1.npz"
    if not clip.is_file():
        raise SystemExit(f"no BEAT2 sample at {a.sample} (set MRLIB_BEAT2_SAMPLE)")
    set_threads(a.threads)
    print(describe(), flush=True)

    import numpy as np

    from mrlib.model.presets import get_preset
    from mrlib.speech import (
        SpeechFeatureExtractor,
        beat2_split,
        evaluate_speech_sync,
        load_speech_model,
        speech_train,
    )
    from mrlib.speech.evaluate import hand_speed

    os.environ.setdefault("MRLIB_BEAT2_DIR", str(a.sample))
    split = beat2_split(
        SpeechFeatureExtractor(kind="logmel", per_utterance=a.per_utterance),
        fps=25.0,
        tail_s=a.tail,
    )
    data = split.data
    print(data, flush=True)
    tail, held = split.with_motion[0], split.audio_only[0]
    real = tail.motion
    audios = {
        f"held-out last {a.tail:g} s": tail.wav,
        "held-out recording, same speaker": held.wav,
        "another speaker (eSpeak NG)": _another_speaker(40.0),
    }
    sr = tail.sr
    real_speed = float(hand_speed(real).mean())
    print(f"real clip: mean wrist speed {real_speed:.3f} m/s\n", flush=True)
    rows = []
    for seed in [int(s) for s in a.seeds.split(",")]:
        cfg = get_preset(a.preset).replace(seed=seed)
        out = a.out / f"{a.preset}_seed{seed}"
        t0 = time.perf_counter()
        res = speech_train(data, cfg, out, progress=False, overwrite=True)
        took = time.perf_counter() - t0
        model = load_speech_model(res.checkpoint)
        utts = [(w, sr) for w in audios.values()]
        sync = evaluate_speech_sync(model, utts, seeds=(seed,), references=[real, None, None])
        for name, r in zip(audios, sync.rows, strict=True):
            rows.append({"audio": name, "seed": seed, **r})
            print(
                f"seed {seed} ({took:.0f} s training) {name}: lift {r['lift_model']:+.3f} own / "
                f"{r['lift_shuffled']:+.3f} control; talking/pause {r['pause_model']:.2f} / "
                f"{r['pause_shuffled']:.2f}; wrist speed {r['speed_model']:.3f} m/s "
                f"({r['speed_model'] / real_speed:.0%} of the real clip's)"
                + (f"; real clip: lift {r['lift_data']:+.3f}" if "lift_data" in r else ""),
                flush=True,
            )
    wins = sum(r["lift_model"] > r["lift_shuffled"] for r in rows)
    diff = np.mean([r["lift_model"] - r["lift_shuffled"] for r in rows])
    speeds = np.array([r["speed_model"] / real_speed for r in rows])
    print(f"\nphrase lift own > control in {wins} of {len(rows)} (audio x seed) runs, ", end="")
    print(f"own - control {diff:+.3f} on average")
    print(f"mean wrist speed {speeds.min():.0%}-{speeds.max():.0%} of the real clip's")
    print("\n| audio | lift own / control (per seed) | wrist speed, % of real |\n|---|---|---|")
    for name in audios:
        rs = [r for r in rows if r["audio"] == name]
        lifts = ", ".join(f"{r['lift_model']:+.2f} / {r['lift_shuffled']:+.2f}" for r in rs)
        sp = ", ".join(f"{r['speed_model'] / real_speed:.0%}" for r in rs)
        print(f"| {name} | {lifts} | {sp} |")


if __name__ == "__main__":
    main()
