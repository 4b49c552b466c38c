"""Where a search run keeps its Optuna studies: a journal file in the run folder by default, or
a database several workers share (``--storage``).

A storage is named by one string, recorded in ``config.json`` and accepted by
``optuna-dashboard`` as it is: a file path ending in ``.log`` is an Optuna journal file
(``JournalStorage``/``JournalFileBackend``, one JSON line per operation), anything of the
form ``scheme://...`` a database URL (``RDBStorage``: SQLite, PostgreSQL, ...).

Why a journal by default: the search writes every trial of every study (~600 per round), and
through SQLite and SQLAlchemy's ORM each costs a transaction of ~20 rows: 600 trials took
18.3 s (30.5 ms a trial) against 0.56 s (0.9 ms) for journal lines, on the quiet 2-core
machine (``python benchmarks/bench_storage.py``, 2026-11-23; under load 53.6 s against 4.1 s,
and ``PRAGMA synchronous=OFF`` only got SQLite to 41 s: the ORM, not the disk). Run folders
made before keep their ``study.db``: ``config.json`` names it, and they resume and plot from it.
"""

from __future__ import annotations

import re
import time
from pathlib import Path
from typing import Any

from sim.errors import DesignError

__all__ = ["JOURNAL_NAME", "check_storage", "dashboard_command", "default_storage",
           "is_database_url", "open_storage", "repair_journal", "storage_file"]  # fmt: skip

#: the run folder's own journal file (``optuna-dashboard runs/NAME/study.log``)
JOURNAL_NAME = "study.log"
_URL = re.compile(r"^[A-Za-z][A-Za-z0-9+.\-]*://")
_EXAMPLE = (
    "a journal file path (e.g. runs/shared/study.log) or a database URL "
    "(e.g. sqlite:///path/study.db, postgresql+psycopg://user:password@host/database)"
)


def default_storage(out: Path) -> str:
    """The journal file of run folder ``out`` (absolute, as ``config.json`` records it)."""
    return str((out / JOURNAL_NAME).resolve())


def is_database_url(spec: str) -> bool:
    """True for ``scheme://...`` (an ``RDBStorage`` URL), False for a journal file path."""
    return bool(_URL.match(spec))


def storage_file(spec: str) -> Path | None:
    """The file a storage lives in (a journal, or an SQLite database), None for a server's."""
    if not is_database_url(spec):
        return Path(spec)
    prefix = "sqlite:///"
    return Path(spec[len(prefix) :]) if spec.startswith(prefix) else None


def dashboard_command(spec: str) -> str:
    """The command that opens the studies of ``spec`` in optuna-dashboard."""
    return f"optuna-dashboard {spec}"


def repair_journal(path: Path) -> str | None:
    """Make a journal left by a killed process appendable again; what was done, or None.

    Optuna appends each operation as one line, under a lock file beside the journal. A kill
    in the middle of an append leaves a last line without its newline (Optuna skips it when
    reading, but the next append would glue onto it and corrupt both) and may leave the lock
    (Optuna breaks a stale one only after 30 s) or the renamed file of a lock being released.
    For a run folder's own journal, which one process writes, all are safe to undo: the cut
    line is dropped (the search asks a cut batch again, identically) and the lock files
    removed."""
    done = []
    lock = Path(f"{path}.lock")
    if lock.exists() or lock.is_symlink():
        lock.unlink()
        done.append("removed a stale lock")
    # Optuna releases its lock by renaming it to <lock><uuid>.rename, then deleting that: a
    # kill in between leaves the renamed file
    for left in path.parent.glob(f"{path.name}.lock*.rename"):
        left.unlink()
        done.append("removed a released lock's leftover")
    if path.is_file():
        with path.open("rb+") as fh:
            data = fh.read()
            if data and not data.endswith(b"\n"):
                fh.truncate(data.rfind(b"\n") + 1)
                done.append("dropped a cut last line")
    return "; ".join(done) or None


def open_storage(spec: str) -> Any:
    """The Optuna storage named by ``spec``: an ``RDBStorage`` URL as it is (Optuna opens it),
    or a ``JournalStorage`` on the file ``spec``."""
    if is_database_url(spec):
        return spec
    import warnings

    import optuna
    from optuna.storages.journal import JournalFileBackend

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
        return optuna.storages.JournalStorage(JournalFileBackend(spec))


def check_storage(spec: str) -> None:
    """Open the storage ``spec`` once (creating a database's tables if needed), or refuse it
    in one line naming ``--storage``: checked before any FE work or folder is made. Workers
    starting together on a new database race to create its tables: the losers try again."""
    if not is_database_url(spec):
        if not spec.endswith(".log"):
            raise DesignError(
                "--storage", f"{spec!r} is neither a journal file (*.log) nor a database URL "
                f"({_EXAMPLE})"
            )  # fmt: skip
        _check_journal(Path(spec))
        return
    import optuna
    from sqlalchemy.engine import make_url
    from sqlalchemy.exc import ArgumentError, IntegrityError, ProgrammingError, SQLAlchemyError

    try:
        make_url(spec)
    except ArgumentError:
        raise DesignError("--storage", f"{spec!r} is not a storage ({_EXAMPLE})") from None
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    for attempt in range(5):
        try:
            storage = optuna.storages.RDBStorage(spec)
            break
        except (IntegrityError, ProgrammingError) as exc:  # another worker's table or type
            if attempt == 4:
                raise DesignError("--storage", f"cannot open {spec}: {_first_line(exc)}") from None
            time.sleep(0.2 * (attempt + 1))
        except (SQLAlchemyError, ImportError, ValueError, OSError, RuntimeError) as exc:
            raise DesignError("--storage", f"cannot open {spec}: {_first_line(exc)}") from None
    storage.remove_session()
    storage.engine.dispose()


def _check_journal(path: Path) -> None:
    """A journal file must sit in an existing folder and be a journal if it exists."""
    if not path.parent.is_dir():
        raise DesignError("--storage", f"cannot open {path}: no folder {path.parent} ({_EXAMPLE})")
    if path.is_dir():
        raise DesignError("--storage", f"{path} is a folder, not a journal file ({_EXAMPLE})")
    if path.is_file():
        with path.open("rb") as fh:
            head = fh.read(16)
        if head.startswith(b"SQLite format 3"):
            raise DesignError(
                "--storage", f"{path} is an SQLite database: give it as sqlite:///{path}"
            )
        if head and not head.startswith(b"{"):
            raise DesignError("--storage", f"{path} is not an Optuna journal file ({_EXAMPLE})")


def _first_line(exc: BaseException) -> str:
    return (str(exc).strip().splitlines() or [type(exc).__name__])[0]
