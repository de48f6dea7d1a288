"""A speech training set from the BEAT2 files mrlib knows (``mrlib.datasets.beat2``) in
one call: speaker 2's paired clip and the unpaired recordings not held out.

    data, held_out = beat2_training_set(SpeechFeatureExtractor(kind="logmel"))
    # data: 1 paired clip (63.5 s) + 2 unpaired recordings; held_out: [.../2_scott_0_4_4.wav]

    split = beat2_split(SpeechFeatureExtractor(kind="logmel"), tail_s=15)
    # split.data: the paired clip's first 48.5 s + 2 unpaired recordings; split.held_out:
    # its last 15 s (audio + the captured motion) and 2_scott_0_4_4 (audio)
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from pathlib import Path

from mrlib.datasets.beat2 import AUDIO_DIR, beat2_clips, beat2_files, beat2_speech_folders
from mrlib.errors import MotionValueError
from mrlib.speech.audio import load_audio
from mrlib.speech.data import (
    SpeechTrainingSet,
    load_paired_folder,
    load_unpaired_folder,
    split_pair,
)
from mrlib.speech.features import SpeechFeatureExtractor
from mrlib.speech.split import HeldOutSpeech, SpeechSplit

__all__ = ["BEAT2_HELD_OUT", "beat2_training_set", "beat2_split"]

BEAT2_LICENCE = "CC BY-NC 4.0 (attribution, non-commercial use only)"
BEAT2_HELD_OUT = ("2_scott_0_4_4",)  # the recording kept out of training by default


def beat2_training_set(
    extractor: SpeechFeatureExtractor | None = None,
    *,
    fps: float = 25.0,
    held_out: Iterable[str] = BEAT2_HELD_OUT,
    fetch: bool = True,
    progress=True,
) -> tuple[SpeechTrainingSet, list[Path]]:
    """``(training set, held-out wav files)``: every BEAT2 clip of mrlib's registry but
    ``held_out`` (stems), read from the local copy or the cache (fetched first when
    ``fetch``; see ``mrlib.datasets.beat2``), the clips with motion paired, the others
    unpaired; motion resampled to ``fps``.

    Args:
        extractor: a ``SpeechFeatureExtractor`` (default WavLM, which needs its weights;
            ``SpeechFeatureExtractor(kind="logmel")`` needs none).
        held_out: stems kept out of training; their audio files are returned.

    Raises:
        DataFetchError: an unknown stem, a failed download.
        MotionValueError: every clip with motion is held out.
    """
    held, paired_dir, unpaired_dir, files = _folders(held_out, fetch, progress)
    data = SpeechTrainingSet.from_folders(paired_dir, unpaired_dir, extractor, fps=fps)
    return data, [files[f"{AUDIO_DIR}/{s}.wav"] for s in held]


def beat2_split(
    extractor: SpeechFeatureExtractor | None = None,
    *,
    fps: float = 25.0,
    tail_s: float = 15.0,
    held_out: Iterable[str] = BEAT2_HELD_OUT,
    fetch: bool = True,
    progress=True,
) -> SpeechSplit:
    """A :class:`~mrlib.speech.SpeechSplit` of the BEAT2 files mrlib knows: the paired
    clips up to their last ``tail_s`` seconds and the unpaired recordings but
    ``held_out`` to train on; held out, each paired clip's last ``tail_s`` seconds (audio
    and the captured motion: judge the model next to the real motion of speech it never
    heard) and the ``held_out`` recordings (audio only).

    Raises:
        DataFetchError: an unknown stem, a failed download (no local copy, no network).
        MotionValueError: every clip with motion held out, or ``tail_s`` leaving a part
            under 2 s.
    """
    ex = extractor if extractor is not None else SpeechFeatureExtractor()
    held, paired_dir, unpaired_dir, files = _folders(held_out, fetch, progress)
    heads, tails = [], []
    for pair in load_paired_folder(paired_dir, ex, motion_fps=fps):
        head, tail = split_pair(pair, tail_s)
        heads.append(head)
        tails.append(tail)
    unpaired = [] if unpaired_dir is None else load_unpaired_folder(unpaired_dir, ex)
    audio = []
    for s in held:
        path = files[f"{AUDIO_DIR}/{s}.wav"]
        audio.append(HeldOutSpeech(s, *load_audio(path), motion=None, audio_path=path))
    data = SpeechTrainingSet.from_clips(heads, unpaired, ex.config, fps=fps)
    speakers = sorted({_speaker(c.name) for c in [*heads, *unpaired]})
    source = f"BEAT2, speaker{'s' if len(speakers) > 1 else ''} {', '.join(speakers)}"
    return SpeechSplit(data, tails + audio, source, synthetic=False, licence=BEAT2_LICENCE)


def _speaker(stem: str) -> str:
    """``"2 (scott)"`` for BEAT2's ``2_scott_0_1_1``."""
    parts = stem.split("_")
    return f"{parts[0]} ({parts[1]})" if len(parts) > 2 else stem


def _folders(held_out, fetch, progress):
    clips = beat2_clips()
    held = list(dict.fromkeys(re.sub(r"\.(npz|wav)$", "", Path(str(s)).name) for s in held_out))
    files = beat2_files(list(clips) + held, fetch=fetch, progress=progress)  # one fetch
    keep = [s for s in clips if s not in held]
    paired_dir, unpaired_dir = beat2_speech_folders(keep, fetch=fetch, progress=progress)
    if paired_dir is None:
        raise MotionValueError(
            f"held_out={held}: leaves no BEAT2 clip with motion to train on (the paired ones: "
            f"{', '.join(s for s, f in clips.items() if len(f) > 1)})"
        )
    return held, paired_dir, unpaired_dir, files
