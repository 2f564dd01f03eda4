"""Seed 003's two test signals of several harmonics: multisine (its "complex harmonic
signal") and multitriangle (its "complex triangular wave"). What a sum spans and how
fast it moves are found on a grid over a period, in pure Python (the io process
checks profiles without numpy).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from pamd.errors import CommandRefused
from pamd.profiles.shapes import Periodic

if TYPE_CHECKING:
    from pamd.profiles.spec import Profile, ProfilePoint, ProfileSpec


#: Seed 003's complex signals (Figs. 12-13) as pamd builds them: the paper shows them
#: but gives no formula, so pamd's default is a fundamental with its 2nd and 3rd
#: harmonics, (harmonic number, share of the half span), the shares adding to 1 so the
#: signal reaches min and max (`harmonics` in a profile changes them).
DEFAULT_HARMONICS: tuple[tuple[int, float], ...] = ((1, 0.6), (2, 0.25), (3, 0.15))
#: Points per fundamental period at which a harmonic signal's extremes are found.
HARMONIC_GRID = 4096


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
        # pure Python (load time only): this leaf module is imported by the io process,
        # which must not import numpy
        ph = [i / HARMONIC_GRID for i in range(HARMONIC_GRID)]
        val, rate = [mid] * HARMONIC_GRID, [0.0] * HARMONIC_GRID
        out = []
        for n, a in spec.harmonic_list():
            for i, x in enumerate(ph):
                val[i] += half * a * self.wave_of(n * x)
                rate[i] += half * a * n * spec.freq_hz * self.slope_of(n * x)
            out.append((n, a, min(val), max(val), max(abs(r) for r in rate)))
        return out

    def span(self, spec: ProfileSpec) -> tuple[float, float]:
        last = self.partial(spec)[-1]
        return last[2], last[3]

    def max_rate(self, spec: ProfileSpec, slew_limit: float) -> float:
        return self.partial(spec)[-1][4]

    def check_params(self, spec: ProfileSpec) -> None:
        super().check_params(spec)
        seen: set[int] = set()
        for n, a in spec.harmonic_list():
            if not (isinstance(n, int) and n >= 1) or n in seen:
                raise CommandRefused(f"{spec.kind} profile: harmonic numbers must be distinct "
                                     f"whole numbers >= 1 (got {n!r})")
            if not (math.isfinite(a) and a != 0.0):
                raise CommandRefused(f"{spec.kind} profile: harmonic {n}'s share must be a "
                                     f"finite non-zero number (got {a!r})")
            seen.add(n)

    def check_harmonics(self, spec: ProfileSpec, low: float, high: float, rate_limit: float,
                        unit: str = "bar", scale: float = 1.0, origin: str = "") -> None:
        """Refuse naming the first harmonic with which the signal leaves [low, high] or
        moves faster than `rate_limit` (values shown times `scale`, in `unit`; `origin`
        says where the limits come from)."""
        k = spec.kind
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
