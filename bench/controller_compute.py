"""Per-tick compute time of the controller, everything but the simulated plant's own
physics (goal: p50 <= 30 us, p99 <= 100 us).

The plant is advanced outside the timed region; the timed region is one
`RigController.tick` (signals, supervisor, profile, PID, limits, valve write,
record) plus handing the record to the summary sink."""

from __future__ import annotations

from _common import controller_compute_us, percentile, sim_config


def main(seconds: float = 60.0) -> None:
    us = controller_compute_us(sim_config("virtual"), [("profile", {"kind": "sine"})],
                               seconds)
    print(f"controller compute per tick, plant excluded ({len(us)} ticks, sine profile "
          f"running): p50 {percentile(us, 50):.1f} us, p99 {percentile(us, 99):.1f} us, "
          f"max {max(us):.0f} us (goal p50 <= 30, p99 <= 100)")


if __name__ == "__main__":
    main()
