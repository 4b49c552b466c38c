"""What a person looks at of a 3D result (``sim.output.result``): the VTU files of the whole pad
mirrored from the quarter model, the figure of the deformed pad and its contact patch
(``sim.output._pad_figure``: its info object, not its pixels) and the curves' labels. One coarse
elastic tap of a two-layer pad (seconds); for the figure of an inclined tapping (the half pad,
docs/model_3d.md, "Inclination") one coarse elastic tap at 30 deg (about 30 s)."""

from __future__ import annotations

import numpy as np
import pytest

from sim.design import design_from_dict
from sim.geometry.mesh3d import MeshOptions3D, element_volumes, jacobian_determinants
from sim.options import ModelOptions, SimOptions, apply_overrides
from sim.output import curve_plot_data, pad_figure_info, write_result, write_vtu
from sim.simulate import simulate

meshio = pytest.importorskip("meshio")

COARSE = MeshOptions3D(h_apex_mm=1.0, h_contact_mm=1.5, h_max_mm=3.0, grading=0.6)
OPTS_3D = SimOptions(model=ModelOptions("3d"), mesh3d=COARSE)
SKIN = {"model": "neo_hookean", "mu_MPa": 0.08, "nu": 0.49}
PULP = {"model": "neo_hookean", "mu_MPa": 0.04, "nu": 0.49}


@pytest.fixture(scope="module")
def tap():
    """An elastic tap to 5 N on the coarse quarter pad, a 1 mm skin on a softer pulp."""
    design = design_from_dict(
        {"layers": [{"thickness_mm": 1.0, "material": SKIN}, {"material": PULP}]}
    )
    res = simulate(design, ("tapping",), OPTS_3D, keep_fields=True)
    assert res.ok, res.failures
    return res


@pytest.fixture(scope="module")
def info(tap):
    return pad_figure_info(tap)


# ----------------------------------------------------------------------------- VTU
def test_the_vtu_files_hold_the_whole_pad(tap, tmp_path):
    disc = tap.discretization
    pm = disc.pmesh
    paths = write_vtu(tap, tmp_path)
    assert sorted(p.name for p in paths) == [
        "deformed_tapping.vtu",
        "deformed_tapping_1N.vtu",
        "deformed_tapping_4N.vtu",
    ]
    # four copies, the nodes on the symmetry planes shared
    on_both = len(np.intersect1d(pm.sym_x, pm.sym_z))
    n_whole = 4 * disc.n_nodes - 2 * len(pm.sym_x) - 2 * len(pm.sym_z) + on_both
    for path in paths:
        u = tap.fields[path.stem.removeprefix("deformed_")]
        mesh = meshio.read(path)
        assert len(mesh.cells) == 1 and mesh.cells[0].type == "hexahedron27"
        cells = mesh.cells[0].data
        assert cells.shape == (4 * disc.n_el, 27)
        assert mesh.points.shape == (n_whole, 3)
        assert len(np.unique(cells)) == n_whole  # every node in a cell
        assert len(np.unique(np.round(mesh.points, 9), axis=0)) == n_whole  # none twice
        disp = mesh.point_data["displacement_mm"]
        assert disp.shape == (n_whole, 3)
        for name in ("layer", "compressive_log_strain", "J"):
            assert mesh.cell_data[name][0].shape == (4 * disc.n_el,)
        assert set(np.unique(mesh.cell_data["layer"][0])) == {0, 1}
        # positive cells (every Gauss point), and 4 x the quarter's deformed volume
        assert np.all(jacobian_determinants(mesh.points, cells) > 0.0)
        volumes = element_volumes(mesh.points, cells)
        quarter = element_volumes(disc.X + u, disc.conn).sum()
        assert volumes.sum() == pytest.approx(4.0 * quarter, rel=1e-10)
        # the whole pad is symmetric about x = 0 and z = 0, its displacements too
        reference = mesh.points - disp
        for axis in (0, 2):
            image = mesh.points * np.where(np.arange(3) == axis, -1.0, 1.0)
            assert _same_rows(image, mesh.points)
            assert _same_rows(reference * np.where(np.arange(3) == axis, -1.0, 1.0), reference)
        assert reference[:, 1].min() == pytest.approx(0.0, abs=1e-12)  # the base
    # the quarter alone when asked
    quarter = meshio.read(write_vtu(tap, tmp_path, whole_pad=False)[0])
    assert quarter.points.shape == (disc.n_nodes, 3)


def test_the_vtu_cells_hold_the_worst_quadrature_point(tap, tmp_path):
    """Strain and J per cell: the extremes over its Gauss points (``sim.protocols.validity``)."""
    from sim.protocols.validity import compressive_log_strain, volume_ratio

    disc = tap.discretization
    path = next(p for p in write_vtu(tap, tmp_path) if p.stem.endswith("4N"))
    cells = meshio.read(path).cell_data
    F = disc.deformation_gradient(tap.fields["tapping_4N"])
    strain, J = compressive_log_strain(F), volume_ratio(F)
    assert strain.shape == J.shape == (disc.n_el, 27)  # the 3D F dispatches
    E = disc.n_el
    np.testing.assert_allclose(cells["compressive_log_strain"][0][:E], strain.max(axis=1))
    np.testing.assert_allclose(cells["J"][0][:E], J.min(axis=1))
    assert 0.0 < strain.max() < 1.0 and 0.5 < J.min() <= 1.0 + 1e-9


def _same_rows(a: np.ndarray, b: np.ndarray, decimals: int = 9) -> bool:
    """Whether the rows of ``a`` and ``b`` are the same set (rounded)."""
    ra, rb = np.round(a, decimals) + 0.0, np.round(b, decimals) + 0.0  # no -0.0
    return np.array_equal(np.unique(ra, axis=0), np.unique(rb, axis=0))


# ----------------------------------------------------------------------------- figure
def test_the_pad_figure_info_has_both_forces(tap, info):
    assert [s.force_N for s in info.states] == [1.0, 4.0]
    assert [s.name for s in info.states] == ["tapping_1N", "tapping_4N"]
    for st in info.states:
        # the state: the first step at or beyond the force (a little beyond it)
        assert st.force_N <= st.state_force_N < 1.5 * st.force_N
        assert st.metric_area_mm2 == tap.metrics[f"contact_area_at_{st.force_N:g}N_mm2"]
        P = len(st.footprint_xz_mm)
        assert st.penetration_mm.shape == st.pressure_kPa.shape == (P,)
        assert st.footprint_triangles.max() < P
    low, high = info.states
    assert 0 < low.patch_area_mm2 < high.patch_area_mm2
    assert high.plate_position_mm < low.plate_position_mm


def test_the_plate_position_is_the_recorded_one(tap, info):
    """Read from the tap's curve: the surface pierces the plate by the penalty's ~1e-4 mm at
    its top, and the penalty forces there add up to the state's force."""
    disc = tap.discretization
    s = disc.surface_nodes
    weights = disc.surface_weights()
    for st in info.states:
        u = tap.fields[st.name]
        p = disc.X[s, 1] + u[s, 1] - st.plate_position_mm
        assert 1e-6 < p.max() < 1e-3
        force = 4.0 * info.kappa_N_per_mm3 * float(weights @ np.maximum(p, 0.0))
        assert force == pytest.approx(st.state_force_N, rel=1e-9)


def test_the_drawn_patch_is_the_metrics_patch(tap, info):
    """The drawn patch's area is the contact area of ``Discretization3D.contact_area_mm2`` at
    the state (another sampling of the same interpolated penetration), and near the metric,
    which is interpolated to exactly 1 N / 4 N while the state is a little beyond it."""
    disc = tap.discretization
    s = disc.surface_nodes
    for st in info.states:
        u = tap.fields[st.name]
        p = disc.X[s, 1] + u[s, 1] - st.plate_position_mm
        assert st.patch_area_mm2 == pytest.approx(disc.contact_area_mm2(u, p, 16), rel=0.02)
        # the area grows about like the force^(2/3) (Hertz) between the metric and the state
        grown = (st.state_force_N / st.force_N) ** (2.0 / 3.0)
        assert st.metric_area_mm2 < st.patch_area_mm2 < 1.25 * grown * st.metric_area_mm2


def test_the_footprint_lies_inside_the_pad(info):
    outline = info.outline_xz_mm
    a, c = np.abs(outline).max(axis=0)
    assert np.allclose(outline[0], outline[-1])  # closed
    for st in info.states:
        x, z = st.footprint_xz_mm.T
        inside = st.penetration_mm > 0.0
        # the reference pad's length exponent is 2: the base outline is an ellipse
        assert np.all((x[inside] / a) ** 2 + (z[inside] / c) ** 2 < 1.0)
        # the whole patch: symmetric about both axes, centred on the apex
        assert x[inside].max() == pytest.approx(-x[inside].min())
        assert z[inside].max() == pytest.approx(-z[inside].min())
        assert np.all(st.pressure_kPa >= 0.0)


def test_the_pressure_carries_the_force(info):
    """The drawn pressure integrated over the footprint is the state's force, within what the
    piecewise bilinear drawing of the nodal pressures changes (a few %)."""
    for st in info.states:
        xy, tri = st.footprint_xz_mm, st.footprint_triangles
        ab, ac = xy[tri[:, 1]] - xy[tri[:, 0]], xy[tri[:, 2]] - xy[tri[:, 0]]
        area = 0.5 * np.abs(ab[:, 0] * ac[:, 1] - ab[:, 1] * ac[:, 0])
        force = 1e-3 * float(area @ st.pressure_kPa[tri].mean(axis=1))
        assert force == pytest.approx(st.state_force_N, rel=0.15)


def test_the_section_is_pressed_flat_under_the_plate(info):
    ref = info.section_reference_zy_mm
    assert ref[:, 0].min() == pytest.approx(-ref[:, 0].max())
    for st in info.states:
        sec = st.section_zy_mm
        assert sec.shape == ref.shape
        assert sec[:, 1].max() == pytest.approx(st.plate_position_mm, abs=1e-3)
        assert len(st.interfaces_zy_mm) == 1  # two layers
        assert st.interfaces_zy_mm[0][:, 1].max() < st.plate_position_mm - 0.5


def test_write_result_draws_the_pad(tap, tmp_path):
    out = write_result(tap, tmp_path / "run", OPTS_3D)
    assert (out / "figures" / "pad.png").stat().st_size > 10_000
    assert (out / "figures" / "tapping.png").exists()
    assert (out / "deformed_tapping_4N.vtu").exists()


#: the quarter's figure info on the ``tap`` fixture, computed before the inclined figure was
#: added (its numbers must not move; a change of the solver or the mesh moves them by design:
#: solver 2.12's, whose kept factorisation takes another Newton path than 2.11's, moved them by
#: at most 2.1e-5, the 4 N state's penetration sum, within Newton's tolerance; solver 2.13's
#: single-precision factorisation, by at most 3.7e-8, the same sum)
QUARTER_INFO = {
    "kappa_N_per_mm3": 715.2,
    "n_elements": 224,
    "state_force_N": (1.2057971745110163, 4.236908950858977),
    "plate_position_mm": (4.530606413296945, 3.87378247492933),
    "patch_area_mm2": (24.46069086902569, 62.09202251438814),
    "footprint_points": (2916, 5508),
    "footprint_triangles": (4608, 8704),
    "pressure_sum_kPa": (88376.25902489468, 287162.58334199444),
    "penetration_sum_mm": (-72.59201557971623, -81.85213022345434),
    "section_sum_mm": (124.95103914977722, 110.56974075399823),
}


def test_the_quarters_pad_figure_info_is_unchanged(info):
    """At 0 deg (the quarter) the info is the one before the inclined figure existed: the same
    numbers on the same coarse tap, level, the pad whole. To 1e-6, not to the bit: the state
    is Newton's to its tolerance, and the path of the single-precision factorisation
    (``sim.fe._linear.PardisoSingle``) may differ between CPUs; a change of the figure's own
    reading moves these sums by far more."""
    q = QUARTER_INFO
    assert info.kappa_N_per_mm3 == pytest.approx(q["kappa_N_per_mm3"], rel=1e-9)
    assert info.n_elements == q["n_elements"]
    assert not info.half and info.inclination_deg == 0.0
    np.testing.assert_array_equal(info.plate_normal, [0.0, 1.0, 0.0])
    assert info.first_touch_zy_mm == (0.0, 5.48) and info.first_touch_s_mm == 0.0
    assert info.outline_xz_mm.shape == (361, 2) and info.section_reference_zy_mm.shape == (33, 2)
    for k, st in enumerate(info.states):
        assert st.state_force_N == pytest.approx(q["state_force_N"][k], rel=1e-6)
        assert st.plate_position_mm == pytest.approx(q["plate_position_mm"][k], rel=1e-6)
        assert st.patch_area_mm2 == pytest.approx(q["patch_area_mm2"][k], rel=1e-6)
        assert st.footprint_xz_mm.shape == (q["footprint_points"][k], 2)
        assert st.footprint_triangles.shape == (q["footprint_triangles"][k], 3)
        assert st.pressure_kPa.sum() == pytest.approx(q["pressure_sum_kPa"][k], rel=1e-6)
        assert st.penetration_mm.sum() == pytest.approx(q["penetration_sum_mm"][k], rel=1e-6)
        assert st.section_zy_mm.sum() == pytest.approx(q["section_sum_mm"][k], rel=1e-6)
        # the new fields: a level plate's trace, the patch centred on the apex
        np.testing.assert_array_equal(st.plate_trace_zy_mm[:, 1], st.plate_position_mm)
        assert st.patch_centre_mm == pytest.approx((0.0, 0.0), abs=1e-9)


def test_the_pad_figure_needs_a_3d_result():
    from types import SimpleNamespace

    with pytest.raises(ValueError, match="3D result"):
        pad_figure_info(SimpleNamespace(discretization=None, fields={}, curves={}))


# ----------------------------------------------------------------------------- inclined figure
INCLINATION_DEG = 30.0
#: a stiffer pad than ``tap``'s, so that the 30 deg tap reaches 4 N on the coarse mesh
SKIN_INCLINED = {"model": "neo_hookean", "mu_MPa": 0.16, "nu": 0.49}
PULP_INCLINED = {"model": "neo_hookean", "mu_MPa": 0.08, "nu": 0.49}
#: the coarse mesh, the plate at 30 deg, two taps at most (elastic: one), and the validity stop
#: off: this soft core reaches a compressive log strain of 0.62 (> its 0.60) near 4 N, which the
#: figure does not depend on
OPTS_INCLINED = apply_overrides(
    OPTS_3D,
    {
        "model.inclination_deg": str(INCLINATION_DEG),
        "tapping.max_taps": "2",
        "validity.stop_at_violation": "false",
    },
)


@pytest.fixture(scope="module")
def inclined_tap():
    """An elastic tap to 5 N on the coarse half pad by a plate inclined by 30 deg."""
    design = design_from_dict(
        {"layers": [{"thickness_mm": 1.0, "material": SKIN_INCLINED}, {"material": PULP_INCLINED}]}
    )
    res = simulate(design, ("tapping",), OPTS_INCLINED, keep_fields=True)
    assert res.ok, res.failures
    assert res.discretization.half
    return res


@pytest.fixture(scope="module")
def inclined_info(inclined_tap):
    return pad_figure_info(inclined_tap)


def _inclined_penetration(tap, info, st) -> np.ndarray:
    """The plate's penetration along e at the surface nodes at the state ``st``."""
    disc = tap.discretization
    s = disc.surface_nodes
    u = tap.fields[st.name]
    return (disc.X[s] + u[s]) @ info.plate_normal - st.plate_position_mm


def test_the_inclined_figure_info_states_the_plate(inclined_tap, inclined_info):
    """The half pad, the angle, the plate's normal and its direction along the finger; the
    plate's position read from the curve along e balances the states' forces (the half pad's
    force is 2 x the half's penalty forces)."""
    info = inclined_info
    t = np.radians(INCLINATION_DEG)
    assert info.half and info.inclination_deg == INCLINATION_DEG
    np.testing.assert_allclose(info.plate_normal, [0.0, np.cos(t), np.sin(t)])
    np.testing.assert_allclose(info.along_plate, [0.0, -np.sin(t), np.cos(t)])
    assert info.n_elements == inclined_tap.discretization.n_el
    assert [s.force_N for s in info.states] == [1.0, 4.0]
    disc = inclined_tap.discretization
    weights = disc.surface_weights()
    for st in info.states:
        p = _inclined_penetration(inclined_tap, info, st)
        assert 1e-6 < p.max() < 1e-3
        force = 2.0 * info.kappa_N_per_mm3 * float(weights @ np.maximum(p, 0.0))
        assert force == pytest.approx(st.state_force_N, rel=1e-9)
        # the plate's trace in x = 0: e . (y, z) = position, falling towards the tip
        (z0, y0), (z1, y1) = st.plate_trace_zy_mm
        assert (y1 - y0) / (z1 - z0) == pytest.approx(-np.tan(t), rel=1e-12)
        assert y0 * np.cos(t) + z0 * np.sin(t) == pytest.approx(st.plate_position_mm, rel=1e-12)


def test_the_inclined_footprint_is_centred_on_the_first_touch(inclined_info):
    """Seen along the plate's normal, the patch is centred on x = 0 and, along the finger,
    near the first-touch point (``first_touch_mm``: s* = t_p . (0, y*, z*)): within a tenth of
    the patch's length (measured: 5.32 and 5.02 mm against s* = 5.42 mm, patches 5.9 and
    8.8 mm long); and it lies on the tip's side, inside the pad's silhouette."""
    from matplotlib.path import Path

    from sim.geometry import PadGeometry, first_touch_mm

    info = inclined_info
    _, y_t, z_t = first_touch_mm(PadGeometry(), INCLINATION_DEG)
    assert info.first_touch_zy_mm == pytest.approx((z_t, y_t), rel=1e-12)
    s_touch = float(np.array([0.0, y_t, z_t]) @ info.along_plate)
    assert info.first_touch_s_mm == pytest.approx(s_touch, rel=1e-12)
    outline = info.outline_xz_mm
    assert np.allclose(outline[0], outline[-1])  # closed
    silhouette = Path(outline)
    for st in info.states:
        x, s = st.footprint_xz_mm.T
        inside = st.penetration_mm > 0.0
        length = float(s[inside].max() - s[inside].min())
        cx, cs = st.patch_centre_mm
        print(f"{st.name}: centre s {cs:.3f} mm (s* {s_touch:.3f}), patch {length:.2f} mm long")
        assert cx == pytest.approx(0.0, abs=1e-9)
        assert abs(cs - s_touch) < 0.1 * length
        assert x[inside].max() == pytest.approx(-x[inside].min())  # mirrored across x = 0
        assert s[inside].min() > 0.0  # the tip's half of the pad
        assert np.all(silhouette.contains_points(st.footprint_xz_mm[inside]))
        assert np.all(st.pressure_kPa >= 0.0)


def test_the_inclined_patch_is_the_metrics_patch(inclined_tap, inclined_info):
    """The drawn patch's area is the result's contact area (``contact_patch_mm``: projected on
    the plate) at the state within 2 %, and within 5 % of the metric at exactly 1 N / 4 N grown
    like the force^(2/3) to the state's force (measured: 10.74 against 10.83 and 10.54 mm^2
    at 1 N, 28.20 against 28.13 and 28.48 mm^2 at 4 N); the drawn pressure carries the force
    (within 15 %, as the quarter's)."""
    disc = inclined_tap.discretization
    info = inclined_info
    for st in info.states:
        u = inclined_tap.fields[st.name]
        p = _inclined_penetration(inclined_tap, info, st)
        area = disc.contact_patch_mm(u, p, info.plate_normal, 16)[0]
        grown = (st.state_force_N / st.force_N) ** (2.0 / 3.0) * st.metric_area_mm2
        print(f"{st.name}: patch {st.patch_area_mm2:.3f}, result's {area:.3f}, {grown:.3f} mm2")
        assert st.patch_area_mm2 == pytest.approx(area, rel=0.02)
        assert st.patch_area_mm2 == pytest.approx(grown, rel=0.05)
        xy, tri = st.footprint_xz_mm, st.footprint_triangles
        ab, ac = xy[tri[:, 1]] - xy[tri[:, 0]], xy[tri[:, 2]] - xy[tri[:, 0]]
        areas = 0.5 * np.abs(ab[:, 0] * ac[:, 1] - ab[:, 1] * ac[:, 0])
        force = 1e-3 * float(areas @ st.pressure_kPa[tri].mean(axis=1))
        assert force == pytest.approx(st.state_force_N, rel=0.15)


def test_the_inclined_section_runs_from_the_heel_to_the_tip(inclined_tap, inclined_info):
    """The section x = 0 is the half pad's, not mirrored: from the heel's end (z = -c) to the
    tip's (z = c) on the base, the undeformed one on the pad's outline y = b s(z), symmetric in
    z (the heel's side is meshed apart: its nodes are not the tip's mirror images), the
    deformed one not symmetric (pressed on the tip's side); no point beyond the plate, the
    plate's face reached; the interfaces too."""
    info = inclined_info
    pad = inclined_tap.discretization.pmesh.geometry
    _, b, c = pad.semi_axes_mm()
    m = float(pad.length_exponent)
    ref = info.section_reference_zy_mm
    np.testing.assert_allclose(ref[[0, -1]], [[-c, 0.0], [c, 0.0]], atol=1e-12)
    assert np.all(np.diff(ref[:, 0]) > 0.0)  # heel to tip
    outline = b * np.maximum(1.0 - np.abs(ref[:, 0] / c) ** m, 0.0) ** (1.0 / m)
    np.testing.assert_allclose(ref[:, 1], outline, atol=1e-9)  # the symmetric outline
    zs = np.linspace(0.1, 0.8, 8) * c
    e = info.plate_normal
    for st in info.states:
        sec = st.section_zy_mm
        assert sec.shape == ref.shape
        np.testing.assert_allclose(sec[[0, -1]], ref[[0, -1]], atol=1e-12)  # the bonded base
        assert np.all(np.diff(sec[:, 0]) > 0.0)
        tip, heel = np.interp(zs, sec[:, 0], sec[:, 1]), np.interp(-zs, sec[:, 0], sec[:, 1])
        assert np.max(heel - tip) > 1e-3  # pressed down on the tip's side
        height = sec[:, 1] * e[1] + sec[:, 0] * e[2]
        assert height.max() == pytest.approx(st.plate_position_mm, abs=1e-3)
        assert sec[np.argmax(height), 0] > 0.0  # it touches on the tip's side
        (interface,) = st.interfaces_zy_mm  # two layers
        assert interface[0, 0] < -0.8 * c and interface[-1, 0] > 0.8 * c
        assert interface[0, 0] == pytest.approx(-interface[-1, 0])  # on the base
        assert np.all(interface[:, 1] * e[1] + interface[:, 0] * e[2] < st.plate_position_mm)


def test_write_result_draws_the_inclined_pad(inclined_tap, tmp_path):
    """``write_result`` (what ``fingertip simulate --out`` calls) draws figures/pad.png for the
    inclined tapping too."""
    out = write_result(inclined_tap, tmp_path / "run", OPTS_INCLINED)
    assert (out / "figures" / "pad.png").stat().st_size > 10_000


# ----------------------------------------------------------------------------- curves
def test_the_force_labels_name_the_model(tap):
    three = curve_plot_data(tap)["tapping"]
    assert three["ylabel"] == "force on the whole pad (N)" and "3D" in three["title"]
    assert "L =" not in three["title"] + three["ylabel"]
    # a 2D result: the section's force times its length, per protocol
    from types import SimpleNamespace

    curves = {
        "tapping": {"displacement_mm": [0, 1], "force_N": [0, 1]},
        "plate": {"displacement_mm": [0, 1], "force_N": [0, 1]},
        "wedge": {"time_s": [0, 1], "force_N": [0, 1]},
    }
    two = curve_plot_data(SimpleNamespace(curves=curves, metrics={}))
    assert "L = 10 mm" in two["tapping"]["ylabel"] and "L = 10 mm" in two["wedge"]["ylabel"]
    assert "L = 22 mm" in two["plate"]["title"] and "L = 22 mm" in two["plate"]["ylabel"]
    # without the discretisation, the options or the metrics tell the model
    assert "L =" not in curve_plot_data(SimpleNamespace(curves=curves), OPTS_3D)["plate"]["title"]
    metrics_3d = {"contact_area_at_1N_mm2": 1.0}
    only = curve_plot_data(SimpleNamespace(curves=curves, metrics=metrics_3d))
    assert only["wedge"]["ylabel"] == "force on the whole pad (N)"
