"""Virtual-clock speed at 1 kHz with one simulated muscle (goal: >= 20 x real time).

Runs the whole daemon (loop thread, controller, sim driver, summary sink) on the
virtual clock through the 0.05 Hz sine and prints rig time / wall time, for the
default simulated rig (air that flows, sensors on a 1 kHz card) and, as the baseline
measured in the same run (the machine's noise cancels in the ratio), the old simple
plant ('lag' pneumatics, ideal sensors). Alternating runs, best of `--rounds`."""

from __future__ import annotations

import argparse
import time
from typing import Any

from _common import sim_config
from tracking_sine import OLD_PLANT, plant_drivers

from pamd.daemon.daemon import Daemon
from pamd.wire.tick import State


def run(cycles: int, **changes: Any) -> tuple[float, float, dict[str, Any]]:
    """(rig seconds, wall seconds, the run's summary)."""
    cfg = sim_config("virtual", **changes)
    d = Daemon(cfg)
    t0 = time.perf_counter()
    d.start(stop_when_profile_done=True)
    d.wait_for_state((State.IDLE,))
    d.command("profile", {"shape": "sine", "cycles": cycles})
    d.wait()
    wall = time.perf_counter() - t0
    d.close()
    r = d.result()
    return r["ticks"] * cfg.period_s, wall, r


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cycles", type=int, default=3)
    ap.add_argument("--rounds", type=int, default=3)
    a = ap.parse_args()
    best: dict[str, tuple[float, dict[str, Any]]] = {}
    for _ in range(a.rounds):
        for name, changes in (("flow", {}), ("lag", {"drivers": plant_drivers(**OLD_PLANT)})):
            rig_s, wall, r = run(a.cycles, **changes)
            if name not in best or rig_s / wall > best[name][0]:
                best[name] = (rig_s / wall, r)
    for name, label in (("flow", "default rig (flow plant)"), ("lag", "old lag plant")):
        speed, r = best[name]
        print(f"virtual clock, 1 kHz, 1 muscle, {label}: {r['ticks']} ticks, "
              f"{speed:.1f} x real time; compute per tick (incl. plant) p50 "
              f"{r['compute_us']['p50']:.0f} us, p99 {r['compute_us']['p99']:.0f} us")
    print(f"  flow / lag speed: {best['flow'][0] / best['lag'][0]:.2f} (best of {a.rounds}); "
          "goal >= 20 x real time")


if __name__ == "__main__":
    main()
