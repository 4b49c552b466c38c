"""The search: conditional suggestions, the trust guard and candidate choice, confirmation
bookkeeping, resume after kill -9, and a tiny end-to-end pipeline (sweep -> train -> optimize
-> report) on real FE."""

from __future__ import annotations

import dataclasses
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import optuna
import pytest
from sweep_fixtures import FAST, tiny_surrogate

import explore.cli
from explore._confirm import compare, confirm, reference_point
from explore._objective import TAPPING
from explore._search import (
    SearchSettings,
    TrialRow,
    catalogue_only,
    check_subspace,
    create_study,
    design_family,
    point_from_params,
    select_candidates,
    suggest_point,
)
from explore._storage import open_storage
from explore._types import Candidate, Confirmation
from sim import METRICS, SimOptions
from sim.design import is_family, load_design, load_space, load_targets, space_from_dict
from sim.protocols import LAYER_STRAIN_OUTPUTS, TRUST_OUTPUTS
from sim.sweep import record_key

REPO = Path(explore.cli.__file__).resolve().parents[1]

#: a tiny space with catalogue and parametric materials (so both searches run)
TINY_OPT = """
[geometry]
half_width_mm = { value = 5.84 }
height_mm = { low = 5.2, high = 5.8 }
exponent = { value = 1.5 }
[layers]
count = { choice = [1, 2] }
[layers.skin]
thickness_mm = { low = 0.3, high = 1.0 }
material = { choice = ["silicone_gls40", "polyurethane_74_45"] }
[layers.core]
material = { choice = ["gel", "silicone_gls40"] }
mu0_MPa = { low = 0.01, high = 0.1, log = true }
alpha = { low = 2.0, high = 4.0 }
g_total = { low = 0.1, high = 0.6 }
tau_s = { low = 0.05, high = 1.0, log = true }
"""


def _env(threads: int = 1) -> dict[str, str]:
    """The environment of a CLI subprocess; ``threads``: torch's (and BLAS') thread count."""
    return {**os.environ, "MPLBACKEND": "Agg", "OMP_NUM_THREADS": str(threads)}


# ----------------------------------------------------------------------------- search space
def test_suggestions_are_conditional_like_the_design_space():
    space = load_space()
    study = optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=0))
    seen_counts, seen_param = set(), False
    for _ in range(60):
        trial = study.ask()
        point = suggest_point(trial, space)
        space.check(point)  # inside the space, a valid design
        count = point["layers.count"]
        seen_counts.add(count)
        # only what the design uses was suggested: one layer never asks for a skin
        assert ("skin.material" in trial.params) == (count == 2)
        for role in ("skin", "core"):
            used = is_family(point[f"{role}.material"])
            seen_param |= used
            assert (f"{role}.mu0_MPa" in trial.params) == used
            assert math.isnan(point[f"{role}.mu0_MPa"]) != used
            # a foam has a Poisson's ratio of its own, a gel none (fixed, nearly incompressible)
            foam = point[f"{role}.material"] == "foam"
            assert (f"{role}.nu" in trial.params) == foam
        assert point_from_params(space, trial.params) == point or _same(
            point_from_params(space, trial.params), point
        )
        study.tell(trial, 0.0)
    assert seen_counts == {1, 2} and seen_param


def _same(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(
        (isinstance(a[k], float) and math.isnan(a[k]) and math.isnan(b[k])) or a[k] == b[k]
        for k in a
    )


def test_catalogue_only_space_and_subspace_check():
    space = load_space()
    build = catalogue_only(space)
    for role in ("skin", "core"):
        assert not any(is_family(c) for c in build[f"{role}.material"].choices)
        assert set(build[f"{role}.material"].choices) < set(space[f"{role}.material"].choices)
    check_subspace(build, space)  # a restriction of the trained space is fine
    wide = space_from_dict({**space.to_dict(), "geometry": {
        **space.to_dict()["geometry"], "height_mm": {"low": 4.0, "high": 6.5}}})  # fmt: skip
    with pytest.raises(ValueError, match=r"geometry\.height_mm"):
        check_subspace(wide, space)
    with pytest.raises(ValueError, match=r"skin\.material"):
        check_subspace(space, build)  # "gel" is not in the catalogue-only space


# ----------------------------------------------------------------------------- candidates
def _row(i: int, score: float, x: float, flags: tuple[str, ...] = ()) -> TrialRow:
    pred = {"disp_at_1N_mm": {"mean": 1.0, "std": 0.1, "lower_90": 0.8, "upper_90": 1.2}}
    return TrialRow(0, i, "continuous", {"x": x}, score, (score, score, 0.0), pred,
                    not flags, 0.5 if flags else 0.01, flags)  # fmt: skip


def test_candidates_are_distinct_trusted_best_then_flagged_promising():
    rows = [
        _row(0, 0.10, 0.500, ("high disagreement 0.5 > 0.1",)),  # best score, but flagged
        _row(1, 0.11, 0.300),
        _row(2, 0.12, 0.301),  # a near-duplicate of trial 1
        _row(3, 0.20, 0.700),
        _row(4, 0.30, 0.900),
        *[_row(5 + i, 1.0 + i, 0.05 * i) for i in range(20)],
    ]

    def features(points):
        return np.array([[p["x"]] for p in points])

    chosen = select_candidates(rows, features, best=2, uncertain=1, min_distance=0.05)
    best = [c for c in chosen if c.reason == "best"]
    assert [c.trial for c in best] == [1, 3]  # trial 0 is flagged, trial 2 duplicates trial 1
    assert all(c.trusted for c in best)
    unc = [c for c in chosen if c.reason == "uncertain"]
    assert [c.trial for c in unc] == [0] and not unc[0].trusted
    # nothing trusted: the best flagged designs still go to FE (FE decides), marked uncertain
    flagged = [_row(i, 0.1 * (i + 1), 0.1 * i, ("out of domain",)) for i in range(10)]
    picked = select_candidates(flagged, features, best=2, uncertain=1)
    assert [c.trial for c in picked] == [0, 1, 2]
    assert {c.reason for c in picked} == {"uncertain"}
    # designs confirmed before are not chosen again
    again = select_candidates(rows, features, best=1, uncertain=0, exclude=[{"x": 0.3}])
    assert [c.trial for c in again] == [3]


def test_confirmation_bookkeeping_compares_prediction_with_fe():
    targets = dataclasses.replace(load_targets(), reading="from_undeformed_top")
    pred = {
        "disp_at_1N_mm": {"mean": 2.0, "std": 0.1, "lower_90": 1.8, "upper_90": 2.2},
        "disp_at_4N_mm": {"mean": 3.0, "std": 0.1, "lower_90": 2.95, "upper_90": 3.05},
        "hysteresis_Nmm": {"mean": 2.0, "std": 0.2, "lower_90": 1.7, "upper_90": 2.3},
        "wedge_peak_force_N": {"mean": None, "std": None, "lower_90": None, "upper_90": None},
    }
    cand = Candidate({"x": 1.0}, "best", 0, 7, "continuous", 0.1, pred, True, 0.05)
    record = {
        "status": "ok",
        "metrics": {
            "disp_at_1N_mm": 1.83,
            "disp_at_4N_mm": 2.91,
            "hysteresis_Nmm": 2.26,
            "wedge_peak_force_N": 0.0,
        },
    }
    c = compare(cand, "k", record, targets)
    assert c.rel_error["disp_at_1N_mm"] == pytest.approx((2.0 - 1.83) / 1.83)
    assert c.rel_error["hysteresis_Nmm"] == pytest.approx((2.0 - 2.26) / 2.26)
    assert c.inside_90 == {"disp_at_1N_mm": True, "disp_at_4N_mm": False,
                           "hysteresis_Nmm": True, "wedge_peak_force_N": None}  # fmt: skip
    assert c.fe_score == pytest.approx(0.0)  # FE equals the targets, no wedge force
    back = Confirmation.from_json(json.loads(json.dumps(c.to_json())))
    assert back.to_json() == c.to_json()
    failed = compare(cand, "k", {"status": "failed", "reason": "diverged", "metrics": {}}, targets)
    assert failed.fe_score == math.inf and failed.rel_error["disp_at_1N_mm"] is None
    # an elastic design's hysteresis is exactly 0 by rule; the FE's round-off is not an error
    exact = {**pred, "hysteresis_Nmm": {"median": 0.0, "mean": 0.0, "std": 0.0,
                                        "lower_90": 0.0, "upper_90": 0.0,
                                        "by_rule": True}}  # fmt: skip
    elastic = Candidate({"x": 1.0}, "best", 0, 7, "continuous", 0.1, exact, True, 0.05)
    noisy = {**record, "metrics": {**record["metrics"], "hysteresis_Nmm": 1.2e-4}}
    c = compare(elastic, "k", noisy, targets)
    assert c.rel_error["hysteresis_Nmm"] is None and c.inside_90["hysteresis_Nmm"] is None
    assert c.rel_error["disp_at_1N_mm"] == pytest.approx((2.0 - 1.83) / 1.83)


def test_rounds_stop_only_when_an_fe_design_meets_every_tapping_target():
    from explore._summary import target_met

    targets = load_targets()
    cand = Candidate({"x": 1.0}, "best", 0, 7, "continuous", 0.1, {}, True, 0.05)
    human = {targets.metric(m): targets.values[m] for m in TAPPING}

    def conf(scale: dict, status: str = "ok", sag: float = 0.1) -> Confirmation:
        fe = {k: v * scale.get(k, 1.0) for k, v in human.items()}
        fe |= {"wedge_peak_force_N": 0.1, "sag_mm": sag}
        return Confirmation(cand, "k", status, "", fe, 0.0)

    near = conf({targets.metric("hysteresis_Nmm"): 1.04})
    far = conf({targets.metric("disp_at_1N_mm"): 1.06})
    assert target_met([far, near], targets, 0.05)
    assert not target_met([far], targets, 0.05)
    assert not target_met([conf({}, status="failed")], targets, 0.05)
    # an FE result whose taps did not reach the periodic state, or that went beyond the
    # validity limits, never meets a target, however close its numbers
    for flag in ("settled", "valid"):
        untrusted = dataclasses.replace(near, diagnostics={flag: False})
        assert not untrusted.trusted and not target_met([untrusted], targets, 0.05)
    # nor does a skin that does not recover between taps (sag over the targets' limit)
    putty = conf({targets.metric("hysteresis_Nmm"): 1.04}, sag=2 * targets.max_sag_mm)
    assert putty.trusted and not target_met([putty], targets, 0.05)


def test_an_untrusted_fe_result_is_never_an_answer():
    from explore._summary import summarise

    targets = load_targets()
    space = load_space()
    point = space.point(np.full(len(space.sampled), 0.5))
    human = {targets.metric(m): targets.values[m] for m in TAPPING}

    def conf(key: str, score: float, **diagnostics) -> Confirmation:
        cand = Candidate(point, "best", 0, 7, "continuous", score, {}, True, score)
        fe = {**human, "sag_mm": 0.1}
        return Confirmation(cand, key, "ok", "", fe, score, diagnostics=diagnostics)

    perfect_but_unsettled = conf("a", 0.0, settled=False, valid=True)
    perfect_but_invalid = conf("b", 0.0, settled=True, valid=False)
    good = conf("c", 0.2, settled=True, valid=True)
    summary = summarise(
        [perfect_but_unsettled, perfect_but_invalid, good], targets, 0.05, [], [], space
    )
    assert summary.answers["best"]["fe_record"] == "fe/records/c.json"
    assert summary.answers["best"]["diagnostics"] == {"settled": True, "valid": True}
    # with no trusted result there is no answer, and the note says why
    none = summarise([perfect_but_unsettled, perfect_but_invalid], targets, 0.05, [], [], space)
    assert none.answers["best"] is None
    assert "1 went beyond the validity limits, 1 did not reach" in none.notes[0]


def test_a_round_without_a_credible_design_finishes_and_says_so(tmp_path):
    """Issue 31, item 1: the round's one FE-confirmed design went beyond the validity limits
    (its tapping stopped: no tapping metrics, an infinite FE score). The round logs
    ``best_fe_score`` None, summary.json is written (strict JSON, null for it) and the report
    says in words that no credible design was found."""
    from explore._report import write_report
    from explore._rounds import _round_info
    from explore._run_folder import read_summary, write_confirmations, write_summary
    from explore._summary import summarise

    targets, space = load_targets(), load_space()
    point = space.point(np.full(len(space.sampled), 0.5))
    cand = Candidate(point, "best", 0, 7, "continuous", 0.1, {}, True, 0.01)
    record = {
        "status": "ok",
        "metrics": {m: None for m in METRICS} | {"wedge_peak_force_N": 0.25},
        "diagnostics": {"valid": False, "stopped": "tapping", "settled": None},
    }
    beyond = compare(cand, "k", record, targets)
    assert beyond.status == "ok" and beyond.fe_score == math.inf and not beyond.trusted
    info = _round_info(0, [beyond], targets, 0.05)
    assert info["best_fe_score"] is None  # no credible design this round (was inf)
    summary = summarise([beyond], targets, 0.05, [info], [], space)
    assert summary.answers["best"] is None
    write_confirmations(tmp_path, [beyond], final=True)
    write_summary(tmp_path, summary, 1.0, {"fe_s": 0.5}, False)
    text = (tmp_path / "summary.json").read_text()
    assert "Infinity" not in text and "NaN" not in text
    assert read_summary(tmp_path)["rounds"][0]["best_fe_score"] is None
    report = write_report(tmp_path).read_text()
    assert "No credible design was found in round(s) 0" in report
    assert "| no credible design |" in report and "| None |" not in report
    assert "did not finish" not in report


def test_confirm_reuses_existing_fe_records(tmp_path, monkeypatch):
    """A resumed run never recomputes an FE design it already has."""
    import explore._confirm as mod

    point = {**reference_point("silicone_gls40")}
    options = SimOptions()
    key = record_key(mod._full_point(point), options)
    stored = {"key": key, "status": "ok", "metrics": {m: 1.0 for m in METRICS}}
    path = tmp_path / "fe" / "records" / f"{key}.json"
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps(stored))

    def boom(*a, **k):
        raise AssertionError("FE was run again")

    monkeypatch.setattr(mod, "evaluate_point", boom)
    pred = {m: {"mean": 1.1, "std": 0.1, "lower_90": 0.9, "upper_90": 1.3} for m in METRICS}
    cand = Candidate(point, "best", 0, 0, "continuous", 0.5, pred, True, 0.01)
    (c,) = confirm([cand], tmp_path, load_targets(), options, progress=False)
    assert c.key == key and c.status == "ok"
    assert c.rel_error["disp_at_1N_mm"] == pytest.approx(0.1)


def test_study_sampler_is_seeded():
    space = load_space()

    def points(seed: int) -> list[dict]:
        study = create_study(None, "s", SearchSettings(seed=seed))
        out = []
        for _ in range(5):
            t = study.ask()
            out.append(suggest_point(t, space))
            study.tell(t, 1.0)
        return out

    a, b, c = points(0), points(0), points(1)
    assert all(_same(x, y) for x, y in zip(a, b, strict=True))
    assert not all(_same(x, y) for x, y in zip(a, c, strict=True))


def test_the_search_bar_ends_at_the_trials_the_study_holds(monkeypatch, tmp_path):
    """Issue 31, item 6f: a study's bar counts the screen's seeds as well as the sampled trials
    (it stopped at 128/192: the 64 seeds were never counted) and ends at the work done when it
    differs from the plan (a screen of 32 designs keeps 32 seeds, not 64)."""
    from types import SimpleNamespace

    import tqdm as tqdm_module

    from explore._config import DEFAULT_CHECKPOINT, OptimizeConfig
    from explore._rounds import Search, _study
    from surrogate import load_checkpoint

    closed: list[tuple[int, int]] = []

    class Bar(tqdm_module.tqdm):
        def close(self) -> None:
            closed.append((self.n, self.total))
            super().close()

    monkeypatch.setattr(tqdm_module, "tqdm", Bar)
    surrogate = load_checkpoint(DEFAULT_CHECKPOINT, allow_solver_mismatch=True)
    storage = open_storage(str(tmp_path / "study.log"))
    run = Search(OptimizeConfig(), tmp_path, SimpleNamespace(targets=load_targets()), storage, None)
    for screen, seeds in ((256, 64), (32, 32)):
        settings = SearchSettings(trials=16, screen=screen, seed=0)
        _study(run, surrogate, 0, f"s{screen}", surrogate.space, settings)
        study = optuna.load_study(study_name=f"fingertip-r0-s{screen}", storage=storage)
        assert len(study.trials) == seeds + 16
        assert closed[-1] == (seeds + 16, seeds + 16)


# ----------------------------------------------------------------------------- pipeline
@pytest.fixture(scope="module")
def tiny_model(tmp_path_factory) -> Path:
    """A real FE sweep of TINY_OPT (10 designs, fast options) and a small surrogate on it."""
    return tiny_surrogate(tmp_path_factory.mktemp("explore"), TINY_OPT)


def _run(args: list[str], threads: int = 1) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "explore.cli", *args],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=900,
        env=_env(threads),
    )


def _optimize_args(ckpt: Path, out: Path, trials: int, rounds: int = 2) -> list[str]:
    return [
        "optimize", "--surrogate", str(ckpt), "--out", str(out), "--trials", str(trials),
        "--buildable-trials", "20" if rounds > 1 else "0", "--rounds", str(rounds),
        "--confirm", "1", "--uncertain", "1" if rounds > 1 else "0",
        "--tolerance", "0.01", "--workers", "2", "--no-progress",
        "--family-trials", "20" if rounds > 1 else "0", "--screen", "2048",
    ]  # fmt: skip


def test_tiny_pipeline_end_to_end(tiny_model, tmp_path):
    out = tmp_path / "opt"
    proc = _run(_optimize_args(tiny_model, out, 60))
    assert proc.returncode == 0, proc.stderr
    assert "report:" in proc.stdout
    summary = json.loads((out / "summary.json").read_text())
    best, build = summary["answers"]["best"], summary["answers"]["buildable"]
    assert best is not None and build is not None
    # the answers are FE results under the metric names of `fingertip simulate --json`
    record = json.loads((out / best["fe_record"]).read_text())
    assert best["fe_metrics"] == record["metrics"] and set(best["fe_metrics"]) == set(METRICS)
    # the prediction of every metric, and of what would make the FE result untrusted
    layers = {m for m in LAYER_STRAIN_OUTPUTS if "_middle_" not in m}  # one or two layers
    assert set(best["predicted"]) == set(METRICS) | set(TRUST_OUTPUTS) | layers
    # both readings and the sag between them
    r = best["readings"]
    assert r["from_first_touch"]["disp_at_1N_mm"] == best["fe_metrics"]["disp_at_1N_from_touch_mm"]
    assert r["from_undeformed_top"]["disp_at_4N_mm"] == best["fe_metrics"]["disp_at_4N_mm"]
    assert r["sag_mm"] == best["fe_metrics"]["sag_mm"] <= 0.37 and best["credible"]
    assert {"median", "mean", "std", "lower_90", "upper_90", "by_rule"} == set(
        best["predicted"]["disp_at_1N_mm"]
    )
    assert best["predicted"]["disp_at_1N_mm"]["by_rule"] is False  # learnt, not by rule
    # the best buildable design uses catalogue materials only, and is a loadable design file
    assert design_family(build["point"]) == "catalogue" and build["family"] == "catalogue"
    from sim.design import design_from_dict

    design_from_dict(build["design"])
    # the best is the lowest FE score of all confirmations; two rounds ran (tolerance 1 %)
    confs = json.loads((out / "confirmations.json").read_text())
    scores = [
        c["fe_score"]
        for c in confs
        if c["trusted"] and c["fe_metrics"]["sag_mm"] <= 0.37  # credible ones only
    ]
    assert best["fe_score"] == pytest.approx(min(scores))
    assert len(summary["rounds"]) == 2 and (out / "surrogates" / "round-1.safetensors").exists()
    assert {c["candidate"]["round"] for c in confs} == {0, 1}
    # the study opens in Optuna (what optuna-dashboard reads); config.json holds the fixed
    # configuration, studies.json the studies as the rounds started them
    cfg = json.loads((out / "config.json").read_text())
    assert "studies" not in cfg
    names = [s["name"] for s in json.loads((out / "studies.json").read_text())]
    assert len(names) == 6  # per round: continuous, gel (one-layer gel cores), buildable
    study = optuna.load_study(study_name=names[0], storage=open_storage(cfg["storage"]))
    assert len(study.trials) == SearchSettings().screen_keep + 60  # the screen's seeds first
    assert study.trials[0].user_attrs["source"] == "screen"
    # the README's answer block is made from a run folder (studies/readme_answer.py)
    from explore._readme_answer import render

    block = render(out)
    assert f"{len(confs)} designs confirmed with full FE" in block
    assert "(6 144 a round: 2 048 for each of 3 studies)" in block  # 2 rounds, --screen 2048
    assert block.count("\n| best ") == 4
    row = next(line for line in block.splitlines() if line.startswith("| best credible |"))
    assert f"{best['readings']['sag_mm']:.2f}" in row and "outline" in row
    report = (out / "report.md").read_text()
    assert "figures/loops.png" in report or "figures/" in report
    # the report leads with the verdict; every answer is a design file (issue 35, items 3, 4)
    assert report.split("\n\n")[1].startswith("**Verdict**")
    for kind, answer in summary["answers"].items():
        path = out / "answers" / f"{kind}.toml"
        assert path.is_file() == (answer is not None), kind
        if answer is not None:
            assert load_design(path).to_dict() == answer["design"], kind
    assert f"answers: {out / 'answers' / 'best.toml'}" in proc.stdout
    # what the surrogate scored: every study's screen (--screen 2048) and the Optuna trials
    n_studies = len(json.loads((out / "studies.json").read_text()))
    n_trials = len((out / "trials.csv").read_text().splitlines()) - 1
    assert (
        f"screened {2048 * n_studies:,} quasi-random designs (2,048 for each of its {n_studies} "
        f"studies) and scored {n_trials} Optuna trials".replace(",", " ")
        in report
    )
    assert (out / "figures").is_dir() and any((out / "figures").glob("*.png"))
    # re-running the finished command computes nothing and rewrites nothing: every file keeps
    # its bytes and its modification time (summary.json its first wall_time_s), the same report
    before = _snapshot(out)
    proc = _run(_optimize_args(tiny_model, out, 60))
    assert proc.returncode == 0, proc.stderr
    after = _snapshot(out)
    assert after.keys() == before.keys()
    changed = sorted(str(p.relative_to(out)) for p in before if after[p] != before[p])
    assert not changed, f"rewritten by the re-run: {changed}"
    assert proc.stdout.splitlines()[-1] == f"report: {out / 'report.md'}"
    # the other commands refuse the run folder, in one line, writing nothing
    for argv, words in (
        (["sweep", "--n", "2", "--out", str(out)], "holds a search run"),
        (["train", str(out), "--out", str(tmp_path / "model")], "holds a search run"),
        (["simulate", "--material", "silicone_gls40", "--out", str(out)], "not empty"),
    ):
        proc = _run(argv)
        assert proc.returncode == 2 and words in proc.stderr, (argv, proc.stderr)
        assert len(proc.stderr.splitlines()) == 1 and "Traceback" not in proc.stderr
    assert _snapshot(out) == before and not (tmp_path / "model").exists()


#: One-layer gel pads of 2.5-3 kPa (the default space's softest gels) on the smallest
#: sections: at 4 N every one compresses its gel beyond the gel's tested limit.
_TOO_SOFT_SPACE = """
description = "gels too soft for 4 N: every design strains its gel beyond its tested limit"
[geometry]
half_width_mm = { low = 5.0, high = 5.5 }
height_mm = { low = 4.5, high = 5.0 }
exponent = { low = 1.3, high = 1.5 }
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
mu0_MPa = { low = 0.0025, high = 0.003, log = true }
alpha = { low = 1.5, high = 2.0 }
nu = { low = 0.0, high = 0.3 }
g_total = { low = 0.0, high = 0.1 }
tau_s = { low = 0.04, high = 0.1, log = true }
"""


def test_the_issue_31_run_without_a_credible_design_finishes(tmp_path):
    """Issue 31, item 1, its command on the shipped 2D surrogate (~15 s), in a space where every
    design goes beyond the validity limits (``_TOO_SOFT_SPACE``), so the one confirmed design
    does. The run finishes (exit 0) with summary.json (its round's ``best_fe_score`` null) and
    a report saying no credible design was found (before, it crashed writing summary.json, at
    every re-run too)."""
    out = tmp_path / "x"
    space = tmp_path / "soft.toml"
    space.write_text(_TOO_SOFT_SPACE)
    args = [
        "optimize", "--model", "2d", "--out", str(out), "--space", str(space), "--trials", "16",
        "--family-trials", "0", "--buildable-trials", "0", "--screen", "256", "--confirm", "1",
        "--uncertain", "0", "--rounds", "1", "--buildable-fe", "0", "--no-progress",
    ]  # fmt: skip
    proc = _run(args)
    assert proc.returncode == 0, proc.stderr
    assert "best design: none credible confirmed by FE" in proc.stdout
    (confirmation,) = json.loads((out / "confirmations.json").read_text())
    assert confirmation["diagnostics"]["valid"] is False and confirmation["fe_score"] is None
    summary = json.loads((out / "summary.json").read_text())
    assert summary["answers"]["best"] is None and summary["rounds"][0]["best_fe_score"] is None
    assert "went beyond the validity limits" in summary["notes"][0]
    report = (out / "report.md").read_text()
    assert "No credible design was found in round(s) 0" in report
    assert "did not finish" not in report


def _snapshot(folder: Path) -> dict[Path, tuple[bytes, int]]:
    """Every file of ``folder``: its bytes and modification time."""
    return {
        p: (p.read_bytes(), p.stat().st_mtime_ns) for p in sorted(folder.rglob("*")) if p.is_file()
    }


def _layers(design: dict) -> list[dict]:
    return design.get("layers", [])


def _stored_trials(journal: Path, study: str | None = None) -> int:
    """Finished trials in a run folder's Optuna journal (of one study, or of all), read while
    the search may be appending to it (0 while it has none)."""
    from explore._storage import open_storage

    if not journal.exists():
        return 0
    states = (optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.FAIL)
    try:
        storage = open_storage(str(journal))
        names = [study] if study else [s.study_name for s in storage.get_all_studies()]
        total = 0
        for name in names:
            sid = storage.get_study_id_from_name(name)
            total += len(storage.get_all_trials(sid, deepcopy=False, states=states))
        return total
    except (KeyError, ValueError):  # no such study yet, or a line being written
        return 0


def _study_trials(journal: Path, name: str) -> list:
    from explore._storage import open_storage

    return optuna.load_study(study_name=name, storage=open_storage(str(journal))).trials


def _kill_when(args: list[str], db: Path, study: str, low: int, high: int) -> int:
    """Start ``args`` and kill -9 it once ``study`` holds between ``low`` and ``high`` finished
    trials; returns how many it holds then."""
    proc = subprocess.Popen(args, cwd=REPO, env=_env(), stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)  # fmt: skip
    stored = 0
    deadline = time.monotonic() + 600
    while time.monotonic() < deadline and proc.poll() is None and not low <= stored < high:
        time.sleep(0.05)
        stored = _stored_trials(db, study)  # a cheap read, so the kill lands right after a flush
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    return _stored_trials(db, study)


def _without(d: dict, *keys: str) -> dict:
    return {k: v for k, v in d.items() if k not in keys}


def test_a_late_kill_resumes_to_the_uninterrupted_answer(tiny_model, tmp_path):
    """kill -9 during round 2's search, after round 1's FE and retraining; the same command
    then ends exactly where an uninterrupted run ends: the same trials, candidates, FE
    confirmations, retrained surrogate, answer, report and figures. Determinism too: the
    uninterrupted run has one FE worker and two torch threads, the killed one two workers and
    one thread (issue 15, item 4)."""
    from surrogate import load_checkpoint

    n = 300
    ref, out = tmp_path / "ref" / "opt", tmp_path / "killed" / "opt"
    ref_args = _optimize_args(tiny_model, ref, n)
    ref_args[ref_args.index("--workers") + 1] = "1"
    proc = _run(ref_args, threads=2)
    assert proc.returncode == 0, proc.stderr
    args = [sys.executable, "-m", "explore.cli", *_optimize_args(tiny_model, out, n)]
    stored = _kill_when(args, out / "study.log", "fingertip-r1-continuous", 128, n)
    assert 128 <= stored < n, f"could not catch round 2's search mid-way ({stored} trials)"
    assert not (out / "summary.json").exists()
    proc = subprocess.run(args, cwd=REPO, capture_output=True, text=True, timeout=900,
                          env=_env())  # fmt: skip
    assert proc.returncode == 0, proc.stderr

    def same_bytes(name: str) -> None:
        a, b = (ref / name).read_bytes(), (out / name).read_bytes()
        assert a == b.replace(str(out).encode(), str(ref).encode()), f"{name} differs"

    files = sorted(str(p.relative_to(ref)) for p in ref.rglob("*") if p.is_file())
    assert files == sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file())
    # byte for byte: everything but the files that record when or how long (checked below)
    timed = ("meta.json", "summary.json", "study.log", "surrogates/", "fe/", "config.json",
             "time.json")  # fmt: skip
    for name in files:
        if name.startswith("answers/"):  # their header names the command: its --workers differ
            a, b = ((d / name).read_text().replace(str(d), "RUN") for d in (ref, out))
            assert a.replace("--workers 1", "--workers 2") == b, f"{name} differs"
        elif not name.startswith(timed):
            same_bytes(name)
    assert "answers/best.toml" in files
    cfg_a = json.loads((ref / "config.json").read_text())
    cfg_b = json.loads((out / "config.json").read_text().replace(str(out), str(ref)))
    assert cfg_a["workers"] == 1 and cfg_b["workers"] == 2  # the one entry that may differ
    assert _without(cfg_a, "workers") == _without(cfg_b, "workers")
    expected = {"trials.csv", "confirmations.json", "report.md", "config.json", "studies.json"}
    assert expected <= set(files)
    assert "rounds/round-1-candidates.json" in files and "figures/importance.png" in files
    timing = ("wall_time_s", "timings", "resumed")
    a, b = (json.loads((d / "summary.json").read_text()) for d in (ref, out))
    assert _without(a, *timing) == _without(b, *timing) and b["resumed"] and not a["resumed"]
    # the resumed run's time is the killed invocation's and its own (issue 31, item 6c)
    parts = json.loads((out / "time.json").read_text())
    assert len(parts) == 2 and parts[0]["timings"]["search_s"] > 0
    assert b["wall_time_s"] == pytest.approx(sum(p["wall_time_s"] for p in parts))
    assert len(a["rounds"]) == 2
    # FE records: the same results (only the time each took differs, wall and CPU)
    rec_a, rec_b = (sorted((d / "fe").rglob("*.json")) for d in (ref, out))
    assert [p.relative_to(ref) for p in rec_a] == [p.relative_to(out) for p in rec_b]
    for pa, pb in zip(rec_a, rec_b, strict=True):
        ra, rb = json.loads(pa.read_text()), json.loads(pb.read_text())
        times = ("wall_time_s", "cpu_time_s", "cost_by_protocol")
        assert _without(ra, *times) == _without(rb, *times), pa.name
    # the surrogate retrained after round 1: the same weights and header (but its date)
    ma, mb = (load_checkpoint(d / "surrogates" / "round-1.safetensors") for d in (ref, out))
    sa, sb = ma.model.state_dict(), mb.model.state_dict()
    assert sa.keys() == sb.keys() and all(torch_equal(sa[k], sb[k]) for k in sa)
    assert _without(ma.header, "created_utc", "sha256") == _without(
        mb.header, "created_utc", "sha256"
    )
    # every study holds the same trials
    for st in json.loads((ref / "studies.json").read_text()):
        ta, tb = (_study_trials(d / "study.log", st["name"]) for d in (ref, out))
        assert [(t.params, t.values) for t in ta] == [(t.params, t.values) for t in tb]


def test_the_readme_answer_block_has_its_markers():
    from explore._readme_answer import replace_block

    text = (REPO / "README.md").read_text()
    block = text.split("<!-- answer:start -->\n", 1)[1].split("<!-- answer:end -->", 1)[0]
    # the main job: the 3D search (no --model, no --surrogate), its answers' contact area shown
    command = block.split("`")[1]
    assert command.startswith("fingertip run ") and command.endswith("--out runs/main")
    assert "--model" not in command and "--surrogate" not in command
    assert "| best credible" in block
    assert "contact area 1 N / 4 N (mm²)" in block
    assert replace_block(text, block) == text  # the block round-trips


def test_the_screened_count_is_the_screen_times_the_studies():
    from explore._run_folder import screened_designs

    studies = [{"name": f"s{i}"} for i in range(6)]
    assert screened_designs({"screen": 2048}, studies) == (2048, 12288)
    # no screen (an older run, or --screen 0), or no study yet: nothing screened
    assert screened_designs({"screen": 0}, studies) == (0, 0)
    assert screened_designs({}, studies) == (0, 0)
    assert screened_designs(None, studies) == (0, 0)
    assert screened_designs({"screen": 2048}, []) == (0, 0)


def torch_equal(a, b) -> bool:
    import torch

    return bool(torch.equal(a, b))


@pytest.mark.parametrize("mode", ["single", "multi"])
def test_a_study_cut_anywhere_resumes_to_the_same_trials(tiny_model, mode):
    """Optuna stores the trials of a flush one by one, so a kill may cut a batch anywhere: the
    resumed study asks the cut batch again and holds exactly the uninterrupted study's trials."""
    from explore._search import run_study
    from surrogate import load_checkpoint

    model = load_checkpoint(tiny_model)
    settings = SearchSettings(trials=150, mode=mode, seed=3)
    targets = load_targets()

    def search(study) -> list:
        run_study(study, model, model.space, targets, settings, round_=0, search="continuous")
        return [(t.number, t.params, t.values, t.state) for t in study.trials]

    whole = create_study(None, "whole", settings)
    reference = search(whole)
    assert len(reference) == 150
    for cut in (0, 16, 37, 130):  # at a batch boundary, inside a batch, inside a later one
        study = create_study(None, f"cut{cut}", settings)
        study.add_trials(whole.trials[:cut])
        assert search(study) == reference, cut


def test_search_resumes_after_kill(tiny_model, tmp_path):
    """kill -9 during the search; the same command finishes with exactly the asked number of
    trials (the screen's seeds and the sampler's), keeping every trial stored before the kill."""
    out = tmp_path / "opt"
    n = 600
    total = SearchSettings().screen_keep + n
    args = [sys.executable, "-m", "explore.cli", *_optimize_args(tiny_model, out, n, rounds=1)]
    proc = subprocess.Popen(args, cwd=REPO, env=_env(), stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)  # fmt: skip
    db = out / "study.log"
    name = "fingertip-r0-continuous"
    stored = 0
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and proc.poll() is None and not 128 <= stored < total:
        time.sleep(0.05)
        stored = _stored_trials(db)  # a cheap read, so the kill lands right after a flush
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    before = _study_trials(db, name)
    assert 128 <= len(before) < total, f"could not catch the search mid-way ({len(before)})"
    proc = subprocess.run(args, cwd=REPO, capture_output=True, text=True, timeout=900,
                          env=_env())  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    after = _study_trials(db, name)
    assert len(after) == total
    for old, new in zip(before, after, strict=False):
        assert old.params == new.params and old.values == new.values
    summary = json.loads((out / "summary.json").read_text())
    # one confirmation with the fast options: a credible answer, or a note saying why not
    assert summary["answers"]["best"] is not None or "no credible answer" in summary["notes"][0]
    assert summary["answers"]["buildable"] is None


def test_optimize_bad_input_is_one_line(tiny_model, tmp_path, capsys):
    code = explore.cli.main(["optimize", "--surrogate", str(tiny_model), "--out",
                             str(tmp_path / "x"), "--rounds", "0"])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "--rounds" in err and "Traceback" not in err
    space = tmp_path / "wide.toml"
    space.write_text(TINY_OPT.replace("low = 5.2, high = 5.8", "low = 4.0, high = 5.8"))
    code = explore.cli.main(["optimize", "--surrogate", str(tiny_model), "--space", str(space),
                             "--out", str(tmp_path / "y")])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2 and "geometry.height_mm" in err and err.count("\n") == 1
    assert not (tmp_path / "x").exists() and not (tmp_path / "y").exists()  # no folder left


def test_a_smaller_n_is_refused_and_the_table_stays(tiny_model, tmp_path, capsys):
    """A sweep folder of N designs: --n may only grow (a smaller one would drop rows from
    table.csv); with a Latin hypercube, whose samples of two sizes differ, it may not change."""
    root = tiny_model.parent.parent
    sweep, space = root / "sweep", root / "space.toml"
    table = (sweep / "table.csv").read_bytes()
    code = explore.cli.main(["sweep", str(space), "--n", "5", "--out", str(sweep), *FAST])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err
    assert "holds a sweep of 10 designs; --n may only grow, got 5" in err
    assert (sweep / "table.csv").read_bytes() == table
    other = [*FAST[:-1], "wedge.hold_s=6"]  # another --set: named in words
    assert explore.cli.main(["sweep", str(space), "--n", "10", "--out", str(sweep), *other]) == 2
    err = capsys.readouterr().err
    assert "holds a sweep with other simulation options (--set)" in err and err.count("\n") == 1
    assert (sweep / "table.csv").read_bytes() == table
    lhs = tmp_path / "lhs"
    shutil.copytree(sweep, lhs)
    cfg = json.loads((lhs / "config.json").read_text())
    (lhs / "config.json").write_text(json.dumps({**cfg, "sampler": "lhs"}))
    argv = ["sweep", str(space), "--n", "12", "--out", str(lhs), "--sampler", "lhs", *FAST]
    assert explore.cli.main(argv) == 2
    err = capsys.readouterr().err
    assert "--n cannot change with --sampler lhs" in err and err.count("\n") == 1


def test_retraining_reports_every_epoch_to_its_progress_bar(tiny_model):
    """fingertip run's retraining drives a bar through a callback (the library prints nothing)."""
    from explore._retrain import retrain
    from surrogate import load_checkpoint

    ticks: list[int] = []
    model = load_checkpoint(tiny_model)
    retrain(model, tiny_model.parent.parent / "sweep", [], 6, 0, progress=ticks.append)
    assert ticks == [1] * 6


def test_report_of_a_folder_that_is_not_a_run_is_one_line(tmp_path, capsys):
    code = explore.cli.main(["report", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "not a search run folder" in err


@pytest.mark.parametrize(("mode", "kind"), [("single", "database"), ("multi", "journal")])
def test_shared_storage_study_by_trial_and_both_modes(tiny_model, tmp_path, mode, kind):
    """--storage URL or journal file: several workers share one study trial by trial (here two
    in turn); multi-objective mode keeps the three objectives apart."""
    from explore._search import run_study
    from explore._storage import open_storage
    from surrogate import load_checkpoint

    model = load_checkpoint(tiny_model)
    if kind == "database":
        storage = f"sqlite:///{tmp_path / 'shared.db'}"
    else:
        storage = open_storage(str(tmp_path / "shared.log"))
    settings = SearchSettings(trials=20, mode=mode, seed=0)
    targets = load_targets()
    first = create_study(storage, "team", settings)
    run_study(first, model, model.space, targets, settings, round_=0, search="continuous",
              shared=True)  # fmt: skip
    second = create_study(storage, "team", dataclasses_replace(settings, trials=40))
    rows = run_study(second, model, model.space, targets, dataclasses_replace(settings, trials=40),
                     round_=0, search="continuous", shared=True)  # fmt: skip
    study = optuna.load_study(study_name="team", storage=storage)
    assert len(study.trials) == 40 and len(rows) == 40
    if mode == "multi":
        assert len(study.directions) == 3 and all(len(t.values) == 3 for t in study.trials)
        assert study.metric_names == ["compliance_error", "hysteresis_error", "wedge_effort"]
    for t, r in zip(study.trials, sorted(rows, key=lambda r: r.trial), strict=True):
        assert t.user_attrs["score"] == pytest.approx(r.score)  # re-scored rows = stored


def dataclasses_replace(obj, **kw):
    import dataclasses

    return dataclasses.replace(obj, **kw)


def test_the_screen_stacks_run_ahead_are_those_the_fe_only_screen_takes(tmp_path):
    """``screen_jobs`` (run beside the rounds' searches) names the very records the FE-only
    screen reads for its random stacks: the first half of its budget, whatever the nearest
    stacks are."""
    from explore._buildable import _choose, screen_jobs, screen_space
    from sim.design import load_space, with_every_layer
    from sim.materials import CATALOGUE
    from sim.options import SimOptions
    from sim.sweep import record_key

    space, options = load_space(), SimOptions()
    jobs, materials = screen_jobs(tmp_path, space, CATALOGUE, options, budget=8, seed=3)
    assert len(jobs) == 4 and materials is None  # no user material
    screen = screen_space(space, CATALOGUE)
    chosen = _choose(None, space, screen, CATALOGUE, 8, 3)  # no best: random stacks only
    keys = [record_key(with_every_layer(c.point), options, screen.catalogue) for c in chosen]
    assert [path.stem for path, _ in jobs] == keys[:4]
    assert all(path.parent == tmp_path / "fe" / "records" for path, _ in jobs)
    assert screen_jobs(tmp_path, space, CATALOGUE, options, budget=0, seed=3) == ([], None)


_PARENT = os.getpid()
_FOREGROUND: list[list] = []


def _fe_starved_in_the_background(jobs, options, **kwargs):
    """``run_fe`` as the rounds see it: in the background process it never gets the CPU (it
    sleeps); in the foreground it records what it was asked."""
    if os.getpid() != _PARENT:
        time.sleep(120)
    _FOREGROUND.append([path.name for path, _ in jobs])
    return {}


def test_a_starved_background_fe_is_stopped_and_its_references_run_in_the_foreground(
    tmp_path, monkeypatch
):
    """On a loaded machine the FE beside the rounds (nice 19) may not finish: the rounds do not
    wait for it; the references it did not make run at the job's own priority."""
    import contextlib
    import types

    import explore._rounds as rounds

    monkeypatch.setattr(rounds, "run_fe", _fe_starved_in_the_background)
    monkeypatch.setattr(rounds, "_screen_jobs", lambda run: ([], None))
    timings = {"fe_s": 0.0}

    @contextlib.contextmanager
    def timed(what):
        t0 = time.perf_counter()
        yield
        timings[what] += time.perf_counter() - t0

    run = types.SimpleNamespace(
        out=tmp_path, config=types.SimpleNamespace(workers=2), progress=False, timed=timed,
        setup=types.SimpleNamespace(options=None),
    )  # fmt: skip
    t0 = time.perf_counter()
    with rounds.fe_alongside(run):
        time.sleep(1.0)  # the rounds
    assert time.perf_counter() - t0 < 30
    assert _FOREGROUND == [["silicone_gls40.json", "polyurethane_74_45.json"]]
    assert timings["fe_s"] > 0


def test_a_validity_override_of_the_training_sweep_is_said_on_stderr_and_in_the_report(capsys):
    """The FE confirms with the training sweep's options: one made with a global strain limit
    (the shipped surrogate's, before the per-layer limits) holds every layer to it, said so."""
    from types import SimpleNamespace

    from explore._pipeline import _note_validity_override
    from explore._report import _validity_override_lines
    from sim.options import options_from_dict

    own = SimOptions()
    over = options_from_dict({**own.as_dict(), "validity": {"max_compressive_log_strain": 0.6}})
    _note_validity_override(SimpleNamespace(options=own))
    assert capsys.readouterr().err == ""
    assert _validity_override_lines(own) == []
    _note_validity_override(SimpleNamespace(options=over))
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "validity.max_compressive_log_strain=0.6" in err[0]
    (line,) = _validity_override_lines(over)
    assert "`validity.max_compressive_log_strain` = 0.6" in line
