"""Training speed: mrlib's batched trainer against a naive GANimator-style loop.

Run from the repository root::

    python bench/train_speed.py                 # paper-size networks, 1 and 4 clips
    python bench/train_speed.py --iters 2       # quicker, noisier
    BENCH_THREADS=1 python bench/train_speed.py # one torch thread (on a busy machine, two
                                                # threads per process thrash)

Both implementations use the same networks (``ModelConfig`` of the ``paper`` preset:
8 levels, 128/256/256 hidden channels), the same losses and the same data (Bandai Namco
``walk_{normal,happy,sad,angry}_001`` from ``$MRLIB_DATA_DIR``, or procedural walks when
the data is missing). One *iteration* is what trains the generator once:

* **naive** (GANimator's published ``joint_train``): 5 critic steps, one adversarial
  generator step and one reconstruction step, each a fresh generation through every
  level, one clip per forward (a loop over clips), one optimizer step per level.
* **mrlib** (``mrlib.training.trainer.Trainer.step``): 5 critic steps fed by one batched,
  gradient-free generation, then one generator step on the summed losses; all clips and
  both levels of the block in one batch, frozen levels' reconstructions cached.
* **mrlib n_critic=2**: the same with the tutorial's critic ratio.

For every block (levels 1-2, 3-4, 5-6, 7-8) it reports iterations per second and the
peak memory of training (CPU: peak resident set of a fresh process per measurement minus
its size before the first step; CUDA: ``torch.cuda.max_memory_allocated``), prints a
table and writes ``bench/results/train_speed.json``. Timings are wall-clock, best of ``--iters`` after one
warm-up iteration; on a shared machine expect noise.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time

import torch
from common import ROOT, bandai_dir, describe, set_threads, write_json

STYLES = ("normal", "happy", "sad", "angry")


def load_data(n_clips: int):
    from mrlib.training.data import TrainingSet

    data_dir = bandai_dir(required=False) / "data"
    files = [data_dir / f"dataset-1_walk_{s}_001.bvh" for s in STYLES[:n_clips]]
    if all(f.exists() for f in files):
        return TrainingSet.from_files(files), "bandai"
    from mrlib.datasets.synthetic import synthetic_walk

    names = ["walk_normal", "walk_happy", "walk_sad", "walk_normal"][:n_clips]
    clips = [synthetic_walk(s, seconds=6.0 + k, seed=k) for k, s in enumerate(names)]
    return TrainingSet.from_motions(
        clips, labels=[f"{s}_{k}" for k, s in enumerate(names)]
    ), "synthetic"


# -- the naive reference ---------------------------------------------------------------------
class NaiveStep:
    """GANimator's joint training loop on mrlib's networks: per iteration, 5 critic steps,
    1 generator step, 1 reconstruction step; every step regenerates every level for each
    clip separately (batch of one) and each level has its own optimizers."""

    def __init__(self, trainer):
        from mrlib.model.pyramid import PackedLevels

        t = self.t = trainer
        c = t.config
        L = c.model.num_levels
        # one clip per forward: plain (unpacked) sequences, reflect-padded at both ends
        self.layouts = [
            PackedLevels.from_table(t.batches.lengths[k : k + 1], 0, t.device)
            for k in range(t.batches.num_clips)
        ]
        adam = lambda m: torch.optim.Adam(m.parameters(), lr=c.lr, betas=c.betas)  # noqa: E731
        self.opt_g = {i: adam(t.generator.levels[i]) for i in t.block_levels}
        self.opt_d = {i: adam(t.critics[i]) for i in t.block_levels}
        self.reals = [
            [t.batches.rec_layout.unpack(t.batches.levels[i].real, i)[k][None] for i in range(L)]
            for k in range(t.batches.num_clips)
        ]

    def _generate(self, k: int, mode: str, stop: int):
        t = self.t
        lay = self.layouts[k]
        lab = int(t.signal.clip_labels[k])
        onehot = torch.zeros(1, 1, t.signal.dim, device=t.device)
        onehot[..., lab] = 1
        n = [int(x) for x in t.batches.lengths[k, :stop]]
        conds = [onehot.expand(1, s, -1) for s in n]
        if mode == "rec":
            noises = [t.batches.zstar[k][None].to(t.device)] + [
                torch.zeros(1, 1, s, device=t.device) for s in n[1:]
            ]
        else:
            noises = [
                torch.randn(1, 1, s, generator=t.rng).to(t.device) * t.signal.sigma[lab, i]
                for i, s in enumerate(n)
            ]
        return t.generator.run(lay, noises, conds, 0, stop, keep=True)  # with a graph, as GANimator

    def __call__(self):
        from mrlib.model.losses import (
            backward_velocity,
            contact_consistency_loss,
            critic_loss,
            generator_adversarial_loss,
            gradient_penalty,
            reconstruction_loss,
            smoothness_loss,
        )

        t, c, w = self.t, self.t.config, self.t.config.loss
        levels = t.block_levels
        hi = levels[-1]
        pad = t.generator.pad
        for step in range(c.n_critic + 2):
            mode = "d" if step < c.n_critic else ("g" if step == c.n_critic else "rec")
            for k in range(t.batches.num_clips):
                imgs = self._generate(k, "rec" if mode == "rec" else "random", hi + 1)
                lay = self.layouts[k]
                opts = self.opt_d if mode == "d" else self.opt_g
                for i in levels:
                    opts[i].zero_grad(set_to_none=True)
                for i in levels:
                    fake, real = imgs[i], self.reals[k][i]
                    wts = lay.weights(i)
                    pidx = lay.pad_index(i, pad)
                    D = t.critics[i]
                    if mode == "d":
                        alpha = torch.rand(1, 1, 1, generator=t.rng).to(t.device)
                        loss = critic_loss(D(real, pidx), D(fake.detach(), pidx), wts, wts)
                        gp = gradient_penalty(
                            lambda x, D=D, pidx=pidx: D(x, pidx), real, fake, wts, alpha
                        )
                        loss = loss + w.gp * gp
                    elif mode == "g":
                        loss = w.adv * generator_adversarial_loss(D(fake, pidx), wts)
                        fps = (
                            t.data.fps
                            * int(t.batches.lengths[k, i])
                            / int(t.batches.lengths[k, -1])
                        )
                        joints, feet, contacts = t.kinematics(fake, fps)
                        w_vel = lay.weights(i, lay.trimmed(i, start=1))
                        vel = backward_velocity(feet, fps)
                        loss = loss + w.con * contact_consistency_loss(vel, contacts, w_vel)
                        if i + 1 >= c.smooth_start:
                            w_s = lay.weights(i, lay.trimmed(i, start=1, end=1))
                            loss = loss + w.smooth * smoothness_loss(joints, w_s)
                    else:
                        loss = w.rec * reconstruction_loss(fake, real, wts)
                    loss.backward(retain_graph=True)
                for (
                    i
                ) in levels:  # stepping after all backwards (PyTorch forbids stepping mid-graph)
                    opts[i].step()


def _current_rss_mib() -> float:
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return 0.0


# -- one measurement in a fresh process --------------------------------------------------------
def measure(impl: str, n_clips: int, device: str, block: int, iters: int) -> dict:
    from mrlib.model.presets import paper
    from mrlib.training.trainer import Trainer

    set_threads(int(os.environ.get("BENCH_THREADS", torch.get_num_threads())))
    data, source = load_data(n_clips)
    n_critic = 2 if impl == "mrlib_nc2" else 5
    cfg = paper().replace(device=device, n_critic=n_critic)
    tr = Trainer(data, cfg, "/tmp/mrlib-bench-unused")
    tr.block = block
    tr.start_block()
    step = NaiveStep(tr) if impl == "naive" else tr.step
    base_rss = _current_rss_mib()
    sync = torch.cuda.synchronize if device.startswith("cuda") else (lambda: None)
    step()  # warm-up
    sync()
    if device.startswith("cuda"):
        torch.cuda.reset_peak_memory_stats()
    times = []
    for _ in range(iters):
        t0 = time.perf_counter()
        step()
        sync()
        times.append(time.perf_counter() - t0)
    if device.startswith("cuda"):
        peak = torch.cuda.max_memory_allocated() / 2**20
    else:
        # peak resident set during the steps, above what the process held before them
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024 - base_rss
    return {
        "impl": impl,
        "clips": n_clips,
        "device": device,
        "block": block,
        "levels": tr.block_levels,
        "it_per_s": 1 / min(times),
        "s_per_it": min(times),
        "peak_mem_mib": peak,
        "data": source,
        "frames": data.lengths,
        "threads": torch.get_num_threads(),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument(
        "--iters", type=int, default=3, help="timed iterations per measurement (best kept)"
    )
    ap.add_argument("--blocks", type=str, default="0,1,2,3", help="0-based blocks to measure")
    ap.add_argument("--clips", type=str, default="1,4", help="numbers of clips")
    ap.add_argument("--impls", type=str, default="naive,mrlib,mrlib_nc2")
    ap.add_argument("--child", type=str, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:  # one measurement, printed as JSON for the parent
        impl, n, dev, b = args.child.split(":")
        print("RESULT " + json.dumps(measure(impl, int(n), dev, int(b), args.iters)))
        return

    print(describe(), flush=True)
    devices = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])
    rows = []
    for dev in devices:
        for n in map(int, args.clips.split(",")):
            for b in map(int, args.blocks.split(",")):
                for impl in args.impls.split(","):
                    cmd = [
                        sys.executable,
                        __file__,
                        "--iters",
                        str(args.iters),
                        "--child",
                        f"{impl}:{n}:{dev}:{b}",
                    ]
                    out = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
                    line = [x for x in out.stdout.splitlines() if x.startswith("RESULT ")]
                    if out.returncode or not line:
                        print(out.stderr[-2000:], file=sys.stderr)
                        raise SystemExit(f"measurement {impl}:{n}:{dev}:{b} failed")
                    r = json.loads(line[0][7:])
                    rows.append(r)
                    lv = f"{r['levels'][0] + 1}-{r['levels'][-1] + 1}"
                    print(
                        f"{dev:5s} clips={n} levels {lv} {impl:10s} "
                        f"{r['it_per_s']:7.3f} it/s  {r['peak_mem_mib']:8.0f} MiB",
                        flush=True,
                    )

    print(
        "\n| device | clips | levels | naive it/s | mrlib it/s | speed-up "
        "| mrlib n_critic=2 it/s | peak MiB naive / mrlib |"
    )
    print("|---|---|---|---|---|---|---|---|")
    key = lambda r: (r["device"], r["clips"], r["block"])
    by = {}
    for r in rows:
        by.setdefault(key(r), {})[r["impl"]] = r
    for (dev, n, _block), d in by.items():
        nv, mb, m2 = d.get("naive"), d.get("mrlib"), d.get("mrlib_nc2")
        lv = (nv or mb or m2)["levels"]
        f = lambda r: f"{r['it_per_s']:.3f}" if r else "-"
        sp = f"{mb['it_per_s'] / nv['it_per_s']:.1f}x" if nv and mb else "-"
        mem = f"{nv['peak_mem_mib']:.0f} / {mb['peak_mem_mib']:.0f}" if nv and mb else "-"
        lvs = f"{lv[0] + 1}-{lv[-1] + 1}"
        print(f"| {dev} | {n} | {lvs} | {f(nv)} | {f(mb)} | {sp} | {f(m2)} | {mem} |")
    meta = {"iters": args.iters, "loadavg_at_end": os.getloadavg()}
    print(f"\nwrote {write_json('train_speed', {'meta': meta, 'rows': rows})}")


if __name__ == "__main__":
    main()
