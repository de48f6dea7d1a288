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
