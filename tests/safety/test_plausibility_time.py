"""Time from the samples (issue 23): the jump checks judge a change over the time
between the samples' stamps, widened by their declared jitter, never over the loop's
period; a burst of late samples stamped on arrival is no jump; a real jump still is.
And the stamps' jitter where it comes from: a stream read after its reader was held
up (`ArrivalWindow`), the simulated bursty link."""

from __future__ import annotations

import math

import pytest
from pamd.drivers.device import ArrivalWindow

from pamd.config.safety_schema import PlausibilityConfig
from pamd.loop.safety.plausibility import Plausibility
from pamd.muscle_type import force_model
from pamd.sim.sensors import SampledSensor

L0 = 200.0


def _plaus() -> Plausibility:
    return Plausibility("m2", ("m2.pressure", "m2.force", "m2.length"), PlausibilityConfig(),
                        L0, force_model("map"))


def _length(pl: Plausibility, now: float, length: float, l_t: float,
            l_j: float = 0.0) -> str | None:
    """One tick whose only new sample is the length (pressure and force unchanged)."""
    return pl.check(now, 3.0, 0.0, 300.0, 0.0, length, l_t, True, 3.0, True, 0.0, 0.0, l_j)


def test_a_late_tick_is_no_jump_the_time_is_the_samples() -> None:
    # the issue: 43 ms between ticks, +3.80 mm (88 mm/s) was "jumped in 1 ms"
    pl = _plaus()
    assert _length(pl, 1.000, 190.00, 1.000) is None
    assert _length(pl, 1.043, 193.80, 1.043) is None
    assert pl.length_ok


def test_a_burst_stamped_on_arrival_is_no_jump_within_its_jitter() -> None:
    # a CAN backlog read after a 40 ms hold: 2 ms apart by arrival, -5.16 mm, each
    # sample declared up to 40 ms older than its stamp
    pl = _plaus()
    assert _length(pl, 1.000, 195.00, 1.000, 0.001) is None
    assert _length(pl, 1.002, 189.84, 1.002, 0.040) is None
    assert pl.length_ok


def test_the_same_change_without_jitter_is_a_jump_naming_the_stamps() -> None:
    pl = _plaus()
    assert _length(pl, 1.000, 195.00, 1.000) is None
    said = _length(pl, 1.002, 189.84, 1.002)
    assert said is not None and "m2.length jumped -5.16 mm in 2 ms" in said
    assert "jitter 0 ms" in said and not pl.length_ok


def test_a_pressure_drop_is_judged_over_the_slow_sensors_own_period() -> None:
    # 10 samples/s: -3 bar in 100 ms is 30 bar/s, nothing like a dead sensor; the same
    # drop between two 1 kHz samples is
    slow, fast = _plaus(), _plaus()
    for pl, dt in ((slow, 0.1), (fast, 0.001)):
        assert pl.check(1.0, 5.0, 1.0, 300.0, 1.0, 190.0, 1.0, True, 5.0, True) is None
        found = pl.check(1.0 + dt, 2.0, 1.0 + dt, 300.0, 1.0, 190.0, 1.0, True, 2.0, True)
        assert (found is None) == (pl is slow), found


def test_a_stream_read_after_a_hold_declares_how_long_it_may_have_waited() -> None:
    w = ArrivalWindow()
    w.before_read(1.0)
    w.after_read(1.0009, True)  # waited 0.9 ms: the frame came after the call
    assert w.jitter_s(1.0009) == pytest.approx(0.0009)
    # the thread was held up 43 ms: the queued frames come back at once
    for k in range(5):
        t = 1.044 + 0.00002 * k
        w.before_read(t)
        w.after_read(t + 0.00001, True)
        assert w.jitter_s(t + 0.00001) >= 0.043
    w.before_read(1.045)
    w.after_read(1.0455, False)  # nothing more: idle
    assert w.jitter_s(1.0455) == 0.0


def test_a_bursty_simulated_link_delivers_old_samples_stamped_on_arrival() -> None:
    s = SampledSensor(period_s=0.001, burst_s=0.04, burst_every_s=0.5)
    seen = []
    for k in range(1, 700):
        t = k * 0.001
        s.update(t, t)  # the true value is the time it was sampled
        seen.append((t, s.value, s.stamp_s, s.jitter_s))
    # during the hold (0.50 .. 0.54 s) nothing new arrives
    hold = [v for t, v, _, _ in seen if 0.5 <= t < 0.54]
    assert len(set(hold)) == 1
    # after it the backlog drains: values older than their stamps, by up to the hold,
    # and each sample's declared jitter covers how much older it really is
    drain = [(t, v, st, j) for t, v, st, j in seen if 0.54 <= t < 0.6]
    assert max(st - v for _, v, st, _ in drain) >= 0.035
    assert all(st - v <= j + 1e-9 for _, v, st, j in drain)
    # a steady link: every sample arrives at once, stamped within a step
    steady = [(v, st, j) for t, v, st, j in seen if 0.1 <= t < 0.5]
    assert all(abs(st - v) < 1e-9 and j <= 0.001 + 1e-9 for v, st, j in steady)


def test_an_adc_saturates_and_reads_in_its_steps() -> None:
    s = SampledSensor(adc_bits=16, range_min=-2000.0, range_max=2000.0)
    step = 4000.0 / 65535
    for true, want in ((294.31, -2000.0 + round(2294.31 / step) * step), (2500.0, 2000.0),
                       (-2500.0, -2000.0)):
        s.update(1.0, true)
        assert s.value == pytest.approx(want)
    with pytest.raises(ValueError, match="ADC"):
        SampledSensor(adc_bits=16, range_min=1.0, range_max=1.0)
    with pytest.raises(ValueError, match="burst_every_s"):
        SampledSensor(burst_s=0.5, burst_every_s=0.5)
    assert math.isinf(SampledSensor().range_max)


@pytest.mark.parametrize("contraction, stuck", [(0.245, False), (-0.035, False),
                                                (0.10, True)])
def test_a_length_standing_while_the_pressure_moves_is_stuck_only_away_from_the_stops(
        contraction: float, stuck: bool) -> None:
    """At the contraction stop (25 %) or the pretension stop the length rightly stands
    still while the pressure moves, and the load cell need not see the stop's share;
    in between, a muscle whose pressure rises 1 bar with an unchanged force has moved."""
    pl = _plaus()
    length = L0 * (1.0 - contraction)
    found = None
    for k in range(400):  # 1 kHz, the pressure ramping 0.0025 bar a sample
        t = 1.0 + 0.001 * k
        found = found or pl.check(t, 2.0 + 0.0025 * k, t, 500.0 + 0.0 * k, t, length, t,
                                  True, 3.0, True)
    assert (found is not None) == stuck, found
    if stuck:
        assert found is not None and "m2.length frozen at" in found
