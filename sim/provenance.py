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

__all__ = ["check_new_folder", "git_commit", "package_versions", "provenance", "run_folder"]

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


def provenance(config: dict[str, Any], seed: int | None = None) -> dict[str, Any]:
    """What a run folder's ``meta.json`` records."""
    from .simulate import SOLVER_VERSION

    return {
        "created_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        "command": " ".join(sys.argv),
        "git_commit": git_commit(),
        "solver_version": SOLVER_VERSION,
        "packages": package_versions(),
        "platform": platform.platform(),
        "seed": seed,
        "config": config,
    }


def check_new_folder(path: str | Path) -> None:
    """Raise ``FileExistsError`` if ``path`` exists and is not empty (runs never overwrite)."""
    path = Path(path)
    if path.exists() and (not path.is_dir() or any(path.iterdir())):
        raise FileExistsError(f"{path} exists and is not empty; choose a new folder")


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
