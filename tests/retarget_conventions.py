"""Loading BVH files of every skeleton convention mrlib is tested on, with no joint map.

For each convention of ``tests/rigs.py`` (Bandai Namco 1 and 2, CMU in both common
conversions, Mixamo, LaFAN1, 3ds Max Biped, a generic game rig; then Character Creator,
DAZ Genesis, Unreal's mannequin and Biped with thighs under the pelvis), the stylised
character (Mixamo's rig, head x1.6, legs x0.7, arms x1.2, torso x1.3) and the CMU and
Xia motion-capture skeletons with their own bone lengths at 120 fps, and each source
motion, the motion is written onto the rig by mrlib's BVH writer and loaded back with
``mrlib.load_motion`` and no ``joint_map``. Printed per convention and source:

* map: the shipped map that fitted, or ``recognised`` (with its confidence);
* mode: ``positions`` (SMPL's shape fitted to the joints) or ``rotations`` (the motion
  transferred by rotations: proportions SMPL's shape space cannot reach);
* fit mean / worst joint: the retargeting error ``load_motion`` reports (positions:
  source joint positions against the SMPL joints they drive; rotations: the normalised
  error, cm; worst = the largest per-joint mean);
* round trip: the loaded motion's SMPL joints against the SMPL joints that made the file
  (cm, mean over joints and frames, after removing the mean root offset; the rigs with a
  body of their own do not have SMPL's joints, so none);
* limb deg: mean angle between the loaded and the source motion's local rotations of
  hips, knees, ankles, shoulders, elbows and wrists;
* contacts: share of the file's foot contacts (ankle and toe joints slower than 0.3 leg
  lengths per second) that the loaded motion has within one frame;
* load time in seconds (this machine; compare within one run only).

    python tests/retarget_conventions.py                     # synthetic walk + Bandai clips
    python tests/retarget_conventions.py --clips walk_happy_001 --seconds 4

A script beside the rigs it writes (``tests/rigs.py``, which the retargeting tests use),
not a test (pytest collects ``test_*.py`` only); formerly ``tests/retarget_conventions.py``.
"""

from __future__ import annotations

import argparse
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
import rigs  # tests/rigs.py, beside this script

import mrlib
from mrlib.datasets.synthetic import synthetic_walk
from mrlib.io import default_data_dir
from mrlib.io.bvh import write_bvh
from mrlib.io.retarget_report import RetargetWarning


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
    print(f"{'convention':17} {'source':18} {'map':16} {'mode':9} {'fit mean':>8} "
          f"{'worst joint':>22} {'round trip':>10} {'limb deg':>8} {'contacts':>8} "
          f"{'load s':>7}")  # fmt: skip
    worst_all: dict[str, list[float]] = {}
    every = {**rigs.RIGS, "stylised": rigs.STYLISED, **rigs.MOCAP}
    with tempfile.TemporaryDirectory() as tmp:
        for name, rig in every.items():
            for sname, src in sources.items():
                bvh = rigs.write_rig(src, rig, body)
                path = write_bvh(Path(tmp) / f"{name}.bvh", bvh)
                t0 = time.perf_counter()
                with warnings.catch_warnings(record=True) as caught:
                    warnings.simplefilter("always", RetargetWarning)
                    m = mrlib.load_motion(path, body=body)
                dt = time.perf_counter() - t0
                per = m.meta["retarget_joint_error_cm"]
                wj = max(per, key=per.get)
                own = bool(rig.geometry or rig.proportions or rig.arms_down)
                if rig.fps is not None:  # compare at the source's rate
                    m = m.resample(src.fps)
                rt = float("nan")
                if not own:
                    a, b = body.motion_joints(m), body.motion_joints(src)
                    d = (a - a[:, :1].mean(0)) - (b - b[:, :1].mean(0))
                    rt = 100 * float(np.linalg.norm(d, axis=-1).mean())
                n = min(m.num_frames, src.num_frames)
                deg = float(rigs.limb_angle_error(src.slice(0, n), m.slice(0, n)).mean())
                jmap = mrlib.io.load_joint_map(m.meta["joint_map_pairs"])
                ref = rigs.joint_contacts(rigs.rig_smpl_joints(bvh, rig, jmap), bvh.fps)
                got = rigs.joint_contacts(body.motion_joints(m.resample(bvh.fps)), bvh.fps)
                n = min(len(ref), len(got))
                share, _ = rigs.contact_timing(ref[:n], got[:n])
                conf = m.meta.get("joint_map_confidence")
                label = m.meta["joint_map"] + (f" {conf:.2f}" if conf is not None else "")
                mean = m.meta["retarget_error_mean_cm"]
                flag = " warned" if caught else ""
                print(f"{name:17} {sname[:18]:18} {label:16} {m.meta['retarget_mode']:9} "
                      f"{mean:8.2f} {wj:>14} {per[wj]:6.2f} {rt:10.2f} {deg:8.2f} "
                      f"{100 * share:7.0f}% {dt:7.2f}{flag}")  # fmt: skip
                prev = worst_all.get(name, [0.0, 0.0, 0.0, 100.0])
                worst_all[name] = [
                    max(prev[0], mean),
                    max(prev[1], per[wj]),
                    max(prev[2], deg),
                    min(prev[3], 100 * share),
                ]
    print(
        "\nper convention, over all sources: largest fit mean / largest per-joint mean (cm), "
        "largest limb angle error (deg), smallest share of contacts kept"
    )
    for name, (mean, worst, deg, share) in worst_all.items():
        print(f"  {name:17} {mean:5.2f} / {worst:5.2f}   {deg:5.2f} deg   {share:4.0f}%")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
