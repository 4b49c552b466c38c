"""One full design evaluation: mesh, discretise, run the protocols, collect metrics and curves.

The metric registry lives in ``sim.metrics`` and the options in ``sim.options``; both are
re-exported here for the imports that name ``sim.simulate``."""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from .design import Design
from .errors import DesignError, SimulationError
from .fe import Body, Discretization, model_newton
from .metrics import (
    DIAGNOSTIC_KEYS,
    METRICS,
    PROTOCOLS,
    SAME_METRICS_AS,
    SETTLE_KEYS,
    SOLVER_VERSION,
    diagnostic_names,
    metric_registry,
    role_strains,
    same_metrics,
)
from .options import SimOptions
from .protocols import REGISTRY, Protocol, ProtocolResult
from .protocols.validity import (
    LAYER_LIMIT_KEYS,
    LAYER_STRAINS,
    ValidityOptions,
    ValidityStop,
    Violation,
    check,
)
from .provenance import finite_or_none

__all__ = [
    "DIAGNOSTIC_KEYS",
    "METRICS",
    "PROTOCOLS",
    "SAME_METRICS_AS",
    "SETTLE_KEYS",
    "SOLVER_VERSION",
    "ProtocolFailure",
    "SimOptions",
    "SimResult",
    "diagnostic_names",
    "discretize",
    "merge_results",
    "same_metrics",
    "simulate",
]


@dataclass(frozen=True)
class ProtocolFailure:
    """A protocol that failed: where (its time, s) and why."""

    protocol: str
    time_s: float
    reason: str


@dataclass(frozen=True)
class SimResult:
    """Metrics (None where a protocol failed), curves, per-protocol figures and failures;
    ``fields`` and ``discretization`` only with ``simulate(..., keep_fields=True)``."""

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
    #: the discretisation of a kept field made on another mesh than ``discretization`` (the
    #: wedge's, when the 3D mesh has a band along its edge), by field name
    field_discretizations: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)

    @property
    def ok(self) -> bool:
        return not self.failures

    def validity_summaries(self) -> dict[str, dict[str, Any]]:
        """Each completed protocol's deformation summary
        (``sim.protocols.validity.DeformationTracker``)."""
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
        """``{"valid", "violations", "protocols", "stopped", "overridden"}``: the overall
        verdict, the violated limits as ``"<limit> (<protocol>)"``, per protocol its summary
        plus its own ``violations`` and ``valid``, the protocols stopped at a violation, and the
        limits that override the materials' own (``ValidityOptions.overridden``: {} when each
        layer is held to its tested limit). Failed protocols have no summary: ``valid`` speaks
        of the completed ones only (see ``ok``)."""
        protocols = {}
        for name, summary in self.validity_summaries().items():
            own = [str(v) for v in check(summary, self.validity_options, name)]
            protocols[name] = {**summary, "violations": own, "valid": not own}
        violations = [f"{v} ({name})" for name, v in self.violations()]
        return {
            "valid": not violations,
            "violations": violations,
            "protocols": protocols,
            "stopped": {name: self.protocols[name]["stopped"] for name in self.stopped},
            "overridden": self.validity_options.overridden,
        }

    @property
    def stopped(self) -> tuple[str, ...]:
        """The protocols stopped at their first step beyond the validity limits (no metrics;
        ``ValidityOptions.stop_at_violation``)."""
        return tuple(name for name, fig in self.protocols.items() if "stopped" in fig)

    def diagnostics(self) -> dict[str, Any]:
        """Flat, JSON/CSV-ready validity figures: ``valid``, ``violations`` (joined by "; "),
        ``stopped`` (the protocols stopped at a violation, joined by ",") and
        per protocol run ``<protocol>_<key>`` for the keys of ``DIAGNOSTIC_KEYS`` (None where the
        protocol failed). Besides (in a record, not a table's columns): each layer's largest
        compressive log strain per protocol (``<protocol>_max_compressive_log_strain_by_layer``)
        and each layer's tested limit (``sim.protocols.validity.LAYER_LIMIT_KEYS``), from which
        ``sim.protocols.validity.strain_summary`` gives a stored record's layers back to
        ``strain_limits``; and those per-layer strains by role (``sim.metrics.role_strains``)."""
        validity = self.validity
        out: dict[str, Any] = {
            "valid": validity["valid"],
            "violations": "; ".join(validity["violations"]),
            "stopped": ",".join(self.stopped),
        }
        for name in self.protocols:
            summary = validity["protocols"].get(name, {})
            for key, source in DIAGNOSTIC_KEYS.items():
                out[f"{name}_{key}"] = summary.get(source)
        for name, summary in validity["protocols"].items():
            out[f"{name}_{LAYER_STRAINS}"] = summary.get(LAYER_STRAINS)
            for key in LAYER_LIMIT_KEYS:
                out[key] = summary.get(key)
        out.update(role_strains(out, len(self.design.layers), tuple(self.protocols)))
        if "tapping" in self.protocols:  # the periodic state (sim.protocols.periodic)
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


def simulate(
    design: Design,
    protocols: tuple[str, ...] | list[str] = PROTOCOLS,
    options: SimOptions = SimOptions(),
    *,
    keep_fields: bool = False,
) -> SimResult:
    """Run ``protocols`` on ``design``. A protocol that fails is recorded, never raised.

    ``keep_fields``: keep the discretisation and each completed protocol's final displacements
    in the result (``discretization``, ``fields``: what ``sim.output.result.write_vtu`` draws), with
    the tapping's states at 1 N and 4 N (``tapping_1N``, ``tapping_4N``); by default the result
    holds figures only.

    Every BLAS call runs on one thread (``threadpoolctl``): the same design gives the same bits
    whatever OMP_NUM_THREADS says (a threaded dot product sums in another order)."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        return _simulate(design, protocols, options, keep_fields)


def _simulate(
    design: Design, protocols: tuple[str, ...] | list[str], options: SimOptions, keep_fields: bool
) -> SimResult:
    t0 = time.perf_counter()
    for p in protocols:
        if p not in REGISTRY:
            raise ValueError(f"unknown protocol {p!r}; known: {', '.join(PROTOCOLS)}")
    if options.model.inclination_deg != 0.0 and "wedge" in protocols:
        raise DesignError(
            "model.inclination_deg",
            "inclines the plate only: the wedge's edge runs across the pad at z = 0 and is not "
            "inclined; run --protocol tapping or --protocol plate",
        )
    disc = discretize(design, options)
    # the wedge on its own mesh when the 3D mesh has a band along its edge (mesh3d.edge_h_mm)
    own_wedge_mesh = options.dimension == "3d" and options.mesh3d.edge_h_mm > 0.0
    metrics: dict[str, float | None] = {
        name: None
        for name, (proto, _, _) in metric_registry(options.dimension).items()
        if proto in protocols
    }
    curves: dict[str, dict[str, list[float]]] = {}
    figures: dict[str, dict[str, Any]] = {}
    failures: list[ProtocolFailure] = []
    fields: dict[str, np.ndarray] = {}
    field_discretizations: dict[str, Any] = {}
    for name in protocols:
        on = discretize(design, options, "wedge") if name == "wedge" and own_wedge_mesh else disc
        body, outcome = _run(on, REGISTRY[name], options)
        if isinstance(outcome, ProtocolFailure):
            failures.append(outcome)
            figures[name] = {"newton_iterations": body.newton_iterations, "failed": True}
            continue
        metrics.update(outcome.metrics)
        curves.update(outcome.curves)
        figures[name] = _figures(outcome, body)
        if keep_fields:
            fields[name] = body.u.copy()
            fields.update(outcome.fields)
            if on is not disc:
                field_discretizations.update(dict.fromkeys((name, *outcome.fields), on))
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
        discretization=disc if keep_fields else None,
        field_discretizations=field_discretizations,
    )


def merge_results(parts: Sequence[SimResult]) -> SimResult:
    """One design's results of disjoint sets of protocols (``simulate(design, (p,))`` in
    separate processes) as the one result of ``simulate`` running them all: each protocol runs
    on a fresh body of its own, so nothing passes from one to the next, and the merged metrics,
    curves, per-protocol figures and failures are those of the sequential run, in the protocols'
    order (``PROTOCOLS``). ``wall_time_s`` is the parts' sum: the seconds the design's FE took,
    wherever it ran. Figures only: no part may keep its fields."""
    if not parts:
        raise ValueError("merge_results needs at least one result")
    first = parts[0]
    seen: list[str] = []
    for part in parts:
        if part.design != first.design or part.validity_options != first.validity_options:
            raise ValueError("merge_results joins results of one design and one set of options")
        if part.fields or part.discretization is not None:
            raise ValueError("merge_results joins results without fields (keep_fields=False)")
        overlap = set(part.protocols) & set(seen)
        if overlap:
            raise ValueError(f"protocol {sorted(overlap)[0]!r} is in two of the results")
        seen.extend(part.protocols)
    order = {name: i for i, name in enumerate(PROTOCOLS)}
    ordered = sorted(parts, key=lambda r: min(order.get(p, len(order)) for p in r.protocols))
    merged = {k: v for part in ordered for k, v in part.metrics.items()}
    # in the registry's order, as simulate's (the 3D registry: the 2D one and the patch after)
    rank = {name: i for i, name in enumerate(metric_registry("3d"))}
    names = sorted(merged, key=lambda name: rank.get(name, len(rank)))
    return SimResult(
        design=first.design,
        metrics={name: merged[name] for name in names},
        curves={k: v for part in ordered for k, v in part.curves.items()},
        protocols={k: v for part in ordered for k, v in part.protocols.items()},
        failures=tuple(f for part in ordered for f in part.failures),
        n_dofs=first.n_dofs,
        wall_time_s=sum(part.wall_time_s for part in parts),
        validity_options=first.validity_options,
    )


def discretize(design: Design, options: SimOptions = SimOptions(), protocol: str = "") -> Any:
    """The design's discretisation for the model of ``options``: the 2D section
    (``sim.fe.fe2d.Discretization`` on ``sim.geometry.mesh2d``) or the 3D quarter pad
    (``sim.fe.fe3d.Discretization3D`` on ``sim.geometry.mesh3d``; the half pad, graded for
    its first touch, for an inclined plate: ``model.inclination_deg``); ``DesignError`` when
    the layers leave no core in the pad. In 3D the band along the wedge's edge
    (``mesh3d.edge_h_mm``) is meshed for ``protocol`` "wedge" only."""
    if options.dimension == "3d":
        from .fe import Discretization3D
        from .geometry import build_pad_mesh

        pad = design.pad
        pad.check_layers(design.thicknesses_mm)
        inclination = options.model.inclination_deg
        mesh = options.mesh3d if protocol == "wedge" else options.mesh3d.without_edge()
        pmesh = build_pad_mesh(pad, design.thicknesses_mm, mesh, inclination)
        return Discretization3D(pmesh, design.materials, element=options.model.element)
    from .geometry import build_mesh

    fmesh = build_mesh(design.geometry, design.thicknesses_mm, options.mesh)
    return Discretization(fmesh, design.materials)


#: The 3D protocols whose tangents PARDISO factorises in single precision
#: (``sim.fe._linear.PardisoSingle``; a step it fails is tried again in double precision, and
#: the body goes back to single at the next step that converges: ``Body.advance``). Since
#: solver 2.14 the wedge too: on four default-space designs its band's tangent made one or two
#: steps fall back each, most of them steps that failed in double precision as well, and the
#: wedge took 9 % less time on the whole, -16 % to +2 % by design (``studies/wedge_precision.py``;
#: docs/fe_speed.md, "The wedge in single precision"). The 2D systems are qdldl's, in double.
SINGLE_PRECISION_PROTOCOLS = ("tapping", "plate", "wedge")


def _run(
    disc: Discretization, protocol: Protocol, options: SimOptions
) -> tuple[Body, ProtocolResult | ProtocolFailure]:
    """``protocol`` on a fresh body of ``disc``: the body and its result, or how it failed."""
    opts = getattr(options, protocol.name)
    newton = model_newton(options.newton, disc.dim)
    indenter = protocol.make_indenter(opts)
    if options.model.inclination_deg != 0.0:  # a plate (the wedge is refused by simulate)
        indenter = replace(indenter, inclination_deg=options.model.inclination_deg)
    body = Body(disc, indenter, newton, getattr(opts, "penalty_per_mm", None))
    body.single_precision = disc.dim == 3 and protocol.name in SINGLE_PRECISION_PROTOCOLS
    if options.validity.stop_at_violation:
        body.stop_beyond = (protocol.name, options.validity)
    t0 = time.perf_counter()
    try:
        return body, protocol.run(body, opts)
    except ValidityStop as stop:  # completed, without metrics: see ValidityOptions
        info = {**stop.info, "stopped": stop.record()}
        wall = time.perf_counter() - t0
        return body, ProtocolResult(
            protocol.name, {}, {}, body.newton_iterations, stop.steps, wall, info
        )
    except SimulationError as exc:
        return body, ProtocolFailure(exc.protocol, exc.time_s, exc.reason)
    except (ArithmeticError, ValueError, np.linalg.LinAlgError) as exc:
        return body, ProtocolFailure(protocol.name, body.t, f"{type(exc).__name__}: {exc}")


def _figures(res: ProtocolResult, body: Body) -> dict[str, Any]:
    """A completed protocol's solver figures and ``info`` (``SimResult.protocols``)."""
    return {
        "newton_iterations": res.newton_iterations,
        "steps": res.steps,
        "factorizations": body.factorizations,
        "evaluations": body.evaluations,
        "timings_s": dict(body.timings),
        "wall_time_s": res.wall_time_s,
        "n_dofs": body.disc.n_free,  # the wedge's own mesh may differ (mesh3d.edge_h_mm)
        "linear_solver": body.solver_name,  # the last one (after a fallback)
        "precision_fallbacks": body.precision_fallbacks,  # failed steps retried in double
        "fresh_retries": body.fresh_retries,  # ... in the same precision, afresh
        # the factorisations kept per tapping step (3D): steps that began with one, and how
        # many the body kept
        **(
            {"step_factor_takes": body.step_factor_takes, "step_factors": body.step_factors_kept}
            if body.step_factors
            else {}
        ),
        **res.info,
    }
