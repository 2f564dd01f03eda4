"""Sensors as hardware delivers them: a sample every `period_s`, available
`latency_s` after it was taken, with noise, an optional first-order filter and
quantisation, in that order (the filter stands for the module's own averaging; the
quantisation is the converter's last step).

The loop sees the newest delivered sample and the time it was *taken*, so its age
is at least the latency and grows to latency + period before the next one: an
ADAM-6024 analog input converting about 10 samples/s is not fresh at 50 ms, a DAQ
card at 1 kHz nearly always is. A period of 0 samples at every plant step.

Pure Python floats; the pending samples sit in a fixed ring (nothing allocated per
step): `update` runs inside the tick.
"""

from __future__ import annotations

import math
from collections.abc import Callable

_MIN_STEP_S = 0.0002


class SampledSensor:
    """One input channel of a simulated device."""

    def __init__(self, *, period_s: float = 0.0, latency_s: float = 0.0,
                 resolution: float = 0.0, noise_sd: float = 0.0, filter_tau_s: float = 0.0,
                 gauss: Callable[[float, float], float] | None = None) -> None:
        if period_s < 0.0 or latency_s < 0.0 or resolution < 0.0 or filter_tau_s < 0.0:
            raise ValueError("sensor period, latency, resolution and filter must be >= 0")
        self.period_s = period_s
        self.latency_s = latency_s
        self.resolution = resolution
        self.noise_sd = noise_sd
        self.filter_tau_s = filter_tau_s
        self._gauss = gauss
        self._next_sample_s = 0.0
        self._filtered = math.nan
        self._last_sample_s = -math.inf
        # Samples taken but not yet delivered: at most latency / period + 2 of them
        # (a period of 0 samples every plant step, which is at least _MIN_STEP_S).
        size = 2 + math.ceil(latency_s / (period_s if period_s > 0.0 else _MIN_STEP_S))
        self._ring_t = [0.0] * size
        self._ring_v = [0.0] * size
        self._head = 0
        self._count = 0
        self.value = math.nan
        self.sampled_at_s = -math.inf

    def update(self, t_s: float, true_value: float) -> None:
        """The plant is at `t_s` with the measured quantity at `true_value`: take the
        samples due by now, and deliver those whose latency has passed."""
        if t_s >= self._next_sample_s - 1e-9:
            self._take(t_s, true_value)
            period = self.period_s
            if period > 0.0:
                nxt = self._next_sample_s + period
                if nxt <= t_s:  # the plant stepped over whole periods
                    nxt = t_s + period
                self._next_sample_s = nxt
            else:
                self._next_sample_s = t_s
        ring_t, ring_v = self._ring_t, self._ring_v
        size = len(ring_t)
        due = t_s - self.latency_s + 1e-9
        while self._count and ring_t[self._head] <= due:
            self.sampled_at_s = ring_t[self._head]
            self.value = ring_v[self._head]
            self._head = (self._head + 1) % size
            self._count -= 1

    def _take(self, t_s: float, true_value: float) -> None:
        v = true_value
        if self.noise_sd > 0.0 and self._gauss is not None:
            v += self._gauss(0.0, self.noise_sd)
        tau = self.filter_tau_s
        if tau > 0.0:
            f = self._filtered
            if f != f:
                f = v
            else:
                f += (v - f) * (1.0 - math.exp(-(t_s - self._last_sample_s) / tau))
            self._filtered = f
            v = f
        self._last_sample_s = t_s
        res = self.resolution
        if res > 0.0:
            v = math.floor(v / res + 0.5) * res
        size = len(self._ring_t)
        if self._count == size:  # cannot happen with the ring sized above; keep newest
            self._head = (self._head + 1) % size
            self._count -= 1
        slot = (self._head + self._count) % size
        self._ring_t[slot] = t_s
        self._ring_v[slot] = v
        self._count += 1
