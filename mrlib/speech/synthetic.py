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

Loaders for real sets are in :mod:`mrlib.speech.data`.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import torch
from scipy.ndimage import gaussian_filter1d

from mrlib.errors import ClipTooShortError, MotionFileError, MotionValueError
from mrlib.io import default_data_dir, load_motion, save_motion
from mrlib.representation.body import resolve_body
from mrlib.representation.motion import Motion
from mrlib.representation.rotations import axis_angle_to_matrix, matrix_to_axis_angle
from mrlib.representation.skeleton import JOINT_NAMES
from mrlib.speech.audio import (
    SAMPLE_RATE,
    detect_onsets,
    energy_envelope,
    onset_strength,
    resample_audio,
)
from mrlib.speech.espeak import SpeechSynthesisError, espeak_backend, espeak_speak

__all__ = [
    "SENTENCES",
    "VOICES",
    "SPEEDS",
    "BASE_CLIPS",
    "SpeechSynthesisError",
    "espeak_available",
    "with_pauses",
    "synthesize_speech",
    "GestureParams",
    "gesture_offsets",
    "apply_offsets",
    "quiet_window",
    "loop_motion",
    "load_base_motions",
    "standing_base",
    "synthetic_utterance",
    "make_synthetic_pair",
    "corpus_text",
    "SyntheticCorpus",
    "synthetic_corpus",
]


J = {name: i for i, name in enumerate(JOINT_NAMES)}

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

# Bandai Namco clips that end in a calm resting stance (``quiet_window`` finds 1.5 s
# with mean wrist speed 0.04-0.11 m/s, arms down, torso upright); file stems in the
# dataset's data/ folder. Chosen by scanning the bow/bye/byebye/guide/call/respond clips.
BASE_CLIPS: tuple[str, ...] = (
    "dataset-1_byebye_sad_001",
    "dataset-1_bow_sad_001",
    "dataset-1_guide_sad_001",
    "dataset-1_bye_sad_001",
)


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


# -- gestures ------------------------------------------------------------------------------
@dataclass(frozen=True)
class GestureParams:
    """Amplitudes (degrees) and timing (seconds) of the synthetic gestures."""

    lift_shoulder_deg: float = 18.0
    lift_elbow_deg: float = 30.0
    lift_smooth_s: float = 0.5  # arms stay up through short pauses
    beat_elbow_deg: float = 24.0
    beat_shoulder_deg: float = 8.0
    beat_wrist_deg: float = 15.0
    nod_deg: float = 4.0
    stroke_s: float = 0.15  # the drop that ends on the onset
    rest_prep_s: float = 0.35  # raise before a stroke that follows a pause
    max_chain_gap_s: float = 1.0  # strokes closer than this are chained without a rest
    min_beat_interval_s: float = 0.3  # strokes on stressed syllables, not on every one
    floor_db: float = -40.0  # loudness mapped to 0 at and below this level


def _loudness(wav: np.ndarray, sr: int, fps: float, T: int, floor_db: float) -> np.ndarray:
    """Energy envelope mapped to [0, 1]: ``floor_db`` -> 0, the loudest frame -> 1."""
    e = energy_envelope(wav, sr, fps, T, floor_db=floor_db)
    return np.clip((e - floor_db) / -floor_db, 0, 1).astype(np.float64)


def _stressed_onsets(wav: np.ndarray, sr: int, min_interval_s: float) -> np.ndarray:
    """The strongest onsets, greedily, no two closer than ``min_interval_s`` (s)."""
    onsets = detect_onsets(wav, sr)
    if len(onsets) == 0:
        return onsets
    flux = onset_strength(wav, sr)
    strength = flux[np.clip(np.round((onsets - 0.0125) / 0.01).astype(int), 0, len(flux) - 1)]
    chosen: list[float] = []
    for k in np.argsort(-strength):
        if all(abs(onsets[k] - c) >= min_interval_s for c in chosen):
            chosen.append(float(onsets[k]))
    return np.sort(np.asarray(chosen))


def _stroke(t: np.ndarray, start: float, onset: float, stroke: float) -> np.ndarray:
    """Raise-then-drop profile in [0, 1] over ``[start, onset]`` (zero elsewhere): a
    raised-cosine rise up to ``onset - stroke``, then a raised-cosine fall that ends on
    ``onset``; the velocity is zero at both ends and at the top."""
    out = np.zeros_like(t)
    top = onset - stroke
    rise = (t >= start) & (t < top)
    out[rise] = 0.5 - 0.5 * np.cos(np.pi * (t[rise] - start) / (top - start))
    fall = (t >= top) & (t <= onset)
    out[fall] = 0.5 + 0.5 * np.cos(np.pi * (t[fall] - top) / stroke)
    return out


def gesture_offsets(
    wav: np.ndarray,
    sr: int,
    fps: float,
    num_frames: int,
    seed: int = 0,
    params: GestureParams = GestureParams(),
) -> dict[str, np.ndarray]:
    """The synthetic gesture of an utterance as rotation offsets (see the module
    docstring for the recipe).

    Args:
        wav: ``(N,)`` speech at ``sr``.
        fps, num_frames: the motion's frame rate and length.
    Returns:
        ``{joint name: (num_frames, 3) axis-angle offset (radians)}``, to be
        left-multiplied onto the joint's local rotation (``apply_offsets``); also
        ``"beats_s"``: ``(K,)`` the onset times strokes end on.
    """
    if num_frames < 2:
        raise ClipTooShortError(f"need at least 2 motion frames, got {num_frames}")
    rng = np.random.default_rng(seed)
    p = params
    d = np.deg2rad
    T = num_frames
    t = np.arange(T) / fps
    loud = _loudness(wav, sr, fps, T, p.floor_db)  # (T,) in [0, 1]
    lift = gaussian_filter1d(loud, p.lift_smooth_s * fps, mode="nearest")
    left_share = rng.uniform(0.35, 0.7)  # the left arm does less
    arm_lift = {"right": lift, "left": left_share * lift}

    beats = _stressed_onsets(wav, sr, p.min_beat_interval_s)
    beat = {"right": np.zeros(T), "left": np.zeros(T)}
    nod = np.zeros(T)
    prev = -np.inf
    for tk in beats:
        # chained after the previous stroke, or raised from rest after a pause
        start = prev if tk - prev <= p.max_chain_gap_s else tk - p.rest_prep_s
        stroke = min(p.stroke_s, 0.45 * (tk - start))
        k = min(T - 1, int(round(tk * fps)))
        amp = loud[k : k + max(1, int(0.1 * fps))].max() * rng.uniform(0.75, 1.25)
        g = amp * _stroke(t, start, tk, stroke)
        side = rng.choice(["right", "left", "both"], p=[0.55, 0.2, 0.25])
        for s in ("right", "left"):
            if side in (s, "both"):
                beat[s] += g
        nod += g
        prev = tk

    zeros = np.zeros(T)
    out: dict[str, np.ndarray] = {}
    for s, sign in (("right", 1.0), ("left", -1.0)):
        shoulder = -(d(p.lift_shoulder_deg) * arm_lift[s] + d(p.beat_shoulder_deg) * beat[s])
        elbow = sign * (d(p.lift_elbow_deg) * arm_lift[s] + d(p.beat_elbow_deg) * beat[s])
        wrist = sign * d(p.beat_wrist_deg) * beat[s]
        # arms hang along -Y: flexion about -X lifts them forward (+Z); in the upper-arm
        # frame the elbow hinge is Y (right arm along -X bends forward with +Y)
        out[f"{s}_shoulder"] = np.stack([shoulder, zeros, zeros], -1)
        out[f"{s}_elbow"] = np.stack([zeros, elbow, zeros], -1)
        out[f"{s}_wrist"] = np.stack([zeros, wrist, zeros], -1)
    out["head"] = np.stack([d(p.nod_deg) * nod, zeros, zeros], -1)  # +X pitches the face down
    out["beats_s"] = beats
    return out


def apply_offsets(motion: Motion, offsets: dict[str, np.ndarray]) -> Motion:
    """Left-multiply rotation offsets onto local joint rotations:
    ``R_j <- R(offset_j) R_j`` for every joint name in ``offsets`` (other keys ignored)."""
    poses = torch.from_numpy(motion.poses.astype(np.float64))
    for name, off in offsets.items():
        if name not in J:
            continue
        off = np.asarray(off, np.float64)
        if off.shape != (motion.num_frames, 3):
            raise MotionValueError(
                f"offset for {name} must be ({motion.num_frames}, 3), got {off.shape}"
            )
        j = J[name]
        R = axis_angle_to_matrix(torch.from_numpy(off)) @ axis_angle_to_matrix(poses[:, j])
        poses[:, j] = matrix_to_axis_angle(R)
    return motion.replace(poses=poses.numpy().astype(np.float32))


# -- base motion ---------------------------------------------------------------------------
def quiet_window(
    motion: Motion, seconds: float = 1.5, body=None, *, rest_pose: bool = True
) -> Motion:
    """The calmest ``seconds``-long window of ``motion``: the lowest mean wrist speed
    among windows where, on every frame, the torso is within 15 degrees of upright
    (pelvis-to-neck) and both wrists hang below the pelvis and less than 20 cm in front
    of or behind it -- a resting stance, not a held gesture (``rest_pose=False``
    drops these conditions). The whole clip if it is shorter; the root is moved to
    x = z = 0 on the first frame.

    Raises:
        MotionValueError: no window of ``motion`` is a resting stance.
    """
    from mrlib.speech.evaluate import hand_speed

    body = resolve_body(body)
    W = min(motion.num_frames, max(2, int(round(seconds * motion.fps))))
    joints = body.motion_joints(motion)  # (T, 24, 3)
    speed = hand_speed(motion, body)
    mean = np.convolve(speed, np.ones(W) / W, mode="valid")  # (T - W + 1,)
    if rest_pose:
        up = joints[:, J["neck"]] - joints[:, J["pelvis"]]
        tilt = np.degrees(np.arccos(np.clip(up[:, 1] / np.linalg.norm(up, axis=1), -1, 1)))
        rel = joints[:, [J["left_wrist"], J["right_wrist"]]] - joints[:, None, J["pelvis"]]
        ok = (tilt < 15) & (rel[..., 1].max(1) < 0) & (np.abs(rel[..., 2]).max(1) < 0.2)
        bad = np.convolve(~ok, np.ones(W), mode="valid") > 0
        if bad.all():
            raise MotionValueError(
                f"{motion!r} has no {W}-frame window in a resting stance (upright, arms "
                "down); pick another clip or pass rest_pose=False"
            )
        mean = np.where(bad, np.inf, mean)
    i = int(np.argmin(mean))
    win = motion.slice(i, i + W)
    trans = win.trans.copy()
    trans[:, [0, 2]] -= trans[:1, [0, 2]]
    return win.replace(trans=trans, meta={**win.meta, "window": [i, i + W]})


def loop_motion(motion: Motion, num_frames: int) -> Motion:
    """Extend or crop to ``num_frames`` by playing the clip forward, then backward, and
    so on (a back-and-forth loop is continuous in pose; velocity flips at the turns)."""
    T = motion.num_frames
    if num_frames < 1:
        raise MotionValueError(f"num_frames must be >= 1, got {num_frames}")
    if T == 1:
        idx = np.zeros(num_frames, np.int64)
    else:
        period = 2 * (T - 1)
        k = np.arange(num_frames) % period
        idx = np.where(k < T, k, period - k)
    return motion.replace(
        poses=motion.poses[idx],
        trans=motion.trans[idx],
        contacts=None if motion.contacts is None else motion.contacts[idx],
    )


def load_base_motions(
    data_dir: str | Path | None = None,
    names: tuple[str, ...] = BASE_CLIPS,
    *,
    fps: float = 25.0,
    seconds: float = 1.5,
    body=None,
) -> list[Motion]:
    """The standing base clips: each of ``names`` read from the Bandai Namco dataset
    (``data_dir``, default ``$MRLIB_DATA_DIR``), cut to its calmest resting
    ``seconds`` (``quiet_window``) and resampled to ``fps``.

    Raises:
        MotionFileError: the dataset or a clip is missing (with where it looked).
    """
    root = default_data_dir(data_dir)
    folder = root / "data" if (root / "data").is_dir() else root
    if not folder.is_dir():
        raise MotionFileError(
            folder,
            "Bandai Namco motion dataset not found; set MRLIB_DATA_DIR or pass data_dir "
            "(https://github.com/BandaiNamcoResearchInc/Bandai-Namco-Research-Motiondataset)",
        )
    out = []
    for name in names:
        m = load_motion(folder / f"{name}.bvh", body=body)
        out.append(quiet_window(m, seconds, body).resample(fps).replace(name=name))
    return out


def standing_base(seconds: float = 2.0, fps: float = 25.0, seed: int = 0) -> Motion:
    """A procedural standing pose (arms hanging, slow breathing sway): a base for the
    synthetic gestures that needs no data. Pelvis at 0.9 m; feet are not pinned."""
    rng = np.random.default_rng(seed)
    T = max(2, int(round(seconds * fps)))
    t = np.arange(T) / fps
    d = np.deg2rad
    poses = np.zeros((T, 24, 3))
    poses[:, J["left_shoulder"], 2] = -d(72)  # arms down from the T-pose
    poses[:, J["right_shoulder"], 2] = d(72)
    poses[:, J["left_elbow"], 1] = -d(8)
    poses[:, J["right_elbow"], 1] = d(8)
    sway = d(1.5) * np.sin(2 * np.pi * rng.uniform(0.2, 0.3) * t + rng.uniform(0, 6.3))
    poses[:, J["spine1"], 2] = sway
    poses[:, J["spine3"], 0] = d(1.0) * np.sin(2 * np.pi * 0.25 * t)  # breathing
    trans = np.tile([0.0, 0.9, 0.0], (T, 1))
    return Motion(poses, trans, fps, name="standing", meta={"synthetic": True})


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
    params: GestureParams = GestureParams(),
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
    params: GestureParams = GestureParams(),
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
    corpus.manifest.write_text(json.dumps(manifest, indent=1))
    return corpus
