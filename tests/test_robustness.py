"""Large deformation, failure reporting, and option overrides."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from sweep_fixtures import shipped_table_lines

from sim import Design, Layer, SimOptions, homogeneous_design, simulate
from sim.errors import DesignError
from sim.materials import material_from_spec
from sim.options import apply_overrides, option_names
from sim.solver import NewtonOptions


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
    from sim.solver import NewtonOptions, _stalled

    opts = NewtonOptions()  # not halved over 6 iterations, judged from iteration 8
    quadratic = [1.0, 1e-1, 1e-3, 1e-7]
    creeping = [1.0, 0.9, 0.85, 0.8, 0.78, 0.75, 0.7, 0.68]
    slow_but_steady = [1.0 * 0.85**k for k in range(20)]  # halves every ~4.3 iterations
    assert not any(_stalled(quadratic[: k + 1], opts) for k in range(len(quadratic)))
    assert not any(_stalled(creeping[: k + 1], opts) for k in range(7))
    assert _stalled(creeping, opts)
    assert not any(_stalled(slow_but_steady[: k + 1], opts) for k in range(20))
