"""Command-line interface: ``mrlib {demo,train,train-speech,sample,restyle,evaluate,export,info,data}``.

Run ``mrlib COMMAND --help`` for the options of each command. Each command lives in a
module of this package as a pair of functions, ``add_<command>`` (its options, with help
texts) and ``cmd_<command>`` (a few lines calling the library); ``train`` holds
``train-speech`` too. The option blocks several commands take, the sample writer and the
one-line error are in :mod:`mrlib.app.cli.common`; the logic lives in ``mrlib``, whose
heavy modules the commands import when they run.
"""

from __future__ import annotations

import argparse
import sys
import warnings

from mrlib import __version__
from mrlib.app.cli.common import describe, threads_option
from mrlib.app.cli.common import sample_files as _sample_files  # noqa: F401 (tests use it)
from mrlib.app.cli.data import add_data
from mrlib.app.cli.data import cmd_data as _cmd_data
from mrlib.app.cli.demo import add_demo
from mrlib.app.cli.demo import cmd_demo as _cmd_demo
from mrlib.app.cli.evaluate import add_evaluate
from mrlib.app.cli.evaluate import cmd_evaluate as _cmd_evaluate
from mrlib.app.cli.export import add_export
from mrlib.app.cli.export import cmd_export as _cmd_export
from mrlib.app.cli.info import add_info
from mrlib.app.cli.info import cmd_info as _cmd_info
from mrlib.app.cli.restyle import add_restyle
from mrlib.app.cli.restyle import cmd_restyle as _cmd_restyle
from mrlib.app.cli.sample import add_sample
from mrlib.app.cli.sample import cmd_sample as _cmd_sample
from mrlib.app.cli.train import add_train, add_train_speech
from mrlib.app.cli.train import cmd_train as _cmd_train
from mrlib.app.cli.train import cmd_train_speech as _cmd_train_speech
from mrlib.errors import MrlibError

__all__ = ["EPILOG", "build_parser", "main"]

EPILOG = """examples:
  mrlib info data_samples/walk_happy.npz
  mrlib train data_samples/*.npz --preset tutorial --out runs/samples
  mrlib sample runs/samples/checkpoint.pt --label walk_happy --seconds 10 --out outputs/happy
  mrlib sample runs/samples/checkpoint.pt --crossover walk_sad:1-4 walk_happy:5-8 --out outputs/mix
  mrlib export clip.bvh clip.npz
  mrlib export outputs/happy/walk_happy_seed0_0.npz happy.glb
"""


class _Parser(argparse.ArgumentParser):
    """A usage error in one line, pointing at the command's help (not argparse's usage
    block of a dozen lines above it)."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    """The ``mrlib`` parser. Each command runs the ``_cmd_<command>`` of this module as it
    is when the parser is built (so a test or a wrapper may replace one here)."""
    parser = _Parser(
        prog="mrlib",
        description="Multi-resolution generative modelling of SMPL human motion from limited data.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--debug", action="store_true", help="show the full traceback of an error")
    parser.add_argument("--version", action="version", version=f"mrlib {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    add_demo(sub).set_defaults(func=_cmd_demo)
    add_train(sub).set_defaults(func=_cmd_train)
    add_train_speech(sub).set_defaults(func=_cmd_train_speech)
    add_sample(sub).set_defaults(func=_cmd_sample)
    add_restyle(sub).set_defaults(func=_cmd_restyle)
    add_evaluate(sub).set_defaults(func=_cmd_evaluate)
    add_export(sub).set_defaults(func=_cmd_export)
    add_info(sub).set_defaults(func=_cmd_info)
    add_data(sub).set_defaults(func=_cmd_data)
    for command in sub.choices.values():
        threads_option(command)
        for action in command._actions:  # an empty value is refused, never taken for "."
            if action.nargs != 0:
                action.type = _not_empty(action.type)
    return parser


def _not_empty(kind):
    """``kind`` (an argparse ``type``, or None for text) refusing an empty or blank value:
    ``--out ""`` would write to the current folder, ``--path ""`` would be no path."""

    def convert(text):
        if isinstance(text, str) and not text.strip():
            raise argparse.ArgumentTypeError(f"wants a value, got {text!r}")
        return text if kind is None else kind(text)

    convert.__name__ = getattr(kind, "__name__", "value")  # argparse's "invalid <name> value"
    return convert


def _one_line_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """A Python warning as the command line shows it: ``warning: <message>``, one line
    (not the file, line number and source line where it was raised)."""
    text = " ".join(str(message).split())
    print(f"warning: {text}", file=sys.stderr if file is None else file)


def main(argv: list[str] | None = None) -> int:
    """Run one command. Errors print one line (``error: ...``) and exit 1 (usage errors
    exit 2); ``--debug`` shows the full traceback instead; warnings print one line each
    (``warning: ...``). The command's output files
    are written in one ``mrlib.io.transaction.output_transaction``: all of them, or (when one
    fails, or the command does) none, the output folder as it was. mrlib's own errors
    name the file or flag; any other exception (a bug, a library's error) is one line
    ``error: <command>: <ExceptionClass>: <message> (run with --debug for the traceback)``."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        from mrlib.io.transaction import output_transaction
        from mrlib.threads import policy

        # a command's outputs are all written or none (a training run's checkpoints,
        # which must reach the disk as it goes, are written outside it)
        with warnings.catch_warnings():
            warnings.showwarning = _one_line_warning  # restored when the command ends
            with policy(args.threads), output_transaction():
                return int(args.func(args) or 0)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except (MrlibError, OSError, MemoryError) as e:
        if args.debug:
            raise
        print(f"error: {describe(e)}", file=sys.stderr)
        return 1
    except Exception as e:  # a bug or a library's own error: one line, not a traceback
        if args.debug:
            raise
        message = " ".join(str(e).split()) or "(no message)"
        print(
            f"error: {args.command}: {type(e).__name__}: {message} "
            "(run with --debug for the traceback)",
            file=sys.stderr,
        )
        return 1
