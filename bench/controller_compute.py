"""Per-tick compute time of the controller, everything but the simulated plant's own
physics (goal: p50 <= 30 us, p99 <= 100 us).

The plant is advanced outside the timed region; the timed region is one
`RigController.tick` (signals, supervisor, profile, PID, limits, valve write,
record) plus handing the record to the summary sink."""

from __future__ import annotations

import gc
import time

from _common import percentile, sim_config

from pamd.calibration import load_calibration
from pamd.commands import apply_command, parse_command
from pamd.controller import RigController
from pamd.loop import VirtualClock
from pamd.rig import Rig
from pamd.summary import SummarySink
from pamd.tick import TickLayout


def main(seconds: float = 60.0) -> None:
    cfg = sim_config("virtual")
    rig = Rig(cfg, load_calibration(cfg.calibration_path))
    sink = SummarySink(TickLayout(["m1"]))
    ctrl = RigController(cfg, rig, sink, rig.calibration)
    sim = rig.drivers["sim"]
    ctrl.steppers = []  # the plant is advanced by hand, outside the timing
    clock = VirtualClock()
    rig.open(clock)
    ctrl.start(0.0)
    dt = cfg.period_s
    t = 0.0
    perf = time.perf_counter
    samples: list[float] = []
    gc.collect()
    gc.freeze()
    gc.disable()
    for k in range(int(seconds / dt)):
        clock.t = t
        sim.advance(dt)
        if k == 10:
            apply_command(ctrl, parse_command("profile", {"kind": "sine"}))
        t0 = perf()
        sink.put(ctrl.tick(t, dt))
        samples.append(perf() - t0)
        t += dt
    gc.enable()
    us = [s * 1e6 for s in samples[1000:]]
    print(f"controller compute per tick, plant excluded ({len(us)} ticks, sine profile "
          f"running): p50 {percentile(us, 50):.1f} us, p99 {percentile(us, 99):.1f} us, "
          f"max {max(us):.0f} us (goal p50 <= 30, p99 <= 100)")


if __name__ == "__main__":
    main()
