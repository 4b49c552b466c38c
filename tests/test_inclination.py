"""The 3D model's finger inclination (``model.inclination_deg``): the plate tilted about the
cross-finger axis x on the half pad x >= 0 (docs/model_3d.md, "Inclination").

- the half mesh (``sim.geometry.mesh3d.half_pad_mesh``): the quarter and its mirror image,
  positive Jacobians, outward faces, twice the volume; inclined, the quarter glued to a
  coarser quarter on the heel's side, conforming, and pressed as the mirror image is;
- the half model at 0 deg reproduces the quarter's plate and tapping readings;
- global equilibrium on the inclined plate: the base's reaction is the plate's force along its
  normal, with no tangential part;
- a sphere pressed by a plate at 20 deg gives the force and contact area it gives at 0 deg;
- the plate first touches where docs/fingertip_3d.md's table says;
- the option: its range, 3D only, not with the wedge, and the dict form (record keys) at 0.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from sweep_fixtures import TINY

from sim.errors import DesignError
from sim.fe import Body, Control, Discretization3D, NewtonOptions, Plate, model_newton
from sim.geometry import (
    COARSE_MESH_3D,
    PAD_MESH_3D,
    Geometry,
    MeshOptions3D,
    PadGeometry,
    build_pad_mesh,
    first_touch_mm,
)
from sim.geometry.mesh3d import element_volumes, jacobian_determinants
from sim.materials._material import material_from_table
from sim.options import ModelOptions, SimOptions, apply_overrides, options_from_dict
from sim.protocols import PlateOptions, TappingOptions, contact_patch, run_plate, run_tapping

#: a coarse mesh and a short pad, as tests/test_fe3d.py: seconds per press
COARSE = MeshOptions3D(h_apex_mm=1.0, h_contact_mm=1.5, h_max_mm=3.0, grading=0.6)
PAD = PadGeometry(Geometry(5.84, 5.48, 1.5), half_length_mm=8.0, length_exponent=2.0)
ELASTIC = {"model": "neo_hookean", "mu_MPa": 0.05, "nu": 0.49}
NEWTON_3D = model_newton(NewtonOptions(), 3)


def _body(pad: PadGeometry, inclination_deg: float, half: bool | None = None) -> Body:
    return _body_on(build_pad_mesh(pad, (), COARSE, inclination_deg, half=half), inclination_deg)


def _body_on(pmesh, inclination_deg: float) -> Body:
    """The elastic pad on the mesh ``pmesh`` under a plate inclined by ``inclination_deg``."""
    disc = Discretization3D(pmesh, [material_from_table(ELASTIC)])
    return Body(disc, Plate(inclination_deg), NEWTON_3D)


# ----------------------------------------------------------------------------- the half mesh
def test_the_half_mesh_is_the_quarter_and_its_mirror_image():
    quarter = build_pad_mesh(PAD, (1.0,), COARSE)
    half = build_pad_mesh(PAD, (1.0,), COARSE, half=True)
    X, Xq = np.asarray(half.nodes), np.asarray(quarter.nodes)
    n_plane = len(quarter.sym_z)
    assert half.half and not quarter.half and half.mirrors == 2 and quarter.mirrors == 4
    assert half.n_nodes == 2 * quarter.n_nodes - n_plane  # the plane's nodes numbered once
    np.testing.assert_array_equal(X[: quarter.n_nodes], Xq)  # the quarter keeps its numbering
    assert len(np.unique(X, axis=0)) == half.n_nodes  # no duplicate node
    assert len(half.sym_z) == 0 and np.all(X[half.sym_x, 0] == 0.0)
    assert jacobian_determinants(X, np.asarray(half.hexes)).min() > 0.0
    vq = element_volumes(Xq, np.asarray(quarter.hexes)).sum()
    assert element_volumes(X, np.asarray(half.hexes)).sum() == pytest.approx(2 * vq, rel=1e-12)
    # every surface face points out of the body: its normal at the centre away from the
    # origin (the pad is star-shaped from the origin), on both halves
    from sim.geometry import _q2

    F = np.asarray(half.surface_faces)
    dN = _q2.face_shape_gradients(np.zeros((1, 2)))[0]  # (9, 2) at the face's centre
    t = np.einsum("fai,ad->fdi", X[F], dN)
    outward = np.einsum("fi,fi->f", np.cross(t[:, 0], t[:, 1]), X[F[:, 8]])
    assert np.all(outward > 0.0) and len(F) == 2 * len(quarter.surface_faces)
    for interface_h, interface_q in zip(half.interfaces, quarter.interfaces, strict=True):
        assert len(interface_h) == 2 * len(interface_q) - len(
            np.intersect1d(interface_q, quarter.sym_z)
        )


def test_an_inclined_half_is_graded_for_its_heel_side_and_conforming():
    """At 30 deg the half pad is the quarter graded for the plate (z >= 0) glued on z = 0 to a
    quarter graded for the heel's side, where the plate does not touch: fewer nodes than the
    quarter's mirror image would give, the quarter's nodes first and unchanged, z = 0 inside
    the body (no element face left alone there: the two sides meet node for node), positive
    Jacobians, every surface face outward, and the volume of the symmetric half to 1e-4 (the
    two approximate the same curved pad)."""
    from sim.geometry import _q2
    from sim.geometry.mesh3d import _build_quarter, half_pad_mesh

    quarter = _build_quarter(PAD, (1.0,), COARSE, 30.0)
    half = build_pad_mesh(PAD, (1.0,), COARSE, 30.0)
    symmetric = half_pad_mesh(quarter)
    X, H = np.asarray(half.nodes), np.asarray(half.hexes)
    assert half.half and half.inclination_deg == 30.0
    assert quarter.n_nodes < half.n_nodes < symmetric.n_nodes
    np.testing.assert_array_equal(X[: quarter.n_nodes], np.asarray(quarter.nodes))
    assert len(np.unique(X, axis=0)) == half.n_nodes and len(half.sym_z) == 0
    assert jacobian_determinants(X, H).min() > 0.0
    # every element face (its 4 corners) used twice inside, once on the boundary; none of
    # the boundary's on z = 0
    corners = [(0, 1, 2, 3), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    faces = np.sort(np.concatenate([H[:, list(c)] for c in corners]), axis=1)
    unique, count = np.unique(faces, axis=0, return_counts=True)
    assert set(count) == {1, 2}
    on_plane = np.all(X[unique[count == 1], 2] == 0.0, axis=1)
    assert not np.any(on_plane)
    volume = element_volumes(X, H).sum()
    v_sym = element_volumes(np.asarray(symmetric.nodes), np.asarray(symmetric.hexes)).sum()
    assert volume == pytest.approx(v_sym, rel=1e-4)
    F = np.asarray(half.surface_faces)
    dN = _q2.face_shape_gradients(np.zeros((1, 2)))[0]
    t = np.einsum("fai,ad->fdi", X[F], dN)
    assert np.all(np.einsum("fi,fi->f", np.cross(t[:, 0], t[:, 1]), X[F[:, 8]]) > 0.0)


def test_the_heel_side_does_not_change_an_inclined_press():
    """The plate at 30 deg pressing the short pad to 0.3 mm: the same forces, within 1e-4, on
    the half graded for its heel's side as on the quarter's mirror image (the plate touches
    the side z > 0, which both mesh alike; measured 5e-6 at 0.3 mm)."""
    from sim.geometry.mesh3d import _build_quarter, half_pad_mesh

    forces = []
    for pmesh in (
        build_pad_mesh(PAD, (), COARSE, 30.0),
        half_pad_mesh(_build_quarter(PAD, (), COARSE, 30.0)),
    ):
        body = _body_on(pmesh, 30.0)
        top = body.top_height()
        f = []
        for k, d in enumerate(np.linspace(0.1, 0.3, 3)):
            assert body.advance(0.1 * (k + 1), Control.position(top - d)).converged
            f.append(body.force)
        forces.append(f)
    print(f"forces (N): graded for the heel {forces[0]}, mirror image {forces[1]}")
    assert forces[0][-1] > 0.01
    np.testing.assert_allclose(forces[0], forces[1], rtol=1e-4)


def test_an_inclined_mesh_is_refined_at_the_first_touch():
    """The finest surface elements move from the apex to the first-touch point: the faces
    around the 30 deg touch point are as fine as those around the apex at 0 deg (within 10 %)
    and finer than the 0 deg mesh's there."""
    pad = PadGeometry(half_length_mm=11.0, length_exponent=2.0)
    touch = np.array(first_touch_mm(pad, 30.0))
    sizes = {}
    for t, centre in ((0.0, [0.0, 5.48, 0.0]), (0.0, touch), (30.0, touch)):
        pmesh = build_pad_mesh(pad, (), COARSE_MESH_3D, t)
        X = np.asarray(pmesh.nodes)[np.asarray(pmesh.surface_faces)]
        diagonal = np.linalg.norm(X[:, 2] - X[:, 0], axis=1)  # corners 0 and 2 of each face
        near = np.linalg.norm(X[:, 8] - centre, axis=1) < 1.5  # face centres near the point
        sizes[(t, "apex" if centre[2] == 0.0 else "touch")] = float(np.mean(diagonal[near]))
    print(f"mean face diagonal within 1.5 mm (mm): {sizes}")
    assert sizes[(30.0, "touch")] <= 1.1 * sizes[(0.0, "apex")]
    assert sizes[(30.0, "touch")] < 0.8 * sizes[(0.0, "touch")]


# ----------------------------------------------------------------------------- physics
def test_the_half_model_at_0_deg_reproduces_the_quarter():
    """The same pad, the quarter and the half at 0 deg: the plate's force and displacement
    curves, and an elastic tapping's readings (force control: the bordered system), agree to
    Newton's tolerance; the contact area and length along the finger too, the width within
    2 % (read at the widest sample on the half, on the plane z = 0 on the quarter)."""
    plate = PlateOptions(depth_mm=0.3, steps=3)
    tap = TappingOptions(peak_force_N=0.3, steps_loaded=12, steps_settle=12)
    out = {}
    for half in (False, True):
        body = _body(PAD, 0.0, half)
        res = run_plate(body, plate)
        patch = contact_patch(body)
        tapping = run_tapping(_body(PAD, 0.0, half), tap)
        out[half] = res.curves["plate"], patch, tapping.curves["tapping"]
    (cq, pq, tq), (ch, ph, th) = out[False], out[True]
    print(f"quarter {cq['force_N'][-1]!r} N, {pq}; half {ch['force_N'][-1]!r} N, {ph}")
    print(f"tapping to 0.3 N: deepest {max(tq['displacement_mm'])!r} / "
          f"{max(th['displacement_mm'])!r} mm")  # fmt: skip
    np.testing.assert_allclose(ch["displacement_mm"], cq["displacement_mm"], rtol=1e-12)
    np.testing.assert_allclose(ch["force_N"], cq["force_N"], rtol=1e-6)
    assert ph[0] == pytest.approx(pq[0], rel=1e-6) and ph[2] == pytest.approx(pq[2], rel=1e-6)
    assert ph[1] == pytest.approx(pq[1], rel=0.02)
    np.testing.assert_allclose(th["force_N"], tq["force_N"], rtol=1e-6, atol=1e-9)
    # near lift-off (forces of 1e-4 N) the displacements agree to 1e-5 of the deepest: Newton's
    # tolerance on the nodes, not the force's 1e-6 relative
    scale = max(tq["displacement_mm"])
    np.testing.assert_allclose(th["displacement_mm"], tq["displacement_mm"], atol=1e-5 * scale)


@pytest.fixture(scope="module")
def inclined_press() -> Body:
    """The short pad pressed 0.3 mm by a plate inclined by 30 deg (half model)."""
    body = _body(PAD, 30.0)
    top = body.top_height()
    for k, d in enumerate(np.linspace(0.05, 0.3, 6)):
        assert body.advance(0.1 * (k + 1), Control.position(top - d)).converged
    return body


def test_the_base_carries_the_inclined_plates_force(inclined_press):
    """Global equilibrium at 30 deg: the internal forces of the free surface nodes (the
    contact forces they balance) sum to the plate's force along its normal, with no component
    along the plate (frictionless), and the bonded base's reaction carries it:
    f_base = F (cos t, sin t) in (y, z)."""
    body = inclined_press
    disc = body.disc
    t = np.radians(30.0)
    e, along = np.array([0.0, np.cos(t), np.sin(t)]), np.array([0.0, -np.sin(t), np.cos(t)])
    free_all = Discretization3D(disc.pmesh, disc.materials, fixed=lambda X: np.zeros(X.shape, bool))
    ev = free_all.evaluate(body.u, body.states, 0.0, tangent=False, frozen_history=True)
    f = ev.residual.reshape(-1, 3)
    base = disc.pmesh.base
    contact = np.setdiff1d(disc.surface_nodes, base)
    f_contact = f[contact].sum(axis=0)  # balances the plate's push on the body
    F = body.force
    print(
        f"F = {F:.6g} N (half); contact: along e {-f_contact @ e:.6g}, along the plate "
        f"{f_contact @ along:.3g}; base: y {f[base, 1].sum():.6g}, z {f[base, 2].sum():.6g}"
    )
    assert F > 0.01
    assert -f_contact @ e == pytest.approx(F, rel=1e-5)
    assert abs(f_contact @ along) < 1e-5 * F
    np.testing.assert_allclose(f[base, 1:].sum(axis=0), F * e[1:], rtol=1e-5)


def test_a_sphere_gives_the_same_contact_at_20_deg():
    """A hemisphere (a = b = c = R = 10 mm, n = m = 2, neo-Hookean) pressed 0.1 and 0.2 mm
    along the plate's normal at 0 deg (quarter) and 20 deg (half, refined at the touch point
    20 deg from the apex): the sphere is the same around both contacts, and the bonded base is
    2 R from them. On this coarse mesh (h = 0.5 mm) the force agrees within 1 % and the
    contact radius sqrt(A / pi) within 5 % (the patch, 4-6 elements across, is read to about
    half an element: the same spread as tests/test_hertz3d.py's radius against Hertz's)."""
    from sim.verification import hertz_sphere_3d

    rows = {
        t: hertz_sphere_3d(0.5, 0.15, 0.2, steps=2, grading=1.0, h_max_mm=8.0, inclination_deg=t)
        for t in (0.0, 20.0)
    }
    for flat, tilted in zip(rows[0.0], rows[20.0], strict=True):
        print(
            f"delta {flat.depth_mm} mm: F {flat.force_N:.5f} / {tilted.force_N:.5f} N, "
            f"a {flat.a_mm:.4f} / {tilted.a_mm:.4f} mm"
        )
        assert tilted.force_N == pytest.approx(flat.force_N, rel=0.01)
        assert tilted.a_mm == pytest.approx(flat.a_mm, rel=0.05)


#: docs/fingertip_3d.md, "Where the plate first touches the pad when it is inclined":
#: m -> ((theta, z mm, s(z)), ...) for c = 11 mm, b = 5.48 mm
DOCS_TABLE = {
    2: ((20, 6.5, 0.81), (30, 8.3, 0.65), (45, 9.8, 0.45)),
    3: ((20, 8.0, 0.85), (30, 9.0, 0.76), (45, 9.9, 0.64)),
    4: ((20, 8.7, 0.88), (30, 9.5, 0.82), (45, 10.1, 0.73)),
    8: ((20, 9.8, 0.94), (30, 10.2, 0.91), (45, 10.5, 0.86)),
}


def test_the_first_touch_point_is_the_docs_table():
    """``first_touch_mm`` gives the docs' table to its rounding (0.05 mm, 0.005)."""
    for m, rows in DOCS_TABLE.items():
        pad = PadGeometry(half_length_mm=11.0, length_exponent=float(m))
        for theta, z, s in rows:
            _, y_t, z_t = first_touch_mm(pad, float(theta))
            assert z_t == pytest.approx(z, abs=0.05) and y_t / 5.48 == pytest.approx(s, abs=0.005)
    assert first_touch_mm(PAD, 0.0) == (0.0, 5.48, 0.0)


@pytest.mark.parametrize(("m", "theta"), [(2, 30), (3, 20), (8, 45)])
def test_a_light_inclined_press_touches_where_the_table_says(m, theta):
    """The default section and c = 11 mm pressed 0.05 mm by the inclined plate: the centre of
    the contact forces (the nodes' penalty forces as weights) lies at the table's z within
    0.1 mm (measured: within 0.04 mm), and the plate's undeformed top is the table's point
    (to the mesh's nodes)."""
    pad = PadGeometry(half_length_mm=11.0, length_exponent=float(m))
    body = _body(pad, float(theta))
    top = body.top_height()
    t = np.radians(theta)
    _, y_t, z_t = first_touch_mm(pad, float(theta))
    exact = y_t * np.cos(t) + z_t * np.sin(t)  # e . (y*, z*): the smooth surface's top
    assert exact - 0.02 < top <= exact + 1e-9  # nodes on that surface, one near the top
    assert body.advance(0.1, Control.position(top - 0.05)).converged
    s = body.disc.surface_nodes
    p = body.indenter_penetration()
    w = body.kappa_indenter * np.maximum(p, 0.0)
    x = body.disc.X[s] + body.u[s]
    centre = w @ x / w.sum()
    z_docs = dict((th, z) for th, z, _ in DOCS_TABLE[m])[theta]
    print(f"m = {m}, {theta} deg: contact centre {centre}, table z = {z_docs} ({z_t:.3f})")
    assert centre[2] == pytest.approx(z_docs, abs=0.1)


# ----------------------------------------------------------------------------- the option
#: record keys computed before the option existed (solver 2.8): the option must not change
#: them at its default (a sweep's records keep their keys). A new SOLVER_VERSION re-keys every
#: record by design, so the keys are computed here as solver 2.8 would.
KEY_3D_POINT = "58582211b5516d37e115"  # sample_points(default_space_3d, 1, seed 0)[0], --model 3d
KEY_2D_POINT = "2fe2b0e1be08a1bdbcc5"  # sample_points(default_space, 1, seed 0)[0], 2D


def test_the_default_inclination_leaves_records_unchanged(monkeypatch):
    import sim.sweep.run
    from sim.design import load_space
    from sim.design.space import DEFAULT_SPACE_3D_PATH

    # the 3D options of records made before the wedge's band was the default (without it),
    # and before solver 2.12 changed the default of newton.reuse_ratio (sim.metrics.
    # DEFAULTS_BEFORE): as solver 2.8 made them
    from sim.metrics import DEFAULTS_BEFORE
    from sim.sweep import record_key, sample_points

    ratio_before = DEFAULTS_BEFORE[("newton", "reuse_ratio")][1]
    newton_before = dataclasses.replace(SimOptions().newton, reuse_ratio=ratio_before)
    three = SimOptions(model=ModelOptions("3d"), mesh3d=PAD_MESH_3D, newton=newton_before)
    assert three.as_dict()["model"] == {"dimension": "3d"}
    assert "model" not in SimOptions().as_dict()
    assert options_from_dict(three.as_dict()) == three
    tilted = apply_overrides(three, {"model.inclination_deg": "30"})
    assert tilted.as_dict()["model"] == {"dimension": "3d", "inclination_deg": 30.0}
    assert options_from_dict(tilted.as_dict()) == tilted
    monkeypatch.setattr(sim.sweep.run, "SOLVER_VERSION", "2.8")
    p3 = sample_points(load_space(DEFAULT_SPACE_3D_PATH), 1, 0)[0]
    p2 = sample_points(load_space(), 1, 0)[0]
    assert record_key(p3, three) == KEY_3D_POINT
    assert record_key(p2, SimOptions(newton=newton_before)) == KEY_2D_POINT
    assert record_key(p3, tilted) != KEY_3D_POINT


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        (
            {"model.dimension": "3d", "model.inclination_deg": "50"},
            "model.inclination_deg: must be in [0, 45] degrees, got 50.0",
        ),
        (
            {"model.dimension": "3d", "model.inclination_deg": "-5"},
            "model.inclination_deg: must be in [0, 45] degrees, got -5.0",
        ),
        (
            {"model.inclination_deg": "30"},
            "model.inclination_deg: applies to the 3d model only, not to --model 2d",
        ),
    ],
)
def test_bad_inclinations_are_one_line(overrides, message):
    with pytest.raises(DesignError) as err:
        apply_overrides(SimOptions(), overrides)
    assert str(err.value) == message
    with pytest.raises(DesignError, match=r"model\.inclination_deg: must be in \[0, 45\]"):
        ModelOptions("3d", 90.0)
    with pytest.raises(DesignError, match="3d model only"):
        dataclasses.replace(SimOptions().model, inclination_deg=10.0)


def test_the_cli_runs_an_inclined_plate_and_refuses_bad_input(tmp_path, capsys):
    """``fingertip simulate --model 3d --protocol plate --set model.inclination_deg=30``; out of
    range, in 2D and with the wedge (the default protocols include it): one line, exit 2."""
    from explore.cli import main

    design = tmp_path / "pad.toml"
    design.write_text('[geometry]\nhalf_length_mm = 8.0\n[[layers]]\nmaterial = "silicone_gls40"\n')
    coarse = ["--set", "mesh3d.h_apex_mm=1.0", "--set", "mesh3d.h_contact_mm=1.5",
              "--set", "mesh3d.h_max_mm=3", "--set", "mesh3d.grading=0.6"]  # fmt: skip
    args = ["simulate", str(design), "--model", "3d", *coarse]
    assert main([*args, "--protocol", "plate", "--set", "model.inclination_deg=30"]) == 0
    out = capsys.readouterr().out
    assert "plate_force_at_1mm_N" in out and "not reached" not in out
    bad = [
        (
            [*args, "--protocol", "plate", "--set", "model.inclination_deg=60"],
            "model.inclination_deg: must be in [0, 45] degrees, got 60.0",
        ),
        (
            ["simulate", str(design), "--set", "model.inclination_deg=20"],
            "model.inclination_deg: applies to the 3d model only, not to --model 2d",
        ),
        (
            [*args, "--set", "model.inclination_deg=20"],
            "model.inclination_deg: inclines the plate only: the wedge's edge runs across the "
            "pad at z = 0 and is not inclined; run --protocol tapping or --protocol plate",
        ),
    ]
    space = tmp_path / "space.toml"
    space.write_text(TINY)
    sweep = ["sweep", str(space), "--n", "2", "--out", str(tmp_path / "sweep"), "--model", "3d"]
    bad.append(
        (
            [*sweep, "--set", "model.inclination_deg=20"],
            "model.inclination_deg: a sweep runs the wedge, which is upright only: must be 0 in "
            "a sweep (an inclined plate or tapping: fingertip simulate --protocol plate|tapping)",
        )
    )
    for argv, message in bad:
        assert main(argv) == 2
        captured = capsys.readouterr()
        assert captured.err.strip().splitlines() == [f"fingertip: error: {message}"]
        assert "Traceback" not in captured.err


def test_an_inclined_press_is_read_along_the_plate(inclined_press):
    """The validity figures of the 30 deg press: the travel is the plate's along its normal
    (0.3 mm), the surface is not folded (the curve in x = 0 runs from the heel's end to the
    tip's: the apex sliding towards the heel is no crossing of a symmetry plane), and the
    contact's extents are those of ``contact_patch``."""
    from sim.protocols import DeformationTracker

    body = inclined_press
    tracker = DeformationTracker(body.disc)
    tracker.observe(body)
    tracker.observe_peak(body)
    summary = tracker.summary()
    area, width, length = contact_patch(body)
    print(f"30 deg, 0.3 mm: area {area:.3f} mm2, width {width:.3f} mm, length {length:.3f} mm")
    assert summary["indenter_travel_mm"] == pytest.approx(0.3, rel=1e-9)
    assert summary["folded"] is False
    assert summary["contact_width_at_peak_mm"] == width > 0.0
    assert summary["contact_length_at_peak_mm"] == length > width
    assert body.u[body.disc.apex_node, 2] < 0.0  # the apex is pushed towards the heel
