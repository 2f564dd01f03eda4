"""One muscle's limits: hard limits and the tracking check (faults), and the soft-limit
guards (bounds on the valve command). The limits stage of its tick.

The guards never write the setpoint: they only bound the command, each in its
restoring direction (near the contraction limit the command may not rise, beyond
it it falls at the slew limit; stretched past the pretension limit it may not
fall, and rises at the slew limit), with a release band so they do not chatter.
A released guard lets the command return to what control wants at the slew limit
(bumpless, as when the guard used to drag the setpoint along).
They act only on a trusted, referenced length: an untrusted length bounds nothing
(the muscle then holds its safe pressure open loop; `pamd.safety.limiter`).

Tick path: float arithmetic on attributes; a message string only on a finding.
"""

from __future__ import annotations

import math
from typing import Any

from pamd.config.loader import MuscleLimitsResolved
from pamd.tick import Flag

F_SOFT_C, F_PRETENSION = int(Flag.SOFT_LIMIT_CONTRACTION), int(Flag.PRETENSION_LIMIT)
F_TRACK = int(Flag.TRACKING)


class LimitMonitor:
    """Hard limits, tracking and soft-limit guards of one muscle."""

    def __init__(self, muscle: str, pressure_name: str, limits: MuscleLimitsResolved,
                 safety: Any) -> None:
        self.muscle = muscle
        self.p_name = pressure_name
        self.set_limits(limits, safety)
        self.set_times(safety)
        self.c_guard = self.s_guard = self.c_recover = self.s_recover = False
        self._over_p_since = self._over_c_since = self._over_s_since = math.inf
        self._track_since = math.inf
        self.lo = 0.0  # guard bounds on the command of this tick
        self.hi = math.inf
        self.flags = 0

    def set_limits(self, lim: MuscleLimitsResolved, saf: Any) -> None:
        self.max_p, self.hard_p = lim.max_pressure_bar, lim.hard_max_pressure_bar
        self.max_c, self.hard_c = lim.max_contraction, lim.hard_max_contraction
        self.soft_c = lim.max_contraction - saf.soft_band_contraction
        self.c_release = self.soft_c - 0.5 * saf.soft_band_contraction
        self.max_stretch, self.hard_stretch = lim.max_pretension, lim.hard_max_pretension
        self.s_release = -self.max_stretch + 0.5 * saf.soft_band_contraction

    def set_times(self, saf: Any) -> None:
        self.hold_s = saf.hard_limit_hold_s
        self.track_band, self.track_s = saf.tracking_band_bar, saf.tracking_time_s

    def reset_guards(self) -> None:
        self.c_guard = self.s_guard = self.c_recover = self.s_recover = False

    # -- faults -------------------------------------------------------------------
    def hard_pressure(self, now: float, p: float) -> str | None:
        if p > self.hard_p:
            if self._over_p_since == math.inf:
                self._over_p_since = now
            elif now - self._over_p_since >= self.hold_s:
                return (f"{self.muscle}: pressure {p:.2f} bar above the hard limit "
                        f"{self.hard_p:.2f} bar")
        else:
            self._over_p_since = math.inf
        return None

    def hard_length(self, now: float, x: float) -> str | None:
        fault = None
        if x > self.hard_c:
            if self._over_c_since == math.inf:
                self._over_c_since = now
            elif now - self._over_c_since >= self.hold_s:
                fault = (f"{self.muscle}: contraction {100 * x:.1f} % beyond the hard limit "
                         f"{100 * self.hard_c:.1f} %")
        else:
            self._over_c_since = math.inf
        if x < -self.hard_stretch:
            if self._over_s_since == math.inf:
                self._over_s_since = now
            elif now - self._over_s_since >= self.hold_s and fault is None:
                fault = (f"{self.muscle}: stretched {-100 * x:.1f} %, beyond the pretension "
                         f"limit {100 * self.hard_stretch:.1f} %")
        else:
            self._over_s_since = math.inf
        return fault

    def tracking(self, now: float, p: float, command: float) -> str | None:
        """The measured pressure must follow the last command within the band."""
        if abs(p - command) > self.track_band:
            self.flags |= F_TRACK
            if self._track_since == math.inf:
                self._track_since = now
            elif now - self._track_since >= self.track_s:
                return (f"{self.muscle}: measured pressure {p:.2f} bar ({self.p_name}) does "
                        f"not follow the command {command:.2f} bar for "
                        f"{now - self._track_since:.1f} s (leak, dead sensor, stuck valve or "
                        "no supply?)")
        else:
            self._track_since = math.inf
        return None

    def stop_tracking(self) -> None:
        self._track_since = math.inf

    # -- guards -------------------------------------------------------------------
    def guard(self, x: float, prev_cmd: float, step: float) -> None:
        """This tick's bounds on the command (`lo`, `hi`) from a trusted contraction `x`;
        `prev_cmd` is the last command, `step` the slew limit times the period."""
        if self.c_guard:
            if x < self.c_release:
                self.c_guard = False
                self.c_recover = True
        elif x >= self.soft_c:
            self.c_guard = True
            self.c_recover = False
        if self.s_guard:
            if x > self.s_release:
                self.s_guard = False
                self.s_recover = True
        elif x <= -self.max_stretch:
            self.s_guard = True
            self.s_recover = False
        self.lo, self.hi = 0.0, math.inf
        if self.c_guard:
            # restoring: never up; beyond the limit, down at the slew limit
            self.hi = prev_cmd - step if x >= self.max_c else prev_cmd
        elif self.c_recover:
            # released: back towards what control wants at the slew limit (bumpless)
            self.hi = prev_cmd + step
        if self.s_guard:
            if not self.c_guard:  # both at once cannot be: contraction wins
                # restoring: never down; beyond the limit, up at the slew limit
                self.lo = prev_cmd + step if x <= -self.max_stretch else prev_cmd
        elif self.s_recover and not self.c_guard:
            self.lo = prev_cmd - step

    def caught_up(self) -> None:
        """The command is inside the bounds: a released guard's recovery is over."""
        self.c_recover = self.s_recover = False

    def no_guard(self) -> None:
        """No trusted length this tick: the guards bound nothing."""
        self.lo, self.hi = 0.0, math.inf
        self.c_recover = self.s_recover = False
