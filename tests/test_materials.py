"""Physics checks of the constitutive laws (sim.materials).

Voigt conventions: ``C = [C11, C22, C12]``, ``S = [S11, S22, S12]``, ``D`` maps
``dE = [dE11, dE22, 2 dE12]`` to ``dS``; units MPa.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from sim.errors import DesignError
from sim.materials import (
    CATALOGUE,
    LAWS,
    Hyperfoam,
    Material,
    MooneyRivlin,
    NeoHookean,
    Prony,
    Yeoh,
    catalogue_material,
    material_from_spec,
    prony_update,
)

SILICONE = CATALOGUE["silicone_gls40"].law
POLYURETHANE = CATALOGUE["polyurethane_74_45"].law

# (law, largest |ln J| used in the random states): nearly incompressible stiff-exponent foams
# are only probed near J = 1, where they live.
LAW_CASES = {
    "silicone": (SILICONE, 0.02),
    "polyurethane": (POLYURETHANE, 0.04),
    "hyperfoam_3term": (Hyperfoam(mu_MPa=[0.1, -0.02, 0.05], alpha=[2.0, -3.0, 0.5], nu=0.3), 0.3),
    "hyperfoam_nu0": (Hyperfoam(mu_MPa=[0.2], alpha=[3.0], nu=0.0), 0.3),
    "hyperfoam_auxetic": (Hyperfoam(mu_MPa=[-0.02, 0.1], alpha=[-2.0, 6.0], nu=-0.4), 0.3),
    "neo_hookean": (NeoHookean(mu_MPa=0.1, nu=0.45), 0.1),
    "mooney_rivlin": (MooneyRivlin(c10_MPa=0.05, c01_MPa=0.02, nu=0.3), 0.3),
    "yeoh": (Yeoh(c10_MPa=0.05, c20_MPa=-0.01, c30_MPa=0.003, nu=0.4), 0.2),
}
LAW_IDS = list(LAW_CASES)

# Column j: the change of C for a unit change of Voigt strain component j (C = I + 2E).
DC_DE = np.array([[2.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 1.0]])


def rot(theta: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]])


def to_mat(x: np.ndarray) -> np.ndarray:
    """Voigt [x11, x22, x12] (3, *batch) -> symmetric (*batch, 2, 2)."""
    return np.moveaxis(np.array([[x[0], x[2]], [x[2], x[1]]]), (0, 1), (-2, -1))


def to_voigt(m: np.ndarray) -> np.ndarray:
    """(*batch, 2, 2) -> Voigt (3, *batch)."""
    return np.stack([m[..., 0, 0], m[..., 1, 1], 0.5 * (m[..., 0, 1] + m[..., 1, 0])])


def deformations(ln_j_max: float, n: int, seed: int = 0) -> np.ndarray:
    """Random in-plane deformation gradients F = R(theta) diag(l1, l2) R(phi)^T, (n, 2, 2)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        l1 = math.exp(rng.uniform(-0.3, 0.3))
        J = math.exp(rng.uniform(-ln_j_max, ln_j_max))
        out.append(rot(rng.uniform(0, math.pi)) @ np.diag([l1, J / l1]) @ rot(rng.uniform(0, 3)).T)
    return np.array(out)


def C_of(F: np.ndarray) -> np.ndarray:
    return to_voigt(np.swapaxes(F, -1, -2) @ F)


def fd_strain(fun, C: np.ndarray, h: float) -> np.ndarray:
    """4th-order central differences of fun(C) w.r.t. Voigt strain; result (..., 3) last."""
    cols = []
    for j in range(3):
        dC = (DC_DE[:, j] * h).reshape((3,) + (1,) * (C.ndim - 1))
        cols.append(
            (-fun(C + 2 * dC) + 8 * fun(C + dC) - 8 * fun(C - dC) + fun(C - 2 * dC)) / (12 * h)
        )
    return np.stack(cols, axis=-1)


def probe_states(ln_j_max: float) -> np.ndarray:
    """Random states + C = I + C = c I + eigenvalues split by 1e-9, shape (3, n)."""
    cs = []
    for c in (1.0, math.exp(ln_j_max), math.exp(-ln_j_max)):
        cs.append([c, c, 0.0])
        for theta in (0.0, 0.7):
            Q = rot(theta)
            M = Q @ np.diag([c * (1 + 5e-10), c * (1 - 5e-10)]) @ Q.T
            cs.append([M[0, 0], M[1, 1], M[0, 1]])
    special = np.array(cs).T
    return np.concatenate([special, C_of(deformations(ln_j_max, 12))], axis=1)


# --------------------------------------------------------------------------------------------
# Derivatives


@pytest.mark.parametrize("name", LAW_IDS)
def test_stress_and_tangent_match_finite_differences(name: str) -> None:
    law, ln_j = LAW_CASES[name]
    C = probe_states(ln_j)
    W, S, D = law.evaluate(C)
    assert W.shape == C.shape[1:] and S.shape == C.shape and D.shape == (3, 3, C.shape[1])
    h = 1e-5
    S_fd = np.moveaxis(fd_strain(lambda c: law.evaluate(c)[0], C, h), -1, 0)  # S = dW/dE
    D_fd = np.moveaxis(fd_strain(law.stress, C, h), -1, 1)  # D = dS/dE
    mu0 = law.initial_shear_modulus_MPa
    for k in range(C.shape[1]):
        s_scale = max(np.abs(S[:, k]).max(), mu0)
        d_scale = np.abs(D[:, :, k]).max()
        assert np.abs(S_fd[:, k] - S[:, k]).max() <= 1e-7 * s_scale, (k, C[:, k])
        assert np.abs(D_fd[:, :, k] - D[:, :, k]).max() <= 1e-7 * d_scale, (k, C[:, k])
    np.testing.assert_array_equal(D, np.swapaxes(D, 0, 1))
    np.testing.assert_array_equal(law.stress(C), S)
    S2, D2 = law.stress_tangent(C)  # what the Newton iterations call: the same S and D
    np.testing.assert_array_equal(S2, S)
    np.testing.assert_array_equal(D2, D)


@pytest.mark.parametrize("name", ["silicone", "polyurethane", "hyperfoam_3term"])
def test_hyperfoam_tangent_on_both_sides_of_the_series_branch(name: str) -> None:
    """Nearly equal eigenvalues (c (1 +- s)) switch the divided difference to a Taylor series
    below s = 2.5e-3: check D tightly against finite differences of S on both sides."""
    law, _ = LAW_CASES[name]
    Q = rot(0.3)
    cols = []
    for c in (0.99, 1.01):
        for split in (1e-6, 1e-4, 2.4e-3, 2.6e-3, 1e-2):
            M = Q @ np.diag([c * (1 + split), c * (1 - split)]) @ Q.T
            cols.append([M[0, 0], M[1, 1], M[0, 1]])
    C = np.array(cols).T
    D = law.evaluate(C)[2]
    D_fd = np.moveaxis(fd_strain(law.stress, C, 1e-5), -1, 1)
    for k in range(C.shape[1]):
        scale = np.abs(D[:, :, k]).max()
        assert np.abs(D_fd[:, :, k] - D[:, :, k]).max() <= 1e-9 * scale, C[:, k]


@pytest.mark.parametrize("name", LAW_IDS)
def test_batch_shapes(name: str) -> None:
    law, ln_j = LAW_CASES[name]
    C = C_of(deformations(ln_j, 6, seed=3)).reshape(3, 2, 3)
    W, S, D = law.evaluate(C)
    assert W.shape == (2, 3) and S.shape == (3, 2, 3) and D.shape == (3, 3, 2, 3)
    assert law.S33(C).shape == (2, 3)
    S2, D2 = law.stress_tangent(C)
    assert S2.shape == (3, 2, 3) and D2.shape == (3, 3, 2, 3)
    W1, S1, D1 = law.evaluate(C[:, 1, 2])
    assert np.ndim(W1) == 0 and S1.shape == (3,) and D1.shape == (3, 3)
    np.testing.assert_allclose(S1, S[:, 1, 2], rtol=1e-14, atol=0)
    np.testing.assert_allclose(D1, D[:, :, 1, 2], rtol=1e-14, atol=0)


# --------------------------------------------------------------------------------------------
# Small strain and analytic stresses


@pytest.mark.parametrize("name", LAW_IDS)
def test_undeformed_state_is_linear_plane_strain_elasticity(name: str) -> None:
    law, _ = LAW_CASES[name]
    W, S, D = law.evaluate(np.array([1.0, 1.0, 0.0]))
    mu, K = law.initial_shear_modulus_MPa, law.bulk_modulus_MPa
    lam = K - 2.0 * mu / 3.0
    expected = np.array([[lam + 2 * mu, lam, 0.0], [lam, lam + 2 * mu, 0.0], [0.0, 0.0, mu]])
    assert abs(W) <= 1e-15 * mu
    assert np.abs(S).max() <= 1e-15 * mu
    assert abs(law.S33(np.array([1.0, 1.0, 0.0]))) <= 1e-15 * mu
    np.testing.assert_allclose(D, expected, rtol=1e-12, atol=1e-12 * mu)
    assert math.isclose(K, 2 * mu * (1 + law.nu) / (3 * (1 - 2 * law.nu)), rel_tol=1e-14)


def test_table1_initial_moduli() -> None:
    """mu0 = sum mu_i and K0 = sum 2 mu_i (1/3 + beta) for the paper's materials."""
    for law, mu0, nu in ((SILICONE, 0.090, 0.49), (POLYURETHANE, 0.163, 0.47)):
        beta = nu / (1 - 2 * nu)
        assert math.isclose(law.initial_shear_modulus_MPa, mu0, rel_tol=1e-14)
        assert math.isclose(law.bulk_modulus_MPa, 2 * mu0 * (1 / 3 + beta), rel_tol=1e-14)


def cauchy_from_S(law, F: np.ndarray) -> np.ndarray:
    """3x3 Cauchy stress sigma = F S F^T / J (in plane) and S33 / J, from the law under test."""
    C = C_of(F)
    S = to_mat(law.stress(C))
    J = np.linalg.det(F)
    sig = np.zeros((len(F), 3, 3))
    sig[:, :2, :2] = F @ S @ np.swapaxes(F, 1, 2) / J[:, None, None]
    sig[:, 2, 2] = law.S33(C) / J
    return sig


@pytest.mark.parametrize("name", [n for n in LAW_IDS if isinstance(LAW_CASES[n][0], Hyperfoam)])
def test_hyperfoam_cauchy_stress_matches_principal_formula(name: str) -> None:
    """sigma_a = (1/J) sum (2 mu_i / alpha_i) [lambda_a^alpha_i - J^(-alpha_i beta)]."""
    law, ln_j = LAW_CASES[name]
    beta = law.nu / (1 - 2 * law.nu)
    rng = np.random.default_rng(7)
    for _ in range(8):
        l1 = math.exp(rng.uniform(-0.3, 0.3))
        l2 = math.exp(rng.uniform(-ln_j, ln_j)) / l1
        theta = rng.uniform(0, math.pi)
        F = rot(theta) @ np.diag([l1, l2]) @ rot(rng.uniform(0, math.pi)).T
        J = l1 * l2
        principal = []
        for lam in (l1, l2, 1.0):
            # lambda^a - J^(-a b) written with expm1 so alpha = 0.001 does not cancel
            terms = [
                2 * m / a * (math.expm1(a * math.log(lam)) - math.expm1(-a * beta * math.log(J)))
                for m, a in zip(law.mu_MPa, law.alpha, strict=True)
            ]
            principal.append(math.fsum(terms) / J)
        R = np.eye(3)
        R[:2, :2] = rot(theta)
        expected = R @ np.diag(principal) @ R.T
        got = cauchy_from_S(law, F[None])[0]
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12 * np.abs(expected).max())


# (dU/dI1b, dU/dI2b) coded from the energies as printed in the Abaqus manual.
INVARIANT_DERIVATIVES = {
    NeoHookean: lambda m, i1, i2: (m.mu_MPa / 2, 0.0),
    MooneyRivlin: lambda m, i1, i2: (m.c10_MPa, m.c01_MPa),
    Yeoh: lambda m, i1, i2: (
        m.c10_MPa + 2 * m.c20_MPa * (i1 - 3) + 3 * m.c30_MPa * (i1 - 3) ** 2,
        0.0,
    ),
}


@pytest.mark.parametrize("name", ["neo_hookean", "mooney_rivlin", "yeoh"])
def test_invariant_cauchy_stress_matches_textbook_formula(name: str) -> None:
    """sigma = (2/J) dev[(W1 + I1b W2) Bb - W2 Bb^2] + U'(J) I, with 3x3 B (B33 = 1)."""
    law, ln_j = LAW_CASES[name]
    F2 = deformations(ln_j, 8, seed=11)
    K = 2 * law.initial_shear_modulus_MPa * (1 + law.nu) / (3 * (1 - 2 * law.nu))
    got = cauchy_from_S(law, F2)
    for k, f2 in enumerate(F2):
        F = np.eye(3)
        F[:2, :2] = f2
        J = np.linalg.det(F)
        Bb = J ** (-2 / 3) * F @ F.T
        i1 = np.trace(Bb)
        i2 = 0.5 * (i1**2 - np.trace(Bb @ Bb))
        W1, W2 = INVARIANT_DERIVATIVES[type(law)](law, i1, i2)
        A = (W1 + i1 * W2) * Bb - W2 * Bb @ Bb
        sigma = 2 / J * (A - np.trace(A) / 3 * np.eye(3)) + K * (J - 1) * np.eye(3)
        np.testing.assert_allclose(got[k], sigma, rtol=0, atol=1e-12 * np.abs(sigma).max())


@pytest.mark.parametrize("name", LAW_IDS)
def test_objectivity(name: str) -> None:
    """S(Q^T C Q) = Q^T S(C) Q, and W, S33 are invariant, for in-plane rotations Q."""
    law, ln_j = LAW_CASES[name]
    C = C_of(deformations(ln_j, 5, seed=5))
    W, S, _ = law.evaluate(C)
    for theta in (0.3, 1.2, -2.5):
        Q = rot(theta)
        Cr = to_voigt(Q.T @ to_mat(C) @ Q)
        Wr, Sr, _ = law.evaluate(Cr)
        expected = to_voigt(Q.T @ to_mat(S) @ Q)
        scale = np.abs(S).max()
        np.testing.assert_allclose(Sr, expected, rtol=0, atol=1e-12 * scale)
        np.testing.assert_allclose(Wr, W, rtol=1e-10, atol=1e-15)
        np.testing.assert_allclose(law.S33(Cr), law.S33(C), rtol=0, atol=1e-12 * scale)


@pytest.mark.parametrize("name", LAW_IDS)
def test_scaled_law_scales_stress_and_moduli(name: str) -> None:
    law, ln_j = LAW_CASES[name]
    C = C_of(deformations(ln_j, 4, seed=2))
    twice = law.scaled(2.5)
    np.testing.assert_allclose(twice.stress(C), 2.5 * law.stress(C), rtol=1e-13, atol=1e-16)
    assert math.isclose(twice.bulk_modulus_MPa, 2.5 * law.bulk_modulus_MPa, rel_tol=1e-14)
    assert twice.nu == law.nu


# --------------------------------------------------------------------------------------------
# Prony series

PRONY_CASES = [CATALOGUE["silicone_gls40"].prony, CATALOGUE["polyurethane_74_45"].prony]


@pytest.mark.parametrize("prony", PRONY_CASES)
def test_step_relaxation_is_exact_for_any_steps(prony: Prony) -> None:
    rng = np.random.default_rng(1)
    S0 = rng.normal(size=(3, 4, 2))
    H = prony.initial_history(S0.shape)
    zero = np.zeros_like(S0)
    S, H, _ = prony.update(S0, zero, H, 0.0)  # the step, at t = 0+
    np.testing.assert_allclose(S, S0, rtol=1e-15)
    t = 0.0
    tau_max = max(prony.tau_s)
    for dt in np.concatenate([[0.0], rng.uniform(0, 0.5 * tau_max, 30), [10 * tau_max]]):
        S, H, _ = prony.update(S0, S0, H, float(dt))
        t += dt
        np.testing.assert_allclose(S, prony.relaxation(t) * S0, rtol=1e-12, atol=0)
    assert np.all(np.isfinite(S))


def _ramp_error(prony: Prony, n: int, T: float, quadratic: bool) -> float:
    """Error at t = T of the recursion for S0(t) = t^2 (or t) against the exact integral."""
    times = np.linspace(0.0, T, n + 1)
    S0_of = (lambda t: np.full((3, 1), t * t)) if quadratic else (lambda t: np.full((3, 1), t))
    H = prony.initial_history((3, 1))
    S0_old = S0_of(0.0)
    for t0, t1 in itertools.pairwise(times):
        S, H, _ = prony.update(S0_of(t1), S0_old, H, float(t1 - t0))
        S0_old = S0_of(t1)
    g, tau = np.array(prony.g), np.array(prony.tau_s)
    decay = -np.expm1(-T / tau)
    if quadratic:  # int_0^T g(T - s) 2 s ds
        exact = prony.g_inf * T**2 + np.sum(g * 2 * (tau * T - tau**2 * decay))
    else:  # int_0^T g(T - s) ds
        exact = prony.g_inf * T + np.sum(g * tau * decay)
    return float(np.abs(S - exact).max() / exact)


@pytest.mark.parametrize("prony", PRONY_CASES)
def test_ramp_recursion_against_hereditary_integral(prony: Prony) -> None:
    T = 2.0
    # exact for a stress history linear in time, whatever the step
    assert _ramp_error(prony, 7, T, quadratic=False) <= 1e-12
    # second-order convergence for a curved history (dt from 0.5 to 0.03 of the shortest tau)
    ns = np.array([40, 80, 160, 320, 640])
    errors = np.array([_ramp_error(prony, int(n), T, quadratic=True) for n in ns])
    slope = np.polyfit(np.log(T / ns), np.log(errors), 1)[0]
    assert 1.9 <= slope <= 2.1, (slope, errors)
    assert errors[-1] < 1e-4


def test_prony_tangent_factor_and_dt_zero() -> None:
    prony = PRONY_CASES[1]
    rng = np.random.default_rng(4)
    S0_old, S0_new = rng.normal(size=(2, 3, 5))
    H = rng.normal(size=(3, 3, 5))
    for dt in (0.0, 1e-12, 0.05, 3.0, 1e4):
        S, _, factor = prony.update(S0_new, S0_old, H, dt)
        dS = prony.update(S0_new + 1e-3, S0_old, H, dt)[0] - S
        np.testing.assert_allclose(dS / 1e-3, factor, rtol=1e-9)
    assert prony.update(S0_new, S0_old, H, 0.0)[2] == pytest.approx(1.0, abs=1e-15)
    tau = np.array(prony.tau_s)
    expected = prony.g_inf + np.sum(np.array(prony.g) * tau / 1e9)  # gamma_i = tau_i / dt
    assert prony.update(S0_new, S0_old, H, 1e9)[2] == pytest.approx(expected, rel=1e-15)
    # the pure function and the method agree; an empty series is elastic
    np.testing.assert_array_equal(
        prony_update(S0_new, S0_old, H, 0.1, prony.g, prony.tau_s)[0],
        prony.update(S0_new, S0_old, H, 0.1)[0],
    )
    S, H0, factor = Prony().update(S0_new, S0_old, np.zeros((0, 3, 5)), 0.1)
    np.testing.assert_array_equal(S, S0_new)
    assert factor == 1.0 and H0.shape == (0, 3, 5)
    assert Prony().is_elastic and Prony().g_inf == 1.0


@pytest.mark.parametrize("name", ["silicone_gls40", "polyurethane_74_45"])
def test_long_term_convention(name: str) -> None:
    """Under moduli = long_term the given law is the relaxed law: S(t -> inf) = law.stress."""
    mat = catalogue_material(name)
    assert mat.moduli == "long_term"
    C = C_of(deformations(0.02, 3, seed=9))
    S0 = mat.instantaneous.stress(C)
    np.testing.assert_allclose(S0 * mat.prony.g_inf, mat.law.stress(C), rtol=1e-13, atol=1e-17)
    H = mat.prony.initial_history(C.shape)
    S, H, _ = mat.prony.update(S0, np.zeros_like(S0), H, 0.0)
    np.testing.assert_allclose(S, S0, rtol=1e-15)  # instantaneous response at t = 0+
    S, H, _ = mat.prony.update(S0, S0, H, 2000.0 * max(mat.prony.tau_s))
    np.testing.assert_allclose(S, mat.law.stress(C), rtol=1e-12, atol=0)
    assert mat.long_term == mat.law

    inst = Material(law=mat.law, prony=mat.prony, moduli="instantaneous")
    assert inst.instantaneous == mat.law
    np.testing.assert_allclose(
        inst.long_term.stress(C), mat.prony.g_inf * mat.law.stress(C), rtol=1e-13, atol=1e-17
    )
    assert math.isclose(
        mat.instantaneous.initial_shear_modulus_MPa,
        mat.law.initial_shear_modulus_MPa / mat.prony.g_inf,
        rel_tol=1e-14,
    )


# --------------------------------------------------------------------------------------------
# Catalogue, design-file form and validation


def test_catalogue_is_table1() -> None:
    si, pu = CATALOGUE["silicone_gls40"], CATALOGUE["polyurethane_74_45"]
    assert si.law == Hyperfoam(mu_MPa=[0.080, 0.010], alpha=[0.001, 15.5], nu=0.49)
    assert si.prony == Prony(g=[0.015, 0.044, 0.029], tau_s=[0.025, 0.150, 0.300])
    assert pu.law == Hyperfoam(mu_MPa=[0.100, 0.063], alpha=[5.5, 8.25], nu=0.47)
    assert pu.prony == Prony(g=[0.167, 0.158, 0.113], tau_s=[0.100, 1.380, 25.472])
    for name in ("silicone_gls40", "polyurethane_74_45"):
        mat = CATALOGUE[name]
        assert mat.name == name and mat.moduli == "long_term" and not mat.is_elastic
        assert "Cabibihan" in mat.source and "Table 1" in mat.source
    assert set(LAWS) == {"hyperfoam", "neo_hookean", "mooney_rivlin", "yeoh"}


INLINE = [
    {"model": "neo_hookean", "mu_MPa": 0.1, "nu": 0.45},
    {"model": "mooney_rivlin", "c10_MPa": 0.05, "c01_MPa": 0.01, "nu": 0.4, "prony_g": [0.3],
     "prony_tau_s": [0.5], "moduli": "instantaneous"},
    {"model": "yeoh", "c10_MPa": 0.05, "c20_MPa": 0.002, "nu": 0.45},
    {"model": "hyperfoam", "mu_MPa": [0.1, 0.02, -0.01], "alpha": [2, 8, -1e-3], "nu": 0.3},
]  # fmt: skip


@pytest.mark.parametrize("spec", [*INLINE, "silicone_gls40", "polyurethane_74_45"])
def test_round_trip_through_design_form(spec) -> None:
    mat = material_from_spec(spec)
    assert material_from_spec(mat.to_dict()) == mat
    assert type(mat.law).from_params(mat.law.to_dict(), "x") == mat.law
    if isinstance(spec, dict):
        assert mat.is_elastic == ("prony_g" not in spec)
        assert mat.moduli == spec.get("moduli", "long_term")


GOOD = {"model": "hyperfoam", "mu_MPa": [0.1, 0.05], "alpha": [2.0, 8.0], "nu": 0.45}


def with_(**changes):
    spec = dict(GOOD)
    spec.update(changes)
    return {k: v for k, v in spec.items() if v is not None}


BAD = [
    (with_(nu=0.5), "material.nu", "0.499"),
    (with_(nu=0.6), "material.nu", "(-1, 0.5)"),
    (with_(nu=-1.0), "material.nu", "(-1, 0.5)"),
    (with_(nu="0.3"), "material.nu", "number"),
    (with_(nu=True), "material.nu", "number"),
    (with_(nu=math.nan), "material.nu", "finite"),
    (with_(mu_MPa=[-0.1, -0.05]), "material.mu_MPa", "> 0"),
    (with_(mu_MPa=[0.1, -0.2], alpha=[2.0, -8.0]), "material.mu_MPa", "sum"),
    (with_(mu_MPa=[0.1, -0.05]), "material.mu_MPa", "alpha"),
    (with_(alpha=[2.0, 0.0]), "material.alpha", "nonzero"),
    (with_(alpha=[2.0]), "material.alpha", "as many"),
    (with_(mu_MPa=[0.1] * 4, alpha=[2.0] * 4), "material.mu_MPa", "1 to 3"),
    (with_(mu_MPa=[]), "material.mu_MPa", "1 to 3"),
    (with_(mu_MPa=0.1), "material.mu_MPa", "list"),
    (with_(alpha=None), "material.alpha", "required"),
    (with_(prony_g=[0.6, 0.4], prony_tau_s=[1.0, 2.0]), "material.prony_g", "sum must be < 1"),
    (with_(prony_g=[-0.1], prony_tau_s=[1.0]), "material.prony_g", ">= 0"),
    (with_(prony_g=[0.1], prony_tau_s=[0.0]), "material.prony_tau_s", "> 0"),
    (with_(prony_g=[0.1, 0.2], prony_tau_s=[1.0]), "material.prony_tau_s", "as many"),
    (with_(prony_g=[0.1]), "material.prony_tau_s", "as many"),
    (with_(prony_g=[0.01] * 7, prony_tau_s=[1.0] * 7), "material.prony_g", "0 to 6"),
    (with_(moduli="relaxed"), "material.moduli", "long_term"),
    (with_(model="ogden"), "material.model", "hyperfoam"),
    (with_(model=None), "material.model", "required"),
    (with_(nuu=0.3), "material.nuu", "unknown key"),
    (with_(c10_MPa=0.3), "material.c10_MPa", "unknown key"),
    ({"model": "neo_hookean", "mu_MPa": 0.0, "nu": 0.3}, "material.mu_MPa", "> 0"),
    ({"model": "mooney_rivlin", "c10_MPa": 0.05, "c01_MPa": -0.06, "nu": 0.3},
     "material.c10_MPa", "> 0"),
    ({"model": "yeoh", "c10_MPa": -0.01, "nu": 0.3}, "material.c10_MPa", "> 0"),
    ({"model": "yeoh", "c10_MPa": 0.01, "nu": 0.5}, "material.nu", "0.499"),
    ("silicon", "material", "silicone_gls40"),
    (42, "material", "catalogue name or a table"),
]  # fmt: skip


@pytest.mark.parametrize(("spec", "field", "text"), BAD)
def test_invalid_input_names_the_field(spec, field: str, text: str) -> None:
    with pytest.raises(DesignError) as err:
        material_from_spec(spec)
    assert err.value.field == field
    assert text in err.value.message


def test_error_field_is_the_dotted_path() -> None:
    with pytest.raises(DesignError) as err:
        material_from_spec(with_(nu=0.5), field="layers[1].material")
    assert err.value.field == "layers[1].material.nu"
    with pytest.raises(DesignError) as err:
        LAWS["yeoh"].from_params({"c10_MPa": 0.1, "nu": 0.3, "c40_MPa": 1.0}, "skin")
    assert err.value.field == "skin.c40_MPa"
    with pytest.raises(DesignError):
        Hyperfoam(mu_MPa=[0.1], alpha=[2.0], nu=0.5)  # direct construction validates too
