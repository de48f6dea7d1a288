"""Render the pictures used in README.md from data that ships with mrlib.

    python tools/make_readme_images.py      # writes docs/images/*.png

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


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    body = mrlib.load_body_model()
    walk = mrlib.load_motion(ROOT / "data_samples" / "walk_happy.npz")
    contacts = mrlib.foot_contacts(walk, body)
    frames = np.linspace(0, 44, 6).astype(int)
    img = mrlib.render_meshes(
        walk.replace(contacts=contacts), body, frames=frames, layout="path", window_size=(1100, 420)
    )
    iio.imwrite(OUT / "walk_contacts.png", img)
    print("wrote", OUT / "walk_contacts.png", img.shape)


if __name__ == "__main__":
    main()
