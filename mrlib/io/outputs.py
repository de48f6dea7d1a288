"""Writing output files without ever clobbering or following what is already there.

Every file mrlib writes (motion files, checkpoints, loss logs, renders) goes through
:func:`atomic_write`:

* the content goes to a temporary file in the target's folder, created with
  ``O_CREAT | O_EXCL | O_NOFOLLOW`` (never an existing file, never through a symbolic
  link), is flushed and ``fsync``-ed, and only then takes the target's name. A failed
  write (a full disk, a file size limit, an exception while producing the content)
  removes the temporary file and leaves the previous target byte for byte as it was;
* a symbolic link at the target is refused: a link planted in an output folder never
  redirects a write to a file elsewhere;
* with ``overwrite=False`` an existing target is refused, atomically (the temporary file
  is hard-linked to the name, which fails if the name exists), so two writers never
  replace each other's file;
* a write that fails in the operating system (``EFBIG`` past a file size limit,
  ``ENOSPC``, ``EROFS``, ``EACCES``...) raises :class:`OutputWriteError`, which names the
  file and the reason (and is an ``OSError`` too).

A command that writes several files writes them in an :func:`output_transaction`
(``mrlib.io.transaction``): each file is staged as a temporary file beside its target and
all of them take their names together when the block ends, or none does (a failure while
publishing restores the files already replaced). Its outputs are all written or none.

:class:`RunLock` guards a folder that one process writes over a long time (a training
run): a second writer gets :class:`RunLockedError` naming the holder (process id, host,
start time). The lock is an ``flock`` on ``<folder>/.mrlib-run.lock``: the kernel
releases it when the holder exits, killed or not, so a lock file left behind by a
dead process is taken over rather than blocking the folder forever.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import secrets
import socket
import sys
import time
from collections.abc import Callable, Iterator
from contextvars import ContextVar
from pathlib import Path
from typing import BinaryIO

from mrlib.errors import MrlibError

try:  # not on Windows: the lock then falls back to the process id it records
    import fcntl
except ImportError:  # pragma: no cover
    fcntl = None

__all__ = [
    "OutputError",
    "OutputExistsError",
    "OutputWriteError",
    "RunLockedError",
    "atomic_write",
    "atomic_file",
    "write_bytes",
    "write_text",
    "open_for_append",
    "check_writable",
    "remove_stale_temporaries",
    "RunLock",
    "LOCK_NAME",
]

LOCK_NAME = ".mrlib-run.lock"
_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)
_CLOEXEC = getattr(os, "O_CLOEXEC", 0)


class OutputError(MrlibError):
    """An output file cannot be written where asked (a symbolic link, not a regular
    file); ``path`` names it."""

    def __init__(self, path: str | Path, problem: str):
        self.path = Path(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")


class OutputExistsError(OutputError):
    """The output exists and replacing it was not asked for (``overwrite=False``)."""


class RunLockedError(OutputError):
    """Another process holds the folder's run lock."""


class OutputWriteError(OutputError, OSError):
    """Writing an output failed in the operating system (a full disk, a file size limit,
    a read-only folder, a target that cannot be replaced): ``path`` names the file,
    ``errno`` and ``strerror`` the reason. An ``OSError`` as well as an ``OutputError``."""

    def __init__(self, path: str | Path, problem: str, cause: OSError | None = None):
        super().__init__(path, problem)
        if cause is not None:
            self.errno, self.strerror = cause.errno, cause.strerror or str(cause)

    def __str__(self) -> str:  # not OSError's "[Errno N] ..."
        return f"{self.path}: {self.problem}"


def write_error(path: str | Path, e: OSError, what: str = "") -> OutputWriteError:
    """``e`` (an OS error while writing ``path``) as an :class:`OutputWriteError` naming
    ``path``; ``what`` says what became of it (default: what :func:`atomic_write` keeps)."""
    if isinstance(e, OutputWriteError):
        return e
    reason = e.strerror or str(e) or type(e).__name__
    blocker = file_in_the_way(path)
    if blocker is not None:
        reason = f"{blocker} is a file, not a folder"
    if not what:
        if _ACTIVE.get() is not None:
            what = "none of this command's outputs was written (earlier files are kept)"
        elif os.path.lexists(path):
            what = "the previous file is kept"
        else:
            what = "nothing was written"
    return OutputWriteError(path, f"cannot write: {reason}; {what}", e)


# the transaction the current command writes in (``mrlib.io.transaction``), or None
_ACTIVE: ContextVar = ContextVar("mrlib_output_transaction", default=None)


def _temporary_name(path: Path) -> Path:
    return path.with_name(f".{path.name}.tmp{os.getpid()}.{secrets.token_hex(4)}")


def _temporary_pid(name: str) -> int | None:
    tail = name.rsplit(".tmp", 1)[-1].split(".", 1)[0]
    return int(tail) if tail.isdigit() else None


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True  # exists, but not ours to signal
    return True


def remove_stale_temporaries(path: str | Path) -> None:
    """Remove temporary files of ``path`` (``.<name>.tmp<PID>...``) left by writers
    that were killed mid-write (their process is gone); a live writer's are left alone."""
    path = Path(path)
    try:
        candidates = list(path.parent.glob(f".{path.name}.tmp*"))
    except OSError:
        return
    for tmp in candidates:
        pid = _temporary_pid(tmp.name)
        if pid is None or pid == os.getpid() or _alive(pid):
            continue
        with contextlib.suppress(OSError):
            if not tmp.is_symlink():
                tmp.unlink()


def file_in_the_way(path: str | Path) -> Path | None:
    """The nearest existing folder of ``path`` that is not a folder (an output folder
    given as a file's name), or None."""
    for parent in Path(path).parents:
        if os.path.lexists(parent):
            return None if os.path.isdir(parent) else parent
    return None


def check_writable(path: str | Path, *, overwrite: bool) -> None:
    """Refuse, before any work, an output that :func:`atomic_write` would refuse: a
    symbolic link or something other than a regular file at ``path``, a file where its
    folder should be, or (unless ``overwrite``) any existing file."""
    path = Path(path)
    blocker = file_in_the_way(path)
    if blocker is not None:
        raise OutputError(blocker, "is a file, not a folder: nothing can be written under it")
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return
    except OSError:
        return  # the write itself reports it (a missing folder, permissions)
    import stat

    if stat.S_ISLNK(st.st_mode):
        raise OutputError(
            path,
            "is a symbolic link; refusing to write through it (remove it, or write elsewhere)",
        )
    if not stat.S_ISREG(st.st_mode):
        raise OutputError(path, "exists and is not a regular file; refusing to replace it")
    if not overwrite:
        raise OutputExistsError(
            path, "already exists; pass --overwrite (overwrite=True) to replace it"
        )


def _fsync_folder(folder: Path) -> None:
    try:
        fd = os.open(folder, os.O_RDONLY | _CLOEXEC)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _publish(tmp: Path, path: Path, overwrite: bool) -> None:
    """Give ``tmp`` the name ``path``: replacing a regular file when ``overwrite``,
    else only if the name is free (atomically, with a hard link where the file system
    has them)."""
    check_writable(path, overwrite=overwrite)
    if overwrite:
        os.replace(tmp, path)
        return
    try:
        os.link(tmp, path, follow_symlinks=False)
    except FileExistsError:
        raise OutputExistsError(
            path, "already exists (written meanwhile by another process); nothing was replaced"
        ) from None
    except OSError as e:
        if e.errno not in (errno.EPERM, errno.ENOTSUP, errno.EOPNOTSUPP, errno.EXDEV):
            raise
        check_writable(path, overwrite=False)  # no hard links here: check, then rename
        os.replace(tmp, path)
        return
    os.unlink(tmp)


def atomic_write(
    path: str | Path, write: Callable[[BinaryIO], object], *, overwrite: bool = False
) -> Path:
    """Write ``path`` by calling ``write(fh)`` on a fresh temporary file beside it, then
    moving it into place (see the module docstring).

    Args:
        path: the file to write; its folder must exist.
        write: fills the binary file object it is given.
        overwrite: replace an existing regular file (never a symbolic link).

    Raises:
        OutputExistsError: ``path`` exists and ``overwrite`` is False.
        OutputError: ``path`` is a symbolic link or not a regular file.
        OSError: the write failed (disk full, file size limit, permissions); the
            previous file, if any, is unchanged and no temporary file remains.
    """
    with atomic_file(path, overwrite=overwrite) as fh:
        write(fh)
    return Path(path)


@contextlib.contextmanager
def atomic_file(path: str | Path, *, overwrite: bool = False) -> Iterator[BinaryIO]:
    """``with atomic_file(path) as fh: ...``: the file takes its name only when the
    block ends without an exception (see :func:`atomic_write`); inside an
    :func:`output_transaction`, when the transaction ends."""
    path = Path(path)
    check_writable(path, overwrite=overwrite)
    remove_stale_temporaries(path)
    tx = _ACTIVE.get()
    tmp = _temporary_name(path)
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _NOFOLLOW | _CLOEXEC, 0o666)
    except OSError as e:
        raise write_error(path, e) from e
    try:
        fh = os.fdopen(fd, "wb")
        try:
            try:
                yield fh
                fh.flush()
                os.fsync(fh.fileno())
                fh.close()
            except OSError as e:  # the disk's limits (a full disk, a file size limit)
                raise write_error(path, e) from e
            except RuntimeError as e:  # torch.save's writer wraps the OS error
                if isinstance(e.__context__, OSError):
                    raise write_error(path, e.__context__) from e
                raise
        finally:
            with contextlib.suppress(OSError):  # a failed close must not hide the error
                fh.close()
        if tx is not None:
            tx.stage(tmp, path, overwrite)  # published when the transaction ends
            return
        try:
            _publish(tmp, path, overwrite)
        except OutputError:
            raise
        except OSError as e:
            raise write_error(path, e) from e
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    _fsync_folder(path.parent)


def write_bytes(path: str | Path, data: bytes, *, overwrite: bool = False) -> Path:
    """:func:`atomic_write` of ``data``."""
    return atomic_write(path, lambda fh: fh.write(data), overwrite=overwrite)


def write_text(
    path: str | Path, text: str, *, overwrite: bool = False, encoding: str = "utf-8"
) -> Path:
    """:func:`atomic_write` of ``text``."""
    return write_bytes(path, text.encode(encoding), overwrite=overwrite)


class _AppendFile:
    """A text file open for appending whose failed writes raise :class:`OutputWriteError`
    naming it (an ``EFBIG`` from a buffered write names no file by itself)."""

    def __init__(self, fh, path: Path):
        self._fh, self.path = fh, path

    def _call(self, name: str, *args):
        try:
            return getattr(self._fh, name)(*args)
        except OSError as e:
            raise write_error(self.path, e, "its earlier lines are kept") from e

    def write(self, text: str) -> int:
        return self._call("write", text)

    def flush(self) -> None:
        self._call("flush")

    def close(self) -> None:
        self._call("close")

    def __getattr__(self, name: str):
        return getattr(self._fh, name)

    def __enter__(self) -> _AppendFile:
        return self

    def __exit__(self, exc_type, *exc) -> None:
        if exc_type is None:
            self.close()
            return
        with contextlib.suppress(OSError):  # the write that failed is being reported
            self._fh.close()


def open_for_append(path: str | Path, newline: str | None = "") -> object:
    """A text file opened for appending to an existing regular file, never through a
    symbolic link (``O_NOFOLLOW``); a failed write raises :class:`OutputWriteError`."""
    path = Path(path)
    try:
        fd = os.open(path, os.O_WRONLY | os.O_APPEND | _NOFOLLOW | _CLOEXEC)
    except OSError as e:
        if e.errno == errno.ELOOP:
            raise OutputError(path, "is a symbolic link; refusing to write through it") from None
        raise write_error(path, e, "nothing was written") from e
    return _AppendFile(os.fdopen(fd, "a", newline=newline, encoding="utf-8"), path)


# -- the run lock ----------------------------------------------------------------------------
def _holder_text(raw: str) -> str:
    try:
        info = json.loads(raw)
        return (
            f"process {info['pid']} on {info['host']}, started "
            f"{time.strftime('%Y-%m-%d %H:%M:%S', time.localtime(info['started']))}"
        )
    except (ValueError, KeyError, TypeError, OverflowError, OSError):
        return "a process that left no details"


class RunLock:
    """An exclusive lock on an output folder for one run (see the module docstring).

    ``with RunLock(folder): ...`` creates the folder if needed, takes the lock or raises
    :class:`RunLockedError`, and releases it (removing the lock file) at the end.
    """

    def __init__(self, folder: str | Path):
        self.folder = Path(folder)
        self.path = self.folder / LOCK_NAME
        self._fd: int | None = None

    @property
    def held(self) -> bool:
        return self._fd is not None

    def _describe_holder(self, fd: int) -> str:
        try:
            os.lseek(fd, 0, os.SEEK_SET)
            return _holder_text(os.read(fd, 4096).decode("utf-8", "replace"))
        except OSError:
            return "a process that left no details"

    def _locked(self, holder: str) -> RunLockedError:
        return RunLockedError(
            self.folder,
            f"another mrlib run is writing here ({holder}); wait for it to end, or choose "
            f"another --out (if no such process exists, remove {self.path})",
        )

    def _open(self) -> int:
        flags = os.O_RDWR | os.O_CREAT | _NOFOLLOW | _CLOEXEC
        try:
            return os.open(self.path, flags, 0o644)
        except OSError as e:
            if e.errno == errno.ELOOP:
                raise OutputError(
                    self.path, "is a symbolic link; refusing to use it as the run lock"
                ) from None
            raise

    def acquire(self) -> RunLock:
        if self._fd is not None:
            raise RuntimeError("RunLock is not reentrant")
        self.folder.mkdir(parents=True, exist_ok=True)
        for _ in range(20):
            fd = self._open()
            try:
                if fcntl is not None:
                    try:
                        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                    except BlockingIOError:
                        raise self._locked(self._describe_holder(fd)) from None
                    except OSError:  # no flock on this file system: trust the recorded pid
                        self._check_recorded_holder(fd)
                else:  # pragma: no cover
                    self._check_recorded_holder(fd)
                # the file may have been removed (released) between our open and our lock:
                # then we hold a lock on a file nobody else will see; try again
                try:
                    st = os.stat(self.path, follow_symlinks=False)
                except FileNotFoundError:
                    os.close(fd)
                    continue
                own = os.fstat(fd)
                if (st.st_dev, st.st_ino) != (own.st_dev, own.st_ino):
                    os.close(fd)
                    continue
                info = {
                    "pid": os.getpid(),
                    "host": socket.gethostname(),
                    "started": time.time(),
                    "argv": sys.argv[:8],
                }
                os.ftruncate(fd, 0)
                os.lseek(fd, 0, os.SEEK_SET)
                os.write(fd, json.dumps(info).encode("utf-8"))
                self._fd = fd
                return self
            except BaseException:
                if self._fd is None:
                    with contextlib.suppress(OSError):
                        os.close(fd)
                raise
        raise self._locked("the lock file keeps changing")

    def _check_recorded_holder(self, fd: int) -> None:
        try:
            os.lseek(fd, 0, os.SEEK_SET)
            info = json.loads(os.read(fd, 4096).decode("utf-8", "replace") or "{}")
        except (OSError, ValueError):
            return
        pid, host = info.get("pid"), info.get("host")
        if not isinstance(pid, int) or pid == os.getpid():
            return
        if host != socket.gethostname() or _alive(pid):
            raise self._locked(_holder_text(json.dumps(info)))

    def release(self) -> None:
        fd, self._fd = self._fd, None
        if fd is None:
            return
        try:
            st, own = os.stat(self.path, follow_symlinks=False), os.fstat(fd)
            if (st.st_dev, st.st_ino) == (own.st_dev, own.st_ino):
                os.unlink(self.path)  # while still locked: no one can take a dying file
        except OSError:
            pass
        finally:
            os.close(fd)

    def __enter__(self) -> RunLock:
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()
