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
    Ogden,
    Prony,
    Yeoh,
    catalogue_material,
    material_from_spec,
    prony_stress,
    prony_stress_split,
    prony_update,
    prony_update_split,
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
    "ogden": (Ogden(mu_MPa=[0.03, 0.002, -0.001], alpha=[1.5, 6.0, -2.5], nu=0.4), 0.2),
    "ogden_neo_hookean": (Ogden(mu_MPa=[0.1], alpha=[2.0], nu=0.45), 0.1),
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


@pytest.mark.parametrize("name", LAW_IDS)
def test_a_layers_strided_slice_gives_the_bits_of_a_contiguous_copy(name: str) -> None:
    """The compiled laws read a layer's points as the assembly hands them over, a slice of the
    elements (not contiguous in memory): the same bits as on a contiguous copy, in plane strain
    and in 3D, whole and split."""
    law, ln_j = LAW_CASES[name]
    C = C_of(deformations(ln_j, 24, seed=4)).reshape(3, 6, 4)
    C3 = np.zeros((6, 6, 4))
    C3[[0, 1, 3]], C3[2] = C, 1.0 + 0.1 * C[2]
    C3[4], C3[5] = 0.05 * C[0], -0.03 * C[1]
    for array, methods in (
        (C, ("stress_tangent", "stress_tangent_split")),
        (C3, ("stress_tangent3", "stress_tangent3_split")),
    ):
        strided = array[:, 1:5]
        assert not strided.flags.c_contiguous
        for method in methods if law.decoupled else methods[:1]:
            got = getattr(law, method)(strided)
            want = getattr(law, method)(np.ascontiguousarray(strided))
            for g, w in zip(got, want, strict=True):
                np.testing.assert_array_equal(g, w)


# --------------------------------------------------------------------------------------------
# Isochoric / volumetric split of the decoupled (invariant) laws

SPLIT_IDS = [n for n in LAW_IDS if LAW_CASES[n][0].decoupled]


def test_only_the_invariant_laws_are_decoupled() -> None:
    assert SPLIT_IDS == ["neo_hookean", "mooney_rivlin", "yeoh", "ogden", "ogden_neo_hookean"]
    foam = LAW_CASES["silicone"][0]
    for method in (foam.evaluate_split, foam.stress_split, foam.stress_tangent_split):
        with pytest.raises(NotImplementedError, match="isochoric and volumetric"):
            method(np.array([1.0, 1.0, 0.0]))


@pytest.mark.parametrize("name", SPLIT_IDS)
def test_split_parts_match_finite_differences_of_their_own_energies(name: str) -> None:
    """S_part = dW_part/dE and D_part = dS_part/dE for each part, and the parts sum to the
    whole law's W, S, D (to rounding: the sums are formed in another order)."""
    law, ln_j = LAW_CASES[name]
    C = probe_states(ln_j)
    W, S, D = law.evaluate_split(C)
    n = C.shape[1]
    assert W.shape == (2, n) and S.shape == (2, 3, n) and D.shape == (2, 3, 3, n)
    h = 1e-5
    mu0 = law.initial_shear_modulus_MPa
    for part in (0, 1):
        S_fd = np.moveaxis(fd_strain(lambda c, p=part: law.evaluate_split(c)[0][p], C, h), -1, 0)
        D_fd = np.moveaxis(fd_strain(lambda c, p=part: law.stress_split(c)[p], C, h), -1, 1)
        for k in range(n):
            s_scale = max(np.abs(S[part, :, k]).max(), mu0)
            d_scale = max(np.abs(D[part, :, :, k]).max(), mu0)
            assert np.abs(S_fd[:, k] - S[part, :, k]).max() <= 1e-7 * s_scale, (part, k)
            assert np.abs(D_fd[:, :, k] - D[part, :, :, k]).max() <= 1e-7 * d_scale, (part, k)
        np.testing.assert_array_equal(D[part], np.swapaxes(D[part], 0, 1))
    W0, S0, D0 = law.evaluate(C)
    np.testing.assert_allclose(W.sum(axis=0), W0, rtol=0, atol=1e-15 * mu0)
    np.testing.assert_allclose(S.sum(axis=0), S0, rtol=0, atol=4e-16 * np.abs(S0).max())
    np.testing.assert_allclose(D.sum(axis=0), D0, rtol=0, atol=4e-16 * np.abs(D0).max())
    np.testing.assert_allclose(law.S33_split(C).sum(axis=0), law.S33(C), rtol=0, atol=1e-15)
    S2, D2 = law.stress_tangent_split(C)  # the Newton path: the same arrays
    np.testing.assert_array_equal(S2, S)
    np.testing.assert_array_equal(D2, D)
    np.testing.assert_array_equal(law.stress_split(C), S)


@pytest.mark.parametrize("name", SPLIT_IDS)
def test_isochoric_stress_is_deviatoric_and_volumetric_stress_is_the_pressure(name: str) -> None:
    """3D, with C33 = 1: C : S_iso = 0 (the isochoric Kirchhoff stress is traceless) and
    S_vol = J U'(J) C^-1 with U'(J) = K (J - 1) (a pure pressure)."""
    law, ln_j = LAW_CASES[name]
    C = C_of(deformations(ln_j, 10, seed=13))
    S = law.stress_split(C)
    S33 = law.S33_split(C)
    trace = C[0] * S[0, 0] + C[1] * S[0, 1] + 2.0 * C[2] * S[0, 2] + S33[0]
    assert np.abs(trace).max() <= 1e-14 * np.abs(S[0]).max()
    det = C[0] * C[1] - C[2] ** 2
    J = np.sqrt(det)
    pJ = law.bulk_modulus_MPa * (J - 1.0) * J  # J U'(J)
    C_inv = np.array([C[1], C[0], -C[2]]) / det
    np.testing.assert_allclose(S[1], pJ * C_inv, rtol=1e-13, atol=1e-16)
    np.testing.assert_allclose(S33[1], pJ, rtol=1e-13, atol=1e-16)


@pytest.mark.parametrize("name", SPLIT_IDS)
def test_scaled_moduli_scales_shear_and_bulk_apart(name: str) -> None:
    law, ln_j = LAW_CASES[name]
    C = C_of(deformations(ln_j, 4, seed=6))
    stiff = law.scaled_moduli(shear=2.0, bulk=1.0)  # a larger mu, the same K: a smaller nu
    assert math.isclose(stiff.initial_shear_modulus_MPa, 2.0 * law.initial_shear_modulus_MPa)
    assert math.isclose(stiff.bulk_modulus_MPa, law.bulk_modulus_MPa, rel_tol=1e-13)
    assert stiff.nu < law.nu
    S, S2 = law.stress_split(C), stiff.stress_split(C)
    np.testing.assert_allclose(S2[0], 2.0 * S[0], rtol=1e-13, atol=1e-16)
    np.testing.assert_allclose(S2[1], S[1], rtol=1e-12, atol=1e-16)
    assert law.scaled_moduli(1.7, 1.7) == law.scaled(1.7)  # equal factors: nu kept exactly
    with pytest.raises(ValueError, match="> 0"):
        law.scaled_moduli(0.0, 1.0)


def test_hyperfoam_scales_shear_and_bulk_together_only() -> None:
    foam = LAW_CASES["polyurethane"][0]
    assert foam.scaled_moduli(2.0, 2.0) == foam.scaled(2.0)
    with pytest.raises(ValueError, match="couples shear and bulk"):
        foam.scaled_moduli(2.0, 1.0)


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


@pytest.mark.parametrize("name", ["ogden", "ogden_neo_hookean"])
def test_ogden_cauchy_stress_matches_principal_formula(name: str) -> None:
    """sigma_a = (1/J) sum (2 mu_p / alpha_p) [lb_a^alpha_p - (1/3) sum_b lb_b^alpha_p]
    + K (J - 1), lb = J^(-1/3) lambda (Abaqus' Ogden form)."""
    law, ln_j = LAW_CASES[name]
    rng = np.random.default_rng(17)
    for _ in range(8):
        l1 = math.exp(rng.uniform(-0.3, 0.3))
        l2 = math.exp(rng.uniform(-ln_j, ln_j)) / l1
        theta = rng.uniform(0, math.pi)
        F = rot(theta) @ np.diag([l1, l2]) @ rot(rng.uniform(0, math.pi)).T
        J = l1 * l2
        lb = np.array([l1, l2, 1.0]) * J ** (-1.0 / 3.0)
        dev = np.zeros(3)
        for m, a in zip(law.mu_MPa, law.alpha, strict=True):
            dev += 2 * m / a * (lb**a - np.mean(lb**a))
        principal = dev / J + law.bulk_modulus_MPa * (J - 1.0)
        R = np.eye(3)
        R[:2, :2] = rot(theta)
        expected = R @ np.diag(principal) @ R.T
        got = cauchy_from_S(law, F[None])[0]
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12 * np.abs(expected).max())


def test_one_term_ogden_with_alpha_2_is_neo_hookean() -> None:
    """alpha = 2: 2 mu / 4 (I1b - 3) = mu/2 (I1b - 3), the neo-Hookean energy."""
    C = C_of(deformations(0.1, 6, seed=21))
    og, nh = Ogden(mu_MPa=[0.1], alpha=[2.0], nu=0.45), NeoHookean(mu_MPa=0.1, nu=0.45)
    for a, b in zip(og.evaluate(C), nh.evaluate(C), strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-15)


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
# Shear and bulk relaxation apart (g_i, k_i)

G2, TAU2 = (0.3, 0.38), (0.1, 1.0)  # relaxes by 68 %, as the problem statement's example


def shear_only(law) -> Material:
    """``law`` relaxing its shear by 68 %, bulk elastic (the default for invariant laws)."""
    return Material(law, Prony(G2, TAU2))


def relax_held(mat: Material, C: np.ndarray, times: np.ndarray):
    """Step to ``C`` at t = 0 and hold it: yields ``(t, S (3, ...), S33 (...))``.

    S33 rides along the same recursion as a fourth stress component (the in-plane ``S`` is
    checked against ``Material.relax`` itself)."""
    S0 = mat.instantaneous.stress_split(C)
    S0_4 = np.concatenate([S0, mat.instantaneous.S33_split(C)[:, None]], axis=1)
    zero = np.zeros_like(S0_4)
    H = np.zeros((len(mat.prony.g), *S0_4.shape))
    S0_in = mat.instantaneous_stress(C)  # split or not, as the material keeps it
    old_in, H_in = mat.initial_state(C.shape[1:])
    t_prev, old = 0.0, zero
    for t in times:
        dt = float(t - t_prev)
        S4, H, _ = prony_update_split(S0_4, old, H, dt, mat.prony.g, mat.prony_k, mat.prony.tau_s)
        S_in, H_in, _ = mat.relax(S0_in, old_in, H_in, dt)
        np.testing.assert_allclose(S_in, S4[:3], rtol=1e-14, atol=1e-17)
        old, old_in, t_prev = S0_4, S0_in, t
        yield float(t), S4[:3], S4[3]


def cauchy3(C: np.ndarray, F: np.ndarray, S: np.ndarray, S33: float) -> np.ndarray:
    """3x3 Cauchy stress from in-plane F (2x2), S (Voigt) and S33 (F33 = 1)."""
    J = np.linalg.det(F)
    sig = np.zeros((3, 3))
    sig[:2, :2] = F @ to_mat(S) @ F.T / J
    sig[2, 2] = S33 / J
    return sig


TIMES = np.array([0.0, 0.02, 0.1, 0.3, 1.0, 3.0, 30.0])


@pytest.mark.parametrize("name", SPLIT_IDS)
def test_shear_only_relaxation_keeps_the_pressure_and_relaxes_the_shear(name: str) -> None:
    """(a) A held dilatation (in-plane C = l^2 I, C33 = 1) and a held simple shear, k_i = 0:
    the pressure -tr(sigma)/3 stays at the elastic -K (J - 1) while the shear stress of the
    shear step follows g(t); with k_i = g_i the pressure relaxes as g(t) too."""
    law, _ = LAW_CASES[name]
    mat = shear_only(law)
    assert mat.prony.k is None and mat.prony_k == (0.0, 0.0) and mat.split_relaxation
    K = mat.instantaneous.bulk_modulus_MPa
    assert math.isclose(K, law.bulk_modulus_MPa, rel_tol=1e-13)  # the bulk does not relax

    lam = 0.93  # 14 % volume loss in plane strain: not purely volumetric (C33 = 1) ...
    F = np.diag([lam, lam])
    C = C_of(F[None])[:, 0]
    J = lam * lam
    pressures, deviators = [], []
    for _, S, S33 in relax_held(mat, C, TIMES):
        sig = cauchy3(C, F, S, S33)
        pressures.append(-np.trace(sig) / 3.0)
        deviators.append(sig[0, 0] - sig[2, 2])
    # ... but its pressure is the volumetric part alone, and that part does not relax
    np.testing.assert_allclose(pressures, -K * (J - 1.0), rtol=1e-12)
    g_t = mat.prony.relaxation(TIMES)
    np.testing.assert_allclose(np.array(deviators) / deviators[0], g_t, rtol=1e-12)
    assert abs(deviators[0]) > 1e-3 * abs(pressures[0])  # there is a deviator to relax

    gamma = 0.2  # simple shear, J = 1: no pressure at all
    F = np.array([[1.0, gamma], [0.0, 1.0]])
    C = C_of(F[None])[:, 0]
    tau0 = None
    for t, S, S33 in relax_held(mat, C, TIMES):
        sig = cauchy3(C, F, S, S33)
        tau0 = sig[0, 1] if tau0 is None else tau0
        assert math.isclose(sig[0, 1] / tau0, float(mat.prony.relaxation(t)), rel_tol=1e-12)
        assert abs(np.trace(sig)) <= 1e-12 * abs(tau0)

    # whole-stress relaxation of the same law (k = g): the pressure relaxes by 68 % too
    whole = Material(law, Prony(G2, TAU2, k=G2))
    assert not whole.split_relaxation and whole.prony.k == G2  # not the default: kept
    F = np.diag([lam, lam])
    C = C_of(F[None])[:, 0]
    p = [-np.trace(cauchy3(C, F, S, S33)) / 3.0 for _, S, S33 in relax_held(whole, C, TIMES)]
    np.testing.assert_allclose(np.array(p) / p[0], g_t, rtol=1e-12)


def test_history_held_is_the_weighted_sum_of_the_state() -> None:
    """With the history held (a re-equilibration after a cycle jump), the compiled recursion
    gives S = g_inf S0 + sum g_i H_i, and split, + k_inf S0_vol + sum k_i H_i^vol."""
    rng = np.random.default_rng(11)
    g, k = np.array(G2), np.array([0.1, 0.05])
    S0, H = rng.normal(size=(3, 5, 2)), rng.normal(size=(2, 3, 5, 2))
    S, g_inf = prony_stress(S0, H, g)
    assert g_inf == pytest.approx(1.0 - g.sum(), rel=1e-15)
    np.testing.assert_allclose(S, g_inf * S0 + g[0] * H[0] + g[1] * H[1], rtol=1e-14, atol=1e-14)
    S0s, Hs = rng.normal(size=(2, 3, 5, 2)), rng.normal(size=(2, 2, 3, 5, 2))
    Ss, factors = prony_stress_split(S0s, Hs, g, k)
    want = factors[0] * S0s[0] + factors[1] * S0s[1]
    want = want + g[0] * Hs[0, 0] + g[1] * Hs[1, 0] + k[0] * Hs[0, 1] + k[1] * Hs[1, 1]
    np.testing.assert_allclose(Ss, want, rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(factors, [1.0 - g.sum(), 1.0 - k.sum()], rtol=1e-15)


@pytest.mark.parametrize("name", SPLIT_IDS)
def test_split_update_with_k_equal_g_is_whole_stress_relaxation(name: str) -> None:
    """(b) k_i = g_i through the split recursion = today's whole-stress recursion of S0_iso +
    S0_vol, step by step over a random strain history (stress, history and tangent)."""
    law, ln_j = LAW_CASES[name]
    mat = Material(law, Prony(G2, TAU2, k=G2), moduli="instantaneous")
    Cs = C_of(deformations(ln_j, 8, seed=21)).T.reshape(8, 3, 1)
    rng = np.random.default_rng(2)
    dts = np.concatenate([[0.0], rng.uniform(0.0, 2.0, 7)])
    S0_old_s, H_s = np.zeros((2, 3, 1)), np.zeros((2, 2, 3, 1))
    S0_old_w, H_w = np.zeros((3, 1)), np.zeros((2, 3, 1))
    for C, dt in zip(Cs, dts, strict=True):
        (S0s, D0s), (S0w, D0w) = law.stress_tangent_split(C), law.stress_tangent(C)
        S_s, H_s, f_s = prony_update_split(S0s, S0_old_s, H_s, dt, G2, G2, TAU2)
        S_w, H_w, f_w = mat.relax(S0w, S0_old_w, H_w, dt)
        scale = np.abs(S_w).max()
        np.testing.assert_allclose(S_s, S_w, rtol=0, atol=1e-14 * scale)
        np.testing.assert_allclose(H_s.sum(axis=1), H_w, rtol=0, atol=1e-14 * scale)
        assert f_s[0] == f_s[1] == pytest.approx(f_w, rel=1e-15)
        D_s = f_s[0] * D0s[0] + f_s[1] * D0s[1]
        np.testing.assert_allclose(D_s, mat.tangent(D0w, f_w), rtol=0, atol=1e-14 * abs(D_s).max())
        S0_old_s, S0_old_w = S0s, S0w


@pytest.mark.parametrize("name", SPLIT_IDS)
@pytest.mark.parametrize("k", [None, (0.1, 0.05)])
def test_viscoelastic_tangent_matches_finite_differences(name: str, k) -> None:
    """(c) dS/dE of the whole update (instantaneous law + split recursion, history from a
    previous state) equals Material.tangent(D0, factor), for steps from 0 to >> tau."""
    law, ln_j = LAW_CASES[name]
    mat = Material(law, Prony(G2, TAU2, k=k))
    assert mat.split_relaxation
    C_all = C_of(deformations(ln_j, 6, seed=8))
    C_old, C_new = C_all[:, :3], C_all[:, 3:]
    rng = np.random.default_rng(5)
    S0_old = mat.instantaneous_stress(C_old)
    H = rng.normal(scale=0.01, size=(2, *S0_old.shape))
    for dt in (0.0, 0.03, 0.4, 50.0):
        S0, D0 = mat.instantaneous_stress_tangent(C_new)
        _, _, factor = mat.relax(S0, S0_old, H, dt)
        D = mat.tangent(D0, factor)

        def stress(c, dt=dt):
            return mat.relax(mat.instantaneous_stress(c), S0_old, H, dt)[0]

        D_fd = np.moveaxis(fd_strain(stress, C_new, 1e-5), -1, 1)
        np.testing.assert_allclose(D_fd, D, rtol=0, atol=1e-8 * np.abs(D).max())
    # history held (frozen): the factor is (g_inf, k_inf)
    _, factor = mat.history_stress(S0, H)
    np.testing.assert_allclose(factor, [mat.prony.g_inf, mat.k_inf], rtol=1e-15)
    D_fd = np.moveaxis(
        fd_strain(lambda c: mat.history_stress(mat.instantaneous_stress(c), H)[0], C_new, 1e-5),
        -1,
        1,
    )
    np.testing.assert_allclose(D_fd, mat.tangent(D0, factor), rtol=0, atol=1e-8 * np.abs(D).max())


@pytest.mark.parametrize("name", SPLIT_IDS)
def test_long_term_convention_with_shear_only_relaxation(name: str) -> None:
    """moduli = long_term: the instantaneous law has mu / g_inf but the same K (a smaller nu),
    and a held strain relaxes to the given (long-term) law; moduli = instantaneous: the
    long-term law has g_inf mu and k_inf K."""
    law, ln_j = LAW_CASES[name]
    mat = shear_only(law)
    inst = mat.instantaneous
    g_inf = mat.prony.g_inf
    assert math.isclose(inst.initial_shear_modulus_MPa, law.initial_shear_modulus_MPa / g_inf)
    assert math.isclose(inst.bulk_modulus_MPa, law.bulk_modulus_MPa, rel_tol=1e-13)
    assert inst.nu < law.nu and mat.k_inf == 1.0
    C = C_of(deformations(ln_j, 3, seed=9))
    S0 = mat.instantaneous_stress(C)
    S, H, _ = mat.relax(S0, np.zeros_like(S0), mat.initial_state(C.shape[1:])[1], 0.0)
    np.testing.assert_allclose(S, inst.stress(C), rtol=1e-13, atol=1e-16)  # t = 0+
    S, H, _ = mat.relax(S0, S0, H, 2000.0 * max(TAU2))
    np.testing.assert_allclose(S, law.stress(C), rtol=1e-12, atol=1e-16)  # t -> inf
    assert mat.long_term == law

    both = Material(law, Prony(G2, TAU2, k=(0.1, 0.2)), moduli="instantaneous")
    lt = both.long_term
    assert math.isclose(lt.initial_shear_modulus_MPa, g_inf * law.initial_shear_modulus_MPa)
    assert math.isclose(lt.bulk_modulus_MPa, 0.7 * law.bulk_modulus_MPa, rel_tol=1e-13)
    np.testing.assert_allclose(both.bulk_relaxation([0.0, 1e9]), [1.0, 0.7], rtol=1e-15)


def test_default_bulk_coefficients_and_canonical_form() -> None:
    """Left out, k is the law's default; given equal to it, it is stored as left out."""
    nh = NeoHookean(mu_MPa=0.1, nu=0.45)
    foam = LAW_CASES["polyurethane"][0]
    assert Material(nh, Prony(G2, TAU2, k=(0.0, 0.0))) == Material(nh, Prony(G2, TAU2))
    assert Material(foam, Prony(G2, TAU2, k=G2)) == Material(foam, Prony(G2, TAU2))
    assert Material(foam, Prony(G2, TAU2)).prony_k == G2  # hyperfoam: the whole stress
    assert not Material(foam, Prony(G2, TAU2)).split_relaxation
    assert Material(nh, Prony(G2, TAU2, k=G2)).prony.k == G2  # not nh's default: kept
    bulk_only = Material(nh, Prony((0.0,), (1.0,), k=(0.2,)))
    assert not bulk_only.is_elastic and bulk_only.split_relaxation
    assert Material(nh, Prony((0.0,), (1.0,))).is_elastic
    assert Material(nh).is_elastic and not Material(nh).split_relaxation


def test_hyperfoam_refuses_separate_bulk_relaxation() -> None:
    """(e) The hyperfoam's shear and bulk are coupled (Abaqus: same relaxation data)."""
    foam = LAW_CASES["polyurethane"][0]
    with pytest.raises(DesignError) as err:
        Material(foam, Prony(G2, TAU2, k=(0.0, 0.0)))
    assert err.value.field == "prony_k"
    assert "\n" not in str(err.value)
    spec = {**GOOD, "prony_g": [0.2], "prony_tau_s": [1.0], "prony_k": [0.1]}
    with pytest.raises(DesignError) as err:
        material_from_spec(spec, field="layers[0].material")
    assert err.value.field == "layers[0].material.prony_k"
    assert "hyperfoam" in err.value.message and "prony_g" in err.value.message


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
    assert set(LAWS) == {"hyperfoam", "neo_hookean", "mooney_rivlin", "yeoh", "ogden"}


INLINE = [
    {"model": "neo_hookean", "mu_MPa": 0.1, "nu": 0.45},
    {"model": "mooney_rivlin", "c10_MPa": 0.05, "c01_MPa": 0.01, "nu": 0.4, "prony_g": [0.3],
     "prony_tau_s": [0.5], "moduli": "instantaneous"},
    {"model": "yeoh", "c10_MPa": 0.05, "c20_MPa": 0.002, "nu": 0.45},
    {"model": "hyperfoam", "mu_MPa": [0.1, 0.02, -0.01], "alpha": [2, 8, -1e-3], "nu": 0.3},
    {"model": "neo_hookean", "mu_MPa": 0.1, "nu": 0.45, "prony_g": [0.3, 0.38],
     "prony_tau_s": [0.1, 1.0], "prony_k": [0.05, 0.0]},
    {"model": "yeoh", "c10_MPa": 0.05, "nu": 0.45, "prony_g": [0.3], "prony_tau_s": [0.1],
     "prony_k": [0.3], "moduli": "instantaneous"},
]  # fmt: skip


@pytest.mark.parametrize("spec", [*INLINE, "silicone_gls40", "polyurethane_74_45"])
def test_round_trip_through_design_form(spec) -> None:
    mat = material_from_spec(spec)
    assert material_from_spec(mat.to_dict()) == mat
    assert type(mat.law).from_params(mat.law.to_dict(), "x") == mat.law
    if isinstance(spec, dict):
        assert mat.is_elastic == ("prony_g" not in spec)
        assert mat.moduli == spec.get("moduli", "long_term")
        assert mat.to_dict().get("prony_k") == spec.get("prony_k")  # only when not the default


PRONY_K_TOML = """\
[shear_only]
model = "mooney_rivlin"
c10_MPa = 0.05
c01_MPa = 0.01
nu = 0.45
prony_g = [0.3, 0.38]
prony_tau_s = [0.1, 1.0]

[default_written_out]
model = "mooney_rivlin"
c10_MPa = 0.05
c01_MPa = 0.01
nu = 0.45
prony_g = [0.3, 0.38]
prony_tau_s = [0.1, 1.0]
prony_k = [0.0, 0.0]

[bulk_too]
model = "neo_hookean"
mu_MPa = 0.1
nu = 0.45
prony_g = [0.3, 0.38]
prony_tau_s = [0.1, 1.0]
prony_k = [0.1, 0.02]

[foam]
model = "hyperfoam"
mu_MPa = [0.1]
alpha = [4.0]
nu = 0.45
prony_g = [0.3, 0.38]
prony_tau_s = [0.1, 1.0]
prony_k = [0.3, 0.38]
"""


def test_round_trip_of_the_prony_k_key() -> None:
    """(f) prony_k from TOML: given, defaulted or written out as the default; to_dict writes
    it only when it differs from the default, and the table reads back to the same material."""
    import tomllib

    tables = tomllib.loads(PRONY_K_TOML)
    mats = {name: material_from_spec(t, field=name) for name, t in tables.items()}
    assert mats["shear_only"] == mats["default_written_out"]
    assert mats["shear_only"].prony_k == (0.0, 0.0)
    assert mats["bulk_too"].prony_k == (0.1, 0.02) and mats["bulk_too"].k_inf == pytest.approx(0.88)
    assert mats["foam"].prony_k == mats["foam"].prony.g and mats["foam"].prony.k is None
    for name, mat in mats.items():
        data = mat.to_dict()
        assert ("prony_k" in data) == (name == "bulk_too"), name
        assert material_from_spec(data) == mat


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
    (with_(prony_g=[0.1], prony_tau_s=[1.0], prony_k=[0.0]), "material.prony_k", "coupled"),
    ({"model": "neo_hookean", "mu_MPa": 0.1, "nu": 0.45, "prony_g": [0.1], "prony_tau_s": [1.0],
      "prony_k": [-0.1]}, "material.prony_k", ">= 0"),
    ({"model": "neo_hookean", "mu_MPa": 0.1, "nu": 0.45, "prony_g": [0.1, 0.1],
      "prony_tau_s": [1.0, 2.0], "prony_k": [0.5, 0.5]}, "material.prony_k", "sum must be < 1"),
    ({"model": "neo_hookean", "mu_MPa": 0.1, "nu": 0.45, "prony_g": [0.1], "prony_tau_s": [1.0],
      "prony_k": [0.1, 0.1]}, "material.prony_k", "as many terms as prony_g"),
    ({"model": "neo_hookean", "mu_MPa": 0.1, "nu": 0.45, "prony_k": [0.1]},
     "material.prony_k", "as many terms as prony_g"),
    ({"model": "neo_hookean", "mu_MPa": 0.1, "nu": 0.45, "prony_g": [0.1], "prony_tau_s": [1.0],
      "prony_k": 0.1}, "material.prony_k", "list"),
    (with_(moduli="relaxed"), "material.moduli", "long_term"),
    (with_(model="arruda_boyce"), "material.model", "hyperfoam"),
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
