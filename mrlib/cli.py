"""Command-line interface: ``mrlib {demo,train,train-speech,sample,evaluate,export,info}``.

Run ``mrlib COMMAND --help`` for the options of each command. Each command is a pair of
functions, ``_add_<command>`` (its options, with help texts) and ``_cmd_<command>`` (a
few lines calling the library); the option lists make the module long, the logic lives
in ``mrlib``.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from mrlib.errors import MrlibError

EPILOG = """examples:
  mrlib info data_samples/walk_happy.npz
  mrlib train data_samples/*.npz --preset tutorial --out runs/samples
  mrlib sample runs/samples/checkpoint.pt --label walk_happy --seconds 10 --out outputs/happy
  mrlib sample runs/samples/checkpoint.pt --crossover walk_sad:1-4 walk_happy:5-8 --out outputs/mix
  mrlib export clip.bvh clip.npz
  mrlib export outputs/happy/walk_happy_seed0_0.npz happy.glb
"""


def _joint_map_option(p) -> None:
    p.add_argument(
        "--joint-map",
        default=None,
        metavar="MAP",
        help="BVH only: a shipped map name or a JSON file {smpl_joint: bvh_joint} (default: "
        "the shipped map that fits, else one recognised from the skeleton)",
    )


def _add_info(sub):
    p = sub.add_parser(
        "info",
        help="print a summary of a motion file",
        description="Load a motion file (.bvh, .npz, EasyMocap folder) and summarise it. For "
        "a BVH, also the joint map used (shipped, given or recognised, with its confidence) "
        "and the retargeting error of each SMPL joint.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n  mrlib info clip.bvh\n  mrlib info clip.bvh --write-map map.json\n"
        "  mrlib info clip.bvh --joint-map map.json   # after editing it",
    )
    p.add_argument("path", type=Path)
    p.add_argument("--fps", type=float, default=None, help="resample to this frame rate first")
    _joint_map_option(p)
    p.add_argument(
        "--write-map",
        type=Path,
        default=None,
        metavar="JSON",
        help="BVH only: write the joint map used to this file, to edit and pass back with "
        "--joint-map",
    )
    p.set_defaults(func=_cmd_info)


def _cmd_info(args) -> int:
    from mrlib.io import JointMap, load_motion

    m = load_motion(args.path, fps=args.fps, joint_map=args.joint_map)
    print(m)
    print(f"  duration     {m.duration:.2f} s")
    print(f"  label        {m.label}")
    print(f"  betas        {[round(float(b), 3) for b in m.betas]}")
    span = m.trans.max(0) - m.trans.min(0)
    print(f"  root travel  x {span[0]:.2f} m, y {span[1]:.2f} m, z {span[2]:.2f} m")
    table = ("joint_map_pairs", "retarget_joint_error_cm", "joint_map_report")
    for k, v in m.meta.items():
        if k not in table:
            print(f"  meta.{k:<10} {f'{v:.4g}' if isinstance(v, float) else v}")
    if "joint_map_pairs" not in m.meta:
        if args.write_map is not None:
            raise MrlibError(f"{args.path}: --write-map is for BVH files (this one has no map)")
        return 0
    pairs, errors = m.meta["joint_map_pairs"], m.meta.get("retarget_joint_error_cm", {})
    if "joint_map_report" in m.meta:
        print("  " + m.meta["joint_map_report"].replace("\n", "\n  "))
    print(f"  {'SMPL joint':<15} {'source joint':<28} error cm")
    from mrlib.skeleton import JOINT_NAMES

    for name in JOINT_NAMES:
        src = pairs.get(name)
        err = f"{errors[name]:8.2f}" if name in errors else "       -"
        print(f"  {name:<15} {src or '- (follows its parent)':<28} {err}")
    if args.write_map is not None:
        desc = f"written by `mrlib info` for {Path(args.path).name} ({m.meta['joint_map']} map)"
        JointMap("custom", pairs, desc).to_json(args.write_map)
        print(f"wrote {args.write_map}: edit it and pass it back with --joint-map")
    return 0


def _add_export(sub):
    p = sub.add_parser(
        "export",
        help="convert a motion file (BVH, SMPL .npz, glTF .glb)",
        description="Convert between formats: any readable motion file to AMASS-style .npz, "
        "to BVH on the SMPL skeleton, or to a .glb with the skinned body mesh and the "
        "animation (browser viewers, Blender, game engines).",
    )
    p.add_argument("src", type=Path, help="input: .bvh, .npz or an EasyMocap folder")
    p.add_argument("dst", type=Path, help="output: .npz, .bvh or .glb")
    p.add_argument("--fps", type=float, default=None, help="resample to this frame rate")
    _joint_map_option(p)
    p.set_defaults(func=_cmd_export)


def _cmd_export(args) -> int:
    from mrlib.io import load_motion, save_motion

    m = load_motion(args.src, fps=args.fps, joint_map=args.joint_map)
    save_motion(m, args.dst)
    print(f"wrote {args.dst} ({m.num_frames} frames @ {m.fps:g} fps)")
    return 0


def _seconds(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not (math.isfinite(v) and 0 < v <= 24 * 3600):
        raise argparse.ArgumentTypeError(f"must be a number of seconds in (0, 86400], got {text!r}")
    return v


def _device(text: str) -> str:
    from mrlib.config import ConfigError, check_device

    try:
        return check_device(text)
    except ConfigError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


# -- train ---------------------------------------------------------------------------------
def _parse_iterations(text: str | None) -> tuple[int, ...] | None:
    if text is None:
        return None
    try:
        its = tuple(int(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"--iterations wants integers, got {text!r}") from None
    if any(i <= 0 for i in its):
        raise argparse.ArgumentTypeError("--iterations must be positive")
    return its


def _parse_steps(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"wants an integer >= 0, got {text!r}") from None
    if n < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {n}")
    return n


def _positive_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"must be a number > 0, got {text!r}")
    return v


def _refuse_on_resume(args, options: dict[str, str]) -> None:
    """A resumed run continues exactly as it was configured (its checkpoint holds the
    config and the data), so an option that would change it is an error, not silently
    dropped. ``options``: attribute name -> option as written."""
    given = [flag for name, flag in options.items() if getattr(args, name) not in (None, False, [])]
    if given:
        raise MrlibError(
            f"--resume continues the run as it was configured; {', '.join(given)} cannot "
            "change it (start a new run in another --out folder instead)"
        )


def _add_train(sub):
    p = sub.add_parser(
        "train",
        help="train a model on a few labelled clips",
        description="Train the multi-resolution GAN on one or more clips. Each clip is one condition "
        "(its label comes from the file: the npz 'label' key, the Bandai JSON next to a BVH, or else "
        "the file name). Writes checkpoint.pt, checkpoint.pt.json (the config) and losses.csv to --out.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n  mrlib train data_samples/*.npz --out runs/samples\n"
        "  mrlib train a.bvh b.bvh --labels calm angry --preset paper --device cuda --out runs/ab\n"
        "  mrlib train --resume runs/ab/checkpoint.pt --out runs/ab",
    )
    p.add_argument(
        "clips", nargs="*", type=Path, help="motion files (.bvh, .npz, EasyMocap folders)"
    )
    p.add_argument(
        "--labels", nargs="+", default=None, help="one label per clip (default: from the files)"
    )
    p.add_argument(
        "--preset",
        default=None,
        choices=["tutorial", "paper"],
        help="training schedule: 'tutorial' (CPU minutes) or 'paper' (the paper's 15k/25k "
        "iterations per block; use a GPU) [default: tutorial]",
    )
    p.add_argument(
        "--iterations",
        type=_parse_iterations,
        default=None,
        metavar="N[,N...]",
        help="iterations per block, overriding the preset (one value for all blocks, or one per block)",
    )
    p.add_argument(
        "--levels", type=int, default=None, help="number of pyramid levels (overrides the preset)"
    )
    p.add_argument(
        "--lr",
        type=_positive_float,
        default=None,
        metavar="RATE",
        help="Adam learning rate, overriding the preset's (tutorial: 5e-4; 2e-3 sharpens each "
        "label, docs/results.md 'Body parts')",
    )
    p.add_argument("--fps", type=float, default=None, help="resample every clip to this frame rate")
    _joint_map_option(p)
    p.add_argument(
        "--checkpoint-every",
        type=int,
        default=None,
        metavar="N",
        help="write the checkpoint every N iterations (default: the preset's; 0: at the end "
        "of each block only)",
    )
    p.add_argument("--seed", type=int, default=None, help="random seed (default: the preset's)")
    p.add_argument(
        "--device",
        type=_device,
        default=None,
        help="cpu or cuda [default: cpu; with --resume, the checkpoint's]",
    )
    p.add_argument(
        "--out", type=Path, default=Path("runs/model"), help="output folder [default: runs/model]"
    )
    p.add_argument("--resume", type=Path, default=None, help="continue from this checkpoint")
    p.add_argument(
        "--per-clip",
        action="store_true",
        help="GANimator-mode baseline: train one model per clip (in OUT/<clip name>/), "
        "so no model sees another condition and no crossover is learned",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.set_defaults(func=_cmd_train)


def _single_clip(data, k: int):
    """Clip ``k`` of a TrainingSet as a set of its own (normaliser refitted)."""
    from mrlib.data import TrainingSet
    from mrlib.features import FeatureNormalizer

    x = data.features[k]
    label = data.labels[data.clip_labels[k]]
    return TrainingSet(
        [x], [0], [label], data.fps, [data.names[k]], FeatureNormalizer.fit([x]), data.betas
    )


def _cmd_train(args) -> int:
    from mrlib.config import ganimator_mode, training_config
    from mrlib.data import TrainingSet
    from mrlib.train import train

    if args.resume is None and not args.clips:
        raise MrlibError("give clips to train on, or --resume a checkpoint")
    if args.resume is not None:
        _refuse_on_resume(
            args,
            {
                "clips": "clips",
                "labels": "--labels",
                "preset": "--preset",
                "iterations": "--iterations",
                "levels": "--levels",
                "lr": "--lr",
                "fps": "--fps",
                "joint_map": "--joint-map",
                "checkpoint_every": "--checkpoint-every",
                "seed": "--seed",
                "per_clip": "--per-clip",
            },
        )
        res = train(
            None,
            None,
            args.out,
            resume=args.resume,
            device=args.device,
            progress=not args.no_progress,
        )
        return _report_training(res)
    data = TrainingSet.from_files(
        args.clips, labels=args.labels, fps=args.fps, joint_map=args.joint_map
    )
    print(
        f"training on {data.num_clips} clips, labels {data.labels}, {data.fps:g} fps, "
        f"lengths {data.lengths}"
    )
    cfg = training_config(
        args.preset or "tutorial",
        args.iterations,
        args.levels,
        args.seed,
        args.device or "cpu",
        lr=args.lr,
    )
    if args.checkpoint_every is not None:
        if args.checkpoint_every < 0:
            raise MrlibError(f"--checkpoint-every must be >= 0, got {args.checkpoint_every}")
        cfg = cfg.replace(checkpoint_every=args.checkpoint_every)
    if args.per_clip:
        from mrlib.io.paths import inside, unique_components

        # one folder per clip, named after the clip but never a path of its own: the name
        # comes from the file, so it is sanitised, and repeated names get distinct folders
        folders = unique_components(data.names, fallback="clip")
        for k in range(data.num_clips):
            one = _single_clip(data, k)
            out = inside(args.out, args.out / folders[k])
            print(f"[{k + 1}/{data.num_clips}] {data.names[k]} -> {out}")
            res = train(one, ganimator_mode(cfg), out, progress=not args.no_progress)
            if res.interrupted:
                return 130
        return 0
    res = train(data, cfg, args.out, progress=not args.no_progress)
    return _report_training(res)


def _report_training(res) -> int:
    state = "interrupted; resume with --resume" if res.interrupted else "done"
    print(f"{state} in {res.wall_time_s:.0f} s -> {res.checkpoint}")
    return 130 if res.interrupted else 0


# -- train-speech --------------------------------------------------------------------------
def _add_train_speech(sub):
    p = sub.add_parser(
        "train-speech",
        help="train a speech-conditioned (co-speech gesture) model",
        description="Train the multi-resolution GAN with speech as the control signal (paper "
        "Sec. 6): the reconstruction loss on paired clips (PAIRED holds <stem>.wav next to "
        "<stem>.npz or <stem>.bvh), random generations on unpaired audio (--unpaired, a folder "
        "of .wav/.flac). Speech FiLM modulates the upper body only. Writes checkpoint.pt, "
        "checkpoint.pt.json and losses.csv to --out; generate with 'mrlib sample --audio'.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n  mrlib train-speech talks/paired --unpaired talks/audio --out runs/speech\n"
        "  mrlib train-speech talks/paired --unpaired talks/audio --features wavlm --wavlm ~/wavlm-base-plus\n"
        "  mrlib train-speech --resume runs/speech/checkpoint.pt --out runs/speech",
    )
    p.add_argument("paired", nargs="?", type=Path, help="folder of paired .wav + motion files")
    p.add_argument("--unpaired", type=Path, default=None, help="folder of unpaired audio files")
    p.add_argument(
        "--features",
        choices=["logmel", "wavlm"],
        default=None,
        help="speech features: 'wavlm' (the paper's; needs local weights) or 'logmel' "
        "(no weights) [default: logmel]",
    )
    p.add_argument(
        "--wavlm", type=Path, default=None, help="folder of WavLM weights (else $MRLIB_WAVLM_PATH)"
    )
    p.add_argument(
        "--preset",
        default=None,
        choices=["tutorial", "paper"],
        help="'tutorial' (CPU, 20-30 min for a dozen 10 s clips) or 'paper' (the paper's "
        "schedule; use a GPU) [default: tutorial]",
    )
    p.add_argument(
        "--iterations",
        type=_parse_iterations,
        default=None,
        metavar="N[,N...]",
        help="iterations per block, overriding the preset (one value, or one per block)",
    )
    p.add_argument(
        "--random-audio",
        choices=["paired", "unpaired", "all"],
        default=None,
        help="audio of the random generations [default: 'paired' for the tutorial preset, "
        "whose critics hear the speech; 'unpaired' for the paper's, as in the paper]",
    )
    p.add_argument("--fps", type=float, default=None, help="motion frame rate [default: 25]")
    p.add_argument("--seed", type=int, default=None, help="random seed (default: the preset's)")
    p.add_argument(
        "--device",
        type=_device,
        default=None,
        help="cpu or cuda [default: cpu; with --resume, the checkpoint's]",
    )
    p.add_argument("--out", type=Path, default=Path("runs/speech"), help="output folder")
    p.add_argument("--resume", type=Path, default=None, help="continue from this checkpoint")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.set_defaults(func=_cmd_train_speech)


def _cmd_train_speech(args) -> int:
    from mrlib.config import block_iterations_for, speech_paper, speech_tutorial
    from mrlib.speech import SpeechFeatureExtractor, SpeechTrainingSet, speech_train

    if args.resume is not None:
        _refuse_on_resume(
            args,
            {
                "paired": "PAIRED",
                "unpaired": "--unpaired",
                "features": "--features",
                "wavlm": "--wavlm",
                "preset": "--preset",
                "iterations": "--iterations",
                "random_audio": "--random-audio",
                "fps": "--fps",
                "seed": "--seed",
            },
        )
    data = cfg = None
    if args.resume is None:
        if args.paired is None:
            raise MrlibError("give a folder of paired clips, or --resume a checkpoint")
        cfg = speech_paper() if args.preset == "paper" else speech_tutorial()
        if args.iterations is not None:
            cfg = cfg.replace(
                block_iterations=block_iterations_for(args.iterations, cfg.num_blocks)
            )
        if args.seed is not None:
            cfg = cfg.replace(seed=args.seed)
        cfg = cfg.replace(device=args.device or "cpu")
        wavlm = None if args.wavlm is None else str(args.wavlm)
        extractor = SpeechFeatureExtractor(kind=args.features or "logmel", wavlm_path=wavlm)
        fps = 25.0 if args.fps is None else args.fps
        data = SpeechTrainingSet.from_folders(args.paired, args.unpaired, extractor, fps=fps)
        print(data)
    res = speech_train(
        data,
        cfg,
        args.out,
        resume=args.resume,
        random_audio=args.random_audio,
        device=args.device if args.resume is not None else None,
        progress=not args.no_progress,
    )
    return _report_training(res)


# -- sample --------------------------------------------------------------------------------
def _parse_range(spec: str) -> tuple[str, tuple[int, int]]:
    try:
        label, levels = spec.rsplit(":", 1)
        a, b = (int(v) for v in levels.split("-"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected LABEL:FIRST-LAST, got {spec!r}") from None
    return label, (a, b)


def _add_sample(sub):
    p = sub.add_parser(
        "sample",
        help="generate motion from a trained model",
        description="Generate new motion. Choose the condition with --label, assign conditions to "
        "level ranges with --crossover (coarse levels first), or blend two labels with --blend. "
        "Writes one .npz (SMPL parameters) and one .bvh per sample, and a mesh render with --render.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n  mrlib sample runs/samples/checkpoint.pt --label walk_happy --seconds 10\n"
        "  mrlib sample ckpt.pt --crossover walk_sad:1-4 walk_happy:5-8 --num 4 --render\n"
        "  mrlib sample ckpt.pt --blend walk_sad walk_happy 0.5\n"
        "  mrlib sample runs/speech/checkpoint.pt --audio talk.wav --render\n"
        "  mrlib sample ckpt.pt --label walk_happy --path circle:2 --seconds 20\n"
        "  mrlib sample ckpt.pt --parts upper=walk_happy,lower=walk_sad --sharpen\n"
        "  mrlib sample ckpt.pt --label walk_sad --loop --seconds 4\n"
        "  mrlib sample ckpt.pt --label walk_sad --keyframes kf.npz --seconds 6\n"
        "  mrlib sample ckpt.pt --label walk_sad --continue clip.bvh --seconds 5",
    )
    p.add_argument("checkpoint", type=Path)
    g = p.add_mutually_exclusive_group()
    g.add_argument(
        "--label", default=None, help="condition for every level (default: the first label)"
    )
    g.add_argument(
        "--crossover",
        nargs="+",
        type=_parse_range,
        metavar="LABEL:A-B",
        help="conditions per level range, e.g. walk_sad:1-4 walk_happy:5-8",
    )
    g.add_argument(
        "--blend",
        nargs=3,
        metavar=("LABEL_A", "LABEL_B", "W"),
        help="interpolate the two label embeddings with weight W of B (0..1) at every level",
    )
    g.add_argument(
        "--audio",
        type=Path,
        default=None,
        help="speech-conditioned models: gestures for this audio file (.wav/.flac), as long as it",
    )
    g.add_argument(
        "--parts",
        type=_parse_parts,
        default=None,
        metavar="PART=LABEL,...",
        help="a label per body part (upper, lower, left_arm, right_arm), e.g. "
        "upper=walk_happy,lower=walk_sad",
    )
    p.add_argument(
        "--in-step",
        action="store_true",
        help="with --parts: retime each part to the gait of the part holding the pelvis, so "
        "the arms swing in step with the legs (mrlib.constraints.phase_align)",
    )
    p.add_argument(
        "--sharpen",
        type=_parse_steps,
        nargs="?",
        const=None,
        default=0,
        metavar="N",
        help="with --parts: fit the noise for N Adam steps (default when given without N: "
        "mrlib.constraints.SHARPEN_STEPS) so that each part's windows are nearer its own "
        "label's training clips than any other label's; seconds per sample instead of "
        "milliseconds (docs/results.md 'Body parts')",
    )
    c = p.add_mutually_exclusive_group()
    c.add_argument(
        "--path",
        default=None,
        metavar="SPEC",
        help="walk a ground path: circle:R, circle-right:R, eight:R, line:L (metres) or a CSV "
        "of x,z[,t]; --seconds defaults to the path's times or its length at the label's pace",
    )
    c.add_argument(
        "--keyframes",
        type=Path,
        default=None,
        metavar="NPZ",
        help="hold these keyframes (mrlib.constraints.save_keyframes); needs --seconds",
    )
    c.add_argument("--loop", action="store_true", help="a seamless loop (the end joins the start)")
    c.add_argument(
        "--continue",
        dest="prefix",
        type=Path,
        default=None,
        metavar="MOTION",
        help="continue this motion file for --seconds more",
    )
    p.add_argument(
        "--seconds",
        type=_seconds,
        default=None,
        help="length in seconds (default: a training clip's)",
    )
    p.add_argument(
        "--fit-steps",
        type=_parse_steps,
        default=None,
        metavar="N",
        help="Adam steps of the noise fit for --keyframes and --continue (0: none; "
        "default: the library's, 300 for keyframes and 100 for continuation)",
    )
    p.add_argument("--num", type=int, default=1, help="number of samples [default: 1]")
    p.add_argument("--seed", type=int, default=0, help="random seed [default: 0]")
    p.add_argument(
        "--raw",
        action="store_true",
        help="skip the foot-contact clean-up (analytic leg IK that plants the feet while "
        "they are labelled in contact; on by default)",
    )
    p.add_argument("--fix-contacts", action="store_true", help=argparse.SUPPRESS)  # the default now
    _add_sampler_options(p)
    p.add_argument(
        "--render", action="store_true", help="also write a mesh render (PNG) per sample"
    )
    p.add_argument(
        "--glb",
        action="store_true",
        help="also write a .glb per sample: the skinned body mesh with the animation",
    )
    p.add_argument("--device", type=_device, default="cpu", help="cpu or cuda [default: cpu]")
    p.add_argument("--out", type=Path, default=Path("outputs/samples"))
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.set_defaults(func=_cmd_sample)


def _parse_parts(text: str) -> dict[str, str]:
    from mrlib.constraints import parse_parts

    try:
        return parse_parts(text)
    except MrlibError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def _constrained(model, kw: dict, length: int | None, args) -> list:
    """Samples under --path / --keyframes / --loop / --continue (one per seed)."""
    from mrlib import constraints as C

    fit = {} if args.fit_steps is None else {"steps": args.fit_steps}
    fit["progress"] = not args.no_progress
    out = []
    for b in range(args.num):
        seed = args.seed + b
        if args.path is not None:
            m = C.generate_on_path(model, args.path, seconds=args.seconds, seed=seed,
                                   clean=not args.raw, **kw)  # fmt: skip
        elif args.keyframes is not None:
            if length is None:
                raise MrlibError("--keyframes needs --seconds (the length of the motion)")
            kfs = C.load_keyframes(args.keyframes)
            m = C.generate_with_keyframes(
                model, kfs, length, seed=seed, clean=not args.raw, **fit, **kw
            )
        elif args.loop:
            m = C.generate_loop(model, length=length, seed=seed, fix_contacts=not args.raw, **kw)
        else:
            from mrlib.io import load_motion

            if args.seconds is None:
                raise MrlibError("--continue needs --seconds (how much to add)")
            prefix = load_motion(args.prefix)
            frames = max(1, round(args.seconds * model.fps))
            m = C.continue_motion(model, prefix, frames, seed=seed, clean=not args.raw, **fit, **kw)
        out.append(m)
    return out


def _add_sampler_options(p) -> None:
    p.add_argument(
        "--fine-noise",
        type=_non_negative,
        default=None,
        metavar="S",
        help="the finest level's noise as a share of its training sigma [default: 1, the "
        "paper's sampler]; lower: less frame-to-frame jitter and less of the fine label's "
        "detail in crossovers (0: as smooth as the training clips)",
    )
    p.add_argument(
        "--guidance",
        type=_non_negative,
        default=None,
        metavar="G",
        help="label models: exaggerate the label, each level's condition pushed G times "
        "its distance away from the mean of all labels [default: 0, the paper's sampler]; "
        "0.25 sharpens the label at about the same coverage, 1 and more leave the training "
        "poses",
    )


def _non_negative(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"must be a number >= 0, got {text!r}")
    return value


def _with_sampler(model, args, guidance: bool = True):
    """``model`` with ``--fine-noise`` and (unless ``guidance=False``) ``--guidance``
    applied where given (``GenerativeModel.fine_noise``, ``.guidance``; a speech model
    takes the first only)."""
    if args.fine_noise is not None:
        model.fine_noise = args.fine_noise
    if guidance and getattr(args, "guidance", None) is not None:
        if model.generator.cond_dim != len(model.labels):
            raise MrlibError("--guidance applies to label models only")
        model.guidance = args.guidance
    return model


def _cmd_sample(args) -> int:
    from mrlib.sample import generate, load_model

    constrained = args.path or args.keyframes or args.loop or args.prefix
    if args.in_step and not args.parts:
        raise MrlibError("--in-step applies to --parts only")
    if args.sharpen != 0 and not args.parts:
        raise MrlibError("--sharpen applies to --parts only")
    if args.fit_steps is not None and args.keyframes is None and args.prefix is None:
        raise MrlibError("--fit-steps applies to --keyframes and --continue only")
    if args.audio is not None:
        if constrained and not args.path:
            raise MrlibError("with --audio only --path applies (keyframes, loops and "
                             "continuation need a label model)")  # fmt: skip
        motions, tag = _audio_samples(args)
        if args.path:
            from mrlib.constraints import follow_path

            motions = [follow_path(m, args.path, clean=not args.raw) for m in motions]
        return _write_samples(motions, tag, args)
    model = _with_sampler(load_model(args.checkpoint, device=args.device), args)
    if model.generator.cond_dim != len(model.labels):
        raise MrlibError(f"{args.checkpoint} is a speech-conditioned model: pass --audio FILE")
    length = None if args.seconds is None else max(2, round(args.seconds * model.fps))
    if args.parts:
        if constrained:
            raise MrlibError("--parts cannot be combined with --path/--keyframes/--loop/--continue")
        from mrlib.constraints import SHARPEN_STEPS, generate_parts

        sharpen = SHARPEN_STEPS if args.sharpen is None else args.sharpen
        motions = generate_parts(model, args.parts, length, seed=args.seed, num_samples=args.num,
                                 fix_contacts=not args.raw, align_gait=args.in_step,
                                 sharpen=sharpen, progress=not args.no_progress)  # fmt: skip
        return _write_samples(motions, ",".join(f"{k}={v}" for k, v in args.parts.items()), args)
    kw = {}
    if args.crossover:
        kw["conditions"] = args.crossover
        tag = "+".join(f"{lab}{a}-{b}" for lab, (a, b) in args.crossover)
    elif args.blend:
        a, b, w = args.blend
        try:
            w = float(w)
        except ValueError:
            raise MrlibError(f"--blend weight must be a number in [0, 1], got {w!r}") from None
        if not 0 <= w <= 1:
            raise MrlibError(f"--blend weight must be in [0, 1], got {w:g}")
        kw["blend"] = (a, b, w)
        tag = f"{a}-{b}-{float(w):g}"
    else:
        kw["condition"] = args.label if args.label is not None else model.labels[0]
        tag = str(kw["condition"])
    if constrained:
        what = (
            "path"
            if args.path
            else "keyframes"
            if args.keyframes
            else "loop"
            if args.loop
            else "continued"
        )
        return _write_samples(_constrained(model, kw, length, args), f"{tag}_{what}", args)
    motions = generate(
        model,
        length=length,
        seed=args.seed,
        num_samples=args.num,
        fix_contacts=not args.raw,
        **kw,
    )
    return _write_samples(motions, tag, args)


def _audio_samples(args):
    from mrlib.speech import generate_from_audio, load_speech_model

    if args.seconds is not None:
        raise MrlibError(
            "--seconds does not apply to --audio: the motion lasts as long as the audio"
        )
    model = load_speech_model(args.checkpoint, device=args.device)
    _with_sampler(model.model, args)
    motions = generate_from_audio(
        model, args.audio, seed=args.seed, num_samples=args.num, fix_contacts=not args.raw
    )
    return motions, args.audio.stem


def _write_samples(motions, tag: str, args) -> int:
    from mrlib.io import save_motion
    from mrlib.io.paths import inside, safe_component

    motions = motions if isinstance(motions, list) else [motions]
    args.out.mkdir(parents=True, exist_ok=True)
    tag = safe_component(tag, fallback="sample")  # labels come from files
    for i, m in enumerate(motions):
        stem = inside(args.out, args.out / f"{tag}_seed{args.seed}_{i}")
        save_motion(m, stem.with_suffix(".npz"))
        save_motion(m, stem.with_suffix(".bvh"))
        kinds = ".npz/.bvh"
        if getattr(args, "glb", False):
            save_motion(m, stem.with_suffix(".glb"))
            kinds += "/.glb"
        if args.render:
            import imageio.v3 as iio

            from mrlib.render import evenly_spaced_frames, render_meshes

            iio.imwrite(
                stem.with_suffix(".png"), render_meshes(m, frames=evenly_spaced_frames(len(m), 6))
            )
        print(f"wrote {stem}{kinds}: {m}")
    return 0


# -- evaluate ------------------------------------------------------------------------------
def _add_evaluate(sub):
    p = sub.add_parser(
        "evaluate",
        help="score a trained model like the paper's Table 1",
        description="Draw samples of 2x the training length with fixed seeds and score them against "
        "each training clip: coverage, global (PNN) and local diversity, reconstruction error, "
        "condition fidelity, foot skating, jitter, penetration and speed distributions, next to "
        "calibration rows (the clip played twice, a frozen frame, other real takes when the clips "
        "are Bandai Namco ones). Writes CSV, Markdown and a plot to --out and prints the table.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n  mrlib evaluate runs/samples/checkpoint.pt --samples 20\n"
        "  mrlib evaluate runs/walks/checkpoint.pt --baseline runs/ganimator_mode --out outputs/table1",
    )
    p.add_argument("checkpoint", type=Path)
    p.add_argument("--samples", type=int, default=200, help="samples per sequence [default: 200]")
    p.add_argument("--eps", type=float, default=2.0, help="coverage threshold [default: 2.0]")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--baseline",
        type=Path,
        default=None,
        help="a folder of single-clip checkpoints (*/checkpoint.pt) to compare against, "
        "e.g. from `mrlib train --per-clip`",
    )
    p.add_argument("--baseline-name", default="GANimator-mode")
    p.add_argument("--no-calibration", action="store_true", help="leave out the calibration rows")
    _add_sampler_options(p)
    p.add_argument(
        "--raw",
        action="store_true",
        help="score only the raw samples (default: the foot-contact cleaned ones, and the "
        "raw ones beside them as 'ours (raw)')",
    )
    p.add_argument("--device", type=_device, default="cpu", help="cpu or cuda [default: cpu]")
    p.add_argument("--out", type=Path, default=Path("outputs/evaluation"))
    p.set_defaults(func=_cmd_evaluate)


def _cmd_evaluate(args) -> int:
    from mrlib.evaluate import evaluate_model, model_references
    from mrlib.sample import load_model

    model = _with_sampler(load_model(args.checkpoint, device=args.device), args)
    baselines = None
    if args.baseline is not None:
        per_key = {}
        refs = model_references(model)
        for path in sorted(args.baseline.glob("*/checkpoint.pt")):
            # the baselines sample as the model does, but a one-label model has no guidance
            m = _with_sampler(load_model(path, device=args.device), args, guidance=False)
            for key in refs:
                if key in m.clip_names or key in m.labels:
                    per_key[key] = m
        if not per_key:
            raise MrlibError(
                f"no baseline checkpoint in {args.baseline} matches this model's clips"
            )
        baselines = {args.baseline_name: per_key}
    result = evaluate_model(
        model,
        baselines,
        num_samples=args.samples,
        eps=args.eps,
        seed=args.seed,
        calibration=not args.no_calibration,
        contacts="raw" if args.raw else "both",
    )
    result.save(args.out)
    print(f"sampler: fine_noise={model.fine_noise:g}, guidance={model.guidance:g}\n")
    print(result.to_markdown())
    print(f"\nwrote {args.out}/")
    return 0


# -- demo ----------------------------------------------------------------------------------
def _add_demo(sub):
    p = sub.add_parser(
        "demo",
        help="end-to-end demo on the bundled data (train, sample, crossover, evaluate)",
        description="Load the synthetic clips in data_samples/, retarget a Bandai Namco BVH if "
        "MRLIB_DATA_DIR points at the dataset, train (the 'demo' preset: a few minutes on two CPU "
        "cores), sample every label and a coarse/fine crossover, evaluate, and write renders, "
        "animated previews, exports and summary.md to --out.",
    )
    p.add_argument("--out", type=Path, default=Path("outputs"))
    p.add_argument(
        "--preset",
        default="demo",
        choices=["demo", "tutorial", "paper"],
        help="training schedule: 'demo' (minutes, clips at 15 fps), 'tutorial' (the tutorial "
        "budget, ~20 min on 2 cores) or 'paper' [default: demo]",
    )
    p.add_argument(
        "--quick", action="store_true", help="smoke-test budget (seconds; results not meaningful)"
    )
    p.add_argument(
        "--iterations", type=int, default=None, help="iterations per block (overrides the preset)"
    )
    p.add_argument(
        "--samples", type=int, default=10, help="evaluation samples per label [default: 10]"
    )
    p.add_argument("--seed", type=int, default=0)
    p.set_defaults(func=_cmd_demo)


def _cmd_demo(args) -> int:
    from mrlib.demo import run_demo

    run_demo(
        args.out,
        preset=args.preset,
        quick=args.quick,
        iterations=args.iterations,
        samples=args.samples,
        seed=args.seed,
    )
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="mrlib",
        description="Multi-resolution generative modelling of SMPL human motion from limited data.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--debug", action="store_true", help="show the full traceback of an error")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    _add_demo(sub)
    _add_train(sub)
    _add_train_speech(sub)
    _add_sample(sub)
    _add_evaluate(sub)
    _add_export(sub)
    _add_info(sub)
    return parser


def _describe(e: BaseException) -> str:
    """One line for an error: the file, the problem, and for OS errors what failed."""
    if isinstance(e, OSError) and not isinstance(e, MrlibError):
        where = f"{e.filename}: " if getattr(e, "filename", None) else ""
        return f"{where}{e.strerror or e}"
    if isinstance(e, MemoryError):
        return "out of memory (try a shorter clip, fewer samples or a lower --fps)"
    return f"{type(e).__name__}: {e}"


def main(argv: list[str] | None = None) -> int:
    """Run one command. Errors print one line (``error: ...``) and exit 1 (usage errors
    exit 2); ``--debug`` shows the full traceback instead."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except (MrlibError, OSError, MemoryError) as e:
        if args.debug:
            raise
        print(f"error: {_describe(e)}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
