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
- the PID of `pamd.loop.control.pid` (pressure loop, and the position loop's `pid`): the
  integral summed each tick (ki T / (1 - z^-1)), the derivative on the measurement
  through its first-order low-pass (kd alpha (1 - z^-1) / (T (1 - (1 - alpha) z^-1)),
  alpha = T / (T + 1 / (2 pi f_c)));
- seed 003's incremental PID (`pamd.loop.control.incremental_pid`), at its own sample
  period: du = Kp (1 - z^-1) e + Ki e + Kd (1 - z^-1)^2 e, accumulated (Method 2,
  / (1 - z^-1)) or not (Method 1).

The judgement, on the loop L(z) = C(z) G(z):
- **stable**: every root of the closed loop's characteristic polynomial (P(q) = den(C)
  den(G) + num(C) num(G), q = z^-1) lies inside the unit circle; by the argument
  principle, exactly when P(e^-jw) does not wind around 0 as w goes over [0, pi] (its
  coefficients are real: the other half mirrors it), sampled finely enough that no
  term turns by more than `_MAX_PHASE_STEP_RAD` between two points (exact for the
  linear loop, whatever the margins say);
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

Pure Python (complex arithmetic on a few thousand frequencies; the polynomials are
sparse: the controller's few terms and the plant's two after its dead time), so that
what imports the config loader does not import numpy; at config time only, never on
the tick path.
"""

from __future__ import annotations

import cmath
import functools
import math
from collections.abc import Callable
from dataclasses import dataclass

#: Below these the gains are refused (see the module doc).
REFUSE_GAIN_MARGIN = 1.5
REFUSE_PHASE_MARGIN_DEG = 20.0
#: Below these they are warned about.
WARN_GAIN_MARGIN = 2.0
WARN_PHASE_MARGIN_DEG = 30.0
#: The frequencies the margins are looked for at: this many per decade over
#: `_DECADES` decades below the Nyquist frequency, and a linear grid fine enough that
#: the highest power's phase moves less than `_MAX_PHASE_STEP_RAD` between two points;
#: each crossing found between two of them is then bisected `_BISECTIONS` times.
_POINTS_PER_DECADE = 40
_BISECTIONS = 30
_DECADES = 5
_MAX_PHASE_STEP_RAD = 0.25

#: A polynomial in q = z^-1: {power: coefficient}, zero terms left out.
Poly = dict[int, float]


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


def poly(*coefficients: float) -> Poly:
    """A polynomial from its coefficients in ascending powers of q."""
    return {k: c for k, c in enumerate(coefficients) if c != 0.0}


def _mul(a: Poly, b: Poly) -> Poly:
    out: Poly = {}
    for i, x in a.items():
        for j, y in b.items():
            out[i + j] = out.get(i + j, 0.0) + x * y
    return {k: c for k, c in out.items() if c != 0.0}


def _add(a: Poly, b: Poly) -> Poly:
    out = dict(a)
    for k, c in b.items():
        out[k] = out.get(k, 0.0) + c
    return {k: c for k, c in out.items() if c != 0.0}


def _scale(a: Poly, f: float) -> Poly:
    return {k: f * c for k, c in a.items() if f * c != 0.0}


def _at(p: Poly, q: complex) -> complex:
    return sum((c * q ** k for k, c in p.items()), 0j)


def sampled_plant(plant: Plant, period_s: float) -> tuple[Poly, Poly]:
    """(numerator, denominator) of the plant behind a zero-order hold (module doc)."""
    d = int(math.floor(plant.dead_time_s / period_s + 1e-9))
    e = max(plant.dead_time_s - d * period_s, 0.0)
    a = math.exp(-period_s / plant.lag_s)
    a1 = math.exp(-(period_s - e) / plant.lag_s)
    num = {d + 1: plant.gain * (1.0 - a1), d + 2: plant.gain * (a1 - a)}
    return {k: c for k, c in num.items() if c != 0.0}, poly(1.0, -a)


def pid(kp: float, ki_per_s: float, kd_s: float, filter_hz: float, period_s: float
        ) -> tuple[Poly, Poly]:
    """`pamd.loop.control.pid.Pid` as a transfer function from the error to the output
    (without an integral, no integrator pole: ki 0 holds the integral where it is;
    without a derivative, no filter pole)."""
    t = period_s
    one = poly(1.0, -1.0)
    if kd_s == 0.0:
        if ki_per_s == 0.0:
            return poly(kp), poly(1.0)
        return poly(kp + ki_per_s * t, -kp), one
    alpha = t / (t + 1.0 / (2.0 * math.pi * filter_hz))
    filt = poly(1.0, alpha - 1.0)
    d = _scale(one, kd_s * alpha / t)
    if ki_per_s == 0.0:
        return _add(_scale(filt, kp), d), filt
    num = _add(_add(_scale(_mul(one, filt), kp), _scale(filt, ki_per_s * t)), _mul(one, d))
    return num, _mul(one, filt)


def incremental(method: int, kp: float, ki: float, kd: float) -> tuple[Poly, Poly]:
    """Seed 003's incremental PID, per sample (`pamd.loop.control.incremental_pid`)."""
    one = poly(1.0, -1.0)
    if method == 2 and ki == 0.0:  # the accumulated Kp and Kd increments: Kp e + Kd de
        return poly(kp + kd, -kd), poly(1.0)
    num = _add(_add(_scale(one, kp), poly(ki)), _scale(_mul(one, one), kd))
    return num, (one if method == 2 else poly(1.0))


def simc(plant: Plant, closed_loop_tau_s: float) -> tuple[float, float]:
    """Skogestad's SIMC PI on the plant, (Kc, Ki = Kc / Ti), Ti = min(tau, 4 (tau_c +
    theta)); `pamd.loop.control.tuning.simc_pi` and the refusals' suggestions use it."""
    kc = plant.lag_s / (abs(plant.gain) * (closed_loop_tau_s + plant.dead_time_s))
    ti = min(plant.lag_s, 4.0 * (closed_loop_tau_s + plant.dead_time_s))
    return kc, kc / ti


def margins(controller: tuple[Poly, Poly], plant: Plant, period_s: float) -> Margins:
    """The closed loop of `controller` on `plant` at `period_s` (module doc)."""
    key = (tuple(sorted(controller[0].items())), tuple(sorted(controller[1].items())),
           plant, period_s)
    return _margins(*key)


@functools.lru_cache(maxsize=256)
def _margins(c_num: tuple[tuple[int, float], ...], c_den: tuple[tuple[int, float], ...],
             plant: Plant, period_s: float) -> Margins:
    cn, cd = dict(c_num), dict(c_den)
    gn, gd = sampled_plant(plant, period_s)
    num, den = _mul(cn, gn), _mul(cd, gd)
    stable = _stable(_add(den, num))
    nyquist = math.pi / period_s
    steps = max(int((max(gn, default=0) + 2) * math.pi / _MAX_PHASE_STEP_RAD), 100)
    top = math.log10(nyquist)
    n_log = _POINTS_PER_DECADE * _DECADES
    w = sorted({10.0 ** (top - _DECADES + _DECADES * i / (n_log - 1)) for i in range(n_log)}
               | {nyquist * (i + 1) / steps for i in range(steps)})
    def at(wi: float) -> complex:
        q = cmath.exp(-1j * wi * period_s)
        return _at(num, q) / _at(den, q)

    gm, pm, at_hz = _gain_margin_and_phase(w, [at(wi) for wi in w], at)
    return Margins(stable, gm, pm, at_hz)


def _stable(char: Poly) -> bool:
    """Every root of the closed loop inside the unit circle: P(e^-jw) does not wind
    around 0 over w in [0, pi] (module doc)."""
    n = max(char, default=0)
    if n == 0:
        return True
    steps = max(int(n * math.pi / _MAX_PHASE_STEP_RAD), 64)
    scale = sum(abs(c) for c in char.values())
    turned = 0.0
    prev = _at(char, 1.0 + 0j)
    for i in range(1, steps + 1):
        value = _at(char, cmath.exp(-1j * math.pi * i / steps))
        if abs(value) <= 1e-12 * scale:  # a root on the unit circle: never settles
            return False
        turned += cmath.phase(value / prev)
        prev = value
    return abs(turned) < math.pi / 2.0


def _gain_margin_and_phase(w: list[float], loop: list[complex],
                           at: Callable[[float], complex]) -> tuple[float, float, float]:
    """(gain margin, phase margin in degrees, the gain crossover in Hz) from the loop
    on the grid `w`; each crossing the grid brackets bisected on `at`, the loop."""
    mag = [abs(v) for v in loop]
    phase = _unwrapped(loop)
    gm = math.inf
    # phase crossovers: the unwrapped phase passes -pi - 2 pi k
    turns = [math.floor((ph + math.pi) / (2.0 * math.pi)) for ph in phase]
    for k in range(len(w) - 1):
        if turns[k] != turns[k + 1]:
            level = 2.0 * math.pi * max(turns[k], turns[k + 1]) - math.pi
            ref = phase[k]

            def below(wi: float, ref: float = ref, level: float = level) -> bool:
                return ref + math.remainder(cmath.phase(at(wi)) - ref, 2.0 * math.pi) \
                    > level

            m = abs(at(_bisect(w[k], w[k + 1], below)))
            if m > 0.0:
                gm = min(gm, 1.0 / m)
    end = loop[-1]  # at the Nyquist frequency the loop is real: on -180 degrees or 0
    if end.real < 0.0 and abs(end.imag) <= 1e-9 * abs(end):
        gm = min(gm, 1.0 / abs(end))
    pm, at_hz = math.inf, math.nan
    for k in range(len(w) - 1):
        if (mag[k] - 1.0) * (mag[k + 1] - 1.0) <= 0.0 and mag[k] != mag[k + 1]:
            rising = mag[k + 1] > mag[k]

            def before(wi: float, rising: bool = rising) -> bool:
                return (abs(at(wi)) < 1.0) is rising

            wc = _bisect(w[k], w[k + 1], before)
            ph = phase[k] + math.remainder(cmath.phase(at(wc)) - phase[k], 2.0 * math.pi)
            margin = math.degrees(ph) + 180.0
            margin = (margin + 180.0) % 360.0 - 180.0
            if margin < pm:
                pm, at_hz = margin, wc / (2.0 * math.pi)
    return gm, pm, at_hz


def _bisect(lo: float, hi: float, before: Callable[[float], bool]) -> float:
    """Where `before` (true at `lo`, false at `hi`) turns, within the bracket."""
    for _ in range(_BISECTIONS):
        mid = 0.5 * (lo + hi)
        if before(mid):
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def _unwrapped(values: list[complex]) -> list[float]:
    """The phases (rad), each within pi of the one before."""
    out: list[float] = []
    for v in values:
        ph = cmath.phase(v)
        out.append(out[-1] + math.remainder(ph - out[-1], 2.0 * math.pi) if out else ph)
    return out
