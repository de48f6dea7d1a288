"""``mrlib restyle``: restyle a clip with a trained label model (its coarse motion kept and
a label's detail added, or the reverse)."""

from __future__ import annotations

import argparse
from pathlib import Path

from mrlib.app.cli.common import (
    joint_map_option,
    parse_seed,
    parse_steps,
    sample_output_options,
    warn_unfinished,
    with_sampler,
    write_samples,
)
from mrlib.errors import MrlibError
from mrlib.sampling.generation import MAX_SAMPLE_SECONDS


def add_restyle(sub) -> argparse.ArgumentParser:
    from mrlib.sampling.constraints.optimise import MAX_FIT_STEPS
    from mrlib.sampling.restyling import INVERT_STEPS, KEEP

    p = sub.add_parser(
        "restyle",
        help="restyle a clip: its coarse motion kept, a label's detail added (or the reverse)",
        description="Restyle a motion file of your own with a trained label model: the clip is "
        "resampled to the model's frame rate and taken down its pyramid to level K; levels "
        "K+1..L then add the detail of --label (--keep coarse), or levels 1..K come from --label "
        "and the clip's own detail goes on top (--keep detail). The root travels and faces as "
        "the clip does. Writes one .npz and one .bvh (and a .glb with --glb) like 'sample'.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n  mrlib restyle ckpt.pt clip.bvh --label walk_sad --out outputs/restyled\n"
        "  mrlib restyle ckpt.pt clip.bvh --label walk_happy --level 2 --glb\n"
        "  mrlib restyle ckpt.pt clip.bvh --label walk_angry --keep detail\n"
        "  mrlib restyle ckpt.pt far.bvh --label walk_sad --invert",
    )
    p.add_argument("checkpoint", type=Path)
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
        "--invert",
        type=parse_steps,
        nargs="?",
        const=INVERT_STEPS,
        default=0,
        metavar="N",
        help=f"fit the coarse levels' noise to the clip for N Adam steps (default when given "
        f"without N: {INVERT_STEPS}; at most {MAX_FIT_STEPS}) and restyle the model's own "
        "version of it; seconds instead of milliseconds, and on the Bandai clips measured it "
        "kept less of the clip (docs/notes/2026-12-04-restyle.md)",
    )
    p.add_argument(
        "--no-align",
        action="store_true",
        help="do not turn the clip to the training clips' facing while restyling",
    )
    joint_map_option(p)
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
    )
    return p


def cmd_restyle(args) -> int:
    from mrlib.io import load_motion
    from mrlib.model.trained import load_model
    from mrlib.sampling.constraints.optimise import check_fit_steps
    from mrlib.sampling.restyling import restyle, restyle_level

    if args.invert:  # bounded before anything is read
        check_fit_steps(args.invert, "--invert", minimum=1)
    model = with_sampler(load_model(args.checkpoint, device=args.device), args)
    if model.generator.cond_dim != len(model.labels):
        raise MrlibError(
            f"{args.checkpoint} is a speech-conditioned model; restyle takes a label model"
        )
    warn_unfinished(model, args.checkpoint)
    level = restyle_level(model, args.level)
    if args.invert and args.keep != "coarse":
        raise MrlibError("--invert fits the coarse levels to the clip: it needs --keep coarse")
    clip = load_motion(args.clip, joint_map=args.joint_map, up_axis=args.up_axis)
    if clip.duration > MAX_SAMPLE_SECONDS:
        raise MrlibError(
            f"{args.clip}: {clip.duration:.0f} s is longer than the {MAX_SAMPLE_SECONDS:.0f} s "
            "mrlib restyles in one pass; cut it into pieces"
        )
    m = restyle(model, clip, args.label, level, keep=args.keep, seed=args.seed,
                invert=bool(args.invert), invert_steps=args.invert or 1,
                align=not args.no_align, fix_contacts=not args.raw,
                progress=not args.no_progress)  # fmt: skip
    label = model.labels[model.label_index(args.label)]
    tag = f"{args.clip.stem}_to_{label}_{args.keep}{level}" + ("_inverted" * bool(args.invert))
    return write_samples([m], tag, args)
