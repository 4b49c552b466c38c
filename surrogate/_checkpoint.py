"""Checkpoints: ONE ``.safetensors`` file, loaded without unpickling anything.

Tensors: the ensemble's stacked weights (``model.weights.<layer>``, ``model.biases.<layer>``)
and the output normaliser (``output.log|shift|scale|observed|offset``). The safetensors string
metadata ``fingertip_surrogate`` holds a JSON header: format and schema version, the
architecture, the design space (parameter names, units, bounds, encoding) and the training
domain, the metrics and their units, the normalisers, the training data (sha256 of table.csv,
split), solver version, git commit, validation metrics, and ``sha256``: a hash over every
tensor's name, dtype, shape and bytes plus the header without that field, which detects any
change to the file.
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from sim.design import space_from_dict
from sim.metrics import METRICS, SOLVER_VERSION, same_metrics
from sim.provenance import json_safe, json_text, replacing

from ._encoding import (
    ELASTIC_FEATURE,
    Encoder,
    is_optional,
    material_descriptors,
    parameter_unit,
)
from ._errors import CheckpointError
from ._normalise import OutputNormaliser
from ._surrogate import ZERO_IF_ELASTIC

__all__ = [
    "CHECKPOINT_NAME",
    "FORMAT",
    "SCHEMA_VERSION",
    "checkpoint_file",
    "load_checkpoint",
    "save_checkpoint",
]

#: the checkpoint file of a training run folder (``fingertip train``)
CHECKPOINT_NAME = "model.safetensors"

FORMAT = "fingertip-surrogate"
SCHEMA_VERSION = 3  # 2: output.offset (shifted-log metrics); 3: material descriptors, groups
META_KEY = "fingertip_surrogate"


def _digest(tensors: dict[str, np.ndarray], header: dict[str, Any]) -> str:
    h = hashlib.sha256()
    for name in sorted(tensors):
        a = np.ascontiguousarray(tensors[name])
        h.update(f"{name}\0{a.dtype.str}\0{a.shape}\0".encode())
        h.update(a.tobytes())
    rest = {k: v for k, v in header.items() if k != "sha256"}
    h.update(json.dumps(rest, sort_keys=True, separators=(",", ":")).encode())
    return h.hexdigest()


def describe(surrogate) -> dict[str, Any]:
    """The structural part of the header (space, encoding, metrics, normalisers)."""
    space, enc, norm = surrogate.space, surrogate.encoder, surrogate.normaliser
    params = []
    for p in space.parameters:
        d: dict[str, Any] = {"name": p.name, "kind": p.kind, "unit": parameter_unit(p.name)}
        if p.kind == "float":
            lo, hi = enc.ranges.get(p.name, (math.nan, math.nan))
            d.update(
                low=p.low,
                high=p.high,
                log=p.log,
                optional=is_optional(space, p),
                encoding="log-unit + active flag" if p.log else "unit + active flag",
                training_range=json_safe([float(lo), float(hi)]),
            )
            if not d["optional"]:
                d["encoding"] = d["encoding"].replace(" + active flag", "")
        elif p.kind == "choice":
            d.update(choices=list(p.choices), encoding="one-hot (all zeros when inactive)")
        else:
            d.update(value=p.value, encoding="none (fixed)")
        params.append(d)
    return {
        "format": FORMAT,
        "schema_version": SCHEMA_VERSION,
        "architecture": {"name": "ensemble_mlp", **surrogate.model.config()},
        "space": space.to_dict(),
        "parameters": params,
        "features": enc.feature_names,
        "material_descriptors": {
            "omega_rad_s": enc.omega_rad_s,
            "definition": " ".join((material_descriptors.__doc__ or "").split()),
        },
        "exact_by_rule": {
            "metrics": sorted(ZERO_IF_ELASTIC),
            "rule": f"0 when {ELASTIC_FEATURE} (no active layer relaxes)",
        },
        "domain": enc.to_dict(),
        "metrics": [
            {
                "name": m,
                "unit": METRICS[m][1] if m in METRICS else "",
                "protocol": METRICS[m][0] if m in METRICS else "",
                "description": METRICS[m][2] if m in METRICS else "",
            }
            for m in surrogate.metric_names
        ],
        "normalisers": {
            m: {
                "transform": (
                    ("log(y)" if norm.offset[j] == 0 else f"log(y + {norm.offset[j]:.6g})")
                    if norm.log[j]
                    else "linear"
                ),
                "offset": float(norm.offset[j]),
                "shift": float(norm.shift[j]),
                "scale": float(norm.scale[j]),
                "observed": int(norm.observed[j]),
                "interval_scale": float(norm.interval_scale[j]),
            }
            for j, m in enumerate(surrogate.metric_names)
        },
    }


def _tensors(surrogate) -> dict[str, np.ndarray]:
    out = {
        f"model.{k}": v.detach().cpu().numpy().copy()
        for k, v in surrogate.model.state_dict().items()
    }
    out.update(
        {f"output.{k}": np.ascontiguousarray(v) for k, v in surrogate.normaliser.arrays().items()}
    )
    return out


def write_checkpoint(path: str | Path, tensors: dict[str, np.ndarray], header: dict) -> Path:
    """Write tensors + header (adds the ``sha256`` field), atomically."""
    from safetensors.numpy import save_file

    path = Path(path)
    header = json_safe({k: v for k, v in header.items() if k != "sha256"})  # hashed as stored
    header["sha256"] = _digest(tensors, header)
    with replacing(path) as tmp:
        save_file(tensors, str(tmp), metadata={META_KEY: json_text(header)})
    return path


def save_checkpoint(surrogate, path: str | Path) -> Path:
    """Save a ``Surrogate`` (its ``header`` carries provenance and validation metrics)."""
    header = {**surrogate.header, **describe(surrogate)}
    return write_checkpoint(path, _tensors(surrogate), header)


def checkpoint_file(path: str | Path) -> Path:
    """The checkpoint file ``path`` names: the file itself, or a folder's ``CHECKPOINT_NAME``
    (a training run folder, the shipped ``surrogate/pretrained/default``); a folder without
    one, or nothing at all, is one error line saying which file is expected."""
    path = Path(path)
    if path.is_dir():
        if (path / CHECKPOINT_NAME).is_file():
            return path / CHECKPOINT_NAME
        raise CheckpointError(
            path,
            f"a folder without {CHECKPOINT_NAME}: give a checkpoint file (.safetensors) or a "
            f"training run folder (fingertip train) that holds {CHECKPOINT_NAME}",
        )
    if not path.is_file():
        raise CheckpointError(
            path,
            "no such checkpoint file (a .safetensors checkpoint, or a training run folder "
            f"that holds {CHECKPOINT_NAME})",
        )
    return path


def read_verified(
    path: Path,
    *,
    meta_key: str,
    fmt: str,
    schema_version: int,
    kind: str,
    elsewhere: dict[str, str],
) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """Tensors and JSON header of a fingertip safetensors file after the checks every kind of
    checkpoint shares: a readable file with a ``meta_key`` header (``elsewhere``: the header key
    of another kind -> the sentence that sends the reader to its loader), valid JSON of format
    ``fmt`` and schema ``schema_version``, and the recorded sha256 over tensors and header
    (``_digest``). ``kind`` names the file in the messages ("surrogate checkpoint")."""
    from safetensors import safe_open

    try:
        with safe_open(str(path), framework="numpy") as fh:
            meta = fh.metadata() or {}
            tensors = {k: fh.get_tensor(k) for k in fh.keys()}
    except Exception:  # any failure of the parser means: not a readable safetensors file
        raise CheckpointError(path, f"not a {kind} (not a readable safetensors file)") from None
    text = meta.get(meta_key)
    if text is None:
        for key, sentence in elsewhere.items():
            if key in meta:
                raise CheckpointError(path, sentence)
        raise CheckpointError(
            path, f"not a {kind} (a safetensors file without the {meta_key} header)"
        )
    try:
        header = json.loads(text)
    except json.JSONDecodeError:
        raise CheckpointError(path, "corrupted checkpoint header (invalid JSON)") from None
    if not isinstance(header, dict) or header.get("format") != fmt:
        raise CheckpointError(path, f"not a {kind} (format is not {fmt!r})")
    version = header.get("schema_version")
    if version != schema_version:
        raise CheckpointError(
            path,
            f"{kind} schema version {version!r}, this fingertip reads {schema_version}; "
            "retrain with `fingertip train`",
        )
    if header.get("sha256") != _digest(tensors, header):
        raise CheckpointError(path, "tampered or corrupted checkpoint (sha256 mismatch)")
    return tensors, header


def read_checkpoint(path: str | Path) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """Tensors and header of a checkpoint (a file, or a folder holding ``CHECKPOINT_NAME``:
    :func:`checkpoint_file`), after the format, schema and hash checks (``read_verified``)."""
    return read_verified(
        checkpoint_file(path),
        meta_key=META_KEY,
        fmt=FORMAT,
        schema_version=SCHEMA_VERSION,
        kind="surrogate checkpoint",
        elsewhere={
            "fingertip_multifidelity": "a multi-fidelity checkpoint (the 3D model's metrics): "
            "load it with surrogate.load_multifidelity"  # _multifidelity_checkpoint.META_KEY
        },
    )


def load_checkpoint(path: str | Path, *, allow_solver_mismatch: bool = False):
    """Load a ``Surrogate``. A ``CheckpointError`` (one-line message) for a file that is not a
    checkpoint, another schema version, a tampered file, or a model trained on FE data of
    another solver version (unless ``allow_solver_mismatch``; a version whose metrics this
    solver reproduces, ``sim.metrics.SAME_METRICS_AS``, is accepted)."""
    import torch

    from ._model import MODELS
    from ._surrogate import Surrogate

    tensors, header = read_checkpoint(path)
    solver = header.get("solver_version")
    if not same_metrics(solver) and not allow_solver_mismatch:
        raise CheckpointError(
            path,
            f"trained on FE results of solver version {solver!r}, this solver is "
            f"{SOLVER_VERSION!r}; retrain, or use it anyway with allow_solver_mismatch=True "
            "(fingertip predict --allow-solver-mismatch)",
        )
    try:
        space = space_from_dict(header["space"])
        encoder = Encoder.from_dict(space, header["domain"])
        arch = dict(header["architecture"])
        cls = MODELS[arch.pop("name")]
        model = cls(**arch, seed=0)
        state = {
            k.removeprefix("model."): torch.from_numpy(v.copy())
            for k, v in tensors.items()
            if k.startswith("model.")
        }
        model.load_state_dict(state, strict=True)
        normaliser = OutputNormaliser.from_arrays(
            {k.removeprefix("output."): v for k, v in tensors.items() if k.startswith("output.")}
        )
        metric_names = [m["name"] for m in header["metrics"]]
        if encoder.n_features != model.n_inputs or len(metric_names) != model.n_outputs:
            raise ValueError("the encoding does not match the network's inputs or outputs")
    except (KeyError, TypeError, ValueError, RuntimeError) as exc:
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise CheckpointError(path, f"inconsistent checkpoint: {first}") from None
    return Surrogate(model, encoder, normaliser, metric_names, header)
