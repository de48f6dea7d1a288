"""A speech training set from the BEAT2 files mrlib knows (``mrlib.datasets.beat2``) in
one call: speaker 2's paired clip and the unpaired recordings not held out.

    data, held_out = beat2_training_set(SpeechFeatureExtractor(kind="logmel"))
    # data: 1 paired clip (63.5 s) + 2 unpaired recordings; held_out: [.../2_scott_0_4_4.wav]
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from pathlib import Path

from mrlib.datasets.beat2 import AUDIO_DIR, beat2_clips, beat2_files, beat2_speech_folders
from mrlib.errors import MotionValueError
from mrlib.speech.data import SpeechTrainingSet
from mrlib.speech.features import SpeechFeatureExtractor

__all__ = ["BEAT2_HELD_OUT", "beat2_training_set"]

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
    data = SpeechTrainingSet.from_folders(paired_dir, unpaired_dir, extractor, fps=fps)
    return data, [files[f"{AUDIO_DIR}/{s}.wav"] for s in held]
