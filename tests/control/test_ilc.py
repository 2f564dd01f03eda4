"""Iterative learning (pamd.loop.control.ilc) alone: what a cycle's error teaches the next
cycle, learned per cycle and spread over ticks, the Q-filter's frequency response, the
lead that compensates a known plant delay, the clamp and forgetting."""

from __future__ import annotations

import math
from collections import deque

import pytest

from pamd.loop.control.ilc import BINS_PER_TICK, Ilc, q_gain, q_pole

DT_S = 0.002
PERIOD_S = 1.0
TICKS = round(PERIOD_S / DT_S)


def make(gain: float = 0.5, lead_s: float = 0.0, forgetting: float = 0.0,
         limit_mm: float = 10.0, cutoff_hz: float = 5.0) -> Ilc:
    return Ilc(PERIOD_S, gain, 0.0, lead_s, forgetting, limit_mm, 0.01, cutoff_hz)


def cycle(ilc: Ilc, k: int, error_mm: float) -> list[float]:
    """The corrections returned over cycle `k` (0-based) with a constant error."""
    return [ilc.step(k * PERIOD_S + i * DT_S, error_mm, DT_S) for i in range(TICKS)]


def test_first_cycle_applies_nothing_and_returns_floats() -> None:
    ilc = make()
    out = cycle(ilc, 0, 1.0)
    assert all(isinstance(u, float) for u in out)
    assert out == [0.0] * TICKS
    assert ilc.cycles == 1


@pytest.mark.parametrize("error_mm", [1.0, -1.0])
def test_a_cycles_error_is_learned_once_for_the_next_cycle(error_mm: float) -> None:
    ilc = make(gain=0.5)
    cycle(ilc, 0, error_mm)
    out = cycle(ilc, 1, 0.0)
    # the pass over the cycle's 100 bins is spread over the first ticks of the next
    # cycle (the last correction, zero, stays applied meanwhile) ...
    work = 5 * ilc.n + 2 * ilc.warm
    spread = math.ceil(work / BINS_PER_TICK)
    assert spread > 3
    assert out[:spread - 1] == [0.0] * (spread - 1)
    # ... then the whole cycle's correction is swapped in at once: gain x error, flat
    # (the Q-filter passes a constant), the same at every phase (not smeared)
    assert out[spread + 1:] == pytest.approx([0.5 * error_mm] * (TICKS - spread - 1))
    assert ilc.learned_cycles == 1 and ilc.cycles == 2


def test_no_error_learns_nothing() -> None:
    ilc = make()
    for k in range(3):
        assert cycle(ilc, k, 0.0) == [0.0] * TICKS


def test_the_correction_is_clamped() -> None:
    ilc = make(gain=1.0, limit_mm=0.3)
    cycle(ilc, 0, 1.0)
    assert max(cycle(ilc, 1, 1.0)) == 0.3
    assert min(cycle(ilc, 2, -5.0)) == 0.3  # applied: learned from cycle 1
    assert min(cycle(ilc, 3, 0.0)) == -0.3


def test_forgetting_shrinks_what_was_learned() -> None:
    ilc = make(forgetting=0.5)
    cycle(ilc, 0, 1.0)
    cycle(ilc, 1, 0.0)
    assert cycle(ilc, 2, 0.0)[-1] == pytest.approx(0.25)


def test_the_correction_is_read_between_bins_at_the_ticks_resolution() -> None:
    ilc = make(gain=1.0, cutoff_hz=1000.0)  # no filtering
    ramp = [ilc.step(i * DT_S, i * DT_S, DT_S) for i in range(TICKS)]
    assert ramp[0] == 0.0
    out = [ilc.step(PERIOD_S + i * DT_S, 0.0, DT_S) for i in range(TICKS)]
    mid = out[TICKS // 4:3 * TICKS // 4]
    steps = [b - a for a, b in zip(mid, mid[1:], strict=False)]
    # a ramp at every tick (not a staircase of 10 ms bins): 2 ms a tick, within the
    # bins' means (4-6 ticks each where the float phase falls on a bin's edge)
    assert steps == pytest.approx([DT_S] * len(steps), abs=3e-4)


@pytest.mark.parametrize("freq_hz", [1.0, 3.0, 5.0, 10.0, 20.0])
def test_q_filter_is_a_zero_phase_low_pass_with_the_designed_response(freq_hz: float) -> None:
    cutoff_hz = 5.0
    ilc = make(gain=1.0, cutoff_hz=cutoff_hz)
    w = 2 * math.pi * freq_hz
    for i in range(TICKS):  # ticks between bin edges: 5 a bin, their mean at its centre
        t = (i + 0.5) * DT_S
        ilc.step(t, math.sin(w * t), DT_S)
    ilc.end_cycle()
    ilc.work(1 << 20)
    h = ilc.bin_s
    avg = (1 + 2 * math.cos(w * DT_S) + 2 * math.cos(2 * w * DT_S)) / 5  # 5 samples' mean
    want = q_gain(freq_hz, cutoff_hz, h) * avg
    for k, u in enumerate(ilc.u):  # zero phase: the learned sine lines up with the error's
        # (the circular passes start 10 time constants early: within e^-10 of exact)
        assert u == pytest.approx(want * math.sin(w * (k + 0.5) * h), abs=1e-4)


def test_q_gain_is_one_half_at_the_cutoff_and_one_well_below() -> None:
    assert q_gain(5.0, 5.0, 0.01) == pytest.approx(0.5)
    assert q_gain(0.1, 5.0, 0.01) == pytest.approx(1.0, abs=1e-3)
    assert q_gain(20.0, 5.0, 0.01) < 0.1
    assert q_pole(100.0, 0.01) == 0.0  # beyond Nyquist: no filter


def delayed_plant_errors(lead_s: float, cycles: int = 25) -> list[float]:
    """RMS error per cycle of a plant that takes the correction 0.15 s late:
    e(t) = d(t) - c(t - 0.15 s), d a periodic error at 1 and 3 Hz."""
    delay = deque([0.0] * round(0.15 / DT_S))
    ilc = make(gain=0.5, lead_s=lead_s, cutoff_hz=20.0)
    out = []
    c = 0.0
    for k in range(cycles):
        sq = 0.0
        for i in range(TICKS):
            t = i * DT_S
            d = math.sin(2 * math.pi * t) + 0.5 * math.sin(6 * math.pi * t + 1.0)
            delay.append(c)
            e = d - delay.popleft()
            c = ilc.step(k * PERIOD_S + t, e, DT_S)
            sq += e * e
        out.append(math.sqrt(sq / TICKS))
    return out


def test_the_lead_compensates_a_known_plant_delay() -> None:
    led = delayed_plant_errors(lead_s=0.15)
    assert led[-1] < 0.05 * led[0]
    assert all(b < a for a, b in zip(led[:5], led[1:5], strict=False))  # falls ...
    assert max(led[5:]) < 0.1 * led[0]  # ... and stays down
    blind = delayed_plant_errors(lead_s=0.0)  # 0.15 s at 3 Hz is 162 degrees: it grows
    assert blind[-1] > blind[0]
