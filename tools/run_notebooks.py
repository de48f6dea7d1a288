"""Execute the notebooks in place at their default budget, so the committed files carry
their outputs (figures as PNG) and a reader on GitHub sees every figure without running.

    python tools/run_notebooks.py                 # all of notebooks/*.ipynb, in order
    python tools/run_notebooks.py notebooks/03_condition_crossover.ipynb

Behind ``make notebooks``. Each notebook runs top to bottom in a fresh kernel from its
own folder (in order, so that later notebooks reuse the models earlier ones trained:
``mrlib.training.trainer.train_cached``). The wall time, the date and a SHA-256 of the code cells'
source are written to the notebook's ``metadata["mrlib"]``;
``tests/test_notebooks.py`` fails when a notebook's code no longer matches the outputs
it carries. Outputs are kept only when the whole notebook ran without an error.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import platform
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MAX_BYTES = 1_000_000  # the largest notebook we commit, outputs included


def code_hash(nb: dict) -> str:
    """SHA-256 of the notebook's code cells' source, in order (markdown edits do not
    change it; any code edit does)."""
    h = hashlib.sha256()
    for cell in nb["cells"]:
        if cell["cell_type"] == "code":
            text = cell["source"] if isinstance(cell["source"], str) else "".join(cell["source"])
            h.update(text.strip().encode() + b"\0")
    return h.hexdigest()


def _palettes() -> list[dict]:
    from PIL import Image

    q = Image.Quantize
    return [
        {"method": q.MEDIANCUT},
        {"method": q.MEDIANCUT, "kmeans": 3},
        {"method": q.MAXCOVERAGE},
    ]


MEAN_TOLERANCE = 2.0  # mean error per channel (of 255) a palette image may add


def shrink_images(nb: dict, colors: int = 256, tolerance: int = 12, flat: int = 50) -> int:
    """Re-encode every PNG output as a palette PNG of at most ``colors`` colours where
    that is smaller and every flat colour (one that fills at least ``flat`` pixels: a
    legend patch, a line, a background) stays within ``tolerance`` (of 255) in every
    channel: shading may round, but two colours of a legend are never merged into one (a
    128-colour palette had made orange and red one colour). Returns how many were
    replaced."""
    import base64
    import io

    import numpy as np
    from PIL import Image

    palettes = _palettes()
    n = 0
    for cell in nb["cells"]:
        for out in cell.get("outputs", []):
            data = out.get("data", {})
            if "image/png" not in data:
                continue
            raw = base64.b64decode(data["image/png"])
            img = Image.open(io.BytesIO(raw)).convert("RGB")
            before = np.asarray(img, np.int16).reshape(-1, 3)
            _, which, counts = np.unique(before, axis=0, return_inverse=True, return_counts=True)
            on_flat = counts[which.ravel()] >= flat
            best = raw
            for how in palettes:  # the smallest palette image that keeps every flat colour
                small = img.quantize(colors=colors, dither=Image.Dither.NONE, **how)
                err = np.abs(np.asarray(small.convert("RGB"), np.int16).reshape(-1, 3) - before)
                if err[on_flat].max(initial=0) > tolerance or err.mean() > MEAN_TOLERANCE:
                    continue
                buf = io.BytesIO()
                small.save(buf, "PNG", optimize=True)
                if buf.tell() < len(best):
                    best = buf.getvalue()
            if best is not raw:
                data["image/png"] = base64.b64encode(best).decode()
                n += 1
    return n


def run(path: Path, timeout: int) -> float:
    import nbformat
    from nbclient import NotebookClient

    nb = nbformat.read(path, as_version=4)
    env_quick = os.environ.pop("MRLIB_QUICK", None)  # the default budget, never the smoke test
    os.environ.setdefault("MRLIB_PROGRESS", "off")  # a committed bar would show it frozen
    try:
        client = NotebookClient(
            nb,
            timeout=timeout,
            kernel_name="python3",
            resources={"metadata": {"path": str(path.parent)}},
        )
        t0 = time.perf_counter()
        client.execute()
        wall = time.perf_counter() - t0
    finally:
        if env_quick is not None:
            os.environ["MRLIB_QUICK"] = env_quick
    nb.metadata["mrlib"] = {
        "source_sha256": code_hash(nb),
        "wall_time_s": round(wall, 1),
        "executed": time.strftime("%Y-%m-%d"),
        "machine": f"{platform.machine()}, {os.cpu_count()} CPUs, {platform.system()}",
    }
    for cell in nb.cells:  # execution counts from 1 in order; no widget state blobs
        cell.get("metadata", {}).pop("execution", None)
    nb.metadata.pop("widgets", None)
    shrink_images(nb)
    nbformat.write(nb, path)
    size = path.stat().st_size
    print(f"{path.name}: {wall:.0f} s, {size / 1e6:.2f} MB", flush=True)
    if size > MAX_BYTES:
        print(f"warning: {path.name} is over {MAX_BYTES / 1e6:g} MB with its outputs", flush=True)
    return wall


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("notebooks", nargs="*", type=Path)
    ap.add_argument("--timeout", type=int, default=1800, help="seconds per cell [1800]")
    args = ap.parse_args(argv)
    paths = args.notebooks or sorted((ROOT / "notebooks").glob("[0-9][0-9]_*.ipynb"))
    times = {}
    for p in paths:
        times[p.name] = run(p.resolve(), args.timeout)
    print(json.dumps({k: round(v, 1) for k, v in times.items()}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
