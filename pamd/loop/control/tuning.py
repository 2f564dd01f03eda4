"""Tuning from measured responses: identify a first-order-plus-dead-time (FOPDT)
model of a loop from a step or a relay-feedback test, and derive controller gains
from it, as a lab with real hardware must (never from a simulator's parameters).

    G(s) = K e^(-theta s) / (tau s + 1)

- `fit_step`: from a recorded step response. A two-point estimate (the times the
  normalised response reaches 28.3 % and 63.2 %; Smith's method) starts a
  least-squares fit of the whole response (Gauss-Newton on theta and tau; K from the
  settled change).
- `relay_fopdt`: from a relay-feedback test (Astrom and Hagglund): the relay of
  amplitude d makes the loop oscillate with amplitude a and period Tu, so the
  ultimate gain is Ku = 4 d / (pi a); with the static gain K (from a step), tau and
  theta follow from the phase and gain conditions at the ultimate frequency.
- `simc_pi`: Skogestad's SIMC rule, Kc = tau / (K (tau_c + theta)),
  Ti = min(tau, 4 (tau_c + theta)), with tau_c = theta unless asked otherwise
  (a fast but robust loop: gain margin about 3, overshoot a few percent).
- `rate_feedforward_s`: the lead that makes a unity-gain loop follow a ramp without
  lag, theta + tau: what `control.rate_feedforward_s` multiplies the setpoint's rate by.

Offline code (numpy): it runs on recorded data after a test, never in the tick.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from pamd.config.stability import Plant, simc
from pamd.wire.errors import PamdError


class IdentificationError(PamdError):
    """A response that does not give a model: too small, not settled, not a step."""


@dataclass(frozen=True)
class Fopdt:
    """K e^(-theta s) / (tau s + 1), with how well it fits the data it came from."""

    gain: float
    tau_s: float
    dead_time_s: float
    rms_error: float = 0.0

    def step_response(self, t_s: ArrayLike, amplitude: float = 1.0) -> np.ndarray:
        """The model's response to a step of `amplitude` at t = 0."""
        t = np.asarray(t_s, dtype=float) - self.dead_time_s
        return np.where(t > 0.0, self.gain * amplitude * (1.0 - np.exp(-t / self.tau_s)), 0.0)

    @property
    def t63_s(self) -> float:
        return self.dead_time_s + self.tau_s


def fit_step(t_s: ArrayLike, y: ArrayLike, step_time_s: float, step_amplitude: float,
             settle_fraction: float = 0.2) -> Fopdt:
    """Fit an FOPDT model to `y(t)` after a step of `step_amplitude` at `step_time_s`.
    The last `settle_fraction` of the record after the step is taken as settled; the
    mean before the step as the start."""
    t = np.asarray(t_s, dtype=float)
    yv = np.asarray(y, dtype=float)
    if t.shape != yv.shape or t.size < 10:
        raise IdentificationError("a step response needs matching time and value arrays "
                                  "of at least 10 samples")
    if step_amplitude == 0.0:
        raise IdentificationError("the step amplitude is 0: nothing to identify")
    before = yv[t < step_time_s]
    after_t = t[t >= step_time_s] - step_time_s
    after_y = yv[t >= step_time_s]
    if before.size == 0 or after_t.size < 10:
        raise IdentificationError("the record must start before the step and run on after it")
    y0 = float(before.mean())
    tail = after_y[after_t >= (1.0 - settle_fraction) * after_t[-1]]
    y_end = float(tail.mean())
    change = y_end - y0
    noise = float(before.std()) if before.size > 2 else 0.0
    if abs(change) <= max(10.0 * noise, 1e-12):
        raise IdentificationError(f"the response changed by {change:.4g}, within the noise "
                                  f"({noise:.3g}): use a larger step")
    r = (after_y - y0) / change
    t28, t63 = _crossing(after_t, r, 0.283), _crossing(after_t, r, 0.632)
    tau = max(1.5 * (t63 - t28), 1e-6)
    theta = max(t63 - tau, 0.0)
    theta, tau = _refine(after_t, r, theta, tau)
    model = Fopdt(change / step_amplitude, tau, theta)
    resid = r - model.step_response(after_t, step_amplitude) / change
    return Fopdt(model.gain, tau, theta, float(np.sqrt(np.mean(resid * resid))) * abs(change))


def _crossing(t: np.ndarray, r: np.ndarray, level: float) -> float:
    """The first time the normalised response reaches `level` (interpolated)."""
    idx = np.nonzero(r >= level)[0]
    if idx.size == 0:
        raise IdentificationError(f"the response never reached {100 * level:.1f} % of its "
                                  "settled change: record for longer")
    k = int(idx[0])
    if k == 0:
        return float(t[0])
    t0, t1, r0, r1 = t[k - 1], t[k], r[k - 1], r[k]
    return float(t0 + (level - r0) * (t1 - t0) / (r1 - r0)) if r1 != r0 else float(t1)


def _refine(t: np.ndarray, r: np.ndarray, theta: float, tau: float) -> tuple[float, float]:
    """Gauss-Newton on (theta, tau) for the normalised response 1 - e^(-(t-theta)/tau)."""
    for _ in range(20):
        s = t - theta
        on = s > 0.0
        e = np.where(on, np.exp(-np.where(on, s, 0.0) / tau), 1.0)
        model = np.where(on, 1.0 - e, 0.0)
        d_theta = np.where(on, -e / tau, 0.0)
        d_tau = np.where(on, -e * s / (tau * tau), 0.0)
        jac = np.column_stack([d_theta, d_tau])
        res = r - model
        step, *_ = np.linalg.lstsq(jac, res, rcond=None)
        new_theta = max(theta + float(step[0]), 0.0)
        new_tau = max(tau + float(step[1]), 1e-6)
        if abs(new_theta - theta) < 1e-9 and abs(new_tau - tau) < 1e-9:
            return new_theta, new_tau
        theta, tau = new_theta, new_tau
    return theta, tau


@dataclass(frozen=True)
class RelayResult:
    """What a relay-feedback test measured."""

    ultimate_gain: float
    ultimate_period_s: float
    amplitude: float
    cycles: int


def relay_oscillation(t_s: ArrayLike, y: ArrayLike, relay_amplitude: float,
                      skip_cycles: int = 2) -> RelayResult:
    """Ultimate gain and period from the oscillation a relay test produced: the
    period from the upward crossings of the mean, the amplitude from the peaks, both
    over the cycles after the first `skip_cycles` (the transient)."""
    t = np.asarray(t_s, dtype=float)
    yv = np.asarray(y, dtype=float)
    mean = float(yv.mean())
    up = np.nonzero((yv[:-1] < mean) & (yv[1:] >= mean))[0]
    if up.size < skip_cycles + 3:
        raise IdentificationError(f"the relay test gave {up.size} cycles; it needs at least "
                                  f"{skip_cycles + 3}: run it longer or raise the amplitude")
    crossings = up[skip_cycles:]
    # each crossing's time interpolated between its two samples (not the tick's)
    y0, y1 = yv[crossings], yv[crossings + 1]
    t_cross = t[crossings] + (mean - y0) / (y1 - y0) * (t[crossings + 1] - t[crossings])
    periods = np.diff(t_cross)
    tu = float(np.median(periods))
    amps = [0.5 * float(yv[a:b].max() - yv[a:b].min()) for a, b in zip(crossings[:-1],
                                                                       crossings[1:],
                                                                       strict=True)]
    a = float(np.median(amps))
    if a <= 0.0:
        raise IdentificationError("the relay test did not oscillate")
    return RelayResult(4.0 * relay_amplitude / (math.pi * a), tu, a, len(amps))


def relay_fopdt(relay: RelayResult, static_gain: float, hysteresis: float = 0.0) -> Fopdt:
    """The FOPDT model with static gain K that oscillates as the relay test did:
    |G(j wu)| = 1 / Ku and arg G(j wu) = -pi + asin(eps / a) at wu = 2 pi / Tu (a relay
    with hysteresis eps, on an oscillation of amplitude a, lags by asin(eps / a); 0
    without)."""
    kk = static_gain * relay.ultimate_gain
    if kk <= 1.0:
        raise IdentificationError(f"K Ku = {kk:.3g} <= 1: the static gain and the relay test "
                                  "disagree (was the static gain measured on the same loop?)")
    wu = 2.0 * math.pi / relay.ultimate_period_s
    tau = math.sqrt(kk * kk - 1.0) / wu
    lag = math.asin(min(hysteresis / relay.amplitude, 1.0)) if hysteresis > 0.0 else 0.0
    theta = (math.pi - lag - math.atan(wu * tau)) / wu
    if theta <= 0.0:
        raise IdentificationError("the oscillation is faster than a first-order lag with "
                                  "dead time allows (is the hysteresis right?)")
    return Fopdt(static_gain, tau, theta)


@dataclass(frozen=True)
class PiGains:
    kp: float
    ki_per_s: float
    closed_loop_tau_s: float


def simc_pi(model: Fopdt, closed_loop_tau_s: float | None = None,
            kp_max: float = math.inf, ki_max: float = math.inf) -> PiGains:
    """Skogestad's SIMC PI gains for the model (tau_c = theta by default). With caps
    (the config's: `pamd.config.control_schema`), a closed loop that would need larger
    gains is made slower (tau_c raised) until both hold: the rule's own way to
    trade speed for gain, so its results always pass the config's checks."""
    tau_c = model.dead_time_s if closed_loop_tau_s is None else closed_loop_tau_s
    tau_c = max(tau_c, 1e-4)
    kc, ki = _simc(model, tau_c)
    for _ in range(200):
        if kc <= kp_max and ki <= ki_max:
            break
        tau_c *= 1.1
        kc, ki = _simc(model, tau_c)
    return PiGains(min(kc, kp_max), min(ki, ki_max), tau_c)


def _simc(model: Fopdt, tau_c: float) -> tuple[float, float]:
    return simc(Plant(model.gain, model.tau_s, model.dead_time_s), tau_c)


def rate_feedforward_s(model: Fopdt) -> float:
    """The lead (s) on the setpoint's rate that cancels the loop's delay for a ramp."""
    return model.dead_time_s + model.tau_s
