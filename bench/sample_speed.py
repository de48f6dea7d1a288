"""Time to generate one-minute motions, raw and with the foot-contact clean-up.

The demo's model: ``demo`` networks (the ``tutorial`` ones; weights barely trained, speed
does not depend on them) on the four synthetic clips of ``data_samples/`` at the demo's
15 fps, so a one-minute sample has 900 frames (``--fps 30`` for 1800). For 1, 8 and 64
samples in one batch, and for 1 and 2 torch threads, it prints the time per call of
``mrlib.sampling.generation.generate`` next to the sampler it replaced (samples packed end to end and
run through the training path with per-frame FiLM, each converted alone with roma), as
ratios measured in the same run; then the clean-up of a one-minute walk with the analytic
IK (``cleanup_foot_contacts``) against the per-frame optimisation
(``experiments/cleanup_studies.py``'s ``cleanup_optimised``):

    python bench/sample_speed.py [--fps 15] [--threads 1,2] [--repeats 3] [--checkpoint ckpt.pt]

Writes ``bench/results/sample_speed.json``.
"""

from __future__ import annotations

import argparse
import platform
import sys
import tempfile
import time
from pathlib import Path

from common import describe, set_threads, write_json
from experiments.cleanup_studies import cleanup_optimised


def _best(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def _packed_generate(model, label: str, length: int, seed: int, num_samples: int):
    """The sampler before the batched path: every sample packed end to end and run through
    the generator's training path (gathers for padding and upsampling, FiLM per frame),
    then converted sample by sample with roma's rotation-matrix-to-rotvec."""
    import numpy as np
    import roma
    import torch

    from mrlib.model.pyramid import PackedLevels, pyramid_lengths
    from mrlib.representation.features import root_velocity_to_trans, split_features
    from mrlib.representation.motion import Motion
    from mrlib.representation.rotations import sixd_to_matrix
    from mrlib.sampling.conditions import Condition

    L = model.num_levels
    W = Condition.label(label).weights(model)
    pad = (model.config.model.kernel_size - 1) // 2
    lengths = pyramid_lengths(length, L, model.config.model.scale_factor, min_length=pad + 1)
    amp = (W * model.sigma.float().T).sum(1)
    layout = PackedLevels.from_table(
        torch.tensor(lengths).expand(num_samples, L), 2 * pad, model.device
    )
    z = [torch.empty(num_samples, 1, n) for n in lengths]
    for b in range(num_samples):
        state = np.random.SeedSequence([seed, b]).generate_state(2, np.uint32)
        g = torch.Generator().manual_seed(int(state[0]) << 32 | int(state[1]))
        for i in range(L):
            z[i][b, 0] = torch.randn(lengths[i], generator=g)
    noises = [layout.pack(list(z[i] * amp[i]), i) for i in range(L)]
    conds = [
        layout.pack([W[i][:, None].expand(-1, n)] * num_samples, i).transpose(1, 2)
        for i, n in enumerate(lengths)
    ]
    with torch.no_grad():
        out = model.generator.run(layout, noises, conds)
    motions = []
    for x in layout.unpack(out, L - 1):
        f = model.normalizer.denormalize(x.T).double()
        rot, root, c = split_features(f)
        poses = roma.rotmat_to_rotvec(sixd_to_matrix(rot))
        trans = root_velocity_to_trans(root, model.fps)
        motions.append(
            Motion(poses.numpy(), trans.numpy(), model.fps, contacts=(c > 0.5).float().numpy())
        )
    return motions


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--fps", type=float, default=15.0, help="the model's frame rate [15]")
    ap.add_argument("--threads", default="1,2", help="torch thread counts [1,2]")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--checkpoint", type=Path, default=None, help="a trained model [train one]")
    args = ap.parse_args(argv)

    import torch

    import mrlib
    import mrlib.datasets.synthetic
    from mrlib.app.demo import DATA_SAMPLES
    from mrlib.model.presets import demo
    from mrlib.model.trained import load_model
    from mrlib.sampling.cleanup import cleanup_foot_contacts
    from mrlib.sampling.generation import generate
    from mrlib.sampling.sampler import Sampler
    from mrlib.training.data import TrainingSet
    from mrlib.training.trainer import train

    body = mrlib.load_body_model()
    with tempfile.TemporaryDirectory() as tmp:
        ckpt = args.checkpoint
        if ckpt is None:
            clips = [mrlib.load_motion(p, fps=args.fps) for p in sorted(DATA_SAMPLES.glob("*.npz"))]
            cfg = demo().replace(block_iterations=(2, 2, 2, 2), fps=args.fps)
            ckpt = train(
                TrainingSet.from_motions(clips, body=body), cfg, tmp, body=body, progress=False
            ).checkpoint
        model = load_model(ckpt)
    T = round(60 * model.fps)
    label = model.labels[0]
    threads = [int(t) for t in args.threads.split(",")]
    rows, result = [], {"frames": T, "fps": model.fps}
    for th in threads:
        set_threads(th)  # explicit: mrlib's own calls keep it (mrlib.threads)
        for n in (1, 8, 64):
            reps = args.repeats if n < 64 else max(1, args.repeats - 1)
            new = _best(
                lambda n=n: generate(
                    model,
                    label,
                    length=T,
                    seed=0,
                    num=n,
                    sampler=Sampler(fix_contacts=False, candidates=1),
                ),
                reps,
            )
            old = _best(lambda n=n: _packed_generate(model, label, T, 0, n), reps)
            rows.append((f"generate {n} x 1 min, {th} thread(s)", new, old))
            result[f"generate_{n}_threads_{th}_s"] = new
            result[f"packed_{n}_threads_{th}_s"] = old
    set_threads(threads[-1])
    # a one-minute walk with contacts labelled from its own motion (a barely trained model
    # predicts few contacts, which would leave the clean-up nothing to do)
    m = mrlib.datasets.synthetic.synthetic_walk(
        "walk_normal", seconds=60.0, fps=model.fps, body=body
    )
    m = m.replace(contacts=mrlib.representation.foot_contacts(m, body))
    ik = _best(lambda: cleanup_foot_contacts(m, body), args.repeats)
    opt = _best(lambda: cleanup_optimised(m, body), 1)
    both = _best(
        lambda: generate(model, label, length=T, seed=0, body=body),
        args.repeats,
    )
    result.update(cleanup_ik_s=ik, cleanup_optimise_s=opt, generate_and_cleanup_s=both)

    print(describe())
    print(
        f"one minute = {T} frames at {model.fps:g} fps; {platform.machine()}, "
        f"{torch.get_num_threads()} threads for the clean-up rows\n"
    )
    print("| what | s per call | replaced sampler, s | speed-up |\n|---|---:|---:|---:|")
    for what, new, old in rows:
        print(f"| {what} | {new:.3f} | {old:.3f} | {old / new:.1f}x |")
    print(f"| clean-up of 1 min, analytic IK | {ik:.3f} | | |")
    print(f"| clean-up of 1 min, per-frame optimisation | {opt:.3f} | | |")
    print(f"| generate 1 x 1 min + IK clean-up | {both:.3f} | | |")
    print(f"\nanalytic IK is {opt / ik:.0f}x faster than the per-frame optimisation")
    write_json("sample_speed", result)
    return 0


if __name__ == "__main__":
    sys.exit(main())
