"""The thread policy (``mrlib.threads``) and ``--threads`` on the command line.

Nothing here measures time: the speed the policy buys is measured by
``bench/busy_machine.py``; these tests check which count it picks and that every
command takes and applies ``--threads``."""

from __future__ import annotations

import pytest
import torch

import mrlib.training.trainer
from mrlib import threads
from mrlib.app.cli import build_parser, main
from mrlib.errors import MrlibError


@pytest.fixture(autouse=True)
def fresh_policy(monkeypatch):
    """No environment choice, mrlib has set nothing yet, torch started with the count it
    has now; the policy's state and torch's count are restored afterwards."""
    for name in threads.ENV_VARS:
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setattr(threads, "_state", threads._State())
    monkeypatch.setattr(threads, "_START", torch.get_num_threads())
    before = torch.get_num_threads()
    yield
    torch.set_num_threads(before)


def _started_with(monkeypatch, n: int, cpus: int) -> None:
    """As if torch had started with ``n`` threads on a machine of ``cpus`` usable CPUs."""
    torch.set_num_threads(n)
    monkeypatch.setattr(threads, "_START", n)
    monkeypatch.setattr(threads, "usable_cpus", lambda: cpus)


@pytest.mark.parametrize("cpus, start, expected", [(2, 2, 1), (1, 1, 1), (8, 4, 4), (8, 8, 4)])
def test_the_default_is_half_the_usable_cpus_at_most_torchs_own(monkeypatch, cpus, start, expected):
    _started_with(monkeypatch, start, cpus)
    assert threads.default_threads() == expected
    assert threads.use() == expected
    assert torch.get_num_threads() == expected


def test_an_explicit_count_wins_over_everything(monkeypatch):
    _started_with(monkeypatch, 2, 2)
    monkeypatch.setenv("OMP_NUM_THREADS", "2")
    assert threads.use(3) == 3
    assert torch.get_num_threads() == 3
    assert threads.use() == 3  # and stays the count for later calls


@pytest.mark.parametrize("name", threads.ENV_VARS)
def test_a_count_from_the_environment_is_kept(monkeypatch, name):
    _started_with(monkeypatch, 2, 2)
    monkeypatch.setenv(name, "2")
    assert threads.use() == 2
    assert torch.get_num_threads() == 2


@pytest.mark.parametrize("value", ["", "0", "abc", "-1"])
def test_an_empty_or_invalid_environment_value_is_not_a_choice(monkeypatch, value):
    _started_with(monkeypatch, 2, 2)
    monkeypatch.setenv("OMP_NUM_THREADS", value)
    assert threads.use() == 1


def test_a_count_the_user_set_after_import_is_kept(monkeypatch):
    _started_with(monkeypatch, 2, 2)
    torch.set_num_threads(3)  # the user's own call
    assert threads.use() == 3
    assert torch.get_num_threads() == 3


def test_a_count_the_user_set_after_mrlibs_default_is_kept(monkeypatch):
    _started_with(monkeypatch, 2, 2)
    assert threads.use() == 1
    assert threads.use() == 1  # mrlib's own default, applied again
    torch.set_num_threads(2)  # the user changes it afterwards
    assert threads.use() == 2


def test_the_policy_block_restores_the_previous_count(monkeypatch):
    _started_with(monkeypatch, 2, 2)
    with threads.policy() as n:
        assert n == torch.get_num_threads() == 1
        with threads.policy() as inner:  # nested library calls agree
            assert inner == 1
        assert torch.get_num_threads() == 1
    assert torch.get_num_threads() == 2
    with threads.policy(3):
        assert torch.get_num_threads() == 3
    assert torch.get_num_threads() == 2
    assert threads.use() == 1  # the explicit count of the block did not stick


# a worker process mrlib starts itself (train_cached_many) may set its own count
WORKER_PROCESSES = {("training/trainer.py", "_train_cached_in_worker")}


def test_only_the_command_line_and_use_set_the_count():
    """``torch.set_num_threads`` is called in ``mrlib.threads`` alone, and what sets a
    count there (``use``, ``policy``, a decorator) is used only by the command line
    (``mrlib.app``): no library function changes the count of the caller's process."""
    import ast
    from pathlib import Path

    root = Path(threads.__file__).resolve().parent
    setters = {"use", "policy", "apply_policy", "with_policy"}
    found = []
    for path in root.rglob("*.py"):
        rel = path.relative_to(root).as_posix()
        if rel == "threads.py" or rel.startswith("app/"):
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        from_threads = {
            a.asname or a.name
            for n in ast.walk(tree)
            if isinstance(n, ast.ImportFrom) and n.module == "mrlib.threads"
            for a in n.names
            if a.name in setters
        }
        workers = [
            n for n in ast.walk(tree)
            if isinstance(n, ast.FunctionDef) and (rel, n.name) in WORKER_PROCESSES
        ]  # fmt: skip
        allowed = {id(x) for w in workers for x in ast.walk(w)}
        for node in ast.walk(tree):
            if id(node) in allowed:
                continue
            if isinstance(node, ast.Attribute) and (
                node.attr == "set_num_threads"
                or (node.attr in setters and getattr(node.value, "id", None) == "threads")
            ):
                found.append(f"{rel}:{node.lineno} {node.attr}")
            elif isinstance(node, ast.Name) and node.id in from_threads:
                found.append(f"{rel}:{node.lineno} {node.id}")
    assert not found, found


def test_library_calls_keep_the_callers_count(monkeypatch, tmp_path):
    """A clean-up and a short training run from Python run on the caller's count and
    leave it as it was (here 2, where mrlib's default would be 1)."""
    from mrlib.datasets.synthetic import synthetic_walk
    from mrlib.representation.contacts import foot_contacts
    from mrlib.sampling.cleanup import cleanup_foot_contacts
    from mrlib.training.trainer import train

    _started_with(monkeypatch, 2, 2)
    calls = []
    real = torch.set_num_threads
    monkeypatch.setattr(torch, "set_num_threads", lambda n: (calls.append(n), real(n)))
    walk = synthetic_walk("walk_happy", seconds=2.0, fps=15.0)
    cleanup_foot_contacts(walk.replace(contacts=foot_contacts(walk)))
    data, cfg = _tiny_run()
    seen = []
    train(data, cfg.replace(block_iterations=(1, 1)), tmp_path, progress=False,
          callback=lambda tr, losses: seen.append(torch.get_num_threads()))  # fmt: skip
    assert calls == [] and set(seen) == {2}


@pytest.mark.parametrize("bad", [0, -2, 1.5, "2", True])
def test_a_bad_explicit_count_is_an_error(bad):
    with pytest.raises(MrlibError, match="positive integer"):
        threads.use(bad)


def test_usable_cpus_is_at_least_one():
    assert threads.usable_cpus() >= 1


# -- the command line -------------------------------------------------------------------------
def _commands():
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    return sub.choices


def test_every_command_takes_threads():
    for name, command in _commands().items():
        option = [a for a in command._actions if "--threads" in a.option_strings]
        assert len(option) == 1, name
        assert option[0].default is None and option[0].type("3") == 3, name


def test_the_command_runs_with_the_threads_given(monkeypatch, tmp_path):
    import mrlib.app.cli

    _started_with(monkeypatch, 2, 2)
    seen = []
    monkeypatch.setattr(
        mrlib.app.cli, "_cmd_info", lambda args: seen.append(torch.get_num_threads())
    )
    assert main(["info", str(tmp_path / "x.npz"), "--threads", "3"]) == 0
    assert main(["info", str(tmp_path / "x.npz")]) == 0
    assert seen == [3, 1]
    assert torch.get_num_threads() == 2  # the caller's count is back afterwards


@pytest.mark.parametrize("value", ["0", "-1", "two", "1.5", ""])
def test_a_bad_threads_value_is_a_one_line_usage_error(capsys, value):
    with pytest.raises(SystemExit) as e:
        main(["info", "clip.npz", "--threads", value])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    errors = [line for line in err.splitlines() if "error:" in line]
    assert len(errors) == 1 and "--threads" in errors[0], err


# -- following the load during training -----------------------------------------------------
# -- a training run's count: fixed at its start, recorded, reused on resume ------------------
def _tiny_run():
    from mrlib.datasets.synthetic import synthetic_walk
    from mrlib.model.config import ModelConfig, TrainConfig
    from mrlib.training.data import TrainingSet

    data = TrainingSet.from_motions(
        [synthetic_walk(lab, seconds=2.0, fps=10.0) for lab in ("walk_sad", "walk_happy")]
    )
    cfg = TrainConfig(model=ModelConfig(num_levels=4, gen_hidden=(16,), disc_hidden=(16,)),
                      block_iterations=(4, 4), n_critic=1, checkpoint_every=0)  # fmt: skip
    return data, cfg


def _weights(path) -> dict[str, torch.Tensor]:
    from mrlib.model.checkpoint import load_checkpoint

    state = load_checkpoint(path)
    return {f"{n}.{k}": v for n in ("generator", "critics") for k, v in state[n].items()}


def test_a_run_records_its_count_and_the_command_line_resumes_on_it(monkeypatch, tmp_path):
    """A run from Python keeps the caller's count (here 2, set with ``use``) through every
    iteration and writes it into the checkpoint; ``mrlib train --resume`` without
    --threads takes it back even where the default would now be another."""
    from mrlib.model.checkpoint import load_checkpoint
    from mrlib.training.trainer import train

    _started_with(monkeypatch, 4, cpus=4)
    threads.use(2)
    data, cfg = _tiny_run()
    seen = []

    def stop_in_block_2(trainer, losses):
        seen.append(torch.get_num_threads())
        if (trainer.block, trainer.iteration) == (1, 2):
            raise KeyboardInterrupt

    part = train(data, cfg, tmp_path, progress=False, callback=stop_in_block_2)
    assert part.interrupted and set(seen) == {2} and len(seen) == 6
    assert load_checkpoint(part.checkpoint)["threads"] == 2

    monkeypatch.setattr(threads, "_state", threads._State())
    _started_with(monkeypatch, 3, cpus=8)  # another machine: its default would be 3
    counts = []
    real_fit = mrlib.training.trainer.Trainer.fit

    def fit(self, *a, **k):
        counts.append(torch.get_num_threads())
        return real_fit(self, *a, **k)

    monkeypatch.setattr(mrlib.training.trainer.Trainer, "fit", fit)
    assert main(["train", "--resume", str(part.checkpoint), "--out", str(tmp_path),
                 "--no-progress"]) == 0  # fmt: skip
    assert counts == [2] and load_checkpoint(part.checkpoint)["threads"] == 2
    assert torch.get_num_threads() == 3  # the command restored the caller's count


def test_resuming_on_another_count_than_the_run_began_with_warns(monkeypatch, tmp_path):
    from mrlib.training.trainer import train

    _started_with(monkeypatch, 2, cpus=2)
    data, cfg = _tiny_run()
    cfg = cfg.replace(block_iterations=(2, 2))

    def stop(trainer, losses):
        if (trainer.block, trainer.iteration) == (0, 1):
            raise KeyboardInterrupt

    threads.use(1)
    part = train(data, cfg, tmp_path, progress=False, callback=stop)
    threads.use(2)
    with pytest.warns(RuntimeWarning, match="started with 1 torch threads and continues with 2"):
        train(None, None, tmp_path, resume=part.checkpoint, progress=False)


_HOG = "import os\np = os.getppid()\nwhile os.getppid() == p:\n    pass"  # ends with its parent


def test_the_same_seed_gives_the_same_weights_beside_a_cpu_hog(monkeypatch, tmp_path):
    """Same seed, same machine, mrlib's own thread count: bit-identical weights whether
    the machine is idle or every CPU also runs a busy loop. The paired contrast (another
    seed) shows the comparison can tell two models apart."""
    import subprocess
    import sys

    from mrlib.training.trainer import train

    cpus = threads.usable_cpus()
    _started_with(monkeypatch, cpus, cpus=cpus)  # torch's own start: one per CPU
    threads.use()  # mrlib's default count, as a script or notebook sets it
    data, cfg = _tiny_run()
    seen = {"alone": set(), "busy": set()}

    def run(name: str):
        return train(data, cfg, tmp_path / name, progress=False,
                     callback=lambda tr, losses: seen[name].add(torch.get_num_threads()))  # fmt: skip

    alone = run("alone")
    hogs = [subprocess.Popen([sys.executable, "-c", _HOG]) for _ in range(cpus)]
    try:
        busy = run("busy")
    finally:
        for h in hogs:
            h.kill()
            h.wait()
    other = train(data, cfg.replace(seed=cfg.seed + 1), tmp_path / "other", progress=False)
    a, b, c = _weights(alone.checkpoint), _weights(busy.checkpoint), _weights(other.checkpoint)
    assert seen["alone"] == seen["busy"] == {threads.default_threads()}
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)
    assert not all(torch.equal(a[k], c[k]) for k in a)
