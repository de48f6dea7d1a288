"""A **synthetic** co-speech set: speech from eSpeak NG, rule-based gestures on real stances.

No paired speech/motion recordings can be shipped or fetched here, so mrlib makes its own
for tests, demos and tutorials. The synthetic set is *not* captured co-speech behaviour:
it is a rule-based stand-in whose only claim is that its arm motion is causally tied to
its audio, which is what a speech-conditioned model has to pick up.

Recipe of one synthetic pair (``make_synthetic_pair``):

1. **Speech**: eSpeak NG (formant synthesis; ``mrlib.speech.espeak``: the library from the
   ``espeakng-loader`` wheel, or an ``espeak-ng`` program) reads a
   text (one or more sentences of ``SENTENCES``) with a voice from ``VOICES`` at a rate
   from ``SPEEDS`` (words per minute) and a random pitch, with pauses of random length
   at punctuation (``with_pauses``: 0.2-0.6 s at commas, 0.5-1 s between sentences)
   and 0.2-0.5 s of silence before and after; resampled to 16 kHz mono.
2. **Base motion**: a standing clip -- by default the calmest 1.5 s resting stance at
   the end of a Bandai Namco clip (``BASE_CLIPS``, ``quiet_window``: real body sway,
   arms down) -- resampled to the motion rate and looped back and forth (forward,
   then reversed, so there is no jump) to the audio's duration.
3. **Gestures** (``gesture_offsets``), rotations left-multiplied onto the local
   rotations (i.e. about the parent's axes) of the shoulders, elbows, wrists and head:
   * *lift*: while the speaker talks, both forearms come up in front of the body by an
     amount following the loudness (``energy_envelope``, -40..0 dB mapped to 0..1)
     smoothed over 0.5 s: shoulder flexion up to ``lift_shoulder_deg``, elbow flexion
     up to ``lift_elbow_deg``; the left arm does 35-70 % of what the right does;
   * *beats*: on stressed onsets (the strongest spectral-flux onsets, at least
     ``min_beat_interval_s`` apart) one arm or both make an up-down stroke -- a raise,
     then a ``stroke_s`` drop that ends exactly on the onset (the hand comes to rest on
     the syllable: a local minimum of hand speed, i.e. a motion beat). Strokes less
     than ``max_chain_gap_s`` apart follow each other directly; after a pause the
     raise starts ``rest_prep_s`` before the onset. Amplitudes follow the loudness at
     the onset (+-25 % jitter); the head nods with every stroke.
   Which arm beats, the jitter and the left/right balance come from ``seed``.

How strongly the synthetic arm motion follows the loudness is in ``docs/results.md``
(``python tools/make_speech_samples.py --out DIR --check``).

Every synthetic ``Motion`` carries ``meta["synthetic"] = True`` and the recipe. Motion
derived from the Bandai Namco clips is CC BY-NC 4.0 data: ``synthetic_corpus`` writes it
to a folder you choose at run time, it is never shipped with mrlib.

Steps 2 and 3 (the base motion and the gestures) are ``mrlib.speech.gestures``'s; their
names are reachable here too. Loaders for real sets are in :mod:`mrlib.speech.data`.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from mrlib.errors import MotionValueError
from mrlib.io import save_motion
from mrlib.io.outputs import write_text
from mrlib.representation.motion import Motion
from mrlib.speech.audio import SAMPLE_RATE, load_audio, resample_audio
from mrlib.speech.data import (
    SpeechTrainingSet,
    load_paired_folder,
    load_unpaired_folder,
)
from mrlib.speech.espeak import espeak_backend, espeak_speak
from mrlib.speech.features import SpeechFeatureExtractor
from mrlib.speech.gestures import (
    GestureParams,
    apply_offsets,
    gesture_offsets,
    load_base_motions,
    loop_motion,
)
from mrlib.speech.split import HeldOutSpeech, SpeechSplit

__all__ = [
    "SENTENCES",
    "VOICES",
    "SPEEDS",
    "espeak_available",
    "with_pauses",
    "synthesize_speech",
    "synthetic_utterance",
    "make_synthetic_pair",
    "corpus_text",
    "SyntheticCorpus",
    "synthetic_corpus",
    "synthetic_split",
]


# Short monologue lines about art and everyday topics (the paper's speakers "discuss a
# piece of art or various topics"), 2-5 s each when spoken.
SENTENCES: tuple[str, ...] = (
    "This painting was finished in the spring, after two very long winters.",
    "Look at the light on the left, it falls exactly on her hands.",
    "Honestly, I think the colours are far too loud for such a quiet room.",
    "The sculptor worked on this one block of marble for almost six years.",
    "We walked around it three times, and every side told a different story.",
    "What strikes me first is the movement, everything seems to be falling.",
    "If you stand back a little, the small dots turn into a harbour at night.",
    "My grandmother had a print of this picture above her kitchen table.",
    "The frame is older than the canvas, and nobody knows where it came from.",
    "So the question is simple: is this a portrait, or is it a landscape?",
    "Yesterday the train was late again, so I finally read the whole book.",
    "The museum opens at ten, but the best time to come is just before closing.",
    "I really love how the blue fades into grey towards the top.",
    "Nobody expected the concert to be that good, least of all the band.",
    "First you mix the flour and the water, then you wait, and wait, and wait.",
    "There are four figures here, but only one of them is looking at you.",
    "It rained all week, and then, on Sunday, the sky was perfectly clear.",
    "The artist painted the same bridge over and over, in every season.",
    "You can almost hear the wind in those trees, can't you?",
    "Let me tell you why this small drawing matters more than the big one.",
    "The city changed completely in ten years, and not always for the better.",
    "Every morning she walked to the studio, even when it was snowing.",
    "Some people see a face in the clouds; I only see the clouds.",
    "At the end of the day, a good story needs a beginning, a middle and an end.",
)

# eSpeak NG voices (language + optional "+variant"); all ship with espeakng-loader's data.
VOICES: tuple[str, ...] = (
    "en-us",
    "en-gb",
    "en-gb-scotland",
    "en-us+f3",
    "en-gb+m3",
    "en-gb-x-rp+f2",
)
SPEEDS: tuple[int, ...] = (140, 160, 185)  # words per minute


# -- speech --------------------------------------------------------------------------------
def espeak_available() -> bool:
    """Whether eSpeak NG can speak here: the ``espeakng-loader`` wheel of the speech
    extra, or an ``espeak-ng`` program on ``PATH`` (``mrlib.speech.espeak``)."""
    return espeak_backend() is not None


def with_pauses(
    text: str,
    rng: np.random.Generator,
    comma_s: tuple[float, float] = (0.2, 0.6),
    stop_s: tuple[float, float] = (0.5, 1.0),
) -> str:
    """``text`` as SSML with a pause after every punctuation mark: uniform in
    ``comma_s`` seconds after ``, ; :`` and in ``stop_s`` after ``. ? !`` (espeak-ng's own
    pauses are ~0.1-0.3 s; talkers pause longer and more variably between phrases)."""
    out = []
    for ch in text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;"):
        out.append(ch)
        if ch in ",;:.?!":
            lo, hi = comma_s if ch in ",;:" else stop_s
            out.append(f' <break time="{int(rng.uniform(lo, hi) * 1000)}ms"/> ')
    return "".join(out)


def synthesize_speech(
    text: str,
    voice: str = "en-us",
    speed: int = 160,
    pitch: int = 50,
    sr: int = SAMPLE_RATE,
    *,
    ssml: bool = False,
    backend: str = "auto",
) -> np.ndarray:
    """Speak ``text`` with eSpeak NG: ``(N,)`` float32 mono at ``sr``.

    Args:
        voice: an eSpeak NG voice, e.g. ``"en-us"``, ``"en-gb+m3"``.
        speed: words per minute (80-450); pitch: 0-99.
        ssml: ``text`` is SSML (``with_pauses``).
        backend: ``"auto"`` (the bundled library, else the program), ``"library"`` or
            ``"program"``; see ``mrlib.speech.espeak``.
    Raises:
        SpeechSynthesisError: eSpeak NG not installed, unknown voice, or no audio.
    """
    wav, sr_in = espeak_speak(text, voice, speed, pitch, ssml=ssml, backend=backend)
    return resample_audio(wav, sr_in, sr)


# -- pairs ---------------------------------------------------------------------------------
def synthetic_utterance(
    text: str, voice: str, seed: int, *, speed: int | None = None
) -> tuple[np.ndarray, dict]:
    """Step 1 of the recipe: ``text`` spoken by espeak-ng with random pauses at
    punctuation (``with_pauses``), a random rate from ``SPEEDS`` (unless ``speed``)
    and pitch (35-64), and 0.2-0.5 s of silence before and after, all drawn from
    ``seed``.

    Returns:
        ``wav (N,)`` float32 at 16 kHz and ``{"speed_wpm", "pitch"}``.
    """
    rng = np.random.default_rng(seed)
    speed = int(rng.choice(SPEEDS)) if speed is None else int(speed)
    pitch = int(rng.integers(35, 65))
    wav = synthesize_speech(with_pauses(text, rng), voice, speed, pitch, ssml=True)
    lead, tail = (np.zeros(int(rng.uniform(0.2, 0.5) * SAMPLE_RATE), np.float32) for _ in "ab")
    return np.concatenate([lead, wav, tail]), {"speed_wpm": speed, "pitch": pitch}


def make_synthetic_pair(
    sentence: str,
    voice: str,
    seed: int,
    base_motion: Motion,
    *,
    speed: int | None = None,
    fps: float | None = 25.0,
    params: GestureParams = GestureParams(),  # noqa: B008 (a frozen dataclass)
) -> tuple[np.ndarray, int, Motion]:
    """One **synthetic** speech/gesture pair (recipe: module docstring).

    Args:
        sentence: the text to speak (one or more sentences); voice: an espeak-ng voice.
        seed: draws the speaking rate (unless ``speed``), pitch, pauses and the
            gesture's random choices.
        base_motion: standing motion to add the gestures to (``load_base_motions``,
            ``standing_base``); looped to the audio's duration.
        fps: motion frame rate (the paper's speech experiments use 25); None keeps
            the base's.
    Returns:
        ``(wav (N,) float32, 16000, Motion)``; the motion has ``round(N / 16000 * fps)``
        frames, frame j at ``j / fps`` seconds of the audio, ``meta["synthetic"] =
        True`` and the recipe and its draws in ``meta``.
    """
    wav, info = synthetic_utterance(sentence, voice, seed, speed=speed)
    sr = SAMPLE_RATE
    base = base_motion if fps is None else base_motion.resample(fps)
    T = max(2, int(round(len(wav) / sr * base.fps)))
    offsets = gesture_offsets(wav, sr, base.fps, T, seed, params)
    motion = apply_offsets(loop_motion(base, T), offsets)
    motion = motion.replace(
        contacts=None,
        label="speech_synthetic",
        name=f"synthetic_{seed:04d}",
        meta={
            "synthetic": True,
            "source": "mrlib.speech.synthetic.make_synthetic_pair",
            "recipe": "espeak-ng speech with random pauses; rule-based gestures (loudness "
            "lift, beat strokes ending on stressed onsets) added to a looped standing base",
            "sentence": sentence,
            "voice": voice,
            **info,
            "seed": int(seed),
            "base": base_motion.name,
            "beats_s": [round(float(b), 4) for b in offsets["beats_s"]],
            "gesture_params": asdict(params),
        },
    )
    return wav, sr, motion


def corpus_text(k: int) -> str:
    """Text of utterance ``k`` of ``synthetic_corpus``: two sentences,
    ``SENTENCES[k]`` and the one half the list further on (24 distinct texts)."""
    n = len(SENTENCES)
    return f"{SENTENCES[k % n]} {SENTENCES[(k + n // 2) % n]}"


@dataclass
class SyntheticCorpus:
    """What ``synthetic_corpus`` wrote: ``paired`` ``[(wav, npz)]`` and ``unpaired``
    ``[wav]`` paths, and the ``manifest.json`` describing them."""

    root: Path
    paired: list[tuple[Path, Path]] = field(default_factory=list)
    unpaired: list[Path] = field(default_factory=list)
    manifest: Path | None = None


def synthetic_corpus(
    n_paired: int,
    n_unpaired: int,
    out_dir: str | Path,
    *,
    seed: int = 0,
    base_motions: list[Motion] | None = None,
    data_dir: str | Path | None = None,
    fps: float = 25.0,
    params: GestureParams = GestureParams(),  # noqa: B008 (a frozen dataclass)
) -> SyntheticCorpus:
    """Write a **synthetic** co-speech training set (the paper's setting in miniature:
    paired clips for reconstruction, extra speech-only clips for random generation).

    Layout: ``out_dir/paired/synthetic_NNNN.wav`` + ``.npz`` (same stem; motion through
    ``mrlib.io.save_motion``), ``out_dir/unpaired/unpaired_NNNN.wav``, and
    ``out_dir/manifest.json`` (text, voice, rate, pitch, seed and base clip of every
    file). Utterance k (paired first, then unpaired) says ``corpus_text(k)`` with
    ``VOICES[k % 6]`` and seed ``seed + k``.

    Args:
        base_motions: standing clips to build on, cycled; default
            ``load_base_motions(data_dir, fps=fps)`` (Bandai Namco clips: the output
            is then CC BY-NC 4.0 derived data -- keep it out of version control).
    Raises:
        SpeechSynthesisError: espeak-ng is missing; MotionFileError: no base data.
    """
    import soundfile

    if n_paired < 0 or n_unpaired < 0:
        raise MotionValueError(f"counts must be >= 0, got {n_paired}, {n_unpaired}")
    root = Path(out_dir)
    (root / "paired").mkdir(parents=True, exist_ok=True)
    (root / "unpaired").mkdir(parents=True, exist_ok=True)
    if base_motions is None and n_paired > 0:
        base_motions = load_base_motions(data_dir, fps=fps)
    corpus = SyntheticCorpus(root)
    entries = []
    for k in range(n_paired + n_unpaired):
        text, voice = corpus_text(k), VOICES[k % len(VOICES)]
        if k < n_paired:
            base = base_motions[k % len(base_motions)]
            wav, sr, motion = make_synthetic_pair(
                text, voice, seed + k, base, fps=fps, params=params
            )
            stem = root / "paired" / f"synthetic_{k:04d}"
            save_motion(motion, stem.with_suffix(".npz"))
            corpus.paired.append((stem.with_suffix(".wav"), stem.with_suffix(".npz")))
            info = {key: motion.meta[key] for key in ("speed_wpm", "pitch", "base")}
        else:
            wav, info = synthetic_utterance(text, voice, seed + k)
            sr = SAMPLE_RATE
            stem = root / "unpaired" / f"unpaired_{k - n_paired:04d}"
            corpus.unpaired.append(stem.with_suffix(".wav"))
        soundfile.write(str(stem.with_suffix(".wav")), wav, sr, subtype="PCM_16")
        entries.append(
            {
                "file": f"{stem.parent.name}/{stem.name}",
                "text": text,
                "voice": voice,
                "seed": seed + k,
                **info,
            }
        )
    corpus.manifest = root / "manifest.json"
    manifest = {
        "synthetic": True,
        "description": "mrlib synthetic co-speech set: espeak-ng speech and rule-based "
        "gestures on standing base motion (mrlib.speech.synthetic); not captured behaviour",
        "license_note": "motion derived from the Bandai Namco Research Motion Dataset is "
        "CC BY-NC 4.0; do not redistribute it with mrlib",
        "fps": fps,
        "gesture_params": asdict(params),
        "files": entries,
    }
    write_text(corpus.manifest, json.dumps(manifest, indent=1), overwrite=True)
    return corpus


def synthetic_split(
    out_dir: str | Path,
    n_paired: int = 8,
    n_unpaired: int = 8,
    n_held_out: int = 3,
    extractor=None,
    *,
    fps: float = 25.0,
    seed: int = 0,
    base_motions: list[Motion] | None = None,
) -> SpeechSplit:
    """A :class:`~mrlib.speech.SpeechSplit` of a **synthetic** set (``synthetic_corpus``
    in ``out_dir``): ``n_paired`` pairs and ``n_unpaired`` speech-only clips to train on,
    and ``n_held_out`` further pairs (audio and their synthetic gestures) held out. The
    stand-in where no recorded co-speech data is at hand (see ``mrlib.speech.beat2_split``).

    Args:
        extractor: a ``SpeechFeatureExtractor`` (default: WavLM, which needs weights).
        base_motions: standing clips to build on (default: ``load_base_motions``).
    Raises:
        SpeechSynthesisError: espeak-ng is missing; MotionValueError: counts below 1.
    """
    if n_paired < 1 or n_held_out < 1:
        raise MotionValueError(
            f"n_paired and n_held_out must be >= 1, got {n_paired}, {n_held_out}"
        )
    corpus = synthetic_corpus(
        n_paired + n_held_out, n_unpaired, out_dir, seed=seed, base_motions=base_motions, fps=fps
    )
    ex = extractor if extractor is not None else SpeechFeatureExtractor()
    pairs = load_paired_folder(corpus.root / "paired", ex, motion_fps=fps)
    unpaired = load_unpaired_folder(corpus.root / "unpaired", ex) if n_unpaired else []
    held = [
        HeldOutSpeech(p.name, *load_audio(p.audio_path), motion=p.motion, audio_path=p.audio_path)
        for p in pairs[n_paired:]
    ]
    data = SpeechTrainingSet.from_clips(pairs[:n_paired], unpaired, ex.config, fps=fps)
    source = "synthetic (eSpeak NG voices, rule-based gestures on standing stances)"
    return SpeechSplit(data, held, source, synthetic=True)
