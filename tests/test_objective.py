"""The closeness score: definition, like-with-like readings, failures never flatter."""

from __future__ import annotations

import numpy as np
import pytest

from explore._objective import WEDGE_REFERENCE_N, WEDGE_WEIGHT, closeness, objectives
from sim.design import Targets

HUMAN = {"disp_at_1N_mm": 1.83, "disp_at_4N_mm": 2.91, "hysteresis_Nmm": 2.26}


def test_meeting_every_target_with_no_wedge_force_scores_zero():
    c = closeness({**HUMAN, "wedge_peak_force_N": 0.0}, Targets(dict(HUMAN)))
    assert float(c.score) == 0.0
    np.testing.assert_allclose(objectives(c), [0.0, 0.0, 0.0])


def test_score_is_rms_relative_error_plus_weighted_wedge_effort():
    m = {
        "disp_at_1N_mm": 1.83 * 1.1,
        "disp_at_4N_mm": 2.91 * 0.8,
        "hysteresis_Nmm": 2.26 * 1.3,
        "wedge_peak_force_N": 1.175,
    }
    c = closeness(m, Targets(dict(HUMAN)))
    rms = np.sqrt((0.1**2 + 0.2**2 + 0.3**2) / 3)
    assert float(c.score) == pytest.approx(rms + WEDGE_WEIGHT * 1.175 / WEDGE_REFERENCE_N)
    np.testing.assert_allclose(
        objectives(c), [np.sqrt((0.1**2 + 0.2**2) / 2), 0.3, 0.5], rtol=1e-12
    )


def test_first_touch_targets_compare_with_first_touch_metrics():
    t = Targets(dict(HUMAN), reading="from_first_touch")
    m = {
        "disp_at_1N_mm": 9.0,  # from the undeformed top: must be ignored for these targets
        "disp_at_4N_mm": 9.0,
        "disp_at_1N_from_touch_mm": 1.83,
        "disp_at_4N_from_touch_mm": 2.91,
        "hysteresis_Nmm": 2.26,
        "wedge_peak_force_N": 0.0,
    }
    assert float(closeness(m, t).score) == 0.0


def test_missing_metric_is_never_a_good_score():
    m = {**HUMAN, "hysteresis_Nmm": None, "wedge_peak_force_N": 0.1}
    assert np.isinf(closeness(m, Targets(dict(HUMAN))).score)


def test_vectorised_over_designs():
    m = {k: np.array([v, 2 * v]) for k, v in HUMAN.items()}
    m["wedge_peak_force_N"] = np.array([0.0, np.nan])
    c = closeness(m, Targets(dict(HUMAN)))
    assert c.score.shape == (2,) and c.score[0] == 0.0 and np.isinf(c.score[1])


def test_the_wedge_reference_is_the_models_own():
    from explore._objective import WEDGE_REFERENCE_3D_N, WEDGE_REFERENCE_N, wedge_reference_N

    # a 2D force per 10 mm of finger against the 2D section's, a pad's against the pad's
    assert wedge_reference_N("2d") == WEDGE_REFERENCE_N == 2.35
    assert wedge_reference_N("3d") == WEDGE_REFERENCE_3D_N == 0.5215
    with pytest.raises(ValueError, match="no wedge reference"):
        wedge_reference_N("1d")
