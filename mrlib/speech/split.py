"""What a speech model is trained on and judged on, from one source: a
:class:`SpeechSplit` holds the training set and the :class:`HeldOutSpeech` utterances kept
out of it (``mrlib.speech.beat2_split``, ``mrlib.speech.synthetic_split``,
``mrlib.speech.split_pair``)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from mrlib.representation.motion import Motion

__all__ = ["HeldOutSpeech", "SpeechSplit"]


@dataclass
class HeldOutSpeech:
    """An utterance kept out of training: its audio, and its real motion where it has one.

    Attributes:
        name: a label for tables (``<stem>`` or ``<stem> (last 15 s)``).
        wav, sr: mono audio and its sample rate.
        motion: the captured motion of the same stretch of time, or None (audio only).
        audio_path: the recording it was read (or cut) from.
    """

    name: str
    wav: object  # (N,) float32 numpy array
    sr: int
    motion: Motion | None = None
    audio_path: Path | None = None

    @property
    def duration(self) -> float:
        return len(self.wav) / self.sr


@dataclass
class SpeechSplit:
    """A training set and the utterances kept out of it, from one source.

    Attributes:
        data: the :class:`SpeechTrainingSet` to train on.
        held_out: :class:`HeldOutSpeech` utterances (with motion first, then audio only).
        source: where the data come from, in words (for titles and tables).
        synthetic: True for the eSpeak NG stand-in (``mrlib.speech.synthetic_split``).
        licence: the data's licence, or "" where none applies.
    """

    data: Any  # a mrlib.speech.SpeechTrainingSet (its module imports this one)
    held_out: list[HeldOutSpeech]
    source: str
    synthetic: bool = False
    licence: str = ""

    @property
    def with_motion(self) -> list[HeldOutSpeech]:
        return [h for h in self.held_out if h.motion is not None]

    @property
    def audio_only(self) -> list[HeldOutSpeech]:
        return [h for h in self.held_out if h.motion is None]
