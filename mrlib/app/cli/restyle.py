"""``mrlib restyle``: restyle a clip with a trained label model (its coarse motion kept and
a label's detail added, or the reverse)."""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

from mrlib.app.cli.common import (
    add_command,
    joint_map_option,
    parse_fps,
    parse_seed,
    sample_output_options,
    sampler_from_args,
    warn_unfinished,
    write_samples,
)
from mrlib.errors import MrlibError
from mrlib.sampling.generation import MAX_SAMPLE_SECONDS


def add_restyle(sub) -> argparse.ArgumentParser:
    from mrlib.sampling.restyling import KEEP

    p = add_command(
        sub,
        "restyle",
        "restyle a clip: its coarse motion kept, a label's detail added (or the reverse)",
        "Restyle a motion file of your own with a trained label model: the clip is "
        "resampled to the model's frame rate and taken down its pyramid to level K; levels "
        "K+1..L then add the detail of --label (--keep coarse), or levels 1..K come from --label "
        "and the clip's own detail goes on top (--keep detail). The root travels and faces as "
        "the clip does, and the result comes back at the clip's frame rate and frame count "
        "(--fps: another rate). Writes one .npz and one .bvh (and a .glb with --glb) like "
        "'sample'.",
        [
            "mrlib restyle ckpt.pt clip.bvh --label walk_sad --out outputs/restyled",
            "mrlib restyle ckpt.pt clip.bvh --label walk_happy --level 2 --glb",
            "mrlib restyle ckpt.pt clip.bvh --label walk_angry --keep detail",
        ],
    )
    p.add_argument("checkpoint", type=Path, help="a trained model (a run's checkpoint.pt)")
    p.add_argument("clip", type=Path, help="the motion to restyle (.bvh, .npz, EasyMocap folder)")
    p.add_argument("--label", required=True, help="the label to restyle towards")
    p.add_argument(
        "--level",
        type=int,
        default=None,
        metavar="K",
        help="levels 1..K keep the clip (--keep coarse) or come from the label (--keep "
        "detail); 1..L-1, higher keeps more of the clip's coarse motion [default: L - 2]",
    )
    p.add_argument(
        "--keep",
        choices=KEEP,
        default="coarse",
        help="what of the clip survives: its coarse motion (the label adds the detail) or "
        "its detail (the label gives the coarse motion) [default: coarse]",
    )
    p.add_argument(
        "--no-align",
        action="store_true",
        help="do not turn the clip to the training clips' facing while restyling",
    )
    joint_map_option(p)
    p.add_argument(
        "--fps",
        type=parse_fps,
        default=None,
        help="frame rate of the result, resampled by cubic splines before the feet are "
        "planted [the clip's own]",
    )
    p.add_argument(
        "--seed", type=parse_seed, default=0, help="noise seed of the label's levels [0]"
    )
    p.add_argument(
        "--raw", action="store_true", help="skip the foot-contact clean-up (on by default)"
    )
    sample_output_options(
        p,
        out=Path("outputs/restyled"),
        render_help="also write a mesh render (PNG)",
        glb_help="also write a .glb (skinned body mesh)",
        overwrite_help="replace files already in --out (refused otherwise)",
        candidates=False,  # a restyle draws once
    )
    return p


def cmd_restyle(args) -> int:
    from mrlib.io import load_motion
    from mrlib.model.trained import load_model
    from mrlib.sampling.restyling import restyle, restyle_level

    sampler = sampler_from_args(args)
    if args.fps is not None:
        sampler = dataclasses.replace(sampler, fps=args.fps)  # its bounds checked there
    model = load_model(args.checkpoint, device=args.device)
    if model.generator.cond_dim != len(model.labels):
        raise MrlibError(
            f"{args.checkpoint} is a speech-conditioned model; restyle takes a label model"
        )
    warn_unfinished(model, args.checkpoint)
    level = restyle_level(model, args.level)
    clip = load_motion(args.clip, joint_map=args.joint_map, up_axis=args.up_axis, unit=args.unit)
    if clip.duration > MAX_SAMPLE_SECONDS:
        raise MrlibError(
            f"{args.clip}: {clip.duration:.0f} s is longer than the {MAX_SAMPLE_SECONDS:.0f} s "
            "mrlib restyles in one pass; cut it into pieces"
        )
    m = restyle(model, clip, args.label, level, keep=args.keep, seed=args.seed,
                align=not args.no_align, sampler=sampler)  # fmt: skip
    label = model.labels[model.label_index(args.label)]
    tag = f"{args.clip.stem}_to_{label}_{args.keep}{level}"
    return write_samples([m], tag, args)
