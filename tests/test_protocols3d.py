"""The three protocols on the 3D pad (``simulate(..., SimOptions(model=ModelOptions("3d")))``):
forces of the whole pad from the quarter model, the contact patch metrics, the options' dict
form of each model, and the 2D results left as they were. A coarse mesh keeps it to seconds;
the verification against closed forms and FElupe: ``tests/test_fe3d_felupe.py``,
``tests/test_hertz3d.py``."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from sim.design import design_from_dict, homogeneous_design
from sim.errors import DesignError
from sim.fe._linear import pardiso_available
from sim.geometry import MeshOptions3D
from sim.metrics import METRICS, METRICS_3D, metric_registry
from sim.options import ModelOptions, SimOptions, apply_overrides, options_from_dict
from sim.protocols import contact_patch
from sim.simulate import discretize, simulate

ROOT = Path(__file__).resolve().parents[1]
COARSE = MeshOptions3D(h_apex_mm=1.0, h_contact_mm=1.5, h_max_mm=3.0, grading=0.6)
OPTS_3D = SimOptions(model=ModelOptions("3d"), mesh3d=COARSE)
ELASTIC = {"model": "neo_hookean", "mu_MPa": 0.08, "nu": 0.49}


@pytest.fixture(scope="module")
def elastic_tap():
    """One elastic tap to 5 N on the coarse quarter pad (an elastic body needs one tap)."""
    design = design_from_dict({"layers": [{"material": ELASTIC}]})
    return simulate(design, ("tapping",), OPTS_3D, keep_fields=True)


def test_the_3d_tapping_reports_every_3d_metric(elastic_tap):
    res = elastic_tap
    assert res.ok, res.failures
    assert set(res.metrics) == {
        n for n, (p, _, _) in metric_registry("3d").items() if p == "tapping"
    }
    m = res.metrics
    assert 0 < m["disp_at_1N_mm"] < m["disp_at_4N_mm"]
    # the patch grows with the force, and a contact area is at most its bounding ellipse
    for what in ("area", "width", "length"):
        unit = "mm2" if what == "area" else "mm"
        assert 0 < m[f"contact_{what}_at_1N_{unit}"] < m[f"contact_{what}_at_4N_{unit}"]
    for f in (1, 4):
        ellipse = np.pi / 4 * m[f"contact_width_at_{f}N_mm"] * m[f"contact_length_at_{f}N_mm"]
        assert m[f"contact_area_at_{f}N_mm2"] < 1.2 * ellipse
    assert res.protocols["tapping"]["taps"] == 1
    # the states at 1 N and 4 N on the way up are kept for the VTU files and the figure
    assert {"tapping", "tapping_1N", "tapping_4N"} <= set(res.fields)
    apex = res.discretization.apex_node
    assert 0 < -res.fields["tapping_1N"][apex, 1] < -res.fields["tapping_4N"][apex, 1]


def test_the_reported_force_is_four_quarters(elastic_tap):
    """The curve's force is the whole pad's, 4 x the quarter model's indenter force: the tap
    asked for a 5 N peak and the force-controlled quarter carried 1.25 N."""
    disc = elastic_tap.discretization
    assert disc.force_scale(10.0) == 4.0
    curve = elastic_tap.curves["tapping"]
    assert max(curve["force_N"]) == pytest.approx(5.0, rel=1e-3)


def test_the_contact_patch_is_zero_without_contact(elastic_tap):
    from sim.fe import Body, Plate

    body = Body(elastic_tap.discretization, Plate())
    assert contact_patch(body) == (0.0, 0.0, 0.0)


def test_plate_and_wedge_run_in_3d():
    design = homogeneous_design("silicone_gls40")
    res = simulate(design, ("plate", "wedge"), OPTS_3D)
    assert res.ok, res.failures
    m = res.metrics
    assert m["plate_force_at_1mm_N"] > 0
    # the gel relaxes under the held wedge: less force at 100 s than at the end of the ramp
    assert 0 < m["wedge_force_at_100s_N"] < m["wedge_peak_force_N"]
    # the wedge's edge runs across the pad: the profile is read along the finger, it is
    # deepest at the wedge and decays away from it
    prof = res.curves["profile_1s"]
    defl = np.asarray(prof["deflection_mm"])
    assert defl[0] > 0.5 and defl[0] > defl[len(defl) // 2] > defl[-1]
    assert res.validity["protocols"]["plate"]["contact_length_at_peak_mm"] > 0
    # PARDISO factorises the plate's and the banded wedge's tangents in single precision
    # (sim.simulate.SINGLE_PRECISION_PROTOCOLS); a step of the wedge may be tried again in
    # double, after which the body goes back to single (Body.advance): the wedge's last,
    # easy steps of the hold are factorised in single precision
    if pardiso_available():
        solvers = {p: res.protocols[p]["linear_solver"] for p in ("plate", "wedge")}
        assert solvers == {"plate": "pardiso-single", "wedge": "pardiso-single"}
        assert res.protocols["plate"]["precision_fallbacks"] == 0


def test_the_wedge_runs_on_its_own_mesh_refined_along_its_edge(tmp_path):
    """``mesh3d.edge_h_mm``: the wedge's mesh has a band along its edge (z = 0, across the
    pad) and below the surface, the other protocols' mesh has none; a kept wedge field is
    written on its own mesh. The band is in the options' dict only when set, so the records
    made before it keep their keys."""
    from sim.geometry import build_pad_mesh
    from sim.output.result import write_vtu

    band = dataclasses.replace(OPTS_3D, mesh3d=dataclasses.replace(COARSE, edge_h_mm=0.3))
    assert "edge_h_mm" not in OPTS_3D.as_dict()["mesh3d"]
    assert band.as_dict()["mesh3d"]["edge_h_mm"] == 0.3
    assert options_from_dict(band.as_dict()) == dataclasses.replace(band, mesh=SimOptions().mesh)
    # the default mesh has a band; a 3D dict without one (the band off, or written before the
    # band existed: the kept plain segments' configs) reads back without it
    assert SimOptions(model=ModelOptions("3d")).as_dict()["mesh3d"]["edge_h_mm"] == 0.05
    assert options_from_dict(OPTS_3D.as_dict()).mesh3d == COARSE
    from sim.sweep import read_config

    plain = read_config(ROOT / "datasets" / "default3d_plain" / "seg_0-31")["options"]
    assert "edge_h_mm" not in plain["mesh3d"]
    assert options_from_dict(plain).mesh3d.edge_h_mm == 0.0
    design = homogeneous_design("silicone_gls40")
    wedge_disc = discretize(design, band, "wedge")
    other = discretize(design, band)
    assert other.n_free == discretize(design, OPTS_3D).n_free < wedge_disc.n_free
    # the band: the first element along z on the top at x = 0 about edge_h, not h_apex (1 mm)
    pmesh = build_pad_mesh(design.pad, (), band.mesh3d)
    top = pmesh.nodes[(pmesh.nodes[:, 0] == 0.0)]
    z = np.unique(np.round(top[np.isclose(top[:, 1], top[:, 1].max(), atol=0.3), 2], 9))
    assert 0.25 < 2 * z[1] < 0.4  # z[1]: the first element's midside node
    res = simulate(design, ("wedge",), band, keep_fields=True)
    assert res.ok, res.failures
    assert res.protocols["wedge"]["n_dofs"] == wedge_disc.n_free > res.n_dofs == other.n_free
    assert res.field_discretizations["wedge"].n_free == wedge_disc.n_free
    assert [p.name for p in write_vtu(res, tmp_path)] == ["deformed_wedge.vtu"]
    # the plain mesh does not resolve the flanks' contact and is too stiff there: the band
    # lowers the wedge's force and the profile's deflection towards the converged values
    # (studies/wedge3d_band.py: by 10-25 % on these sizes)
    plain = simulate(design, ("wedge",), OPTS_3D).metrics
    for name in ("wedge_peak_force_N", "profile_1s_defl_at_1mm_mm"):
        assert res.metrics[name] < 0.95 * plain[name], name


def test_the_options_dict_holds_what_the_model_reads():
    """A 2D run's options dict is the one stored before the 3D model existed (no ``model`` or
    ``mesh3d``: stored 2D records keep their keys); a 3D run's has no 2D ``mesh``; both read
    back to the same options."""
    two, three = SimOptions(), OPTS_3D
    assert {"model", "mesh3d"}.isdisjoint(two.as_dict()) and "mesh" in two.as_dict()
    assert "mesh" not in three.as_dict() and three.as_dict()["model"] == {"dimension": "3d"}
    assert options_from_dict(two.as_dict()) == two
    assert options_from_dict(three.as_dict()) == dataclasses.replace(three, mesh=two.mesh)
    assert metric_registry("2d") == METRICS and set(METRICS_3D) < set(metric_registry("3d"))


def test_a_bad_model_names_the_field():
    with pytest.raises(DesignError, match=r"model\.dimension: must be one of 2d, 3d"):
        apply_overrides(SimOptions(), {"model.dimension": "4d"})


def test_a_3d_design_needs_a_core_in_the_pad():
    """The layers must leave a core along the pad's half-length too (``PadGeometry``)."""
    table = {
        "geometry": {"half_length_mm": 3.0},
        "layers": [{"thickness_mm": 2.9, "material": "silicone_gls40"}, {"material": ELASTIC}],
    }
    design = design_from_dict(table)  # a valid 2D design: a = 5.84, b = 5.48
    with pytest.raises(DesignError, match="half_length"):
        discretize(design, OPTS_3D)


def test_the_pad_keys_round_trip_and_stay_out_of_2d_dicts():
    plain = design_from_dict({"layers": [{"material": "silicone_gls40"}]})
    assert set(plain.to_dict()["geometry"]) == {"half_width_mm", "height_mm", "exponent"}
    pad = design_from_dict(
        {
            "geometry": {"half_length_mm": 9.0, "length_exponent": 3.0},
            "layers": [{"material": "silicone_gls40"}],
        }
    )
    assert pad.pad.half_length_mm == 9.0 and pad.pad.length_exponent == 3.0
    assert design_from_dict(pad.to_dict()) == pad
    with pytest.raises(DesignError, match=r"geometry\.length_exponent: must be in \[1\.2, 8\.0\]"):
        design_from_dict({"geometry": {"length_exponent": 9}, "layers": [{"material": ELASTIC}]})


def test_the_3d_stall_rule_is_in_the_options_dict_only_when_not_the_default():
    """``newton.stall_rule_3d`` (solver 2.20, "stagnation"): the options' dict of either model
    leaves it out at its default, so the records made before it keep their keys; another rule
    is there and reads back; an unknown one names the rules."""
    three = SimOptions(model=ModelOptions("3d"))
    for opts in (SimOptions(), three):
        assert "stall_rule_3d" not in opts.as_dict()["newton"]
        assert options_from_dict(opts.as_dict()) == opts
    old = apply_overrides(three, {"newton.stall_rule_3d": "halving"})
    assert old.as_dict()["newton"]["stall_rule_3d"] == "halving"
    assert options_from_dict(old.as_dict()) == old
    with pytest.raises(DesignError, match=r"3d: the stall rule must be one of halving, "):
        apply_overrides(three, {"newton.stall_rule_3d": "never"})


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"model.dimension": "3d", "mesh.h_apex_mm": "0.1"}, r"mesh\.h_apex_mm: applies to the 2d"),
        ({"mesh3d.h_apex_mm": "0.5"}, r"mesh3d\.h_apex_mm: applies to the 3d model only"),
        ({"model.dimension": "3d", "tapping.length_mm": "5"}, r"tapping\.length_mm: applies to"),
        ({"newton.stall_rule_3d": "off"}, r"newton\.stall_rule_3d: applies to the 3d model only"),
        (
            {"model.dimension": "3d", "mesh3d.contact_fraction": "2"},
            r"contact_fraction: .*\(0, 1\]",
        ),
    ],
)
def test_an_option_of_the_other_model_is_refused(overrides, message):
    """A 2D-only option with the 3D model (or the reverse) is one error naming it, not a
    silent no-op; a 3D mesh option out of its range names its range."""
    with pytest.raises(DesignError, match=message):
        apply_overrides(SimOptions(), overrides)


def test_the_cli_simulates_in_3d_and_refuses_2d_options(tmp_path, capsys):
    """``fingertip simulate DESIGN --model 3d``: the 3D metrics in newtons of the whole pad;
    a 2D-only option with it is one line and exit 2."""
    from explore.cli import main

    design = tmp_path / "pad.toml"
    design.write_text('[geometry]\nhalf_length_mm = 9.0\n[[layers]]\nmaterial = "silicone_gls40"\n')
    coarse = ["--set", "mesh3d.h_apex_mm=1.0", "--set", "mesh3d.h_contact_mm=1.5",
              "--set", "mesh3d.h_max_mm=3", "--set", "mesh3d.grading=0.6"]  # fmt: skip
    assert main(["simulate", str(design), "--model", "3d", "--protocol", "plate", *coarse]) == 0
    out = capsys.readouterr().out
    assert "plate_force_at_1mm_N" in out and " x length " in out
    assert main(["simulate", str(design), "--model", "3d", "--set", "mesh.h_apex_mm=0.1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        "fingertip: error: mesh.h_apex_mm: applies to the 2d model only, not to --model 3d"
    ]


def test_a_3d_sweep_keys_and_tables_its_own_results(tmp_path):
    """A 3D record's key differs from the 2D one of the same design (and includes the pad as
    simulated); a 3D sweep's table has the contact patch columns, a 2D one has not."""
    from sim.design import load_space
    from sim.sweep import SweepStore, record_key, sample_points, table_header

    point = sample_points(load_space(), 1, 0)[0]
    assert record_key(point, SimOptions()) != record_key(point, OPTS_3D)
    assert set(METRICS_3D) <= set(table_header(["x"], "3d"))
    assert set(METRICS_3D).isdisjoint(table_header(["x"], "2d"))
    store = SweepStore(tmp_path)
    store.write(
        "k", {"status": "ok", "params": {"x": 1.0}, "metrics": {"contact_area_at_1N_mm2": 50.0}}
    )
    store.consolidate(["k"], ["x"], dimension="3d")
    header, row = (tmp_path / "table.csv").read_text().splitlines()[:2]
    assert row.split(",")[header.split(",").index("contact_area_at_1N_mm2")] == "50.0"


def test_the_3d_tapping_keeps_a_factorisation_per_loading_step(monkeypatch):
    """A viscoelastic pad tapped to its periodic state with one factorisation kept per loading
    step (``sim.protocols.loading.KEEP_STEP_FACTORS``, solver 2.15) and without (2.14's path):
    later taps' loading steps begin with their step's factorisation, and every tapping metric
    is the same to the periodic state's tolerance (1e-3)."""
    if not pardiso_available():
        pytest.skip("the kept factorisations live in PARDISO's slots")
    from sim.protocols import loading

    material = {**ELASTIC, "prony_g": [0.3], "prony_tau_s": [0.05]}
    design = design_from_dict({"layers": [{"material": material}]})
    tapping = dataclasses.replace(OPTS_3D.tapping, steps_loaded=16, steps_settle=16)
    options = dataclasses.replace(OPTS_3D, tapping=tapping)
    runs = {}
    for keep in (True, False):
        monkeypatch.setattr(loading, "KEEP_STEP_FACTORS", keep)
        runs[keep] = simulate(design, ("tapping",), options)
    kept, last = runs[True], runs[False]
    assert kept.ok and last.ok
    figures = kept.protocols["tapping"]
    assert figures["taps"] >= 3 and figures["step_factor_takes"] > 0
    assert figures["step_factors"] > 0 and "step_factor_takes" not in last.protocols["tapping"]
    # the sag (about 0.1 micrometre here) within 1e-3 of the displacement it is taken
    # from, as the periodic state's residual is
    scale = {"sag_mm": 1e-3 * last.metrics["disp_at_4N_mm"]}
    for name, value in last.metrics.items():
        if isinstance(value, float) and name.startswith(("disp", "hyst", "sag", "contact")):
            tol = scale.get(name, 1e-9)
            assert kept.metrics[name] == pytest.approx(value, rel=1e-3, abs=tol), name


def test_the_wedge_ramp_moves_its_edge_half_a_band_element_a_sub_step(monkeypatch):
    """The 3D wedge's ramp goes in sub-steps in which its edge travels at most
    ``WEDGE_BAND_TRAVEL`` (half) of the band's element size, from the first one on. An elastic
    pad under a frictionless wedge does not depend on the path to its state: the force at the
    end of the ramp is the one of the schedule's single step (``WEDGE_BAND_TRAVEL = 0``, as
    until solver 2.17) within Newton's tolerance."""
    from sim.protocols import loading

    design = design_from_dict({"layers": [{"material": ELASTIC}]})
    wedge = dataclasses.replace(OPTS_3D.wedge, depth_mm=0.3, ramp_steps=1, hold_s=1.0)
    band = dataclasses.replace(
        OPTS_3D, mesh3d=dataclasses.replace(COARSE, edge_h_mm=0.1), wedge=wedge
    )
    assert loading.WEDGE_BAND_TRAVEL == 0.5
    res = simulate(design, ("wedge",), band)
    assert res.ok, res.failures
    t = np.asarray(res.curves["wedge"]["time_s"])
    ramp = t[(t > 0.0) & (t <= wedge.ramp_s + 1e-9)]
    # 0.05 mm of the 0.3 mm ramp a sub-step: six of 1/6 s
    np.testing.assert_allclose(ramp, np.arange(1, 7) / 6.0, atol=1e-9)
    monkeypatch.setattr(loading, "WEDGE_BAND_TRAVEL", 0.0)
    schedule = simulate(design, ("wedge",), band)
    t_schedule = np.asarray(schedule.curves["wedge"]["time_s"])
    assert t_schedule[(t_schedule > 0.0) & (t_schedule <= wedge.ramp_s + 1e-9)][0] > 0.2
    peak = res.metrics["wedge_peak_force_N"]
    assert peak > 0.0
    # Newton stops at a residual of 1e-6 E0 a (NewtonOptions.rtol), a few 1e-5 of this
    # 0.04 N force (3e-5 apart here)
    assert schedule.metrics["wedge_peak_force_N"] == pytest.approx(peak, rel=2e-4)
