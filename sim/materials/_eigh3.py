"""Compiled eigen-decomposition of a batch of real symmetric 3x3 matrices (cyclic Jacobi).

The 3D spectral laws (``sim.materials._law3.eigh3``) decompose ``C`` at every quadrature point;
``numpy.linalg.eigh`` on an ``(n, 3, 3)`` stack spends most of its time on per-matrix overhead
(a LAPACK call, workspace, copies, per matrix). Here one compiled loop does the whole batch with
the cyclic Jacobi method (Golub & Van Loan, *Matrix Computations*, 4th ed., 2013, §8.5): sweeps
of plane rotations over the pairs ``(0, 1), (0, 2), (1, 2)``, each annihilating one
off-diagonal entry with the 2-by-2 symmetric Schur decomposition in its numerically stable form

    tau = (a_qq - a_pp) / (2 a_pq),   t = sign(tau) / (|tau| + sqrt(1 + tau^2)),
    c = 1 / sqrt(1 + t^2),   s = t c

(``t`` the root of ``t^2 + 2 tau t - 1 = 0`` of smaller modulus, so the rotation angle is at most
pi/4 and nothing cancels), the diagonal updated as ``a_pp - t a_pq``, ``a_qq + t a_pq``. A zero
``a_pq`` is skipped (no division by zero: a diagonal matrix is returned as is, exactly); a huge
``tau`` gives ``t = 0``. The sweeps stop once the off-diagonal entries are below ``eps`` times
the norm of the matrix (at most :data:`MAX_SWEEPS`; the convergence is quadratic: two to four
sweeps, mostly three). Jacobi's method is backward stable: the eigenvalues are exact to a few
``eps |C|`` and the eigenvectors orthonormal to rounding, whatever the spread of the eigenvalues
or their multiplicity (the eigenvectors of a repeated eigenvalue are then some orthonormal basis
of its eigenspace, those of nearly equal ones accurate to ``O(eps / gap)``, as LAPACK's).

Same inputs, same bits (a fixed order of operations, each point on its own). Compiled on first
use and cached on disk by numba (``cache=True``); imported lazily by ``_law3.eigh3`` so that
``import sim`` does not load numba.
"""

from __future__ import annotations

import numba as nb
import numpy as np

__all__ = ["MAX_SWEEPS", "eigh3_voigt"]

#: Upper bound on the Jacobi sweeps per matrix (a handful suffice; this bounds NaN or inf input).
MAX_SWEEPS = 50
_EPS = float(np.finfo(np.float64).eps)


@nb.njit(cache=True)
def _schur2(app: float, aqq: float, apq: float) -> tuple[float, float, float]:
    """The rotation ``(c, s)`` that zeroes ``apq`` (nonzero) of ``[[app, apq], [apq, aqq]]``,
    and ``t = s / c``: the 2-by-2 symmetric Schur decomposition (Golub & Van Loan, §8.5).
    ``tau^2`` overflowing (``|tau| > 1e154``) gives ``t = 0`` where ``|t| < 1e-154``."""
    tau = (aqq - app) / (2.0 * apq)
    t = 1.0 / (abs(tau) + np.sqrt(1.0 + tau * tau))
    if tau < 0.0:
        t = -t
    c = 1.0 / np.sqrt(1.0 + t * t)
    return c, t * c, t


@nb.njit(cache=True)
def _rot(x: float, y: float, c: float, s: float) -> tuple[float, float]:
    """``(x, y) J`` for the plane rotation ``J = [[c, s], [-s, c]]``."""
    return c * x - s * y, s * x + c * y


@nb.njit(cache=True)
def eigh3_voigt(C: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues ``c`` (3, n), ascending, and unit eigenvectors ``N`` (3, 3, n), ``N[a, i, k]``
    the component ``i`` of the eigenvector of ``c[a, k]``, of the symmetric matrices given in
    Voigt form ``C`` (6, n) = ``[C11, C22, C33, C12, C23, C13]``.

    The matrix ``A`` (entries ``aij``) and the accumulated rotation ``V`` (``A_in = V A V^T``
    throughout, entries ``vij``) are scalars, unrolled: each rotation in the plane ``(p, q)``
    sets ``apq = 0``, updates ``app``, ``aqq``, the third row ``(arp, arq)`` and the columns
    ``p``, ``q`` of ``V``."""
    n = C.shape[1]
    out = np.empty((3, n))
    N = np.empty((3, 3, n))
    for k in range(n):
        a00 = C[0, k]
        a11 = C[1, k]
        a22 = C[2, k]
        a01 = C[3, k]
        a12 = C[4, k]
        a02 = C[5, k]
        v00, v01, v02 = 1.0, 0.0, 0.0
        v10, v11, v12 = 0.0, 1.0, 0.0
        v20, v21, v22 = 0.0, 0.0, 1.0
        # The off-diagonal size against the initial entrywise 1-norm (between 1 and 3 times the
        # Frobenius norm, which the rotations keep; no squares: no overflow).
        off = abs(a01) + abs(a02) + abs(a12)
        tol = _EPS * (abs(a00) + abs(a11) + abs(a22) + 2.0 * off)
        for _ in range(MAX_SWEEPS):
            if off <= tol:
                break
            if a01 != 0.0:  # plane (0, 1), third row 2
                c, s, t = _schur2(a00, a11, a01)
                a00 -= t * a01
                a11 += t * a01
                a01 = 0.0
                a02, a12 = _rot(a02, a12, c, s)
                v00, v01 = _rot(v00, v01, c, s)
                v10, v11 = _rot(v10, v11, c, s)
                v20, v21 = _rot(v20, v21, c, s)
            if a02 != 0.0:  # plane (0, 2), third row 1
                c, s, t = _schur2(a00, a22, a02)
                a00 -= t * a02
                a22 += t * a02
                a02 = 0.0
                a01, a12 = _rot(a01, a12, c, s)
                v00, v02 = _rot(v00, v02, c, s)
                v10, v12 = _rot(v10, v12, c, s)
                v20, v22 = _rot(v20, v22, c, s)
            if a12 != 0.0:  # plane (1, 2), third row 0
                c, s, t = _schur2(a11, a22, a12)
                a11 -= t * a12
                a22 += t * a12
                a12 = 0.0
                a01, a02 = _rot(a01, a02, c, s)
                v01, v02 = _rot(v01, v02, c, s)
                v11, v12 = _rot(v11, v12, c, s)
                v21, v22 = _rot(v21, v22, c, s)
            off = abs(a01) + abs(a02) + abs(a12)
        # Ascending order: a three-element sorting network, swapping eigenpairs (ties and NaN
        # keep their order).
        if a11 < a00:
            a00, a11 = a11, a00
            v00, v01, v10, v11, v20, v21 = v01, v00, v11, v10, v21, v20
        if a22 < a11:
            a11, a22 = a22, a11
            v01, v02, v11, v12, v21, v22 = v02, v01, v12, v11, v22, v21
        if a11 < a00:
            a00, a11 = a11, a00
            v00, v01, v10, v11, v20, v21 = v01, v00, v11, v10, v21, v20
        out[0, k] = a00
        out[1, k] = a11
        out[2, k] = a22
        N[0, 0, k], N[0, 1, k], N[0, 2, k] = v00, v10, v20
        N[1, 0, k], N[1, 1, k], N[1, 2, k] = v01, v11, v21
        N[2, 0, k], N[2, 1, k], N[2, 2, k] = v02, v12, v22
    return out, N
