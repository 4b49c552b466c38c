"""Neural surrogate of the FE model: design point -> every metric of ``sim.METRICS``, with
uncertainty, from a deep ensemble trained on a sweep.

Public API::

    train_surrogate(sweep_dir, out_dir=None, seed=0, members=5, ...) -> Path   # checkpoint
    fine_tune(surrogate, data, points, targets, epochs=, seed=, weight=1) -> Surrogate
    load_checkpoint(path, allow_solver_mismatch=False) -> Surrogate
    Surrogate.predict(points | table) -> Prediction(mean, std, lower_90, upper_90, in_domain)
    read_points(path, space) / check_point(space, point)   # TOML / CSV design points
    train_seeds(sweep_dir, out_dir, seeds, jobs=1, ...) -> {seed: report}   # one per seed
    learning_curve(sweep_dir, sizes, seed=0, repeats=3, ...) -> dict  # error vs FE designs
    CheckpointError                                        # a refused checkpoint file

    # the 3D model's metrics from many 2D designs (a 2D surrogate) and few 3D ones
    train_multifidelity(sweep3d_dir, low_fidelity=None, method=None, out_dir=None, seed=0)
    load_multifidelity(path, low_fidelity=None) -> MultiFidelitySurrogate   # .predict(points)
    retrain_multifidelity(mf, data3d, points, targets, seed=) -> MultiFidelitySurrogate
    load_surrogate(path) / save_surrogate(model, path)    # either kind, as the file says
    multifidelity_curve(sweep3d, sizes, low_fidelity=..., methods=...) -> dict
    MULTIFIDELITY_METHODS                                  # name -> method class

Importing this package is cheap; torch is imported on first use of a name that needs it.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING

from ._arithmetic import pin_arithmetic
from ._errors import CheckpointError

# before this package first uses torch: the same bits on every x86-64 CPU with AVX2
pin_arithmetic()

if TYPE_CHECKING:
    from ._checkpoint import load_checkpoint, save_checkpoint
    from ._encoding import Encoder
    from ._evaluate import Report, Speed
    from ._io import SweepData, check_point, read_points, read_sweep
    from ._learning_curve import learning_curve
    from ._multifidelity import METHODS as MULTIFIDELITY_METHODS
    from ._multifidelity import (
        MultiFidelitySurrogate,
        fit_multifidelity,
        retrain_multifidelity,
    )
    from ._multifidelity_checkpoint import (
        is_multifidelity,
        load_multifidelity,
        load_surrogate,
        save_multifidelity,
        save_surrogate,
    )
    from ._multifidelity_run import multifidelity_curve, train_multifidelity
    from ._run import train_surrogate
    from ._spread import train_seeds
    from ._surrogate import Prediction, Surrogate
    from ._train import TrainConfig, fine_tune

__all__ = [
    "CHECKPOINT_NAME",
    "MULTIFIDELITY_METHODS",
    "CheckpointError",
    "Encoder",
    "MultiFidelitySurrogate",
    "Prediction",
    "Report",
    "Speed",
    "Surrogate",
    "SweepData",
    "TrainConfig",
    "check_point",
    "fine_tune",
    "fit_multifidelity",
    "is_multifidelity",
    "learning_curve",
    "load_checkpoint",
    "load_multifidelity",
    "load_surrogate",
    "multifidelity_curve",
    "read_points",
    "read_sweep",
    "retrain_multifidelity",
    "save_checkpoint",
    "save_multifidelity",
    "save_surrogate",
    "train_multifidelity",
    "train_seeds",
    "train_surrogate",
]

_LAZY = {
    "CHECKPOINT_NAME": "_run",
    "Encoder": "_encoding",
    "MultiFidelitySurrogate": "_multifidelity",
    "Prediction": "_surrogate",
    "Report": "_evaluate",
    "Speed": "_evaluate",
    "Surrogate": "_surrogate",
    "SweepData": "_io",
    "TrainConfig": "_train",
    "check_point": "_io",
    "fine_tune": "_train",
    "fit_multifidelity": "_multifidelity",
    "learning_curve": "_learning_curve",
    "load_checkpoint": "_checkpoint",
    "is_multifidelity": "_multifidelity_checkpoint",
    "load_multifidelity": "_multifidelity_checkpoint",
    "load_surrogate": "_multifidelity_checkpoint",
    "retrain_multifidelity": "_multifidelity",
    "save_surrogate": "_multifidelity_checkpoint",
    "multifidelity_curve": "_multifidelity_run",
    "read_points": "_io",
    "read_sweep": "_io",
    "save_checkpoint": "_checkpoint",
    "save_multifidelity": "_multifidelity_checkpoint",
    "train_multifidelity": "_multifidelity_run",
    "train_seeds": "_spread",
    "train_surrogate": "_run",
}


#: names bound to another name of their module
_RENAMED = {"MULTIFIDELITY_METHODS": ("_multifidelity", "METHODS")}


def __getattr__(name: str):
    if name in _RENAMED:
        module, attr = _RENAMED[name]
        value = getattr(import_module(f".{module}", __name__), attr)
        globals()[name] = value
        return value
    if name in _LAZY:
        value = getattr(import_module(f".{_LAZY[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
