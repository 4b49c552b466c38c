"""A design's protocols run as jobs of their own and joined (``sim.sweep.simulate_part``,
``point_record``, ``sim.simulate.merge_results``) give the record of the design run as one
(``evaluate_point``): the protocols share nothing, so the same machine gives the same bits."""

import dataclasses

import pytest
from sweep_fixtures import FAST

from explore._confirm import PART_ORDER, run_fe
from sim.design import load_space
from sim.geometry import COARSE_MESH_3D
from sim.metrics import PROTOCOLS, metric_registry
from sim.options import ModelOptions, SimOptions, apply_overrides, parse_override
from sim.simulate import merge_results
from sim.sweep import evaluate_point, point_record, sample_points, simulate_part

#: the tests' fast options (three taps, a 5 s wedge hold)
OPTIONS = apply_overrides(SimOptions(), dict(parse_override(s) for s in FAST[1::2]))
#: the same on the coarse 3D pad: the patch's metrics sit after the wedge's in the registry
OPTIONS_3D = dataclasses.replace(OPTIONS, model=ModelOptions("3d"), mesh3d=COARSE_MESH_3D)


def _without_times(record: dict) -> dict:
    times = ("wall_time_s", "cpu_time_s", "cost_by_protocol")
    return {k: v for k, v in record.items() if k not in times}


@pytest.fixture(scope="module")
def point() -> dict:
    return sample_points(load_space(), 1, 0)[0]


@pytest.mark.parametrize("options", [OPTIONS, OPTIONS_3D], ids=["2d", "3d"])
def test_protocols_run_apart_give_the_record_of_the_design_run_as_one(point, options):
    options_dict = options.as_dict()
    whole = evaluate_point(point, options_dict)
    parts = [simulate_part(point, options_dict, None, (p,)) for p in reversed(PROTOCOLS)]
    joined = point_record(point, parts)
    assert whole["status"] == "ok"
    assert _without_times(joined) == _without_times(whole)
    # the same order of every mapping too: the record's JSON is the same text
    assert list(joined["metrics"]) == list(whole["metrics"])
    assert list(joined["metrics"]) == list(metric_registry(options.dimension))
    assert list(joined["curves"]) == list(whole["curves"])
    assert list(joined["diagnostics"]) == list(whole["diagnostics"])
    assert joined["cpu_time_s"] == pytest.approx(sum(p.cpu_time_s for p in parts))
    # what each protocol cost, kept apart from the results: its parts' figures, within the
    # seconds of the part that ran it; the same counts as the design run as one
    cost, whole_cost = joined["cost_by_protocol"], whole["cost_by_protocol"]
    assert list(cost) == list(whole_cost) == list(PROTOCOLS)
    for name, part in zip(reversed(PROTOCOLS), parts, strict=True):
        assert 0.0 < cost[name]["wall_time_s"] <= part.wall_time_s
        assert cost[name]["factorizations"] >= 1 and cost[name]["newton_iterations"] >= 1
        counts = ("steps", "newton_iterations", "factorizations", "evaluations", "n_dofs")
        assert {k: cost[name][k] for k in counts} == {k: whole_cost[name][k] for k in counts}


def test_a_part_that_cannot_be_built_fails_the_record_with_its_reason(point):
    """A design the model refuses (here a layer thicker than the pad's section leaves no core)
    fails each part as it fails the whole."""
    bad = {**point, "layers.count": 2, "skin.thickness_mm": 50.0}
    options_dict = OPTIONS.as_dict()
    whole = evaluate_point(bad, options_dict)
    parts = [simulate_part(bad, options_dict, None, (p,)) for p in PROTOCOLS]
    joined = point_record(bad, parts)
    assert whole["status"] == joined["status"] == "failed"
    assert joined["reason"] == whole["reason"] and "DesignError" in whole["reason"]


def test_merge_refuses_overlapping_or_foreign_results(point):
    options_dict = OPTIONS.as_dict()
    plate = simulate_part(point, options_dict, None, ("plate",)).result
    with pytest.raises(ValueError, match="'plate' is in two"):
        merge_results([plate, plate])
    other = {**point, "geometry.height_mm": point["geometry.height_mm"] * 1.05}
    plate_other = simulate_part(other, options_dict, None, ("plate",)).result
    with pytest.raises(ValueError, match="one design"):
        merge_results([plate, plate_other])


def test_run_fe_on_two_workers_writes_the_records_of_one(point, tmp_path):
    """The FE confirmation splits its designs into protocols on several workers: the records
    it writes are those of one worker, which runs each design whole."""
    assert set(PART_ORDER) == set(PROTOCOLS)
    points = [point, sample_points(load_space(), 2, 0)[1]]
    one = run_fe([(tmp_path / "one" / f"{i}.json", p) for i, p in enumerate(points)],
                 OPTIONS, workers=1, progress=False)  # fmt: skip
    two = run_fe([(tmp_path / "two" / f"{i}.json", p) for i, p in enumerate(points)],
                 OPTIONS, workers=2, progress=False)  # fmt: skip
    for i in range(2):
        a, b = one[tmp_path / "one" / f"{i}.json"], two[tmp_path / "two" / f"{i}.json"]
        assert _without_times(a) == _without_times(b)
        assert (tmp_path / "two" / f"{i}.json").exists()
