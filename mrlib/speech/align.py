"""From 50 fps speech features to the per-level conditions of the multi-resolution GAN.

The paper (Sec. 6, Fig. 6): speech features at ~50 fps are linearly interpolated in time
to the motion frame rate (25 fps there), then downsampled to the length of every pyramid
level, giving ``s~_1 .. s~_L`` (level 1 coarsest, level L = the motion's own rate);
finer levels are then turned into residuals,

    s_1 = s~_1,        s_i = up(s~_{i-1}) - s~_i   for i > 1,

so that each level carries only what its coarser neighbour does not (the paper writes
``s~_{i-1} - s~_i``; the two sequences have different lengths, so the coarser one is
first brought to ``T_i`` frames by ``up`` = linear interpolation,
``mrlib.model.pyramid.resample_linear``, the same operator the generator upsamples its
motion with). ``residuals_to_levels`` inverts this exactly: ``s~_i = up(s~_{i-1}) - s_i``.

Shapes: one clip's features are ``(T, D)`` (frames first, as the GAN's conditions
``(B, T_i, D)`` are); L levels of lengths ``T_1 < ... < T_L``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F

from mrlib.errors import MotionValueError
from mrlib.model.config import SPEECH_NUM_LEVELS
from mrlib.model.pyramid import pyramid_lengths, resample_linear

__all__ = [
    "interpolate_to_fps",
    "downsample_levels",
    "align_to_levels",
    "levels_to_residuals",
    "residuals_to_levels",
    "SpeechNormalizer",
    "speech_conditions",
    "level_lengths",
    "motion_frames_for_audio",
    "stack_conditions",
]


def _check_features(features: torch.Tensor, what: str = "features") -> torch.Tensor:
    f = torch.as_tensor(features)
    if f.ndim != 2 or f.shape[0] < 1:
        raise MotionValueError(f"{what} must have shape (T, D) with T >= 1, got {tuple(f.shape)}")
    if not torch.is_floating_point(f):
        f = f.float()
    if not torch.isfinite(f).all():
        raise MotionValueError(f"{what} have NaN or inf values")
    return f


def interpolate_to_fps(
    features: torch.Tensor,
    src_fps: float,
    dst_fps: float,
    num_frames: int,
    *,
    offset_s: float = 0.0,
) -> torch.Tensor:
    """Linear interpolation in time of ``(T_a, D)`` features onto ``num_frames`` frames.

    Source frame k is at time ``k / src_fps + offset_s`` (``offset_s`` = 12.5 ms for
    mrlib's speech features: the centre of the first window); output frame j is at
    ``j / dst_fps``. Each output is the linear interpolation between the two source
    frames around its time; times before the first or after the last source frame
    take that frame's value (the edge is held, never extrapolated).

    Returns:
        ``(num_frames, D)``, the dtype of ``features``.
    """
    f = _check_features(features)
    if not (src_fps > 0 and dst_fps > 0):
        raise MotionValueError(f"frame rates must be positive, got {src_fps} and {dst_fps}")
    if num_frames < 1:
        raise MotionValueError(f"num_frames must be >= 1, got {num_frames}")
    Ta = f.shape[0]
    t = torch.arange(num_frames, dtype=torch.float64) / dst_fps
    pos = ((t - offset_s) * src_fps).clamp(0, Ta - 1)  # fractional source index
    i0 = pos.floor().long().clamp(max=Ta - 1)
    i1 = (i0 + 1).clamp(max=Ta - 1)
    w = (pos - i0).to(f.dtype)[:, None]
    return torch.lerp(f[i0], f[i1], w)


def _interpolate_naive(features, src_fps, dst_fps, num_frames, offset_s=0.0) -> np.ndarray:
    """Frame-by-frame reference of ``interpolate_to_fps`` (numpy ``np.interp`` per channel)."""
    f = np.asarray(features, np.float64)
    ts = np.arange(len(f)) / src_fps + offset_s
    t = np.arange(num_frames) / dst_fps
    return np.stack([np.interp(t, ts, f[:, d]) for d in range(f.shape[1])], 1)


def downsample_levels(
    finest: torch.Tensor, lengths: list[int], method: str = "area"
) -> list[torch.Tensor]:
    """``finest (T_L, D)`` -> ``[(T_1, D), ..., (T_L, D)]``, each level resampled from
    the finest one (not from its neighbour).

    ``method``: ``"area"`` (default) averages the finest frames each coarse frame spans
    (``F.interpolate(mode="area")``, a box low-pass), so a coarse level summarises the
    speech in its interval instead of sampling it; ``"linear"`` is the motion pyramid's
    operator (``mrlib.model.pyramid.build_pyramid``, point sampling at large ratios). The
    paper only says "downsample"; area is our choice for features that change much
    faster than the coarse levels' frame rates (level 1 of 10 is ~1.9 fps at 25 fps).
    """
    f = _check_features(finest)
    lengths = [int(n) for n in lengths]
    if not lengths or lengths[-1] != f.shape[0]:
        raise MotionValueError(
            f"the finest level must have the features' {f.shape[0]} frames, got lengths {lengths}"
        )
    if any(b <= a for a, b in zip(lengths, lengths[1:], strict=False)) or lengths[0] < 1:
        raise MotionValueError(f"level lengths must be positive and increasing, got {lengths}")
    if method not in ("area", "linear"):
        raise MotionValueError(f"method must be 'area' or 'linear', got {method!r}")
    x = f.T[None]  # (1, D, T_L)
    out = []
    for n in lengths:
        if n == f.shape[0]:
            y = x
        elif method == "area":
            y = F.interpolate(x, size=n, mode="area")
        else:
            y = resample_linear(x, n)
        out.append(y[0].T.contiguous())
    return out


def align_to_levels(
    features: torch.Tensor,
    audio_fps: float,
    motion_fps: float,
    lengths: list[int],
    *,
    offset_s: float = 0.0,
    method: str = "area",
) -> list[torch.Tensor]:
    """Speech features onto every level of a motion pyramid: ``[s~_1, ..., s~_L]``.

    Step 1, ``interpolate_to_fps``: ``(T_a, D)`` at ``audio_fps`` -> ``(T_L, D)`` at
    ``motion_fps`` with ``T_L = lengths[-1]`` (motion frame j at ``j / motion_fps``).
    Step 2, ``downsample_levels``: the finest level -> every ``T_i``.

    Args:
        features: ``(T_a, D)``.
        lengths: ``[T_1, ..., T_L]`` of the motion pyramid (``mrlib.model.pyramid.pyramid_lengths``).
        offset_s: time of feature frame 0 (``SpeechFeatureExtractor.frame_offset_s``).
        method: downsampling, see ``downsample_levels``.
    Returns:
        ``[(T_1, D), ..., (T_L, D)]``.
    """
    finest = interpolate_to_fps(
        features, audio_fps, motion_fps, int(lengths[-1]), offset_s=offset_s
    )
    return downsample_levels(finest, lengths, method)


def levels_to_residuals(levels: list[torch.Tensor]) -> list[torch.Tensor]:
    """``[s~_1, ..., s~_L]`` -> ``[s_1, ..., s_L]``: ``s_1 = s~_1``,
    ``s_i = up(s~_{i-1}) - s~_i`` with ``up`` linear interpolation (``align_corners=False``)
    of ``(T_{i-1}, D)`` to ``(T_i, D)``. Shapes are unchanged."""
    if not levels:
        raise MotionValueError("need at least one level")
    out = [levels[0]]
    for prev, cur in zip(levels[:-1], levels[1:], strict=False):
        out.append(resample_linear(prev.T[None], cur.shape[0])[0].T - cur)
    return out


def residuals_to_levels(residuals: list[torch.Tensor]) -> list[torch.Tensor]:
    """Inverse of ``levels_to_residuals``: ``s~_1 = s_1``, ``s~_i = up(s~_{i-1}) - s_i``."""
    if not residuals:
        raise MotionValueError("need at least one level")
    out = [residuals[0]]
    for res in residuals[1:]:
        out.append(resample_linear(out[-1].T[None], res.shape[0])[0].T - res)
    return out


# -- normalisation ------------------------------------------------------------------------------
@dataclass(frozen=True)
class SpeechNormalizer:
    """Per-dimension standardisation ``(x - mean) / std`` of speech features, fitted on all
    frames of the training audio (paired and unpaired) and saved with the model.

    Attributes:
        mean, std: ``(D,)`` float32 tensors.
    """

    mean: torch.Tensor
    std: torch.Tensor

    @classmethod
    def fit(cls, features: list[torch.Tensor] | torch.Tensor, min_std: float = 1e-3):
        """Statistics over every frame of every clip ``[(T_b, D)]``; ``min_std`` floors
        near-constant dimensions so they are not blown up."""
        xs = features if isinstance(features, (list, tuple)) else [features]
        if not xs:
            raise MotionValueError("SpeechNormalizer.fit needs at least one clip")
        xs = [_check_features(x) for x in xs]
        dims = {x.shape[1] for x in xs}
        if len(dims) != 1:
            raise MotionValueError(f"clips have different feature sizes {sorted(dims)}")
        allx = torch.cat(xs).double()
        std = allx.std(0) if len(allx) > 1 else torch.zeros(allx.shape[1], dtype=torch.float64)
        return cls(allx.mean(0).float(), std.clamp_min(min_std).float())

    @property
    def dim(self) -> int:
        return int(self.mean.shape[0])

    def _check(self, x: torch.Tensor) -> None:
        if x.shape[-1] != self.dim:
            raise MotionValueError(
                f"features have {x.shape[-1]} dimensions, the normaliser was fitted on {self.dim}"
            )

    def normalize(self, x: torch.Tensor) -> torch.Tensor:
        """``(..., D)`` -> ``(..., D)``."""
        self._check(x)
        return (x - self.mean.to(x)) / self.std.to(x)

    def denormalize(self, x: torch.Tensor) -> torch.Tensor:
        self._check(x)
        return x * self.std.to(x) + self.mean.to(x)

    def state_dict(self) -> dict[str, torch.Tensor]:
        return {"mean": self.mean.clone(), "std": self.std.clone()}

    @classmethod
    def from_state_dict(cls, d: dict) -> SpeechNormalizer:
        return cls(torch.as_tensor(d["mean"]).float(), torch.as_tensor(d["std"]).float())


# -- what the GAN consumes ----------------------------------------------------------------------
def level_lengths(num_frames: int, model_config) -> list[int]:
    """Frames ``[T_1, ..., T_L]`` of every level for a clip of ``num_frames`` motion frames
    under a ``mrlib.model.config.ModelConfig`` (its L, F and the shortest level its kernels
    accept)."""
    mc = model_config
    return pyramid_lengths(
        int(num_frames), mc.num_levels, mc.scale_factor, min_length=(mc.kernel_size - 1) // 2 + 1
    )


def motion_frames_for_audio(num_feature_frames: int, audio_fps: float, motion_fps: float) -> int:
    """Motion frames covering ``num_feature_frames`` speech frames (unpaired audio has no
    motion to take the length from): ``round(T_a * motion_fps / audio_fps)``."""
    return max(1, int(round(num_feature_frames * motion_fps / audio_fps)))


def speech_conditions(
    features: torch.Tensor,
    audio_fps: float,
    motion_fps: float,
    lengths: list[int] | None = None,
    *,
    num_levels: int = SPEECH_NUM_LEVELS,
    scale_factor: float = 4 / 3,
    normalizer: SpeechNormalizer | None = None,
    offset_s: float = 0.0,
    method: str = "area",
    residual: bool = True,
) -> list[torch.Tensor]:
    """The per-level speech conditions of one clip, as the generator consumes them.

    normalise -> ``align_to_levels`` -> ``levels_to_residuals`` (if ``residual``).

    Args:
        features: ``(T_a, D)`` raw features at ``audio_fps``.
        lengths: the clip's pyramid lengths ``[T_1..T_L]``; default
            ``pyramid_lengths(motion_frames_for_audio(T_a, ...), num_levels, scale_factor)``.
        normalizer: applied to the raw features first (None: none).
    Returns:
        ``[(T_1, D), ..., (T_L, D)]`` float32.
    """
    f = _check_features(features).float()
    if normalizer is not None:
        f = normalizer.normalize(f)
    if lengths is None:
        T = motion_frames_for_audio(f.shape[0], audio_fps, motion_fps)
        lengths = pyramid_lengths(T, num_levels, scale_factor)
    levels = align_to_levels(f, audio_fps, motion_fps, lengths, offset_s=offset_s, method=method)
    return levels_to_residuals(levels) if residual else levels


def stack_conditions(
    clips: list[list[torch.Tensor]],
) -> tuple[list[torch.Tensor], torch.Tensor]:
    """Batch the conditions of several clips.

    Args:
        clips: per clip, the list ``[(T_{b,1}, D), ..., (T_{b,L}, D)]``.
    Returns:
        per level a padded ``(B, max_b T_{b,i}, D)`` tensor (frames past a clip's length
        repeat its last frame), and the ``(B, L)`` table of valid lengths.
    """
    if not clips:
        raise MotionValueError("need at least one clip")
    L = len(clips[0])
    if any(len(c) != L for c in clips):
        raise MotionValueError(
            f"every clip needs the same number of levels, got {[len(c) for c in clips]}"
        )
    table = torch.tensor([[c[i].shape[0] for i in range(L)] for c in clips], dtype=torch.long)
    out = []
    for i in range(L):
        size = int(table[:, i].max())
        out.append(
            torch.stack(
                [torch.cat([c[i], c[i][-1:].expand(size - c[i].shape[0], -1)]) for c in clips]
            )
        )  # (B, T_max, D)
    return out, table
