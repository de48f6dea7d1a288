"""Outputs never clobber: one atomic writer for every file, sample names built from parts,
a lock per run folder, and nothing written through a symbolic link planted in --out.

The sweep of issue #39's data-loss cases, one table per class: file writers x targets,
sample names, run folders, symbolic links, a filled disk (RLIMIT_FSIZE in a subprocess)
and two concurrent trainings."""

from __future__ import annotations

import ast
import csv
import json
import os
import shutil
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from mrlib.app.cli import main
from mrlib.datasets.synthetic import synthetic_walk
from mrlib.io import load_motion, save_motion
from mrlib.io.outputs import (
    LOCK_NAME,
    OutputError,
    OutputExistsError,
    RunLock,
    RunLockedError,
    atomic_write,
    write_bytes,
)
from mrlib.model.checkpoint import load_checkpoint, save_checkpoint
from mrlib.training.run import RunExistsError, check_run_folder

TRAIN = ["--iterations", "1", "--levels", "2", "--no-progress"]


def _clip(path: Path, label: str, seed: int = 0) -> Path:
    m = synthetic_walk("walk_sad", seconds=2.4, fps=10.0, seed=seed)
    return save_motion(m.replace(name=path.stem, label=label), path)


def _snapshot(root: Path) -> dict[Path, bytes]:
    """Every regular file under ``root`` (links not followed) and its bytes."""
    return {p: p.read_bytes() for p in root.rglob("*") if p.is_file() and not p.is_symlink()}


def _temporaries(root: Path) -> list[Path]:
    return [p for p in root.rglob("*") if ".tmp" in p.name]


@pytest.fixture(scope="module")
def clips(tmp_path_factory) -> list[Path]:
    """Two clips whose labels hold dots (``v1.0``, ``v1.1``: one file each, not ``v1``)."""
    root = tmp_path_factory.mktemp("clips")
    return [_clip(root / "a.npz", "v1.0"), _clip(root / "b.npz", "v1.1", seed=1)]


@pytest.fixture(scope="module")
def run(clips, tmp_path_factory) -> Path:
    """A finished run trained by the CLI (seconds: 2 levels, 1 iteration)."""
    out = tmp_path_factory.mktemp("run") / "run"
    assert main(["train", *map(str, clips), *TRAIN, "--out", str(out)]) == 0
    return out


def _copy_run(run: Path, dst: Path) -> Path:
    shutil.copytree(run, dst)
    return dst


# -- the writer ----------------------------------------------------------------------------
def _write_npz(m, path, overwrite):
    return save_motion(m, path, overwrite=overwrite)


def _write_bvh(m, path, overwrite):
    return save_motion(m, path.with_suffix(".bvh"), overwrite=overwrite)


def _write_checkpoint(m, path, overwrite):
    return save_checkpoint(path, {"x": 1.0}, overwrite=overwrite)


def _write_raw(m, path, overwrite):
    return write_bytes(path, b"new", overwrite=overwrite)


WRITERS = {"npz": _write_npz, "bvh": _write_bvh, "checkpoint": _write_checkpoint, "raw": _write_raw}
SUFFIX = {"npz": ".npz", "bvh": ".bvh", "checkpoint": ".pt", "raw": ".bin"}


@pytest.fixture(scope="module")
def walk():
    return synthetic_walk("walk_sad", seconds=1.0, fps=10.0)


@pytest.mark.parametrize("kind", list(WRITERS))
def test_an_existing_file_is_refused_unless_overwrite(kind, walk, tmp_path):
    path = tmp_path / f"out{SUFFIX[kind]}"
    path.write_bytes(b"old")
    with pytest.raises(OutputExistsError, match="already exists"):
        WRITERS[kind](walk, path, False)
    assert path.read_bytes() == b"old"
    WRITERS[kind](walk, path, True)
    assert path.read_bytes() != b"old" and not _temporaries(tmp_path)


@pytest.mark.parametrize("overwrite", [False, True])
@pytest.mark.parametrize("kind", list(WRITERS))
def test_a_symbolic_link_at_the_target_is_refused_never_followed(kind, overwrite, walk, tmp_path):
    victim = tmp_path / "victim"
    victim.write_bytes(b"precious")
    out = tmp_path / "out"
    out.mkdir()
    link = out / f"x{SUFFIX[kind]}"
    link.symlink_to(victim)
    with pytest.raises(OutputError, match="symbolic link"):
        WRITERS[kind](walk, link, overwrite)
    assert victim.read_bytes() == b"precious" and link.is_symlink()
    assert not _temporaries(tmp_path)


def test_a_dangling_symbolic_link_is_refused_and_creates_nothing(tmp_path):
    link = tmp_path / "x.npz"
    link.symlink_to(tmp_path / "would_be_created")
    with pytest.raises(OutputError, match="symbolic link"):
        write_bytes(link, b"x", overwrite=True)
    assert not (tmp_path / "would_be_created").exists()


def test_a_fifo_at_the_target_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "x.npz"
    os.mkfifo(fifo)
    with pytest.raises(OutputError, match="not a regular file"):
        write_bytes(fifo, b"x", overwrite=True)


def test_a_failed_write_leaves_the_previous_file_and_no_temporary(tmp_path):
    path = write_bytes(tmp_path / "f.bin", b"previous")

    def half_then_fail(fh):
        fh.write(b"half of the new content")
        raise OSError(28, "No space left on device")

    with pytest.raises(OSError, match="No space left"):
        atomic_write(path, half_then_fail, overwrite=True)
    assert path.read_bytes() == b"previous" and not _temporaries(tmp_path)


def test_temporaries_of_dead_writers_are_removed(tmp_path):
    path = tmp_path / "f.bin"
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True).stdout.strip()  # fmt: skip
    stale = tmp_path / f".f.bin.tmp{dead}.abcd"
    stale.write_bytes(b"left by a killed writer")
    write_bytes(path, b"x")
    assert not stale.exists()


# -- sample names ---------------------------------------------------------------------------
def test_sample_num_3_of_a_blend_writes_three_files(run, tmp_path, capsys):
    out = tmp_path / "o"
    argv = ["sample", str(run / "checkpoint.pt"), "--blend", "v1.0", "v1.1", "0.5"]
    assert main([*argv, "--num", "3", "--out", str(out)]) == 0
    names = sorted(p.name for p in out.iterdir())
    assert names == [f"v1.0-v1.1-0.5_seed0_{i}{k}" for i in range(3) for k in (".bvh", ".npz")]
    printed = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("wrote")]
    assert len(printed) == 3 and all(f"-0.5_seed0_{i}.npz" in ln for i, ln in enumerate(printed))
    poses = [load_motion(out / f"v1.0-v1.1-0.5_seed0_{i}.npz").poses for i in range(3)]
    assert not np.array_equal(poses[0], poses[1])  # three samples, not one written thrice


def test_dotted_labels_get_their_own_files(run, tmp_path):
    out = tmp_path / "o"
    for label in ("v1.0", "v1.1"):
        argv = ["sample", str(run / "checkpoint.pt"), "--label", label, "--out", str(out)]
        assert main(argv) == 0
    assert sorted(p.name for p in out.glob("*.npz")) == ["v1.0_seed0_0.npz", "v1.1_seed0_0.npz"]


@pytest.mark.parametrize(
    "tags, expected",
    [
        (["talk.v1", "talk.v2"], ["talk.v1_seed0_0.npz", "talk.v2_seed0_0.npz"]),
        (["a-b-0.25", "a-b-0.5"], ["a-b-0.25_seed0_0.npz", "a-b-0.5_seed0_0.npz"]),
        (["x.npz", "x.bvh"], ["x.bvh_seed0_0.npz", "x.npz_seed0_0.npz"]),
    ],
)
def test_sample_names_are_built_from_parts_not_cut_at_a_dot(tags, expected, tmp_path):
    from argparse import Namespace

    from mrlib.app.cli import _sample_files

    args = Namespace(out=tmp_path, seed=0, render=False, glb=True)
    names = sorted(_sample_files(t, args, 1)[0][".npz"].name for t in tags)
    assert names == expected


def test_a_second_sample_run_is_refused_then_replaces_with_overwrite(run, tmp_path, capsys):
    out = tmp_path / "o"
    base = ["sample", str(run / "checkpoint.pt"), "--label", "v1.0", "--out", str(out)]
    assert main(base) == 0
    before = _snapshot(out)
    capsys.readouterr()
    assert main([*base, "--raw"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and "already exists" in err and "--overwrite" in err
    assert len(err.splitlines()) == 1 and _snapshot(out) == before
    assert main([*base, "--seed", "1"]) == 0  # another seed: other names, nothing replaced
    assert all(_snapshot(out)[p] == b for p, b in before.items())
    assert main([*base, "--raw", "--overwrite"]) == 0
    assert _snapshot(out)[out / "v1.0_seed0_0.npz"] != before[out / "v1.0_seed0_0.npz"]


# -- run folders ----------------------------------------------------------------------------
def test_training_into_a_finished_run_is_refused(run, clips, tmp_path, capsys):
    out = _copy_run(run, tmp_path / "r")
    before = _snapshot(out)
    t = time.perf_counter()
    assert main(["train", *map(str, clips), *TRAIN, "--out", str(out)]) == 1
    assert time.perf_counter() - t < 5  # refused before loading anything
    err = capsys.readouterr().err
    assert "already holds a training run" in err and "--resume" in err and "--overwrite" in err
    assert _snapshot(out) == before


def test_overwrite_replaces_a_run_with_a_fresh_one(run, clips, tmp_path):
    out = _copy_run(run, tmp_path / "r")
    (out / "losses.csv").write_text("stale\n")
    argv = ["train", str(clips[0]), *TRAIN, "--seed", "7", "--out", str(out), "--overwrite"]
    assert main(argv) == 0
    state = load_checkpoint(out / "checkpoint.pt")
    assert state["labels"] == ["v1.0"] and json.loads(state["config"])["seed"] == 7
    rows = (out / "losses.csv").read_text().splitlines()
    assert rows[0].startswith("time_s,") and "stale" not in rows
    assert not (out / LOCK_NAME).exists() and not _temporaries(out)


def test_resume_in_its_own_folder_needs_no_flag(run, tmp_path):
    out = _copy_run(run, tmp_path / "r")
    argv = ["train", "--resume", str(out / "checkpoint.pt"), "--out", str(out), "--no-progress"]
    assert main(argv) == 0
    assert load_checkpoint(out / "checkpoint.pt")["progress"]["done"]


def test_resume_without_out_continues_in_the_checkpoints_folder(run, tmp_path, monkeypatch, capsys):
    out = _copy_run(run, tmp_path / "r")
    monkeypatch.chdir(tmp_path)  # not into ./runs/model, train's default for a new run
    assert main(["train", "--resume", str(out / "checkpoint.pt"), "--no-progress"]) == 0
    assert not (tmp_path / "runs").exists()
    assert "nothing to do" in capsys.readouterr().out  # the run is finished
    # a missing checkpoint is named before any folder's state
    assert main(["train", "--resume", "nosuch.pt", "--out", str(out), "--no-progress"]) == 1
    assert "nosuch.pt: no such checkpoint file" in capsys.readouterr().err


def test_resume_into_a_folder_of_another_run_is_refused(run, clips, tmp_path, capsys):
    other = tmp_path / "other"
    assert main(["train", str(clips[1]), *TRAIN, "--out", str(other)]) == 0
    before = _snapshot(other)
    argv = ["train", "--resume", str(run / "checkpoint.pt"), "--out", str(other), "--no-progress"]
    assert main(argv) == 1
    assert "holds another run" in capsys.readouterr().err
    assert _snapshot(other) == before


def test_resume_of_a_finished_run_into_a_new_folder_writes_it_there(run, tmp_path, capsys):
    new = tmp_path / "new"
    argv = ["train", "--resume", str(run / "checkpoint.pt"), "--out", str(new), "--no-progress"]
    assert main(argv) == 0
    assert f"-> {new / 'checkpoint.pt'}" in capsys.readouterr().out
    a, b = load_checkpoint(run / "checkpoint.pt"), load_checkpoint(new / "checkpoint.pt")
    assert all(np.array_equal(a["generator"][k], b["generator"][k]) for k in a["generator"])
    assert (new / "losses.csv").read_text() == (run / "losses.csv").read_text()


def test_the_api_refuses_too(run, tmp_path):
    out = _copy_run(run, tmp_path / "r")
    with pytest.raises(RunExistsError, match="already holds a training run"):
        check_run_folder(out)
    check_run_folder(out, resume=out / "checkpoint.pt")
    check_run_folder(out, overwrite=True)
    check_run_folder(tmp_path / "empty")


# -- symbolic links planted in --out --------------------------------------------------------
def test_symbolic_links_in_a_training_folder_are_never_followed(clips, tmp_path, capsys):
    victim, elsewhere = tmp_path / "victim", tmp_path / "elsewhere"
    victim.write_bytes(b"precious")
    elsewhere.write_bytes(b"log kept elsewhere")
    out = tmp_path / "t"
    out.mkdir()
    (out / "losses.csv").symlink_to(elsewhere)
    (out / "checkpoint.pt").symlink_to(victim)
    assert main(["train", str(clips[0]), *TRAIN, "--out", str(out)]) == 1
    assert "already holds a training run" in capsys.readouterr().err
    assert main(["train", str(clips[0]), *TRAIN, "--out", str(out), "--overwrite"]) == 0
    assert victim.read_bytes() == b"precious" and elsewhere.read_bytes() == b"log kept elsewhere"
    assert not (out / "losses.csv").is_symlink() and not (out / "checkpoint.pt").is_symlink()
    assert load_checkpoint(out / "checkpoint.pt")["progress"]["done"]


def test_a_symbolic_link_as_the_lock_file_is_refused(clips, tmp_path, capsys):
    victim = tmp_path / "victim"
    victim.write_bytes(b"precious")
    out = tmp_path / "t"
    out.mkdir()
    (out / LOCK_NAME).symlink_to(victim)
    assert main(["train", str(clips[0]), *TRAIN, "--out", str(out)]) == 1
    assert "symbolic link" in capsys.readouterr().err
    assert victim.read_bytes() == b"precious" and not (out / "checkpoint.pt").exists()


@pytest.mark.parametrize("overwrite", [[], ["--overwrite"]])
def test_symbolic_links_in_a_sample_folder_are_never_followed(run, tmp_path, overwrite, capsys):
    victim = tmp_path / "victim"
    victim.write_bytes(b"precious")
    out = tmp_path / "o"
    out.mkdir()
    (out / "v1.0_seed0_0.npz").symlink_to(Path("..") / "victim")
    argv = ["sample", str(run / "checkpoint.pt"), "--label", "v1.0", "--out", str(out)]
    assert main(argv + overwrite) == 1
    err = capsys.readouterr().err  # the link leaves --out (checked first), and is a link
    assert "outside the output folder" in err or "symbolic link" in err
    assert victim.read_bytes() == b"precious"
    assert [p.name for p in out.iterdir()] == ["v1.0_seed0_0.npz"]  # nothing written


# -- the run lock ---------------------------------------------------------------------------
def test_a_held_lock_refuses_a_second_run_naming_the_holder(clips, tmp_path, capsys):
    out = tmp_path / "t"
    with RunLock(out) as lock:
        assert lock.held and (out / LOCK_NAME).is_file()
        with pytest.raises(RunLockedError, match=f"process {os.getpid()}"):
            RunLock(out).acquire()
        assert main(["train", str(clips[0]), *TRAIN, "--out", str(out)]) == 1
        err = capsys.readouterr().err.strip()
        assert err.startswith("error: ") and len(err.splitlines()) == 1
        assert f"another mrlib run is writing here (process {os.getpid()} on" in err
    assert not (out / LOCK_NAME).exists() and not (out / "checkpoint.pt").exists()
    assert main(["train", str(clips[0]), *TRAIN, "--out", str(out)]) == 0


def test_a_lock_left_by_a_dead_process_is_taken_over(clips, tmp_path):
    out = tmp_path / "t"
    out.mkdir()
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True).stdout.strip()  # fmt: skip
    info = {"pid": int(dead), "host": os.uname().nodename, "started": time.time()}
    (out / LOCK_NAME).write_text(json.dumps(info))
    assert main(["train", str(clips[0]), *TRAIN, "--out", str(out)]) == 0


def test_two_concurrent_trainings_into_one_folder_one_succeeds_one_refuses(clips, tmp_path):
    out = tmp_path / "same"
    cmd = [sys.executable, "-m", "mrlib.app.cli", "train", *map(str, clips), "--levels", "2",
           "--iterations", "40", "--no-progress", "--out", str(out)]  # fmt: skip
    procs = [subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for _ in range(2)]  # fmt: skip
    results = [(p.wait(timeout=300), *p.communicate()) for p in procs]
    codes = sorted(r[0] for r in results)
    assert codes == [0, 1], results
    (err,) = [r[2].strip() for r in results if r[0] == 1]
    assert err.startswith("error: ") and len(err.splitlines()) == 1, err
    assert "another mrlib run is writing here" in err or "already holds a training run" in err
    state = load_checkpoint(out / "checkpoint.pt")
    assert state["progress"]["done"]
    with open(out / "losses.csv") as fh:  # one run's log: no row twice, none out of order
        rows = [(int(r["iteration"]), int(r["level"])) for r in csv.DictReader(fh)]
    assert rows and rows == sorted(set(rows)) and rows[-1] == (40, 2), rows
    assert not (out / LOCK_NAME).exists() and not _temporaries(out)


# -- a filled disk --------------------------------------------------------------------------
def test_a_filled_disk_leaves_every_previous_file_byte_identical(run, clips, tmp_path):
    """RLIMIT_FSIZE (writes past the limit fail with EFBIG, as on a full disk) in a
    subprocess: export over an existing .npz, .bvh and .glb and sample over its files
    with --overwrite; each fails with one error line and changes nothing."""
    old = {}
    for ext in (".npz", ".bvh", ".glb"):
        path = tmp_path / f"dst{ext}"
        path.write_bytes(b"previous " + ext.encode())
        old[path] = path.read_bytes()
    samples = tmp_path / "samples"
    samples.mkdir()
    for ext in (".npz", ".bvh"):
        path = samples / f"v1.0_seed0_0{ext}"
        path.write_bytes(b"previous sample")
        old[path] = path.read_bytes()
    runs = [["export", str(clips[0]), str(p), "--overwrite"] for p in old if p.parent == tmp_path]
    runs.append(["sample", str(run / "checkpoint.pt"), "--label", "v1.0", "--overwrite",
                 "--out", str(samples)])  # fmt: skip
    script = textwrap.dedent(
        f"""
        import contextlib, io, resource
        from mrlib.app.cli import main
        resource.setrlimit(resource.RLIMIT_FSIZE, (2048, resource.RLIM_INFINITY))
        for argv in {runs!r}:
            err = io.StringIO()
            with contextlib.redirect_stderr(err):
                code = main(argv)
            print(code, repr(err.getvalue()))
        """
    )
    res = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    lines = res.stdout.strip().splitlines()
    assert len(lines) == len(runs), res.stdout
    for line in lines:
        code, err = line.split(" ", 1)
        err = ast.literal_eval(err)  # the repr printed above
        assert code == "1" and err.startswith("error: ") and len(err.splitlines()) == 1, line
        assert "Traceback" not in err and ("too large" in err or "limit" in err), line
    assert all(p.read_bytes() == b for p, b in old.items())
    assert not _temporaries(tmp_path)


# -- reading: what is not a regular file is named as such ----------------------------------
@pytest.mark.parametrize(
    "make, message",
    [
        (lambda p: os.mkfifo(p), "is a named pipe (FIFO), not a regular file"),
        (lambda p: p.symlink_to(p.parent / "gone.npz"), "is a broken symbolic link"),
        (lambda p: None, "no such file"),
    ],
)
def test_reading_a_fifo_or_a_broken_link_says_what_it_is(make, message, tmp_path, capsys):
    path = tmp_path / "clip.npz"
    make(path)
    assert main(["info", str(path)]) == 1
    err = capsys.readouterr().err.strip()
    assert err == f"error: {path}: {message}" or err.startswith(f"error: {path}: {message}")
