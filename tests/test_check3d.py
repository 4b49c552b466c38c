"""``fingertip run --model 3d`` (``explore._check3d``): a run's answers simulated with the 3D
pad and set against the targets."""

from __future__ import annotations

import json
import math

import pytest

import explore._confirm
from explore._check3d import RECORDS_3D, check_in_3d, options_3d
from explore._confirm import reference_point
from explore._objective import WEDGE_REFERENCE_3D_N, WEDGE_WEIGHT
from explore._run_folder import read_answers_3d
from sim import SimOptions
from sim.design import load_targets, point_to_design, with_every_layer
from sim.geometry import COARSE_MESH_3D
from sim.provenance import json_safe
from sim.simulate import simulate


@pytest.fixture(scope="module")
def checked(tmp_path_factory):
    """A run folder whose best and buildable answers are one design (the paper's silicone on
    the reference outline), checked in 3D on the coarse pad mesh."""
    out = tmp_path_factory.mktemp("run")
    point = with_every_layer(reference_point("silicone_gls40"))
    fe2d = simulate(point_to_design(point)).metrics
    answer = {
        "design": point_to_design(point).to_dict(),
        "point": json_safe(point),
        "reason": "best",
        "round": 0,
        "search": "continuous",
        "fe_metrics": json_safe(fe2d),
    }
    summary = {"answers": {"best": answer, "gel": None, "foam": None, "buildable": answer}}
    (out / "summary.json").write_text(json.dumps(summary))
    options = options_3d(SimOptions(mesh3d=COARSE_MESH_3D))
    targets = load_targets()
    data = check_in_3d(out, targets, options, tolerance=0.05, workers=1, progress=False)
    return out, data, fe2d, targets, options


def test_each_answer_is_simulated_once_in_3d_and_judged_like_the_2d_one(checked):
    out, data, fe2d, targets, _ = checked
    records = sorted((out / RECORDS_3D).glob("*.json"))
    assert len(records) == 1  # two answers, one design: one simulation
    assert data["answers"]["gel"] is None and data["answers"]["foam"] is None
    best, buildable = data["answers"]["best"], data["answers"]["buildable"]
    assert best == buildable and best["status"] == "ok"
    record = json.loads((out / best["fe_record"]).read_text())
    assert record["solver_version"] and record["n_dofs"] == best["n_dofs"] > 3000
    fe = record["metrics"]
    errors = best["errors_vs_targets"]
    for name, error in errors.items():
        value, target = fe[targets.metric(name)], targets.values[name]
        assert error == pytest.approx((value - target) / target, rel=1e-12)
        assert best["within_tolerance"][name] == (abs(error) <= 0.05)
    rms = math.sqrt(sum(e * e for e in errors.values()) / 3)
    assert best["tapping_rms_error"] == pytest.approx(rms, rel=1e-12)
    # the wedge's effort against the 3D reference, the paper's silicone as the default pad:
    # this design is that silicone, on the coarse pad mesh without the band along the wedge's
    # edge, which is stiffer under the wedge than the reference's banded mesh (on the two pads
    # of docs/model_3d.md, "Mesh convergence", the plain meshes' wedge forces lie 30-44 %
    # above the converged value, the banded one's 1.6-1.8 %): 1.23 here; the 2D reference
    # (2.35 N against 0.5215 N) would give about a fifth of it
    effort = best["wedge_effort"]
    assert effort == pytest.approx(fe["wedge_peak_force_N"] / WEDGE_REFERENCE_3D_N, rel=1e-12)
    assert 1.05 < effort < 1.5
    assert best["fe_score"] == pytest.approx(rms + WEDGE_WEIGHT * effort, rel=1e-12)
    # the contact patch exists in 3D only, and grows with the force
    assert 0 < fe["contact_area_at_1N_mm2"] < fe["contact_area_at_4N_mm2"]
    assert best["fe_metrics"]["contact_area_at_4N_mm2"] == fe["contact_area_at_4N_mm2"]
    # the pad is more compliant than the plane-strain section times 10 mm (docs/model_3d.md)
    for m in ("disp_at_1N_mm", "disp_at_4N_mm"):
        assert best["change_from_2d"][m] == pytest.approx(fe[m] / fe2d[m] - 1, rel=1e-12)
        assert best["change_from_2d"][m] > 0
    assert best["credible"] == (
        best["diagnostics"]["valid"]
        and best["diagnostics"]["settled"]
        and targets.sag_ok(fe["sag_mm"])
    )
    assert read_answers_3d(out) == json.loads(json.dumps(data))


def test_a_second_check_reuses_the_records(checked, monkeypatch):
    out, data, _, targets, options = checked

    def boom(*a, **k):
        raise AssertionError("simulated again")

    monkeypatch.setattr(explore._confirm, "evaluate_point", boom)
    again = check_in_3d(out, targets, options, tolerance=0.05, workers=1, progress=False)
    assert again["answers"] == data["answers"]


def test_a_2d_option_set_is_refused(checked):
    out, _, _, targets, _ = checked
    with pytest.raises(ValueError, match="3D model"):
        check_in_3d(out, targets, SimOptions(), tolerance=0.05)


def test_the_report_shows_the_3d_answers(checked):
    from explore._report import write_report

    out, data, _, _, _ = checked
    text = write_report(out).read_text()
    assert "## The answers as 3D fingertips" in text
    best = data["answers"]["best"]
    area = best["fe_metrics"]["contact_area_at_4N_mm2"]
    row = next(line for line in text.splitlines() if line.startswith("| [best]"))
    assert f"{area:.3g}" in row


def test_a_model_other_than_2d_or_3d_is_one_line(capsys, tmp_path):
    import explore.cli

    code = explore.cli.main(["optimize", "--model", "4d", "--out", str(tmp_path / "r")])
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["fingertip: error: --model: must be 2d or 3d, got '4d'"]


def test_the_3d_options_run_every_protocol_to_its_end():
    """An answer beyond the limits in 3D keeps its metrics (flagged), where a sweep stops."""
    options = options_3d(SimOptions())
    assert options.dimension == "3d" and SimOptions().validity.stop_at_violation
    assert not options.validity.stop_at_violation


def test_the_readme_block_shows_the_3d_answers(checked):
    from explore._readme_answer import _rows_3d

    _, data, _, _, _ = checked
    lines = _rows_3d(data)
    assert "1 designs" in lines[1]  # best and buildable: one design
    best = data["answers"]["best"]
    fe = best["fe_metrics"]
    row = next(line for line in lines if line.startswith("| best credible = best buildable |"))
    assert f"{fe['disp_at_1N_from_touch_mm']:.2f} / {fe['disp_at_4N_from_touch_mm']:.2f}" in row
    assert f"{fe['contact_area_at_1N_mm2']:.0f} / {fe['contact_area_at_4N_mm2']:.0f}" in row
    assert row.endswith("| yes |") == bool(best["credible"])
