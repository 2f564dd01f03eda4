"""Virtual-clock speed at 1 kHz with one simulated muscle (goal: >= 20 x real time).

Runs the whole daemon (loop thread, controller, sim driver, summary sink) on the
virtual clock through the 0.05 Hz sine and prints rig time / wall time."""

from __future__ import annotations

import time

from _common import sim_config

from pamd.daemon import Daemon
from pamd.tick import State


def main(cycles: int = 3) -> None:
    cfg = sim_config("virtual")
    d = Daemon(cfg)
    t0 = time.perf_counter()
    d.start(stop_when_profile_done=True)
    d.wait_for_state((State.IDLE,))
    d.command("profile", {"kind": "sine", "cycles": cycles})
    d.wait()
    wall = time.perf_counter() - t0
    d.close()
    r = d.result()
    rig_s = r["ticks"] * cfg.period_s
    print(f"virtual clock, 1 kHz, 1 muscle: {r['ticks']} ticks = {rig_s:.1f} s of rig time "
          f"in {wall:.2f} s wall clock -> {rig_s / wall:.1f} x real time (goal >= 20 x)")
    print(f"  compute per tick (incl. plant) p50 {r['compute_us']['p50']:.0f} us, "
          f"p99 {r['compute_us']['p99']:.0f} us")


if __name__ == "__main__":
    main()
