"""`pamd tune --loop onoff`'s dead band from the PWM's shortest pulse, three times per
valve, alternating, the median step taken (pamd/tune/onoff.py): one pulse's step is not
the valve's (its spool's switching delays, not the tick, decide how long it is really
open: 7, 8 or 9 ms of spool for the same 6-tick pulse on the real clock), so one long
or short repeat must not move the dead band, and a normal run's three are all counted.
The step test is the session's one run (tests/tune/conftest.py)."""

from __future__ import annotations

from pathlib import Path

import pytest

from pamd.tune.onoff import (
    LEVEL_BAR,
    PULSES,
    SHORTEST_REPEATS,
    Measurement,
    Pulse,
    StepTest,
    derive,
    measurements,
    shortest_steps_bar,
)

PWM_PERIOD_S = 0.02


def _dead_band(measured: list[Measurement], count_mm: float) -> float:
    return derive(measured, count_mm, PWM_PERIOD_S)["dead_band_bar"]


def _scaled(measured: list[Measurement], k: int, factor: float) -> list[Measurement]:
    """`measured` with the k-th pulse's pressure step times `factor`."""
    return [(p, dp * factor if i == k else dp, v) for i, (p, dp, v) in enumerate(measured)]


def test_the_shortest_pulses_alternate_near_the_level(onoff_run: tuple[StepTest, Path]) -> None:
    """Three of each, inflate and exhaust alternating: the pressures before them span
    one inflate step (~0.05 bar) and the pairs' net (~0.02 bar each) and the level's
    slow drift, 0.09 bar in all, where three inflate pulses in a row would span their
    three steps, 0.15 bar (the step depends on the level: on the supply's and the
    atmosphere's differences from it)."""
    test, _ = onoff_run
    assert [p.valve for p in PULSES if p.pulse_s is None] == ["inflate", "exhaust"] * 3
    assert [r.pulse for r in test.shortest] == [p for p in PULSES if p.pulse_s is None]
    before = [r.trace.pressure_before_bar for r in test.shortest]
    assert max(before) - min(before) < 0.12
    assert all(abs(p - LEVEL_BAR) < 0.15 for p in before)


def test_a_normal_run_counts_all_three_repeats(onoff_run: tuple[StepTest, Path]) -> None:
    """No repeat is dropped in a normal run: the dead band is half the middle of the
    exhaust valve's three steps (the smaller valve's), and moves with whichever repeat
    is the middle one (the session's -0.0274, -0.0296, -0.0293 bar: the third)."""
    test, _ = onoff_run
    measured = measurements(test)
    steps = shortest_steps_bar(measured, "exhaust")
    assert len(steps) == SHORTEST_REPEATS and len(shortest_steps_bar(measured, "inflate")) == 3
    ordered = sorted(abs(dp) for dp in steps)
    assert _dead_band(measured, test.count_mm) == pytest.approx(0.5 * ordered[1])
    assert min(ordered) < ordered[1] < max(ordered)  # three different steps: a real median
    middle = 2 + 2 * [abs(dp) for dp in steps].index(ordered[1]) + 1  # its place in PULSES
    assert measured[middle][0] == Pulse("exhaust", None)
    nudge = 1.0 + 0.5 * (ordered[2] - ordered[1]) / ordered[1]  # still the middle one
    assert _dead_band(_scaled(measured, middle, nudge), test.count_mm) == pytest.approx(
        0.5 * nudge * ordered[1])


@pytest.mark.parametrize(("which", "factor"), [
    ("largest", 1.2),  # a late spool or tick: 9 ms of flow instead of 8 (the real clock's)
    ("smallest", 0.8),  # an early spool: 7 ms
])
def test_one_long_or_short_shortest_pulse_does_not_move_the_dead_band(
        onoff_run: tuple[StepTest, Path], which: str, factor: float) -> None:
    """One of the exhaust valve's three repeats moved 20 % further out, longer or
    shorter than the others (the spread measured on the real clock, where the single
    pulse's dead band ranged 0.0126-0.0164 bar over 9 runs): the median holds. The
    smallest is the first repeat, the single pulse of the test before the repeats."""
    test, _ = onoff_run
    measured = measurements(test)
    normal = _dead_band(measured, test.count_mm)
    steps = [abs(dp) for dp in shortest_steps_bar(measured, "exhaust")]
    k = steps.index(max(steps) if which == "largest" else min(steps))
    spoilt = _scaled(measured, 2 + 2 * k + 1, factor)
    assert spoilt != measured
    assert _dead_band(spoilt, test.count_mm) == normal
