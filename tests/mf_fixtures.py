"""SYNTHETIC 3D sweeps for the multi-fidelity surrogate's tests and the 3D search's.

A 3D design costs minutes of FE, and the kept 3D dataset (``datasets/default3d``) grows with
every segment. These sweeps' "2D model" is the
shipped 2D surrogate itself (cheap: microseconds a design), and their "3D model" a known smooth
map (``synthetic_3d``) of its predictions and of the pad's length and profile: they test methods
and machinery, not the accuracy on FE results (``studies/multifidelity_study.py`` measures that
on the kept 3D dataset; ``tests/test_slice.py`` checks the slice model against it).
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np

from sim.design import DEFAULT_SPACE_3D_PATH, load_space
from sim.metrics import METRICS, SOLVER_VERSION
from sim.options import ModelOptions, SimOptions
from sim.sweep import sample_points, table_header

DISPLACEMENTS = [m for m in METRICS if m.startswith("disp_")]


def synthetic_3d(low, points: list[dict]) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """SYNTHETIC 3D metrics and validity figures of 3D design points: the 2D metrics of the
    design's section and layers (the shipped 2D surrogate's prediction) through a known smooth
    map of them and of the pad's half-length c and length exponent m. Displacements and
    hysteresis: a log ratio to the 2D value that depends on c, m and the value itself; forces:
    power laws of c; the contact patch: of the 3D displacement from touch and the pad's shape."""
    pred = low.predict([{k: v for k, v in p.items() if k in low.space.names} for p in points])
    y2 = {m: pred.median[:, j] for j, m in enumerate(pred.metric_names)}
    c = np.array([p["geometry.half_length_mm"] for p in points])
    m = np.array([p["geometry.length_exponent"] for p in points])
    a = np.array([p["geometry.half_width_mm"] for p in points])
    u, v = np.log(c / 11.0), np.log(m / 4.0)
    out = {}
    for name in DISPLACEMENTS:
        d = y2[name]
        out[name] = d * np.exp(0.12 + 0.15 * u - 0.05 * v + 0.06 * np.log(d / 0.6) * (1 + 2 * u))
    h = y2["hysteresis_Nmm"]
    out["hysteresis_Nmm"] = np.where(h > 0, h * np.exp(0.1 + 0.2 * u - 0.04 * v), 0.0)
    out["sag_mm"] = 1.2 * y2["sag_mm"] + 0.01 * u
    out["plate_force_at_1mm_N"] = y2["plate_force_at_1mm_N"] * 2.0 * (c / 11.0) ** 0.7
    for name in ("wedge_peak_force_N", "wedge_force_at_100s_N"):
        out[name] = y2[name] * 1.5 * (c / 11.0) ** 0.3 * (m / 4.0) ** 0.05
    for name in ("profile_1s_area_2mm_mm2", "profile_100s_area_2mm_mm2"):
        out[name] = y2[name] * (1 + 0.05 * u)
    for name in ("profile_1s_defl_at_1mm_mm", "profile_100s_defl_at_1mm_mm"):
        out[name] = y2[name] * 1.05 + 0.005 * v
    for f, k in ((1, 40.0), (4, 110.0)):
        area = k * out[f"disp_at_{f}N_from_touch_mm"] ** 1.2 * (c / 11.0) ** 0.5 * (m / 4) ** 0.1
        width = 2 * np.sqrt(area / math.pi) * (a / 7.0) ** 0.3
        out[f"contact_area_at_{f}N_mm2"] = area
        out[f"contact_width_at_{f}N_mm"] = width
        out[f"contact_length_at_{f}N_mm"] = 4 * area / (math.pi * width)
    figures = {
        "tapping_max_compressive_log_strain": 1.05 * y2["tapping_max_compressive_log_strain"],
        "plate_max_compressive_log_strain": 1.05 * y2["plate_max_compressive_log_strain"],
        "wedge_max_compressive_log_strain": 1.05 * y2["plate_max_compressive_log_strain"],
        "tapping_min_J": y2["tapping_min_J"],
        "plate_min_J": y2["plate_min_J"],
        "wedge_min_J": y2["wedge_min_J"],
    }
    return out, figures


def write_synthetic_sweep(
    folder: Path, n: int, seed: int, low, options: SimOptions | None = None
) -> Path:
    """A SYNTHETIC 3D sweep folder (config.json of the 3D model, table.csv with the 3D table's
    columns) of ``n`` designs of the default 3D space: ``synthetic_3d``'s metrics with 0.2 %
    noise; a design whose tapping strain passes 0.6 is invalid (its metrics of the protocols
    within the limits are still learnt, as ``read_sweep`` reads a real sweep). ``options``: the
    FE options config.json records (default: the 3D model's defaults); a search confirms with
    them."""
    space = load_space(DEFAULT_SPACE_3D_PATH)
    points = sample_points(space, n, seed)
    metrics, figures = synthetic_3d(low, points)
    rng = np.random.default_rng(seed)
    folder.mkdir(parents=True)
    config = {
        "space": space.to_dict(),
        "n": n,
        "seed": seed,
        "sampler": "sobol",
        "options": (options or SimOptions(model=ModelOptions("3d"))).as_dict(),
        "solver_version": SOLVER_VERSION,
    }
    (folder / "config.json").write_text(json.dumps(config))
    with (folder / "table.csv").open("w", newline="") as fh:
        writer = csv.DictWriter(fh, table_header(space.names, "3d"))
        writer.writeheader()
        for i, p in enumerate(points):
            row = {"index": i, "key": f"synthetic{i}", "status": "ok", "settled": True}
            row.update(
                {k: "" if isinstance(v, float) and math.isnan(v) else v for k, v in p.items()}
            )
            row.update(
                {k: col[i] * (1 + 0.002 * rng.standard_normal()) for k, col in metrics.items()}
            )
            row.update({k: col[i] for k, col in figures.items()})
            row["valid"] = bool(figures["tapping_max_compressive_log_strain"][i] < 0.6)
            for protocol in ("tapping", "plate", "wedge"):
                row[f"{protocol}_reached_base"] = row[f"{protocol}_folded"] = False
            row["tapping_residual"] = row["tapping_max_estimated_error"] = 1e-4
            writer.writerow(row)
    return folder
