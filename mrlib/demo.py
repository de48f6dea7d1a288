"""The end-to-end demo behind ``make demo`` / ``mrlib demo``.

Runs on the synthetic clips in ``data_samples/`` (nothing to download):

1. load the labelled clips, compute foot contacts, render them;
2. if the Bandai Namco clips are found (``MRLIB_DATA_DIR``), retarget one BVH onto SMPL
   and render it next to its contact labels;
3. train the multi-resolution GAN on the four clips (``tutorial`` preset);
4. sample every label, and a crossover: one label's coarse levels with another label's
   fine levels, rendered with the labels named;
5. evaluate against the training clips (coverage, diversity, plausibility, calibration
   rows) and export the samples as SMPL ``.npz`` and ``.bvh``.

Everything goes to one output folder; ``summary.md`` there lists what was made.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np

__all__ = ["run_demo", "DATA_SAMPLES"]

DATA_SAMPLES = Path(__file__).resolve().parents[1] / "data_samples"


def _save_png(img: np.ndarray, path: Path) -> Path:
    import imageio.v3 as iio

    iio.imwrite(path, img)
    return path


def _titled(img: np.ndarray, title: str, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    h, w = img.shape[:2]
    fig = Figure(figsize=(w / 100, h / 100 + 0.4), dpi=100)
    ax = fig.add_axes((0, 0, 1, h / (h + 40)))
    ax.imshow(img)
    ax.axis("off")
    fig.suptitle(title, fontsize=12, y=0.99)
    fig.savefig(path)
    return path


def run_demo(
    out: str | Path = "outputs",
    *,
    quick: bool = False,
    iterations: int | None = None,
    samples: int = 10,
    seed: int = 0,
) -> Path:
    """Run the demo, writing into ``out``; returns the path of ``summary.md``.

    ``quick`` shrinks training to a smoke-test budget (seconds, results not meaningful);
    ``iterations`` overrides the per-block iteration count of the tutorial preset.
    """
    import mrlib
    from mrlib.config import tutorial
    from mrlib.data import TrainingSet
    from mrlib.evaluate import evaluate_model
    from mrlib.render import evenly_spaced_frames, render_meshes
    from mrlib.sample import generate, load_model
    from mrlib.train import train

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    lines = ["# mrlib demo", ""]
    t0 = time.time()
    body = mrlib.load_body_model()

    # 1. the labelled training clips
    clips = [mrlib.load_motion(p) for p in sorted(DATA_SAMPLES.glob("*.npz"))]
    print(f"[1/5] {len(clips)} synthetic training clips: {[c.label for c in clips]}")
    clips = [c.replace(contacts=mrlib.foot_contacts(c, body)) for c in clips]
    for c in clips:
        img = render_meshes(c, body, frames=evenly_spaced_frames(len(c), 5))
        _titled(
            img,
            f"training clip '{c.label}' (synthetic, contacts in red)",
            out / f"train_{c.label}.png",
        )
    lines += ["## Training clips (synthetic, `data_samples/`)", ""]
    lines += [
        f"- `{c.label}`: {c.num_frames} frames @ {c.fps:g} fps -> `train_{c.label}.png`"
        for c in clips
    ]

    # 2. retargeting a real capture, when the Bandai Namco clips are there
    from mrlib.evaluate import default_data_dir

    bvh = Path(default_data_dir()) / "data" / "dataset-1_walk_happy_001.bvh"
    if bvh.exists():
        t = time.time()
        real = mrlib.load_motion(bvh)
        real = real.replace(contacts=mrlib.foot_contacts(real, body))
        dt = time.time() - t
        img = render_meshes(real, body, frames=evenly_spaced_frames(len(real), 6))
        _titled(
            img,
            f"{bvh.name} retargeted onto SMPL ({real.meta['retarget_error_mean_cm']:.1f} cm mean joint error)",
            out / "retargeted_bvh.png",
        )
        print(
            f"[2/5] retargeted {bvh.name} in {dt:.2f} s, mean joint error "
            f"{real.meta['retarget_error_mean_cm']:.2f} cm"
        )
        lines += [
            "",
            "## Retargeting",
            "",
            f"- `{bvh.name}` -> SMPL in {dt:.2f} s, mean joint error "
            f"{real.meta['retarget_error_mean_cm']:.2f} cm -> `retargeted_bvh.png`",
        ]
    else:
        print(f"[2/5] skipped: no Bandai Namco clips at {bvh.parent} (set MRLIB_DATA_DIR)")

    # 3. training
    cfg = tutorial()
    its = 10 if quick else iterations
    if its is not None:
        cfg = cfg.replace(block_iterations=(its,) * cfg.num_blocks, checkpoint_every=0)
    cfg = dataclasses.replace(cfg, seed=seed)
    data = TrainingSet.from_motions(clips, body=body)
    print(
        f"[3/5] training: {cfg.model.num_levels} levels, blocks of {cfg.block_size}, "
        f"iterations per block {cfg.block_iterations}"
    )
    res = train(data, cfg, out / "model", body=body)
    model = load_model(res.checkpoint)
    lines += [
        "",
        "## Training",
        "",
        f"- {cfg.model.num_levels} levels, iterations per block "
        f"{cfg.block_iterations}, {res.wall_time_s:.0f} s -> `model/checkpoint.pt`",
    ]

    # 4. sampling and crossover
    print("[4/5] sampling every label and a crossover")
    lines += ["", "## Samples", ""]
    (out / "samples").mkdir(exist_ok=True)
    L = model.num_levels
    for lab in model.labels:
        m = generate(model, lab, length=2 * clips[0].num_frames, seed=seed)
        mrlib.save_motion(m, out / "samples" / f"{lab}.npz")
        mrlib.save_motion(m, out / "samples" / f"{lab}.bvh")
        img = render_meshes(m, body, frames=evenly_spaced_frames(len(m), 6))
        _titled(img, f"generated '{lab}' (seed {seed})", out / f"sample_{lab}.png")
        lines.append(f"- `{lab}`: `samples/{lab}.npz`, `samples/{lab}.bvh`, `sample_{lab}.png`")
    coarse, fine = (
        ("walk_sad", "walk_happy")
        if {"walk_sad", "walk_happy"} <= set(model.labels)
        else (model.labels[0], model.labels[-1])
    )
    split = L // 2
    mix = generate(
        model,
        conditions=[(coarse, (1, split)), (fine, (split + 1, L))],
        length=2 * clips[0].num_frames,
        seed=seed,
    )
    mrlib.save_motion(mix, out / "samples" / "crossover.npz")
    img = render_meshes(mix, body, frames=evenly_spaced_frames(len(mix), 6))
    _titled(
        img,
        f"crossover: '{coarse}' at levels 1-{split} (coarse), '{fine}' at levels {split + 1}-{L} (fine)",
        out / "crossover.png",
    )
    lines.append(
        f"- crossover `{coarse}` (levels 1-{split}) + `{fine}` (levels {split + 1}-{L}): `crossover.png`"
    )

    # 5. evaluation
    n = 2 if quick else samples
    print(f"[5/5] evaluating with {n} samples per label")
    result = evaluate_model(model, num_samples=n, seed=seed, body=body, progress=False)
    result.save(out / "evaluation")
    lines += ["", "## Evaluation", "", result.to_markdown(), ""]
    lines.append(f"Total time {time.time() - t0:.0f} s.")
    summary = out / "summary.md"
    summary.write_text("\n".join(lines) + "\n")
    print(f"done in {time.time() - t0:.0f} s: see {summary}")
    return summary
