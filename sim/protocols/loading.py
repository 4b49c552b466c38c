"""The paper's three loading protocols and their metrics.

Forces are in N for the whole fingertip (``force_scale`` of the discretisation): in 2D the
plane-strain force per unit thickness times the stated out-of-plane length L, times 2 for the
symmetric half model; in 3D the quarter pad's force times 4, with no length. Displacements in
mm, time in s. In 3D the tapping also reports the contact patch with the plate at 1 N and 4 N
(its area, and its extents across and along the finger), and the wedge's edge runs across the
pad (its surface profile is read along the finger, on the plane x = 0).

- ``tapping`` (§4.1.1): force-controlled taps, each a half sine to ``peak_force_N`` lasting
  ``1 / (2 f)`` s, then ``rest_s`` with the plate lifted off (steps spaced geometrically from
  the shortest relaxation time, so the fastest free recovery is resolved); L = 10 mm. Taps
  repeat until the periodic state (``sim.protocols.periodic``: per-term closed forms plus Anderson
  acceleration, stopped on a residual with an error estimate per metric). Metrics come from the
  last tap.
- ``plate`` (§3.2.2): the plate pushed 1 mm at 0.2 mm/s from first touch; L = 22 mm.
- ``wedge`` (§3.1, §4.1.2): the wedge pushed 1 mm in 1 s, then held for 100 s; L = 10 mm.

In 3D the plate of the tapping and of ``plate`` may be inclined about the cross-finger axis x
(``model.inclination_deg``, ``sim.fe.contact.Plate``): the model is then the half pad, the
displacements are the plate's travel along its normal, the forces the plate's force along its
normal and the contact patch is measured in the plate's plane.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import SimulationError
from ..fe import FORCE_RTOL, Body, Control, Plate, Wedge, residual_tolerance, youngs_moduli
from .validity import DeformationTracker, ValidityStop, check

if TYPE_CHECKING:
    from ..design import Design
    from ..options import SimOptions

__all__ = [
    "REGISTRY",
    "PlateOptions",
    "Protocol",
    "ProtocolResult",
    "TappingOptions",
    "WedgeOptions",
    "contact_patch",
    "hysteresis_resolution_Nmm",
    "run_plate",
    "run_tapping",
    "run_wedge",
    "shown_hysteresis",
]


@dataclass(frozen=True)
class TappingOptions:
    peak_force_N: float = 5.0
    frequency_Hz: float = 0.5  # of the half-sine: loaded for 1 / (2 f) seconds
    rest_s: float = 1.0
    length_mm: float = 10.0
    # Steps while the plate is in contact (denser near touch and lift-off, see _tap_times), for
    # the measured tap and for the settling taps (if different, one more tap follows). 48: with
    # 32 the loop area of the soft, fast-relaxing corner designs moves by 0.6-1.0 % when every
    # step is quartered; with 48 by <= 0.45 % (docs/validation.md, time-step convergence).
    steps_loaded: int = 48
    steps_settle: int = 48
    # Rest (plate lifted): geometric steps from rest_first_step_tau x the shortest relaxation
    # time, each at most rest_growth x the one before, and at least steps_rest of them. The body
    # recovers freely with time constants no shorter than its shortest tau (retardation times
    # are longer than relaxation times); a geometric sequence resolves every time constant from
    # the first step to the rest's length with the same relative step (rest_growth - 1). The
    # sag left at the next touch is a small difference of large displacements, so it needs
    # fine steps: with a growth of 1.6 (1.25) the sag of the soft, fast corner design was off
    # by 80 % (17 %) against quartered steps, moving the displacements from touch by 2 %; with
    # 1.12 and a first step of tau / 4, by <= 1 % of the sag and 0.3 % of those displacements.
    steps_rest: int = 4
    rest_first_step_tau: float = 0.25
    rest_growth: float = 1.12
    max_taps: int = 25
    min_taps: int = 3
    # The periodic state (sim.protocols.periodic): taps stop when the relative residual of the Prony
    # state and every metric's estimated relative error are below these; 0 never stops early.
    residual_tol: float = 1e-3
    settle_tol: float = 1e-3
    # Give up early on a design whose residual falls too slowly to reach residual_tol within
    # max_taps at the rate of its last stall_window taps (see _cannot_settle); 0: never. Such a
    # design is reported unsettled, as it would be after max_taps, at a third of the cost.
    stall_window: int = 6
    accelerate: bool = (
        True  # per-term jumps + Anderson mixing after each tap (sim.protocols.periodic)
    )

    def with_steps_scaled(self, factor: float) -> TappingOptions:
        """Every step count times ``factor`` and every step size divided by it."""
        return replace(
            self,
            steps_loaded=2 * round(self.steps_loaded * factor / 2),
            steps_settle=2 * round(self.steps_settle * factor / 2),
            steps_rest=max(2, round(self.steps_rest * factor)),
            rest_first_step_tau=self.rest_first_step_tau / factor,
            rest_growth=self.rest_growth ** (1.0 / factor),
        )


@dataclass(frozen=True)
class PlateOptions:
    depth_mm: float = 1.0
    speed_mm_per_s: float = 0.2
    length_mm: float = 22.0
    steps: int = 10


@dataclass(frozen=True)
class WedgeOptions:
    depth_mm: float = 1.0
    ramp_s: float = 1.0
    hold_s: float = 100.0
    length_mm: float = 10.0
    tip_width_mm: float = 0.05
    half_angle_deg: float = 30.0
    ramp_steps: int = 10
    hold_steps: int = 16
    # the tip concentrates the load: a stiffer penalty keeps the penetration far below the
    # tip radius (0.029 mm) and 1 % of the depth (checked in the result's max_penetration_mm)
    penalty_per_mm: float = 20000.0
    profile_length_mm: float = 7.0
    profile_points: int = 71


@dataclass
class ProtocolResult:
    """Metrics (names carry units), curves (name -> column name -> list) and solver figures."""

    protocol: str
    metrics: dict[str, float]
    curves: dict[str, dict[str, list[float]]]
    newton_iterations: int
    steps: int
    wall_time_s: float
    info: dict = field(default_factory=dict)
    #: displacement fields (n_nodes, dim) of chosen states by name, e.g. the measured tap's
    #: ``tapping_1N`` and ``tapping_4N`` (``SNAPSHOT_FORCES_N``); not JSON, not in records
    fields: dict[str, np.ndarray] = field(default_factory=dict, repr=False)


# ---------------------------------------------------------------------------- stepping
@dataclass(frozen=True)
class StepGrowth:
    """When a protocol's sub-step grows back after a cut (``_march``): it doubles, at most to
    the schedule's own spacing, once ``easy_steps`` steps in a row (counted from the last cut or
    the last step that was not easy) have each converged within ``within_iterations`` Newton
    iterations. The default: after any step of at most 5 iterations. A step that converged
    only after more than ``shrink_above`` iterations halves the next one (None: never), as a
    step that failed does, but without the failed attempt's cost. No sub-step is larger than
    ``largest`` times the schedule's spacing, and the first is that large."""

    within_iterations: int = 5
    easy_steps: int = 1
    shrink_above: int | None = None
    largest: float = 1.0


#: The wedge's step growth by the model's dimension (``run_wedge``; the other protocols grow as
#: ``StepGrowth()``). 2D: the default (its records were made so). 3D: after two steps in a row
#: of at most 4 iterations. On the 3D wedge's band a step grown back at the first easy step
#: fails again and again (the tip crosses elements smaller than a step's travel): failed
#: attempts took 78 of the 186 factorisations of a silicone pad's wedge (coarse banded mesh).
#: On five pads of the default 3D mesh this
#: rule took 31 % fewer (49 to 117 % of the old count each), the metrics within 1.3e-5; the
#: tapping, whose whole steps start from the previous tap (``_Replay``), took 82 % more on one
#: pad with it, so it keeps the default (docs/fe_speed.md, "The 3D wedge's sub-steps").
#: Since solver 2.16 a 3D wedge step that took more than 8 iterations halves the next: the
#: first steps of the ramp, where the edge first presses into the band, took 12-14 and the
#: full step after them failed and was cut twice, a third of the wedge's time in failed
#: attempts; the band's working sub-steps of 0.025 mm take 4-8, which 8 leaves alone (6 halved
#: some of them and cost more, studies/wedge_steps.py --against 6: docs/fe_speed.md, "A slow
#: step halves the next").
WEDGE_STEP_GROWTH = {
    2: StepGrowth(),
    3: StepGrowth(within_iterations=4, easy_steps=2, shrink_above=8),
}

#: The 3D wedge's ramp: the edge travels at most this fraction of the band's element size
#: (``MeshOptions3D.edge_h_mm``; the Q2 nodes' spacing is half of it) in one sub-step, from the
#: ramp's first (since solver 2.18; 0: the schedule's steps, as until 2.17). With the
#: schedule's 0.1 mm steps the edge's first bite into the band (0.05 mm elements) took up to
#: 16 Newton iterations and 11 factorisations, and the halving rules above then took the
#: sub-step down to 0.025 mm, where the ramp went on. Starting there, on six default-space
#: designs: 334 factorisations of the wedge against 382 and 12 % less time, the metrics within
#: 2.1e-4; on four of them a whole element a sub-step made 317 and a quarter 369 against half's
#: 284 (studies/wedge_steps.py --travel 0 / 1 / 0.25; docs/fe_speed.md, "The wedge's first
#: bite").
WEDGE_BAND_TRAVEL = 0.5

#: Whether a tapping body with modified Newton (the 3D model) keeps one factorisation per
#: loading step across taps (``Body.step_factors``; solver 2.15): each loading step begins
#: with the factorisation the same step made in an earlier tap (docs/fe_speed.md, "One
#: factorisation per tapping step"). False gives solver 2.14's path (``studies/tap_factors.py``).
KEEP_STEP_FACTORS = True


def _march(
    body: Body,
    times: np.ndarray,
    control: Callable[[float], Control],
    protocol: str,
    on_step: Callable[[float], None] | None = None,
    max_cuts: int = 12,
    max_attempts: int = 2000,
    replay: _Replay | None = None,
    growth: StepGrowth = StepGrowth(),
) -> int:
    """Advance through the schedule ``times`` with adaptive sub-steps.

    A step that fails is retried at half the size; after a cut the step grows back (x2 after
    easy steps: ``growth``; at most to the schedule's own spacing). Gives up with
    ``SimulationError`` when a step has been halved ``max_cuts`` times in a row, when the
    sub-step falls below 2^-max_cuts of the schedule spacing, or after ``max_attempts``
    attempts in all.
    ``replay`` starts each whole schedule step from the previous tap's increment (``_Replay``).
    """
    steps = 0
    attempts = 0
    scale = growth.largest  # current sub-step as a fraction of the schedule spacing
    easy = growth.easy_steps  # easy steps in a row since the last cut or hard step
    for j, t_target in enumerate(times):
        t_begin = body.t
        span = t_target - t_begin
        cuts = 0
        while body.t < t_target - 1e-12 * max(1.0, abs(t_target)):
            attempts += 1
            if attempts > max_attempts:
                raise SimulationError(protocol, body.t, f"more than {max_attempts} step attempts")
            t_next = min(t_target, body.t + scale * span) if span > 0 else t_target
            if t_target - t_next < 0.05 * scale * span:  # avoid a sliver step at the end
                t_next = t_target
            whole = replay is not None and t_next == t_target and body.t == t_begin and not cuts
            guess = replay.guess(j, body) if whole else None
            key = replay.factor_key(j) if replay is not None else None
            res = body.advance(t_next, control(t_next), guess=guess, factor_key=key)
            if res.converged:
                steps += 1
                cuts = 0
                if replay is not None and t_next == t_target:
                    replay.store(j, body)
                if on_step is not None:
                    on_step(t_next)
                easy = easy + 1 if res.iterations <= growth.within_iterations else 0
                if easy >= growth.easy_steps:
                    scale = min(growth.largest, 2.0 * scale)
                elif growth.shrink_above is not None and res.iterations > growth.shrink_above:
                    scale = max(0.5 * scale, 2.0**-max_cuts)
                if span <= 0:
                    break
                continue
            cuts += 1
            easy = 0
            if cuts > max_cuts or span <= 0 or scale < 2.0**-max_cuts:
                raise SimulationError(protocol, body.t, res.reason + " after step cutting")
            scale *= 0.5
    return steps


class _Replay:
    """Newton's starting point from the previous tap at the same phase.

    Taps repeat one schedule, and near the periodic state each tap repeats the last: the
    displacement increment of schedule step ``j`` in the previous tap predicts this tap's far
    better than extrapolating this tap's last step (which knows nothing of first touch or of
    the free recovery after lift-off). One ``_Replay`` serves one phase (loaded or rest) of
    every tap; :meth:`start` is called at the phase's start. A ``keyed`` one also names each
    schedule step for the body's factorisations kept per step (``factor_key``,
    ``Body.step_factors``)."""

    def __init__(self, keyed: bool = False) -> None:
        self.prev: dict[int, tuple[np.ndarray, float, float]] = {}
        self.cur: dict[int, tuple[np.ndarray, float, float]] = {}
        self.keyed = keyed

    def start(self, body: Body, schedule: object = None) -> None:
        """A new tap's phase begins; ``schedule`` tells taps with other step times apart."""
        same = schedule == getattr(self, "_schedule", schedule)
        self.prev, self.cur = (self.cur if same else {}), {}
        self._schedule = schedule
        self.store(-1, body)

    def store(self, j: int, body: Body) -> None:
        """The committed state at the end of schedule step ``j`` (``-1``: the phase's start)."""
        self.cur[j] = (body.u, body.indenter_position, body.top_height())

    def factor_key(self, j: int) -> tuple[object, int] | None:
        """The key of schedule step ``j`` of this phase's schedule (None if not ``keyed``)."""
        return (getattr(self, "_schedule", None), j) if self.keyed else None

    def guess(self, j: int, body: Body) -> tuple[np.ndarray, float] | None:
        before, after = self.prev.get(j - 1), self.prev.get(j)
        if before is None or after is None or (j - 1) not in self.cur:
            return None
        u = body.u + (after[0] - before[0])
        d_before = before[1] if np.isfinite(before[1]) else before[2]  # free: at the top
        d_now = body.indenter_position if np.isfinite(body.indenter_position) else body.top_height()
        d = d_now + (after[1] - d_before) if np.isfinite(after[1]) else np.inf
        return u, d


def _result(protocol, body, t0, it0, steps, metrics, curves, info=None) -> ProtocolResult:
    return ProtocolResult(
        protocol=protocol,
        metrics=metrics,
        curves=curves,
        newton_iterations=body.newton_iterations - it0,
        steps=steps,
        wall_time_s=time.perf_counter() - t0,
        info=info or {},
    )


class _Recorder:
    """What every protocol records at each committed step (``_march``'s ``on_step``).

    The curve: the time from the curve's start, the indenter's displacement from ``top`` and the
    force in N (``force_N`` converts the model's indenter force), in 3D the contact patch
    (``contact_patch``); over the whole run: the deepest indenter penetration, the most surface
    nodes resting on the base and the deformation (``DeformationTracker``, whose peak state the
    protocol marks). ``new_curve`` starts another curve (each tap), keeping the rest."""

    def __init__(self, body: Body, top: float, force_N: Callable[[float], float]) -> None:
        self.body = body
        self.top = top
        self.force_N = force_N
        self.max_penetration = 0.0
        self.max_base_nodes = 0
        self.tracker = DeformationTracker(body.disc)
        self.new_curve()

    def new_curve(self, disp0: float = 0.0) -> None:
        """Start a curve at the current time, at displacement ``disp0`` and no force."""
        self.t_start = self.body.t
        self.t, self.disp, self.force = [0.0], [disp0], [0.0]
        self.patch: list[tuple[float, float, float]] = [(0.0, 0.0, 0.0)]
        self.snapshots: dict[str, np.ndarray] = {}  # tapping_<F>N -> u, on loading
        self.peak_force = -np.inf
        self.peak_H = [s.H for s in self.body.states]

    def record(self, t: float, peak: bool = False) -> None:
        """The step just committed at ``t``; ``peak``: it is the state of the peak load."""
        body = self.body
        self.t.append(t - self.t_start)
        self.disp.append(self.top - body.indenter_position)
        self.force.append(self.force_N(body.force))
        if body.disc.dim == 3:
            self.patch.append(contact_patch(body))
        self.max_penetration = max(self.max_penetration, body.max_penetration())
        self.max_base_nodes = max(self.max_base_nodes, body.base_contact_nodes())
        self.tracker.observe(body)
        if peak:
            self.tracker.observe_peak(body)
        if body.stop_beyond is not None:
            protocol, limits = body.stop_beyond
            broken = check(self.tracker.summary(), limits, protocol)
            if broken:
                raise ValidityStop(protocol, body.t, broken, self.info(), self.tracker.observed)

    def record_peak_force(self, t: float) -> None:
        """``record``, the peak being the step of the curve's largest force so far (its Prony
        history kept as ``peak_H``; committed states are new arrays: no copy needed); the
        state of the first step at or beyond each of ``SNAPSHOT_FORCES_N`` on the way up is
        kept in ``snapshots``."""
        body = self.body
        peak = body.force > self.peak_force
        if peak:
            self.peak_force, self.peak_H = body.force, [s.H for s in body.states]
        self.record(t, peak)
        if peak:
            for f in SNAPSHOT_FORCES_N:
                name = f"tapping_{f:g}N"
                if name not in self.snapshots and self.force[-1] >= f * (1.0 - 1e-9):
                    self.snapshots[name] = body.u

    def info(self) -> dict[str, Any]:
        """The figures over the whole run for ``ProtocolResult.info``."""
        return {
            "max_penetration_mm": self.max_penetration,
            "max_base_contact_nodes": self.max_base_nodes,
            "validity": self.tracker.summary(),
        }


def contact_patch(body: Body) -> tuple[float, float, float]:
    """The contact with the indenter of a 3D body in its committed state: the area (mm^2,
    ``Discretization3D.contact_area_mm2``) and the full extents across (x) and along (z) the
    finger (mm, on the symmetry planes, ``contact_half_width_mm``). On the half pad (an
    inclined plate) the patch is measured in the plate's plane, its extents across (x) and
    along the finger in that plane (``Discretization3D.contact_patch_mm``)."""
    from .validity import contact_half_width_mm

    disc = body.disc
    if disc.half or not body.vertical_indenter:
        return disc.contact_patch_mm(body.u, body.indenter_penetration(), body.indenter_axis)
    area = disc.contact_area_mm2(body.u, body.indenter_penetration())
    extent = {}
    for nodes, axis in disc.section_curves():
        coordinate = disc.X[nodes, axis] + body.u[nodes, axis]
        extent[axis] = 2.0 * contact_half_width_mm(coordinate, body.indenter_penetration(nodes))
    return area, extent[0], extent[2]


#: The forces (N) on the measured tap's loading branch whose states a tapping keeps: the first
#: committed step at or beyond each (``ProtocolResult.fields``, ``tapping_<F>N``), for the VTU
#: files and the figure of the deformed pad and its contact patch.
SNAPSHOT_FORCES_N = (1.0, 4.0)

#: The 3D tapping's contact metrics, read at 1 N and 4 N on the loading branch like the
#: displacements: (metric prefix, index in ``contact_patch``'s tuple).
PATCH_METRICS = (("contact_area", 0), ("contact_width", 1), ("contact_length", 2))


def _patch_metrics(t, force, patch, t_load) -> dict[str, float]:
    """The contact patch at 1 N and 4 N of the loading branch (PCHIP in the force, as the
    displacements), NaN where the force was not reached; names from ``PATCH_METRICS``."""
    from scipy.interpolate import PchipInterpolator

    t, force, patch = np.asarray(t), np.asarray(force), np.asarray(patch)
    load = t <= 0.5 * t_load + 1e-12
    fl, first = np.unique(force[load], return_index=True)
    out = {}
    for name, k in PATCH_METRICS:
        of_f = PchipInterpolator(fl, patch[load][first, k])
        unit = "mm2" if name == "contact_area" else "mm"
        for f in (1.0, 4.0):
            value = float(of_f(f)) if fl[-1] >= f else float("nan")
            out[f"{name}_at_{f:g}N_{unit}"] = value
    return out


# ---------------------------------------------------------------------------- tapping
def _tap_times(t_load: float, n: int) -> np.ndarray:
    """Times in [0, t_load] for a half-sine tap, dense where the displacement changes fast.

    Steps are even along the curve (t / t_load, sqrt(F / F_peak)): the square root puts more steps
    near first touch and lift-off, where a soft pulp's displacement grows like a power < 1 of the
    force.
    """
    theta = np.linspace(0.0, np.pi, 4001)
    arc = np.concatenate(
        [[0.0], np.cumsum(np.hypot(np.diff(theta / np.pi), np.diff(np.sqrt(np.sin(theta)))))]
    )
    th = np.interp(np.linspace(0.0, arc[-1], n + 1), arc, theta)
    return th / np.pi * t_load


def _tap_metrics(t, delta, force, t_load, peak, omega):
    """Displacements at 1 N and 4 N on the loading branch and the loop area (N mm)."""
    from scipy.interpolate import PchipInterpolator  # here: `import sim` stays light

    t = np.asarray(t)
    delta = np.asarray(delta)
    force = np.asarray(force)
    load = t <= 0.5 * t_load + 1e-12
    fl, dl = force[load], delta[load]
    fl, first = np.unique(fl, return_index=True)  # sorted; a repeated force keeps its first
    d_of_f = PchipInterpolator(fl, dl[first])
    d1 = float(d_of_f(1.0)) if peak >= 1.0 else float("nan")
    d4 = float(d_of_f(4.0)) if peak >= 4.0 else float("nan")
    # loop area = -closed integral of delta dF, F(t) = peak sin(omega t) known exactly
    d_of_t = PchipInterpolator(t, delta)
    tt = np.linspace(t[0], t[-1], 4001)
    dF = peak * omega * np.cos(omega * tt)
    hyst = -float(np.trapezoid(d_of_t(tt) * dF, tt))
    return d1, d4, hyst


def hysteresis_resolution_Nmm(
    design: Design | None, metrics: Mapping[str, Any], options: SimOptions | None = None
) -> float:
    """The smallest loop area (N mm) the tapping's FE tells from 0, by Newton's tolerances.

    The loop area is ``-closed integral of delta dF`` = ``closed integral of F d(delta)``. Newton
    ends a step once the indenter force matches the applied one within ``FORCE_RTOL`` of it and
    every other equation's residual is within ``Body.atol`` (``sim.fe.residual_tolerance``:
    rtol x E0 x size, N/mm of the half model; E0 the largest Young's modulus, size the largest
    coordinate). Each force of the
    loop is then known to ``dF = FORCE_RTOL x peak + 2 L x atol`` (N: L the out-of-plane length,
    2 for the half model) at worst, and the integral, whose path is twice the travel from first
    touch to the peak (``closed integral of |d delta|``), to ``2 x travel x dF``. A smaller
    value is the tolerances' noise, not dissipation: an elastic design (0 by physics) gives a
    few 1e-5 N mm of either sign. The travel: ``disp_at_4N_from_touch_mm`` of ``metrics``
    scaled to the peak force (an upper bound: the contact stiffens), else the design's height.
    ``design`` None (or an unknown one): the indenter term alone. ``options``: default ones."""
    from ..geometry import REFERENCE_GEOMETRY
    from ..options import SimOptions

    options = options or SimOptions()
    tapping, newton = options.tapping, options.newton
    geometry = design.geometry if design is not None else REFERENCE_GEOMETRY
    size = max(geometry.half_width_mm, geometry.height_mm)  # Body: the largest coordinate
    d4 = metrics.get("disp_at_4N_from_touch_mm")
    finite = isinstance(d4, int | float) and np.isfinite(d4)
    travel = d4 * max(1.0, tapping.peak_force_N / 4.0) if finite else geometry.height_mm
    e0 = max(youngs_moduli(design.materials)) if design is not None else 0.0
    if options.model.dimension == "3d":  # Body.atol in N; the quarter pad's force x 4
        if design is not None:
            size = max(size, design.pad.half_length_mm)
        atol_N = residual_tolerance(newton.rtol, e0, size, 3)
        force = FORCE_RTOL * tapping.peak_force_N + 4.0 * atol_N
    else:  # Body.atol in N/mm of the half section; x 2 L
        atol_N_per_mm = residual_tolerance(newton.rtol, e0, size, 2)
        force = FORCE_RTOL * tapping.peak_force_N + 2.0 * tapping.length_mm * atol_N_per_mm
    return 2.0 * abs(travel) * force


def shown_hysteresis(
    metrics: Mapping[str, Any],
    design: Design | Mapping[str, Any] | None = None,
    options: SimOptions | None = None,
) -> float | None:
    """The FE ``hysteresis_Nmm`` of ``metrics`` as a reader is shown it: 0 when it is below
    :func:`hysteresis_resolution_Nmm` (so a negative loop area, which no passive material
    makes, is never shown), else its value; None when there is none. Only the display: the
    records keep the computed value, so the stored metric and the sweeps made with it (keyed by
    solver version) do not change. ``design``: a ``Design`` or its design-file dict (one this
    catalogue cannot build: the indenter term of the resolution alone)."""
    value = metrics.get("hysteresis_Nmm")
    if value is None or not np.isfinite(value):
        return None
    if isinstance(design, Mapping):
        from ..design import design_from_dict
        from ..errors import DesignError

        try:
            design = design_from_dict(design)
        except DesignError:  # a user catalogue's material
            design = None
    return 0.0 if value < hysteresis_resolution_Nmm(design, metrics, options) else float(value)


def _rest_times(opts: TappingOptions, tau_min_s: float) -> np.ndarray:
    """Offsets in (0, rest_s] of the rest steps, the last exactly ``rest_s``.

    Viscoelastic: geometric from ``rest_first_step_tau * tau_min_s`` with a ratio of at most
    ``rest_growth`` and at least ``steps_rest`` steps (see ``TappingOptions``). Elastic
    (``tau_min_s = inf``): nothing relaxes, ``steps_rest`` steps denser at the start.
    """
    n_min = max(1, opts.steps_rest)
    if not np.isfinite(tau_min_s):
        return opts.rest_s * (np.arange(1, n_min + 1) / n_min) ** 1.5
    dt0 = min(opts.rest_first_step_tau * tau_min_s, opts.rest_s / n_min)
    growth = max(opts.rest_growth, 1.0 + 1e-9)
    n = int(np.ceil(np.log1p(opts.rest_s * (growth - 1.0) / dt0) / np.log(growth) - 1e-9))
    n = max(n_min, n)
    if dt0 * n >= opts.rest_s * (1.0 - 1e-12):
        return opts.rest_s * np.arange(1, n + 1) / n
    lo, hi = 1.0, growth  # the ratio q with dt0 (q^n - 1) / (q - 1) = rest_s, by bisection
    for _ in range(100):
        q = 0.5 * (lo + hi)
        if dt0 * np.expm1(n * np.log(q)) / (q - 1.0) < opts.rest_s:
            lo = q
        else:
            hi = q
    times = np.cumsum(dt0 * q ** np.arange(n))
    times *= opts.rest_s / times[-1]  # round-off: end exactly at rest_s
    return times


def _shortest_relaxation_time(body: Body) -> float:
    """The shortest relaxation time (s) of any term that relaxes; ``inf`` for an elastic body."""
    taus = [
        t
        for m in body.disc.materials
        for g, k, t in zip(m.prony.g, m.prony_k, m.prony.tau_s, strict=True)
        if g or k
    ]
    return min(taus, default=float("inf"))


#: The tapping metrics in the order of the vectors the periodic state works on.
TAP_METRICS = (
    "disp_at_1N_mm",
    "disp_at_4N_mm",
    "disp_at_1N_from_touch_mm",
    "disp_at_4N_from_touch_mm",
    "hysteresis_Nmm",
)


def _cannot_settle(residuals: list[float], opts: TappingOptions) -> bool:
    """Whether the periodic state is out of reach within ``max_taps`` at the observed rate.

    With ``b_k`` the best residual after ``k`` taps and ``w = stall_window``, the residual fell
    by ``rate = (b_k / b_(k-w))^(1/w)`` per tap over the last ``w`` taps; at that rate it needs
    ``log(residual_tol / b_k) / log(rate)`` more taps. Judged from tap ``w + 2`` on (the first
    taps fall fastest: they settle the fast terms) and after ``min_taps`` (a fixed number of taps
    asked for is always made), and never while the residual is within its tolerance (then the
    error estimate decides)."""
    w, k = opts.stall_window, len(residuals)
    if w <= 0 or k < max(w + 2, opts.min_taps):  # min_taps are always made
        return False
    best = np.minimum.accumulate(np.asarray(residuals, dtype=float))
    if best[-1] <= opts.residual_tol:
        return False
    rate = (best[-1] / best[-1 - w]) ** (1.0 / w)
    if not rate < 1.0:
        return True
    needed = np.log(opts.residual_tol / best[-1]) / np.log(rate)
    return bool(k + needed > opts.max_taps)


class _Taps:
    """One tap after another on ``body``: the tap's schedule, the Newton starting points from
    the previous tap (``_Replay``), the record and the count of steps, shared by all taps."""

    def __init__(self, body: Body, opts: TappingOptions) -> None:
        self.body = body
        self.opts = opts
        self.top0 = body.top_height()
        self.t_load = 0.5 / opts.frequency_Hz
        self.omega = np.pi / self.t_load
        # N -> the model's indenter force (N/mm on the 2D half model, N on the 3D quarter)
        self.scale = scale = 1.0 / body.disc.force_scale(opts.length_mm)
        self.s_rest = self.t_load + _rest_times(opts, _shortest_relaxation_time(body))
        self.steps = 0
        #: per tap and phase (loaded, rest): steps, factorisations and residual evaluations,
        #: counts that do not depend on the machine's load (studies/fe_time_study.py)
        self.cost: list[dict[str, int]] = []
        self.replay_load, self.replay_rest = _Replay(keyed=True), _Replay()
        # modified Newton (the 3D model) keeps a factorisation per loading step across taps
        if body.options.reuse_factorization and KEEP_STEP_FACTORS:
            body.step_factors = max(opts.steps_loaded, opts.steps_settle)
        self.recorder = _Recorder(body, self.top0, lambda f: f / scale)

    @contextmanager
    def _counted(self, phase: str) -> Iterator[None]:
        """Log the steps, factorisations and evaluations of the block as ``phase`` of this tap
        (also when it raises: a failed tap's cost is part of the run's)."""
        body = self.body
        before = (self.steps, body.factorizations, body.evaluations)
        try:
            yield
        finally:
            self.cost.append(
                {
                    "tap": len(self.cost) // 2 + 1,  # a loaded and a rest entry per tap
                    "phase": phase,
                    "steps": self.steps - before[0],
                    "factorizations": body.factorizations - before[1],
                    "evaluations": body.evaluations - before[2],
                }
            )

    def tap(self, n_loaded: int) -> tuple[np.ndarray, dict, list[np.ndarray]]:
        """One tap (contact then rest) from the current state: its metrics (``TAP_METRICS``),
        its record and the Prony state at its peak force."""
        body, opts, t_load, rec = self.body, self.opts, self.t_load, self.recorder
        omega, scale = self.omega, self.scale
        s_load = _tap_times(t_load, n_loaded)[1:]
        s_load[-1] = t_load * (1.0 - 1e-4)  # stop just short of zero force; the plate lifts
        t_start = body.t
        touch = self.top0 - body.top_height()
        rec.new_curve(touch)

        def force_at(t: float) -> Control:
            return Control.force(opts.peak_force_N * np.sin(omega * (t - t_start)) * scale)

        self.replay_load.start(body, n_loaded)
        on_step, replay = rec.record_peak_force, self.replay_load
        with self._counted("loaded"):
            self.steps += _march(
                body, t_start + s_load, force_at, "tapping", on_step, replay=replay
            )
        rec.t.append(t_load)
        rec.disp.append(rec.disp[-1])
        rec.force.append(0.0)
        body.indenter_position = np.inf
        self.replay_rest.start(body)
        free = lambda t: Control.free()  # noqa: E731
        with self._counted("rest"):
            self.steps += _march(
                body, t_start + self.s_rest, free, "tapping", replay=self.replay_rest
            )
        d1, d4, hyst = _tap_metrics(rec.t, rec.disp, rec.force, t_load, opts.peak_force_N, omega)
        metrics = np.array([d1, d4, d1 - touch, d4 - touch, hyst])
        record = {"t": rec.t, "disp": rec.disp, "force": rec.force, "touch": touch}
        if body.disc.dim == 3:
            patch = [*rec.patch, rec.patch[-1]]  # the lift-off point appended above
            record["patch"] = _patch_metrics(rec.t, rec.force, patch, t_load)
        return metrics, record, rec.peak_H


def run_tapping(body: Body, opts: TappingOptions = TappingOptions()) -> ProtocolResult:
    """Tap until the periodic (quasi-steady) state; the metrics are those of the last tap.

    After each tap the Prony state is moved towards its periodic value (``accelerate``,
    :class:`sim.protocols.periodic.PeriodicState`); taps stop once the residual of the periodic
    state and every metric's estimated error are within ``residual_tol`` and ``settle_tol`` (and at
    least ``min_taps`` were made); a body that does not get there in ``max_taps`` is reported
    unsettled, with its residual and error estimate. If ``steps_settle`` differs from
    ``steps_loaded`` the settling taps use it and one more tap with ``steps_loaded`` steps gives the
    metrics. An elastic body needs no settling: one tap.
    """
    from .periodic import PeriodicState

    t0, it0 = time.perf_counter(), body.newton_iterations
    if not isinstance(body.indenter, Plate):
        raise ValueError("tapping needs a Plate indenter")
    taps = _Taps(body, opts)
    history: list[np.ndarray] = []
    if all(m.is_elastic for m in body.disc.materials):
        metrics_k, last, _ = taps.tap(opts.steps_loaded)
        history.append(metrics_k)
        settled, residual, rel_error = True, 0.0, np.zeros(len(TAP_METRICS))
        residuals, accelerated, stalled = [0.0], {}, False
    else:
        periodic = PeriodicState(body, taps.t_load + opts.rest_s)
        settled = stalled = False
        residuals = []
        for k in range(opts.max_taps):
            H_start = [s.H for s in body.states]
            metrics_k, last, H_peak = taps.tap(opts.steps_settle)
            history.append(metrics_k)
            status = periodic.after_tap(H_start, H_peak, metrics_k)
            residuals.append(status.residual)
            if len(history) >= opts.min_taps and status.converged(
                metrics_k, opts.residual_tol, opts.settle_tol
            ):
                settled = True
                break
            if _cannot_settle(residuals, opts):
                stalled = True
                break
            if opts.accelerate and k + 1 < opts.max_taps:
                periodic.accelerate()
        residual, rel_error = status.residual, status.relative_error(metrics_k)
        accelerated = dict(periodic.used)
        if opts.steps_settle != opts.steps_loaded:  # a finer tap for the metrics
            metrics_k, last, _ = taps.tap(opts.steps_loaded)
            history.append(metrics_k)
    metrics = {name: float(v) for name, v in zip(TAP_METRICS, history[-1], strict=True)}
    metrics["sag_mm"] = float(last["touch"])
    metrics.update(last.get("patch", {}))
    curves = {
        "tapping": {
            "time_s": last["t"],
            "displacement_mm": last["disp"],
            "force_N": last["force"],
        }
    }
    errors = {n: _json_float(e) for n, e in zip(TAP_METRICS, rel_error, strict=True)}
    finite = [e for e in rel_error if np.isfinite(e)]
    info = {
        "taps": len(history),
        "settled": settled,
        "residual": float(residual),
        "estimated_error": errors,  # relative, per metric; null where a metric was not reached
        "max_estimated_error": float(max(finite, default=float("inf"))),
        "touch_mm": last["touch"],
        "rest_steps": len(taps.s_rest),
        "history": [[_json_float(v) for v in h] for h in history],
        "residual_history": [_json_float(r) for r in residuals],
        "accelerated": accelerated,
        "stalled": stalled,  # stopped early: the periodic state was out of reach (unsettled)
        "cost": taps.cost,
        **taps.recorder.info(),
    }
    res = _result("tapping", body, t0, it0, taps.steps, metrics, curves, info)
    res.fields.update(taps.recorder.snapshots)  # the measured tap's (new_curve resets them)
    return res


def _json_float(v: float) -> float | None:
    return float(v) if np.isfinite(v) else None


# ---------------------------------------------------------------------------- plate
def run_plate(body: Body, opts: PlateOptions = PlateOptions()) -> ProtocolResult:
    """Quasi-static plate indentation from first touch to ``depth_mm``."""
    t0, it0 = time.perf_counter(), body.newton_iterations
    top = body.top_height()
    duration = opts.depth_mm / opts.speed_mm_per_s
    times = body.t + duration * np.arange(1, opts.steps + 1) / opts.steps
    t_start = body.t
    scale = body.disc.force_scale(opts.length_mm)

    def position(t: float) -> Control:
        return Control.position(top - opts.speed_mm_per_s * (t - t_start))

    rec = _Recorder(body, top, lambda f: f * scale)
    last = times[-1] - 1e-9 * max(1.0, abs(times[-1]))

    def record(t: float) -> None:
        rec.record(t, peak=t >= last)  # the last step: the peak load

    steps = _march(body, times, position, "plate", record)
    rec_d, rec_f = rec.disp, rec.force
    reached = rec_d[-1] >= 1.0 - 1e-9  # the metric is defined only if the plate gets to 1 mm
    metrics = {
        "plate_force_at_1mm_N": float(np.interp(1.0, rec_d, rec_f)) if reached else float("nan")
    }
    curves = {"plate": {"displacement_mm": rec_d, "force_N": rec_f}}
    return _result("plate", body, t0, it0, steps, metrics, curves, rec.info())


# ---------------------------------------------------------------------------- wedge
def surface_profile(body: Body, tip_half_width_mm: float, length_mm: float, n: int) -> dict:
    """Surface deflection vs horizontal distance from the wedge's corner.

    The deflection is the downward displacement of the surface's material points (-u_y, mm),
    plotted at their deformed horizontal distance from the corner of the wedge's tip, sampled at
    ``n`` points over ``length_mm`` (as far as the surface reaches). Unlike the gap between two
    outlines at equal x, this stays well defined where the surface turns steep near the base.
    The surface is the section's in 2D; in 3D the curve on x = 0, along the finger (normal to
    the wedge's edge, which runs across the pad).
    """
    s, axis = body.disc.section_curves()[0]
    x_def = body.disc.X[s, axis] + body.u[s, axis] - tip_half_width_mm
    defl = -body.u[s, 1]
    order = np.argsort(x_def)
    dist = np.linspace(0.0, length_mm, n)
    dist = dist[dist <= x_def.max()]
    return {
        "distance_mm": dist.tolist(),
        "deflection_mm": np.interp(dist, x_def[order], defl[order]).tolist(),
    }


def profile_summary(curves: dict) -> dict[str, float]:
    """Compact descriptors of the wedge's surface-deflection profiles (at 1 s and 100 s):
    ``profile_<t>_area_2mm_mm2``, the area under the deflection profile from the wedge corner
    to 2 mm (how much and how widely the surface wraps the wedge; an integral, so it converges
    with the mesh like the metrics do), and ``profile_<t>_defl_at_1mm_mm``, the deflection 1 mm
    from the corner. NaN when absent."""
    out = {}
    for t in ("1s", "100s"):
        prof = curves.get(f"profile_{t}")
        area, at1 = float("nan"), float("nan")
        if prof and len(prof["distance_mm"]) > 1:
            d = np.asarray(prof["distance_mm"])
            y = np.asarray(prof["deflection_mm"])
            if d[-1] >= 2.0:
                grid = np.linspace(0.0, 2.0, 201)
                area = float(np.trapezoid(np.interp(grid, d, y), grid))
            if d[-1] >= 1.0:
                at1 = float(np.interp(1.0, d, y))
        out[f"profile_{t}_area_2mm_mm2"] = area
        out[f"profile_{t}_defl_at_1mm_mm"] = at1
    return out


def run_wedge(body: Body, opts: WedgeOptions = WedgeOptions()) -> ProtocolResult:
    """Wedge ramp to ``depth_mm`` in ``ramp_s`` and hold for ``hold_s``."""
    t0, it0 = time.perf_counter(), body.newton_iterations
    if not isinstance(body.indenter, Wedge):
        raise ValueError("wedge protocol needs a Wedge indenter")
    top = body.top_height()
    t_start = body.t
    scale = body.disc.force_scale(opts.length_mm)
    ramp = t_start + opts.ramp_s * np.arange(1, opts.ramp_steps + 1) / opts.ramp_steps
    # hold: geometric steps from 1 % of the ramp time, hitting t = 100 s exactly
    t_prof = 100.0 if opts.ramp_s < 100.0 < opts.ramp_s + opts.hold_s else opts.ramp_s + opts.hold_s
    geo = np.geomspace(0.01 * opts.ramp_s, opts.hold_s, opts.hold_steps)
    hold = np.unique(np.concatenate([opts.ramp_s + geo, [t_prof, opts.ramp_s + opts.hold_s]]))
    hold = t_start + hold[hold > opts.ramp_s]
    profiles: dict[str, dict] = {}
    snapshots = [("profile_1s", opts.ramp_s)] + (
        [("profile_100s", 100.0)] if t_prof == 100.0 else []
    )

    def position(t: float) -> Control:
        frac = min(1.0, (t - t_start) / opts.ramp_s)
        return Control.position(top - opts.depth_mm * frac)

    rec = _Recorder(body, top, lambda f: f * scale)

    def record(t: float) -> None:
        rec.record(t, peak=abs(t - t_start - opts.ramp_s) < 1e-9)  # the deepest indentation
        for label, when in snapshots:
            if abs(t - t_start - when) < 1e-9:
                profiles[label] = surface_profile(
                    body, 0.5 * opts.tip_width_mm, opts.profile_length_mm, opts.profile_points
                )

    growth = WEDGE_STEP_GROWTH[body.disc.dim]
    travel = opts.depth_mm / opts.ramp_steps  # the edge's travel in a step of the ramp
    band = WEDGE_BAND_TRAVEL * body.disc.band_h_mm  # 0 without a band (2D: none)
    ramp_growth = replace(growth, largest=min(1.0, band / travel)) if band > 0.0 else growth
    steps = _march(body, ramp, position, "wedge", record, growth=ramp_growth)
    steps += _march(body, hold, position, "wedge", record, growth=growth)
    rec_t, rec_f = rec.t, rec.force
    rec_t_arr = np.array(rec_t)
    metrics = {
        "wedge_peak_force_N": float(np.max(rec_f)),
        "wedge_force_at_100s_N": (
            float(np.interp(100.0, rec_t_arr, rec_f)) if rec_t_arr[-1] >= 100.0 else float("nan")
        ),
    }
    curves = {"wedge": {"time_s": rec_t, "force_N": rec_f}, **profiles}
    metrics.update(profile_summary(curves))
    return _result("wedge", body, t0, it0, steps, metrics, curves, rec.info())


# ---------------------------------------------------------------------------- registry
@dataclass(frozen=True)
class Protocol:
    """One protocol: its indenter, made from the protocol's options, and its runner."""

    name: str
    make_indenter: Callable[[Any], Plate | Wedge]
    run: Callable[[Body, Any], ProtocolResult]


def _plate(opts: TappingOptions | PlateOptions) -> Plate:
    return Plate()


def _wedge(opts: WedgeOptions) -> Wedge:
    return Wedge(opts.tip_width_mm, opts.half_angle_deg)


#: Protocol name -> its registry entry (the names and order of ``sim.metrics.PROTOCOLS``).
REGISTRY: dict[str, Protocol] = {
    p.name: p
    for p in (
        Protocol("tapping", _plate, run_tapping),
        Protocol("plate", _plate, run_plate),
        Protocol("wedge", _wedge, run_wedge),
    )
}
