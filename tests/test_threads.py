"""The thread policy (``mrlib.threads``) and ``--threads`` on the command line.

Nothing here measures time: the speed the policy buys is measured by
``bench/busy_machine.py``; these tests check which count it picks and that every
command takes and applies ``--threads``."""

from __future__ import annotations

import pytest
import torch

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
    assert threads.apply_policy() == expected
    assert torch.get_num_threads() == expected


def test_an_explicit_count_wins_over_everything(monkeypatch):
    _started_with(monkeypatch, 2, 2)
    monkeypatch.setenv("OMP_NUM_THREADS", "2")
    assert threads.apply_policy(3) == 3
    assert torch.get_num_threads() == 3
    assert threads.apply_policy() == 3  # and stays the count for later calls


@pytest.mark.parametrize("name", threads.ENV_VARS)
def test_a_count_from_the_environment_is_kept(monkeypatch, name):
    _started_with(monkeypatch, 2, 2)
    monkeypatch.setenv(name, "2")
    assert threads.apply_policy() == 2
    assert torch.get_num_threads() == 2


@pytest.mark.parametrize("value", ["", "0", "abc", "-1"])
def test_an_empty_or_invalid_environment_value_is_not_a_choice(monkeypatch, value):
    _started_with(monkeypatch, 2, 2)
    monkeypatch.setenv("OMP_NUM_THREADS", value)
    assert threads.apply_policy() == 1


def test_a_count_the_user_set_after_import_is_kept(monkeypatch):
    _started_with(monkeypatch, 2, 2)
    torch.set_num_threads(3)  # the user's own call
    assert threads.apply_policy() == 3
    assert torch.get_num_threads() == 3


def test_a_count_the_user_set_after_mrlibs_default_is_kept(monkeypatch):
    _started_with(monkeypatch, 2, 2)
    assert threads.apply_policy() == 1
    assert threads.apply_policy() == 1  # mrlib's own default, applied again
    torch.set_num_threads(2)  # the user changes it afterwards
    assert threads.apply_policy() == 2


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
    assert threads.apply_policy() == 1  # the explicit count of the block did not stick


def test_library_entry_points_run_under_the_policy(monkeypatch):
    from mrlib.evaluation.evaluate import evaluate_model
    from mrlib.sampling.cleanup import cleanup_foot_contacts
    from mrlib.sampling.generation import generate
    from mrlib.training.trainer import Trainer

    for fn in (generate, evaluate_model, cleanup_foot_contacts, Trainer.fit):
        assert getattr(fn, "__wrapped__", None) is not None, fn.__qualname__
    _started_with(monkeypatch, 2, 2)
    seen = threads.with_policy(torch.get_num_threads)()
    assert seen == 1 and torch.get_num_threads() == 2


@pytest.mark.parametrize("bad", [0, -2, 1.5, "2", True])
def test_a_bad_explicit_count_is_an_error(bad):
    with pytest.raises(MrlibError, match="positive integer"):
        threads.apply_policy(bad)


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
class _Scripted:
    """A clock, the machine's busy CPU seconds and this process's CPU seconds, advanced
    by hand: ``others`` CPUs kept busy by other processes over each step of ``dt``."""

    def __init__(self):
        self.t = self.busy = self.own = 0.0

    def advance(self, dt: float, others: float, own: float = 1.0) -> None:
        self.t += dt
        self.own += own * dt
        self.busy += (others + own) * dt


def _follower(
    monkeypatch, cpus: int, start_others: float
) -> tuple[threads.LoadFollower, _Scripted]:
    s = _Scripted()
    monkeypatch.setattr(threads, "usable_cpus", lambda: cpus)
    monkeypatch.setattr(threads, "_START", cpus)  # torch started with one per CPU
    monkeypatch.setattr(threads, "_busy_cpu_seconds", lambda: s.busy)
    monkeypatch.setattr("time.monotonic", lambda: s.t)
    monkeypatch.setattr("time.process_time", lambda: s.own)
    monkeypatch.setattr("time.sleep", lambda dt: s.advance(dt, start_others, own=0.0))
    return threads.LoadFollower(interval=2.0, patience=2), s


def test_the_follower_starts_from_what_other_processes_leave(monkeypatch):
    idle, _ = _follower(monkeypatch, cpus=2, start_others=0.05)
    assert idle.threads == 2 and torch.get_num_threads() == 2
    busy, _ = _follower(monkeypatch, cpus=2, start_others=1.0)
    assert busy.threads == 1 and torch.get_num_threads() == 1
    assert threads.user_threads() is None  # its own count is not taken for the user's


def test_the_follower_steps_down_at_once_and_up_after_calm_checks(monkeypatch):
    f, s = _follower(monkeypatch, cpus=2, start_others=0.0)
    assert f.threads == 2
    s.advance(1.0, others=1.0)
    assert f.tick() == 2  # within the interval: nothing read
    s.advance(1.5, others=1.0, own=1.0)
    assert f.tick() == 1 and torch.get_num_threads() == 1  # a busy neighbour: down at once
    s.advance(2.5, others=1.0)
    assert f.tick() == 1
    s.advance(2.5, others=0.1)
    assert f.tick() == 1  # one calm check is not enough
    s.advance(2.5, others=0.1)
    assert f.tick() == 2 and torch.get_num_threads() == 2
    s.advance(2.5, others=0.4)  # background noise under half a core keeps the count
    assert f.tick() == 2
    assert [n for _, _, n in f.history] == [1, 1, 1, 2, 2]


def test_no_follower_where_the_user_chose_the_count(monkeypatch):
    monkeypatch.setattr(threads, "usable_cpus", lambda: 2)
    threads.apply_policy(2)  # --threads 2
    assert threads.load_follower() is None
    monkeypatch.setattr(threads, "_state", threads._State())
    monkeypatch.setenv("OMP_NUM_THREADS", "1")
    assert threads.load_follower() is None
    monkeypatch.delenv("OMP_NUM_THREADS")
    monkeypatch.setattr(threads, "usable_cpus", lambda: 1)
    assert threads.load_follower() is None  # one CPU: nothing to follow


def test_training_does_not_depend_on_the_thread_count_here(tmp_path):
    """What lets the follower change the count mid-run: on this build, training at one
    thread, at two and alternating gives the same weights (if a build breaks this, runs
    depend on the load, and ``--threads N`` is the way to fixed results)."""
    from mrlib.datasets.synthetic import synthetic_walk
    from mrlib.model.config import ModelConfig, TrainConfig
    from mrlib.training.data import TrainingSet
    from mrlib.training.trainer import Trainer

    data = TrainingSet.from_motions(
        [synthetic_walk(lab, seconds=2.0, fps=15.0) for lab in ("walk_sad", "walk_happy")]
    )
    cfg = TrainConfig(model=ModelConfig(num_levels=4, gen_hidden=(32, 64), disc_hidden=(32,)),
                      block_iterations=(3, 3), n_critic=1, checkpoint_every=0)  # fmt: skip

    def run(schedule: list[int]) -> dict[str, torch.Tensor]:
        tr, k = Trainer(data, cfg, tmp_path / "-".join(map(str, schedule))), 0
        for b in range(2):
            tr.block = b
            tr.start_block()
            for _ in range(3):
                torch.set_num_threads(schedule[k % len(schedule)])
                k += 1
                tr.step()
        return {n: p.detach().clone() for n, p in tr.generator.named_parameters()}

    one, two, mixed = run([1]), run([2]), run([1, 2, 2])
    assert all(torch.equal(one[k], two[k]) and torch.equal(one[k], mixed[k]) for k in one)


def test_a_raise_taken_back_at_once_makes_the_next_one_wait_longer(monkeypatch):
    """A neighbour working in bursts: each raise it takes back within two checks doubles
    the calm checks the next raise needs, so the count does not flap."""
    f, s = _follower(monkeypatch, cpus=2, start_others=1.0)
    assert f.threads == 1 and f.patience == 2

    def check(others: float) -> int:
        s.advance(2.5, others=others)
        return f.tick()

    assert [check(0.0), check(0.0)] == [1, 2]  # raised after two calm checks
    assert check(1.0) == 1 and f.patience == 4  # taken back at once: wait twice as long
    assert [check(0.0) for _ in range(4)] == [1, 1, 1, 2]
    assert check(1.0) == 1 and f.patience == 8
    assert [check(0.0) for _ in range(8)][-2:] == [1, 2]
    assert [check(0.1) for _ in range(10)][-1] == 2 and f.patience == 2  # held: reset


def test_a_short_run_keeps_the_policys_count(monkeypatch, tmp_path):
    """Runs shorter than MIN_FOLLOW_ITERATIONS (tests, smoke runs) make no probe."""
    from mrlib.datasets.synthetic import synthetic_walk
    from mrlib.model.config import ModelConfig, TrainConfig
    from mrlib.training.data import TrainingSet
    from mrlib.training.trainer import train

    made = []
    monkeypatch.setattr(threads, "LoadFollower", lambda **kw: made.append(kw))
    data = TrainingSet.from_motions([synthetic_walk("walk_sad", seconds=2.0, fps=10.0)])
    cfg = TrainConfig(model=ModelConfig(num_levels=2, gen_hidden=(8,), disc_hidden=(8,)),
                      block_iterations=(2,), n_critic=1, checkpoint_every=0)  # fmt: skip
    train(data, cfg, tmp_path, progress=False)
    assert made == []
    assert threads.MIN_FOLLOW_ITERATIONS > 2
