"""Search the design space for human-like skins: Optuna on the surrogate, FE confirmation,
active learning, design-space plots and the ``fingertip`` command line.

Public API::

    optimize(OptimizeConfig(...), out) -> Summary     # fingertip optimize (2D or, with a
                                                       # multi-fidelity surrogate, 3D)
    run(OptimizeConfig(...), out, from_scratch=N)      # fingertip run (--from-scratch)
    closeness(metrics, targets), objectives(c)         # the documented closeness score
    wedge_reference_N(dimension)                       # its wedge reference, by model
    write_figures(run_dir), write_report(run_dir)      # fingertip report
    check_in_3d(run_dir, targets, options_3d(opts), tolerance=0.05)  # --model 3d: the answers
    Candidate, Confirmation, Summary                   # the data of a run folder

Importing this package is cheap; Optuna, torch and matplotlib load on first use. With two
workers or more, ``optimize`` and ``run`` start a spawned helper process, which imports the
calling script: a script needs the ``if __name__ == "__main__":`` guard.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING

from ._objective import (
    WEDGE_REFERENCE_3D_N,
    WEDGE_REFERENCE_N,
    WEDGE_WEIGHT,
    Closeness,
    closeness,
    objectives,
    wedge_reference_N,
)
from ._types import Candidate, Confirmation, Summary

if TYPE_CHECKING:
    from ._check3d import check_in_3d, options_3d
    from ._config import DEFAULT_CHECKPOINT, OptimizeConfig
    from ._pipeline import optimize, run
    from ._plots import write_figures
    from ._report import write_report

__all__ = [
    "DEFAULT_CHECKPOINT",
    "WEDGE_REFERENCE_3D_N",
    "WEDGE_REFERENCE_N",
    "WEDGE_WEIGHT",
    "Candidate",
    "Closeness",
    "Confirmation",
    "OptimizeConfig",
    "Summary",
    "check_in_3d",
    "closeness",
    "objectives",
    "optimize",
    "options_3d",
    "run",
    "wedge_reference_N",
    "write_figures",
    "write_report",
]

_LAZY = {
    "check_in_3d": "_check3d",
    "options_3d": "_check3d",
    "DEFAULT_CHECKPOINT": "_config",
    "OptimizeConfig": "_config",
    "optimize": "_pipeline",
    "run": "_pipeline",
    "write_figures": "_plots",
    "write_report": "_report",
}


def __getattr__(name: str):
    if name in _LAZY:
        return getattr(import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
