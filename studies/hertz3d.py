"""Hertz contact of an elastic hemisphere pressed by the rigid plate, on the 3D model: the
figures of ``docs/model_3d.md``, "Hertz contact".

    python studies/hertz3d.py                  # h = 0.25 mm at the apex (54 k dofs, ~1.5 min)
    python studies/hertz3d.py --h 0.5 --fraction 0.1
    python studies/hertz3d.py --depth-ratio 4  # a half-ellipsoid 4 R deep, the same apex radius
    python studies/hertz3d.py --depth-ratio 4 --grading 1.0 --h-max 8 \
        --h 0.0625 --fraction 0.08 --depth 0.05  # within 2 % at delta = 0.05 mm (133 k dofs)

The pad with a = b = c = R and n = m = 2 is a hemisphere bonded on the base (quarter model),
neo-Hookean with mu = 0.1 MPa, nu = 0.3 (small strain: E* = 2 mu (1 + nu) / (1 - nu^2)).
The plate is pushed to ``depth`` in four steps; at each the script prints the whole force F,
the contact radius from the contact area, a = sqrt(A / pi), and Hertz's
a_H = (3 F R / (4 E*))^(1/3) and F_H = 4/3 E* R^(1/2) delta^(3/2). Hertz is a half-space
solution: the hemisphere on its rigid base is stiffer, more so as the contact grows (F above
F_H by an amount that grows with delta / R), while the contact radius at a given force is set
by the contact's near field. ``--depth-ratio k`` makes the body a half-ellipsoid of depth
b = k R and semi-axes a = c = R sqrt(k), whose apex has the same radius of curvature
a^2 / b = R: a deeper body, closer to Hertz's half-space (its surface y = b - r^2 / (2 R) -
r^4 / (8 k R^3) - ...: closer to Hertz's paraboloid than the sphere's r^4 / (8 R^3) too).
The computation: ``sim.verification.hertz_sphere_3d`` (a coarse version is a test,
``tests/test_hertz3d.py``)."""

from __future__ import annotations

import argparse
import time

from sim.verification import hertz_sphere_3d

if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--h", type=float, default=0.25, help="element size at the apex, mm")
    ap.add_argument("--fraction", type=float, default=0.15, help="contact region / R")
    ap.add_argument("--depth", type=float, default=0.2, help="final plate travel, mm")
    ap.add_argument("--depth-ratio", type=float, default=1.0, help="body depth / R (1: hemisphere)")
    ap.add_argument("--grading", type=float, default=0.4, help="element size growth per mm")
    ap.add_argument("--h-max", type=float, default=3.0, help="largest element size, mm")
    args = ap.parse_args()
    t0 = time.perf_counter()
    rows = hertz_sphere_3d(args.h, args.fraction, args.depth, depth_ratio=args.depth_ratio,
                           grading=args.grading, h_max_mm=args.h_max)  # fmt: skip
    print(
        f"depth ratio {args.depth_ratio:g}, grading {args.grading:g}, h_max {args.h_max:g} mm: "
        f"{rows[0].dofs} free dofs"
    )
    for r in rows:
        print(
            f"delta {r.depth_mm:.3f} mm  F {r.force_N:.5f} N (Hertz {r.hertz_force_N:.5f},"
            f" {r.force_N / r.hertz_force_N - 1:+.1%})  a {r.a_mm:.4f} mm (Hertz "
            f"{r.hertz_a_mm:.4f}, {r.a_mm / r.hertz_a_mm - 1:+.1%})"
        )
    print(f"{time.perf_counter() - t0:.0f} s")
