"""Every output file goes through ``mrlib.io.outputs`` (issue #39): a source check.

A direct write (``open(..., "w")``, ``Path.write_text``, ``savefig(path)``,
``np.savez(path)``, ``imageio`` to a path, ``torch.save(path)``, a rename) anywhere in
``mrlib/`` outside the writer module is a file that can be truncated by a full disk,
written through a symbolic link or silently clobbered. Each remaining match is listed
below with the reason it is not such a write; a new one fails this test until it goes
through ``atomic_write``/``write_text``/``write_bytes`` (or is listed with a reason).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1] / "mrlib"

# the modules that implement the writer: the only places allowed to write directly
WRITER_MODULES = {"io/outputs.py", "io/transaction.py"}

WRITE_CALL = re.compile(
    r"open\(|\.write_text\(|\.write_bytes\(|savefig\(|imwrite\(|mimsave\(|mimwrite\("
    r"|np\.savez|np\.save\(|torch\.save\(|\.save\(str\(|\.tofile\(|os\.replace\("
    r"|os\.rename\(|\.rename\(|shutil\.(copy|move)"
)

# (file under mrlib/, text on the matching line) -> why it is not a direct output write
ALLOWED: dict[tuple[str, str], str] = {
    ("viz/widget_kit.py", 'fig.savefig(png, format="png", bbox_inches="tight")'): (
        "into memory (a BytesIO): a view's still picture"
    ),
    (
        "datasets/fetching.py",
        'with open(output_file, "wb") as fh:',
    ): "pooch's own temporary download file, which pooch checks (SHA-256) and renames",
    (
        "model/checkpoint.py",
        "atomic_write(path, lambda fh: torch.save(state, fh)",
    ): "torch.save into the atomic writer's temporary file object",
    (
        "io/npz.py",
        "atomic_write(path, lambda f: np.savez(f, **out)",
    ): "np.savez into the atomic writer's temporary file object",
    ("io/npz.py", 'with open(path, "rb") as f:'): "reads the first bytes of the file to load",
    ("model/checkpoint.py", 'with open(path, "rb") as fh:'): "reads a checkpoint's first bytes",
    ("io/npz.py", "# a file object: np.savez would append"): "a comment",
    ("io/npz.py", "with z.zip.open(member) as fh:"): "reads an archive member",
    (
        "sampling/constraints/keyframe_files.py",
        "lambda fh: np.savez(fh, **arrays)",
    ): "np.savez into the atomic writer's temporary file object",
    (
        "sampling/constraints/keyframe_files.py",
        "with z.open(member) as fh:",
    ): "reads a keyframe file's array member",
    (
        "sampling/constraints/keyframe_files.py",
        "# a file object: np.savez would append",
    ): "a comment",
    (
        "viz/plots.py",
        "lambda fh: fig.savefig(fh, format=fmt, **kwargs)",
    ): "savefig into the atomic writer's temporary file object (save_figure)",
    (
        "viz/meshes.py",
        'frames_or_animation.save(str(scratch), writer="pillow"',
    ): "matplotlib's pillow writer needs a file name: a private temporary folder, "
    "published with write_bytes",
    (
        "viz/meshes.py",
        'iio.imwrite("<bytes>", images, extension=".gif"',
    ): "encodes to bytes in memory, written with write_bytes",
    (
        "viz/player.py",
        'iio.imwrite("<bytes>", picture, extension=".png")',
    ): "encodes to bytes in memory for the notebook display; no file",
    (
        "app/cli/common.py",
        'write_bytes(path, iio.imwrite("<bytes>", image',
    ): "encodes to bytes in memory, written with write_bytes",
    ("threads.py", 'open("/sys/fs/cgroup/cpu.max").read()'): "reads the CPU quota",
    ("training/monitor.py", 'with open(source, newline="") as fh:'): "reads a loss log",
    ("training/run.py", 'with open(log, newline="") as fh:'): "reads a loss log",
    (
        "training/run.py",
        "f.rename(keep / f.name)",
    ): "moves the run's own earlier files aside inside the locked run folder "
    "(an --overwrite of a finished run); nothing is written",
    (
        "representation/smpl_files.py",
        '"numpy arrays (np.savez) or pass the original',
    ): "an error message",
    ("representation/smpl_files.py", 'with open(path, "rb") as fh:'): "reads a .pkl",
}


def _matches() -> list[tuple[str, int, str]]:
    hits = []
    for path in sorted(ROOT.rglob("*.py")):
        rel = path.relative_to(ROOT).as_posix()
        if rel in WRITER_MODULES:
            continue
        for no, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if WRITE_CALL.search(line):
                hits.append((rel, no, line.strip()))
    return hits


def _allowed(rel: str, line: str) -> bool:
    return any(rel == f and text in line for f, text in ALLOWED)


def test_no_direct_writes_outside_the_writer():
    bad = [f"mrlib/{rel}:{no}: {line}" for rel, no, line in _matches() if not _allowed(rel, line)]
    assert not bad, (
        "direct file writes outside mrlib/io/outputs.py (use atomic_write / write_text / "
        "write_bytes, or list the line in ALLOWED with a reason):\n" + "\n".join(bad)
    )


def test_every_allow_list_entry_is_still_needed():
    hits = _matches()
    stale = [
        f"{f}: {text!r}"
        for f, text in ALLOWED
        if not any(rel == f and text in line for rel, _, line in hits)
    ]
    assert not stale, "ALLOWED entries that match nothing any more:\n" + "\n".join(stale)


@pytest.mark.parametrize("reason", list(ALLOWED.values()))
def test_every_entry_has_a_reason(reason):
    assert len(reason) > 8


# -- the writers converted for #39: atomic, never through a link, no-clobber on request --
def _bvh(path, overwrite):
    import numpy as np

    from mrlib.io.bvh import read_bvh, write_bvh
    from mrlib.io.export import smpl_to_bvh
    from mrlib.representation.motion import Motion

    m = Motion(np.zeros((3, 24, 3)), np.zeros((3, 3)), fps=30.0)
    bvh = smpl_to_bvh(m)
    write_bvh(path, bvh, overwrite=overwrite)
    read_bvh(path)


def _joint_map(path, overwrite):
    from mrlib.io.jointmap import SMPL_JOINT_MAP

    SMPL_JOINT_MAP.to_json(path, overwrite=overwrite)


def _keyframes(path, overwrite):
    import numpy as np

    from mrlib.sampling.constraints import Keyframe, load_keyframes, save_keyframes

    save_keyframes(path, [Keyframe(0, np.zeros((24, 3)))], overwrite=overwrite)
    assert len(load_keyframes(path)) == 1


def _evaluation_csv(path, overwrite):
    from mrlib.evaluation.results import EvaluationResult, EvaluationSettings

    r = EvaluationResult(
        [{"method": "ours", "kind": "model", "sequence": "a"}], EvaluationSettings()
    )
    r.to_csv(path, overwrite=overwrite)


def _figure(path, overwrite):
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    from mrlib.viz.plots import save_figure

    fig = Figure(figsize=(1, 1))
    fig.add_subplot().plot([0, 1])
    save_figure(fig, path, overwrite=overwrite)


def _gif(path, overwrite):
    import numpy as np

    from mrlib.viz.meshes import save_gif

    save_gif([np.zeros((4, 4, 3), np.uint8)] * 2, path, fps=5, overwrite=overwrite)


WRITERS = {
    "x.bvh": _bvh,
    "map.json": _joint_map,
    "kf.npz": _keyframes,
    "evaluation.csv": _evaluation_csv,
    "figure.png": _figure,
    "anim.gif": _gif,
}


@pytest.mark.parametrize("name", list(WRITERS))
def test_writer_refuses_a_symlink_and_an_existing_file(name, tmp_path):
    from mrlib.io.outputs import OutputError, OutputExistsError

    write = WRITERS[name]
    victim = tmp_path / "victim"
    victim.write_bytes(b"precious")
    (tmp_path / "out").mkdir()
    link = tmp_path / "out" / name
    link.symlink_to(victim)
    with pytest.raises(OutputError, match="symbolic link"):
        write(link, True)
    assert victim.read_bytes() == b"precious"
    link.unlink()

    write(link, False)  # a fresh name: written
    first = link.read_bytes()
    with pytest.raises(OutputExistsError):
        write(link, False)
    assert link.read_bytes() == first
    write(link, True)  # replaced on request
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [name]  # no temporaries


def test_evaluation_save_refuses_before_writing_any(tmp_path):
    from mrlib.evaluation.results import EvaluationResult, EvaluationSettings
    from mrlib.io.outputs import OutputExistsError

    r = EvaluationResult(
        [{"method": "ours", "kind": "model", "sequence": "a"}], EvaluationSettings()
    )
    (tmp_path / "evaluation.md").write_text("mine")
    with pytest.raises(OutputExistsError):
        r.save(tmp_path, overwrite=False)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["evaluation.md"]
    paths = r.save(tmp_path)
    assert set(paths) == {"csv", "summary_csv", "markdown", "settings"}
    assert (tmp_path / "evaluation.md").read_text().startswith("# Evaluation")


# -- the CLI: an unexpected exception is one line, not a traceback -------------------------
@pytest.mark.parametrize(
    "exc", [RuntimeError("CUDA error: device-side assert\ntriggered"), KeyError("x")]
)
def test_an_unexpected_exception_is_one_line(exc, monkeypatch, capsys, tmp_path):
    import mrlib.app.cli as cli

    def boom(args):
        raise exc

    monkeypatch.setattr(cli, "_cmd_info", boom)
    code = cli.main(["info", str(tmp_path / "x.npz")])
    err = capsys.readouterr().err
    assert code == 1
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith(f"error: info: {type(exc).__name__}: ")
    assert lines[0].endswith("(run with --debug for the traceback)")
    with pytest.raises(type(exc)):
        cli.main(["--debug", "info", str(tmp_path / "x.npz")])


def test_info_write_map_refuses_an_existing_file(tmp_path, capsys):
    from mrlib.app.cli import main

    target = tmp_path / "map.json"
    target.write_text("mine")
    code = main(["info", str(tmp_path / "clip.bvh"), "--write-map", str(target)])
    err = capsys.readouterr().err
    assert code == 1 and "--overwrite" in err and target.read_text() == "mine"
