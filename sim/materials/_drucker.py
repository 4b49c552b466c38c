"""The Drucker-stable strains of a fitted material: what ``fingertip fit-material`` records of
them in the entry's ``provenance`` (:func:`stable_ranges`, checked as a catalogue is read) and
the compressive log strain an FE layer of it may reach within them
(:func:`stable_log_strain`, held against the FE's by ``sim.protocols.validity.check``).

``sim.materials.fit`` checks a fitted law as Abaqus does (``d sigma : d eps > 0``) in the
homogeneous deformations ``STABILITY_MODES`` at nominal strains ``STABILITY_STRAIN_RANGE``, and
writes, per deformation, the interval around 0 in which every checked strain is stable, as
``drucker_stable_<deformation> = [low, high]``. An end inside the checked range is where the law
turned unstable; an end at the range's edge is stable as far as the check looked.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from numbers import Real
from typing import TYPE_CHECKING, Any

from sim.errors import DesignError

if TYPE_CHECKING:
    from sim.materials._law import Law

__all__ = [
    "PROVENANCE_KEY",
    "STABILITY_MODES",
    "STABILITY_STRAIN_RANGE",
    "stable_log_strain",
    "stable_ranges",
]

#: nominal strains of the Drucker stability check, as asked of Abaqus' evaluation here
STABILITY_STRAIN_RANGE = (-0.8, 2.0)
#: the deformations checked (uniaxial covers compression with its negative strains)
STABILITY_MODES = ("uniaxial", "biaxial", "planar")
#: the provenance key of a deformation's stable range (``PROVENANCE_KEY.format(mode)``)
PROVENANCE_KEY = "drucker_stable_{}"


def stable_ranges(provenance: Mapping[str, Any], field: str) -> dict[str, tuple[float, float]]:
    """The Drucker-stable nominal strain range per deformation that ``provenance`` records
    (``drucker_stable_<mode>`` for the modes of ``STABILITY_MODES``; none: {}), checked: two
    numbers ``low <= 0 <= high``, ``low > -1`` (a nominal strain of -1 is a stretch of 0). A
    ``DesignError`` names ``f"{field}.drucker_stable_<mode>"`` otherwise."""
    prefix = PROVENANCE_KEY.format("")
    out = {}
    for key, value in provenance.items():
        if not key.startswith(prefix):
            continue
        mode, name = key[len(prefix) :], f"{field}.{key}"
        if mode not in STABILITY_MODES:
            known = ", ".join(PROVENANCE_KEY.format(m) for m in STABILITY_MODES)
            raise DesignError(name, f"unknown deformation; fingertip fit-material writes {known}")
        ok = isinstance(value, list | tuple) and len(value) == 2
        ok = ok and all(isinstance(x, Real) and not isinstance(x, bool) for x in value)
        ok = ok and all(math.isfinite(x) for x in value) and -1.0 < value[0] <= 0.0 <= value[1]
        if not ok:
            raise DesignError(
                name,
                f"must be [low, high], nominal strains with -1 < low <= 0 <= high, got {value!r}",
            )
        out[mode] = (float(value[0]), float(value[1]))
    return out


def stable_log_strain(law: Law, ranges: Mapping[str, tuple[float, float]]) -> float | None:
    """The largest compressive log strain, ``-ln`` of the smallest principal stretch (the FE's
    measure, ``sim.protocols.validity``), that a material of ``law`` may reach and stay
    Drucker-stable, by its ``ranges`` (:func:`stable_ranges`); None when no range was cut short by
    an instability (stable wherever the check looked, or nothing recorded).

    At each end of a range inside ``STABILITY_STRAIN_RANGE`` (the last stable strain before
    the law turned unstable), the smallest principal stretch of that homogeneous deformation
    (``sim.materials.fit.mode_stretches``: the test's own, with the law's Poisson's ratio) gives a
    compressive log strain; the smallest over the ends is returned. Conservative: the plane-
    strain FE is nearest to the planar test (one principal stretch 1), but a layer is flagged
    at the first strain at which any checked deformation of its law turned unstable."""
    low_edge, high_edge = STABILITY_STRAIN_RANGE
    cut = [
        (mode, end)
        for mode, (low, high) in ranges.items()
        for end, inside in ((low, low > low_edge), (high, high < high_edge))
        if inside
    ]
    if not cut:
        return None
    import numpy as np

    from sim.materials.fit import (
        mode_stretches,  # only for a law found unstable: sim.materials.fit stays unloaded
    )

    strains = []
    for mode, end in cut:
        lam, _ = mode_stretches(law.model, mode, np.array([end]), law.nu)
        strains.append(max(0.0, -float(np.log(lam.min()))))
    return min(strains)
