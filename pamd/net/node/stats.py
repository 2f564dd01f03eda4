"""Loop timing statistics kept by the io process from the tick records it drains
(each record carries its wake-up latency, compute time, overruns and lost records),
so that the loop's process never spends time on percentiles for status queries.
Histograms of 1 us bins like `pamd.timing.Histogram`; percentiles at most
every `period_s`, in the io loop."""

from __future__ import annotations

import bisect
import itertools
from array import array
from collections.abc import Sequence

from pamd.declare.jsonsafe import JsonObject
from pamd.tick import I_COMPUTE, I_LOST, I_OVERRUNS, I_TICK, I_WAKE

MAX_US = 100_000


def percentiles(bins: array[int], qs: tuple[float, ...], top: int = MAX_US) -> list[float]:
    """The bins' percentiles `qs` (in bins, 1 us each): the first bin whose cumulative
    count reaches q% of the total (numpy's searchsorted, side left). Plain Python (C
    speed: accumulate, bisect), so the io process needs no numpy. `top`: the highest
    bin that may hold a count (the largest value seen), so only those are summed."""
    cum = list(itertools.accumulate(bins[:min(top, MAX_US) + 1]))
    total = cum[-1]
    if total == 0:
        return [0.0 for _ in qs]
    return [float(bisect.bisect_left(cum, q / 100.0 * total)) for q in qs]


def _top_bin(max_s: float) -> int:
    """The bin `add` put the largest value in (and every smaller one below it)."""
    return max(0, int(max_s * 1e6 + 0.5))


class TickStats:
    def __init__(self, period_s: float = 0.5) -> None:
        self.wake = array("q", bytes(8 * (MAX_US + 1)))
        self.compute = array("q", bytes(8 * (MAX_US + 1)))
        self.wake_max_s = self.compute_max_s = 0.0
        self.last: Sequence[float] | None = None
        self.period_s = period_s
        self.t = -1e9
        self.summary: JsonObject = {}

    def add(self, rows: Sequence[Sequence[float]]) -> None:
        wake, comp, top = self.wake, self.compute, MAX_US
        wmax, cmax = self.wake_max_s, self.compute_max_s
        for row in rows:
            w, c = row[I_WAKE], row[I_COMPUTE]
            wake[min(top, max(0, int(w * 1e6 + 0.5)))] += 1
            comp[min(top, max(0, int(c * 1e6 + 0.5)))] += 1
            if w > wmax:
                wmax = w
            if c > cmax:
                cmax = c
        self.wake_max_s, self.compute_max_s = wmax, cmax
        self.last = rows[-1]

    def refresh(self, now: float) -> None:
        """Recompute the percentiles if `period_s` has passed (the io loop)."""
        if now - self.t < self.period_s or self.last is None:
            return
        self.t = now
        w50, w99 = percentiles(self.wake, (50.0, 99.0), _top_bin(self.wake_max_s))
        c50, c99 = percentiles(self.compute, (50.0, 99.0), _top_bin(self.compute_max_s))
        last = self.last
        self.summary = {
            "ticks": int(last[I_TICK]) + 1, "overruns": int(last[I_OVERRUNS]),
            "lost_records": int(last[I_LOST]),
            "wake_latency_us": {"p50": w50, "p99": w99, "max": self.wake_max_s * 1e6},
            "compute_us": {"p50": c50, "p99": c99, "max": self.compute_max_s * 1e6},
            "source": "the tick records the io process drained",
        }
