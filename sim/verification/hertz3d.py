"""Hertz contact of an elastic sphere pressed by the rigid plate, on the 3D model.

The pad with a = b = c = R and n = m = 2 is a hemisphere bonded on the base (quarter model);
``depth_ratio = k`` makes it a half-ellipsoid of depth b = k R and semi-axes a = c = R sqrt(k),
whose apex has the same radius of curvature a^2 / b = R: a deeper body, closer to Hertz's
half-space (its surface y = b - r^2 / (2 R) - r^4 / (8 k R^3) - ...). Neo-Hookean with
mu = 0.1 MPa, nu = 0.3 (small strain: E* = 2 mu (1 + nu) / (1 - nu^2)).

Hertz (a sphere of radius R on a half-space, small strain): at the approach delta the force is
F_H = 4/3 E* R^(1/2) delta^(3/2), and at the force F the contact radius is
a_H = (3 F R / (4 E*))^(1/3). The model's contact radius is read from its contact area,
a = sqrt(A / pi) (``sim.protocols.contact_patch``). ``studies/hertz3d.py`` prints the table of
``docs/model_3d.md``, "Hertz contact"; ``tests/test_hertz3d.py`` runs a coarse version.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["HertzRow3D", "hertz_sphere_3d"]

R_MM, MU_MPA, NU = 10.0, 0.1, 0.3


@dataclass(frozen=True)
class HertzRow3D:
    """One plate position: the whole body's force and contact radius against Hertz's."""

    depth_mm: float
    force_N: float
    hertz_force_N: float  # F_H at this approach
    a_mm: float  # sqrt(contact area / pi)
    hertz_a_mm: float  # a_H at this force
    dofs: int


def hertz_sphere_3d(
    h_mm: float,
    fraction: float,
    depth_mm: float,
    steps: int = 4,
    depth_ratio: float = 1.0,
    grading: float = 0.4,
    h_max_mm: float = 3.0,
    inclination_deg: float = 0.0,
) -> list[HertzRow3D]:
    """The plate pushed to ``depth_mm`` in ``steps`` equal steps on the body of ``depth_ratio``,
    meshed with elements of ``h_mm`` over the region ``fraction`` R around the apex, growing by
    ``grading`` per mm to ``h_max_mm``. ``inclination_deg``: the plate tilted about x (the half
    model, refined around the first-touch point instead of the apex; the approach and force
    along the plate's normal, the area in its plane: ``model.inclination_deg``)."""
    from ..fe import Body, Control, Discretization3D, NewtonOptions, Plate
    from ..geometry import Geometry, MeshOptions3D, PadGeometry, build_pad_mesh
    from ..materials._material import material_from_table
    from ..protocols import contact_patch

    side = R_MM * np.sqrt(depth_ratio)  # a = c, with a^2 / b = R at the apex
    pad = PadGeometry(Geometry(side, depth_ratio * R_MM, 2.0), side, 2.0)
    options = MeshOptions3D(
        h_apex_mm=h_mm,
        h_contact_mm=h_mm,
        contact_fraction=fraction * R_MM / side,  # the same refined region, in mm
        grading=grading,
        h_max_mm=h_max_mm,
    )
    law = {"model": "neo_hookean", "mu_MPa": MU_MPA, "nu": NU}
    pmesh = build_pad_mesh(pad, (), options, inclination_deg)
    disc = Discretization3D(pmesh, [material_from_table(law)])
    body = Body(disc, Plate(inclination_deg), NewtonOptions(reuse_factorization=True))
    top = body.top_height()
    e_star = 2.0 * MU_MPA * (1.0 + NU) / (1.0 - NU**2)
    rows = []
    for k, d in enumerate(np.linspace(depth_mm / steps, depth_mm, steps)):
        if not body.advance(k + 1.0, Control.position(top - d)).converged:
            raise RuntimeError(f"no convergence at depth {d} mm")
        force = disc.force_scale(0.0) * body.force
        area = contact_patch(body)[0]
        rows.append(
            HertzRow3D(
                depth_mm=float(d),
                force_N=float(force),
                hertz_force_N=float(4.0 / 3.0 * e_star * np.sqrt(R_MM) * d**1.5),
                a_mm=float(np.sqrt(area / np.pi)),
                hertz_a_mm=float((3.0 * force * R_MM / (4.0 * e_star)) ** (1.0 / 3.0)),
                dofs=int(disc.n_free),
            )
        )
    return rows
