"""Hand-picked designs of the default space that bracket the human fingertip: FE runs of them
land below and above every human target value (``tests/test_sweep.py`` checks it;
``studies/bracket_human.py`` writes their table into ``docs/design_space.md``).

The points (each checked by ``DesignSpace.check``): the paper's silicone and polyurethane (far
stiffer and less dissipative than a finger), a gel skin over a soft gel core, a gel skin over a
foam core and very soft, dissipative gel cores. :func:`evaluate` taps each to its periodic state
(to the end, beyond the validity limits too: a bracketing design may go beyond them, its
diagnostics say so); :func:`bracket` tabulates both readings, the sag and the validity, and
gives per design the value compared with each human target.
"""

from __future__ import annotations

import math
from typing import Any

from ..design import load_space, load_targets
from ..options import SimOptions
from ..simulate import simulate

__all__ = ["COLUMNS", "POINTS", "bracket", "describe_point", "evaluate"]

PAPER_GEOMETRY = {
    "geometry.half_width_mm": 5.84,
    "geometry.height_mm": 5.48,
    "geometry.exponent": 1.5,
}
#: the narrowest, tallest, pointiest outline of the default space: the most compliant
SOFT_GEOMETRY = {"geometry.half_width_mm": 5.0, "geometry.height_mm": 6.5, "geometry.exponent": 1.3}


def _gel(role: str, mu0: float, alpha: float, g_total: float, tau_s: float) -> dict[str, Any]:
    return {
        f"{role}.material": "gel",
        f"{role}.mu0_MPa": mu0,
        f"{role}.alpha": alpha,
        f"{role}.g_total": g_total,
        f"{role}.tau_s": tau_s,
    }


def _foam(role: str, mu0: float, alpha: float, nu: float, g: float, tau: float) -> dict[str, Any]:
    return {**_gel(role, mu0, alpha, g, tau), f"{role}.material": "foam", f"{role}.nu": nu}


POINTS: dict[str, dict[str, Any]] = {
    "silicone GLS 40 (paper)": {
        **PAPER_GEOMETRY,
        "layers.count": 1,
        "core.material": "silicone_gls40",
    },
    "polyurethane 74-45 (paper)": {
        **PAPER_GEOMETRY,
        "layers.count": 1,
        "core.material": "polyurethane_74_45",
    },
    "0.5 mm gel skin over a soft gel core": {
        **PAPER_GEOMETRY,
        "layers.count": 2,
        "skin.thickness_mm": 0.5,
        **_gel("skin", 0.05, 3.0, 0.2, 0.04),
        **_gel("core", 0.004, 2.0, 0.5, 0.04),
    },
    "0.5 mm gel skin over a foam core": {
        **PAPER_GEOMETRY,
        "layers.count": 2,
        "skin.thickness_mm": 0.5,
        **_gel("skin", 0.05, 3.0, 0.2, 0.04),
        **_foam("core", 0.01, 2.0, 0.3, 0.5, 0.04),
    },
    "very soft, very dissipative gel core": {
        **SOFT_GEOMETRY,
        "layers.count": 1,
        **_gel("core", 0.004, 2.0, 0.8, 0.04),
    },
    "softest gel core, dissipative": {
        **SOFT_GEOMETRY,
        "layers.count": 1,
        **_gel("core", 0.0025, 1.5, 0.6, 0.04),
    },
    "softest gel core, elastic": {
        **SOFT_GEOMETRY,
        "layers.count": 1,
        **_gel("core", 0.0025, 1.5, 0.0, 0.04),
    },
}

#: the table's columns: header, metric or diagnostic key, format
COLUMNS = [
    ("1 N, top (mm)", "disp_at_1N_mm", "{:.3f}"),
    ("4 N, top (mm)", "disp_at_4N_mm", "{:.3f}"),
    ("1 N, touch (mm)", "disp_at_1N_from_touch_mm", "{:.3f}"),
    ("4 N, touch (mm)", "disp_at_4N_from_touch_mm", "{:.3f}"),
    ("hysteresis (N mm)", "hysteresis_Nmm", "{:.3f}"),
    ("sag (mm)", "sag_mm", "{:.3f}"),
    ("settled", "settled", "{}"),
    ("valid", "valid", "{}"),
    ("max log strain", "tapping_max_compressive_log_strain", "{:.2f}"),
    ("min J", "tapping_min_J", "{:.2f}"),
]


def describe_point(point: dict[str, Any]) -> str:
    """A design point in one line (active values only)."""
    g = (
        f"outline {point['geometry.half_width_mm']:g} x {point['geometry.height_mm']:g} mm, "
        f"exponent {point['geometry.exponent']:g}"
    )
    layers = []
    for role in ("skin", "core"):
        mat = point.get(f"{role}.material")
        if not isinstance(mat, str) or not mat:
            continue
        text = f"{role} `{mat}`"
        keys = ("mu0_MPa", "alpha", "nu", "g_total", "tau_s")
        vals = [
            f"{k} {point[f'{role}.{k}']:g}"
            for k in keys
            if isinstance(point.get(f"{role}.{k}"), float) and not math.isnan(point[f"{role}.{k}"])
        ]
        if vals:
            text += " (" + ", ".join(vals) + ")"
        thickness = point.get(f"{role}.thickness_mm")
        if isinstance(thickness, float) and not math.isnan(thickness):
            text = f"{thickness:g} mm " + text
        layers.append(text)
    return g + "; " + " over ".join(layers)


def evaluate() -> dict[str, dict[str, Any]]:
    """label -> the checked point, its tapping metrics and diagnostics (flat)."""
    space = load_space()
    out = {}
    for label, point in POINTS.items():
        checked = space.check(point)
        # to the end: a bracketing design may be beyond the limits (its diagnostics say so)
        res = simulate(space.design(checked), ("tapping",), SimOptions().without_validity_stop())
        out[label] = {
            "point": checked,
            **res.metrics,
            **res.diagnostics(),
            "failed": "; ".join(f.reason for f in res.failures),
        }
        print(label, {k: out[label].get(k) for _, k, _ in COLUMNS}, flush=True)
    return out


def _cell(fmt: str, v: Any) -> str:
    return "failed" if v is None else fmt.format(v)


def bracket(
    evaluated: dict[str, dict[str, Any]] | None = None,
) -> tuple[list[str], dict[str, dict[str, float]]]:
    """The Markdown table (both readings, sag, validity) and, per design, the value compared
    with each human target (``Targets.metric``: the targets file's reading)."""
    evaluated = evaluate() if evaluated is None else evaluated
    targets = load_targets()
    human = {targets.metric(k): v for k, v in targets.values.items()}
    if targets.max_sag_mm is not None:
        human["sag_mm"] = f"<= {targets.max_sag_mm}"
    lines = [
        "| design | " + " | ".join(h for h, _, _ in COLUMNS) + " | violations |",
        "|---|" + "---|" * (len(COLUMNS) + 1),
        "| **human fingertip (target)** | "
        + " | ".join(f"**{human[k]}**" if k in human else "" for _, k, _ in COLUMNS)
        + " | |",
    ]
    for label, r in evaluated.items():
        cells = [_cell(fmt, r.get(key)) for _, key, fmt in COLUMNS]
        notes = r["violations"] or "none"
        if r["failed"]:
            notes += f"; failed: {r['failed']}"
        lines.append(f"| {label} | " + " | ".join(cells) + f" | {notes} |")
    results = {
        label: {k: r[targets.metric(k)] for k in targets.values} for label, r in evaluated.items()
    }
    return lines, results
