r"""3D machinery of the hyperelastic laws: Voigt conventions, invariants, spectral tangents.

Conventions (every law's ``evaluate3``; total Lagrangian, units MPa):

* ``C`` has shape ``(6, *batch)`` = ``[C11, C22, C33, C12, C23, C13]`` (tensor components).
* ``W`` (MPa) has shape ``batch``.
* ``S`` = ``2 dW/dC`` (MPa) has shape ``(6, *batch)``, the same order (tensor components).
* ``D`` = ``4 d2W/dCdC`` (MPa) has shape ``(6, 6, *batch)``, Voigt form with engineering shear:
  ``dS_i = D_ij dE_j`` with ``dE = [dE11, dE22, dE33, 2 dE12, 2 dE23, 2 dE13]``; symmetric.
  Its entries are the tensor components ``4 d2W/dC_IJ dC_KL`` at the Voigt index pairs.
* A decoupled law's ``*3_split`` methods stack ``[iso, vol]`` on a leading axis of length 2.

With ``C33 = 1``, ``C23 = C13 = 0`` the rows and columns ``[0, 1, 3]`` are the plane-strain
``evaluate`` (``C = [C11, C22, C12]``) and ``S[2]`` is ``S33``.

**Invariant part** (compiled: ``sim.materials._kernels.volumetric3`` and the invariant laws'
kernels).  For ``W(I1, I2, I3)`` with
``I1 = tr C``, ``I2`` the sum of the principal 2x2 minors, ``I3 = det C`` and
``G1 = dI1/dC = I``, ``G2 = dI2/dC = I1 I - C``, ``G3 = dI3/dC = cof C``:

.. math::

    S = 2 \sum_a W_a G_a, \qquad
    D = 4 \sum_{a,b} W_{ab} G_a \otimes G_b + 4 W_2 (I \otimes I - \mathbb{I})
        + 4 W_3 \frac{\partial\, \mathrm{cof}\, C}{\partial C}

(``𝕀`` the symmetric fourth-order identity, Voigt ``diag(1, 1, 1, 1/2, 1/2, 1/2)``); the last
term is polynomial in ``C`` (``sim.materials._kernels.add_dcof``), so nothing is divided
by ``det C``.

**Spectral part** (:func:`eigh3`; compiled: ``sim.materials._kernels.spectral3``).  For a
symmetric function ``Phi(c1, c2, c3)`` of the eigenvalues ``c_a`` of ``C`` (eigenvectors
``N_a``, ``M_a = N_a (x) N_a``), the stress and the tangent are (Ogden, *Non-linear Elastic
Deformations*, 1984; Simo and Taylor, Comput. Methods Appl. Mech. Engrg. 85 (1991) 273-310)

.. math::

    S = 2 \sum_a \Phi_a M_a, \qquad
    D = 4 \sum_{a,b} \Phi_{ab} M_a \otimes M_b
        + 2 \sum_{a<b} \theta_{ab}\, W_{ab} \otimes W_{ab}, \qquad
    \theta_{ab} = \frac{\Phi_a - \Phi_b}{c_a - c_b},

with ``Phi_a = dPhi/dc_a``, ``Phi_ab = d2Phi/dc_a dc_b`` and ``W_ab = N_a (x) N_b + N_b (x) N_a``
(in the principal frame ``D_abab = 2 theta_ab`` with engineering shear).  The second term is the
first-order perturbation of the eigenprojections, ``dM_a = sum_{b != a} (N_b . dC . N_a) /
(c_a - c_b) (N_a (x) N_b + N_b (x) N_a)`` (the Daleckii-Krein divided difference of a matrix
function).  The classic difficulty is ``c_a -> c_b`` (the undeformed state, uniaxial and
equibiaxial states): there ``theta_ab -> Phi_aa - Phi_ab``, and the tangent is then
independent of the (arbitrary) eigenvectors chosen in the degenerate eigenspace.  Here every law
supplies ``theta_ab`` *analytically*, as a smooth function of ``(c_a, c_b)`` evaluated without
cancellation for any split (the Ogden law with ``sinh`` ratios in log-eigenvalues, the hyperfoam
with a Taylor series below a relative split of ``5e-3``), instead of a perturbation of the
eigenvalues (Miehe, Commun. Numer. Methods Eng. 9 (1993) 889-896) or a tolerance-switched
limit.  Hence the tangent is continuous across coinciding eigenvalues, and the errors of the
eigenvectors of nearly equal eigenvalues (``O(eps / gap)``) multiply differences
``Phi_a - Phi_b = O(gap)``: the result stays accurate to rounding.  The eigenvalues and
eigenvectors come from a compiled cyclic Jacobi solver for symmetric 3x3 matrices
(:mod:`sim.materials._eigh3`; Golub and Van Loan, *Matrix Computations*, 4th ed., §8.5): one
loop over the points, several times faster than ``numpy.linalg.eigh`` on an ``(n, 3, 3)``
stack (whose time goes to per-matrix overhead), and as accurate, to rounding (backward stable:
eigenvalues within a few ``eps |C|``, eigenvectors orthonormal to rounding, for repeated,
nearly repeated and widely spread eigenvalues alike).
"""

from __future__ import annotations

from typing import Any

import numpy as np

Array = np.ndarray

#: Voigt order of the 3D symmetric tensors: tensor index pairs of the six components.
VOIGT3 = ((0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (0, 2))
#: Eigenvalue pairs ``(a, b)`` of the spectral shear terms, in the order of ``theta``.
PAIRS = ((0, 1), (1, 2), (0, 2))
#: The in-plane components of a 3D Voigt vector: ``[11, 22, 12]``.
PLANE = (0, 1, 3)

_EYE = np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0])  # I in Voigt form


def as_C3(C: Any) -> Array:
    """``C`` as a float array of shape ``(6, *batch)``."""
    C = np.asarray(C, dtype=float)
    if C.ndim < 1 or C.shape[0] != 6:
        raise ValueError(
            f"C must have shape (6, *batch) = [C11, C22, C33, C12, C23, C13], got {C.shape}"
        )
    return C


def flat3(C: Any) -> tuple[Array, tuple[int, ...]]:
    """``C`` as ``(6, n)`` and the batch shape to restore."""
    C = as_C3(C)
    return C.reshape(6, -1), C.shape[1:]


def invariants3(C: Array) -> tuple[Array, Array, Array, Array]:
    """``I1 = tr C``, ``I2`` (sum of the principal minors), ``I3 = det C`` and ``cof C``
    (Voigt, shape ``(6, *batch)``), all polynomial in ``C``."""
    C11, C22, C33, C12, C23, C13 = C
    cof = np.stack(
        (
            C22 * C33 - C23 * C23,
            C11 * C33 - C13 * C13,
            C11 * C22 - C12 * C12,
            C13 * C23 - C12 * C33,
            C12 * C13 - C11 * C23,
            C12 * C23 - C13 * C22,
        )
    )
    I1 = C11 + C22 + C33
    I2 = cof[0] + cof[1] + cof[2]
    I3 = C11 * cof[0] + C12 * cof[3] + C13 * cof[5]
    return I1, I2, I3, cof


def eigh3(C: Array) -> tuple[Array, Array]:
    """Eigenvalues ``c`` (shape ``(3, n)``, ascending) and eigenvectors ``N`` (shape
    ``(3, 3, n)``, ``N[a]`` the unit eigenvector of ``c[a]``) of ``C`` (shape ``(6, n)``).

    Compiled cyclic Jacobi (:mod:`sim.materials._eigh3`), imported here so that importing the
    laws does not load numba."""
    from ._eigh3 import eigh3_voigt

    return eigh3_voigt(np.ascontiguousarray(C, dtype=np.float64))
