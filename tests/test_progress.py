"""Progress (``mrlib.progress``): a live bar on a terminal, one line per task in a log,
nothing with ``--no-progress``; every command that shows progress takes the flag."""

from __future__ import annotations

import io

import pytest
import torch

from mrlib import progress


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_log_gets_one_line_per_task_and_no_redraws(monkeypatch):
    monkeypatch.delenv("MRLIB_PROGRESS", raising=False)
    log = io.StringIO()
    monkeypatch.setattr("sys.stderr", log)
    assert not progress.interactive()
    with progress.bar(total=5000, desc="block 1/2") as bar:
        for _ in range(5000):
            bar.update(1)
        bar.set_postfix({"D": "-0.3"}, refresh=False)
    assert sum(1 for _ in progress.bar(range(300), desc="render")) == 300
    lines = log.getvalue().splitlines()
    assert "\r" not in log.getvalue() and len(lines) == 2, log.getvalue()
    assert lines[0].startswith("block 1/2: 5000/5000 in ") and lines[0].endswith("D=-0.3")
    assert lines[1].startswith("render: 300/300 in ")


def test_a_terminal_gets_a_live_bar_and_no_progress_gets_nothing(monkeypatch):
    monkeypatch.delenv("MRLIB_PROGRESS", raising=False)
    term = _Terminal()
    monkeypatch.setattr("sys.stderr", term)
    assert progress.interactive()
    from tqdm import tqdm

    live = progress.bar(total=3, file=term)
    assert isinstance(live, tqdm)
    live.close()
    log = io.StringIO()
    monkeypatch.setattr("sys.stderr", log)
    with progress.bar(total=10, desc="quiet", enabled=False) as bar:
        bar.update(10)
    assert list(progress.bar(range(3), enabled=False)) == [0, 1, 2]
    monkeypatch.setenv("MRLIB_PROGRESS", "off")
    with progress.bar(total=10, desc="off") as bar:
        bar.update(10)
    assert log.getvalue() == ""


def test_training_into_a_log_writes_one_line_per_block(monkeypatch, tmp_path):
    from mrlib.datasets.synthetic import synthetic_walk
    from mrlib.model.config import ModelConfig, TrainConfig
    from mrlib.training.data import TrainingSet
    from mrlib.training.trainer import train

    monkeypatch.delenv("MRLIB_PROGRESS", raising=False)
    log = io.StringIO()
    monkeypatch.setattr("sys.stderr", log)
    torch.set_num_threads(1)
    data = TrainingSet.from_motions([synthetic_walk("walk_sad", seconds=2.0, fps=10.0)])
    cfg = TrainConfig(model=ModelConfig(num_levels=4, gen_hidden=(8,), disc_hidden=(8,)),
                      block_iterations=(30, 30), n_critic=1, checkpoint_every=0, log_every=5)  # fmt: skip
    train(data, cfg, tmp_path, progress=True)
    lines = log.getvalue().splitlines()
    assert "\r" not in log.getvalue()
    assert [ln.split(":")[0] for ln in lines] == [
        "block 1/2 (levels 1-2)",
        "block 2/2 (levels 3-4)",
    ]
    assert all(" 30/30 in " in ln and "rec=" in ln for ln in lines), lines


def _commands():
    from mrlib.app.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    return sub.choices


@pytest.mark.parametrize(
    "name", ["train", "train-speech", "sample", "restyle", "evaluate", "demo", "data"]
)
def test_every_command_that_shows_progress_takes_no_progress(name):
    command = _commands()[name]
    assert any("--no-progress" in a.option_strings for a in command._actions), name


def test_a_task_that_fails_writes_no_line_claiming_it_finished(monkeypatch):
    monkeypatch.delenv("MRLIB_PROGRESS", raising=False)
    log = io.StringIO()
    monkeypatch.setattr("sys.stderr", log)
    with pytest.raises(RuntimeError):
        for i in progress.bar(range(10), desc="download"):
            if i == 3:
                raise RuntimeError("mirror gone")
    with pytest.raises(RuntimeError), progress.bar(total=4, desc="evaluate") as bar:
        bar.update(2)
        raise RuntimeError("disk full")
    assert log.getvalue() == ""
