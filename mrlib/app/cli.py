"""Command-line interface: ``mrlib {demo,train,train-speech,sample,restyle,evaluate,export,info,data}``.

Run ``mrlib COMMAND --help`` for the options of each command. Each command is a pair of
functions, ``_add_<command>`` (its options, with help texts) and ``_cmd_<command>`` (a
few lines calling the library); the option lists make the module long, the logic lives
in ``mrlib``.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import sys
import warnings
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
    p.add_argument("--overwrite", action="store_true", help="replace DST if it exists")
    p.set_defaults(func=_cmd_export)


def _cmd_export(args) -> int:
    from mrlib.io import load_motion, save_motion
    from mrlib.io.outputs import check_writable

    check_writable(args.dst, overwrite=args.overwrite)  # before reading anything
    m = load_motion(args.src, fps=args.fps, joint_map=args.joint_map)
    save_motion(m, args.dst, overwrite=args.overwrite)
    print(f"wrote {args.dst} ({m.num_frames} frames @ {m.fps:g} fps)")
    return 0


MAX_SAMPLES = 1000  # --num: each sample is generated, cleaned up and written (2-4 files)
MAX_SEED = 2**32 - 1  # numpy's and torch's seeds are 32/64-bit unsigned


def _seed(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"wants an integer >= 0, got {text!r}") from None
    if not 0 <= v <= MAX_SEED:
        raise argparse.ArgumentTypeError(f"must be in [0, {MAX_SEED}], got {v}")
    return v


def _level_count(text: str) -> int:
    from mrlib.model.config import MAX_LEVELS

    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"wants an integer, got {text!r}") from None
    if not 1 <= v <= MAX_LEVELS:
        raise argparse.ArgumentTypeError(
            f"must be in [1, {MAX_LEVELS}], got {v} (the paper uses 8; a level needs about "
            "4/3 times the frames of the one below)"
        )
    return v


MAX_SAMPLE_SECONDS = (
    600.0  # one sample: a 10-minute walk stays within mrlib.representation.motion's 1000 m
)
MAX_SAMPLE_FRAMES = 200_000  # all samples of one command (~0.5 GB while generating)


def _check_sample_frames(frames: int, fps: float, args) -> None:
    """Refuse, before generating, samples longer than ``MAX_SAMPLE_SECONDS`` or more
    frames in all than ``MAX_SAMPLE_FRAMES``."""
    what = "--continue: the clip plus --seconds" if args.prefix is not None else "--seconds"
    if frames > MAX_SAMPLE_SECONDS * fps + 1:
        raise MrlibError(
            f"{what}: {frames / fps:.0f} s is longer than the {MAX_SAMPLE_SECONDS:.0f} s mrlib "
            "generates in one sample (a longer walk leaves the 1000 m a motion may span); "
            "generate shorter pieces and join them with --continue"
        )
    if frames * args.num > MAX_SAMPLE_FRAMES:
        raise MrlibError(
            f"--num: {args.num} samples of {frames} frames are {frames * args.num} frames, more "
            f"than the {MAX_SAMPLE_FRAMES} one command generates; use fewer --num or a "
            "shorter --seconds, and run again with another --seed"
        )


def _sample_count(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"wants an integer >= 1, got {text!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {v}")
    if v > MAX_SAMPLES:
        raise argparse.ArgumentTypeError(
            f"must be at most {MAX_SAMPLES}, got {v} (for more, run again with another --seed)"
        )
    return v


def _seconds(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not (math.isfinite(v) and 0 < v <= 24 * 3600):
        raise argparse.ArgumentTypeError(f"must be a number of seconds in (0, 86400], got {text!r}")
    return v


def _device(text: str) -> str:
    from mrlib.model.config import ConfigError, check_device

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


@contextlib.contextmanager
def _retarget_check(accept: bool):
    """Loads inside refuse BVH clips retargeted with an error above the threshold (their
    RetargetWarning), unless ``accept``; other warnings pass through."""
    from mrlib.io.retarget import RetargetWarning

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        yield
    bad = []
    for w in caught:
        if issubclass(w.category, RetargetWarning):
            bad.append(str(w.message))
        if not issubclass(w.category, RetargetWarning) or accept:
            warnings.showwarning(w.message, w.category, w.filename, w.lineno)
    if bad and not accept:
        raise MrlibError(
            f"{len(bad)} clip(s) retargeted with a joint error above the threshold (or joint "
            "angles no person holds); fix their joint map, or pass --accept-retarget-error "
            "to train on them anyway:\n  " + "\n  ".join(bad)
        )


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
        "  mrlib train --resume runs/ab/checkpoint.pt --out runs/ab\n"
        "  mrlib train data_samples/*.npz --preset demo --out runs/demo\n\n"
        "presets (--preset, mrlib.model.config.PRESETS):\n" + _preset_help("labels"),
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
        choices=_preset_choices("labels"),
        help="training schedule, one of the presets listed below; 'demo' also resamples "
        "the clips to its frame rate unless --fps is given [default: tutorial]",
    )
    p.add_argument(
        "--iterations",
        type=_parse_iterations,
        default=None,
        metavar="N[,N...]",
        help="iterations per block, overriding the preset (one value for all blocks, or one per block)",
    )
    p.add_argument(
        "--levels",
        type=_level_count,
        default=None,
        help="number of pyramid levels (overrides the preset)",
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
    p.add_argument("--seed", type=_seed, default=None, help="random seed (default: the preset's)")
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
        "--overwrite",
        action="store_true",
        help="replace a run already in --out (refused otherwise; --resume in the "
        "checkpoint's own folder needs no flag)",
    )
    p.add_argument(
        "--per-clip",
        action="store_true",
        help="GANimator-mode baseline: train one model per clip (in OUT/<clip name>/), "
        "so no model sees another condition and no crossover is learned",
    )
    p.add_argument(
        "--accept-retarget-error",
        action="store_true",
        help="train on BVH clips retargeted with an error above "
        "mrlib.io.retarget.RETARGET_WARN_CM or with joint angles no person holds (refused "
        "otherwise, with a RetargetWarning each: check their joint map with "
        "`mrlib info CLIP --write-map`)",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.set_defaults(func=_cmd_train)


def _single_clip(data, k: int):
    """Clip ``k`` of a TrainingSet as a set of its own (normaliser refitted)."""
    from mrlib.representation.features import FeatureNormalizer
    from mrlib.training.data import TrainingSet

    x = data.features[k]
    label = data.labels[data.clip_labels[k]]
    return TrainingSet(
        [x], [0], [label], data.fps, [data.names[k]], FeatureNormalizer.fit([x]), data.betas
    )


def _cmd_train(args) -> int:
    from mrlib.model.config import ganimator_mode, training_config
    from mrlib.training.data import TrainingSet
    from mrlib.training.trainer import check_run_folder, train

    if args.resume is None and not args.clips:
        raise MrlibError("give clips to train on, or --resume a checkpoint")
    if not args.per_clip:  # before loading anything (checked again under the run's lock)
        check_run_folder(args.out, resume=args.resume, overwrite=args.overwrite)
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
                "accept_retarget_error": "--accept-retarget-error",
            },
        )
        res = train(
            None,
            None,
            args.out,
            resume=args.resume,
            device=args.device,
            progress=not args.no_progress,
            overwrite=args.overwrite,
        )
        return _report_training(res)
    fps = args.fps if args.fps is not None else _preset_fps(args.preset or "tutorial")
    with _retarget_check(args.accept_retarget_error):
        data = TrainingSet.from_files(
            args.clips, labels=args.labels, fps=fps, joint_map=args.joint_map
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
            res = train(
                one,
                ganimator_mode(cfg),
                out,
                progress=not args.no_progress,
                overwrite=args.overwrite,
            )
            if res.interrupted:
                return 130
        return 0
    res = train(data, cfg, args.out, progress=not args.no_progress, overwrite=args.overwrite)
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
        "  mrlib train-speech --resume runs/speech/checkpoint.pt --out runs/speech\n\n"
        "presets (--preset, mrlib.model.config.PRESETS):\n" + _preset_help("speech"),
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
        choices=_preset_choices("speech") + [_short(n) for n in _preset_choices("speech")],
        help="training schedule, one of the speech presets listed below ('tutorial' and "
        "'paper' are short for speech_tutorial and speech_paper) [default: speech_tutorial]",
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
    p.add_argument("--seed", type=_seed, default=None, help="random seed (default: the preset's)")
    p.add_argument(
        "--device",
        type=_device,
        default=None,
        help="cpu or cuda [default: cpu; with --resume, the checkpoint's]",
    )
    p.add_argument("--out", type=Path, default=Path("runs/speech"), help="output folder")
    p.add_argument("--resume", type=Path, default=None, help="continue from this checkpoint")
    p.add_argument("--overwrite", action="store_true", help="replace a run already in --out")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.set_defaults(func=_cmd_train_speech)


def _cmd_train_speech(args) -> int:
    from mrlib.model.config import block_iterations_for, get_preset
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
    from mrlib.training.trainer import check_run_folder

    check_run_folder(args.out, resume=args.resume, overwrite=args.overwrite)  # before loading
    data = cfg = None
    if args.resume is None:
        if args.paired is None:
            raise MrlibError("give a folder of paired clips, or --resume a checkpoint")
        name = args.preset or "speech_tutorial"
        cfg = get_preset(name if name.startswith("speech_") else f"speech_{name}")
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
        overwrite=args.overwrite,
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
        "the arms swing in step with the legs (mrlib.sampling.constraints.phase_align)",
    )
    p.add_argument(
        "--sharpen",
        type=_parse_steps,
        nargs="?",
        const=None,
        default=0,
        metavar="N",
        help="with --parts: fit the noise for N Adam steps (default when given without N: "
        "mrlib.sampling.constraints.SHARPEN_STEPS) so that each part's windows are nearer its own "
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
        help="hold these keyframes (mrlib.sampling.constraints.save_keyframes); needs --seconds",
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
    p.add_argument(
        "--num",
        type=_sample_count,
        default=1,
        help=f"number of samples, 1 to {MAX_SAMPLES} [default: 1]",
    )
    p.add_argument("--seed", type=_seed, default=0, help="random seed [default: 0]")
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
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace sample files already in --out (refused otherwise)",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.set_defaults(func=_cmd_sample)


def _parse_parts(text: str) -> dict[str, str]:
    from mrlib.sampling.constraints import parse_parts

    try:
        return parse_parts(text)
    except MrlibError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def _constrained(model, kw: dict, length: int | None, args) -> list:
    """Samples under --path / --keyframes / --loop / --continue (one per seed)."""
    from mrlib.sampling import constraints as C

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
            # the prefix is resampled to the model's rate: its duration counts, not its frames
            _check_sample_frames(round(prefix.duration * model.fps) + frames, model.fps, args)
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
    from mrlib.model.trained import load_model
    from mrlib.sampling.generation import generate

    constrained = args.path or args.keyframes or args.loop or args.prefix
    if args.seed + args.num - 1 > MAX_SEED:
        raise MrlibError(f"--seed: the samples' seeds run to --seed + --num - 1, past {MAX_SEED}")
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
            from mrlib.sampling.constraints import follow_path

            motions = [follow_path(m, args.path, clean=not args.raw) for m in motions]
        return _write_samples(motions, tag, args)
    model = _with_sampler(load_model(args.checkpoint, device=args.device), args)
    if model.generator.cond_dim != len(model.labels):
        raise MrlibError(f"{args.checkpoint} is a speech-conditioned model: pass --audio FILE")
    length = None if args.seconds is None else max(2, round(args.seconds * model.fps))
    if length is not None:
        _check_sample_frames(length, model.fps, args)
    if args.parts:
        if constrained:
            raise MrlibError("--parts cannot be combined with --path/--keyframes/--loop/--continue")
        from mrlib.sampling.constraints import SHARPEN_STEPS, generate_parts

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


def _sample_files(tag: str, args, count: int) -> list[dict[str, Path]]:
    """Per sample, the files to write: ``<tag>_seed<seed>_<i>`` and one suffix per format,
    joined as text (a tag such as ``walk-run-0.5`` or ``talk.v1`` keeps its dots: the name is
    never cut at its last dot), each checked to stay in ``--out``."""
    from mrlib.io.paths import inside, safe_component

    tag = safe_component(tag, fallback="sample")  # labels come from files
    kinds = [".npz", ".bvh"]
    if getattr(args, "glb", False):
        kinds.append(".glb")
    if args.render:
        kinds.append(".png")
    return [
        {k: inside(args.out, args.out / f"{tag}_seed{args.seed}_{i}{k}") for k in kinds}
        for i in range(count)
    ]


def _write_samples(motions, tag: str, args) -> int:
    from mrlib.io import save_motion
    from mrlib.io.outputs import check_writable, write_bytes

    motions = motions if isinstance(motions, list) else [motions]
    args.out.mkdir(parents=True, exist_ok=True)
    files = _sample_files(tag, args, len(motions))
    for paths in files:  # refuse before writing any, not after half of them
        for path in paths.values():
            check_writable(path, overwrite=args.overwrite)
    for m, paths in zip(motions, files, strict=True):
        for kind, path in paths.items():
            if kind == ".png":
                import imageio.v3 as iio

                from mrlib.viz.render import evenly_spaced_frames, render_meshes

                image = render_meshes(m, frames=evenly_spaced_frames(len(m), 6))
                write_bytes(path, iio.imwrite("<bytes>", image, extension=".png"),
                            overwrite=args.overwrite)  # fmt: skip
            else:
                save_motion(m, path, overwrite=args.overwrite)
        stem = str(paths[".npz"])[: -len(".npz")]
        kinds = "/".join(k for k in paths if k != ".png")
        print(f"wrote {stem}{kinds}: {m}")
    return 0


# -- restyle -------------------------------------------------------------------------------
def _add_restyle(sub):
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
        type=_parse_steps,
        nargs="?",
        const=INVERT_STEPS,
        default=0,
        metavar="N",
        help=f"fit the coarse levels' noise to the clip for N Adam steps (default when given "
        f"without N: {INVERT_STEPS}) and restyle the model's own version of it; seconds "
        "instead of milliseconds, and on the Bandai clips measured it kept less of the clip "
        "(docs/notes/2026-12-04-restyle.md)",
    )
    p.add_argument(
        "--no-align",
        action="store_true",
        help="do not turn the clip to the training clips' facing while restyling",
    )
    _joint_map_option(p)
    p.add_argument("--seed", type=_seed, default=0, help="noise seed of the label's levels [0]")
    p.add_argument(
        "--raw", action="store_true", help="skip the foot-contact clean-up (on by default)"
    )
    _add_sampler_options(p)
    p.add_argument("--render", action="store_true", help="also write a mesh render (PNG)")
    p.add_argument("--glb", action="store_true", help="also write a .glb (skinned body mesh)")
    p.add_argument("--device", type=_device, default="cpu", help="cpu or cuda [default: cpu]")
    p.add_argument("--out", type=Path, default=Path("outputs/restyled"))
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace files already in --out (refused otherwise)",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.set_defaults(func=_cmd_restyle)


def _cmd_restyle(args) -> int:
    from mrlib.io import load_motion
    from mrlib.model.trained import load_model
    from mrlib.sampling.restyling import restyle, restyle_level

    model = _with_sampler(load_model(args.checkpoint, device=args.device), args)
    if model.generator.cond_dim != len(model.labels):
        raise MrlibError(
            f"{args.checkpoint} is a speech-conditioned model; restyle takes a label model"
        )
    level = restyle_level(model, args.level)
    if args.invert and args.keep != "coarse":
        raise MrlibError("--invert fits the coarse levels to the clip: it needs --keep coarse")
    clip = load_motion(args.clip, joint_map=args.joint_map)
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
    return _write_samples([m], tag, args)


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
    p.add_argument("--seed", type=_seed, default=0)
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
    from mrlib.evaluation.evaluate import evaluate_model, model_references
    from mrlib.model.trained import load_model
    from mrlib.viz.plots import plot_evaluation

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
    plot_evaluation(result, Path(args.out) / "evaluation.png")
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
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="presets (--preset, mrlib.model.config.PRESETS):\n" + _preset_help("labels"),
    )
    p.add_argument("--out", type=Path, default=Path("outputs"))
    p.add_argument(
        "--preset",
        default="demo",
        choices=_preset_choices("labels"),
        help="training schedule, one of the presets listed below [default: demo]",
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
    p.add_argument("--seed", type=_seed, default=0)
    p.set_defaults(func=_cmd_demo)


def _cmd_demo(args) -> int:
    from mrlib.app.demo import run_demo

    run_demo(
        args.out,
        preset=args.preset,
        quick=args.quick,
        iterations=args.iterations,
        samples=args.samples,
        seed=args.seed,
    )
    return 0


# -- data ----------------------------------------------------------------------------------
def _add_data(sub):
    p = sub.add_parser(
        "data",
        help="fetch or locate the public motion data the notebooks use",
        description="The Bandai Namco Research Motion Dataset 1 (CC BY-NC 4.0) is read from "
        "$MRLIB_DATA_DIR or ../shared when such a folder exists, else fetched on first use "
        "into mrlib's cache ($MRLIB_CACHE_DIR, default ~/.cache/mrlib) and checked against "
        "SHA-256 hashes. 'fetch' downloads ahead of time; 'where' says which folder is used.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n  mrlib data fetch bandai          # the clips the notebooks use\n"
        "  mrlib data fetch bandai --all    # all 174 clips (40 MB)\n  mrlib data where bandai",
    )
    p.add_argument("action", choices=["fetch", "where", "list"])
    p.add_argument("dataset", choices=["bandai"])
    p.add_argument("--all", action="store_true", help="fetch: every clip, not only the notebooks'")
    p.add_argument(
        "--clips", nargs="+", default=None, metavar="CLIP", help="fetch: these clips only"
    )
    p.set_defaults(func=_cmd_data)


def _cmd_data(args) -> int:
    from mrlib.datasets import bandai as datasets

    if args.action == "list":
        for name in datasets.bandai_registry():
            if name.endswith(".bvh"):
                print(name[len("data/dataset-1_") : -len(".bvh")])
        return 0
    if args.action == "where":
        local = datasets.bandai_local_dir()
        print(local if local is not None else f"{datasets.bandai_cache_dir()} (cache)")
        return 0
    local = datasets.bandai_local_dir()
    if local is not None:
        print(f"note: a local copy at {local} is read first; fetching into the cache anyway")
    root = datasets.fetch_bandai(args.clips or datasets.NOTEBOOK_CLIPS, everything=args.all)
    n = len(list((root / "data").glob("*.bvh")))
    print(f"{n} clips in {root}")
    return 0


# -- presets and threads, shared by the commands ---------------------------------------------
def _preset_choices(kind: str) -> list[str]:
    from mrlib.model.config import preset_names

    return preset_names(kind)


def _short(name: str) -> str:
    return name.removeprefix("speech_")


def _preset_help(kind: str) -> str:
    from mrlib.model.config import describe_presets

    return describe_presets(kind)


def _preset_fps(name: str) -> float | None:
    from mrlib.model.config import PRESET_FPS

    return PRESET_FPS.get(name)


def _threads(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"wants a positive integer, got {text!r}") from None
    if n < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text!r}")
    return n


def _add_threads_option(p) -> None:
    p.add_argument(
        "--threads",
        type=_threads,
        default=None,
        metavar="N",
        help="torch threads for the CPU work [default: OMP_NUM_THREADS if set, else half the "
        "usable CPUs, 1 on 2 cores; see mrlib.threads]",
    )


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
    _add_restyle(sub)
    _add_evaluate(sub)
    _add_export(sub)
    _add_info(sub)
    _add_data(sub)
    for command in sub.choices.values():
        _add_threads_option(command)
    return parser


def _describe(e: BaseException) -> str:
    """One line for an error: the file, the problem, and for OS errors what failed."""
    if isinstance(e, OSError) and not isinstance(e, MrlibError):
        where = f"{e.filename}: " if getattr(e, "filename", None) else ""
        return f"{where}{e.strerror or e}"
    if isinstance(e, MemoryError):
        return "out of memory (try a shorter clip, fewer samples or a lower --fps)"
    return str(e) or type(e).__name__  # mrlib's errors name the file or flag themselves


def main(argv: list[str] | None = None) -> int:
    """Run one command. Errors print one line (``error: ...``) and exit 1 (usage errors
    exit 2); ``--debug`` shows the full traceback instead."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        from mrlib.threads import policy

        with policy(args.threads):
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
