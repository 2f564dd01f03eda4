"""Seed 003's incremental PID in velocity form, the position mode's feedback with
`control.position.feedback: incremental` (`position.incremental`).

Every `sample_period_s` (the controller's sample k; between samples the output holds)
the increment of the error e(k) (measured - target length, mm: the paper's target
displacement - actual displacement, displacement being contraction) is

    du(k) = Kp (e(k) - e(k-1)) + Ki e(k) + Kd (e(k) - 2 e(k-1) + e(k-2))

and the pressure compensation u(k) added to the QUPI inverse's pressure is

* Method 1 (seed 003, sec. 3.3, "feedforward + incremental PID feedback"):
  u(k) = du(k), the increment itself, as the paper prints it: a law on the last
  three samples only (k = 3), no accumulation, so Ki e(k) acts as a proportional term
  and a steady error remains (the paper measures Method 1 ten times worse);
* Method 2 (sec. 3.4, "incremental PID-type iterative learning"): u(k) = u(k-1) +
  du(k), the increment accumulated sample to sample (the velocity form of a PID
  whose integral gain is Ki / T). pamd's cycle-to-cycle iterative learning
  (`ilc: true`, `pamd.loop.control.ilc`) is a separate option on top of either.

u is held to +-`output_limit_bar`. When the command it feeds is clamped (the pressure
limit, the slew limit, a guard), the caller restores Method 2's accumulated value
(`hold`: the sample's integral increment is dropped): it does not wind up into the
clamp. On the tick path: float arithmetic on
attributes, nothing allocated.
"""

from __future__ import annotations

import math


class IncrementalPid:
    """One muscle's incremental PID (see the module doc)."""

    __slots__ = ("method", "kp", "ki", "kd", "period_s", "limit", "u", "du", "di", "e1",
                 "e2", "next_s", "primed", "sampled")

    def __init__(self, method: int, kp: float, ki: float, kd: float, period_s: float,
                 output_limit: float) -> None:
        if method not in (1, 2):
            raise ValueError(f"incremental PID: method 1 or 2, not {method!r}")
        if not period_s > 0:
            raise ValueError("incremental PID: sample_period_s must be > 0")
        self.method = method
        self.kp, self.ki, self.kd = kp, ki, kd
        self.period_s = period_s
        self.limit = output_limit
        self.u = self.du = self.di = 0.0
        self.e1 = self.e2 = 0.0
        self.next_s = -math.inf
        self.primed = self.sampled = False

    def reset(self, u: float = 0.0) -> None:
        """Start (a mode change): Method 2 starts from `u` (bumpless), Method 1 from 0;
        the first sample takes its error as the previous ones (no kick)."""
        lim = self.limit
        self.u = max(-lim, min(lim, u)) if self.method == 2 else 0.0
        self.du = self.di = 0.0
        self.next_s = -math.inf
        self.primed = self.sampled = False

    def step(self, now_s: float, error: float) -> float:
        """The compensation (bar) at `now_s` for the length error (mm)."""
        if now_s < self.next_s:
            self.sampled = False
            return self.u
        self.sampled = True
        self.next_s = now_s + self.period_s if self.next_s == -math.inf else \
            self.next_s + self.period_s
        if self.next_s <= now_s:  # fell behind (a stalled loop): resume from now
            self.next_s = now_s + self.period_s
        if not self.primed:
            self.e1 = self.e2 = error
            self.primed = True
        du = (self.kp * (error - self.e1) + self.ki * error
              + self.kd * (error - 2.0 * self.e1 + self.e2))
        self.e2, self.e1 = self.e1, error
        self.du, self.di = du, self.ki * error
        u = self.u + du if self.method == 2 else du
        lim = self.limit
        self.u = lim if u > lim else (-lim if u < -lim else u)
        return self.u

    def hold(self, u_before: float) -> None:
        """The command this step fed was clamped: Method 2 drops this sample's integral
        increment Ki e(k) (as the position PID's integral stops), so it does not wind up
        into the clamp; the proportional and derivative increments stay (dropping them
        would shift u off Kp e + Kd de for good). Method 1 keeps no sum."""
        if self.method == 2 and self.sampled:
            u = u_before + self.du - self.di
            lim = self.limit
            self.u = lim if u > lim else (-lim if u < -lim else u)
