"""How many threads PyTorch uses for mrlib's CPU work.

mrlib's networks are small: a training iteration or a sample is thousands of short
kernels (convolutions of a few hundred channels over a few hundred frames). Each kernel
that runs on several threads ends on a barrier, and when another process holds one of
the cores the kernel waits for a time slice of the thread that lost its core. PyTorch's
default, one thread per physical core, leaves no core for anything else. Measured on a
2-core x86-64 VM with no GPU (``python bench/busy_machine.py``,
``docs/notes/2026-12-04-threads.md``): beside one CPU-bound process, two threads trained
the ``demo`` preset 4.5-12x slower than on the idle machine, one thread 0.97-1.6x (the
latter with other jobs on the cores too), and foot-contact cleaned samples took 960 ms
instead of 89 on two threads, 101 instead of 100 on one. On the idle machine two threads
were 18-35 % faster per block than one; one thread ran at 0.87x the speed two threads
had before the fused Adam step (``mrlib.training.build.make_adam``) and the masked gradients of
``mrlib.model.networks.SkeletonConv1d``, which made it about 13 % faster.

The policy (:func:`apply_policy`), in order:

1. a count passed explicitly (``mrlib ... --threads N``, ``apply_policy(N)``);
2. the user's own choice: ``OMP_NUM_THREADS`` or ``MKL_NUM_THREADS`` set, or
   ``torch.set_num_threads`` called after mrlib was imported (a count other than the
   one torch started with, or other than the one mrlib last set) -- kept as it is;
3. otherwise :func:`default_threads`: half the CPUs this process may use (at least one,
   at most torch's own starting count), so that as many other busy threads as mrlib
   runs fit beside it. On 2 cores that is one thread; counts above 2 CPUs follow the
   same rule but were not measured here.

During training (``mrlib.training.loop.run_blocks``) a count that is mrlib's own choice
then follows the machine's load (:class:`LoadFollower`): all usable CPUs while other
processes leave them free, fewer as soon as they take one, so an idle machine trains
at two threads' speed and a busy one does not collapse (``python bench/busy_machine.py``:
1.27x slower beside a CPU-bound process than idle, against 3.46x on torch's count;
idle 1.25x the speed of the code before the policy).

The command line applies the policy around each command; ``mrlib.training.trainer.Trainer.fit``,
``mrlib.sampling.generation.generate``, ``mrlib.evaluation.evaluate.evaluate_model``,
``mrlib.sampling.cleanup.cleanup_foot_contacts``, ``mrlib.sampling.constraints.optimise.optimise_noise`` and
``mrlib.speech.generate_from_audio`` run under :func:`policy`, which applies it for the
call and restores the previous count after, so a script that trains with mrlib gets the
same count as ``mrlib train`` and its own torch work keeps its setting. What cannot be
told from torch's default: a count set with ``torch.set_num_threads`` before mrlib was
imported (taken for torch's own, so capped at the default) and one set afterwards that
equals torch's starting count; pass such a count to :func:`apply_policy` (or
``--threads``).
"""

from __future__ import annotations

import contextlib
import functools
import os
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TypeVar

import torch

from mrlib.errors import MrlibError

__all__ = [
    "ENV_VARS",
    "LoadFollower",
    "MIN_FOLLOW_ITERATIONS",
    "load_follower",
    "apply_policy",
    "default_threads",
    "policy",
    "usable_cpus",
    "user_threads",
    "with_policy",
]

# environment variables through which a user sets the thread count of torch's CPU kernels
ENV_VARS = ("OMP_NUM_THREADS", "MKL_NUM_THREADS")

_START = torch.get_num_threads()  # torch's count when mrlib was first imported


class _State:
    last_set: int | None = None  # the count mrlib last set
    explicit: bool = False  # whether that count was asked for explicitly


_state = _State()

F = TypeVar("F", bound=Callable)


def _env_threads() -> int | None:
    for name in ENV_VARS:
        text = os.environ.get(name, "").strip()
        if text.isdigit() and int(text) > 0:
            return int(text)
    return None


def usable_cpus() -> int:
    """CPUs this process may run on: its affinity mask, lowered by a cgroup CPU quota
    (``/sys/fs/cgroup/cpu.max``, a container's ``--cpus``) where there is one."""
    try:
        n = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        n = os.cpu_count() or 1
    try:
        quota, period = open("/sys/fs/cgroup/cpu.max").read().split()[:2]
        if quota != "max":
            n = min(n, max(1, int(int(quota) // int(period))))
    except (OSError, ValueError):
        pass
    return max(1, n)


def default_threads() -> int:
    """mrlib's default: half the usable CPUs, at least 1, at most torch's own count."""
    return max(1, min(_START, usable_cpus() // 2))


def _check(threads) -> int:
    if isinstance(threads, bool) or not isinstance(threads, int) or threads < 1:
        raise MrlibError(f"threads must be a positive integer, got {threads!r}")
    return threads


def _set(n: int) -> None:
    if torch.get_num_threads() != n:
        torch.set_num_threads(n)


def user_threads() -> int | None:
    """The count the user chose (environment or ``torch.set_num_threads``), else None."""
    current = torch.get_num_threads()
    if _env_threads() is not None:
        return current
    reference = _START if _state.last_set is None else _state.last_set
    if current != reference or _state.explicit:
        return current
    return None


def apply_policy(threads: int | None = None) -> int:
    """Set torch's intra-op thread count for mrlib's CPU work and return it.

    ``threads``: an explicit count (wins over everything). Otherwise the user's own
    choice is kept (``OMP_NUM_THREADS`` / ``MKL_NUM_THREADS``, or a count set with
    ``torch.set_num_threads`` after importing mrlib), and else :func:`default_threads`
    is set. Notebooks call ``mrlib.threads.apply_policy()`` once at the top."""
    if threads is not None:
        n = _check(threads)
        _set(n)
        _state.last_set, _state.explicit = n, True
        return n
    chosen = user_threads()
    if chosen is not None:
        return chosen
    n = default_threads()
    _set(n)
    _state.last_set, _state.explicit = n, False
    return n


@contextlib.contextmanager
def policy(threads: int | None = None) -> Iterator[int]:
    """Apply the policy for the ``with`` block, then restore torch's previous count."""
    before = torch.get_num_threads()
    saved = (_state.last_set, _state.explicit)
    n = apply_policy(threads)
    try:
        yield n
    finally:
        _set(before)
        _state.last_set, _state.explicit = saved


def with_policy(fn: F) -> F:
    """Decorator: run ``fn`` under :func:`policy` (the default count unless the user
    chose one)."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        with policy():
            return fn(*args, **kwargs)

    return wrapper  # type: ignore[return-value]


# -- following the load during a long run ---------------------------------------------------
def _busy_cpu_seconds() -> float | None:
    """CPU seconds all processes have spent busy since boot (``/proc/stat``: user, nice,
    system, irq, softirq and steal, the last being time the hypervisor gave away), or
    None where there is no ``/proc/stat``."""
    try:
        first = Path("/proc/stat").read_text().split("\n", 1)[0]  # the "cpu" line
        v = [int(x) for x in first.split()[1:]]
        return (v[0] + v[1] + v[2] + v[5] + v[6] + (v[7] if len(v) > 7 else 0)) / _HZ
    except (OSError, ValueError, IndexError):
        return None


try:
    _HZ = os.sysconf("SC_CLK_TCK")
except (AttributeError, ValueError, OSError):
    _HZ = 100


MAX_PATIENCE = 16  # calm checks (of 2 s) a raise may have to wait for after raises taken back
MIN_FOLLOW_ITERATIONS = 200  # shorter runs keep the policy's count (no probe, no checks)


class LoadFollower:
    """Torch's thread count during a long run (training), following the machine's load.

    Two threads train the small networks 18-35 % faster than one on an idle 2-core
    machine, and 4.5-12x slower when another process holds a core (the module docstring).
    The follower takes what the other processes leave: every ``interval`` seconds it
    reads how many CPUs they kept busy (``/proc/stat``'s busy time minus this process's
    own CPU time, over the wall time), and

    * lowers the count at once to the CPUs left, rounded to the nearest (others busy on
      half a core or more take that core);
    * raises it by one when a whole further CPU has been left free (others below a
      quarter of it) at ``patience`` checks in a row; a raise that the next two checks
      take back doubles the patience (up to ``MAX_PATIENCE``), so a neighbour that
      works in bursts (a test runner, a notebook) does not make it switch back and
      forth, and a raise that lasts ten checks restores it.

    It starts from a short sample taken before the run's own work. Between 1 and
    ``max_threads`` (the usable CPUs, at most torch's own count). Where the counts give the same numbers, as on
    this build (training at 1, 2 and alternating counts: identical weights,
    ``tests/test_threads.py``), the run's result does not depend on the load; pass
    ``--threads N`` for a fixed count.
    """

    def __init__(self, max_threads: int | None = None, interval: float = 2.0,
                 patience: int = 2, probe: float = 0.1):  # fmt: skip
        import time

        top = min(usable_cpus(), _START) if max_threads is None else int(max_threads)
        self.max_threads = max(1, top)
        self.interval, self.base_patience = float(interval), int(patience)
        self.patience = self.base_patience
        self._since_raise: int | None = None  # checks since the last raise
        self._clock, self._cpu = time.monotonic, time.process_time
        self._calm = 0
        self.history: list[tuple[float, float, int]] = []  # (time, others' CPUs, count)
        start = self._sample()
        time.sleep(probe)
        self.threads = self._decide(self._others(start), initial=True)
        _set(self.threads)
        _state.last_set = self.threads
        self._last = self._sample()

    def _sample(self) -> tuple[float, float, float]:
        return self._clock(), _busy_cpu_seconds() or 0.0, self._cpu()

    def _others(self, since: tuple[float, float, float]) -> float:
        now = self._sample()
        wall = max(now[0] - since[0], 1e-6)
        return max(0.0, ((now[1] - since[1]) - (now[2] - since[2])) / wall)

    def _decide(self, others: float, initial: bool = False) -> int:
        free = self.max_threads - others
        down = max(1, min(self.max_threads, int(free + 0.5)))
        if initial:
            return down
        if self._since_raise is not None:
            self._since_raise += 1
            if self._since_raise >= 10:  # the raise held: back to the usual patience
                self.patience, self._since_raise = self.base_patience, None
        if down < self.threads:
            self._calm = 0
            if self._since_raise is not None and self._since_raise <= 2:
                self.patience = min(MAX_PATIENCE, 2 * self.patience)
            self._since_raise = None
            return down
        if free >= self.threads + 0.75:
            self._calm += 1
            if self._calm >= self.patience:
                self._calm, self._since_raise = 0, 0
                return min(self.max_threads, self.threads + 1)
        else:
            self._calm = 0
        return self.threads

    def tick(self) -> int:
        """Call between iterations: checks the load once per ``interval`` seconds (a
        clock read otherwise) and sets the new count; returns the count in use."""
        if self._clock() - self._last[0] < self.interval:
            return self.threads
        others = self._others(self._last)
        self._last = self._sample()
        n = self._decide(others)
        self.history.append((self._last[0], others, n))
        if n != self.threads:
            self.threads = n
            _set(n)
            _state.last_set = n
        return n


def load_follower(**kwargs) -> LoadFollower | None:
    """A :class:`LoadFollower` when the thread count is mrlib's own choice (no
    ``--threads``, no ``OMP_NUM_THREADS``, no ``torch.set_num_threads`` of the user's),
    more than one CPU is usable and ``/proc/stat`` can be read; else None (the count
    stays as :func:`apply_policy` set it)."""
    if user_threads() is not None or usable_cpus() < 2 or _busy_cpu_seconds() is None:
        return None
    return LoadFollower(**kwargs)
