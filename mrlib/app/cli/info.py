"""``mrlib info``: summarise a motion file (and, for a BVH, its joint map)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from mrlib.app.cli.common import add_command, joint_map_option, overwrite_option, parse_fps
from mrlib.errors import MrlibError


def add_info(sub) -> argparse.ArgumentParser:
    p = add_command(
        sub,
        "info",
        "print a summary of a motion file",
        "Load a motion file (.bvh, .npz, EasyMocap folder) and summarise it. For "
        "a BVH, also the joint map used (shipped, given or recognised, with its confidence) "
        "and the retargeting error of each SMPL joint.",
        [
            "mrlib info clip.bvh",
            "mrlib info clip.bvh --write-map map.json",
            "mrlib info clip.bvh --joint-map map.json   # after editing it",
        ],
    )
    p.add_argument("path", type=Path)
    p.add_argument("--fps", type=parse_fps, default=None, help="resample to this frame rate first")
    joint_map_option(p)
    p.add_argument(
        "--write-map",
        type=Path,
        default=None,
        metavar="JSON",
        help="BVH only: write the joint map used to this file, to edit and pass back with "
        "--joint-map",
    )
    overwrite_option(p, "replace the --write-map file if it exists (refused otherwise)")
    return p


def _write_map_template(args) -> None:
    """``--write-map`` for a skeleton no map fits: every SMPL joint with an empty source
    joint, the file's joints listed in the description, to fill in."""
    import json

    from mrlib.io.bvh import read_bvh
    from mrlib.io.outputs import write_text
    from mrlib.representation.skeleton import JOINT_NAMES

    names = read_bvh(args.path).skeleton.names
    data = {
        "name": "custom",
        "description": f"fill in the joint of {Path(args.path).name} each SMPL joint follows "
        f"(leave out those it has none for); its joints: {', '.join(names)}",
        "map": {n: "" for n in JOINT_NAMES},
    }
    write_text(args.write_map, json.dumps(data, indent=2) + "\n", overwrite=args.overwrite)
    print(f"wrote {args.write_map}: a template to fill in, then pass it back with --joint-map")


def cmd_info(args) -> int:
    from mrlib.errors import JointMapError
    from mrlib.io import JointMap, load_motion

    if args.write_map is not None:  # before reading anything
        from mrlib.io.outputs import check_writable

        check_writable(args.write_map, overwrite=args.overwrite)
    try:
        m = load_motion(
            args.path, fps=args.fps, joint_map=args.joint_map, up_axis=args.up_axis, unit=args.unit
        )
    except JointMapError as e:
        if args.write_map is None or args.joint_map is not None:
            raise
        print(f"error: {e}", file=sys.stderr)
        _write_map_template(args)  # written: the command ends here without an error
        return 1
    print(m)
    print(f"  duration     {m.duration:.2f} s")
    print(f"  label        {m.label}")
    print(f"  betas        {[round(float(b), 3) for b in m.betas]}")
    span = m.trans.max(0) - m.trans.min(0)
    path = float(np.linalg.norm(np.diff(m.trans[:, [0, 2]], axis=0), axis=1).sum())
    print(f"  root extent  x {span[0]:.2f} m, y {span[1]:.2f} m, z {span[2]:.2f} m")
    print(f"  root path    {path:.2f} m on the ground, {path / max(m.duration, 1e-9):.2f} m/s")
    table = ("joint_map_pairs", "retarget_joint_error_cm", "joint_map_report")
    shown = [k for k in m.meta if k not in table]
    width = max((len(k) for k in shown), default=0)
    for k in shown:
        v = m.meta[k]
        print(f"  meta.{k:<{width}} {f'{v:.4g}' if isinstance(v, float) else v}")
    if "joint_map_pairs" not in m.meta:
        if args.write_map is not None:
            raise MrlibError(f"{args.path}: --write-map is for BVH files (this one has no map)")
        return 0
    pairs, errors = m.meta["joint_map_pairs"], m.meta.get("retarget_joint_error_cm", {})
    if "joint_map_report" in m.meta:
        print("  " + m.meta["joint_map_report"].replace("\n", "\n  "))
    if m.meta.get("retarget_mode") == "rotations":
        print(
            "  body fit: motion transferred by rotations onto SMPL's mean shape (the source's "
            f"proportions are beyond its shape space), the root scaled by {m.meta['scale']:.3g}"
        )
    elif "retarget_mode" in m.meta:
        pinned = m.meta.get("retarget_betas_at_bound") or []
        print(
            "  body fit: motion transferred by positions; "
            + (f"betas {pinned} at the shape bound" if pinned else "no beta at the shape bound")
        )
    print(f"  {'SMPL joint':<15} {'source joint':<28} error cm")
    from mrlib.representation.skeleton import JOINT_NAMES

    for name in JOINT_NAMES:
        src = pairs.get(name)
        err = f"{errors[name]:8.2f}" if name in errors else "       -"
        print(f"  {name:<15} {src or '- (follows its parent)':<28} {err}")
    if args.write_map is not None:
        desc = f"written by `mrlib info` for {Path(args.path).name} ({m.meta['joint_map']} map)"
        JointMap("custom", pairs, desc).to_json(args.write_map, overwrite=args.overwrite)
        print(f"wrote {args.write_map}: edit it and pass it back with --joint-map")
    return 0
