"""Iterative learning control (ILC) for the position mode: a correction of the position
loop's length target over one cycle of a periodic length profile, learned from cycle to
cycle (seed 003's PID-type ILC, filtered, learned per cycle; the serial arrangement:
the learned correction shifts what the position PID aims at):

    c_{j+1}(t) = Q[ (1 - forgetting) c_j(t) + Kp e_j(t + lead) + Kd de_j/dt(t + lead) ]

* e_j is the length error (measured - target, mm) of cycle j, averaged into bins of
  `resolution_s`; c_j the correction applied in cycle j (mm: the PID sees the error
  e + c, so a muscle too long at t is aimed shorter there next cycle), read between bin
  centres by linear interpolation, so it is smooth at the tick's resolution.
* Why the target, not the pressure: from the target to the length the closed position
  loop passes the correction with gain ~1 and a near-constant delay (the loop's dead
  time + lag: 75-79 ms from 0.2 to 6 Hz for the simulated DMSP-20 at 30 kg), so one
  lead lines it up at every frequency the learning needs. From the pressure, the PID's
  integral advances the low frequencies (+52 degrees at 1 Hz) and delays the high ones:
  no single lead fits, and the learning circles instead of converging.
* `lead` is that delay (the position loop's measured dead time + lag, `pamd tune
  --loop position`), applied exactly (a fractional number of bins, the error
  interpolated), not rounded to a bin.
* Q is a zero-phase low-pass over the whole cycle: a first-order low-pass run forward
  and then backward around the cycle (circular: the cycle repeats), each pass -3 dB at
  `cutoff_hz`, so Q's gain is 1/2 at `cutoff_hz`, ~1 well below it, and its phase is 0.
  The learning converges monotonically where |Q (1 - Kp T e^{i w lead})| < 1 (T: the
  closed position loop); Q keeps what the lead cannot line up (fast dynamics, noise)
  from piling up cycle after cycle.
* The correction is clamped to +-`limit_mm`.

The error of cycle j is learned into a buffer; the new correction is computed once
the cycle is over, spread over the following ticks (`BINS_PER_TICK` bins a tick, a few
ms at 1 Hz) while c_j stays applied, then swapped in. `Ilc.step` is on the tick path:
float arithmetic on preallocated `array`s, its work per tick bounded.
"""

from __future__ import annotations

import math
from array import array

#: Bins of the once-per-cycle learning pass done per tick (bounds the tick's cost).
BINS_PER_TICK = 32
#: The circular low-pass passes start this many time constants before their start
#: (the state the cycle's end leaves, to e^-10 = 0.005 %).
WARM_TIME_CONSTANTS = 10.0

IDLE, MEANS, LEARN, FORWARD, BACKWARD, COMMIT = range(6)


def q_pole(cutoff_hz: float, bin_s: float) -> float:
    """The pole of a discrete first-order low-pass (y += (1 - a)(x - y)) sampled every
    `bin_s` whose gain is 1/sqrt(2) at `cutoff_hz` (0 if the cutoff is at or beyond the
    Nyquist frequency: no filtering)."""
    w = 2.0 * math.pi * cutoff_hz * bin_s
    if w >= math.pi:
        return 0.0
    c = 2.0 - math.cos(w)
    return c - math.sqrt(c * c - 1.0)


def q_gain(freq_hz: float, cutoff_hz: float, bin_s: float) -> float:
    """The gain of the zero-phase Q-filter (forward + backward pass) at `freq_hz`."""
    a = q_pole(cutoff_hz, bin_s)
    w = 2.0 * math.pi * freq_hz * bin_s
    return (1.0 - a) ** 2 / (1.0 - 2.0 * a * math.cos(w) + a * a)


class Ilc:
    """A correction over one cycle of a periodic length profile, learned across cycles
    (see the module docstring). Error = measured - target length (mm); the correction
    (mm) is added to it before the position PID: too long means aim shorter."""

    __slots__ = ("period_s", "n", "bin_s", "lead_bins", "gain", "gain_d", "keep", "limit",
                 "pole", "warm", "u", "nxt", "e_sum", "e_cnt", "e_last", "e_last_cnt",
                 "stage", "pos", "y", "cycles", "last_cycle", "value", "learned_cycles")

    def __init__(self, period_s: float, gain: float, gain_d_s: float, lead_s: float,
                 forgetting: float, limit_mm: float, resolution_s: float,
                 cutoff_hz: float) -> None:
        self.period_s = period_s
        n = self.n = max(4, round(period_s / resolution_s))
        self.bin_s = period_s / n
        self.lead_bins = lead_s / self.bin_s
        self.gain, self.gain_d = gain, gain_d_s
        self.keep = 1.0 - forgetting
        self.limit = limit_mm
        a = self.pole = q_pole(cutoff_hz, self.bin_s)
        self.warm = 0 if a <= 0.0 else min(n, math.ceil(WARM_TIME_CONSTANTS / -math.log(a)))
        zeros = bytes(8 * n)
        self.u = array("d", zeros)  # the correction applied in this cycle
        self.nxt = array("d", zeros)  # the next cycle's, while it is computed
        self.e_sum = array("d", zeros)  # this cycle's error per bin (sum, count)
        self.e_cnt = array("d", zeros)
        self.e_last = array("d", zeros)  # the last cycle's (sum, then mean)
        self.e_last_cnt = array("d", zeros)
        self.stage = IDLE
        self.pos = 0
        self.y = 0.0
        self.cycles = 0  # cycles begun
        self.learned_cycles = 0  # corrections computed and swapped in
        self.last_cycle = -1
        self.value = 0.0

    def step(self, tau_s: float, error_mm: float, dt_s: float) -> float:
        """The correction (mm) at time `tau_s` into the periodic part of the profile;
        learns this tick's error `error_mm`. (`dt_s`: the tick, kept for the caller.)"""
        period = self.period_s
        cyc = int(tau_s / period)
        if cyc != self.last_cycle:
            if self.last_cycle >= 0:
                self.end_cycle()
            self.last_cycle = cyc
            self.cycles += 1
        n = self.n
        x = (tau_s - cyc * period) / self.bin_s
        k = int(x)
        if k >= n:
            k = n - 1
        self.e_sum[k] += error_mm
        self.e_cnt[k] += 1.0
        if self.stage != IDLE:
            self.work(BINS_PER_TICK)
        u = self.u
        x -= 0.5  # bin centres
        i = math.floor(x)
        f = x - i
        i0 = i % n
        i1 = i0 + 1
        if i1 == n:
            i1 = 0
        v = self.value = u[i0] + f * (u[i1] - u[i0])
        return v

    def end_cycle(self) -> None:
        """A cycle's error is complete: start computing the next correction from it."""
        if self.stage != IDLE:  # the last one is not done (a cycle shorter than its pass)
            self.work(1 << 30)
        self.e_sum, self.e_last = self.e_last, self.e_sum
        self.e_cnt, self.e_last_cnt = self.e_last_cnt, self.e_cnt
        self.stage = MEANS
        self.pos = 0

    def work(self, budget: int) -> None:
        """Advance the learning pass by up to `budget` bins."""
        n = self.n
        while budget > 0 and self.stage != IDLE:
            stage = self.stage
            p = self.pos
            if stage == FORWARD or stage == BACKWARD:
                end = min(n + self.warm, p + budget)
            else:
                end = min(n, p + budget)
            budget -= end - p
            if stage == MEANS:
                self.means(p, end)
            elif stage == LEARN:
                self.learn(p, end)
            elif stage == FORWARD:
                self.forward(p, end)
            elif stage == BACKWARD:
                self.backward(p, end)
            else:
                self.commit(p, end)
            if end == (n + self.warm if stage == FORWARD or stage == BACKWARD else n):
                self.pos = 0
                self.y = 0.0
                self.stage = IDLE if stage == COMMIT else stage + 1
                if stage == COMMIT:
                    self.u, self.nxt = self.nxt, self.u
                    self.learned_cycles += 1
            else:
                self.pos = end

    def means(self, p: int, end: int) -> None:
        """Sums to means; a bin no tick fell in (bins finer than the tick) holds the
        previous bin's mean."""
        s, c = self.e_last, self.e_last_cnt
        last = s[p - 1] if p > 0 else 0.0
        for k in range(p, end):
            m = c[k]
            last = s[k] = s[k] / m if m > 0.0 else last

    def learn(self, p: int, end: int) -> None:
        n = self.n
        e, u, out = self.e_last, self.u, self.nxt
        keep, kp = self.keep, self.gain
        kd = self.gain_d / (2.0 * self.bin_s)
        lead = self.lead_bins
        for k in range(p, end):
            x = k + lead
            i = math.floor(x)
            f = x - i
            i0 = i % n
            i1 = (i0 + 1) % n
            ek = e[i0] + f * (e[i1] - e[i0])
            w = keep * u[k] + kp * ek
            if kd != 0.0:
                w += kd * (e[i1] - e[(i0 - 1) % n])  # the slope around x, over two bins
            out[k] = w

    def forward(self, p: int, end: int) -> None:
        self.low_pass(p, end, 1, 0)

    def backward(self, p: int, end: int) -> None:
        self.low_pass(p, end, -1, -1)

    def low_pass(self, p: int, end: int, sign: int, offset: int) -> None:
        """One pass of the circular first-order low-pass over the next correction, bins
        p to end of it (the first `warm` of them only warm the filter up): forward
        (sign 1) from bin -warm, or backward (sign -1, offset -1) from bin warm - 1."""
        n, warm = self.n, self.warm
        a = self.pole
        b = 1.0 - a
        w = self.nxt
        y = self.y
        if p == 0:
            y = w[(offset - sign * warm) % n]
        for v in range(p, end):
            idx = (sign * (v - warm) + offset) % n
            y = a * y + b * w[idx]
            if v >= warm:
                w[idx] = y
        self.y = y

    def commit(self, p: int, end: int) -> None:
        w, s, c = self.nxt, self.e_last, self.e_last_cnt
        lim = self.limit
        for k in range(p, end):
            x = w[k]
            w[k] = lim if x > lim else (-lim if x < -lim else x)
            s[k] = 0.0
            c[k] = 0.0
