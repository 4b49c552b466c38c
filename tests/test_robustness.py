"""Large deformation, failure reporting, and option overrides."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import pytest
from sweep_fixtures import shipped_table_lines

from sim import Design, Layer, SimOptions, homogeneous_design, simulate
from sim.errors import DesignError
from sim.fe import NewtonOptions
from sim.materials import material_from_spec
from sim.options import apply_overrides, option_names


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "explore.cli", *args], capture_output=True, text=True, timeout=600
    )


def test_failed_protocol_is_recorded_not_raised():
    """A protocol that cannot converge comes back as a failure naming protocol and time."""
    opts = SimOptions(newton=NewtonOptions(max_iterations=1))
    res = simulate(homogeneous_design("polyurethane_74_45"), ["plate", "wedge"], opts)
    assert not res.ok
    assert {f.protocol for f in res.failures} == {"plate", "wedge"}
    for f in res.failures:
        assert 0.0 <= f.time_s < 1.0
        assert "convergence" in f.reason or "line search" in f.reason
    assert res.metrics["plate_force_at_1mm_N"] is None
    out = res.to_json()
    assert out["ok"] is False and out["plate_force_at_1mm_N"] is None
    json.dumps(out, allow_nan=False)  # valid JSON even with failures


def test_cli_reports_failure_with_exit_code_1():
    p = _cli(
        "simulate",
        "--material",
        "polyurethane_74_45",
        "--protocol",
        "plate",
        "--json",
        "--set",
        "newton.max_iterations=1",
    )
    assert p.returncode == 1
    assert json.loads(p.stdout)["ok"] is False
    lines = [line for line in p.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("fingertip: simulation failed: plate at t =")
    assert "Traceback" not in p.stderr


def test_overrides_reach_the_protocols():
    """tapping.peak_force_N = 3 N never reaches 4 N: that metric is undefined, not faked."""
    opts = apply_overrides(SimOptions(), {"tapping.peak_force_N": "3", "tapping.rest_s": "0.5"})
    assert opts.tapping.peak_force_N == 3.0 and opts.tapping.rest_s == 0.5
    res = simulate(homogeneous_design("silicone_gls40"), ["tapping"], opts)
    assert (
        res.metrics["disp_at_4N_mm"] is None
        or res.metrics["disp_at_4N_mm"] != res.metrics["disp_at_4N_mm"]
    )
    assert max(res.curves["tapping"]["force_N"]) == pytest.approx(3.0, rel=1e-6)
    short = simulate(
        homogeneous_design("silicone_gls40"),
        ["plate"],
        apply_overrides(SimOptions(), {"plate.depth_mm": "0.5"}),
    )
    assert short.to_json()["plate_force_at_1mm_N"] is None


@pytest.mark.parametrize(
    ("override", "field"),
    [
        ({"tapping.bogus": "1"}, "tapping.bogus"),
        ({"nosuch.x": "1"}, "nosuch.x"),
        ({"tapping.peak_force_N": "abc"}, "tapping.peak_force_N"),
        ({"plate.steps": "0"}, "plate.steps"),
        ({"wedge.hold_s": "-1"}, "wedge.hold_s"),
        ({"tapping.frequency_Hz": "nan"}, "tapping.frequency_Hz"),
    ],
)
def test_bad_overrides_name_the_option(override, field):
    with pytest.raises(DesignError) as exc:
        apply_overrides(SimOptions(), override)
    assert exc.value.field == field


def test_cli_bad_override_is_one_line_exit_2():
    p = _cli("simulate", "--material", "silicone_gls40", "--set", "tapping.peak_force=4")
    assert p.returncode == 2
    lines = [line for line in p.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "tapping.peak_force" in lines[0]


def test_option_names_cover_every_section():
    names = option_names()
    for section in ("mesh", "newton", "tapping", "plate", "wedge"):
        assert any(n.startswith(section + ".") for n in names)


@pytest.mark.slow
def test_human_like_soft_layered_design_solves_at_large_deformation():
    """A thin silicone skin over a very soft, very dissipative core: compresses more than half
    the pulp's height at 4 N and still solves all three protocols."""
    core = material_from_spec(
        {
            "model": "neo_hookean",
            "mu_MPa": 0.004,
            "nu": 0.45,
            "prony_g": [0.4, 0.3, 0.1],
            "prony_tau_s": [0.1, 1.0, 10.0],
        }
    )
    design = Design((Layer(material_from_spec("silicone_gls40"), 0.5), Layer(core)))
    # beyond the validity limits by design: the solver's robustness there is what is tested
    res = simulate(design, options=SimOptions().without_validity_stop())
    assert res.ok, res.failures
    assert res.metrics["disp_at_4N_mm"] > 0.5 * design.geometry.height_mm
    assert res.metrics["hysteresis_Nmm"] > 0.5
    for info in res.protocols.values():
        assert info["max_penetration_mm"] < 0.01


# ----------------------------------------------------------------------------- damaged sweeps
SHIPPED = Path(__file__).resolve().parents[1] / "surrogate" / "pretrained" / "default"


def _damaged_sweep(tmp_path: Path, damage: str) -> Path:
    """The first 40 designs of the shipped training table, damaged as ``damage`` says."""
    folder = tmp_path / "sweep"
    folder.mkdir()
    (folder / "config.json").write_text((SHIPPED / "config.json").read_text())
    lines = shipped_table_lines(41)
    if damage == "truncated":  # a copy cut off mid-line
        text = "".join(lines)
        text = text[: len(text) - len(lines[-1]) // 2]
    elif damage == "non-numeric":
        header = lines[0].rstrip("\n").split(",")
        cells = lines[7].rstrip("\n").split(",")
        cells[header.index("hysteresis_Nmm")] = "abc"
        lines[7] = ",".join(cells) + "\n"
        text = "".join(lines)
    elif damage == "binary":
        text = None
        (folder / "table.csv").write_bytes(b"\xff\xfe\x00" * 50)
    elif damage == "gzip-cut":  # a shipped (gzipped) table cut short
        import gzip

        text = None
        data = gzip.compress("".join(lines).encode(), mtime=0)
        (folder / "table.csv.gz").write_bytes(data[: len(data) // 2])
    else:
        raise AssertionError(damage)
    if text is not None:
        (folder / "table.csv").write_text(text)
    return folder


@pytest.mark.parametrize(
    ("damage", "words"),
    [
        ("truncated", "row 40 does not have the"),
        ("non-numeric", "row 7: hysteresis_Nmm: expected a number"),
        ("binary", "not UTF-8"),
        ("gzip-cut", "damaged gzip file"),
    ],
)
def test_train_on_a_damaged_table_is_one_line(tmp_path, damage, words):
    folder = _damaged_sweep(tmp_path, damage)
    p = _cli("train", str(folder), "--out", str(tmp_path / "model"), "--no-progress")
    assert p.returncode == 2, p.stderr
    assert "Traceback" not in p.stderr
    lines = [line for line in p.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("fingertip: error: ") and words in lines[0]
    assert not (tmp_path / "model").exists()


def test_the_undamaged_copy_reads(tmp_path):
    from surrogate import read_sweep

    folder = tmp_path / "sweep"
    folder.mkdir()
    (folder / "config.json").write_text((SHIPPED / "config.json").read_text())
    lines = shipped_table_lines(41)
    (folder / "table.csv").write_text("".join(lines))
    assert len(read_sweep(folder).points) == 40


# ----------------------------------------------------------------------------- training range
def test_a_design_on_the_space_bound_is_inside_the_training_range():
    """The shipped surrogate's samples stop just short of the space's bounds (within
    ``BOUND_REACH`` of the width): a design on the bound is not flagged, one farther off than
    the sample's edge gap is, with a range printed to enough digits to see why."""
    import math

    import numpy as np

    from surrogate import load_checkpoint
    from surrogate._encoding import BOUND_REACH, Encoder

    model = load_checkpoint(SHIPPED / "model.safetensors", allow_solver_mismatch=True)
    space = model.space
    base = space.point(np.full(len(space.sampled), 0.5))
    lo, _ = model.encoder.ranges["geometry.half_width_mm"]
    p = space["geometry.half_width_mm"]
    assert p.low < lo < p.low + BOUND_REACH * (p.high - p.low)  # short of the bound, in reach
    pred = model.predict([{**base, "geometry.half_width_mm": p.low}, base])
    assert pred.in_domain.tolist() == [True, True], pred.reasons
    # a training range that stops well short of the bound keeps its edge (a few designs)
    far = p.low + 4 * BOUND_REACH * (p.high - p.low)
    enc = Encoder(space, {**model.encoder.ranges, p.name: (far, 6.5)}, model.encoder.seen)
    coded = enc.encode([{**base, p.name: p.low}, {**base, p.name: far}])
    assert coded.in_domain.tolist() == [False, True]
    assert f"outside the training range [{far:.6g}, 6.5]" in coded.reasons[0]
    assert not math.isclose(far, p.low)


def test_newton_abandons_a_stalled_step_but_never_a_converging_one():
    from sim.fe.solver import NewtonOptions, _stalled

    opts = NewtonOptions()  # not halved over 6 iterations, judged from iteration 8
    quadratic = [1.0, 1e-1, 1e-3, 1e-7]
    creeping = [1.0, 0.9, 0.85, 0.8, 0.78, 0.75, 0.7, 0.68]
    slow_but_steady = [1.0 * 0.85**k for k in range(20)]  # halves every ~4.3 iterations
    assert not any(_stalled(quadratic[: k + 1], opts) for k in range(len(quadratic)))
    assert not any(_stalled(creeping[: k + 1], opts) for k in range(7))
    assert _stalled(creeping, opts)
    assert not any(_stalled(slow_but_steady[: k + 1], opts) for k in range(20))
    never = dataclasses.replace(opts, stall_window=0)  # 0: the rule off
    assert not any(_stalled(creeping[: k + 1], never) for k in range(len(creeping)))


#: Newton's residuals (/ its tolerance) per iteration in 3D steps pursued without a stall rule
#: (``--set newton.stall_rule_3d=off``; the step logs of docs/fe_speed.md, "The stall rule in
#: 3D"). Two converge after their residual rose for a few iterations: a tapping step of a
#: two-layer Ecoflex 00-10 pad (0.4506 -> 0.5 s), which "halving" abandoned, and its halves down
#: to 1e-4 s, so that the design failed; and a plate step of default-space design 3. Two fail at
#: the 20-iteration limit: design 3's tapping (a plateau after a jump) and design 7's wedge
#: (a slow creep).
RISES_THEN_CONVERGES = (
    [3.7e4, 1.4e2, 3.6e2, 1.2e3, 4.1e3, 3.6e3, 6.8e3, 2.9e3, 3.9e3, 3.4e3, 7.3e2, 5.9e2, 77, 13,
     3.1],
    [3.1e6, 2.7e4, 3.7e4, 8.7e4, 8.6e4, 8.3e4, 5.9e4, 3.3e4, 1.8e4, 4.9e3, 3.3e3, 6.6e2, 1.2e2, 48,
     11, 4.6, 1.1],
)  # fmt: skip
NEVER_CONVERGES = (
    [1e7, 7.1e4, 5.3e4, 5e4, 2.6e4, 2.3e4, 3.4e6, 3.3e6, 3.3e6, 3e6, 3e6, 4.6e6, 4.6e6, 4.5e6,
     4.4e6, 4.1e6, 4.1e6, 4e6, 3.9e6, 3.9e6],
    [2.6e3, 1.5e3, 3.3e5, 3.1e5, 3.1e5, 3.1e5, 3e5, 2.4e5, 2.3e5, 2.2e5, 2.2e5, 2.2e5, 1.9e5,
     1.9e5, 1.6e5, 1.6e5, 1.5e5, 1.4e5, 1.4e5, 1.4e5],
)  # fmt: skip


def test_the_3d_model_pursues_a_step_whose_residual_rises_before_it_falls():
    """Solver 2.20: the 3D model abandons a step whose residual stagnates ("stagnation"), not
    one whose residual rises for a few iterations and then falls; the 2D model keeps
    "halving", which abandons both (``_stalled``)."""
    from sim.fe.solver import NewtonOptions, _stalled

    def stops(norms, opts, dim):
        return next((k for k in range(1, len(norms) + 1) if _stalled(norms[:k], opts, dim)), None)

    opts = NewtonOptions()
    for norms in RISES_THEN_CONVERGES:
        assert stops(norms, opts, 2) == 8  # 2D: not halved over 6 iterations
        assert stops(norms, opts, 3) is None
    # the plateau within a factor 2 over 7 residuals, after the jump at iteration 7; the
    # creep within a factor 2 from its jump at iteration 3
    assert [stops(n, opts, 3) for n in NEVER_CONVERGES] == [13, 9]
    assert [stops(n, opts, 2) for n in NEVER_CONVERGES] == [8, 8]
    halving = dataclasses.replace(opts, stall_rule_3d="halving")  # solver 2.19's 3D rule
    assert [stops(n, halving, 3) for n in RISES_THEN_CONVERGES] == [8, 8]
    off = dataclasses.replace(opts, stall_rule_3d="off")
    assert [stops(n, off, 3) for n in (*RISES_THEN_CONVERGES, *NEVER_CONVERGES)] == [None] * 4
    # slow, not flat: not halved over 12 iterations
    slow = [1.0 * 0.96**k for k in range(20)]  # within a factor 2 over 7, at iteration 8
    assert stops(slow, opts, 3) == 8
    bumpy = [1.0, 0.4, 0.9, 0.35, 0.85, 0.3, 0.8, 0.3, 0.75, 0.3, 0.7, 0.3, 0.65, 0.3, 0.6]
    assert stops(bumpy, opts, 3) == 14  # never flat, but 0.3 has not halved 0.4 in 12 iterations


# ----------------------------------------------------------------------------- issue 31, item 4
def test_torch_threads_are_the_cores_left_by_the_fe_workers(monkeypatch):
    """torch's threads for a training: the cores of the process's affinity less the FE workers
    running beside it, at least 1, at most the cap (1 by default: the same bits whatever the
    machine)."""
    import os

    from surrogate import _threads

    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 2, 5, 7}, raising=False)
    assert _threads.torch_threads(0, most=8) == 4
    assert _threads.torch_threads(1, most=8) == 3
    assert _threads.torch_threads(3, most=8) == 1
    assert _threads.torch_threads(9, most=8) == 1  # never fewer than one
    assert _threads.torch_threads(0, most=2) == 2
    assert _threads.torch_threads(0, cores=16, most=8) == 8
    assert _threads.MAX_TRAINING_THREADS == 1 and _threads.torch_threads(0) == 1


def test_retraining_runs_on_the_decided_threads_and_gives_the_callers_back(monkeypatch):
    """``explore._retrain.retrain`` trains on ``torch_threads(fe_workers)`` threads (measured
    inside the training), records them in the checkpoint's header and sets the caller's count
    again afterwards."""
    import os

    import torch

    import surrogate._threads
    import surrogate._train
    from explore._retrain import retrain
    from surrogate import load_checkpoint

    seen = []
    real = surrogate._train._train

    def spy(*args, **kwargs):
        seen.append(torch.get_num_threads())
        return real(*args, **kwargs)

    monkeypatch.setattr(surrogate._train, "_train", spy)
    shipped = load_checkpoint(SHIPPED / "model.safetensors", allow_solver_mismatch=True)
    before = torch.get_num_threads()
    try:
        torch.set_num_threads(2)
        model = retrain(shipped, SHIPPED, [], epochs=1, seed=0, replay=8, fe_workers=1)
        assert seen == [1] and model.header["training"]["torch_threads"] == 1
        assert torch.get_num_threads() == 2
        # a higher cap: the cores of the affinity (6) less the one FE worker beside it
        monkeypatch.setattr(surrogate._threads, "MAX_TRAINING_THREADS", 8)
        monkeypatch.setattr(os, "sched_getaffinity", lambda pid: set(range(6)), raising=False)
        model = retrain(shipped, SHIPPED, [], epochs=1, seed=0, replay=8, fe_workers=1)
        assert seen == [1, 5] and model.header["training"]["torch_threads"] == 5
        assert torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(before)


# ----------------------------------------------------------------------------- issue 31, item 5
def test_the_seed_range_is_the_samplers_and_one_line_outside_it():
    """[0, 2**32 - 1]: Optuna's samplers take no more (numpy's RandomState), nothing takes a
    negative seed; a search's last round (seed + rounds - 1) must be inside too."""
    import optuna

    from sim.errors import SEED_MAX, check_seed

    assert SEED_MAX == 2**32 - 1
    optuna.samplers.TPESampler(seed=SEED_MAX)  # the largest seed is usable
    with pytest.raises(ValueError):
        optuna.samplers.TPESampler(seed=SEED_MAX + 1)
    assert check_seed(0) == 0 and check_seed(SEED_MAX) == SEED_MAX
    for bad in (-1, SEED_MAX + 1, 1.5, True, "3"):
        with pytest.raises(DesignError) as exc:
            check_seed(bad)
        assert exc.value.field == "--seed" and "[0, 4294967295]" in exc.value.message
    assert check_seed(SEED_MAX - 2, uses=3) == SEED_MAX - 2
    with pytest.raises(DesignError, match=r"\[0, 4294967293\]"):
        check_seed(SEED_MAX - 1, uses=3)


def test_every_catalogue_entry_and_space_bound_is_inside_the_moduli_range():
    """The physical moduli range (``MU0_MIN_MPA``-``MU0_MAX_MPA``) refuses none of the shipped
    materials (each read again through the validation of a user's table) nor any shipped
    design space (its families' mu0 bounds), and the families' limit is that range."""
    import tomllib

    from sim.design import FAMILIES, load_space
    from sim.materials import CATALOGUE, CATALOGUE_PATH
    from sim.materials._validate import MU0_MAX_MPA, MU0_MIN_MPA

    tables = tomllib.loads(CATALOGUE_PATH.read_text())
    assert set(tables) == set(CATALOGUE) and len(CATALOGUE) >= 20
    for name, table in tables.items():
        mat = material_from_spec(table, f"materials.{name}")
        assert MU0_MIN_MPA <= mat.law.initial_shear_modulus_MPa <= MU0_MAX_MPA, name
        assert mat.drucker_limit_log_strain is None, name  # every shipped fit is stable
    spaces = sorted((Path(__file__).resolve().parents[1] / "sim" / "data").glob("*_space.toml"))
    assert len(spaces) >= 2
    for path in spaces:
        space = load_space(path)
        for p in space.parameters:
            if p.name.endswith(".mu0_MPa") and p.kind == "float":
                assert MU0_MIN_MPA <= p.low <= p.high <= MU0_MAX_MPA, (path.name, p.name)
    for fam in FAMILIES.values():
        assert fam.limits["mu0_MPa"][:2] == (MU0_MIN_MPA, MU0_MAX_MPA)


@pytest.mark.parametrize(
    ("table", "field", "words"),
    [
        ({"model": "neo_hookean", "mu_MPa": 1e12, "nu": 0.3}, "mu_MPa", "[0.0001, 1000] MPa"),
        ({"model": "neo_hookean", "mu_MPa": 1e-12, "nu": 0.3}, "mu_MPa", "[0.0001, 1000] MPa"),
        ({"model": "yeoh", "c10_MPa": 1e4, "nu": 0.4}, "c10_MPa", "[0.0001, 1000] MPa"),
        (  # the sum is soft, one term is not
            {"model": "ogden", "mu_MPa": [2000.0, -1999.9], "alpha": [2.0, -2.0], "nu": 0.4},
            "mu_MPa",
            "mu_MPa[0] = 2000 MPa is beyond +-1000 MPa",
        ),
        (
            {"model": "hyperfoam", "mu_MPa": [5e-5], "alpha": [2.0], "nu": 0.3},
            "mu_MPa",
            "initial shear modulus 5e-05 MPa is outside",
        ),
    ],
)
def test_moduli_outside_the_physical_range_name_the_field(table, field, words):
    with pytest.raises(DesignError) as exc:
        material_from_spec(table, "layers[0].material")
    assert exc.value.field == f"layers[0].material.{field}"
    assert words in exc.value.message


def _fitted(planar: list[float], uniaxial: tuple[float, float] = (-0.8, 2.0)) -> dict:
    """A gel as ``fingertip fit-material`` writes it, Drucker-stable in the given ranges."""
    return {
        "model": "ogden", "mu_MPa": [0.05], "alpha": [3.0], "nu": 0.499, "name": "my_gel",
        "provenance": {
            "method": "fingertip fit-material",
            "drucker_stable_uniaxial": list(uniaxial),
            "drucker_stable_biaxial": [-0.8, 2.0],
            "drucker_stable_planar": planar,
        },
    }  # fmt: skip


def test_a_fitted_materials_drucker_limit_is_the_first_unstable_strain():
    """The compressive log strain at the first end of a stable range cut short by an
    instability (the smallest principal stretch of that test); none when nothing was cut."""
    import math

    assert material_from_spec(_fitted([-0.8, 2.0])).drucker_limit_log_strain is None
    cut = material_from_spec(_fitted([-0.1, 2.0]))
    assert cut.drucker_limit_log_strain == pytest.approx(-math.log(0.9))
    # uniaxial tension to 100 %: lateral stretch 2 ** -0.5 (incompressible), the smaller limit
    both = material_from_spec(_fitted([-0.5, 2.0], uniaxial=(-0.8, 1.0)))
    assert both.drucker_limit_log_strain == pytest.approx(0.5 * math.log(2.0))
    # the entry's table is unchanged: a design's record key does not move
    table = _fitted([-0.1, 2.0])
    assert cut.to_dict() == {**table, "moduli": "long_term"}


@pytest.mark.parametrize(
    ("key", "value"),
    [
        ("drucker_stable_planar", [0.1, 2.0]),
        ("drucker_stable_planar", [-1.0, 2.0]),
        ("drucker_stable_planar", "everywhere"),
        ("drucker_stable_shear", [-0.8, 2.0]),
    ],
)
def test_a_malformed_drucker_range_is_refused_naming_it(key, value):
    table = _fitted([-0.8, 2.0])
    table["provenance"] = {**table["provenance"], key: value}
    with pytest.raises(DesignError) as exc:
        material_from_spec(table, "layers[0].material")
    assert exc.value.field == f"layers[0].material.provenance.{key}"


def test_a_layer_strained_past_its_drucker_limit_is_flagged(tmp_path, capsys):
    """The FE result of a design whose material's fit is unstable beyond 0.105 (planar
    compression to -10 %) carries a validity violation naming the layer, the plate stops
    there, and ``fingertip simulate`` warns; the same material stable everywhere runs as
    before, without the new summary key."""
    import explore.cli

    design = Design((Layer(material_from_spec(_fitted([-0.1, 2.0]))),))
    res = simulate(design, ["plate"])
    validity = res.validity
    assert not validity["valid"] and "plate" in res.stopped
    (violation,) = validity["violations"]
    assert violation.startswith("layer 0 compressive log strain (Drucker-stable fit) 0.1")
    summary = validity["protocols"]["plate"]
    assert summary["drucker_stable_log_strain_by_layer"] == [pytest.approx(0.10536, abs=1e-5)]
    ok = simulate(Design((Layer(material_from_spec(_fitted([-0.8, 2.0]))),)), ["plate"])
    assert ok.validity["valid"] and ok.metrics["plate_force_at_1mm_N"] is not None
    assert "drucker_stable_log_strain_by_layer" not in ok.validity["protocols"]["plate"]
    # the command line: a warning naming the layer and the fit, exit code 0 (a result)
    path = tmp_path / "design.toml"
    path.write_text(
        '[[layers]]\n[layers.material]\nmodel = "ogden"\nmu_MPa = [0.05]\nalpha = [3.0]\n'
        "nu = 0.499\n[layers.material.provenance]\ndrucker_stable_planar = [-0.1, 2.0]\n"
    )
    assert explore.cli.main(["simulate", str(path), "--protocol", "plate"]) == 0
    warnings = [w for w in capsys.readouterr().err.splitlines() if "Drucker" in w]
    assert len(warnings) == 1 and warnings[0].startswith("warning: plate: layer 0 ")
    assert "fingertip fit-material found the fitted law Drucker-unstable there" in warnings[0]
