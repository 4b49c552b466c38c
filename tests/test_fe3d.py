"""The 3D discretisation (``sim.fe.fe3d``) on the pad's Q2 mesh: a patch test, the consistent
viscoelastic tangent against finite differences of the residual (two layers, shear and bulk
relaxing apart), the shared ``Body``'s contact in 3D (its tangent, and global equilibrium of a
plate press: the base's reaction carries the plate's force), and the linear solvers agreeing.
Against an independent code (FElupe): ``tests/test_fe3d_felupe.py``."""

from __future__ import annotations

import numpy as np
import pytest
from fe_helpers import check_contact_slope

from sim.fe import Body, Control, Discretization3D, NewtonOptions, Plate
from sim.geometry import Geometry, MeshOptions3D, PadGeometry, build_pad_mesh
from sim.materials._material import material_from_table

#: a coarse mesh: a few hundred elements, seconds per test
COARSE = MeshOptions3D(h_apex_mm=1.0, h_contact_mm=1.5, h_max_mm=3.0, grading=0.6)
PAD = PadGeometry(Geometry(5.84, 5.48, 1.5), half_length_mm=8.0, length_exponent=2.0)

SKIN = {"model": "neo_hookean", "mu_MPa": 0.08, "nu": 0.49, "prony_g": [0.3, 0.2],
        "prony_tau_s": [0.01, 0.5], "prony_k": [0.1, 0.0]}  # fmt: skip
CORE = {"model": "ogden", "mu_MPa": [0.02], "alpha": [4.0], "nu": 0.495}


@pytest.fixture(scope="module")
def two_layers() -> Discretization3D:
    pmesh = build_pad_mesh(PAD, (1.0,), COARSE)
    return Discretization3D(pmesh, [material_from_table(SKIN), material_from_table(CORE)])


def _smooth(X: np.ndarray) -> np.ndarray:
    x, y, z = X.T
    return np.column_stack(
        [0.03 * x * y / 5, -0.1 * y**2 / 5 + 0.02 * np.cos(z / 4), 0.02 * y * z / 8]
    )


def test_homogeneous_deformation_passes_the_patch_test():
    """Every boundary node prescribed by u = (F0 - I) X: the same stress everywhere, so the
    interior nodes' internal forces vanish (one material: no interface tractions)."""
    pmesh = build_pad_mesh(PAD, (), COARSE)
    boundary = np.zeros(len(pmesh.nodes), dtype=bool)
    for nodes in (pmesh.base, pmesh.sym_x, pmesh.sym_z, pmesh.surface_nodes):
        boundary[nodes] = True
    disc = Discretization3D(
        pmesh,
        [material_from_table(CORE)],
        fixed=lambda X: np.repeat(boundary[:, None], 3, axis=1),
    )
    assert disc.n_free > 0
    F0 = np.array([[1.08, 0.04, -0.02], [0.03, 0.9, 0.05], [-0.04, 0.02, 1.05]])
    u = disc.X @ (F0 - np.eye(3)).T
    ev = disc.evaluate(u, disc.initial_states(), 0.0)
    F = ev._tangent_args[0]
    np.testing.assert_allclose(F, np.broadcast_to(F0[:, :, None, None], F.shape), atol=1e-12)
    # the scale: one node's share of a stress times an element face
    S = ev._tangent_args[1]
    scale = np.abs(S).max() * np.mean(disc.w) ** (2 / 3)
    assert np.abs(ev.residual).max() < 1e-10 * scale


def test_viscoelastic_tangent_is_the_residuals_derivative(two_layers):
    disc = two_layers
    rng = np.random.default_rng(2)
    u = _smooth(disc.X)
    u[disc.fixed] = 0.0
    # a committed history from a first step, then a second step of dt
    ev0 = disc.evaluate(0.5 * u, disc.initial_states(), 0.02)
    states = ev0.states
    ev = disc.evaluate(u, states, 0.01)
    K = disc.pattern_matrix(ev.tangent())
    assert abs(K - K.T).max() <= 1e-12 * abs(K).max()
    for _ in range(2):
        du = np.zeros_like(u)
        du.ravel()[disc.free] = rng.standard_normal(disc.n_free)
        du *= 1e-2
        h = 1e-5
        rp = disc.evaluate(u + h * du, states, 0.01, tangent=False).residual
        rm = disc.evaluate(u - h * du, states, 0.01, tangent=False).residual
        fd = (rp - rm) / (2 * h)
        np.testing.assert_allclose(K @ du.ravel()[disc.free], fd, rtol=0, atol=2e-7 * abs(fd).max())


def test_contact_tangent_is_the_residuals_derivative_in_3d(two_layers):
    """The shared ``Body``'s penalty contact with 3D normals: its tangent (with the element
    tangent) is the derivative of its residual, with nodes pressed by the plate."""
    body = Body(two_layers, Plate(), NewtonOptions())
    disc = two_layers
    u = _smooth(disc.X)
    u[disc.fixed] = 0.0
    d = body.top_height(u) - 0.3  # the plate 0.3 mm below the deformed top
    control = Control.position(d)
    _, data, *_ = body._evaluate(u, control, d, 0.01, True)
    K = disc.pattern_matrix(data())
    rng = np.random.default_rng(3)
    du = np.zeros_like(u)
    du.ravel()[disc.free] = 1e-2 * rng.standard_normal(disc.n_free)
    h = 1e-6
    rp = body._evaluate(u + h * du, control, d, 0.01, False)[0]
    rm = body._evaluate(u - h * du, control, d, 0.01, False)[0]
    fd = (rp - rm) / (2 * h)
    active = body._contact(u, control, d)[1][0] > 0
    assert active.sum() >= 3
    np.testing.assert_allclose(K @ du.ravel()[disc.free], fd, rtol=0, atol=1e-6 * abs(fd).max())


@pytest.fixture(scope="module")
def pressed():
    """An elastic one-layer pad pressed 0.3 mm by the plate (quarter model)."""
    pmesh = build_pad_mesh(PAD, (), COARSE)
    mat = material_from_table({"model": "neo_hookean", "mu_MPa": 0.05, "nu": 0.49})
    body = Body(Discretization3D(pmesh, [mat]), Plate(), NewtonOptions())
    top = body.top_height()
    for k, d in enumerate(np.linspace(0.05, 0.3, 6)):
        assert body.advance(0.1 * (k + 1), Control.position(top - d)).converged
    return body


def test_the_base_carries_the_plates_force(pressed):
    """Global equilibrium: the vertical internal forces of the bonded base (its reaction)
    balance the plate's force; the symmetry planes carry no vertical force."""
    body = pressed
    disc = body.disc
    free_all = Discretization3D(disc.pmesh, disc.materials, fixed=lambda X: np.zeros(X.shape, bool))
    # internal forces at every dof for the committed state (no time passes: history held)
    ev = free_all.evaluate(body.u, body.states, 0.0, tangent=False, frozen_history=True)
    f = ev.residual.reshape(-1, 3)
    base = disc.pmesh.base
    assert body.force > 0
    np.testing.assert_allclose(f[base, 1].sum(), body.force, rtol=1e-5)


def test_pardiso_and_qdldl_give_the_same_step(pressed):
    """One step of the same press solved by both factorisations: the same displacements to
    the Newton tolerance's order."""
    pytest.importorskip("pypardiso")
    bodies = []
    for name in ("pardiso", "qdldl"):
        body = Body(pressed.disc, Plate(), NewtonOptions())
        body.linear_solver = name
        top = body.top_height()
        assert body.advance(0.1, Control.position(top - 0.1)).converged
        bodies.append(body)
    scale = np.abs(bodies[0].u).max()
    np.testing.assert_allclose(bodies[0].u, bodies[1].u, rtol=0, atol=1e-6 * scale)
    assert bodies[0]._solver.name == "pardiso" and bodies[1]._solver.name == "qdldl"


def test_pardiso_orders_by_nested_dissection(pressed):
    """``PARDISO_IPARM``: the pressed pad's tangent factorised by the FE's PARDISO solves it
    to rounding, with a smaller factor (PARDISO's own count, iparm(18)) than the same solver
    with minimum degree ordering, which it used while its settings' flag was set alone."""
    pytest.importorskip("pypardiso")
    import scipy.sparse as sp

    from sim.fe._linear import Pardiso

    disc = pressed.disc
    ev = disc.evaluate(pressed.u, pressed.states, 0.0, frozen_history=True)
    upper = disc.upper_matrix(ev.tangent()).tocsc()
    K = upper + sp.triu(upper, k=1).T
    b = np.random.default_rng(0).standard_normal(K.shape[0])
    entries = {}
    for ordering in ("as set", 0):  # iparm(2): the FE's setting; 0, minimum degree
        solver = Pardiso()
        if ordering == 0:
            solver._ps.iparm[1] = ordering
        solver.factor(upper)
        x = solver.solve(b)
        assert np.linalg.norm(K @ x - b) <= 1e-10 * np.linalg.norm(b)
        entries[ordering] = int(solver._ps.iparm[17])
    print(f"factor entries: as set {entries['as set']}, minimum degree {entries[0]}")
    assert 0 < entries["as set"] < entries[0]


def test_single_precision_pardiso_factorises_in_float32_for_newtons_answer(pressed):
    """``PardisoSingle``: the pressed pad's tangent solved to float32's accuracy (worse than
    double's rounding, so the factor is really single; far better than bytes read in the wrong
    precision), and a press stepped with it reaches double precision's state to the order of
    Newton's tolerance: Newton stops on the double residual."""
    pytest.importorskip("pypardiso")
    import scipy.sparse as sp

    from sim.fe._linear import PardisoSingle, default_solver

    assert default_solver(10_000, 3, single_precision=True) == "pardiso-single"
    assert default_solver(10_000, 3) == "pardiso"
    assert default_solver(2_000, 2, single_precision=True) == "qdldl"
    disc = pressed.disc
    ev = disc.evaluate(pressed.u, pressed.states, 0.0, frozen_history=True)
    upper = disc.upper_matrix(ev.tangent()).tocsc()
    K = upper + sp.triu(upper, k=1).T
    b = np.random.default_rng(0).standard_normal(K.shape[0])
    solver = PardisoSingle()
    solver.factor(upper)
    x = solver.solve(b)
    error = np.linalg.norm(K @ x - b) / np.linalg.norm(b)
    print(f"single precision: relative residual {error:.1e}")
    assert x.dtype == np.float64 and 1e-10 < error < 1e-4
    X = solver.solve_many(np.column_stack([b, -2 * b]))
    np.testing.assert_allclose(X[:, 1], -2 * x, rtol=1e-6, atol=1e-6 * np.abs(x).max())
    bodies = []
    for single in (False, True):
        body = Body(disc, Plate(), NewtonOptions())
        body.single_precision = single
        top = body.top_height()
        for k, d in enumerate(np.linspace(0.05, 0.3, 6)):
            assert body.advance(0.1 * (k + 1), Control.position(top - d)).converged
        assert body.precision_fallbacks == 0
        bodies.append(body)
    assert [b.solver_name for b in bodies] == ["pardiso", "pardiso-single"]
    scale = np.abs(bodies[0].u).max()
    np.testing.assert_allclose(bodies[1].u, bodies[0].u, rtol=0, atol=1e-6 * scale)
    np.testing.assert_allclose(bodies[1].force, bodies[0].force, rtol=1e-6)


def test_a_step_failed_in_single_precision_is_tried_again_in_double(pressed, monkeypatch):
    """``Body.advance``: where the single-precision solves mislead Newton (here made useless:
    a direction of the wrong sign), the step is tried again with double precision and
    converges to double precision's answer; the next step is single precision's again."""
    pytest.importorskip("pypardiso")
    from sim.fe._linear import PardisoSingle

    monkeypatch.setattr(PardisoSingle, "solve", lambda self, b: -_double_solve(self, b))
    reference = Body(pressed.disc, Plate(), NewtonOptions())
    body = Body(pressed.disc, Plate(), NewtonOptions())
    body.single_precision = True
    top = body.top_height()
    for b in (reference, body):
        assert b.advance(0.1, Control.position(top - 0.1)).converged
    assert body.precision_fallbacks == 1 and body.solver_name == "pardiso"
    assert reference.precision_fallbacks == 0
    np.testing.assert_array_equal(body.u, reference.u)  # double precision's own path
    monkeypatch.undo()  # single precision's directions are good again
    for b in (reference, body):
        assert b.advance(0.2, Control.position(top - 0.2)).converged
    assert body.precision_fallbacks == 1 and body.solver_name == "pardiso-single"
    assert body.linear_solver is None and reference.solver_name == "pardiso"
    scale = np.abs(reference.u).max()
    np.testing.assert_allclose(body.u, reference.u, rtol=0, atol=1e-6 * scale)


def test_a_step_that_fails_in_both_precisions_is_cut_in_double(pressed, monkeypatch):
    """``Body.advance``: a step that fails in double precision too (here: Newton allowed one
    iteration) leaves the body in double precision for the protocol's cut step, and the first
    step that converges there hands it back to single precision."""
    pytest.importorskip("pypardiso")
    from sim.fe._linear import PardisoSingle

    monkeypatch.setattr(PardisoSingle, "solve", lambda self, b: -_double_solve(self, b))
    body = Body(pressed.disc, Plate(), NewtonOptions(max_iterations=1))
    body.single_precision = True
    top = body.top_height()
    assert not body.advance(0.1, Control.position(top - 0.1)).converged
    assert body.precision_fallbacks == 1 and body.linear_solver == "pardiso"
    body.options = NewtonOptions()
    assert body.advance(0.05, Control.position(top - 0.05)).converged  # the cut step
    assert body.precision_fallbacks == 1 and body.solver_name == "pardiso"
    assert body.linear_solver is None  # the next step is single precision's


def test_a_failed_step_with_good_single_precision_is_retried_afresh_in_single(pressed, monkeypatch):
    """``Body.advance``: a step that Newton abandons (here: declared stalled after its first
    iteration) while its single-precision factorisation solves the tangent to float32's
    accuracy is tried again in single precision from a fresh factorisation, and reaches
    double precision's state; an attempt that began with a fresh factorisation is not
    repeated (the retry would be the same bits); a factorisation that solves its tangent
    worse than ``INEXACT_SOLVE_RTOL`` sends the retry to double precision."""
    pytest.importorskip("pypardiso")
    import sim.fe.solver as solver_module
    from sim.fe._linear import PardisoSingle
    from sim.fe.solver import model_newton

    options = model_newton(NewtonOptions(), 3)  # factorisations kept, as in 3D
    top = pressed.top_height()
    reference = Body(pressed.disc, Plate(), options)
    body = Body(pressed.disc, Plate(), options)
    body.single_precision = True
    for b in (reference, body):
        assert b.advance(0.1, Control.position(top - 0.1)).converged
    assert 1e-10 < body.last_factor_residual() < 1e-4  # single precision, and good
    assert reference.last_factor_residual() != reference.last_factor_residual()  # nan: exact
    stalls = {"left": 1}
    stalled = solver_module._stalled

    def stall_once(norms, opts, dim):  # the first attempt is abandoned after one iteration
        if len(norms) == 2 and stalls["left"]:
            stalls["left"] -= 1
            return True
        return stalled(norms, opts, dim)

    monkeypatch.setattr(solver_module, "_stalled", stall_once)
    assert body.advance(0.2, Control.position(top - 0.2)).converged  # began with the kept one
    assert (body.fresh_retries, body.precision_fallbacks) == (1, 0)
    assert body.solver_name == "pardiso-single" and body.linear_solver is None
    assert reference.advance(0.2, Control.position(top - 0.2)).converged
    # both within Newton's tolerance of the answer (modified Newton stops just inside it,
    # as in test_modified_newton_saves_factorisations_for_the_same_answer)
    scale = np.abs(reference.u).max()
    print(
        f"retried: |du| {np.abs(body.u - reference.u).max() / scale:.1e} of the largest u, "
        f"force {body.force:.8f} against {reference.force:.8f} N/mm"
    )
    np.testing.assert_allclose(body.u, reference.u, rtol=0, atol=1e-4 * scale)
    np.testing.assert_allclose(body.force, reference.force, rtol=1e-4)
    # a first step factorises afresh: abandoned, it is left to the protocol to cut
    first = Body(pressed.disc, Plate(), options)
    first.single_precision = True
    stalls["left"] = 1
    assert not first.advance(0.1, Control.position(top - 0.1)).converged
    assert (first.fresh_retries, first.precision_fallbacks, first.linear_solver) == (0, 0, None)
    # the same step with single precision's solves made useless goes to double precision
    monkeypatch.setattr(PardisoSingle, "solve", lambda self, b: -_double_solve(self, b))
    assert first.advance(0.1, Control.position(top - 0.1)).converged
    assert first.last_factor_residual() != first.last_factor_residual()  # double's: none kept
    assert (first.fresh_retries, first.precision_fallbacks) == (0, 1)
    assert first.solver_name == "pardiso"


def _double_solve(solver, b):
    """The double-precision class's solve on a single-precision solver (its own bytes)."""
    from sim.fe._linear import Pardiso

    return Pardiso.solve(solver, b)


def test_modified_newton_saves_factorisations_for_the_same_answer():
    """``NewtonOptions.reuse_factorization``: the press of ``pressed`` with the factorisation
    kept while the residual falls fast: fewer factorisations, the same state to the order of
    the Newton tolerance."""
    pmesh = build_pad_mesh(PAD, (), COARSE)
    mat = material_from_table({"model": "neo_hookean", "mu_MPa": 0.05, "nu": 0.49})
    disc = Discretization3D(pmesh, [mat])
    bodies = []
    for reuse in (False, True):
        body = Body(disc, Plate(), NewtonOptions(reuse_factorization=reuse))
        top = body.top_height()
        for k, d in enumerate(np.linspace(0.05, 0.3, 6)):
            assert body.advance(0.1 * (k + 1), Control.position(top - d)).converged
        bodies.append(body)
    full, modified = bodies
    print(f"factorisations: full Newton {full.factorizations}, modified {modified.factorizations}")
    assert modified.factorizations < full.factorizations
    scale = np.abs(full.u).max()
    np.testing.assert_allclose(modified.u, full.u, rtol=0, atol=1e-5 * scale)
    np.testing.assert_allclose(modified.force, full.force, rtol=1e-5)


def test_contact_corrected_solve_is_the_new_matrixs_solve():
    """``_ContactCorrected``: a factorisation of K0 with a change on a few dofs (two nodes
    entering contact: rank-one blocks n n^T, one node leaving) solves K0 + P D P^T exactly
    (Woodbury's identity), with PARDISO's many right-hand sides and qdldl's one by one."""
    import scipy.sparse as sp

    from sim.fe._linear import make_solver, pardiso_available
    from sim.fe.solver import _ContactCorrected, _KeptColumns

    rng = np.random.default_rng(0)
    n = 60
    A = sp.random(n, n, density=0.1, random_state=1)
    K0 = (A + A.T + sp.eye(n) * 8.0).tocsc()
    dofs = np.array([3, 4, 5, 17, 18, 19, 40])
    D = np.zeros((7, 7))
    for at, normal in ((0, [0.0, 1.0, 0.0]), (3, [0.3, 0.9, 0.1])):
        nrm = np.asarray(normal) / np.linalg.norm(normal)
        D[at : at + 3, at : at + 3] = 50.0 * np.outer(nrm, nrm)  # entering: rank one
    D[6, 6] = -3.0  # leaving: its penalty removed
    K = K0.toarray()
    K[np.ix_(dofs, dofs)] += D
    b = rng.normal(size=n)
    names = ["qdldl"] + (["pardiso"] if pardiso_available() else [])
    for name in names:
        solver = make_solver(name)
        solver.factor(sp.triu(K0).tocsc())
        corrected = _ContactCorrected(solver, dofs, D, n)
        assert corrected.ok
        np.testing.assert_allclose(corrected.solve(b), np.linalg.solve(K, b), rtol=1e-10)
        unchanged = _ContactCorrected(solver, dofs[:0], D[:0, :0], n)
        np.testing.assert_allclose(unchanged.solve(b), np.linalg.solve(K0.toarray(), b))
        # with the columns kept for this factorisation: a second change sharing four of the
        # dofs solves for the new ones only, and is still exact
        kept = _KeptColumns()
        _ContactCorrected(solver, dofs, D, n, kept)
        dofs2 = np.array([17, 18, 19, 40, 52])
        D2 = np.diag([5.0, 6.0, 7.0, -3.0, 9.0])
        corrected2 = _ContactCorrected(solver, dofs2, D2, n, kept)
        assert (kept.solved, kept.served) == (7 + 1, 4)
        K2 = K0.toarray()
        K2[np.ix_(dofs2, dofs2)] += D2
        np.testing.assert_allclose(corrected2.solve(b), np.linalg.solve(K2, b), rtol=1e-10)

    class Overflowed:  # a factorisation whose solves are not finite (float32 overflow)
        def solve_many(self, B: np.ndarray) -> np.ndarray:
            return np.full(B.shape, np.nan)

    # not usable, without LAPACK's "SVD did not converge" (it failed a tapping, solver 2.20)
    assert not _ContactCorrected(Overflowed(), dofs, D, n).ok


def _pressed_body(opts: NewtonOptions) -> Body:
    """A viscoelastic pad pressed by force control to 1 N in 8 steps, its patch growing over
    surface nodes at every step."""
    pmesh = build_pad_mesh(PAD, (), COARSE)
    table = {"model": "neo_hookean", "mu_MPa": 0.05, "nu": 0.49}
    mat = material_from_table({**table, "prony_g": [0.3], "prony_tau_s": [0.5]})
    body = Body(Discretization3D(pmesh, [mat]), Plate(), opts)
    scale = 1.0 / body.disc.force_scale(10.0)
    for k, f in enumerate(np.linspace(0.1, 1.0, 8)):
        assert body.advance(0.05 * (k + 1), Control.force(f * scale)).converged
    return body


def test_contact_update_keeps_factorisations_across_contact_changes():
    """``NewtonOptions.contact_update``: force-controlled steps of a viscoelastic pad whose
    patch grows over surface nodes step by step keep one factorisation across the changes,
    corrected for the contact; fewer factorisations for the same states (to the order of the
    Newton tolerance)."""
    kept, updated = (
        _pressed_body(NewtonOptions(reuse_factorization=True, contact_update=update))
        for update in (False, True)
    )
    n_kept, n_updated = kept.factorizations, updated.factorizations
    print(f"factorisations: contact set must match {n_kept}, updated {n_updated}")
    assert updated.factorizations < kept.factorizations
    size = np.abs(kept.u).max()
    np.testing.assert_allclose(updated.u, kept.u, rtol=0, atol=1e-5 * size)
    np.testing.assert_allclose(updated.indenter_position, kept.indenter_position, atol=1e-5)


def test_a_direction_for_a_contact_set_solves_that_sets_linear_penalty():
    """``Body._solve_for_set``: Newton's direction for a chosen contact set (nodes entering
    and leaving the plate's patch) from the kept factorisation corrected by Woodbury's
    identity is the solution of the system assembled directly: the material's tangent plus
    kappa n n^T on the set's nodes, the material's residual plus the linear penalty
    -kappa p n on them (a node outside the plate pulled in: p < 0), position control."""
    import scipy.sparse.linalg as spla

    opts = NewtonOptions(reuse_factorization=True, contact_update=True)
    body = _pressed_body(opts)
    disc = body.disc
    control = Control.position(body.indenter_position - 0.05)
    r, data, _, _, _, _, parts = body._evaluate(body.u, control, control.value, 0.01, True)
    body._factor(data(), parts[1][0] >= 0, body._contact_blocks(parts))
    p = parts[1][0]  # the plate
    now = p >= 0
    gap = np.where(now, np.inf, -p)
    entering = np.argsort(gap)[:5]  # the five nearest nodes outside the patch
    leaving = np.flatnonzero(now)[:2]
    assert np.all(p[entering] < 0) and len(leaving) == 2
    plate_set = now.copy()
    plate_set[entering] = True
    plate_set[leaving] = False
    masks = [parts[0][0] >= 0, plate_set]
    du, dd = body._solve_for_set(parts, data, masks, r, control)
    assert dd == 0.0

    ev = disc.evaluate(body.u, body.states, 0.01)  # the body alone, no contact
    K = disc.pattern.matrix(ev.tangent()).tolil()
    b = ev.residual.copy()
    for (pk, nk, _, is_plate), mask in zip(parts, masks, strict=True):
        kappa = body.kappa_indenter if is_plate else body.kappa_nodes
        for node in np.flatnonzero(mask):
            dofs = [body._sdof[i][node] for i in range(3)]
            for i, di in enumerate(dofs):
                if di < 0:
                    continue
                b[di] -= kappa[node] * pk[node] * nk[node, i]
                for j, dj in enumerate(dofs):
                    if dj >= 0:
                        K[di, dj] += kappa[node] * nk[node, i] * nk[node, j]
    expected = spla.spsolve(K.tocsc(), -b)
    np.testing.assert_allclose(du, expected, rtol=0, atol=1e-8 * np.abs(expected).max())


def test_active_set_solves_reach_the_same_state_in_fewer_iterations():
    """``NewtonOptions.active_set_solves``: the press of the contact-update test, its patch
    growing over surface nodes at every step, solved again for the contact set each Newton
    step leads to: the same states (to the order of the Newton tolerance), and the rim's
    nodes no longer cost iterations."""
    bodies = [
        _pressed_body(
            NewtonOptions(reuse_factorization=True, contact_update=True, active_set_solves=k)
        )
        for k in (0, 4)
    ]
    plain, settled = bodies
    print(f"Newton iterations: {plain.newton_iterations} -> {settled.newton_iterations}")
    assert settled.newton_iterations < plain.newton_iterations
    size = np.abs(plain.u).max()
    np.testing.assert_allclose(settled.u, plain.u, rtol=0, atol=1e-5 * size)
    np.testing.assert_allclose(settled.indenter_position, plain.indenter_position, atol=1e-5)


def test_active_set_solves_factorise_afresh_at_most_once_an_iteration():
    """With a Woodbury bound of 16 dofs, changes of the contact set in the active-set solves
    need fresh factorisations: a settle makes at most one (solver 2.8; a set beyond the bound
    again keeps the last set's direction), so an iteration factorises at most twice, and the
    press reaches the state of plain modified Newton. (Solver 2.7, which factorised for every
    such set, made two in one settle here and failed the press's line search.)"""
    from sim.fe.solver import Body as _Body

    settles: list[int] = []
    settle = _Body._settle_active_set

    def counted(self, *args, **kwargs):
        before = self.factorizations
        out = settle(self, *args, **kwargs)
        settles.append(self.factorizations - before)
        return out

    _Body._settle_active_set = counted
    try:
        opts = dict(reuse_factorization=True, contact_update=True, contact_update_dofs=16)
        body = _pressed_body(NewtonOptions(**opts, active_set_solves=4))
    finally:
        _Body._settle_active_set = settle
    plain = _pressed_body(NewtonOptions(**opts))
    assert settles and max(settles) == 1  # the bound made some settles factorise
    assert body.factorizations <= 2 * body.newton_iterations
    size = np.abs(plain.u).max()
    np.testing.assert_allclose(body.u, plain.u, rtol=0, atol=1e-5 * size)


def test_kept_columns_are_emptied_when_full():
    """``_KeptColumns`` holds at most ``capacity`` columns: a change that would overflow it
    empties it and solves its own columns afresh, which are then exact."""
    import scipy.sparse as sp

    from sim.fe._linear import make_solver
    from sim.fe.solver import _KeptColumns

    n = 20
    K = (sp.diags(np.arange(1.0, n + 1)) + sp.eye(n, k=1) + sp.eye(n, k=-1)).tocsc()
    solver = make_solver("qdldl")
    solver.factor(sp.triu(K).tocsc())
    kept = _KeptColumns(capacity=3)
    kept.columns(solver, np.array([0, 1]), n)
    Z = kept.columns(solver, np.array([1, 5]), n)  # one new: fits (3 columns)
    assert (kept.solved, kept.served) == (3, 1)
    Z = kept.columns(solver, np.array([7, 8]), n)  # would hold 5: emptied, both solved
    assert (kept.solved, kept.served) == (5, 1)
    np.testing.assert_allclose(K @ Z, np.eye(n)[:, [7, 8]], atol=1e-12)


def test_a_plane_strain_slab_carries_the_2d_line_load():
    """The 2D section extruded into a slab of Q2 hexahedra (``extruded_section_mesh``) with
    u_z = 0 everywhere: plane strain, the middle of a long extrusion. Its plate force per unit
    thickness is the 2D model's line load up to the two discretisations' errors (P2 triangles
    of ``MeshOptions()`` against Q2 hexahedra on ``PAD_MESH_3D``'s face z = 0): measured
    -0.69 % and +0.62 % at 0.5 and 1 mm; -0.05 % and +0.27 % on the finest meshes of
    ``python studies/plane_strain_slab.py`` (docs/model_3d.md). Its force per mm does not
    depend on the slab's thickness (to Newton's tolerance, which is per node)."""
    from sim.fe import Discretization
    from sim.geometry import PAD_MESH_3D, MeshOptions, build_mesh, extruded_section_mesh
    from sim.verification import press_plate

    mat = material_from_table({"model": "neo_hookean", "mu_MPa": 0.05, "nu": 0.49})
    depths = (0.5, 1.0)
    flat = Body(Discretization(build_mesh(PAD.section, (), MeshOptions()), [mat]), Plate())
    line_load = press_plate(flat, depths, 0.1)

    def plane_strain(X: np.ndarray) -> np.ndarray:
        mask = np.zeros(X.shape, dtype=bool)
        mask[X[:, 1] == 0.0] = True  # the bonded base
        mask[X[:, 0] == 0.0, 0] = True  # the symmetry plane x = 0
        mask[:, 2] = True  # plane strain
        return mask

    per_mm = {}
    for thickness in (0.5, 2.0):
        slab = extruded_section_mesh(build_pad_mesh(PAD, (), PAD_MESH_3D), thickness)
        body = Body(Discretization3D(slab, [mat], fixed=plane_strain), Plate())
        per_mm[thickness] = press_plate(body, depths, 0.1) / thickness
    rel = per_mm[0.5] / line_load - 1.0
    print(f"slab / 2D line load - 1 at {depths} mm: {rel}")
    assert np.all(np.abs(rel) < 0.01), rel
    np.testing.assert_allclose(per_mm[2.0], per_mm[0.5], rtol=1e-5)


def test_a_script_using_pardiso_exits_without_noise():
    """PARDISO's memory is freed when its solver goes, also at interpreter exit, with
    nothing printed (a user's `fingertip simulate --model 3d` ends clean)."""
    pytest.importorskip("pypardiso")
    import subprocess
    import sys

    code = (
        "import scipy.sparse as sp, numpy as np\n"
        "from sim.fe._linear import make_solver\n"
        "s = make_solver('pardiso')\n"
        "s.factor(sp.triu(sp.diags([4.0] * 50) + sp.eye(50, k=1) + sp.eye(50, k=-1)).tocsc())\n"
        "print(s.solve(np.ones(50))[0])\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stderr == ""


def test_the_line_searchs_contact_part_is_the_residuals(two_layers):
    """``Body._contact_slope``, evaluated from the surface nodes alone, is the contacts' part of
    the line search's g(a) = [du, dd] . residual(a) under force control: g minus the body's own
    part (its internal forces alone), at steps where nodes enter the plate."""
    body = Body(two_layers, Plate(), NewtonOptions())
    disc = two_layers
    u = _smooth(disc.X)
    u[disc.fixed] = 0.0
    d = body.top_height(u) - 0.2
    control = Control.force(0.3)
    rng = np.random.default_rng(5)
    du = 2e-3 * rng.standard_normal(disc.n_free)
    dd = -0.2  # the plate moves down: more nodes enter contact along the line
    entered = check_contact_slope(body, u, d, du, dd, control)
    assert entered[0] >= 1 and entered[-1] > entered[0]


def test_the_contact_edge_study_reads_a_face_bilinearly():
    """``studies/contact_edge3d.py``'s bilinear reading of a 9-node face: positive everywhere
    when every node touches, and for a penetration linear in s (nodes at s = -1, 0, 1 with
    p = s - 0.25) the samples beyond s = 0.25 exactly, as a linear field's zero crossing is."""
    import importlib.util
    from pathlib import Path

    from sim.geometry import _q2

    path = Path(__file__).resolve().parents[1] / "studies" / "contact_edge3d.py"
    spec = importlib.util.spec_from_file_location("contact_edge3d", path)
    study = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(study)
    samples = 8
    assert study.bilinear_inside(np.full((1, 9), 1e-4), samples).all()
    p = (_q2.FACE_REFERENCE_POINTS[:, 0] - 0.25)[None, :]
    t = (np.arange(samples) + 0.5) / samples * 2.0 - 1.0
    S, _ = np.meshgrid(t, t, indexing="ij")
    np.testing.assert_array_equal(study.bilinear_inside(p, samples)[0], S.ravel() > 0.25)


def test_pardiso_keeps_one_factorisation_per_slot(pressed):
    """``Pardiso(slots)``: two matrices of the one pattern factorised in two slots (PARDISO's
    ``maxfct``/``mnum``) each solve their own system to rounding, also after the other slot
    was factorised again, and a slot's view solves with its slot whatever the solver's
    current slot is."""
    pytest.importorskip("pypardiso")
    import scipy.sparse as sp

    from sim.fe._linear import make_solver

    disc = pressed.disc
    ev = disc.evaluate(pressed.u, pressed.states, 0.0, frozen_history=True)
    upper = disc.upper_matrix(ev.tangent()).tocsc()
    col = np.repeat(np.arange(upper.shape[0]), np.diff(upper.indptr))
    stiffer = upper.copy()
    stiffer.data[upper.indices == col] *= 1.5  # another matrix of the same pattern
    full = [m + sp.triu(m, k=1).T for m in (upper, stiffer)]
    b = np.random.default_rng(0).standard_normal(upper.shape[0])
    solver = make_solver("pardiso", slots=3)
    solver.factor(upper)  # slot 1
    solver.slot = 3
    solver.refactor(stiffer.data)
    views = [solver.view(1), solver.view(3)]
    for _ in range(2):  # the second time after slot 3 was factorised again
        for view, K in zip(views, full, strict=True):
            x = view.solve(b)
            assert np.linalg.norm(K @ x - b) <= 1e-10 * np.linalg.norm(b)
        solver.slot = 3
        solver.refactor(stiffer.data)
    x1, x3 = (v.solve(b) for v in views)
    assert np.linalg.norm(x1 - x3) > 1e-3 * np.linalg.norm(x1)  # two factorisations indeed
    assert make_solver("qdldl", slots=3).view(2).slots == 1  # qdldl keeps one


@pytest.mark.parametrize("name", ["qdldl", "pardiso", "pardiso-single"])
def test_refactor_gathers_the_upper_triangle_from_the_tangent(pressed, name):
    """``refactor(data, index)`` (the body's call: the tangent's data and the upper triangle's
    positions in it, gathered once into the solver's order) factorises the same matrix as
    ``refactor(data[index])``: the same solution bits, in every slot, also after ``factor``
    analysed another pattern."""
    if name != "qdldl":
        pytest.importorskip("pypardiso")
    from sim.fe._linear import make_solver

    disc = pressed.disc
    data = disc.evaluate(pressed.u, pressed.states, 0.0, frozen_history=True).tangent()
    index = disc.upper_data
    b = np.random.default_rng(1).standard_normal(disc.n_free)
    stiffer = data * 1.25
    solvers = [make_solver(name, slots=2) for _ in range(2)]
    for solver in solvers:
        solver.factor(disc.upper_matrix(data))
    for slot in (1, 2) if name != "qdldl" else (1,):
        for solver in solvers:
            solver.slot = slot
        solvers[0].refactor(stiffer, index)
        solvers[1].refactor(np.take(stiffer, index))
        np.testing.assert_array_equal(solvers[0].solve(b), solvers[1].solve(b))
    small = disc.upper_matrix(data)[:60, :60]  # another pattern: the composed order follows it
    for solver in solvers:
        solver.slot = 1
        solver.factor(small)
    solvers[0].refactor(small.data * 2.0, np.arange(small.nnz))
    solvers[1].refactor(small.data * 2.0)
    np.testing.assert_array_equal(solvers[0].solve(b[:60]), solvers[1].solve(b[:60]))


def _step_keyed_body(step_factors_MB: float = 1e6) -> Body:
    """A viscoelastic pad under modified Newton that keeps a factorisation per step key."""
    pmesh = build_pad_mesh(PAD, (), COARSE)
    table = {"model": "neo_hookean", "mu_MPa": 0.05, "nu": 0.49}
    mat = material_from_table({**table, "prony_g": [0.3], "prony_tau_s": [0.5]})
    opts = NewtonOptions(reuse_factorization=True, contact_update=True, active_set_solves=4)
    body = Body(Discretization3D(pmesh, [mat]), Plate(), opts)
    body.single_precision = True
    body.step_factors, body.step_factors_MB = 4, step_factors_MB
    return body


def test_a_keyed_step_begins_with_its_keys_factorisation():
    """``Body.advance(factor_key=...)``: a step's factorisations go to its key's own slot, and
    a later step of the same key begins with that factorisation (not the last one made); the
    state is Newton's answer either way (the same press without keys, to Newton's
    tolerance)."""
    pytest.importorskip("pypardiso")
    scale = None
    bodies = []
    for keyed in (True, False):
        body = _step_keyed_body()
        scale = 1.0 / body.disc.force_scale(10.0)
        for k, f in enumerate([0.1, 0.2, 0.3]):  # a ramp, no keys
            assert body.advance(0.05 * (k + 1), Control.force(f * scale)).converged
        loads = [0.4, 0.5, 0.4, 0.5]  # keys A, B, A, B: a schedule that repeats
        for k, f in enumerate(loads):
            key = "AB"[k % 2] if keyed else None
            body._stale = k < 2  # the first round factorises afresh (in the key's slot)
            t = 0.05 * (k + 4)
            assert body.advance(t, Control.force(f * scale), factor_key=key).converged
            if keyed and k < 2:
                assert body._step_factors[key].serial == body._serial
            if keyed and k >= 2:  # the second round: each step began with its key's
                assert body.step_factor_takes == k - 1
        bodies.append(body)
    keyed, plain = bodies
    assert set(keyed._step_factors) == {"A", "B"} and plain.step_factors_kept == 0
    assert {s.solver.slot for s in keyed._step_factors.values()} == {2, 3}
    assert plain.step_factor_takes == 0
    size = np.abs(plain.u).max()
    np.testing.assert_allclose(keyed.u, plain.u, rtol=0, atol=1e-5 * size)
    np.testing.assert_allclose(keyed.force, plain.force, rtol=1e-5)


def test_keyed_factorisations_stay_within_their_memory():
    """``Body.step_factors_MB``: where one slot's factorisation (``slot_memory_MB``) fits
    once, one key keeps its own and the others share slot 1."""
    pytest.importorskip("pypardiso")
    probe = _step_keyed_body()
    scale = 1.0 / probe.disc.force_scale(10.0)
    assert probe.advance(0.05, Control.force(0.1 * scale), factor_key="A").converged
    per_slot = probe._solvers["pardiso-single"].slot_memory_MB()
    assert per_slot is not None and per_slot > 0
    body = _step_keyed_body(step_factors_MB=1.5 * per_slot)
    for k, (f, key) in enumerate(zip([0.1, 0.2, 0.3], "ABC", strict=True)):
        assert body.advance(0.05 * (k + 1), Control.force(f * scale), factor_key=key).converged
    assert body.step_factors_kept == 1 and body.factorizations >= 3


def test_an_entry_beyond_single_precision_is_cast_quietly_and_solves_its_tangent_badly():
    """A tangent entry beyond float32's range (a pursued iterate far from the solution) becomes
    inf in the single-precision factorisation without a warning, and that factorisation then
    solves its own tangent worse than ``INEXACT_SOLVE_RTOL``, so a failed attempt with it is
    retried in double precision (``Body._retry``)."""
    pytest.importorskip("pypardiso")
    import warnings

    import scipy.sparse as sp

    from sim.fe._linear import PardisoSingle
    from sim.fe.solver import INEXACT_SOLVE_RTOL

    n = 6
    K = sp.diags([np.full(n - 1, -1.0), np.full(n, 4.0), np.full(n - 1, -1.0)], [-1, 0, 1])
    upper = sp.triu(K).tocsc()
    solver = PardisoSingle()
    solver.factor(upper)
    data = upper.data.copy()
    data[0] = 1e39  # finite in double, beyond float32's 3.4e38
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        solver.refactor(data)
    big = sp.csc_matrix((data, upper.indices, upper.indptr), shape=upper.shape)
    big = big + sp.triu(big, k=1).T
    b = np.random.default_rng(0).standard_normal(n)
    x = solver.solve(b)
    assert np.linalg.norm(big @ x - b) / np.linalg.norm(b) > INEXACT_SOLVE_RTOL
