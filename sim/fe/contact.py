"""Rigid, frictionless obstacles and their node-to-surface penalty contact.

Each obstacle reports, for the current positions of the surface nodes, the penetration depth
``p`` (> 0 inside the obstacle) and the unit normal ``n`` along which the node is pushed out.
The contact force on a node is ``kappa_i * p * n`` with ``kappa_i = kappa * w_i``: a penalty per
unit area ``kappa`` (N/mm^3, per unit thickness) times the node's share ``w_i`` of the surface
length (the P2 boundary weights 1/6, 2/3, 1/6 of each edge), so that the penetration equals the
contact pressure divided by ``kappa`` whatever the node.

Positions: an indenter's ``position_mm`` is the height y of its lowest point (plate face or wedge
tip); an inclined plate's is the height of its face along its own normal (``Plate``). Where an
obstacle's surface is curved (the wedge's rounded tip) the tangent includes the rotation of the
normal, ``-kappa_i p / rho (I - n n^T)``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

__all__ = ["Base", "Plate", "Wedge"]


@dataclass(frozen=True)
class Plate:
    """Flat rigid plate pressing down; its face is the line y = position_mm.

    ``inclination_deg`` = t tilts it about the axis normal to the obstacles' plane (in 3D the
    cross-finger axis x; the plane's coordinates are (h, v) = (z, y)): its outward unit normal
    (pointing from the body into the plate) is e = (sin t, cos t) in (h, v), i.e.
    (0, cos t, sin t) in (x, y, z), and its face is the line e . (h, v) = position_mm, so

        p = e . (h, v) - position_mm,    n = -e,

    ``position_mm`` is the face's height along e and dp/d(position) = -1 as for the flat plate.
    The plate is lowest at +h: in 3D it first touches the pad's end z > 0, the fingertip.
    ``axis`` is e; at t = 0 it is (0, 1) and the penetration is computed as for the flat plate,
    bit for bit."""

    inclination_deg: float = 0.0
    name = "plate"

    @property
    def axis(self) -> np.ndarray:
        """e = (sin t, cos t): the plate's outward normal in the obstacles' plane (h, v)."""
        t = np.radians(self.inclination_deg)
        return np.array([np.sin(t), np.cos(t)])

    def penetration(self, xy: np.ndarray, position_mm: float):
        if self.inclination_deg == 0.0:
            return xy[:, 1] - position_mm, vertical_normals(len(xy), -1.0)
        e = self.axis
        p = xy @ e - position_mm
        n = np.broadcast_to(-e, xy.shape).copy()
        return p, n


@dataclass(frozen=True)
class Wedge:
    """Rigid wedge pressing down: flanks at ``half_angle_deg`` from the vertical, and a tip
    rounded to a circle tangent to both flanks whose tangent points are ``tip_width_mm`` apart
    (radius R = tip_width / (2 cos(half_angle))). The rounding keeps the obstacle's surface C1,
    so Newton's method sees a continuous normal. ``position_mm`` is the tip's lowest point.
    """

    tip_width_mm: float = 0.05
    half_angle_deg: float = 30.0
    name = "wedge"

    @property
    def radius_mm(self) -> float:
        return 0.5 * self.tip_width_mm / np.cos(np.radians(self.half_angle_deg))

    def surface_height(self, x: np.ndarray, position_mm: float) -> np.ndarray:
        """Height of the wedge's lower outline above x (mm)."""
        th = np.radians(self.half_angle_deg)
        R = self.radius_mm
        yc = position_mm + R
        xa = np.abs(x)
        on_arc = xa <= R * np.cos(th)
        arc = yc - np.sqrt(np.maximum(R**2 - xa**2, 0.0))
        # flank: tangent to the circle at (R cos th, yc - R sin th)
        flank = yc - R * np.sin(th) + (xa - R * np.cos(th)) / np.tan(th)
        return np.where(on_arc, arc, flank)

    def penetration(self, xy: np.ndarray, position_mm: float):
        p, n, _ = self.penetration_curvature(xy, position_mm)
        return p, n

    def penetration_curvature(self, xy: np.ndarray, position_mm: float):
        """Penetration, normal, and curvature 1/rho of the normal field (0 on the flanks)."""
        th = np.radians(self.half_angle_deg)
        R = self.radius_mm
        # the wedge is the set of points within R of the sharp core wedge with apex c
        cy = position_mm + R / np.sin(th)
        rel = xy - np.array([0.0, cy])
        n_f = np.array([np.cos(th), -np.sin(th)])  # outward normal of the right flank
        t_f = np.array([np.sin(th), np.cos(th)])  # flank direction, up and out
        s = rel @ n_f
        tau = rel @ t_f
        rho = np.hypot(rel[:, 0], rel[:, 1])
        near_apex = (tau < 0.0) & (s > 0.0)
        dist = np.where(near_apex, rho, s)
        n = np.where(near_apex[:, None], rel / np.maximum(rho, 1e-300)[:, None], n_f[None, :])
        curvature = np.where(near_apex, 1.0 / np.maximum(rho, 1e-300), 0.0)
        return R - dist, n, curvature


@dataclass(frozen=True)
class Base:
    """The rigid base y = 0 beside the bonded interface: the bulging surface may fold onto it."""

    name = "base"

    def penetration(self, xy: np.ndarray, position_mm: float = 0.0):
        return -xy[:, 1], vertical_normals(len(xy), 1.0)


@lru_cache(maxsize=16)
def vertical_normals(m: int, v: float) -> np.ndarray:
    """The normals (0, v) of m nodes in the obstacles' plane (m, 2), read-only: a horizontal
    obstacle's, made once per surface rather than at every evaluation."""
    n = np.zeros((m, 2))
    n[:, 1] = v
    n.setflags(write=False)
    return n


def surface_weights(xy: np.ndarray) -> np.ndarray:
    """P2 boundary weights of the ordered surface nodes (vertex, mid, vertex, mid, ..., vertex).

    Each quadratic edge of length l contributes l/6, 2l/3, l/6 (Simpson) to its three nodes.
    """
    verts = xy[::2]
    lengths = np.linalg.norm(np.diff(verts, axis=0), axis=1)
    w = np.zeros(len(xy))
    w[0:-1:2] += lengths / 6.0
    w[2::2] += lengths / 6.0
    w[1::2] += 2.0 * lengths / 3.0
    return w
