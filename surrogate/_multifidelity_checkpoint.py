"""Multi-fidelity checkpoints: ONE ``.safetensors`` file, loaded without unpickling anything.

As ``surrogate._checkpoint``: the tensors are the 3D ensemble's stacked weights (``model.*``)
and the output normaliser (``output.*``); the safetensors string metadata
``fingertip_multifidelity`` holds a JSON header: format and schema version, the method, the
architecture, the 3D design space and training domain, the features, the metrics (with the 2D
output each delta output is learnt against), the normalisers, the 3D training data (the sweep's
table sha256, its designs, space, solver version and split), the low fidelity's identity (its
path relative to the repository, the sha256 of its file, and its own training data: table
sha256, designs, solver version), the git commit, the calibration and validation figures, and
``sha256``: a hash over every tensor and the header (``surrogate._checkpoint._digest``), which
detects any change to the file.

The low fidelity is not copied into the file: loading reads it from the recorded path (or the
one given) and refuses it unless its sha256 is the recorded one, then loads it with
``load_checkpoint`` (and its own checks).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from sim.design import space_from_dict
from sim.metrics import SOLVER_VERSION, same_metrics
from sim.provenance import REPO, json_safe, json_text, recorded_path, replacing, sha256_file

from ._checkpoint import (
    _digest,
    checkpoint_file,
    describe,
    load_checkpoint,
    read_verified,
    save_checkpoint,
)
from ._encoding import Encoder
from ._errors import CheckpointError
from ._multifidelity import METHODS, METRICS_3D_MODEL, MultiFidelityEncoder, MultiFidelitySurrogate
from ._normalise import OutputNormaliser
from ._surrogate import Surrogate

__all__ = [
    "FORMAT",
    "META_KEY",
    "SCHEMA_VERSION",
    "is_multifidelity",
    "load_multifidelity",
    "load_surrogate",
    "low_fidelity_path",
    "save_multifidelity",
    "save_surrogate",
]

FORMAT = "fingertip-multifidelity"
SCHEMA_VERSION = 1
META_KEY = "fingertip_multifidelity"


def low_fidelity_path(recorded: str) -> Path:
    """The file a recorded low-fidelity path names (a relative one: inside the repository)."""
    path = Path(recorded)
    return path if path.is_absolute() else REPO / path


def _low_identity(surrogate: MultiFidelitySurrogate) -> dict[str, Any]:
    """The low fidelity's record: its file (path, sha256) and its own training data."""
    low, source = surrogate.low, surrogate.low_file
    if source is None:
        raise ValueError(
            "the low fidelity's file is unknown: give fit_multifidelity its checkpoint's path"
        )
    data = low.header.get("training_data", {})
    return {
        "path": recorded_path(Path(source)),
        "sha256": sha256_file(source),
        "format": low.header.get("format"),
        "schema_version": low.header.get("schema_version"),
        "header_sha256": low.header.get("sha256"),
        "solver_version": low.header.get("solver_version"),
        "training_data": {
            "table_sha256": data.get("table_sha256"),
            "n_rows": data.get("n_rows"),
            "n_used": data.get("n_used"),
        },
        "space": low.space.to_dict(),
        "outputs": list(low.metric_names),
    }


def _header(surrogate: MultiFidelitySurrogate) -> dict[str, Any]:
    """The structural part of the header (``describe``'s, for the 3D ensemble) and the method,
    the delta outputs and the low fidelity."""
    own = describe(surrogate._net)
    registry = METRICS_3D_MODEL
    own["metrics"] = [
        {
            "name": m,
            "unit": registry[m][1] if m in registry else "",
            "protocol": registry[m][0] if m in registry else "",
            "description": registry[m][2] if m in registry else "",
            "delta_of": d,
            "trend": None if surrogate.trend is None else [float(b) for b in surrogate.trend[j]],
        }
        for j, (m, d) in enumerate(zip(surrogate.metric_names, surrogate.delta, strict=True))
    ]
    for m, d in zip(surrogate.metric_names, surrogate.delta, strict=True):
        if d is not None:
            entry = own["normalisers"][m]
            entry["transform"] = f"{entry['transform']} - the 2D prediction's"
    own["features"] = surrogate.encoder.feature_names
    return {
        **own,
        "format": FORMAT,
        "schema_version": SCHEMA_VERSION,
        "method": surrogate.method.name,
        "method_summary": surrogate.method.summary,
        "network_inputs": surrogate.model.n_inputs,
        "trend_inputs": surrogate.trend_inputs if surrogate.trend is not None else None,
        "low_fidelity": None if surrogate.low is None else _low_identity(surrogate),
    }


def save_multifidelity(surrogate: MultiFidelitySurrogate, path: str | Path) -> Path:
    """Save a ``MultiFidelitySurrogate`` (its ``header``: provenance, calibration, validation),
    atomically; the low fidelity is recorded by path and sha256."""
    from safetensors.numpy import save_file

    tensors = {
        f"model.{k}": v.detach().cpu().numpy().copy()
        for k, v in surrogate.model.state_dict().items()
    }
    tensors.update(
        {f"output.{k}": np.ascontiguousarray(v) for k, v in surrogate.normaliser.arrays().items()}
    )
    header = {**surrogate.header, **_header(surrogate)}
    header = json_safe({k: v for k, v in header.items() if k != "sha256"})
    header["sha256"] = _digest(tensors, header)
    path = Path(path)
    with replacing(path) as tmp:
        save_file(tensors, str(tmp), metadata={META_KEY: json_text(header)})
    return path


def is_multifidelity(path: str | Path) -> bool:
    """Whether ``path`` (a file, or a folder holding ``model.safetensors``) is a readable
    multi-fidelity checkpoint's file (its header is not checked)."""
    from safetensors import safe_open

    try:
        with safe_open(str(checkpoint_file(path)), framework="numpy") as fh:
            return META_KEY in (fh.metadata() or {})
    except Exception:
        return False


def _read(path: Path) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """Tensors and header after the format, schema and hash checks (``read_verified``)."""
    return read_verified(
        path,
        meta_key=META_KEY,
        fmt=FORMAT,
        schema_version=SCHEMA_VERSION,
        kind="multi-fidelity checkpoint",
        elsewhere={
            "fingertip_surrogate": "a 2D surrogate checkpoint, not a multi-fidelity one: load "
            "it with load_checkpoint (or give it as the low fidelity)"
        },
    )


def _load_low(
    path: Path, record: dict[str, Any], given: str | Path | None, allow_solver_mismatch: bool
) -> tuple[Any, Path]:
    """The recorded low fidelity (at ``given`` when given) and its file, refused unless the
    file's sha256 is the recorded one."""
    try:
        recorded, digest = str(record["path"]), str(record["sha256"])
    except (KeyError, TypeError):
        raise CheckpointError(path, "inconsistent checkpoint: no low-fidelity record") from None
    low_path = checkpoint_file(given) if given is not None else low_fidelity_path(recorded)
    if not low_path.is_file():
        raise CheckpointError(
            path,
            f"its low-fidelity 2D surrogate {low_path} is missing; give its location "
            "(load_multifidelity(..., low_fidelity=PATH))",
        )
    found = sha256_file(low_path)
    if found != digest:
        raise CheckpointError(
            path,
            f"the low-fidelity 2D surrogate {low_path} is not the one it was trained with "
            f"(sha256 {found[:12]}..., recorded {digest[:12]}...): tampered, or another "
            "checkpoint; retrain, or give the recorded one",
        )
    return load_checkpoint(low_path, allow_solver_mismatch=allow_solver_mismatch), low_path


def load_multifidelity(
    path: str | Path,
    *,
    low_fidelity: str | Path | None = None,
    allow_solver_mismatch: bool = False,
) -> MultiFidelitySurrogate:
    """Load a ``MultiFidelitySurrogate`` (a file, or a training run folder holding
    ``model.safetensors``). A ``CheckpointError`` (one line) for a file that is not a
    multi-fidelity checkpoint, another schema version, a tampered file, a model trained on FE
    results of another solver version (unless ``allow_solver_mismatch``; ``same_metrics``), and
    a low-fidelity file (the recorded path, or ``low_fidelity`` when given) whose sha256 is not
    the recorded one or that ``load_checkpoint`` refuses."""
    import torch

    from ._model import MODELS

    path = checkpoint_file(path)
    tensors, header = _read(path)
    solver = header.get("solver_version")
    if not same_metrics(solver) and not allow_solver_mismatch:
        raise CheckpointError(
            path,
            f"trained on FE results of solver version {solver!r}, this solver is "
            f"{SOLVER_VERSION!r}; retrain, or use it anyway with allow_solver_mismatch=True",
        )
    try:
        method = str(header["method"])
        if method not in METHODS:
            raise ValueError(f"unknown method {method!r}")
        record = header["low_fidelity"]
    except (KeyError, ValueError) as exc:
        raise CheckpointError(path, f"inconsistent checkpoint: {exc}") from None
    low, low_file = None, None
    if record is not None:
        low, low_file = _load_low(path, record, low_fidelity, allow_solver_mismatch)
    elif METHODS[method].low_fidelity:
        raise CheckpointError(path, f"inconsistent checkpoint: {method} without a low fidelity")
    try:
        space = space_from_dict(header["space"])
        own = Encoder.from_dict(space, header["domain"])
        arch = dict(header["architecture"])
        model = MODELS[arch.pop("name")](**arch, seed=0)
        state = {
            k.removeprefix("model."): torch.from_numpy(v.copy())
            for k, v in tensors.items()
            if k.startswith("model.")
        }
        model.load_state_dict(state, strict=True)
        normaliser = OutputNormaliser.from_arrays(
            {k.removeprefix("output."): v for k, v in tensors.items() if k.startswith("output.")}
        )
        names = [m["name"] for m in header["metrics"]]
        delta = [m.get("delta_of") for m in header["metrics"]]
        encoder = MultiFidelityEncoder(own, low)
        if encoder.feature_names != list(header["features"]):
            raise ValueError("the features differ from the recorded ones")
        trend = None
        if header.get("trend_inputs") is not None:
            trend = np.array([m["trend"] for m in header["metrics"]], dtype=np.float64)
        surrogate = MultiFidelitySurrogate(
            method, model, encoder, normaliser, names, delta, header, low_file=low_file,
            trend=trend,
        )  # fmt: skip
        if trend is not None and surrogate.trend_inputs != list(header["trend_inputs"]):
            raise ValueError("the trend's inputs differ from the recorded ones")
        if surrogate.net_features(np.zeros((1, encoder.n_features))).shape[1] != model.n_inputs:
            raise ValueError("the encoding does not match the network's inputs")
        if len(names) != model.n_outputs:
            raise ValueError("the metrics do not match the network's outputs")
    except (KeyError, TypeError, ValueError, RuntimeError) as exc:
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise CheckpointError(path, f"inconsistent checkpoint: {first}") from None
    return surrogate


def load_surrogate(
    path: str | Path, *, allow_solver_mismatch: bool = False
) -> Surrogate | MultiFidelitySurrogate:
    """Either kind of checkpoint, as its file says (:func:`is_multifidelity`): a
    ``MultiFidelitySurrogate`` (``load_multifidelity``) or a 2D ``Surrogate``
    (``load_checkpoint``), with their checks."""
    if is_multifidelity(path):
        return load_multifidelity(path, allow_solver_mismatch=allow_solver_mismatch)
    return load_checkpoint(path, allow_solver_mismatch=allow_solver_mismatch)


def save_surrogate(surrogate: Surrogate | MultiFidelitySurrogate, path: str | Path) -> Path:
    """Save either kind of surrogate in its own format, atomically."""
    if isinstance(surrogate, MultiFidelitySurrogate):
        return save_multifidelity(surrogate, path)
    return save_checkpoint(surrogate, path)
