"""Per-tick timing statistics in fixed memory: histograms of wake-up latency and
compute time (1 us bins), overrun counts, percentiles at any time."""

from __future__ import annotations

from array import array
from dataclasses import dataclass


class Histogram:
    """Counts of durations in 1 us bins up to `max_us`; the last bin holds the rest."""

    def __init__(self, max_us: int = 100_000) -> None:
        self.bins = array("q", bytes(8 * (max_us + 1)))
        self.last = max_us
        self.count = 0
        self.max_s = 0.0

    def add(self, seconds: float) -> None:
        us = int(seconds * 1e6 + 0.5)
        if us < 0:
            us = 0
        elif us > self.last:
            us = self.last
        self.bins[us] += 1
        self.count += 1
        if seconds > self.max_s:
            self.max_s = seconds

    def percentile_s(self, q: float) -> float:
        """The q-th percentile (0-100) in seconds, to 1 us; 0 when empty."""
        if self.count == 0:
            return 0.0
        rank = q / 100.0 * self.count
        seen = 0
        for us, n in enumerate(self.bins):
            seen += n
            if n and seen >= rank:
                return us * 1e-6
        return self.last * 1e-6

    def reset(self) -> None:
        self.bins = array("q", bytes(8 * (self.last + 1)))
        self.count = 0
        self.max_s = 0.0


@dataclass
class TimingSummary:
    ticks: int
    overruns: int
    wake_p50_us: float
    wake_p99_us: float
    wake_max_us: float
    compute_p50_us: float
    compute_p99_us: float
    compute_max_us: float


class TickTiming:
    """Wake-up latency and compute time of every tick, and skipped periods."""

    def __init__(self) -> None:
        self.wake = Histogram()
        self.compute = Histogram()
        self.ticks = 0
        self.overruns = 0

    def summary(self) -> TimingSummary:
        w, c = self.wake, self.compute
        return TimingSummary(
            ticks=self.ticks,
            overruns=self.overruns,
            wake_p50_us=w.percentile_s(50) * 1e6,
            wake_p99_us=w.percentile_s(99) * 1e6,
            wake_max_us=w.max_s * 1e6,
            compute_p50_us=c.percentile_s(50) * 1e6,
            compute_p99_us=c.percentile_s(99) * 1e6,
            compute_max_us=c.max_s * 1e6,
        )
