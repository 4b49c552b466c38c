"""The sweep segments kept in git (``datasets/*/seg_S-E``): each is the part of the sample it
names, made with the options and solver its config records, and the 3D ones join into one sweep
that a surrogate reads, each layer's strain included.

A run folder lives only as long as its machine (``runs/`` is not kept), so what is here is all
that carries a dataset from one machine to the next: these checks catch a segment copied from
the wrong folder, cut short, or made with other options before anything trains on it."""

from __future__ import annotations

import csv
import shutil
from pathlib import Path

import pytest

from sim.design import load_space
from sim.metrics import SOLVER_VERSION, same_metrics
from sim.options import ModelOptions, SimOptions, options_from_dict
from sim.sweep import (
    open_table,
    read_config,
    record_key,
    sample_points,
    table_path,
    with_todays_defaults,
)

ROOT = Path(__file__).resolve().parents[1]
SEGMENTS = sorted(ROOT.glob("datasets/*/seg_*"))
SEGMENTS_3D = sorted(ROOT.glob("datasets/default3d/seg_*"))


def _rows(folder: Path) -> list[dict[str, str]]:
    with open_table(table_path(folder)) as fh:
        return list(csv.DictReader(fh))


@pytest.mark.parametrize("folder", SEGMENTS, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_a_kept_segment_holds_the_designs_it_names(folder: Path) -> None:
    """``seg_S-E`` holds designs S to E of its sample, each once, in order; made with this
    solver, each row's key is the hash of its design, the options and the solver
    (``record_key``): the sample and options its config records; made with an earlier one, that
    version's metrics are this solver's (``SAME_METRICS_AS``)."""
    config = read_config(folder)
    first, last = (int(x) for x in folder.name.removeprefix("seg_").split("-"))
    assert (config.get("start", 0), config["n"]) == (first, last + 1)
    rows = _rows(folder)
    assert [int(r["index"]) for r in rows] == list(range(first, last + 1))
    assert all(r["status"] in ("ok", "failed") for r in rows)
    version = config["solver_version"]
    assert same_metrics(version), f"{folder}: solver {version}"
    if version != SOLVER_VERSION:
        return
    from sim.design import space_from_dict

    space = space_from_dict(config["space"])
    options = options_from_dict(config["options"])
    points = sample_points(space, config["n"], config["seed"], config["sampler"])[first:]
    keys = [record_key(p, options, space.catalogue) for p in points]
    assert [r["key"] for r in rows] == keys


@pytest.mark.skipif(len(SEGMENTS_3D) == 0, reason="no 3D segment kept yet")
def test_the_3d_segments_are_the_default_3d_sweep_and_teach_each_layers_strain(tmp_path):
    """The 3D segments are the default 3D space with the 3D model's default options (as
    ``with_todays_defaults`` reads an earlier solver's; the
    fidelity of every row is its config's ``model.dimension``), and joined (one segment is
    copied, several are merged) they are a 3D sweep whose trusted designs a surrogate learns,
    each layer's largest strain among the trust outputs."""
    from sim.sweep import merge_sweeps
    from surrogate import read_sweep

    space = load_space(ROOT / "sim" / "data" / "default_space_3d.toml")
    want = SimOptions(model=ModelOptions("3d")).as_dict()
    for folder in SEGMENTS_3D:
        config = read_config(folder)
        assert config["space"] == space.to_dict() and config["seed"] == 0
        # a segment of an earlier solver at a default changed since counts as made at today's
        assert with_todays_defaults(config)["options"] == want
    joined = tmp_path / "sweep3d"
    if len(SEGMENTS_3D) == 1:
        shutil.copytree(SEGMENTS_3D[0], joined)
    else:
        merge_sweeps(SEGMENTS_3D, joined)
    data = read_sweep(joined, dimension="3d")
    assert len(data.points) == sum(len(_rows(f)) for f in SEGMENTS_3D)
    assert {"tapping_skin_max_compressive_log_strain", "tapping_core_max_compressive_log_strain",
            "contact_area_at_1N_mm2"} <= set(data.metric_names)  # fmt: skip
    assert data.whole.sum() > 0  # some designs settled and valid: their metrics are learnt


def test_the_same_metrics_study_reruns_a_3d_segment_with_its_own_options() -> None:
    """``studies/same_metrics.py`` on a kept 3D segment: the designs are re-run with the
    segment's own options (the 3D model, its mesh, today's defaults) and compared on the 3D
    metrics its table holds; on a 2D sweep with the default options, as before."""
    import importlib.util

    path = ROOT / "studies" / "same_metrics.py"
    spec = importlib.util.spec_from_file_location("same_metrics", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    folder = SEGMENTS_3D[0]
    options = module.sweep_options(folder)
    assert options.dimension == "3d"
    assert options == options_from_dict(with_todays_defaults(read_config(folder))["options"])
    first = int(folder.name.removeprefix("seg_").split("-")[0])
    rows = module.table_rows(folder, range(first, first + 4))
    assert sorted(rows) == list(range(first, first + 4))
    assert any("contact_area_at_4N_mm2" in row for row in rows.values())
    assert module.sweep_options(ROOT / "surrogate" / "pretrained" / "default") == SimOptions()
