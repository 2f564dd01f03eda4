"""Per-tick compute time of the controller, everything but the simulated plant's own
physics (goal: p50 <= 30 us, p99 <= 100 us).

The plant is advanced outside the timed region; the timed region is one
`RigController.tick` (signals, supervisor, profile, PID, limits, valve write,
record) plus handing the record to the summary sink.

Also the iterative learning's share (mode position, `ilc: true`, a 1 Hz length sine):
the whole tick with and without it in the same run, and `Ilc.step` alone, on the ticks
that carry a share of the once-per-cycle learning pass (spread over ticks,
`pamd.loop.control.ilc.BINS_PER_TICK` bins each) and on the others, at 1 Hz (100 bins) and
0.05 Hz (2000 bins: the longest pass). On a shared machine the max is the scheduler's
(a preempted tick), not the code's: compare the p99s."""

from __future__ import annotations

import gc
import math
import time

from _common import controller_compute_us, percentile, sim_config

from pamd.loop.control.ilc import IDLE, Ilc

FAST = {"slew_limit_bar_per_s": 25.0, "position": {"max_rate_per_s": 1.0}}


def position_us(seconds: float, ilc: bool) -> list[float]:
    """Tick compute in mode position (no model) tracking a 1 Hz 5-20 % sine."""
    cmds = [("mode", {"muscle": "m1", "mode": "position", "feedforward": False, "ilc": ilc}),
            ("profile", {"muscle": "m1", "shape": "sine", "min_contraction": 0.05,
                         "max_contraction": 0.2, "freq_hz": 1.0})]
    return controller_compute_us(sim_config("virtual", control=FAST), cmds, seconds)


def ilc_step_us(period_s: float, cycles: int = 4, dt_s: float = 0.001
                ) -> tuple[list[float], list[float]]:
    """`Ilc.step` alone (us): on ticks doing a share of the learning pass, and not."""
    ilc = Ilc(period_s, 0.5, 0.0, 0.068, 0.0, 10.0, 0.01, 12.0)
    perf = time.perf_counter
    busy: list[float] = []
    idle: list[float] = []
    gc.collect()
    gc.disable()
    try:
        for k in range(round(cycles * period_s / dt_s)):
            t = k * dt_s
            e = math.sin(2 * math.pi * t / period_s)
            before = ilc.stage != IDLE or ilc.cycles != int(t / period_s) + 1
            t0 = perf()
            ilc.step(t, e, dt_s)
            us = (perf() - t0) * 1e6
            (busy if before or ilc.stage != IDLE else idle).append(us)
    finally:
        gc.enable()
    return busy, idle


def main(seconds: float = 60.0) -> None:
    us = controller_compute_us(sim_config("virtual"), [("profile", {"shape": "sine"})],
                               seconds)
    print(f"controller compute per tick, plant excluded ({len(us)} ticks, sine profile "
          f"running): p50 {percentile(us, 50):.1f} us, p99 {percentile(us, 99):.1f} us, "
          f"max {max(us):.0f} us (goal p50 <= 30, p99 <= 100)")
    off = position_us(seconds / 3, ilc=False)
    on = position_us(seconds / 3, ilc=True)
    print(f"mode position, 1 Hz length sine: without ILC p50 {percentile(off, 50):.1f} / p99 "
          f"{percentile(off, 99):.1f} / max {max(off):.0f} us; with ILC p50 "
          f"{percentile(on, 50):.1f} / p99 {percentile(on, 99):.1f} / max {max(on):.0f} us "
          f"(p99 ratio {percentile(on, 99) / percentile(off, 99):.2f})")
    for period in (1.0, 20.0):
        busy, idle = ilc_step_us(period)
        print(f"Ilc.step alone, {period:g} s cycle: {len(busy)} ticks a cycle's pass over "
              f"{round(period / 0.01)} bins is spread on take p50 {percentile(busy, 50):.1f} "
              f"/ p99 {percentile(busy, 99):.1f} / max {max(busy):.0f} us; the other ticks "
              f"p50 {percentile(idle, 50):.1f} / "
              f"p99.9 {percentile(idle, 99.9):.1f} / max {max(idle):.0f} us")


if __name__ == "__main__":
    main()
