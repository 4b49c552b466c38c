"""The periodic state of repeated taps and force-controlled creep against closed forms.

At small strain, a body whose whole stress relaxes with one normalised function
``g(t) = g_inf + sum g_i exp(-t / tau_i)`` (the hyperfoam convention: constant Poisson's ratio)
responds to a plate force ``F(t)`` like one generalised Maxwell element (the correspondence
principle): ``F = k0 [g_inf delta + sum g_i h_i]`` with ``h_i' = delta' - h_i / tau_i`` and
``k0 = 1 / c`` the instantaneous stiffness. Here ``c`` comes from an elastic FE run with the
instantaneous moduli; everything time-dependent comes from the closed form: the modal solution of
the linear ODE ``M h' = -T h + (c / g_inf) 1 F'`` (``M = I + 1 g^T / g_inf``, ``T = diag(1/tau)``),
exact for the half-sine taps and for a linear force ramp, and its periodic solution
``h(0) = (I - exp(A T))^-1 int_0^T exp(A (T - s)) b F'(s) ds``.

The body is the unit square of ``tests/fe_helpers``, bonded at its base and pressed on its flat
top by the plate, so that the contact area stays the whole top (a curved fingertip's growing
contact would make the problem nonlinear even at small strain).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from fe_helpers import square_mesh

from sim.fe import Body, Control, Discretization, NewtonOptions, Plate
from sim.materials import LAWS, Material, Prony
from sim.protocols import TappingOptions, run_tapping

G = (0.3, 0.25)  # a fast and a slow term: g_inf = 0.45 makes the creep 2.2x the elastic step
TAU_S = (0.08, 0.9)
PEAK_N = 2e-4  # strain ~ 1e-4: geometric nonlinearity ~ 1e-4 relative, below the tolerances
LENGTH_MM = 10.0
# tight Newton tolerance: the default (1e-6 E0 a) is 2 % of this tiny load; the default
# penalty adds an elastic compliance of ~3e-4 of the body's, below the tolerances
NEWTON = NewtonOptions(rtol=1e-10)


def _material(prony: Prony) -> Material:
    # one-term hyperfoam with alpha = 2: linear elastic with mu, nu at small strain
    law = LAWS["hyperfoam"](mu_MPa=(0.1,), alpha=(2.0,), nu=0.3)
    return Material(law, prony, "long_term")


def _body(material: Material) -> Body:
    disc = Discretization(square_mesh(4), [material])
    return Body(disc, Plate(), NEWTON)


def _instantaneous_compliance_mm_per_N(opts: TappingOptions) -> float:
    """c = delta / F of the elastic body with the instantaneous moduli (long-term / g_inf)."""
    visco = _material(Prony(G, TAU_S))
    elastic = Material(visco.instantaneous, Prony(), "long_term")
    res = run_tapping(_body(elastic), opts)
    d = np.asarray(res.curves["tapping"]["displacement_mm"])
    f = np.asarray(res.curves["tapping"]["force_N"])
    return float(np.polyfit(f, d, 1)[0])  # linear: the slope over the whole tap


class Maxwell:
    """The generalised Maxwell element of the module docstring, solved in closed form."""

    def __init__(self, c: float, g=G, tau=TAU_S) -> None:
        self.c = c
        self.g = np.asarray(g)
        self.g_inf = 1.0 - self.g.sum()
        M = np.eye(len(g)) + np.outer(np.ones(len(g)), self.g) / self.g_inf
        self.A = -np.linalg.solve(M, np.diag(1.0 / np.asarray(tau)))
        self.b = np.linalg.solve(M, np.ones(len(g))) * c / self.g_inf
        lam, V = np.linalg.eig(self.A)
        self.lam, self.V, self.Vinv = lam.real, V.real, np.linalg.inv(V).real

    def _flow(self, t: float) -> np.ndarray:
        return self.V @ np.diag(np.exp(self.lam * t)) @ self.Vinv

    def forced(self, t: float, amp: float, omega: float) -> np.ndarray:
        """int_0^t exp(A (t - s)) b amp cos(omega s) ds, per mode in closed form."""
        lam = self.lam
        # int_0^t e^{lam (t-s)} cos(w s) ds = [w sin(w t) - lam cos(w t) + lam e^{lam t}] /
        #                                     (lam^2 + w^2)
        wt = omega * t
        I = (omega * np.sin(wt) - lam * np.cos(wt) + lam * np.exp(lam * t)) / (lam**2 + omega**2)
        return amp * self.V @ (I * (self.Vinv @ self.b))

    def ramp(self, t: float, rate: float) -> np.ndarray:
        """int_0^t exp(A (t - s)) b rate ds."""
        I = np.expm1(self.lam * t) / self.lam
        return rate * self.V @ (I * (self.Vinv @ self.b))

    def delta(self, F: float, h: np.ndarray) -> float:
        return (self.c * F - self.g @ h) / self.g_inf


def _periodic_tap(model: Maxwell, t_load: float, rest: float, peak: float, t: np.ndarray):
    """delta(t) in the loaded part of the periodic state, and the dissipation per cycle."""
    omega = np.pi / t_load

    def h_at(h0: np.ndarray, s: float) -> np.ndarray:
        if s <= t_load:
            return model._flow(s) @ h0 + model.forced(s, peak * omega, omega)
        return model._flow(s - t_load) @ h_at(h0, t_load)

    period = t_load + rest
    h_end_from_zero = h_at(np.zeros(len(model.g)), period)
    h0 = np.linalg.solve(np.eye(len(model.g)) - model._flow(period), h_end_from_zero)
    delta = np.array([model.delta(peak * np.sin(omega * s), h_at(h0, s)) for s in t])
    # dissipation: dashpot i carries k0 g_i h_i at the rate h_i / tau_i
    s = np.linspace(0.0, period, 20001)
    H = np.array([h_at(h0, si) for si in s])
    k0 = 1.0 / model.c
    power = (k0 * np.asarray(G) / np.asarray(TAU_S) * H**2).sum(axis=1)
    return delta, float(np.trapezoid(power, s))


@pytest.fixture(scope="module")
def tapped():
    opts = TappingOptions(
        peak_force_N=PEAK_N, length_mm=LENGTH_MM, steps_loaded=64, steps_settle=64,
        rest_first_step_tau=0.1, rest_growth=1.25, max_taps=30,
    )  # fmt: skip
    c = _instantaneous_compliance_mm_per_N(opts)
    res = run_tapping(_body(_material(Prony(G, TAU_S))), opts)
    return opts, c, res


def test_periodic_taps_match_the_closed_form(tapped):
    opts, c, res = tapped
    assert res.info["settled"], res.info
    t = np.asarray(res.curves["tapping"]["time_s"])[:-1]  # the last point is the lift-off
    d = np.asarray(res.curves["tapping"]["displacement_mm"])[:-1]
    t_load = 0.5 / opts.frequency_Hz
    exact, _ = _periodic_tap(Maxwell(c), t_load, opts.rest_s, PEAK_N, t)
    # within 0.3 % of the peak displacement: second-order time stepping at 64 steps per tap
    assert np.max(np.abs(d - exact)) < 3e-3 * np.max(exact), np.max(np.abs(d - exact))
    # the periodic state is not the first tap: the body starts each tap sagged
    assert exact[0] > 0.05 * np.max(exact)


def test_loop_area_equals_the_energy_dissipated_per_cycle(tapped):
    opts, c, res = tapped
    t_load = 0.5 / opts.frequency_Hz
    t = np.linspace(0.0, t_load, 4001)
    exact, dissipated = _periodic_tap(Maxwell(c), t_load, opts.rest_s, PEAK_N, t)
    omega = np.pi / t_load
    loop = -np.trapezoid(exact * PEAK_N * omega * np.cos(omega * t), t)
    assert loop == pytest.approx(dissipated, rel=1e-4)  # the closed form is self-consistent
    assert res.metrics["hysteresis_Nmm"] == pytest.approx(dissipated, rel=5e-3)


def test_residual_and_error_estimate_are_reported(tapped):
    opts, _, res = tapped
    info = res.info
    assert info["residual"] <= opts.residual_tol
    assert info["estimated_error"]["hysteresis_Nmm"] <= opts.settle_tol
    assert info["estimated_error"]["disp_at_1N_mm"] is None  # a 0.2 mN tap never reaches 1 N
    assert 2 <= info["taps"] <= 12


def test_estimated_error_bounds_the_error_of_an_unsettled_tap(tapped):
    """Stopped after two taps (a few accelerations short of the periodic state), the estimate of
    the hysteresis error is of the size of the actual error against the settled value."""
    opts, _, settled = tapped
    short = dataclasses.replace(opts, max_taps=2, min_taps=2)
    res = run_tapping(_body(_material(Prony(G, TAU_S))), short)
    assert not res.info["settled"]
    true = abs(res.metrics["hysteresis_Nmm"] / settled.metrics["hysteresis_Nmm"] - 1.0)
    est = res.info["estimated_error"]["hysteresis_Nmm"]
    assert true > 10 * opts.settle_tol  # two taps are visibly not enough
    assert 0.3 * true < est < 3.0 * true, (true, est)


def test_force_controlled_creep_follows_the_creep_compliance():
    """A fast ramp to F0, then held: delta(t) follows the closed form and tends to
    c F0 / g_inf, the long-term creep compliance."""
    opts = TappingOptions(peak_force_N=PEAK_N, length_mm=LENGTH_MM)
    c = _instantaneous_compliance_mm_per_N(opts)
    model = Maxwell(c)
    body = _body(_material(Prony(G, TAU_S)))
    scale = 1.0 / (2.0 * LENGTH_MM)
    t_ramp = 0.01
    rate = PEAK_N / t_ramp
    times = np.concatenate(
        [np.linspace(0.0, t_ramp, 11)[1:], t_ramp + np.geomspace(1e-3, 40.0, 120)]
    )
    top0 = body.top_height()
    got, want = [], []
    for t in times:
        F = PEAK_N * min(1.0, t / t_ramp)
        res = body.advance(t, Control.force(F * scale))
        assert res.converged, res.reason
        got.append(top0 - body.indenter_position)
        h_ramp = model.ramp(min(t, t_ramp), rate)
        h = h_ramp if t <= t_ramp else model._flow(t - t_ramp) @ h_ramp
        want.append(model.delta(F, h))
    got, want = np.array(got), np.array(want)
    assert np.max(np.abs(got - want)) < 2e-3 * want[-1], np.max(np.abs(got - want) / want[-1])
    assert got[-1] == pytest.approx(c * PEAK_N / (1.0 - sum(G)), rel=2e-3)
    assert got[-1] > 2.0 * got[9]  # it really creeps: 1 / g_inf = 2.2 times the elastic step


@pytest.mark.parametrize("tau", [0.002, 0.05, 0.9])
def test_rest_steps_are_geometric_from_the_shortest_relaxation_time(tau):
    from sim.protocols.loading import _rest_times

    opts = TappingOptions()
    t = _rest_times(opts, tau)
    dt = np.diff(np.concatenate([[0.0], t]))
    assert t[-1] == pytest.approx(opts.rest_s, rel=1e-12) and np.all(dt > 0)
    assert len(t) >= opts.steps_rest
    assert dt[0] <= opts.rest_first_step_tau * tau * (1 + 1e-9)  # resolves the fastest term
    assert np.all(dt[1:] / dt[:-1] <= opts.rest_growth * (1 + 1e-9))
    # the fewest steps that do it: one step fewer could not reach rest_s at that growth
    n = len(t)
    if n > opts.steps_rest:
        reach = dt[0] * (opts.rest_growth ** (n - 1) - 1) / (opts.rest_growth - 1)
        assert reach < opts.rest_s


def test_quartered_steps_quarter_every_step():
    from sim.protocols.loading import _rest_times

    opts = TappingOptions()
    fine = opts.with_steps_scaled(4)
    assert fine.steps_loaded == 4 * opts.steps_loaded
    assert fine.rest_first_step_tau == pytest.approx(opts.rest_first_step_tau / 4)
    assert fine.rest_growth**4 == pytest.approx(opts.rest_growth)
    coarse, quartered = _rest_times(opts, 0.01), _rest_times(fine, 0.01)
    assert 3.5 * len(coarse) < len(quartered) < 4.5 * len(coarse)
    assert len(_rest_times(opts, np.inf)) == opts.steps_rest  # elastic: nothing to resolve


def test_a_design_that_cannot_settle_in_time_is_stopped_early():
    """Residual histories of FE runs (docs/designs and the default sweep): one that falls
    steadily is never cut, one that stagnates is cut as soon as it can be judged, one that
    falls too slowly for the tap limit is cut when that becomes clear."""
    from sim.protocols.loading import _cannot_settle

    opts = TappingOptions()
    # settled after 22 taps in the default sweep: never cut on the way
    steady = [3.3e-1, 2.5e-1, 9.5e-2, 8.0e-2, 7.3e-2, 4.4e-2, 2.2e-2, 1.9e-2, 1.9e-2, 1.5e-2,
              5.7e-3, 3.1e-3, 2.2e-3, 1.6e-3, 1.2e-3, 7.6e-4, 6.3e-4, 4.6e-4, 4.2e-4, 4.2e-4,
              4.4e-4, 2.5e-4]  # fmt: skip
    assert not any(_cannot_settle(steady[:k], opts) for k in range(1, len(steady) + 1))
    # unsettled after 25 taps: its residual hovers at 0.1-0.2 from the fourth tap on
    stagnant = [3.8e-1, 1.9e-1, 1.4e-1, 1.2e-1, 1.2e-1, 1.6e-1, 1.7e-1, 1.7e-1, 1.7e-1]
    first = next(k for k in range(1, 10) if _cannot_settle(stagnant[:k], opts))
    assert first == opts.stall_window + 2
    # docs/designs/slow_creep.toml: halves every ~6 taps at 3e-2, 30 more taps needed
    creep = [3.05e-1, 1.61e-1, 6.82e-2, 5.43e-2, 4.98e-2, 4.30e-2, 4.12e-2, 3.37e-2, 5.72e-2]
    assert not _cannot_settle(creep[:8], opts) and _cannot_settle(creep, opts)
    # never while the residual is within its tolerance (the error estimate decides then)
    assert not _cannot_settle([1e-2] * 8 + [5e-4] * 8, opts)
    assert not _cannot_settle(stagnant, dataclasses.replace(opts, stall_window=0))
    assert not _cannot_settle(stagnant, dataclasses.replace(opts, min_taps=64, max_taps=64))


def test_the_cost_log_adds_up_to_the_run(tapped):
    """``info["cost"]``: one entry per tap and phase, in order, whose counts add up to the
    run's steps, and without the periodic-state jumps (which re-equilibrate the body between
    taps) to every factorisation and evaluation of the body."""
    _, _, res = tapped
    cost = res.info["cost"]
    taps = res.info["taps"]
    assert [(e["tap"], e["phase"]) for e in cost] == [
        (k, phase) for k in range(1, taps + 1) for phase in ("loaded", "rest")
    ]
    assert sum(e["steps"] for e in cost) == res.steps
    assert all(e["factorizations"] >= 1 and e["evaluations"] >= e["steps"] for e in cost)
    body = _body(_material(Prony(G, TAU_S)))
    plain = TappingOptions(
        peak_force_N=PEAK_N, length_mm=LENGTH_MM, max_taps=3, min_taps=3, accelerate=False
    )
    res = run_tapping(body, plain)
    cost = res.info["cost"]
    assert len(cost) == 2 * res.info["taps"] == 6
    assert sum(e["factorizations"] for e in cost) == body.factorizations
    assert sum(e["evaluations"] for e in cost) == body.evaluations
    assert sum(e["steps"] for e in cost) == res.steps
