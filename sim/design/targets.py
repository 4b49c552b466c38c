"""Targets a design is compared with: the human fingertip by default, or a user's own file.

A targets TOML file (the shipped one is ``sim/data/human_targets.toml``)::

    [tapping]
    disp_at_1N_mm = 1.83
    disp_at_4N_mm = 2.91
    hysteresis_Nmm = 2.26
    displacement_reading = "from_first_touch"   # or "from_undeformed_top"
    max_sag_mm = 0.37               # optional: the skin must recover between taps
    source = "..."
    [conformance]
    wedge_peak_force_N = 0.0        # an ideal: lower is better
    direction = "lower_is_better"
    surface_profile_csv = "profile.csv"   # optional: columns distance_mm, deflection_mm

The displacement reading says how the target displacements were measured: from the original
undeformed top (as the paper reads its simulations) or from the first touch of each tap (as a
tapping experiment on a finger measures them). ``Targets.metric`` maps each target to the
simulator metric read the same way, so every comparison is like with like.

``max_sag_mm`` (optional) bounds the sag, the displacement left at the start of the measured tap
by the earlier ones (metric ``sag_mm``): a reading from first touch cannot see it, so without a
limit a skin that never recovers (putty) could match the human values. A design whose sag
exceeds it is not an answer (``Targets.sag_ok``).

Descriptive keys may go with them (``source``, ``note``, ``displacement_reading_rationale``,
``loading_frequency_Hz``, ``inclination_deg``; ``surface_profile``, ``surface_profile_note``);
any other table or key is refused with one line naming it (``ALLOWED_KEYS``).
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import DesignError, read_toml

__all__ = [
    "ALLOWED_KEYS",
    "DEFAULT_TARGETS_PATH",
    "LOADING_CURVE_SOURCE",
    "READINGS",
    "LoadingCurve",
    "Targets",
    "load_targets",
    "loading_curve",
]

DEFAULT_TARGETS_PATH = Path(__file__).parents[1] / "data" / "human_targets.toml"
READINGS = {
    "from_undeformed_top": {"disp_at_1N_mm": "disp_at_1N_mm", "disp_at_4N_mm": "disp_at_4N_mm"},
    "from_first_touch": {
        "disp_at_1N_mm": "disp_at_1N_from_touch_mm",
        "disp_at_4N_mm": "disp_at_4N_from_touch_mm",
    },
}
_TAPPING = ("disp_at_1N_mm", "disp_at_4N_mm", "hysteresis_Nmm")
#: every key a targets file may hold, per table: the target values, how they are read, and
#: descriptive entries (sources, notes, the conditions of the experiment). The conditions
#: (``loading_frequency_Hz``, ``inclination_deg``) document the measurement and do not change
#: the simulated protocol (that is ``--set tapping.frequency_Hz=...``). Any other key is refused,
#: as in design and space files: a misspelt target must not leave the default in place.
ALLOWED_KEYS = {
    "tapping": (
        *_TAPPING,
        "displacement_reading",
        "displacement_reading_rationale",
        "max_sag_mm",
        "max_sag_rationale",
        "loading_frequency_Hz",
        "inclination_deg",
        "source",
        "note",
    ),
    "conformance": (
        "wedge_peak_force_N",
        "direction",
        "surface_profile_csv",
        "surface_profile",
        "surface_profile_note",
        "source",
        "note",
    ),
}
_TEXT_KEYS = (
    "surface_profile_csv",
    "displacement_reading_rationale",
    "max_sag_rationale",
    "source",
    "note",
    "surface_profile",
    "surface_profile_note",
)


@dataclass(frozen=True)
class Targets:
    """Target values by name (mm, N mm, N), the displacement reading, the sag limit (mm, None:
    no limit), the sources, and an optional measured surface-deflection profile (distance_mm,
    deflection_mm arrays)."""

    values: dict[str, float]
    reading: str = "from_undeformed_top"
    wedge_force_N: float | None = 0.0
    profile: tuple[np.ndarray, np.ndarray] | None = field(default=None, compare=False)
    sources: dict[str, str] = field(default_factory=dict, compare=False)
    max_sag_mm: float | None = None

    def metric(self, name: str) -> str:
        """The simulator metric that is compared with target ``name`` (like with like)."""
        return READINGS[self.reading].get(name, name)

    def sag_ok(self, sag_mm: Any) -> Any:
        """Whether a sag (mm; array or number) is within ``max_sag_mm`` (always, without a
        limit; a missing sag, NaN, is not)."""
        sag = np.asarray(sag_mm, dtype=float)
        ok = np.ones(sag.shape, bool) if self.max_sag_mm is None else sag <= self.max_sag_mm
        return bool(ok) if ok.ndim == 0 else ok


def _number(value: Any, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise DesignError(name, f"must be a finite number, got {value!r}")
    return float(value)


def load_targets(path: str | Path | None = None) -> Targets:
    """Read and validate a targets file (the human fingertip when ``path`` is None)."""
    path = DEFAULT_TARGETS_PATH if path is None else Path(path)
    data = read_toml(path, "TARGETS")
    _check_keys(data)
    tap = data.get("tapping")
    if not isinstance(tap, dict):
        raise DesignError("tapping", "missing: a [tapping] table with the target values")
    values = {}
    for key in _TAPPING:
        if key not in tap:
            raise DesignError(f"tapping.{key}", "missing")
        values[key] = _number(tap[key], f"tapping.{key}")
        if values[key] <= 0:
            raise DesignError(f"tapping.{key}", f"must be > 0, got {values[key]}")
    reading = tap.get("displacement_reading", "from_undeformed_top")
    if reading not in READINGS:
        raise DesignError(
            "tapping.displacement_reading", f"must be one of {', '.join(READINGS)}, got {reading!r}"
        )
    max_sag = tap.get("max_sag_mm")
    if max_sag is not None:
        max_sag = _number(max_sag, "tapping.max_sag_mm")
        if max_sag < 0:
            raise DesignError("tapping.max_sag_mm", f"must be >= 0, got {max_sag}")
    conf = data.get("conformance", {})
    wedge = conf.get("wedge_peak_force_N", 0.0)
    wedge = None if wedge is None else _number(wedge, "conformance.wedge_peak_force_N")
    if wedge is not None and wedge < 0:
        raise DesignError("conformance.wedge_peak_force_N", f"must be >= 0, got {wedge}")
    profile = None
    if "surface_profile_csv" in conf:
        profile = _read_profile(path.parent / conf["surface_profile_csv"])
    sources = {k: v["source"] for k, v in data.items() if isinstance(v, dict) and "source" in v}
    return Targets(values, reading, wedge, profile, sources, max_sag)


def _check_keys(data: dict[str, Any]) -> None:
    """Refuse any table or key a targets file may not hold (one line naming it and the allowed
    ones), and descriptive entries of the wrong type."""
    for table, body in data.items():
        if table not in ALLOWED_KEYS:
            what = "table" if isinstance(body, dict) else "key"
            raise DesignError(
                table, f"unknown {what}; a targets file holds the tables [tapping], [conformance]"
            )
        if not isinstance(body, dict):
            raise DesignError(table, "must be a table ([tapping], [conformance])")
        for key, value in body.items():
            if key not in ALLOWED_KEYS[table]:
                raise DesignError(
                    f"{table}.{key}", f"unknown key; allowed: {', '.join(ALLOWED_KEYS[table])}"
                )
            if key in _TEXT_KEYS and not isinstance(value, str):
                raise DesignError(f"{table}.{key}", f"must be text, got {value!r}")
            if key in ("loading_frequency_Hz", "inclination_deg", "max_sag_mm"):
                _number(value, f"{table}.{key}")
    direction = data.get("conformance", {}).get("direction", "lower_is_better")
    if direction != "lower_is_better":
        raise DesignError("conformance.direction", f'must be "lower_is_better", got {direction!r}')


def _read_profile(path: Path) -> tuple[np.ndarray, np.ndarray]:
    field_name = "conformance.surface_profile_csv"
    try:
        with path.open(newline="") as fh:
            rows = list(csv.DictReader(fh))
    except OSError as exc:
        raise DesignError(field_name, f"cannot read {path}: {exc}") from None
    if not rows or not {"distance_mm", "deflection_mm"} <= set(rows[0]):
        raise DesignError(field_name, f"{path} needs the columns distance_mm, deflection_mm")
    try:
        d = np.array([float(r["distance_mm"]) for r in rows])
        y = np.array([float(r["deflection_mm"]) for r in rows])
    except ValueError:
        raise DesignError(field_name, f"{path} has a non-numeric value") from None
    if len(d) < 2 or np.any(np.diff(d) <= 0) or d[0] < 0 or not np.all(np.isfinite(y)):
        raise DesignError(field_name, f"{path}: distances must increase from >= 0, values finite")
    return d, y


# ---------------------------------------------------------------------------------------------
# The human loading curve (force against displacement from touch) drawn with the tapping loops
# ---------------------------------------------------------------------------------------------

#: Where the loading curve comes from. Serina, Mote & Rempel (J. Biomech. 30(10) (1997)
#: 1035-1040) fitted a force-displacement law per loading angle and rate, but neither its form nor
#: its parameters could be read from any available source (docs/fingertip_3d.md, "Human
#: force-displacement curve"; searched again for issue 35: only abstracts of other studies were
#: found). So the curve is *derived, not Serina's fit*: the exponential F = B (exp(k d) - 1)
#: through the two loading points the targets source (Serina et al. 1997 as listed in Table 2 of
#: Cabibihan et al.: 1.83 mm at 1 N and 2.91 mm at 4 N, 0.5 Hz, 0 deg). The exponential form is
#: the one measured on the fingerpad under a flat probe: "The instantaneous elastic response
#: increased exponentially with position" (Pawluk DTV, Howe RD, J. Biomech. Eng. 121(2) (1999)
#: 178-183, abstract). For the human targets it gives B = 0.1243 N, k = 1.2035 1/mm
#: (docs/fingertip_3d.md). Only the stretch between the two points is supported by data; below
#: 1 N and above 4 N the curve is an extrapolation.
LOADING_CURVE_SOURCE = (
    "exponential F = B (exp(k d) - 1) through the targets' loading points (disp_at_1N_mm, 1 N) "
    "and (disp_at_4N_mm, 4 N); for the human targets these are Serina, Mote & Rempel, J. Biomech. "
    "30 (1997) 1035-1040, as listed in Table 2 of Cabibihan et al. Derived, not Serina et al.'s "
    "own fit, whose form and parameters could not be found; exponential form after Pawluk & "
    "Howe, J. Biomech. Eng. 121 (1999) 178-183"
)


@dataclass(frozen=True)
class LoadingCurve:
    """Force (N) against displacement from first touch (mm) on loading, F = B (exp(k d) - 1),
    through ``points`` ((displacement mm, force N) pairs); ``source``: where it comes from."""

    B_N: float
    k_per_mm: float
    points: tuple[tuple[float, float], ...]
    source: str = LOADING_CURVE_SOURCE

    def force(self, displacement_mm: Any) -> np.ndarray:
        """F(d) in N for displacements d in mm (array or number)."""
        return self.B_N * np.expm1(self.k_per_mm * np.asarray(displacement_mm, dtype=float))

    def displacement(self, force_N: Any) -> np.ndarray:
        """d(F) in mm for forces F in N (the inverse of ``force``)."""
        return np.log1p(np.asarray(force_N, dtype=float) / self.B_N) / self.k_per_mm


def _growth(k: float, d1: float, d2: float) -> float:
    """expm1(k d2) / expm1(k d1): the force ratio of the exponential, d2 / d1 at k = 0."""
    return d2 / d1 if k == 0.0 else math.expm1(k * d2) / math.expm1(k * d1)


def loading_curve(targets: Targets | None = None) -> LoadingCurve | None:
    """The exponential loading curve through the targets' (disp_at_1N_mm, 1 N) and
    (disp_at_4N_mm, 4 N) (the human targets when ``targets`` is None); see
    ``LOADING_CURVE_SOURCE``. None when the targets lack them or the 4 N displacement is not the
    larger (no rising curve passes through both). ``k`` < 0 when the points rise less than
    proportionally (d4 / d1 > 4)."""
    values = (targets or load_targets()).values
    d1, d4 = values.get("disp_at_1N_mm"), values.get("disp_at_4N_mm")
    if d1 is None or d4 is None or not 0.0 < d1 < d4:
        return None
    from scipy.optimize import brentq  # here: `import sim` stays light

    ratio = 4.0  # F(d4) / F(d1)
    # the growth rises with k (monotonic) from below 1 to beyond any ratio on this bracket
    k = brentq(lambda k: _growth(k, d1, d4) - ratio, -50.0 / d4, 50.0 / d4, xtol=1e-14)
    if k == 0.0:  # exactly proportional points: a line, as the limit of the exponential
        k = 1e-12
    return LoadingCurve(1.0 / math.expm1(k * d1), k, ((d1, 1.0), (d4, 4.0)))
