"""The motion half of the synthetic co-speech set (``mrlib.speech.synthetic``, whose
docstring gives the whole recipe): a standing base motion, the calmest resting stance
at the end of a Bandai Namco clip (:func:`quiet_window`, :func:`load_base_motions`) or a
procedural one (:func:`standing_base`), looped to an utterance's length
(:func:`loop_motion`), and the rule-based gestures the audio drives
(:func:`gesture_offsets`), added onto it (:func:`apply_offsets`). Every name is also
reachable as ``mrlib.speech.synthetic.<name>``.

Motion derived from the Bandai Namco clips is CC BY-NC 4.0 data; it is never shipped with
mrlib.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from scipy.ndimage import gaussian_filter1d

from mrlib.errors import ClipTooShortError, MotionFileError, MotionValueError
from mrlib.io import default_data_dir, load_motion
from mrlib.representation.body import resolve_body
from mrlib.representation.motion import Motion
from mrlib.representation.rotations import axis_angle_to_matrix, matrix_to_axis_angle
from mrlib.representation.skeleton import JOINT_NAMES
from mrlib.speech.audio import detect_onsets, energy_envelope, onset_strength

__all__ = [
    "BASE_CLIPS",
    "GestureParams",
    "gesture_offsets",
    "apply_offsets",
    "quiet_window",
    "loop_motion",
    "load_base_motions",
    "standing_base",
]


J = {name: i for i, name in enumerate(JOINT_NAMES)}

# Bandai Namco clips that end in a calm resting stance (``quiet_window`` finds 1.5 s
# with mean wrist speed 0.04-0.11 m/s, arms down, torso upright); file stems in the
# dataset's data/ folder. Chosen by scanning the bow/bye/byebye/guide/call/respond clips.
BASE_CLIPS: tuple[str, ...] = (
    "dataset-1_byebye_sad_001",
    "dataset-1_bow_sad_001",
    "dataset-1_guide_sad_001",
    "dataset-1_bye_sad_001",
)


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
