"""The protocols' adaptive sub-steps (``sim.protocols.loading._march``): cut on failure, grow
back after easy steps, by the rule ``StepGrowth`` the wedge chooses per model dimension."""

from __future__ import annotations

from collections.abc import Callable
from types import SimpleNamespace

import numpy as np
import pytest

from sim.errors import SimulationError
from sim.fe import Control
from sim.fe.solver import StepResult
from sim.protocols.loading import WEDGE_STEP_GROWTH, StepGrowth, _march


class _Stub:
    """A body whose step converges in ``iterations`` when it spans at most ``largest`` s and
    fails otherwise; it logs every attempt as (start, end, converged)."""

    def __init__(self, largest: float, iterations: int | Callable[[float], int] = 3) -> None:
        self.t = 0.0
        self.disc = SimpleNamespace(dim=3)
        self.largest, self.iterations = largest, iterations
        self.log: list[tuple[float, float, bool]] = []

    def advance(self, t_new: float, control: Control, guess=None, factor_key=None) -> StepResult:
        ok = t_new - self.t <= self.largest + 1e-12
        self.log.append((self.t, t_new, ok))
        if ok:
            size, self.t = t_new - self.t, t_new
            its = self.iterations(size) if callable(self.iterations) else self.iterations
            return StepResult(True, its)
        return StepResult(False, 8, "stalled")


def _run(growth: StepGrowth, largest: float, iterations: int | Callable[[float], int] = 3) -> _Stub:
    body = _Stub(largest, iterations)
    times = np.linspace(0.1, 1.0, 10)
    _march(body, times, lambda t: Control.position(-t), "wedge", growth=growth)  # type: ignore[arg-type]
    assert body.t == pytest.approx(1.0)
    return body


def test_the_default_grows_back_after_one_easy_step():
    # steps of 0.1 fail, of 0.05 converge: cut, one easy step, doubled to 0.1 which fails again
    body = _run(StepGrowth(), largest=0.05)
    sizes = [round(b - a, 6) for a, b, _ in body.log[:6]]
    assert sizes == [0.1, 0.05, 0.05, 0.1, 0.05, 0.05]
    assert [ok for *_, ok in body.log[:4]] == [False, True, True, False]
    assert sum(not ok for *_, ok in body.log) == 10  # one failure in every schedule step


def test_two_easy_steps_in_a_row_before_the_step_grows():
    # steps of at most 0.025 converge: by the default every easy step at 0.025 doubles to 0.05,
    # which fails (fail, ok, fail, ok, ...); with (4, 2) two steps of 0.025 come first
    body = _run(StepGrowth(within_iterations=4, easy_steps=2), largest=0.025)
    sizes = [round(b - a, 6) for a, b, _ in body.log[:8]]
    assert sizes == [0.1, 0.05, 0.025, 0.025, 0.05, 0.025, 0.025, 0.05]
    default = _run(StepGrowth(), largest=0.025)
    assert [round(b - a, 6) for a, b, _ in default.log[:6]] == [0.1, 0.05, 0.025, 0.05, 0.025, 0.05]
    # the same 40 converged sub-steps, and about half the failed attempts
    assert sum(ok for *_, ok in body.log) == sum(ok for *_, ok in default.log) == 40
    assert sum(not ok for *_, ok in body.log) == 21
    assert sum(not ok for *_, ok in default.log) == 40


def test_a_step_not_easy_does_not_count_toward_growth():
    # converged steps of 5 iterations: easy by the default, not by within_iterations = 4, so
    # after the first cut the step never grows again
    body = _run(StepGrowth(within_iterations=4, easy_steps=2), largest=0.05, iterations=5)
    assert sum(not ok for *_, ok in body.log) == 1
    default = _run(StepGrowth(), largest=0.05, iterations=5)
    assert sum(not ok for *_, ok in default.log) == 10


def _slower_when_larger(size: float) -> int:
    """Newton's iterations of a converged step: 12 at 0.1 s, 8 at 0.05 s, 6 at 0.025 s."""
    return {0.1: 12, 0.05: 8, 0.025: 6}[round(size, 6)]


def test_a_slow_step_halves_the_next_until_the_steps_are_not_slow():
    # steps of 0.1 converge in 12 iterations, of 0.05 in 8: halving after more than 8
    # iterations gives 0.1 then 0.05 for good (8 is not more than 8, and not easy)
    body = _run(StepGrowth(4, 2, shrink_above=8), largest=0.1, iterations=_slower_when_larger)
    sizes = [round(b - a, 6) for a, b, _ in body.log]
    assert sizes[:3] == [0.1, 0.05, 0.05] and set(sizes[1:]) == {0.05}
    assert all(ok for *_, ok in body.log)
    # at shrink_above = 6 the 8 iterations of 0.05 halve once more, down to 0.025 for good
    finer = _run(StepGrowth(4, 2, shrink_above=6), largest=0.1, iterations=_slower_when_larger)
    assert [round(b - a, 6) for a, b, _ in finer.log][:3] == [0.1, 0.05, 0.025]
    # without the rule every step stays at the schedule's 0.1
    plain = _run(StepGrowth(4, 2), largest=0.1, iterations=_slower_when_larger)
    assert {round(b - a, 6) for a, b, _ in plain.log} == {0.1}


def test_a_halved_step_grows_back_after_easy_steps():
    # a slow first step halves the second; two easy steps in a row double it again
    body = _run(
        StepGrowth(4, 2, shrink_above=8),
        largest=0.1,
        iterations=lambda size: 12 if size > 0.075 else 3,
    )
    sizes = [round(b - a, 6) for a, b, _ in body.log[:5]]
    assert sizes == [0.1, 0.05, 0.05, 0.1, 0.05]


def test_largest_bounds_every_sub_step_from_the_first():
    # a quarter of the schedule's 0.1 from the start, where 0.1 itself would converge
    body = _run(StepGrowth(4, 2, shrink_above=8, largest=0.25), largest=0.1)
    assert {round(b - a, 6) for a, b, _ in body.log} == {0.025}
    assert len(body.log) == 40 and all(ok for *_, ok in body.log)
    # after a cut the step grows back to the bound, not to the schedule's spacing
    cut = _run(StepGrowth(4, 2, largest=0.5), largest=0.025)
    sizes = [round(b - a, 6) for a, b, _ in cut.log]
    assert sizes[:5] == [0.05, 0.025, 0.025, 0.05, 0.025] and max(sizes) == 0.05


def test_the_2d_wedge_keeps_the_rule_its_records_were_made_with():
    assert WEDGE_STEP_GROWTH[2] == StepGrowth(within_iterations=5, easy_steps=1, largest=1.0)
    assert WEDGE_STEP_GROWTH[3] != WEDGE_STEP_GROWTH[2]


def test_a_step_that_always_fails_gives_up_after_its_cuts():
    with pytest.raises(SimulationError, match="after step cutting"):
        _run(StepGrowth(), largest=0.0)
