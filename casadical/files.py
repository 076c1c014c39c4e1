"""Writing files safely: atomically, never over a user's file by accident.

Every file casadical writes goes through :func:`atomic_write` (or
:func:`atomic_open`): the content is written to a temporary file in the
same folder and moved into place only when complete, so an interrupted run
or a full disk never leaves a half-written file, and an existing file is
replaced only when the caller says so.
"""

from __future__ import annotations

import contextlib
import math
import os
import tempfile
import tomllib
from pathlib import Path
from typing import IO, Iterator

from .errors import CasadicalError, InputError

EXISTS = "exists already; choose another name or pass --force to replace it"


@contextlib.contextmanager
def atomic_open(path: str | Path, mode: str = "w", overwrite: bool = False,
                newline: str | None = None, encoding: str | None = "utf-8") -> Iterator[IO]:
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
        if overwrite:
            os.replace(tmp, path)
        else:
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


def atomic_write(path: str | Path, data: str | bytes, overwrite: bool = False) -> None:
    """Write ``data`` (text or bytes) to ``path`` atomically; see :func:`atomic_open`."""
    with atomic_open(path, "wb" if isinstance(data, bytes) else "w", overwrite=overwrite) as fh:
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
