"""Iterative learning in mode position on the simulated rig (virtual clock, the flow
plant, 30 kg, 5-20 % contraction, no model): stable over 50 cycles at 1 Hz, converging
at 0.5 Hz. A 250 Hz tick keeps it cheap (bench/ilc_fast.py has the figures at 1 kHz).
(The old 'lag' pneumatics are no cheaper here, and on them the position PID's error at
1 Hz changes from cycle to cycle by a factor of two: a test of that plant, not of the
learning.)"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from pamd.loop.harness import Harness
from pamd.wire.tick import State

FAST = {"slew_limit_bar_per_s": 25.0, "position": {"max_rate_per_s": 1.0}}


def track(harness: Callable[..., Harness], freq_hz: float, cycles: int,
          ilc: bool = True) -> tuple[list[float], list[float]]:
    """Length RMSE (mm) per cycle, and the largest learned correction (mm) per cycle."""
    h = harness(control=FAST, loop={"rate_hz": 250})
    h.step(0.05)
    assert h.cmd("mode", muscle="m1", mode="position", feedforward=False, ilc=ilc)["ok"]
    assert h.cmd("profile", muscle="m1", kind="sine", min_contraction=0.05,
                 max_contraction=0.20, freq_hz=freq_hz, cycles=cycles)["ok"]
    m = h.m1
    period = 1.0 / freq_hz
    t0 = h.t + m.profile.lead_in_s
    sq = [0.0] * cycles
    n = [0] * cycles
    peak = [0.0] * cycles
    while h.ctrl.supervisor.state == State.RUNNING:
        h.step(h.period_s)
        c = int((h.t - t0) / period)
        if h.t > t0 and c < cycles and m.profile is not None:
            e = m.length_mm - m.target_length_mm
            sq[c] += e * e
            n[c] += 1
            learned: Any = m.length_control.ilc
            if learned is not None:
                peak[c] = max(peak[c], abs(learned.value))
    return [math.sqrt(s / k) for s, k in zip(sq, n, strict=True)], peak


def test_ilc_at_1_hz_is_stable_over_50_cycles(harness: Callable[..., Harness]) -> None:
    rmse, peak = track(harness, 1.0, 50)
    alone, _ = track(harness, 1.0, 3, ilc=False)
    assert rmse[9] < 0.25 * alone[2]  # it learned within 10 cycles ...
    assert rmse[49] <= rmse[9] * 1.05  # ... and after 50 it is no worse: no growth
    assert max(rmse[10:]) < 0.3 * alone[2]
    assert max(peak) < 10.0  # the correction stays bounded, inside its clamp
    assert max(peak[40:]) < 1.2 * max(peak[10:20])


def test_ilc_converges_at_0_5_hz(harness: Callable[..., Harness]) -> None:
    rmse, _ = track(harness, 0.5, 8)
    assert all(b < a for a, b in zip(rmse[:5], rmse[1:5], strict=False))
    assert rmse[7] < 0.2 * rmse[0]
