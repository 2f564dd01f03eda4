"""Cost of one simulated muscle per 1 ms tick (`SimDriver.advance`), for each plant
option: the 'lag' regulator, air that flows ('flow'), on/off valves, and sensors
sampled as devices. The loop runs the plant inside the tick, so this is part of
what the virtual clock's speed (goal >= 20 x real time) and the tick budget pay.

Printed as the best of 5 rounds of 5000 steps, and as a ratio to the 'lag' plant
measured in the same run (the machine's noise cancels in the ratio)."""

from __future__ import annotations

import math
import time

from pamd.drivers.sim import SimDriver

from pamd.sim.options import SimMuscleOptions, SimOptions

#: Every case states its sensors: sampled every plant step without delay (the cheap
#: path) unless it says otherwise.
IDEAL_SENSORS = {"pressure_sample_period_s": 0.0, "force_sample_period_s": 0.0,
                 "length_sample_period_s": 0.0}

CASES: dict[str, dict[str, object]] = {
    "lag (old plant)": {"pneumatics": "lag", **IDEAL_SENSORS},
    "flow": {"pneumatics": "flow", **IDEAL_SENSORS},
    "flow + stiction + drift": {"pneumatics": "flow", "stiction_ratio": 1.3,
                                "force_drift_per_hour": -0.05, **IDEAL_SENSORS},
    "default (flow, 1 kHz sensors)": {},
    "flow + sampled sensors, latency": {"pneumatics": "flow", "length_latency_s": 0.001},
    "onoff": {"actuation": "onoff"},
}


def cost_us(options: dict[str, object]) -> float:
    drv = SimDriver("sim", SimOptions(muscles=(SimMuscleOptions(**options),)))  # type: ignore[arg-type]
    drv.open(time.monotonic)
    drv.write(0, 1.0 if options.get("actuation") == "onoff" else 3.0)
    best = math.inf
    for _ in range(5):
        n = 5000
        t0 = time.perf_counter()
        for _ in range(n):
            drv.advance(0.001)
        best = min(best, (time.perf_counter() - t0) / n)
    return best * 1e6


def main() -> None:
    base = cost_us(CASES["lag (old plant)"])
    print("one simulated muscle, 1 ms tick, best of 5 x 5000 steps:")
    for name, options in CASES.items():
        us = base if name == "lag (old plant)" else cost_us(options)
        print(f"  {name:32s} {us:6.1f} us per tick  ({us / base:4.2f} x lag)")


if __name__ == "__main__":
    main()
