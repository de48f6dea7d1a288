"""Render the pictures used in README.md from data that ships with mrlib.

    python tools/make_readme_images.py                  # writes docs/images/*.png
    python tools/make_readme_images.py --no-crossover   # only the contact render (seconds)

The crossover picture trains the ``tutorial`` preset on the four clips of
``data_samples/`` (19-26 minutes on a 2-core CPU running two other jobs; the run is kept in
``outputs/readme_model`` and reused), then renders a coarse-A / fine-B sample next to
pure A and pure B samples with the same noise.

Only the embedded default body and the synthetic data_samples are used, so the images
carry no third-party data.
"""

from __future__ import annotations

from pathlib import Path

import imageio.v3 as iio
import numpy as np

import mrlib

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "images"


def crossover_figure(
    body, coarse: str = "walk_sad", fine: str = "walk_happy", split: int = 2, seed: int = 2
):
    """Three mesh strips (pure coarse label, pure fine label, crossover), labels named."""
    import torch
    from matplotlib.figure import Figure

    from mrlib.model.presets import tutorial
    from mrlib.sampling.conditions import Condition
    from mrlib.sampling.generation import generate
    from mrlib.training.data import TrainingSet
    from mrlib.training.trainer import train_or_reuse
    from mrlib.viz.meshes import crop_to_bodies, evenly_spaced_frames

    torch.set_num_threads(1)
    clips = [mrlib.load_motion(p) for p in sorted((ROOT / "data_samples").glob("*.npz"))]
    data = TrainingSet.from_motions(clips, body=body)
    model, _ = train_or_reuse(data, tutorial(), ROOT / "outputs" / "readme_model", body=body)
    L, length = model.num_levels, 90
    rows = [
        (f"'{coarse}' at every level", generate(model, coarse, length=length, seed=seed)),
        (
            f"crossover: '{coarse}' at levels 1-{split} (coarse), '{fine}' at levels {split + 1}-{L} (fine)",
            generate(model, Condition.crossover(coarse, fine, split), length=length, seed=seed),
        ),
        (f"'{fine}' at every level", generate(model, fine, length=length, seed=seed)),
    ]
    frames = evenly_spaced_frames(length, 6)
    imgs = [
        crop_to_bodies(
            mrlib.viz.render_meshes(
                m, body, frames=frames, highlight_contacts=False, window_size=(1400, 520)
            )
        )
        for _, m in rows
    ]
    h, w = max(i.shape[0] for i in imgs), max(i.shape[1] for i in imgs)
    imgs = [
        np.pad(i, ((0, h - i.shape[0]), (0, w - i.shape[1]), (0, 0)), constant_values=255)
        for i in imgs
    ]
    fig = Figure(figsize=(w / 100, 3 * (h + 36) / 100), dpi=100)
    for k, ((title, _), img) in enumerate(zip(rows, imgs, strict=True)):
        ax = fig.add_axes((0, 1 - (k + 1) / 3, 1, (h / (h + 36)) / 3))
        ax.imshow(img)
        ax.axis("off")
        ax.set_title(title, fontsize=11)
    fig.savefig(OUT / "crossover.png")
    print("wrote", OUT / "crossover.png")


def main() -> None:
    import argparse

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--no-crossover", action="store_true", help="skip the crossover picture")
    args = p.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    body = mrlib.load_body_model()
    walk = mrlib.load_motion(ROOT / "data_samples" / "walk_happy.npz")
    contacts = mrlib.representation.foot_contacts(walk, body)
    frames = np.linspace(0, 44, 6).astype(int)
    img = mrlib.viz.render_meshes(
        walk.replace(contacts=contacts), body, frames=frames, layout="path", window_size=(1100, 420)
    )
    iio.imwrite(OUT / "walk_contacts.png", img)
    print("wrote", OUT / "walk_contacts.png", img.shape)
    if not args.no_crossover:
        crossover_figure(body)


if __name__ == "__main__":
    main()
