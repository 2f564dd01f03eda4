"""What a proportional regulator makes of its setpoint before any air moves:
zero-point suppression, a backlash band (its hysteresis) and the pilot's dead time.

A setpoint below the zero-point threshold means 0 bar (the regulator vents); any
other passes through the backlash band, so the effective setpoint moves only once
the command leaves the band. Changes of the effective setpoint take effect one
dead time later (a ring buffer of time-stamped changes; nothing allocated per step).
"""

from __future__ import annotations

_RING_SIZE = 128  # setpoint changes held within one dead time (power of two)
_RING_MASK = _RING_SIZE - 1
_TIME_EPS_S = 1e-7  # float slack when comparing accumulated times


class SetpointPilot:
    """Setpoint -> (zero point, backlash) -> dead time; `delayed_bar` is the result."""

    def __init__(self, *, max_bar: float, dead_time_s: float, backlash_bar: float,
                 zero_bar: float, initial_bar: float) -> None:
        self.max_bar = max_bar
        self.dead_time_s = dead_time_s
        self.half_backlash_bar = 0.5 * backlash_bar
        self.zero_bar = zero_bar
        p0 = min(max(initial_bar, 0.0), max_bar)
        self.setpoint_bar = p0  # as written (clamped to the input range)
        self.effective_bar = p0  # after zero point and backlash
        self.delayed_bar = p0  # after the dead time
        self._ring_t = [0.0] * _RING_SIZE
        self._ring_v = [0.0] * _RING_SIZE
        self._head = 0
        self._count = 0

    def set_setpoint(self, value_bar: float) -> None:
        """The commanded pressure; clamped to the regulator's input range."""
        if value_bar < 0.0:
            value_bar = 0.0
        elif value_bar > self.max_bar:
            value_bar = self.max_bar
        self.setpoint_bar = value_bar

    def step(self, t0_s: float) -> float:
        """The delayed setpoint for the step starting at `t0_s`."""
        u = self.setpoint_bar
        e = self.effective_bar
        half = self.half_backlash_bar
        if u < self.zero_bar:
            e = 0.0
        elif u > e + half:
            e = u - half
        elif u < e - half:
            e = u + half
        if e != self.effective_bar:
            self.effective_bar = e
            if self.dead_time_s <= 0.0:
                self.delayed_bar = e
            else:
                count = self._count
                if count == _RING_SIZE:  # full: the oldest change takes effect now
                    self.delayed_bar = self._ring_v[self._head]
                    self._head = (self._head + 1) & _RING_MASK
                    count -= 1
                slot = (self._head + count) & _RING_MASK
                self._ring_t[slot] = t0_s
                self._ring_v[slot] = e
                self._count = count + 1
        # A change made at t takes effect for steps starting at t + dead time.
        if self._count:
            due = t0_s - self.dead_time_s + _TIME_EPS_S
            ring_t = self._ring_t
            head = self._head
            count = self._count
            while count and ring_t[head] <= due:
                self.delayed_bar = self._ring_v[head]
                head = (head + 1) & _RING_MASK
                count -= 1
            self._head = head
            self._count = count
        return self.delayed_bar
