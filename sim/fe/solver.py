"""Newton solver with penalty contact, displacement or force control, and step cutting.

A ``Body`` holds the discretisation, the committed state (displacements, material history, time)
and the contact obstacles. ``Body.advance`` takes one time step to ``t_new`` under a given control:

- ``Control.position(d)``: the indenter's lowest point is at height ``d`` (mm);
- ``Control.force(F)``: the indenter (a plate) carries the force ``F`` per unit thickness of the
  half model (N/mm); its position is an extra unknown, solved for with a bordered (Schur
  complement) Newton system that reuses the one factorisation for both right-hand sides;
- ``Control.free()``: no indenter (lifted off), the body relaxes.

The LDL^T factorisation (``sim.fe._linear``: qdldl for the 2D systems, PARDISO for the large 3D
ones) keeps its symbolic analysis across all iterations and steps because the sparsity pattern
never changes. Failed steps are cut by the caller
(``sim.protocols.loading``), never here.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from .contact import Base
from .fe2d import Discretization, LayerState

if TYPE_CHECKING:
    from ..materials import Material

_log = logging.getLogger(__name__)
TIMED = ("residual+material", "tangent assembly", "LDL^T factorisation", "triangular solves")
__all__ = [
    "FORCE_RTOL",
    "Body",
    "Control",
    "NewtonOptions",
    "StepResult",
    "model_newton",
    "residual_tolerance",
    "youngs_moduli",
]


@dataclass(frozen=True)
class Control:
    """How the indenter is driven during a step (see module docstring)."""

    kind: str  # "position" | "force" | "free"
    value: float = 0.0

    @staticmethod
    def position(d_mm: float) -> Control:
        return Control("position", float(d_mm))

    @staticmethod
    def force(f_N_per_mm: float) -> Control:
        return Control("force", float(f_N_per_mm))

    @staticmethod
    def free() -> Control:
        return Control("free")


#: a force-controlled step matches its applied force to this fraction of it (or to the round-off
#: floor of the contact force, ``Body.force_floor``, if larger)
FORCE_RTOL = 1e-6


def youngs_moduli(materials: Sequence[Material]) -> list[float]:
    """Each material's instantaneous small-strain Young's modulus 2 mu0 (1 + nu) (MPa); the
    largest sets the scale of Newton's residual tolerance (``Body.atol``)."""
    return [
        2.0 * m.instantaneous.initial_shear_modulus_MPa * (1.0 + m.instantaneous.nu)
        for m in materials
    ]


def residual_tolerance(rtol: float, e0_MPa: float, size_mm: float, dim: int) -> float:
    """Newton's tolerance on every nodal force (``Body.atol``): ``rtol`` x E0 x size, in N/mm
    in 2D (a force per unit thickness) and x 1 mm, in N, in 3D.

    So a 3D node is held to the tolerance of a 2D node on a slice 1 mm thick. A tolerance of
    ``rtol`` E0 size^2 (the same stress on a whole face) was 10x looser: on a tapping of the
    coarse pad (5 400 dofs) the Prony state's tap-to-tap residual then stalled at 3e-3 to 7e-3
    from the fourth tap on (its tolerance: 1e-3), 16 taps without settling, where this one
    settles in 6 with metrics within 3e-4 of a tolerance 100x tighter (docs/fe_speed.md, "3D")."""
    slice_mm = 1.0  # the 2D model's forces are those of a slice of unit thickness
    return rtol * e0_MPa * size_mm * slice_mm ** (dim - 2)


@dataclass(frozen=True)
class NewtonOptions:
    max_iterations: int = 20
    line_search_eta: float = 0.8  # accept when |g(alpha)| <= eta |g(0)|
    min_step: float = 1e-3  # a line search ending below this fraction of the step fails
    rtol: float = 1e-6  # residual tolerance relative to E0 * a (N/mm)
    max_backtracks: int = 10
    # A step whose residual has not halved over the last `stall_window` iterations (judged from
    # iteration `stall_from` on) is abandoned, and the caller cuts it. On default-space designs
    # about a third of all factorisations went into steps that then failed at `max_iterations`,
    # creeping down between jumps as surface nodes enter and leave contact. (6, 8) saved 14-27 %
    # of the factorisations and 29-38 % of the residual evaluations on three samples; (4, 6)
    # cost more than it saved (docs/fe_speed.md, "Newton"; studies/newton_study.py).
    # 0: never abandon a step for stalling (``_stalled``).
    stall_window: int = 6
    stall_from: int = 8
    stall_reduction: float = 0.5
    # The 3D model's rule for a stalled step (``STALL_RULES``; the 2D model's is "halving",
    # the rule above). "stagnation" since solver 2.20: the last stall_window + 1 residuals
    # within a factor 1 / stall_reduction of each other, or not reduced by stall_reduction over
    # 2 stall_window iterations. In 3D (modified Newton, the contact set's corrected solves)
    # a step's residual often rises for a few iterations while the contact set settles and
    # then falls to convergence; "halving" abandoned such steps, and where their halves did
    # the same down to 1e-4 s the design failed (docs/fe_speed.md, "The stall rule in 3D";
    # studies/stall_rule3d.py). "off": pursue every step to max_iterations.
    stall_rule_3d: str = "stagnation"
    # plate and base penalty per unit area: kappa = penalty_per_mm * E0_max (N/mm^3), so the
    # penetration is the contact pressure / kappa, about 1e-4 of a strain-level pressure in mm
    penalty_per_mm: float = 3000.0
    # Modified Newton: keep the last factorisation (within a step and into the next) while
    # the residual falls at least by `reuse_ratio` per iteration, and factorise afresh where it
    # does not or where a step with the kept one fails its line search. Off by default: the 2D
    # systems factorise in milliseconds, and the 2D records were made with full Newton (with the
    # 3D model's options the 2D model took 4.49 s a design against full Newton's 3.70, fewer
    # factorisations but more iterations and solves: docs/fe_speed.md, "Modified Newton in
    # 2D?"). On for 3D, where a factorisation costs as much as a few residual evaluations.
    reuse_factorization: bool = False
    # 0.5: keep the factorisation while the residual at least halves an iteration. 0.25 (until
    # solver 2.12, chosen on a plate press before the contact corrections and the wedge's band)
    # threw away factorisations that still converged: on the banded 3D wedge the iteration after
    # a fresh one often barely moves the residual (a ratio near 0.9) and is refactorised at any
    # ratio, but one that halves it is worth keeping. On five pads (studies/reuse_ratio3d.py)
    # 0.5 made 25 % fewer factorisations than 0.25 and was faster on four of them; 0.75 made
    # fewer still but took up to twice the Newton iterations of a creeping pad's tapping and was
    # slower on the viscoelastic pads (docs/fe_speed.md, "The 3D model's kept factorisation")
    reuse_ratio: float = 0.5
    # With reuse: a kept factorisation also serves where the contact set has changed since it
    # was made, corrected exactly for the change of the contact's stiffness (a few surface
    # nodes' blocks: Woodbury's identity, ``_ContactCorrected``), from a step's first iteration
    # on; at most `contact_update_dofs` changed dofs, else a fresh factorisation.
    contact_update: bool = False
    # 32: the update costs one solve with s right-hand sides (s changed dofs); a fresh
    # refactorisation of the pad's tangent costs about 23 solves (81.7 against 3.6 ms, quiet:
    # docs/fe_speed.md, PARDISO's ordering), more with its assembly. With the active-set solves
    # below, which change dozens of the rim's dofs at once, a bound of 96 spent more in solves
    # than it saved (docs/fe_speed.md, "Newton's step for the contact set it leads to"):
    # soft_fast 42.7 s against 37.1 s with 32, quiet
    contact_update_dofs: int = 32
    # With contact_update: solve each Newton step again for the contact set the step itself
    # leads to, at most this many times (``Body._settle_active_set``); 0: never. Off in 2D (its
    # records were made without), on in 3D (``model_newton``).
    active_set_solves: int = 0

    def __post_init__(self) -> None:
        if self.stall_rule_3d not in STALL_RULES:
            rules = ", ".join(STALL_RULES)
            raise ValueError(f"the stall rule must be one of {rules}, got {self.stall_rule_3d!r}")


def model_newton(options: NewtonOptions, dim: int) -> NewtonOptions:
    """Newton as a model of ``dim`` dimensions runs it: in 3D, where a factorisation costs as
    much as a few residual evaluations, modified Newton kept across changes of the contact set
    (``reuse_factorization``, ``contact_update``; docs/fe_speed.md, "Contact update"); the 2D
    model runs full Newton (its records were made so). Each model's stall rule: ``_stalled``."""
    if dim == 3:
        return replace(options, reuse_factorization=True, contact_update=True, active_set_solves=4)
    return options


@dataclass(frozen=True)
class StepResult:
    converged: bool
    iterations: int
    reason: str = ""


def _model_root(
    g_contact: Callable[[float], float], a_lo: float, gb_lo: float, a_hi: float, gb_hi: float
) -> float:
    """The next trial of the line search: the root in [a_lo, a_hi] of the model
    g(a) ~ (the body's part, linear between its values at a_lo and a_hi) + g_contact(a) (exact).
    The model equals g at both ends (g < 0 at a_lo, > 0 at a_hi), so the root is bracketed;
    found by bisection to 1/4096 of the bracket (a dozen cheap evaluations of the contacts'
    part, far finer than the acceptance |g| <= eta |g0| needs; scipy.optimize would load
    scipy.sparse.linalg into every simulation) and kept 1 % of the bracket away from either
    end, where g is already known, so that every trial learns something new."""
    width = a_hi - a_lo

    def model(a: float) -> float:
        return gb_lo + (gb_hi - gb_lo) * (a - a_lo) / width + g_contact(a)

    lo, hi = a_lo + 0.01 * width, a_hi - 0.01 * width
    if model(lo) >= 0.0:
        return lo
    if model(hi) <= 0.0:
        return hi
    for _ in range(12):
        mid = 0.5 * (lo + hi)
        if model(mid) < 0.0:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def _penalty_factors(p: np.ndarray, curv: np.ndarray | None, k: np.ndarray):
    """The penalty stiffness's factors per surface node (``Body._penalty_stiffness``): kappa
    where the node touches or lies on the obstacle (else 0), and c = p / rho where it is inside
    a rounded one (0 on a flat one)."""
    ka = np.where(p >= 0, k, 0.0)
    c = 0.0 if curv is None else np.where(p > 0, p * curv, 0.0)
    return ka, c


def _not_halved(norms: list[float], window: int, start: int, reduction: float) -> bool:
    """The residual has not fallen by ``reduction`` over the last ``window`` iterations,
    judged from iteration ``start`` on."""
    return len(norms) >= max(start, window + 1) and norms[-1] > reduction * norms[-1 - window]


def _halving(norms: list[float], opts: NewtonOptions) -> bool:
    """Not halved (``stall_reduction``) over ``stall_window`` iterations, judged from iteration
    ``stall_from`` on (the 2D model's rule since solver 2.2, the 3D model's until 2.19)."""
    return _not_halved(norms, opts.stall_window, opts.stall_from, opts.stall_reduction)


def _stagnation(norms: list[float], opts: NewtonOptions) -> bool:
    """The 3D model's rule since solver 2.20: the last ``stall_window`` + 1 residuals lie within
    a factor 1 / ``stall_reduction`` of each other (judged from ``stall_from`` on: the residual
    has stopped moving), or it has not fallen by ``stall_reduction`` over 2 ``stall_window``
    iterations (judged from ``stall_from`` + ``stall_window`` on: it moves, but too slowly to
    converge within ``max_iterations``). A residual that rises for a few iterations while the
    contact set settles, then falls, is pursued."""
    k = opts.stall_window
    if len(norms) >= max(opts.stall_from, k + 1):
        last = norms[-1 - k :]
        if max(last) * opts.stall_reduction < min(last):
            return True
    return _not_halved(norms, 2 * k, opts.stall_from + k, opts.stall_reduction)


#: The stall rules by name (``NewtonOptions.stall_rule_3d``): whether Newton abandons a step
#: with the residuals ``norms`` so far (one per iteration), for the protocol to cut it.
STALL_RULES: dict[str, Callable[[list[float], NewtonOptions], bool]] = {
    "halving": _halving,
    "stagnation": _stagnation,
    "off": lambda norms, opts: False,
}


def _stalled(norms: list[float], opts: NewtonOptions, dim: int = 2) -> bool:
    """True when the step is better cut than pursued: by ``_halving`` in 2D, by
    ``opts.stall_rule_3d`` in 3D; never with ``stall_window`` 0."""
    if opts.stall_window <= 0:
        return False
    rule = STALL_RULES["halving" if dim == 2 else opts.stall_rule_3d]
    return rule(norms, opts)


class Body:
    """A meshed fingertip with its materials, contact obstacles and committed state."""

    def __init__(
        self,
        disc: Discretization,
        indenter=None,
        options: NewtonOptions = NewtonOptions(),
        indenter_penalty_per_mm: float | None = None,
    ) -> None:
        self.disc = disc
        self.indenter = indenter
        self.options = options
        self.base = Base()
        moduli = youngs_moduli(disc.materials)
        e0 = max(moduli)
        self.E0_MPa = e0
        # the penalty follows the outermost layer, the one in contact: a soft skin on a stiff
        # core would otherwise see a penalty orders of magnitude stiffer than itself
        self.kappa = options.penalty_per_mm * moduli[0]
        size = float(np.max(disc.X))
        self.atol = residual_tolerance(options.rtol, e0, size, disc.dim)
        s = disc.surface_nodes
        self.kappa_nodes = self.kappa * disc.surface_weights()
        factor = indenter_penalty_per_mm or options.penalty_per_mm
        self.kappa_indenter = self.kappa_nodes * (factor / options.penalty_per_mm)
        # round-off floor of the indenter force (N/mm): penetrations are differences of
        # coordinates of size ~size, each good to ~eps size, times the summed penalty
        self.force_floor = 64.0 * np.finfo(float).eps * float(np.sum(self.kappa_indenter)) * size
        dim = disc.dim
        self._sdof = tuple(disc.gmap[dim * s + i] for i in range(dim))  # dofs of each component
        # each component's surface nodes with a free dof, and those dofs: the contact's forces
        # go there at every evaluation
        self._sfree = tuple((dofs >= 0, dofs[dofs >= 0]) for dofs in self._sdof)
        pos = disc.pattern_position
        # the positions in the tangent's data of each surface node's entry (i, j), where both
        # dofs are free, and the nodes that have them
        self._kfree = {}
        for i in range(dim):
            for j in range(dim):
                at = pos(self._sdof[i], self._sdof[j])
                self._kfree[i, j] = (at >= 0, at[at >= 0])
        # every obstacle is a cylinder normal to the plane of the coordinates ``obstacle_axes``
        # (2D: the section; 3D: y-z, the wedge's edge across the pad): the curvature of a
        # rounded obstacle (the wedge's tip) lies in that plane
        self._axes = tuple(disc.obstacle_axes)
        self._surface_plane = np.ix_(s, list(self._axes))  # the surface's plane coordinates
        self._surface_X = disc.X[self._surface_plane]
        self._inplane = np.zeros(dim)
        self._inplane[list(self._axes)] = 1.0
        # the indenter's outward direction e in the body's space (from the body into the
        # indenter): its force, position and the body's top are measured along it. Vertical
        # (y) but for an inclined plate (``Plate.axis``); the vertical keeps the y-only code
        self.indenter_axis = np.zeros(dim)
        self.indenter_axis[1] = 1.0
        axis = getattr(indenter, "axis", None)
        if axis is not None:
            self.indenter_axis = np.zeros(dim)
            self.indenter_axis[list(self._axes)] = axis
        self.vertical_indenter = bool(
            self.indenter_axis[1] == 1.0 and np.count_nonzero(self.indenter_axis) == 1
        )
        # committed state
        self.u = np.zeros((disc.n_nodes, dim))
        self.states: list[LayerState] = disc.initial_states()
        self.t = 0.0
        self.indenter_position = np.inf
        #: the sparse direct solvers by name (``sim.fe._linear.LinearSolver``), each made at
        #: its first factorisation and kept (its symbolic analysis with it)
        self._solvers: dict[str, Any] = {}
        self._solver = None  # what solves with the kept factorisation (a solver or a slot's view)
        self._serial = 0  # the kept factorisation's number (``factorizations`` when it was made)
        self._stale = False  # the kept factorisation failed a line search: factorise afresh
        self._factored_active: np.ndarray | None = None  # the indenter's contact at that time
        self._factored_blocks: np.ndarray | None = None  # the contact's stiffness at that time
        self._corrected = None  # (key, _ContactCorrected) of the last contact update
        self._kept_columns = _KeptColumns()  # of the kept factorisation (contact updates)
        self._x2 = None  # (key, solution, solver) of the last bordered column (force control)
        #: the sparse direct solver by name (``sim.fe._linear.SOLVERS``); None: by the size
        self.linear_solver: str | None = None
        #: with ``linear_solver`` None: PARDISO may factorise in single precision
        #: (``sim.fe._linear.default_solver``); set per protocol by ``sim.simulate``
        self.single_precision = False
        #: steps tried again in double precision after a failed attempt whose single-precision
        #: factorisation solved its tangent worse than ``INEXACT_SOLVE_RTOL`` (``advance``)
        self.precision_fallbacks = 0
        #: steps tried again from a fresh factorisation in the same precision (``advance``)
        self.fresh_retries = 0
        self._last_factored: tuple[Any, np.ndarray] | None = None  # ``last_factor_residual``
        self._began_fresh = False  # the last attempt's first direction was a fresh factorisation's
        #: (``linear_solver``,) to go back to after a fallback (``advance``); None: not in one
        self._own_solver: tuple[str | None] | None = None
        self._factored_by: str | None = None  # ``solver_name``
        #: factorisations kept at once, one per step of a tap (``advance``'s ``factor_key``),
        #: beside the shared one; 0: none. Set by the tapping protocol (``sim.protocols``)
        self.step_factors = 0
        #: the resident memory those may take at most (MB); the count is cut to fit
        self.step_factors_MB = STEP_FACTORS_MB
        self._step_factors: dict[Any, _StepFactor] = {}  # by ``factor_key``
        self._key: Any = None  # the ``factor_key`` of the step being advanced
        #: steps that began with the factorisation made at their key in an earlier tap
        self.step_factor_takes = 0
        self.timings: dict[str, float] = dict.fromkeys(TIMED, 0.0)
        self._last = None  # (kind, previous value, value, du, dd) of the last committed step
        self._last_control: Control | None = None
        self.force = 0.0
        #: (protocol name, ``ValidityOptions``): the protocol's recorder stops the run at its
        #: first recorded step beyond these limits (``sim.protocols.validity.ValidityStop``);
        #: None: never. Set by ``sim.simulate`` when ``validity.stop_at_violation``.
        self.stop_beyond: tuple[str, Any] | None = None
        self.newton_iterations = 0
        self.factorizations = 0
        self.evaluations = 0  # residual evaluations, line-search trials included

    # ------------------------------------------------------------------ contact
    def plane_coordinates(
        self, u: np.ndarray | None = None, nodes: np.ndarray | None = None
    ) -> np.ndarray:
        """The deformed (horizontal, vertical) coordinates of ``nodes`` (default: the surface
        nodes) in the obstacles' plane (``obstacle_axes``), (m, 2): what the obstacles see."""
        u = self.u if u is None else u
        if nodes is None:
            return self._surface_X + u[self._surface_plane]
        at = np.ix_(nodes, list(self._axes))
        return self.disc.X[at] + u[at]

    def indenter_penetration(self, nodes: np.ndarray | None = None) -> np.ndarray:
        """The indenter's penetration (mm, > 0 inside) at ``nodes`` (default: the surface
        nodes) in the committed state; zeros when it is lifted off."""
        xy = self.plane_coordinates(nodes=nodes)
        if self.indenter is None or not np.isfinite(self.indenter_position):
            return np.zeros(len(xy))
        return self.indenter.penetration(xy, self.indenter_position)[0]

    def along_indenter(self, v: np.ndarray) -> np.ndarray:
        """The components (m,) of the vectors ``v`` (m, dim) along the indenter's direction e
        (``indenter_axis``): ``v[:, 1]`` for a vertical one."""
        return v[:, 1] if self.vertical_indenter else v @ self.indenter_axis

    def _contact(self, u: np.ndarray, control: Control, d: float):
        """(penetration, normal, curvature, is_indenter) per obstacle at the surface nodes."""
        return self._contact_at(self.plane_coordinates(u), control, d)

    def _contact_at(self, xy: np.ndarray, control: Control, d: float):
        """``_contact`` from the surface nodes' coordinates in the obstacles' plane."""
        p_b, n_b = self.base.penetration(xy)
        parts = [(p_b, self._full_normal(n_b), None, False)]
        if control.kind != "free" and self.indenter is not None:
            if hasattr(self.indenter, "penetration_curvature"):
                p_i, n_i, k_i = self.indenter.penetration_curvature(xy, d)
            else:
                (p_i, n_i), k_i = self.indenter.penetration(xy, d), None
            parts.append((p_i, self._full_normal(n_i), k_i, True))
        return parts

    def _full_normal(self, n: np.ndarray) -> np.ndarray:
        """An obstacle's normal in its plane (m, 2) as a normal in the body's space (m, dim)."""
        if self.disc.dim == 2:
            return n
        out = np.zeros((len(n), self.disc.dim))
        out[:, list(self._axes)] = n
        return out

    def base_contact_nodes(self) -> int:
        """Number of surface nodes resting on the rigid base beside the bone (committed state)."""
        return int(np.sum(self.base.penetration(self.plane_coordinates())[0] > 0))

    def max_penetration(self) -> float:
        """Deepest penetration of the indenter into the committed surface (mm); 0 if none."""
        return float(max(0.0, self.indenter_penetration().max(initial=0.0)))

    def _add_contact(
        self, r: np.ndarray | None, data: np.ndarray | None, parts
    ) -> tuple[float, np.ndarray]:
        """Add penalty forces to r and stiffness to data; return indenter force and coupling
        (``r`` None: the stiffness alone, as a factorisation's tangent asks for it).

        The force on node i is f = kappa_i p n; its derivative is
        kappa_i (n n^T - p * curvature * (I - n n^T)), curvature = 1/rho on a rounded surface.
        """
        force = 0.0
        coupling = np.zeros(len(self.kappa_nodes))
        for p, n, curv, is_indenter in parts:
            k = self.kappa_indenter if is_indenter else self.kappa_nodes
            if not np.any(p >= 0):
                continue
            # every surface node has its own dofs and matrix entries: plain indexed updates
            if data is not None:
                ka, c = _penalty_factors(p, curv, k)
                for (i, j), (ok, at) in self._kfree.items():
                    data[at] += self._penalty_entry(ka, c, n, i, j)[ok]
            if r is None:
                continue
            act = p > 0
            f = np.where(act, k * p, 0.0)  # pushes the node along n
            for i, (ok, dofs) in enumerate(self._sfree):
                r[dofs] -= (f * n[:, i])[ok]
            if is_indenter:
                # the force on the indenter along its direction e (up > 0)
                force = float(np.sum(-f * self.along_indenter(n)))
                coupling = np.where(act, k, 0.0)
        return force, coupling

    def _penalty_stiffness(self, p, n, curv, k, i: int, j: int) -> np.ndarray:
        """Entry (i, j) of each surface node's penalty stiffness against one obstacle:
        ``kappa (n n^T - c (P - n n^T))``, ``c = p / rho`` on a rounded surface, P the projector
        on the curvature's plane. A node exactly on the obstacle (p = 0: a surface node lying on
        the base in the reference state) is stiff too, so that Newton's step does not push it
        in unopposed (the generalised derivative of the penalty's kink from that side)."""
        return self._penalty_entry(*_penalty_factors(p, curv, k), n, i, j)

    def _penalty_entry(self, ka, c, n, i: int, j: int) -> np.ndarray:
        """``_penalty_stiffness`` from its factors ``_penalty_factors(p, curv, k)``."""
        nn = n[:, i] * n[:, j]
        return ka * (nn - c * (self._inplane[i] * (i == j) - nn))

    def _contact_blocks(self, parts) -> np.ndarray:
        """The contact's stiffness per surface node, (m, dim, dim): what ``_add_contact`` adds
        to the tangent at the contact state ``parts`` (``_contact``)."""
        dim = self.disc.dim
        out = np.zeros((len(self.kappa_nodes), dim, dim))
        for p, n, curv, is_indenter in parts:
            if not np.any(p >= 0):
                continue
            k = self.kappa_indenter if is_indenter else self.kappa_nodes
            for i in range(dim):
                for j in range(dim):
                    out[:, i, j] += self._penalty_stiffness(p, n, curv, k, i, j)
        return out

    def _contact_corrected(self, parts) -> _ContactCorrected | None:
        """The kept factorisation corrected for the contact's stiffness that changed since it
        was made (``NewtonOptions.contact_update``); None if more than
        ``contact_update_dofs`` free dofs changed (then a fresh factorisation is cheaper)."""
        return self._corrected_for(self._contact_blocks(parts))

    def _corrected_for(self, blocks: np.ndarray) -> _ContactCorrected | None:
        """The kept factorisation corrected to hold the contact blocks ``blocks`` (m, dim, dim)
        instead of those it was made with; None as in ``_contact_corrected``."""
        changed = np.flatnonzero(np.any(blocks != self._factored_blocks, axis=(1, 2)))
        dim = self.disc.dim
        dofs = np.stack([self._sdof[i][changed] for i in range(dim)], axis=1).ravel()
        D = np.zeros((len(dofs), len(dofs)))  # block diagonal: one block per changed node
        at = np.arange(len(changed))[:, None] * dim + np.arange(dim)  # (c, dim)
        D[at[:, :, None], at[:, None, :]] = blocks[changed] - self._factored_blocks[changed]
        # only the free dofs the change touches (a flat plate's: the normal one of each node)
        keep = (dofs >= 0) & (np.any(D != 0.0, axis=0) | np.any(D != 0.0, axis=1))
        dofs, D = dofs[keep], D[np.ix_(keep, keep)]
        if len(dofs) > self.options.contact_update_dofs:
            return None
        key = (self._serial, dofs.tobytes(), D.tobytes())
        if self._corrected is not None and self._corrected[0] == key:
            return self._corrected[1]  # the same change as the last iteration's: kept
        t0 = time.perf_counter()
        out = _ContactCorrected(self._solver, dofs, D, self.disc.n_free, self._kept_columns)
        self.timings["triangular solves"] += time.perf_counter() - t0
        out = out if out.ok else None
        self._corrected = (key, out)
        return out

    def _surface_step(self, du: np.ndarray) -> np.ndarray:
        """The surface nodes' part (m, dim) of ``du`` on the free dofs (0 on a fixed dof)."""
        step = np.zeros((len(self.kappa_nodes), self.disc.dim))
        for i, dofs in enumerate(self._sdof):
            ok = dofs >= 0
            step[ok, i] = du[dofs[ok]]
        return step

    def _newton_step(self, solver, r, rd, coupling, control) -> tuple[np.ndarray, float]:
        """Newton's direction ``K du = -r``; under force control bordered by the plate's force
        balance ``rd`` (its position's change ``dd`` an unknown, tied to the nodes it touches
        by their ``coupling``)."""
        with np.errstate(all="ignore"):  # a singular tangent is caught by the caller
            du = solver.solve(-r)
            dd = 0.0
            if control.kind == "force":
                # d(residual)/d(position) = -kappa_i e at the nodes in contact (p = e.x - d)
                kcol = np.zeros(self.disc.n_free)
                for i, dofs in enumerate(self._sdof):
                    if self.indenter_axis[i] == 0.0:
                        continue
                    ok = dofs >= 0  # x 1.0 is exact: a vertical indenter's bits as before
                    kcol[dofs[ok]] = -coupling[ok] * self.indenter_axis[i]
                x2 = self._bordered_column(solver, kcol)
                c = float(np.sum(coupling))
                dd = (-rd - kcol @ du) / (c - kcol @ x2)
                du = du - x2 * dd
        return du, dd

    def _settle_active_set(
        self,
        parts,
        data: Callable,
        r: np.ndarray,
        rd: float,
        control: Control,
        du: np.ndarray,
        dd: float,
    ) -> tuple[np.ndarray, float, float] | None:
        """Newton's direction for the contact set that the direction itself leads to
        (``NewtonOptions.active_set_solves``).

        The tangent holds the penalty of the nodes in contact now. A node that Newton's step
        moves into an obstacle is held by it only at the next iteration, after the step has
        driven it deep into the stiff penalty (and one the step pulls out is held back by it
        meanwhile): on the rim of the 3D plate's contact patch, dozens of nodes, Newton then
        chatters for several iterations, its residual jumping by 100x where a rim node went in.
        Instead the step is solved again for the contact set its linearised penetrations
        ``p - n . du + (n . e) dd`` give (e the indenter's direction, ``indenter_axis``): each
        node of that set under the linear penalty force ``kappa p`` (negative for one not yet
        in contact: it reaches the obstacle within the step), the others free; until the set
        repeats, at most ``active_set_solves`` times (the primal-dual active-set iteration on
        the linearised contact problem: Hintermüller, Ito & Kunisch 2002, SIAM J. Optim.
        13:865-888). Each solve is the kept factorisation
        corrected for that set (``_ContactCorrected``), or where that changes more than
        ``contact_update_dofs`` dofs a fresh factorisation of the tangent ``data`` with the
        set's contact stiffness (then kept), once per call at most: a set that is again beyond
        the bound keeps the last set's direction (on a default-space design whose rim moved
        by dozens of nodes an iteration, each of the four solves had factorised afresh: more
        factorisations than Newton iterations). Returns the direction, its
        indenter change and its slope ``g0`` on the true residual, or None where the set does
        not change, the correction is not possible or the direction does not descend."""
        force_control = control.kind == "force"
        masks = [p >= 0 for p, *_ in parts]  # the set the tangent holds
        out = None
        factorizations = self.factorizations
        for _ in range(self.options.active_set_solves):
            step = self._surface_step(du)
            new = []
            for p, n, _, is_indenter in parts:
                p_lin = p - np.einsum("ij,ij->i", n, step)
                if is_indenter and force_control:
                    p_lin = p_lin + self.along_indenter(n) * dd  # the indenter moves by dd e
                new.append(p_lin >= 0)
            if all(np.array_equal(a, b) for a, b in zip(new, masks, strict=True)):
                break
            masks = new
            # one fresh factorisation at most: a set that changes more than the correction's
            # bound again is left for the next iteration (the direction of the last set)
            may_factor = self.factorizations == factorizations
            solved = self._solve_for_set(parts, data, masks, r, control, may_factor)
            if solved is None:
                return out if not may_factor else None
            du, dd = solved
            if not (np.all(np.isfinite(du)) and np.isfinite(dd)):
                return None
            with np.errstate(all="ignore"):
                g0 = float(du @ r) + dd * rd
            out = (du, dd, g0) if np.isfinite(g0) and g0 < 0.0 else None
        return out

    def _solve_for_set(
        self,
        parts,
        data: Callable,
        masks: list[np.ndarray],
        r: np.ndarray,
        control: Control,
        may_factor: bool = True,
    ) -> tuple[np.ndarray, float] | None:
        """Newton's direction with each obstacle's contact set ``masks`` (``_settle_active_set``):
        the residual's and the tangent's contact parts replaced by the linear penalty on those
        nodes; None where the tangent ``data`` is not finite."""
        r2 = r.copy()
        force, coupling = 0.0, np.zeros(len(self.kappa_nodes))
        held_parts = []
        for (p, n, curv, is_indenter), m in zip(parts, masks, strict=True):
            k = self.kappa_indenter if is_indenter else self.kappa_nodes
            f = np.where(m, k * p, 0.0)  # the linear penalty on the set
            change = f - np.where(p > 0, k * p, 0.0)  # against the forces r holds
            for i, dofs in enumerate(self._sdof):
                ok = dofs >= 0
                r2[dofs[ok]] -= (change * n[:, i])[ok]
            # the penetrations as the penalty's stiffness sees them: in the set or not
            held_parts.append((np.where(m, np.maximum(p, 0.0), -1.0), n, curv, is_indenter))
            if is_indenter:
                force = float(np.sum(-f * self.along_indenter(n)))
                coupling = np.where(m, k, 0.0)
        blocks = self._contact_blocks(held_parts)
        solver = self._corrected_for(blocks)  # times its own solves
        if solver is None and not may_factor:
            return None
        if solver is None:  # too many changes to correct for: factorise with the set
            tangent = data(held_parts)
            if not np.all(np.isfinite(tangent)):
                return None
            solver = self._factor(tangent, coupling > 0, blocks)
        t0 = time.perf_counter()
        rd2 = control.value - force if control.kind == "force" else 0.0
        out = self._newton_step(solver, r2, rd2, coupling, control)
        self.timings["triangular solves"] += time.perf_counter() - t0
        return out

    def _bordered_column(self, solver, kcol: np.ndarray) -> np.ndarray:
        """``solver.solve(kcol)``, the force control's second right-hand side: kept while
        the factorisation (and its contact correction) and the plate's coupling are those of
        the last solve, where modified Newton gives the same system again."""
        key = (self._serial, id(solver), kcol.tobytes())
        if self._x2 is not None and self._x2[0] == key and self._x2[2] is solver:
            return self._x2[1]
        x2 = solver.solve(kcol)
        self._x2 = (key, x2, solver)
        return x2

    # ------------------------------------------------------------------ evaluation
    def _evaluate(self, u, control, d, dt, tangent, frozen=False):
        t0 = time.perf_counter()
        self.evaluations += 1
        ev = self.disc.evaluate(u, self.states, dt, tangent=tangent, frozen_history=frozen)
        self.timings["residual+material"] += time.perf_counter() - t0
        if not ev.ok:
            return None
        r = ev.residual.copy()
        parts = self._contact(u, control, d)
        force, coupling = self._add_contact(r, None, parts)
        rd = 0.0
        if control.kind == "force":
            rd = control.value - force
        data = None
        if tangent:

            def data(contact=parts) -> np.ndarray:  # assembled when a factorisation needs it
                t0 = time.perf_counter()
                out = ev.tangent()  # assembled for this factorisation only: add to it in place
                self._add_contact(None, out, contact)
                self.timings["tangent assembly"] += time.perf_counter() - t0
                return out

        return r, data, force, coupling, rd, ev.states, parts

    def _norm(self, r, rd):
        return max(float(np.max(np.abs(r))) if r.size else 0.0, abs(rd))

    def _may_reuse(self, norms: list[float], active: np.ndarray) -> bool:
        """Modified Newton (``NewtonOptions.reuse_factorization``): the factorisation made
        earlier may serve this iteration if the last iteration cut the residual by
        ``reuse_ratio`` and the indenter touches the same nodes (``active``) as when it was
        made. A step's first iteration factorises afresh unless the body is free of the
        indenter now and was then: the predictor moves the state, and a factorisation from
        before a change of the contact set misleads Newton, but a free body only relaxes (the
        rest between taps: its tangent changes with the material's history alone). A kept
        factorisation that fails the line search is replaced at once (``_stale``)."""
        opts = self.options
        if not opts.reuse_factorization or self._stale:
            self._stale = False
            return False
        if opts.contact_update:  # the contact's change is corrected for (_contact_corrected)
            kept = self._factored_blocks is not None
            return kept and (len(norms) < 2 or norms[-1] <= opts.reuse_ratio * norms[-2])
        same_contact = self._factored_active is not None and np.array_equal(
            active, self._factored_active
        )
        if len(norms) < 2:
            return same_contact and not np.any(active)
        return same_contact and norms[-1] <= opts.reuse_ratio * norms[-2]

    def _factor(self, data, active: np.ndarray, blocks: np.ndarray | None):
        """Factorise the tangent ``data`` made with the indenter's contact ``active`` and the
        contact's stiffness ``blocks`` (``_contact_blocks``; None without contact updates):
        the first time with the symbolic analysis, then numerically only (the pattern never
        changes), in the step's own slot where it has one (``_slot_for``); returns what solves
        with it (``.solve(b)``)."""
        t0 = time.perf_counter()
        name = self._solver_name()
        solver = self._solvers.get(name)
        first = solver is None
        if first:
            from ._linear import make_solver  # `import sim` stays light

            own = self.step_factors and self._own_solver is None  # not a fallback's
            solver = self._solvers[name] = make_solver(name, 1 + self.step_factors if own else 1)
        slot = solver.slot = self._slot_for(solver)
        if first:
            solver.factor(self.disc.upper_matrix(data))
        else:  # same pattern: new values, the symbolic analysis kept
            solver.refactor(data, self.disc.upper_data)
        self.factorizations += 1
        self._serial = self.factorizations
        self._solver = solver.view(slot)
        self._factored_by = name
        # an inexact solver's last factorisation and its tangent: ``last_factor_residual``
        self._last_factored = (self._solver, data) if solver.fallback is not None else None
        self._factored_active, self._factored_blocks = active, blocks
        self._kept_columns.clear()  # the columns of the factorisation replaced or left
        self._kept_columns = _KeptColumns()
        if slot > 1:
            self._step_factors[self._key] = _StepFactor(
                self._serial, self._solver, active, blocks, self._kept_columns
            )
        self.timings["LDL^T factorisation"] += time.perf_counter() - t0
        return self._solver

    def _solver_name(self) -> str:
        """The linear solver this body factorises with now (``linear_solver`` or by size)."""
        from ._linear import default_solver  # `import sim` stays light

        if self.linear_solver:
            return self.linear_solver
        return default_solver(self.disc.n_free, self.disc.dim, self.single_precision)

    def _slot_for(self, solver: Any) -> int:
        """The slot of ``solver`` for the factorisation to make now: the step's own
        (``factor_key``), one of ``step_factors`` while they fit in ``step_factors_MB``, else
        the shared slot 1. Only the body's own solver has step slots (not a precision
        fallback's, nor qdldl)."""
        if self._key is None or solver.slots == 1 or self._own_solver is not None:
            return 1
        kept = self._step_factors.get(self._key)
        if kept is not None:
            return kept.solver.slot
        used, limit = len(self._step_factors), solver.slots - 1
        per_slot = solver.slot_memory_MB()  # None before the first factorisation
        if per_slot:
            limit = min(limit, int(self.step_factors_MB // per_slot))
        return 2 + used if used < limit else 1

    def _take_step_factor(self) -> None:
        """Begin the step with the factorisation made during its key in an earlier tap, if
        there is one and the body's solver is its own: near the periodic state a tap repeats
        the last, and the same step's tangent of the last tap is closer to this step's than
        the previous step's of this tap (the load moves along the half-sine)."""
        kept = self._step_factors.get(self._key)
        if kept is None or kept.serial == self._serial or self._own_solver is not None:
            return
        self._kept_columns.clear()  # the factorisation left keeps no columns
        self._solver, self._serial = kept.solver, kept.serial
        self._factored_active, self._factored_blocks = kept.active, kept.blocks
        self._kept_columns = kept.columns
        self._factored_by = kept.solver.name
        self._stale = False
        self._corrected = self._x2 = None
        self.step_factor_takes += 1

    def top_height(self, u: np.ndarray | None = None) -> float:
        """Highest point of the current outer surface (mm) along the indenter's direction e:
        max e . x over the surface nodes (the height y for a vertical indenter). An indenter
        at this position just touches."""
        return float(np.max(self._surface_heights(u)))

    def _surface_heights(self, u: np.ndarray | None = None) -> np.ndarray:
        """e . x (m,) of the current surface nodes (``top_height``)."""
        u = self.u if u is None else u
        s = self.disc.surface_nodes
        if self.vertical_indenter:
            return self.disc.X[s, 1] + u[s, 1]
        return self.along_indenter(self.disc.X[s] + u[s])

    # ------------------------------------------------------------------ stepping
    def advance(
        self,
        t_new: float,
        control: Control,
        frozen_history: bool = False,
        guess: tuple[np.ndarray, float] | None = None,
        factor_key: Any = None,
    ) -> StepResult:
        """Solve the step to ``t_new``; commit the state only if Newton converges.

        ``guess``: a starting displacement and indenter position for Newton (for example the
        previous tap's increment at the same phase); by default the last increment is
        extrapolated (``_predict``). A position control keeps its prescribed position.

        ``factor_key``: the step of a schedule that repeats (a tap's loading step, with
        ``step_factors``): the step begins with the factorisation made during the same key
        before (``_take_step_factor``), and one it makes is kept in the key's own slot.

        A step that Newton fails with an inexact linear solver (single-precision PARDISO) is
        tried once more from a fresh factorisation (``_retry``): with that solver's
        ``fallback`` (double precision) where its last factorisation solves its own tangent
        worse than ``INEXACT_SOLVE_RTOL``, else with the same solver, unless the failed
        attempt already began with a fresh factorisation (the retry would repeat it bit for
        bit). The body keeps the retry's solver until a step converges with it (the step the
        protocol cuts after a failed retry, its halves, ...), then goes back to the body's own
        solver and its kept factorisations: most such failures are a step too large for any
        start (the wedge's first ramp step fails in double too), and one such step made the
        whole rest of the run double before solver 2.14. Until solver 2.16 every retry was in
        double precision; the directions of the failed attempts were as good as Newton needs
        (docs/fe_speed.md, "What rescues a failed 3D step")."""
        self._key = factor_key
        if factor_key is not None:
            self._take_step_factor()
        result = self._advance(t_new, control, frozen_history, guess)
        if not result.converged and self._retry():
            result = self._advance(t_new, control, frozen_history, guess)
        if result.converged and self._own_solver is not None:  # back to the body's own
            (self.linear_solver,) = self._own_solver
            self._own_solver = None
            self._forget_factorization()
        return result

    def _retry(self) -> bool:
        """After a failed attempt with an inexact solver: set the body up to try the step
        again from a fresh factorisation (``advance``); False where it would not."""
        fallback = getattr(self._solver, "fallback", None)
        if fallback is None:
            return False
        inexact = self.last_factor_residual() > INEXACT_SOLVE_RTOL
        if not inexact and self._began_fresh:
            return False
        if self._own_solver is None:
            self._own_solver = (self.linear_solver,)
        if inexact:
            self.linear_solver = fallback
            self.precision_fallbacks += 1
        else:  # the same solver (its shared slot), afresh
            self.linear_solver = self._solver_name()
            self.fresh_retries += 1
        self._forget_factorization()
        return True

    def last_factor_residual(self) -> float:
        """The relative residual ``|K x - b| / |b|`` of a solve with the last factorisation
        made by an inexact solver, on its own tangent ``K`` (in double precision) and a fixed
        random ``b``: in single precision on the 3D pads mostly 1e-4-1e-2 (float32's epsilon
        times the tangent's conditioning), a few up to 0.3 (``INEXACT_SOLVE_RTOL``); nan where
        the last factorisation was exact (double precision) or before the first."""
        if self._last_factored is None:
            return float("nan")
        solver, data = self._last_factored
        K = self.disc.pattern_matrix(data)
        b = np.random.default_rng(0).standard_normal(K.shape[0])
        with np.errstate(all="ignore"):
            x = solver.solve(b)
            out = float(np.linalg.norm(K @ x - b) / np.linalg.norm(b))
        return out if np.isfinite(out) else float("inf")

    @property
    def step_factors_kept(self) -> int:
        """Factorisations kept for tapping steps now (``step_factors``, ``_slot_for``)."""
        return len(self._step_factors)

    @property
    def solver_name(self) -> str | None:
        """The linear solver that made the last factorisation (None before the first)."""
        return self._factored_by

    def _forget_factorization(self) -> None:
        """Drop the kept factorisation and what was derived from it (another solver follows;
        each solver keeps its analysis, and the body's own its steps' factorisations)."""
        self._solver = None
        self._stale = False
        self._factored_active = self._factored_blocks = None
        self._corrected = self._x2 = None
        self._kept_columns.clear()

    def _advance(
        self,
        t_new: float,
        control: Control,
        frozen_history: bool,
        guess: tuple[np.ndarray, float] | None,
    ) -> StepResult:
        """``advance`` with the body's linear solver."""
        opts = self.options
        dt = t_new - self.t
        u = self.u.copy()
        d = control.value if control.kind == "position" else self.indenter_position
        if control.kind == "force" and not np.isfinite(d):
            d = self.top_height()
        if guess is not None:
            u = guess[0].copy()
            if control.kind == "force" and np.isfinite(guess[1]):
                d = guess[1]
        else:
            u, d = self._predict(u, d, control)
        self._began_fresh = False
        ev = self._evaluate(u, control, d, dt, True, frozen_history)
        if ev is None:
            return StepResult(False, 0, "inverted element at start of step")
        norms: list[float] = []
        for it in range(1, opts.max_iterations + 1):
            r, data, force, coupling, rd, states, parts = ev
            if control.kind == "force" and not np.any(coupling > 0):
                # the plate lost contact: re-seat it on the highest point with a small overlap
                top = int(np.argmax(self._surface_heights(u)))
                d = self.top_height(u) - control.value / self.kappa_indenter[top]
                ev = self._evaluate(u, control, d, dt, True, frozen_history)
                if ev is None:
                    return StepResult(False, it, "inverted element")
                continue
            norm0 = self._norm(r, rd)
            if _log.isEnabledFor(logging.DEBUG):
                _log.debug("it %d |r| %.3e rd %.3e d %.5f", it, float(np.abs(r).max()), rd, d)
            force_ok = control.kind != "force" or abs(rd) <= max(
                FORCE_RTOL * abs(control.value), self.force_floor
            )
            if norm0 <= self.atol and force_ok:  # the load is matched relative to itself too
                self._commit(u, states, t_new, d, control, force)
                self.newton_iterations += it - 1
                return StepResult(True, it - 1)
            norms.append(norm0)
            if _stalled(norms, opts, self.disc.dim):
                self.newton_iterations += it - 1
                return StepResult(False, it - 1, "stalled")
            active = coupling > 0
            fresh = not self._may_reuse(norms, active)
            solver = None
            if not fresh:
                solver = self._contact_corrected(parts) if opts.contact_update else self._solver
                fresh = solver is None
            if len(norms) == 1:  # the attempt's first direction (after a re-seat, a stale one)
                self._began_fresh = fresh
            if fresh:
                tangent = data()
                if not np.all(np.isfinite(tangent)):  # the material tangent, computed lazily
                    self.newton_iterations += it
                    return StepResult(False, it, "non-finite tangent")
                blocks = self._contact_blocks(parts) if opts.contact_update else None
                solver = self._factor(tangent, active, blocks)
            t0 = time.perf_counter()
            du, dd = self._newton_step(solver, r, rd, coupling, control)
            self.timings["triangular solves"] += time.perf_counter() - t0
            if not (np.all(np.isfinite(du)) and np.isfinite(dd)):
                self.newton_iterations += it
                return StepResult(False, it, "singular tangent")
            with np.errstate(all="ignore"):
                g0 = float(du @ r) + dd * rd
            if not np.isfinite(g0):
                self.newton_iterations += it
                return StepResult(False, it, "singular tangent")
            if opts.active_set_solves and opts.contact_update:
                settled = self._settle_active_set(parts, data, r, rd, control, du, dd)
                if settled is not None:
                    du, dd, g0 = settled
            accepted = self._line_search(u, d, du, dd, g0, control, dt, frozen_history)
            if accepted is None and not fresh:  # the kept factorisation misled: a fresh one
                self._stale = True
                norms.pop()
                continue
            if accepted is None:
                self.newton_iterations += it
                return StepResult(False, it, "line search failed")
            u, d, ev = accepted
        self.newton_iterations += opts.max_iterations
        return StepResult(False, opts.max_iterations, "no convergence")

    def _line_search(
        self,
        u: np.ndarray,
        d: float,
        du: np.ndarray,
        dd: float,
        g0: float,
        control: Control,
        dt: float,
        frozen_history: bool,
    ) -> tuple[np.ndarray, float, tuple] | None:
        """The accepted point (displacements, indenter position, its ``_evaluate``) along the
        Newton direction (``du`` on the free dofs, ``dd``) from (``u``, ``d``); None when the
        line search fails (no admissible trial, or a step below ``min_step``).

        On the directional derivative g(a) = [du, dd] . residual(a), i.e. on the incremental
        potential (hyperelasticity, the Prony update within a step, penalty contact and the dead
        load on the plate are all variational; ``g0`` = g(0)). The full step is taken when it does
        not overshoot the minimum along the line by much; otherwise the root of g is bracketed
        (regula falsi). Inverted elements halve the step. Each trial's tangent is assembled only
        if a factorisation asks for it (``sim.fe._assembly.Evaluation``)."""
        opts = self.options
        free = self.disc.free
        g_contact = None  # the contacts' part of g (``_contact_slope``), made once needed
        a_lo, gb_lo = 0.0, 0.0  # gb: the body's part of g at a_lo
        a_hi = gb_hi = None  # smallest step known to overshoot the minimum along the line
        alpha = 1.0
        for bt in range(opts.max_backtracks + 1):
            u_try = u.copy()
            u_try.reshape(-1)[free] += alpha * du
            d_try = d + alpha * dd
            # the trial's tangent costs nothing until a factorisation assembles it
            trial = self._evaluate(u_try, control, d_try, dt, True, frozen_history)
            if trial is None:
                alpha = 0.5 * (a_lo + alpha)
                continue
            with np.errstate(all="ignore"):
                g = float(du @ trial[0]) + dd * trial[4]
            small = g0 >= 0.0 or abs(g) <= opts.line_search_eta * abs(g0)
            if small or bt == opts.max_backtracks or (g < 0.0 and alpha >= 1.0):
                return None if alpha < opts.min_step else (u_try, d_try, trial)
            if not np.isfinite(g):
                alpha = 0.5 * (a_lo + alpha)
                continue
            if g_contact is None:  # the full step is not taken (most are): model the line
                g_contact = self._contact_slope(u, d, du, dd, control)
                gb_lo = g0 - g_contact(0.0)
            if g < 0.0:  # still descending: the minimum lies beyond alpha
                a_lo, gb_lo = alpha, g - g_contact(alpha)
                alpha = min(1.0, 2.0 * alpha) if a_hi is None else 0.5 * (a_lo + a_hi)
            else:  # overshoot: the root of the model of g inside [a_lo, alpha]
                a_hi, gb_hi = alpha, g - g_contact(alpha)
                alpha = _model_root(g_contact, a_lo, gb_lo, a_hi, gb_hi)
        return None

    def _contact_slope(
        self, u: np.ndarray, d: float, du: np.ndarray, dd: float, control: Control
    ) -> Callable[[float], float]:
        """The contacts' part of the line search's g(a): from the surface nodes alone, exact,
        and cheap beside an evaluation of the body.

        g(a) = [du, dd] . residual(a) is the body's part (smooth: nearly linear over a Newton
        step) plus the contacts' (the penalty forces on the surface nodes and, under force
        control, the plate's force balance), which kinks wherever a node enters or leaves an
        obstacle along the line. A node that enters contact within the step makes g jump by
        orders of magnitude at the full step, and a secant of the total g then crawls towards
        the root (``_model_root`` uses this part exactly instead)."""
        step = self._surface_step(du)  # the line's direction at the surface nodes
        axes = list(self._axes)
        xy0, dxy = self.plane_coordinates(u), step[:, axes]
        push = control.value if control.kind == "force" else 0.0

        def g_contact(alpha: float) -> float:
            out = 0.0
            parts = self._contact_at(xy0 + alpha * dxy, control, d + alpha * dd)
            for p, n, _, is_indenter in parts:
                k = self.kappa_indenter if is_indenter else self.kappa_nodes
                f = np.where(p > 0, k * p, 0.0)
                out -= float(np.sum(f * np.einsum("ij,ij->i", n, step)))
                if is_indenter and control.kind == "force":
                    out += dd * (push - float(np.sum(-f * self.along_indenter(n))))
            return out

        return g_contact

    def _predict(self, u, d, control):
        """Extrapolate the last increment in proportion to the change of the control value."""
        prev = self._last
        if prev is None or prev[0] != control.kind or control.kind == "free":
            return u, d
        _, v_prev, v_now, du_prev, dd_prev = prev
        if abs(v_now - v_prev) < 1e-14 * max(abs(v_now), 1e-30):
            return u, d
        ratio = float(np.clip((control.value - v_now) / (v_now - v_prev), -2.0, 2.0))
        u_pred = u + ratio * du_prev
        if control.kind == "force":
            d = d + ratio * dd_prev
        return u_pred, d

    def _commit(self, u, states, t_new, d, control, force):
        if self._last_control is not None and self._last_control.kind == control.kind:
            self._last = (
                control.kind,
                self._last_control.value,
                control.value,
                u - self.u,
                d - self.indenter_position if np.isfinite(self.indenter_position) else 0.0,
            )
        else:
            self._last = None
        self._last_control = control
        self.u = u
        self.states = states
        self.t = t_new
        self.indenter_position = d if control.kind != "free" else np.inf
        self.force = force

    def snapshot(self):
        """Everything needed to return to the current committed state."""
        return (
            self.u.copy(),
            [LayerState(s.S0.copy(), s.H.copy()) for s in self.states],
            self.t,
            self.indenter_position,
        )

    def restore(self, snap) -> None:
        self.u, states, self.t, self.indenter_position = snap
        self.states = [LayerState(s.S0.copy(), s.H.copy()) for s in states]
        self._last = None
        self._last_control = None


#: Resident memory the factorisations kept per tapping step may take in one body (MB;
#: ``Body.step_factors_MB``): two sweep workers then hold 4 GB of them on this 24 GB machine.
STEP_FACTORS_MB = 2048.0

#: A failed step is retried in double precision only where the single-precision factorisation
#: it ended with solves its own tangent worse than this (``Body.last_factor_residual``, on a
#: random right-hand side; ``Body.advance``). Newton with directions of relative residual eta
#: converges at a rate of about eta (Dembo, Eisenstat & Steihaug 1982, SIAM J. Numer. Anal.
#: 19:400-408). On the 3D pads whose steps fail most (default-space designs 3's tapping, a
#: soft compressible foam core, and 4's plate) the single-precision factorisations gave a
#: median of 9.5e-4 and 3.4e-4 and a 90th percentile of 3.6e-3 and 1.2e-3, but a few up to 0.29
#: and 0.33: a factorisation beyond 1e-2 is in the worst twentieth, and its step goes to double
#: precision; the others' steps are retried in single precision from a fresh factorisation,
#: which rescues as many (docs/fe_speed.md, "What rescues a failed 3D step").
INEXACT_SOLVE_RTOL = 1e-2


@dataclass(frozen=True)
class _StepFactor:
    """A factorisation kept for one tapping step (``Body._factor``): its number, what solves
    with it, the contact it was made with and its solved columns (``_KeptColumns``)."""

    serial: int
    solver: Any
    active: np.ndarray
    blocks: np.ndarray | None
    columns: _KeptColumns


class _KeptColumns:
    """Columns ``K0^-1 e_j`` of one factorisation of ``K0``, solved once per dof ``j``.

    The contact's changes against a kept factorisation are made of the same few dozen rim
    dofs, iteration after iteration (on ``soft_fast``'s 3D tapping half of the columns the
    corrections asked for had been solved before with the same factorisation). Made empty
    with every new factorisation (``Body._factor``); holds at most ``capacity`` columns
    (then emptied: the dofs of a patch's rim move on). 512: 16 corrections' worth at the
    Woodbury bound of 32, and 82 MB on the default space's largest 3D pads (20 000 dofs), so
    that two sweep workers stay far inside this machine's memory."""

    def __init__(self, capacity: int = 512) -> None:
        self.capacity = capacity
        self._columns: dict[int, np.ndarray] = {}
        #: columns solved, and columns served from the store (counts)
        self.solved = 0
        self.served = 0

    def clear(self) -> None:
        self._columns.clear()

    def columns(self, solver: Any, dofs: np.ndarray, n_free: int) -> np.ndarray:
        """``K0^-1 P`` (n_free, len(dofs)), P the unit columns of ``dofs``: the missing ones
        in one solve with as many right-hand sides."""
        missing = [int(j) for j in dofs if int(j) not in self._columns]
        if len(self._columns) + len(missing) > self.capacity:
            self._columns.clear()
            missing = [int(j) for j in dofs]
        if missing:
            P = np.zeros((n_free, len(missing)))
            P[missing, np.arange(len(missing))] = 1.0
            Z = solver.solve_many(P)
            for k, j in enumerate(missing):
                self._columns[j] = Z[:, k]
        self.solved += len(missing)
        self.served += len(dofs) - len(missing)
        return np.column_stack([self._columns[int(j)] for j in dofs])


class _ContactCorrected:
    """Solves with a kept factorisation of ``K0`` as if it held today's contact stiffness,
    ``K = K0 + P D P^T`` (``D`` the change of the contact's blocks on the free dofs ``dofs``, P
    their unit columns), by Woodbury's identity:
    ``K^-1 b = y - Z (I + D P^T Z)^-1 D P^T y`` with ``y = K0^-1 b``, ``Z = K0^-1 P`` (the
    columns from ``kept``, a ``_KeptColumns`` of this factorisation; without one, one solve
    with ``len(dofs)`` right-hand sides). ``ok`` is False where ``I + D P^T Z`` is
    singular (K itself is then singular or nearly so)."""

    def __init__(
        self,
        solver: Any,
        dofs: np.ndarray,
        D: np.ndarray,
        n_free: int,
        kept: _KeptColumns | None = None,
    ) -> None:
        self._solver = solver
        self._dofs = dofs
        self._D = D
        s = len(dofs)
        self._Z = None
        self.ok = True
        if s == 0:
            return
        self._Z = (kept if kept is not None else _KeptColumns()).columns(solver, dofs, n_free)
        with np.errstate(all="ignore"):
            M = np.eye(s) + D @ self._Z[dofs]
            # columns that are not finite (a single-precision factorisation of a tangent
            # beyond float32's range: ``Pardiso.refactor``) correct nothing, and LAPACK's SVD
            # would raise on them
            cond = float(np.linalg.cond(M)) if np.all(np.isfinite(M)) else math.inf
        # beyond 1e12 the small system would keep only ~4 of double precision's 16 digits:
        # K is then (nearly) singular, and a fresh factorisation says so
        self.ok = cond < 1e12
        self._M = M

    def solve(self, b: np.ndarray) -> np.ndarray:
        y = self._solver.solve(b)
        if self._Z is None:
            return y
        return y - self._Z @ np.linalg.solve(self._M, self._D @ y[self._dofs])
