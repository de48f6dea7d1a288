"""``mrlib export``: convert a motion file (BVH, SMPL .npz, glTF .glb)."""

from __future__ import annotations

import argparse
from pathlib import Path

from mrlib.app.cli.common import add_command, joint_map_option, overwrite_option, parse_fps


def add_export(sub) -> argparse.ArgumentParser:
    p = add_command(
        sub,
        "export",
        "convert a motion file (BVH, SMPL .npz, glTF .glb)",
        "Convert between formats: any readable motion file to AMASS-style .npz, "
        "to BVH on the SMPL skeleton, or to a .glb with the skinned body mesh and the "
        "animation (browser viewers, Blender, game engines).",
    )
    p.add_argument("src", type=Path, help="input: .bvh, .npz or an EasyMocap folder")
    p.add_argument("dst", type=Path, help="output: .npz, .bvh or .glb")
    p.add_argument("--fps", type=parse_fps, default=None, help="resample to this frame rate")
    joint_map_option(p)
    overwrite_option(p, "replace DST if it exists")
    return p


def cmd_export(args) -> int:
    from mrlib.io import load_motion, save_motion
    from mrlib.io.outputs import check_writable

    check_writable(args.dst, overwrite=args.overwrite)  # before reading anything
    m = load_motion(
        args.src, fps=args.fps, joint_map=args.joint_map, up_axis=args.up_axis, unit=args.unit
    )
    save_motion(m, args.dst, overwrite=args.overwrite)
    print(f"wrote {args.dst} ({m.num_frames} frames @ {m.fps:g} fps)")
    return 0
