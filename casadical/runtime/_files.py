"""Writing files safely: atomically, never over a user's file by accident.

Every file casadical writes goes through :func:`atomic_write` (or
:func:`atomic_open`): the content is written to a temporary file in the
same folder and moved into place only when complete, so an interrupted run
or a full disk never leaves a half-written file, and an existing file is
replaced only when the caller says so.

Inside :func:`outputs_together` (every command of the command line runs in
one) the complete temporary files are not moved into place at once but
kept until the block ends: then all of them are moved, or, if the block
fails or is interrupted, all are removed. A command's outputs appear
together or not at all.
"""

from __future__ import annotations

import contextlib
import math
import os
import shutil
import tempfile
import threading
import tomllib
from pathlib import Path
from typing import IO, Iterator

from ..errors import CasadicalError, InputError
from ._interrupts import checkpoint, deferred, finish, received, since

EXISTS = "exists already; choose another name or pass --force to replace it"


class _Staged:
    """The complete temporary files of an :func:`outputs_together` block, moved into place at its end."""

    def __init__(self):
        self.files: list[tuple[str, Path, bool]] = []     # (temporary file, target, overwrite)

    def targets(self) -> set[Path]:
        return {target.resolve() for _, target, _ in self.files}


_staged: _Staged | None = None
_staged_lock = threading.Lock()


@contextlib.contextmanager
def outputs_together() -> Iterator[None]:
    """Files written inside the block appear together when it ends, or none if it fails.

    Every :func:`atomic_open` (and so :func:`atomic_write`) inside the block,
    from any thread, writes its temporary file as usual but leaves it under
    its temporary name; when the block ends without an exception, every
    such file is moved into place (with signals held back, so Ctrl-C cannot
    stop it halfway); when it raises (an error, Ctrl-C, SIGTERM) every one
    is removed and no target is touched. A signal that came during the block
    also stops it at its end, even if some library caught the
    ``KeyboardInterrupt`` on the way or turned it into another exception;
    one that comes while the files are moved takes them all back (a file
    replaced with ``overwrite`` is restored); once all are in place the
    command is finished (:func:`casadical.runtime._interrupts.finish`). Files written with
    ``atomic_open(..., at_once=True)`` are not held back (a study's results,
    the cache of compiled functions). Blocks do not nest: an inner block
    belongs to the outer one.

    Raises
    ------
    InputError
        A target that must not be replaced appeared meanwhile, or cannot be
        written; nothing of the block is then left behind.
    """
    global _staged
    with _staged_lock:
        outer = _staged is not None
        if not outer:
            _staged = _Staged()
        staged = _staged
    if outer:
        yield
        return
    start = received()
    try:
        yield
        stop = since(start)
        if stop is not None:       # a signal that something on the way swallowed, or turned into another error
            raise stop
        _commit(staged.files)
        staged.files = []
    finally:
        with _staged_lock:
            _staged = None
        for tmp, _, _ in staged.files:
            with contextlib.suppress(OSError):
                os.unlink(tmp)


def _commit(files: list[tuple[str, Path, bool]]) -> None:
    """Move staged files into place, all or none, a signal held back meanwhile (Python handlers, any thread).

    A signal during the moves takes them back and is raised; once all are in
    place the command is finished and a signal is said at its end.
    """
    with deferred() as got:
        done = _move_all(files)
        if got:
            _undo(done)
        else:
            finish(len(files))
            for _, backup in done:
                if backup is not None:
                    with contextlib.suppress(OSError):
                        os.unlink(backup)


def _move_all(files: list[tuple[str, Path, bool]]) -> list[tuple[Path, str | None]]:
    """Move staged files into place: all, or (a target appeared meanwhile, a failed move) none.

    Returns what undoes it: each target with the backup of the file it
    replaced (None: it was new).
    """
    for _, target, overwrite in files:
        if not overwrite and target.exists():
            raise InputError(EXISTS, file=str(target))
    done: list[tuple[Path, str | None]] = []
    try:
        for tmp, target, overwrite in files:
            backup = _backup(target) if overwrite else None
            try:
                _place(tmp, target, overwrite)
            except BaseException:
                if backup is not None:
                    with contextlib.suppress(OSError):
                        os.unlink(backup)
                raise
            done.append((target, backup))
            if len(done) == 1:
                checkpoint("commit")
    except BaseException:
        _undo(done)
        raise
    return done


def _backup(target: Path) -> str | None:
    """A second name for the file ``target`` holds now (None if there is none), to put it back with."""
    if not target.is_file():
        return None
    try:
        fd, backup = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".old.part", dir=target.parent)
        os.close(fd)
        os.unlink(backup)
        try:
            os.link(target, backup)
        except OSError:               # file systems without hard links
            shutil.copy2(target, backup)
    except OSError as e:
        raise InputError(f"cannot write: {e.strerror or e}", file=str(target)) from e
    return backup


def _undo(done: list[tuple[Path, str | None]]) -> None:
    """Take back moved files: a new one removed, a replaced one restored."""
    for target, backup in reversed(done):
        with contextlib.suppress(OSError):
            if backup is None:
                target.unlink()
            else:
                os.replace(backup, target)


def _place(tmp: str, path: Path, overwrite: bool) -> None:
    """Move the complete temporary file ``tmp`` to ``path`` (never over a file unless ``overwrite``)."""
    try:
        if overwrite:
            os.replace(tmp, path)
            return
        try:
            os.link(tmp, path)        # fails if path appeared meanwhile: never replaces
        except FileExistsError:
            raise InputError(EXISTS, file=str(path)) from None
        except OSError:               # file systems without hard links
            if path.exists():
                raise InputError(EXISTS, file=str(path)) from None
            os.replace(tmp, path)
    except OSError as e:
        raise InputError(f"cannot write: {e.strerror or e}", file=str(path)) from e
    finally:
        if os.path.exists(tmp):
            with contextlib.suppress(OSError):
                os.unlink(tmp)


@contextlib.contextmanager
def atomic_open(path: str | Path, mode: str = "w", overwrite: bool = False,
                newline: str | None = None, encoding: str | None = "utf-8", at_once: bool = False) -> Iterator[IO]:
    """Open a temporary file beside ``path``; on success it becomes ``path``.

    Parameters
    ----------
    path : str or Path
    mode : {"w", "wb"}
    overwrite : bool
        Replace an existing ``path``; otherwise an existing file is an error
        (checked when the file is moved into place, so no race either).
    newline, encoding
        As for :func:`open` (text mode only).
    at_once : bool
        Move the file into place when it is complete even inside an
        :func:`outputs_together` block (files that must outlive a failed
        command: a study's results, the cache of compiled functions).

    Raises
    ------
    InputError
        ``path`` exists (and not ``overwrite``), or the file cannot be
        written (full disk, no permission): the message names the file and
        nothing is left behind.
    """
    path = Path(path)
    if mode not in ("w", "wb"):
        raise ValueError(f"atomic_open writes new files only: mode 'w' or 'wb', got {mode!r}")
    if not overwrite and path.exists():
        raise InputError(EXISTS, file=str(path))
    folder = path.parent if str(path.parent) else Path(".")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=folder)
    except OSError as e:
        raise InputError(f"cannot write: {e.strerror or e}", file=str(path)) from e
    try:
        kw = {} if "b" in mode else {"newline": newline, "encoding": encoding}
        with os.fdopen(fd, mode, **kw) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        # keep the permissions a plain open() would give, not mkstemp's 0600
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        with _staged_lock:
            staged = None if at_once else _staged
            if staged is not None:
                if path.resolve() in staged.targets():
                    raise InputError("is written twice by one command", file=str(path))
                staged.files.append((tmp, path, overwrite))
                tmp = None                # the block moves it into place, or removes it
        if tmp is not None:
            _place(tmp, path, overwrite)
        else:
            checkpoint("output")
    except OSError as e:
        raise InputError(f"cannot write: {e.strerror or e}", file=str(path)) from e
    finally:
        if tmp is not None and os.path.exists(tmp):
            with contextlib.suppress(OSError):
                os.unlink(tmp)


def atomic_write(path: str | Path, data: str | bytes, overwrite: bool = False, at_once: bool = False) -> None:
    """Write ``data`` (text or bytes) to ``path`` atomically; see :func:`atomic_open`."""
    with atomic_open(path, "wb" if isinstance(data, bytes) else "w", overwrite=overwrite, at_once=at_once) as fh:
        fh.write(data)


def read_toml(path: str | Path, error: type[CasadicalError] = InputError, label: str | None = None) -> dict:
    """Parse a TOML file (UTF-8; a byte-order mark is skipped); any failure is one ``error`` naming the file.

    ``label`` names the file in messages (default: ``path``).
    """
    label = str(path) if label is None else label
    try:
        raw = Path(path).read_bytes()
    except OSError as e:
        raise error(f"cannot read: {e.strerror or e}", file=label) from e
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise error(f"is not UTF-8 text (byte 0x{raw[e.start]:02x} at offset {e.start}); save it as UTF-8",
                    file=label) from e
    try:
        return tomllib.loads(text)
    except (tomllib.TOMLDecodeError, RecursionError) as e:
        raise error(f"not valid TOML: {e}", file=label) from e


def named_toml(spec: str | Path, folder: Path, missing: str) -> Path:
    """``spec`` if it is a file, else ``folder/<spec>.toml``; else an InputError naming ``spec``.

    ``missing``: the message, with ``{known}`` standing for the names the folder holds.
    """
    path = Path(spec)
    if not path.is_file():
        path = folder / f"{spec}.toml"
    if not path.is_file():
        known = ", ".join(sorted(p.stem for p in folder.glob("*.toml")))
        raise InputError(missing.format(known=known), file=str(spec))
    return path


def finite_number(x) -> bool:
    """A number read from a file (JSON or TOML; not a boolean) that is finite."""
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        return False
    try:
        return math.isfinite(x)
    except OverflowError:   # an integer too large for a float
        return False
