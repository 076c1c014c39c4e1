"""Compiled model functions, kept on disk between runs.

A per-pose model Function (:meth:`casadical.model._symbolic.Model.per_pose_function`)
is compiled once per machine: CasADi writes its C source, the system C
compiler turns it into a shared library, and the library is stored in the
cache folder under a key that changes whenever the code it would contain
could change:

- the Function's serialized expression graph (which the C source is
  generated from, so the same graph always gives the same source; hashing
  it costs about a quarter of generating the source);
- the CasADi version (its code generator);
- the compiler (resolved path, size and modification time) and its flags.

Every later run loads the library (well under 1 ms) instead of compiling
it (0.2-3 s per Function).

A first run need not wait for the optimised code (:func:`load_all` with
``quick``, what the model's superset asks for when a core is free,
:func:`spare_core`): the Functions are compiled
without optimisation (``-O0``: a fifth of ``-O1``'s compile time, 1.4x its
evaluation time, the same bits), used at once, and compiled again with
:data:`FLAGS` in the background, one compiler process each; the run takes
the optimised code when it is ready (:func:`upgraded`) and only that goes
into the cache. No compiler outlives the process: at its end the run waits
for those still running (:func:`finish`; killed instead when the process
ends on an error or a signal), so the next run finds them in the cache. Each
compiler runs in a process group of its own, which is killed whole: the
driver's own children (cc1, the assembler) go with it.

The folder is ``$CASADICAL_CACHE`` if set, else ``$XDG_CACHE_HOME/casadical``
or ``~/.cache/casadical``. An entry is one file,
``NAME-KEY-DIGEST.so``, where DIGEST is the hash of the library's own bytes:
it is written under a temporary name and renamed into place when complete,
so concurrent runs never see half a file, two runs compiling the same
Function end with one entry, and an entry whose bytes no longer match its
name (a damaged disk, a hand edit) is deleted and compiled again. The
folder is kept under ``$CASADICAL_CACHE_MAX_MB`` megabytes (default 256) by
removing the entries used least recently. ``casadical cache --info`` and
``--clear`` show and empty it.
"""

from __future__ import annotations

import contextlib
import hashlib
import math
import os
import shutil
import signal
import subprocess
import tempfile
import threading
import time
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import CasadicalError, InputError, SettingError
from ..runtime._files import atomic_write
from ..runtime._interrupts import checkpoint

if TYPE_CHECKING:      # casadi is imported where a function is compiled: the other commands start without it
    import casadi as ca

#: flags of every compilation: -O1 compiles the large Jacobian and Gauss-Newton Functions in about
#: 60% of -O2's time and evaluates them as fast (benchmarks/speed/bench_calibrate_cli.py)
FLAGS = ("-O1", "-fPIC", "-shared")
#: flags of the quick compile a first run uses while the optimised one runs in the background (the UR10's
#: full-pose Jacobian of the superset with the torques, 12,688 instructions: 0.35 s of gcc's CPU against 1.94 s
#: at -O1, evaluated in 15.7 against 11.4 us a pose; benchmarks/speed/bench_first_run.py)
QUICK_FLAGS = ("-O0", "-fPIC", "-shared")
#: a Function below this many instructions is compiled with FLAGS at once even when asked to be quick: its
#: -O1 compile takes about 0.1 s (the superset's fk and probe, 531-1,413 instructions: 0.08-0.14 s), beside a
#: large Function's quick compile
QUICK_MIN_INSTRUCTIONS = 3000
DEFAULT_MAX_MB = 256.0
_SUFFIX = ".so"
_PART = ".part"
#: a partial file older than this belongs to a run that was killed
_STALE_PART_S = 3600.0


_LISTENERS: list = []


@contextlib.contextmanager
def announcing(say):
    """Within the block, ``say(text)`` hears of the first compilation that takes seconds before it starts (the
    command line's progress line: a first run must not look as if it hangs). Once per block: a run compiles
    the parts of the model it needs as it needs them (a diagnosis: those with and without the gravity
    torques, of positions and of full poses), and the notice said at the first covers them all."""
    said = []

    def once(text: str) -> None:
        if not said:
            said.append(text)
            say(text)
    _LISTENERS.append(once)
    try:
        yield
    finally:
        _LISTENERS.remove(once)


def announce(text: str) -> None:
    """Tell the innermost :func:`announcing` listener, if any."""
    if _LISTENERS:
        _LISTENERS[-1](text)


class CompileError(CasadicalError):
    """The C compiler is missing or failed (the caller falls back to CasADi's virtual machine)."""


def cache_dir() -> Path:
    """The cache folder (created only when the first entry is written)."""
    env = os.environ.get("CASADICAL_CACHE")
    if env:
        return Path(env).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "casadical"


def max_bytes() -> int:
    """Size limit of the cache folder (``$CASADICAL_CACHE_MAX_MB``, default 256 MB).

    Raises
    ------
    SettingError
        The variable is not a finite number >= 0 (as for its siblings
        ``CASADICAL_THREADS`` and ``CASADICAL_EVAL_THREADS``).
    """
    text = os.environ.get("CASADICAL_CACHE_MAX_MB")
    if text is None or not text.strip():
        return int(DEFAULT_MAX_MB * 1e6)
    try:
        mb = float(text)
    except ValueError:
        mb = math.nan
    if not (math.isfinite(mb) and mb >= 0):
        raise SettingError(f"environment variable CASADICAL_CACHE_MAX_MB must be a number of megabytes >= 0 "
                           f"(default {DEFAULT_MAX_MB:g}); got {text!r}")
    return int(mb * 1e6)


def jit_setting() -> bool:
    """``$CASADICAL_JIT``: automatic compilation on (``1``, the default) or off (``0``).

    Raises
    ------
    SettingError
        Any other value (``off`` would otherwise leave it on).
    """
    text = os.environ.get("CASADICAL_JIT", "1").strip().lower()
    if text in ("1", "", "true", "yes", "on"):
        return True
    if text in ("0", "false", "no", "off"):
        return False
    raise SettingError(f"environment variable CASADICAL_JIT must be 1 (compile model functions, the default) or 0 "
                       f"(never); got {os.environ['CASADICAL_JIT']!r}")


@cache
def compiler() -> str | None:
    """The C compiler on PATH (gcc, else cc), or None."""
    return shutil.which("gcc") or shutil.which("cc")


@cache
def _compiler_id(cc: str) -> str:
    real = os.path.realpath(cc)
    st = os.stat(real)
    return f"{real}:{st.st_size}:{st.st_mtime_ns}"


def entry_key(fun: ca.Function, cc: str) -> str:
    """Hash of everything the compiled library depends on (see the module docstring)."""
    h = hashlib.sha256()
    import casadi as ca

    for part in ("casadical-jit-1", ca.__version__, _compiler_id(cc), " ".join(FLAGS), fun.name()):
        h.update(part.encode() + b"\0")
    h.update(fun.serialize().encode())
    return h.hexdigest()[:32]


def spare_core() -> bool:
    """A core is free for a background compile: two cores or more, and the load average of the last minute at
    most the number of cores less one. On a loaded machine the background compile only adds the quick one's
    CPU (README job, load 4 on 2 cores: 9.5 s of CPU against 7.5 s, the wall the same), so the optimised code
    is compiled at once there, as before."""
    n = os.cpu_count() or 1
    try:
        load = os.getloadavg()[0]
    except OSError:
        return False
    return n >= 2 and load <= n - 1


def load(fun: ca.Function, compile: bool = True) -> ca.Function | None:
    """``fun`` as compiled code: from the cache, else compiled now and stored.

    Parameters
    ----------
    fun : casadi.Function
        An SX Function (its name becomes the symbol in the library).
    compile : bool
        Compile on a cache miss; with False a miss returns None.

    Raises
    ------
    CompileError
        No compiler, or the compiler failed (with ``compile=True``).
    KeyboardInterrupt
        Ctrl-C while the compiler ran; nothing is left in the cache.
    """
    return load_all([fun], compile)[0]


def load_all(funs: list[ca.Function], compile: bool = True, before=None, quick: bool = False
             ) -> list[ca.Function | None]:
    """:func:`load` of several Functions; those missing from the cache are compiled side by side (one compiler
    process each), and ``before(missing)`` is called with them first (to say that it takes a while).

    ``quick``: a missing Function is compiled with :data:`QUICK_FLAGS` (not kept) and again with
    :data:`FLAGS` in the background (kept in the cache once done; :func:`upgraded` gives it)."""
    cc = compiler()
    if cc is None:
        if compile:
            raise CompileError("no C compiler (gcc or cc) on PATH")
        return [None] * len(funs)
    out: list = []
    missing: list[tuple[int, ca.Function, str]] = []
    for fun in funs:
        try:
            key = entry_key(fun, cc)
        except (RuntimeError, OSError) as e:   # a Function CasADi cannot serialize, a compiler gone meanwhile
            if compile:
                raise CompileError(f"cannot key {fun.name()} for the cache: {e}") from e
            out.append(None)
            continue
        out.append(_lookup(fun.name(), key))
        if out[-1] is None and compile:
            missing.append((len(out) - 1, fun, key))
    if missing:
        if before is not None:
            before([f for _, f, _ in missing])
        compiled = (_compile_quick if quick else _compile)([(f, key) for _, f, key in missing], cc)
        for (k, _, _), done in zip(missing, compiled):
            out[k] = done
    return out


def _lookup(name: str, key: str) -> ca.Function | None:
    """The cache's entry of ``name`` under ``key``, loaded (None: no valid entry)."""
    with contextlib.suppress(OSError):
        for path in sorted(cache_dir().glob(f"{name}-{key}-*{_SUFFIX}")):
            loaded = _load_entry(path, name)
            if loaded is not None:
                return loaded
    return None


def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()[:16]


def _load_entry(path: Path, name: str) -> ca.Function | None:
    """A verified entry loaded; a damaged one is deleted (None)."""
    import casadi as ca

    try:
        ok = _digest(path.read_bytes()) == path.stem.rsplit("-", 1)[-1]
    except OSError:  # removed meanwhile by another run's clean-up
        return None
    if ok:
        try:
            fun = ca.external(name, str(path))
        except RuntimeError:
            ok = False
    if not ok:
        with contextlib.suppress(OSError):
            path.unlink()
        return None
    with contextlib.suppress(OSError):
        os.utime(path)  # most recently used: kept longest
    return fun


def _compile(items: list[tuple[ca.Function, str]], cc: str) -> list[ca.Function]:
    """Compile in a private temporary folder (one compiler process per Function, side by side), store each
    library atomically, load them."""
    import casadi as ca

    folder = cache_dir()
    with tempfile.TemporaryDirectory(prefix="casadical-jit-") as tmp:
        jobs = []
        try:
            for fun, _ in items:
                jobs.append(_start(cc, FLAGS, _generate(fun, tmp), os.path.join(tmp, fun.name() + _SUFFIX)))
            checkpoint("compile")     # where a test has the process signal itself while the compilers run
            _wait([p for p, _ in jobs], cc)
        finally:      # an error or an interrupt: no compiler outlives the call
            for p, _ in jobs:
                _kill(p)
        out = []
        for (fun, key), (_, library) in zip(items, jobs):
            data = Path(library).read_bytes()
            _store(folder, f"{fun.name()}-{key}-{_digest(data)}{_SUFFIX}", data)
            try:
                out.append(ca.external(fun.name(), library))  # loaded before the temporary folder goes
            except RuntimeError as e:
                raise CompileError(f"cannot load the compiled {fun.name()}: {e}") from e
        return out


@dataclass
class _Background:
    """An optimised compile running in the background: its Function, cache key, process and folder."""

    fun: "ca.Function"
    key: str
    process: subprocess.Popen
    library: str
    folder: str
    owner: int          # the process that started it (a forked child has no say over it)
    cache: Path         # the cache folder when it started (its entry goes there)


_PENDING: dict[int, _Background] = {}       # by id() of the Function (held by the entry)
_PENDING_LOCK = threading.Lock()
_AT_EXIT = [False]


def _compile_quick(items: list[tuple[ca.Function, str]], cc: str) -> list[ca.Function]:
    """Compile with :data:`QUICK_FLAGS` now (side by side; nothing stored), then start each Function's
    compile with :data:`FLAGS` in the background, in the same private folder. A Function below
    :data:`QUICK_MIN_INSTRUCTIONS` is compiled with :data:`FLAGS` at once (stored), beside the others."""
    import casadi as ca

    folders, jobs = [], []
    quick = [fun.n_instructions() >= QUICK_MIN_INSTRUCTIONS for fun, _ in items]
    try:
        for (fun, _), q in zip(items, quick):
            folder = tempfile.mkdtemp(prefix="casadical-jit-")
            folders.append(folder)
            c_file = _generate(fun, folder)
            jobs.append((_start(cc, QUICK_FLAGS if q else FLAGS, c_file,
                                os.path.join(folder, fun.name() + ("-quick" if q else "") + _SUFFIX)), c_file))
        checkpoint("compile")     # where a test has the process signal itself while the compilers run
        _wait([p for (p, _), _ in jobs], cc)
        out = []
        for (fun, key), q, ((_, library), _) in zip(items, quick, jobs):
            if not q:
                data = Path(library).read_bytes()
                _store(cache_dir(), f"{fun.name()}-{key}-{_digest(data)}{_SUFFIX}", data)
            try:
                out.append(ca.external(fun.name(), library))
            except RuntimeError as e:
                raise CompileError(f"cannot load the compiled {fun.name()}: {e}") from e
    except BaseException:
        for (p, _), _ in jobs:
            _kill(p)
        for folder in folders:
            shutil.rmtree(folder, ignore_errors=True)
        raise
    for (fun, key), q, folder, (_, c_file) in zip(items, quick, folders, jobs):
        if not q:
            shutil.rmtree(folder, ignore_errors=True)
            continue
        library = os.path.join(folder, fun.name() + _SUFFIX)
        try:
            process, _ = _start(cc, FLAGS, c_file, library)
        except CompileError:        # the quick code serves this run; the next compiles again
            shutil.rmtree(folder, ignore_errors=True)
            continue
        with _PENDING_LOCK:
            _PENDING[id(fun)] = _Background(fun, key, process, library, folder, os.getpid(), cache_dir())
            if not _AT_EXIT[0]:
                import atexit

                atexit.register(finish)
                _AT_EXIT[0] = True
    return out


def _generate(fun: ca.Function, folder: str) -> str:
    """``fun``'s C source in ``folder``; its path."""
    import casadi as ca

    gen = ca.CodeGenerator(f"{fun.name()}.c", {"with_header": False})
    gen.add(fun)
    return gen.generate(folder + os.sep)


def _start(cc: str, flags: tuple[str, ...], c_file: str, library: str) -> tuple[subprocess.Popen, str]:
    """A compiler process, a child Python waits for (CasADi's own JIT runs the compiler through system(), which
    ignores Ctrl-C in the caller), in a process group of its own: the driver (gcc) starts the compiler proper
    (cc1) and the assembler as its children, and :func:`_kill` stops them all (killing the driver alone left
    cc1 running after the command had ended). A terminal's Ctrl-C then reaches this process alone, which
    stops the group."""
    try:
        p = subprocess.Popen([cc, *flags, c_file, "-o", library], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             text=True, process_group=0)
    except OSError as e:
        raise CompileError(f"cannot run {cc}: {e}") from e
    return p, library


def _wait(processes: list[subprocess.Popen], cc: str) -> None:
    for p in processes:
        _, err = p.communicate()
        if p.returncode == -signal.SIGINT:
            raise KeyboardInterrupt  # the compiler alone got the Ctrl-C
        if p.returncode:
            raise CompileError(f"{cc} failed: {(err or '').strip()[-200:]}")


def _kill(p: subprocess.Popen) -> None:
    """Stop a compiler with every process of its group (its children too, should the driver have ended without
    them). The group's id is the driver's: until the driver is reaped here no other process can have it."""
    if p.returncode is None:
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(p.pid, signal.SIGKILL)
        p.wait()


def pending(fun: ca.Function) -> bool:
    """An optimised compile of ``fun`` runs in the background (started by this process)."""
    with _PENDING_LOCK:
        job = _PENDING.get(id(fun))
        return job is not None and job.owner == os.getpid()


def upgraded(fun: ca.Function, wait: bool = False) -> ca.Function | None:
    """``fun``'s optimised code once its background compile is done (stored in the cache, loaded), else None
    (still running, failed, or none started); ``wait``: wait for it."""
    with _PENDING_LOCK:
        job = _PENDING.get(id(fun))
        if job is None or job.owner != os.getpid():
            return None
        if job.process.poll() is None and not wait:
            return None
        del _PENDING[id(fun)]
    return _collect(job)


def _collect(job: _Background) -> ca.Function | None:
    """A finished (or, waited for) background compile: stored and loaded; None if the compiler failed."""
    import casadi as ca

    try:
        job.process.communicate()
        if job.process.returncode:
            return None
        data = Path(job.library).read_bytes()
        _store(job.cache, f"{job.fun.name()}-{job.key}-{_digest(data)}{_SUFFIX}", data)
        try:
            return ca.external(job.fun.name(), job.library)   # loaded before the folder goes
        except RuntimeError:
            return None
    except OSError:
        return None
    finally:
        _kill(job.process)
        shutil.rmtree(job.folder, ignore_errors=True)


def finish(kill: bool | None = None) -> int:
    """End this process's background compiles: wait for each and keep it in the cache, or (``kill``; by
    default when the command line ends on an error or a signal) stop them. Runs at the process's exit.

    Returns
    -------
    int
        Number of compiles kept in the cache.
    """
    if kill is None:
        from ..runtime import _interrupts as interrupts

        kill = bool(interrupts._exit_code or interrupts.late_exit_code())
    with _PENDING_LOCK:
        jobs = [j for j in _PENDING.values() if j.owner == os.getpid()]
        for j in jobs:
            del _PENDING[id(j.fun)]
    kept = 0
    try:
        for j in jobs:
            if kill:
                _kill(j.process)
                shutil.rmtree(j.folder, ignore_errors=True)
            elif _collect(j) is not None:
                kept += 1
    except BaseException:      # a Ctrl-C while waiting: no compiler outlives the process
        for j in jobs:
            _kill(j.process)
            shutil.rmtree(j.folder, ignore_errors=True)
        raise
    return kept


def _store(folder: Path, filename: str, data: bytes) -> None:
    """Write an entry atomically (skipped if the folder is not writable); same name = same bytes, so a
    concurrent writer's rename is harmless."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        atomic_write(folder / filename, data, overwrite=True, at_once=True)   # its temporary files end in _PART
    except (OSError, InputError):
        return
    prune(folder)


def _entries(folder: Path) -> list[tuple[float, int, Path]]:
    out = []
    with contextlib.suppress(OSError):
        for p in folder.iterdir():
            if p.suffix == _SUFFIX or p.name.endswith(_PART):
                with contextlib.suppress(OSError):
                    st = p.stat()
                    out.append((st.st_mtime, st.st_size, p))
    return out


def prune(folder: Path | None = None, limit: int | None = None) -> int:
    """Remove the least recently used entries beyond ``limit`` bytes, and stale partial files.

    Returns
    -------
    int
        Number of files removed.
    """
    folder = cache_dir() if folder is None else folder
    limit = max_bytes() if limit is None else limit
    now, total, removed = time.time(), 0, 0
    for mtime, size, p in sorted(_entries(folder), key=lambda e: e[0], reverse=True):
        if p.name.endswith(_PART):
            drop = now - mtime > _STALE_PART_S
        else:
            total += size
            drop = total > limit
        if drop:
            with contextlib.suppress(OSError):
                p.unlink()
                removed += 1
    return removed


@dataclass
class CacheInfo:
    """What the cache folder holds."""

    folder: Path
    entries: int
    bytes: int
    max_bytes: int
    compiler: str | None
    casadi_version: str

    def to_dict(self) -> dict:
        return {"folder": str(self.folder), "entries": self.entries, "bytes": self.bytes,
                "max_bytes": self.max_bytes, "compiler": self.compiler, "flags": list(FLAGS),
                "casadi_version": self.casadi_version}


def info() -> CacheInfo:
    """Folder, number and total size of the entries, limit, compiler."""
    import casadi as ca

    entries = [e for e in _entries(cache_dir()) if e[2].suffix == _SUFFIX]
    return CacheInfo(cache_dir(), len(entries), sum(e[1] for e in entries), max_bytes(), compiler(),
                     ca.__version__)


def clear() -> int:
    """Remove every entry (and partial file) of the cache folder; other files are left alone.

    Returns
    -------
    int
        Number of files removed.
    """
    removed = 0
    for _, _, p in _entries(cache_dir()):
        with contextlib.suppress(OSError):
            p.unlink()
            removed += 1
    return removed
