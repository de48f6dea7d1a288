"""Speech training data: paired speech + motion and unpaired speech, from folders, and the
training set a speech-conditioned model learns from.

Folder layouts: ``load_paired_folder`` reads ``<stem>.wav`` next to ``<stem>.npz`` /
``<stem>.bvh``; ``load_unpaired_folder`` reads ``.wav`` / ``.flac`` only. Their clips make a
:class:`SpeechTrainingSet` (``from_clips``, or ``from_folders`` in one step): the paired
clips' motion as an ordinary ``mrlib.training.data.TrainingSet`` (every clip labelled
``SPEECH_LABEL``), the raw speech features of every clip, and the speech normaliser.

Shapes: T_a speech frames at ``audio_fps`` (50), D speech feature size, T motion frames.
"""

from __future__ import annotations

import json
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path

import torch

from mrlib.errors import ClipTooShortError, MotionFileError, MotionValueError
from mrlib.representation.motion import Motion
from mrlib.speech.align import SpeechNormalizer, interpolate_to_fps
from mrlib.speech.audio import FEATURE_FPS, FRAME_OFFSET_S, AudioFileError, load_audio
from mrlib.speech.features import SpeechFeatureConfig, SpeechFeatureExtractor
from mrlib.speech.split import HeldOutSpeech
from mrlib.training.data import TrainingSet

__all__ = [
    "SPEECH_LABEL",
    "AUDIO_EXTENSIONS",
    "MOTION_EXTENSIONS",
    "SpeechClip",
    "SpeechMotionPair",
    "load_paired_folder",
    "load_unpaired_folder",
    "SpeechTrainingSet",
    "split_pair",
]

SPEECH_LABEL = "speech"  # the one label every paired clip carries (sigma is averaged over them)


# -- folders -------------------------------------------------------------------------------
AUDIO_EXTENSIONS = (".wav", ".flac", ".ogg", ".mp3", ".aiff", ".aif")  # what load_audio reads
MOTION_EXTENSIONS = (".npz", ".bvh")


@dataclass
class SpeechClip:
    """Features of one unpaired utterance.

    Attributes:
        name: file stem; features: ``(T_a, D)`` at ``fps``; frame_offset_s: time of
        frame 0; duration: seconds of audio; audio_path.
    """

    name: str
    features: torch.Tensor
    fps: float
    frame_offset_s: float
    duration: float
    audio_path: Path


@dataclass
class SpeechMotionPair(SpeechClip):
    """A :class:`SpeechClip` with its ``motion`` (a ``Motion``) and ``motion_path``."""

    motion: Motion | None = None
    motion_path: Path | None = None


def _default_extractor(extractor):
    return extractor if extractor is not None else SpeechFeatureExtractor()


def _audio_files(folder: Path) -> list[Path]:
    if not folder.is_dir():
        raise AudioFileError(folder, "no such folder")
    return sorted(p for p in folder.iterdir() if p.suffix.lower() in AUDIO_EXTENSIONS)


def _clip(path: Path, extractor, min_seconds: float) -> SpeechClip:
    wav, sr = load_audio(path, min_seconds=min_seconds)
    try:
        feats = extractor(wav, sr)
    except ClipTooShortError as e:
        raise AudioFileError(path, str(e)) from None
    return SpeechClip(
        path.stem, feats, extractor.fps, extractor.frame_offset_s, len(wav) / sr, path
    )


def load_unpaired_folder(
    folder: str | Path, extractor=None, *, min_seconds: float = 1.0
) -> list[SpeechClip]:
    """Features of every ``.wav``/``.flac`` file in ``folder`` (sorted by name).

    Args:
        extractor: a ``SpeechFeatureExtractor`` (default: WavLM, which needs weights).
        min_seconds: refuse clips shorter than this (a 10-level pyramid at 25 fps
            needs about 1.6 s of motion).
    Raises:
        AudioFileError: no such folder, no audio in it, or a file that is unreadable,
            below 8 kHz, or too short.
    """
    folder = Path(folder)
    files = _audio_files(folder)
    if not files:
        raise AudioFileError(
            folder, f"no audio files ({', '.join(AUDIO_EXTENSIONS)}) in the folder"
        )
    ex = _default_extractor(extractor)
    return [_clip(p, ex, min_seconds) for p in files]


def load_paired_folder(
    folder: str | Path,
    extractor=None,
    *,
    motion_dir: str | Path | None = None,
    motion_fps: float | None = None,
    max_mismatch_s: float = 1.0,
    min_seconds: float = 1.0,
    strict: bool = True,
    body=None,
    up_axis: str | None = None,
) -> list[SpeechMotionPair]:
    """Paired speech and motion: every ``<stem>.wav`` in ``folder`` with the motion
    file of the same stem (``<stem>.npz``: SMPL/AMASS-style or mrlib's, or
    ``<stem>.bvh``, retargeted) in ``motion_dir`` (default: the same folder).

    Args:
        extractor: a ``SpeechFeatureExtractor`` (default: WavLM).
        motion_fps: resample motion to this rate (the paper uses 25 fps); None keeps it.
        max_mismatch_s: refuse pairs whose audio and motion durations differ by more
            (a sign of a wrong pairing or a cut recording); within it, both are cut to
            the shorter from their start (BEAT2's audio runs ~0.6 s past its motion).
        strict: raise on an unpaired file; False skips it with a warning.
        up_axis: the motion files' up axis (``mrlib.io.load_motion``; default: an npz's
            key, else told from the body).
    Raises:
        AudioFileError / MotionFileError: missing partner file (strict), a stem with
            both ``.npz`` and ``.bvh``, unreadable or too short files, mismatched
            durations.
    """
    from mrlib.io import load_motion

    folder = Path(folder)
    mdir = folder if motion_dir is None else Path(motion_dir)
    if not mdir.is_dir():
        raise MotionFileError(mdir, "no such folder")
    audio: dict[str, Path] = {}
    for p in _audio_files(folder):
        if p.stem in audio:  # c.wav and c.flac: which one is the take's?
            raise AudioFileError(p, f"ambiguous partner: {audio[p.stem].name} and {p.name}")
        audio[p.stem] = p
    motions: dict[str, list[Path]] = {}
    for p in sorted(mdir.iterdir()):
        if p.suffix.lower() in MOTION_EXTENSIONS:
            motions.setdefault(p.stem, []).append(p)
    problems = []
    for stem in sorted(set(audio) - set(motions)):
        problems.append((audio[stem], f"no motion file {stem}.npz or {stem}.bvh in {mdir}"))
    for stem in sorted(set(motions) - set(audio)):
        problems.append((motions[stem][0], f"no audio file {stem}.wav in {folder}"))
    if problems:
        if strict:
            path, why = problems[0]
            more = f" (and {len(problems) - 1} more unpaired files)" if len(problems) > 1 else ""
            raise MotionFileError(
                path,
                f"missing partner: {why}{more}; to train on the pairs alone: "
                "--skip-unpaired-files on the command line, strict=False in Python",
            )
        for path, why in problems:
            warnings.warn(f"{path}: skipped, {why}", stacklevel=2)
    stems = sorted(set(audio) & set(motions))
    if not stems:
        raise MotionFileError(folder, "no audio/motion pairs with the same stem")
    ex = _default_extractor(extractor)
    out = []
    for stem in stems:
        if len(motions[stem]) > 1:
            raise MotionFileError(
                motions[stem][0], f"ambiguous partner: {[p.name for p in motions[stem]]}"
            )
        mpath = motions[stem][0]
        motion = load_motion(mpath, motion_fps, body=body, up_axis=up_axis)
        clip = _clip(audio[stem], ex, min_seconds)
        gap = abs(clip.duration - motion.duration)
        if gap > max_mismatch_s:
            raise MotionFileError(
                mpath,
                f"motion lasts {motion.duration:.2f} s but {audio[stem].name} lasts "
                f"{clip.duration:.2f} s (more than {max_mismatch_s:g} s apart): wrong pair "
                "or a cut recording? (to accept: --max-mismatch SECONDS on the command line, "
                "max_mismatch_s= in Python)",
            )
        clip, motion = _trim_to_common(clip, motion)
        out.append(SpeechMotionPair(**vars(clip), motion=motion, motion_path=mpath))
    return out


def _trim_to_common(
    clip: SpeechClip, motion: Motion, seconds: float | None = None
) -> tuple[SpeechClip, Motion]:
    """Audio and motion cut to the shorter of the two (or to ``seconds``), both from their
    start (BEAT2's audio usually runs ~0.6 s past its motion; recordings start together)."""
    seconds = min(clip.duration, motion.duration, seconds or float("inf"))
    if clip.duration > seconds:
        frames = max(1, int(round((seconds - clip.frame_offset_s) * clip.fps)) + 1)
        clip = replace(clip, features=clip.features[:frames], duration=seconds)
    frames = int(round(seconds * motion.fps))
    if motion.num_frames > frames >= 2:
        motion = motion.slice(0, frames)
    return clip, motion


def split_pair(pair: SpeechMotionPair, tail_s: float) -> tuple[SpeechMotionPair, HeldOutSpeech]:
    """One recording, two parts: the pair up to its last ``tail_s`` seconds (to train on)
    and those last seconds, audio and motion (held out: a model is judged on speech it
    never heard, next to the motion that was captured with it).

    Raises:
        MotionValueError: ``tail_s`` not positive, or leaving under 2 s on either side.
    """
    if pair.motion is None:
        raise MotionValueError(f"{pair.name}: no motion to split")
    total = min(pair.duration, pair.motion.duration)
    if not tail_s > 0 or total - tail_s < 2.0 or tail_s < 2.0:
        raise MotionValueError(
            f"tail_s={tail_s}: {pair.name} lasts {total:.1f} s; both parts need at least 2 s"
        )
    cut = total - tail_s
    clip, motion = _trim_to_common(pair, pair.motion, cut)
    head = SpeechMotionPair(**{**vars(clip), "motion": motion, "motion_path": pair.motion_path})
    wav, sr = load_audio(pair.audio_path)
    start = int(round(motion.num_frames / motion.fps * sr))
    frames = int(round(tail_s * pair.motion.fps))
    tail_motion = pair.motion.slice(motion.num_frames, motion.num_frames + frames)
    tail_wav = wav[start : start + int(round(tail_motion.duration * sr))]
    name = f"{pair.name} (last {tail_s:g} s)"
    return head, HeldOutSpeech(name, tail_wav, sr, tail_motion, Path(pair.audio_path))


# -- the training set ----------------------------------------------------------------------
def _check_clip_features(f, what: str) -> torch.Tensor:
    f = torch.as_tensor(f, dtype=torch.float32)
    if f.ndim != 2 or f.shape[0] < 1:
        raise MotionValueError(f"{what} must have shape (T_a, D), got {tuple(f.shape)}")
    if not torch.isfinite(f).all():
        raise MotionValueError(f"{what} has NaN or inf values")
    return f


@dataclass
class SpeechTrainingSet:
    """Paired speech + motion clips and unpaired speech for one speech-conditioned model.

    Attributes:
        motion: the paired clips' motion (a ``TrainingSet``, every clip labelled
            ``SPEECH_LABEL``); clip k goes with ``paired_features[k]``.
        paired_features: N raw feature tensors ``(T_a,k, D)`` at ``audio_fps``.
        unpaired_features: M raw feature tensors ``(T_a,u, D)``.
        unpaired_frames: motion frames (at ``motion.fps``) each unpaired clip spans.
        normalizer: fitted on every frame of paired and unpaired audio.
        feature_config: how the features were computed (saved with the model, used again
            at generation time).
        audio_fps, frame_offset_s: the features' frame rate and the time of frame 0.
        downsample: ``"area"`` or ``"linear"`` (``mrlib.speech.downsample_levels``).
        unpaired_names: file stems of the unpaired clips.
    """

    motion: TrainingSet
    paired_features: list[torch.Tensor]
    unpaired_features: list[torch.Tensor]
    unpaired_frames: list[int]
    normalizer: SpeechNormalizer
    feature_config: SpeechFeatureConfig
    audio_fps: float = FEATURE_FPS
    frame_offset_s: float = FRAME_OFFSET_S
    downsample: str = "area"
    unpaired_names: list[str] = field(default_factory=list)

    def __post_init__(self):
        self.paired_features = [
            _check_clip_features(f, f"paired clip {k} features")
            for k, f in enumerate(self.paired_features)
        ]
        self.unpaired_features = [
            _check_clip_features(f, f"unpaired clip {k} features")
            for k, f in enumerate(self.unpaired_features)
        ]
        if len(self.paired_features) != self.motion.num_clips:
            raise MotionValueError(
                f"{self.motion.num_clips} motion clips but {len(self.paired_features)} "
                "paired feature tensors"
            )
        dims = {f.shape[1] for f in self.paired_features + self.unpaired_features}
        if len(dims) != 1:
            raise MotionValueError(f"speech clips have different feature sizes {sorted(dims)}")
        if self.normalizer.dim not in dims:
            raise MotionValueError(
                f"the normaliser has {self.normalizer.dim} dimensions, the features {dims}"
            )
        if len(self.unpaired_frames) != len(self.unpaired_features):
            raise MotionValueError("unpaired_frames needs one entry per unpaired clip")
        if any(int(n) < 1 for n in self.unpaired_frames):
            raise MotionValueError(f"unpaired_frames must be >= 1, got {self.unpaired_frames}")
        self.unpaired_frames = [int(n) for n in self.unpaired_frames]
        if not self.unpaired_names:
            self.unpaired_names = [f"unpaired{u}" for u in range(len(self.unpaired_features))]
        if self.downsample not in ("area", "linear"):
            raise MotionValueError(
                f"downsample must be 'area' or 'linear', got {self.downsample!r}"
            )
        if set(self.motion.labels) != {SPEECH_LABEL}:
            raise MotionValueError(
                f"every paired clip must carry the label {SPEECH_LABEL!r}, got {self.motion.labels}"
            )

    # -- construction ----------------------------------------------------------------------
    @classmethod
    def from_clips(
        cls,
        paired,
        unpaired=(),
        feature_config: SpeechFeatureConfig | None = None,
        *,
        fps: float | None = None,
        body=None,
        downsample: str = "area",
    ) -> SpeechTrainingSet:
        """From the clips of the folder loaders: ``paired`` ``SpeechMotionPair`` s (features +
        motion) and ``unpaired`` ``SpeechClip`` s; motion resampled to ``fps`` (default
        the first pair's). ``feature_config``: the extractor's config (stored with the
        model so generation computes the same features)."""
        paired, unpaired = list(paired), list(unpaired)
        if not paired:
            raise MotionValueError("a speech training set needs at least one paired clip")
        fps = float(paired[0].motion.fps if fps is None else fps)
        rates = {float(c.fps) for c in paired + unpaired}
        offsets = {float(c.frame_offset_s) for c in paired + unpaired}
        if len(rates) != 1 or len(offsets) != 1:
            raise MotionValueError(f"speech clips have different frame grids: {rates}, {offsets}")
        motions = [p.motion.replace(label=SPEECH_LABEL, name=p.name) for p in paired]
        motion = TrainingSet.from_motions(motions, [SPEECH_LABEL] * len(motions), fps, body)
        feats = [p.features for p in paired] + [u.features for u in unpaired]
        return cls(
            motion=motion,
            paired_features=[p.features for p in paired],
            unpaired_features=[u.features for u in unpaired],
            unpaired_frames=[max(1, int(round(u.duration * fps))) for u in unpaired],
            normalizer=SpeechNormalizer.fit(list(feats)),
            feature_config=feature_config or SpeechFeatureConfig(kind="logmel"),
            audio_fps=rates.pop(),
            frame_offset_s=offsets.pop(),
            downsample=downsample,
            unpaired_names=[u.name for u in unpaired],
        )

    @classmethod
    def from_folders(
        cls,
        paired_dir: str | Path,
        unpaired_dir: str | Path | None = None,
        extractor: SpeechFeatureExtractor | None = None,
        *,
        fps: float = 25.0,
        body=None,
        downsample: str = "area",
        max_mismatch_s: float = 1.0,
        up_axis: str | None = None,
        strict: bool = True,
    ) -> SpeechTrainingSet:
        """``paired_dir``: ``<stem>.wav`` + ``<stem>.npz|.bvh`` (``load_paired_folder``,
        which refuses a pair whose durations differ by more than ``max_mismatch_s``);
        ``unpaired_dir``: ``.wav`` files (``load_unpaired_folder``). ``extractor``
        defaults to WavLM (needs local weights); motion is resampled to ``fps`` (the
        paper uses 25)."""
        ex = extractor if extractor is not None else SpeechFeatureExtractor()
        pairs = load_paired_folder(
            paired_dir, ex, motion_fps=fps, body=body, max_mismatch_s=max_mismatch_s,
            up_axis=up_axis, strict=strict,
        )  # fmt: skip
        unpaired = [] if unpaired_dir is None else load_unpaired_folder(unpaired_dir, ex)
        return cls.from_clips(pairs, unpaired, ex.config, fps=fps, body=body, downsample=downsample)

    # -- views -----------------------------------------------------------------------------
    @property
    def dim(self) -> int:
        return int(self.paired_features[0].shape[1])

    @property
    def fps(self) -> float:
        return float(self.motion.fps)

    @property
    def num_paired(self) -> int:
        return len(self.paired_features)

    @property
    def num_unpaired(self) -> int:
        return len(self.unpaired_features)

    def finest(self) -> tuple[list[torch.Tensor], list[str]]:
        """Every audio clip's normalised features at the motion frame rate (level L before
        downsampling): paired clips first (``(T_k, D)``, T_k = the motion's frames), then
        unpaired ones (``(unpaired_frames[u], D)``); and ``"paired"``/``"unpaired"`` per
        clip."""
        frames = self.motion.lengths + self.unpaired_frames
        feats = self.paired_features + self.unpaired_features
        out = [
            interpolate_to_fps(
                self.normalizer.normalize(f),
                self.audio_fps,
                self.fps,
                n,
                offset_s=self.frame_offset_s,
            )
            for f, n in zip(feats, frames, strict=True)
        ]
        return out, ["paired"] * self.num_paired + ["unpaired"] * self.num_unpaired

    def speech_state(self) -> dict:
        """What a checkpoint stores under ``"speech"`` (tensors, lists and strings only)."""
        return {
            "feature_config": json.dumps(self.feature_config.to_dict(), sort_keys=True),
            "normalizer": self.normalizer.state_dict(),
            "dim": self.dim,
            "audio_fps": float(self.audio_fps),
            "frame_offset_s": float(self.frame_offset_s),
            "downsample": self.downsample,
            "paired_features": [f.clone() for f in self.paired_features],
            "unpaired_features": [f.clone() for f in self.unpaired_features],
            "unpaired_frames": list(self.unpaired_frames),
            "unpaired_names": list(self.unpaired_names),
        }

    @classmethod
    def from_state(cls, state: dict) -> SpeechTrainingSet:
        """Rebuild from a checkpoint's state dict (see :meth:`speech_state`)."""
        sp = state["speech"]
        motion = TrainingSet.from_state(state)
        return cls(
            motion=motion,
            paired_features=list(sp["paired_features"]),
            unpaired_features=list(sp["unpaired_features"]),
            unpaired_frames=list(sp["unpaired_frames"]),
            normalizer=SpeechNormalizer.from_state_dict(sp["normalizer"]),
            feature_config=SpeechFeatureConfig.from_dict(json.loads(sp["feature_config"])),
            audio_fps=float(sp["audio_fps"]),
            frame_offset_s=float(sp["frame_offset_s"]),
            downsample=str(sp["downsample"]),
            unpaired_names=list(sp["unpaired_names"]),
        )

    def __repr__(self) -> str:
        return (
            f"SpeechTrainingSet({self.num_paired} paired, {self.num_unpaired} unpaired, "
            f"D={self.dim}, {self.feature_config.kind}, fps={self.fps:g})"
        )
