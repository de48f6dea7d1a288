"""Block-wise adversarial training of the multi-resolution conditional GAN.

Levels are trained in blocks of two consecutive levels (paper Sec. 3.4, after GANimator
and Hinz et al. 2021); levels of earlier blocks are frozen. One *iteration* of a block is

1. ``n_critic`` critic steps. The fakes of all of them come from one batched, gradient-free
   generation (the generator does not change between critic steps, so this equals
   GANimator's one-generation-per-step in distribution). Each step scores real and fake
   clips of every level in the block and adds the gradient penalty (WGAN-GP).
2. one generator step on ``L = adv*L_adv + con*L_con + rec*L_rec + smooth*L_smooth``
   (paper Eq. 6), summed over the levels of the block. Reconstructions (every training
   clip with its fixed noise z* and its own label) and random generations (one per clip,
   90% of them mixing two labels at a random crossover level) run as one batch; the
   frozen levels' reconstructions are computed once per block.

Batches mix clips of different lengths (``mrlib.pyramid.RaggedLevels``): random generation
b follows the pyramid of clip ``b mod N``, so reals and fakes line up sample by sample.

Checkpoints (``mrlib.checkpoint``) hold everything needed to resume bit-exactly on CPU:
networks, optimizers, iteration, and the RNG states. Ctrl-C finishes the current
iteration, writes a checkpoint and returns.
"""

from __future__ import annotations

import csv
import random
import signal
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

from mrlib.checkpoint import CheckpointError, load_checkpoint, save_checkpoint
from mrlib.config import TrainConfig, config_from_json, config_to_json
from mrlib.data import TrainingSet
from mrlib.features import NUM_FEATURES, FeatureNormalizer
from mrlib.losses import (
    backward_velocity,
    body_kinematics,
    contact_consistency_loss,
    critic_loss,
    generator_adversarial_loss,
    gradient_penalty,
    reconstruction_loss,
    smoothness_loss,
)
from mrlib.models import MultiResGenerator, build_critics, build_generator
from mrlib.pyramid import RaggedLevels, build_pyramid, noise_amplitudes, pad_stack, pyramid_lengths

__all__ = ["train", "Trainer", "TrainResult", "LOSS_NAMES", "wgan_gp_critic_loss"]

LOSS_NAMES = ("D", "gp", "adv", "rec", "con", "smooth")
CSV_FIELDS = ["time_s", "block", "iteration", "level", *LOSS_NAMES]


@dataclass
class TrainResult:
    """What :func:`train` returns."""

    checkpoint: Path
    log: Path
    interrupted: bool
    wall_time_s: float
    losses: dict[int, dict[str, float]]  # last logged losses per level (1-based)


def wgan_gp_critic_loss(
    critic,
    pad_index: torch.Tensor,
    real: torch.Tensor,
    fake: torch.Tensor,
    mask: torch.Tensor,
    alpha: torch.Tensor,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Critic loss ``E[D(fake)] - E[D(real)]`` (one critic forward on ``[real; fake]``) and
    the gradient penalty (a separate forward: double backward through the real and fake
    halves would be wasted work).

    Args:
        critic: a ``PatchCritic``; ``pad_index (2B, 1, T + 2p)`` its reflect-pad index
            (the first B rows serve the penalty's forward).
        real, fake: ``(B, C, T)``; ``mask (B, T)``; ``alpha (B, 1, 1)``.
    """
    B = real.shape[0]
    scores = critic(torch.cat([real, fake]), pad_index)  # (2B, T)
    gp = gradient_penalty(lambda x: critic(x, pad_index[:B]), real, fake, mask, alpha)
    return critic_loss(scores[:B], scores[B:], mask, mask), gp


def _rng_state() -> dict:
    np_state = np.random.get_state()
    state = {
        "torch": torch.get_rng_state(),
        "numpy": [
            np_state[0],
            torch.from_numpy(np_state[1].astype(np.int64)),
            *map(float, np_state[2:]),
        ],
        "python": list(random.getstate()),
    }
    if torch.cuda.is_available():
        state["cuda"] = torch.cuda.get_rng_state_all()
    return state


def _set_rng_state(state: dict) -> None:
    torch.set_rng_state(state["torch"])
    n = state["numpy"]
    np.random.set_state((n[0], n[1].numpy().astype(np.uint32), int(n[2]), int(n[3]), float(n[4])))
    py = state["python"]
    random.setstate((py[0], tuple(py[1]), py[2]))
    if "cuda" in state and torch.cuda.is_available():
        torch.cuda.set_rng_state_all(state["cuda"])


class Trainer:
    """Holds the networks, data pyramids, layouts and optimizers of one training run.

    Use :func:`train` unless you need step-level control (``step`` runs one iteration of
    the current block and returns its losses).
    """

    def __init__(self, data: TrainingSet, config: TrainConfig, out_dir: str | Path, body=None):
        self.data = data
        self.config = config
        self.out_dir = Path(out_dir)
        self.device = torch.device(config.device)
        mc = config.model
        L = mc.num_levels
        self.rng = torch.Generator().manual_seed(config.seed)  # every random draw of training
        torch.manual_seed(config.seed)  # network initialisation
        np.random.seed(config.seed)
        random.seed(config.seed)
        if body is None:
            from mrlib.body import load_body_model

            body = load_body_model()
        self.body = body.to(self.device) if hasattr(body, "to") else body
        self.betas = torch.as_tensor(
            np.asarray(data.betas), dtype=torch.float32, device=self.device
        )

        # 1. pyramids, noise amplitudes, reconstruction noise --------------------------------
        pad = (mc.kernel_size - 1) // 2
        self.lengths = torch.tensor(
            [pyramid_lengths(t, L, mc.scale_factor, min_length=pad + 1) for t in data.lengths]
        )  # (N, L)
        clips = data.normalized()
        pyramids = [build_pyramid(x, self.lengths[k].tolist()) for k, x in enumerate(clips)]
        self.sigma_clip = torch.stack([noise_amplitudes(p) for p in pyramids])  # (N, L)
        lab = torch.tensor(data.clip_labels)
        self.sigma = torch.stack(
            [self.sigma_clip[lab == k].mean(0) for k in range(data.num_labels)]
        )
        # GANimator's default z*: N(0, 1) on every channel (full_zstar=1, not scaled by sigma_1)
        self.zstar = [
            torch.randn(NUM_FEATURES, int(self.lengths[k, 0]), generator=self.rng)
            for k in range(data.num_clips)
        ]

        # 2. networks -------------------------------------------------------------------------
        self.cond_dim = data.num_labels
        self.generator: MultiResGenerator = build_generator(mc, self.cond_dim).to(self.device)
        self.critics = build_critics(mc).to(self.device)
        self.block = 0
        self.iteration = 0
        self.done = False
        self.opt_g: torch.optim.Adam | None = None
        self.opt_d: torch.optim.Adam | None = None

        # 3. fixed batch layouts --------------------------------------------------------------
        N, S = data.num_clips, config.samples_per_clip
        self.N, self.B = N, N * S
        self.rand_clip = torch.arange(self.B) % N  # clip whose pyramid random sample b follows
        dev = self.device
        self.rec_layout = RaggedLevels.from_table(self.lengths, dev)
        self.rand_layout = RaggedLevels.from_table(self.lengths[self.rand_clip], dev)
        self.g_layout = RaggedLevels.from_table(
            torch.cat([self.lengths, self.lengths[self.rand_clip]]), dev
        )
        self.fake_layout = RaggedLevels.from_table(
            self.lengths[self.rand_clip].repeat(max(1, config.n_critic), 1), dev
        )
        self.critic_layout = RaggedLevels.from_table(self.lengths[self.rand_clip].repeat(2, 1), dev)
        self.real = [
            pad_stack([p[i] for p in pyramids])[0].to(dev) for i in range(L)
        ]  # (N, C, T_i)
        self.real_rand = [r[self.rand_clip.to(dev)] for r in self.real]  # (B, C, T_i)
        self.rec_labels = lab[:, None].expand(N, L)  # (N, L)
        self.clip_labels = lab
        fps_table = data.fps * self.lengths.double() / self.lengths[:, -1:].double()  # (N, L)
        self.rand_fps = fps_table[self.rand_clip].float().to(dev)  # (B, L)
        self.zstar_pad = pad_stack(self.zstar)[0].to(dev)  # (N, C, T_1)
        self._rec_cache: tuple[int, torch.Tensor] | None = None

    # -- conditions and noise --------------------------------------------------------------
    def conditions(
        self, label_table: torch.Tensor, layout: RaggedLevels, stop: int
    ) -> list[torch.Tensor]:
        """One-hot label conditions ``(B, T_i, K)`` of levels ``0..stop-1`` from a ``(B, L)``
        table of label indices (constant over time)."""
        onehot = F.one_hot(label_table.to(self.device), self.cond_dim).float()  # (B, L, K)
        return [onehot[:, i, None, :].expand(-1, layout.sizes[i], -1) for i in range(stop)]

    def draw_random(self, batch: int, stop: int) -> tuple[torch.Tensor, list[torch.Tensor]]:
        """Labels ``(batch, L)`` and noises ``[(batch, 1, T_i)]`` of random generations.

        Sample b follows clip ``b mod N``; its coarse label is that clip's. With probability
        ``mix_prob`` a second label (uniform) takes over from a random crossover level on
        (style-mixing regularisation, paper Sec. 4.3)."""
        L, K = self.config.model.num_levels, self.cond_dim
        clip = torch.arange(batch) % self.N
        a = self.clip_labels[clip]
        mix = torch.rand(batch, generator=self.rng) < self.config.mix_prob
        b = torch.randint(K, (batch,), generator=self.rng)
        cross = torch.randint(1, max(L, 2), (batch,), generator=self.rng)  # levels >= cross use b
        levels = torch.arange(L)[None]
        table = torch.where(mix[:, None] & (levels >= cross[:, None]), b[:, None], a[:, None])
        lengths = self.lengths[clip]
        noises = []
        for i in range(stop):
            z = torch.randn(batch, 1, int(lengths[:, i].max()), generator=self.rng)
            noises.append((z * self.sigma[table[:, i], i][:, None, None]).to(self.device))
        return table, noises

    # -- blocks ------------------------------------------------------------------------------
    @property
    def block_levels(self) -> list[int]:
        return self.config.blocks[self.block]

    def start_block(self) -> None:
        """Freeze earlier levels, create this block's optimizers."""
        lo, hi = self.block_levels[0], self.block_levels[-1]
        for i, (g, d) in enumerate(zip(self.generator.levels, self.critics, strict=False)):
            g.requires_grad_(lo <= i <= hi)
            d.requires_grad_(lo <= i <= hi)
        c = self.config
        g_params = [p for i in self.block_levels for p in self.generator.levels[i].parameters()]
        d_params = [p for i in self.block_levels for p in self.critics[i].parameters()]
        self.opt_g = torch.optim.Adam(g_params, lr=c.lr, betas=c.betas)
        self.opt_d = torch.optim.Adam(d_params, lr=c.lr, betas=c.betas)
        self._rec_cache = None

    def _rec_input(self, lo: int) -> torch.Tensor | None:
        """Frozen levels' reconstruction of every clip (output of level lo-1), cached."""
        if lo == 0:
            return None
        if self._rec_cache is None or self._rec_cache[0] != lo:
            with torch.no_grad():
                noises = [self.zstar_pad] + [
                    self.zstar_pad.new_zeros(self.N, 1, s) for s in self.rec_layout.sizes[1:]
                ]
                conds = self.conditions(self.rec_labels, self.rec_layout, lo)
                x = self.generator.run(self.rec_layout, noises, conds, 0, lo)
            self._rec_cache = (lo, x)
        return self._rec_cache[1]

    def step(self) -> dict[int, dict[str, torch.Tensor]]:
        """One iteration (critic steps + one generator step) of the current block."""
        c, w = self.config, self.config.loss
        lo, hi = self.block_levels[0], self.block_levels[-1]
        G, B, N = self.generator, self.B, self.N
        losses: dict[int, dict[str, torch.Tensor]] = {i: {} for i in self.block_levels}

        # 1. critic steps -------------------------------------------------------------------
        if c.n_critic > 0:
            nb = B * c.n_critic
            table, noises = self.draw_random(nb, hi + 1)
            with torch.no_grad():
                conds = self.conditions(table, self.fake_layout, hi + 1)
                fakes = G.run(self.fake_layout, noises, conds, 0, hi + 1, keep=True)[lo:]
            alphas = torch.rand(c.n_critic, B, 1, 1, generator=self.rng).to(self.device)
            for j in range(c.n_critic):
                self.opt_d.zero_grad(set_to_none=True)
                total = 0.0
                for k, i in enumerate(self.block_levels):
                    fake = fakes[k][j * B : (j + 1) * B]
                    real = self.real_rand[i][..., : fake.shape[-1]]
                    pad = self.critic_layout.pad_index(i, self.generator.pad)
                    wl, gp = wgan_gp_critic_loss(
                        self.critics[i], pad, real, fake, self.rand_layout.masks[i], alphas[j]
                    )
                    total = total + wl + w.gp * gp
                    losses[i]["D"], losses[i]["gp"] = wl.detach(), gp.detach()
                total.backward()
                self.opt_d.step()

        # 2. generator step: reconstruction + random generation in one batch -----------------
        self.opt_g.zero_grad(set_to_none=True)
        table, noises = self.draw_random(B, hi + 1)
        rec_noises = [self.zstar_pad] + [
            self.zstar_pad.new_zeros(N, 1, s) for s in self.rec_layout.sizes[1:]
        ]
        rand_conds = self.conditions(table, self.rand_layout, hi + 1)
        x_in = None
        if lo > 0:
            with torch.no_grad():
                x_rand = G.run(self.rand_layout, noises, rand_conds, 0, lo)
            x_in = torch.cat([self._rec_input(lo), x_rand])
        all_noises, all_conds = [], []
        rec_conds = self.conditions(self.rec_labels, self.rec_layout, hi + 1)
        for i in range(hi + 1):
            zr, zn = rec_noises[i], noises[i]
            if zr.shape[1] != zn.shape[1]:
                zn = zn.expand(-1, zr.shape[1], -1)
            all_noises.append(torch.cat([zr, zn]))
            all_conds.append(torch.cat([rec_conds[i], rand_conds[i]]))
        outs = G.run(self.g_layout, all_noises, all_conds, lo, hi + 1, x=x_in, keep=True)
        total = 0.0
        for k, i in enumerate(self.block_levels):
            out_rec, out_rand = outs[k][:N], outs[k][N:]
            mask_rec, mask_rand = self.rec_layout.masks[i], self.rand_layout.masks[i]
            rec = reconstruction_loss(out_rec, self.real[i], mask_rec)
            terms = {"rec": rec}
            if c.n_critic > 0 and w.adv:
                score = self.critics[i](out_rand, self.rand_layout.pad_index(i, G.pad))
                terms["adv"] = generator_adversarial_loss(score, mask_rand)
            need_con = w.con and i + 1 >= c.contact_from_level
            need_smooth = w.smooth and i + 1 >= c.smooth_start
            if need_con or need_smooth:
                joints, feet, contacts = body_kinematics(
                    out_rand, self.data_normalizer, self.rand_fps[:, i], self.body, self.betas
                )
                if need_con:
                    vel = backward_velocity(feet, self.rand_fps[:, i])
                    m = mask_rand.clone()
                    m[:, 0] = False
                    terms["con"] = contact_consistency_loss(vel, contacts, m)
                if need_smooth:
                    terms["smooth"] = smoothness_loss(joints, mask_rand)
            for name, value in terms.items():
                total = total + getattr(w, name) * value
                losses[i][name] = value.detach()
        total.backward()
        self.opt_g.step()
        return losses

    @property
    def data_normalizer(self) -> FeatureNormalizer:
        if not hasattr(self, "_norm_dev"):
            n = self.data.normalizer
            self._norm_dev = FeatureNormalizer(n.mean.to(self.device), n.std.to(self.device))
        return self._norm_dev

    # -- checkpoints -------------------------------------------------------------------------
    def state_dict(self) -> dict:
        d = self.data
        return {
            "config": config_to_json(self.config),
            "labels": list(d.labels),
            "clip_labels": [int(k) for k in d.clip_labels],
            "clip_names": list(d.names),
            "fps": float(d.fps),
            "betas": torch.as_tensor(np.asarray(d.betas), dtype=torch.float32),
            "cond_dim": int(self.cond_dim),
            "normalizer": d.normalizer.state_dict(),
            "features": [f.detach().cpu().clone() for f in d.features],
            "lengths": self.lengths.clone(),
            "sigma_clip": self.sigma_clip.clone(),
            "sigma": self.sigma.clone(),
            "zstar": [z.clone() for z in self.zstar],
            "generator": {k: v.cpu() for k, v in self.generator.state_dict().items()},
            "critics": {k: v.cpu() for k, v in self.critics.state_dict().items()},
            "progress": {
                "block": int(self.block),
                "iteration": int(self.iteration),
                "done": bool(self.done),
            },
            "optim_g": None if self.opt_g is None else self.opt_g.state_dict(),
            "optim_d": None if self.opt_d is None else self.opt_d.state_dict(),
            "rng": {**_rng_state(), "trainer": self.rng.get_state()},
        }

    @classmethod
    def from_checkpoint(
        cls,
        path: str | Path,
        out_dir: str | Path | None = None,
        body=None,
        device: str | None = None,
    ) -> Trainer:
        """Rebuild a trainer (data included) from a checkpoint to continue training."""
        state = load_checkpoint(path)
        config = config_from_json(state["config"])
        if device is not None:
            config = config.replace(device=device)
        data = TrainingSet(
            features=list(state["features"]),
            clip_labels=list(state["clip_labels"]),
            labels=list(state["labels"]),
            fps=float(state["fps"]),
            names=list(state["clip_names"]),
            normalizer=FeatureNormalizer.from_state_dict(state["normalizer"]),
            betas=state["betas"].numpy(),
        )
        trainer = cls(data, config, Path(path).parent if out_dir is None else out_dir, body=body)
        trainer.load_state_dict(state)
        return trainer

    def load_state_dict(self, state: dict) -> None:
        if state["lengths"].shape != self.lengths.shape or not torch.equal(
            state["lengths"], self.lengths
        ):
            raise CheckpointError(None, "checkpoint pyramid lengths do not match the training data")
        self.zstar = [z.clone() for z in state["zstar"]]
        self.zstar_pad = pad_stack(self.zstar)[0].to(self.device)
        self.generator.load_state_dict(state["generator"])
        self.critics.load_state_dict(state["critics"])
        p = state["progress"]
        self.block, self.iteration, self.done = (
            int(p["block"]),
            int(p["iteration"]),
            bool(p["done"]),
        )
        if not self.done and self.block < self.config.num_blocks:
            self.start_block()
            if state["optim_g"] is not None:
                self.opt_g.load_state_dict(state["optim_g"])
                self.opt_d.load_state_dict(state["optim_d"])
        _set_rng_state(state["rng"])
        self.rng.set_state(state["rng"]["trainer"])

    def save(self, path: Path | None = None) -> Path:
        return save_checkpoint(path or self.out_dir / "checkpoint.pt", self.state_dict())

    # -- the loop ----------------------------------------------------------------------------
    def fit(
        self,
        progress: bool = True,
        callback: Callable[[Trainer, dict[int, dict[str, float]]], None] | None = None,
    ) -> TrainResult:
        """Train every remaining block; see :func:`train`."""
        from tqdm.auto import tqdm

        c = self.config
        self.out_dir.mkdir(parents=True, exist_ok=True)
        log_path = self.out_dir / "losses.csv"
        self._prepare_log(log_path)
        t0 = time.perf_counter()
        last: dict[int, dict[str, float]] = {}
        stop = {"flag": False}
        old_handler = None
        if threading.current_thread() is threading.main_thread():

            def _on_sigint(signum, frame):  # first Ctrl-C: stop after this iteration
                if stop["flag"]:
                    raise KeyboardInterrupt
                stop["flag"] = True

            old_handler = signal.signal(signal.SIGINT, _on_sigint)
        interrupted = False
        try:
            with open(log_path, "a", newline="") as fh:
                writer = csv.DictWriter(fh, CSV_FIELDS)
                while self.block < c.num_blocks and not interrupted:
                    if self.opt_g is None:
                        self.start_block()
                    levels = self.block_levels
                    n_iter = c.block_iterations[self.block]
                    bar = tqdm(
                        total=n_iter,
                        initial=self.iteration,
                        disable=not progress,
                        leave=True,
                        desc=f"block {self.block + 1}/{c.num_blocks} "
                        f"(levels {levels[0] + 1}-{levels[-1] + 1})",
                    )
                    try:
                        while self.iteration < n_iter:
                            losses = self.step()
                            self.iteration += 1
                            if self.iteration % c.log_every == 0 or self.iteration == n_iter:
                                last = {
                                    i + 1: {k: float(v) for k, v in d.items()}
                                    for i, d in losses.items()
                                }
                                t = time.perf_counter() - t0
                                for lv, d in last.items():
                                    writer.writerow(
                                        {
                                            "time_s": f"{t:.2f}",
                                            "block": self.block + 1,
                                            "iteration": self.iteration,
                                            "level": lv,
                                            **{k: f"{d[k]:.6g}" for k in d},
                                        }
                                    )
                                fh.flush()
                                top = last[levels[-1] + 1]
                                bar.set_postfix(
                                    {k: f"{v:.3g}" for k, v in top.items()}, refresh=False
                                )
                            bar.update(1)
                            if callback is not None:
                                callback(self, last)
                            if (
                                c.checkpoint_every
                                and self.iteration % c.checkpoint_every == 0
                                and self.iteration < n_iter
                            ):
                                self.save()
                            if stop["flag"]:
                                raise KeyboardInterrupt
                    except KeyboardInterrupt:
                        interrupted = True
                    finally:
                        bar.close()
                    if not interrupted:
                        self.block += 1
                        self.iteration = 0
                        self.opt_g = self.opt_d = None
                        self.done = self.block >= c.num_blocks
                    self.save()
        finally:
            if old_handler is not None:
                signal.signal(signal.SIGINT, old_handler)
        return TrainResult(
            self.out_dir / "checkpoint.pt", log_path, interrupted, time.perf_counter() - t0, last
        )

    def _prepare_log(self, path: Path) -> None:
        """Create the CSV with its header, or drop rows logged after the checkpoint we
        resume from (they will be logged again)."""
        if not path.exists():
            with open(path, "w", newline="") as fh:
                csv.DictWriter(fh, CSV_FIELDS).writeheader()
            return
        with open(path, newline="") as fh:
            rows = list(csv.DictReader(fh))
        keep = [
            r
            for r in rows
            if (int(r["block"]) - 1, int(r["iteration"])) <= (self.block, self.iteration)
        ]
        with open(path, "w", newline="") as fh:
            w = csv.DictWriter(fh, CSV_FIELDS)
            w.writeheader()
            w.writerows(keep)


def train(
    data: TrainingSet | None,
    config: TrainConfig | None,
    out_dir: str | Path,
    *,
    resume: str | Path | None = None,
    body=None,
    progress: bool = True,
    callback: Callable[[Trainer, dict[int, dict[str, float]]], None] | None = None,
) -> TrainResult:
    """Train a model, or continue one.

    Args:
        data: the clips (ignored when resuming: the checkpoint holds them).
        config: a ``TrainConfig`` (e.g. ``mrlib.config.tutorial()``); ignored when resuming.
        out_dir: folder for ``checkpoint.pt`` (+ ``checkpoint.pt.json``) and ``losses.csv``.
        resume: a checkpoint to continue from, exactly where it stopped.
        body: body model for the contact and smoothness losses (default ``load_body_model()``).
        progress: show a tqdm bar per block with the latest losses.
        callback: called after every iteration with the trainer and the last logged losses
            ``{level: {name: value}}``; raising ``KeyboardInterrupt`` in it stops training
            like Ctrl-C (a checkpoint is written first).
    Returns:
        a :class:`TrainResult`; ``interrupted`` tells whether it stopped early.
    """
    if resume is not None:
        trainer = Trainer.from_checkpoint(resume, out_dir=out_dir, body=body)
    else:
        if data is None or config is None:
            raise CheckpointError(None, "train() needs data and config unless resume is given")
        trainer = Trainer(data, config, out_dir, body=body)
    return trainer.fit(progress=progress, callback=callback)
