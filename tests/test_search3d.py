"""The 3D search (``fingertip run`` / ``optimize`` with a multi-fidelity surrogate): it searches
the 3D design space on the multi-fidelity surrogate, confirms with the 3D FE model, retrains the
multi-fidelity surrogate on its confirmed 3D designs and scores the wedge against the 3D
reference.

The multi-fidelity surrogate is trained on a SYNTHETIC 3D sweep (``mf_fixtures``; its config.json
records the coarse pad mesh and a loose periodic state, so that a confirmation costs seconds):
what is tested is the machinery, with real 3D FE confirmations.
"""

from __future__ import annotations

import json
import math

import pytest
import torch
from mf_fixtures import write_synthetic_sweep
from sweep_fixtures import SHIPPED

import explore.cli
from explore import OptimizeConfig, optimize
from explore._objective import WEDGE_REFERENCE_3D_N, closeness
from explore._run_folder import read_confirmations
from sim.design import DesignSpace, load_targets
from sim.errors import DesignError
from sim.geometry import COARSE_MESH_3D
from sim.metrics import METRICS_3D
from sim.options import ModelOptions, SimOptions, options_from_dict
from surrogate import (
    MultiFidelitySurrogate,
    TrainConfig,
    fit_multifidelity,
    is_multifidelity,
    load_surrogate,
    read_sweep,
    save_multifidelity,
)

LOW_FILE = SHIPPED / "model.safetensors"
TINY = TrainConfig(members=2, hidden=(16, 16), max_epochs=15, patience=15)
#: the confirmations' FE: the coarse pad mesh, three taps accepted at a loose residual (as the
#: 2D tests' ``FAST``), a 5 s wedge hold
OPTIONS = options_from_dict(
    {
        **SimOptions(model=ModelOptions("3d"), mesh3d=COARSE_MESH_3D).as_dict(),
        "tapping": {"max_taps": 3, "residual_tol": 0.5, "settle_tol": 0.1},
        "wedge": {"hold_s": 5.0},
    }
)
#: a 3D subspace whose designs are cheap and stay within the validity limits: a short pad of
#: the smallest section, one gel layer stiff enough not to pass the strain limit (no foam: a
#: sharp wedge takes a foam past the volume-ratio limit; the gel has no ``nu``, which the search
#: completes, ``complete_subspace``), short relaxation times (a few taps settle it); the pad's
#: profile exponent is searched
SPACE = """
description = "3D search test: a short pad, one stiff layer"
[geometry]
half_width_mm = { value = 5.0 }
height_mm = { value = 4.5 }
exponent = { value = 2.0 }
half_length_mm = { value = 8.0 }
length_exponent = { low = 2.0, high = 4.0 }
[layers]
count = { choice = [1] }
[layers.skin]
thickness_mm = { low = 0.2, high = 1.5 }
material = { choice = ["gel"] }
mu0_MPa = { low = 0.0025, high = 0.35, log = true }
alpha = { low = 1.5, high = 4.0 }
g_total = { low = 0.0, high = 0.9 }
tau_s = { low = 0.04, high = 2.0, log = true }
[layers.core]
material = { choice = ["gel"] }
mu0_MPa = { low = 0.1, high = 0.35, log = true }
alpha = { low = 1.5, high = 2.5 }
g_total = { low = 0.0, high = 0.3 }
tau_s = { low = 0.04, high = 0.2, log = true }
"""
ERROR_PREFIX = "fingertip: error: "


@pytest.fixture(scope="module")
def mf(tmp_path_factory):
    """A multi-fidelity checkpoint (delta method, tiny) trained on a synthetic 3D sweep whose
    recorded FE options are ``OPTIONS``; returns (checkpoint, sweep, space file)."""
    root = tmp_path_factory.mktemp("search3d")
    low = load_surrogate(LOW_FILE)
    sweep = write_synthetic_sweep(root / "sweep3d", 40, 3, low, options=OPTIONS)
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        fit = fit_multifidelity(read_sweep(sweep, dimension="3d"), LOW_FILE, "delta", TINY,
                                progress=False)  # fmt: skip
    finally:
        torch.set_num_threads(before)
    ckpt = save_multifidelity(fit.surrogate, root / "mf.safetensors")
    space = root / "space.toml"
    space.write_text(SPACE)
    return ckpt, sweep, space


def _config(mf, **changes) -> OptimizeConfig:
    ckpt, _, space = mf
    base = dict(surrogate=str(ckpt), space=str(space), trials=8, screen=256, confirm=1,
                uncertain=0, family_trials=0, buildable_trials=0, rounds=2, workers=1)  # fmt: skip
    return OptimizeConfig(**{**base, **changes})


@pytest.fixture(scope="module")
def searched(mf, tmp_path_factory):
    """Two rounds of the 3D search, one 3D FE confirmation each, a retraining between them."""
    out = tmp_path_factory.mktemp("run3d") / "run"
    summary = optimize(_config(mf), out, progress=False)
    return out, summary


def test_a_multifidelity_surrogate_searches_and_confirms_in_3d(searched, mf):
    out, summary = searched
    del mf
    config = json.loads((out / "config.json").read_text())
    # the FE options are the 3D sweep's (like with like), recorded in the run folder
    recorded = options_from_dict(config["sim_options"])
    assert recorded.dimension == "3d" and recorded.mesh3d == COARSE_MESH_3D
    assert recorded.tapping.max_taps == 3
    confirmations = read_confirmations(out)
    assert len(confirmations) == 2  # one a round
    targets = load_targets()
    for c in confirmations:
        point = c.candidate.point
        assert point["geometry.half_length_mm"] == 8.0
        assert 2.0 <= point["geometry.length_exponent"] <= 4.0
        record = json.loads((out / "fe" / "records" / f"{c.key}.json").read_text())
        assert record["n_dofs"] > 1000  # a 3D mesh (the 2D section has ~1000 dofs)
        # the 3D metrics (the contact patch) are confirmed and compared with the prediction
        assert set(METRICS_3D) <= set(c.fe_metrics)
        assert c.rel_error.get("contact_area_at_4N_mm2") is not None or c.status != "ok"
        if c.status == "ok":
            assert c.fe_metrics["contact_area_at_1N_mm2"] > 0
            # the wedge against the pad's reference, not the 2D section's per 10 mm
            score = closeness(c.fe_metrics, targets, wedge_reference_N=WEDGE_REFERENCE_3D_N)
            assert c.fe_score == pytest.approx(float(score.score), rel=1e-12)
    # the answers are 3D results: no separate 3D check of them
    assert not (out / "answers_3d.json").exists()
    assert summary.answers.get("best") is not None


def test_the_round_after_searches_with_the_multifidelity_surrogate_retrained(searched, mf):
    out, _ = searched
    ckpt, _, _ = mf
    nxt = out / "surrogates" / "round-1.safetensors"
    assert is_multifidelity(nxt)
    retrained = load_surrogate(nxt)
    first = load_surrogate(ckpt)
    assert isinstance(retrained, MultiFidelitySurrogate)
    assert retrained.method.name == first.method.name == "delta"
    assert retrained.low_file.resolve() == LOW_FILE.resolve()  # the same 2D file, recorded
    round0 = [c for c in read_confirmations(out) if c.candidate.round == 0]
    learnt = retrained.header["active_learning"]["confirmed_designs"]
    assert learnt == sum(c.status == "ok" for c in round0) >= 1
    # the confirmed designs join the training designs (each counted CONFIRMED_WEIGHT times)
    n_before = len(first.header["training_data"]["split_table_index"]["train"])
    n_after = len(retrained.header["training_data"]["split_table_index"]["train"])
    assert n_after == n_before + 10 * learnt
    # and the search of round 1 scored the retrained surrogate's predictions
    point = round0[0].candidate.point
    assert not math.isclose(
        float(retrained.predict([point]).median[0, 0]), float(first.predict([point]).median[0, 0])
    )


def test_a_finished_3d_search_rerun_computes_nothing(searched, mf):
    out, summary = searched
    records = sorted((out / "fe" / "records").glob("*.json"))
    again = optimize(_config(mf), out, progress=False)
    assert sorted((out / "fe" / "records").glob("*.json")) == records
    assert again.answers == summary.answers


def test_the_report_and_answer_files_speak_of_the_3d_model(searched):
    out, _ = searched
    explore.cli.main(["report", str(out)])
    report = (out / "report.md").read_text()
    assert "multi-fidelity neural surrogate" in report
    assert "3D finite-element (FE) model of the pad" in report
    assert f"{WEDGE_REFERENCE_3D_N} N, the paper's silicone as the default 3D pad" in report
    assert "`contact_area_at_4N_mm2`" in report
    answer = (out / "answers" / "best.toml").read_text()
    assert "--set model.dimension=3d" in answer  # the check runs the 3D model
    assert "length_exponent" in answer


def test_the_readme_block_of_a_3d_search_shows_the_pad_and_its_contact_area(searched, mf):
    """``explore._readme_answer.render`` of a 3D search: the command names its checkpoint (not
    the shipped one), each answer's row its pad length and its contact area at 1 N and 4 N."""
    from explore._readme_answer import render

    out, summary = searched
    block = render(out)
    assert block.startswith(f"`fingertip run --surrogate {mf[0]} --trials 8 --out ")
    assert "| contact area 1 N / 4 N (mm²) | errors |" in block
    best = summary.answers["best"]
    row = next(line for line in block.splitlines() if line.startswith("| best credible"))
    fe = best["fe_metrics"]
    area = f"| {fe['contact_area_at_1N_mm2']:.0f} / {fe['contact_area_at_4N_mm2']:.0f} |"
    assert "pad half-length 8.0 mm, length exponent" in row and area in row
    assert "as 3D fingertips" not in block  # the answers are 3D already: no second table


def load_space_text(text: str):
    import tempfile
    from pathlib import Path

    from sim.design import load_space

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "space.toml"
        path.write_text(text)
        return load_space(path)


def one_line(capsys) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(ERROR_PREFIX), err
    return lines[0].removeprefix(ERROR_PREFIX)


def test_a_multifidelity_surrogate_with_model_2d_is_one_line(mf, tmp_path, capsys):
    ckpt, _, _ = mf
    argv = ["optimize", "--surrogate", str(ckpt), "--model", "2d", "--out", str(tmp_path / "r")]
    assert explore.cli.main(argv) == 2
    assert one_line(capsys).startswith("--model: 2d needs a 2D surrogate")
    assert not (tmp_path / "r").exists()  # refused before any work


def test_a_2d_sweep_as_the_multifidelity_dataset_is_refused(mf, tmp_path):
    two_d = tmp_path / "sweep2d"
    two_d.mkdir()
    (two_d / "config.json").write_text(json.dumps({"options": SimOptions().as_dict()}))
    (two_d / "table.csv").write_text("index\n")
    with pytest.raises(DesignError, match="sweep of the 2D model"):
        optimize(_config(mf, dataset=str(two_d)), tmp_path / "r", progress=False)


#: a user's catalogue (``fingertip run --catalogue FILE``): one stiff gel, so that the coarse
#: pad stays within its tested strain and every protocol gives its metrics
USER_GEL = """
[labgel]
source = "a test's own"
model = "neo_hookean"
mu_MPa = 0.1
nu = 0.49
[labgel.provenance]
tested_mode = "uniaxial_compression"
max_compressive_log_strain = 0.6
"""


def test_a_user_catalogue_material_is_confirmed_in_3d_by_worker_processes(tmp_path):
    """``fingertip run --catalogue FILE`` in 3D: a design of the user's material reaches the
    3D FE in worker processes (its table handed to them: ``run_fe(materials=...)``), each
    protocol in a process of its own, and comes back with the 3D metrics (the contact patch)."""
    from explore._confirm import record_path, run_fe
    from sim.materials import load_user_catalogues, material_tables

    file = tmp_path / "gel.toml"
    file.write_text(USER_GEL)
    _, merged = load_user_catalogues([file])
    point = {"geometry.half_width_mm": 5.0, "geometry.height_mm": 4.5, "geometry.exponent": 2.0,
             "geometry.half_length_mm": 8.0, "geometry.length_exponent": 2.0,
             "layers.count": 1, "core.material": "labgel"}  # fmt: skip
    path = record_path(tmp_path, point, OPTIONS, merged)
    tables = material_tables({"labgel": merged["labgel"]})
    record = run_fe([(path, point)], OPTIONS, workers=2, progress=False, materials=tables)[path]
    assert record["status"] == "ok", record["reason"]
    assert record["diagnostics"]["valid"] and record["diagnostics"]["tested_material_by_layer"] == [
        "labgel"
    ]
    metrics = record["metrics"]
    assert set(METRICS_3D) <= set(metrics)
    assert metrics["contact_area_at_4N_mm2"] > metrics["contact_area_at_1N_mm2"] > 0.0
    assert metrics["hysteresis_Nmm"] == pytest.approx(0.0, abs=1e-3)  # an elastic gel
    assert set(record["cost_by_protocol"]) == {"tapping", "plate", "wedge"}


def test_a_subspace_without_a_parameter_none_of_its_designs_use_is_completed():
    from explore._search import check_subspace, complete_subspace
    from sim.design import DEFAULT_SPACE_3D_PATH, load_space

    trained = load_space(DEFAULT_SPACE_3D_PATH)
    gel_core = load_space_text(SPACE)
    assert "core.nu" not in gel_core.names  # no choice of its core uses nu
    done = complete_subspace(gel_core, trained)
    assert done.names == trained.names
    assert done["core.nu"] == trained["core.nu"]
    assert done["core.mu0_MPa"] == gel_core["core.mu0_MPa"]
    check_subspace(done, trained)
    # a parameter its designs use is never made up: still refused
    smaller = DesignSpace(
        tuple(p for p in gel_core.parameters if p.name != "geometry.length_exponent"),
        gel_core.materials,
    )
    with pytest.raises(ValueError, match=r"geometry\.length_exponent"):
        check_subspace(complete_subspace(smaller, trained), trained)


def test_retraining_a_multifidelity_surrogate_is_the_same_bits_for_the_same_seed(mf):
    from surrogate import retrain_multifidelity

    ckpt, sweep, _ = mf
    first = load_surrogate(ckpt)
    data = read_sweep(sweep, dimension="3d")
    points = data.points[:2]
    targets = data.targets[:2] * 1.1  # two "confirmed" designs, 10 % off the sweep's values
    torch.set_num_threads(1)
    a = retrain_multifidelity(first, data, points, targets, seed=3, weight=2)
    b = retrain_multifidelity(first, data, points, targets, seed=3, weight=2)
    pa, pb = a.predict(data.points[:8]), b.predict(data.points[:8])
    assert (pa.mean == pb.mean).all() and (pa.std == pb.std).all()
    n_train = len(first.header["training_data"]["split_table_index"]["train"])
    assert len(a.header["training_data"]["split_table_index"]["train"]) == n_train + 4
    assert (
        a.header["training_data"]["split_table_index"]["val"]
        == (first.header["training_data"]["split_table_index"]["val"])
    )
