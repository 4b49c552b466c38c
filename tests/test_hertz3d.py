"""Hertz contact of a sphere on the 3D model (``sim.verification.hertz_sphere_3d``): a coarse,
fast version of ``python studies/hertz3d.py`` (docs/model_3d.md, "Hertz contact"), whose finer
runs put the force and the contact radius within 2 % of Hertz's at delta / R = 0.5 %.

The body: a half-ellipsoid 4 R deep with the apex radius R = 10 mm (closer to Hertz's
half-space than a hemisphere on its rigid base), h = 0.5 mm at the apex (22 k dofs, seconds).
Hertz's scaling laws are checked by fitted exponents (F ~ delta^(3/2), a ~ F^(1/3)), and the
values against the closed forms within the coarse mesh's error (the finer meshes' figures in
the docs: the force within 2 % at the smallest load, the radius approaching Hertz's as h
halves)."""

from __future__ import annotations

import numpy as np
import pytest

from sim.verification import hertz_sphere_3d


@pytest.fixture(scope="module")
def rows():
    return hertz_sphere_3d(0.5, 0.15, 0.2, depth_ratio=4.0, grading=1.0, h_max_mm=8.0)


def test_force_grows_as_the_approach_to_the_three_halves(rows):
    """Hertz: F = 4/3 E* R^(1/2) delta^(3/2); the fitted exponent within 0.05 of 1.5 (a
    neo-Hookean body's finite strain lowers it slightly: 1.48 here), and the force at the
    smallest approach within 3 % of the closed form."""
    d = np.array([r.depth_mm for r in rows])
    f = np.array([r.force_N for r in rows])
    slope = np.polyfit(np.log(d), np.log(f), 1)[0]
    errors = [round(r.force_N / r.hertz_force_N - 1, 4) for r in rows]
    print(f"F ~ delta^{slope:.3f}; F / F_H - 1 = {errors}")
    assert abs(slope - 1.5) < 0.05
    assert abs(rows[0].force_N / rows[0].hertz_force_N - 1.0) < 0.03
    assert all(abs(r.force_N / r.hertz_force_N - 1.0) < 0.05 for r in rows)


def test_contact_radius_grows_as_the_cube_root_of_the_force(rows):
    """Hertz: a = (3 F R / (4 E*))^(1/3); the fitted exponent within 0.03 of 1/3 and every
    radius within 8 % of the closed form at its force (the coarse patch, 3-6 elements across,
    reads its edge to about half an element)."""
    f = np.array([r.force_N for r in rows])
    a = np.array([r.a_mm for r in rows])
    slope = np.polyfit(np.log(f), np.log(a), 1)[0]
    errors = [round(r.a_mm / r.hertz_a_mm - 1, 4) for r in rows]
    print(f"a ~ F^{slope:.3f}; a / a_H - 1 = {errors}")
    assert abs(slope - 1.0 / 3.0) < 0.03
    assert all(abs(r.a_mm / r.hertz_a_mm - 1.0) < 0.08 for r in rows)
