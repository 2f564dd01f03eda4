"""Reference profiles for a pressure (or length) setpoint.

Every profile starts with a lead-in ramp from the present value to its own start
value, then runs its shape: constant, step (a square wave whose edges are ramps),
ramp, sine (the seeds' (p/2) sin + p/2: starts at mid-range rising with maximum
slope) or triangle, for a number of cycles (None: until stopped). `sample(t)` sets
`value`, `rate`, `cycle` and `done` without allocating; `check()` refuses a
profile that is faster than the slew limit or leaves the allowed range.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from pamd.errors import CommandRefused

ProfileKind = Literal["constant", "step", "ramp", "sine", "triangle"]


@dataclass(frozen=True)
class ProfileSpec:
    """What an operator asks for; validated by `check` before anything moves."""

    kind: ProfileKind = "sine"
    min_bar: float = 0.0
    max_bar: float = 6.0
    freq_hz: float = 0.05
    cycles: int | None = None
    to_bar: float | None = None  # ramp and constant: target value
    rate_bar_per_s: float | None = None  # ramp: rate (default: half the slew limit)
    rise_s: float | None = None  # step: edge duration (default: at the slew limit)
    duration_s: float | None = None  # constant: how long (None: until stopped)
    lead_in_bar_per_s: float = 1.0  # lead-in ramp rate from the present value

    def start_value(self) -> float:
        if self.kind in ("ramp",):
            return math.nan  # starts where it is
        if self.kind == "constant":
            return self.to_bar if self.to_bar is not None else self.min_bar
        if self.kind == "sine":
            return 0.5 * (self.min_bar + self.max_bar)
        return self.min_bar

    def shape_max_rate(self, slew_limit: float) -> float:
        """Steepest slope of the shape itself (not the lead-in)."""
        span = self.max_bar - self.min_bar
        if self.kind == "sine":
            return math.pi * self.freq_hz * span
        if self.kind == "triangle":
            return 2.0 * span * self.freq_hz
        if self.kind == "step":
            return span / self.edge_s(slew_limit)
        if self.kind == "ramp":
            return self.rate_bar_per_s if self.rate_bar_per_s is not None else 0.5 * slew_limit
        return 0.0

    def edge_s(self, slew_limit: float) -> float:
        if self.rise_s is not None:
            return self.rise_s
        return (self.max_bar - self.min_bar) / slew_limit

    def check(self, low_bar: float, high_bar: float, slew_limit: float) -> None:
        """Refuse (CommandRefused) a profile outside [low, high] or faster than the slew
        limit, saying which parameter to change."""
        k = self.kind
        if k in ("sine", "triangle", "step"):
            if not self.max_bar > self.min_bar:
                raise CommandRefused(f"{k} profile: max_bar ({self.max_bar}) must exceed "
                                     f"min_bar ({self.min_bar})")
            if not self.freq_hz > 0:
                raise CommandRefused(f"{k} profile: freq_hz must be positive")
            lo, hi = self.min_bar, self.max_bar
        else:
            if self.to_bar is None and k == "ramp":
                raise CommandRefused("ramp profile: give to_bar, the value to ramp to")
            lo = hi = self.start_value() if k == "constant" else self.to_bar  # type: ignore[assignment]
        if self.cycles is not None and self.cycles < 1:
            raise CommandRefused(f"{k} profile: cycles must be at least 1")
        if lo < low_bar - 1e-9 or hi > high_bar + 1e-9:
            raise CommandRefused(
                f"{k} profile spans {lo:g}-{hi:g} bar but the allowed range is "
                f"{low_bar:g}-{high_bar:g} bar; lower max_bar or raise min_bar")
        rate = self.shape_max_rate(slew_limit)
        if rate > slew_limit * (1 + 1e-9):
            raise CommandRefused(
                f"{k} profile needs {rate:.3g} bar/s but the slew limit is {slew_limit:g} bar/s"
                f"; lower freq_hz or the span, or raise control.slew_limit_bar_per_s")
        if not 0 < self.lead_in_bar_per_s <= slew_limit:
            raise CommandRefused(f"lead-in rate must be in (0, {slew_limit:g}] bar/s")

    def shape_period_s(self) -> float:
        return 1.0 / self.freq_hz if self.kind in ("sine", "triangle", "step") else 0.0


class Profile:
    """A running profile. Create with the spec, the present value and the start time."""

    def __init__(self, spec: ProfileSpec, t0_s: float, present_bar: float,
                 slew_limit: float) -> None:
        self.spec = spec
        self.kind = spec.kind
        self.t0_s = t0_s
        self.from_bar = present_bar
        start = spec.start_value()
        if spec.kind == "ramp":
            start = present_bar
        self.start_bar = start
        self.lead_in_s = abs(start - present_bar) / spec.lead_in_bar_per_s
        self.lead_rate = math.copysign(spec.lead_in_bar_per_s, start - present_bar)
        self.lo, self.hi = spec.min_bar, spec.max_bar
        self.span = spec.max_bar - spec.min_bar
        self.freq = spec.freq_hz
        self.period_s = spec.shape_period_s()
        self.edge_s = spec.edge_s(slew_limit) if spec.kind == "step" else 0.0
        if spec.kind == "ramp":
            rate = spec.rate_bar_per_s or 0.5 * slew_limit
            assert spec.to_bar is not None
            self.ramp_rate = math.copysign(rate, spec.to_bar - present_bar)
            self.ramp_s = abs(spec.to_bar - present_bar) / rate
        self.value = present_bar
        self.rate = 0.0
        self.cycle = 0
        self.done = False

    def total_s(self) -> float | None:
        """Lead-in plus shape duration; None if it runs until stopped."""
        s = self.spec
        if s.kind == "ramp":
            return self.lead_in_s + self.ramp_s
        if s.kind == "constant":
            return None if s.duration_s is None else self.lead_in_s + s.duration_s
        if s.cycles is None:
            return None
        return self.lead_in_s + s.cycles * self.period_s

    def sample(self, t_s: float) -> None:
        tau = t_s - self.t0_s
        if tau < self.lead_in_s:
            self.value = self.from_bar + self.lead_rate * tau
            self.rate = self.lead_rate
            return
        tau -= self.lead_in_s
        kind = self.kind
        if kind == "ramp":
            if tau >= self.ramp_s:
                self.value, self.rate, self.done = self.spec.to_bar, 0.0, True  # type: ignore[assignment]
            else:
                self.value, self.rate = self.start_bar + self.ramp_rate * tau, self.ramp_rate
            return
        if kind == "constant":
            self.value, self.rate = self.start_bar, 0.0
            d = self.spec.duration_s
            self.done = d is not None and tau >= d
            return
        cycles = self.spec.cycles
        cyc = int(tau * self.freq)
        if cycles is not None and cyc >= cycles:
            self.done = True
            self.cycle = cycles
            tau = cycles * self.period_s  # hold the end value
        else:
            self.cycle = cyc
        phase = tau * self.freq - int(tau * self.freq)
        if self.done:
            phase = 0.0
        if kind == "sine":
            w = 2.0 * math.pi * self.freq
            self.value = self.lo + 0.5 * self.span * (1.0 + math.sin(w * tau))
            self.rate = 0.0 if self.done else 0.5 * self.span * w * math.cos(w * tau)
        elif kind == "triangle":
            slope = 2.0 * self.span * self.freq
            if phase < 0.5:
                self.value, self.rate = self.lo + slope * phase / self.freq, slope
            else:
                self.value, self.rate = self.hi - slope * (phase - 0.5) / self.freq, -slope
            if self.done:
                self.rate = 0.0
        else:  # step: low half period, high half period, edges ramped
            t_in = phase / self.freq
            half = 0.5 * self.period_s
            e = self.edge_s
            r = self.span / e if e > 0 else 0.0
            if t_in < half:
                if t_in < e and (self.cycle > 0 or self.done):
                    self.value, self.rate = self.hi - r * t_in, -r
                else:
                    self.value, self.rate = self.lo, 0.0
            elif t_in - half < e:
                self.value, self.rate = self.lo + r * (t_in - half), r
            else:
                self.value, self.rate = self.hi, 0.0
            if self.done:
                self.value, self.rate = self.hi, 0.0
