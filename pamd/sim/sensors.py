"""Sensors as hardware delivers them: a sample every `period_s`, available
`latency_s` after it was taken, with noise, an optional first-order filter and
quantisation, in that order (the filter stands for the module's own averaging; the
quantisation is the converter's last step: an ADC of `bits` over `range_min` ..
`range_max` saturates at its ends and reads in steps of range / (2^bits - 1); an
encoder reads in steps of its `resolution`).

The loop sees the newest delivered sample and the time it was *taken*, so its age
is at least the latency and grows to latency + period before the next one: an
ADAM-6024 analog input converting about 10 samples/s is not fresh at 50 ms, a DAQ
card at 1 kHz nearly always is. A period of 0 samples at every plant step.

Bursty delivery (`burst_s` > 0): every `burst_every_s` the link holds the samples
for `burst_s` (a busy host, a USB or Ethernet stack that batches), then the
backlog arrives oldest first, `BURST_CATCH_UP` samples per plant step, as a
driver thread drains its socket. Such a sensor is stamped the way a protocol
without a sample time forces (a CANopen TPDO, a streamed line): with its
*arrival*, and a declared `jitter_s`, how much earlier than its stamp it may have
been taken (the time since the link was last seen idle). Without bursts a sample
is stamped with the time it was taken, jitter 0 (a protocol that says when).

Pure Python floats; the pending samples sit in a fixed ring (nothing allocated per
step): `update` runs inside the tick.
"""

from __future__ import annotations

import math
from collections.abc import Callable

_MIN_STEP_S = 0.0002
#: samples of a held backlog delivered per plant step once the link resumes
BURST_CATCH_UP = 3


class SampledSensor:
    """One input channel of a simulated device."""

    def __init__(self, *, period_s: float = 0.0, latency_s: float = 0.0,
                 resolution: float = 0.0, noise_sd: float = 0.0, filter_tau_s: float = 0.0,
                 gauss: Callable[[float, float], float] | None = None,
                 adc_bits: int = 0, range_min: float = -math.inf, range_max: float = math.inf,
                 burst_s: float = 0.0, burst_every_s: float = 1.0) -> None:
        if (period_s < 0.0 or latency_s < 0.0 or resolution < 0.0 or filter_tau_s < 0.0
                or noise_sd < 0.0 or burst_s < 0.0):
            raise ValueError("sensor period, latency, resolution, noise, filter and burst "
                             "must be >= 0")
        if adc_bits:
            if not (1 <= adc_bits <= 32 and math.isfinite(range_min)
                    and math.isfinite(range_max) and range_min < range_max):
                raise ValueError("an ADC needs 1..32 bits and a finite range_min < range_max")
            resolution = (range_max - range_min) / (2 ** adc_bits - 1)
        if burst_s > 0.0 and not burst_every_s > burst_s:
            raise ValueError("burst_every_s must be longer than burst_s")
        self.period_s = period_s
        self.latency_s = latency_s
        self.resolution = resolution
        self.range_min = range_min if adc_bits else -math.inf
        self.range_max = range_max if adc_bits else math.inf
        self._q0 = self.range_min if adc_bits else 0.0
        self.noise_sd = noise_sd
        self.filter_tau_s = filter_tau_s
        self.burst_s = burst_s
        self.burst_every_s = burst_every_s
        self._gauss = gauss
        self._next_sample_s = 0.0
        self._filtered = math.nan
        self._last_sample_s = -math.inf
        # Samples taken but not yet delivered: at most (latency + burst) / period + 2 of
        # them (a period of 0 samples every plant step, which is at least _MIN_STEP_S).
        step = period_s if period_s > 0.0 else _MIN_STEP_S
        size = 2 + math.ceil((latency_s + 2.0 * burst_s) / step)
        self._ring_t = [0.0] * size
        self._ring_v = [0.0] * size
        self._head = 0
        self._count = 0
        self.value = math.nan
        self.sampled_at_s = -math.inf
        #: what the driver publishes: the sample's time, or its arrival (bursty link)
        self.stamp_s = -math.inf
        #: how much earlier than `stamp_s` the sample may have been taken
        self.jitter_s = 0.0
        self._idle_since_s = 0.0  # the link was last seen with nothing queued

    @property
    def bursty(self) -> bool:
        return self.burst_s > 0.0

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
        if self.burst_s > 0.0:
            self._deliver_bursty(t_s)
            return
        ring_t, ring_v = self._ring_t, self._ring_v
        size = len(ring_t)
        due = t_s - self.latency_s + 1e-9
        while self._count and ring_t[self._head] <= due:
            self.sampled_at_s = self.stamp_s = ring_t[self._head]
            self.value = ring_v[self._head]
            self._head = (self._head + 1) % size
            self._count -= 1

    def _deliver_bursty(self, t_s: float) -> None:
        """Nothing arrives while the link holds; afterwards the backlog drains
        BURST_CATCH_UP samples per step, each stamped on arrival."""
        if t_s % self.burst_every_s < self.burst_s:
            return  # the link holds
        ring_t, ring_v = self._ring_t, self._ring_v
        size = len(ring_t)
        due = t_s - self.latency_s + 1e-9
        n = 0
        while self._count and ring_t[self._head] <= due and n < BURST_CATCH_UP:
            self.sampled_at_s = ring_t[self._head]
            self.value = ring_v[self._head]
            self._head = (self._head + 1) % size
            self._count -= 1
            n += 1
        if n:
            self.stamp_s = t_s
            self.jitter_s = t_s - self._idle_since_s
        if not (self._count and ring_t[self._head] <= due):
            self._idle_since_s = t_s  # nothing more queued: the link is idle now

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
        if v < self.range_min:
            v = self.range_min
        elif v > self.range_max:
            v = self.range_max
        res = self.resolution
        if res > 0.0:
            q0 = self._q0
            v = q0 + math.floor((v - q0) / res + 0.5) * res
        size = len(self._ring_t)
        if self._count == size:  # cannot happen with the ring sized above; keep newest
            self._head = (self._head + 1) % size
            self._count -= 1
        slot = (self._head + self._count) % size
        self._ring_t[slot] = t_s
        self._ring_v[slot] = v
        self._count += 1
