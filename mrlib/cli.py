"""Command-line interface: ``mrlib {demo,train,sample,evaluate,export,info}``.

Run ``mrlib COMMAND --help`` for the options of each command.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from mrlib.errors import MrlibError

EPILOG = """examples:
  mrlib info data_samples/walk_happy.npz
  mrlib train data_samples/*.npz --preset tutorial --out runs/samples
  mrlib sample runs/samples/model.pt --label walk_happy --seconds 10 --out outputs/happy
  mrlib sample runs/samples/model.pt --crossover walk_sad:1-4 walk_happy:5-8 --out outputs/mix
  mrlib evaluate runs/samples/model.pt --samples 50 --out outputs/eval
  mrlib export clip.bvh clip.npz
"""


def _add_info(sub):
    p = sub.add_parser("info", help="print a summary of a motion file",
                       description="Load a motion file (.bvh, .npz, EasyMocap folder) and summarise it.")
    p.add_argument("path", type=Path)
    p.add_argument("--fps", type=float, default=None, help="resample to this frame rate first")
    p.set_defaults(func=_cmd_info)


def _cmd_info(args) -> int:
    from mrlib.io import load_motion

    m = load_motion(args.path, fps=args.fps)
    print(m)
    print(f"  duration     {m.duration:.2f} s")
    print(f"  label        {m.label}")
    print(f"  betas        {m.betas.round(3).tolist()}")
    span = m.trans.max(0) - m.trans.min(0)
    print(f"  root travel  x {span[0]:.2f} m, y {span[1]:.2f} m, z {span[2]:.2f} m")
    for k, v in m.meta.items():
        print(f"  meta.{k:<10} {v}")
    return 0


def _add_export(sub):
    p = sub.add_parser("export", help="convert a motion file (BVH <-> SMPL .npz)",
                       description="Convert between formats: any readable motion file to AMASS-style .npz "
                       "or to BVH on the SMPL skeleton (opens in Blender).")
    p.add_argument("src", type=Path, help="input: .bvh, .npz or an EasyMocap folder")
    p.add_argument("dst", type=Path, help="output: .npz or .bvh")
    p.add_argument("--fps", type=float, default=None, help="resample to this frame rate")
    p.set_defaults(func=_cmd_export)


def _cmd_export(args) -> int:
    from mrlib.io import load_motion, save_motion

    m = load_motion(args.src, fps=args.fps)
    save_motion(m, args.dst)
    print(f"wrote {args.dst} ({m.num_frames} frames @ {m.fps:g} fps)")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="mrlib",
        description="Multi-resolution generative modelling of SMPL human motion from limited data.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    _add_info(sub)
    _add_export(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except MrlibError as e:
        print(f"error: {type(e).__name__}: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
