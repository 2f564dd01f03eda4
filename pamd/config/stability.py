"""Gains judged against stability: the closed loop of a controller and the muscle's
identified plant, as the tick runs it (discrete, at the loop's rate), before anything
moves.

The plant is a first-order-plus-dead-time model, K e^(-theta s) / (tau s + 1), what
`pamd tune` fits to recorded steps (`control.plant`: regulator setpoint -> measured
pressure; `control.position.plant`: pressure setpoint -> measured length; each
muscle's own in `muscles[].control`), or, where none was measured, the stated default
(`pamd.config.control_schema.DEFAULT_*_PLANT`: the simulated rig's measured response).
Sampled through the tick's zero-order hold at the period T, with theta = d T + e
(0 <= e < T), a = e^(-T / tau) and a' = e^(-(T - e) / tau), it is exactly

    G(z) = K z^-(d+1) ((1 - a') + (a' - a) z^-1) / (1 - a z^-1)

(the modified z-transform: the response a command written at one tick has on the
readings of the ticks after it, which is what the recorded steps measured).

The controllers are those of the tick, term for term:
- the PID of `pamd.control.pid` (pressure loop, and the position loop's `pid`): the
  integral summed each tick (ki T / (1 - z^-1)), the derivative on the measurement
  through its first-order low-pass (kd alpha (1 - z^-1) / (T (1 - (1 - alpha) z^-1)),
  alpha = T / (T + 1 / (2 pi f_c)));
- seed 003's incremental PID (`pamd.control.incremental_pid`), at its own sample
  period: du = Kp (1 - z^-1) e + Ki e + Kd (1 - z^-1)^2 e, accumulated (Method 2,
  / (1 - z^-1)) or not (Method 1).

The judgement, on the loop L(z) = C(z) G(z):
- **stable**: every root of the closed loop's characteristic polynomial lies inside
  the unit circle (exact for the linear loop, whatever the margins say);
- **gain margin**: by how much the loop gain may grow before the loop oscillates
  (1 / |L| where the phase is -180 degrees, the smallest over every such frequency);
- **phase margin**: how much more lag (dead time) the loop stands where |L| = 1
  (180 degrees + the phase there, the smallest over every such frequency).
Refused below `REFUSE_GAIN_MARGIN` or `REFUSE_PHASE_MARGIN_DEG` (or unstable): the
identified plant is never exact (one muscle's step fits spread by about 10 % in gain
and 50 % in lag between up and down steps, and the plant moves with the pressure and
the load), and a loop that a 50 % gain error or 20 degrees of lag turns into an
oscillation is not one the rig should run. Warned below `WARN_GAIN_MARGIN` or
`WARN_PHASE_MARGIN_DEG`, the usual floor of a robust loop (Astrom and Hagglund: gain
margin 2-5, phase margin 30-60 degrees). SIMC, what `pamd tune` derives, has about 3
and 45-60 degrees.

Offline (numpy), at config time only: never on the tick path.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

#: Below these the gains are refused (see the module doc).
REFUSE_GAIN_MARGIN = 1.5
REFUSE_PHASE_MARGIN_DEG = 20.0
#: Below these they are warned about.
WARN_GAIN_MARGIN = 2.0
WARN_PHASE_MARGIN_DEG = 30.0
#: The frequencies the margins are looked for at: this many per decade over
#: `_DECADES` decades below the Nyquist frequency, and a linear grid fine enough that
#: the dead time's phase moves less than `_MAX_PHASE_STEP_RAD` between two points.
_POINTS_PER_DECADE = 200
_DECADES = 5
_MAX_PHASE_STEP_RAD = 0.25

Poly = np.ndarray  # coefficients in ascending powers of z^-1


@dataclass(frozen=True)
class Plant:
    """K e^(-theta s) / (tau s + 1); `gain` in the loop's units (bar/bar, mm/bar)."""

    gain: float
    lag_s: float
    dead_time_s: float

    def settle_s(self) -> float:
        """How long a step takes to be answered to 95 %: dead time + 3 lags."""
        return self.dead_time_s + 3.0 * self.lag_s


@dataclass(frozen=True)
class Margins:
    """How far a closed loop is from oscillating."""

    stable: bool
    gain_margin: float  # inf: no phase crossover
    phase_margin_deg: float  # inf: |L| never reaches 1
    crossover_hz: float  # where |L| = 1 (nan: nowhere)

    def text(self) -> str:
        gm = "no phase crossover" if math.isinf(self.gain_margin) else \
            f"{self.gain_margin:.3g} ({20.0 * math.log10(self.gain_margin):+.1f} dB)"
        pm = "no gain crossover" if math.isinf(self.phase_margin_deg) else \
            f"{self.phase_margin_deg:.3g} deg at {self.crossover_hz:.3g} Hz"
        return (("" if self.stable else "UNSTABLE: ") +
                f"gain margin {gm}, phase margin {pm}")

    def refused(self) -> bool:
        return not self.stable or self.gain_margin < REFUSE_GAIN_MARGIN or \
            self.phase_margin_deg < REFUSE_PHASE_MARGIN_DEG

    def warned(self) -> bool:
        return self.gain_margin < WARN_GAIN_MARGIN or \
            self.phase_margin_deg < WARN_PHASE_MARGIN_DEG


def sampled_plant(plant: Plant, period_s: float) -> tuple[Poly, Poly]:
    """(numerator, denominator) of the plant behind a zero-order hold (module doc)."""
    d = int(math.floor(plant.dead_time_s / period_s + 1e-9))
    e = max(plant.dead_time_s - d * period_s, 0.0)
    a = math.exp(-period_s / plant.lag_s)
    a1 = math.exp(-(period_s - e) / plant.lag_s)
    num = np.zeros(d + 3)
    num[d + 1], num[d + 2] = plant.gain * (1.0 - a1), plant.gain * (a1 - a)
    return num, np.array([1.0, -a])


def pid(kp: float, ki_per_s: float, kd_s: float, filter_hz: float, period_s: float
        ) -> tuple[Poly, Poly]:
    """`pamd.control.pid.Pid` as a transfer function from the error to the output
    (without an integral, no integrator pole: ki 0 holds the integral where it is;
    without a derivative, no filter pole)."""
    t = period_s
    if kd_s == 0.0:
        if ki_per_s == 0.0:
            return np.array([kp]), np.array([1.0])
        return np.array([kp + ki_per_s * t, -kp]), np.array([1.0, -1.0])
    alpha = t / (t + 1.0 / (2.0 * math.pi * filter_hz))
    one = np.array([1.0, -1.0])
    filt = np.array([1.0, alpha - 1.0])
    d = kd_s * alpha / t
    if ki_per_s == 0.0:
        return kp * filt + d * one, filt
    num = kp * np.convolve(one, filt) + ki_per_s * t * np.append(filt, 0.0) + \
        d * np.convolve(one, one)
    return num, np.convolve(one, filt)


def incremental(method: int, kp: float, ki: float, kd: float) -> tuple[Poly, Poly]:
    """Seed 003's incremental PID, per sample (`pamd.control.incremental_pid`)."""
    one = np.array([1.0, -1.0])
    if method == 2 and ki == 0.0:  # the accumulated Kp and Kd increments: Kp e + Kd de
        return np.array([kp + kd, -kd]), np.array([1.0])
    num = kp * np.append(one, 0.0) + ki * np.array([1.0, 0.0, 0.0]) + \
        kd * np.convolve(one, one)
    return num, (one if method == 2 else np.array([1.0]))


def simc(plant: Plant, closed_loop_tau_s: float) -> tuple[float, float]:
    """Skogestad's SIMC PI on the plant, (Kc, Ki = Kc / Ti), Ti = min(tau, 4 (tau_c +
    theta)); `pamd.control.tuning.simc_pi` and the refusals' suggestions use it."""
    kc = plant.lag_s / (abs(plant.gain) * (closed_loop_tau_s + plant.dead_time_s))
    ti = min(plant.lag_s, 4.0 * (closed_loop_tau_s + plant.dead_time_s))
    return kc, kc / ti


def margins(controller: tuple[Poly, Poly], plant: Plant, period_s: float) -> Margins:
    """The closed loop of `controller` on `plant` at `period_s` (module doc)."""
    key = (tuple(controller[0]), tuple(controller[1]), plant, period_s)
    return _margins(*key)


@functools.lru_cache(maxsize=256)
def _margins(c_num: tuple[float, ...], c_den: tuple[float, ...], plant: Plant,
             period_s: float) -> Margins:
    cn, cd = np.array(c_num), np.array(c_den)
    gn, gd = sampled_plant(plant, period_s)
    char = np.trim_zeros(_add(np.convolve(cd, gd), np.convolve(cn, gn)), "b")
    roots = np.roots(char) if char.size > 1 else np.array([])
    stable = bool(np.all(np.abs(roots) < 1.0 - 1e-9))
    nyquist = math.pi / period_s
    steps = max(int((gn.size + 1) * math.pi / _MAX_PHASE_STEP_RAD), 100)
    w = np.union1d(np.logspace(math.log10(nyquist) - _DECADES, math.log10(nyquist),
                               _POINTS_PER_DECADE * _DECADES),
                   np.linspace(nyquist / steps, nyquist, steps))
    q = np.exp(-1j * w * period_s)
    loop = _at(cn, q) * _at(gn, q) / (_at(cd, q) * _at(gd, q))
    gm, pm, at_hz = _gain_margin_and_phase(w, loop)
    return Margins(stable, float(gm), float(pm), float(at_hz))


def _add(a: Poly, b: Poly) -> Poly:
    out = np.zeros(max(a.size, b.size))
    out[:a.size] += a
    out[:b.size] += b
    return out


def _at(p: Poly, q: np.ndarray) -> np.ndarray:
    """p(q) for coefficients in ascending powers of q; the plant's leading zeros (its
    dead time) as a power of q."""
    nz = np.flatnonzero(p)
    if nz.size == 0:
        return np.zeros_like(q)
    lead = int(nz[0])
    out = np.zeros_like(q)
    for c in p[lead:][::-1]:
        out = out * q + c
    return out * q ** lead if lead else out


def _gain_margin_and_phase(w: np.ndarray, loop: np.ndarray) -> tuple[float, float, float]:
    mag = np.abs(loop)
    phase = np.degrees(np.unwrap(np.angle(loop)))
    gm = math.inf
    # phase crossovers: the unwrapped phase passes -180 - 360 k
    turns = np.floor((phase + 180.0) / 360.0)
    for k in np.flatnonzero(np.diff(turns) != 0):
        level = 360.0 * max(turns[k], turns[k + 1]) - 180.0
        f = (level - phase[k]) / (phase[k + 1] - phase[k])
        m = mag[k] + f * (mag[k + 1] - mag[k])
        if m > 0.0:
            gm = min(gm, 1.0 / m)
    end = loop[-1]  # at the Nyquist frequency the loop is real: on -180 degrees or 0
    if end.real < 0.0 and abs(end.imag) <= 1e-9 * abs(end):
        gm = min(gm, 1.0 / abs(end))
    pm, at_hz = math.inf, math.nan
    for k in np.flatnonzero(np.diff(np.sign(mag - 1.0)) != 0):
        f = (1.0 - mag[k]) / (mag[k + 1] - mag[k])
        ph = phase[k] + f * (phase[k + 1] - phase[k])
        margin = (ph + 180.0) % 360.0
        margin = margin - 360.0 if margin > 180.0 else margin
        if margin < pm:
            pm, at_hz = margin, (w[k] + f * (w[k + 1] - w[k])) / (2.0 * math.pi)
    return gm, pm, at_hz
