"""Calibrate a catalogue material from test data (``fingertip fit-material``).

Test data follow Abaqus' conventions (Abaqus Analysis User's Guide, "Hyperelastic behavior of
rubberlike materials", test data): nominal (engineering) strain and nominal stress (force per
undeformed area), one CSV per test with the header ``nominal_strain,nominal_stress_MPa``:

* ``uniaxial``: uniaxial tension (strain >= 0, increasing);
* ``compression``: uniaxial compression, negative strain and stress (strain <= 0, decreasing);
* ``biaxial``: equibiaxial tension (the stress in each of the two pulled directions);
* ``planar``: planar tension ("pure shear": the width held, the thickness free).

Blank lines and lines starting with ``#`` are skipped (a place to note the specimen).

A relaxation CSV (``time_s,g_R``) holds the normalised shear relaxation modulus
``g_R(t) = G(t) / G(0)`` (1 at ``t = 0``, in (0, 1]), fitted by ``N`` Prony terms
``g_R = 1 - sum g_i (1 - exp(-t / tau_i))``.

The closed forms are those of Abaqus' material evaluation: homogeneous 3D states, the
invariant laws and the Ogden law incompressible (their deviatoric response; ``nu`` then sets the
bulk modulus, as Abaqus adds ``D1`` to a deviatoric fit), the hyperfoam compressible with its
lateral stretches from the lateral stress-free condition, which for one ``beta`` shared by all
terms has the closed forms ``l_lat = l^-nu`` (uniaxial), ``l3 = l^(-2 beta / (1 + beta))``
(equibiaxial) and ``l3 = l^(-beta / (1 + beta))`` (planar).  With the principal Kirchhoff
stresses ``tau_i = l_i dU/dl_i`` the nominal stress of a test is ``T = (tau_1 - tau_free) / l_1``
(``tau_free``: a traction-free direction; its difference removes the pressure).

Fit (``scipy.optimize.least_squares`` with bounds, every test together): relative errors
``(T_fit - T) / max(|T|, 5 % of the test's largest |T|)`` (Abaqus minimises relative errors; the
floor keeps the noisy first points of a real curve from dominating), each test divided by the
square root of its number of points so that each test counts the same whatever its sampling.
Parametrisations keep every fitted law admissible: Mooney-Rivlin through ``mu0 = 2 (C10 + C01)
> 0``, Yeoh ``C10 > 0``, Ogden and hyperfoam through ``mu_p alpha_p > 0`` per term (Ogden's
sufficient stability condition, which the laws require), from several starting points (their
fits have local minima).  The Drucker stability check follows Abaqus: ``d sigma : d eps > 0``
(positive definite tangent of the principal stresses in the log strains; incompressible: of
``sigma_1 - sigma_3`` and ``sigma_2 - sigma_3``; compressible: of the Kirchhoff stress) at
nominal strains -0.8..+2 in uniaxial, equibiaxial and planar deformation; the stable range of
each is the interval around 0 in which every checked strain is stable.

Which moduli the fit gives (``moduli`` of the entry):

* elastic (no relaxation data): the law's moduli are the test's; ``"long_term"`` is written
  and means the same as ``"instantaneous"`` for an elastic material;
* relaxation data without a rate: the curves are taken as the relaxed (equilibrium) response,
  so the moduli are ``"long_term"`` (Abaqus' default convention), and the provenance says so;
* relaxation data and the test's strain rate (``rate_per_s``): the curves are fitted *through*
  the viscoelastic model (the same Prony recursion on the second Piola-Kirchhoff stress as the
  solver, shear only for the decoupled laws, the whole stress for the hyperfoam), each test a
  ramp from rest at that constant nominal strain rate, so the fitted moduli are the
  ``"instantaneous"`` ones; a test at a finite rate is neither relaxed nor instantaneous, and
  only this way does the catalogue entry reproduce it.
"""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import json
import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import DesignError, read_bytes
from ..provenance import json_text
from . import LAWS, MAX_PRONY_TERMS, Material, Prony
from ._drucker import PROVENANCE_KEY, STABILITY_MODES, STABILITY_STRAIN_RANGE
from ._law import MAX_TERMS
from ._special import exprel
from ._validate import poisson

__all__ = [
    "DEFAULT_NU",
    "FIT_MODELS",
    "MODES",
    "STABILITY_STRAIN_RANGE",
    "TESTED_MODES",
    "Curve",
    "MaterialFit",
    "ModeFit",
    "PronyFit",
    "RelaxationData",
    "drucker_stable_ranges",
    "fit_material",
    "fit_plot_data",
    "fit_prony",
    "nominal_stress",
    "reached_log_strains",
    "read_curve",
    "read_relaxation",
    "write_fit",
]

MODES = ("uniaxial", "compression", "biaxial", "planar")
FIT_MODELS = ("neo_hookean", "mooney_rivlin", "yeoh", "ogden", "hyperfoam")
# the Drucker stability check's nominal strains and deformations, and the provenance key of
# each stable range: ``sim.materials._drucker``'s (a material carries its ranges to the FE)
#: Poisson's ratio when none is given: the catalogue's convention for silicones (0.499 as the gel
#: family's ``sim.design.families.GEL_NU``, an assumption recorded in the entry: a tensile test says
#: nothing of the bulk modulus; the incompressible fits do not depend on it)
DEFAULT_NU = 0.499
DEFAULT_TERMS = {"yeoh": 3, "ogden": 1, "hyperfoam": 1}  # Abaqus: Yeoh has 3, N = 1 default
DEFAULT_PRONY_TERMS = 3
MIN_CURVE_POINTS = 3
#: relative-error floor, as a fraction of a test's largest |stress| (see the module docstring)
_FLOOR = 0.05
_HEADERS = {"curve": ("nominal_strain", "nominal_stress_MPa"), "relaxation": ("time_s", "g_R")}
_NAME = re.compile(r"^[A-Za-z0-9_-]+$")

Array = np.ndarray


# ----------------------------------------------------------------------------- test data
@dataclass(frozen=True, eq=False)
class Curve:
    """One hyperelastic test: ``mode`` (``MODES``), nominal strain and nominal stress (MPa)."""

    mode: str
    nominal_strain: Array
    nominal_stress_MPa: Array
    path: str = ""
    sha256: str = ""

    @property
    def strain_range(self) -> tuple[float, float]:
        return float(self.nominal_strain.min()), float(self.nominal_strain.max())


@dataclass(frozen=True, eq=False)
class RelaxationData:
    """A relaxation test: times (s) and the normalised shear relaxation modulus ``g_R``."""

    time_s: Array
    g_R: Array
    path: str = ""
    sha256: str = ""


def _read_rows(path: str | Path, option: str, kind: str) -> tuple[Array, Array, str]:
    """The two numeric columns of a CSV with the header of ``kind``; every problem is one
    ``DesignError`` naming ``option``, the file and the line."""
    path = Path(path)
    header = _HEADERS[kind]
    raw = read_bytes(path, option, "CSV file")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise DesignError(option, f"{path} is not UTF-8 text") from None
    rows = [
        (n, row)
        for n, row in enumerate(csv.reader(text.splitlines()), start=1)
        if row and any(c.strip() for c in row) and not row[0].lstrip().startswith("#")
    ]
    if not rows:
        raise DesignError(option, f"{path} is empty (expected the header {','.join(header)})")
    n0, first = rows[0]
    if tuple(c.strip() for c in first) != header:
        raise DesignError(
            option,
            f"{path} line {n0}: the header must be {','.join(header)}, got {','.join(first)}",
        )
    x, y = [], []
    for n, row in rows[1:]:
        if len(row) != 2:
            raise DesignError(option, f"{path} line {n}: expected 2 values, got {len(row)}")
        try:
            a, b = float(row[0]), float(row[1])
        except ValueError:
            raise DesignError(option, f"{path} line {n}: not a number: {','.join(row)}") from None
        if not (math.isfinite(a) and math.isfinite(b)):
            raise DesignError(option, f"{path} line {n}: values must be finite")
        x.append(a)
        y.append(b)
    return np.asarray(x), np.asarray(y), hashlib.sha256(raw).hexdigest()


def read_curve(path: str | Path, mode: str) -> Curve:
    """Read a hyperelastic test CSV (``nominal_strain,nominal_stress_MPa``) for ``mode``."""
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
    option = f"--{mode}"
    strain, stress, sha = _read_rows(path, option, "curve")
    if len(strain) < MIN_CURVE_POINTS:
        raise DesignError(
            option, f"{path}: too few points ({len(strain)}); at least {MIN_CURVE_POINTS}"
        )
    if mode == "compression":
        if strain.max() > 0.0 or strain.min() <= -1.0:
            raise DesignError(
                option, f"{path}: compression strains must be in (-1, 0], got "
                f"{strain.min():g}..{strain.max():g}"
            )  # fmt: skip
        step = -np.diff(strain)
        direction = "decreasing (0, -0.05, -0.1, ...)"
    else:
        if strain.min() < 0.0:
            raise DesignError(
                option, f"{path}: {mode} strains must be >= 0 (compression goes to "
                f"--compression), got {strain.min():g}"
            )  # fmt: skip
        step = np.diff(strain)
        direction = "increasing"
    if not (step > 0).all():
        k = int(np.argmax(step <= 0))
        raise DesignError(
            option, f"{path}: nominal_strain must be strictly {direction}; it is not at data "
            f"row {k + 2} ({strain[k]:g} then {strain[k + 1]:g})"
        )  # fmt: skip
    return Curve(mode, strain, stress, str(path), sha)


def read_relaxation(path: str | Path) -> RelaxationData:
    """Read a relaxation CSV (``time_s,g_R``): times >= 0 strictly increasing, ``g_R`` in
    (0, 1]."""
    t, g, sha = _read_rows(path, "--relaxation", "relaxation")
    if len(t) < 2:
        raise DesignError("--relaxation", f"{path}: too few points ({len(t)})")
    if t.min() < 0.0 or not (np.diff(t) > 0).all():
        raise DesignError("--relaxation", f"{path}: time_s must be >= 0 and strictly increasing")
    bad = (g <= 0.0) | (g > 1.0)
    if bad.any():
        k = int(np.argmax(bad))
        raise DesignError(
            "--relaxation",
            f"{path}: g_R must be in (0, 1] (normalised: 1 at t = 0), got {g[k]:g} at "
            f"t = {t[k]:g} s",
        )
    return RelaxationData(t, g, str(path), sha)


# ----------------------------------------------------------------------------- closed forms
def _beta(nu: float) -> float:
    return nu / (1.0 - 2.0 * nu)


def mode_stretches(model: str, mode: str, strain: Array, nu: float) -> tuple[Array, int]:
    """Principal stretches ``(3, n)`` of a homogeneous test at nominal ``strain`` and the
    index of a traction-free direction (see the module docstring)."""
    lam = 1.0 + np.asarray(strain, dtype=float)
    one = np.ones_like(lam)
    foam = model == "hyperfoam"
    if mode in ("uniaxial", "compression"):
        lat = lam ** (-nu) if foam else lam**-0.5
        return np.stack((lam, lat, lat)), 1
    beta = _beta(nu)
    if mode == "biaxial":
        l3 = lam ** (-2.0 * beta / (1.0 + beta)) if foam else lam**-2.0
        return np.stack((lam, lam, l3)), 2
    if mode == "planar":
        l3 = lam ** (-beta / (1.0 + beta)) if foam else 1.0 / lam
        return np.stack((lam, one, l3)), 2
    raise ValueError(f"unknown mode {mode!r}")


def kirchhoff(model: str, params: Mapping[str, Any], lam: Array, nu: float) -> Array:
    """Principal Kirchhoff stresses ``tau_i = l_i dU/dl_i`` (MPa) at stretches ``lam`` (3, n);
    up to a common pressure for the incompressible forms."""
    if model == "neo_hookean":
        return params["mu_MPa"] * lam**2
    if model == "mooney_rivlin":
        return 2.0 * params["c10_MPa"] * lam**2 - 2.0 * params["c01_MPa"] * lam**-2.0
    if model == "yeoh":
        x = (lam**2).sum(axis=0) - 3.0
        c1, c2, c3 = (params.get(k, 0.0) for k in ("c10_MPa", "c20_MPa", "c30_MPa"))
        return 2.0 * (c1 + x * (2.0 * c2 + 3.0 * c3 * x)) * lam**2
    if model in ("ogden", "hyperfoam"):
        tau = np.zeros_like(lam)
        J = lam.prod(axis=0)
        beta = _beta(nu)
        for mu, alpha in zip(params["mu_MPa"], params["alpha"], strict=True):
            term = lam**alpha
            if model == "hyperfoam":
                term = term - J ** (-alpha * beta)
            tau += 2.0 * mu / alpha * term
        return tau
    raise ValueError(f"unknown model {model!r}")


def nominal_stress(
    model: str, params: Mapping[str, Any], mode: str, strain: Array, nu: float
) -> Array:
    """Nominal stress (MPa) of a homogeneous test (elastic closed form)."""
    lam, free = mode_stretches(model, mode, strain, nu)
    tau = kirchhoff(model, params, lam, nu)
    return (tau[0] - tau[free]) / lam[0]


def _piola2(model: str, params: Mapping[str, Any], lam: Array, nu: float) -> Array:
    """Principal 2nd Piola-Kirchhoff stresses of the part that relaxes: the isochoric one
    (deviatoric Kirchhoff / l^2) for the decoupled laws, the whole stress for the hyperfoam."""
    tau = kirchhoff(model, params, lam, nu)
    if model != "hyperfoam":
        tau = tau - tau.mean(axis=0)
    return tau / lam**2


def _relaxation_matrix(time_s: Array, g: Sequence[float], tau_s: Sequence[float]) -> Array:
    """``A`` with ``S(t_k) = sum_j A_kj (S0(t_j) - S0(t_(j-1)))``: the hereditary integral of a
    piecewise-linear ``S0`` (exact), ``A_kj = g_inf + sum_i g_i e^(-(t_k - t_j)/tau_i)
    exprel(-dt_j/tau_i)`` for ``j <= k``."""
    t = np.asarray(time_s, dtype=float)
    dt = np.diff(t)
    A = np.full((len(t), len(dt)), 1.0 - float(sum(g)))
    lag = t[:, None] - t[None, 1:]
    for gi, ti in zip(g, tau_s, strict=True):
        A += gi * np.exp(-np.maximum(lag, 0.0) / ti) * exprel(-dt / ti)[None, :]
    A[lag < 0] = 0.0
    return A


@dataclass(frozen=True, eq=False)
class _Ramp:
    """A test seen as a ramp from rest at a constant nominal strain rate: the path's strains,
    the data points' places on it and the relaxation matrix."""

    strain: Array
    at_data: Array
    A: Array


def _ramp(curve: Curve, rate_per_s: float, prony: Prony) -> _Ramp:
    e_end = curve.nominal_strain[np.argmax(np.abs(curve.nominal_strain))]
    path = np.union1d(np.linspace(0.0, e_end, 201), np.append(curve.nominal_strain, 0.0))
    path = path[np.argsort(np.abs(path))]
    at = np.searchsorted(np.abs(path), np.abs(curve.nominal_strain))
    A = _relaxation_matrix(np.abs(path) / rate_per_s, prony.g, prony.tau_s)
    return _Ramp(path, at, A)


def _viscous_nominal(
    model: str, params: Mapping[str, Any], mode: str, ramp: _Ramp, nu: float
) -> Array:
    """Nominal stress along a ramp through the Prony recursion (see the module docstring):
    ``T = l1 S1 - l_free^2 S_free / l1`` with the relaxed ``S`` (the pressure keeps the free
    direction traction-free)."""
    lam, free = mode_stretches(model, mode, ramp.strain, nu)
    S0 = _piola2(model, params, lam, nu)
    S = ramp.A @ np.diff(S0, axis=1).T  # (n_path, 3), S(0) = 0 at rest
    T = lam[0] * S[:, 0] - lam[free] ** 2 * S[:, free] / lam[0]
    return T[ramp.at_data]


# ----------------------------------------------------------------------------- parametrisation
@dataclass(frozen=True)
class _Spec:
    """How a model's law parameters map to the least-squares vector ``x``."""

    lower: tuple[float, ...]
    upper: tuple[float, ...]
    to_params: Callable[[Array], dict[str, Any]]
    starts: tuple[tuple[float, ...], ...]


_STRETCH_ALPHAS = {
    1: ((2.0,), (4.0,), (8.0,), (1.0,), (-2.0,)),
    2: ((2.0, 8.0), (1.0, 4.0), (3.0, 12.0), (4.0, -2.0), (8.0, -4.0), (1.5, -1.0)),
    3: ((1.0, 4.0, 10.0), (2.0, 6.0, -2.0), (1.5, 8.0, -4.0), (3.0, 12.0, -1.0)),
}


def _spec(model: str, terms: int, mu0: float) -> _Spec:
    inf = math.inf
    if model == "neo_hookean":
        return _Spec((0.0,), (inf,), lambda x: {"mu_MPa": float(x[0])}, ((mu0,),))

    if model == "mooney_rivlin":  # x = (mu0, C01), C10 = mu0 / 2 - C01

        def mr(x: Array) -> dict[str, Any]:
            return {"c10_MPa": float(x[0] / 2 - x[1]), "c01_MPa": float(x[1])}

        return _Spec((0.0, -inf), (inf, inf), mr, ((mu0, 0.0), (mu0, 0.2 * mu0)))
    if model == "yeoh":
        keys = ("c10_MPa", "c20_MPa", "c30_MPa")[:terms]
        return _Spec(
            (0.0,) + (-inf,) * (terms - 1),
            (inf,) * terms,
            lambda x: {k: float(v) for k, v in zip(keys, x, strict=True)},
            ((mu0 / 2,) + (0.0,) * (terms - 1),),
        )
    # Ogden / hyperfoam: x = (m_1..m_N, alpha_1..alpha_N), mu_p = m_p / alpha_p, m_p > 0
    starts = []
    for alphas in _STRETCH_ALPHAS[terms]:
        pos = sum(a > 0 for a in alphas)
        mus = [mu0 * 1.1 / pos if a > 0 else -0.1 * mu0 for a in alphas]
        starts.append(tuple(m * a for m, a in zip(mus, alphas, strict=True)) + alphas)

    def stretch(x: Array) -> dict[str, Any]:
        m, a = x[:terms], x[terms:]
        return {"mu_MPa": tuple(float(v) for v in m / a), "alpha": tuple(float(v) for v in a)}

    return _Spec((), (), stretch, tuple(starts))


def _bounds_for(spec: _Spec, start: tuple[float, ...], terms: int) -> tuple[Array, Array]:
    if spec.lower:
        return np.asarray(spec.lower), np.asarray(spec.upper)
    signs = np.sign(start[terms:])
    lo_a = np.where(signs > 0, 0.1, -40.0)
    hi_a = np.where(signs > 0, 40.0, -0.1)
    return (
        np.concatenate([np.zeros(terms), lo_a]),
        np.concatenate([np.full(terms, math.inf), hi_a]),
    )


# ----------------------------------------------------------------------------- results
@dataclass(frozen=True)
class ModeFit:
    """The fit's agreement with one test: ``r2`` (coefficient of determination of the nominal
    stress), ``rms_MPa`` and ``max_abs_error_MPa`` (nominal stress), ``strain_range``."""

    mode: str
    path: str
    sha256: str
    n_points: int
    strain_range: tuple[float, float]
    r2: float
    rms_MPa: float
    max_abs_error_MPa: float


@dataclass(frozen=True)
class PronyFit:
    """Prony terms fitted to a relaxation test, with ``r2`` and ``rms`` of ``g_R``."""

    g: tuple[float, ...]
    tau_s: tuple[float, ...]
    r2: float
    rms: float
    n_points: int
    time_range_s: tuple[float, float]
    path: str = ""
    sha256: str = ""

    @property
    def prony(self) -> Prony:
        return Prony(self.g, self.tau_s)


@dataclass(frozen=True, eq=False)
class MaterialFit:
    """Everything ``fit-material`` found: the entry (:meth:`entry`), the agreement per test,
    the Drucker-stable range per deformation and the data (for the figure)."""

    name: str
    model: str
    params: dict[str, Any]
    nu: float
    nu_given: bool
    terms: int | None
    modes: tuple[ModeFit, ...]
    prony: PronyFit | None
    moduli: str
    moduli_reason: str
    stable_ranges: dict[str, tuple[float, float]]
    source: str
    rate_per_s: float | None
    curves: tuple[Curve, ...] = field(repr=False)
    relaxation: RelaxationData | None = field(default=None, repr=False)

    @property
    def stable_everywhere(self) -> bool:
        lo, hi = STABILITY_STRAIN_RANGE
        return all(r == (lo, hi) for r in self.stable_ranges.values())

    @property
    def material(self) -> Material:
        from . import material_from_spec

        return material_from_spec({**self.entry(), "name": self.name}, self.name)

    def provenance(self) -> dict[str, Any]:
        """The entry's ``provenance`` table (flat: strings, numbers, booleans, lists)."""
        from ..provenance import git_commit

        tested = {m.mode for m in self.modes}
        out: dict[str, Any] = {
            "method": "fingertip fit-material: scipy.optimize.least_squares on relative errors, "
            "every test together and weighted equally (sim/materials/fit.py)",
            "git_commit": git_commit(),
            "tests": [m.mode for m in self.modes],
            "files": [Path(m.path).name for m in self.modes],
            "sha256": [m.sha256 for m in self.modes],
        }
        for m in self.modes:
            out[f"{m.mode}_strain_range"] = list(m.strain_range)
            out[f"{m.mode}_points"] = m.n_points
            out[f"{m.mode}_r2"] = _round(m.r2)
            out[f"{m.mode}_rms_MPa"] = _round(m.rms_MPa)
        if "compression" not in tested:
            out["compression"] = (
                "extrapolated from tension" if tested & {"uniaxial", "biaxial", "planar"} else ""
            )
        out.update(reached_log_strains(self.model, self.modes, self.nu))
        if self.rate_per_s is not None:
            out["rate_per_s"] = self.rate_per_s
        if self.prony is None:
            out["relaxation"] = "none: ELASTIC-ONLY"
        else:
            p = self.prony
            out["relaxation"] = f"{len(p.g)} Prony terms fitted to {Path(p.path).name}"
            out["relaxation_file_sha256"] = p.sha256
            out["relaxation_time_range_s"] = list(p.time_range_s)
            out["relaxation_r2"] = _round(p.r2)
            out["relaxation_rms"] = _round(p.rms)
        out["moduli_reason"] = self.moduli_reason
        out["nu_assumed"] = not self.nu_given
        for mode, (lo, hi) in self.stable_ranges.items():
            out[PROVENANCE_KEY.format(mode)] = [lo, hi]
        return {k: v for k, v in out.items() if not (isinstance(v, float) and not math.isfinite(v))}

    def entry(self) -> dict[str, Any]:
        """The catalogue table (without its name): source, law, Prony terms, moduli,
        provenance."""
        law = LAWS[self.model].from_params({**self.params, "nu": self.nu}, self.name)
        table: dict[str, Any] = {"source": self.source, **law.to_dict()}
        if self.prony is not None:
            table["prony_g"] = list(self.prony.g)
            table["prony_tau_s"] = list(self.prony.tau_s)
        table["moduli"] = self.moduli
        table["provenance"] = self.provenance()
        return table

    def to_json(self) -> dict[str, Any]:
        def finite(d: dict[str, Any]) -> dict[str, Any]:
            return {k: None if isinstance(v, float) and not math.isfinite(v) else v
                    for k, v in d.items()}  # fmt: skip

        return {
            "name": self.name,
            "entry": self.entry(),
            "tests": [finite(dataclasses.asdict(m)) for m in self.modes],
            "relaxation": None if self.prony is None else finite(dataclasses.asdict(self.prony)),
            "drucker_stable_range": {k: list(v) for k, v in self.stable_ranges.items()},
            "stability_strain_range": list(STABILITY_STRAIN_RANGE),
            "stable_everywhere": self.stable_everywhere,
        }


def _round(x: float, digits: int = 6) -> float:
    return float(f"{x:.{digits}g}")


def _round_params(params: dict[str, Any]) -> dict[str, Any]:
    return {
        k: tuple(_round(v) for v in val) if isinstance(val, tuple) else _round(val)
        for k, val in params.items()
    }


# ----------------------------------------------------------------------------- tested range
#: the mode of each test (``MODES``) in the words of ``sim/data/material_tests.toml``
#: (``sim.materials._tests.MODES``)
TESTED_MODES = {
    "uniaxial": "uniaxial_tension",
    "compression": "uniaxial_compression",
    "biaxial": "biaxial",
    "planar": "shear",
}


def reached_log_strains(model: str, modes: Sequence[ModeFit], nu: float) -> dict[str, Any]:
    """The tested range of the data a law was fitted to, as the provenance keys that
    ``sim.protocols.validity.layer_limit`` reads (``sim.materials._tests.PROVENANCE_KEYS``):
    ``tested_mode`` (each test's mode, ``TESTED_MODES``), ``max_compressive_log_strain`` and
    ``max_tensile_log_strain``, the largest ``-ln`` of the smallest and ``ln`` of the largest
    principal stretch (``mode_stretches``: the test's own, with the law's Poisson's ratio) over
    the tests that exercise that side (``sim.materials._tests.MODES``: a compression test the
    compressive side, a uniaxial tension test the tensile side, equibiaxial and planar tests
    both), at the ends of each test's fitted strain range.

    With no test that compresses the material (tension only), the compressive limit is ARGUED,
    never absent: the lateral contraction of the tension tests, the stretches at which the law
    was evaluated in them (``l^-1/2`` for the incompressible fits, ``l^-nu`` for the hyperfoam;
    a compressive log strain of ``ln(l) / 2`` for the former), said in ``tested_note``."""
    from ._tests import MODES as SIDES

    reached: dict[str, float] = {}
    for m in modes:
        lam, _ = mode_stretches(model, m.mode, np.asarray(m.strain_range, dtype=float), nu)
        logs = np.log(lam)
        sides = SIDES[TESTED_MODES[m.mode]]
        for side, value in (("compressive", -float(logs.min())), ("tensile", float(logs.max()))):
            key = side if side in sides else f"lateral_{side}"
            reached[key] = max(reached.get(key, 0.0), value, 0.0)
    out: dict[str, Any] = {"tested_mode": list(dict.fromkeys(TESTED_MODES[m.mode] for m in modes))}
    if "compressive" in reached:
        out["max_compressive_log_strain"] = _round(reached["compressive"], 4)
    else:
        lateral = _round(reached.get("lateral_compressive", 0.0), 4)
        out["max_compressive_log_strain"] = lateral
        out["tested_note"] = (
            "ARGUED: no test compressed the material; the compressive limit is the lateral "
            "contraction of its tension tests, the stretches at which the law was evaluated in "
            f"them (a compressive log strain of {lateral:g}; docs/materials.md, 'The range each "
            "material was tested in')"
        )
    if "tensile" in reached:
        out["max_tensile_log_strain"] = _round(reached["tensile"], 4)
    return out


# ----------------------------------------------------------------------------- fitting
def _initial_shear_modulus(curves: Sequence[Curve]) -> float:
    """``mu0`` from the small-strain slopes: T = 3 mu e (uniaxial), 6 mu e (equibiaxial),
    4 mu e (planar), over |e| <= 0.1 (or the first four points)."""
    factor = {"uniaxial": 3.0, "compression": 3.0, "biaxial": 6.0, "planar": 4.0}
    estimates = []
    for c in curves:
        e, T = c.nominal_strain, c.nominal_stress_MPa
        near = np.abs(e) <= 0.1
        if near.sum() < 4:
            near = np.argsort(np.abs(e))[:4]
        slope = float(e[near] @ T[near] / max(float(e[near] @ e[near]), 1e-300))
        if slope > 0:
            estimates.append(slope / factor[c.mode])
    if not estimates:
        raise DesignError("test data", "the stress does not rise with the strain in any test")
    return float(np.median(estimates))


def _stats(curve: Curve, model_T: Array) -> ModeFit:
    T = curve.nominal_stress_MPa
    res = model_T - T
    ss_tot = float(((T - T.mean()) ** 2).sum())
    r2 = 1.0 - float((res**2).sum()) / ss_tot if ss_tot > 0 else math.nan
    return ModeFit(
        mode=curve.mode,
        path=curve.path,
        sha256=curve.sha256,
        n_points=len(T),
        strain_range=curve.strain_range,
        r2=r2,
        rms_MPa=float(np.sqrt((res**2).mean())),
        max_abs_error_MPa=float(np.abs(res).max()),
    )


def _fit_law(
    model: str,
    curves: Sequence[Curve],
    terms: int,
    nu: float,
    predict: Callable[[dict[str, Any], Curve], Array],
) -> dict[str, Any]:
    """Least squares over every test together; the best admissible start."""
    mu0 = _initial_shear_modulus(curves)
    spec = _spec(model, terms, mu0)
    scales = [
        np.maximum(np.abs(c.nominal_stress_MPa), _FLOOR * np.abs(c.nominal_stress_MPa).max())
        * math.sqrt(len(c.nominal_strain))
        for c in curves
    ]

    def residuals(x: Array) -> Array:
        params = spec.to_params(x)
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            parts = [
                (predict(params, c) - c.nominal_stress_MPa) / s
                for c, s in zip(curves, scales, strict=True)
            ]
        r = np.concatenate(parts)
        return np.where(np.isfinite(r), r, 1e6)

    from scipy.optimize import least_squares  # scipy only when fitting, not for the CLI parser

    best = None
    for start in spec.starts:
        lo, hi = _bounds_for(spec, start, terms)
        x0 = np.clip(np.asarray(start, dtype=float), lo, hi)
        try:
            sol = least_squares(residuals, x0, bounds=(lo, hi), x_scale="jac", max_nfev=4000)
        except ValueError:
            continue
        params = spec.to_params(sol.x)
        try:
            LAWS[model].from_params({**params, "nu": nu}, model)
        except DesignError:
            continue  # inadmissible (e.g. a term that vanished): another start
        if best is None or sol.cost < best[0]:
            best = (sol.cost, params)
    if best is None:
        raise DesignError(
            "--model", f"no admissible {model} fit to these data (every start failed)"
        )
    return best[1]


def fit_prony(data: RelaxationData, n_terms: int) -> PronyFit:
    """``n_terms`` Prony terms (``g_i >= 0``, ``sum g_i < 1``, ``tau_i`` in the data's time
    range widened tenfold) fitted to ``g_R`` by least squares on relative errors."""
    if not 1 <= n_terms <= MAX_PRONY_TERMS:
        raise DesignError("--prony", f"must be 1 to {MAX_PRONY_TERMS}, got {n_terms}")
    if len(data.time_s) < 2 * n_terms + 1:
        raise DesignError(
            "--relaxation",
            f"{data.path}: too few points ({len(data.time_s)}) for {n_terms} Prony terms; at "
            f"least {2 * n_terms + 1}",
        )
    t, g_R = data.time_s, data.g_R
    positive = t[t > 0]
    lo_tau, hi_tau = math.log10(positive.min() / 10.0), math.log10(t.max() * 10.0)
    n = n_terms

    def model(x: Array, times: Array) -> Array:
        g, tau = x[:n], 10.0 ** x[n:]
        return 1.0 - (g[:, None] * -np.expm1(-times[None, :] / tau[:, None])).sum(axis=0)

    def residuals(x: Array) -> Array:
        r = (model(x, t) - g_R) / g_R / math.sqrt(len(t))
        excess = max(0.0, float(x[:n].sum()) - (1.0 - 1e-6))
        return np.append(r, 1e3 * excess)

    from scipy.optimize import least_squares

    best = None
    span = np.linspace(math.log10(positive.min()), math.log10(t.max()), n + 2)[1:-1]
    for shift in (0.0, -0.5, 0.5):
        logtau = np.clip(span + shift, lo_tau, hi_tau)
        drop = max(1.0 - float(g_R.min()), 0.05)
        x0 = np.concatenate([np.full(n, 0.9 * drop / n), logtau])
        lo = np.concatenate([np.zeros(n), np.full(n, lo_tau)])
        hi = np.concatenate([np.ones(n), np.full(n, hi_tau)])
        sol = least_squares(residuals, x0, bounds=(lo, hi), max_nfev=4000)
        if best is None or sol.cost < best.cost:
            best = sol
    order = np.argsort(best.x[n:])
    g = tuple(_round(float(v)) for v in best.x[:n][order])
    tau = tuple(_round(float(10.0**v)) for v in best.x[n:][order])
    fitted = Prony(g, tau).relaxation(t)
    res = fitted - g_R
    ss_tot = float(((g_R - g_R.mean()) ** 2).sum())
    return PronyFit(
        g=g,
        tau_s=tau,
        r2=1.0 - float((res**2).sum()) / ss_tot if ss_tot > 0 else math.nan,
        rms=float(np.sqrt((res**2).mean())),
        n_points=len(t),
        time_range_s=(float(t.min()), float(t.max())),
        path=data.path,
        sha256=data.sha256,
    )


def drucker_stable_ranges(
    model: str, params: Mapping[str, Any], nu: float, n: int = 281
) -> dict[str, tuple[float, float]]:
    """Per deformation (``STABILITY_MODES``), the interval of nominal strain around 0 within
    ``STABILITY_STRAIN_RANGE`` (checked at ``n`` points) where ``d sigma : d eps > 0``."""
    lo, hi = STABILITY_STRAIN_RANGE
    strains = np.round(np.linspace(lo, hi, n), 6)
    out = {}
    for mode in STABILITY_MODES:
        lam, _ = mode_stretches(model, mode, strains, nu)
        stable = _drucker(model, params, np.log(lam), nu)
        i0 = int(np.argmin(np.abs(strains)))
        a = i0
        while a > 0 and stable[a - 1]:
            a -= 1
        b = i0
        while b < n - 1 and stable[b + 1]:
            b += 1
        out[mode] = (float(strains[a]), float(strains[b])) if stable[i0] else (0.0, 0.0)
    return out


def _drucker(model: str, params: Mapping[str, Any], eps: Array, nu: float) -> Array:
    """Whether the principal tangent is positive definite at the log strains ``eps`` (3, n):
    incompressible laws ``d(sigma_1 - sigma_3, sigma_2 - sigma_3) / d(eps_1, eps_2)``
    (``eps_3 = -eps_1 - eps_2``, so ``d sigma : d eps`` over isochoric changes), the hyperfoam
    ``d tau / d eps`` (3x3, Kirchhoff stress: Abaqus' statement of Drucker's condition for a
    compressible material, ``d tau : d eps > 0``; the Cauchy stress ``tau / J`` would add the
    non-symmetric ``-sigma (x) 1`` of the volume change)."""
    h = 1e-6
    with np.errstate(over="ignore", invalid="ignore"):
        if model == "hyperfoam":

            def sigma(e: Array) -> Array:  # the Kirchhoff stress (Abaqus' criterion)
                return kirchhoff(model, params, np.exp(e), nu)

            D = np.empty((eps.shape[1], 3, 3))
            for j in range(3):
                d = np.zeros((3, 1))
                d[j] = h
                D[:, :, j] = ((sigma(eps + d) - sigma(eps - d)) / (2 * h)).T
        else:
            base = eps[:2]

            def diff(e2: Array) -> Array:
                lam = np.exp(np.vstack((e2, -e2.sum(axis=0))))
                tau = kirchhoff(model, params, lam, nu)
                return tau[:2] - tau[2]

            D = np.empty((eps.shape[1], 2, 2))
            for j in range(2):
                d = np.zeros((2, 1))
                d[j] = h
                D[:, :, j] = ((diff(base + d) - diff(base - d)) / (2 * h)).T
        sym = 0.5 * (D + np.swapaxes(D, 1, 2))
        ok = np.isfinite(sym).all(axis=(1, 2))
        eig = np.linalg.eigvalsh(np.where(ok[:, None, None], sym, 0.0))
    return ok & (eig.min(axis=1) > 0.0)


def fit_material(
    model: str,
    curves: Sequence[Curve],
    *,
    name: str,
    relaxation: RelaxationData | None = None,
    terms: int | None = None,
    nu: float | None = None,
    prony_terms: int | None = None,
    source: str | None = None,
    rate_per_s: float | None = None,
) -> MaterialFit:
    """Fit ``model`` to the tests (and the Prony terms to the relaxation test); see the module
    docstring.  Errors are one-line ``DesignError``s naming the option."""
    if model not in FIT_MODELS:
        raise DesignError("--model", f"must be one of {', '.join(FIT_MODELS)}, got {model!r}")
    if not isinstance(name, str) or not _NAME.match(name):
        raise DesignError("--name", f"must be letters, digits, _ or - (a TOML key), got {name!r}")
    if not curves:
        raise DesignError(
            "test data", "give at least one of --uniaxial, --compression, --biaxial, --planar"
        )
    modes = [c.mode for c in curves]
    if len(set(modes)) != len(modes):
        raise DesignError("test data", "one CSV per test type")
    if terms is None:
        terms = DEFAULT_TERMS.get(model, 1)
    elif model not in DEFAULT_TERMS:
        raise DesignError("--terms", f"applies to yeoh, ogden and hyperfoam, not {model}")
    if not 1 <= terms <= MAX_TERMS:
        raise DesignError("--terms", f"must be 1 to {MAX_TERMS}, got {terms}")
    nu_given = nu is not None
    nu = DEFAULT_NU if nu is None else float(nu)
    poisson(nu, "--nu")
    if prony_terms is not None and relaxation is None:
        raise DesignError("--prony", "needs a --relaxation test")
    if rate_per_s is not None and not (math.isfinite(rate_per_s) and rate_per_s > 0):
        raise DesignError("--rate-per-s", f"must be > 0, got {rate_per_s}")
    n_params = {"neo_hookean": 1, "mooney_rivlin": 2, "yeoh": terms}.get(model, 2 * terms)
    n_points = sum(len(c.nominal_strain) for c in curves)
    if n_points <= n_params:
        raise DesignError(
            "test data", f"too few points ({n_points}) for the {n_params} parameters of {model}"
        )
    prony_fit = None
    if relaxation is not None:
        prony_fit = fit_prony(relaxation, prony_terms or DEFAULT_PRONY_TERMS)
    if prony_fit is not None and rate_per_s is not None:
        ramps = {c.mode: _ramp(c, rate_per_s, prony_fit.prony) for c in curves}

        def predict(params: dict[str, Any], c: Curve) -> Array:
            return _viscous_nominal(model, params, c.mode, ramps[c.mode], nu)

        moduli = "instantaneous"
        reason = (
            f"the curves were fitted through the Prony terms as ramps at {rate_per_s:g} /s "
            "(the solver's recursion), so the law's moduli are the instantaneous ones"
        )
    else:

        def predict(params: dict[str, Any], c: Curve) -> Array:
            return nominal_stress(model, params, c.mode, c.nominal_strain, nu)

        moduli = "long_term"
        reason = (
            "elastic: no relaxation data, the law is the tests' response"
            if prony_fit is None
            else "no --rate-per-s: the curves are taken as the relaxed (equilibrium) response, so "
            "the law's moduli are the long-term ones"
        )
    params = _round_params(_fit_law(model, curves, terms, nu, predict))
    stats = tuple(_stats(c, predict(params, c)) for c in curves)
    text = source or "fingertip fit-material of " + ", ".join(
        f"{Path(c.path).name} (sha256 {c.sha256[:12]})" for c in curves
    )
    notes = []
    if prony_fit is None:
        notes.append("ELASTIC-ONLY (no relaxation data)")
    if "compression" not in modes:
        notes.append("compression extrapolated from tension")
    if not nu_given:
        notes.append(f"nu = {nu:g} is our assumption (no volumetric test)")
    full_source = "; ".join([text, *notes]) if notes else text
    return MaterialFit(
        name=name,
        model=model,
        params=params,
        nu=nu,
        nu_given=nu_given,
        terms=terms if model in DEFAULT_TERMS else None,
        modes=stats,
        prony=prony_fit,
        moduli=moduli,
        moduli_reason=reason,
        stable_ranges=drucker_stable_ranges(model, params, nu),
        source=full_source,
        rate_per_s=rate_per_s,
        curves=tuple(curves),
        relaxation=relaxation,
    )


# ----------------------------------------------------------------------------- output
def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ValueError(f"not a finite number: {value}")
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False).replace("\x7f", "\\u007f")
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise TypeError(f"cannot write {type(value).__name__} to TOML")


def entry_toml(name: str, entry: Mapping[str, Any], header: str = "") -> str:
    """A catalogue entry as TOML text: ``[name]`` then ``[name.provenance]``."""
    lines = [f"# {line}" for line in header.splitlines()] if header else []
    lines.append(f"[{name}]")
    for key, value in entry.items():
        if key != "provenance":
            lines.append(f"{key} = {_toml_value(value)}")
    if entry.get("provenance"):
        lines += ["", f"[{name}.provenance]"]
        lines += [f"{k} = {_toml_value(v)}" for k, v in entry["provenance"].items()]
    return "\n".join(lines) + "\n"


def fit_plot_data(fit: MaterialFit) -> dict[str, Any]:
    """What the figure shows, computed first: per test the data and the fit over the data's
    range and beyond (to the stability check's range), the fitted law in every deformation
    with its stable range, and the relaxation data vs the Prony fit."""
    lo, hi = STABILITY_STRAIN_RANGE
    panels = []
    for c, m in zip(fit.curves, fit.modes, strict=True):
        e_lo, e_hi = (lo, 0.0) if c.mode == "compression" else (0.0, hi)
        e = np.linspace(e_lo, e_hi, 201)
        panels.append(
            {
                "title": f"{c.mode} (R² = {m.r2:.4f}, rms {m.rms_MPa:.3g} MPa)",
                "data": (c.nominal_strain.tolist(), c.nominal_stress_MPa.tolist()),
                "law": (
                    e.tolist(),
                    nominal_stress(fit.model, fit.params, c.mode, e, fit.nu).tolist(),
                ),
                "data_range": list(c.strain_range),
                "xlabel": "nominal strain",
                "ylabel": "nominal stress (MPa)",
            }
        )
    e = np.linspace(lo, hi, 281)
    modes = {
        mode: nominal_stress(fit.model, fit.params, mode, e, fit.nu).tolist()
        for mode in STABILITY_MODES
    }
    relax = None
    if fit.prony is not None and fit.relaxation is not None:
        t = fit.relaxation.time_s
        positive = t[t > 0]
        tt = np.geomspace(positive.min() / 3, t.max() * 3, 200)
        relax = {
            "data": (t.tolist(), fit.relaxation.g_R.tolist()),
            "fit": (tt.tolist(), fit.prony.prony.relaxation(tt).tolist()),
            "title": f"relaxation, {len(fit.prony.g)} Prony terms (R² = {fit.prony.r2:.4f})",
        }
    return {
        "name": fit.name,
        "model": fit.model,
        "panels": panels,
        "all_modes": {"strain": e.tolist(), "stress": modes, "stable": fit.stable_ranges},
        "relaxation": relax,
    }


def _render(info: dict[str, Any], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(info["panels"]) + 1 + (info["relaxation"] is not None)
    fig, axes = plt.subplots(1, n, figsize=(4.2 * n, 3.8), squeeze=False)
    axes = axes[0]
    for ax, p in zip(axes, info["panels"], strict=False):
        x, y = np.asarray(p["law"][0]), np.asarray(p["law"][1])
        a, b = p["data_range"]
        inside = (x >= a) & (x <= b)
        ax.plot(*p["data"], "o", ms=3, color="0.4", label="test data")
        ax.plot(x, np.where(~inside, y, np.nan), "--", color="C0", lw=0.8, label="extrapolated")
        ax.plot(x, np.where(inside, y, np.nan), "-", color="C0", label=f"{info['model']} fit")
        ax.set(title=p["title"], xlabel=p["xlabel"], ylabel=p["ylabel"])
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    ax = axes[len(info["panels"])]
    e = np.asarray(info["all_modes"]["strain"])
    scale = 0.0
    for k, (mode, stress) in enumerate(info["all_modes"]["stress"].items()):
        lo, hi = info["all_modes"]["stable"][mode]
        s = np.asarray(stress)
        ok = (e >= lo) & (e <= hi)
        ax.plot(
            e, np.where(ok, s, np.nan), "-", color=f"C{k}", label=f"{mode}, stable {lo:g}..{hi:g}"
        )
        ax.plot(e, np.where(ok, np.nan, s), ":", color=f"C{k}")
        scale = max(scale, float(np.nanmax(np.abs(s[(e >= 0) & (e <= 1)]))))
    # the stresses span decades from -0.8 to 2 (equibiaxial compression is extreme): symlog
    ax.set_yscale("symlog", linthresh=max(scale, 1e-12))
    ax.set(title="fitted law (dotted: Drucker-unstable)", xlabel="nominal strain",
           ylabel="nominal stress (MPa), symlog")  # fmt: skip
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    if info["relaxation"] is not None:
        ax = axes[-1]
        r = info["relaxation"]
        ax.plot(*r["data"], "o", ms=3, color="0.4", label="test data")
        ax.plot(*r["fit"], "-", color="C3", label="Prony fit")
        ax.set_xscale("log")
        ax.set(title=r["title"], xlabel="time (s)", ylabel="g_R")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(info["name"])
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _report_md(fit: MaterialFit, toml_path: Path) -> str:
    lo, hi = STABILITY_STRAIN_RANGE
    lines = [
        f"# Material fit: `{fit.name}` ({fit.model})",
        "",
        f"Catalogue entry: `{toml_path.name}` (use it with `--catalogue {toml_path.name}`).",
        f"Source: {fit.source}",
        "",
        "## Parameters",
        "",
        "| parameter | value |",
        "|---|---|",
    ]
    for k, v in {**fit.params, "nu": fit.nu}.items():
        lines.append(f"| `{k}` | {v} |")
    if fit.prony is not None:
        lines.append(f"| `prony_g` | {list(fit.prony.g)} |")
        lines.append(f"| `prony_tau_s` | {list(fit.prony.tau_s)} |")
    lines += [
        f"| `moduli` | {fit.moduli} ({fit.moduli_reason}) |",
        "",
        "## Agreement with each test",
        "",
        "| test | file | points | nominal strain | R² | rms error (MPa) | max error (MPa) |",
        "|---|---|---|---|---|---|---|",
    ]
    for m in fit.modes:
        lines.append(
            f"| {m.mode} | `{Path(m.path).name}` | {m.n_points} | {m.strain_range[0]:g} to "
            f"{m.strain_range[1]:g} | {m.r2:.4f} | {m.rms_MPa:.3g} | {m.max_abs_error_MPa:.3g} |"
        )
    if fit.prony is not None:
        p = fit.prony
        lines.append(
            f"| relaxation | `{Path(p.path).name}` | {p.n_points} | t = {p.time_range_s[0]:g} to "
            f"{p.time_range_s[1]:g} s | {p.r2:.4f} | {p.rms:.3g} (g_R) | |"
        )
    lines += [
        "",
        f"## Drucker stability (nominal strain {lo:g} to {hi:g})",
        "",
        "| deformation | stable range |",
        "|---|---|",
    ]
    for mode, (a, b) in fit.stable_ranges.items():
        lines.append(f"| {mode} | {a:g} to {b:g} |")
    lines += [
        "",
        "Stable over the whole range."
        if fit.stable_everywhere
        else "**Not stable over the whole range**: keep designs within the stable strains.",
        "",
        f"![fit]({toml_path.stem}.fit.png)",
        "",
    ]
    return "\n".join(lines)


def write_fit(fit: MaterialFit, out: str | Path) -> list[Path]:
    """Write the catalogue entry ``out`` (TOML) and, next to it, ``<stem>.fit.md``,
    ``<stem>.fit.json`` and ``<stem>.fit.png``.  Never overwrites (``FileExistsError``).  The
    entry is read back through the catalogue loader before anything is written."""
    from ._catalogue import load_catalogue_text

    out = Path(out)
    paths = [out] + [out.with_name(f"{out.stem}.fit.{ext}") for ext in ("md", "json", "png")]
    for p in paths:
        if p.exists():
            raise FileExistsError(f"{p} exists; choose another --out (nothing was overwritten)")
    if not out.parent.is_dir():
        raise DesignError("--out", f"no such folder: {out.parent}")
    text = entry_toml(
        fit.name,
        fit.entry(),
        header=f"Catalogue entry written by fingertip fit-material ({fit.model}).",
    )
    load_catalogue_text(text, out.name)  # raises if the loader would refuse it
    out.write_text(text)
    paths[1].write_text(_report_md(fit, out))
    paths[2].write_text(json_text(fit.to_json(), indent=1) + "\n")
    _render(fit_plot_data(fit), paths[3])
    return paths
