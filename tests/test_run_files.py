"""One owner per run-folder file and one rule for which parameters a design uses (issue 16,
items 1 and 2): the atomic write, the JSON-safe conversion, trials.csv written then read, and
``DesignSpace.is_active`` / ``is_optional`` / ``complete`` against the rules they replace."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from explore._run_folder import (
    OBJECTIVE_NAMES,
    TIMING_KEYS,
    add_study,
    parameter_columns,
    read_config,
    read_studies,
    read_summary,
    read_trials,
    run_time,
    time_parts,
    trials_header,
    write_config,
    write_summary,
    write_trials,
)
from explore._search import TrialRow
from explore._types import Summary
from sim.design import (
    DEFAULT_SPACE_PATH,
    LAYER_ROLES,
    PARAM_MATERIAL_KEYS,
    active_roles,
    family_uses,
    load_space,
)
from sim.errors import DesignError
from sim.provenance import atomic_write, json_safe, json_text, write_if_changed, write_json

SPACES = {"default": DEFAULT_SPACE_PATH, "wide": DEFAULT_SPACE_PATH.parent / "wide_space.toml"}


def _points(space, n: int = 200, seed: int = 0) -> list[dict]:
    rng = np.random.default_rng(seed)
    return [space.point(rng.random(len(space.sampled))) for _ in range(n)]


# ---------------------------------------------------------------------------- writing files
def test_atomic_write_leaves_no_temporary_file(tmp_path):
    path = tmp_path / "a.json"
    atomic_write(path, "one")
    atomic_write(path, b"two")
    assert path.read_text() == "two" and [p.name for p in tmp_path.iterdir()] == ["a.json"]


def test_write_if_changed_writes_only_a_change(tmp_path):
    path = tmp_path / "t.csv"
    assert write_if_changed(path, "a\r\n")
    assert not write_if_changed(path, "a\r\n")
    assert not write_if_changed(path, "b", keep=lambda old: old == "a\r\n")
    assert write_if_changed(path, "b") and path.read_text() == "b"


def test_json_safe_is_strict_json():
    value = {"a": math.nan, "b": [1.0, math.inf, (np.float64(2.5), np.int64(3))], "c": None}
    out = json_safe(value)
    assert out == {"a": None, "b": [1.0, None, [2.5, 3]], "c": None}
    assert type(out["b"][2][1]) is int
    assert json.loads(json.dumps(out, allow_nan=False)) == out


def test_write_json_is_one_line_without_indent(tmp_path):
    write_json(tmp_path / "r.json", {"k": 1}, indent=None)
    assert (tmp_path / "r.json").read_text() == '{"k": 1}'


def test_every_json_writer_writes_a_non_finite_value_as_null(tmp_path):
    """Issue 31, item 1: one conversion for every JSON writer (``json_text``): NaN and
    infinities become null (a round's best FE score of inf crashed summary.json before), and
    anything else strict JSON cannot hold still raises (``allow_nan=False`` behind it)."""
    text = json_text({"a": math.inf, "b": [np.float64("nan"), 1.5]})
    assert text == '{"a": null, "b": [null, 1.5]}'
    with pytest.raises(TypeError):
        json_text({"a": object()})
    write_json(tmp_path / "r.json", {"x": -math.inf}, indent=None)
    assert (tmp_path / "r.json").read_text() == '{"x": null}'
    rounds = [{"round": 0, "best_fe_score": math.inf, "max_rel_error": math.nan}]
    summary = Summary({"best": None}, {"disp_at_1N_mm": 1.83}, 0.05, rounds, [])
    write_summary(tmp_path, summary, math.inf, {"fe_s": math.nan}, False)
    stored = read_summary(tmp_path)
    assert stored["rounds"] == [{"round": 0, "best_fe_score": None, "max_rel_error": None}]
    assert stored["wall_time_s"] is None and stored["timings"] == {"fe_s": None}
    # the same answer re-written: recognised as the one the file holds
    assert write_summary(tmp_path, summary, 2.0, {}, True)["wall_time_s"] is None


# ---------------------------------------------------------------------------- trials.csv
def test_trials_csv_round_trips_its_parameter_columns(tmp_path):
    space = load_space()
    points = _points(space, 12)
    rows = [
        TrialRow(
            round=0, trial=i, search="continuous", point=p, score=0.1 * i,
            objectives=(0.1, math.inf, 0.3),
            predicted={"disp_at_1N_mm": {"median": 1.5, "std": 0.1}},
            in_domain=True, disagreement=0.01, flags=() if i % 2 else ("x",),
        )
        for i, p in enumerate(points)
    ]  # fmt: skip
    write_trials(tmp_path, rows, space.names, ["disp_at_1N_mm"])
    columns, params = read_trials(tmp_path)
    assert params == tuple(space.names)
    assert list(columns) == trials_header(space.names, ["disp_at_1N_mm"])
    assert parameter_columns(list(columns)) == params
    for name in space.names:
        for value, cell in zip((p[name] for p in points), columns[name], strict=True):
            if isinstance(value, str):
                assert cell == value
            elif isinstance(value, float) and math.isnan(value):
                assert math.isnan(cell)
            else:
                assert cell == pytest.approx(value)
    assert np.isinf(columns["hysteresis_error"]).sum() == 0  # non-finite: an empty cell
    assert set(OBJECTIVE_NAMES) <= set(columns)


# ---------------------------------------------------------------------------- config and studies
def test_config_json_is_fixed_and_the_studies_have_their_own_log(tmp_path):
    """config.json is written once; the studies the rounds start go to studies.json (once
    each), which reads back in order."""
    record = {"storage": "sqlite:///x.db", "seed": 0}
    write_config(tmp_path, record, {"kind": "optimize"})
    config = (tmp_path / "config.json").read_bytes()
    assert read_config(tmp_path) == record and read_studies(tmp_path) == []
    add_study(tmp_path, "s-r0-continuous", "continuous", 0, "single")
    add_study(tmp_path, "s-r0-gel", "gel", 0, "multi")
    add_study(tmp_path, "s-r0-continuous", "continuous", 0, "single")  # a resume: once
    assert read_studies(tmp_path) == [
        {"name": "s-r0-continuous", "search": "continuous", "round": 0,
         "directions": ["minimize"]},
        {"name": "s-r0-gel", "search": "gel", "round": 0, "directions": ["minimize"] * 3},
    ]  # fmt: skip
    assert json.loads((tmp_path / "studies.json").read_text()) == read_studies(tmp_path)
    assert (tmp_path / "config.json").read_bytes() == config  # never rewritten
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "config.json",
        "meta.json",
        "studies.json",
    ]


def test_an_older_folder_keeps_its_studies_in_config_json(tmp_path):
    """A folder made before studies.json: its studies are read from config.json, and a resumed
    run continues them in studies.json, leaving config.json as it is."""
    old = {
        "name": "s-r0-continuous",
        "search": "continuous",
        "round": 0,
        "directions": ["minimize"],
    }
    (tmp_path / "config.json").write_text(
        json.dumps({"storage": "sqlite:///x.db", "studies": [old]})
    )
    config = (tmp_path / "config.json").read_bytes()
    assert read_studies(tmp_path) == [old]
    add_study(tmp_path, "s-r1-continuous", "continuous", 1, "single")
    assert [s["name"] for s in read_studies(tmp_path)] == ["s-r0-continuous", "s-r1-continuous"]
    assert (tmp_path / "config.json").read_bytes() == config


def test_an_older_folder_resumes_with_the_same_configuration(tmp_path):
    """Its config.json holds the studies beside the configuration: no reason to refuse it;
    another configuration is still refused in one line."""
    from explore._config import _check_resume

    record = {"storage": "sqlite:///x.db", "seed": 0, "workers": 2}
    studies = [{"name": "s-r0-continuous", "search": "continuous", "round": 0,
                "directions": ["minimize"]}]  # fmt: skip
    (tmp_path / "config.json").write_text(json.dumps({**record, "studies": studies}))
    _check_resume(tmp_path, {**record, "workers": 1})  # --workers may differ too
    with pytest.raises(DesignError, match=r"another configuration \(seed\)"):
        _check_resume(tmp_path, {**record, "seed": 1})


def test_a_config_json_that_is_no_search_configuration_is_one_error(tmp_path):
    (tmp_path / "config.json").write_text(json.dumps({"space": {}, "sampler": "sobol"}))
    with pytest.raises(DesignError, match="not the configuration of a search run"):
        read_config(tmp_path)


# ---------------------------------------------------------------------------- summary.json
def test_write_summary_returns_the_timing_the_file_keeps(tmp_path):
    """summary.json's timing is the invocation's that wrote the answer: a re-run with the same
    answer keeps the first one (and returns it, for ``Summary.timing``), a new answer its own."""
    summary = Summary({"best": None}, {"disp_at_1N_mm": 1.83}, 0.05, [], ["a note"])
    first = write_summary(tmp_path, summary, 3.5, {"fe_s": 2.0}, False)
    assert first == {"wall_time_s": 3.5, "timings": {"fe_s": 2.0}, "resumed": False}
    assert write_summary(tmp_path, summary, 9.0, {"fe_s": 0.0}, True) == first
    stored = read_summary(tmp_path)
    assert {k: stored[k] for k in TIMING_KEYS} == first
    assert {k: v for k, v in stored.items() if k not in TIMING_KEYS} == summary.to_json()
    other = Summary({"best": None}, {"disp_at_1N_mm": 1.83}, 0.05, [], ["another note"])
    assert write_summary(tmp_path, other, 1.0, {}, True)["wall_time_s"] == 1.0
    assert read_summary(tmp_path)["notes"] == ["another note"]


def test_a_resumed_run_counts_the_time_of_its_earlier_parts(tmp_path):
    """Issue 31, item 6c: each invocation records its time in time.json as each stage ends,
    an interrupted stage too; the run's time (what summary.json holds and `fingertip optimize`
    prints) sums every part, the killed ones included."""
    from explore._config import OptimizeConfig
    from explore._rounds import Search
    from explore.cli import _time_line

    killed = Search(OptimizeConfig(), tmp_path, None, None, None, time_part=time_parts(tmp_path))
    with killed.timed("search_s"):
        killed.started -= 100.0  # it had run 100 s before this stage ended
    with pytest.raises(KeyboardInterrupt), killed.timed("fe_s"):
        raise KeyboardInterrupt  # a kill in the middle of its FE: the stage still counts
    resumed = Search(OptimizeConfig(), tmp_path, None, None, None, time_part=time_parts(tmp_path))
    assert resumed.time_part == 1
    with resumed.timed("fe_s"):
        resumed.started -= 7.0
    wall, timings = run_time(tmp_path)
    assert wall == pytest.approx(107.0, abs=1.0)  # both parts, not the last one's 7 s
    assert set(timings) == {"search_s", "fe_s", "retrain_s"}
    assert len(json.loads((tmp_path / "time.json").read_text())) == 2
    line = _time_line({"wall_time_s": wall, "timings": timings, "resumed": True})
    assert line.startswith("time: search 0 s, FE 0 s, retraining 0 s; 107 s in all")
    assert "earlier parts included" in line
    # run --from-scratch: its sweep and training are stages of the run too
    assert "sweep 3600 s, training 60 s, search" in _time_line(
        {"wall_time_s": 4000.0, "timings": {"sweep_s": 3600.0, "train_s": 60.0}}
    )


# ---------------------------------------------------------------------------- the one rule
def _old_used(point: dict, name: str) -> bool:
    """``explore._search._used`` before the rule was ``DesignSpace.is_active``."""
    head, _, key = name.partition(".")
    if head in ("geometry", "layers"):
        return True
    count = point.get("layers.count")
    if count is None:
        return True
    if head not in active_roles(count):
        return False
    if key == "thickness_mm":
        return head != "core"
    if key in PARAM_MATERIAL_KEYS:
        return family_uses(point.get(f"{head}.material"), key)
    return True


def _old_optional(space, name: str) -> bool:
    """``surrogate._encoding.is_optional`` before it was ``DesignSpace.is_optional``."""
    head, key = name.split(".", 1)
    if head not in LAYER_ROLES:
        return False
    count = space["layers.count"]
    counts = count.choices if count.kind == "choice" else (count.value,)
    always = all(head in active_roles(c) for c in counts)
    if key in ("material", "thickness_mm"):
        return not always
    m = space[f"{head}.material"]
    names = m.choices if m.kind == "choice" else (m.value,)
    return not (always and all(family_uses(x, key) for x in names))


def _old_complete(space, params: dict) -> dict:
    """``explore._search.point_from_params`` before it was ``DesignSpace.complete``."""
    from sim.design import mask_inactive

    full = {}
    for p in space.parameters:
        if p.name in params:
            full[p.name] = params[p.name]
        elif not p.sampled:
            full[p.name] = p.from_unit(0.0)
        else:
            full[p.name] = "" if p.kind == "choice" else math.nan
    return mask_inactive(full)


def _same(a: dict, b: dict) -> bool:
    return list(a) == list(b) and all(
        (isinstance(a[k], float) and math.isnan(a[k]) and math.isnan(b[k])) or a[k] == b[k]
        for k in a
    )


@pytest.mark.parametrize("which", sorted(SPACES))
def test_is_active_agrees_with_the_old_rule(which):
    space = load_space(SPACES[which])
    for point in _points(space):
        for name in space.names:
            assert space.is_active(name, point) == _old_used(point, name), name
            blank = point[name] == "" or (
                isinstance(point[name], float) and math.isnan(point[name])
            )
            assert space.is_active(name, point) == (not blank), name  # the masking agrees
            # a define-by-run prefix: the parameters chosen before ``name``, in space order
            prefix = {n: point[n] for n in space.names[: space.names.index(name)]}
            assert space.is_active(name, prefix) == _old_used(prefix, name), name


@pytest.mark.parametrize("which", sorted(SPACES))
def test_is_optional_and_complete_agree_with_the_old_rules(which):
    space = load_space(SPACES[which])
    for name in space.names:
        assert space.is_optional(name) == _old_optional(space, name), name
    for point in _points(space, 50, seed=1):
        used = {n: v for n, v in point.items() if space.is_active(n, point) and space[n].sampled}
        assert _same(space.complete(used), _old_complete(space, used))
        assert _same(space.complete(used), point)
