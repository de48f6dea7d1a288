"""Output paths from file contents stay under --out; errors reach the user as one line."""

from __future__ import annotations

import os

import pytest

from mrlib.app.cli import main
from mrlib.datasets.synthetic import synthetic_walk
from mrlib.io import save_motion
from mrlib.io.paths import UnsafePathError, inside, safe_component, unique_components

HOSTILE = [
    "/tmp/absolute/evil",
    "../../escape",
    "a/b\\c",
    "nul\x00byte",
    "x" * 300,
    "..",
    ".",
    "",
    "C:\\windows\\evil",
    "~/home",
]


@pytest.mark.parametrize("name", HOSTILE)
def test_safe_component_is_one_plain_component(name, tmp_path):
    c = safe_component(name)
    assert c and "/" not in c and "\\" not in c and "\x00" not in c
    assert not c.startswith(".") and len(c) <= 100
    assert inside(tmp_path, tmp_path / c).parent == tmp_path


def test_distinct_names_stay_distinct_and_repeats_get_numbers():
    names = ["take", "take", "Take", "a/b", "a_b", "a:b"]
    out = unique_components(names)
    assert len({n.lower() for n in out}) == len(names)
    assert out[:3] == ["take", "take-2", "Take-3"]


def test_inside_refuses_paths_outside_the_root(tmp_path):
    with pytest.raises(UnsafePathError, match="outside the output folder"):
        inside(tmp_path / "out", tmp_path / "out" / ".." / "x")
    link = tmp_path / "out" / "link"
    (tmp_path / "out").mkdir()
    os.symlink(tmp_path, link)
    with pytest.raises(UnsafePathError):
        inside(tmp_path / "out", link / "x")


def _clip(path, name, label, seed=0):
    m = synthetic_walk("walk_sad", seconds=2.4, fps=10.0, seed=seed)
    save_motion(m.replace(name=name, label=label), path)
    return path


def _files(root):
    return {p for p in root.rglob("*") if p.is_file()}


@pytest.mark.slow
def test_per_clip_training_writes_only_under_out_with_distinct_folders(tmp_path):
    """Hostile clip names (absolute, ../, a repeat) give sanitised, distinct folders."""
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    clips = [
        _clip(tmp_path / "a" / "take.npz", str(tmp_path / "abs_target"), "walk"),
        _clip(tmp_path / "b" / "take.npz", "../../escape", "walk", seed=1),
        _clip(tmp_path / "b" / "same.npz", "../../escape", "walk", seed=2),
    ]
    out = tmp_path / "o" / "pc"
    before = _files(tmp_path)
    args = ["train", *map(str, clips), "--per-clip", "--iterations", "1", "--levels", "2"]
    assert main(args + ["--no-progress", "--out", str(out)]) == 0
    new = _files(tmp_path) - before
    assert new and all(out in p.parents for p in new), sorted(new)
    folders = sorted(p.name for p in out.iterdir())
    assert len(folders) == 3 and all((out / f / "checkpoint.pt").is_file() for f in folders)
    assert not (tmp_path / "abs_target").exists() and not (tmp_path / "escape").exists()


@pytest.mark.slow
@pytest.mark.parametrize("label", ["../up", "walk/happy", "/abs", "nul\x00x"])
def test_sample_with_a_hostile_label_writes_under_out(tmp_path, label):
    clip = _clip(tmp_path / "c.npz", "c", label)
    run = tmp_path / "run"
    assert main(["train", str(clip), "--iterations", "1", "--levels", "2", "--no-progress",
                 "--out", str(run)]) == 0  # fmt: skip
    out = tmp_path / "samples"
    before = _files(tmp_path)
    assert main(["sample", str(run / "checkpoint.pt"), "--out", str(out)]) == 0
    new = _files(tmp_path) - before
    assert len(new) == 2 and all(p.parent == out for p in new), sorted(new)


@pytest.mark.parametrize(
    "argv, message",
    [
        (["sample", "missing.pt"], "no such checkpoint file"),
        (["info", "missing.bvh"], "missing.bvh"),
        (["export", "{wave}", "/proc/mrlib-test/x.bvh"], "/proc/mrlib-test"),
        (["export", "{wave}", "{tmp}/no/such/dir/x.bvh"], "no/such/dir"),
    ],
)
def test_cli_errors_are_one_line_without_a_traceback(argv, message, tmp_path, capsys):
    from mrlib.app.demo import DATA_SAMPLES

    argv = [a.format(wave=DATA_SAMPLES / "wave.npz", tmp=tmp_path) for a in argv]
    assert main(argv) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and message in err and "Traceback" not in err
    assert len(err.splitlines()) == 1


def test_cli_debug_shows_the_traceback():
    with pytest.raises(Exception, match="no such checkpoint"):
        main(["--debug", "sample", "missing.pt"])


@pytest.mark.parametrize(
    "argv, message",
    [
        (["sample", "x.pt", "--device", "cuda"], "use --device cpu"),
        (["sample", "x.pt", "--device", "bogus"], "unknown device 'bogus'"),
        (["sample", "x.pt", "--seconds", "nan"], "--seconds"),
        (["sample", "x.pt", "--seconds", "0"], "--seconds"),
        (["sample", "x.pt", "--seconds", "-3"], "--seconds"),
    ],
)
def test_cli_usage_errors_exit_2_and_name_the_flag(argv, message, capsys):
    import torch

    if "cuda" in argv and torch.cuda.is_available():
        pytest.skip("CUDA is available here")
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
    assert message in capsys.readouterr().err


def test_blend_weight_is_checked(tmp_path, capsys):
    clip = _clip(tmp_path / "c.npz", "c", "walk")
    clip2 = _clip(tmp_path / "d.npz", "d", "run", seed=1)
    run = tmp_path / "run"
    assert main(["train", str(clip), str(clip2), "--iterations", "1", "--levels", "2",
                 "--no-progress", "--out", str(run)]) == 0  # fmt: skip
    ckpt = str(run / "checkpoint.pt")
    for w, msg in (("abc", "must be a number"), ("1.5", "must be in [0, 1]")):
        assert main(["sample", ckpt, "--blend", "walk", "run", w, "--out", str(tmp_path)]) == 1
        assert msg in capsys.readouterr().err


@pytest.mark.slow
def test_kill_9_during_training_then_resume_gives_the_uninterrupted_result(tmp_path):
    """One trial of bench/kill_resume.py (which runs 20): SIGKILL mid-training, the
    checkpoint on disk loads, --resume finishes with the uninterrupted run's weights."""
    import signal
    import subprocess
    import sys
    import time

    import torch

    from mrlib.model.checkpoint import load_checkpoint

    clip = _clip(tmp_path / "c.npz", "c", "walk")

    def cmd(out, resume=False):
        base = [sys.executable, "-m", "mrlib.app.cli", "train", "--no-progress", "--out", str(out)]
        if resume:
            return base + ["--resume", str(out / "checkpoint.pt")]
        return base + [str(clip), "--levels", "2", "--iterations", "20", "--seed", "1",
                       "--checkpoint-every", "1"]  # fmt: skip

    t = time.perf_counter()
    subprocess.run(cmd(tmp_path / "ref"), check=True, capture_output=True)
    full = time.perf_counter() - t
    proc = subprocess.Popen(
        cmd(tmp_path / "run"), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    deadline = time.monotonic() + 4 * full
    ckpt = tmp_path / "run" / "checkpoint.pt"
    while not ckpt.exists() and time.monotonic() < deadline:  # wait for the first save
        time.sleep(0.05)
    time.sleep(0.1)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    state = load_checkpoint(ckpt)
    if state["progress"]["done"]:
        pytest.skip("the run finished before the kill; the machine is too fast for this timing")
    subprocess.run(cmd(tmp_path / "run", resume=True), check=True, capture_output=True)
    a = load_checkpoint(tmp_path / "ref" / "checkpoint.pt")
    b = load_checkpoint(ckpt)
    assert b["progress"]["done"]
    assert all(torch.equal(a["generator"][k], b["generator"][k]) for k in a["generator"])


def test_a_file_size_limit_during_a_checkpoint_write_keeps_the_previous_one(tmp_path):
    """A real write failure from the OS (RLIMIT_FSIZE: writes past the limit fail with
    EFBIG, as on a full disk): the old checkpoint stays, the error says so."""
    import subprocess
    import sys
    import textwrap

    script = textwrap.dedent(
        f"""
        import resource, signal, torch
        from mrlib.model.checkpoint import CheckpointError, load_checkpoint, save_checkpoint
        path = save_checkpoint({str(tmp_path / "c.pt")!r}, {{"w": torch.zeros(1000)}})
        before = path.read_bytes()
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # fail the write instead of the process
        resource.setrlimit(resource.RLIMIT_FSIZE, (len(before) + 4096, resource.RLIM_INFINITY))
        try:
            save_checkpoint(path, {{"w": torch.zeros(100_000)}})
        except CheckpointError as e:
            print("ERROR", e)
        assert path.read_bytes() == before
        assert load_checkpoint(path)["w"].shape == (1000,)
        print("KEPT")
        """
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert (
        "ERROR" in out.stdout and "the previous one is kept" in out.stdout and "KEPT" in out.stdout
    )
    assert not any(".tmp" in p.name for p in tmp_path.iterdir())
