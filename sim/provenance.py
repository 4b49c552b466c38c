"""Run folders: provenance (versions, git commit, configuration), atomic creation, and the one
way every run-folder file is written.

Every file a command writes into a run folder goes through :func:`atomic_write` (a temporary
file in the same folder, then ``os.replace``: a kill leaves the old file or the new one, never
half of one); :func:`write_if_changed` leaves a file alone when it holds the text already (a
re-run that changes nothing rewrites nothing). JSON is strict (``allow_nan=False``): every
writer of JSON text (files, standard output) makes it with :func:`json_text`, which puts the
values through :func:`json_safe` first (NaN and infinities -> None, numpy scalars -> Python
numbers), so a non-finite value is written as null, never as a crash or as ``Infinity``.
"""

from __future__ import annotations

import json
import math
import os
import platform
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from .metrics import SOLVER_VERSION

__all__ = [
    "KINDS",
    "REPO",
    "atomic_write",
    "check_folder_kind",
    "check_new_folder",
    "finite_or_none",
    "folder_kind",
    "git_commit",
    "json_safe",
    "json_text",
    "nan_if_none",
    "package_versions",
    "provenance",
    "recorded_path",
    "replacing",
    "run_folder",
    "sha256_file",
    "write_if_changed",
    "write_json",
]

_PACKAGES = ("numpy", "scipy", "scikit-fem", "qdldl", "triangle", "meshio", "matplotlib", "torch")
#: the repository's root: a path inside it is recorded relative to it (``recorded_path``)
REPO = Path(__file__).resolve().parents[1]


def recorded_path(path: str | Path) -> str:
    """``path`` as a record names it: relative to the repository when inside it (a POSIX
    path, the same on every checkout), else absolute."""
    path = Path(path).resolve()
    try:
        return path.relative_to(REPO).as_posix()
    except ValueError:
        return str(path)


def sha256_file(path: str | Path) -> str:
    """The sha256 of a file's bytes (hex), read in 1 MiB chunks."""
    import hashlib

    h = hashlib.sha256()
    with Path(path).open("rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def package_versions() -> dict[str, str]:
    from importlib import metadata  # here: ~0.05 s that `fingertip simulate` without --out skips

    out = {"python": platform.python_version()}
    for name in _PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
    return out


def git_commit() -> str:
    """The checkout's commit (with ``-dirty`` if it has uncommitted changes), or ``unknown``."""
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True, check=True
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=REPO,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return commit + ("-dirty" if dirty else "")


#: the kinds of folder the commands make (``meta.json``'s ``"kind"``), in words
KINDS = {
    "simulate": "simulation result (fingertip simulate --out)",
    "sweep": "sweep (fingertip sweep)",
    "train": "surrogate training run (fingertip train)",
    "optimize": "search run (fingertip optimize / run)",
}


def provenance(
    config: dict[str, Any], seed: int | None = None, kind: str | None = None
) -> dict[str, Any]:
    """What a run folder's ``meta.json`` records; ``kind`` (``KINDS``) says which command made
    the folder, so that the others refuse it."""
    return {
        **({"kind": kind} if kind is not None else {}),
        "created_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        "command": " ".join(sys.argv),
        "git_commit": git_commit(),
        "solver_version": SOLVER_VERSION,
        "packages": package_versions(),
        "platform": platform.platform(),
        "seed": seed,
        "config": config,
    }


def _read_dict(path: Path) -> dict[str, Any] | None:
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def folder_kind(path: str | Path) -> str | None:
    """Which command made the folder ``path`` (a key of ``KINDS``): ``meta.json``'s ``"kind"``,
    else (folders made before the marker) recognised by their files; None for a folder no
    command made, an empty one or none."""
    path = Path(path)
    if not path.is_dir():
        return None
    kind = (_read_dict(path / "meta.json") or {}).get("kind")
    if kind in KINDS:
        return kind
    if (path / "result.json").is_file():
        return "simulate"
    if (path / "model.safetensors").is_file() and (path / "history.json").is_file():
        return "train"
    config = _read_dict(path / "config.json") or {}
    if "studies" in config or (path / "study.db").is_file():
        return "optimize"
    if {"space", "sampler"} <= set(config) or (path / "records").is_dir():
        return "sweep"  # also a folder holding only the records of a sweep (README)
    return None


def _check_parents(path: Path, option: str) -> None:
    from .errors import DesignError

    for parent in path.parents:
        if parent.exists():
            if not parent.is_dir():
                raise DesignError(option, f"{parent} is a file, not a folder")
            return


def check_folder_kind(path: str | Path, kind: str, option: str = "--out") -> None:
    """Refuse ``path`` in one line (``DesignError`` naming ``option``) unless it is absent,
    empty, or a folder of ``kind`` (``KINDS``): a command never writes into another command's
    folder, or into a folder of other files."""
    from .errors import DesignError

    path = Path(path)
    _check_parents(path, option)
    if not path.exists():
        return
    if not path.is_dir():
        raise DesignError(option, f"{path} is a file, not a folder")
    if not any(path.iterdir()):
        return
    found = folder_kind(path)
    if found == kind:
        return
    what = f"a {KINDS[found]}" if found else "files no fingertip command made"
    raise DesignError(option, f"{path} holds {what}, not a {KINDS[kind]}; choose another folder")


def check_new_folder(path: str | Path) -> None:
    """Raise ``FileExistsError`` if ``path`` exists and is not an empty folder (runs never
    overwrite)."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise FileExistsError(f"{path} is a file, not a folder; choose a new folder")
    if path.exists() and any(path.iterdir()):
        found = folder_kind(path)
        what = f" (a {KINDS[found]})" if found else ""
        raise FileExistsError(f"{path} exists and is not empty{what}; choose a new folder")
    for parent in path.parents:
        if parent.exists():
            if not parent.is_dir():
                raise FileExistsError(f"{parent} is a file, not a folder; choose a new folder")
            break


@contextmanager
def run_folder(path: str | Path):
    """Yield a temporary folder beside ``path``; rename it to ``path`` when the block succeeds.

    An existing, non-empty ``path`` is never overwritten (``FileExistsError``).
    """
    path = Path(path)
    check_new_folder(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", dir=path.parent))
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    if path.exists():
        path.rmdir()
    os.replace(tmp, path)


# ---------------------------------------------------------------------------- writing files
@contextmanager
def replacing(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path in ``path``'s folder; when the block succeeds it replaces ``path``
    (``os.replace``, atomic), when it fails it is removed. For writers that need a file name
    (safetensors); text and bytes: :func:`atomic_write`."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        yield tmp
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    os.replace(tmp, path)


def atomic_write(path: str | Path, data: str | bytes) -> None:
    """Write ``data`` (text is UTF-8) to ``path`` atomically: the file is the old one or the
    new one, never half of one, whenever the process is killed."""
    with replacing(path) as tmp:
        if isinstance(data, bytes):
            tmp.write_bytes(data)
        else:
            tmp.write_text(data, encoding="utf-8")


def write_if_changed(
    path: str | Path, data: str | bytes, keep: Callable[[str], bool] | None = None
) -> bool:
    """Write ``data`` to ``path`` atomically unless the file holds it already, byte for byte
    (or ``keep``, given the old text, says it is to stay). Returns whether it wrote."""
    path = Path(path)
    new = data.encode() if isinstance(data, str) else data
    if path.is_file():
        old = path.read_bytes()  # exact bytes: csv's "\r\n" line ends included
        if old == new or (keep is not None and keep(old.decode(errors="replace"))):
            return False
    atomic_write(path, new)
    return True


def json_safe(value: Any) -> Any:
    """``value`` as strict JSON can hold it, recursively: a non-finite float (NaN, inf) becomes
    None, a numpy scalar or array a Python number or list, a tuple a list; anything else is
    left as it is (a mapping's keys too)."""
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    if hasattr(value, "tolist") and type(value).__module__ == "numpy":
        return json_safe(value.tolist())  # numpy scalar -> int/float/bool, array -> list
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def finite_or_none(x: Any) -> float | None:
    """A number as a JSON float: None for None, NaN and infinities (the scalar form of
    :func:`json_safe`; ints and numpy numbers become floats)."""
    return None if x is None else json_safe(float(x))


def nan_if_none(x: Any) -> float:
    """The inverse of :func:`finite_or_none` for a value read back: None -> NaN."""
    return math.nan if x is None else float(x)


def json_text(data: Any, indent: int | None = None, **options: Any) -> str:
    """``data`` as strict JSON text: the one way this project writes JSON. Values go through
    :func:`json_safe` (a NaN or infinity becomes null), then ``json.dumps`` with
    ``allow_nan=False``, so anything else that is not JSON raises instead of being written;
    ``options``: more ``json.dumps`` arguments (``sort_keys``, ``ensure_ascii``...)."""
    return json.dumps(json_safe(data), indent=indent, allow_nan=False, **options)


def write_json(path: str | Path, data: Any, indent: int | None = 1) -> None:
    """Write ``data`` as strict JSON (:func:`json_text`) to ``path`` atomically;
    ``indent=None``: one line."""
    text = json_text(data, indent=indent)
    atomic_write(path, text + "\n" if indent is not None else text)
