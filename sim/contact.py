"""Rigid, frictionless obstacles and their node-to-surface penalty contact.

Each obstacle reports, for the current positions of the surface nodes, the penetration depth
``p`` (> 0 inside the obstacle) and the unit normal ``n`` along which the node is pushed out.
The contact force on a node is ``kappa_i * p * n`` with ``kappa_i = kappa * w_i``: a penalty per
unit area ``kappa`` (N/mm^3, per unit thickness) times the node's share ``w_i`` of the surface
length (the P2 boundary weights 1/6, 2/3, 1/6 of each edge), so that the penetration equals the
contact pressure divided by ``kappa`` whatever the node. Every face is flat, so the penalty
tangent ``kappa_i n n^T`` is exact away from the obstacles' corners.

Positions: an indenter's ``position_mm`` is the height y of its lowest point (plate face or wedge
tip). The wedge has a flat tip of width ``tip_width_mm`` centred on x = 0 and flanks at
``half_angle_deg`` from the vertical.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Base", "Plate", "Wedge"]


@dataclass(frozen=True)
class Plate:
    """Flat rigid plate pressing down; its face is the line y = position_mm."""

    name = "plate"

    def penetration(self, xy: np.ndarray, position_mm: float):
        p = xy[:, 1] - position_mm
        n = np.zeros_like(xy)
        n[:, 1] = -1.0
        return p, n


@dataclass(frozen=True)
class Wedge:
    """Sharp rigid wedge pressing down, tip at (0, position_mm); the half x >= 0 is modelled."""

    tip_width_mm: float = 0.05
    half_angle_deg: float = 30.0
    name = "wedge"

    def surface_height(self, x: np.ndarray, position_mm: float) -> np.ndarray:
        """Height of the wedge's lower outline above x (mm)."""
        cot = 1.0 / np.tan(np.radians(self.half_angle_deg))
        return position_mm + np.maximum(0.0, np.abs(x) - 0.5 * self.tip_width_mm) * cot

    def penetration(self, xy: np.ndarray, position_mm: float):
        th = np.radians(self.half_angle_deg)
        x, y = xy[:, 0], xy[:, 1]
        depth_tip = y - position_mm
        depth_flank = (y - position_mm - (x - 0.5 * self.tip_width_mm) / np.tan(th)) * np.sin(th)
        use_flank = depth_flank < depth_tip
        p = np.minimum(depth_tip, depth_flank)
        n = np.zeros_like(xy)
        n[:, 1] = -1.0
        n[use_flank, 0] = np.cos(th)
        n[use_flank, 1] = -np.sin(th)
        return p, n


@dataclass(frozen=True)
class Base:
    """The rigid base y = 0 beside the bonded interface: the bulging surface may fold onto it."""

    name = "base"

    def penetration(self, xy: np.ndarray, position_mm: float = 0.0):
        p = -xy[:, 1]
        n = np.zeros_like(xy)
        n[:, 1] = 1.0
        return p, n


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
