"""Loading BVH files of every skeleton convention mrlib is tested on, with no joint map.

For each convention of ``tests/rigs.py`` (Bandai Namco 1 and 2, CMU in both common
conversions, Mixamo, LaFAN1, 3ds Max Biped, a generic game rig) and each source motion,
the motion is written onto the rig by mrlib's BVH writer and loaded back with
``mrlib.load_motion`` and no ``joint_map``. Printed per convention and source:

* map: the shipped map that fitted, or ``recognised`` (with its confidence);
* fit mean / worst joint: the retargeting error ``load_motion`` reports (source joint
  positions against the SMPL joints they drive, cm; worst = the largest per-joint mean);
* round trip: the loaded motion's SMPL joints against the SMPL joints that made the file
  (cm, mean over joints and frames, after removing the mean root offset);
* load time in seconds (this machine; compare within one run only).

    python bench/retarget_conventions.py                     # synthetic walk + Bandai clips
    python bench/retarget_conventions.py --clips walk_happy_001 --seconds 4
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

import rigs  # noqa: E402

import mrlib  # noqa: E402
from mrlib.io import default_data_dir  # noqa: E402
from mrlib.io.bvh import write_bvh  # noqa: E402
from mrlib.synthetic import synthetic_walk  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument(
        "--clips",
        nargs="*",
        default=["walk_happy_001", "bow_proud_001", "dance-short_normal_001"],
        help="Bandai Namco dataset-1 clips (without prefix) used as sources",
    )
    ap.add_argument("--seconds", type=float, default=6.0, help="length used of each source")
    args = ap.parse_args()

    body = mrlib.load_body_model()
    sources = {"synthetic walk": synthetic_walk("walk_happy", seconds=args.seconds, fps=30.0)}
    data = default_data_dir() / "data"
    for c in args.clips:
        p = data / f"dataset-1_{c}.bvh"
        if p.is_file():
            m = mrlib.load_motion(p, body=body)
            sources[c] = m.slice(0, min(m.num_frames, int(args.seconds * m.fps)))
        else:
            print(f"(skipping {c}: {p} not found; set MRLIB_DATA_DIR)")
    print(f"{'convention':15} {'source':18} {'map':16} {'fit mean':>9} {'worst joint':>22} "
          f"{'round trip':>10} {'load s':>7}")  # fmt: skip
    worst_all: dict[str, tuple[float, float]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, rig in rigs.RIGS.items():
            for sname, src in sources.items():
                path = write_bvh(Path(tmp) / f"{name}.bvh", rigs.write_rig(src, rig, body))
                t0 = time.perf_counter()
                m = mrlib.load_motion(path, body=body)
                dt = time.perf_counter() - t0
                per = m.meta["retarget_joint_error_cm"]
                wj = max(per, key=per.get)
                a, b = body.motion_joints(m), body.motion_joints(src)
                d = (a - a[:, :1].mean(0)) - (b - b[:, :1].mean(0))
                rt = 100 * float(np.linalg.norm(d, axis=-1).mean())
                conf = m.meta.get("joint_map_confidence")
                label = m.meta["joint_map"] + (f" {conf:.2f}" if conf is not None else "")
                mean = m.meta["retarget_error_mean_cm"]
                print(f"{name:15} {sname[:18]:18} {label:16} {mean:8.2f}  {wj:>14} {per[wj]:6.2f} "
                      f"{rt:10.2f} {dt:7.2f}")  # fmt: skip
                prev = worst_all.get(name, (0.0, 0.0))
                worst_all[name] = (max(prev[0], mean), max(prev[1], per[wj]))
    print("\nper convention, over all sources: largest fit mean / largest per-joint mean (cm)")
    for name, (mean, worst) in worst_all.items():
        print(f"  {name:15} {mean:5.2f} / {worst:5.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
