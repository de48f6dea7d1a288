"""Speed of loading and retargeting BVH files (``mrlib.io.load_motion``).

Run from the repository root::

    python bench/load_speed.py                  # all Bandai Namco clips + a one-minute file
    python bench/load_speed.py --repeats 5      # more repeats of the one-minute file

Needs the Bandai Namco Research Motion Dataset 1, found as mrlib finds it
(``$MRLIB_DATA_DIR``, the ``../shared`` mirror, else the clips fetched into mrlib's cache:
``mrlib data fetch bandai --all`` for every clip). Two parts, printed and written to
``bench/results/load_speed.json`` (with the machine, ``bench/common.py``):

1. **Every clip**: parse + retarget time of each clip, with its retargeting error.
2. **One minute**: 1800 frames (60 s at 30 fps) made by looping the frames of a walking
   clip, written to a temporary file outside the repository, then loaded ``--repeats``
   times; the time of each stage (parse, forward kinematics + retarget, the rest) is
   reported for the best run.

Timings are wall-clock on whatever machine runs this; the figures in the project
notes were taken on a 2-core CPU machine.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
from common import RESULTS, bandai_dir, describe, write_json

from mrlib.io import load_motion
from mrlib.io.bodyfit import default_body
from mrlib.io.bvh import format_bvh, parse_bvh, read_bvh
from mrlib.io.retarget import retarget_bvh


def one_minute_file(src: Path, frames: int, out_dir: Path) -> Path:
    """A BVH of ``frames`` frames: ``src``'s frames repeated (the root jumps back at
    each loop, which does not change the cost)."""
    bvh = read_bvh(src)
    idx = np.arange(frames) % bvh.num_frames
    looped = type(bvh)(bvh.skeleton, bvh.motion[idx], bvh.frame_time, str(src))
    path = out_dir / "one_minute.bvh"
    path.write_text(format_bvh(looped))
    return path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument(
        "--repeats", type=int, default=3, help="loads of the one-minute file (best is kept)"
    )
    ap.add_argument(
        "--frames", type=int, default=1800, help="frames of the long file (1800 = 1 min at 30 fps)"
    )
    ap.add_argument("--out", type=Path, default=RESULTS / "load_speed.json")
    args = ap.parse_args()
    files = sorted((bandai_dir() / "data").glob("*.bvh"))  # exits when there are none
    print(describe(), flush=True)
    body = default_body()
    load_motion(files[0], body=body)  # warm-up: imports, caches

    # 1. every clip
    rows = []
    for f in files:
        t0 = time.perf_counter()
        m = load_motion(f, body=body)
        dt = time.perf_counter() - t0
        rows.append(
            (
                f.stem,
                m.num_frames,
                dt,
                m.meta["retarget_error_mean_cm"],
                m.meta["retarget_error_max_cm"],
            )
        )
    frames = np.array([r[1] for r in rows])
    secs = np.array([r[2] for r in rows])
    mean_err = np.array([r[3] for r in rows])
    max_err = np.array([r[4] for r in rows])
    print(f"{len(rows)} clips, {frames.sum()} frames, {secs.sum():.2f} s in total")
    print(f"  per clip: median {np.median(secs) * 1e3:.0f} ms, max {secs.max() * 1e3:.0f} ms "
          f"({rows[int(secs.argmax())][0]}, {frames[secs.argmax()]} frames)")  # fmt: skip
    print(f"  per 1000 frames: {secs.sum() / frames.sum() * 1e3:.3f} s")
    print(f"  retarget error: mean over all frames {np.average(mean_err, weights=frames):.2f} cm, "
          f"worst clip mean {mean_err.max():.2f} cm ({rows[int(mean_err.argmax())][0]}), "
          f"max {max_err.max():.2f} cm ({rows[int(max_err.argmax())][0]})")  # fmt: skip

    # 2. one minute
    src = next((f for f in files if f.stem == "dataset-1_walk_normal_001"), files[0])
    with tempfile.TemporaryDirectory() as tmp:
        path = one_minute_file(src, args.frames, Path(tmp))
        best = None
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            bvh = parse_bvh(path.read_text(), source=path)
            t1 = time.perf_counter()
            retarget_bvh(bvh, body=body)
            t2 = time.perf_counter()
            load_motion(path, body=body)  # the whole public call, label lookup included
            t3 = time.perf_counter()
            run = {"parse_s": t1 - t0, "retarget_s": t2 - t1, "load_motion_s": t3 - t2}
            if best is None or run["load_motion_s"] < best["load_motion_s"]:
                best = run
    print(f"one minute ({args.frames} frames of {src.stem}), best of {args.repeats}: "
          f"load_motion {best['load_motion_s']:.3f} s (parse {best['parse_s']:.3f} s, "
          f"retarget {best['retarget_s']:.3f} s)")  # fmt: skip

    result = {
        "clips": [
            {
                "name": n,
                "frames": int(t),
                "seconds": round(s, 4),
                "error_mean_cm": round(e, 3),
                "error_max_cm": round(x, 3),
            }
            for n, t, s, e, x in rows
        ],
        "summary": {
            "clips": len(rows),
            "frames": int(frames.sum()),
            "total_s": float(secs.sum()),
            "median_clip_s": float(np.median(secs)),
            "error_mean_cm": float(np.average(mean_err, weights=frames)),
            "error_worst_clip_mean_cm": float(mean_err.max()),
            "error_max_cm": float(max_err.max()),
        },
        "one_minute": {"frames": args.frames, "source": src.stem, "repeats": args.repeats, **best},
    }
    print(f"wrote {write_json('load_speed', result, args.out)}")


if __name__ == "__main__":
    main()
