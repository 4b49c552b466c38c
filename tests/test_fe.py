"""Verification of the FE discretisation: patch tests, consistent tangents, assembly vs
scikit-fem, relaxation, invariances."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from fe_helpers import cauchy, check_contact_slope, compress, square_mesh, uniaxial_body
from scipy.optimize import brentq
from skfem import Basis, BilinearForm, ElementTriP2, ElementVector, LinearForm, MeshTri, asm
from skfem.helpers import grad

from sim import MeshOptions, SimOptions, homogeneous_design, simulate
from sim.fe import Body, Control, Discretization, Plate, Wedge
from sim.geometry import build_mesh
from sim.materials import CATALOGUE, LAWS, Material
from sim.protocols import WedgeOptions, run_wedge

ELASTIC = {
    "silicone_gls40": CATALOGUE["silicone_gls40"].law,
    "polyurethane_74_45": CATALOGUE["polyurethane_74_45"].law,
    "neo_hookean": LAWS["neo_hookean"].from_params({"mu_MPa": 0.1, "nu": 0.49}, "m"),
    "mooney_rivlin": LAWS["mooney_rivlin"].from_params(
        {"c10_MPa": 0.05, "c01_MPa": 0.02, "nu": 0.45}, "m"
    ),
    "yeoh": LAWS["yeoh"].from_params(
        {"c10_MPa": 0.05, "c20_MPa": 0.01, "c30_MPa": 0.002, "nu": 0.48}, "m"
    ),
}


# ----------------------------------------------------------------------------- analytic stresses
def analytic_cauchy(law, lx: float, ly: float) -> np.ndarray:
    """Principal Cauchy stresses (xx, yy) for the plane-strain stretches lx, ly (lz = 1),
    coded independently of sim.materials from the laws' textbook forms."""
    J = lx * ly
    name = type(law).__name__
    if name == "Hyperfoam":
        beta = law.nu / (1 - 2 * law.nu)
        return np.array(
            [
                sum(
                    2 * m / a * (lam**a - J ** (-a * beta))
                    for m, a in zip(law.mu_MPa, law.alpha, strict=True)
                )
                / J
                for lam in (lx, ly)
            ]
        )
    K = law.bulk_modulus_MPa
    B = np.diag([lx**2, ly**2, 1.0])
    Bb = J ** (-2 / 3) * B
    I1 = np.trace(Bb)
    I2 = 0.5 * (I1**2 - np.trace(Bb @ Bb))
    if name == "NeoHookean":
        W1, W2 = law.mu_MPa / 2, 0.0
    elif name == "MooneyRivlin":
        W1, W2 = law.c10_MPa, law.c01_MPa
    else:  # Yeoh
        W1 = law.c10_MPa + 2 * law.c20_MPa * (I1 - 3) + 3 * law.c30_MPa * (I1 - 3) ** 2
        W2 = 0.0
    del I2
    T = (W1 + I1 * W2) * Bb - W2 * Bb @ Bb
    sig = 2 / J * (T - np.trace(T) / 3 * np.eye(3)) + K * (J - 1) * np.eye(3)
    return np.array([sig[0, 0], sig[1, 1]])


@pytest.mark.parametrize("name", sorted(ELASTIC))
def test_patch_plane_strain_compression(name):
    """Uniaxial plane-strain compression of a distorted patch: the FE field is exactly affine
    and the stress at every quadrature point equals the analytic one (lateral stress zero)."""
    law = ELASTIC[name]
    body = uniaxial_body(Material(law))
    ly = 0.75
    compress(body, ly, 1.0)
    lx = brentq(lambda s: analytic_cauchy(law, s, ly)[0], 0.5, 2.0, xtol=1e-15, rtol=1e-15)
    sig = cauchy(body)
    ref = analytic_cauchy(law, lx, ly)
    scale = abs(ref[1])
    np.testing.assert_allclose(sig[0, 0], 0.0, atol=1e-11 * scale)
    np.testing.assert_allclose(sig[1, 1], ref[1], rtol=1e-11)
    np.testing.assert_allclose(sig[0, 1], 0.0, atol=1e-11 * scale)
    X = body.disc.X
    np.testing.assert_allclose(body.u[:, 0], (lx - 1) * X[:, 0], atol=1e-12)
    np.testing.assert_allclose(body.u[:, 1], (ly - 1) * X[:, 1], atol=1e-12)


def test_step_strain_relaxation_follows_g():
    """A held compression applied at once relaxes exactly as g(t) at every point."""
    mat = CATALOGUE["polyurethane_74_45"]
    body = uniaxial_body(mat)
    compress(body, 0.8, 0.0)  # dt = 0: the instantaneous response
    sig0 = cauchy(body)[1, 1]
    for t in (0.05, 0.3, 1.0, 3.0, 10.0, 30.0, 100.0):
        res = body.advance(t, Control.free())
        assert res.converged
        ratio = cauchy(body)[1, 1] / sig0
        np.testing.assert_allclose(ratio, mat.prony.relaxation(t), rtol=1e-9)
    # long-term moduli: at t -> inf the stress is the given (long-term) law's
    assert mat.moduli == "long_term"


# ----------------------------------------------------------------------------- tangents
def _fd_check(body: Body, control: Control, d: float, dt: float, seed: int = 0) -> float:
    rng = np.random.default_rng(seed)
    u = body.u.copy()
    _, data, *_ = body._evaluate(u, control, d, dt, True)
    K = body.disc.pattern_matrix(data())
    v = rng.standard_normal(body.disc.n_free)
    h = 1e-7
    up, um = u.copy(), u.copy()
    up.reshape(-1)[body.disc.free] += h * v
    um.reshape(-1)[body.disc.free] -= h * v
    fd = body._evaluate(up, control, d, dt, False)[0] - body._evaluate(um, control, d, dt, False)[0]
    fd /= 2 * h
    Kv = K @ v
    return float(np.max(np.abs(fd - Kv)) / np.max(np.abs(Kv)))


def test_tangent_matches_finite_differences_with_wedge_contact():
    """Material + geometric + contact (incl. the rounded tip's curvature) tangent, at a
    viscoelastic state in the middle of a wedge indentation of a two-layer body."""
    mats = [CATALOGUE["silicone_gls40"], CATALOGUE["polyurethane_74_45"]]
    fm = build_mesh(homogeneous_design(mats[0]).geometry, (1.0,), MeshOptions().refined(0.6))
    disc = Discretization(fm, mats)
    body = Body(disc, Wedge(), indenter_penalty_per_mm=WedgeOptions().penalty_per_mm)
    run_wedge(body, dataclasses.replace(WedgeOptions(), depth_mm=0.4, hold_s=0.5, hold_steps=2))
    s = disc.surface_nodes
    p, _, curv = body.indenter.penetration_curvature(disc.X[s] + body.u[s], body.indenter_position)
    assert np.sum(p > 0) >= 2  # several nodes in contact, some on the rounded tip
    assert np.any(curv[p > 0] > 0)
    err = _fd_check(body, Control.position(body.indenter_position), body.indenter_position, 0.1)
    assert err < 1e-5


def test_tangent_matches_finite_differences_at_undeformed_state():
    """At u = 0 (equal principal stretches everywhere) the tangent is still exact."""
    fm = build_mesh(homogeneous_design("silicone_gls40").geometry, (), MeshOptions().refined(0.5))
    body = Body(Discretization(fm, [CATALOGUE["silicone_gls40"]]), Plate())
    err = _fd_check(body, Control.free(), np.inf, 0.05)
    assert err < 1e-6


def test_a_non_finite_tangent_fails_the_step_not_the_program(monkeypatch):
    """The material tangent is computed when a factorisation asks for it; at an extreme state
    it can be non-finite where the stress is not. That is a failed step (the protocol cuts
    back), not a crash: a non-finite tangent once raised a TypeError that stopped a sweep."""
    body = uniaxial_body(CATALOGUE["silicone_gls40"])
    real = body.disc._tangent
    calls = []

    def nan_after_the_first(*args):
        calls.append(1)
        data = real(*args)
        return data if len(calls) == 1 else np.full_like(data, np.nan)

    monkeypatch.setattr(body.disc, "_tangent", nan_after_the_first)
    X = body.disc.X
    body.u[:, 1] = -0.1 * X[:, 1]  # a compressed start that is not in equilibrium
    res = body.advance(0.1, Control.free())
    assert not res.converged and res.reason == "non-finite tangent"
    assert len(calls) == 2


def test_force_control_border_is_consistent():
    """d(residual)/d(plate position) equals the coupling column used in the bordered solve."""
    fm = build_mesh(homogeneous_design("polyurethane_74_45").geometry, (), MeshOptions(0.1))
    body = Body(Discretization(fm, [CATALOGUE["polyurethane_74_45"]]), Plate())
    assert body.advance(0.1, Control.force(0.005)).converged
    d = body.indenter_position
    ctl = Control.force(0.006)
    coupling = body._evaluate(body.u, ctl, d, 0.1, True)[3]
    h = 1e-8
    rp = body._evaluate(body.u, ctl, d + h, 0.1, False)
    rm = body._evaluate(body.u, ctl, d - h, 0.1, False)
    dr_dd = (rp[0] - rm[0]) / (2 * h)
    kcol = np.zeros(body.disc.n_free)
    dofs = body._sdof[1]
    np.add.at(kcol, dofs[dofs >= 0], -coupling[dofs >= 0])
    np.testing.assert_allclose(dr_dd, kcol, atol=1e-6 * np.abs(kcol).max())
    np.testing.assert_allclose((rp[4] - rm[4]) / (2 * h), np.sum(coupling), rtol=1e-6)


# ----------------------------------------------------------------------------- vs scikit-fem
def test_assembly_matches_scikit_fem_forms():
    """The 2D assembly (compiled kernels) equals scikit-fem's assembly of the same weak form."""
    mat = Material(ELASTIC["yeoh"])
    law = mat.law
    fm = build_mesh(homogeneous_design(mat).geometry, (0.8,), MeshOptions().refined(0.5))
    disc = Discretization(fm, [mat, mat])
    X = disc.X
    u = np.column_stack([0.03 * X[:, 0] * X[:, 1], -0.08 * X[:, 1] + 0.01 * np.sin(X[:, 0])])
    ev = disc.evaluate(u, disc.initial_states(), 0.1)

    def stress_tangent(F):
        C = np.array(
            [
                F[0, 0] ** 2 + F[1, 0] ** 2,
                F[0, 1] ** 2 + F[1, 1] ** 2,
                F[0, 0] * F[0, 1] + F[1, 0] * F[1, 1],
            ]
        )
        _, S, D = law.evaluate(C)
        return np.array([[S[0], S[2]], [S[2], S[1]]]), D

    def deformation(w):
        F = grad(w["u"]).copy()
        F[0, 0] += 1
        F[1, 1] += 1
        return F

    @LinearForm
    def residual(v, w):
        F = deformation(w)
        S, _ = stress_tangent(F)
        P = np.einsum("ij...,jk...->ik...", F, S)
        return np.einsum("ij...,ij...", P, grad(v))

    @BilinearForm
    def jacobian(du, v, w):
        F = deformation(w)
        S, D = stress_tangent(F)
        dF = grad(du)
        FtdF = np.einsum("ki...,kj...->ij...", F, dF)
        dE = np.array([FtdF[0, 0], FtdF[1, 1], FtdF[0, 1] + FtdF[1, 0]])
        dSv = np.einsum("ab...,b...->a...", D, dE)
        dS = np.array([[dSv[0], dSv[2]], [dSv[2], dSv[1]]])
        dP = np.einsum("ij...,jk...->ik...", dF, S) + np.einsum("ij...,jk...->ik...", F, dS)
        return np.einsum("ij...,ij...", dP, grad(v))

    vb = Basis(MeshTri(disc.mesh.p, disc.mesh.t), ElementVector(ElementTriP2()), intorder=2)
    nv = disc.mesh.p.shape[1]
    perm = np.empty(2 * disc.n_nodes, dtype=int)
    for c in range(2):
        perm[2 * np.arange(nv) + c] = vb.nodal_dofs[c]
        perm[2 * (nv + np.arange(disc.mesh.facets.shape[1])) + c] = vb.facet_dofs[c]
    uvec = np.zeros(vb.N)
    uvec[perm] = u.reshape(-1)
    R = asm(residual, vb, u=vb.interpolate(uvec))[perm][disc.free]
    K = asm(jacobian, vb, u=vb.interpolate(uvec))[perm][:, perm][disc.free][:, disc.free]
    np.testing.assert_allclose(ev.residual, R, atol=1e-12 * np.abs(R).max())
    ours = disc.pattern_matrix(ev.tangent()).toarray()
    np.testing.assert_allclose(ours, K.toarray(), atol=1e-12 * np.abs(ours).max())


# ----------------------------------------------------------------------------- invariances
def _nh(mu: float, nu: float = 0.45) -> Material:
    return Material(LAWS["neo_hookean"].from_params({"mu_MPa": mu, "nu": nu}, "m"))


def test_plate_force_scales_with_moduli():
    """Displacement-controlled, elastic: doubling every modulus doubles the force exactly."""
    o = SimOptions(mesh=MeshOptions().refined(0.6))
    f1 = simulate(homogeneous_design(_nh(0.1)), ["plate"], o).curves["plate"]["force_N"]
    f2 = simulate(homogeneous_design(_nh(0.2)), ["plate"], o).curves["plate"]["force_N"]
    np.testing.assert_allclose(np.array(f2), 2 * np.array(f1), rtol=1e-7, atol=1e-12)


def test_same_material_in_three_layers_equals_homogeneous():
    """Layer interfaces only constrain the mesh: three layers of one material behave as one."""
    from sim import Design, Layer

    mat = CATALOGUE["polyurethane_74_45"]
    one = simulate(homogeneous_design(mat), ["plate"]).metrics["plate_force_at_1mm_N"]
    three = simulate(Design((Layer(mat, 0.5), Layer(mat, 1.0), Layer(mat))), ["plate"]).metrics[
        "plate_force_at_1mm_N"
    ]
    assert abs(three - one) / one < 5e-3


def test_elastic_material_has_no_hysteresis():
    """Without relaxation the loading and unloading branches coincide."""
    law = CATALOGUE["silicone_gls40"].law
    res = simulate(homogeneous_design(Material(law)), ["tapping"])
    assert res.ok
    assert res.metrics["disp_at_4N_mm"] > 0.5  # a real tap happened
    loop_scale = 5.0 * res.metrics["disp_at_4N_mm"]  # peak force x displacement (N mm)
    assert abs(res.metrics["hysteresis_Nmm"]) < 1e-4 * loop_scale  # the silicone's is 4e-2
    # with nothing to relax, the second tap repeats the first
    h = np.array(res.protocols["tapping"]["history"])
    np.testing.assert_allclose(h[-1], h[0], rtol=1e-6)


def test_viscoelastic_material_dissipates():
    res = simulate(homogeneous_design("polyurethane_74_45"), ["tapping"])
    assert res.metrics["hysteresis_Nmm"] > 0.1
    # sag left by earlier taps: the last tap touches below the undeformed top
    assert res.metrics["disp_at_1N_mm"] > res.metrics["disp_at_1N_from_touch_mm"] + 0.05
    assert res.protocols["tapping"]["settled"]


def test_square_mesh_helper_is_sane():
    fm = square_mesh(4)
    assert len(fm.base) == 5 and len(fm.axis) == 5 and len(fm.surface) == 9


def test_rigid_base_contact_supports_the_body():
    """The frictionless base y = 0 beside the bone: a strip whose left edge is pushed 0.15 mm
    below the base rests on it (no surface node penetrates more than the penalty allows) and the
    contact tangent matches finite differences."""
    import numpy as np

    from sim.geometry import FingertipMesh

    mesh = MeshTri.init_tensor(np.linspace(0.0, 1.0, 7), np.linspace(0.0, 0.5, 4))
    x, y = mesh.p
    bottom = np.flatnonzero(np.abs(y) < 1e-12)
    right = np.flatnonzero(np.abs(x - 1) < 1e-12)
    left = np.flatnonzero(np.abs(x) < 1e-12)
    surface = np.concatenate(
        [bottom[np.argsort(-x[bottom])][::-1], right[np.argsort(y[right])][1:]]
    )
    fm = FingertipMesh(mesh, np.zeros(mesh.t.shape[1], dtype=int), surface, left[:0], left)

    def fixed(X):
        m = np.zeros_like(X, dtype=bool)
        m[np.abs(X[:, 0]) < 1e-12, :] = True
        return m

    disc = Discretization(fm, [_nh(0.05, 0.3)], fixed=fixed)
    body = Body(disc, indenter=None)
    left_nodes = np.abs(disc.X[:, 0]) < 1e-12
    for depth in np.linspace(0.05, 0.15, 3):
        body.u[left_nodes, 1] = -depth
        assert body.advance(depth, Control.free()).converged
    s = disc.surface_nodes[disc.X[disc.surface_nodes, 0] > 1e-12]  # the free surface nodes
    y_surf = disc.X[s, 1] + body.u[s, 1]
    assert body.base_contact_nodes() >= 3  # the bottom rests on the base
    assert y_surf.min() > -1e-2 * 0.15  # penetration below 1 % of the push everywhere,
    away = disc.X[s, 0] > 0.2  # and below 0.1 % away from the corner forced under the base
    assert y_surf[away].min() > -1e-3 * 0.15
    err = _fd_check(body, Control.free(), np.inf, 0.0)
    assert err < 1e-5


# ----------------------------------------------------------------------------- shear vs bulk
HOLD_TIMES = (0.0, 0.02, 0.1, 0.3, 1.0, 3.0, 10.0, 100.0, 1000.0)  # the last: fully relaxed


def _shear_only_nh(k=None) -> Material:
    """neo-Hookean, nu = 0.45 (long-term), relaxing its shear by 68 % (tau 0.1 s, 1 s); bulk
    elastic by default (k_i = 0, the invariant laws' default)."""
    from sim.materials import Prony

    law = LAWS["neo_hookean"].from_params({"mu_MPa": 0.1, "nu": 0.45}, "m")
    return Material(law, Prony((0.3, 0.38), (0.1, 1.0), k=k))


def _material_point_compression(mat: Material, ly: float, times) -> list[tuple[float, float]]:
    """The homogeneous answer of the plane-strain compression patch, one material point: at
    each time the lateral stretch lx that makes S11 = 0 under the same Prony recursion.
    Returns (lx, sigma_yy) per time."""
    S0_old, H = mat.initial_state(())
    out, t_prev = [], 0.0
    for t in times:
        dt = t - t_prev

        def s11(lx, S0_old=S0_old, H=H, dt=dt):
            S0 = mat.instantaneous_stress([lx * lx, ly * ly, 0.0])
            return mat.relax(S0, S0_old, H, dt)[0][0]

        lx = brentq(s11, 0.8, 1.6, xtol=1e-15, rtol=1e-15)
        S0 = mat.instantaneous_stress([lx * lx, ly * ly, 0.0])
        S, H, _ = mat.relax(S0, S0_old, H, dt)
        out.append((lx, ly * ly * S[1] / (lx * ly)))
        S0_old, t_prev = S0, t
    return out


def test_shear_only_relaxation_patch_keeps_the_bulk_response_elastic():
    """(d) Held plane-strain compression of the distorted patch, shear relaxing, bulk not.

    The FE field stays affine and equals the material-point answer at every time; the
    axial stress relaxes from the instantaneous to the long-term elastic value; the volume
    goes from the instantaneous law's elastic J to the long-term law's (the same bulk modulus:
    only the shear, hence nu, changed), and at every time the volumetric stress is the elastic
    K (J - 1) J C^-1 of the current J. (J is not constant: with the lateral face free, the
    lateral expansion follows nu, which rises as the shear relaxes; it is whole-stress
    relaxation, all moduli scaled by g(t), that keeps the deformation fixed.)"""
    mat = _shear_only_nh()
    assert mat.split_relaxation
    ly = 0.8
    body = uniaxial_body(mat)
    compress(body, ly, 0.0)
    ref = _material_point_compression(mat, ly, HOLD_TIMES)
    X = body.disc.X
    right = np.abs(X[:, 0] - 1.0) < 1e-12
    K = mat.law.bulk_modulus_MPa
    sig_yy, J_t = [], []
    for t, (lx, s_yy) in zip(HOLD_TIMES, ref, strict=True):
        if t > 0.0:
            assert body.advance(t, Control.free()).converged
        np.testing.assert_allclose(body.u[:, 0], (lx - 1.0) * X[:, 0], atol=1e-12)
        np.testing.assert_allclose(body.u[:, 1], (ly - 1.0) * X[:, 1], atol=1e-12)
        sig = cauchy(body)
        np.testing.assert_allclose(sig[1, 1], s_yy, rtol=1e-10)
        np.testing.assert_allclose(sig[0, 0], 0.0, atol=1e-11 * abs(s_yy))
        lx = 1.0 + body.u[right, 0].mean()  # the FE lateral stretch (= the reference's)
        J = lx * ly
        # the stored volumetric stress: K (J - 1) J C^-1, C^-1 = diag(1/lx^2, 1/ly^2)
        S_vol = body.states[0].S0[1]
        np.testing.assert_allclose(S_vol[0], K * (J - 1) * J / lx**2, rtol=1e-11)
        np.testing.assert_allclose(S_vol[1], K * (J - 1) * J / ly**2, rtol=1e-11)
        sig_yy.append(float(np.mean(sig[1, 1])))
        J_t.append(J)

    def elastic_lx(law):
        return brentq(lambda s: analytic_cauchy(law, s, ly)[0], 0.5, 2.0, xtol=1e-15, rtol=1e-15)

    lx0, lx_inf = elastic_lx(mat.instantaneous), elastic_lx(mat.long_term)
    assert mat.instantaneous.bulk_modulus_MPa == pytest.approx(mat.long_term.bulk_modulus_MPa)
    np.testing.assert_allclose(J_t[0], lx0 * ly, rtol=1e-12)  # t = 0+: instantaneous, elastic
    np.testing.assert_allclose(J_t[-1], lx_inf * ly, rtol=1e-10)  # t >> tau: long-term
    sig0 = analytic_cauchy(mat.instantaneous, lx0, ly)[1]
    sig_inf = analytic_cauchy(mat.long_term, lx_inf, ly)[1]
    np.testing.assert_allclose(sig_yy[0], sig0, rtol=1e-10)
    np.testing.assert_allclose(sig_yy[-1], sig_inf, rtol=1e-9)
    assert np.all(np.diff(np.abs(sig_yy)) < 0)  # the axial stress relaxes monotonically
    assert np.all(np.diff(J_t) > -1e-12)  # as nu rises, the volume recovers (0.89 -> 0.955)
    assert abs(sig_yy[-1]) < 0.5 * abs(sig_yy[0])


def test_split_path_with_k_close_to_g_matches_whole_stress_relaxation():
    """(b) In the assembly: k = g (the whole-stress path) and k = g (1 - 1e-12) (the split
    path, S0 and H kept as isochoric + volumetric parts) give the same patch history."""
    whole = _shear_only_nh(k=(0.3, 0.38))
    split = _shear_only_nh(k=(0.3 * (1 - 1e-12), 0.38 * (1 - 1e-12)))
    assert not whole.split_relaxation and split.split_relaxation
    bodies = [uniaxial_body(m) for m in (whole, split)]
    for b in bodies:
        compress(b, 0.8, 0.0)
    for t in HOLD_TIMES[1:5]:
        for b in bodies:
            assert b.advance(t, Control.free()).converged
        np.testing.assert_allclose(bodies[1].u, bodies[0].u, rtol=0, atol=1e-10)
        s0, s1 = cauchy(bodies[0]), cauchy(bodies[1])
        np.testing.assert_allclose(s1, s0, rtol=0, atol=1e-9 * np.abs(s0).max())
    assert bodies[1].states[0].H.shape[:3] == (2, 2, 3)  # terms first, then [iso, vol]


def test_split_relaxation_tangent_and_frozen_history_in_the_assembly():
    """(c) The assembled tangent of a split (shear and bulk apart) material matches finite
    differences mid-relaxation, and re-equilibrating with the history held at the committed
    state leaves it where it is."""
    body = uniaxial_body(_shear_only_nh(k=(0.1, 0.05)))
    compress(body, 0.85, 0.0)
    for t in (0.05, 0.2):
        assert body.advance(t, Control.free()).converged
    committed = body.u.copy()
    rng = np.random.default_rng(1)
    body.u.reshape(-1)[body.disc.free] += 1e-3 * rng.standard_normal(body.disc.n_free)
    for dt in (0.0, 0.1, 5.0):
        assert _fd_check(body, Control.free(), np.inf, dt) < 1e-6
    # from the perturbed field, Newton with the history held returns to the committed state
    assert body.advance(body.t, Control.free(), frozen_history=True).converged
    np.testing.assert_allclose(body.u, committed, rtol=0, atol=1e-11)


def test_mesh_size_distance_matches_a_kd_tree():
    """The mesh-size function's distance to the contact part of the outline (numpy, brute
    force) is the KD-tree's it replaced, to round-off, without importing scipy.spatial."""
    from scipy.spatial import cKDTree

    from sim.geometry.mesh2d import _nearest_distance

    rng = np.random.default_rng(3)
    theta = np.linspace(0.0, np.pi / 2, 600)
    curve = np.column_stack([5.84 * np.cos(theta) ** 0.8, 5.48 * np.sin(theta) ** 0.8])
    points = rng.uniform([0.0, 0.0], [6.0, 5.5], size=(9000, 2))  # more than one chunk
    want = cKDTree(curve).query(points)[0]
    np.testing.assert_allclose(_nearest_distance(points, curve), want, rtol=1e-15, atol=0)


def test_the_model_root_is_bracketed_and_exact_for_a_linear_body():
    """``_model_root``: with a body part linear in a (as the model assumes) the next trial is the
    root of g itself, a kink of the contact part included; it stays inside the bracket."""
    from sim.fe.solver import _model_root

    def g_contact(a: float) -> float:  # a node entering contact at a = 0.4, stiff beyond
        return 50.0 * max(a - 0.4, 0.0)

    def g_body(a: float) -> float:
        return -1.0 + 0.5 * a

    a = _model_root(g_contact, 0.0, g_body(0.0), 1.0, g_body(1.0))
    assert a == pytest.approx(0.4 + 0.8 / 50.5, rel=1e-3)  # -1 + 0.5 a + 50 (a - 0.4) = 0
    assert 0.0 < a < 1.0
    # a root at the bracket's end is kept 1 % inside it
    assert _model_root(lambda a: 0.0, 0.0, -1.0, 1.0, -1e-9) == pytest.approx(0.99)


@pytest.mark.parametrize("indenter", [Plate(), Wedge()], ids=["plate", "wedge"])
@pytest.mark.parametrize("kind", ["force", "position"])
def test_the_line_searchs_contact_part_is_the_residuals_2d(indenter, kind):
    """``Body._contact_slope`` (a flat plate and the base from the nodes' heights alone, the
    rounded wedge from its full normals) is the contacts' part of the line search's
    g(a) = [du, dd] . residual(a): g minus the body's own part, at steps where nodes enter the
    indenter."""
    fm = build_mesh(homogeneous_design("silicone_gls40").geometry, (), MeshOptions(0.1))
    disc = Discretization(fm, [CATALOGUE["silicone_gls40"]])
    body = Body(disc, indenter)
    y = disc.X[:, 1]
    u = np.zeros_like(disc.X)
    d = body.top_height(u) - 0.05
    control = Control.force(0.3) if kind == "force" else Control.position(d)
    rng = np.random.default_rng(7)
    du = 1e-4 * rng.standard_normal(disc.n_free)  # small beside 0.1 mm elements: no law blows up
    lift = np.zeros_like(u)
    lift[:, 1] = 0.15 * y / y.max()  # a vertical stretch into the indenter
    du += lift.reshape(-1)[disc.free]
    dd = -0.1 if kind == "force" else 0.0
    entered = check_contact_slope(body, u, d, du, dd, control)
    assert entered[0] >= 1 and entered[-1] > entered[0]
