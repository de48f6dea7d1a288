"""What the commands share: argument types, option blocks (each defined once here and
added by every command that takes it), the sample writer and the one-line error.

Heavy mrlib modules are imported inside the functions, so that building the parser
stays light.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from mrlib.errors import MAX_SEED, MrlibError


# -- argument types ------------------------------------------------------------------------
def read_number(text: str, kind, unreadable: str):
    """``kind(text)`` (``int``, ``float``, a whole number), or argparse's error saying
    ``unreadable`` where ``text`` is no such number; its range is the caller's check."""
    try:
        return kind(text)
    except ValueError:
        raise argparse.ArgumentTypeError(unreadable) from None


def parse_seed(text: str) -> int:
    v = read_number(text, int, f"wants an integer >= 0, got {text!r}")
    if not 0 <= v <= MAX_SEED:
        raise argparse.ArgumentTypeError(f"must be in [0, {MAX_SEED}], got {v}")
    return v


def parse_device(text: str) -> str:
    from mrlib.model.config import ConfigError, check_device

    try:
        return check_device(text)
    except ConfigError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def parse_iterations(text: str | None) -> tuple[int, ...] | None:
    if text is None:
        return None
    try:
        its = tuple(int(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"wants integers, got {text!r}") from None
    if any(i <= 0 for i in its):
        raise argparse.ArgumentTypeError(f"must be positive, got {text!r}")
    return its


def _whole(text: str) -> int:
    """``text`` as an int: ``"300"``, or a whole number written as ``"1e8"``."""
    try:
        return int(text)
    except ValueError:
        v = float(text)  # ValueError for what is no number at all
        if not (math.isfinite(v) and v.is_integer()):
            raise ValueError(text) from None
        return int(v)


def _count(text: str, least: int) -> int:
    """A whole number of at least ``least`` (0 or 1)."""
    kind = "a positive integer" if least == 1 else f"an integer >= {least}"
    n = read_number(text, _whole, f"wants {kind}, got {text!r}")
    if n < least:
        raise argparse.ArgumentTypeError(f"must be {kind}, got {text!r}")
    return n


def parse_steps(text: str) -> int:
    """A count of steps (its cap is the command's check, in one line:
    ``mrlib.sampling.constraints.optimise.check_fit_steps``)."""
    return _count(text, 0)


def parse_non_negative(text: str) -> float:
    value = read_number(text, float, f"not a number: {text!r}")
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"must be a number >= 0, got {text!r}")
    return value


def _sampler_setting(limit_name: str):
    """``--fine-noise`` / ``--guidance``: a number in [0, the sampler's bound]."""

    def parse(text: str) -> float:
        from mrlib.sampling import sampler

        value = parse_non_negative(text)
        limit = getattr(sampler, limit_name)
        if value > limit:
            raise argparse.ArgumentTypeError(f"must be at most {limit:g}, got {text!r}")
        return value

    parse.__name__ = "number"
    return parse


def parse_positive(text: str) -> int:
    """A count of at least one (samples, iterations)."""
    return _count(text, 1)


def parse_fps(text: str) -> float:
    """A frame rate in (0, ``MAX_FPS``]."""
    from mrlib.representation.motion import MAX_FPS

    value = read_number(text, float, f"not a frame rate: {text!r}")
    if not (math.isfinite(value) and 0 < value <= MAX_FPS):
        raise argparse.ArgumentTypeError(f"must be a frame rate in (0, {MAX_FPS:g}], got {text!r}")
    return value


def parse_threads(text: str) -> int:
    """A positive count (its cap, 4 x the usable CPUs, is ``mrlib.threads``'s check)."""
    return _count(text, 1)


# -- presets -------------------------------------------------------------------------------
def preset_choices(kind: str) -> list[str]:
    from mrlib.model.presets import preset_names

    return preset_names(kind)


def preset_help(kind: str) -> str:
    """The "presets:" block of a command's epilog: the presets of ``kind``, described."""
    from mrlib.model.presets import describe_presets

    return "presets (--preset, mrlib.model.presets.PRESETS):\n" + describe_presets(kind)


# -- option blocks -------------------------------------------------------------------------
def threads_option(p) -> None:
    """``--threads``: every command takes it (``mrlib.threads``)."""
    p.add_argument(
        "--threads",
        type=parse_threads,
        default=None,
        metavar="N",
        help="torch threads for the CPU work, at most 4 x the usable CPUs [default: "
        "OMP_NUM_THREADS if set, else half the usable CPUs, 1 on 2 cores; see mrlib.threads]",
    )


def joint_map_option(p) -> None:
    """``--joint-map`` and ``--up-axis``: how a motion file is read."""
    p.add_argument(
        "--joint-map",
        default=None,
        metavar="MAP",
        help="BVH only: a shipped map name or a JSON file {smpl_joint: bvh_joint} (default: "
        "the shipped map that fits, else one recognised from the skeleton)",
    )
    p.add_argument(
        "--unit",
        type=parse_unit,
        default="auto",
        metavar="UNIT",
        help="BVH only: the file's length unit: m, cm, mm, inch, cmu (CMU's 0.45 in) or "
        "metres per unit [default: auto, the unit that gives the bones a person's length]",
    )
    up_axis_option(p)


def parse_unit(text: str) -> str | float:
    """``--unit``: a unit's name, ``auto``, or a positive number of metres per unit."""
    from mrlib.io.axes import UNITS

    if text == "auto" or text in UNITS:
        return text
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (value > 0 and value < float("inf")):
        raise argparse.ArgumentTypeError(
            f"expected auto, {', '.join(UNITS)} or metres per unit (a positive number), "
            f"got {text!r}"
        )
    return value


UP_AXES = ("auto", "x", "y", "z", "-x", "-y", "-z")


def up_axis_option(p) -> None:
    p.add_argument(
        "--up-axis",
        choices=UP_AXES,
        default=None,
        help="the motion files' up axis [default: an npz's own up_axis key, else told from "
        "the body (AMASS: z, BEAT2: y); a BVH's from its skeleton]",
    )


def device_option(p, *, resume: bool = False) -> None:
    """``--device``: cpu by default, or (``resume``) the checkpoint's when resuming."""
    if resume:
        p.add_argument(
            "--device",
            type=parse_device,
            default=None,
            help="cpu or cuda [default: cpu; with --resume, the checkpoint's]",
        )
    else:
        p.add_argument(
            "--device", type=parse_device, default="cpu", help="cpu or cuda [default: cpu]"
        )


def overwrite_option(p, help: str) -> None:
    p.add_argument("--overwrite", action="store_true", help=help)


def progress_option(p) -> None:
    p.add_argument("--no-progress", action="store_true", help="no progress bars")


def iterations_option(p, help: str) -> None:
    """``--iterations N[,N...]`` of ``train`` and ``train-speech``."""
    p.add_argument(
        "--iterations", type=parse_iterations, default=None, metavar="N[,N...]", help=help
    )


def run_options(p, *, out: Path, out_help: str, overwrite_help: str) -> None:
    """``--seed --device --out --resume --overwrite`` of ``train`` and ``train-speech``."""
    p.add_argument(
        "--seed", type=parse_seed, default=None, help="random seed (default: the preset's)"
    )
    device_option(p, resume=True)
    p.add_argument(
        "--out",
        type=Path,
        default=None,
        help=f"{out_help} [default: {out}; with --resume, the checkpoint's own folder]",
    )
    p.add_argument("--resume", type=Path, default=None, help="continue from this checkpoint")
    p.set_defaults(default_out=out)
    overwrite_option(p, overwrite_help)


def run_folder(args) -> Path:
    """``--out`` of ``train`` / ``train-speech``: as given, else the folder of the
    checkpoint ``--resume`` continues, else the command's default."""
    if args.resume is not None:  # before any folder's state
        from mrlib.model.checkpoint import check_checkpoint_file

        check_checkpoint_file(args.resume)
    if args.out is None:
        args.out = args.resume.parent if args.resume is not None else args.default_out
    return args.out


def sampler_options(p, candidates: bool = True) -> None:
    """``--fine-noise``, ``--guidance`` and (``candidates``) ``--candidates``,
    ``--match-contact-rate`` and ``--cut-contacts`` (read by :func:`sampler_from_args`)."""
    p.add_argument(
        "--fine-noise",
        type=_sampler_setting("MAX_FINE_NOISE"),
        default=None,
        metavar="S",
        help="the finest level's noise as a share of its training sigma [default: 1, the "
        "paper's sampler]; lower: less frame-to-frame jitter and less of the fine label's "
        "detail in crossovers (0: as smooth as the training clips)",
    )
    p.add_argument(
        "--guidance",
        type=_sampler_setting("MAX_GUIDANCE"),
        default=None,
        metavar="G",
        help="label models: exaggerate the label, each level's condition pushed G times "
        "its distance away from the mean of all labels [default: 0, the paper's sampler]; "
        "0.25 sharpens the label at about the same coverage, 1 and more leave the training "
        "poses",
    )
    if not candidates:
        return
    p.add_argument(
        "--candidates",
        type=_candidates,
        default=None,
        metavar="K",
        help="label models: draw K candidates per sample and keep the one the model's "
        "critics score highest [default: 8; 1: the paper's sampler, every draw kept]; "
        "more: closer to the labels' clips, less varied",
    )
    reading = p.add_mutually_exclusive_group()
    reading.add_argument(
        "--match-contact-rate",
        action="store_const",
        const=True,
        default=None,
        help="label models: every label's foot vertices in contact on as many frames as "
        "the label's training clips, those of highest contact output [default: as the "
        "model chose per label when its training ended]; plants slow walks' feet longer",
    )
    reading.add_argument(
        "--cut-contacts",
        dest="match_contact_rate",
        action="store_const",
        const=False,
        help="label models: every label's contact labels where the generator's output "
        "exceeds 0.5, the paper's sampler [default: as the model chose per label]",
    )


def _candidates(text: str) -> int:
    from mrlib.sampling.sampler import MAX_CANDIDATES

    value = read_number(text, _whole, f"wants a whole number, got {text!r}")
    if not 1 <= value <= MAX_CANDIDATES:
        raise argparse.ArgumentTypeError(f"must be in [1, {MAX_CANDIDATES}], got {text!r}")
    return value


def sample_output_options(
    p, *, out: Path, render_help: str, glb_help: str, overwrite_help: str, candidates: bool = True
) -> None:
    """The sampler options (``--candidates`` where ``candidates``), then ``--render --glb
    --device --out --overwrite --no-progress`` of ``sample`` and ``restyle`` (written by
    :func:`write_samples`)."""
    sampler_options(p, candidates)
    p.add_argument("--render", action="store_true", help=render_help)
    p.add_argument("--glb", action="store_true", help=glb_help)
    device_option(p)
    p.add_argument(
        "--out", type=Path, default=out, help=f"folder the samples are written to [default: {out}]"
    )
    overwrite_option(p, overwrite_help)
    progress_option(p)


# -- helpers of the commands ---------------------------------------------------------------
def sampler_from_args(args, *, label_model: bool = True):
    """The ``mrlib.Sampler`` of ``--fine-noise``, ``--guidance``, ``--candidates``,
    ``--match-contact-rate`` / ``--cut-contacts`` and ``--raw`` (the sampler's defaults
    where one is not given);
    the label models' options are refused for a speech model (``label_model=False``)."""
    from mrlib.sampling.sampler import CANDIDATES, FINE_NOISE, GUIDANCE, Sampler

    guidance = getattr(args, "guidance", None)
    candidates = getattr(args, "candidates", None)
    matched = getattr(args, "match_contact_rate", None)
    reading = {True: "--match-contact-rate", False: "--cut-contacts", None: ""}[matched]
    for flag, value in (
        ("--guidance", guidance), ("--candidates", candidates), (reading, matched),
    ):  # fmt: skip
        if value is not None and not label_model:
            raise MrlibError(f"{flag} applies to label models only")
    return Sampler(
        fine_noise=FINE_NOISE if args.fine_noise is None else args.fine_noise,
        guidance=GUIDANCE if guidance is None else guidance,
        fix_contacts=not getattr(args, "raw", False),
        candidates=CANDIDATES if candidates is None else candidates,
        match_contact_rate=matched,
    )


def warn_unfinished(model, checkpoint, command: str = "train") -> None:
    """One line on stderr when ``model`` (a label model, or a speech model's) comes from
    an unfinished run: where its training stopped and the command that finishes it. The
    command goes on: a partly trained model samples, only not what the run would give."""
    import sys

    where = getattr(getattr(model, "model", model), "unfinished", lambda: None)()
    if where:
        print(
            f"warning: {checkpoint} is from an unfinished run (stopped at {where}): its "
            f"samples come from a partly trained model; finish it with `mrlib {command} "
            f"--resume {checkpoint} --out {Path(checkpoint).parent}`",
            file=sys.stderr,
        )


def sample_files(tag: str, args, count: int) -> list[dict[str, Path]]:
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


def write_samples(motions, tag: str, args) -> int:
    """Write every sample's files (:func:`sample_files`) in one output transaction: all of
    them, or (a full disk, a file that cannot be replaced) none, ``--out`` as it was."""
    from mrlib.io import save_motion
    from mrlib.io.outputs import check_writable, write_bytes
    from mrlib.io.transaction import make_folders, output_transaction, when_written

    motions = motions if isinstance(motions, list) else [motions]
    files = sample_files(tag, args, len(motions))
    for paths in files:  # refuse before writing any, not after half of them
        for path in paths.values():
            check_writable(path, overwrite=args.overwrite)
    with output_transaction():
        make_folders(args.out)
        for m, paths in zip(motions, files, strict=True):
            for kind, path in paths.items():
                if kind == ".png":
                    import imageio.v3 as iio

                    from mrlib.viz.meshes import evenly_spaced_frames, render_meshes

                    image = render_meshes(m, frames=evenly_spaced_frames(len(m), 6))
                    write_bytes(path, iio.imwrite("<bytes>", image, extension=".png"),
                                overwrite=args.overwrite)  # fmt: skip
                else:
                    save_motion(m, path, overwrite=args.overwrite)
            stem = str(paths[".npz"])[: -len(".npz")]
            kinds = "/".join(paths)
            # printed once the files exist (at the end of the command's transaction)
            when_written(lambda line=f"wrote {stem}{kinds}: {m}": print(line))
    return 0


def one_line(text: str) -> str:
    """``text`` on one line: a newline, tab or other control character (in a file name,
    say) is shown escaped (``\\n``), as Python writes it in a string."""
    return "".join(c if c.isprintable() else ascii(c)[1:-1] for c in text)


def describe(e: BaseException) -> str:
    """One line for an error: the file, the problem, and for OS errors what failed."""
    if isinstance(e, OSError) and not isinstance(e, MrlibError):
        where = f"{e.filename}: " if getattr(e, "filename", None) else ""
        return one_line(f"{where}{e.strerror or e}")
    if isinstance(e, MemoryError):
        return "out of memory (try a shorter clip, fewer samples or a lower --fps)"
    return one_line(str(e) or type(e).__name__)  # mrlib's errors name the file or flag


# -- a command's parser ----------------------------------------------------------------------
def add_command(
    sub,
    name: str,
    help: str,
    description: str,
    examples: list[str] | tuple[str, ...] = (),
    more: str | None = None,
) -> argparse.ArgumentParser:
    """The parser of command ``name``: its one-line ``help``, its ``description`` and an
    epilog of an "examples:" block, one example command line each, then ``more`` (a
    block such as the presets), a blank line between, all shown as written. A command
    with neither has no epilog, and its description is wrapped to the terminal."""
    blocks = ["examples:\n" + "\n".join(f"  {e}" for e in examples)] if examples else []
    if more is not None:
        blocks.append(more)
    if not blocks:
        return sub.add_parser(name, help=help, description=description)
    return sub.add_parser(
        name,
        help=help,
        description=description,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="\n\n".join(blocks),
    )
