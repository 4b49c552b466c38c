"""Verification machinery shared by ``tests/test_verification.py``, ``tests/test_felupe.py`` and
``studies/verify_fe.py`` (which regenerates ``docs/verification.md``): closed-form stresses of
every law in homogeneous modes, plane-strain Hertz contact, a manufactured solution on the curved
P2 mesh, global equilibrium, and the comparison with FElupe (imported on first use: the ``test``
extra).

The closed forms here are derived by hand from the energies (see each docstring); they use no
code from ``sim.materials`` other than reading the laws' parameters.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.optimize import brentq

from sim.materials import Hyperfoam, Law, MooneyRivlin, NeoHookean, Yeoh

if TYPE_CHECKING:
    from sim.fe import Body, Discretization
    from sim.geometry import FingertipMesh

__all__ = [
    "MMS_FIELD",
    "MODES",
    "Balance",
    "FelupeComparison",
    "HertzResult",
    "MMSResult",
    "ManufacturedSolution",
    "ModeError",
    "balance",
    "boundary_fixed_mask",
    "code_cauchy",
    "equibiaxial_errors",
    "felupe_internal_forces",
    "felupe_model",
    "felupe_p2_element",
    "felupe_plate_comparison",
    "hand_moduli",
    "hertz_case",
    "hertz_line_contact",
    "law_cases",
    "mms_case",
    "nodal_contact_pressure",
    "principal_cauchy",
    "shape_gradient_error",
    "shear_errors",
    "simple_shear_cauchy",
    "sweep",
    "uniaxial_errors",
    "uniaxial_lateral_stretch",
]

# ============================================================================================
# 1. Closed-form stresses in homogeneous modes (plane strain, F33 = 1)
# ============================================================================================


def hand_moduli(law: Law) -> tuple[float, float]:
    """(mu0, K0) from the textbook definitions, not from the law's properties.

    Invariant laws: mu0 = 2 (dU/dI1b + dU/dI2b) at the reference state, K0 from (mu0, nu);
    hyperfoam: mu0 = sum mu_i, K0 = sum 2 mu_i (1/3 + beta)."""
    nu = law.nu
    if isinstance(law, Hyperfoam):
        mu0 = math.fsum(law.mu_MPa)
        return mu0, 2.0 * mu0 * (1.0 / 3.0 + nu / (1.0 - 2.0 * nu))
    if isinstance(law, NeoHookean):
        mu0 = law.mu_MPa
    elif isinstance(law, MooneyRivlin):
        mu0 = 2.0 * (law.c10_MPa + law.c01_MPa)
    elif isinstance(law, Yeoh):
        mu0 = 2.0 * law.c10_MPa
    else:
        raise TypeError(type(law))
    return mu0, 2.0 * mu0 * (1.0 + nu) / (3.0 * (1.0 - 2.0 * nu))


def _invariant_derivatives(law: Law, i1b: float) -> tuple[float, float]:
    """(W1, W2) = (dU/dI1b, dU/dI2b) of the Abaqus energies
    NH: mu/2 (I1b - 3); MR: C10 (I1b - 3) + C01 (I2b - 3); Yeoh: sum Ci0 (I1b - 3)^i."""
    if isinstance(law, NeoHookean):
        return 0.5 * law.mu_MPa, 0.0
    if isinstance(law, MooneyRivlin):
        return law.c10_MPa, law.c01_MPa
    x = i1b - 3.0
    return law.c10_MPa + 2.0 * law.c20_MPa * x + 3.0 * law.c30_MPa * x * x, 0.0


def principal_cauchy(law: Law, l1: float, l2: float) -> np.ndarray:
    """Principal Cauchy stresses (sigma_1, sigma_2, sigma_3) at stretches (l1, l2, 1).

    sigma_a = (lambda_a / J) dU/dlambda_a, with J = l1 l2 (the stretches as independent
    variables, l3 = 1 set after differentiating).

    Invariant laws, U = U_iso(I1b, I2b) + K/2 (J - 1)^2, I1b = J^(-2/3) I1, I2b = J^(-4/3) I2,
    I1 = sum l^2, I2 = sum_{a<b} l_a^2 l_b^2: lambda_a dJ/dlambda_a = J, so
    lambda_a dI1b/dlambda_a = 2 J^(-2/3) l_a^2 - 2/3 I1b,
    lambda_a dI2b/dlambda_a = 2 J^(-4/3) l_a^2 (I1 - l_a^2) - 4/3 I2b, and
    sigma_a = [W1 (2 J^(-2/3) l_a^2 - 2/3 I1b) + W2 (2 J^(-4/3) l_a^2 (I1 - l_a^2) - 4/3 I2b)] / J
    + K (J - 1).

    Hyperfoam, U = sum 2 mu_i / alpha_i^2 [sum_a l_a^alpha_i - 3 + (J^(-alpha_i beta) - 1)/beta]:
    sigma_a = (1/J) sum 2 mu_i / alpha_i (l_a^alpha_i - J^(-alpha_i beta)), written with expm1
    so that alpha = 0.001 does not cancel.
    """
    lam = np.array([l1, l2, 1.0])
    J = l1 * l2
    if isinstance(law, Hyperfoam):
        beta = law.nu / (1.0 - 2.0 * law.nu)
        out = np.zeros(3)
        for mu, a in zip(law.mu_MPa, law.alpha, strict=True):
            out += 2.0 * mu / a * (np.expm1(a * np.log(lam)) - math.expm1(-a * beta * math.log(J)))
        return out / J
    _, K = hand_moduli(law)
    sq = lam**2
    I1 = float(sq.sum())
    I2 = float(sq[0] * sq[1] + sq[1] * sq[2] + sq[0] * sq[2])
    i1b, i2b = J ** (-2.0 / 3.0) * I1, J ** (-4.0 / 3.0) * I2
    W1, W2 = _invariant_derivatives(law, i1b)
    d1 = 2.0 * J ** (-2.0 / 3.0) * sq - 2.0 / 3.0 * i1b
    d2 = 2.0 * J ** (-4.0 / 3.0) * sq * (I1 - sq) - 4.0 / 3.0 * i2b
    return (W1 * d1 + W2 * d2) / J + K * (J - 1.0)


def uniaxial_lateral_stretch(law: Law, l1: float) -> float:
    """Plane-strain uniaxial stress: the in-plane lateral stretch l2 with sigma_2 = 0.

    The root is bracketed outwards from the isochoric l2 = 1 / l1 (stiff-exponent foams overflow
    far from J = 1), then found by Brent's method to machine precision."""
    mu0, _ = hand_moduli(law)

    def s2(l2: float) -> float:
        return float(principal_cauchy(law, l1, l2)[1]) / mu0

    lo = hi = 1.0 / l1
    for _ in range(100):  # 1.05^100 = 130: far beyond any physical lateral stretch
        if s2(lo) <= 0.0 <= s2(hi):
            return brentq(s2, lo, hi, xtol=1e-15, rtol=1e-15)
        lo, hi = lo / 1.05, hi * 1.05
    raise ValueError(f"no lateral stretch with sigma_2 = 0 at l1 = {l1}")


def simple_shear_cauchy(law: Law, gamma: float) -> np.ndarray:
    """Cauchy stress (sigma11, sigma22, sigma33, sigma12) in simple shear F = [[1, g], [0, 1]].

    J = 1, so the volumetric term vanishes.  Invariant laws, from sigma = -p I + 2 W1 B
    - 2 W2 B^-1 with B = [[1 + g^2, g], [g, 1]], B^-1 = [[1, -g], [-g, 1 + g^2]] and p fixed by
    the deviatoric split (tr B = tr B^-1 = 3 + g^2, I1b = I2b = 3 + g^2):
    sigma12 = 2 g (W1 + W2), sigma11 = 2/3 g^2 (2 W1 + W2), sigma22 = -2/3 g^2 (W1 + 2 W2),
    sigma33 = -2/3 g^2 (W1 - W2).

    Hyperfoam: principal stretches l+- = sqrt(1 + g^2/4) +- |g|/2 (l+ l- = 1), the larger
    eigenvector of B at angle theta with cos 2theta = |g| / sqrt(g^2 + 4),
    sin 2theta = sign(g) 2 / sqrt(g^2 + 4); sigma = R diag(s+, s-) R^T.
    """
    g2 = gamma * gamma
    if not isinstance(law, Hyperfoam):
        W1, W2 = _invariant_derivatives(law, 3.0 + g2)
        return np.array(
            [
                2.0 / 3.0 * g2 * (2.0 * W1 + W2),
                -2.0 / 3.0 * g2 * (W1 + 2.0 * W2),
                -2.0 / 3.0 * g2 * (W1 - W2),
                2.0 * gamma * (W1 + W2),
            ]
        )
    root = math.sqrt(g2 + 4.0)
    lp = math.sqrt(1.0 + 0.25 * g2) + 0.5 * abs(gamma)
    sp, sm, s3 = principal_cauchy(law, lp, 1.0 / lp)
    c2, s2 = abs(gamma) / root, math.copysign(2.0, gamma) / root
    mean, half = 0.5 * (sp + sm), 0.5 * (sp - sm)
    return np.array([mean + half * c2, mean - half * c2, s3, half * s2])


def code_cauchy(law: Law, F: np.ndarray) -> np.ndarray:
    """(sigma11, sigma22, sigma33, sigma12) from the law under test at the in-plane F (2x2):
    sigma = F S F^T / J with S = law.stress(C), sigma33 = law.S33(C) / J."""
    C = F.T @ F
    Cv = np.array([C[0, 0], C[1, 1], C[0, 1]])
    S = law.stress(Cv)
    Sm = np.array([[S[0], S[2]], [S[2], S[1]]])
    J = float(np.linalg.det(F))
    sig = F @ Sm @ F.T / J
    return np.array([sig[0, 0], sig[1, 1], float(law.S33(Cv)) / J, sig[0, 1]])


@dataclass(frozen=True)
class ModeError:
    """Largest relative error of the code's stresses against the closed form over a sweep."""

    mode: str
    max_rel_error: float
    n_points: int
    worst_at: float


def _rel(got: np.ndarray, ref: np.ndarray) -> float:
    """Componentwise relative error; a component below 1e-3 of the state's largest stress
    (e.g. a stress that vanishes in the closed form) is compared against that 1e-3 instead."""
    floor = 1e-3 * float(np.max(np.abs(ref)))
    return float(np.max(np.abs(got - ref) / np.maximum(np.abs(ref), floor)))


def _sweep(mode: str, values: np.ndarray, pair: Callable) -> ModeError:
    """Worst ``_rel`` over ``values`` of ``pair(v) -> (code, closed form)``."""
    errs = np.array([_rel(*pair(float(v))) for v in values])
    k = int(np.argmax(errs))
    return ModeError(mode, float(errs[k]), len(values), float(values[k]))


def uniaxial_errors(law: Law, stretches: np.ndarray, code_law: Law | None = None) -> ModeError:
    """Plane-strain uniaxial stress: nominal stress P11 = sigma_1 J / l1 = sigma_1 l2, the
    lateral sigma_2 (zero), sigma_3 and sigma_12 (zero), with l2 from the closed form.
    ``code_law`` (default ``law``) is the law whose implementation is checked."""
    code_law = law if code_law is None else code_law

    def pair(l1: float) -> tuple[np.ndarray, np.ndarray]:
        l2 = uniaxial_lateral_stretch(law, l1)
        ref = principal_cauchy(law, l1, l2)
        got = code_cauchy(code_law, np.diag([l1, l2]))
        return got * np.array([l2, 1.0, 1.0, 1.0]), np.array([ref[0] * l2, 0.0, ref[2], 0.0])

    return _sweep("uniaxial", stretches, pair)


def equibiaxial_errors(law: Law, stretches: np.ndarray, code_law: Law | None = None) -> ModeError:
    """Equibiaxial l1 = l2 = l: sigma_1 = sigma_2, sigma_3, sigma_12 = 0."""
    code_law = law if code_law is None else code_law

    def pair(lam: float) -> tuple[np.ndarray, np.ndarray]:
        ref = principal_cauchy(law, lam, lam)
        return code_cauchy(code_law, np.diag([lam, lam])), np.append(ref, 0.0)

    return _sweep("equibiaxial", stretches, pair)


def shear_errors(law: Law, gammas: np.ndarray, code_law: Law | None = None) -> ModeError:
    """Simple shear F = [[1, g], [0, 1]]: all four Cauchy components."""
    code_law = law if code_law is None else code_law

    def pair(g: float) -> tuple[np.ndarray, np.ndarray]:
        F = np.array([[1.0, g], [0.0, 1.0]])
        return code_cauchy(code_law, F), simple_shear_cauchy(law, g)

    return _sweep("simple shear", gammas, pair)


MODES = {"uniaxial": uniaxial_errors, "equibiaxial": equibiaxial_errors, "shear": shear_errors}


def law_cases() -> dict[str, Law]:
    """The laws checked against the closed forms: both catalogue hyperfoams (stiff exponents,
    nu = 0.47-0.49, alpha = 0.001), a three-term foam with a negative exponent, a foam with
    nu = 0 (beta = 0), and the invariant laws with I2b (Mooney-Rivlin) and I1b^3 (Yeoh) terms."""
    from sim.materials import CATALOGUE

    return {
        "silicone_gls40": CATALOGUE["silicone_gls40"].law,
        "polyurethane_74_45": CATALOGUE["polyurethane_74_45"].law,
        "hyperfoam_3term": Hyperfoam(mu_MPa=[0.1, -0.02, 0.05], alpha=[2.0, -3.0, 0.5], nu=0.3),
        "hyperfoam_nu0": Hyperfoam(mu_MPa=[0.2], alpha=[3.0], nu=0.0),
        "neo_hookean": NeoHookean(mu_MPa=0.1, nu=0.45),
        "mooney_rivlin": MooneyRivlin(c10_MPa=0.05, c01_MPa=0.02, nu=0.3),
        "yeoh": Yeoh(c10_MPa=0.05, c20_MPa=-0.01, c30_MPa=0.003, nu=0.4),
    }


def sweep(mode: str, n: int) -> np.ndarray:
    """n stretches in [0.5, 1.5] (shear: n amounts in [-0.5, 0.5]) without the reference
    state, where every stress vanishes and a relative error is meaningless."""
    values = np.linspace(-0.5, 0.5, n) if mode == "shear" else np.linspace(0.5, 1.5, n)
    rest = 0.0 if mode == "shear" else 1.0
    return values[np.abs(values - rest) > 1e-12]


# ============================================================================================
# 2. Plane-strain Hertz contact of a half-disc pressed by the flat plate
# ============================================================================================


@dataclass(frozen=True)
class HertzResult:
    """One plate-on-half-disc contact at a small load against plane-strain Hertz.

    Lengths in mm, forces per unit thickness of the full (symmetric) body in N/mm, pressures MPa.
    ``a_fit``/``p0_fit``: least-squares ellipse p^2 = p0^2 (1 - x^2 / a^2) through the nodal
    pressures; ``p_apex``: the nodal pressure at the apex (the largest); ``a_bracket``: the
    deformed x of the last node in contact and of the first node out of contact."""

    radius_mm: float
    a_over_h: float
    n_elements: int
    force_N_per_mm: float
    a_hertz: float
    p0_hertz: float
    a_fit: float
    p0_fit: float
    p_apex: float
    a_bracket: tuple[float, float]
    max_penetration_mm: float

    @property
    def a_over_R(self) -> float:
        return self.a_hertz / self.radius_mm

    @property
    def errors(self) -> dict[str, float]:
        """Relative errors of a (fit), p0 (fit) and the apex pressure."""
        return {
            "a_fit": self.a_fit / self.a_hertz - 1.0,
            "p0_fit": self.p0_fit / self.p0_hertz - 1.0,
            "p_apex": self.p_apex / self.p0_hertz - 1.0,
        }


def hertz_line_contact(force: float, radius: float, E: float, nu: float) -> tuple[float, float]:
    """Plane-strain Hertz (cylinder on a flat, one elastic body; Johnson, Contact Mechanics
    §4.3): a = sqrt(4 P R / (pi E*)), p0 = 2 P / (pi a), E* = E / (1 - nu^2), P per unit length."""
    E_star = E / (1.0 - nu * nu)
    a = math.sqrt(4.0 * force * radius / (math.pi * E_star))
    return a, 2.0 * force / (math.pi * a)


def nodal_contact_pressure(body: Body) -> tuple[np.ndarray, np.ndarray]:
    """Deformed x of the surface nodes and their plate pressure (MPa).

    The penalty force on node i is f_i = kappa_i * penetration_i (``Body._add_contact``), with
    kappa_i = kappa * w_i(reference); the pressure is f_i over the node's tributary length
    ``surface_weights`` of the deformed surface."""
    from sim.fe.contact import surface_weights

    disc = body.disc
    s = disc.surface_nodes
    xy = disc.X[s] + body.u[s]
    pen, _ = body.indenter.penetration(xy, body.indenter_position)
    force = np.where(pen > 0.0, body.kappa_indenter * pen, 0.0)
    return xy[:, 0], force / surface_weights(xy)


def hertz_case(
    a_over_R: float,
    a_over_h: float,
    radius_mm: float = 5.0,
    grading: float = 0.1,
    mu: float = 0.1,
    nu: float = 0.3,
    penalty_per_mm: float = 2e4,
) -> HertzResult:
    """Press a neo-Hookean half-disc of radius R (bonded base) with the plate to the load whose
    Hertz half-width is ``a_over_R * R``; elements of size a / ``a_over_h`` over the contact.

    The plate is moved down in growing position steps until the force exceeds the target, then
    one force-controlled step lands on it exactly (force control from first touch is fragile).
    The penalty (``penalty_per_mm`` x E0 per mm) keeps the penetration ~1e-4 of a^2 / R."""
    from sim.fe import Body, Control, Discretization, NewtonOptions, Plate
    from sim.geometry import Geometry, MeshOptions, build_mesh
    from sim.materials import Material

    E = 2.0 * mu * (1.0 + nu)
    a_target = a_over_R * radius_mm
    force = math.pi * E / (1.0 - nu * nu) * a_target**2 / (4.0 * radius_mm)
    h = a_target / a_over_h
    opts = MeshOptions(h, h, min(1.0, 1.5 * a_over_R), grading, radius_mm / 5.0)
    fm = build_mesh(Geometry(radius_mm, radius_mm, 2.0), (), opts)
    disc = Discretization(fm, [Material(NeoHookean(mu_MPa=mu, nu=nu))])
    body = Body(disc, Plate(), NewtonOptions(rtol=1e-9), indenter_penalty_per_mm=penalty_per_mm)
    depth, t = 0.1 * a_target**2 / radius_mm, 0.0
    while 2.0 * body.force < force:  # body.force is per unit thickness of the half model
        t += 1.0
        res = body.advance(t, Control.position(radius_mm - depth))
        if not res.converged:
            raise RuntimeError(f"Hertz approach step failed: {res.reason}")
        depth *= 1.5
    res = body.advance(t + 1.0, Control.force(0.5 * force))
    if not res.converged:
        raise RuntimeError(f"Hertz force step failed: {res.reason}")
    P = 2.0 * body.force
    a_h, p0_h = hertz_line_contact(P, radius_mm, E, nu)
    x, p = nodal_contact_pressure(body)
    on = p > 0.0
    slope, intercept = np.polyfit(x[on] ** 2, p[on] ** 2, 1)
    return HertzResult(
        radius_mm=radius_mm,
        a_over_h=a_over_h,
        n_elements=disc.n_el,
        force_N_per_mm=P,
        a_hertz=a_h,
        p0_hertz=p0_h,
        a_fit=math.sqrt(-intercept / slope),
        p0_fit=math.sqrt(intercept),
        p_apex=float(p[0]),
        a_bracket=(float(x[on].max()), float(x[~on].min())),
        max_penetration_mm=body.max_penetration(),
    )


# ============================================================================================
# 3. Manufactured solution on the curved P2 fingertip mesh
# ============================================================================================

# the exact displacement (mm) on the fingertip (x in [0, 5.84], y in [0, 5.48]): smooth, not a
# polynomial, strains up to ~10 %, so the law is well into its nonlinear range
MMS_FIELD = (
    "0.2 * sin(0.5 * x + 0.1) * cos(0.3 * y) + 0.03 * x * y / 5",
    "-0.15 * sin(0.4 * y) * cos(0.25 * x) + 0.05 * sin(0.3 * x + 0.2 * y)",
)


class ManufacturedSolution:
    """u_exact (``MMS_FIELD``) and the body force b = -Div P(F(u_exact)) for an invariant law.

    Derived with sympy, independently of ``sim.materials``: the energy is written from scratch
    in the entries of the in-plane F (F33 = 1), U = U_iso(I1b, I2b) + K/2 (J - 1)^2 with
    I1 = tr C + 1, I2 = (I1^2 - tr C^2 - 1) / 2, J = det F, and differentiated twice:
    A_iJkL = d2U / dF_iJ dF_kL.  Then b_i = -A_iJkL(F) u_k,LJ (chain rule of Div P, exact).
    """

    def __init__(self, law: Law, field: tuple[str, str] = MMS_FIELD) -> None:
        import sympy as sym

        x, y = sym.symbols("x y", real=True)
        f = sym.symbols("f00 f01 f10 f11", real=True)
        Fm = sym.Matrix([[f[0], f[1]], [f[2], f[3]]])
        C = Fm.T * Fm
        J = Fm.det()
        I1 = C.trace() + 1
        I2 = (I1**2 - (C * C).trace() - 1) / 2
        i1b, i2b = J ** sym.Rational(-2, 3) * I1, J ** sym.Rational(-4, 3) * I2
        U = self._energy(law, i1b, i2b) + sym.Rational(1, 2) * hand_moduli(law)[1] * (J - 1) ** 2
        P = [sym.diff(U, fi) for fi in f]  # P_iJ in the order 00, 01, 10, 11
        A = [[sym.diff(Pi, fk) for fk in f] for Pi in P]
        u = [sym.sympify(e, locals={"x": x, "y": y}) for e in field]
        grad = [[sym.diff(uk, v) for v in (x, y)] for uk in u]
        hess = [[[sym.diff(uk, a, b) for b in (x, y)] for a in (x, y)] for uk in u]
        self._u = sym.lambdify((x, y), u, "numpy")
        self._grad = sym.lambdify((x, y), grad, "numpy")
        self._hess = sym.lambdify((x, y), hess, "numpy")
        self._P = sym.lambdify(f, P, "numpy", cse=True)
        self._A = sym.lambdify(f, A, "numpy", cse=True)

    @staticmethod
    def _energy(law: Law, i1b, i2b):
        if isinstance(law, NeoHookean):
            return law.mu_MPa / 2 * (i1b - 3)
        if isinstance(law, MooneyRivlin):
            return law.c10_MPa * (i1b - 3) + law.c01_MPa * (i2b - 3)
        if isinstance(law, Yeoh):
            return sum(c * (i1b - 3) ** k for k, c in enumerate(_yeoh_coeffs(law), start=1))
        raise TypeError(f"no manufactured solution for {type(law).__name__}")

    def _bc(self, fn, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """A lambdified nested list evaluated and broadcast to the points' shape."""
        return np.array(np.broadcast_arrays(*_flatten(fn(x, y)), np.zeros_like(x))[:-1])

    def displacement(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """u_exact (2, *x.shape)."""
        return self._bc(self._u, x, y)

    def gradient(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """grad u_exact (2, 2, *x.shape): [k, L] = du_k / dX_L."""
        return self._bc(self._grad, x, y).reshape(2, 2, *np.shape(x))

    def _hessian(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """(2, 2, 2, *x.shape): [k, J, L] = d2 u_k / dX_J dX_L."""
        return self._bc(self._hess, x, y).reshape(2, 2, 2, *np.shape(x))

    def body_force(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """b = -Div P(u_exact) (2, *x.shape), N/mm^3."""
        return self._body_force_from(self.gradient(x, y), self._hessian(x, y), x)

    def _body_force_from(self, G: np.ndarray, H: np.ndarray, x: np.ndarray) -> np.ndarray:
        """-A_iJkL(I + G) H_kJL for a displacement gradient G and Hessian H."""
        F = [1.0 + G[0, 0], G[0, 1], G[1, 0], 1.0 + G[1, 1]]
        A = np.array(np.broadcast_arrays(*_flatten(self._A(*F)), x)[:-1])
        A = A.reshape(2, 2, 2, 2, *np.shape(x))  # [i, J, k, L]
        return -np.einsum("iJkL...,kJL...->i...", A, H)

    def first_piola(self, F: np.ndarray) -> np.ndarray:
        """P(F) (2, 2, ...) of the hand-written energy, for F (2, 2, ...)."""
        P = self._P(F[0, 0], F[0, 1], F[1, 0], F[1, 1])
        return np.array(np.broadcast_arrays(*P, F[0, 0])[:-1]).reshape(2, 2, *F.shape[2:])


def _yeoh_coeffs(law: Yeoh) -> tuple[float, float, float]:
    return law.c10_MPa, law.c20_MPa, law.c30_MPa


def _flatten(nested: Any) -> list:
    if isinstance(nested, list | tuple):
        return [v for item in nested for v in _flatten(item)]
    return [nested]


@dataclass(frozen=True)
class MMSResult:
    """Errors of the FE solution against u_exact on one mesh (relative to u_exact's norms)."""

    factor: float
    h_mm: float  # sqrt(domain area / elements): the element size the mesh options scale
    n_elements: int
    n_dofs: int
    l2_error: float
    h1_error: float
    newton_iterations: int
    residual: float  # final max |residual| (N/mm)


def boundary_fixed_mask(fmesh: FingertipMesh) -> Callable[[np.ndarray], np.ndarray]:
    """``fixed(X)`` for ``Discretization``: every P2 node on the mesh boundary (vertices and
    midpoints of the boundary facets), both components."""
    from scipy.spatial import cKDTree

    m = fmesh.mesh
    f = m.facets[:, m.boundary_facets()]
    pts = np.vstack([m.p[:, np.unique(f)].T, 0.5 * (m.p[:, f[0]] + m.p[:, f[1]]).T])
    tree = cKDTree(pts)

    def fixed(X: np.ndarray) -> np.ndarray:
        on = tree.query(X)[0] < 1e-10
        return np.repeat(on[:, None], 2, axis=1)

    return fixed


def _newton(
    disc: Discretization, u: np.ndarray, load: np.ndarray, tol: float, max_it: int = 25
) -> tuple[int, float]:
    """Newton on r(u) = f_int(u) - load = 0 over the free dofs (u updated in place).

    A trial that inverts an element is halved; returns (iterations, final max |r|)."""
    from scipy.sparse.linalg import splu

    states = disc.initial_states()
    flat = u.reshape(-1)
    for it in range(max_it):
        ev = disc.evaluate(u, states, 0.0)
        r = ev.residual - load[disc.free]
        norm = float(np.abs(r).max())
        if norm <= tol:
            return it, norm
        du = splu(disc.pattern_matrix(ev.tangent()).tocsc()).solve(-r)
        step = 1.0
        while True:
            trial = flat.copy()
            trial[disc.free] += step * du
            if disc.evaluate(trial.reshape(u.shape), states, 0.0, tangent=False).ok:
                break
            step *= 0.5
            if step < 1e-3:
                raise RuntimeError("Newton step inverts elements")
        flat[:] = trial
    raise RuntimeError(f"no convergence in {max_it} iterations (|r| = {norm:.3e})")


def _lift(disc: Discretization, u: np.ndarray, jump: np.ndarray, load: np.ndarray) -> None:
    """Move the constrained dofs by ``jump`` (zero on free dofs) and the free dofs by the
    linearised response, K_ff du = -(r(u) - load + K_fc jump), in place.

    K_fc jump is the directional derivative of the free residual along the jump, by central
    differences of size 1e-6 mm (well inside the elements, O(1e-12) relative error); the
    returned state is only Newton's starting point, so that the boundary jump of a load step
    does not invert the thin boundary elements."""
    from scipy.sparse.linalg import splu

    states = disc.initial_states()
    scale = 1e-6 / max(float(np.abs(jump).max()), 1e-300)
    ev = disc.evaluate(u, states, 0.0)
    rp = disc.evaluate(u + scale * jump, states, 0.0, tangent=False).residual
    rm = disc.evaluate(u - scale * jump, states, 0.0, tangent=False).residual
    rhs = ev.residual - load[disc.free] + (rp - rm) / (2.0 * scale)
    du = splu(disc.pattern_matrix(ev.tangent()).tocsc()).solve(-rhs)
    u += jump
    u.reshape(-1)[disc.free] += du


def mms_case(msol: ManufacturedSolution, law: Law, factor: float, load_steps: int = 4) -> MMSResult:
    """Solve the manufactured problem on the reference fingertip mesh ``refined(factor)``.

    The discrete domain is the polygon through the mesh's boundary nodes; u_exact is a smooth
    function on all of R^2, so it solves the problem posed on that polygon with the body force
    b = -Div P(u_exact) and its own trace as Dirichlet data.  Prescribing u_exact at every
    boundary P2 node (the midside nodes lie on the straight chords, inside the true outline)
    interpolates that trace, so there is no geometry error: the only errors are those of the P2
    discretisation.  The load is applied in ``load_steps`` steps (s u_exact, b(s u_exact))
    from rest, so the solution is the solver's, not the interpolant.
    """
    from skfem import LinearForm

    from sim import REFERENCE_GEOMETRY
    from sim.fe import Discretization
    from sim.geometry import DEFAULT_MESH, build_mesh
    from sim.materials import Material

    fm = build_mesh(REFERENCE_GEOMETRY, (), DEFAULT_MESH.refined(factor))
    disc = Discretization(fm, [Material(law)], fixed=boundary_fixed_mask(fm))
    X = disc.X
    u = np.zeros_like(X)
    fixed = disc.fixed
    basis = disc.skfem_basis()  # scikit-fem's, on the FE's dof numbering
    iterations = 0
    tol = 1e-10 * law.initial_shear_modulus_MPa * float(np.max(X))  # ~round-off of the forces
    for s in np.arange(1, load_steps + 1) / load_steps:
        msol_s = _Scaled(msol, s) if s < 1.0 else msol

        @LinearForm
        def body_force(v, w, m=msol_s):
            return m.body_force(w.x[0], w.x[1])[w.idx] * v

        load = np.empty_like(X)
        for c in range(2):
            load[:, c] = body_force.assemble(basis, idx=c)
        target = np.zeros_like(X)
        target[fixed] = (msol_s.displacement(X[:, 0], X[:, 1]).T)[fixed]
        _lift(disc, u, target - np.where(fixed, u, 0.0), load.reshape(-1))
        it, res = _newton(disc, u, load.reshape(-1), tol)
        iterations += it
    l2, h1 = _mms_errors(disc, u, msol)
    area = float(np.sum(disc.w))
    return MMSResult(
        factor, math.sqrt(area / disc.n_el), disc.n_el, disc.n_free, l2, h1, iterations, res
    )


class _Scaled:
    """u = s u_exact (an intermediate load step) through the same derivation."""

    def __init__(self, msol: ManufacturedSolution, s: float) -> None:
        self.m, self.s = msol, s

    def displacement(self, x, y):
        return self.s * self.m.displacement(x, y)

    def body_force(self, x, y):
        G = self.s * self.m.gradient(x, y)
        return self.m._body_force_from(G, self.s * self.m._hessian(x, y), x)


def _mms_errors(
    disc: Discretization, u: np.ndarray, msol: ManufacturedSolution
) -> tuple[float, float]:
    """Relative L2 and H1-seminorm errors, by a 6th-order rule on the same mesh."""
    basis = disc.skfem_basis(intorder=6)
    x, y = basis.mapping.F(basis.quadrature[0])
    dx = basis.dx
    uh = [basis.interpolate(u[:, c]) for c in range(2)]
    ue = msol.displacement(x, y)
    ge = msol.gradient(x, y)
    e0 = sum((np.asarray(uh[c]) - ue[c]) ** 2 for c in range(2))
    e1 = sum((uh[c].grad[L] - ge[c, L]) ** 2 for c in range(2) for L in range(2))
    n0 = sum(ue[c] ** 2 for c in range(2))
    n1 = sum(ge[c, L] ** 2 for c in range(2) for L in range(2))
    return (
        math.sqrt(np.sum(e0 * dx) / np.sum(n0 * dx)),
        math.sqrt(np.sum(e1 * dx) / np.sum(n1 * dx)),
    )


# ============================================================================================
# 4. Global equilibrium (see sim/fe/_reactions.py)
# ============================================================================================


@dataclass(frozen=True)
class Balance:
    """External forces on the body in a committed state, per unit thickness of the half model.

    ``plate``: the force the body exerts on the plate (up > 0, ``body.force``); ``base_reaction``
    the vertical support force of the bonded base (and axis) on the body; ``base_contact`` the
    vertical force of the rigid base beside the bone; ``residual_*`` the sums of all external
    forces (N/mm) and their moment about the origin (N), all zero at equilibrium."""

    plate: float
    base_reaction: float
    base_contact: float
    residual_x: float
    residual_y: float
    residual_moment: float

    @property
    def relative_imbalance(self) -> float:
        """|vertical reaction + base contact - plate force| / plate force."""
        return abs(self.base_reaction + self.base_contact - self.plate) / abs(self.plate)


def balance(body: Body) -> Balance:
    """All external forces on ``body`` (support reactions from the element forces, contact
    forces from the penalty law) and their resultant and moment."""
    from sim.fe._reactions import contact_forces, support_reactions

    R = support_reactions(body)
    cf = contact_forces(body)
    ext = R + sum(cf.values())
    x = body.disc.X + body.u
    moment = float(np.sum(x[:, 0] * ext[:, 1] - x[:, 1] * ext[:, 0]))
    return Balance(
        plate=float(body.force),
        base_reaction=float(R[:, 1].sum()),
        base_contact=float(cf["base"][:, 1].sum()),
        residual_x=float(ext[:, 0].sum()),
        residual_y=float(ext[:, 1].sum()),
        residual_moment=moment,
    )


# ============================================================================================
# 5. The independent code: FElupe
# ============================================================================================


def _p2_gradient(rs: np.ndarray) -> np.ndarray:
    """d h_a / d(r, s) of FElupe's six-node triangle h = [v0, v1, v2, m01, m12, m20]
    (hierarchical form: 1 - r - s, r, s, 4 r t, 4 r s, 4 s t with t = 1 - r - s, and the
    vertices corrected by half the adjacent edge functions), shape (6, 2)."""
    r, s = rs
    t = 1.0 - r - s
    d = np.array(
        [[-1, -1], [1, 0], [0, 1], [4 * (t - r), -4 * r], [4 * s, 4 * r], [-4 * s, 4 * (t - s)]],
        dtype=float,
    )
    d[0] += -d[3] / 2 - d[5] / 2
    d[1] += -d[3] / 2 - d[4] / 2
    d[2] += -d[4] / 2 - d[5] / 2
    return d


def shape_gradient_error(element: Any) -> float:
    """Largest difference between ``element.gradient`` and central differences of
    ``element.function`` at the three quadrature points and an off-centre point."""
    worst = 0.0
    h = 1e-6
    for rs in ([1 / 6, 1 / 6], [2 / 3, 1 / 6], [1 / 6, 2 / 3], [0.2, 0.5]):
        rs = np.array(rs)
        fd = np.column_stack(
            [
                (element.function(rs + h * e) - element.function(rs - h * e)) / (2 * h)
                for e in np.eye(2)
            ]
        )
        worst = max(worst, float(np.abs(np.asarray(element.gradient(rs)) - fd).max()))
    return worst


def felupe_p2_element() -> tuple[Any, bool]:
    """FElupe's ``QuadraticTriangle``, with its shape-function gradient corrected if needed.

    FElupe 11.3.0 writes d h5 / ds (h5 = 4 s (1 - r - s), the mid-node of edge 2-0) as
    4 (t1 - t2) instead of 4 (t1 - t3): wrong wherever r != s, i.e. at two of the three
    quadrature points, so that its six-node triangle does not reproduce a quadratic field. The
    corrected gradient (``_p2_gradient``) is the exact derivative of FElupe's own shape
    functions; the stock element is used unchanged once it agrees with them."""
    import felupe as fem

    stock = fem.QuadraticTriangle()
    if shape_gradient_error(stock) < 1e-8:
        return stock, False

    class QuadraticTriangleFixed(fem.QuadraticTriangle):
        def gradient(self, rs):
            return _p2_gradient(rs)

    return QuadraticTriangleFixed(), True


def felupe_model(
    disc: Discretization,
    law: NeoHookean,
    element: Any = None,
    extra_points: np.ndarray | None = None,
) -> tuple[Any, Any, Any]:
    """FElupe's plane-strain model of the discretisation ``disc`` (same P2 nodes and
    triangles, same 3-point rule), with optional ``extra_points`` (no cells) appended after the
    P2 nodes: returns (field container, displacement field, solid).

    Triangles that the mesh generator left clockwise are reordered counter-clockwise
    (FElupe rejects negative volumes); FElupe's NeoHooke(mu, bulk) is
    mu/2 (J^(-2/3) I1 - 3) + bulk/2 (J - 1)^2, the same energy as ours."""
    import felupe as fem

    X = disc.X
    cells = disc.edofs_scalar.copy()
    v = X[cells]
    det = (v[:, 1, 0] - v[:, 0, 0]) * (v[:, 2, 1] - v[:, 0, 1]) - (v[:, 1, 1] - v[:, 0, 1]) * (
        v[:, 2, 0] - v[:, 0, 0]
    )
    cw = det < 0.0
    cells[cw] = cells[cw][:, [0, 2, 1, 5, 4, 3]]
    if element is None:
        element = felupe_p2_element()[0]
    points = X if extra_points is None else np.vstack([X, extra_points])
    mesh = fem.Mesh(points, cells, cell_type="triangle6")
    region = fem.Region(mesh, element, fem.TriangleQuadrature(order=2))
    u = fem.FieldPlaneStrain(region, dim=2)
    field = fem.FieldContainer([u])
    solid = fem.SolidBody(fem.NeoHooke(mu=law.mu_MPa, bulk=law.bulk_modulus_MPa), field)
    return field, u, solid


def felupe_internal_forces(
    disc: Discretization, law: NeoHookean, u_nodes: np.ndarray, element: Any = None
) -> np.ndarray:
    """FElupe's internal force vector (n_nodes, 2) at the displacement ``u_nodes``."""
    field, u, solid = felupe_model(disc, law, element)
    u.values[:] = u_nodes
    return solid.assemble.vector(field).toarray().reshape(-1, 2)


@dataclass(frozen=True)
class FelupeComparison:
    """Plate force (N/mm, half model per unit thickness) at the same plate displacements."""

    depths_mm: np.ndarray
    ours: np.ndarray
    felupe: np.ndarray
    n_elements: int
    penalty_factor: float
    patched_element: bool

    @property
    def relative_difference(self) -> np.ndarray:
        return self.felupe / self.ours - 1.0


def press_plate(
    body: Body, depths_mm: Sequence[float], step_mm: float, min_step_mm: float = 1e-3
) -> np.ndarray:
    """The indenter's force (the model's units) at each of ``depths_mm`` from first touch, the
    plate moved down in increments of ``step_mm`` (the simulated time equal to the depth), a
    step that fails halved down to ``min_step_mm``: the quasi-static press of the verification
    cases and the 3D comparisons (against FElupe, against the 2D model)."""
    from sim.fe import Control

    top = body.top_height()
    d, out = 0.0, []
    for target in depths_mm:
        while d < target - 1e-12:
            dd = min(step_mm, target - d)
            while not body.advance(d + dd, Control.position(top - d - dd)).converged:
                dd *= 0.5
                if dd < min_step_mm:
                    raise RuntimeError(f"the plate step at {d} mm failed")
            d += dd
        out.append(body.force)
    return np.array(out)


def felupe_plate_comparison(
    law: NeoHookean,
    depths_mm: np.ndarray,
    mesh_factor: float = 1.0,
    penalty_factor: float = 1.0,
    element: Any = None,
) -> FelupeComparison:
    """Push the plate onto the reference fingertip in both codes; compare the forces.

    Contact: ours is the node-to-surface penalty kappa_i = kappa w_i (``penalty_factor`` x the
    default 3000 E0 per mm); FElupe's ``ContactRigidPlane`` is a node-to-plane penalty with one
    multiplier for all nodes, set to the same kappa times the median tributary length of the
    nodes near the apex. Both converge to the same frictionless node-on-plane constraint as the
    penalties grow, so their difference is O(penetration / depth)."""
    import felupe as fem

    from sim import REFERENCE_GEOMETRY
    from sim.fe import Body, Control, Discretization, NewtonOptions
    from sim.fe.contact import Plate, surface_weights
    from sim.geometry import DEFAULT_MESH, build_mesh
    from sim.materials import Material

    fm = build_mesh(REFERENCE_GEOMETRY, (), DEFAULT_MESH.refined(mesh_factor))
    disc = Discretization(fm, [Material(law)])
    penalty = 3000.0 * penalty_factor
    body = Body(disc, Plate(), NewtonOptions(rtol=1e-10), indenter_penalty_per_mm=penalty)
    top = body.top_height()
    ours = []
    for k, d in enumerate(depths_mm):
        res = body.advance(k + 1.0, Control.position(top - d))
        if not res.converged:
            raise RuntimeError(f"our plate step to {d} mm failed: {res.reason}")
        ours.append(body.force)

    if element is None:
        element, patched = felupe_p2_element()
    else:
        patched = False
    X = disc.X
    center = disc.n_nodes  # the plate's reference point, appended after the P2 nodes
    field, u, solid = felupe_model(disc, law, element, np.array([[0.0, top]]))
    mesh = field.region.mesh
    s = disc.surface_nodes
    near_apex = s[X[s, 0] < 0.5]
    multiplier = penalty * body.E0_MPa * float(np.median(surface_weights(X[s])[: len(near_apex)]))
    contact = fem.ContactRigidPlane(
        field, points=s, centerpoint=center, normal=[0.0, -1.0], multiplier=multiplier
    )
    ids = np.arange(mesh.npoints)
    on_base = (np.abs(mesh.points[:, 1]) < 1e-12) & (ids != center)
    on_axis = (np.abs(mesh.points[:, 0]) < 1e-12) & (ids != center)
    boundaries = {
        "base": fem.Boundary(u, mask=on_base),
        "axis": fem.Boundary(u, mask=on_axis, skip=(0, 1)),
        "plate_x": fem.Boundary(u, mask=ids == center, skip=(0, 1)),
        "plate_y": fem.Boundary(u, mask=ids == center, skip=(1, 0)),
    }
    theirs: list[float] = []

    def record(context, state) -> None:  # the reaction on the plate's reference point
        theirs.append(-float(context.substep.fun.reshape(-1, 2)[center, 1]))

    step = fem.Step(
        items=[solid, contact],
        ramp={boundaries["plate_y"]: -np.asarray(depths_mm, dtype=float)},
        boundaries=boundaries,
    )
    fem.Job(steps=[step], plugins=[record]).evaluate(verbose=0, tol=1e-10)
    return FelupeComparison(
        np.asarray(depths_mm, dtype=float),
        np.array(ours),
        np.array(theirs),
        disc.n_el,
        penalty_factor,
        patched,
    )
