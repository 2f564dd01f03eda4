"""The simulated proportional pressure regulator (Festo VPPM) and dump valve.

A setpoint below the zero-point threshold vents (zero-point suppression); any
other passes through a backlash band (standing in for the regulator's
hysteresis). The result goes through a dead time (a ring buffer of time-stamped
setpoint changes) and a first-order lag, exact for any step length, toward the
delayed setpoint clamped to [0, min(supply, full scale)]. Without supply the
pressure cannot rise: it holds (or falls, if the setpoint asks for less). An
open exhaust valve vents the muscle toward 0 bar with its own time constant,
whatever the regulator does.

Pure Python, nothing allocated per step: `step` runs inside the 1 kHz tick.
"""

from __future__ import annotations

import math

_RING_SIZE = 128  # setpoint changes held within one dead time (power of two)
_RING_MASK = _RING_SIZE - 1
_TIME_EPS_S = 1e-7  # float slack when comparing accumulated times


class Regulator:
    """One regulator feeding one muscle; `pressure_bar` is the muscle pressure."""

    def __init__(
        self,
        *,
        supply_bar: float,
        max_bar: float,
        dead_time_s: float,
        lag_s: float,
        backlash_bar: float,
        zero_bar: float,
        vent_time_constant_s: float,
        initial_bar: float,
    ) -> None:
        self.supply_bar = supply_bar
        self.max_bar = max_bar
        self.dead_time_s = dead_time_s
        self.lag_s = lag_s
        self.half_backlash_bar = 0.5 * backlash_bar
        self.zero_bar = zero_bar
        self.vent_time_constant_s = vent_time_constant_s
        self.supply_ok = True
        self.stuck = False  # an injected fault: new setpoints are ignored
        self.exhaust_open = False
        p0 = min(max(initial_bar, 0.0), max_bar, supply_bar)
        self.setpoint_bar = p0  # as written (clamped to the input range)
        self.pressure_bar = p0
        self.t_s = 0.0
        self._effective_bar = p0  # after backlash
        self._delayed_bar = p0  # after dead time
        self._ring_t = [0.0] * _RING_SIZE
        self._ring_v = [0.0] * _RING_SIZE
        self._head = 0
        self._count = 0
        self._dt_s = -1.0
        self._alpha_lag = 0.0
        self._alpha_vent = 0.0

    def set_setpoint(self, value_bar: float) -> None:
        """The commanded pressure; clamped to the regulator's input range. Ignored while
        `stuck` (an injected fault)."""
        if self.stuck:
            return
        if value_bar < 0.0:
            value_bar = 0.0
        elif value_bar > self.max_bar:
            value_bar = self.max_bar
        self.setpoint_bar = value_bar

    def _set_dt(self, dt_s: float) -> None:
        self._dt_s = dt_s
        self._alpha_lag = 1.0 - math.exp(-dt_s / self.lag_s)
        self._alpha_vent = 1.0 - math.exp(-dt_s / self.vent_time_constant_s)

    def step(self, dt_s: float) -> float:
        """Advance by `dt_s` (a zero-order hold over the step); the new pressure."""
        if dt_s != self._dt_s:
            self._set_dt(dt_s)
        t0 = self.t_s
        # Zero-point suppression on the command, else backlash: the effective
        # setpoint moves only once the command leaves the band.
        u = self.setpoint_bar
        e = self._effective_bar
        half = self.half_backlash_bar
        if u < self.zero_bar:
            e = 0.0
        elif u > e + half:
            e = u - half
        elif u < e - half:
            e = u + half
        if e != self._effective_bar:
            self._effective_bar = e
            if self.dead_time_s <= 0.0:
                self._delayed_bar = e
            else:
                count = self._count
                if count == _RING_SIZE:  # full: the oldest change takes effect now
                    self._delayed_bar = self._ring_v[self._head]
                    self._head = (self._head + 1) & _RING_MASK
                    count -= 1
                slot = (self._head + count) & _RING_MASK
                self._ring_t[slot] = t0
                self._ring_v[slot] = e
                self._count = count + 1
        # Dead time: a change made at t takes effect for steps starting at t + dead time.
        if self._count:
            due = t0 - self.dead_time_s + _TIME_EPS_S
            ring_t = self._ring_t
            head = self._head
            count = self._count
            while count and ring_t[head] <= due:
                self._delayed_bar = self._ring_v[head]
                head = (head + 1) & _RING_MASK
                count -= 1
            self._head = head
            self._count = count
        target = self._delayed_bar
        top = self.max_bar if self.max_bar < self.supply_bar else self.supply_bar
        if target > top:
            target = top
        p = self.pressure_bar
        if self.exhaust_open:
            p -= p * self._alpha_vent
        else:
            if not self.supply_ok and target > p:
                target = p  # no air to fill with: hold
            p += (target - p) * self._alpha_lag
        self.pressure_bar = p
        self.t_s = t0 + dt_s
        return p
