"""Errors of the surrogate package (no torch import: the CLI catches them cheaply)."""

from __future__ import annotations


class CheckpointError(ValueError):
    """A file that is not a usable surrogate checkpoint.

    Raised for a non-checkpoint file, a wrong schema version, a different solver version and a
    tampered or corrupted file. ``str()`` is always one line, fit for ``fingertip: error: ...``.
    """

    def __init__(self, path: object, message: str) -> None:
        text = f"{path}: {message}"
        super().__init__(" ".join(text.split()))
        self.path = path
        self.message = message
