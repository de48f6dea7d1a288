"""How many threads PyTorch uses for mrlib's CPU work.

mrlib's networks are small: a training iteration or a sample is thousands of short
kernels (convolutions of a few hundred channels over a few hundred frames). Each kernel
that runs on several threads ends on a barrier, and when another process holds one of
the cores the kernel waits for a time slice of the thread that lost its core. PyTorch's
default, one thread per physical core, leaves no core for anything else. Measured on a
2-core x86-64 VM with no GPU (``python bench/busy_machine.py``,
``docs/notes/2026-12-02-training-speed.md``): beside one CPU-bound process, two threads trained
the ``demo`` preset 4.5-12x slower than on the idle machine, one thread 0.97-1.6x (the
latter with other jobs on the cores too), and foot-contact cleaned samples took 960 ms
instead of 89 on two threads, 101 instead of 100 on one. On the idle machine two threads
were 18-35 % faster per block than one; one thread ran at 0.87x the speed two threads
had before the fused Adam step (``mrlib.training.build.make_adam``) and the masked gradients of
``mrlib.model.skeleton_conv.SkeletonConv1d``, which made it about 13 % faster.

The policy (:func:`use`), in order:

1. a count passed explicitly (``mrlib ... --threads N``, ``use(N)``);
2. the user's own choice: ``OMP_NUM_THREADS`` or ``MKL_NUM_THREADS`` set, or
   ``torch.set_num_threads`` called after mrlib was imported (a count other than the
   one torch started with, or other than the one mrlib last set) -- kept as it is, up to
   4 x the usable CPUs like ``--threads`` (above that: a warning, once, and that cap);
3. otherwise :func:`default_threads`: half the CPUs this process may use (at least one,
   at most torch's own starting count), so that as many other busy threads as mrlib
   runs fit beside it. On 2 cores that is one thread; counts above 2 CPUs follow the
   same rule but were not measured here.

A training run fixes its count when it starts and keeps it to the end
(:func:`run_threads`): the user's choice, else the count recorded in the checkpoint of
the run it resumes, else :func:`default_threads`. The count is stored in every checkpoint
(``threads``), so a resumed run continues on the count it began with. Nothing reads the
machine's load: float kernels may round differently at different thread counts (on an
AVX-512 / AMX Xeon, training at one and at two threads gave different weights), so a count
that followed the load would make the same seed give another model whenever something else
ran beside it. Same seed, same machine and same count give bit-identical weights whatever
else runs (``tests/test_threads.py`` trains beside a CPU-bound process and alone and
compares); across thread counts and CPUs results agree only to float rounding, and no
test assumes more.

Who sets the count: the command line, around each command (a training run's count fixed
as above), and :func:`use`, the one entry for a script or a notebook
(``mrlib.threads.use()`` once at the top: the policy's count; ``use(4)``: four threads).
No other mrlib function changes torch's count: a library call runs on the count the
process has, so a script's own torch work keeps its setting, and a training run started
from Python keeps that count from start to end (it records it in its checkpoints and warns
when a resume runs on another). What cannot be told from torch's default: a count set
with ``torch.set_num_threads`` before mrlib was imported (taken for torch's own) and one
set afterwards that equals torch's starting count; pass such a count to :func:`use` (or
``--threads``).
"""

from __future__ import annotations

import contextlib
import os
import warnings
from collections.abc import Iterator

import torch

from mrlib.errors import MrlibError

__all__ = [
    "ENV_VARS",
    "use",
    "default_threads",
    "policy",
    "run_threads",
    "usable_cpus",
    "user_threads",
]

# environment variables through which a user sets the thread count of torch's CPU kernels
ENV_VARS = ("OMP_NUM_THREADS", "MKL_NUM_THREADS")

_START = torch.get_num_threads()  # torch's count when mrlib was first imported


class _State:
    last_set: int | None = None  # the count mrlib last set
    explicit: bool = False  # whether that count was asked for explicitly


_state = _State()
_warned: set[tuple[str, int]] = set()  # the counts above the cap already warned about


def _env_choice() -> tuple[str, int] | None:
    """The variable and count ``OMP_NUM_THREADS`` / ``MKL_NUM_THREADS`` sets (the first of
    an OpenMP list such as ``4,2``), else None (unset, empty, or no positive integer)."""
    for name in ENV_VARS:
        text = os.environ.get(name, "").split(",")[0].strip()
        if text.isdigit() and int(text) > 0:
            return name, int(text)
    return None


def _capped(n: int, source: str) -> int:
    """A count the user chose outside mrlib (environment, ``torch.set_num_threads``), at
    most the 4 x usable CPUs an explicit ``--threads`` may ask for: above that a warning,
    and the cap (``OMP_NUM_THREADS=10000`` only adds threads that wait on each other)."""
    cap = 4 * usable_cpus()
    if n <= cap:
        return n
    if (source, n) in _warned:
        return cap
    _warned.add((source, n))  # once a process: the policy is applied around every call
    warnings.warn(
        f"{source}: {n} threads are more than the {cap} mrlib runs here (4 x the "
        f"{usable_cpus()} usable CPUs); capped at {cap} (set it <= {cap}, or pass --threads N)",
        stacklevel=3,
    )
    return cap


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
    """An explicit count: a positive integer, at most 4 x the usable CPUs (more only
    adds threads that wait on each other: 10000 made a sample 6x slower and 2x larger)."""
    if isinstance(threads, bool) or not isinstance(threads, int) or threads < 1:
        raise MrlibError(f"threads must be a positive integer, got {threads!r}")
    cpus = usable_cpus()
    if threads > 4 * cpus:
        raise MrlibError(
            f"threads: {threads} is more than the {4 * cpus} mrlib runs here (4 x the {cpus} "
            f"usable CPUs); pass --threads N (use(N)) with N <= {4 * cpus}, or leave "
            "it out for the default"
        )
    return threads


def _set(n: int) -> None:
    if torch.get_num_threads() != n:
        torch.set_num_threads(n)


def user_threads() -> int | None:
    """The count the user chose (environment or ``torch.set_num_threads``), else None."""
    current = torch.get_num_threads()
    if _state.explicit:  # --threads N / use(N), checked when it was set
        return current
    env = _env_choice()
    if env is not None:  # torch may have lowered the count already; the larger is checked
        name, n = env
        return min(current, _capped(max(n, current), f"{name}={n}"))
    reference = _START if _state.last_set is None else _state.last_set
    if current != reference:
        return _capped(current, "torch.set_num_threads")
    return None


def use(threads: int | None = None) -> int:
    """Set torch's intra-op thread count for mrlib's CPU work and return it: the one
    function of mrlib that changes it outside the command line.

    ``threads``: an explicit count (wins over everything). Otherwise the user's own
    choice is kept (``OMP_NUM_THREADS`` / ``MKL_NUM_THREADS``, or a count set with
    ``torch.set_num_threads`` after importing mrlib), and else :func:`default_threads`
    is set. Notebooks call ``mrlib.threads.use()`` once at the top."""
    if threads is not None:
        n = _check(threads)
        _set(n)
        _state.last_set, _state.explicit = n, True
        return n
    chosen = user_threads()
    if chosen is not None:
        _set(chosen)  # the cap, where the user's count was above it
        return chosen
    n = default_threads()
    _set(n)
    _state.last_set, _state.explicit = n, False
    return n


@contextlib.contextmanager
def policy(threads: int | None = None) -> Iterator[int]:
    """Apply the policy for the ``with`` block, then restore torch's previous count: how
    the command line runs each command."""
    before = torch.get_num_threads()
    saved = (_state.last_set, _state.explicit)
    n = use(threads)
    try:
        yield n
    finally:
        _set(before)
        _state.last_set, _state.explicit = saved


# -- the count of a training run ---------------------------------------------------------------
def run_threads(recorded: int | None = None) -> tuple[int, str]:
    """The thread count a training run uses from its start to its end, and why.

    ``recorded``: the count stored in the checkpoint of the run being resumed (None for a
    new run or a checkpoint written before counts were recorded). The user's choice
    (:func:`user_threads`: ``--threads``, ``OMP_NUM_THREADS``, ``torch.set_num_threads``)
    wins; else the recorded count, so that a resumed run continues exactly as it would
    have; else :func:`default_threads`. Returns ``(count, reason)``; the reason is one of
    ``"user"``, ``"resumed"``, ``"default"``."""
    chosen = user_threads()
    if chosen is not None:
        return chosen, "user"
    if recorded is not None and not isinstance(recorded, bool) and int(recorded) >= 1:
        return int(recorded), "resumed"
    return default_threads(), "default"
