"""Generative motion matching (GenMM; Li, Chen, Li, Sorkine-Hornung and Chen, SIGGRAPH
2023) on mrlib's features, as a training-free baseline for the benchmarks.

The method, as the paper describes it and with its public defaults: a pyramid of the
example clip, coarsest level 5 patches long (``coarse_patches``), each finer level 4/3
longer (``pyr_factor`` 0.75); the synthesis starts from the coarsest example stretched to
the output's coarsest length plus noise (sigma 10, wrapped into (-1, 1)); at every level,
``steps`` (3) rounds of: cut the synthesis into every patch of ``patch_size`` (11) frames,
find each one's nearest example patch under the bidirectional similarity (squared
distance per value, divided by ``alpha`` (0.01) + the distance from that example patch to
its nearest synthesised patch, so that example patches nobody uses come closer: the
completeness term), and blend the chosen example patches (each frame the mean of the
patches over it); then upsample the synthesis linearly to the next level.

Written here from the paper; the features are mrlib's (``Motion`` -> 6D rotations, root
velocity and height, foot contacts, unnormalised, as GenMM uses its own unnormalised
6D-rotation and root-velocity features), and the output goes back through
``features_to_motion`` (Gram-Schmidt rotations, contacts at 0.5).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F


@dataclass(frozen=True)
class GenMMSettings:
    patch_size: int = 11
    alpha: float = 0.01
    steps: int = 3
    noise_sigma: float = 10.0
    coarse_patches: float = 5.0  # coarsest example level: this many patches long
    pyr_factor: float = 0.75


def pyramid_lengths(final: int, coarse_ratio: float, factor: float) -> list[int]:
    """Lengths from ``round(final * coarse_ratio)`` up to ``final``, each 1/``factor``
    times the one before (at least one frame more)."""
    lengths = [max(1, int(round(final * coarse_ratio)))]
    while lengths[-1] < final:
        nxt = int(round(lengths[-1] / factor))
        lengths.append(max(nxt, lengths[-1] + 1))
    lengths[-1] = final
    return lengths


def _resample(x: torch.Tensor, length: int, align: bool = False) -> torch.Tensor:
    """``(1, C, T)`` -> ``(1, C, length)``, linear."""
    return F.interpolate(x, size=length, mode="linear", align_corners=align)


def _patches(x: torch.Tensor, k: int) -> torch.Tensor:
    """``(1, C, T)`` -> every patch of ``k`` frames, flattened: ``(T - k + 1, C * k)``."""
    return F.unfold(x[:, :, None], kernel_size=(1, k))[0].T


def _blend(patches: torch.Tensor, length: int, channels: int, k: int) -> torch.Tensor:
    """The inverse of :func:`_patches`: each frame the mean of the patches over it."""
    total = F.fold(patches.T[None], output_size=(1, length), kernel_size=(1, k))
    ones = torch.ones(1, channels * k, patches.shape[0], dtype=patches.dtype)
    count = F.fold(ones, output_size=(1, length), kernel_size=(1, k))
    return (total / count)[:, :, 0]


def _nearest(query: torch.Tensor, keys: torch.Tensor, alpha: float) -> torch.Tensor:
    """Index of each query patch's nearest key under the normalised (completeness)
    distance: ``d(q, k) / (alpha + min_q' d(q', k))``, ``d`` the mean squared difference."""
    d = (query * query).sum(1)[:, None] + (keys * keys).sum(1)[None] - 2 * query @ keys.T
    d = d / query.shape[1]
    return (d / (alpha + d.min(0).values[None])).argmin(1)


def synthesise(
    example: torch.Tensor, length: int, generator: torch.Generator, s: GenMMSettings
) -> torch.Tensor:
    """A new sequence of ``length`` frames ``(length, C)`` from an example ``(T, C)``."""
    x = example.T[None].double()  # (1, C, T)
    T, C, k = x.shape[-1], x.shape[1], s.patch_size
    if T < k * s.coarse_patches or length < k:
        raise ValueError(f"the example ({T} frames) and output ({length}) are too short")
    ratio = k * s.coarse_patches / T
    ex_lengths = pyramid_lengths(T, ratio, s.pyr_factor)
    out_lengths = pyramid_lengths(length, ratio, s.pyr_factor)
    levels = min(len(ex_lengths), len(out_lengths))
    ex_lengths, out_lengths = ex_lengths[-levels:], out_lengths[-levels:]
    coarse = _resample(x, ex_lengths[0])
    y = _resample(coarse, out_lengths[0], align=True)
    noise = torch.randn(y.shape, generator=generator, dtype=y.dtype)
    y = torch.fmod(y + s.noise_sigma * noise, 1.0)
    for lvl, (n_ex, n_out) in enumerate(zip(ex_lengths, out_lengths, strict=True)):
        if lvl > 0:
            y = _resample(y, n_out)
        keys = _patches(_resample(x, n_ex), k) if n_ex != T else _patches(x, k)
        if keys.shape[0] < 1 or n_out < k:
            continue
        for _ in range(s.steps):
            nn = _nearest(_patches(y, k), keys, s.alpha)
            y = _blend(keys[nn], n_out, C, k)
    return y[0].T.float()


def genmm_sample_fn(references: dict, settings: GenMMSettings | None = None):
    """``sample_fn(label, length, seed) -> Motion`` for ``mrlib.evaluation.evaluate``:
    GenMM on each label's reference clip alone (one example, as GenMM on one clip)."""
    from mrlib.representation.features import features_to_motion, motion_to_features

    s = settings or GenMMSettings()
    feats = {k: motion_to_features(m) for k, m in references.items()}

    def sample(label: str, length: int, seed: int):
        ref = references[label]
        g = torch.Generator().manual_seed(int(seed))
        y = synthesise(feats[label], int(length), g, s)
        return features_to_motion(
            y, ref.fps, betas=np.asarray(ref.betas), label=ref.label, name=f"genmm_{label}_{seed}"
        )

    return sample
