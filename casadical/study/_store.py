"""The results of a study: a folder that is a Parquet dataset, appended as repetitions finish.

Layout of ``RESULTS/``:

- ``part-<first>-<last>-<token>.parquet``: rows of finished repetitions, one
  file per flushed batch, each written to a temporary name and renamed
  when complete (a crash never leaves half a file);
- ``_study.json``: what the study is (protocol digest, plans, methods,
  columns, versions); ``_protocol.toml``: the protocol as given;
- ``_lock``: held while a run writes (one run per folder at a time).

Any Parquet reader takes the folder as one table (files starting with
``_`` or ``.`` are skipped by convention): ``pandas.read_parquet(RESULTS)``,
``pyarrow.parquet.read_table(RESULTS)``, ``polars.read_parquet(RESULTS/*.parquet)``.

Parquet (through pyarrow) rather than CSV or SQLite: typed columns with
exact float64 values, NaN and a map column, compressed, appendable as a
dataset of files without rewriting anything, and read directly by every
data-frame library and by Spark or DuckDB on a cluster.
"""

from __future__ import annotations

import json
import re
import secrets
import shutil
import warnings
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from .. import __version__
from ..errors import CasadicalError, CasadicalWarning, InputError
from ..runtime._files import atomic_open, atomic_write
from ..runtime._interrupts import checkpoint
from ._protocol import Study
from ._task import COLUMNS, TIME_COLUMNS

MANIFEST = "_study.json"
PROTOCOL_COPY = "_protocol.toml"
LOCK = "_lock"
FORMAT = "casadical-study"


def arrow():
    """The pyarrow modules, or a one-line error naming the optional extra."""
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        raise CasadicalError("study results are Parquet files and need pyarrow, which is not installed: "
                             "pip install 'casadical[study]'") from None
    return pa, pq


def schema():
    pa, _ = arrow()
    kinds = {"int": pa.int64(), "float": pa.float64(), "str": pa.string(),
             "map": pa.map_(pa.string(), pa.float64())}
    return pa.schema([(name, kinds[kind]) for name, kind in COLUMNS])


def manifest_of(study: Study) -> dict:
    """``_study.json``: what a results folder holds."""
    return {"format": FORMAT, "format_version": 1, "casadical_version": __version__, "name": study.name,
            "description": study.description, "protocol_file": study.path, "digest": study.digest(),
            "seed": study.seed, "repetitions": study.repetitions, "robot": study.robot.name,
            "plans": [{"name": p.name, "selector": p.selector, "poses": list(p.poses), "pool": p.pool,
                       **({"placements": p.placements, "rows_per_point": list(p.rows_per_point)} if p.placements
                          else {})} for p in study.plans],
            **({"touch": True} if study.touch is not None else {}),
            "methods": [m.name for m in study.methods], "columns": [c for c, _ in COLUMNS],
            "created": datetime.now(timezone.utc).isoformat(timespec="seconds")}


class ResultStore:
    """A results folder: create or resume it, append finished repetitions, read the table.

    Use :meth:`for_study` to write (it takes the folder's lock; close the
    store or use it as a context manager) and :meth:`open` to read.
    """

    def __init__(self, path: str | Path, manifest: dict):
        self.path = Path(path)
        self.manifest = manifest
        self._lock = None
        #: this run made the folder (a failed start removes it again: :meth:`discard_if_empty`)
        self.created = False

    # --- opening -----------------------------------------------------------------

    @classmethod
    def open(cls, path: str | Path) -> "ResultStore":
        """An existing results folder, for reading.

        Raises
        ------
        InputError
            Not a folder written by ``casadical study``.
        """
        path = Path(path)
        if not path.exists():
            raise InputError("no such results folder", file=str(path))
        manifest = _read_manifest(path)
        if manifest is None:
            raise InputError(f"is not a casadical study results folder (no {MANIFEST})", file=str(path))
        return cls(path, manifest)

    @classmethod
    def for_study(cls, path: str | Path, study: Study, force: bool = False) -> "ResultStore":
        """Create ``path`` for ``study``, or resume it if it holds results of the same protocol.

        Parameters
        ----------
        force : bool
            Discard the results a folder holds (of this or another protocol) and start over.

        Raises
        ------
        InputError
            ``path`` is a file or a folder that is not a study; it holds
            another protocol's results (without ``force``); another run
            writes to it; its parent folder does not exist.
        """
        arrow()
        path = Path(path)
        where = str(path)
        if path.exists() and not path.is_dir():
            raise InputError("exists and is not a study results folder; choose another --out", file=where)
        created = False
        if not path.exists():
            if not path.parent.exists():
                raise InputError(f"folder {str(path.parent)!r} does not exist", file=where)
            checkpoint("study-folder")
            try:
                path.mkdir()
                created = True
            except FileExistsError:     # another run made it meanwhile: the lock below says which runs
                if not path.is_dir():
                    raise InputError("exists and is not a study results folder; choose another --out",
                                     file=where) from None
        foreign = [p.name for p in path.iterdir() if not _ours(p.name)]
        if foreign and _read_manifest(path) is None:       # checked before the lock file is made
            raise InputError(f"is a folder that is not a study results folder (it holds {foreign[0]!r}); "
                             "choose another --out", file=where)
        store = cls(path, {})
        store.created = created
        store._take_lock()
        checkpoint("study-locked")
        try:
            old = _read_manifest(path)
            new = manifest_of(study)
            if old is not None and not force:
                if old.get("digest") != new["digest"]:
                    raise InputError("holds the results of another protocol (or of this one before it "
                                     "changed); choose another --out, or pass --force to discard them", file=where)
                new["created"] = old.get("created", new["created"])
                if old.get("casadical_version") != __version__:
                    warnings.warn(f"{where}: results of casadical {old.get('casadical_version')} are resumed by "
                                  f"{__version__}; rows of the two versions may differ", CasadicalWarning,
                                  stacklevel=2)
            elif old is not None:
                if foreign:
                    raise InputError(f"also holds files casadical did not write ({foreign[0]!r}); not discarding "
                                     "anything: choose another --out", file=where)
                for p in store.parts():
                    p.unlink()
            atomic_write(path / MANIFEST, json.dumps(new, indent=1), overwrite=True, at_once=True)
            atomic_write(path / PROTOCOL_COPY, study.text, overwrite=True, at_once=True)
            store.manifest = new
        except BaseException:
            store.discard_if_empty()
            store.close()
            raise
        return store

    def _take_lock(self) -> None:
        try:
            import fcntl
        except ImportError:        # no advisory locks (Windows): one run per folder is up to the user
            return
        fh = open(self.path / LOCK, "a")
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            fh.close()
            raise InputError("another casadical study is writing to this folder; wait for it or choose "
                             "another --out", file=str(self.path)) from None
        self._lock = fh

    def discard_if_empty(self) -> None:
        """Remove the folder if this run made it and holds no repetition (a failed start leaves nothing).

        Only while this run holds the lock: a run that was refused it never
        touches the folder of the run that has it.
        """
        if self._lock is not None and self.created and self.path.is_dir() and not self.parts():
            shutil.rmtree(self.path, ignore_errors=True)

    def close(self) -> None:
        """Release the folder's lock."""
        if self._lock is not None:
            self._lock.close()
            self._lock = None

    def __enter__(self) -> "ResultStore":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # --- parts -------------------------------------------------------------------

    def parts(self) -> list[Path]:
        """The Parquet files of finished repetitions, in name order."""
        return sorted(self.path.glob("part-*.parquet"))

    def finished(self) -> set[int]:
        """Repetitions whose rows are in the folder (those the backend lost, all ``lost``, are not).

        Raises
        ------
        InputError
            A part file is damaged (truncated, empty, not Parquet, other columns).
        """
        return set().union(*(_computed(_read_part(p, columns=["repetition", "status"])) for p in self.parts()))

    def append(self, rows: list[dict]) -> Path:
        """Write the rows of finished repetitions as one new part (atomically)."""
        pa, pq = arrow()
        maps = [c for c, kind in COLUMNS if kind == "map"]
        rows = [{**r, **{c: list(r[c].items()) for c in maps}} for r in rows]   # (key, value) pairs: any pyarrow
        table = pa.Table.from_pylist(rows, schema=schema())
        reps = [r["repetition"] for r in rows]
        path = self.path / f"part-{min(reps):06d}-{max(reps):06d}-{secrets.token_hex(4)}.parquet"
        with atomic_open(path, "wb", at_once=True) as fh:   # kept when the run stops: it resumes from them
            pq.write_table(table, fh)
        return path

    def read(self):
        """Every row as a pyarrow Table, by repetition then protocol order.

        A repetition found in several parts is taken from the first that
        holds it computed: a lost one is computed again by a resumed run,
        and two runs writing at once (which the lock prevents) would
        duplicate it.
        """
        pa, _ = arrow()
        parts = [_read_part(p, schema=schema()) for p in self.parts()]
        computed = [_computed(t) for t in parts]
        done = set().union(*computed)
        tables, seen = [], set()
        for k, t in enumerate(parts):
            reps = np.asarray(t.column("repetition").to_numpy())
            # not yet taken, and computed here or nowhere (lost here but computed elsewhere: those rows)
            keep = ~np.isin(reps, list(seen | (done - computed[k])))
            seen.update(reps[keep].tolist())
            tables.append(t.filter(pa.array(keep)) if not keep.all() else t)
        if not tables:
            return schema().empty_table()
        table = pa.concat_tables(tables)
        order = np.argsort(np.asarray(table.column("repetition").to_numpy()), kind="stable")
        return table.take(pa.array(order))


def differing_columns(a, b) -> list[str]:
    """Columns in which two results tables differ, row by row, times aside.

    Floats are compared bit for bit (NaN equal to NaN): runs of one study
    on any backend and number of workers must give the same values.
    """
    if a.column_names != b.column_names or a.num_rows != b.num_rows:
        return ["<shape>"]
    out = []
    for c in a.column_names:
        if c in TIME_COLUMNS:
            continue
        x, y = a.column(c), b.column(c)
        if dict(COLUMNS)[c] == "map":
            same = x.to_pylist() == y.to_pylist()
        else:
            x, y = x.to_numpy(zero_copy_only=False), y.to_numpy(zero_copy_only=False)
            same = np.array_equal(x, y, equal_nan=x.dtype.kind == "f")
        if not same:
            out.append(c)
    return out


def _read_part(path: Path, **kwargs):
    """A part file as a pyarrow Table; a damaged one is one InputError naming it and the way out."""
    pa, pq = arrow()
    try:
        table = pq.read_table(path, **kwargs)
        if "columns" in kwargs:
            missing = [c for c in kwargs["columns"] if c not in table.column_names]
            if missing:
                raise pa.ArrowInvalid(f"no column {missing[0]!r}")
        return table
    except (pa.ArrowException, OSError, KeyError, ValueError) as e:
        text = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        text = re.sub(r"^Could not open Parquet input source '[^']*': ", "", text)
        raise InputError(f"is damaged and holds no readable results ({text.rstrip('.')}); delete it to run its "
                         "repetitions again, or pass --force to discard every result and start over",
                         file=str(path)) from e


def _ours(name: str) -> bool:
    return name.startswith((".", "_")) or (name.startswith("part-") and name.endswith(".parquet"))


def _read_manifest(path: Path) -> dict | None:
    f = path / MANIFEST
    if not f.exists():
        return None
    try:
        doc = json.loads(f.read_text())
    except (OSError, ValueError) as e:
        raise InputError(f"cannot read {MANIFEST}: {e}", file=str(path)) from e
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise InputError(f"{MANIFEST} is not a casadical study manifest", file=str(path))
    return doc


__all__ = ["LOCK", "MANIFEST", "PROTOCOL_COPY", "ResultStore", "arrow", "differing_columns", "manifest_of",
           "schema"]


def _computed(table) -> set[int]:
    """Repetitions a table (of a part) holds computed, not ``lost``."""
    return {r for r, s in zip(table.column("repetition").to_pylist(), table.column("status").to_pylist())
            if s != "lost"}
