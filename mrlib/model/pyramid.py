"""Temporal pyramids: level lengths, linear resampling, data pyramids and noise amplitudes.

Level ``i`` (1-based, ``1 <= i <= L``) of a clip of ``T`` frames has about
``T / F**(L - i)`` frames: level ``L`` is the clip itself, every coarser level is the
clip linearly resampled by a further factor ``F`` (``F = 4/3`` in the paper and in
GANimator). A level is a clip at a lower frame rate, ``fps_i = fps * T_i / T_L``.

Batches mix clips of different lengths. Rather than padding every sample to the longest
one, a batch is *packed*: the B samples of a level lie end to end along time in one
``(1, C, S)`` tensor, each followed by ``gap`` junk frames (:class:`PackedLevels`). The
networks read a sample's frames only (reflect padding is a gather that stays inside the
sample, and the gap keeps convolution windows of neighbouring samples apart), so every
sample is processed exactly as if it were alone, and no work is spent on padding.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import torch
import torch.nn.functional as F

from mrlib.errors import ClipTooShortError, MotionValueError

__all__ = [
    "pyramid_lengths",
    "shortest_length",
    "level_fps",
    "resample_linear",
    "resample_periodic",
    "build_pyramid",
    "noise_amplitudes",
    "PackedLevels",
]


def _coarsest(length: int, num_levels: int, factor: float) -> int:
    lengths = [max(1, round(length / factor ** (num_levels - 1 - k))) for k in range(num_levels)]
    lengths[-1] = int(length)
    for k in range(num_levels - 2, -1, -1):
        lengths[k] = min(lengths[k], lengths[k + 1] - 1)
    return lengths[0]


def _shortest(num_levels: int, factor: float, min_length: int) -> int:
    """The fewest frames whose pyramid's coarsest level has ``min_length`` frames: the
    coarsest level grows with the clip, so a doubling search and a bisection find it in
    ``O(L log T)`` (a frame-by-frame search took minutes for 50 levels)."""
    lo = hi = min_length + num_levels - 1  # levels are strictly increasing
    while _coarsest(hi, num_levels, factor) < min_length:
        lo, hi = hi, hi * 2
    while lo < hi:
        mid = (lo + hi) // 2
        if _coarsest(mid, num_levels, factor) < min_length:
            lo = mid + 1
        else:
            hi = mid
    return hi


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
        need = _shortest(num_levels, factor, min_length)
        raise ClipTooShortError(
            f"a clip of {length} frames is too short for {num_levels} levels and factor "
            f"{factor:g}: its coarsest level needs at least {min_length} frames (use clips "
            f"of >= {need} frames or fewer levels)"
        )
    return lengths


def shortest_length(num_levels: int, factor: float = 4 / 3, min_length: int = 3) -> int:
    """The fewest frames :func:`pyramid_lengths` accepts for these levels."""
    return _shortest(num_levels, factor, min_length)


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


def resample_periodic(x: torch.Tensor, size: int) -> torch.Tensor:
    """:func:`resample_linear` of a periodic signal ``(B, C, T) -> (B, C, size)``: the
    same sample positions (``align_corners=False``), interpolated across the wrap from
    the last frame to the first instead of clamped at the ends."""
    if x.ndim != 3:
        raise MotionValueError(f"expected (B, C, T), got shape {tuple(x.shape)}")
    T = x.shape[-1]
    if T == size:
        return x
    pos = (torch.arange(size, dtype=torch.float64, device=x.device) + 0.5) * T / size - 0.5
    lo = torch.floor(pos)
    w = (pos - lo).to(x.dtype)
    i0 = lo.long() % T
    i1 = (i0 + 1) % T
    return x[..., i0] * (1 - w) + x[..., i1] * w


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


@dataclass
class PackedLevels:
    """Layout of a batch of B samples at every level of their pyramids, packed along time.

    At level i, sample b occupies frames ``[offsets[i][b], offsets[i][b] + T_ib)`` of a
    ``(1, C, sizes[i])`` tensor and is followed by ``gap`` junk frames (``gap >= 2p`` for
    convolutions with padding p). All index tables are built once (the layout of a
    training batch never changes) and live on ``device``.

    Attributes:
        table: ``(B, L)`` int, the pyramid lengths of every sample (CPU).
        gap: junk frames after every sample.
        offsets: per level ``(B,)`` first frame of every sample.
        sizes: per level, total packed length ``S_i = sum_b (T_ib + gap)``.
        owner: per level ``(S_i,)`` the sample each frame belongs to (gap frames belong to
            the sample they follow).
        local: per level ``(S_i,)`` frame index within its sample (``>= T_ib`` in the gap).
        valid: per level ``(1, S_i)`` bool, False on gap frames.

    A padded batch would spend ``B * max_b T_ib - sum_b T_ib`` frames on padding (a third
    of the work for the four Bandai walks of 143-347 frames); packing spends ``B * gap``.
    """

    table: torch.Tensor
    gap: int
    device: torch.device
    offsets: list[torch.Tensor]
    sizes: list[int]
    owner: list[torch.Tensor]
    local: list[torch.Tensor]
    valid: list[torch.Tensor]
    _cache: dict = field(default_factory=dict, repr=False)

    @classmethod
    def from_table(cls, table, gap: int = 4, device: str | torch.device = "cpu") -> PackedLevels:
        """``table (B, L)``: the pyramid lengths of every sample (``(L,)`` for one)."""
        table = torch.as_tensor(table, dtype=torch.long).cpu()
        if table.ndim == 1:
            table = table[None]
        if table.ndim != 2 or table.numel() == 0:
            raise MotionValueError(f"table must be (B, L) lengths, got shape {tuple(table.shape)}")
        if int(table.min()) < 1:
            raise ClipTooShortError(f"every level needs at least one frame, got {table.tolist()}")
        dev = torch.device(device)
        offsets, sizes, owner, local, valid = [], [], [], [], []
        for i in range(table.shape[1]):
            n = table[:, i]
            span = n + gap
            off = torch.cumsum(span, 0) - span  # (B,)
            own = torch.repeat_interleave(torch.arange(len(n)), span)  # (S,)
            loc = torch.arange(int(span.sum())) - off[own]
            offsets.append(off.to(dev))
            sizes.append(int(span.sum()))
            owner.append(own.to(dev))
            local.append(loc.to(dev))
            valid.append((loc < n[own])[None].to(dev))
        return cls(table, gap, dev, offsets, sizes, owner, local, valid)

    @property
    def batch_size(self) -> int:
        return self.table.shape[0]

    @property
    def num_levels(self) -> int:
        return self.table.shape[1]

    def lengths(self, level: int) -> torch.Tensor:
        """``(B,)`` frames of every sample at ``level`` (0-based)."""
        return self.table[:, level]

    # -- moving data in and out -----------------------------------------------------------
    def pack(self, clips: list[torch.Tensor], level: int) -> torch.Tensor:
        """``[(C, T_ib)] -> (1, C, S_i)`` (gap frames are zeros)."""
        if len(clips) != self.batch_size:
            raise MotionValueError(f"expected {self.batch_size} clips, got {len(clips)}")
        parts = []
        for b, c in enumerate(clips):
            if c.shape[-1] != int(self.table[b, level]):
                raise MotionValueError(
                    f"clip {b} has {c.shape[-1]} frames at level {level + 1}, "
                    f"the layout says {int(self.table[b, level])}"
                )
            parts += [c, c.new_zeros(c.shape[0], self.gap)]
        return torch.cat(parts, -1)[None].to(self.device)

    def unpack(self, x: torch.Tensor, level: int) -> list[torch.Tensor]:
        """``(1, C, S_i) -> [(C, T_ib)]`` (views)."""
        off = self.offsets[level].tolist()
        return [
            x[0, :, o : o + int(n)] for o, n in zip(off, self.table[:, level].tolist(), strict=True)
        ]

    def per_sample(self, values: torch.Tensor, level: int) -> torch.Tensor:
        """Spread per-sample values ``(B, ...)`` over frames: ``(S_i, ...)``."""
        return values.to(self.device)[self.owner[level]]

    def per_sample_rms(self, x: torch.Tensor, level: int) -> torch.Tensor:
        """Per-sample, per-channel root mean square over a sample's own frames:
        ``(1, C, S_i) -> (B, C)``."""
        m = self.valid[level][0].to(x.dtype)  # (S_i,)
        sq = (x[0] * x[0] * m).T  # (S_i, C)
        total = sq.new_zeros(self.batch_size, x.shape[1]).index_add_(0, self.owner[level], sq)
        count = self.table[:, level].to(device=x.device, dtype=x.dtype)[:, None]
        return (total / count + 1e-12).sqrt()

    def split(self, level: int, n: int) -> int:
        """Packed size of the first ``n`` samples at ``level`` (where sample n starts)."""
        return self.sizes[level] if n >= self.batch_size else int(self.offsets[level][n])

    # -- weights for per-sample means ---------------------------------------------------------
    def trimmed(self, level: int, start: int = 0, end: int = 0) -> torch.Tensor:
        """``(1, S_i)`` bool: frames ``[start, T_b - end)`` of every sample."""
        n = self.table[:, level].to(self.device)[self.owner[level]]
        loc = self.local[level]
        return ((loc >= start) & (loc < n - end))[None]

    def weights(self, level: int, mask: torch.Tensor | None = None) -> torch.Tensor:
        """``(1, S_i)`` frame weights of a per-sample mean averaged over samples: frame t of
        sample b weighs ``1 / (count_b * B)`` where ``count_b`` is its number of frames in
        ``mask`` (default: all valid frames); weights sum to 1."""
        m = self.valid[level] if mask is None else mask
        own = self.owner[level]
        count = torch.zeros(self.batch_size, device=self.device).index_add_(0, own, m[0].float())
        return (m[0].float() / (count.clamp_min(1)[own] * self.batch_size))[None]

    # -- what the networks need ----------------------------------------------------------------
    def pad_index(self, level: int, pad: int) -> torch.Tensor:
        """Gather indices ``(1, 1, S_i + 2 * pad)`` that reflect-pad every sample at its own
        boundaries, as ``F.pad(mode="reflect")`` would for the sample alone."""
        key = ("pad", level, pad)
        if key in self._cache:
            return self._cache[key]
        if 2 * pad > self.gap and self.batch_size > 1:
            raise MotionValueError(
                f"padding {pad} needs a gap of at least {2 * pad} frames, got {self.gap}"
            )
        n = self.table[:, level]
        if int(n.min()) <= pad:
            raise ClipTooShortError(
                f"reflect padding of {pad} needs more than {pad} frames, "
                f"got a sample of {int(n.min())} at level {level + 1}"
            )
        off = self.offsets[level].cpu()
        t = torch.arange(-pad, self.sizes[level] + pad)  # centre of each padded position
        # the sample whose reflect-padded span [o - p, o + T + p) holds t
        b = (torch.searchsorted(off, t + pad, right=True) - 1).clamp(0, self.batch_size - 1)
        u = t - off[b]
        T = n[b]
        u = u.abs()  # reflect at the start
        u = torch.where(u >= T, 2 * (T - 1) - u, u)  # reflect at the end
        u = torch.minimum(u.clamp_min(0), T - 1)  # junk positions read any frame of b
        idx = (off[b] + u)[None, None].to(self.device)
        self._cache[key] = idx
        return idx

    def _lerp_index(self, src: int, dst: int):
        """Gather indices and weights of a per-sample linear resampling from level ``src``
        to level ``dst`` (``F.interpolate(mode="linear", align_corners=False)``)."""
        key = ("lerp", src, dst)
        if key not in self._cache:
            n_in, n_out = self.table[:, src], self.table[:, dst]
            own = self.owner[dst].cpu()
            loc = self.local[dst].cpu().clamp_max(n_out[own] - 1)  # gap frames copy the last
            scale = n_in.double()[own] / n_out.double()[own]
            pos = ((loc.double() + 0.5) * scale - 0.5).clamp_min(0)
            i0 = torch.minimum(pos.floor().long(), n_in[own] - 1)
            i1 = torch.minimum(i0 + 1, n_in[own] - 1)
            w = (pos - i0).clamp(0, 1).float()
            base = self.offsets[src].cpu()[own]
            self._cache[key] = (
                (base + i0)[None, None].to(self.device),
                (base + i1)[None, None].to(self.device),
                w[None, None].to(self.device),
            )
        return self._cache[key]

    def _resample(self, x: torch.Tensor, src: int, dst: int) -> torch.Tensor:
        i0, i1, w = self._lerp_index(src, dst)
        C = x.shape[1]
        a = x.gather(2, i0.expand(1, C, -1))
        b = x.gather(2, i1.expand(1, C, -1))
        return torch.lerp(a, b, w.to(x.dtype))

    def upsample(self, x: torch.Tensor, level: int) -> torch.Tensor:
        """Linear resampling of every sample from level ``level - 1`` to ``level``
        (``F.interpolate(mode="linear", align_corners=False)`` per sample):
        ``(1, C, S_{i-1}) -> (1, C, S_i)``."""
        return self._resample(x, level - 1, level)

    def downsample(self, x: torch.Tensor, level: int) -> torch.Tensor:
        """Linear resampling of every sample from level ``level`` to ``level - 1``, as the
        data pyramid is made (:func:`build_pyramid`): ``(1, C, S_i) -> (1, C, S_{i-1})``."""
        return self._resample(x, level, level - 1)

    def level_band(self, x: torch.Tensor, level: int) -> torch.Tensor:
        """The detail of ``x (1, C, S_i)`` that level ``i`` adds over level ``i - 1``:
        ``x - up(down(x))`` with the pyramid's own resampling, i.e. what level ``i - 1``
        cannot hold (on the data its RMS is the noise amplitude sigma_i,
        :func:`noise_amplitudes`, up to the downsampling of ``x`` itself). At the coarsest
        level (``level == 0``) everything is its own: ``x``."""
        if level == 0:
            return x
        return x - self.upsample(self.downsample(x, level), level)
