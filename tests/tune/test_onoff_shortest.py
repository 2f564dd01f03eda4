"""`pamd tune --loop onoff`'s dead band from the PWM's shortest pulse, three times per
valve, alternating, their typical step taken (pamd/client/tune/onoff_steps.py): one pulse's step is
not the valve's (its spool's switching delays, not the tick, decide how long it is
really open: 7, 8 or 9 ms of spool for the same 6-tick pulse on the real clock), so
the typical step is the mean of the three; one held open by a stall or cut short is
left out, the spool's own scatter never is. A pulse's recorded length is the loop time
from the tick that opened its valve to the one that shut it: a skipped tick (a busy
PC) neither shortens it nor hides one a tick long, which is left out too. The step
test is the session's one run (tests/tune/conftest.py)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from pamd.client.tune.ident_run import TuneRefused
from pamd.client.tune.onoff_steps import (
    INFLATE_OPEN,
    LEVEL_BAR,
    PULSES,
    RATE_PULSE_S,
    SHORTEST_REPEATS,
    Measurement,
    Pulse,
    StepTest,
    check,
    counted,
    derive,
    measurements,
    response,
    shortest_of,
    typical_step_bar,
)

PWM_PERIOD_S = 0.02
#: where the exhaust valve's shortest pulses are in PULSES (the smaller valve's: the
#: dead band is half its typical step)
EXHAUST_SHORTEST = (3, 5, 7)

#: the shortest pulses' steps (bar, in the order they ran: inflate, exhaust x 3) of 13
#: runs on the real clock (loaded 2-core PC; the last 6 beside two CPU hogs)
REAL_CLOCK_STEPS_BAR = [
    (+0.0512, -0.0249, +0.0572, -0.0330, +0.0501, -0.0280),
    (+0.0512, -0.0297, +0.0501, -0.0332, +0.0491, -0.0294),
    (+0.0506, -0.0296, +0.0487, -0.0290, +0.0427, -0.0336),
    (+0.0457, -0.0283, +0.0575, -0.0321, +0.0447, -0.0286),
    (+0.0512, -0.0287, +0.0490, -0.0317, +0.0490, -0.0265),
    (+0.0576, -0.0290, +0.0560, -0.0255, +0.0487, -0.0264),
    (+0.0509, -0.0287, +0.0554, -0.0288, +0.0484, -0.0302),
    (+0.0492, -0.0289, +0.0488, -0.0318, +0.0555, -0.0292),
    (+0.0557, -0.0281, +0.0487, -0.0282, +0.0552, -0.0334),
    (+0.0489, -0.0321, +0.0548, -0.0285, +0.0494, -0.0261),
    (+0.0519, -0.0330, +0.0494, -0.0319, +0.0505, -0.0292),
    (+0.0500, -0.0326, +0.0555, -0.0284, +0.0435, -0.0329),
    (+0.0520, -0.0282, +0.0505, -0.0280, +0.0440, -0.0254),
]


def _dead_band(measured: list[Measurement], count_mm: float) -> float:
    return derive(measured, count_mm, PWM_PERIOD_S)["dead_band_bar"]


def _scaled(measured: list[Measurement], k: int, factor: float) -> list[Measurement]:
    """`measured` with the k-th pulse's pressure step times `factor`."""
    return [m._replace(pressure_step_bar=m.pressure_step_bar * factor) if i == k else m
            for i, m in enumerate(measured)]


def _exhaust(measured: list[Measurement]) -> list[float]:
    return [abs(measured[k].pressure_step_bar) for k in EXHAUST_SHORTEST]


def _repeats(steps_bar: list[float], valve: str = "exhaust") -> list[Measurement]:
    return [Measurement(Pulse("inflate" if valve == "inflate" else "exhaust", None), dp, 0.0)
            for dp in steps_bar]


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
    """No repeat is left out of a normal run: the dead band is half the mean of the
    exhaust valve's three steps (the session's -0.0274, -0.0296, -0.0293 bar), and
    moves with each of them."""
    test, _ = onoff_run
    measured = measurements(test)
    assert [measured[k].pulse.valve for k in EXHAUST_SHORTEST] == ["exhaust"] * 3
    assert [r.off_by_s for r in test.responses()] == [0.0] * len(PULSES)  # all as commanded
    assert counted(shortest_of(measured, "exhaust")) == [True] * SHORTEST_REPEATS
    assert counted(shortest_of(measured, "inflate")) == [True] * SHORTEST_REPEATS
    steps = _exhaust(measured)
    assert _dead_band(measured, test.count_mm) == pytest.approx(0.5 * sum(steps) / 3)
    for k in EXHAUST_SHORTEST:
        nudged = _scaled(measured, k, 1.03)
        assert _dead_band(nudged, test.count_mm) == pytest.approx(
            0.5 * sum(_exhaust(nudged)) / 3)


@pytest.mark.parametrize("factor", [2.0, 0.3])
def test_a_pulse_held_open_or_cut_short_is_left_out(onoff_run: tuple[StepTest, Path],
                                                     factor: float) -> None:
    """One exhaust repeat's step twice the others' (a pulse the PC held open 6 ms past
    its 6: a stall) or a third of them (cut short): not the PWM's shortest pulse, so the
    dead band is half the mean of the other two; a mean over all three would move 30 %."""
    test, _ = onoff_run
    measured = measurements(test)
    spoilt = _scaled(measured, EXHAUST_SHORTEST[1], factor)
    assert counted(shortest_of(spoilt, "exhaust")) == [True, False, True]
    others = [_exhaust(measured)[k] for k in (0, 2)]
    assert _dead_band(spoilt, test.count_mm) == pytest.approx(0.5 * sum(others) / 2)


def test_the_spools_own_scatter_is_never_left_out(onoff_run: tuple[StepTest, Path]) -> None:
    """The spool open 9 against 7 ms of flow (its plant step of scatter both ways,
    +29 %) is the valve's own: counted. So is every step of 13 real-clock runs, quiet
    and beside CPU hogs, whose dead bands (half the smaller mean of three) then lie
    within 0.0135-0.0157 bar, the single pulse's 0.0124-0.0165."""
    test, _ = onoff_run
    measured = measurements(test)
    wide = _scaled(measured, EXHAUST_SHORTEST[1], 9.0 / 7.0)
    assert counted(shortest_of(wide, "exhaust")) == [True] * 3
    assert _dead_band(wide, test.count_mm) == pytest.approx(0.5 * sum(_exhaust(wide)) / 3)
    bands, single = [], []
    for steps in REAL_CLOCK_STEPS_BAR:
        fill, vent = _repeats(list(steps[0::2]), "inflate"), _repeats(list(steps[1::2]))
        assert counted(fill) == counted(vent) == [True] * 3, steps
        bands.append(0.5 * min(typical_step_bar(fill), -typical_step_bar(vent)))
        single.append(0.5 * min(steps[0], -steps[1]))
    assert min(bands) >= 0.0134 and max(bands) <= 0.0157
    assert max(bands) - min(bands) < 0.6 * (max(single) - min(single))


def _recording(open_ms: list[int], shut_ms: int, skipped_ms: list[int]
               ) -> tuple[np.ndarray, ...]:
    """A recording at 1 kHz around one inflate pulse, its valve open at the ticks
    `open_ms` (deadlines, ms) and shut from `shut_ms`; the ticks `skipped_ms` missing (a
    busy PC: overrun_policy skip runs the next tick at the later deadline, no sample for
    the one skipped); the pressure 0.05 bar higher from the valve's shutting."""
    ticks = np.array([k for k in range(1000) if k not in skipped_ms])
    t_s = ticks * 1e-3
    flags = np.where(np.isin(ticks, open_ms), float(INFLATE_OPEN), 0.0)
    pressure = np.where(ticks >= shut_ms, 3.05, 3.0)
    return t_s, pressure, np.full(len(ticks), 190.0), flags


def test_a_skipped_tick_does_not_shorten_the_recorded_pulse() -> None:
    """A 300 ms pulse through 33 skipped ticks (as on the loaded PC, where 267 samples
    were refused as 'open 267 ms'): recorded 300 ms, as commanded. A 6 ms one
    with a tick skipped inside it: 6 ms, counted."""
    skipped = list(range(150, 399, 15))[:16] + list(range(151, 399, 15))[:17]
    t, p, length, flags = _recording([k for k in range(100, 400) if k not in skipped], 400,
                                     skipped)
    r, _ = response(t, p, length, flags, Pulse("inflate", 0.3), 0.05, 0.006)
    assert int(np.sum(flags > 0)) == 267
    assert r.pulse_s == pytest.approx(0.3) and r.off_by_s == 0.0
    t, p, length, flags = _recording([100, 101, 102, 104, 105], 106, [103])
    r, _ = response(t, p, length, flags, Pulse("inflate", None), 0.05, 0.006)
    assert r.pulse_s == pytest.approx(0.006) and r.off_by_s == 0.0
    assert r.pressure_step_bar == pytest.approx(0.05)
    assert counted([Measurement(r.pulse, r.pressure_step_bar, 0.0, r.off_by_s)] * 3) == [True] * 3


def test_a_shortest_pulse_a_tick_long_is_left_out(onoff_run: tuple[StepTest, Path]) -> None:
    """The tick before a 6 ms pulse's last skipped: the next one, at the later deadline,
    is still within the pulse (its middle at 6 ms), so the valve shuts a tick late: 6
    samples over 7 ms of loop time. Recorded 7 ms, 1 ms off: left out of the typical
    step (the dead band is about the PWM's shortest pulse), though its step is within
    the scatter; the dead band is then the other two's."""
    t, p, length, flags = _recording([100, 101, 102, 103, 104, 106], 107, [105])
    r, _ = response(t, p, length, flags, Pulse("inflate", None), 0.05, 0.006)
    assert r.pulse_s == pytest.approx(0.007) and r.off_by_s == pytest.approx(0.001)
    test, _ = onoff_run
    measured = measurements(test)
    k = EXHAUST_SHORTEST[1]
    late = [m._replace(off_by_s=0.001) if i == k else m for i, m in enumerate(measured)]
    assert counted(shortest_of(late, "exhaust")) == [True, False, True]
    others = [_exhaust(measured)[j] for j in (0, 2)]
    assert _dead_band(late, test.count_mm) == pytest.approx(0.5 * sum(others) / 2)


def test_a_valve_whose_every_shortest_pulse_ran_long_is_refused(
        onoff_run: tuple[StepTest, Path]) -> None:
    """All three exhaust pulses a tick long: no typical step to take; the test is
    refused with the reason and what to do. The session's own run passes the check."""
    test, _ = onoff_run
    check(test)
    late = tuple(replace(r, pulse_s=r.pulse_s + 0.001, off_by_s=0.001)
                 if r.pulse.valve == "exhaust" else r for r in test.shortest)
    with pytest.raises(TuneRefused, match=r"none of the exhaust valve's shortest pulses ran "
                       r"the PWM's shortest pulse \(open 7, 7, 7 ms in the recording\): the "
                       r"PC skipped ticks"):
        check(replace(test, shortest=late))


def test_a_rate_pulse_a_tick_long_gives_the_same_rate(onoff_run: tuple[StepTest, Path]) -> None:
    """A 40 ms pulse the recording shows 41 ms long (a skipped tick near its end) moved
    the pressure for 41 ms: its step is scaled back by the recorded length, so the rate
    is the valve's, not 2.5 % high; an on-time pulse is taken as it is."""
    test, _ = onoff_run
    measured = measurements(test)
    nominal = derive(measured, test.count_mm, PWM_PERIOD_S)
    longer = [m._replace(pressure_step_bar=m.pressure_step_bar * 41 / 40, off_by_s=0.001)
              if m.pulse.pulse_s == RATE_PULSE_S else m for m in measured]
    again = derive(longer, test.count_mm, PWM_PERIOD_S)
    for key in ("fill_rate_bar_per_s", "vent_rate_bar_per_s"):
        assert again[key] == pytest.approx(nominal[key], rel=1e-12), key
    assert nominal["fill_rate_bar_per_s"] == pytest.approx(
        measured[0].pressure_step_bar / RATE_PULSE_S, rel=1e-12)
