"""Credible answers: what the surrogate learns of an FE result's trust (sim.protocols.trust), how
the search keeps away from designs predicted not credible (explore._objective.infeasibility), which
FE results may be answers (explore._summary.credible, per family) and the sensitivities that say
what would close a missed target (explore._sensitivity)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from explore._objective import infeasibility, point_layer_limits, point_strain_limits
from explore._search import design_family, family_space, predict_rows
from explore._sensitivity import STEP, sensitivities, sensitivity_notes
from explore._summary import credible, summarise
from explore._types import Candidate, Confirmation
from sim.design import Targets, load_space, point_to_design
from sim.protocols import (
    LAYER_STRAIN_OUTPUTS,
    TRUST_OUTPUTS,
    TappingOptions,
    ValidityOptions,
    strain_limit_of,
    trust_flags,
    trust_values,
)
from sim.protocols.validity import PAPER_LOG_STRAIN

HUMAN = {"disp_at_1N_mm": 1.83, "disp_at_4N_mm": 2.91, "hysteresis_Nmm": 2.26}
TARGETS = Targets(dict(HUMAN), reading="from_first_touch", max_sag_mm=0.37)


# ----------------------------------------------------------------------------- sim.protocols.trust
def test_trust_values_read_diagnostics_and_table_cells():
    diag = {
        "tapping_max_compressive_log_strain": 0.4,
        "plate_max_compressive_log_strain": "0.7",  # a table.csv cell
        "tapping_min_J": 0.9,
        "plate_min_J": 0.8,
        "wedge_min_J": "",
        "tapping_reached_base": False,
        "plate_reached_base": "True",
        "wedge_folded": False,
        "tapping_residual": 1e-4,
        "tapping_max_estimated_error": None,
        "status": "failed",
    }
    v = trust_values(diag)
    assert v["failed"] == 1.0 and trust_values({"status": "ok"})["failed"] == 0.0
    assert list(v) == [*TRUST_OUTPUTS, *LAYER_STRAIN_OUTPUTS]
    assert all(math.isnan(v[m]) for m in LAYER_STRAIN_OUTPUTS)  # a table without the columns
    assert v["plate_max_compressive_log_strain"] == 0.7 and math.isnan(v["wedge_min_J"])
    assert v["reached_base"] == 1.0 and v["folded"] == 0.0  # any protocol
    assert math.isnan(v["tapping_max_estimated_error"])


def test_trust_flags_apply_the_solvers_thresholds():
    validity, tapping = ValidityOptions(), TappingOptions()
    lim, tol = strain_limit_of(validity), tapping.residual_tol
    assert lim == PAPER_LOG_STRAIN  # without the designs' materials: the paper's limit
    values = {
        "tapping_max_compressive_log_strain": np.array([0.5 * lim, 1.1 * lim, 0.5, np.nan]),
        "wedge_min_J": np.array([0.9, 0.9, 0.5 * validity.min_J, 0.9]),
        "tapping_residual": np.array([0.1 * tol, 0.1 * tol, 0.1 * tol, 10 * tol]),
    }
    f = trust_flags(values, validity, tapping)
    np.testing.assert_array_equal(f["valid"], [True, False, False, True])
    np.testing.assert_array_equal(f["settled"], [True, True, True, False])
    assert f["why"][0] == "" and "strain" in f["why"][1] and "J" in f["why"][2]
    assert "unsettled" in f["why"][3]
    assert not trust_flags({"failed": np.array([0.8])}, validity, tapping)["valid"][0]
    # the wedge's strain is not held against a design by default (its tip is a singularity)
    wedge = {"wedge_max_compressive_log_strain": np.array([5.0])}
    assert trust_flags(wedge, validity, tapping)["valid"].all()


def test_on_the_bound_a_design_is_credible_only_where_its_interval_keeps_within_the_limits():
    """``--credible-at bound`` (``explore._search._judged``): a strain whose median is within
    its limit and whose 90 % interval passes it is credible on the median, not on the bound; a
    volume ratio J is judged on its interval's lower end; a yes/no output by its mean either
    way. Design 0 keeps within every limit on either rule, design 1 passes the strain limit
    at the interval's top, design 2 the J limit at its bottom."""
    from types import SimpleNamespace

    from explore._search import _judged

    validity, tapping = ValidityOptions(), TappingOptions()
    lim, j = PAPER_LOG_STRAIN, validity.min_J
    names = ["tapping_max_compressive_log_strain", "wedge_min_J", "folded"]
    median = np.array([[0.5 * lim, j + 0.3, 0.0], [0.95 * lim, j + 0.3, 0.0],
                       [0.5 * lim, 1.05 * j, 0.0]])  # fmt: skip
    spread = np.array([[0.1 * lim, 0.1, 0.0], [0.1 * lim, 0.1, 0.0], [0.1 * lim, 0.1, 0.0]])
    pred = SimpleNamespace(metric_names=names, median=median, mean=median,
                           lower_90=median - spread, upper_90=median + spread)  # fmt: skip
    cols = {m: i for i, m in enumerate(names)}
    on_median, _ = infeasibility(_judged(pred, cols, False), TARGETS, validity, tapping)
    on_bound, why = infeasibility(_judged(pred, cols, True), TARGETS, validity, tapping)
    np.testing.assert_array_equal(on_median == 0, [True, True, True])
    np.testing.assert_array_equal(on_bound == 0, [True, False, False])
    assert "strain" in why[1] and "J" in why[2]
    # a probability is no interval: a folding predicted at 0.3 stays credible on the bound
    pred.mean = pred.median = median + np.array([0.0, 0.0, 0.3])
    pred.upper_90 = pred.median + 0.6
    assert _judged(pred, cols, True)["folded"][0] == pytest.approx(0.3)


def test_credible_at_takes_median_or_bound_and_names_itself_otherwise():
    from explore._config import OptimizeConfig
    from sim.errors import DesignError

    OptimizeConfig(credible_at="bound").check()
    OptimizeConfig(credible_at=None).check()
    with pytest.raises(DesignError, match=r"--credible-at.*median or bound, got 'upper'"):
        OptimizeConfig(credible_at="upper").check()


@pytest.mark.parametrize(
    ("argv", "model", "judged_on"),
    [
        ([], "3d", "bound"),  # the 3D search: its answers sit on the limits, FE costs minutes
        ([], "2d", "median"),
        (["--credible-at", "median"], "3d", "median"),
        (["--credible-at", "bound"], "2d", "bound"),
    ],
)
def test_credible_at_defaults_to_the_bound_in_3d_and_the_median_in_2d(argv, model, judged_on):
    """``explore._config.credible_at``: what a search judges credibility on when
    ``--credible-at`` is not given depends on its model; a given one is kept as given (and
    recorded: a 3D run asked for the median is not turned into a bound one)."""
    from explore._config import credible_at
    from explore.cli import _optimize_config, build_parser

    config = _optimize_config(build_parser().parse_args(["run", *argv]))
    assert config.credible_at == (argv[1] if argv else None)
    assert credible_at(config.credible_at, model) == judged_on


@pytest.mark.parametrize(
    ("given", "model", "trials"), [(None, "2d", 128), (None, "3d", 1024), (7, "3d", 7)]
)
def test_the_continuous_studys_trials_default_to_the_models(given, model, trials):
    """``explore._config.search_trials``: 128 in 2D, 1024 in 3D (a search costs seconds where a
    3D confirmation costs minutes: ``studies/search_budget.py``); a given ``--trials`` is kept."""
    from explore._config import search_trials
    from explore.cli import _optimize_config, build_parser

    argv = ["run"] + ([] if given is None else ["--trials", str(given)])
    config = _optimize_config(build_parser().parse_args(argv))
    assert config.trials == given and search_trials(config.trials, model) == trials


def test_config_json_records_the_rule_and_an_older_folder_resumes_on_the_median(tmp_path):
    """config.json records the rule the search used (``explore._config.setup``); a folder made
    when None meant the median resumes with the median, and is refused with the bound."""
    from explore._config import OptimizeConfig, setup
    from explore._run_folder import write_config
    from sim.errors import DesignError
    from sim.provenance import provenance

    out = tmp_path / "run"
    two = OptimizeConfig(model="2d")
    record = setup(two, out).record
    assert record["credible_at"] == "median" and record["trials"] == 128  # and its budget
    write_config(out, {**record, "credible_at": None}, provenance(record, 0, kind="optimize"))
    assert setup(two, out).record["credible_at"] == "median"  # resumes
    with pytest.raises(DesignError, match=r"another configuration \(credible_at\)"):
        setup(OptimizeConfig(model="2d", credible_at="bound"), out)


def test_trust_flags_hold_each_design_to_its_own_strain_limit():
    """The same predicted strain is credible in a design whose materials were tested further
    and not in one tested less far; an override holds every design to one number, and says
    so."""
    tapping = TappingOptions()
    strain = {"tapping_max_compressive_log_strain": np.array([0.7, 0.7])}
    own = np.array([1.0498, 0.5276])  # a foam core's limit, a gel's
    f = trust_flags(strain, ValidityOptions(), tapping, own)
    np.testing.assert_array_equal(f["valid"], [True, False])
    assert f["why"][1] == "tapping strain > 0.5276"
    f = trust_flags(strain, ValidityOptions(max_compressive_log_strain=0.65), tapping)
    np.testing.assert_array_equal(f["valid"], [False, False])
    assert f["why"][0] == "tapping strain > 0.65 (overridden)"
    # the search's penalty grows with the strain over each design's own limit
    penalty, _ = infeasibility(strain, TARGETS, ValidityOptions(), tapping, own)
    assert penalty[0] == 0.0 and penalty[1] == pytest.approx(1.0 + 1.0 + (0.7 / 0.5276 - 1))


def test_a_design_point_is_held_to_the_largest_of_its_layers_limits():
    """Per point, the limit of its materials (sim.protocols.validity.layer_limit): a family by
    its family, a catalogue material by its name; the largest of the layers' (the surrogate
    predicts the design's largest strain, wherever it is); None under an override."""
    from sim.materials._tests import tested_range

    gel_only = _gel_point(0.01, 0.2)
    gel_over_foam = {
        **gel_only, "layers.count": 2, "skin.material": "gel", "skin.thickness_mm": 1.0,
        "skin.mu0_MPa": 0.02, "skin.alpha": 3.0, "skin.g_total": 0.2, "skin.tau_s": 0.1,
        "core.material": "foam", "core.nu": 0.2,
    }  # fmt: skip
    paper = {**gel_only, "core.material": "silicone_gls40"}
    limits = point_strain_limits([gel_only, gel_over_foam, paper], None, ValidityOptions())
    want = [tested_range(n).max_compressive_log_strain
            for n in ("family.gel", "family.foam", "silicone_gls40")]  # fmt: skip
    np.testing.assert_array_equal(limits, want)
    assert want == [0.5276, 1.0498, 0.5978]
    over = ValidityOptions(max_compressive_log_strain=0.7)
    assert point_strain_limits([gel_only], None, over) is None


def test_each_layer_is_held_to_its_own_limit_where_its_strain_is_predicted():
    """A gel skin over a foam core whose skin is strained 0.7 and core 0.9: within the design's
    largest limit (the foam's 1.05), beyond the skin's own (the gel's 0.53). Judged layer by
    layer it is not credible, and the reason names the layer; a single-layer design has no skin
    (NaN) and is judged on its core alone; the penalty grows with each layer's excess."""
    gel_only = _gel_point(0.01, 0.2)
    gel_over_foam = {
        **gel_only, "layers.count": 2, "skin.material": "gel", "skin.thickness_mm": 1.0,
        "skin.mu0_MPa": 0.02, "skin.alpha": 3.0, "skin.g_total": 0.2, "skin.tau_s": 0.1,
        "core.material": "foam", "core.nu": 0.2,
    }  # fmt: skip
    validity, tapping = ValidityOptions(), TappingOptions()
    layers = point_layer_limits([gel_over_foam, gel_only], None, validity)
    np.testing.assert_array_equal(layers["skin"], [0.5276, np.nan])
    np.testing.assert_array_equal(layers["core"], [1.0498, 0.5276])
    assert np.isnan(layers["middle"]).all()
    values = {
        "tapping_max_compressive_log_strain": np.array([0.9, 0.5]),
        "tapping_skin_max_compressive_log_strain": np.array([0.7, np.nan]),
        "tapping_core_max_compressive_log_strain": np.array([0.9, 0.5]),
    }
    largest = point_strain_limits([gel_over_foam, gel_only], None, validity)
    # judged on the largest strain alone, the gel skin's strain passes unseen
    assert trust_flags(values, validity, tapping, largest)["valid"].all()
    f = trust_flags(values, validity, tapping, role_limits=layers)
    np.testing.assert_array_equal(f["valid"], [False, True])
    assert f["why"][0] == "tapping skin strain > 0.5276"
    penalty, why = infeasibility(values, TARGETS, validity, tapping, layer_limits=layers)
    assert penalty[1] == 0.0 and why[0] == "tapping skin strain > 0.5276"
    assert penalty[0] == pytest.approx(1.0 + 1.0 + (0.7 / 0.5276 - 1))
    # an override holds every layer to one number: the layers' limits are not used
    assert (
        point_layer_limits([gel_over_foam], None, ValidityOptions(max_compressive_log_strain=1))
        is None
    )


# ----------------------------------------------------------------------------- the search
def test_infeasibility_ranks_credible_designs_first_and_grows_with_the_excess():
    validity, tapping = ValidityOptions(), TappingOptions()
    lim = strain_limit_of(validity)
    values = {
        "tapping_max_compressive_log_strain": np.array([0.3, 1.2 * lim, 2.0 * lim, 0.3]),
        "sag_mm": np.array([0.1, 0.1, 0.1, 0.5]),
    }
    penalty, why = infeasibility(values, TARGETS, validity, tapping)
    assert penalty[0] == 0.0 and why[0] == ""
    assert 1.0 < penalty[1] < penalty[2]  # further beyond the limit: worse
    assert penalty[3] > 1.0 and "sag" in why[3]
    no_limit = Targets(dict(HUMAN))
    assert infeasibility({"sag_mm": np.array([5.0])}, no_limit, validity, tapping)[0][0] == 0.0


@dataclass
class _Pred:
    metric_names: tuple
    median: np.ndarray
    mean: np.ndarray
    std: np.ndarray
    lower_90: np.ndarray
    upper_90: np.ndarray
    in_domain: np.ndarray
    reasons: tuple
    by_rule: np.ndarray


class FakeSurrogate:
    """A smooth stand-in: the displacements from touch grow as the core softens (1.83 mm at
    1 N for a core of 10 kPa), the tapping strain with them, the sag with the core's g_total;
    hysteresis on target. Enough to check the search's bookkeeping, not the physics."""

    names = (
        "disp_at_1N_from_touch_mm", "disp_at_4N_from_touch_mm", "hysteresis_Nmm",
        "wedge_peak_force_N", "sag_mm", *TRUST_OUTPUTS,
    )  # fmt: skip

    def __init__(self):
        self.space = load_space()

    def predict(self, points):
        n = len(points)
        out = np.full((n, len(self.names)), np.nan)
        for i, p in enumerate(points):
            mu = p.get("core.mu0_MPa")
            mu = 0.05 if mu is None or not math.isfinite(mu) else mu
            g = p.get("core.g_total")
            g = 0.0 if g is None or not math.isfinite(g) else g
            d1 = 1.83 * (0.01 / mu) ** 0.5
            row = {
                "disp_at_1N_from_touch_mm": d1,
                "disp_at_4N_from_touch_mm": 2.91 * d1 / 1.83,
                "hysteresis_Nmm": 2.26,
                "wedge_peak_force_N": 0.1,
                "sag_mm": 0.5 * g,
                "tapping_max_compressive_log_strain": 0.25 * d1,
                "tapping_min_J": 0.99,
                "tapping_residual": 0.0,
                "tapping_max_estimated_error": 0.0,
                "reached_base": 0.0,
                "folded": 0.0,
                "failed": 0.0,
            }
            out[i] = [row.get(m, np.nan) for m in self.names]
        ones = np.ones(n, dtype=bool)
        return _Pred(self.names, out, out, 0.01 * np.abs(out), 0.9 * out, 1.1 * out, ones,
                     ("",) * n, np.zeros_like(out, dtype=bool))  # fmt: skip


def _gel_point(mu: float, g: float) -> dict:
    space = load_space()
    p = {
        "geometry.half_width_mm": 6.0, "geometry.height_mm": 5.5, "geometry.exponent": 1.8,
        "layers.count": 1, "core.material": "gel", "core.mu0_MPa": mu, "core.alpha": 3.0,
        "core.g_total": g, "core.tau_s": 0.1,
    }  # fmt: skip
    return space.check(p)


def test_the_search_flags_and_penalises_designs_predicted_not_credible():
    sur = FakeSurrogate()
    on_target = _gel_point(0.01, 0.2)  # predicted human-like, strain 0.46, sag 0.1: credible
    # strain 0.55: within the paper's 0.60, beyond the gel family's own 0.53: not credible
    too_soft = _gel_point(0.007, 0.2)
    putty = _gel_point(0.01, 0.9)  # sag 0.45 > 0.37
    rows = predict_rows(sur, [on_target, too_soft, putty], TARGETS)
    assert not rows[0].flags and rows[0].score == pytest.approx(0.1 * 0.1 / 2.35)
    for r in rows[1:]:
        assert any(f.startswith("predicted not credible") for f in r.flags)
        assert r.score > 1.0 > rows[0].score
    free = predict_rows(sur, [putty], TARGETS, allow_untrusted=True)[0]
    assert free.score == pytest.approx(rows[0].score) and free.flags  # scored freely, flagged


def test_sensitivities_name_the_parameter_that_closes_the_gap():
    sur = FakeSurrogate()
    stiff = _gel_point(0.04, 0.2)  # displacements half the human's: the core must soften
    sens = {(s.name, s.direction): s for s in sensitivities(sur, stiff, TARGETS)}
    down = sens[("core.mu0_MPa", -1)]
    assert down.d_error["disp_at_1N_mm"] > 0 and down.credible
    p = sur.space["core.mu0_MPa"]
    assert math.log(down.value / down.moved) == pytest.approx(
        STEP * math.log(p.high / p.low), rel=1e-9
    )
    assert sens[("core.g_total", 1)].d_error["disp_at_1N_mm"] == 0.0  # no effect here
    notes = sensitivity_notes(sur, stiff, TARGETS, 0.05)
    assert len(notes) == 2  # both displacements missed; the hysteresis is met
    assert "core.mu0_MPa lower" in notes[0].split(": ", 1)[1].split(";")[0]
    # d1 = 1.83 (0.01 / mu)^0.5: linearised on log(mu), the target is met near mu = 0.01
    needed = float(notes[0].split("core.mu0_MPa <= ")[1].split(" ")[0])
    assert 0.006 < needed < 0.012 and "within the space" in notes[0]
    # from the stiffest core, linear in log(mu) the target lies beyond the space's lower bound
    far = sensitivity_notes(sur, _gel_point(0.35, 0.2), TARGETS, 0.05)[0]
    assert "core.mu0_MPa alone cannot meet" in far and "stops at 0.0025" in far
    # a change per step of nearly nothing extrapolates beyond any bound, not to an overflow
    from explore._sensitivity import _needed

    up = sens[("core.mu0_MPa", 1)]
    for d in (1e-300, -1e-300):
        v, outside = _needed(sur, up, 0.5, d)
        assert outside and v == pytest.approx(math.exp(700.0))


# ----------------------------------------------------------------------------- answers
def _confirmation(point: dict, fe: dict, search="continuous", **diag) -> Confirmation:
    cand = Candidate(point, "best", 0, 0, search, 0.0, {}, True, 0.0)
    from explore._objective import closeness

    score = float(closeness(fe, TARGETS).score)
    return Confirmation(cand, f"k{id(fe)}", "ok", "", fe, score,
                        diagnostics={"settled": True, "valid": True, **diag})  # fmt: skip


def _fe(scale: float, sag: float) -> dict:
    return {
        "disp_at_1N_mm": 1.83 * scale + sag, "disp_at_4N_mm": 2.91 * scale + sag,
        "disp_at_1N_from_touch_mm": 1.83 * scale, "disp_at_4N_from_touch_mm": 2.91 * scale,
        "hysteresis_Nmm": 2.26, "wedge_peak_force_N": 0.1, "sag_mm": sag,
    }  # fmt: skip


def test_answers_are_credible_per_family_with_both_readings():
    space = load_space()
    gel = _gel_point(0.01, 0.2)
    foam = space.check({**gel, "core.material": "foam", "core.nu": 0.1})
    cat = space.check(
        {k: v for k, v in gel.items() if not k.startswith("core.")}
        | {"core.material": "ecoflex_0030_dawood"}
    )
    assert [design_family(p) for p in (gel, foam, cat)] == ["gel", "foam", "catalogue"]
    perfect_putty = _confirmation(gel, _fe(1.0, 1.2))  # on target from touch, sags 1.2 mm
    good_gel = _confirmation(gel | {"core.alpha": 2.5}, _fe(0.97, 0.1))
    foam_c = _confirmation(foam, _fe(0.9, 0.2), search="foam")
    invalid = _confirmation(cat, _fe(1.0, 0.0), search="buildable", valid=False)
    cat_c = _confirmation(cat | {"geometry.height_mm": 6.0}, _fe(0.6, 0.0), search="buildable")
    assert not credible(perfect_putty, TARGETS) and credible(good_gel, TARGETS)
    assert credible(perfect_putty, TARGETS, allow_untrusted=True)
    s = summarise([perfect_putty, good_gel, foam_c, invalid, cat_c], TARGETS, 0.05, [], [], space)
    a = s.answers
    assert a["best"]["point"]["core.alpha"] == 2.5 and a["gel"]["fe_score"] == a["best"]["fe_score"]
    assert a["foam"]["family"] == "foam" and a["buildable"]["point"]["geometry.height_mm"] == 6.0
    r = a["best"]["readings"]
    assert r["from_first_touch"]["disp_at_1N_mm"] == pytest.approx(1.83 * 0.97)
    assert r["from_undeformed_top"]["disp_at_1N_mm"] == pytest.approx(1.83 * 0.97 + 0.1)
    assert r["sag_mm"] == 0.1 and a["best"]["credible"]
    none = summarise([perfect_putty, invalid], TARGETS, 0.05, [], [], space)
    assert none.answers["best"] is None and "sagged" in none.notes[0]
    assert point_to_design(gel, space.catalogue).layers[0].material.law.nu >= 0.495


def test_a_family_space_drops_the_layers_that_cannot_be_of_the_family():
    from sim.design import space_from_dict

    space = space_from_dict(
        {
            "layers": {
                "count": {"choice": [1, 2]},
                "skin": {"thickness_mm": {"low": 0.3, "high": 1.0},
                         "material": {"choice": ["silicone_gls40"]}},
                "core": {"material": {"choice": ["gel", "polyurethane_74_45"]},
                         "mu0_MPa": {"low": 0.01, "high": 0.1}, "alpha": {"value": 2.0},
                         "g_total": {"value": 0.3}, "tau_s": {"value": 0.1}},
            }
        }
    )  # fmt: skip
    gel = family_space(space, "gel")
    assert gel["layers.count"].choices == (1,) and gel["core.material"].choices == ("gel",)
    assert family_space(space, "foam") is None  # no foam in this space


def test_family_spaces_hold_one_family():
    space = load_space()
    gel, foam = family_space(space, "gel"), family_space(space, "foam")
    assert gel["core.material"].choices == ("gel",) == gel["skin.material"].choices
    assert foam["core.material"].choices == ("foam",)
    assert "foam" not in foam["skin.material"].choices
    rng = np.random.default_rng(1)
    for sub, family in ((gel, "gel"), (foam, "foam")):
        for _ in range(20):
            p = sub.point(rng.random(len(sub.sampled)))
            assert design_family(p) == family


def test_untrusted_answers_are_confirmed_to_the_end(tmp_path):
    """FE confirms like the training sweep, which stops a protocol at its first step beyond
    the validity limits; with --allow-untrusted an answer may lie beyond them, so its FE runs to
    the end and reports the (extrapolated) numbers."""
    from explore._config import OptimizeConfig, setup

    trusted = setup(OptimizeConfig(), tmp_path / "a").options
    untrusted = setup(OptimizeConfig(allow_untrusted=True), tmp_path / "b").options
    assert trusted.validity.stop_at_violation is True
    assert untrusted.validity.stop_at_violation is False
    assert untrusted == trusted.without_validity_stop()
