"""A stalled loop: when it is only an event and when it latches FAULT.

A stall is a gap longer than `loop.stall_timeout_s` in which no tick completed (the
loop's process got no CPU, or its thread was held). While the loop stalls nothing
commands the valves and nothing watches the sensors; what the outputs do meanwhile
depends on the actuation, and that sets how long a stall may last before it is a
fault (`loop.stall_fault_s`; null derives it here, per muscle, the shortest wins):

* a **proportional regulator** keeps regulating the last setpoint by itself: the
  pressure holds. An I/O module with a communication watchdog (`comm_safety` in the
  driver's options) puts its outputs at their safe values once the host has been
  silent for the watchdog time; past that time the outputs may no longer be what the
  loop last wrote, so the stall latches FAULT (whose safe state is those same safe
  values). Without a watchdog the limit is `HOLD_S` (0.5 s, the watchdog time an I/O
  module has by default): beyond that a sensor that failed meanwhile went unseen too
  long;
* **on/off valves** do not hold: an inflate or exhaust valve left open keeps moving
  the pressure at up to `onoff.fill_rate_bar_per_s` / `vent_rate_bar_per_s`. The
  stall may last until that moves the pressure by `safety.tracking_band_bar`, the
  pressure error the rig already tolerates (0.5 bar at 4.64 bar/s: 108 ms), or the
  valves' module watchdog, whichever is shorter.

The derived limit is never below `loop.stall_timeout_s` (a shorter gap is not a
stall at all; a rig that sets a long stall timeout accepts that much).

A stall that ends sooner is an event (`stall`), a counter and a warning, never a
fault. A sample that aged while the loop stalled is not a dead sensor: the inputs
judge staleness with the stall's length excused (`Inputs.stall_excuse_s`) until the
longest signal timeout has passed after it.
"""

from __future__ import annotations

from dataclasses import dataclass

from pamd.config.schema import MuscleConfig, RigConfig
from pamd.wire.declare.jsonsafe import JsonObject

HOLD_S = 0.5  # a proportional regulator without a module watchdog: see the docstring


@dataclass(frozen=True)
class StallLimit:
    """How long a stall may last before it latches FAULT, and why."""

    fault_s: float
    why: str


def _watchdog_s(rig: RigConfig, driver: str) -> float | None:
    """The communication watchdog time of a driver's module (`comm_safety.timeout_s` in
    its options), or None."""
    for d in rig.drivers:
        if d.name == driver:
            cs: object = getattr(d.options, "comm_safety", None)
            t = getattr(cs, "timeout_s", None)
            return float(t) if isinstance(t, (int, float)) else None
    return None


def _muscle_limit(rig: RigConfig, m: MuscleConfig) -> StallLimit:
    sig = m.signals
    if m.actuation == "onoff":
        o = m.onoff
        rate = max(o.fill_rate_bar_per_s, o.vent_rate_bar_per_s)
        band = rig.safety.tracking_band_bar
        limit = StallLimit(band / rate, f"{m.name}: an on/off valve left open moves the "
                           f"pressure at up to {rate:g} bar/s, {band:g} bar "
                           "(safety.tracking_band_bar) in that time")
        drivers = [s.driver for s in (sig.inflate, sig.exhaust) if s is not None]
    else:
        limit = StallLimit(HOLD_S, f"{m.name}: the proportional regulator holds its "
                           "pressure; no module watchdog, so the default hold time")
        drivers = [s.driver for s in (sig.valve, sig.exhaust) if s is not None]
    watchdogs = [(wd, d) for d in drivers if (wd := _watchdog_s(rig, d)) is not None]
    if watchdogs:
        wd, d = min(watchdogs)
        if m.actuation != "onoff" or wd < limit.fault_s:
            limit = StallLimit(wd, f"{m.name}: the module of driver {d!r} puts its outputs "
                               f"at their safe values after {wd:g} s of silence (its comm "
                               "watchdog)")
    return limit


def stall_limit(rig: RigConfig) -> StallLimit:
    """`loop.stall_fault_s`, or the limit the rig's actuation allows (the shortest of
    its muscles'), never below `loop.stall_timeout_s` (a shorter gap is no stall)."""
    if rig.loop.stall_fault_s is not None:
        return StallLimit(rig.loop.stall_fault_s, "loop.stall_fault_s")
    limits = [_muscle_limit(rig, m) for m in rig.muscles]
    derived = (min(limits, key=lambda s: s.fault_s) if limits
               else StallLimit(HOLD_S, "no muscles: the default hold time"))
    timeout = rig.loop.stall_timeout_s
    if derived.fault_s < timeout:
        return StallLimit(timeout, f"loop.stall_timeout_s (above what the actuation holds: "
                          f"{derived.why}, {1000 * derived.fault_s:.0f} ms)")
    return derived


class StallWatch:
    """Counts the stalls of one loop and says which ones are faults."""

    def __init__(self, timeout_s: float, limit: StallLimit) -> None:
        self.timeout_s = timeout_s
        self.limit = limit
        self.count = 0
        self.longest_s = 0.0

    @property
    def check_s(self) -> float:
        """A gap longer than this is a stall."""
        return min(self.timeout_s, self.limit.fault_s)

    def record(self, gap_s: float) -> bool:
        """Count a stall of `gap_s`; True when it latches FAULT."""
        self.count += 1
        if gap_s > self.longest_s:
            self.longest_s = gap_s
        return gap_s > self.limit.fault_s

    def describe(self, gap_s: float) -> str:
        return (f"loop stalled: no tick completed for {1000 * gap_s:.0f} ms (stall "
                f"{self.count}; limit {1000 * self.limit.fault_s:.0f} ms: "
                f"{self.limit.why})")

    def summary(self) -> JsonObject:
        return {"count": self.count, "longest_ms": round(1000 * self.longest_s, 1),
                "timeout_ms": 1000 * self.timeout_s,
                "fault_ms": round(1000 * self.limit.fault_s, 1), "why": self.limit.why}
