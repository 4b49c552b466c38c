"""``sim._special.exprel`` (numpy) gives the bits of ``scipy.special.exprel``, which it replaced
to keep scipy.special out of ``fingertip simulate``'s start-up."""

from __future__ import annotations

import numpy as np
from scipy.special import exprel as scipy_exprel

from sim._special import exprel


def test_exprel_matches_scipy_bit_for_bit():
    rng = np.random.default_rng(0)
    eps = np.finfo(float).eps
    x = np.concatenate(
        [
            -(10.0 ** rng.uniform(-20, 3, 200_000)),  # -dt/tau: the Prony updates
            10.0 ** rng.uniform(-20, 2.8, 20_000),  # alpha s / 2 of the hyperfoam law
            rng.uniform(-4 * eps, 4 * eps, 20_000),  # around the switch to exactly 1
            [0.0, -0.0, eps, -eps, np.nextafter(eps, 0), 709.0, 710.0, 800.0, -800.0],
        ]
    )
    assert np.array_equal(exprel(x), scipy_exprel(x))


def test_exprel_of_a_scalar_is_a_scalar():
    assert exprel(0.0) == 1.0 and np.ndim(exprel(-0.5)) == 0
    assert exprel(-0.5) == scipy_exprel(-0.5)
