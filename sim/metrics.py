"""The metric registry: the protocols, their metrics with units, the diagnostic figures of a
result and the solver version that keys stored results.

Plain data, no numerics: the surrogate, the search and the CLI read metric names from here
without importing the simulation itself (``sim.simulate``, the FE code)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

__all__ = [
    "DEFAULTS_BEFORE",
    "DIAGNOSTIC_KEYS",
    "METRICS",
    "METRICS_3D",
    "PROTOCOLS",
    "SAME_METRICS_AS",
    "SETTLE_KEYS",
    "SOLVER_VERSION",
    "diagnostic_names",
    "metric_registry",
    "role_strain_name",
    "role_strain_names",
    "role_strains",
    "same_metrics",
]

#: Bumped whenever a change alters computed metrics (keys sweep records and checkpoints).
SOLVER_VERSION = "2.20"
#: Earlier solver versions whose metrics this one reproduces within its tolerances: a surrogate
#: trained on their FE results is as good as one trained on this version's (2.1 -> 2.2 changed
#: only when Newton gives up on a step; docs/fe_speed.md, "Newton"; 2.2 -> 2.3 only the
#: designs beyond the validity limits, which lose their metrics, and a surrogate learns metrics
#: from settled, valid designs; 2.3 -> 2.4 other sub-steps where a contact changes, the metrics
#: within their time-discretisation error; 2.4 -> 2.5 the 2D model bit for bit, the 3D one
#: within Newton's tolerance; 2.5 -> 2.6 the same, PARDISO's ordering; 2.6 -> 2.7 the same,
#: Newton's step solved for the contact set it leads to; 2.7 -> 2.8 the same, at most one
#: fresh factorisation in those solves; 2.8 -> 2.9 the 3D model bit for bit, the 2D one
#: within Newton's tolerance, its assembly compiled; 2.9 -> 2.10 the 2D model bit for bit, the
#: 3D wedge's sub-steps grow back more slowly, its metrics within Newton's tolerance and the
#: time discretisation's error; 2.10 -> 2.11 the 2D model and the 3D quarter bit for bit, the
#: inclined half pad's heel side meshed coarser, its forces within 2e-5; 2.11 -> 2.12 the material
#: laws compiled, every model within Newton's tolerance, and the 3D model's factorisation kept
#: while the residual halves, its metrics within the time discretisation's error; 2.12 -> 2.13
#: the 2D model bit for bit, the 3D tapping and plate factorised in single precision, their
#: metrics within Newton's tolerance; 2.13 -> 2.14 the same, the 3D wedge too, and a step
#: that fell back to double precision hands the body back to single; 2.14 -> 2.15 the 2D model
#: bit for bit, the 3D tapping's loading steps begin with the same step's factorisation of
#: an earlier tap, its metrics within the periodic state's tolerance; 2.15 -> 2.16 the 2D
#: model bit for bit, a 3D wedge step that took more than 8 iterations halves the next, its
#: metrics within the time discretisation's error; 2.16 -> 2.17 the 2D model bit for bit, a
#: failed 3D step is retried in single precision from a fresh factorisation unless its factorisation
#: solved its tangent worse than 1e-2, its metrics within Newton's tolerance; 2.17 -> 2.18 the
#: 2D model bit for bit, the 3D wedge's ramp in sub-steps of half the band's element from its
#: first, its metrics within the time discretisation's error; 2.18 -> 2.19 the metrics of both
#: models bit for bit, the 3D validity's strains within rounding, 1e-15; 2.19 -> 2.20 the 2D
#: model bit for bit, the 3D model's other sub-steps where Newton's stall rule decides
#: otherwise, the same tolerances, as 2.1 -> 2.2).
SAME_METRICS_AS = (
    "2.19", "2.18", "2.17", "2.16", "2.15", "2.14", "2.13", "2.12", "2.11", "2.10", "2.9", "2.8",
    "2.7", "2.6", "2.5", "2.4", "2.3", "2.2", "2.1",
)  # fmt: skip
#: Options whose default a solver of this line changed, with that version and the default
#: before it: a sweep of an earlier version made at the old default counts as made at today's
#: (its metrics are this solver's: ``SAME_METRICS_AS``), so that it is carried over, resumed and
#: joined with the later segments under today's options (``sim.sweep.with_todays_defaults``).
#: ``newton.reuse_ratio``: 0.25 until 2.12 (the 3D model's; the 2D model does not read it).
DEFAULTS_BEFORE: dict[tuple[str, str], tuple[str, float]] = {
    ("newton", "reuse_ratio"): ("2.12", 0.25)
}
# 2.20: 3D only: Newton abandons a step for the protocol to cut only when its residual
#      stagnates (NewtonOptions.stall_rule_3d "stagnation": the last 7 residuals within a
#      factor 2, or not halved over 12 iterations; was "halving", the 2D model's rule: not
#      halved over 6 iterations from the 8th). In 3D a step's residual often rises for a few
#      iterations while the contact set settles, then falls to convergence; "halving"
#      abandoned such steps and their halves, and the designs whose every half did so failed
#      (docs/fe_speed.md, "The stall rule in 3D"; studies/stall_rule3d.py). The same
#      tolerances: the metrics change only where a step is pursued that was cut. A kept
#      factorisation whose contact-correction columns are not finite (a pursued iterate's
#      tangent beyond float32's range) is replaced by a fresh one instead of failing the
#      protocol with LAPACK's "SVD did not converge". 2D: the same bits.
# 2.19: the same metrics, bit for bit, in less time: the deformation gradient's kernel gathers
#      an element's nodal displacements once for its quadrature points (the same sums);
#      PARDISO's values are gathered from the tangent's data in one pass (was: the upper
#      triangle, then PARDISO's order); the 3D validity's smallest principal stretch by the
#      spectral laws' compiled Jacobi (was: numpy's eigvalsh), its strains within 1e-15. Six
#      default-space 3D designs: 115.0 against 123.1 s (docs/fe_speed.md, "Gathers and the
#      validity's eigenvalues"). 2D: the same bits.
# 2.18: 3D wedge only: the ramp's sub-steps move the edge by at most half the band's element
#      size (sim.protocols.loading.WEDGE_BAND_TRAVEL; with the default band of 0.05 mm and
#      the schedule's 0.1 mm steps: 0.025 mm), from the ramp's first sub-step on (was: the
#      schedule's step first, then the halving rules took it down to 0.025 mm after the
#      edge's first bite). Six default-space designs' wedges: 334 factorisations against 382,
#      12 % less time, the metrics within 2.1e-4 (studies/wedge_steps.py --travel 0;
#      docs/fe_speed.md, "The wedge's first bite"). 2D and the 3D tapping and plate: the
#      same bits.
# 2.16: 3D wedge only: a sub-step that converged after more than 8 Newton iterations halves
#      the next (sim.protocols.loading.StepGrowth.shrink_above, WEDGE_STEP_GROWTH; was: the
#      next kept its size, failed and was cut). The wedge of six default-space designs: 25 %
#      less time, 21 % fewer factorisations, its metrics within 1.2e-4 (studies/wedge_steps.py;
#      docs/fe_speed.md, "A slow step halves the next"). 2D and the 3D tapping and plate: the
#      same bits.
# 2.15: 3D tapping only: the body keeps one factorisation per loading step across taps, in
#      PARDISO's slots (Body.step_factors, sim.protocols.loading.KEEP_STEP_FACTORS), and each
#      loading step begins with the one its step made in an earlier tap (was: the last one
#      of this tap). Six default-space designs' tapping against 2.14's path: 19 % less time,
#      the settled designs' metrics within 1e-4 (studies/tap_factors.py; docs/fe_speed.md,
#      "One factorisation per tapping step"). 2D: the same bits.
# 2.14: 3D only: the wedge's tangents are factorised in single precision too, and a step that
#      fails in single precision and is tried again in double hands the body back to single at
#      the next converged step (Body.advance; was: double for the rest of the protocol). The
#      wedge of four default-space designs: 9 % less time, its metrics within 4.5e-7
#      (studies/wedge_precision.py); six designs against 2.13: the wedge within 2.4e-5, a
#      tapping that had fallen back within the periodic state's tolerance (9.8e-4) (docs/
#      fe_speed.md, "The wedge in single precision"). 2D: the same bits.
# 2.13: 3D tapping and plate only: PARDISO factorises their tangents in single precision
#      (sim.fe._linear.PardisoSingle; sim.simulate.SINGLE_PRECISION_PROTOCOLS), a step that
#      fails with it is tried again in double precision, which the body then keeps
#      (Body.advance). The residual and Newton's test stay in double. Designs 128-135 of the
#      3D dataset against their 2.12 records: the displacements within 4e-7, the plate force
#      within 1.8e-5, the others within 6.9e-6, validity and settling unchanged
#      (docs/fe_speed.md, "Single precision"). The 2D model and the 3D wedge: the same bits.
# 2.12: the material laws' stress and tangent and the Prony update are compiled loops
#      (sim.materials._kernels, sim.materials._prony_kernels; was: numpy), the same formulas:
#      the laws equal to rounding (4e-16), 2D metrics within 1e-11 of 2.11 (Newton's tolerance).
#      3D only: a kept factorisation serves while the residual falls at least by half an
#      iteration (NewtonOptions.reuse_ratio 0.5; was 0.25): on five pads 25 % fewer
#      factorisations, the metrics within the time discretisation's error (docs/fe_speed.md,
#      "Compiled material laws", "The 3D model's kept factorisation").
# 2.11: 3D inclined plate only (model.inclination_deg > 0): the half pad is the quarter graded
#      for the plate glued on z = 0 to a quarter graded for the heel's side, where the plate
#      does not touch (sim.geometry.mesh3d.half_pad_mesh; was: the quarter's mirror image,
#      refined at -z* too). 17-21 % fewer dofs on the default mesh; the plate's force at 20 deg
#      within 1.9e-5 (docs/model_3d.md, "Inclination"). At 0 deg (every default run) and in 2D:
#      the same bits.
# 2.10: 3D wedge only: after a cut its sub-step doubles again only after two steps in a row
#      of at most 4 Newton iterations (sim.protocols.loading.WEDGE_STEP_GROWTH; was: after any
#      step of at most 5), as on its band of 0.05 mm elements a step grown back at once failed
#      again and again. Five pads: 31 % fewer factorisations in all, the metrics within 1.3e-5
#      (docs/fe_speed.md, "The 3D wedge's sub-steps"). The 2D model and the 3D tapping and
#      plate: the same bits.
# 2.9: 2D only: the 2D residual and tangent are assembled by the compiled kernels of the 3D
#      model (sim.fe._assembly, shared by both; the numpy assembly of sim.fe.fe2d is gone), and
#      the material tangent is computed when a factorisation asks for it (an accepted
#      backtracked step is no longer evaluated again for its tangent). 64 designs of the
#      default space: every metric within 7.4e-6 of 2.8 (a plate force; the displacements
#      within 4.5e-11), the same validity and settling, 12 % fewer residual evaluations
#      (docs/fe_speed.md, "The 2D assembly compiled"). The 3D model: the same bits.
# 2.8: 3D only: the active-set solves of a Newton iteration factorise afresh at most once (a
#      set beyond the Woodbury bound again keeps the last set's direction), and the columns
#      K0^-1 e_j of the Woodbury correction are kept for the factorisation's life
#      (sim.fe.solver._KeptColumns: solved once per dof, not once per change). The three corner
#      designs 24.8/36.4/139.4 -> 22.6/31.1/114.9 s, quiet, back to back (docs/fe_speed.md,
#      "One fresh factorisation per active-set settle"). The 2D model: the same bits.
# 2.7: 3D only: each Newton step is solved again for the contact set its own linearised
#      penetrations give (NewtonOptions.active_set_solves, Body._settle_active_set), and a
#      kept factorisation is corrected for at most 32 changed dofs (was 96); the metrics within
#      Newton's tolerance of 2.6 (a default-space design: every metric within 2.2e-6);
#      soft_fast and slow_creep 14 and 31 % faster, stiff_skin_soft_core 7 % slower (quiet,
#      back to back: docs/fe_speed.md). The 2D model: the same bits.
# 2.6: 3D only: PARDISO orders by nested dissection (METIS), as its settings' comment said;
#      it had ordered by minimum degree (the settings' flag iparm(1) was set to 2 where
#      iparm(2) was meant): a refactorisation of the pad's tangent 81.7 against 122.5 ms
#      (sim.fe._linear.PARDISO_IPARM). The 2D model's systems (at most 3 550 dofs in the
#      default space's sweeps) are factorised by qdldl: the same bits.
# 2.5: 3D only (the 2D model computes the same bits: studies/same_metrics.py): modified Newton
#      keeps its factorisation across changes of the contact set, corrected for them exactly
#      (NewtonOptions.contact_update, Woodbury); the material tangent computed only when the
#      tangent is assembled; the 3D laws' eigen-decomposition compiled (sim.materials._eigh3).
#      Other Newton iterates, the same tolerances (docs/fe_speed.md, "Contact update")
# 2.4: the line search models the contacts' part of its slope exactly (sim.fe.solver._model_root):
#      other sub-steps where a contact changes, the same tolerances. Designs 0-63 of the shipped
#      sweep, solver 2.3 against 2.4 on one machine (`python studies/same_metrics.py --n 64
#      --save` at each, docs/fe_speed.md, "Line search"): every metric within 3.2e-4 (a wedge's
#      force; displacements 6e-5), medians 7.4e-7 or less, below the time steps' own error
#      (docs/validation.md); validity and settling unchanged. 3D only: Newton's tolerance
#      10x tighter (sim.fe.residual_tolerance)
# 2.3: a protocol stops at its first recorded step beyond the validity limits
#      (ValidityOptions.stop_at_violation): no metrics, its validity figures censored there;
#      the metrics of a design within the limits are those of 2.2, bit for bit
# 2.2: Newton abandons a stalled step early (NewtonOptions.stall_*), so the step is cut sooner:
#      same tolerances; metrics within 0.1 % of 2.1 but for hysteresis values below 1e-3 N mm
#      (numerical noise of nearly elastic designs; docs/fe_speed.md, "Newton")
# 2.1: sag_mm metric (the displacement at the start of the measured tap); catalogue silicones at
#      nu = 0.499 (was 0.49); material families gel/foam (sim.design.families)
# 2.0: tapping to the periodic state on a residual (sim.protocols.periodic), rest steps from the
#      shortest relaxation time, 48 loaded steps, Newton started from the previous tap's increment,
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

#: The 3D model's metrics beside those of ``METRICS`` (its forces are the whole pad's, with no
#: length): the contact patch with the plate on the tapping's loading branch.
METRICS_3D: dict[str, tuple[str, str, str]] = {
    f"contact_{what}_at_{f}N_{unit}": ("tapping", unit.replace("mm2", "mm^2"), f"{text} at {f} N")
    for f in (1, 4)
    for what, unit, text in (
        ("area", "mm2", "contact area with the plate (projected on its plane)"),
        ("width", "mm", "contact extent across the finger (x)"),
        ("length", "mm", "contact extent along the finger (z)"),
    )
}


def metric_registry(dimension: str = "2d") -> dict[str, tuple[str, str, str]]:
    """The metrics a model computes: ``METRICS`` in 2D, and ``METRICS_3D`` besides in 3D."""
    return {**METRICS, **METRICS_3D} if dimension == "3d" else METRICS


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


def role_strain_name(protocol: str, role: str) -> str:
    """The diagnostic (and table column) of one layer's largest compressive log strain in one
    protocol, by the layer's role: ``tapping_skin_max_compressive_log_strain``."""
    return f"{protocol}_{role}_max_compressive_log_strain"


def role_strain_names(protocols: tuple[str, ...] | list[str] = PROTOCOLS) -> list[str]:
    """``role_strain_name`` of every protocol of ``protocols`` and every layer role
    (``sim.design.LAYER_ROLES``), protocol by protocol."""
    from .design.space import LAYER_ROLES

    return [role_strain_name(p, r) for p in protocols for r in LAYER_ROLES]


def role_strains(
    diagnostics: Mapping[str, Any],
    n_layers: int,
    protocols: tuple[str, ...] | list[str] = PROTOCOLS,
) -> dict[str, float | None]:
    """Each layer's largest compressive log strain per protocol, by role
    (``role_strain_names``), from the per-layer lists of a result's diagnostics
    (``<protocol>_max_compressive_log_strain_by_layer``, outermost layer first, as
    ``sim.design.active_roles(n_layers)`` names them). None for a role the design does not have,
    and for a protocol without the lists (not run, failed, or a record made before solver 2.3
    kept them): the validity of each layer is judged against its own limit from these."""
    from .design.space import active_roles

    roles = active_roles(n_layers)
    out: dict[str, float | None] = dict.fromkeys(role_strain_names(protocols))
    for p in protocols:
        strains = diagnostics.get(f"{p}_max_compressive_log_strain_by_layer")
        if isinstance(strains, list | tuple) and len(strains) == len(roles):
            for role, value in zip(roles, strains, strict=True):
                out[role_strain_name(p, role)] = None if value is None else float(value)
    return out


def diagnostic_names(protocols: tuple[str, ...] | list[str] = PROTOCOLS) -> list[str]:
    """The keys of ``SimResult.diagnostics()`` for a run of ``protocols``, in a fixed order (the
    diagnostic columns of a sweep's table.csv): each layer's largest strain by role
    (``role_strain_names``) among them."""
    names = ["settled", "valid"] if "tapping" in protocols else ["valid"]
    if "tapping" in protocols:
        names += [f"tapping_{k}" for k in SETTLE_KEYS if k != "settled"]
    names += [f"{p}_{k}" for p in protocols for k in DIAGNOSTIC_KEYS]
    names += role_strain_names(protocols)
    return [*names, "violations", "stopped"]
