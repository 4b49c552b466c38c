"""Physics checks of the 3D constitutive laws (``evaluate3`` etc., sim.materials._law3).

Voigt conventions: ``C = [C11, C22, C33, C12, C23, C13]``, ``S`` in the same order, ``D`` maps
``dE = [dE11, dE22, dE33, 2 dE12, 2 dE23, 2 dE13]`` to ``dS``; units MPa.  The plane-strain
laws (``evaluate``, tests/test_materials.py) are the reference where ``C33 = 1``.
"""

from __future__ import annotations

import functools
import importlib
import math

import numpy as np
import pytest

from sim.materials import (
    CATALOGUE,
    LAWS,
    Hyperfoam,
    MooneyRivlin,
    NeoHookean,
    Ogden,
    Yeoh,
)
from sim.materials._law3 import PLANE, VOIGT3, eigh3

# (law, largest |ln J| of the random states), as tests/test_materials.py, plus an Ogden term
# with a tiny exponent (the silicone hyperfoam's alpha) next to a stiff one.
LAW_CASES = {
    "silicone": (CATALOGUE["silicone_gls40"].law, 0.02),
    "polyurethane": (CATALOGUE["polyurethane_74_45"].law, 0.04),
    "hyperfoam_3term": (Hyperfoam(mu_MPa=[0.1, -0.02, 0.05], alpha=[2.0, -3.0, 0.5], nu=0.3), 0.3),
    "hyperfoam_nu0": (Hyperfoam(mu_MPa=[0.2], alpha=[3.0], nu=0.0), 0.3),
    "hyperfoam_auxetic": (Hyperfoam(mu_MPa=[-0.02, 0.1], alpha=[-2.0, 6.0], nu=-0.4), 0.3),
    "neo_hookean": (NeoHookean(mu_MPa=0.1, nu=0.45), 0.1),
    "mooney_rivlin": (MooneyRivlin(c10_MPa=0.05, c01_MPa=0.02, nu=0.3), 0.3),
    "yeoh": (Yeoh(c10_MPa=0.05, c20_MPa=-0.01, c30_MPa=0.003, nu=0.4), 0.2),
    "ogden": (Ogden(mu_MPa=[0.03, 0.002, -0.001], alpha=[1.5, 6.0, -2.5], nu=0.4), 0.2),
    "ogden_neo_hookean": (Ogden(mu_MPa=[0.1], alpha=[2.0], nu=0.45), 0.1),
    "ogden_small_alpha": (Ogden(mu_MPa=[0.08, 0.01], alpha=[0.001, 8.0], nu=0.45), 0.1),
}
# Every catalogue material (sim/data/materials.toml): nearly incompressible, probed near J = 1.
CATALOGUE_CASES = {f"catalogue:{name}": (mat.law, 0.02) for name, mat in CATALOGUE.items()}
ALL_CASES = {**LAW_CASES, **CATALOGUE_CASES}
ALL_IDS = list(ALL_CASES)
SPLIT_IDS = [n for n in ALL_IDS if ALL_CASES[n][0].decoupled]
SPECTRAL_IDS = [n for n in ALL_IDS if isinstance(ALL_CASES[n][0], Ogden | Hyperfoam)]

# Column j: the change of C for a unit change of Voigt strain component j (C = I + 2E).
DC_DE = np.diag([2.0, 2.0, 2.0, 1.0, 1.0, 1.0])
PLANE_IX = np.ix_(PLANE, PLANE)


# --------------------------------------------------------------------------------------------
# Helpers


def to_mat(x: np.ndarray) -> np.ndarray:
    """Voigt (6, *batch) -> symmetric (*batch, 3, 3)."""
    m = np.empty((3, 3, *x.shape[1:]))
    for k, (i, j) in enumerate(VOIGT3):
        m[i, j] = m[j, i] = x[k]
    return np.moveaxis(m, (0, 1), (-2, -1))


def to_voigt(m: np.ndarray) -> np.ndarray:
    """(*batch, 3, 3) -> Voigt (6, *batch) (the symmetric part)."""
    return np.stack([0.5 * (m[..., i, j] + m[..., j, i]) for i, j in VOIGT3])


def to_tensor4(D: np.ndarray) -> np.ndarray:
    """Voigt (6, 6, *batch) -> (3, 3, 3, 3, *batch) with the minor symmetries."""
    out = np.empty((3, 3, 3, 3, *D.shape[2:]))
    for a, (i, j) in enumerate(VOIGT3):
        for b, (k, m) in enumerate(VOIGT3):
            for p, q in {(i, j), (j, i)}:
                for r, s in {(k, m), (m, k)}:
                    out[p, q, r, s] = D[a, b]
    return out


def from_tensor4(T: np.ndarray) -> np.ndarray:
    return np.array([[T[i, j, k, m] for k, m in VOIGT3] for i, j in VOIGT3])


def rotation(rng: np.random.Generator) -> np.ndarray:
    """A random proper rotation (QR of a Gaussian matrix, signs fixed)."""
    Q, R = np.linalg.qr(rng.normal(size=(3, 3)))
    Q = Q * np.sign(np.diag(R))
    return Q if np.linalg.det(Q) > 0 else -Q


def deformations(ln_j_max: float, n: int, seed: int = 0) -> np.ndarray:
    """Random F = Q1 diag(l) Q2^T with det F > 0, isochoric stretches within exp(+-0.3) and
    |ln J| <= ln_j_max, shape (n, 3, 3)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        e = rng.uniform(-0.3, 0.3, 3)
        e += rng.uniform(-ln_j_max, ln_j_max) / 3.0 - e.mean()
        out.append(rotation(rng) @ np.diag(np.exp(e)) @ rotation(rng).T)
    return np.array(out)


def C_of(F: np.ndarray) -> np.ndarray:
    return to_voigt(np.swapaxes(F, -1, -2) @ F)


def principal_states(c: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """C = Q diag(c) Q^T for each row of eigenvalues c (n, 3), Voigt (6, n)."""
    return to_voigt(Q @ (c[:, :, None] * np.eye(3)) @ Q.T)


def equal_eigenvalue_states(ln_j: float, split: float = 0.0) -> np.ndarray:
    """Hydrostatic (c, c, c), uniaxial (l^2, c, c) and equibiaxial (c, c, l^-2 ...) states,
    the equal eigenvalues split by +-split (relative), shape (n, 3)."""
    rows = []
    for c in (1.0, math.exp(2 * ln_j / 3), math.exp(-2 * ln_j / 3)):
        for lam in (1.0, 1.2, 0.85):
            rows.append([c * lam * lam, c / lam * (1 + split), c / lam * (1 - split)])  # uniaxial
            rows.append([c / lam**4, c * lam * lam * (1 + split), c * lam * lam * (1 - split)])
    rows.append([1.0 + split, 1.0, 1.0 - split])
    return np.array(rows)


def probe_states(ln_j_max: float) -> np.ndarray:
    """Equal and nearly equal (1e-9) eigenvalues, rotated and not, plus random states."""
    Q = rotation(np.random.default_rng(42))
    cols = []
    for split in (0.0, 1e-9):
        c = equal_eigenvalue_states(ln_j_max, split)
        cols += [principal_states(c, np.eye(3)), principal_states(c, Q)]
    cols.append(C_of(deformations(ln_j_max, 12)))
    return np.concatenate(cols, axis=1)


def fd_strain(fun, C: np.ndarray, h: float) -> np.ndarray:
    """4th-order central differences of fun(C) w.r.t. Voigt strain; result (..., 6) last."""
    cols = []
    for j in range(6):
        dC = (DC_DE[:, j] * h).reshape((6,) + (1,) * (C.ndim - 1))
        cols.append(
            (-fun(C + 2 * dC) + 8 * fun(C + dC) - 8 * fun(C - dC) + fun(C - 2 * dC)) / (12 * h)
        )
    return np.stack(cols, axis=-1)


def plane_strain(C2: np.ndarray) -> np.ndarray:
    """In-plane [C11, C22, C12] (3, n) -> 3D Voigt with C33 = 1, C23 = C13 = 0."""
    C = np.zeros((6, C2.shape[1]))
    C[list(PLANE)] = C2
    C[2] = 1.0
    return C


def plane_states(ln_j: float) -> np.ndarray:
    """Plane-strain states (3, n): in-plane c I, near-equal, and random in-plane F."""
    rng = np.random.default_rng(3)
    cols = [[1.0, 1.0, 0.0], [math.exp(ln_j), math.exp(ln_j), 0.0]]
    for _ in range(12):
        l1 = math.exp(rng.uniform(-0.3, 0.3))
        J = math.exp(rng.uniform(-ln_j, ln_j))
        t1, t2 = rng.uniform(0, math.pi, 2)
        R1 = np.array([[math.cos(t1), -math.sin(t1)], [math.sin(t1), math.cos(t1)]])
        R2 = np.array([[math.cos(t2), -math.sin(t2)], [math.sin(t2), math.cos(t2)]])
        F = R1 @ np.diag([l1, J / l1]) @ R2.T
        M = F.T @ F
        cols.append([M[0, 0], M[1, 1], M[0, 1]])
    return np.array(cols).T


# --------------------------------------------------------------------------------------------
# Derivatives


@pytest.mark.parametrize("name", ALL_IDS)
def test_stress_and_tangent_match_finite_differences(name: str) -> None:
    """S = dW/dE and D = dS/dE (4th-order central differences, engineering shear) at random
    states and at equal / nearly equal eigenvalues; D symmetric; stress3 and stress_tangent3
    give the same arrays as evaluate3."""
    law, ln_j = ALL_CASES[name]
    C = probe_states(ln_j)
    n = C.shape[1]
    W, S, D = law.evaluate3(C)
    assert W.shape == (n,) and S.shape == (6, n) and D.shape == (6, 6, n)
    h = 1e-5
    S_fd = np.moveaxis(fd_strain(lambda c: law.evaluate3(c)[0], C, h), -1, 0)
    D_fd = np.moveaxis(fd_strain(law.stress3, C, h), -1, 1)
    mu0 = law.initial_shear_modulus_MPa
    for k in range(n):
        s_scale = max(np.abs(S[:, k]).max(), mu0)
        d_scale = np.abs(D[:, :, k]).max()
        assert np.abs(S_fd[:, k] - S[:, k]).max() <= 1e-7 * s_scale, (k, C[:, k])
        assert np.abs(D_fd[:, :, k] - D[:, :, k]).max() <= 1e-7 * d_scale, (k, C[:, k])
    np.testing.assert_array_equal(D, np.swapaxes(D, 0, 1))
    np.testing.assert_array_equal(law.stress3(C), S)
    S2, D2 = law.stress_tangent3(C)
    np.testing.assert_array_equal(S2, S)
    np.testing.assert_array_equal(D2, D)


@pytest.mark.parametrize("name", SPLIT_IDS)
def test_split_parts_match_finite_differences_of_their_own_energies(name: str) -> None:
    law, ln_j = ALL_CASES[name]
    C = probe_states(ln_j)
    n = C.shape[1]
    W, S, D = law.evaluate3_split(C)
    assert W.shape == (2, n) and S.shape == (2, 6, n) and D.shape == (2, 6, 6, n)
    h = 1e-5
    mu0 = law.initial_shear_modulus_MPa
    for part in (0, 1):
        S_fd = np.moveaxis(fd_strain(lambda c, p=part: law.evaluate3_split(c)[0][p], C, h), -1, 0)
        D_fd = np.moveaxis(fd_strain(lambda c, p=part: law.stress3_split(c)[p], C, h), -1, 1)
        for k in range(n):
            s_scale = max(np.abs(S[part, :, k]).max(), mu0)
            d_scale = max(np.abs(D[part, :, :, k]).max(), mu0)
            assert np.abs(S_fd[:, k] - S[part, :, k]).max() <= 1e-7 * s_scale, (part, k)
            assert np.abs(D_fd[:, :, k] - D[part, :, :, k]).max() <= 1e-7 * d_scale, (part, k)
        np.testing.assert_array_equal(D[part], np.swapaxes(D[part], 0, 1))
    W0, S0, D0 = law.evaluate3(C)
    np.testing.assert_allclose(W.sum(axis=0), W0, rtol=0, atol=1e-15 * mu0)
    np.testing.assert_allclose(S.sum(axis=0), S0, rtol=0, atol=4e-16 * np.abs(S0).max())
    np.testing.assert_allclose(D.sum(axis=0), D0, rtol=0, atol=1e-15 * np.abs(D0).max())
    S2, D2 = law.stress_tangent3_split(C)
    np.testing.assert_array_equal(S2, S)
    np.testing.assert_array_equal(D2, D)
    np.testing.assert_array_equal(law.stress3_split(C), S)


@pytest.mark.parametrize("name", SPLIT_IDS)
def test_isochoric_stress_is_deviatoric_and_volumetric_stress_is_the_pressure(name: str) -> None:
    """C : S_iso = 0 and S_vol = J U'(J) C^-1, U'(J) = K (J - 1)."""
    law, ln_j = ALL_CASES[name]
    C = C_of(deformations(ln_j, 10, seed=13))
    S = law.stress3_split(C)
    Cm, Sm = to_mat(C), to_mat(S[0])
    trace = np.einsum("nij,nij->n", Cm, Sm)
    assert np.abs(trace).max() <= 1e-13 * np.abs(S[0]).max()
    J = np.sqrt(np.linalg.det(Cm))
    pJ = law.bulk_modulus_MPa * (J - 1.0) * J
    np.testing.assert_allclose(S[1], pJ * to_voigt(np.linalg.inv(Cm)), rtol=1e-12, atol=1e-16)


# --------------------------------------------------------------------------------------------
# Plane-strain reduction: the 3D laws are the 2D laws where C33 = 1


@pytest.mark.parametrize("name", ALL_IDS)
def test_plane_strain_reduction_equals_the_2d_law(name: str) -> None:
    """For C33 = 1, C23 = C13 = 0: W, S[11, 22, 12], D[11, 22, 12]^2 equal evaluate(), S[33]
    equals S33(), and so do the [iso, vol] parts of a decoupled law (to ~1e-12 relative)."""
    law, ln_j = ALL_CASES[name]
    C2 = plane_states(ln_j)
    C3 = plane_strain(C2)
    W2, S2, D2 = law.evaluate(C2)
    W3, S3, D3 = law.evaluate3(C3)
    mu0 = law.initial_shear_modulus_MPa
    for k in range(C2.shape[1]):
        s_scale = max(np.abs(S2[:, k]).max(), mu0)
        d_scale = np.abs(D2[:, :, k]).max()
        assert abs(W3[k] - W2[k]) <= 1e-12 * max(abs(W2[k]), mu0), k
        assert np.abs(S3[PLANE, k] - S2[:, k]).max() <= 1e-12 * s_scale, k
        assert abs(S3[2, k] - law.S33(C2[:, k])) <= 1e-12 * s_scale, k
        assert np.abs(D3[:, :, k][PLANE_IX] - D2[:, :, k]).max() <= 1e-12 * d_scale, k
    np.testing.assert_array_equal(S3[[4, 5]], 0.0 * S3[[4, 5]])  # no out-of-plane shear
    if law.decoupled:
        Ws2, Ss2, Ds2 = law.evaluate_split(C2)
        Ws3, Ss3, Ds3 = law.evaluate3_split(C3)
        S33 = law.S33_split(C2)
        s_scale = np.abs(Ss2).max()
        d_scale = np.abs(Ds2).max()
        np.testing.assert_allclose(Ws3, Ws2, rtol=0, atol=1e-12 * np.abs(Ws2).max())
        np.testing.assert_allclose(Ss3[:, PLANE], Ss2, rtol=0, atol=1e-12 * s_scale)
        np.testing.assert_allclose(Ss3[:, 2], S33, rtol=0, atol=1e-12 * s_scale)
        np.testing.assert_allclose(Ds3[:, :, :][:, PLANE][:, :, PLANE], Ds2, atol=1e-12 * d_scale)


# --------------------------------------------------------------------------------------------
# The eigen-decomposition of the spectral laws (eigh3: compiled cyclic Jacobi)


def check_eigh3(C: np.ndarray, tol: float = 1e-13) -> tuple[np.ndarray, np.ndarray]:
    """``eigh3`` of the Voigt ``C`` (6, n): the shapes, ascending eigenvalues equal to
    ``numpy.linalg.eigvalsh``'s, orthonormal eigenvectors and ``sum_a c_a N_a N_a^T = C``, all
    to ``tol`` relative to the largest |eigenvalue| of each matrix."""
    c, N = eigh3(C)
    n = C.shape[1]
    assert c.shape == (3, n) and N.shape == (3, 3, n)
    assert np.all(np.isfinite(c)) and np.all(np.isfinite(N))
    assert np.all(np.diff(c, axis=0) >= 0.0)
    M = to_mat(C)  # (n, 3, 3)
    ref = np.linalg.eigvalsh(M).T
    scale = np.abs(ref).max(axis=0)
    assert np.all(np.abs(c - ref) <= tol * scale)
    rebuilt = np.einsum("ak,aik,ajk->kij", c, N, N)
    assert np.all(np.abs(rebuilt - M) <= tol * scale[:, None, None])
    gram = np.einsum("aik,bik->kab", N, N)
    assert np.all(np.abs(gram - np.eye(3)) <= tol)
    return c, N


def spectral_states(c: np.ndarray, seed: int) -> np.ndarray:
    """Each row of eigenvalues ``c`` (m, 3) in the principal frame and in four random ones,
    Voigt (6, 5 m)."""
    rng = np.random.default_rng(seed)
    frames = [np.eye(3)] + [rotation(rng) for _ in range(4)]
    return np.concatenate([principal_states(c, Q) for Q in frames], axis=1)


def test_eigh3_matches_numpy_on_random_spd_matrices() -> None:
    """Random SPD matrices (``A A^T + 0.1 I`` and ``C = F^T F``): numpy's eigenvalues to
    1e-13, and numpy's eigenvectors (up to their signs) where the eigenvalues are at least 1e-2
    apart, relative."""
    rng = np.random.default_rng(7)
    A = rng.normal(size=(500, 3, 3))
    C = np.concatenate(
        [to_voigt(A @ np.swapaxes(A, -1, -2) + 0.1 * np.eye(3)), C_of(deformations(0.3, 500))],
        axis=1,
    )
    c, N = check_eigh3(C)
    _, v = np.linalg.eigh(to_mat(C))  # v[k, i, a]
    apart = np.diff(c, axis=0) >= 1e-2 * c[2]
    for a, ok in ((0, apart[0]), (1, apart[0] & apart[1]), (2, apart[1])):
        cos = np.abs(np.einsum("ik,ki->k", N[a], v[:, :, a]))
        assert ok.sum() > 200
        np.testing.assert_allclose(cos[ok], 1.0, rtol=0, atol=1e-12)


def test_eigh3_of_diagonal_matrices_is_exact() -> None:
    """Zero off-diagonals (I, repeated, zero and negative entries): no rotation, so the
    eigenvalues are the sorted diagonal and the eigenvectors the matching unit vectors, exactly
    (nothing divided by a zero off-diagonal)."""
    d = np.array(
        [
            [1.0, 1.0, 1.0],
            [3.0, 1.0, 2.0],
            [2.0, 2.0, 1.0],
            [0.0, 0.0, 0.0],
            [5.0, -1.0, 0.0],
            [1e6, 1.0, 1e-6],
            [1.0, 1.0 + 1e-15, 1.0],
        ]
    )
    C = np.zeros((6, len(d)))
    C[:3] = d.T
    c, N = check_eigh3(C)
    order = np.argsort(d, axis=1, kind="stable")
    np.testing.assert_array_equal(c, np.take_along_axis(d, order, axis=1).T)
    np.testing.assert_array_equal(N, np.moveaxis(np.eye(3)[order], 0, -1))
    np.testing.assert_array_equal(N[..., 0], np.eye(3))  # C = I: N = I


@pytest.mark.parametrize("split", [0.0, 1e-12, 1e-9, 1e-6])
def test_eigh3_of_repeated_and_nearly_repeated_eigenvalues(split: float) -> None:
    """Hydrostatic, uniaxial and equibiaxial states (two or three equal eigenvalues, split by
    +-split) in random frames: the checks of ``check_eigh3``, the eigenvalues the exact ones,
    and the projector on the eigenspace of the nearly equal pair the exact one."""
    c_exact = equal_eigenvalue_states(0.2, split)
    C = spectral_states(c_exact, seed=5)
    c, N = check_eigh3(C)
    c_exact = np.sort(np.tile(c_exact, (5, 1)), axis=1).T
    assert np.all(np.abs(c - c_exact) <= 1e-13 * c_exact[2])
    # The pair within 3 split of each other (a distinct third eigenvalue): its projector.
    for a, b, other in ((0, 1, 2), (1, 2, 0)):
        pair = (c[b] - c[a] <= (3 * split + 1e-12) * c[b]) & (np.abs(c[other] - c[a]) > 0.1 * c[2])
        assert pair.sum() >= 10
        P = np.einsum("ik,jk->kij", N[a], N[a]) + np.einsum("ik,jk->kij", N[b], N[b])
        Nc = N[other]
        P_exact = np.eye(3) - np.einsum("ik,jk->kij", Nc, Nc)
        np.testing.assert_allclose(P[pair], P_exact[pair], rtol=0, atol=1e-13)


def test_eigh3_of_widely_spread_eigenvalues() -> None:
    """Eigenvalue ratios up to 1e6, two of them equal or not, in random frames."""
    c = np.array(
        [[1e-6, 1e-3, 1.0], [1.0, 1.0, 1e6], [1e-6, 1e-6, 1.0], [1e-3, 1.0, 1e3], [2e3, 1e-3, 7.0]]
    )
    check_eigh3(spectral_states(c, seed=9))
    check_eigh3(spectral_states(c * 1e-3, seed=9))


def test_eigh3_point_by_point_and_any_layout() -> None:
    """Each point is decomposed on its own (the same bits alone or in a batch); a strided or
    integer input is accepted; an empty batch gives empty arrays."""
    C = C_of(deformations(0.2, 8, seed=2))
    c, N = eigh3(C)
    for k in range(C.shape[1]):
        ck, Nk = eigh3(C[:, k : k + 1])
        np.testing.assert_array_equal(ck[:, 0], c[:, k])
        np.testing.assert_array_equal(Nk[..., 0], N[..., k])
    c2, N2 = eigh3(np.repeat(C, 2, axis=1)[:, ::2])
    np.testing.assert_array_equal(c2, c)
    np.testing.assert_array_equal(N2, N)
    ci, _ = eigh3(np.array([[2, 1, 1, 0, 0, 0]]).T)
    np.testing.assert_array_equal(ci[:, 0], [1.0, 1.0, 2.0])
    c0, N0 = eigh3(np.zeros((6, 0)))
    assert c0.shape == (3, 0) and N0.shape == (3, 3, 0)


# --------------------------------------------------------------------------------------------
# Equal eigenvalues


@pytest.mark.parametrize("name", ALL_IDS)
def test_undeformed_state_is_isotropic_linear_elasticity(name: str) -> None:
    """C = I: W = 0, S = 0 and D = lambda I(x)I + 2 mu Isym with the law's mu0 and K0
    (D11 = K + 4 mu/3, D12 = K - 2 mu/3, D44 = mu)."""
    law, _ = ALL_CASES[name]
    I = np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0])
    W, S, D = law.evaluate3(I)
    mu, K = law.initial_shear_modulus_MPa, law.bulk_modulus_MPa
    expected = np.zeros((6, 6))
    expected[:3, :3] = K - 2.0 * mu / 3.0
    expected[[0, 1, 2], [0, 1, 2]] = K + 4.0 * mu / 3.0
    expected[[3, 4, 5], [3, 4, 5]] = mu
    assert abs(W) <= 1e-15 * mu
    assert np.abs(S).max() <= 1e-15 * mu
    np.testing.assert_allclose(D, expected, rtol=1e-12, atol=1e-12 * mu)
    if law.decoupled:  # the isochoric part carries mu, the volumetric part K
        _, Ss, Ds = law.evaluate3_split(I)
        assert np.abs(Ss).max() <= 1e-15 * mu
        iso = 2.0 * mu * (np.diag([1.0, 1.0, 1.0, 0.5, 0.5, 0.5]))
        iso[:3, :3] -= 2.0 * mu / 3.0
        np.testing.assert_allclose(Ds[0], iso, rtol=1e-12, atol=1e-12 * mu)
        np.testing.assert_allclose(Ds[1][:3, :3], np.full((3, 3), K), rtol=1e-12)


@pytest.mark.parametrize("name", ALL_IDS)
def test_equal_eigenvalues_are_the_limit_of_nearly_equal_ones(name: str) -> None:
    """Uniaxial, equibiaxial and hydrostatic states (two or three equal eigenvalues), rotated:
    W, S and D at exactly equal eigenvalues differ from those at eigenvalues split by
    +-1e-7 and +-1e-12 (relative) by O(split) (measured <= 2.2 split), and a hydrostatic state
    has an isotropic tangent (D11 - D12 = 2 D44) whatever its eigenvectors."""
    law, ln_j = ALL_CASES[name]
    Q = rotation(np.random.default_rng(8))
    exact = principal_states(equal_eigenvalue_states(ln_j), Q)
    W0, S0, D0 = law.evaluate3(exact)
    mu0 = law.initial_shear_modulus_MPa
    for split in (1e-7, 1e-12):
        W1, S1, D1 = law.evaluate3(principal_states(equal_eigenvalue_states(ln_j, split), Q))
        tol = 10.0 * split
        for k in range(exact.shape[1]):
            d_scale = np.abs(D0[:, :, k]).max()
            s_scale = max(np.abs(S0[:, k]).max(), mu0)
            assert np.abs(D1[:, :, k] - D0[:, :, k]).max() <= tol * d_scale, (split, k)
            assert np.abs(S1[:, k] - S0[:, k]).max() <= tol * s_scale, (split, k)
        np.testing.assert_allclose(W1, W0, rtol=0, atol=tol * mu0)
    for c in (1.0, math.exp(ln_j)):
        D = law.evaluate3(np.array([c, c, c, 0.0, 0.0, 0.0]))[2]
        assert math.isclose(D[0, 0] - D[0, 1], 2.0 * D[3, 3], rel_tol=1e-12)
        Dr = law.evaluate3(principal_states(np.array([[c, c, c]]), Q)[:, 0])[2]
        np.testing.assert_allclose(Dr, D, rtol=0, atol=1e-12 * np.abs(D).max())


@pytest.mark.parametrize("name", SPECTRAL_IDS)
def test_spectral_tangent_on_both_sides_of_nearly_equal_eigenvalues(name: str) -> None:
    """Two eigenvalues c (1 +- split), split from 1e-8 to 1e-2 (the hyperfoam's divided
    difference switches to its Taylor series below 2.5e-3): D against finite differences of S,
    tightly, in a rotated frame."""
    law, _ = ALL_CASES[name]
    Q = rotation(np.random.default_rng(11))
    rows = []
    for c in (0.99, 1.01):
        for split in (1e-8, 1e-6, 1e-4, 2.4e-3, 2.6e-3, 1e-2):
            rows.append([c * (1 + split), c * (1 - split), 1.0 / (c * c)])
            rows.append([c * (1 + split), c * (1 - split), c * (1 + 2 * split)])  # all three
    C = principal_states(np.array(rows), Q)
    D = law.evaluate3(C)[2]
    D_fd = np.moveaxis(fd_strain(law.stress3, C, 1e-5), -1, 1)
    for k in range(C.shape[1]):
        scale = np.abs(D[:, :, k]).max()
        assert np.abs(D_fd[:, :, k] - D[:, :, k]).max() <= 1e-9 * scale, rows[k]


# --------------------------------------------------------------------------------------------
# Objectivity, shapes, closed forms


@pytest.mark.parametrize("name", ALL_IDS)
def test_objectivity(name: str) -> None:
    """S(Q^T C Q) = Q^T S(C) Q, D rotates as a fourth-order tensor and W is invariant, for
    random rotations Q, at random states and at equal-eigenvalue states."""
    law, ln_j = ALL_CASES[name]
    rng = np.random.default_rng(5)
    C = np.concatenate(
        [
            C_of(deformations(ln_j, 5, seed=5)),
            principal_states(equal_eigenvalue_states(ln_j), Q=rotation(rng)),
        ],
        axis=1,
    )
    W, S, D = law.evaluate3(C)
    D4 = to_tensor4(D)
    for _ in range(3):
        Q = rotation(rng)
        Cr = to_voigt(Q.T @ to_mat(C) @ Q)
        Wr, Sr, Dr = law.evaluate3(Cr)
        expected_S = to_voigt(Q.T @ to_mat(S) @ Q)
        expected_D = from_tensor4(np.einsum("aI,bJ,cK,dL,abcdn->IJKLn", Q, Q, Q, Q, D4))
        s_scale = max(np.abs(S).max(), law.initial_shear_modulus_MPa)
        np.testing.assert_allclose(Sr, expected_S, rtol=0, atol=1e-12 * s_scale)
        np.testing.assert_allclose(Dr, expected_D, rtol=0, atol=1e-12 * np.abs(D).max())
        np.testing.assert_allclose(Wr, W, rtol=1e-10, atol=1e-15)


@pytest.mark.parametrize("name", list(LAW_CASES))
def test_batch_shapes(name: str) -> None:
    law, ln_j = LAW_CASES[name]
    C = C_of(deformations(ln_j, 6, seed=3)).reshape(6, 2, 3)
    W, S, D = law.evaluate3(C)
    assert W.shape == (2, 3) and S.shape == (6, 2, 3) and D.shape == (6, 6, 2, 3)
    assert law.stress3(C).shape == (6, 2, 3)
    W1, S1, D1 = law.evaluate3(C[:, 1, 2])
    assert np.ndim(W1) == 0 and S1.shape == (6,) and D1.shape == (6, 6)
    np.testing.assert_allclose(S1, S[:, 1, 2], rtol=1e-14, atol=0)
    np.testing.assert_allclose(D1, D[:, :, 1, 2], rtol=1e-14, atol=1e-300)
    if law.decoupled:
        W, S, D = law.evaluate3_split(C)
        assert W.shape == (2, 2, 3) and S.shape == (2, 6, 2, 3) and D.shape == (2, 6, 6, 2, 3)
    with pytest.raises(ValueError, match=r"\(6, \*batch\)"):
        law.evaluate3(np.ones((3, 4)))


def test_only_the_decoupled_laws_split_in_3d() -> None:
    foam = LAW_CASES["polyurethane"][0]
    for method in (foam.evaluate3_split, foam.stress3_split, foam.stress_tangent3_split):
        with pytest.raises(NotImplementedError, match="isochoric and volumetric"):
            method(np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0]))
    assert all(hasattr(cls, "evaluate3") for cls in LAWS.values())


def test_one_term_ogden_with_alpha_2_is_neo_hookean() -> None:
    """alpha = 2: the spectral path (eigenvalues) equals the invariant path, also at equal
    eigenvalues."""
    og, nh = Ogden(mu_MPa=[0.1], alpha=[2.0], nu=0.45), NeoHookean(mu_MPa=0.1, nu=0.45)
    C = probe_states(0.1)
    for part_og, part_nh in zip(og.evaluate3_split(C), nh.evaluate3_split(C), strict=True):
        scale = np.abs(part_nh).max()
        np.testing.assert_allclose(part_og, part_nh, rtol=0, atol=1e-13 * scale)


def test_hyperfoam_cauchy_stress_matches_principal_formula() -> None:
    """sigma_a = (1/J) sum (2 mu_i / alpha_i) [lambda_a^alpha_i - J^(-alpha_i beta)], 3D."""
    law = LAW_CASES["hyperfoam_3term"][0]
    F = deformations(0.3, 6, seed=17)
    S = to_mat(law.stress3(C_of(F)))
    for k, f in enumerate(F):
        J = np.linalg.det(f)
        sigma = f @ S[k] @ f.T / J
        lam2, n = np.linalg.eigh(f @ f.T)
        lam = np.sqrt(lam2)
        principal = np.zeros(3)
        for m, a in zip(law.mu_MPa, law.alpha, strict=True):
            principal += 2 * m / a * (lam**a - J ** (-a * law.beta)) / J
        expected = n @ np.diag(principal) @ n.T
        np.testing.assert_allclose(sigma, expected, rtol=0, atol=1e-13 * np.abs(expected).max())


# --------------------------------------------------------------------------------------------
# An independent code: FElupe


def first_piola(F: np.ndarray, S: np.ndarray) -> np.ndarray:
    """P = F S (n, 3, 3) from F (n, 3, 3) and Voigt S (6, n)."""
    return F @ to_mat(S)


def material_tangent(F: np.ndarray, S: np.ndarray, D: np.ndarray) -> np.ndarray:
    """A_iJkL = dP_iJ / dF_kL = F_iI F_kK D_IJKL + delta_ik S_JL, shape (3, 3, 3, 3, n)."""
    Ft = np.moveaxis(F, 0, -1)  # (3, 3, n)
    A = np.einsum("iIn,kKn,IJKLn->iJkLn", Ft, Ft, to_tensor4(D))
    A += np.einsum("ik,nJL->iJkLn", np.eye(3), to_mat(S))
    return A


def felupe_material(fem, law):
    """The FElupe model with the same energy: FElupe's own isochoric energies (tensortrax
    automatic differentiation) + ``Volumetric(K)`` (``K/2 (J - 1)^2``, the laws' ``U(J)``, as
    in tests/test_felupe.py); the hyperfoam is FElupe's Storakers foam with ``beta_i = beta``."""
    if isinstance(law, Hyperfoam):
        n = len(law.mu_MPa)
        return fem.Hyperelastic(
            fem.storakers, mu=list(law.mu_MPa), alpha=list(law.alpha), beta=[law.beta] * n
        )
    if isinstance(law, NeoHookean):
        iso = fem.Hyperelastic(fem.neo_hooke, mu=law.mu_MPa)
    elif isinstance(law, MooneyRivlin):
        iso = fem.Hyperelastic(fem.mooney_rivlin, C10=law.c10_MPa, C01=law.c01_MPa)
    elif isinstance(law, Yeoh):
        iso = fem.Hyperelastic(fem.yeoh, C10=law.c10_MPa, C20=law.c20_MPa, C30=law.c30_MPa)
    elif isinstance(law, Ogden):
        iso = fem.Hyperelastic(fem.ogden, mu=list(law.mu_MPa), alpha=list(law.alpha))
    else:
        raise TypeError(type(law))
    return iso & fem.Volumetric(bulk=law.bulk_modulus_MPa)


@pytest.fixture
def felupe_exact_eigenvalues(monkeypatch):
    """FElupe with tensortrax, its eigenvalue perturbation switched off.

    tensortrax' ``eigvalsh`` adds ``sqrt(eps) |C| = 1.5e-8 |C|`` times a fixed matrix to ``C``
    before the eigen-decomposition (to separate repeated eigenvalues), which moves the Ogden and
    Storakers stresses by ~1e-8 relative; with ``eps = 0`` the stresses are exact (at distinct
    eigenvalues, the states used here).  Everything else is FElupe's own code."""
    fem = pytest.importorskip("felupe")
    pytest.importorskip("tensortrax")
    from tensortrax.math.linalg import eigvalsh

    for model in ("_ogden", "_storakers"):
        module = importlib.import_module(
            f"felupe.constitution.tensortrax.models.hyperelastic.{model}"
        )
        monkeypatch.setattr(module, "eigvalsh", functools.partial(eigvalsh, eps=0.0))
    return fem


# FElupe's Storakers energy divides by beta: the nu = 0 hyperfoam (beta = 0) is left out.
FELUPE_IDS = [
    n for n in ALL_IDS if not (isinstance(ALL_CASES[n][0], Hyperfoam) and ALL_CASES[n][0].nu == 0)
]


@pytest.mark.filterwarnings("ignore::DeprecationWarning")
@pytest.mark.parametrize("name", FELUPE_IDS)
def test_stress_and_tangent_match_felupe(name: str, felupe_exact_eigenvalues) -> None:
    """P = F S and A = dP/dF of every law against FElupe's hyperelastic models with the same
    parameters, at random 3D states: within 1e-10 relative (measured ~1e-15)."""
    fem = felupe_exact_eigenvalues
    law, ln_j = ALL_CASES[name]
    F = deformations(ln_j, 12, seed=29)
    _, S, D = law.evaluate3(C_of(F))
    umat = felupe_material(fem, law)
    FF = np.moveaxis(F, 0, -1)[..., None]  # (3, 3, n, 1): FElupe's trailing axes
    P_fe = np.moveaxis(umat.gradient([FF, None])[0][..., 0], -1, 0)
    A_fe = umat.hessian([FF, None])[0][..., 0]
    P = first_piola(F, S)
    for k in range(F.shape[0]):
        assert np.abs(P[k] - P_fe[k]).max() <= 1e-10 * np.abs(P_fe[k]).max(), k
    A = material_tangent(F, S, D)
    np.testing.assert_allclose(A, A_fe, rtol=0, atol=1e-10 * np.abs(A_fe).max())


@pytest.mark.filterwarnings("ignore::DeprecationWarning")
def test_neo_hookean_matches_felupe_closed_form() -> None:
    """FElupe's hand-written NeoHooke(mu, bulk) (no automatic differentiation needed)."""
    fem = pytest.importorskip("felupe")
    law = LAW_CASES["neo_hookean"][0]
    F = deformations(0.1, 12, seed=31)
    _, S, D = law.evaluate3(C_of(F))
    umat = fem.NeoHooke(mu=law.mu_MPa, bulk=law.bulk_modulus_MPa)
    FF = np.moveaxis(F, 0, -1)[..., None]
    P_fe = np.moveaxis(umat.gradient([FF, None])[0][..., 0], -1, 0)
    A_fe = umat.hessian([FF, None])[0][..., 0]
    np.testing.assert_allclose(first_piola(F, S), P_fe, rtol=0, atol=1e-12 * np.abs(P_fe).max())
    A = material_tangent(F, S, D)
    np.testing.assert_allclose(A, A_fe, rtol=0, atol=1e-12 * np.abs(A_fe).max())


# --------------------------------------------------------------------------------------------
# The viscoelastic material (law + Prony series) in 3D


@pytest.mark.parametrize(
    "name", [*sorted(CATALOGUE), "split_relaxation"], ids=[*sorted(CATALOGUE), "split"]
)
def test_viscoelastic_update_in_plane_strain_equals_the_2d_update(name: str) -> None:
    """A ``Material`` given 6-component ``C`` runs the 3D law through the same Prony update
    and tangent: in plane strain its stress, history and tangent restricted to the plane are
    the 2D material's, over two steps (shear and bulk relaxing apart for ``split``)."""
    from sim.materials._material import material_from_table

    if name == "split_relaxation":
        mat = material_from_table(
            {
                "model": "neo_hookean",
                "mu_MPa": 0.05,
                "nu": 0.49,
                "prony_g": [0.3, 0.2],
                "prony_tau_s": [0.01, 1.0],
                "prony_k": [0.1, 0.0],
            }
        )
        assert mat.split_relaxation
    else:
        mat = CATALOGUE[name]
    C2 = plane_states(0.2)
    C3 = plane_strain(C2)
    n = C2.shape[1]
    S0_2, H_2 = mat.initial_state((n,))
    S0_3, H_3 = mat.initial_state((n,), n_voigt=6)
    plane = (..., list(PLANE), slice(None))
    for step, scale in enumerate((0.5, 1.0)):
        eye = np.array([[1.0], [1.0], [0.0]])
        c2 = eye + scale * (C2 - eye)  # between I and C2: positive definite
        c3 = plane_strain(c2)
        new2, D2 = mat.instantaneous_stress_tangent(c2)
        new3, D3 = mat.instantaneous_stress_tangent(c3)
        S2, H_2, f2 = mat.relax(new2, S0_2, H_2, 0.01 * (step + 1))
        S3, H_3, f3 = mat.relax(new3, S0_3, H_3, 0.01 * (step + 1))
        scale_S = np.abs(S2).max() + 1e-30
        np.testing.assert_allclose(S3[list(PLANE)], S2, rtol=0, atol=1e-12 * scale_S)
        np.testing.assert_allclose(H_3[plane], H_2, rtol=0, atol=1e-12 * scale_S)
        T2, T3 = mat.tangent(D2, f2), mat.tangent(D3, f3)
        np.testing.assert_allclose(
            T3[np.ix_(PLANE, PLANE)], T2, rtol=0, atol=1e-12 * np.abs(T2).max()
        )
        S0_2, S0_3 = new2, new3
    assert C3.shape == (6, n)
