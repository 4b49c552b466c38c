"""The shipped multi-fidelity checkpoint (`surrogate/pretrained/default3d`): it loads with its
2D file (the shipped 2D checkpoint), matches its shipped 3D training table and the current
solver, its report's numbers are reproduced on its held-out designs, and a search finds its
3D sweep beside it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from shipped_report import assert_report_reproduced

from sim import SOLVER_VERSION
from sim.design import DEFAULT_SPACE_3D_PATH, load_space
from sim.metrics import SAME_METRICS_AS
from sim.sweep import table_sha256
from surrogate import load_multifidelity

REPO = Path(__file__).resolve().parents[1]
SHIPPED = REPO / "surrogate" / "pretrained" / "default3d"
SHIPPED_2D = REPO / "surrogate" / "pretrained" / "default" / "model.safetensors"


@pytest.fixture(scope="module")
def model():
    return load_multifidelity(SHIPPED / "model.safetensors", allow_solver_mismatch=True)


def test_shipped_multifidelity_checkpoint_matches_its_data_the_solver_and_the_2d_file(model):
    header = model.header
    assert header["solver_version"] in {SOLVER_VERSION, *SAME_METRICS_AS}
    digest = table_sha256(SHIPPED / "table.csv.gz")  # the hash of the CSV bytes
    assert header["training_data"]["table_sha256"] == digest
    assert model.space.to_dict() == load_space(DEFAULT_SPACE_3D_PATH).to_dict()
    # its low fidelity is the shipped 2D checkpoint, named relative to the repository
    low = header["low_fidelity"]
    assert not Path(low["path"]).is_absolute()
    assert (REPO / low["path"]).resolve() == SHIPPED_2D.resolve()
    assert model.low_file.resolve() == SHIPPED_2D.resolve()
    report = json.loads((SHIPPED / "report.json").read_text())  # no path of the training machine
    assert report["low_fidelity"] == {"path": low["path"], "sha256": low["sha256"]}
    assert (SHIPPED / "model.safetensors").stat().st_size < 2_000_000  # a small file
    assert not (SHIPPED / "table.csv").exists()
    readme = (SHIPPED / "README.md").read_text()
    assert digest in readme and "fingertip sweep --model 3d" in readme
    assert f"--method {header['method']}" in readme


def test_shipped_multifidelity_report_is_reproduced_on_the_held_out_designs(model):
    """The numbers in report.json are what the checkpoint does on its test split."""
    checked = assert_report_reproduced(model, SHIPPED, dimension="3d")
    assert checked >= 19  # the 3D model's FE metrics: displacements, hysteresis, contact patch


def test_a_search_with_the_shipped_multifidelity_checkpoint_finds_its_3d_sweep(tmp_path):
    """``fingertip run --surrogate surrogate/pretrained/default3d/model.safetensors`` retrains
    between rounds on the 3D sweep shipped beside it, with its FE options (the 3D model)."""
    from explore._config import OptimizeConfig, setup

    config = OptimizeConfig(surrogate=str(SHIPPED / "model.safetensors"))
    found = setup(config, tmp_path / "run")
    assert found.model == "3d" and found.options.dimension == "3d"
    assert found.dataset is not None and found.dataset.resolve() == SHIPPED.resolve()
    from sim.sweep import sample_points

    points = sample_points(load_space(DEFAULT_SPACE_3D_PATH), 8, seed=1)
    assert np.isfinite(found.surrogate.predict(points).median).all()
