"""One muscle's limits, two stages of its tick: `LimitMonitor` in its read, the hard
limits and the tracking check (faults); `Guards` in its write, the soft-limit guards
(bounds on the valve command) before the limiter.

The guards never write the setpoint: they only bound the command, each in its
restoring direction (near the contraction limit the command may not rise, beyond
it it falls at the slew limit; stretched past the pretension limit it may not
fall, and rises at the slew limit), with a release band so they do not chatter.
A released guard lets the command return to what control wants at the slew limit
(bumpless, as when the guard used to drag the setpoint along).
They act only on a trusted length with its datum: an untrusted length bounds nothing
(the muscle then holds its safe pressure open loop; `pamd.loop.safety.limiter`).

Tick path: float arithmetic on attributes; a message string only on a finding.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from pamd.config.safety_schema import SafetyConfig
from pamd.loop.safety.limiter import held_back
from pamd.wire.tick import Flag, MuscleTick

if TYPE_CHECKING:
    from pamd.loop.safety.envelope import MuscleEnvelope
    from pamd.loop.safety.plausibility import Plausibility

F_SOFT_C, F_PRETENSION = int(Flag.SOFT_LIMIT_CONTRACTION), int(Flag.PRETENSION_LIMIT)
F_SOFT_P = int(Flag.SOFT_LIMIT_PRESSURE)
F_AT_LIMIT = F_SOFT_P | F_SOFT_C | F_PRETENSION
F_TRACK = int(Flag.TRACKING)
#: A profile held at a soft limit longer than this is reported (event, summary).
SOFT_LIMIT_REPORT_S = 1.0


class LimitMonitor:
    """Hard limits and tracking of one muscle: what its readings say is a fault."""

    def __init__(self, envelope: MuscleEnvelope, pressure_name: str,
                 safety: SafetyConfig, plausibility: Plausibility) -> None:
        self.muscle = envelope.name
        self.p_name = pressure_name
        self.plausibility = plausibility  # a pressure that does not follow: distrusted
        self.set_envelope(envelope)
        self.set_times(safety)
        self._over_p_since = self._over_c_since = self._over_s_since = math.inf
        self._track_since = math.inf
        self.flags = 0

    def set_envelope(self, env: MuscleEnvelope) -> None:
        """Limits (set-up and IDLE reloads)."""
        self.hard_p = env.hard_max_pressure_bar
        self.hard_c = env.hard_max_contraction
        self.hard_stretch = env.hard_max_pretension

    def set_times(self, saf: SafetyConfig) -> None:
        """The hard-limit hold and the tracking band and time (set-up and any reload)."""
        self.hold_s = saf.hard_limit_hold_s
        self.track_band, self.track_s = saf.tracking_band_bar, saf.tracking_time_s

    def update(self, t: MuscleTick, now: float, dt: float) -> None:
        """The read's checks on this tick's readings: the hard limits (on trusted
        readings), then whether the measured pressure follows the command written last
        (judged before this tick's command, so that a fault it finds shapes that
        command; not while the air is out or held, `t.air_cut`: no air follows a
        command then, and a leak is the hold's, not a sensor's). A pressure that does
        not follow is distrusted, with what the force and length point to; the first
        fault of the tick stays `t.fault`."""
        p = t.pressure_bar
        fault = self.check_hard(now, p, t.contraction, t.pressure_ok, t.length_ok)
        if fault is not None and t.fault is None:
            t.fault = fault
        command = t.last_command_bar
        tracked = t.pressure_ok and not t.air_cut
        if tracked and abs(p - command) <= self.track_band:  # it follows: `track`'s
            self.flags = 0  # common path, inline (a call less a tick)
            self._track_since = math.inf
            return
        reason = self.track(now, p, command, tracked)
        t.flags |= self.flags
        if reason is not None:
            reason = self.plausibility.distrust_pressure(reason, p, command, t.force_n,
                                                         t.length_mm)
            t.finding = reason
            if t.fault is None:
                t.fault = reason

    # -- faults -------------------------------------------------------------------
    def check_hard(self, now: float, p: float, x: float, pressure_ok: bool,
                   length_ok: bool) -> str | None:
        """The hard limits, held for `hard_limit_hold_s`, on trusted readings only: a
        fault reason (the pressure's first), or None."""
        fault = None
        if pressure_ok:
            if p > self.hard_p:
                if self._over_p_since == math.inf:
                    self._over_p_since = now
                elif now - self._over_p_since >= self.hold_s:
                    fault = (f"{self.muscle}: pressure {p:.2f} bar above the hard limit "
                             f"{self.hard_p:.2f} bar")
            else:
                self._over_p_since = math.inf
        if not length_ok:
            return fault
        if x > self.hard_c:
            if self._over_c_since == math.inf:
                self._over_c_since = now
            elif now - self._over_c_since >= self.hold_s and fault is None:
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

    def track(self, now: float, p: float, command: float, pressure_ok: bool) -> str | None:
        """The measured pressure must follow the last command within the band (on a
        trusted pressure only); `flags` holds TRACKING while it does not."""
        self.flags = 0
        if not pressure_ok:
            self._track_since = math.inf
            return None
        if abs(p - command) > self.track_band:
            self.flags = F_TRACK
            if self._track_since == math.inf:
                self._track_since = now
            elif now - self._track_since >= self.track_s:
                return (f"{self.muscle}: measured pressure {p:.2f} bar ({self.p_name}) does "
                        f"not follow the command {command:.2f} bar for "
                        f"{now - self._track_since:.1f} s")
        else:
            self._track_since = math.inf
        return None

    def stop_tracking(self) -> None:
        self._track_since = math.inf


class Guards:
    """The soft-limit guards of one muscle: bounds on its command (module docstring),
    and a profile held back at a soft limit reported."""

    def __init__(self, envelope: MuscleEnvelope) -> None:
        self.set_envelope(envelope)
        self.c_guard = self.s_guard = self.c_recover = self.s_recover = False
        self._engaged = False  # either guard engaged (`_engage` judges every tick then)
        self._held_since = math.inf
        self._held_reported = False
        self.holding_back = False  # a profile is held back at a limit (held_at_limit)
        self.lo = -math.inf  # guard bounds on the command of this tick (none: +-inf;
        # the limiter keeps the command >= 0 without naming a guard)
        self.hi = math.inf

    def set_envelope(self, env: MuscleEnvelope) -> None:
        """Limits and bands (set-up and IDLE reloads)."""
        self.max_c = env.max_contraction
        self.soft_c = env.soft_max_contraction
        self.c_release = self.soft_c - 0.5 * env.soft_band_contraction
        self.max_stretch = env.max_pretension
        self.s_release = -self.max_stretch + 0.5 * env.soft_band_contraction
        self._stretch_at = -self.max_stretch  # the pretension guard engages at or below

    def reset(self) -> None:
        self.c_guard = self.s_guard = self.c_recover = self.s_recover = False
        self._engaged = False

    def update(self, t: MuscleTick, now: float, dt: float) -> None:
        """The write's bounds on the command (`t.lo_bar`, `t.hi_bar`, also `lo`, `hi`)
        from a trusted contraction (an untrusted length bounds nothing), around the
        command written last (`t.last_command_bar`) and `t.step_bar` (the slew limit
        times the period); the flag of a guard that holds what control wants
        (`t.command_bar`) back."""
        if not t.length_ok:
            self.lo = t.lo_bar = -math.inf  # (one name each: a chained tuple target
            self.hi = t.hi_bar = math.inf  # would build a tuple every tick)
            self.c_recover = self.s_recover = False
            return
        x = t.contraction
        if self._engaged or not self._stretch_at < x < self.soft_c:
            self._engage(x)  # else between both soft limits, neither engaged: nothing to do
        prev_cmd, step = t.last_command_bar, t.step_bar
        lo, hi = -math.inf, math.inf  # no guard: 0 bar is the limiter's, not a guard
        if self.c_guard:
            # restoring: never up; beyond the limit, down at the slew limit
            hi = prev_cmd - step if x >= self.max_c else prev_cmd
        elif self.c_recover:
            # released: back towards what control wants at the slew limit (bumpless)
            hi = prev_cmd + step
        if self.s_guard:
            if not self.c_guard:  # both at once cannot be: contraction wins
                # restoring: never down; beyond the limit, up at the slew limit
                lo = prev_cmd + step if x <= -self.max_stretch else prev_cmd
        elif self.s_recover and not self.c_guard:
            lo = prev_cmd - step
        self.lo = t.lo_bar = lo
        self.hi = t.hi_bar = hi
        wanted = t.command_bar
        if wanted > hi:
            t.flags |= F_SOFT_C
        elif wanted < lo:
            t.flags |= F_PRETENSION
        else:
            self.c_recover = self.s_recover = False  # inside the bounds: recovery is over

    def _engage(self, x: float) -> None:
        """Each guard engaged at its soft limit, released (to recover) past its band."""
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
        self._engaged = self.c_guard or self.s_guard

    # -- a profile held back ----------------------------------------------------------
    def held_at_limit(self, now: float, flags: int, moving: bool, setpoint_bar: float,
                      command_bar: float) -> str | None:
        """A profile held back at a soft limit (`held_back`) for more than
        SOFT_LIMIT_REPORT_S while RUNNING or LOAD_CHANGE (`moving`): the limit's name,
        once per episode (the controller reports it); else None. The tick calls it only
        with a limit flag set or while `holding_back`."""
        if flags & F_AT_LIMIT and moving and held_back(flags, setpoint_bar, command_bar):
            self.holding_back = True
            if self._held_since == math.inf:
                self._held_since = now
                self._held_reported = False
            elif not self._held_reported and now - self._held_since > SOFT_LIMIT_REPORT_S:
                self._held_reported = True
                if flags & F_SOFT_C:
                    return "contraction"
                if flags & F_PRETENSION:
                    return "pretension"
                return "pressure"
        else:
            self._held_since = math.inf
            self.holding_back = False
        return None
