"""What a training run builds before its first step (paper Sec. 3.2-3.4).

* :func:`build_batches`: the fixed batches of the run (:class:`Batches`): every clip's
  pyramid, its noise amplitudes and its fixed reconstruction noise z*_1, packed
  (``mrlib.model.pyramid.PackedLevels``: clips of different lengths end to end; random
  generation b follows the pyramid of clip b, so reals and fakes line up sample by
  sample), with the frame weights of every loss term;
* :func:`build_networks`: the generator and the critics;
* :func:`make_adam`: a block's optimiser; :func:`frozen`: networks held still for a step;
* :class:`Kinematics`: the body-model pass of the contact and smoothness terms.

The conditions (labels, or speech) are ``mrlib.training.signals``; the run itself is
``mrlib.training.trainer``.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
import torch

from mrlib.errors import ClipTooShortError
from mrlib.model.config import ModelConfig, TrainConfig
from mrlib.model.critic import build_critics
from mrlib.model.generator import MultiResGenerator, build_generator
from mrlib.model.losses import body_kinematics
from mrlib.model.pyramid import PackedLevels, build_pyramid, noise_amplitudes, pyramid_lengths
from mrlib.representation.features import FeatureNormalizer
from mrlib.training.data import TrainingSet
from mrlib.training.objective import LevelData

__all__ = ["Batches", "build_batches", "build_networks", "make_adam", "frozen", "Kinematics"]


@dataclass
class Batches:
    """The fixed batches of one run: N clips, L levels, B = N random generations per
    step (generation b follows the pyramid of clip ``rand_clip[b]``).

    Attributes:
        lengths: ``(N, L)`` frames of every clip at every level.
        sigma_clip: ``(N, L)`` noise amplitudes of every clip (paper Sec. 3.2).
        zstar: per clip ``(1, T_k,1)``, the fixed reconstruction noise z*_1 (Sec. 3.4).
        rand_clip: ``(B,)`` the clip each random generation follows.
        rec_layout: every clip once (the reconstructions); ``rand_layout``: the random
            generations; ``g_layout``: ``[reconstructions; random]`` (one generator run);
            ``fake_layout``: ``n_critic`` copies of ``rand_layout`` (the critic steps'
            fakes); ``critic_layout``: ``[real; fake]`` (one critic forward).
        levels: per level, the real clips and the frame weights of its terms.
        zstar_packed: ``(1, 1, S_1)`` z*_1 in the reconstruction layout.
        device: where the tensors live.
    """

    lengths: torch.Tensor
    sigma_clip: torch.Tensor
    zstar: list[torch.Tensor]
    rand_clip: torch.Tensor
    rec_layout: PackedLevels
    rand_layout: PackedLevels
    g_layout: PackedLevels
    fake_layout: PackedLevels
    critic_layout: PackedLevels
    levels: list[LevelData]
    zstar_packed: torch.Tensor
    device: torch.device

    @property
    def num_clips(self) -> int:
        return int(self.lengths.shape[0])

    def set_zstar(self, zstar: list[torch.Tensor]) -> None:
        """Take the reconstruction noise of a checkpoint."""
        self.zstar = [z.clone() for z in zstar]
        self.zstar_packed = self.rec_layout.pack(self.zstar, 0)

    def rec_noises(self, stop: int) -> list[torch.Tensor]:
        """The reconstructions' noise of levels ``0..stop-1``: z*_1 at level 1, zero above
        (paper Sec. 3.4)."""
        zeros = [self.zstar_packed.new_zeros(1, 1, s) for s in self.rec_layout.sizes[1:stop]]
        return [self.zstar_packed, *zeros]


def _clip_lengths(name: str, length: int, L: int, factor: float, min_length: int) -> list[int]:
    try:
        return pyramid_lengths(length, L, factor, min_length=min_length)
    except ClipTooShortError as e:
        raise ClipTooShortError(f"clip '{name}': {e}") from None


def build_batches(
    data: TrainingSet, config: TrainConfig, rng: torch.Generator, device: torch.device
) -> Batches:
    """Every clip's pyramid and noise amplitudes, its z*_1 (drawn from ``rng``: a draw of
    the random noise itself, N(0, sigma_1) shared by all channels, zero above level 1),
    and the packed batches and frame weights of every loss term."""
    mc = config.model
    L, pad = mc.num_levels, (mc.kernel_size - 1) // 2
    lengths = torch.tensor(
        [
            _clip_lengths(name, t, L, mc.scale_factor, pad + 1)
            for name, t in zip(data.names, data.lengths, strict=True)
        ]
    )  # (N, L)
    pyramids = [build_pyramid(x, lengths[k].tolist()) for k, x in enumerate(data.normalized())]
    sigma_clip = torch.stack([noise_amplitudes(p) for p in pyramids])  # (N, L)
    zstar = []
    for k in range(data.num_clips):
        z = torch.randn(1, int(lengths[k, 0]), generator=rng)
        zstar.append(z * sigma_clip[k, 0])

    rand_clip = torch.arange(data.num_clips)  # one random generation per clip and step
    rand_table = lengths[rand_clip]
    packed = lambda table: PackedLevels.from_table(table, 2 * pad, device)  # noqa: E731
    rec, rand = packed(lengths), packed(rand_table)
    fps_table = data.fps * lengths.double() / lengths[:, -1:].double()  # (N, L)
    rand_fps = fps_table[rand_clip].float()  # (B, L)
    levels = [
        LevelData(
            real=rec.pack([p[i] for p in pyramids], i),
            real_rand=rand.pack([pyramids[k][i] for k in rand_clip], i),
            w_rec=rec.weights(i),
            w_rand=rand.weights(i),
            w_vel=rand.weights(i, rand.trimmed(i, start=1)),
            w_smooth=rand.weights(i, rand.trimmed(i, start=1, end=1)),
            fps=rand.per_sample(rand_fps[:, i], i)[None],
        )
        for i in range(L)
    ]
    return Batches(
        lengths=lengths,
        sigma_clip=sigma_clip,
        zstar=zstar,
        rand_clip=rand_clip,
        rec_layout=rec,
        rand_layout=rand,
        g_layout=packed(torch.cat([lengths, rand_table])),
        fake_layout=packed(rand_table.repeat(max(1, config.n_critic), 1)),
        critic_layout=packed(rand_table.repeat(2, 1)),
        levels=levels,
        zstar_packed=rec.pack(zstar, 0),
        device=device,
    )


def build_networks(
    mc: ModelConfig, cond_dim: int, device: torch.device
) -> tuple[MultiResGenerator, torch.nn.ModuleList]:
    """The generator and the critics for conditions of ``cond_dim`` channels (weights from
    torch's global generator, which the trainer seeds first)."""
    generator = build_generator(mc, cond_dim).to(device)
    critics = build_critics(mc, cond_dim if mc.critic_condition else 0).to(device)
    return generator, critics


@contextlib.contextmanager
def frozen(modules: Iterable[torch.nn.Module]):
    """``modules`` with ``requires_grad`` off inside the block, on again after: the
    generator step backpropagates through the critics without computing their weight
    gradients, which the next critic step would discard (the generator's gradients are
    the same; the step costs less)."""
    modules = list(modules)
    for m in modules:
        m.requires_grad_(False)
    try:
        yield
    finally:
        for m in modules:
            m.requires_grad_(True)


def make_adam(params, lr: float, betas: tuple[float, float], device) -> torch.optim.Adam:
    """Adam with PyTorch's fused kernel where this torch has one for the device (CPU from
    torch 2.4 on, CUDA), else its default implementation. Fused, the step of all of a
    block's parameters is one kernel instead of a dozen small ones per tensor: on a
    2-core x86-64 VM, one thread, the ``demo`` preset trained 4 % faster than with the
    for-loop Adam (most in the coarse blocks, where the networks' work is least;
    ``python bench/busy_machine.py --extras``; foreach: 1 %). Its results differ from
    the for-loop's by float rounding (~1e-7 after 50 steps)."""
    params = list(params)
    if torch.device(device).type in ("cpu", "cuda"):
        try:
            return torch.optim.Adam(params, lr=lr, betas=betas, fused=True)
        except (RuntimeError, TypeError, ValueError):  # an older torch: no fused CPU kernel
            pass
    return torch.optim.Adam(params, lr=lr, betas=betas)


class Kinematics:
    """``losses.body_kinematics`` with one run's body model, feature normaliser and body
    shape: ``kinematics(x (1, C, S), fps)`` gives joints, foot vertices and contacts."""

    def __init__(self, data: TrainingSet, body, device: torch.device):
        from mrlib.representation.body import resolve_body

        body = resolve_body(body)
        self.body = body.to(device) if hasattr(body, "to") else body
        self.betas = torch.as_tensor(np.asarray(data.betas), dtype=torch.float32, device=device)
        norm = data.normalizer
        self.normalizer = FeatureNormalizer(norm.mean.to(device), norm.std.to(device))

    def __call__(self, x: torch.Tensor, fps: torch.Tensor):
        return body_kinematics(x, self.normalizer, fps, self.body, self.betas)
