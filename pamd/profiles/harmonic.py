"""Seed 003's two test signals of several harmonics: multisine (its "complex harmonic
signal") and multitriangle (its "complex triangular wave"). What a sum spans and how
fast it moves are found on a grid over a period, in pure Python (the io process
checks profiles without numpy), once per profile (`_grid_sums`, cached).

What a tick can afford bounds them (issue 47): every harmonic costs each evaluation of
the profile a sine and a cosine (or a triangle) in the tick, so a profile may have at
most `max_harmonics(period_s)` of them (a tenth of the loop's period for the
evaluations a tick makes: 83 at 1 kHz, 8 at 10 kHz), and numbers up to
MAX_HARMONIC_NUMBER (64, what the grid resolves). A 3000-harmonic plan cost 1.0-1.8 ms
a tick against a 1 ms period, after 140 s of checking; now it is refused at once.
"""

from __future__ import annotations

import functools
import math
import sys
from typing import TYPE_CHECKING

from pamd.profiles.shapes import Periodic
from pamd.wire.errors import CommandRefused

if TYPE_CHECKING:
    from pamd.profiles.spec import Profile, ProfilePoint, ProfileSpec


#: Seed 003's complex signals (Figs. 12-13) as pamd builds them: the paper shows them
#: but gives no formula, so pamd's default is a fundamental with its 2nd and 3rd
#: harmonics, (harmonic number, share of the half span), the shares adding to 1 so the
#: signal reaches min and max (`harmonics` in a profile changes them).
DEFAULT_HARMONICS: tuple[tuple[int, float], ...] = ((1, 0.6), (2, 0.25), (3, 0.15))
#: Points per fundamental period at which a harmonic signal's extremes are found.
HARMONIC_GRID = 4096
#: The highest harmonic number: the grid samples each harmonic's period at 64 points
#: at least (a sine's peak between two is missed by at most 1 - cos(pi/64), 0.12 % of
#: its share).
MAX_HARMONIC_NUMBER = HARMONIC_GRID // 64
#: What one harmonic costs one evaluation of the profile in the tick (s): a sine and a
#: cosine (a triangle for multitriangle) and the sums in CPython. bench/profile_harmonics.py
#: measures 0.2 us of CPU on the 2-core test machine; a real-clock run of 3000 harmonics
#: cost 1.0-1.8 ms a tick (0.3-0.6 us each, issue 47): the higher taken, for a slower PC.
HARMONIC_TICK_COST_S = 0.6e-6
#: Evaluations of a running profile per tick: the setpoint's, and in position mode the
#: feedforward's preview of the planned motion.
EVALUATIONS_PER_TICK = 2
#: The share of the loop's period one muscle's profile may take.
PROFILE_TICK_SHARE = 0.1


def max_harmonics(period_s: float) -> int:
    """How many harmonics a profile may have on a loop of period `period_s` (at least
    one): what PROFILE_TICK_SHARE of the period affords at EVALUATIONS_PER_TICK
    evaluations of HARMONIC_TICK_COST_S each."""
    return max(1, int(PROFILE_TICK_SHARE * period_s
                      / (EVALUATIONS_PER_TICK * HARMONIC_TICK_COST_S)))


def unit_triangle(phase: float) -> float:
    """A triangle of amplitude 1 and period 1 shaped like sin(2 pi phase): 0 at phase 0,
    rising to 1 at 1/4, -1 at 3/4."""
    ph = phase - math.floor(phase)
    if ph < 0.25:
        return 4.0 * ph
    return 2.0 - 4.0 * ph if ph < 0.75 else 4.0 * ph - 4.0


class Harmonic(Periodic):
    """mid + half * sum_n a_n w(n f t) (mid, half: of min..max; w: sin or a triangle of
    amplitude 1 starting at 0 rising). Starts at mid-range rising (as the sine). What
    it spans and how fast it moves are the sum's, found on a grid over a period; a
    sum that leaves the allowed range or outruns the rate limit is refused naming the
    first harmonic whose partial sum does (`check_harmonics`)."""


    def wave_of(self, phase: float) -> float:
        raise NotImplementedError

    def slope_of(self, phase: float) -> float:
        """d wave / d phase."""
        raise NotImplementedError

    def start_value(self, spec: ProfileSpec) -> float:
        return 0.5 * (spec.min_bar + spec.max_bar)

    def partial(self, spec: ProfileSpec) -> list[tuple[int, float, float, float, float]]:
        """Per harmonic (number, share, lowest value, highest value, steepest rate) of
        the sum up to and including it."""
        mid, half = 0.5 * (spec.min_bar + spec.max_bar), 0.5 * (spec.max_bar - spec.min_bar)
        return [(n, a, mid + half * lo, mid + half * hi, abs(half) * spec.freq_hz * rate)
                for n, a, lo, hi, rate in _grid_sums(self, spec.harmonic_list())]

    def span(self, spec: ProfileSpec) -> tuple[float, float]:
        last = self.partial(spec)[-1]
        return last[2], last[3]

    def max_rate(self, spec: ProfileSpec, slew_limit: float) -> float:
        return self.partial(spec)[-1][4]

    def check_params(self, spec: ProfileSpec) -> None:
        super().check_params(spec)
        seen: set[int] = set()
        if not spec.harmonic_list():
            raise CommandRefused(f"{spec.shape_name} profile: harmonics is empty; give at least "
                                 "one {number, share}, or leave harmonics out for the "
                                 "default (1, 2, 3 with shares 0.6, 0.25, 0.15)")
        for n, a in spec.harmonic_list():
            if not (isinstance(n, int) and 1 <= n <= MAX_HARMONIC_NUMBER) or n in seen:
                raise CommandRefused(f"{spec.shape_name} profile: harmonic numbers must be "
                                     f"distinct whole numbers from 1 to {MAX_HARMONIC_NUMBER} (got "
                                     f"{n!r})")
            if not (math.isfinite(a) and abs(a) >= sys.float_info.min):
                raise CommandRefused(f"{spec.shape_name} profile: harmonic {n}'s share must be a "
                                     f"finite non-zero number of a physical size (got {a!r})")
            seen.add(n)

    def check_cost(self, spec: ProfileSpec, period_s: float) -> None:
        """Refuse a sum of more harmonics than a tick of `period_s` affords
        (`max_harmonics`): before its span is computed, so that it costs nothing."""
        count, most = len(spec.harmonic_list()), max_harmonics(period_s)
        if count > most:
            raise CommandRefused(
                f"{spec.shape_name} profile: {count} harmonics cost a tick about "
                f"{1e6 * EVALUATIONS_PER_TICK * HARMONIC_TICK_COST_S * count:.0f} us, more "
                f"than a tenth of the loop's {1e3 * period_s:g} ms period affords: at most "
                f"{most} harmonics")

    def check_harmonics(self, spec: ProfileSpec, low: float, high: float, rate_limit: float,
                        unit: str = "bar", scale: float = 1.0, origin: str = "") -> None:
        """Refuse naming the first harmonic with which the signal leaves [low, high] or
        moves faster than `rate_limit` (values shown times `scale`, in `unit`; `origin`
        says where the limits come from)."""
        k = spec.shape_name
        for n, a, lo, hi, rate in self.partial(spec):
            what = f"{k} profile: with harmonic {n} (share {a:g})"
            if lo < low - 1e-9 or hi > high + 1e-9:
                raise CommandRefused(
                    f"{what} it spans {lo * scale:.4g}-{hi * scale:.4g} {unit}, outside the "
                    f"allowed {low * scale:.4g}-{high * scale:.4g} {unit}{origin}; lower that "
                    "harmonic's share or the span")
            if rate > rate_limit * (1 + 1e-9):
                raise CommandRefused(
                    f"{what} it needs {rate * scale:.3g} {unit}/s but the limit is "
                    f"{rate_limit * scale:.3g} {unit}/s{origin}; lower that harmonic's share, "
                    "freq_hz or the span")

    def begin(self, run: Profile, slew_limit: float) -> None:
        run.harmonics = run.spec.harmonic_list()

    def wave(self, run: Profile, tau: float, phase: float, out: ProfilePoint) -> None:
        if out.done:
            out.value, out.rate = run.lo + 0.5 * run.span, 0.0
            return
        self.harmonic_wave(run, tau, out)

    def harmonic_wave(self, run: Profile, tau: float, out: ProfilePoint) -> None:
        raise NotImplementedError


@functools.lru_cache(maxsize=64)
def _grid_sums(shape: Harmonic, harmonics: tuple[tuple[int, float], ...]
               ) -> tuple[tuple[int, float, float, float, float], ...]:
    """Per harmonic (number, share, lowest, highest, steepest) of the unit sum up to and
    including it (mid 0, half span 1, rate per unit frequency) on HARMONIC_GRID points
    of a period: what a profile's span and rate scale, computed once per set of
    harmonics (a plan's check asks three times per step). A harmonic n at grid point i
    is the shape's wave at grid point n i mod HARMONIC_GRID: looked up, not evaluated
    (pure Python, load time only: the io process imports this leaf module and must not
    import numpy)."""
    g = HARMONIC_GRID
    wave = [shape.wave_of(i / g) for i in range(g)]
    slope = [shape.slope_of(i / g) for i in range(g)]
    val, rate = [0.0] * g, [0.0] * g
    out = []
    for n, a in harmonics:
        an = a * n
        idx = [j % g for j in range(0, n * g, n)]
        val = [v + a * wave[j] for v, j in zip(val, idx, strict=True)]
        rate = [r + an * slope[j] for r, j in zip(rate, idx, strict=True)]
        out.append((n, a, min(val), max(val), max(max(rate), -min(rate))))
    return tuple(out)


class Multisine(Harmonic):
    """Seed 003's complex harmonic signal: a sum of sines."""

    name = "multisine"

    def wave_of(self, phase: float) -> float:
        return math.sin(2.0 * math.pi * phase)

    def slope_of(self, phase: float) -> float:
        return 2.0 * math.pi * math.cos(2.0 * math.pi * phase)

    def harmonic_wave(self, run: Profile, tau: float, out: ProfilePoint) -> None:
        half = 0.5 * run.span
        w0 = 2.0 * math.pi * run.freq
        v = r = acc = 0.0
        for n, a in run.harmonics:
            w = w0 * n
            s = math.sin(w * tau)
            v += a * s
            r += a * w * math.cos(w * tau)
            acc -= a * w * w * s
        out.value, out.rate, out.accel = run.lo + half * (1.0 + v), half * r, half * acc


class Multitriangle(Harmonic):
    """Seed 003's complex triangular wave: a sum of triangles."""

    name = "multitriangle"

    def wave_of(self, phase: float) -> float:
        ph = phase - math.floor(phase)
        return 4.0 * ph if ph < 0.25 else (2.0 - 4.0 * ph if ph < 0.75 else 4.0 * ph - 4.0)

    def slope_of(self, phase: float) -> float:
        ph = phase - math.floor(phase)
        return -4.0 if 0.25 <= ph < 0.75 else 4.0

    def harmonic_wave(self, run: Profile, tau: float, out: ProfilePoint) -> None:
        half = 0.5 * run.span
        v = r = 0.0
        for n, a in run.harmonics:
            ph = n * run.freq * tau
            v += a * unit_triangle(ph)
            f = ph - math.floor(ph)
            r += a * n * run.freq * (-4.0 if 0.25 <= f < 0.75 else 4.0)
        out.value, out.rate = run.lo + half * (1.0 + v), half * r
