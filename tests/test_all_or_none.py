"""A command's outputs are all written or none (the "data loss" class of the bad-input
sweep): a full disk, a file size limit (RLIMIT_FSIZE, as ``ulimit -f``), a file that
cannot be replaced or a non-finite first loss leaves the output folder exactly as it
was, and the one-line error names the file that failed and why.

The output transaction itself (``mrlib.io.transaction.output_transaction``: the k-th publish
failing for every k), then the commands: ``sample``, ``restyle``, ``evaluate`` and
``train`` under a real file size limit in a subprocess, and training runs that stop
before (or after) their first checkpoint."""

from __future__ import annotations

import ast
import errno
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
import torch

from mrlib.app.cli import main
from mrlib.datasets.synthetic import synthetic_walk
from mrlib.errors import MrlibError
from mrlib.io import outputs, save_motion
from mrlib.io.outputs import (
    OutputError,
    OutputWriteError,
    atomic_write,
    open_for_append,
    write_bytes,
)
from mrlib.io.transaction import make_folders, output_transaction, when_written
from mrlib.training.trainer import Trainer

TRAIN = ["--levels", "2", "--no-progress"]


def _snapshot(root: Path) -> dict[str, bytes | None]:
    """Every entry under ``root`` (folders as None) and the bytes of every file."""
    if not root.exists():
        return {}
    return {
        p.relative_to(root).as_posix(): None if p.is_dir() else p.read_bytes()
        for p in root.rglob("*")
    }


def _temporaries(root: Path) -> list[Path]:
    return [p for p in root.rglob("*") if ".tmp" in p.name]


# -- the transaction ------------------------------------------------------------------------
def _folder(tmp_path: Path) -> Path:
    out = tmp_path / "out"
    out.mkdir()
    (out / "a.bin").write_bytes(b"old a")
    (out / "b.bin").write_bytes(b"old b")
    return out


def _write_five(out: Path) -> list[Path]:
    """New, replaced, new in a new folder, replaced, new: five publishes."""
    make_folders(out / "sub" / "deeper")
    targets = [out / "c.bin", out / "a.bin", out / "sub" / "deeper" / "d.bin", out / "b.bin",
               out / "e.bin"]  # fmt: skip
    for path in targets:
        write_bytes(path, b"new " + path.name.encode(), overwrite=True)
    return targets


@pytest.mark.parametrize("hard_links", [True, False])
@pytest.mark.parametrize("k", range(5))
def test_the_kth_publish_failing_leaves_the_folder_as_it_was(k, hard_links, tmp_path, monkeypatch):
    out = _folder(tmp_path)
    before = _snapshot(out)
    if not hard_links:  # a file system without them: replaced files are moved aside instead

        def no_link(*a, **kw):
            raise OSError(errno.EPERM, "Operation not permitted")

        monkeypatch.setattr(os, "link", no_link)
    real, calls, said = outputs._publish, [], []

    def publish(tmp, path, overwrite):
        calls.append(path)
        if len(calls) == k + 1:
            raise OSError(errno.EFBIG, "File too large")
        return real(tmp, path, overwrite)

    monkeypatch.setattr(outputs, "_publish", publish)
    with pytest.raises(OutputWriteError) as info:
        with output_transaction():
            targets = _write_five(out)
            when_written(lambda: said.append("wrote"))
    assert info.value.path == targets[k] and isinstance(info.value, OSError)
    assert str(info.value).startswith(f"{targets[k]}: cannot write: File too large; none of")
    assert _snapshot(out) == before and not _temporaries(tmp_path) and not said


def test_all_files_are_published_together_then_the_message(tmp_path):
    out = _folder(tmp_path)
    seen = []
    with output_transaction() as tx:
        targets = _write_five(out)
        assert (out / "a.bin").read_bytes() == b"old a" and not (out / "c.bin").exists()
        when_written(lambda: seen.append(all(p.exists() for p in targets)))
        with output_transaction() as inner:  # joins the outer one
            assert inner is tx
            write_bytes(out / "f.bin", b"f")
        assert not (out / "f.bin").exists()
    assert seen == [True] and tx.published == [*targets, out / "f.bin"]
    assert all(p.read_bytes() == b"new " + p.name.encode() for p in targets)
    assert not _temporaries(tmp_path)


@pytest.mark.parametrize("exc", [KeyboardInterrupt, MrlibError])
def test_an_error_in_the_command_writes_nothing_and_says_so(exc, tmp_path):
    out = _folder(tmp_path)
    before = _snapshot(out)
    with pytest.raises(exc) as info, output_transaction() as tx:
        _write_five(out)
        scratch = tx.scratch_folder(out / "model")
        raise exc(f"{scratch}: went wrong")
    assert _snapshot(out) == before and not _temporaries(tmp_path)
    if exc is MrlibError:  # the scratch folder is named as what it stands for
        assert (
            str(info.value) == f"{out / 'model'}: went wrong; no output of this command was written"
        )


def test_a_target_that_turned_into_a_folder_is_refused_before_any_publish(tmp_path):
    out = _folder(tmp_path)
    with pytest.raises(OutputError, match="not a regular file.*none of this command's 2 files"):
        with output_transaction():
            write_bytes(out / "a.bin", b"new", overwrite=True)
            write_bytes(out / "c.bin", b"new")
            (out / "c.bin").mkdir()  # appears meanwhile: nothing can replace it
    assert (out / "a.bin").read_bytes() == b"old a" and not _temporaries(tmp_path)


def test_a_failed_write_names_the_file_and_the_reason(tmp_path):
    def efbig(fh):
        fh.write(b"part")
        raise OSError(errno.EFBIG, "File too large")  # as a write past RLIMIT_FSIZE: no name

    path = tmp_path / "x.bin"
    with pytest.raises(OutputWriteError, match="x.bin: cannot write: File too large; nothing"):
        atomic_write(path, efbig)
    path.write_bytes(b"old")
    with pytest.raises(OSError, match="x.bin: cannot write: File too large; the previous file"):
        atomic_write(path, efbig, overwrite=True)
    assert path.read_bytes() == b"old" and not _temporaries(tmp_path)
    with pytest.raises(OutputWriteError, match="/dev/full: cannot write: No space left"):
        with open_for_append("/dev/full") as fh:  # a full disk, for appends
            fh.write("row\n")
            fh.flush()


# -- the commands under a real file size limit ----------------------------------------------
def _clip(path: Path, label: str, seconds: float, seed: int) -> Path:
    m = synthetic_walk("walk_sad", seconds=seconds, fps=10.0, seed=seed)
    return save_motion(m.replace(name=path.stem, label=label), path)


@pytest.fixture(scope="module")
def clips(tmp_path_factory) -> list[Path]:
    """Two 6 s clips (long enough for ``evaluate``)."""
    root = tmp_path_factory.mktemp("clips")
    return [_clip(root / "a.npz", "v1.0", 6.0, 0), _clip(root / "b.npz", "v1.1", 6.0, 1)]


@pytest.fixture(scope="module")
def run(clips, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("run") / "run"
    assert main(["train", *map(str, clips), *TRAIN, "--iterations", "1", "--out", str(out)]) == 0
    return out


def _limited(runs: list[tuple[int, list[str]]]) -> list[tuple[str, str]]:
    """``main(argv)`` of each ``(kib, argv)`` in a subprocess whose files may not exceed
    ``kib`` KiB (writes past it fail with EFBIG, as on a full disk); ``(exit code,
    stderr)`` of each."""
    script = textwrap.dedent(
        f"""
        import contextlib, io, resource
        from mrlib.app.cli import main
        for kib, argv in {runs!r}:
            resource.setrlimit(resource.RLIMIT_FSIZE, (kib * 1024, resource.RLIM_INFINITY))
            err = io.StringIO()
            with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
                code = main(argv)
            print(code, repr(err.getvalue()))
        """
    )
    res = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    lines = [ln.split(" ", 1) for ln in res.stdout.strip().splitlines()]
    return [(code, ast.literal_eval(err)) for code, err in lines]


def _failed_on(result: tuple[str, str], name: str) -> None:
    code, err = result  # stderr: progress lines (no terminal), then the error
    errors = [ln for ln in err.splitlines() if ln.startswith("error: ")]
    assert code == "1" and len(errors) == 1 and "Traceback" not in err, err
    assert name in errors[0] and "File too large" in errors[0], err


def test_sample_num_3_glb_under_a_file_size_limit_writes_none(run, tmp_path):
    """.npz (25 KiB) and .bvh (50 KiB) fit under 64 KiB, the .glb (1 MB) does not: no
    file of the 9, and no --out folder; over an earlier sample set with --overwrite, the
    .npz fits under 32 KiB and the .bvh does not: every earlier file stays as it was."""
    fresh, old = tmp_path / "fresh", tmp_path / "old"
    base = ["sample", str(run / "checkpoint.pt"), "--label", "v1.0", "--num", "3"]
    assert main([*base, "--raw", "--out", str(old)]) == 0
    before = _snapshot(old)
    results = _limited(
        [
            (64, [*base, "--glb", "--out", str(fresh)]),
            (32, [*base, "--overwrite", "--out", str(old)]),
        ]
    )
    _failed_on(results[0], ".glb")
    _failed_on(results[1], ".bvh")
    assert not fresh.exists() and _snapshot(old) == before and not _temporaries(tmp_path)


def test_evaluate_under_a_file_size_limit_names_the_file_and_writes_none(run, tmp_path):
    """The CSV, Markdown and JSON files fit under 8 KiB, the figure does not."""
    fresh, old = tmp_path / "fresh", tmp_path / "old"
    base = ["evaluate", str(run / "checkpoint.pt"), "--samples", "1", "--no-calibration", "--raw"]
    old.mkdir()
    for name in ("evaluation.csv", "evaluation_summary.csv", "evaluation.md",
                 "evaluation_settings.json", "evaluation.png"):  # fmt: skip
        (old / name).write_text(f"previous {name}")
    before = _snapshot(old)
    results = _limited(
        [(8, [*base, "--out", str(fresh)]), (8, [*base, "--overwrite", "--out", str(old)])]
    )
    for result in results:
        _failed_on(result, "evaluation.png")
        assert "none of this command's outputs was written" in result[1]
    assert not fresh.exists() and _snapshot(old) == before and not _temporaries(tmp_path)


def test_train_under_a_file_size_limit_keeps_nothing_or_the_previous_run(run, clips, tmp_path):
    """The checkpoint (4.8 MB) does not fit: a fresh run leaves no folder (no losses.csv);
    a run over an earlier one (--overwrite) leaves that one byte for byte."""
    fresh, old = tmp_path / "fresh", shutil.copytree(run, tmp_path / "old")
    before = _snapshot(old)
    base = ["train", *map(str, clips), *TRAIN, "--iterations", "1"]
    results = _limited(
        [(100, [*base, "--out", str(fresh)]), (100, [*base, "--out", str(old), "--overwrite"])]
    )
    for result, folder in zip(results, (fresh, old), strict=True):
        _failed_on(result, f"{folder / 'checkpoint.pt'}: could not write the checkpoint")
        assert f"nothing was kept ({folder} is as it was before)" in result[1]
        assert "previous one is kept" not in result[1]
    assert not fresh.exists() and _snapshot(old) == before and not _temporaries(tmp_path)


# -- a file that cannot be replaced ---------------------------------------------------------
@pytest.mark.parametrize("command", ["sample", "restyle"])
def test_overwrite_onto_a_pair_whose_bvh_cannot_be_replaced(command, run, clips, tmp_path,
                                                            monkeypatch, capsys):  # fmt: skip
    """The .bvh of the pair cannot take its name (EPERM, as an immutable file): the new
    .npz is not left beside the old .bvh. A folder at the .bvh's name is refused before
    any work."""
    out = tmp_path / "o"
    argv = [command, str(run / "checkpoint.pt")]
    argv += ["--label", "v1.0"] if command == "sample" else [str(clips[0]), "--label", "v1.1"]
    argv += ["--no-progress", "--out", str(out)]
    assert main(argv) == 0
    (bvh,) = out.glob("*.bvh")
    before = _snapshot(out)
    real = outputs._publish

    def publish(tmp, path, overwrite):
        if path.suffix == ".bvh":
            raise OSError(errno.EPERM, "Operation not permitted")
        return real(tmp, path, overwrite)

    monkeypatch.setattr(outputs, "_publish", publish)
    capsys.readouterr()
    assert main([*argv, "--seed", "0", "--raw", "--overwrite"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"error: {bvh}: cannot write: Operation not permitted; none of")
    assert _snapshot(out) == before and not _temporaries(tmp_path)
    monkeypatch.setattr(outputs, "_publish", real)
    bvh.unlink()
    bvh.mkdir()
    assert main([*argv, "--raw", "--overwrite"]) == 1
    assert "not a regular file" in capsys.readouterr().err
    assert _snapshot(out) == {**before, bvh.name: None}


# -- training runs that stop before (or after) their first checkpoint -----------------------
def _nan_from_step(monkeypatch, first: int) -> None:
    """Every iteration from the ``first``-th (1-based, counted in this process) has a
    non-finite loss."""
    real, calls = Trainer.step, {"n": 0}

    def step(self):
        losses = real(self)
        calls["n"] += 1
        if calls["n"] >= first:
            losses[self.block_levels[-1]]["rec"] = torch.tensor(float("nan"))
        return losses

    monkeypatch.setattr(Trainer, "step", step)


def test_a_non_finite_first_loss_leaves_no_run_folder(clips, tmp_path, monkeypatch, capsys):
    out = tmp_path / "new" / "run"
    _nan_from_step(monkeypatch, 1)
    assert main(["train", *map(str, clips), *TRAIN, "--iterations", "2", "--out", str(out)]) == 1
    err = capsys.readouterr().err.strip()
    assert "loss 'rec' of level 2 is not finite at block 1, iteration 1" in err
    assert err.endswith(f"nothing was kept ({out} is as it was before)") and "kept:" not in err
    assert not (tmp_path / "new").exists()


def test_a_non_finite_first_loss_over_a_run_leaves_it_as_it_was(run, clips, tmp_path,
                                                                monkeypatch, capsys):  # fmt: skip
    out = shutil.copytree(run, tmp_path / "r")
    before = _snapshot(out)
    _nan_from_step(monkeypatch, 1)
    argv = ["train", *map(str, clips), *TRAIN, "--iterations", "2", "--overwrite"]
    assert main([*argv, "--out", str(out)]) == 1
    assert f"nothing was kept ({out} is as it was before)" in capsys.readouterr().err
    assert _snapshot(out) == before and not _temporaries(out)


def test_a_run_says_which_checkpoint_it_kept(clips, tmp_path, monkeypatch, capsys):
    """A checkpoint at iteration 2, a non-finite loss at 3: that checkpoint is named. Its
    resumption failing at once keeps it, and the folder, as they were."""
    out = tmp_path / "r"
    _nan_from_step(monkeypatch, 3)
    argv = ["train", *map(str, clips), *TRAIN, "--iterations", "4", "--checkpoint-every", "2"]
    assert main([*argv, "--out", str(out)]) == 1
    err = capsys.readouterr().err.strip()
    ckpt = out / "checkpoint.pt"
    assert err.endswith(f"training stopped; kept: the checkpoint of block 1, iteration 2 ({ckpt})")
    before = _snapshot(out)
    _nan_from_step(monkeypatch, 1)
    assert main(["train", "--resume", str(ckpt), "--out", str(out), "--no-progress"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.endswith(
        f"kept: the checkpoint it resumed from (block 1, iteration 2), {out} as it was"
    )
    assert _snapshot(out) == before and not _temporaries(out)
    other = tmp_path / "other"
    assert main(["train", "--resume", str(ckpt), "--out", str(other), "--no-progress"]) == 1
    assert f"nothing was written to {other} ({ckpt} is unchanged)" in capsys.readouterr().err
    assert not other.exists() and _snapshot(out) == before


def test_per_clip_runs_are_all_written_or_none(clips, tmp_path, monkeypatch, capsys):
    """The second clip's run fails at once: the first clip's finished run is not left
    behind (the runs take their folders together at the end)."""
    out = tmp_path / "per"
    real, calls = Trainer.step, {"n": 0}

    def step(self):
        losses = real(self)
        calls["n"] += 1
        if self.data.names == ["b"]:
            losses[self.block_levels[-1]]["rec"] = torch.tensor(float("nan"))
        return losses

    monkeypatch.setattr(Trainer, "step", step)
    argv = ["train", *map(str, clips), *TRAIN, "--iterations", "1", "--per-clip"]
    assert main([*argv, "--out", str(out)]) == 1
    assert "is not finite" in capsys.readouterr().err
    assert not out.exists()
    monkeypatch.setattr(Trainer, "step", real)
    assert main([*argv, "--out", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["a", "b"] and not _temporaries(out)
    assert all(sorted(p.name for p in (out / k).iterdir()) == sorted(
        ["checkpoint.pt", "checkpoint.pt.json", "losses.csv"]) for k in "ab")  # fmt: skip
