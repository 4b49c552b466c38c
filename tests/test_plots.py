"""Design-space figures and the run report: the numbers behind every figure (info objects)."""

from __future__ import annotations

import csv
import dataclasses
import itertools
import json
import math
from pathlib import Path

import numpy as np
import optuna
import pytest

from explore._objective import closeness
from explore._plots import (
    ANSWER_NAMES,
    FIGURES,
    LOG_TICKS_PER_DECADE,
    importance_info,
    load_run,
    log_axis,
    log_ticks,
    loops_info,
    parallel_info,
    pareto_front_indices,
    pareto_info,
    parity_info,
    projections_info,
    wedge_info,
    write_figures,
)
from explore._report import write_report
from explore._storage import open_storage
from explore._types import Candidate, Confirmation
from sim.design import Targets, load_targets, loading_curve

HUMAN = {"disp_at_1N_mm": 1.83, "disp_at_4N_mm": 2.91, "hysteresis_Nmm": 2.26}
F_REF = 2.35  # explore._objective.WEDGE_REFERENCE_N
PARAMS = ("geometry.half_width_mm", "skin.thickness_mm", "core.material", "core.mu0_MPa")
NUMERIC = ("geometry.half_width_mm", "skin.thickness_mm", "core.mu0_MPa", "core.g_total")
N_TRIALS = 40
INF_ROW = 5  # a trial whose score is infinite (a failed prediction)
# Hand-checked objectives of the first rows; every other row is >= 0.6 in all three, so the
# non-dominated set is exactly rows 0-3 (rows 0 and 3 are equal: neither dominates the other).
FRONT_ROWS = {
    0: (0.01, 0.5, 0.5),
    1: (0.5, 0.01, 0.5),
    2: (0.5, 0.5, 0.01),
    3: (0.01, 0.5, 0.5),
    4: (math.nan, 0.1, 0.1),  # not finite: left out
}
# Confirmations: FE metrics as factors of the targets (wedge as a factor of F_REF), and the
# surrogate's disp_at_1N_mm prediction (mean, lower_90, upper_90) for the parity check.
CONFIRMED = (
    ("best", 7, (1.1, 0.9, 1.2, 0.5), (2.1, 1.9, 2.3)),  # FE 2.013: inside
    ("uncertain", 11, (0.8, 1.0, 0.9, 1.0), (1.7, 1.6, 1.8)),  # FE 1.464: below
    ("buildable", 3, (0.5, 0.6, 0.3, 2.0), (0.85, 0.8, 0.9)),  # FE 0.915: above
)


def _objective(trial: optuna.Trial) -> float:
    """Cheap analytic score: the skin thickness dominates by far."""
    hw = trial.suggest_float("geometry.half_width_mm", 5.0, 7.0)
    t = trial.suggest_float("skin.thickness_mm", 0.2, 1.5)
    score = 5.0 * (t - 0.6) ** 2 + 0.002 * (hw - 6.0) ** 2 + 0.01
    if trial.suggest_categorical("core.material", ["param", "silicone_gls40"]) == "param":
        mu = trial.suggest_float("core.mu0_MPa", 0.001, 0.3, log=True)
        g = trial.suggest_float("core.g_total", 0.0, 0.9)
        score += 0.001 * abs(math.log10(mu)) + 0.001 * g
    trial.set_user_attr("score", score)
    return score


def _tapping(scale: float) -> dict[str, list[float]]:
    t = np.linspace(0.0, 1.0, 41)
    force = 4.5 * np.sin(np.pi * t)
    disp = 0.05 + scale * (np.sqrt(force / 4.5) + 0.1 * np.sin(2 * np.pi * t) ** 2 * (t > 0.5))
    return {"time_s": t.tolist(), "displacement_mm": disp.tolist(), "force_N": force.tolist()}


def _record(key: str, metrics: dict[str, float], scale: float) -> dict:
    time = np.concatenate([np.linspace(0, 1, 21), np.linspace(2, 100, 10)])
    wedge = metrics["wedge_peak_force_N"] * np.minimum(time, 1.0) * (1 - 0.002 * time)
    dist = np.arange(0, 7.0, 0.1)
    profile = {"distance_mm": dist.tolist(), "deflection_mm": (scale * np.exp(-dist)).tolist()}
    return {
        "key": key,
        "status": "ok",
        "metrics": metrics,
        "curves": {
            "tapping": _tapping(scale),
            "plate": {"displacement_mm": [0.0, 0.5, 1.0], "force_N": [0.0, 5.0, 20.0]},
            "wedge": {"time_s": time.tolist(), "force_N": wedge.tolist()},
            "profile_1s": profile,
            "profile_100s": profile,
        },
    }


def _metrics(factors: tuple[float, float, float, float]) -> dict[str, float]:
    values = [HUMAN[k] * f for k, f in zip(HUMAN, factors[:3], strict=True)]
    return {**dict(zip(HUMAN, values, strict=True)), "wedge_peak_force_N": F_REF * factors[3]}


def _confirmations(run: Path) -> list[Confirmation]:
    out = []
    for k, (reason, trial, factors, (mean, lo, hi)) in enumerate(CONFIRMED):
        metrics = _metrics(factors)
        predicted = {
            m: {"mean": 1.05 * v, "std": 0.05 * v, "lower_90": 0.9 * v, "upper_90": 1.1 * v}
            for m, v in metrics.items()
        }
        predicted["disp_at_1N_mm"] = {"mean": mean, "std": 0.1, "lower_90": lo, "upper_90": hi}
        flags = ("high disagreement 0.12 > 0.05",) if k == 1 else ()
        point = {"geometry.half_width_mm": 6.0, "skin.thickness_mm": 0.3 + 0.2 * k}
        core = {"core.mu0_MPa": 0.01, "core.g_total": 0.3} if reason != "buildable" else {}
        point |= {"core.material": "param" if core else "silicone_gls40", **core}
        cand = Candidate(point, reason, 0, trial, "continuous", 0.1, predicted, True, 0.01, flags)
        score = float(closeness(metrics, Targets(values=HUMAN)).score)
        out.append(Confirmation(cand, f"key{k}", "ok", "", metrics, score))
        record = _record(f"key{k}", metrics, 1.0 + k)
        (run / "fe" / "records" / f"key{k}.json").write_text(json.dumps(record))
    wide = {"disp_at_1N_mm": {"mean": 1.0, "lower_90": 0.0, "upper_90": 9.0}}
    failed = Candidate(
        {"skin.thickness_mm": 1.4}, "uncertain", 0, 20, "continuous", 0.2, wide, False, 0.3
    )
    out.append(Confirmation(failed, "key_failed", "failed", "did not converge", {}, math.inf))
    return out


def _write_trials(run: Path, study: optuna.Study) -> None:
    rng = np.random.default_rng(0)
    objective_names = ("compliance_error", "hysteresis_error", "wedge_effort")
    surrogate = ("pred.disp_at_1N_mm", "std.disp_at_1N_mm", "in_domain", "disagreement")
    header = [
        "round",
        "trial",
        "search",
        *PARAMS,
        "core.g_total",
        "score",
        *objective_names,
        *surrogate,
        "trusted",
    ]
    with (run / "trials.csv").open("w", newline="") as fh:
        writer = csv.DictWriter(fh, header)
        writer.writeheader()
        for t in study.trials:
            objs = FRONT_ROWS.get(t.number, tuple(0.6 + rng.random(3)))
            score = math.inf if t.number == INF_ROW else t.user_attrs["score"]
            row = dict(zip(surrogate, (1.5, 0.1, 1, 0.01), strict=True))
            row |= {"round": 0, "trial": t.number, "search": "continuous", "score": score}
            row["trusted"] = int(t.number % 4 != 0)
            for name, v in zip(objective_names, objs, strict=True):
                row[name] = "" if math.isnan(v) else v
            row |= {p: t.params.get(p, "") for p in (*PARAMS, "core.g_total")}
            writer.writerow(row)


def _summary(confirmations: list[Confirmation]) -> dict:
    best, buildable = confirmations[0], confirmations[2]
    design_best = {
        "geometry": {"half_width_mm": 6.1, "height_mm": 5.2, "exponent": 1.7},
        "layers": [
            {"thickness_mm": 0.5, "material": "silicone_gls40"},
            {
                "material": {
                    "model": "hyperfoam",
                    "mu_MPa": [0.012],
                    "alpha": [4.2],
                    "nu": 0.48,
                    "prony_g": [0.2, 0.2, 0.2],
                    "prony_tau_s": [0.1, 1.0, 10.0],
                }
            },
        ],
    }
    design_build = {
        "geometry": {"half_width_mm": 5.84, "height_mm": 5.48, "exponent": 1.5},
        "layers": [{"material": "ecoflex_0010_dawood"}],
    }

    def answer(c: Confirmation, design: dict) -> dict:
        errors = {k: c.fe_metrics[k] / HUMAN[k] - 1 for k in HUMAN}
        within = {k: abs(e) <= 0.15 for k, e in errors.items()}
        return {
            "design": design,
            "point": c.candidate.point,
            "predicted": c.candidate.predicted,
            "fe_metrics": c.fe_metrics,
            "fe_score": c.fe_score,
            "errors_vs_targets": errors,
            "within_tolerance": within,
            "fe_record": f"fe/records/{c.key}.json",
        }

    # as explore._summary writes them: the best design is also the best gel one (one record,
    # two answers), and no foam design was credible (null)
    return {
        "answers": {
            "best": answer(best, design_best),
            "gel": answer(best, design_best),
            "foam": None,
            "buildable": answer(buildable, design_build),
        },
        "targets": HUMAN,
        "tolerance": 0.15,
        "rounds": [
            {
                "round": 0,
                "n_confirmed": 4,
                "max_rel_error": 0.16,
                "median_rel_error": 0.05,
                "agreed": False,
            }
        ],
        "notes": ["The best design's hysteresis is 20 % above the target."],
    }


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small finished run: 40 trials, 3 confirmed designs + 1 failed, 2 references."""
    run = tmp_path_factory.mktemp("run")
    (run / "fe" / "records").mkdir(parents=True)
    (run / "fe" / "references").mkdir()
    storage = str(run / "study.log")  # the run folder's journal (explore._storage)
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    scratch = optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=3))
    scratch.optimize(_objective, n_trials=N_TRIALS)
    study = optuna.create_study(storage=open_storage(storage), study_name="r0-continuous")
    study.add_trials(scratch.trials)
    _write_trials(run, study)
    confirmations = _confirmations(run)
    (run / "confirmations.json").write_text(json.dumps([c.to_json() for c in confirmations]))
    for name, scale in (("silicone_gls40", 0.3), ("polyurethane_74_45", 0.2)):
        metrics = _metrics((0.2, 0.3, 0.1, 1.0 + scale))
        rec = _record(name, metrics, scale)
        (run / "fe" / "references" / f"{name}.json").write_text(json.dumps(rec))
    (run / "summary.json").write_text(json.dumps(_summary(confirmations)))
    studies = [
        {"name": "r0-buildable", "search": "buildable", "round": 0, "directions": ["minimize"]},
        {"name": "r0-continuous", "search": "continuous", "round": 0, "directions": ["minimize"]},
    ]
    config = {"targets": HUMAN, "storage": storage}
    (run / "config.json").write_text(json.dumps(config))
    (run / "studies.json").write_text(json.dumps(studies))
    return run


def _dominates(a: np.ndarray, b: np.ndarray) -> bool:
    return bool(np.all(a <= b) and np.any(a < b))


# ---------------------------------------------------------------------------------------------


def test_load_run_reads_every_file_and_marks_inactive_as_nan(run_dir: Path) -> None:
    run = load_run(run_dir)
    assert run.n_trials == N_TRIALS
    assert set(run.params) == {*PARAMS, "core.g_total"}
    assert set(run.numeric_params) == set(NUMERIC)  # the categorical and pred./std. left out
    assert len(run.confirmations) == 4
    assert set(run.records) == {"key0", "key1", "key2"}  # the failed one has no record
    assert set(run.references) == {"silicone_gls40", "polyurethane_74_45"}
    inactive = run.trials["core.material"] != "param"
    assert inactive.any() and (~inactive).any()
    assert np.all(np.isnan(run.trials["core.mu0_MPa"][inactive]))
    assert np.all(np.isfinite(run.trials["core.mu0_MPa"][~inactive]))
    assert math.isinf(run.column("score")[INF_ROW])


def test_pareto_front_of_a_hand_checked_example() -> None:
    points = np.array(
        [
            [1.0, 2.0, 3.0],  # 0: front
            [2.0, 1.0, 3.0],  # 1: front
            [2.0, 2.0, 3.0],  # 2: dominated by 0 and 1
            [1.0, 2.0, 3.0],  # 3: equal to 0, so not dominated
            [0.5, 5.0, 5.0],  # 4: front (best first objective)
            [3.0, 3.0, 0.0],  # 5: front (best third objective)
            [3.0, 3.0, 0.5],  # 6: dominated by 5
        ]
    )
    assert pareto_front_indices(points).tolist() == [0, 1, 3, 4, 5]
    assert pareto_front_indices(np.zeros((0, 3))).tolist() == []


@pytest.mark.parametrize("chunk", [1, 7, 1024])
def test_pareto_front_is_exactly_the_non_dominated_set(chunk: int) -> None:
    points = np.round(np.random.default_rng(1).random((60, 3)), 1)  # rounding makes ties
    front = set(pareto_front_indices(points, chunk=chunk).tolist())
    for i, j in itertools.product(range(len(points)), repeat=2):
        if i in front:
            assert not _dominates(points[j], points[i])
    for i in set(range(len(points))) - front:
        assert any(_dominates(points[j], points[i]) for j in front)


def test_pareto_info_finds_the_planted_front_and_recomputes_fe_objectives(run_dir: Path) -> None:
    info = pareto_info(load_run(run_dir))
    # row 4 has a NaN objective and is dropped (INF_ROW has an infinite score, finite objectives)
    assert len(info.points) == N_TRIALS - 1 and 4 not in info.rows.tolist()
    assert info.rows[info.front].tolist() == [0, 1, 2, 3]
    for i in info.front:
        assert not any(_dominates(p, info.points[i]) for p in info.points)
    # FE objectives of the first confirmation: errors +10 %, -10 %, +20 %, wedge 0.5 F_ref
    assert len(info.confirmed) == 3  # the failed confirmation is left out
    np.testing.assert_allclose(info.confirmed[0], [0.1, 0.2, 0.5], rtol=1e-12)
    assert info.confirmed_labels[0] == "best r0/t7"


def test_parallel_coordinates_are_normalised_with_nan_for_inactive(run_dir: Path) -> None:
    run = load_run(run_dir)
    info = parallel_info(run)
    ok = np.isfinite(run.column("score"))
    assert info.params == run.numeric_params
    assert info.values.shape == (ok.sum(), len(info.params))
    for k, name in enumerate(info.params):
        col = info.values[:, k]
        raw = run.trials[name][ok]
        np.testing.assert_array_equal(np.isnan(col), np.isnan(raw))
        assert np.nanmin(col) == 0.0 and np.nanmax(col) == 1.0
        lo, hi = info.low[k], info.high[k]
        back = lo * (hi / lo) ** col if info.log[k] else lo + col * (hi - lo)
        np.testing.assert_allclose(back, raw)
        assert info.log[k] == (name == "core.mu0_MPa")  # 0.001-0.3 MPa spans decades
    n_best = math.ceil(0.1 * ok.sum())
    assert info.best.sum() == n_best
    assert info.score[info.best].max() <= info.score[~info.best].min()


def test_parallel_highlights_the_best_k_by_score_drawn_best_last(run_dir: Path) -> None:
    """The coloured lines are exactly the best k trials by score, drawn worst of them first (the
    best on top); every other trial is one grey line behind them."""
    from explore._plots import render_parallel

    info = parallel_info(load_run(run_dir), best_fraction=0.25)
    k = math.ceil(0.25 * len(info.score))
    assert set(np.flatnonzero(info.best)) == set(np.argsort(info.score, kind="stable")[:k])
    order = info.best_order
    assert sorted(order) == sorted(np.flatnonzero(info.best))
    assert np.all(np.diff(info.score[order]) <= 0) and order[-1] == np.argmin(info.score)
    fig = render_parallel(info)
    ax = fig.axes[0]
    grey, ramp, best = ax.collections[:3]
    coloured = np.asarray(ramp.get_array())
    assert set(coloured) == set(info.score[info.best])  # coloured: the best k, by their score
    assert coloured[-1] == info.score.min()  # the very best drawn last (on top), and in black
    assert len(best.get_segments()) >= 1 and grey.get_alpha() < 0.5
    bar = fig.axes[1]
    assert "best 25 %" in bar.get_ylabel() and "lower is better" in bar.get_ylabel()
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert legend[0] == f"other trials ({len(info.score) - k})"
    assert legend[1].startswith(f"best 25 % ({k} trials)")


def test_parity_inside_fraction_and_median_error_match_a_hand_computation(run_dir: Path) -> None:
    info = parity_info(load_run(run_dir))
    by_name = {m.name: m for m in info.metrics}
    assert set(by_name) == {*HUMAN, "wedge_peak_force_N"}
    d1 = by_name["disp_at_1N_mm"]
    assert len(d1.fe) == 3  # status ok only
    assert d1.inside_fraction == pytest.approx(1 / 3)  # one inside, one below, one above
    fe = np.array([1.83 * 1.1, 1.83 * 0.8, 1.83 * 0.5])
    rel = np.abs(np.array([2.1, 1.7, 0.85]) - fe) / fe  # 4.3 %, 16.1 %, 7.1 %
    assert d1.median_abs_rel_error == pytest.approx(np.median(rel))
    assert d1.median_abs_rel_error == pytest.approx(0.065 / 0.915)
    wedge = by_name["wedge_peak_force_N"]
    assert wedge.inside_fraction == 1.0 and wedge.median_abs_rel_error == pytest.approx(0.05)


def test_loops_show_the_answers_of_summary_json_by_name(run_dir: Path) -> None:
    run = load_run(run_dir)
    info = loops_info(run)
    answers = {k for k, v in run.summary["answers"].items() if v}
    assert set(info.answers) == answers and len(info.answers) == len(answers)
    assert info.answers == ("best", "gel", "buildable")  # report order
    assert info.missing == ("foam",)  # null in summary.json: no curve, and said so
    designs = [c for c in info.curves if c.role == "answer"]
    refs = [c for c in info.curves if c.role == "reference"]
    # one record that is two answers is one curve, named by both
    assert [c.answers for c in designs] == [("best", "gel"), ("buildable",)]
    assert [c.label.split(" (")[0] for c in designs] == ["best credible = gel", "buildable"]
    assert all(ANSWER_NAMES[k] in c.label for c in designs for k in c.answers)
    assert {c.label for c in refs} == {"silicone_gls40", "polyurethane_74_45"}
    tap = run.records["key0"]["curves"]["tapping"]
    np.testing.assert_array_equal(designs[0].x, tap["displacement_mm"])
    np.testing.assert_array_equal(designs[0].y, tap["force_N"])
    assert designs[0].value == pytest.approx(2.26 * 1.2)  # the record's hysteresis
    assert max(c.y.max() for c in info.curves) >= 4.0  # the loops reach the 4 N target
    assert info.target_points == ((1.83, 1.0), (2.91, 4.0))
    assert info.target_hysteresis_Nmm == 2.26


def test_loops_draw_the_human_loading_curve_of_the_sourced_points(run_dir: Path) -> None:
    """The human curve is F = B (exp(k d) - 1) through Serina et al.'s 1 N and 4 N points
    (sim.design.targets.LOADING_CURVE_SOURCE); B = 0.1243 N, k = 1.2035 1/mm are the values derived
    in docs/fingertip_3d.md ("Human force-displacement curve"), checked here at a few points."""
    info = loops_info(load_run(run_dir))
    assert info.human_is_finger and info.human is not None and info.human.role == "human"
    b, k = info.human_fit
    assert (b, k) == pytest.approx((0.1243, 1.2035), abs=5e-5)
    d, f = info.human.x, info.human.y
    np.testing.assert_allclose(f, b * np.expm1(k * d), rtol=1e-12)
    # the docs' table: displacement (mm) at 0.25, 0.5, 2, 3 and 5 N, and the two targets
    table = {0.25: 0.92, 0.5: 1.34, 1.0: 1.83, 2.0: 2.36, 3.0: 2.68, 4.0: 2.91, 5.0: 3.09}
    np.testing.assert_allclose(np.interp(list(table), f, d), list(table.values()), atol=0.006)
    assert d[0] == 0.0 and f[0] == 0.0 and f[-1] == pytest.approx(5.0)  # up to the tap's peak
    assert info.human.value == 2.26  # the target hysteresis goes with it
    curve = loading_curve()  # the human targets: the same curve
    assert curve.force([1.83, 2.91]) == pytest.approx([1.0, 4.0], rel=1e-9)
    assert curve.displacement(curve.force(2.5)) == pytest.approx(2.5)
    assert "Serina" in curve.source and "not Serina et al.'s own fit" in curve.source
    assert load_targets().values == HUMAN  # the values it is drawn through are unchanged


def test_loading_curve_through_other_targets_and_none_without_a_rise() -> None:
    soft = loading_curve(Targets(values={"disp_at_1N_mm": 1.0, "disp_at_4N_mm": 5.0}))
    assert soft.k_per_mm < 0  # rises less than proportionally: concave
    assert soft.force([1.0, 5.0]) == pytest.approx([1.0, 4.0], rel=1e-9)
    line = loading_curve(Targets(values={"disp_at_1N_mm": 1.0, "disp_at_4N_mm": 4.0}))
    assert line.force([1.0, 2.0, 4.0]) == pytest.approx([1.0, 2.0, 4.0], rel=1e-6)
    assert loading_curve(Targets(values={"disp_at_1N_mm": 2.0, "disp_at_4N_mm": 1.0})) is None


def test_an_answer_of_the_fe_only_screen_is_drawn_from_its_record(run_dir, tmp_path) -> None:
    """A buildable answer found by the FE-only screen is no confirmation: its record is read
    through summary.json's ``fe_record``; an answer whose record is missing is listed."""
    import shutil

    run = tmp_path / "run"
    shutil.copytree(run_dir, run, ignore=shutil.ignore_patterns("figures"))
    record = json.loads((run / "fe" / "records" / "key2.json").read_text())
    (run / "fe" / "records" / "screen0.json").write_text(json.dumps({**record, "key": "screen0"}))
    summary = json.loads((run / "summary.json").read_text())
    summary["answers"]["buildable"]["fe_record"] = "fe/records/screen0.json"
    summary["answers"]["foam"] = {**summary["answers"]["gel"], "fe_record": "fe/records/x.json"}
    summary["answers"]["gel"] = None
    (run / "summary.json").write_text(json.dumps(summary))
    info = loops_info(load_run(run))
    assert info.answers == ("best", "buildable") and info.missing == ("gel", "foam")
    assert wedge_info(load_run(run)).answers == ("best", "buildable")


def test_first_touch_loops_start_at_zero_displacement(run_dir: Path) -> None:
    run = load_run(run_dir)
    targets = {**HUMAN, "displacement_reading": "from_first_touch"}
    touch = dataclasses.replace(run, config={**run.config, "targets": targets})
    info = loops_info(touch)
    assert info.reading == "from_first_touch"
    assert all(c.x[0] == 0.0 for c in info.curves)


def test_wedge_info_has_the_same_answers_with_force_and_profiles(run_dir: Path) -> None:
    run = load_run(run_dir)
    info = wedge_info(run)
    assert info.answers == loops_info(run).answers == ("best", "gel", "buildable")
    assert info.missing == ("foam",)
    assert len(info.force) == len(info.profile_1s) == len(info.profile_100s) == 4
    peaks = [c.value for c in info.force if c.role == "answer"]
    np.testing.assert_allclose(peaks, [F_REF * f for f in (0.5, 2.0)])
    for c in info.force:
        assert c.y.max() == pytest.approx(c.value, rel=0.01)  # curve peak = recorded peak
    assert all(c.x[0] == 0.0 and np.all(np.diff(c.x) > 0) for c in info.profile_1s)


def test_importance_ranks_the_dominant_parameter_first(run_dir: Path) -> None:
    info = importance_info(load_run(run_dir))
    assert info.study_name == "r0-continuous"  # the first *continuous* study, not buildable
    assert info.names[0] == "skin.thickness_mm"
    assert sum(info.importances) == pytest.approx(1.0)
    assert list(info.importances) == sorted(info.importances, reverse=True)


def test_an_older_run_folder_finds_its_study_in_config_json(run_dir: Path, tmp_path) -> None:
    """Folders made before studies.json kept the studies' log in config.json."""
    import shutil

    old = tmp_path / "old"
    shutil.copytree(run_dir, old)
    studies = json.loads((old / "studies.json").read_text())
    (old / "studies.json").unlink()
    config = json.loads((old / "config.json").read_text())
    (old / "config.json").write_text(json.dumps({**config, "studies": studies}))
    run = load_run(old)
    assert run.studies == tuple(studies)
    assert importance_info(run).study_name == "r0-continuous"


def test_projections_follow_importance_and_drop_infinite_scores(run_dir: Path) -> None:
    run = load_run(run_dir)
    importance = importance_info(run)
    info = projections_info(run, top=4, importance=importance)
    expected = [n for n in importance.names if n in run.numeric_params]
    assert list(info.params) == expected and info.ranked_by == "importance"
    assert info.params[0] == "skin.thickness_mm" and len(info.pairs) == 6
    full = next(p for p in info.pairs if "core." not in p.x_name + p.y_name)
    assert len(full.x) == N_TRIALS - 1  # the infinite score is left out
    assert np.all(np.isfinite(full.score))
    assert len(full.confirmed_x) == len(full.confirmed_y) == 3  # FE status ok only
    assert np.all(np.isfinite(full.confirmed_x) & np.isfinite(full.confirmed_y))
    mu = next(p for p in info.pairs if "core.mu0_MPa" in (p.x_name, p.y_name))
    coords = mu.confirmed_x if mu.x_name == "core.mu0_MPa" else mu.confirmed_y
    np.testing.assert_array_equal(coords, [0.01, 0.01, np.nan])  # buildable: no param core
    assert (mu.x_log, mu.y_log) == (mu.x_name == "core.mu0_MPa", mu.y_name == "core.mu0_MPa")


def test_an_older_run_folder_reads_its_sqlite_study(tmp_path: Path, run_dir: Path) -> None:
    """Run folders made before the journal keep their study.db (config.json names it)."""
    import shutil

    old = tmp_path / "old"
    shutil.copytree(run_dir, old, ignore=shutil.ignore_patterns("study.log*", "figures"))
    trials = optuna.load_study(study_name="r0-continuous", storage=open_storage(
        str(run_dir / "study.log"))).trials  # fmt: skip
    url = f"sqlite:///{old / 'study.db'}"
    optuna.create_study(storage=url, study_name="r0-continuous").add_trials(trials)
    config = json.loads((old / "config.json").read_text())
    (old / "config.json").write_text(json.dumps({**config, "storage": url}))
    run = load_run(old)
    assert importance_info(run).study_name == "r0-continuous"
    assert importance_info(run).names == importance_info(load_run(run_dir)).names


def test_projections_fall_back_to_variation_without_a_study(tmp_path: Path, run_dir: Path) -> None:
    run = load_run(run_dir)
    missing = tmp_path / "nowhere.db"
    config = {**run.config, "storage": f"sqlite:///{missing}"}
    no_study = dataclasses.replace(run, run_dir=tmp_path, config=config)
    importance = importance_info(no_study)
    assert importance.empty and not missing.exists()  # loading must not create a database
    info = projections_info(no_study, top=2, importance=importance)
    assert info.ranked_by == "variation" and len(info.pairs) == 1


def test_report_writes_every_figure_and_links_it(run_dir: Path) -> None:
    text = write_report(run_dir).read_text()  # calls write_figures (rendering twice is slow)
    assert sorted(p.stem for p in (run_dir / "figures").glob("*.png")) == sorted(FIGURES)
    for name in FIGURES:
        png = (run_dir / "figures" / f"{name}.png").read_bytes()
        assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 5000
    assert "Best credible design" in text and "Best buildable design" in text
    assert "silicone_gls40" in text and "ecoflex_0010_dawood" in text
    assert "| `hysteresis_Nmm` | 2.26 | 2.71 | +20.0 % | ✗ |" in text
    for name in FIGURES:
        assert f"(figures/{name}.png)" in text
    assert f"`optuna-dashboard {run_dir.as_posix()}/study.log`" in text
    assert "high disagreement 0.12 > 0.05" in text and "20 % above the target" in text
    # one row per confirmed design in the surrogate-vs-FE table, errors as the run recorded
    table = text.split("## Confirmed designs: surrogate vs FE")[1].split("\n## ")[0]
    rows = [line for line in table.splitlines() if line.startswith("| ") and "---" not in line]
    confs = json.loads((run_dir / "confirmations.json").read_text())
    assert len(rows) == 1 + len(confs)  # header + designs
    for row, c in zip(rows[1:], confs, strict=True):
        err = c["rel_error"].get("disp_at_1N_mm")
        assert (f"{100 * err:+.1f} %" if err is not None else "–") in row


def test_an_empty_run_folder_does_not_crash(tmp_path: Path) -> None:
    (tmp_path / "config.json").write_text(json.dumps({"targets": HUMAN}))
    run = load_run(tmp_path)
    assert run.n_trials == 0 and not run.confirmations and not run.summary
    assert pareto_info(run).empty and parallel_info(run).empty and parity_info(run).empty
    assert importance_info(run).empty and projections_info(run).empty
    assert loops_info(run).target_points and not loops_info(run).curves
    paths = write_figures(tmp_path)
    assert list(paths) == list(FIGURES)
    assert all(p == tmp_path / "figures" / f"{n}.png" for n, p in paths.items())
    assert all(p.read_bytes()[:4] == b"\x89PNG" for p in paths.values())
    text = write_report(tmp_path).read_text()
    assert "No summary.json" in text and "(figures/parity.png)" in text
    assert not (tmp_path / "study.db").exists()


def test_figures_drawn_in_two_processes_are_the_same_bytes(run_dir: Path, tmp_path: Path) -> None:
    """``write_figures(workers=2)`` (what ``write_report`` does for a run with two FE workers)
    draws in child processes: the PNGs are those drawn in this one, byte for byte."""
    import shutil

    other = tmp_path / "copy"
    shutil.copytree(run_dir, other)
    one = write_figures(run_dir, workers=1)
    two = write_figures(other, workers=2)
    assert list(one) == list(two) == list(FIGURES)
    for name in FIGURES:
        assert one[name].read_bytes() == two[name].read_bytes(), name


# ---------------------------------------------------------------------------------------------
# Legibility: labels that do not overlap, titles inside the figure, one direction of deflection
# ---------------------------------------------------------------------------------------------


def _text_boxes(fig, texts):
    """The boxes of the texts themselves (an annotation's own extent includes its line)."""
    from matplotlib.text import Text

    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    return [Text.get_window_extent(t, renderer) for t in texts if t.get_text()]


def _overlap(a, b) -> bool:
    return a.x0 < b.x1 and b.x0 < a.x1 and a.y0 < b.y1 and b.y0 < a.y1


def test_spread_labels_keeps_order_and_gap_and_stays_close() -> None:
    from explore._plots import spread_labels

    wanted = np.array([0.50, 0.51, 0.10, 0.505, 0.99, 0.98])
    got = spread_labels(wanted, gap=0.05)
    order = np.argsort(wanted, kind="stable")
    assert np.all(np.diff(got[order]) >= 0.05 - 1e-12)  # the gap, in the wanted order
    assert got.min() >= 0.0 and got.max() <= 1.0
    assert got[2] == pytest.approx(0.10)  # alone: exactly where it wanted to be
    assert np.max(np.abs(got - wanted)) < 0.1  # the crowded ones moved by a few gaps only


def test_pareto_labels_of_coinciding_designs_do_not_overlap(run_dir: Path) -> None:
    """Confirmed designs that sit (almost) on top of each other get legible labels."""
    from explore._plots import render_pareto

    info = pareto_info(load_run(run_dir))
    close = np.array([[0.5, 0.8, 0.2], [0.501, 0.801, 0.3], [0.5, 0.799, 0.4], [0.05, 0.3, 1.0]])
    labels = ("uncertain r1/t18", "uncertain r0/t9", "best r2/t7", "buildable r0/t3")
    crowded = dataclasses.replace(info, confirmed=close, confirmed_labels=labels)
    fig = render_pareto(crowded)
    ax = fig.axes[0]
    texts = [t for t in ax.texts if t.get_text() in labels]
    assert sorted(t.get_text() for t in texts) == sorted(labels)
    boxes = _text_boxes(fig, texts)
    assert not any(_overlap(a, b) for a, b in itertools.combinations(boxes, 2))
    page = fig.bbox
    assert all(page.x0 <= b.x0 and b.x1 <= page.x1 and page.y0 <= b.y0 for b in boxes)


def test_importance_title_fits_the_figure() -> None:
    from explore._plots import ImportanceInfo, render_importance

    info = ImportanceInfo(
        ("geometry.height_mm", "core.tau_s", "skin.thickness_mm"),
        (0.5, 0.3, 0.2),
        "a-rather-long-study-prefix-r0-continuous",
        3000,
    )
    fig = render_importance(info)
    (box,) = _text_boxes(fig, [fig.axes[0].title])
    page = fig.bbox
    assert page.x0 <= box.x0 and box.x1 <= page.x1 and box.y1 <= page.y1


def test_wedge_profiles_point_down_in_the_report_as_in_simulate(run_dir: Path) -> None:
    """The surface-deflection profile is drawn the same way up by `fingertip simulate --out`
    (sim.output.result) and by the report: deflection downward."""
    from types import SimpleNamespace

    from explore._plots import render_wedge, wedge_info
    from sim.output import curve_plot_data

    record = json.loads(next((run_dir / "fe" / "records").glob("*.json")).read_text())
    simulate = curve_plot_data(SimpleNamespace(curves=record["curves"]))["profile"]
    fig = render_wedge(wedge_info(load_run(run_dir)))
    profile_axes = fig.axes[1:3]
    assert simulate["invert_y"] is True
    assert all(ax.yaxis_inverted() for ax in profile_axes)
    assert all("downward" in ax.get_ylabel() for ax in profile_axes)
    assert "downward" in simulate["ylabel"]


def test_tied_importances_are_ranked_by_name_whatever_the_string_hashing():
    """Optuna returns tied importances in hash order (here: a set's order, which follows
    PYTHONHASHSEED); the figure must not change between runs."""
    import subprocess
    import sys

    code = (
        "from explore._plots import _ranked; "
        "imp = {n: 0.0 for n in {'skin.material', 'core.material', 'layers.count'}}; "
        "imp['geometry.height_mm'] = 0.9; print([n for n, _ in _ranked(imp)])"
    )
    runs = {
        subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                       env={**__import__("os").environ, "PYTHONHASHSEED": seed}).stdout
        for seed in ("1", "2", "3", "4", "5")
    }  # fmt: skip
    assert runs == {"['geometry.height_mm', 'core.material', 'layers.count', 'skin.material']\n"}


# ---------------------------------------------------------------------------------------------
# Log axes: few labelled ticks per decade, labels apart
# ---------------------------------------------------------------------------------------------

RANGES = [
    (0.24, 8.3),  # runs/main's compliance error: minor-tick labels ran into each other
    (0.0021, 9.3),  # its hysteresis error
    (0.00255, 0.0683),  # core.mu0_MPa
    (0.04, 1.99),
    (0.6, 0.9),
    (0.61, 0.64),
    (1e-6, 1e3),
    (2e-5, 3e-5),
    (1e5, 5e7),
]


def _per_decade(ticks) -> int:
    decades = np.floor(np.log10(ticks) + 1e-9)
    return max(int(np.sum(decades == d)) for d in set(decades))


@pytest.mark.parametrize(("low", "high"), RANGES)
def test_log_ticks_are_few_per_decade_inside_the_range_and_apart(low, high) -> None:
    ticks = np.array(log_ticks(low, high))
    assert len(ticks) >= 1 and np.all((low <= ticks) & (ticks <= high))
    assert _per_decade(ticks) <= LOG_TICKS_PER_DECADE and len(ticks) <= 6
    assert np.all(ticks[1:] / ticks[:-1] >= 4 / 3 - 1e-12)  # 1.3 decades apart at the least
    if high / low >= 2.5:
        assert len(ticks) >= 2


def test_log_axis_limits_and_plain_labels() -> None:
    axis = log_axis([0.3, 9.0, np.nan, -1.0])  # NaN and negative values ignored
    lo, hi = axis.limits
    assert lo < 0.3 and hi > 9.0 and np.log10(0.3 / lo) == pytest.approx(0.05 * np.log10(30))
    assert axis.ticks == (0.5, 1.0, 2.0, 5.0, 10.0)  # 10 is inside the widened limits
    assert axis.labels == ("0.5", "1", "2", "5", "10")
    assert log_axis([1e-6, 1.0]).labels[0] == "$10^{-6}$"  # no mix of 0.0001 and 10^-6
    assert log_axis([np.nan]) is None


def _tick_label_boxes(fig, axis):
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    lo, hi = sorted(axis.get_view_interval())
    return [
        t.get_window_extent(renderer)
        for tick in axis.get_major_ticks() + axis.get_minor_ticks()
        if lo <= tick.get_loc() <= hi
        for t in (tick.label1, tick.label2)
        if t.get_visible() and t.get_text()
    ]


def _assert_apart(fig, axis) -> list:
    boxes = _tick_label_boxes(fig, axis)
    assert len(boxes) >= 2
    assert not any(_overlap(a, b) for a, b in itertools.combinations(boxes, 2))
    return boxes


def test_pareto_log_axes_have_separate_labels(run_dir: Path) -> None:
    """The spans of runs/main (compliance error 0.24-8.3, hysteresis error 0.0021-9.3), where
    matplotlib's own log axis labelled the minor ticks (one decade tick in view) and they ran
    into each other: the labels are the info's ticks and no two of them touch."""
    from explore._plots import render_pareto

    info = pareto_info(load_run(run_dir))
    assert info.x_axis is not None and info.y_axis is not None
    wide = np.column_stack([np.geomspace(0.24, 8.3, 50), np.geomspace(0.0021, 9.3, 50),
                            np.linspace(0.0, 1.0, 50)])  # fmt: skip
    crowded = dataclasses.replace(
        info, points=wide, x_axis=log_axis(wide[:, 0]), y_axis=log_axis(wide[:, 1])
    )
    for one in (info, crowded):
        fig = render_pareto(one)
        ax = fig.axes[0]
        for axis, log in ((ax.xaxis, one.x_axis), (ax.yaxis, one.y_axis)):
            _assert_apart(fig, axis)
            shown = [t.get_text() for t in axis.get_ticklabels(which="both") if t.get_text()]
            assert shown == list(log.labels)  # minor ticks unlabelled
            assert _per_decade(log.ticks) <= LOG_TICKS_PER_DECADE


def test_projection_log_axes_and_score_scale_have_separate_labels(run_dir: Path) -> None:
    from explore._plots import render_projections

    run = load_run(run_dir)
    info = projections_info(run, top=4, importance=importance_info(run))
    logs = [(p, p.x_axis if p.x_log else p.y_axis) for p in info.pairs if p.x_log or p.y_log]
    assert logs and all(log is not None for _, log in logs)
    # runs/main's core.mu0_MPa, 0.0027-0.068 MPa: one decade tick (0.01) in view, so
    # matplotlib labelled the minor ticks too, into one unreadable string
    pair = info.pairs[0]
    mu = np.geomspace(0.0027, 0.068, len(pair.x))
    crowded = dataclasses.replace(pair, x=mu, x_log=True, x_axis=log_axis(mu))
    for one in (info, dataclasses.replace(info, pairs=(crowded, *info.pairs[1:]))):
        fig = render_projections(one)
        for ax in fig.axes:
            for axis, scale in ((ax.xaxis, ax.get_xscale()), (ax.yaxis, ax.get_yscale())):
                if ax.get_visible() and scale == "log":
                    _assert_apart(fig, axis)
    for _, log in logs:
        assert _per_decade(log.ticks) <= LOG_TICKS_PER_DECADE
    # the colour scale: the lowest finite score to the median one
    scores = run.column("score")
    scores = scores[np.isfinite(scores)]
    assert info.score_axis.limits == pytest.approx((scores.min(), np.median(scores)))
