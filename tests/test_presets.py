"""One registry of presets (``mrlib.model.presets.PRESETS``) behind every ``--preset``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from mrlib.app.cli import build_parser, main
from mrlib.model.config import ConfigError, config_to_json
from mrlib.model.presets import (
    PRESET_SUMMARIES,
    PRESETS,
    demo,
    describe_presets,
    get_preset,
    preset_names,
)

SAMPLES = Path(__file__).resolve().parents[1] / "data_samples"


def test_every_preset_has_a_one_line_summary_and_a_kind():
    assert set(PRESET_SUMMARIES) == set(PRESETS)
    assert all(s and "\n" not in s for s in PRESET_SUMMARIES.values())
    assert preset_names() == list(PRESETS)
    assert sorted(preset_names("labels") + preset_names("speech")) == sorted(PRESETS)
    assert "demo" in preset_names("labels") and "speech_tutorial" in preset_names("speech")
    assert get_preset("demo").fps == 30.0 and get_preset("tutorial").fps is None
    assert get_preset("preview").fps == 15.0 and "preview" in preset_names("labels")
    with pytest.raises(ConfigError):
        preset_names("images")


def test_preview_is_the_demo_preset_at_15_fps_on_the_smaller_budget():
    d, p = get_preset("demo"), get_preset("preview")
    assert (d.fps, p.fps) == (30.0, 15.0)
    assert sum(p.block_iterations) < sum(d.block_iterations)
    assert p.replace(fps=d.fps, block_iterations=d.block_iterations) == d


def test_describe_presets_lists_each_with_its_summary():
    text = describe_presets("labels")
    for name in preset_names("labels"):
        assert any(line.split()[0] == name for line in text.splitlines()), name
        assert PRESET_SUMMARIES[name] in text
    assert "speech_paper" not in text


@pytest.mark.parametrize(
    "command, kind", [("train", "labels"), ("demo", "labels"), ("train-speech", "speech")]
)
def test_help_lists_the_registry(capsys, command, kind):
    with pytest.raises(SystemExit) as e:
        main([command, "--help"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    for name in preset_names(kind):
        assert PRESET_SUMMARIES[name] in out, (command, name)


def test_preset_choices_come_from_the_registry():
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command").choices

    def choices(command):
        return next(a for a in sub[command]._actions if a.dest == "preset").choices

    assert choices("train") == preset_names("labels")
    assert choices("demo") == preset_names("labels")
    assert set(preset_names("speech")) <= set(choices("train-speech"))
    assert {"tutorial", "paper"} <= set(choices("train-speech"))  # the short names still work


@pytest.mark.parametrize(
    "argv",
    [
        ["train", "clip.npz", "--preset", "speech_tutorial"],
        ["demo", "--preset", "speech_tutorial"],
        ["train-speech", "paired", "--preset", "speech_speech_tutorial"],
    ],
)
def test_a_preset_of_the_other_kind_is_a_usage_error(capsys, argv):
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 2
    assert "--preset" in capsys.readouterr().err


def test_mrlib_train_preset_demo(tmp_path):
    """``mrlib train --preset demo`` trains the demo preset on clips at its frame rate
    (a budget of 2 iterations per block here, so it takes seconds)."""
    from mrlib.model.trained import load_model

    out = tmp_path / "run"
    clips = [str(SAMPLES / "walk_happy.npz"), str(SAMPLES / "walk_sad.npz")]
    argv = ["train", *clips, "--preset", "demo", "--iterations", "2", "--out", str(out)]
    assert main([*argv, "--no-progress"]) == 0
    saved = json.loads((out / "checkpoint.pt.json").read_text())
    expected = demo().replace(block_iterations=(2, 2, 2, 2))
    assert saved == json.loads(config_to_json(expected))
    model = load_model(out / "checkpoint.pt")
    assert model.fps == get_preset("demo").fps
    assert model.trained_levels == model.num_levels == demo().model.num_levels


def test_an_explicit_fps_overrides_the_presets(tmp_path):
    from mrlib.model.trained import load_model

    out = tmp_path / "run"
    argv = [
        "train",
        str(SAMPLES / "walk_sad.npz"),
        "--preset",
        "demo",
        "--fps",
        "10",
        "--iterations",
        "1",
        "--levels",
        "2",
        "--out",
        str(out),
        "--no-progress",
    ]
    assert main(argv) == 0
    assert load_model(out / "checkpoint.pt").fps == 10
    assert get_preset("demo").lr == json.loads((out / "checkpoint.pt.json").read_text())["lr"]
