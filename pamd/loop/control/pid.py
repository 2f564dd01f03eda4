"""PID pressure controller: anti-windup, derivative on a filtered measurement,
output limits, bumpless (re)start. Pure Python, no allocation per step."""

from __future__ import annotations

import math


class Pid:
    """u = kp*e + ki*integral(e) - kd*d(measured)/dt, each term kept for the record.

    The integral stops growing while the output is saturated in the direction of the
    error (conditional integration) and is clamped to `integral_limit`.
    """

    def __init__(self, kp: float, ki_per_s: float, kd_s: float, derivative_filter_hz: float,
                 integral_limit: float, output_limit: float) -> None:
        self.kp, self.ki, self.kd = kp, ki_per_s, kd_s
        self.filter_tau_s = 1.0 / (2.0 * math.pi * derivative_filter_hz)
        self.integral_limit, self.output_limit = integral_limit, output_limit
        self.p = self.i = self.d = 0.0
        self.saturated = False
        self._filtered = math.nan
        self._deriv = 0.0

    def reset(self, measured: float, integral: float = 0.0) -> None:
        """Bumpless start: no derivative kick, integral preset."""
        self._filtered = measured
        self._deriv = 0.0
        self.i = max(-self.integral_limit, min(self.integral_limit, integral))
        self.p = self.d = 0.0
        self.saturated = False

    def keep_integral_off_clamp(self, i_before: float, clamped_down: bool) -> None:
        """The command was clamped after this step (a guard or a limit): the integral may
        move away from the clamp, never into it. Clamped down (the command was lowered),
        it may only fall; clamped up, only rise. Then a clamp that lets go finds no
        wound-up integral, and one that holds never pins it."""
        if clamped_down:
            if self.i > i_before:
                self.i = i_before
        elif self.i < i_before:
            self.i = i_before

    def step(self, error: float, measured: float, dt_s: float) -> float:
        if self._filtered != self._filtered:  # NaN: first step
            self.reset(measured)
        # Derivative on the measurement through a first-order low-pass. (Each term is
        # kept in a local as it is stored: the same arithmetic, fewer attribute reads.)
        alpha = dt_s / (self.filter_tau_s + dt_s)
        prev = self._filtered
        filtered = self._filtered = prev + alpha * (measured - prev)
        deriv = self._deriv = (filtered - prev) / dt_s
        p = self.p = self.kp * error
        d = self.d = -self.kd * deriv
        lim = self.output_limit
        i = self.i
        unsat = p + i + d
        pushing_out = (unsat >= lim and error > 0.0) or (unsat <= -lim and error < 0.0)
        if not pushing_out:
            i = i + self.ki * error * dt_s
            il = self.integral_limit
            i = self.i = il if i > il else (-il if i < -il else i)
        u = p + i + d
        if u >= lim:
            self.saturated = True
            return lim
        if u <= -lim:
            self.saturated = True
            return -lim
        self.saturated = False
        return u
