"""A card's sample clock on this PC's clock, and the hand-over that lets it pace the
loop (`loop.clock: daq`; `pamd.drivers.SampleClock`).

`EdgeEstimate`: when the sample clock's edges happen, in the loop's time. The driver
learns of edge k when its wait for the next sample clock returns, which is never
before the edge (the card sampled at the edge, then the host heard of it): so edge k
is at most that return time, and the earliest return seen, less k periods, is the
clock's phase. The card's oscillator and the PC's clock drift apart (a DAQ card's
timebase is specified to tens of ppm), so the phase may move later than that earliest
return by at most `DRIFT` of a period per period (100 ppm); a return earlier than the
estimate moves it at once.

`PacedSamples`: the driver's thread publishes each sample (its edge and the sample
clocks missed before it), the loop's thread waits for it, ticks, says its outputs are
stored, and the driver's thread writes them before the next edge.
"""

from __future__ import annotations

import math
import threading
import time

#: how much later than the earliest return the phase may move, a fraction of a period per
#: period (100 ppm: above a DAQ timebase's drift against the PC's clock)
DRIFT = 1e-4


class EdgeEstimate:
    """The time of sample clock edge k on this PC's clock (module docstring)."""

    def __init__(self, period_s: float) -> None:
        self.period_s = period_s
        self.phase_s = math.nan

    def reset(self) -> None:
        """The clock restarted (the tasks were made again): learn its phase anew."""
        self.phase_s = math.nan

    def edge_s(self, k: int, returned_s: float) -> float:
        """Edge k, whose wait returned at `returned_s`: never later than that."""
        p = self.period_s
        phase = self.phase_s + DRIFT * p
        seen = returned_s - k * p
        if not phase <= seen:  # earlier (or the first): the edge was at most then
            phase = seen
        self.phase_s = phase
        return phase + k * p


class PacedSamples:
    """The `pamd.drivers.SampleClock` of a driver whose thread waits for its card's sample
    clock: published samples in, ticks' outputs out (module docstring)."""

    def __init__(self, period_s: float, label: str) -> None:
        self.period_s = period_s
        self.label = label
        self._cv = threading.Condition(threading.Lock())
        self._seq = 0  # samples published
        self._taken = 0  # the newest sample the loop took
        self._done = 0  # the newest sample whose tick stored its outputs
        self._edge_s = math.nan
        self._missed = 0
        self._missed_total = 0  # every missed clock published (`handed`)
        self.attached = False

    def describe(self) -> str:
        return self.label

    # -- the driver's thread ----------------------------------------------------------------
    def publish(self, edge_s: float, missed: int) -> None:
        """A sample's inputs are stamped: its edge, and the sample clocks that went by
        unread before it (late samples the device reported)."""
        with self._cv:
            self._seq += 1
            self._edge_s = edge_s
            self._missed += missed
            self._missed_total += missed
            self._cv.notify_all()

    def await_tick(self, deadline_s: float) -> bool:
        """Until the loop's tick for the newest sample stored its outputs (True), or
        `deadline_s` (monotonic) passed (False). True at once with no loop attached."""
        mono = time.monotonic
        with self._cv:
            while self.attached and self._done < self._seq:
                rest = deadline_s - mono()
                if rest <= 0.0:
                    return False
                self._cv.wait(rest)
            return True

    # -- the loop's thread ------------------------------------------------------------------
    def attach(self) -> None:
        with self._cv:
            self.attached = True
            self._taken = self._done = self._seq  # older samples are not the loop's
            self._missed = 0

    def detach(self) -> None:
        with self._cv:
            self.attached = False
            self._cv.notify_all()

    def wait(self, deadline_s: float) -> float:
        """The edge of the next sample not yet taken (the newest, if several came: the
        ones skipped count as missed), or NaN if none came by `deadline_s`."""
        mono = time.monotonic
        with self._cv:
            while self._seq == self._taken:
                rest = deadline_s - mono()
                if rest <= 0.0:
                    return math.nan
                self._cv.wait(rest)
            self._missed += self._seq - self._taken - 1
            self._taken = self._seq
            return self._edge_s

    def handed(self) -> tuple[int, int]:
        """(the sample clocks handed so far: samples and the missed ones published with
        them; of those, the ones the loop has not taken yet): the tests' accounting."""
        with self._cv:
            return (self._seq + self._missed_total,
                    self._seq - self._taken + self._missed)

    def take_missed(self) -> int:
        with self._cv:
            missed, self._missed = self._missed, 0
            return missed

    def tick_done(self) -> None:
        with self._cv:
            self._done = self._taken
            self._cv.notify_all()
