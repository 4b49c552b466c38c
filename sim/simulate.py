"""One full design evaluation: mesh, discretise, run the protocols, collect metrics and curves."""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .contact import Plate, Wedge
from .design import Design
from .errors import SimulationError
from .mesh import DEFAULT_MESH, MeshOptions
from .protocols import (
    PlateOptions,
    ProtocolResult,
    TappingOptions,
    WedgeOptions,
    run_plate,
    run_tapping,
    run_wedge,
)
from .provenance import finite_or_none
from .solver import Body, NewtonOptions
from .validity import ValidityOptions, Violation, check

__all__ = [
    "DIAGNOSTIC_KEYS",
    "METRICS",
    "PROTOCOLS",
    "SETTLE_KEYS",
    "SOLVER_VERSION",
    "SimOptions",
    "SimResult",
    "diagnostic_names",
    "simulate",
]

#: Bumped whenever a change alters computed metrics (keys sweep records and checkpoints).
SOLVER_VERSION = "2.2"
#: Earlier solver versions whose metrics this one reproduces within its tolerances: a surrogate
#: trained on their FE results is as good as one trained on this version's (2.1 -> 2.2 changed
#: only when Newton gives up on a step; docs/validation.md, "Newton").
SAME_METRICS_AS = ("2.1",)
# 2.2: Newton abandons a stalled step early (NewtonOptions.stall_*), so the step is cut sooner:
#      same tolerances; metrics within 0.1 % of 2.1 but for hysteresis values below 1e-3 N mm
#      (numerical noise of nearly elastic designs; docs/validation.md, "Newton")
# 2.1: sag_mm metric (the displacement at the start of the measured tap); catalogue silicones at
#      nu = 0.499 (was 0.49); material families gel/foam (sim.families)
# 2.0: tapping to the periodic state on a residual (sim.periodic), rest steps from the shortest
#      relaxation time, 48 loaded steps, Newton started from the previous tap's increment,
#      separate shear/bulk relaxation, validity and settling recorded
# 1.3: profile summary = area to 2 mm (was half-width)

PROTOCOLS = ("tapping", "plate", "wedge")

#: Metric name -> (protocol, unit, description).
METRICS: dict[str, tuple[str, str, str]] = {
    "disp_at_1N_mm": (
        "tapping",
        "mm",
        "loading-branch displacement at 1 N from the undeformed top",
    ),
    "disp_at_4N_mm": (
        "tapping",
        "mm",
        "loading-branch displacement at 4 N from the undeformed top",
    ),
    "disp_at_1N_from_touch_mm": (
        "tapping",
        "mm",
        "displacement at 1 N from first touch of the tap",
    ),
    "disp_at_4N_from_touch_mm": (
        "tapping",
        "mm",
        "displacement at 4 N from first touch of the tap",
    ),
    "hysteresis_Nmm": ("tapping", "N mm", "area of the last tap's force-displacement loop"),
    "sag_mm": (
        "tapping",
        "mm",
        "displacement at the start (first touch) of the measured tap from the undeformed top: "
        "what the earlier taps left unrecovered",
    ),
    "plate_force_at_1mm_N": ("plate", "N", "plate force at 1 mm indentation (L = 22 mm)"),
    "wedge_peak_force_N": ("wedge", "N", "peak wedge force, at the end of the 1 s ramp"),
    "wedge_force_at_100s_N": ("wedge", "N", "wedge force at t = 100 s of the hold"),
    "profile_1s_area_2mm_mm2": (
        "wedge",
        "mm^2",
        "area under the surface-deflection profile from the wedge corner to 2 mm, at 1 s",
    ),
    "profile_1s_defl_at_1mm_mm": ("wedge", "mm", "surface deflection 1 mm from the corner, 1 s"),
    "profile_100s_area_2mm_mm2": ("wedge", "mm^2", "as profile_1s_area_2mm_mm2, at 100 s"),
    "profile_100s_defl_at_1mm_mm": ("wedge", "mm", "as profile_1s_defl_at_1mm_mm, at 100 s"),
}


@dataclass(frozen=True)
class SimOptions:
    """Numerical and protocol options; the defaults are the converged reference settings."""

    mesh: MeshOptions = DEFAULT_MESH
    newton: NewtonOptions = NewtonOptions()
    tapping: TappingOptions = TappingOptions()
    plate: PlateOptions = PlateOptions()
    wedge: WedgeOptions = WedgeOptions()
    validity: ValidityOptions = ValidityOptions()

    def with_steps_scaled(self, factor: float) -> SimOptions:
        """Every step count multiplied by ``factor`` (time-step convergence studies)."""
        tap, plate, wedge = self.tapping, self.plate, self.wedge
        return dataclasses.replace(
            self,
            tapping=tap.with_steps_scaled(factor),
            plate=dataclasses.replace(plate, steps=max(2, round(plate.steps * factor))),
            wedge=dataclasses.replace(
                wedge,
                ramp_steps=max(2, round(wedge.ramp_steps * factor)),
                hold_steps=max(4, round(wedge.hold_steps * factor)),
            ),
        )

    def with_mesh_refined(self, factor: float) -> SimOptions:
        """Every element size divided by ``factor`` (mesh convergence studies)."""
        return dataclasses.replace(self, mesh=self.mesh.refined(factor))


@dataclass(frozen=True)
class ProtocolFailure:
    protocol: str
    time_s: float
    reason: str


@dataclass(frozen=True)
class SimResult:
    """Metrics (None where a protocol failed), curves, per-protocol figures and failures."""

    design: Design
    metrics: dict[str, float | None]
    curves: dict[str, dict[str, list[float]]]
    protocols: dict[str, dict[str, Any]]
    failures: tuple[ProtocolFailure, ...] = ()
    n_dofs: int = 0
    wall_time_s: float = 0.0
    validity_options: ValidityOptions = ValidityOptions()
    fields: dict[str, np.ndarray] = field(default_factory=dict, repr=False, compare=False)
    discretization: Any = field(default=None, repr=False, compare=False)

    @property
    def ok(self) -> bool:
        return not self.failures

    def validity_summaries(self) -> dict[str, dict[str, Any]]:
        """Each completed protocol's deformation summary (``sim.validity.DeformationTracker``)."""
        return {name: fig["validity"] for name, fig in self.protocols.items() if "validity" in fig}

    def violations(self) -> list[tuple[str, Violation]]:
        """(protocol, violated limit) for every validity limit a completed protocol broke."""
        return [
            (name, v)
            for name, summary in self.validity_summaries().items()
            for v in check(summary, self.validity_options, name)
        ]

    @property
    def validity(self) -> dict[str, Any]:
        """``{"valid", "violations", "protocols"}``: the overall verdict, the violated limits as
        ``"<limit> (<protocol>)"`` and per protocol its summary plus its own ``violations`` and
        ``valid``. Failed protocols have no summary: ``valid`` speaks of the completed ones only
        (see ``ok``)."""
        protocols = {}
        for name, summary in self.validity_summaries().items():
            own = [str(v) for v in check(summary, self.validity_options, name)]
            protocols[name] = {**summary, "violations": own, "valid": not own}
        violations = [f"{v} ({name})" for name, v in self.violations()]
        return {"valid": not violations, "violations": violations, "protocols": protocols}

    def diagnostics(self) -> dict[str, Any]:
        """Flat, JSON/CSV-ready validity figures: ``valid``, ``violations`` (joined by "; ") and
        per protocol run ``<protocol>_<key>`` for the keys of ``DIAGNOSTIC_KEYS`` (None where the
        protocol failed)."""
        validity = self.validity
        out: dict[str, Any] = {
            "valid": validity["valid"],
            "violations": "; ".join(validity["violations"]),
        }
        for name in self.protocols:
            summary = validity["protocols"].get(name, {})
            for key, source in DIAGNOSTIC_KEYS.items():
                out[f"{name}_{key}"] = summary.get(source)
        if "tapping" in self.protocols:  # the periodic state (sim.periodic)
            tap = self.protocols["tapping"]
            for key in SETTLE_KEYS:
                out[f"tapping_{key}"] = tap.get(key)
            out["settled"] = tap.get("settled")
        return out

    def to_json(self) -> dict[str, Any]:
        """JSON-ready dict: metric names at the top level, then curves and diagnostics."""
        return {
            **{k: finite_or_none(v) for k, v in self.metrics.items()},
            "ok": self.ok,
            "failures": [f.__dict__ for f in self.failures],
            "curves": self.curves,
            "protocols": self.protocols,
            "n_dofs": self.n_dofs,
            "wall_time_s": self.wall_time_s,
            "solver_version": SOLVER_VERSION,
            "design": self.design.to_dict(),
            "validity": self.validity,
        }


#: The tapping protocol's periodic-state figures in diagnostics() (as ``tapping_<key>``).
SETTLE_KEYS = ("settled", "taps", "residual", "max_estimated_error", "touch_mm")

#: diagnostics() key suffix -> key of the protocol's validity summary.
DIAGNOSTIC_KEYS = {
    "max_compressive_log_strain": "max_compressive_log_strain",
    "min_J": "min_J",
    "contact_width_mm": "contact_width_at_peak_mm",
    "reached_base": "reached_base",
    "folded": "folded",
    "nominal_compression": "nominal_compression",
}


def same_metrics(version: str | None) -> bool:
    """Whether FE results of solver ``version`` are those of this solver (``SAME_METRICS_AS``)."""
    return version == SOLVER_VERSION or version in SAME_METRICS_AS


def diagnostic_names(protocols: tuple[str, ...] | list[str] = PROTOCOLS) -> list[str]:
    """The keys of ``SimResult.diagnostics()`` for a run of ``protocols``, in a fixed order (the
    diagnostic columns of a sweep's table.csv)."""
    names = ["settled", "valid"] if "tapping" in protocols else ["valid"]
    if "tapping" in protocols:
        names += [f"tapping_{k}" for k in SETTLE_KEYS if k != "settled"]
    names += [f"{p}_{k}" for p in protocols for k in DIAGNOSTIC_KEYS]
    return [*names, "violations"]


_RUNNERS = {
    "tapping": (Plate, run_tapping, "tapping"),
    "plate": (Plate, run_plate, "plate"),
    "wedge": (Wedge, run_wedge, "wedge"),
}


def simulate(
    design: Design,
    protocols: tuple[str, ...] | list[str] = PROTOCOLS,
    options: SimOptions = SimOptions(),
) -> SimResult:
    """Run ``protocols`` on ``design``. A protocol that fails is recorded, never raised.

    Every BLAS call runs on one thread (``threadpoolctl``): the same design gives the same bits
    whatever OMP_NUM_THREADS says (a threaded dot product sums in another order)."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        return _simulate(design, protocols, options)


def _simulate(
    design: Design,
    protocols: tuple[str, ...] | list[str] = PROTOCOLS,
    options: SimOptions = SimOptions(),
) -> SimResult:
    from .fe import Discretization  # the FE stack (scikit-fem) only when something is simulated
    from .mesh import build_mesh

    t0 = time.perf_counter()
    for p in protocols:
        if p not in _RUNNERS:
            raise ValueError(f"unknown protocol {p!r}; known: {', '.join(PROTOCOLS)}")
    fmesh = build_mesh(design.geometry, design.thicknesses_mm, options.mesh)
    disc = Discretization(fmesh, design.materials)
    metrics: dict[str, float | None] = {
        name: None for name, (proto, _, _) in METRICS.items() if proto in protocols
    }
    curves: dict[str, dict[str, list[float]]] = {}
    figures: dict[str, dict[str, Any]] = {}
    failures: list[ProtocolFailure] = []
    fields: dict[str, np.ndarray] = {}
    for name in protocols:
        indenter_cls, runner, _ = _RUNNERS[name]
        opts = getattr(options, name)
        indenter = (
            Wedge(opts.tip_width_mm, opts.half_angle_deg) if indenter_cls is Wedge else Plate()
        )
        body = Body(
            disc,
            indenter,
            options.newton,
            getattr(opts, "penalty_per_mm", None),
        )
        try:
            res: ProtocolResult = runner(body, opts)
        except SimulationError as exc:
            failures.append(ProtocolFailure(exc.protocol, exc.time_s, exc.reason))
            figures[name] = {"newton_iterations": body.newton_iterations, "failed": True}
            continue
        except (ArithmeticError, ValueError, np.linalg.LinAlgError) as exc:
            failures.append(ProtocolFailure(name, body.t, f"{type(exc).__name__}: {exc}"))
            figures[name] = {"newton_iterations": body.newton_iterations, "failed": True}
            continue
        metrics.update(res.metrics)
        curves.update(res.curves)
        figures[name] = {
            "newton_iterations": res.newton_iterations,
            "steps": res.steps,
            "factorizations": body.factorizations,
            "evaluations": body.evaluations,
            "timings_s": dict(body.timings),
            "wall_time_s": res.wall_time_s,
            **res.info,
        }
        fields[name] = body.u.copy()
    return SimResult(
        design=design,
        metrics=metrics,
        curves=curves,
        protocols=figures,
        failures=tuple(failures),
        n_dofs=disc.n_free,
        wall_time_s=time.perf_counter() - t0,
        validity_options=options.validity,
        fields=fields,
        discretization=disc,
    )
