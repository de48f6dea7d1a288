"""The docs' picture of the panel from ``run.sh``'s screenshots: the sidebar of each (while
training, after generating, after Cancel) side by side, the status bar of the first below.

    .venv/bin/python blender/ui_check/compose.py OUT [ROWS]   # writes OUT/panel.png

ROWS: how many pixel rows of the sidebar to keep from its top (default 900: the panel and
its Train, Generate and Restyle sections at run.sh's 1600x1600 screen; below is empty
viewport).
"""

import json
import sys
from pathlib import Path

import matplotlib.image as mpimg
import numpy as np


def crop(image: np.ndarray, rect: list[int]) -> np.ndarray:
    """``rect`` (x, y, width, height; Blender's window coordinates, y up) of ``image``."""
    x, y, w, h = rect
    top = image.shape[0] - (y + h)
    return image[max(top, 0) : image.shape[0] - y, x : x + w]


def main(out: Path, rows: int = 900) -> Path:
    log = json.loads((out / "ui_log.json").read_text())
    shots = [mpimg.imread(out / f"ui_{n}.png")[..., :3] for n in ("training", "generated", "cancelled")]  # fmt: skip
    panels = [crop(s, log["sidebar"])[:rows] for s in shots]
    gap = np.zeros((panels[0].shape[0], 4, 3), panels[0].dtype)
    row = np.concatenate([panels[0], gap, panels[1], gap, panels[2]], axis=1)
    # the status bar: Blender's bottom strip (a global area, not among the screen's in 3.4)
    bar = crop(shots[0], log.get("statusbar") or [0, 0, log["window"][0], 26])
    if bar.size:
        bar = bar[:, : row.shape[1]]
        pad = np.zeros((bar.shape[0], row.shape[1] - bar.shape[1], 3), row.dtype)
        row = np.concatenate([row, np.concatenate([bar, pad], axis=1)], axis=0)
    path = out / "panel.png"
    mpimg.imsave(path, row)
    print(f"wrote {path}: {row.shape[1]} x {row.shape[0]}")
    return path


if __name__ == "__main__":
    main(Path(sys.argv[1]), *(int(a) for a in sys.argv[2:3]))
