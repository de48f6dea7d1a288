"""Every command-line flag that mrlib's messages and docstrings name exists: an error
that says "--max-mismatch" or "--skip-unpaired-files" points at a real way around."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# flags of other programs that mrlib's text names, each with where it belongs
OTHER_PROGRAMS = {
    "--check": "tools/make_speech_samples.py's",
    "--cpus": "docker's (a container's CPU quota)",
    "--extras": "bench/busy_machine.py's",
    "--local-dir": "huggingface-cli's",
    "--root": "python -m mrlib.tools.layers's own parser",
}


def _options() -> set[str]:
    from mrlib.app.cli import build_parser

    found: set[str] = set()

    def walk(parser: argparse.ArgumentParser) -> None:
        for action in parser._actions:
            found.update(o for o in action.option_strings if o.startswith("--"))
            if isinstance(action, argparse._SubParsersAction):
                for sub in action.choices.values():
                    walk(sub)

    walk(build_parser())
    return found


def test_every_flag_mrlib_names_exists():
    options = _options()
    named: dict[str, set[str]] = {}
    for f in (ROOT / "mrlib").rglob("*.py"):
        for m in re.finditer(r"(?<![\w-])--[a-z][a-z0-9-]+", f.read_text(encoding="utf-8")):
            named.setdefault(m.group(0), set()).add(str(f.relative_to(ROOT)))
    missing = {k: sorted(v) for k, v in named.items() if k not in options | set(OTHER_PROGRAMS)}
    assert not missing, f"flags named but not on the command line: {missing}"
    stale = set(OTHER_PROGRAMS) - set(named)
    assert not stale, f"OTHER_PROGRAMS entries nothing names any more: {stale}"


def test_version_is_the_packages(capsys):
    import pytest

    from mrlib.app.cli import main

    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0
    text = (ROOT / "pyproject.toml").read_text()  # tomllib: Python 3.11 on
    want = re.search(r'^version = "([^"]+)"', text, re.M).group(1)
    assert capsys.readouterr().out.strip() == f"mrlib {want}"
