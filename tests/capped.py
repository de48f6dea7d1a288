"""Run CLI cases in a child process under a memory cap, with each case's exit code,
stderr, seconds and the child's peak resident memory: how the bounds tests show that a
refusal comes before the work (the issue's acceptance: < 1 GB and < 30 s before the
error), and a regression fails under the cap instead of swapping the machine."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

CAP_BYTES = 3 * 2**30  # the child's data segment (torch alone takes ~0.4 GB)
PEAK_MB = 1024
SECONDS = 30


def sparse_file(path: Path, head: bytes, size: int) -> Path:
    """A file of ``size`` bytes that starts with ``head`` and takes no disk (a sparse
    file): the 2 GB input a reader must refuse from its size, not by reading it."""
    with open(path, "wb") as fh:
        fh.write(head)
        fh.truncate(size)
    return path


def run_capped(cases: list[list[str]]) -> list[dict]:
    """Run ``mrlib.app.cli.main`` on every argv in a child under ``CAP_BYTES``; per case its
    exit code, stderr and seconds, and the child's peak resident memory (MB) so far
    (``VmHWM``: ``ru_maxrss`` carries the parent's peak over fork + exec, and the parent
    may be a test worker that has trained models)."""
    script = textwrap.dedent(
        f"""
        import contextlib, io, json, resource, sys, time
        def vm_hwm_mb():
            with open("/proc/self/status") as fh:
                line = next(l for l in fh if l.startswith("VmHWM:"))
            return int(line.split()[1]) / 1024
        resource.setrlimit(resource.RLIMIT_DATA, ({CAP_BYTES}, {CAP_BYTES}))
        from mrlib.app.cli import main
        for argv in json.loads(sys.argv[1]):
            err, t = io.StringIO(), time.perf_counter()
            with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
                try:
                    code = main(argv)
                except SystemExit as e:
                    code = e.code
            peak = vm_hwm_mb()
            print(json.dumps({{"code": code, "err": err.getvalue(),
                               "s": time.perf_counter() - t, "peak_mb": peak}}))
        """
    )
    res = subprocess.run(
        [sys.executable, "-c", script, json.dumps(cases)], capture_output=True, text=True
    )
    assert res.returncode == 0, res.stderr[-2000:]
    return [json.loads(line) for line in res.stdout.splitlines()]


def run_capped_python(setup: str, cases: list[str]) -> list[dict]:
    """Run ``setup`` once, then every Python statement in ``cases``, in a child under
    ``CAP_BYTES``: per case the exception it raised (``"error"``: ``Class: message``, or
    None when it raised none), its seconds and the child's peak resident memory (MB) so
    far; how a bound of the Python API is shown to come before the work."""
    script = textwrap.dedent(
        f"""
        import contextlib, io, json, resource, sys, time
        def vm_hwm_mb():
            with open("/proc/self/status") as fh:
                line = next(l for l in fh if l.startswith("VmHWM:"))
            return int(line.split()[1]) / 1024
        resource.setrlimit(resource.RLIMIT_DATA, ({CAP_BYTES}, {CAP_BYTES}))
        env = {{}}
        with contextlib.redirect_stdout(io.StringIO()):
            exec(sys.argv[1], env)
        for code in json.loads(sys.argv[2]):
            t, error = time.perf_counter(), None
            try:
                with contextlib.redirect_stdout(io.StringIO()):
                    exec(code, dict(env))
            except Exception as e:
                error = f"{{type(e).__name__}}: {{e}}"
            print(json.dumps({{"error": error, "s": time.perf_counter() - t,
                               "peak_mb": vm_hwm_mb()}}))
        """
    )
    res = subprocess.run(
        [sys.executable, "-c", script, setup, json.dumps(cases)], capture_output=True, text=True
    )
    assert res.returncode == 0, res.stderr[-2000:]
    return [json.loads(line) for line in res.stdout.splitlines()]
