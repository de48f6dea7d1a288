"""Regenerate data_samples/: the small labelled set the demo and tests use.

    python tools/make_data_samples.py            # writes data_samples/*.npz

The clips are procedural (mrlib.datasets.synthetic), made on the embedded default body; nothing
is downloaded and nothing comes from captured data.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from mrlib.datasets.synthetic import synthetic_dataset
from mrlib.io import save_motion
from mrlib.representation.body import load_body_model


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument(
        "--out", type=Path, default=Path(__file__).resolve().parents[1] / "data_samples"
    )
    ap.add_argument("--seconds", type=float, default=8.0)
    ap.add_argument("--fps", type=float, default=30.0)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    body = load_body_model()
    for clip in synthetic_dataset(args.seconds, args.fps, args.seed, body=body):
        path = args.out / f"{clip.label}.npz"
        save_motion(clip, path)
        print(f"wrote {path}: {clip}")


if __name__ == "__main__":
    main()
