"""The 27-node triquadratic Lagrange hexahedron (Q2) and its 9-node faces, in VTK's node order.

Reference cube [-1, 1]^3 with coordinates (xi, eta, zeta). The 1D quadratic Lagrange polynomials
on the nodes -1, 0, 1 are

    L_-(t) = t (t - 1) / 2,   L_0(t) = 1 - t^2,   L_+(t) = t (t + 1) / 2,

and the shape function of the node at (i, j, k) in {-1, 0, 1}^3 is L_i(xi) L_j(eta) L_k(zeta).

Local node order: VTK_TRIQUADRATIC_HEXAHEDRON (cell type 29; meshio's "hexahedron27"), as the
parametric coordinates of VTK's ``vtkTriQuadraticHexahedron`` implementation (and felupe's
``TriQuadraticHexahedron``) give it::

    corners    0 (-,-,-)  1 (+,-,-)  2 (+,+,-)  3 (-,+,-)
               4 (-,-,+)  5 (+,-,+)  6 (+,+,+)  7 (-,+,+)
    mid-edges  8 (0,-,-)  9 (+,0,-) 10 (0,+,-) 11 (-,0,-)         edges 0-1, 1-2, 2-3, 3-0
              12 (0,-,+) 13 (+,0,+) 14 (0,+,+) 15 (-,0,+)         edges 4-5, 5-6, 6-7, 7-4
              16 (-,-,0) 17 (+,-,0) 18 (+,+,0) 19 (-,+,0)         edges 0-4, 1-5, 2-6, 3-7
    mid-faces 20 (-,0,0) 21 (+,0,0) 22 (0,-,0) 23 (0,+,0) 24 (0,0,-) 25 (0,0,+)
    centre    26 (0,0,0)

(the face list in VTK's class documentation names another face order; the implementation's
parametric coordinates, used here, put the xi = -1 face centre at 20.)

Faces: 9-node biquadratic quadrilaterals in the order of VTK_BIQUADRATIC_QUAD (type 28): corners
0-3, mid-edges 4 (0-1), 5 (1-2), 6 (2-3), 7 (3-0), centre 8, on the reference square [-1, 1]^2
with coordinates (s, t). ``FACE_NODES[f]`` lists the local hexahedron nodes of face f (order
xi-, xi+, eta-, eta+, zeta-, zeta+) so that dX/ds x dX/dt points out of the element.

Quadrature: the 3-point Gauss-Legendre rule (points 0, +-sqrt(3/5), weights 8/9, 5/9) in each
direction, exact for polynomials of degree <= 5 in each variable.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "FACE_NODES",
    "FACE_REFERENCE_POINTS",
    "REFERENCE_POINTS",
    "face_gauss_rule",
    "face_shape_functions",
    "face_shape_gradients",
    "gauss_rule",
    "shape_functions",
    "shape_gradients",
]

#: reference coordinates (27, 3) of the local nodes, VTK order
REFERENCE_POINTS = np.array(
    [
        [-1, -1, -1],
        [1, -1, -1],
        [1, 1, -1],
        [-1, 1, -1],
        [-1, -1, 1],
        [1, -1, 1],
        [1, 1, 1],
        [-1, 1, 1],
        [0, -1, -1],
        [1, 0, -1],
        [0, 1, -1],
        [-1, 0, -1],
        [0, -1, 1],
        [1, 0, 1],
        [0, 1, 1],
        [-1, 0, 1],
        [-1, -1, 0],
        [1, -1, 0],
        [1, 1, 0],
        [-1, 1, 0],
        [-1, 0, 0],
        [1, 0, 0],
        [0, -1, 0],
        [0, 1, 0],
        [0, 0, -1],
        [0, 0, 1],
        [0, 0, 0],
    ],
    dtype=float,
)
REFERENCE_POINTS.setflags(write=False)

#: reference coordinates (9, 2) of the face nodes, VTK_BIQUADRATIC_QUAD order
FACE_REFERENCE_POINTS = np.array(
    [[-1, -1], [1, -1], [1, 1], [-1, 1], [0, -1], [1, 0], [0, 1], [-1, 0], [0, 0]], dtype=float
)
FACE_REFERENCE_POINTS.setflags(write=False)

#: local hexahedron nodes (6, 9) of the faces xi-, xi+, eta-, eta+, zeta-, zeta+, each in
#: VTK_BIQUADRATIC_QUAD order and oriented so that dX/ds x dX/dt is the outward normal
FACE_NODES = np.array(
    [
        [0, 4, 7, 3, 16, 15, 19, 11, 20],  # xi = -1: along zeta then eta, normal -xi
        [1, 2, 6, 5, 9, 18, 13, 17, 21],  # xi = +1: along eta then zeta, normal +xi
        [0, 1, 5, 4, 8, 17, 12, 16, 22],  # eta = -1: along xi then zeta, normal -eta
        [3, 7, 6, 2, 19, 14, 18, 10, 23],  # eta = +1: along zeta then xi, normal +eta
        [0, 3, 2, 1, 11, 10, 9, 8, 24],  # zeta = -1: along eta then xi, normal -zeta
        [4, 5, 6, 7, 12, 13, 14, 15, 25],  # zeta = +1: along xi then eta, normal +zeta
    ]
)
FACE_NODES.setflags(write=False)

_GAUSS_1D = np.array([-np.sqrt(0.6), 0.0, np.sqrt(0.6)])
_GAUSS_W_1D = np.array([5.0, 8.0, 5.0]) / 9.0


def _lagrange_1d(t: np.ndarray) -> np.ndarray:
    """Values (..., 3) of L_-, L_0, L_+ at ``t``."""
    return np.stack([0.5 * t * (t - 1.0), 1.0 - t * t, 0.5 * t * (t + 1.0)], axis=-1)


def _lagrange_1d_derivative(t: np.ndarray) -> np.ndarray:
    """Derivatives (..., 3) of L_-, L_0, L_+ at ``t``."""
    return np.stack([t - 0.5, -2.0 * t, t + 0.5], axis=-1)


def _node_index(points: np.ndarray) -> np.ndarray:
    """Which 1D polynomial (0: -1, 1: 0, 2: +1) each node uses in each direction."""
    return np.rint(points).astype(int) + 1


_HEX_INDEX = _node_index(REFERENCE_POINTS)  # (27, 3)
_FACE_INDEX = _node_index(FACE_REFERENCE_POINTS)  # (9, 2)


def shape_functions(points: np.ndarray) -> np.ndarray:
    """The 27 shape functions (P, 27) at reference points (P, 3)."""
    X = np.atleast_2d(np.asarray(points, dtype=float))
    L = [_lagrange_1d(X[:, d]) for d in range(3)]  # 3 x (P, 3)
    return L[0][:, _HEX_INDEX[:, 0]] * L[1][:, _HEX_INDEX[:, 1]] * L[2][:, _HEX_INDEX[:, 2]]


def shape_gradients(points: np.ndarray) -> np.ndarray:
    """Reference gradients (P, 27, 3) of the 27 shape functions at reference points (P, 3):
    ``[p, a, d]`` is dN_a/dxi_d at point p."""
    X = np.atleast_2d(np.asarray(points, dtype=float))
    L = [_lagrange_1d(X[:, d])[:, _HEX_INDEX[:, d]] for d in range(3)]  # 3 x (P, 27)
    dL = [_lagrange_1d_derivative(X[:, d])[:, _HEX_INDEX[:, d]] for d in range(3)]
    return np.stack([dL[0] * L[1] * L[2], L[0] * dL[1] * L[2], L[0] * L[1] * dL[2]], axis=-1)


def face_shape_functions(points: np.ndarray) -> np.ndarray:
    """The 9 face shape functions (P, 9) at face reference points (P, 2)."""
    S = np.atleast_2d(np.asarray(points, dtype=float))
    L = [_lagrange_1d(S[:, d]) for d in range(2)]
    return L[0][:, _FACE_INDEX[:, 0]] * L[1][:, _FACE_INDEX[:, 1]]


def face_shape_gradients(points: np.ndarray) -> np.ndarray:
    """Reference gradients (P, 9, 2) of the 9 face shape functions at points (P, 2)."""
    S = np.atleast_2d(np.asarray(points, dtype=float))
    L = [_lagrange_1d(S[:, d])[:, _FACE_INDEX[:, d]] for d in range(2)]
    dL = [_lagrange_1d_derivative(S[:, d])[:, _FACE_INDEX[:, d]] for d in range(2)]
    return np.stack([dL[0] * L[1], L[0] * dL[1]], axis=-1)


def gauss_rule() -> tuple[np.ndarray, np.ndarray]:
    """The 3 x 3 x 3 Gauss-Legendre rule on [-1, 1]^3: points (27, 3), weights (27,) (sum 8).

    The points run xi fastest, then eta, then zeta."""
    z, y, x = np.meshgrid(_GAUSS_1D, _GAUSS_1D, _GAUSS_1D, indexing="ij")
    wz, wy, wx = np.meshgrid(_GAUSS_W_1D, _GAUSS_W_1D, _GAUSS_W_1D, indexing="ij")
    points = np.column_stack([x.ravel(), y.ravel(), z.ravel()])
    return points, (wx * wy * wz).ravel()


def face_gauss_rule() -> tuple[np.ndarray, np.ndarray]:
    """The 3 x 3 Gauss-Legendre rule on [-1, 1]^2: points (9, 2), weights (9,) (sum 4)."""
    t, s = np.meshgrid(_GAUSS_1D, _GAUSS_1D, indexing="ij")
    wt, ws = np.meshgrid(_GAUSS_W_1D, _GAUSS_W_1D, indexing="ij")
    return np.column_stack([s.ravel(), t.ravel()]), (ws * wt).ravel()
