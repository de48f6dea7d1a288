"""``mrlib sample``: generate motion from a trained model (a label, a crossover, a blend,
body parts, speech), optionally under a path, keyframes, a loop or a continuation."""

from __future__ import annotations

import argparse
import dataclasses
import math
from pathlib import Path

from mrlib.app.cli.common import (
    add_command,
    parse_fps,
    parse_seed,
    parse_steps,
    read_number,
    sample_output_options,
    sampler_from_args,
    up_axis_option,
    warn_unfinished,
    write_samples,
)
from mrlib.errors import MAX_SEED, MrlibError
from mrlib.sampling.generation import MAX_SAMPLE_FRAMES, MAX_SAMPLE_SECONDS
from mrlib.sampling.sampler import model_frames

MAX_SAMPLES = 1000  # --num: each sample is generated, cleaned up and written (2-4 files)


def _check_sample_frames(frames: int, fps: float, args, what: str | None = None) -> None:
    """Refuse, before generating, samples longer than ``MAX_SAMPLE_SECONDS`` or more
    frames in all than ``MAX_SAMPLE_FRAMES``."""
    if what is None:
        what = "--continue: the clip plus --seconds" if args.prefix is not None else "--seconds"
    if frames > MAX_SAMPLE_SECONDS * fps + 1:
        way = (
            "pass a shorter --seconds (the path is then walked that long) or a shorter path"
            if what.startswith("--path")
            else "generate shorter pieces and join them with --continue"
        )
        raise MrlibError(
            f"{what}: {frames / fps:.0f} s is longer than the {MAX_SAMPLE_SECONDS:.0f} s mrlib "
            f"generates in one sample (a longer walk leaves the 1000 m a motion may span); {way}"
        )
    if frames * args.num > MAX_SAMPLE_FRAMES:
        raise MrlibError(
            f"--num: {args.num} samples of {frames} frames are {frames * args.num} frames, more "
            f"than the {MAX_SAMPLE_FRAMES} one command generates; use fewer --num or a "
            "shorter --seconds, and run again with another --seed"
        )


def _sample_count(text: str) -> int:
    v = read_number(text, int, f"wants an integer >= 1, got {text!r}")
    if v < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {v}")
    if v > MAX_SAMPLES:
        raise argparse.ArgumentTypeError(
            f"must be at most {MAX_SAMPLES}, got {v} (for more, run again with another --seed)"
        )
    return v


class _Once(argparse.Action):
    """An option that may be given once (a second ``--label`` is refused, not the last
    one silently kept)."""

    def __call__(self, parser, namespace, values, option_string=None):
        if getattr(namespace, self.dest) is not None:
            raise argparse.ArgumentError(self, "given twice: pass one (--crossover or "
                                         "--blend mix labels)")  # fmt: skip
        setattr(namespace, self.dest, values)


def _seconds(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not (math.isfinite(v) and 0 < v <= MAX_SAMPLE_SECONDS):
        raise argparse.ArgumentTypeError(
            f"must be a number of seconds in (0, {MAX_SAMPLE_SECONDS:g}] (the most mrlib "
            f"generates in one sample; join longer motion with --continue), got {text!r}"
        )
    return v


def _parse_range(spec: str) -> tuple[str, tuple[int, int]]:
    try:
        label, levels = spec.rsplit(":", 1)
        a, b = (int(v) for v in levels.split("-"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected LABEL:FIRST-LAST, got {spec!r}") from None
    return label, (a, b)


def add_sample(sub) -> argparse.ArgumentParser:
    p = add_command(
        sub,
        "sample",
        "generate motion from a trained model",
        "Generate new motion. Choose the condition with --label, assign conditions to "
        "level ranges with --crossover (coarse levels first), or blend two labels with --blend. "
        "Writes one .npz (SMPL parameters) and one .bvh per sample, and a mesh render with --render.",
        [
            "mrlib sample runs/samples/checkpoint.pt --label walk_happy --seconds 10",
            "mrlib sample ckpt.pt --crossover walk_sad:1-4 walk_happy:5-8 --num 4 --render",
            "mrlib sample ckpt.pt --blend walk_sad walk_happy 0.5",
            "mrlib sample runs/speech/checkpoint.pt --audio talk.wav --render",
            "mrlib sample ckpt.pt --label walk_happy --path circle:2 --seconds 20",
            "mrlib sample ckpt.pt --parts upper=walk_happy,lower=walk_sad --sharpen",
            "mrlib sample ckpt.pt --label walk_sad --loop --seconds 4",
            "mrlib sample ckpt.pt --label walk_sad --keyframes kf.npz --seconds 6",
            "mrlib sample ckpt.pt --label walk_sad --continue clip.bvh --seconds 5",
        ],
    )
    p.add_argument("checkpoint", type=Path, help="a trained model (a run's checkpoint.pt)")
    g = p.add_mutually_exclusive_group()
    g.add_argument(
        "--label",
        default=None,
        action=_Once,
        help="condition for every level (default: the first label)",
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
        help="speech-conditioned models: gestures for this audio file (.wav, .flac, .ogg, .mp3, .aiff), as long as it",
    )
    p.add_argument(
        "--wavlm",
        type=Path,
        default=None,
        help="--audio with a WavLM model: the folder of its weights here, where the one "
        "recorded at training is not (default: that one, else $MRLIB_WAVLM_PATH)",
    )
    g.add_argument(
        "--parts",
        type=_parse_parts,
        default=None,
        metavar="PART=LABEL,...",
        help="a label per body part (upper, lower, left_arm, right_arm, or an SMPL joint "
        "name such as head or left_wrist), e.g. upper=walk_happy,lower=walk_sad",
    )
    p.add_argument(
        "--in-step",
        action="store_true",
        help="with --parts: retime each part to the gait of the part holding the pelvis, so "
        "the arms swing in step with the legs (mrlib.sampling.constraints.phase_align)",
    )
    p.add_argument(
        "--sharpen",
        type=parse_steps,
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
        help="walk a ground path: circle:R, circle-right:R, eight:R, line:L (metres; R 2 and "
        "L 10 when left out, as in 'circle') or a CSV of x,z[,t]; --seconds defaults to the "
        "path's times or its length at the label's pace",
    )
    c.add_argument(
        "--keyframes",
        type=Path,
        default=None,
        metavar="NPZ",
        help="hold these keyframes (mrlib.sampling.constraints.save_keyframes; their frames "
        "count frames at the samples' rate, --fps); needs --seconds",
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
    up_axis_option(p)
    p.add_argument(
        "--seconds",
        type=_seconds,
        default=None,
        help=f"length in seconds, at most {MAX_SAMPLE_SECONDS:g} (default: a training clip's)",
    )
    p.add_argument(
        "--fps",
        type=parse_fps,
        default=None,
        help="frame rate of the samples (and of a --keyframes file's frames): the model draws "
        "at its own rate (the preview preset: 15 fps; demo: 30), resampled by cubic splines "
        "before the feet are planted at this rate [default: the rate of the clips it was "
        "trained on (24-fps captures come back at 24 fps), recorded in checkpoints since "
        "2026-12-06; else the model's]",
    )
    p.add_argument(
        "--fit-steps",
        type=parse_steps,
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
    p.add_argument("--seed", type=parse_seed, default=0, help="random seed [default: 0]")
    p.add_argument(
        "--raw",
        action="store_true",
        help="skip the foot-contact clean-up (analytic leg IK that plants the feet while "
        "they are labelled in contact; on by default)",
    )
    p.add_argument("--fix-contacts", action="store_true", help=argparse.SUPPRESS)  # the default now
    sample_output_options(
        p,
        out=Path("outputs/samples"),
        render_help="also write a mesh render (PNG) per sample",
        glb_help="also write a .glb per sample: the skinned body mesh with the animation",
        overwrite_help="replace sample files already in --out (refused otherwise)",
    )
    return p


def _parse_parts(text: str) -> dict[str, str]:
    from mrlib.sampling.constraints import parse_parts

    try:
        return parse_parts(text)
    except MrlibError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def _constrained(model, condition, sampler, length: int | None, args) -> list:
    """Samples under --path / --keyframes / --loop / --continue (one per seed)."""
    from mrlib.sampling import constraints as C

    fit = {} if args.fit_steps is None else {"steps": args.fit_steps}
    fit["progress"] = not args.no_progress
    kw = {"condition": condition, "sampler": sampler}
    seconds = args.seconds
    if args.path is not None and seconds is None:  # the path's length: bounded up front
        seconds, _ = C.path_seconds(model, args.path, condition, sampler=sampler)
        what = f"--path {args.path} (without --seconds: its times, or its length at the pace)"
        _check_sample_frames(max(2, round(seconds * model.fps)), model.fps, args, what)
    out = []
    for b in range(args.num):
        seed = args.seed + b
        if args.path is not None:
            # without --seconds: the path's own length (an open one walked to its end)
            m = C.generate_on_path(model, args.path, seconds=args.seconds, seed=seed, **kw)
        elif args.keyframes is not None:
            if length is None:
                raise MrlibError("--keyframes needs --seconds (the length of the motion)")
            kfs = C.load_keyframes(args.keyframes)
            if not kfs:
                raise MrlibError(f"{args.keyframes}: holds no keyframes")
            fps = sampler.fps or model.fps
            frames = max(2, round(args.seconds * fps))
            late = sorted(k.frame for k in kfs if k.frame >= frames)
            if late:
                raise MrlibError(
                    f"{args.keyframes}: keyframes at frames {late} are beyond the motion's "
                    f"{frames} frames ({args.seconds:g} s at {fps:g} fps)"
                )
            m = C.generate_with_keyframes(
                model, kfs, length, seed=seed, fit=C.KeyframeFit(**fit), **kw
            )
        elif args.loop:
            m = C.generate_loop(model, length=length, seed=seed, **kw)
        else:
            from dataclasses import replace

            from mrlib.io import load_motion

            if args.seconds is None:
                raise MrlibError("--continue needs --seconds (how much to add)")
            prefix = load_motion(args.prefix, up_axis=args.up_axis)
            if prefix.num_frames < 2 or prefix.resampled_frames(model.fps) < 2:
                raise MrlibError(
                    f"{args.prefix}: {prefix.num_frames} frame(s) at {prefix.fps:g} fps are "
                    f"fewer than two at the model's {model.fps:g} fps; --continue needs a "
                    "longer clip"
                )
            frames = model_frames(args.seconds, model.fps, least=1)
            # the prefix is resampled to the model's rate: its duration counts, not its frames
            _check_sample_frames(round(prefix.duration * model.fps) + frames, model.fps, args)
            cont = replace(C.keyframes.CONTINUE_FIT, **fit)
            m = C.continue_motion(model, prefix, frames, seed=seed, fit=cont, **kw)
            if b == 0 and args.fps is None and m.fps != model.fps:
                print(f"continued at {m.fps:g} fps, the prefix's rate (the model draws at "
                      f"{model.fps:g} fps: --fps for another)")  # fmt: skip
        out.append(m)
    return out


def cmd_sample(args) -> int:
    from mrlib.model.trained import load_model
    from mrlib.sampling.conditions import Condition, label_weights
    from mrlib.sampling.generation import generate

    constrained = args.path or args.keyframes or args.loop or args.prefix
    if args.seed + args.num - 1 > MAX_SEED:
        raise MrlibError(f"--seed: the samples' seeds run to --seed + --num - 1, past {MAX_SEED}")
    if args.in_step and not args.parts:
        raise MrlibError("--in-step applies to --parts only")
    if args.candidates is not None and (args.keyframes or args.loop or args.prefix):
        raise MrlibError("--candidates applies to label, crossover, blend, --path and --parts "
                         "samples (keyframes, loops and continuations draw once)")  # fmt: skip
    if args.up_axis is not None and args.prefix is None:
        raise MrlibError("--up-axis applies to --continue only (the one file sample reads)")
    if args.fps is not None and args.audio is not None:
        raise MrlibError("--fps applies to label models' samples (speech samples come at the "
                         "model's rate)")  # fmt: skip
    if args.sharpen != 0 and not args.parts:
        raise MrlibError("--sharpen applies to --parts only")
    if args.wavlm is not None and args.audio is None:
        raise MrlibError("--wavlm applies to --audio only (a speech model's WavLM weights)")
    if args.fit_steps is not None and args.keyframes is None and args.prefix is None:
        raise MrlibError("--fit-steps applies to --keyframes and --continue only")
    from mrlib.sampling.constraints.optimise import check_fit_steps

    for flag, steps in (("--fit-steps", args.fit_steps), ("--sharpen", args.sharpen)):
        if steps:  # bounded before the model is read
            check_fit_steps(steps, flag)
    if args.audio is not None:
        if constrained and not args.path:
            raise MrlibError("with --audio only --path applies (keyframes, loops and "
                             "continuation need a label model)")  # fmt: skip
        motions, tag = _audio_samples(args)
        if args.path:
            from mrlib.sampling.constraints import follow_path

            motions = [follow_path(m, args.path, clean=not args.raw) for m in motions]
        return write_samples(motions, tag, args)
    sampler = sampler_from_args(args)
    if args.fps is not None:
        sampler = dataclasses.replace(sampler, fps=args.fps)  # its bounds checked there
    model = load_model(args.checkpoint, device=args.device)
    if model.generator.cond_dim != len(model.labels):
        raise MrlibError(f"{args.checkpoint} is a speech-conditioned model: pass --audio FILE")
    warn_unfinished(model, args.checkpoint)
    length = None if args.seconds is None else model_frames(args.seconds, model.fps)
    if length is not None:
        _check_sample_frames(length, model.fps, args)
        out_fps = args.fps or model.source_fps or model.fps  # what is written, at most
        _check_sample_frames(round(args.seconds * out_fps), out_fps, args)
    if args.parts:
        if constrained:
            raise MrlibError("--parts cannot be combined with --path/--keyframes/--loop/--continue")
        from mrlib.sampling.constraints import SHARPEN_STEPS, Sharpening, generate_parts

        steps = SHARPEN_STEPS if args.sharpen is None else args.sharpen
        parts = Condition.parts(args.parts, in_step=args.in_step)
        for lab in args.parts.values():
            model.label_index(lab)  # an unknown label is refused before the notice
        sampler = _output_rate(model, sampler, args)
        motions = generate_parts(model, parts, length=length, seed=args.seed, num=args.num,
                                 sampler=sampler, sharpen=Sharpening(
                                     steps=steps, progress=not args.no_progress))  # fmt: skip
        motions = _as_long_as(motions, args.seconds)
        return write_samples(motions, ",".join(f"{k}={v}" for k, v in args.parts.items()), args)
    if args.crossover:
        condition = Condition.levels(args.crossover)
        tag = "+".join(f"{lab}{a}-{b}" for lab, (a, b) in args.crossover)
    elif args.blend:
        a, b, w = args.blend
        try:
            w = float(w)
        except ValueError:
            raise MrlibError(f"--blend weight must be a number in [0, 1], got {w!r}") from None
        if not 0 <= w <= 1:
            raise MrlibError(f"--blend weight must be in [0, 1], got {w:g}")
        condition = Condition.blend(a, b, w)
        tag = f"{a}-{b}-{float(w):g}"
    else:
        condition = args.label if args.label is not None else model.labels[0]
        tag = str(condition)
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
        label_weights(model, condition)  # an unknown label is refused before the notice
        if args.path is not None:  # and a path spec or file that is not one
            from mrlib.sampling.constraints import parse_path

            parse_path(args.path)
        if args.prefix is None:  # a continuation comes at its prefix's rate
            sampler = _output_rate(model, sampler, args)
        motions = _constrained(model, condition, sampler, length, args)
        if not args.loop:  # a loop keeps its cycle whole
            motions = _as_long_as(motions, args.seconds)
        return write_samples(motions, f"{tag}_{what}", args)
    label_weights(model, condition)  # an unknown label is refused before the notice
    sampler = _output_rate(model, sampler, args)
    motions = generate(
        model, condition, length=length, seed=args.seed, num=args.num, sampler=sampler
    )
    return write_samples(_as_long_as(motions, args.seconds), tag, args)


def _as_long_as(motions: list, seconds: float | None) -> list:
    """Each motion cut to ``round(seconds * fps)`` frames at its own rate (the model
    drew ``model_frames`` frames, enough for that at any output rate); a continuation
    keeps its prefix and adds that many."""
    if seconds is None:
        return motions
    out = []
    for m in motions:
        n = m.meta.get("prefix_frames", 0) + max(2, round(seconds * m.fps))
        out.append(m.slice(0, n) if m.num_frames > n else m)
    return out


def _output_rate(model, sampler, args):
    """``sampler`` at the training clips' rate where the model draws at another and
    ``--fps`` is not given, with a line that says so (and that keyframe files count
    frames at that rate)."""
    if args.fps is not None or model.source_fps is None:
        return sampler
    whose = "the training clips' rate" if len(set(model.clip_fps)) == 1 else (
        "the highest rate of the training clips")  # fmt: skip
    keys = "; --keyframes count frames at this rate" if args.keyframes else ""
    print(f"samples at {model.source_fps:g} fps, {whose} (the model draws "
          f"at {model.fps:g} fps: --fps {model.fps:g} for that){keys}")  # fmt: skip
    return dataclasses.replace(sampler, fps=model.source_fps)


def _audio_samples(args):
    from mrlib.speech import generate_from_audio, load_speech_model

    if args.seconds is not None:
        raise MrlibError(
            "--seconds does not apply to --audio: the motion lasts as long as the audio"
        )
    from mrlib.speech.audio import MAX_AUDIO_SECONDS, audio_duration, check_audio_seconds

    seconds = audio_duration(args.audio)  # the header only: refused before any work
    check_audio_seconds(seconds, args.audio, MAX_AUDIO_SECONDS)
    model = load_speech_model(args.checkpoint, device=args.device, wavlm_path=args.wavlm)
    warn_unfinished(model, args.checkpoint, "train-speech")
    frames = round(seconds * model.fps)
    if frames * args.num > MAX_SAMPLE_FRAMES:
        raise MrlibError(
            f"--num: {args.num} samples of {args.audio} ({frames} frames each) are "
            f"{frames * args.num} frames, more than the {MAX_SAMPLE_FRAMES} one command "
            "generates; use fewer --num, and run again with another --seed"
        )
    sampler = sampler_from_args(args, label_model=False)
    motions = generate_from_audio(model, args.audio, seed=args.seed, num=args.num, sampler=sampler)
    return motions, args.audio.stem
