"""Held-out speech/gesture synchrony of a speech preset (the figures of ``speech_tutorial``).

Run from the repository root (needs ``espeak-ng`` and ``$MRLIB_DATA_DIR``)::

    python bench/speech_sync.py                      # speech_tutorial, seed 0 (~20-30 min CPU)
    python bench/speech_sync.py --seed 1 --random-audio all
    python bench/speech_sync.py --paper-critics       # the paper's unconditional critics

Training set: ``synthetic_corpus(16, 12)`` (the corpus of notebook 04, seed 0), its first
12 paired clips and all 12 unpaired clips, log-mel features, motion at 25 fps. Held out:
clips 12-23 of ``synthetic_corpus(24, 0, seed=500)``, new texts, voices and gestures.
Each held-out utterance drives the model with 3 sampling seeds, with its own audio and
with another utterance's (``mrlib.speech.evaluate_speech_sync``); the table gives
the loudness / hand-speed r, beat alignment and phrase lift, and their paired differences.
"""

import argparse
import dataclasses
import tempfile
import time
from pathlib import Path

from common import set_threads

import mrlib
from mrlib.speech import (
    SpeechFeatureExtractor,
    SpeechTrainingSet,
    evaluate_speech_sync,
    load_audio,
    load_paired_folder,
    load_speech_model,
    load_unpaired_folder,
    speech_train,
    speech_tutorial,
    synthetic_corpus,
)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--seed", type=int, default=0, help="training seed [0]")
    p.add_argument("--random-audio", choices=["paired", "unpaired", "all"], default=None)
    p.add_argument("--paper-critics", action="store_true", help="unconditional critics")
    p.add_argument("--iterations", type=int, default=None, help="per block (smoke tests)")
    p.add_argument("--held-out", type=int, default=12, help="held-out utterances, >= 2 [12]")
    p.add_argument("--work", type=Path, default=None, help="folder for data and run")
    a = p.parse_args()
    set_threads(1)  # explicit: mrlib's own calls keep it (mrlib.threads)
    work = a.work or Path(tempfile.mkdtemp(prefix="mrlib_speech_sync_"))
    body = mrlib.load_body_model()
    train_dir, held_dir = work / "corpus", work / "heldout"
    if not (train_dir / "manifest.json").exists():
        synthetic_corpus(16, 12, train_dir, fps=25.0)
    if not (held_dir / "manifest.json").exists():
        synthetic_corpus(24, 0, held_dir, seed=500, fps=25.0)
    ex = SpeechFeatureExtractor(kind="logmel")
    pairs = load_paired_folder(train_dir / "paired", ex, motion_fps=25.0, body=body)[:12]
    unpaired = load_unpaired_folder(train_dir / "unpaired", ex)
    data = SpeechTrainingSet.from_clips(pairs, unpaired, ex.config, fps=25.0, body=body)
    cfg = speech_tutorial().replace(seed=a.seed)
    if a.paper_critics:
        model = dataclasses.replace(cfg.model, critic_condition=False, critic_band="full")
        cfg = cfg.replace(model=model, loss=dataclasses.replace(cfg.loss, mismatch=0.0))
    if a.iterations is not None:
        cfg = cfg.replace(block_iterations=(a.iterations,) * cfg.num_blocks)
    t = time.perf_counter()
    res = speech_train(
        data, cfg, work / "run", body=body, random_audio=a.random_audio, progress=False
    )
    print(f"trained in {time.perf_counter() - t:.0f} s -> {res.checkpoint}")
    held = sorted((held_dir / "paired").glob("*.wav"))[12 : 12 + a.held_out]
    sync = evaluate_speech_sync(
        load_speech_model(res.checkpoint),
        [load_audio(w) for w in held],
        seeds=(0, 1, 2),
        references=[mrlib.load_motion(w.with_suffix(".npz")) for w in held],
        body=body,
    )
    print(sync.to_markdown())


if __name__ == "__main__":
    main()
