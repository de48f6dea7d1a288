"""All of a command's output files, or none of them: :func:`output_transaction`.

``with output_transaction(): ...`` makes every file written in the block through
``mrlib.io.outputs`` (``save_motion``, checkpoints, figures, CSV files...) a *staged*
file: its content goes, as ``atomic_write`` writes it, to a temporary file beside its
target, and nothing takes a target's name until the block ends. Then

* the block ended with an exception (a full disk while writing the third file, an
  error in the command, Ctrl-C): every staged temporary file is removed, the folders
  the block created (:func:`make_folders`) too; the targets were never touched;
* the block ended normally: every target is checked again, then the files take their
  names one after the other, a replaced file first kept aside under a hard link. If one
  of them fails (a file size limit, a read-only folder, a target that turned into a
  folder), the files already published are rolled back (each replaced file restored,
  each new one removed) and the error names the file that failed and why.

So the output folder ends either with all of the command's files or exactly as it was,
byte for byte, with no temporary file left. A transaction inside a transaction joins
the outer one. Work that must reach the disk as it goes (a training run's checkpoints
and loss log) runs in :func:`outside_transactions`.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import shutil
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

from mrlib.io import outputs as _out

__all__ = [
    "OutputTransaction",
    "output_transaction",
    "outside_transactions",
    "current_transaction",
    "when_written",
    "make_folders",
    "set_aside",
    "put_back",
    "with_note",
]


@dataclass
class _Staged:
    tmp: Path
    path: Path
    overwrite: bool


class OutputTransaction:
    """The files staged by one :func:`output_transaction` (see the module docstring)."""

    def __init__(self) -> None:
        self._staged: dict[str, _Staged] = {}
        self._folders: list[Path] = []  # created by this transaction, deepest last
        self._scratch: dict[Path, Path] = {}  # scratch folder -> the path it stands for
        self._after: list[Callable[[], object]] = []
        self.published: list[Path] = []

    @property
    def paths(self) -> list[Path]:
        """The targets staged so far, in the order they were written."""
        return [s.path for s in self._staged.values()]

    def stage(self, tmp: Path, path: Path, overwrite: bool) -> None:
        """Take the written temporary file ``tmp`` (in ``path``'s folder) as ``path``'s
        content, published at the end; a second write of ``path`` replaces the first
        (refused unless ``overwrite``)."""
        key = os.path.abspath(path)
        old = self._staged.get(key)
        if old is not None:
            if not overwrite:
                with contextlib.suppress(OSError):
                    os.unlink(tmp)
                raise _out.OutputExistsError(path, "written twice by this command")
            with contextlib.suppress(OSError):
                os.unlink(old.tmp)
            del self._staged[key]
        self._staged[key] = _Staged(Path(tmp), Path(path), overwrite)

    def adopt(self, src: str | Path, path: str | Path, *, overwrite: bool = False) -> None:
        """Stage the finished file ``src`` (on the same file system, e.g. in a
        :meth:`scratch_folder`) as ``path``: it is moved beside ``path`` now and takes
        its name when the transaction ends."""
        path = Path(path)
        _out.check_writable(path, overwrite=overwrite)
        tmp = _out._temporary_name(path)
        try:
            os.rename(src, tmp)
        except OSError as e:
            raise _out.write_error(path, e) from e
        self.stage(tmp, path, overwrite)

    def folder(self, path: str | Path) -> Path:
        """Create the folder ``path`` (and its parents); those created here are removed
        again if the transaction fails (when still empty)."""
        path = Path(path)
        missing = []
        p = path
        while not os.path.lexists(p) and p != p.parent:
            missing.append(p)
            p = p.parent
        try:
            path.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise _out.write_error(path, e, "nothing was written") from e
        self._folders.extend(reversed(missing))
        return path

    def scratch_folder(self, beside: str | Path) -> Path:
        """A private empty folder next to ``beside`` (so on its file system), for work
        that writes files by name before they are :meth:`adopt`-ed; removed with what it
        holds when the transaction ends."""
        beside = Path(beside)
        self.folder(beside.parent)
        for stale in beside.parent.glob(f".{beside.name}.tmp*"):  # of killed processes
            pid = _out._temporary_pid(stale.name)
            if pid is not None and pid != os.getpid() and not _out._alive(pid):
                shutil.rmtree(stale, ignore_errors=True)
        scratch = _out._temporary_name(beside)
        try:
            scratch.mkdir()
        except OSError as e:
            raise _out.write_error(beside, e, "nothing was written") from e
        self._scratch[scratch] = beside
        return scratch

    def after(self, fn: Callable[[], object]) -> None:
        """Call ``fn`` once the files are published (a ``wrote ...`` message)."""
        self._after.append(fn)

    # -- the end -----------------------------------------------------------------------
    def abort(self) -> None:
        """Remove every staged temporary file, the scratch folders and the folders this
        transaction created; publish nothing."""
        for s in self._staged.values():
            with contextlib.suppress(OSError):
                os.unlink(s.tmp)
        self._staged.clear()
        self._after.clear()
        self._cleanup(remove_folders=True)

    def _cleanup(self, *, remove_folders: bool) -> None:
        for scratch in self._scratch:
            shutil.rmtree(scratch, ignore_errors=True)
        self._scratch.clear()
        if remove_folders:
            for folder in reversed(self._folders):
                with contextlib.suppress(OSError):
                    folder.rmdir()  # only when empty: never what someone else put there
        self._folders.clear()

    def commit(self) -> list[Path]:
        """Publish every staged file, or (on the first failure) none; see the module
        docstring. Returns the paths published."""
        staged = list(self._staged.values())
        try:
            for s in staged:  # refused before any file is published
                _out.check_writable(s.path, overwrite=s.overwrite)
        except BaseException as e:
            self.abort()
            if isinstance(e, _out.OutputError) and staged:
                e.problem += f"; none of this command's {len(staged)} files was written"
                e.args = (f"{e.path}: {e.problem}",)
            raise
        done: list[tuple[_Staged, Path | None, tuple[int, int]]] = []
        current = None
        try:
            for s in staged:
                current = s
                st = os.lstat(s.tmp)
                backup = _keep_aside(s.path) if s.overwrite else None
                try:
                    _out._publish(s.tmp, s.path, s.overwrite)
                except BaseException:
                    if backup is not None:
                        _restore(backup, s.path)
                    raise
                done.append((s, backup, (st.st_dev, st.st_ino)))
        except BaseException as e:
            for s, backup, ident in reversed(done):
                if backup is not None:
                    _restore(backup, s.path)
                else:
                    _remove_if(s.path, ident)
            self.abort()
            if isinstance(e, OSError) and not isinstance(e, _out.OutputWriteError):
                what = (
                    f"none of this command's {len(staged)} files was written (earlier "
                    "files are kept as they were)"
                )
                raise _out.write_error(current.path, e, what) from e
            raise
        for _, backup, _ in done:
            if backup is not None:
                with contextlib.suppress(OSError):
                    os.unlink(backup)
        for folder in {s.path.parent for s in staged}:
            _out._fsync_folder(folder)
        self._staged.clear()
        self._cleanup(remove_folders=False)
        self.published = [s.path for s in staged]
        after, self._after = self._after, []
        for fn in after:
            fn()
        return self.published


def set_aside(path: str | Path, *, move: bool = False) -> Path | None:
    """Give the file at ``path`` a second, hidden name beside it, so that
    :func:`put_back` can restore it after ``path`` was replaced: a hard link (where the
    file system has them), or with ``move`` (or no hard links) the file itself moved
    there, leaving ``path`` free. None when nothing is at ``path``."""
    path = Path(path)
    if not os.path.lexists(path):
        return None
    backup = path.with_name(f".{path.name}.tmp{os.getpid()}.{secrets.token_hex(4)}.old")
    if not move:
        try:
            os.link(path, backup, follow_symlinks=False)
            return backup
        except OSError:
            pass
    os.rename(path, backup)
    return backup


_keep_aside = set_aside


def put_back(backup: str | Path, path: str | Path) -> None:
    """Restore the file :func:`set_aside` kept as ``backup`` at ``path`` (best effort)."""
    _restore(Path(backup), Path(path))


def _restore(backup: Path, path: Path) -> None:
    with contextlib.suppress(OSError):
        os.replace(backup, path)
    with contextlib.suppress(OSError):  # a rename onto a link of itself leaves both names
        os.unlink(backup)


def _remove_if(path: Path, ident: tuple[int, int]) -> None:
    """Remove ``path`` if it is still the file this transaction published there."""
    with contextlib.suppress(OSError):
        st = os.lstat(path)
        if (st.st_dev, st.st_ino) == ident:
            os.unlink(path)


@contextlib.contextmanager
def output_transaction() -> Iterator[OutputTransaction]:
    """``with output_transaction() as tx:``: the outputs written in the block are
    published together at its end, or none (see the module docstring). Inside another
    transaction, joins it (publishing at the outer one's end).

    Raises (at the end of the block):
        OutputWriteError: a file could not take its name; it is named, and the folder
            is as it was before the block.
        OutputError: a target turned into something that cannot be replaced meanwhile.
    """
    outer = _out._ACTIVE.get()
    if outer is not None:
        yield outer
        return
    tx = OutputTransaction()
    token = _out._ACTIVE.set(tx)
    try:
        yield tx
    except BaseException as e:
        _out._ACTIVE.reset(token)
        staged, scratch = len(tx._staged), {str(a): str(b) for a, b in tx._scratch.items()}
        tx.abort()
        if isinstance(e, Exception):  # say so, naming no scratch folder
            _rename_in_message(e, scratch)
            if staged and "none of this command's" not in str(e):
                with_note(e, "no output of this command was written")
        raise
    _out._ACTIVE.reset(token)
    tx.commit()


def _rename_in_message(e: Exception, names: dict[str, str]) -> None:
    def fix(text: str) -> str:
        for a, b in names.items():
            text = text.replace(a, b)
        return text

    if not names:
        return
    if e.args and isinstance(e.args[0], str):
        e.args = (fix(e.args[0]), *e.args[1:])
    if isinstance(getattr(e, "problem", None), str):
        e.problem = fix(e.problem)
    if isinstance(getattr(e, "path", None), Path):
        e.path = Path(fix(str(e.path)))


def with_note(e: BaseException, note: str, where: Path | None = None) -> BaseException:
    """``e`` with ``; note`` at the end of its message: mrlib's errors in place; an
    ``OSError`` of no mrlib kind becomes an ``OutputWriteError`` naming its file (or
    ``where``); any other exception is returned as it is."""
    from mrlib.errors import MotionFileError, MrlibError

    if isinstance(e, (_out.OutputError, MotionFileError)):
        e.problem = f"{e.problem}; {note}"
        e.args = (e.problem if e.path is None else f"{e.path}: {e.problem}",)
    elif isinstance(e, MrlibError):
        e.args = (f"{e}; {note}",)
    elif isinstance(e, OSError) and (e.filename or where):
        return _out.OutputWriteError(e.filename or where, f"{e.strerror or e}; {note}", e)
    return e


@contextlib.contextmanager
def outside_transactions() -> Iterator[None]:
    """Writes in the block go straight to disk, as without a transaction (a training
    run's checkpoints, which a resumed run must find)."""
    token = _out._ACTIVE.set(None)
    try:
        yield
    finally:
        _out._ACTIVE.reset(token)


def current_transaction() -> OutputTransaction | None:
    """The transaction the current code writes in, or None."""
    return _out._ACTIVE.get()


def when_written(fn: Callable[[], object]) -> None:
    """Call ``fn`` when the current transaction has published its files (now, without
    one): messages such as ``wrote ...`` are printed only for files that exist."""
    tx = _out._ACTIVE.get()
    if tx is None:
        fn()
    else:
        tx.after(fn)


def make_folders(path: str | Path) -> Path:
    """``path.mkdir(parents=True, exist_ok=True)``; inside a transaction, the folders
    created are removed again if it fails (when empty)."""
    tx = _out._ACTIVE.get()
    if tx is not None:
        return tx.folder(path)
    path = Path(path)
    path.mkdir(parents=True, exist_ok=True)
    return path
