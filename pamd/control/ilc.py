"""Iterative learning control (ILC) for the position mode: a pressure correction over
one cycle of a periodic length profile, learned across cycles (seed 003's PID-type
ILC: u_{j+1}(t) = u_j(t) + Kp e_j(t + lead) + Kd de_j/dt).

`Ilc.step` is on the tick path: float arithmetic on a preallocated array.
"""

from __future__ import annotations

import math
from array import array


class Ilc:
    """A correction over one cycle of a periodic length profile, learned across cycles.

    The cycle is cut into bins of about `resolution_s`. Each tick applies the present
    bin's correction and, for the next cycle, moves the bin `lead_s` earlier by
    gain x error (+ gain_d x error rate), pro rata of the tick's share of a bin; the
    error is first low-passed over a bin. Each bin, once learned for the cycle, is
    smoothed with its neighbours (1/4, 1/2, 1/4: the Q-filter that keeps noise and
    fast dynamics from piling up cycle after cycle) and shrunk by `forgetting` per
    cycle; corrections are clamped to +-`limit_bar`. Error = measured - target
    length (mm): too long means more pressure."""

    __slots__ = ("period_s", "n", "bin_s", "lead", "gain", "gain_d", "keep", "limit", "u",
                 "e_f", "prev_e", "cycles", "last_cycle", "last_bin", "value")

    def __init__(self, period_s: float, gain_bar_per_mm: float, gain_d_bar_s_per_mm: float,
                 lead_s: float, forgetting: float, limit_bar: float, resolution_s: float) -> None:
        self.period_s = period_s
        self.n = max(3, round(period_s / resolution_s))
        self.bin_s = period_s / self.n
        self.lead = round(lead_s / self.bin_s)
        self.gain, self.gain_d = gain_bar_per_mm, gain_d_bar_s_per_mm
        self.keep = forgetting  # applied as (1 - forgetting * dt / period) per tick
        self.limit = limit_bar
        self.u = array("d", bytes(8 * self.n))
        self.e_f = math.nan
        self.prev_e = math.nan
        self.cycles = 0
        self.last_cycle = -1
        self.last_bin = -1
        self.value = 0.0

    def step(self, tau_s: float, error_mm: float, dt_s: float) -> float:
        """Correction at time `tau_s` into the periodic part of the profile."""
        cyc = int(tau_s / self.period_s)
        if cyc != self.last_cycle:
            self.last_cycle = cyc
            self.cycles += 1
        n = self.n
        k = int((tau_s - cyc * self.period_s) / self.bin_s)
        if k >= n:
            k = n - 1
        u = self.u
        lead = self.lead
        lim = self.limit
        if k != self.last_bin:
            if self.last_bin >= 0:  # the bin learned last is done for this cycle: smooth it
                j = (self.last_bin - lead) % n
                w = 0.25 * u[j - 1] + 0.5 * u[j] + 0.25 * u[(j + 1) % n]
                u[j] = lim if w > lim else (-lim if w < -lim else w)
            self.last_bin = k
        self.value = u[k]
        ef = self.e_f
        if ef != ef:
            ef = error_mm
        ef += dt_s / (self.bin_s + dt_s) * (error_mm - ef)
        pe = self.prev_e
        de = (ef - pe) / dt_s if pe == pe else 0.0
        self.e_f = self.prev_e = ef
        j = k - lead
        if j < 0:
            j += n
        w = u[j] * (1.0 - self.keep * dt_s / self.period_s) + dt_s / self.bin_s * (
            self.gain * ef + self.gain_d * de)
        u[j] = lim if w > lim else (-lim if w < -lim else w)
        return self.value
