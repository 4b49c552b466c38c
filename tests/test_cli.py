"""The ``fingertip`` command line (explore.cli).

Contract: invalid input prints ONE line ``fingertip: error: <field>: <message>`` on stderr,
exits with 2 and never shows a traceback; success exits with 0. Real simulations use
``--protocol plate`` only (well under a second each) to keep the file fast.

The full list of invalid inputs runs in-process through ``main()`` (the same code path, without
paying the interpreter start-up per case); a representative subset, the JSON output, the run
folder and the installed console script run as real subprocesses.
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from sweep_fixtures import shipped_table_lines

import explore.cli
import sim
from explore.cli import main
from sim import METRICS, SOLVER_VERSION, design_from_dict, homogeneous_design

REPO = Path(explore.cli.__file__).resolve().parents[1]
PLATE_METRICS = [name for name, (proto, _, _) in METRICS.items() if proto == "plate"]
OTHER_METRICS = [name for name, (proto, _, _) in METRICS.items() if proto != "plate"]
ERROR_PREFIX = "fingertip: error: "

TWO_LAYER_TOML = """\
[[layers]]                    # outermost first
thickness_mm = 1.0
material = "silicone_gls40"
[[layers]]                    # the last layer fills the rest
material = "polyurethane_74_45"
"""


def _env() -> dict[str, str]:
    return {**os.environ, "MPLBACKEND": "Agg"}


def run_cli(*args: str | Path, cwd: Path, exe: list[str] | None = None):
    cmd = [*(exe or [sys.executable, "-m", "explore.cli"]), *map(str, args)]
    return subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=300, env=_env())


def assert_one_line_error(stderr: str, field: str) -> str:
    assert "Traceback" not in stderr
    lines = stderr.splitlines()
    assert len(lines) == 1, stderr
    line = lines[0]
    assert line.startswith(ERROR_PREFIX), line
    assert field in line, line
    return line


def parse_one_json_object(stdout: str) -> dict:
    def reject(constant: str) -> float:
        raise AssertionError(f"non-standard JSON constant {constant} on stdout")

    decoder = json.JSONDecoder(parse_constant=reject)
    text = stdout.lstrip()
    obj, end = decoder.raw_decode(text)
    assert text[end:].strip() == "", f"more than one JSON value on stdout: {text[end:][:200]!r}"
    assert isinstance(obj, dict)
    return obj


def metric_from_text(stdout: str, name: str) -> float:
    match = re.search(rf"^{name}\s+([-+0-9.eE]+) N$", stdout, flags=re.MULTILINE)
    assert match, f"no line for {name} in:\n{stdout}"
    return float(match.group(1))


def write(tmp_path: Path, text: str, name: str = "design.toml") -> Path:
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


# --- invalid input: one line on stderr naming the field, exit 2, no traceback -------------------
NU_TOO_HIGH = """\
[[layers]]
[layers.material]
model = "neo_hookean"
mu_MPa = 0.1
nu = 0.5
"""

INVALID_FILES: dict[str, tuple[str, str]] = {
    "unknown_material": ('[[layers]]\nmaterial = "silicone_gls41"\n', "layers[0].material"),
    "nu_half": (NU_TOO_HIGH, "layers[0].material.nu"),
    "nu_above_half_in_core": (
        TWO_LAYER_TOML.replace(
            'material = "polyurethane_74_45"',
            '[layers.material]\nmodel = "yeoh"\nc10_MPa = 0.05\nnu = 0.55',
        ),
        "layers[1].material.nu",
    ),
    "mu_zero": (
        NU_TOO_HIGH.replace("0.5", "0.3").replace("0.1", "0.0"),
        "layers[0].material.mu_MPa",
    ),
    "mu_negative_hyperfoam": (
        '[[layers]]\n[layers.material]\nmodel = "hyperfoam"\nmu_MPa = [-0.1]\nalpha = [2.0]\n'
        "nu = 0.3\n",
        "layers[0].material.mu_MPa",
    ),
    "prony_sum_one": (
        '[[layers]]\n[layers.material]\nmodel = "neo_hookean"\nmu_MPa = 0.1\nnu = 0.3\n'
        "prony_g = [0.6, 0.4]\nprony_tau_s = [1.0, 2.0]\n",
        "layers[0].material.prony_g",
    ),
    "layer_as_thick_as_the_body": (
        TWO_LAYER_TOML.replace("thickness_mm = 1.0", "thickness_mm = 5.48"),
        "thickness_mm",
    ),
    "layers_leave_less_than_the_core": (
        TWO_LAYER_TOML.replace("thickness_mm = 1.0", "thickness_mm = 4.99"),
        "thickness_mm",
    ),
    "malformed_toml": ('[[layers]\nmaterial = "silicone_gls40"\n', "DESIGN"),
    "malformed_value": ("[[layers]]\nmaterial = silicone_gls40\n", "DESIGN"),
    "unknown_top_level_key": ('color = "red"\n[[layers]]\nmaterial = "silicone_gls40"\n', "color"),
    "unknown_geometry_key": (
        '[geometry]\nradius_mm = 5.0\n[[layers]]\nmaterial = "silicone_gls40"\n',
        "geometry.radius_mm",
    ),
    "unknown_layer_key": (
        '[[layers]]\nthickness = 1.0\nmaterial = "silicone_gls40"\n',
        "layers[0].thickness",
    ),
    "unknown_material_key": (
        NU_TOO_HIGH.replace("nu = 0.5", "nu = 0.3\nmu = 0.1"),
        "layers[0].material.mu",
    ),
    "thickness_on_the_last_layer": (
        TWO_LAYER_TOML + "thickness_mm = 2.0\n",
        "layers[1].thickness_mm",
    ),
    "zero_layers": ("layers = []\n", "layers"),
    "no_layers_at_all": ("[geometry]\nexponent = 2.0\n", "layers"),
    "four_layers": (
        '[[layers]]\nthickness_mm = 0.5\nmaterial = "silicone_gls40"\n' * 3
        + '[[layers]]\nmaterial = "polyurethane_74_45"\n',
        "layers",
    ),
    "exponent_out_of_range": (
        '[geometry]\nexponent = 9.0\n[[layers]]\nmaterial = "silicone_gls40"\n',
        "geometry.exponent",
    ),
    "half_width_out_of_range": (
        '[geometry]\nhalf_width_mm = 0.5\n[[layers]]\nmaterial = "silicone_gls40"\n',
        "geometry.half_width_mm",
    ),
    "height_out_of_range": (
        '[geometry]\nheight_mm = 60.0\n[[layers]]\nmaterial = "silicone_gls40"\n',
        "geometry.height_mm",
    ),
    "thickness_below_min": (
        TWO_LAYER_TOML.replace("thickness_mm = 1.0", "thickness_mm = 0.01"),
        "layers[0].thickness_mm",
    ),
    # physical moduli only (issue 31: mu_MPa = 1e12 ran, a plate force of 9.97e13 N)
    "mu_far_too_stiff": (
        NU_TOO_HIGH.replace("0.5", "0.3").replace("0.1", "1e12"),
        "layers[0].material.mu_MPa",
    ),
    "mu_far_too_soft": (
        NU_TOO_HIGH.replace("0.5", "0.3").replace("0.1", "1e-12"),
        "layers[0].material.mu_MPa",
    ),
}

# A representative subset that also runs as a real subprocess.
SUBPROCESS_CASES = [
    "nu_half",
    "malformed_toml",
    "unknown_material",
    "four_layers",
    "mu_far_too_stiff",
]


@pytest.mark.parametrize("case", list(INVALID_FILES))
def test_invalid_design_file_in_process(
    case: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text, field = INVALID_FILES[case]
    path = write(tmp_path, text)
    code = main(["simulate", str(path), "--protocol", "plate"])
    out, err = capsys.readouterr()
    assert code == 2
    assert out == ""
    assert_one_line_error(err, field)


@pytest.mark.parametrize("case", SUBPROCESS_CASES)
def test_invalid_design_file_subprocess(case: str, tmp_path: Path) -> None:
    text, field = INVALID_FILES[case]
    write(tmp_path, text)
    res = run_cli("simulate", "design.toml", "--protocol", "plate", cwd=tmp_path)
    assert res.returncode == 2
    assert res.stdout == ""
    assert_one_line_error(res.stderr, field)


def test_nu_error_line_is_clear(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write(tmp_path, NU_TOO_HIGH)
    assert main(["simulate", str(path)]) == 2
    line = assert_one_line_error(capsys.readouterr().err, "layers[0].material.nu")
    assert line.startswith(f"{ERROR_PREFIX}layers[0].material.nu: ")
    assert "0.5" in line


def test_missing_design_file(tmp_path: Path) -> None:
    res = run_cli("simulate", "missing.toml", "--protocol", "plate", cwd=tmp_path)
    assert res.returncode == 2
    assert res.stdout == ""
    line = assert_one_line_error(res.stderr, "missing.toml")
    assert "DESIGN" in line


def test_design_file_not_utf8(tmp_path: Path) -> None:
    (tmp_path / "design.toml").write_bytes(b'[[layers]]\nmaterial = "silicone_gls40" # caf\xe9\n')
    res = run_cli("simulate", "design.toml", "--protocol", "plate", cwd=tmp_path)
    assert res.returncode == 2
    assert_one_line_error(res.stderr, "DESIGN")


def test_design_path_is_a_directory(tmp_path: Path) -> None:
    (tmp_path / "designs").mkdir()
    res = run_cli("simulate", "designs", "--protocol", "plate", cwd=tmp_path)
    assert res.returncode == 2
    assert_one_line_error(res.stderr, "designs")


def test_nan_thickness(tmp_path: Path) -> None:
    write(tmp_path, TWO_LAYER_TOML.replace("thickness_mm = 1.0", "thickness_mm = nan"))
    res = run_cli("simulate", "design.toml", "--protocol", "plate", cwd=tmp_path)
    assert res.returncode == 2
    assert_one_line_error(res.stderr, "layers[0].thickness_mm")


def test_boolean_thickness(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write(tmp_path, TWO_LAYER_TOML.replace("thickness_mm = 1.0", "thickness_mm = true"))
    # Checked on load_design first so that the bug costs no simulation here.
    with pytest.raises(sim.DesignError):
        sim.load_design(path)
    assert main(["simulate", str(path), "--protocol", "plate"]) == 2
    assert_one_line_error(capsys.readouterr().err, "layers[0].thickness_mm")


def test_unknown_material_option(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["simulate", "--material", "rubber", "--protocol", "plate"]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    line = assert_one_line_error(err, "material")
    assert "rubber" in line
    assert "silicone_gls40" in line  # lists what is known


def test_design_and_material_together(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write(tmp_path, TWO_LAYER_TOML)
    assert main(["simulate", str(path), "--material", "silicone_gls40"]) == 2
    assert_one_line_error(capsys.readouterr().err, "--material")


def test_neither_design_nor_material(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["simulate", "--protocol", "plate"]) == 2
    assert_one_line_error(capsys.readouterr().err, "DESIGN.toml")


def test_unknown_protocol_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main(["simulate", "--material", "silicone_gls40", "--protocol", "poke"])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert "--protocol" in err
    assert "poke" in err


# --- --out refuses an existing non-empty folder before computing ---------------------------------
def test_out_existing_non_empty_folder_subprocess(tmp_path: Path) -> None:
    out = tmp_path / "run"
    out.mkdir()
    (out / "keep.txt").write_text("earlier results")
    res = run_cli(
        "simulate",
        "--material",
        "silicone_gls40",
        "--protocol",
        "plate",
        "--out",
        "run",
        cwd=tmp_path,
    )
    assert res.returncode == 2
    assert res.stdout == ""
    assert_one_line_error(res.stderr, "run")
    assert "not empty" in res.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]  # no temporary folder left
    assert [p.name for p in out.iterdir()] == ["keep.txt"]
    assert (out / "keep.txt").read_text() == "earlier results"


@pytest.mark.parametrize("kind", ["non_empty_folder", "file"])
def test_out_is_checked_before_any_computing(
    kind: str,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    calls: list[object] = []

    def fake_simulate(*args: object, **kwargs: object) -> None:
        calls.append(args)
        raise AssertionError("simulate must not run when --out is unusable")

    monkeypatch.setattr(explore.cli, "simulate", fake_simulate)
    out = tmp_path / "run"
    if kind == "file":
        out.write_text("x")
    else:
        out.mkdir()
        (out / "result.json").write_text("{}")
    path = write(tmp_path, TWO_LAYER_TOML)
    code = main(["simulate", str(path), "--protocol", "all", "--out", str(out)])
    assert code == 2
    assert calls == []
    assert_one_line_error(capsys.readouterr().err, str(out))


# --- real simulations ----------------------------------------------------------------------------
def test_an_elastic_design_s_hysteresis_is_shown_as_0_never_negative(capsys) -> None:
    """Issue 31, item 6a: an elastic design dissipates nothing; its FE loop area is the noise
    of the solver's tolerances, of either sign (-2.8e-05 N mm was printed). Below the
    resolution those tolerances give (``sim.protocols.loading.hysteresis_resolution_Nmm``) it is
    shown as 0, in `fingertip simulate` and in the report; a larger value is shown as it is."""
    from explore._report import _answer_rows
    from sim.design import load_targets
    from sim.options import SimOptions
    from sim.protocols import hysteresis_resolution_Nmm, shown_hysteresis

    design = homogeneous_design("dragon_skin_30_marechal")  # no relaxation: elastic
    metrics = {"hysteresis_Nmm": -2.8e-05, "disp_at_4N_from_touch_mm": 0.69}
    resolution = hysteresis_resolution_Nmm(design, metrics)
    assert 2.8e-05 < resolution < 1e-3
    assert shown_hysteresis(metrics, design) == 0.0
    assert shown_hysteresis(metrics, design.to_dict()) == 0.0  # the design-file form
    assert shown_hysteresis({**metrics, "hysteresis_Nmm": -0.01}, design) == 0.0  # never < 0
    assert shown_hysteresis({**metrics, "hysteresis_Nmm": 2 * resolution}, design) == 2 * resolution
    assert shown_hysteresis({**metrics, "hysteresis_Nmm": None}, design) is None
    answer = {"design": design.to_dict(), "fe_metrics": metrics}
    (row,) = [r for r in _answer_rows(answer, load_targets(), 0.05, SimOptions())
              if r.startswith("| `hysteresis_Nmm`")]  # fmt: skip
    assert row.split(" | ")[2] == "0"
    assert main(["simulate", "--material", "dragon_skin_30_marechal", "--protocol", "tapping"]) == 0
    out = capsys.readouterr().out
    (line,) = [x for x in out.splitlines() if x.startswith("hysteresis_Nmm")]
    assert line.split()[1:] == ["0.0000", "N", "mm"]  # was -0.0000 (FE: -4.5e-06 N mm)


@pytest.fixture(scope="module")
def workdir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("cli")


@pytest.fixture(scope="module")
def pu_json(workdir: Path) -> dict:
    res = run_cli(
        "simulate",
        "--material",
        "polyurethane_74_45",
        "--protocol",
        "plate",
        "--json",
        cwd=workdir,
    )
    assert res.returncode == 0, res.stderr
    assert "Traceback" not in res.stderr
    return parse_one_json_object(res.stdout)


@pytest.fixture(scope="module")
def pu_run(workdir: Path) -> tuple[subprocess.CompletedProcess, Path]:
    out = workdir / "runs" / "pu_plate"  # parent folders are created
    res = run_cli(
        "simulate",
        "--material",
        "polyurethane_74_45",
        "--protocol",
        "plate",
        "--out",
        out,
        cwd=workdir,
    )
    return res, out


def test_json_output(pu_json: dict) -> None:
    force = pu_json["plate_force_at_1mm_N"]
    assert isinstance(force, float)
    assert 0.0 < force < 1000.0
    assert pu_json["ok"] is True
    assert pu_json["failures"] == []
    assert pu_json["solver_version"] == SOLVER_VERSION
    # only the chosen protocol's metrics and curves
    assert all(name not in pu_json for name in OTHER_METRICS)
    assert set(pu_json["curves"]) == {"plate"}
    assert set(pu_json["protocols"]) == {"plate"}
    assert isinstance(pu_json["n_dofs"], int)
    assert pu_json["n_dofs"] > 0


def test_json_plate_curve(pu_json: dict) -> None:
    curve = pu_json["curves"]["plate"]
    disp, force = curve["displacement_mm"], curve["force_N"]
    assert isinstance(disp, list)
    assert isinstance(force, list)
    assert len(disp) == len(force) >= 5
    assert all(isinstance(x, float) for x in disp + force)
    assert disp[0] == pytest.approx(0.0, abs=1e-12)
    assert disp[-1] == pytest.approx(1.0, abs=1e-9)  # indentation to 1 mm
    assert np.all(np.diff(disp) > 0)
    assert force[0] == pytest.approx(0.0, abs=1e-9)
    assert np.all(np.diff(force) > 0)  # stiffens monotonically under compression
    # the metric is the curve's force at 1 mm
    at_1mm = float(np.interp(1.0, disp, force))
    assert pu_json["plate_force_at_1mm_N"] == pytest.approx(at_1mm, rel=1e-9)


def test_json_design(pu_json: dict) -> None:
    design = pu_json["design"]
    assert design == homogeneous_design("polyurethane_74_45").to_dict()
    assert design["layers"] == [{"material": "polyurethane_74_45"}]
    assert design_from_dict(design) == homogeneous_design("polyurethane_74_45")


def test_human_readable_output_lists_the_metrics(pu_run, pu_json: dict) -> None:
    res, out = pu_run
    assert res.returncode == 0, res.stderr
    assert "Traceback" not in res.stderr
    assert PLATE_METRICS  # the plate protocol has metrics
    for name in PLATE_METRICS:
        unit = METRICS[name][1]
        assert re.search(rf"^{name}\s+\S+ {re.escape(unit)}$", res.stdout, flags=re.MULTILINE)
    for name in OTHER_METRICS:
        assert name not in res.stdout
    # same numbers as the JSON run (printed to 4 decimals)
    value = metric_from_text(res.stdout, "plate_force_at_1mm_N")
    assert value == pytest.approx(pu_json["plate_force_at_1mm_N"], abs=1e-4)
    assert re.search(r"\(\d+ dofs, [0-9.]+ s\)", res.stdout)
    assert f"written to {out}" in res.stdout
    with pytest.raises(json.JSONDecodeError):
        json.loads(res.stdout)


def test_out_folder_contents(pu_run) -> None:
    res, out = pu_run
    assert res.returncode == 0, res.stderr
    assert (out / "result.json").is_file()
    assert (out / "meta.json").is_file()
    assert (out / "figures" / "plate.png").is_file()
    assert (out / "deformed_plate.vtu").is_file()
    # only the plate protocol was run: no other figures or meshes
    assert sorted(p.name for p in (out / "figures").iterdir()) == ["plate.png"]
    assert sorted(p.name for p in out.glob("*.vtu")) == ["deformed_plate.vtu"]
    assert (out / "figures" / "plate.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # no temporary folder left beside the run folder
    assert sorted(p.name for p in out.parent.iterdir()) == [out.name]


def test_out_result_json(pu_run, pu_json: dict) -> None:
    _, out = pu_run
    result = parse_one_json_object((out / "result.json").read_text())
    assert result["ok"] is True
    assert result["solver_version"] == SOLVER_VERSION
    assert result["design"] == pu_json["design"]
    assert result["plate_force_at_1mm_N"] == pytest.approx(
        pu_json["plate_force_at_1mm_N"], rel=1e-9
    )
    for key in ("displacement_mm", "force_N"):
        expected = pu_json["curves"]["plate"][key]
        assert result["curves"]["plate"][key] == pytest.approx(expected, rel=1e-9, abs=1e-12)


def test_out_meta_json(pu_run) -> None:
    _, out = pu_run
    meta = parse_one_json_object((out / "meta.json").read_text())
    assert meta["solver_version"] == SOLVER_VERSION
    if (REPO / ".git").exists():
        assert re.fullmatch(r"[0-9a-f]{40}(-dirty)?", meta["git_commit"]), meta["git_commit"]
    else:
        assert meta["git_commit"]
    packages = meta["packages"]
    assert packages["numpy"] == np.__version__
    assert packages["python"] == ".".join(map(str, sys.version_info[:3]))
    for name in ("scipy", "meshio", "scikit-fem"):
        assert packages[name]
    config = meta["config"]
    assert config["design"] == homogeneous_design("polyurethane_74_45").to_dict()
    assert "options" in config
    assert set(config["options"]) >= {"mesh", "newton", "plate"}


def test_out_deformed_mesh(pu_run, pu_json: dict) -> None:
    meshio = pytest.importorskip("meshio")
    _, out = pu_run
    mesh = meshio.read(out / "deformed_plate.vtu")
    assert [block.type for block in mesh.cells] == ["triangle6"]
    cells = mesh.cells_dict["triangle6"]
    assert cells.shape[1] == 6
    assert len(cells) > 50
    assert cells.max() < len(mesh.points)
    u = np.asarray(mesh.point_data["displacement_mm"])
    assert u.shape == (len(mesh.points), 3)
    assert np.all(np.isfinite(u))
    assert 0.9 <= np.abs(u[:, 1]).max() <= 1.1  # the plate indents the apex by 1 mm
    # the points are the deformed positions: the apex of the 5.48 mm body is pushed down ~1 mm
    undeformed = mesh.points - u
    height = sim.REFERENCE_GEOMETRY.height_mm
    assert undeformed[:, 1].max() == pytest.approx(height, abs=1e-9)
    assert mesh.points[:, 1].max() == pytest.approx(height - 1.0, abs=0.1)
    # symmetry: nodes on the axis x = 0 stay on it; the bonded base does not move
    on_axis = np.isclose(undeformed[:, 0], 0.0, atol=1e-9)
    on_base = np.isclose(undeformed[:, 1], 0.0, atol=1e-9)
    assert on_axis.sum() > 2
    assert on_base.sum() > 2
    assert np.abs(u[on_axis, 0]).max() < 1e-9
    assert np.abs(u[on_base]).max() < 1e-9
    assert set(np.unique(mesh.cell_data["layer"][0])) == {0}  # one layer


def test_two_layer_design_file(workdir: Path, pu_json: dict) -> None:
    (workdir / "two_layer.toml").write_text(TWO_LAYER_TOML)
    res = run_cli("simulate", "two_layer.toml", "--protocol", "plate", "--json", cwd=workdir)
    assert res.returncode == 0, res.stderr
    assert "Traceback" not in res.stderr
    result = parse_one_json_object(res.stdout)
    assert result["ok"] is True
    assert [layer.get("thickness_mm") for layer in result["design"]["layers"]] == [1.0, None]
    assert [layer["material"] for layer in result["design"]["layers"]] == [
        "silicone_gls40",
        "polyurethane_74_45",
    ]
    force = result["plate_force_at_1mm_N"]
    # A soft 1 mm silicone skin over a polyurethane core is softer than polyurethane alone and
    # stiffer than silicone alone (silicone's shear and bulk moduli are both the smaller).
    silicone = sim.simulate(homogeneous_design("silicone_gls40"), ("plate",))
    assert silicone.ok
    f_silicone = silicone.metrics["plate_force_at_1mm_N"]
    assert f_silicone is not None
    assert math.isfinite(f_silicone)
    assert f_silicone < force < pu_json["plate_force_at_1mm_N"]


def test_installed_console_script(workdir: Path, pu_json: dict) -> None:
    exe = shutil.which("fingertip")
    if exe is None:
        pytest.skip("the `fingertip` console script is not on PATH (project not installed)")
    res = run_cli(
        "simulate",
        "--material",
        "polyurethane_74_45",
        "--protocol",
        "plate",
        cwd=workdir,
        exe=[exe],
    )
    assert res.returncode == 0, res.stderr
    assert "Traceback" not in res.stderr
    value = metric_from_text(res.stdout, "plate_force_at_1mm_N")
    assert value == pytest.approx(pu_json["plate_force_at_1mm_N"], abs=1e-4)


def test_installed_console_script_error(tmp_path: Path) -> None:
    exe = shutil.which("fingertip")
    if exe is None:
        pytest.skip("the `fingertip` console script is not on PATH (project not installed)")
    write(tmp_path, NU_TOO_HIGH)
    res = run_cli("simulate", "design.toml", cwd=tmp_path, exe=[exe])
    assert res.returncode == 2
    assert_one_line_error(res.stderr, "layers[0].material.nu")


# --- each command keeps to its own folders ------------------------------------------------------
SHIPPED = REPO / "surrogate" / "pretrained" / "default"


def _snapshot(folder: Path) -> dict[str, tuple[bytes, int]]:
    return {
        str(p.relative_to(folder)): (p.read_bytes(), p.stat().st_mtime_ns)
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def _sweep_copy(tmp_path: Path) -> Path:
    """A sweep folder: the shipped training sweep's config.json and first rows."""
    folder = tmp_path / "sweep"
    folder.mkdir()
    shutil.copy(SHIPPED / "config.json", folder / "config.json")
    lines = shipped_table_lines(6)
    (folder / "table.csv").write_text("".join(lines))
    return folder


@pytest.mark.parametrize("marker", [True, False])
def test_a_simulate_folder_is_refused_by_the_other_commands(
    pu_run, tmp_path: Path, capsys: pytest.CaptureFixture[str], marker: bool
) -> None:
    """sweep --out, optimize --out, run --out and report on a `simulate --out` folder: one
    line each, and the folder keeps every byte (also a folder made before the kind marker,
    recognised by its result.json)."""
    res, made = pu_run
    assert res.returncode == 0, res.stderr
    out = tmp_path / "pu"
    shutil.copytree(made, out)
    meta = json.loads((out / "meta.json").read_text())
    assert meta["kind"] == "simulate"
    if not marker:
        del meta["kind"]
        (out / "meta.json").write_text(json.dumps(meta))
    before = _snapshot(out)
    for argv in (
        ["sweep", "--n", "2", "--out", str(out)],
        ["optimize", "--out", str(out)],
        ["run", "--out", str(out)],
        ["report", str(out)],
    ):
        assert main(argv) == 2, argv
        line = assert_one_line_error(capsys.readouterr().err, str(out))
        assert "simulation result" in line, line
    assert _snapshot(out) == before


def test_report_and_optimize_refuse_a_sweep_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = _sweep_copy(tmp_path)
    before = _snapshot(folder)
    assert main(["report", str(folder)]) == 2
    line = assert_one_line_error(capsys.readouterr().err, str(folder))
    assert "sweep" in line and "nothing written" in line
    assert main(["optimize", "--out", str(folder)]) == 2
    assert "holds a sweep" in assert_one_line_error(capsys.readouterr().err, "--out")
    assert _snapshot(folder) == before
    assert not (folder / "figures").exists() and not (folder / "report.md").exists()


def test_report_on_a_damaged_run_folder_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = tmp_path / "run"
    run.mkdir()
    (run / "meta.json").write_text(json.dumps({"kind": "optimize"}))
    (run / "config.json").write_text("{not json")
    assert main(["report", str(run)]) == 2
    assert "not readable JSON" in assert_one_line_error(capsys.readouterr().err, "config.json")
    # the same folder refuses a resume in one line too
    assert main(["optimize", "--out", str(run)]) == 2
    assert "not readable JSON" in assert_one_line_error(capsys.readouterr().err, "config.json")


def test_sweep_out_on_another_kind_of_folder(tmp_path: Path, capsys) -> None:
    opt = tmp_path / "opt"
    opt.mkdir()
    (opt / "config.json").write_text(json.dumps({"studies": []}))  # a search run's config
    other = tmp_path / "mine"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    afile = tmp_path / "afile"
    afile.write_text("")
    for out, words in (
        (opt, "holds a search run"),
        (other, "holds files no fingertip command made"),
        (afile, "is a file, not a folder"),
        (afile / "below", "is a file, not a folder"),
    ):
        assert main(["sweep", "--n", "1", "--out", str(out)]) == 2
        line = assert_one_line_error(capsys.readouterr().err, "--out")
        assert words in line and "Errno" not in line, line
    assert (other / "notes.txt").read_text() == "mine" and len(list(other.iterdir())) == 1
    assert afile.read_text() == ""


def test_an_empty_file_as_out_is_called_a_file(tmp_path: Path, capsys) -> None:
    afile = tmp_path / "empty"
    afile.write_text("")
    code = main(["simulate", "--material", "silicone_gls40", "--out", str(afile)])
    assert code == 2
    line = assert_one_line_error(capsys.readouterr().err, str(afile))
    assert "is a file, not a folder" in line and "not empty" not in line


# --- the search is refused before any work, and leaves no folder ----------------------------------
@pytest.mark.parametrize(
    ("url", "words"),
    [
        ("notaurl", "is neither a journal file (*.log) nor a database URL"),
        ("/nonexistent/folder/study.log", "cannot open /nonexistent/folder/study.log"),
        ("foo://", "cannot open foo://"),
        ("postgresql://nobody@127.0.0.1:1/nodb", "cannot open postgresql://"),
        ("postgresql+psycopg://nobody@127.0.0.1:1/nodb", "cannot open postgresql+psycopg://"),
        ("sqlite:////nonexistent/folder/study.db", "cannot open sqlite:////nonexistent"),
    ],
)
def test_a_bad_storage_url_is_refused_before_any_work(
    url: str, words: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    assert main(["optimize", "--storage", url, "--out", str(out), "--no-progress"]) == 2
    line = assert_one_line_error(capsys.readouterr().err, "--storage")
    assert words in line, line
    assert not out.exists()  # so the corrected command is not refused as "another storage"
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_run_from_scratch_checks_its_inputs_before_the_sweep(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    targets = tmp_path / "t.toml"
    targets.write_text("[tapping]\ndisp_at_1N_mm = 1.8\ndisp_at_4N_mm = 2.9\nhysteresis = 2\n")
    out = tmp_path / "main"
    for argv, field in (
        (["--targets", str(targets)], "tapping.hysteresis"),
        (["--storage", "notaurl"], "--storage"),
        (["--space", str(tmp_path / "missing.toml")], "SPACE"),
        (["--trials", "0"], "--trials"),
    ):
        code = main(["run", "--from-scratch", "--n", "2", "--out", str(out), *argv])
        assert code == 2, argv
        assert_one_line_error(capsys.readouterr().err, field)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.toml"]  # no sweep, no run folder


def test_run_from_scratch_with_the_3d_model_is_refused_before_any_work(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The sweep and training of ``--from-scratch`` are the 2D model's; a 3D search starts from
    a multi-fidelity surrogate, so ``--from-scratch --model 3d`` is one line, nothing made."""
    code = main(["run", "--from-scratch", "--n", "2", "--model", "3d", "--out",
                 str(tmp_path / "main")])  # fmt: skip
    assert code == 2
    assert_one_line_error(capsys.readouterr().err, "--model")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("argv", "shipped"),
    [([], "default3d"), (["--model", "2d"], "default"), (["--model", "3d"], "default3d")],
)
def test_without_surrogate_a_search_starts_from_the_shipped_checkpoint_of_its_model(
    argv: list[str], shipped: str
) -> None:
    """``explore._config.default_checkpoint``: the search starts from the shipped
    multi-fidelity surrogate (3D), with ``--model 2d`` from the shipped 2D one; a given
    --surrogate is kept."""
    from explore._config import OptimizeConfig
    from explore.cli import _optimize_config, build_parser

    config = _optimize_config(build_parser().parse_args(["run", *argv]))
    want = REPO / "surrogate" / "pretrained" / shipped / "model.safetensors"
    assert Path(config.surrogate).resolve() == want.resolve() and want.is_file()
    given = build_parser().parse_args(["run", *argv, "--surrogate", "elsewhere.safetensors"])
    assert _optimize_config(given).surrogate == "elsewhere.safetensors"
    assert OptimizeConfig(model=config.model).surrogate == config.surrogate


# --- one --workers default, documented seeds ----------------------------------------------------
def test_one_workers_default_and_every_seed_documented() -> None:
    from explore._config import OptimizeConfig
    from explore.cli import build_parser
    from sim.sweep import default_workers

    parser = build_parser()
    sub = next(
        a for a in parser._actions if isinstance(a, __import__("argparse")._SubParsersAction)
    )
    n = default_workers()
    assert n >= 1 and OptimizeConfig().workers == n
    assert parser.parse_args(["sweep", "--n", "1", "--out", "x"]).workers == n
    for name in ("sweep", "optimize", "run"):
        helps = {a.dest: a.help or "" for a in sub.choices[name]._actions}
        assert f"default {n}:" in helps["workers"], (name, helps["workers"])
    for name in ("sweep", "train", "optimize", "run"):
        helps = {a.dest: a.help or "" for a in sub.choices[name]._actions}
        assert "seed" in helps["seed"] and "default" in helps["seed"], name


# --- optimize / run: the pipeline is explore's, the CLI parses and reports ----------------------
def _a_summary():
    from explore._types import Summary

    answer = {
        "errors_vs_targets": {"disp_at_1N_mm": 0.012, "hysteresis_Nmm": -0.2},
        "within_tolerance": {"disp_at_1N_mm": True, "hysteresis_Nmm": False},
        "fe_metrics": {"wedge_peak_force_N": 0.123456},
        "readings": {"sag_mm": 0.0456},
        "credible": True,
    }
    timing = {"wall_time_s": 12.4, "timings": {"search_s": 3.2, "fe_s": 8.9, "retrain_s": 0.0},
              "resumed": False}  # fmt: skip
    answers = {"best": answer, "gel": None, "foam": {**answer, "credible": False},
               "buildable": None}  # fmt: skip
    return Summary(answers, {}, 0.05, [], ["best: hysteresis is missed"], timing)


@pytest.mark.parametrize(
    ("argv", "scratch"),
    [(["optimize"], None), (["run"], None), (["run", "--from-scratch", "--n", "5"], 5)],
)
def test_optimize_and_run_call_the_pipeline_once_and_report_its_summary(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys, argv: list[str], scratch
) -> None:
    """``fingertip optimize`` / ``run`` hand their options to ``explore._pipeline.optimize`` /
    ``run`` (with ``--from-scratch`` the number of designs of the sweep) and report the
    ``Summary`` it returns: no summary.json is read (there is none here)."""
    import explore._pipeline
    import explore._report

    calls = []

    def fake(config, out, *, from_scratch=None, progress=True):
        calls.append((config, out, from_scratch, progress))
        return _a_summary()

    monkeypatch.setattr(explore._pipeline, argv[0], fake)
    monkeypatch.setattr(explore._report, "write_report", lambda out: out / "report.md")
    out = tmp_path / "main"
    assert main([*argv, "--out", str(out), "--trials", "7", "--no-progress"]) == 0
    ((config, given_out, from_scratch, progress),) = calls
    assert config.trials == 7 and given_out == out and progress is False
    assert from_scratch == scratch
    assert capsys.readouterr().out.splitlines() == [
        "best design (FE): disp_at_1N_mm +1.2 %, hysteresis_Nmm -20.0 % (outside); wedge peak "
        "0.123 N; sag 0.0456 mm",
        "best gel-only design: none credible confirmed by FE",
        "best foam-core design (FE) [NOT CREDIBLE: --allow-untrusted]: disp_at_1N_mm +1.2 %, "
        "hysteresis_Nmm -20.0 % (outside); wedge peak 0.123 N; sag 0.0456 mm",
        "best buildable design: none credible confirmed by FE",
        "  best: hysteresis is missed",
        "time: search 3 s, FE 9 s, retraining 0 s; 12 s in all",
        f"report: {out / 'report.md'}",
    ]
    assert not out.exists()


def test_run_from_scratch_sweeps_trains_then_searches_with_them(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``explore._pipeline.run(..., from_scratch=n)``: the sweep (seed 0) and the training
    (seed 0) beside the run folder, then the search on that surrogate and dataset; a surrogate
    already trained there is not trained again (a resumed run)."""
    import explore._pipeline
    import sim.sweep
    import surrogate
    from explore._config import OptimizeConfig

    calls = []

    def sweep_(space, n, out, **kw):
        calls.append(("sweep", n, out, kw["seed"], kw["workers"]))

    def train_(sweep, out, **kw):
        calls.append(("train", sweep, out, kw["seed"]))

    def optimize_(config, out, **kw):
        calls.append(("optimize", config.surrogate, config.dataset, config.trials, out))
        return "summary"

    monkeypatch.setattr(sim.sweep, "run_sweep", sweep_)
    monkeypatch.setattr(surrogate, "train_surrogate", train_)
    monkeypatch.setattr(explore._pipeline, "optimize", optimize_)
    out = tmp_path / "main"
    sweep, trained = tmp_path / "main-sweep", tmp_path / "main-surrogate"
    config = OptimizeConfig(trials=9, workers=1)
    assert explore._pipeline.run(config, out, from_scratch=6, progress=False) == "summary"
    ckpt = str(trained / "model.safetensors")
    assert calls == [("sweep", 6, sweep, 0, 1), ("train", sweep, trained, 0),
                     ("optimize", ckpt, str(sweep), 9, out)]  # fmt: skip
    calls.clear()
    trained.mkdir()
    (trained / "model.safetensors").write_bytes(b"")
    (trained / "meta.json").write_text(json.dumps({"kind": "train"}))
    explore._pipeline.run(config, out, from_scratch=6, progress=False)
    assert [c[0] for c in calls] == ["sweep", "optimize"]
    calls.clear()
    explore._pipeline.run(config, out, progress=False)  # no --from-scratch: the search alone
    assert calls == [("optimize", config.surrogate, None, 9, out)]


def test_an_sqlite_file_given_as_a_journal_is_refused_with_its_url(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import sqlite3
    from contextlib import closing

    db = tmp_path / "old.log"
    with closing(sqlite3.connect(db)) as con:
        con.execute("CREATE TABLE t (x)")
    out = tmp_path / "run"
    assert main(["optimize", "--storage", str(db), "--out", str(out), "--no-progress"]) == 2
    line = assert_one_line_error(capsys.readouterr().err, "--storage")
    assert f"give it as sqlite:///{db}" in line and not out.exists()


def test_run_from_scratch_sweeps_as_many_designs_as_the_shipped_table():
    """``fingertip run --from-scratch`` remakes the shipped surrogate: its default ``--n`` is
    the shipped sweep's (re-shipping a larger table must move it too)."""
    import json
    from pathlib import Path

    from explore.cli import build_parser

    shipped = Path(__file__).resolve().parents[1] / "surrogate/pretrained/default/config.json"
    args = build_parser("run").parse_args(["run", "--from-scratch"])
    assert args.n == json.loads(shipped.read_text())["n"]


# --- issue 31, item 5: bad inputs are one line, exit 2, before any work, no folder made --------
def _argv_with_out(command: str, tmp_path: Path) -> list[str]:
    out = str(tmp_path / "out")
    return {
        "sweep": ["sweep", "--n", "2", "--out", out],
        "train": ["train", str(tmp_path / "sweep"), "--out", out],
        "optimize": ["optimize", "--out", out, "--no-progress"],
        "run": ["run", "--out", out, "--no-progress"],
    }[command]


@pytest.mark.parametrize("seed", ["-1", "4294967296"])
@pytest.mark.parametrize("command", ["sweep", "train", "optimize", "run"])
def test_a_seed_out_of_range_is_one_line_before_any_work(
    command: str, seed: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Every subcommand's --seed is an integer in [0, 2**32 - 1] (sim.errors.SEED_MAX): a
    negative one no longer reaches numpy, nor leaves a folder that refuses the corrected
    command."""
    assert main([*_argv_with_out(command, tmp_path), "--seed", seed]) == 2
    line = assert_one_line_error(capsys.readouterr().err, "--seed")
    assert "[0, 4294967295]" in line and f"got {seed}" in line, line
    assert sorted(tmp_path.iterdir()) == []


@pytest.mark.parametrize("command", ["optimize", "run"])
def test_a_search_seed_whose_last_round_is_out_of_range_is_refused(
    command: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Round r searches with seed + r: with 3 rounds the largest seed is 2**32 - 3."""
    argv = [*_argv_with_out(command, tmp_path), "--seed", "4294967295", "--rounds", "3"]
    assert main(argv) == 2
    line = assert_one_line_error(capsys.readouterr().err, "--seed")
    assert "[0, 4294967293]" in line and "3 rounds" in line, line
    assert sorted(tmp_path.iterdir()) == []


def test_a_negative_seed_is_one_line_in_a_subprocess(tmp_path: Path) -> None:
    res = run_cli("sweep", "--n", "2", "--out", "out", "--seed", "-1", cwd=tmp_path)
    assert res.returncode == 2 and res.stdout == ""
    assert_one_line_error(res.stderr, "--seed")
    assert sorted(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("kind", "words"),
    [
        ("missing", "does not exist"),
        ("empty", "is not a sweep folder: it has no config.json"),
        ("no_table", "is not a sweep folder: it has no table.csv"),
    ],
)
def test_a_dataset_that_is_no_sweep_is_named_not_replaced(
    kind: str, words: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--dataset given is used or refused: never silently replaced by the shipped table."""
    dataset = tmp_path / "sweep"
    if kind != "missing":
        dataset.mkdir()
    if kind == "no_table":
        (dataset / "config.json").write_text("{}")
    out = tmp_path / "run"
    for command in ("optimize", "run"):
        argv = [command, "--dataset", str(dataset), "--out", str(out), "--no-progress"]
        assert main(argv) == 2
        line = assert_one_line_error(capsys.readouterr().err, "--dataset")
        assert f"{dataset} {words}" in line, line
    assert not out.exists()


def test_run_n_without_from_scratch_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``run --n 5`` alone would be ignored: it is one line naming --n, before any work; with
    --from-scratch it is the sweep's size (test_optimize_and_run_call_the_pipeline_once...)."""
    out = tmp_path / "main"
    assert main(["run", "--n", "5", "--out", str(out), "--no-progress"]) == 2
    line = assert_one_line_error(capsys.readouterr().err, "--n")
    assert "--from-scratch" in line
    assert sorted(tmp_path.iterdir()) == []


def test_a_user_catalogue_with_an_unphysical_modulus_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cat = write(
        tmp_path,
        '[stiff]\nsource = "a typo"\nmodel = "neo_hookean"\nmu_MPa = 1e12\nnu = 0.3\n',
        "cat.toml",
    )
    out = tmp_path / "sim"
    argv = ["simulate", "--material", "stiff", "--catalogue", str(cat), "--out", str(out)]
    assert main(argv) == 2
    line = assert_one_line_error(capsys.readouterr().err, "stiff.mu_MPa")
    assert "[0.0001, 1000] MPa" in line
    assert not out.exists()


def test_a_user_material_without_a_tested_range_is_noted_once(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Its own tests are unknown: the paper's limit holds it, and the user is told so."""
    cat = write(
        tmp_path,
        '[soft]\nsource = "a datasheet"\nmodel = "neo_hookean"\nmu_MPa = 0.05\nnu = 0.45\n'
        '[fitted]\nsource = "my tests"\nmodel = "neo_hookean"\nmu_MPa = 0.05\nnu = 0.45\n'
        '[fitted.provenance]\ntested_mode = "uniaxial_compression"\n'
        "max_compressive_log_strain = 0.9\n",
        "cat.toml",
    )
    import sim.materials

    reads = []
    load = sim.materials.load_user_catalogues
    monkeypatch.setattr(
        sim.materials, "load_user_catalogues", lambda paths: reads.append(paths) or load(paths)
    )
    argv = ["simulate", "--material", "soft", "--catalogue", str(cat), "--protocol", "plate"]
    assert main(argv) == 0
    assert len(reads) == 1  # the note and the command share one reading of the files
    err = capsys.readouterr().err
    notes = [line for line in err.splitlines() if line.startswith("note: cat.toml:")]
    assert notes == [
        "note: cat.toml:soft: no tested strain range (fingertip fit-material records it); held "
        "to the paper's compressive log strain of 0.6, flagged untested"
    ]
