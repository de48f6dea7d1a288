"""Temporal pyramids: level lengths, linear resampling, data pyramids and noise amplitudes.

Level ``i`` (1-based, ``1 <= i <= L``) of a clip of ``T`` frames has about
``T / F**(L - i)`` frames: level ``L`` is the clip itself, every coarser level is the
clip linearly resampled by a further factor ``F`` (``F = 4/3`` in the paper and in
GANimator). A level is a clip at a lower frame rate, ``fps_i = fps * T_i / T_L``.

Batches mix clips of different lengths, so every function here also has a *ragged*
form: a padded tensor ``(B, C, T_max)`` plus the valid length of each sample
``lengths (B,)``. Frames past a sample's length are padding; the ragged functions
never read them, so each sample is processed exactly as if it were alone.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import torch
import torch.nn.functional as F

from mrlib.errors import ClipTooShortError, MotionValueError

__all__ = [
    "pyramid_lengths",
    "level_fps",
    "resample_linear",
    "resample_linear_ragged",
    "build_pyramid",
    "noise_amplitudes",
    "pad_stack",
    "length_mask",
    "reflect_pad_index",
    "RaggedLevels",
]


def pyramid_lengths(
    length: int, num_levels: int, factor: float = 4 / 3, min_length: int = 3
) -> list[int]:
    """Frame counts ``[T_1, ..., T_L]`` of an ``L``-level pyramid whose finest level has
    ``length`` frames: ``T_i = round(length / factor**(L - i))``, made strictly increasing.

    GANimator builds its pyramid upwards from ``T/5`` until it reaches ``T`` (so the number
    of levels depends on the clip); the paper fixes the number of levels instead (L = 8
    for labels), which is what this function does. ``min_length`` is the shortest level
    the networks accept (reflect padding needs more frames than its pad width).
    """
    if num_levels < 1:
        raise MotionValueError(f"num_levels must be >= 1, got {num_levels}")
    if not factor > 1:
        raise MotionValueError(f"scale factor must be > 1, got {factor}")
    lengths = [max(1, round(length / factor ** (num_levels - 1 - k))) for k in range(num_levels)]
    lengths[-1] = int(length)
    for k in range(num_levels - 2, -1, -1):  # strictly increasing from coarse to fine
        lengths[k] = min(lengths[k], lengths[k + 1] - 1)
    if lengths[0] < min_length:
        need = math.ceil(min_length * factor ** (num_levels - 1))
        raise ClipTooShortError(
            f"a clip of {length} frames gives a coarsest level of {lengths[0]} frames with "
            f"{num_levels} levels and factor {factor:g}; need at least {min_length} "
            f"(use clips of >= {need} frames or fewer levels)"
        )
    return lengths


def level_fps(fps: float, lengths: list[int]) -> list[float]:
    """Frame rate of every level, ``fps_i = fps * T_i / T_L`` (``fps`` of the finest)."""
    return [fps * t / lengths[-1] for t in lengths]


def resample_linear(x: torch.Tensor, size: int) -> torch.Tensor:
    """Linear temporal resampling ``(B, C, T) -> (B, C, size)`` (GANimator's interpolator:
    ``F.interpolate(mode="linear", align_corners=False)``)."""
    if x.ndim != 3:
        raise MotionValueError(f"expected (B, C, T), got shape {tuple(x.shape)}")
    if x.shape[-1] == size:
        return x
    return F.interpolate(x, size=size, mode="linear", align_corners=False)


def _resample_table(lengths_in: torch.Tensor, lengths_out: torch.Tensor, size_out: int):
    """Indices ``i0, i1 (B, 1, size_out)`` and weight ``w (B, 1, size_out)`` of linear
    resampling with ``align_corners=False``: output frame t reads input position
    ``(t + 0.5) * T_in / T_out - 0.5`` (clamped at 0), the convention of ``F.interpolate``."""
    t = torch.arange(size_out, dtype=torch.float64, device=lengths_in.device)
    scale = lengths_in.double() / lengths_out.double()  # (B,)
    src = ((t[None] + 0.5) * scale[:, None] - 0.5).clamp_min(0)  # (B, size_out)
    i0 = src.floor().long()
    last = (lengths_in - 1)[:, None]
    i0 = torch.minimum(i0, last)
    i1 = torch.minimum(i0 + 1, last)
    w = (src - i0).clamp(0, 1)
    return i0[:, None], i1[:, None], w[:, None]


def resample_linear_ragged(
    x: torch.Tensor,
    lengths_in: torch.Tensor,
    lengths_out: torch.Tensor,
    size_out: int | None = None,
    table=None,
) -> torch.Tensor:
    """Per-sample linear resampling of a padded batch.

    Args:
        x: ``(B, C, T_in_max)``; sample b is valid on ``[0, lengths_in[b])``.
        lengths_in, lengths_out: ``(B,)`` int.
        size_out: padded output length (default ``max(lengths_out)``).
        table: precomputed ``_resample_table`` (an optimisation for fixed layouts).
    Returns:
        ``(B, C, size_out)``; sample b equals ``resample_linear(x[b:b+1, :, :T_in_b], T_out_b)``
        on its valid frames. Frames past ``lengths_out[b]`` are finite filler.
    """
    if size_out is None:
        size_out = int(lengths_out.max())
    i0, i1, w = table if table is not None else _resample_table(lengths_in, lengths_out, size_out)
    B, C, _ = x.shape
    a = x.gather(2, i0.expand(B, C, size_out))
    b = x.gather(2, i1.expand(B, C, size_out))
    return torch.lerp(a, b, w.to(x.dtype))


def build_pyramid(x: torch.Tensor, lengths: list[int]) -> list[torch.Tensor]:
    """Data pyramid of one clip: ``x (C, T)`` -> ``[(C, T_1), ..., (C, T_L)]`` by linear
    resampling of the finest level (each level is resampled from the original, not from
    its neighbour, as GANimator does)."""
    if x.ndim != 2:
        raise MotionValueError(f"expected one clip (C, T), got shape {tuple(x.shape)}")
    return [resample_linear(x[None], n)[0] for n in lengths]


def noise_amplitudes(pyramid: list[torch.Tensor]) -> torch.Tensor:
    """Noise amplitude ``sigma_i`` of every level, ``(L,)``.

    GANimator (Li et al. 2022, Sec. 4.2 and its train.py) sets ``sigma_i`` to the RMS
    error between level i and the linearly upsampled level i-1 of the training clip: the
    amount of detail level i has to add. Level 1 compares against zeros, i.e. its
    amplitude is the RMS of the coarsest level itself.
    """
    amps = []
    prev = torch.zeros_like(pyramid[0])
    for level in pyramid:
        up = resample_linear(prev[None], level.shape[-1])[0]
        amps.append(((level - up) ** 2).mean().sqrt())
        prev = level
    return torch.stack(amps)


def pad_stack(
    clips: list[torch.Tensor], size: int | None = None
) -> tuple[torch.Tensor, torch.Tensor]:
    """``[(C, T_b), ...]`` -> padded ``(B, C, T_max)`` (edge-replicated) and ``lengths (B,)``."""
    lengths = torch.tensor([c.shape[-1] for c in clips], dtype=torch.long)
    size = int(lengths.max()) if size is None else size
    out = torch.stack(
        [
            F.pad(c[None], (0, size - c.shape[-1]), mode="replicate")[0]
            if c.shape[-1] < size
            else c
            for c in clips
        ]
    )
    return out, lengths


def length_mask(lengths: torch.Tensor, size: int) -> torch.Tensor:
    """``(B, size)`` bool, True on valid frames."""
    return torch.arange(size, device=lengths.device)[None] < lengths[:, None]


def reflect_pad_index(lengths: torch.Tensor, size: int, pad: int) -> torch.Tensor:
    """Gather indices ``(B, 1, size + 2*pad)`` that reflect-pad every sample at its own
    boundaries (``F.pad(mode="reflect")`` per sample). Positions past a sample's length
    read valid frames only, so padding never leaks into valid outputs."""
    if int(lengths.min()) <= pad:
        raise ClipTooShortError(
            f"reflect padding of {pad} needs more than {pad} frames, "
            f"got a sample of {int(lengths.min())}"
        )
    t = torch.arange(-pad, size + pad, device=lengths.device)[None]  # (1, size + 2p)
    n = lengths[:, None]
    idx = t.abs()  # reflect at the start
    idx = torch.where(idx >= n, 2 * (n - 1) - idx, idx)  # reflect at the end
    idx = idx.clamp(0, None)
    idx = torch.minimum(idx, n - 1)
    return idx[:, None]


@dataclass
class RaggedLevels:
    """Layout of a batch across all pyramid levels, computed once and reused.

    ``lengths[i] (B,)`` valid frames of every sample at level i, ``sizes[i]`` the padded
    length, ``masks[i] (B, T_i)``; resampling tables and reflect-pad indices are cached.
    """

    lengths: list[torch.Tensor]
    sizes: list[int]
    masks: list[torch.Tensor]
    uniform: bool
    _up: dict = field(default_factory=dict, repr=False)
    _pad: dict = field(default_factory=dict, repr=False)

    @classmethod
    def from_table(cls, table: torch.Tensor, device: str | torch.device = "cpu") -> RaggedLevels:
        """``table (B, L)`` int: the pyramid lengths of every sample."""
        table = torch.as_tensor(table, dtype=torch.long, device=device)
        lengths = [table[:, i].contiguous() for i in range(table.shape[1])]
        sizes = [int(n.max()) for n in lengths]
        masks = [length_mask(n, s) for n, s in zip(lengths, sizes, strict=False)]
        return cls(lengths, sizes, masks, bool((table == table[:1]).all()))

    @property
    def batch_size(self) -> int:
        return len(self.lengths[0])

    @property
    def num_levels(self) -> int:
        return len(self.lengths)

    def upsample(self, x: torch.Tensor, level: int) -> torch.Tensor:
        """Resample the output of level ``level - 1`` (0-based ``level``) to level ``level``."""
        if level not in self._up:
            self._up[level] = _resample_table(
                self.lengths[level - 1], self.lengths[level], self.sizes[level]
            )
        return resample_linear_ragged(
            x,
            self.lengths[level - 1],
            self.lengths[level],
            self.sizes[level],
            table=self._up[level],
        )

    def pad_index(self, level: int, pad: int) -> torch.Tensor:
        key = (level, pad)
        if key not in self._pad:
            self._pad[key] = reflect_pad_index(self.lengths[level], self.sizes[level], pad)
        return self._pad[key]

    def select(self, index: torch.Tensor | slice) -> RaggedLevels:
        """The layout of a sub-batch."""
        table = torch.stack(self.lengths, 1)[index]
        return RaggedLevels.from_table(table, table.device)
