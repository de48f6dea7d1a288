"""The demo end to end on its smoke-test budget: every stage, the previews, the summary."""

from __future__ import annotations

import pytest

pytest.importorskip("pyvista")


@pytest.mark.slow
def test_quick_demo_writes_every_stage_and_the_quality_table(tmp_path, capsys):
    from mrlib.app.cli import main

    assert main(["demo", "--quick", "--out", str(tmp_path)]) == 0
    printed = capsys.readouterr().out
    for k, stage in enumerate(["load", "retarget", "train", "sample", "crossover", "evaluate"]):
        assert f"[{k + 1}/6] {stage}:" in printed
    summary = (tmp_path / "summary.md").read_text()
    assert "## Quality at a glance" in summary and "| calib: played twice |" in summary
    assert "Cond. fidelity %" in summary and "Foot skating %" in summary
    for gif in ("sample.gif", "crossover.gif"):
        assert (tmp_path / gif).stat().st_size > 10_000 and f"({gif})" in summary
    assert (tmp_path / "samples" / "crossover.bvh").is_file()
    assert "## Time per stage" in summary and "- train:" in summary


def test_demo_rejects_an_unknown_preset(tmp_path):
    from mrlib.app.demo import run_demo
    from mrlib.model.config import ConfigError

    with pytest.raises(ConfigError, match="unknown preset"):
        run_demo(tmp_path, preset="fast")


@pytest.mark.parametrize("earlier", ["summary.md", "samples/walk_sad.npz", "sample_walk_sad.png"])
def test_demo_refuses_an_earlier_run_before_any_work(tmp_path, capsys, earlier):
    """A second `mrlib demo` into the same folder stops in one line, the earlier run's files
    untouched; `--overwrite` is the way around (what `make demo` passes)."""
    import time

    from mrlib.app.cli import main

    old = tmp_path / earlier
    old.parent.mkdir(parents=True, exist_ok=True)
    old.write_bytes(b"earlier run")
    t0 = time.perf_counter()
    assert main(["demo", "--quick", "--out", str(tmp_path)]) != 0
    assert time.perf_counter() - t0 < 5
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--overwrite" in err[0] and earlier.split("/")[0] in err[0]
    assert "Error" not in err[0].split(":")[0]  # no exception class name
    assert old.read_bytes() == b"earlier run"


def test_demo_folder_check_leaves_other_files_alone(tmp_path):
    from mrlib.app.demo import check_demo_folder
    from mrlib.io.outputs import OutputError, OutputExistsError

    (tmp_path / "notes.txt").write_text("mine")
    (tmp_path / "cleanup_natural").mkdir()
    check_demo_folder(tmp_path, overwrite=False)  # nothing of a demo run: accepted
    (tmp_path / "model").mkdir()
    with pytest.raises(OutputExistsError, match="overwrite"):
        check_demo_folder(tmp_path, overwrite=False)
    check_demo_folder(tmp_path, overwrite=True)
    with pytest.raises(OutputError, match="not a folder"):
        check_demo_folder(tmp_path / "notes.txt", overwrite=False)
