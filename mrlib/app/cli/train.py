"""``mrlib train`` and ``mrlib train-speech``: train a label model, or a speech-conditioned
one. Their shared options (``--iterations``, ``--seed --device --out --resume
--overwrite``, ``--no-progress``) are the blocks in :mod:`mrlib.app.cli.common`."""

from __future__ import annotations

import argparse
import contextlib
import math
import warnings
from pathlib import Path

from mrlib.app.cli.common import (
    add_command,
    iterations_option,
    joint_map_option,
    parse_fps,
    preset_choices,
    preset_help,
    progress_option,
    read_number,
    run_folder,
    run_options,
    up_axis_option,
)
from mrlib.errors import MrlibError
from mrlib.threads import use as use_threads

# frames of one training clip at the training rate: 10 minutes at 30 fps. Every level of
# the pyramid, its features and the discriminator's windows scale with it, and a clip this
# long is already minutes per iteration; more is a wrong --fps or a whole session.
MAX_TRAIN_CLIP_FRAMES = 18_000


def check_training_clips(motions, paths, fps: float | None) -> None:
    """Refuse, before resampling anything, a clip longer than ``MAX_TRAIN_CLIP_FRAMES``
    at the training rate ``fps`` (None: the first clip's, as ``TrainingSet``), naming the
    file, the limit and the way around it."""
    if fps is None and motions:
        fps = motions[0].fps
    if fps is None or not math.isfinite(fps) or fps <= 0:
        return  # a bad --fps or clip rate is reported where it is checked, in its own words
    for m, path in zip(motions, paths, strict=True):
        frames = m.duration * fps
        if not frames <= MAX_TRAIN_CLIP_FRAMES:
            raise MrlibError(
                f"{path}: {m.duration:.0f} s at {fps:g} fps is {frames:.0f} frames, more than "
                f"the {MAX_TRAIN_CLIP_FRAMES} a training clip may have "
                f"({MAX_TRAIN_CLIP_FRAMES / fps:.0f} s at this rate); cut it into shorter "
                "clips, or train at a lower --fps"
            )


def _level_count(text: str) -> int:
    from mrlib.model.config import MAX_LEVELS

    v = read_number(text, int, f"wants an integer, got {text!r}")
    if not 1 <= v <= MAX_LEVELS:
        raise argparse.ArgumentTypeError(
            f"must be in [1, {MAX_LEVELS}], got {v} (the paper uses 8; a level needs about "
            "4/3 times the frames of the one below)"
        )
    return v


def _positive_float(text: str) -> float:
    v = read_number(text, float, f"not a number: {text!r}")
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"must be a number > 0, got {text!r}")
    return v


def _short(name: str) -> str:
    return name.removeprefix("speech_")


@contextlib.contextmanager
def _retarget_check(accept: bool):
    """Loads inside refuse BVH clips retargeted with an error above the threshold (their
    RetargetWarning), unless ``accept``; other warnings pass through."""
    from mrlib.io.retarget_report import RetargetWarning

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


def _resume(args, trainer_class, options: dict[str, str]) -> int:
    """``--resume``: continue the run of ``args.resume`` with ``trainer_class`` (``Trainer``
    or ``SpeechTrainer``) at the thread count it began with, refusing ``options`` (as
    :func:`_refuse_on_resume`)."""
    from mrlib.training.run import resume_thread_count

    _refuse_on_resume(args, options)
    trainer = trainer_class.start(
        None, None, args.out, resume=args.resume, device=args.device, overwrite=args.overwrite
    )
    if trainer.done and Path(args.out).resolve() == Path(args.resume).resolve().parent:
        print(f"{args.resume}: the run is already complete (every block trained); nothing to do")
        return 0
    use_threads(resume_thread_count(trainer.threads))  # the count the run began with
    return _report_training(trainer.fit(progress=not args.no_progress, overwrite=args.overwrite))


# -- train ---------------------------------------------------------------------------------
def add_train(sub) -> argparse.ArgumentParser:
    p = add_command(
        sub,
        "train",
        "train a model on a few labelled clips",
        "Train the multi-resolution GAN on one or more clips. Each clip is one condition "
        "(its label comes from the file: the npz 'label' key, the Bandai JSON next to a BVH, or else "
        "the file name). Writes checkpoint.pt, checkpoint.pt.json (the config) and losses.csv to --out.",
        [
            "mrlib train data_samples/*.npz --out runs/samples",
            "mrlib train a.bvh b.bvh --labels calm angry --preset paper --device cuda --out runs/ab",
            "mrlib train --resume runs/ab/checkpoint.pt",
            "mrlib train data_samples/*.npz --preset demo --out runs/demo",
        ],
        preset_help("labels"),
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
        choices=preset_choices("labels"),
        help="training schedule, one of the presets listed below; one with a rate "
        "('demo', 'preview') also resamples the clips to it unless --fps is given "
        "[default: tutorial]",
    )
    iterations_option(
        p,
        "iterations per block, overriding the preset (one value for all blocks, or one per block)",
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
    p.add_argument(
        "--fps", type=parse_fps, default=None, help="resample every clip to this frame rate"
    )
    joint_map_option(p)
    p.add_argument(
        "--checkpoint-every",
        type=int,
        default=None,
        metavar="N",
        help="write the checkpoint every N iterations (default: the preset's; 0: at the end "
        "of each block only)",
    )
    run_options(
        p,
        out=Path("runs/model"),
        out_help="output folder",
        overwrite_help="replace a run already in --out (refused otherwise; --resume in the "
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
    progress_option(p)
    return p


def _single_clip(data, k: int):
    """Clip ``k`` of a TrainingSet as a set of its own (normaliser refitted)."""
    from mrlib.representation.features import FeatureNormalizer
    from mrlib.training.data import TrainingSet

    x = data.features[k]
    label = data.labels[data.clip_labels[k]]
    return TrainingSet(
        [x], [0], [label], data.fps, [data.names[k]], FeatureNormalizer.fit([x]), data.betas
    )


def cmd_train(args) -> int:
    from mrlib.model.presets import ganimator_mode, training_config
    from mrlib.training.data import TrainingSet
    from mrlib.training.run import check_run_folder
    from mrlib.training.trainer import Trainer, train

    if args.resume is None and not args.clips:
        raise MrlibError("give clips to train on, or --resume a checkpoint")
    run_folder(args)
    if not args.per_clip:  # before loading anything (checked again under the run's lock)
        check_run_folder(args.out, resume=args.resume, overwrite=args.overwrite)
    if args.resume is not None:
        return _resume(
            args,
            Trainer,
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
    from mrlib.io import joint_maps_for, load_motion

    with _retarget_check(args.accept_retarget_error):
        # TrainingSet.from_files, with the clips' lengths checked before they are resampled
        maps = joint_maps_for(args.clips, args.joint_map)  # BVH files only
        motions = [
            load_motion(p, joint_map=m, up_axis=args.up_axis, unit=args.unit)
            for p, m in zip(args.clips, maps, strict=True)
        ]
        # the preset's frame rate (TrainConfig.fps), unless --fps; None: the first clip's
        fps = cfg.fps if args.fps is None else args.fps
        check_training_clips(motions, args.clips, fps)
        data = TrainingSet.from_motions(motions, args.labels, fps)
    if args.fps is not None:  # the run trains at --fps, which its config records
        cfg = cfg.replace(fps=data.fps)
    print(
        f"training on {data.num_clips} clips, labels {data.labels}, {data.fps:g} fps, "
        f"lengths {data.lengths}"
    )
    if args.per_clip:
        from mrlib.io.paths import inside, unique_components

        # one folder per clip, named after the clip but never a path of its own: the name
        # comes from the file, so it is sanitised, and repeated names get distinct folders
        folders = unique_components(data.names, fallback="clip")
        outs = [inside(args.out, args.out / f) for f in folders]
        for out in outs:  # every clip's folder, before any training
            check_run_folder(out, overwrite=args.overwrite)
        from mrlib.io.transaction import current_transaction
        from mrlib.training.run import stage_run

        # the command's transaction (mrlib.app.cli.main): each run trains in a scratch
        # folder and all of them take their folders at the end, or (one fails) none
        tx = current_transaction()
        for k, out in enumerate(outs):
            one = _single_clip(data, k)
            print(f"[{k + 1}/{data.num_clips}] {data.names[k]} -> {out}")
            where = out if tx is None else tx.scratch_folder(out)
            res = train(one, ganimator_mode(cfg), where, progress=not args.no_progress,
                        overwrite=args.overwrite or tx is not None)  # fmt: skip
            if tx is not None:
                stage_run(tx, where, out, overwrite=args.overwrite)
            if res.interrupted:
                return 130
        return 0
    res = train(data, cfg, args.out, progress=not args.no_progress, overwrite=args.overwrite)
    return _report_training(res)


def _report_training(res) -> int:
    state = "interrupted; resume with --resume" if res.interrupted else "done"
    print(f"{state} in {res.wall_time_s:.0f} s -> {res.checkpoint}")
    return 130 if res.interrupted else 0


def parse_mismatch(text: str) -> float:
    """``--max-mismatch``: seconds, finite, 0 to 60."""
    value = read_number(text, float, f"not a number of seconds: {text!r}")
    if not math.isfinite(value) or not 0.0 <= value <= 60.0:
        raise argparse.ArgumentTypeError(f"must be between 0 and 60 seconds, got {text}")
    return value


# -- train-speech --------------------------------------------------------------------------
def add_train_speech(sub) -> argparse.ArgumentParser:
    p = add_command(
        sub,
        "train-speech",
        "train a speech-conditioned (co-speech gesture) model",
        "Train the multi-resolution GAN with speech as the control signal (paper "
        "Sec. 6): the reconstruction loss on paired clips (PAIRED holds <stem>.wav next to "
        "<stem>.npz or <stem>.bvh), random generations on unpaired audio (--unpaired, a folder "
        "of .wav, .flac, .ogg, .mp3 or .aiff). Speech FiLM modulates the upper body only. "
        "Writes checkpoint.pt, checkpoint.pt.json and losses.csv to --out; generate with "
        "'mrlib sample --audio'.",
        [
            "mrlib train-speech talks/paired --unpaired talks/audio --out runs/speech",
            "mrlib train-speech talks/paired --unpaired talks/audio --features wavlm "
            "--wavlm ~/wavlm-base-plus",
            "mrlib train-speech --resume runs/speech/checkpoint.pt --out runs/speech",
        ],
        preset_help("speech"),
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
        "--feature-scale",
        choices=["utterance", "training-set"],
        default=None,
        help="standardise the speech features over each utterance (so another voice, "
        "microphone or loudness reaches the model on the training speaker's scale) or over "
        "the training set only [default: utterance]",
    )
    p.add_argument(
        "--preset",
        default=None,
        choices=preset_choices("speech") + [_short(n) for n in preset_choices("speech")],
        help="training schedule, one of the speech presets listed below ('tutorial' and "
        "'paper' are short for speech_tutorial and speech_paper) [default: speech_tutorial]",
    )
    iterations_option(
        p, "iterations per block, overriding the preset (one value, or one per block)"
    )
    p.add_argument(
        "--random-audio",
        choices=["paired", "unpaired", "all"],
        default=None,
        help="audio of the random generations [default: 'paired' for the tutorial preset, "
        "whose critics hear the speech; 'unpaired' for the paper's, as in the paper]",
    )
    p.add_argument("--fps", type=parse_fps, default=None, help="motion frame rate [default: 25]")
    up_axis_option(p)
    p.add_argument(
        "--skip-unpaired-files",
        action="store_true",
        help="train on the audio/motion pairs of PAIRED and skip, with a warning, a file "
        "there without its partner (refused otherwise)",
    )
    p.add_argument(
        "--max-mismatch",
        type=parse_mismatch,
        default=None,
        metavar="SECONDS",
        help="accept pairs whose audio and motion durations differ by up to this many "
        "seconds, cutting both to the shorter (more: refused as a wrong pair) [default: 1]",
    )
    run_options(
        p,
        out=Path("runs/speech"),
        out_help="output folder",
        overwrite_help="replace a run already in --out",
    )
    progress_option(p)
    return p


def cmd_train_speech(args) -> int:
    from mrlib.model.presets import block_iterations_for, get_preset
    from mrlib.speech import SpeechFeatureExtractor, SpeechTrainer, SpeechTrainingSet, speech_train
    from mrlib.training.run import check_run_folder

    run_folder(args)
    if args.resume is not None:
        return _resume(
            args,
            SpeechTrainer,
            {
                "paired": "PAIRED",
                "unpaired": "--unpaired",
                "features": "--features",
                "wavlm": "--wavlm",
                "feature_scale": "--feature-scale",
                "preset": "--preset",
                "iterations": "--iterations",
                "random_audio": "--random-audio",
                "fps": "--fps",
                "max_mismatch": "--max-mismatch",
                "up_axis": "--up-axis",
                "skip_unpaired_files": "--skip-unpaired-files",
                "seed": "--seed",
            },
        )
    check_run_folder(args.out, overwrite=args.overwrite)  # before loading
    if args.paired is None:
        raise MrlibError("give a folder of paired clips, or --resume a checkpoint")
    name = args.preset or "speech_tutorial"
    cfg = get_preset(name if name.startswith("speech_") else f"speech_{name}")
    if args.iterations is not None:
        cfg = cfg.replace(block_iterations=block_iterations_for(args.iterations, cfg.num_blocks))
    if args.seed is not None:
        cfg = cfg.replace(seed=args.seed)
    cfg = cfg.replace(device=args.device or "cpu")
    if args.wavlm is not None and args.features != "wavlm":
        raise MrlibError("--wavlm applies with --features wavlm (the default features are logmel)")
    wavlm = None if args.wavlm is None else str(args.wavlm)
    extractor = SpeechFeatureExtractor(
        kind=args.features or "logmel",
        wavlm_path=wavlm,
        per_utterance=args.feature_scale != "training-set",
    )
    fps = args.fps if args.fps is not None else cfg.fps if cfg.fps is not None else 25.0
    mismatch = 1.0 if args.max_mismatch is None else args.max_mismatch
    data = SpeechTrainingSet.from_folders(
        args.paired, args.unpaired, extractor, fps=fps, max_mismatch_s=mismatch,
        up_axis=args.up_axis, strict=not args.skip_unpaired_files,
    )  # fmt: skip
    print(data)
    res = speech_train(
        data,
        cfg,
        args.out,
        random_audio=args.random_audio,
        progress=not args.no_progress,
        overwrite=args.overwrite,
    )
    return _report_training(res)
