"""Run folders: provenance (versions, git commit, configuration) and atomic creation."""

from __future__ import annotations

import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
from contextlib import contextmanager
from datetime import UTC, datetime
from importlib import metadata
from pathlib import Path
from typing import Any

__all__ = [
    "KINDS",
    "check_folder_kind",
    "check_new_folder",
    "folder_kind",
    "git_commit",
    "package_versions",
    "provenance",
    "run_folder",
]

_PACKAGES = ("numpy", "scipy", "scikit-fem", "qdldl", "triangle", "meshio", "matplotlib", "torch")


def package_versions() -> dict[str, str]:
    out = {"python": platform.python_version()}
    for name in _PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
    return out


def git_commit() -> str:
    """The checkout's commit (with ``-dirty`` if it has uncommitted changes), or ``unknown``."""
    root = Path(__file__).resolve().parent.parent
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True, check=True
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=root,
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
    from .simulate import SOLVER_VERSION

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


def write_json(path: Path, data: Any) -> None:
    path.write_text(json.dumps(data, indent=1, allow_nan=False) + "\n")
