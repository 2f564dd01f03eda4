"""Reference profiles for a pressure (or length) setpoint, and the registry of their
shapes.

Every profile starts with a lead-in ramp from the present value to its own start
value, then runs its shape: constant, step (a square wave whose edges are ramps),
ramp, sine (the seeds' (p/2) sin + p/2: starts at mid-range rising with maximum
slope), triangle, or seed 003's two test signals of several harmonics, multisine
(its "complex harmonic signal") and multitriangle (its "complex triangular wave"),
for a number of cycles (None: until stopped). `sample(t)` sets
`value`, `rate`, `cycle` and `done` without allocating; `check()` refuses a
profile that is faster than the slew limit or leaves the allowed range.

A shape is one `Shape` subclass, registered in `SHAPES`: its name, the `ProfileSpec`
fields it reads, its own checks and its evaluator. The command schema, experiment
plans, `pamd run --profile` and length profiles take their kinds from `SHAPES`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar, Literal

from pamd.errors import CommandRefused


class Shape:
    """A profile's shape after its lead-in: what it reads of a `ProfileSpec`, what it
    refuses, the values it spans and how fast, and its evaluator (`sample`, which
    allocates nothing: it runs in the tick)."""

    name: ClassVar[str]
    params: ClassVar[tuple[str, ...]]
    """The ProfileSpec fields the shape reads (beyond lead_in_bar_per_s)."""
    periodic: ClassVar[bool] = False
    """Spans min_bar..max_bar and repeats at freq_hz for `cycles` cycles."""

    def start_value(self, spec: ProfileSpec) -> float:
        """Where the shape starts (the lead-in ramps there); NaN: where the value is."""
        return spec.min_bar

    def span(self, spec: ProfileSpec) -> tuple[float, float]:
        """The lowest and highest value the shape reaches (after `check_params`)."""
        return spec.min_bar, spec.max_bar

    def max_rate(self, spec: ProfileSpec, slew_limit: float) -> float:
        """The steepest slope of the shape itself (not the lead-in)."""
        return 0.0

    def check_params(self, spec: ProfileSpec) -> None:
        """Refuse (CommandRefused) parameters the shape cannot run."""

    def begin(self, run: Profile, slew_limit: float) -> None:
        """Fill the running profile's shape-specific constants (before any tick)."""

    def total_s(self, run: Profile) -> float | None:
        """The shape's duration after the lead-in; None: until stopped."""
        return None

    def sample(self, run: Profile, tau: float, out: ProfilePoint) -> None:
        """Set out.value, out.rate, out.accel (and out.done, out.cycle) at `tau` s after
        the lead-in; `run` gives the constants (`out` is `run` itself when it runs)."""
        raise NotImplementedError


class Constant(Shape):
    name = "constant"
    params = ("to_bar", "duration_s")

    def start_value(self, spec: ProfileSpec) -> float:
        return spec.to_bar if spec.to_bar is not None else spec.min_bar

    def span(self, spec: ProfileSpec) -> tuple[float, float]:
        v = self.start_value(spec)
        return v, v

    def total_s(self, run: Profile) -> float | None:
        return run.spec.duration_s

    def sample(self, run: Profile, tau: float, out: ProfilePoint) -> None:
        out.value, out.rate, out.accel = run.start_bar, 0.0, 0.0
        d = run.spec.duration_s
        out.done = d is not None and tau >= d


class Ramp(Shape):
    name = "ramp"
    params = ("to_bar", "rate_bar_per_s")

    def start_value(self, spec: ProfileSpec) -> float:
        return math.nan  # starts where it is

    def span(self, spec: ProfileSpec) -> tuple[float, float]:
        v = spec.to_bar if spec.to_bar is not None else spec.min_bar
        return v, v

    def max_rate(self, spec: ProfileSpec, slew_limit: float) -> float:
        return spec.rate_bar_per_s if spec.rate_bar_per_s is not None else 0.5 * slew_limit

    def check_params(self, spec: ProfileSpec) -> None:
        if spec.to_bar is None:
            raise CommandRefused("ramp profile: give to_bar, the value to ramp to")

    def begin(self, run: Profile, slew_limit: float) -> None:
        spec = run.spec
        rate = spec.rate_bar_per_s or 0.5 * slew_limit
        assert spec.to_bar is not None
        run.start_bar = run.from_bar
        run.ramp_rate = math.copysign(rate, spec.to_bar - run.from_bar)
        run.ramp_s = abs(spec.to_bar - run.from_bar) / rate

    def total_s(self, run: Profile) -> float | None:
        return run.ramp_s

    def sample(self, run: Profile, tau: float, out: ProfilePoint) -> None:
        out.accel = 0.0
        if tau >= run.ramp_s:
            out.value, out.rate, out.done = run.spec.to_bar, 0.0, True  # type: ignore[assignment]
        else:
            out.value, out.rate = run.start_bar + run.ramp_rate * tau, run.ramp_rate


class Periodic(Shape):
    """A wave between min_bar and max_bar at freq_hz, for `cycles` cycles; at its end
    it holds the value its phase 0 has."""

    periodic = True

    def check_params(self, spec: ProfileSpec) -> None:
        k = spec.kind
        if not spec.max_bar > spec.min_bar:
            raise CommandRefused(f"{k} profile: max_bar ({spec.max_bar}) must exceed "
                                 f"min_bar ({spec.min_bar})")
        if not spec.freq_hz > 0:
            raise CommandRefused(f"{k} profile: freq_hz must be positive")

    def total_s(self, run: Profile) -> float | None:
        cycles = run.spec.cycles
        return None if cycles is None else cycles * run.period_s

    def sample(self, run: Profile, tau: float, out: ProfilePoint) -> None:
        cycles = run.spec.cycles
        cyc = int(tau * run.freq)
        if cycles is not None and cyc >= cycles:
            out.done = True
            out.cycle = cycles
            tau = cycles * run.period_s  # hold the end value
        else:
            out.cycle = cyc
        phase = tau * run.freq - int(tau * run.freq)
        if out.done:
            phase = 0.0
        out.accel = 0.0
        self.wave(run, tau, phase, out)

    def wave(self, run: Profile, tau: float, phase: float, out: ProfilePoint) -> None:
        """Set out.value and out.rate (a smooth shape also out.accel) at `tau` (phase:
        the fraction of the cycle)."""
        raise NotImplementedError


class Step(Periodic):
    """Low half period, high half period, edges ramped (rise_s, default at the slew
    limit)."""

    name = "step"
    params = ("min_bar", "max_bar", "freq_hz", "cycles", "rise_s")

    def max_rate(self, spec: ProfileSpec, slew_limit: float) -> float:
        return (spec.max_bar - spec.min_bar) / spec.edge_s(slew_limit)

    def begin(self, run: Profile, slew_limit: float) -> None:
        run.edge_s = run.spec.edge_s(slew_limit)

    def wave(self, run: Profile, tau: float, phase: float, out: ProfilePoint) -> None:
        t_in = phase / run.freq
        half = 0.5 * run.period_s
        e = run.edge_s
        r = run.span / e if e > 0 else 0.0
        if t_in < half:
            if t_in < e and (out.cycle > 0 or out.done):
                out.value, out.rate = run.hi - r * t_in, -r
            else:
                out.value, out.rate = run.lo, 0.0
        elif t_in - half < e:
            out.value, out.rate = run.lo + r * (t_in - half), r
        else:
            out.value, out.rate = run.hi, 0.0
        if out.done:
            out.value, out.rate = run.hi, 0.0


class Sine(Periodic):
    """(p/2) sin + p/2 over the span: starts at mid-range rising with maximum slope."""

    name = "sine"
    params = ("min_bar", "max_bar", "freq_hz", "cycles")

    def start_value(self, spec: ProfileSpec) -> float:
        return 0.5 * (spec.min_bar + spec.max_bar)

    def max_rate(self, spec: ProfileSpec, slew_limit: float) -> float:
        return math.pi * spec.freq_hz * (spec.max_bar - spec.min_bar)

    def wave(self, run: Profile, tau: float, phase: float, out: ProfilePoint) -> None:
        w = 2.0 * math.pi * run.freq
        s = math.sin(w * tau)
        out.value = run.lo + 0.5 * run.span * (1.0 + s)
        if out.done:
            out.rate = 0.0
        else:
            out.rate = 0.5 * run.span * w * math.cos(w * tau)
            out.accel = -0.5 * run.span * w * w * s


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

    params = ("min_bar", "max_bar", "freq_hz", "cycles", "harmonics")

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


class Triangle(Periodic):
    name = "triangle"
    params = ("min_bar", "max_bar", "freq_hz", "cycles")

    def max_rate(self, spec: ProfileSpec, slew_limit: float) -> float:
        return 2.0 * (spec.max_bar - spec.min_bar) * spec.freq_hz

    def wave(self, run: Profile, tau: float, phase: float, out: ProfilePoint) -> None:
        slope = 2.0 * run.span * run.freq
        if phase < 0.5:
            out.value, out.rate = run.lo + slope * phase / run.freq, slope
        else:
            out.value, out.rate = run.hi - slope * (phase - 0.5) / run.freq, -slope
        if out.done:
            out.rate = 0.0


SHAPES: dict[str, Shape] = {s.name: s for s in (Constant(), Step(), Ramp(), Sine(), Triangle(),
                                                 Multisine(), Multitriangle())}
"""Every profile shape by name: a new shape is one `Shape` subclass added here."""

SHAPE_NAMES: tuple[str, ...] = tuple(SHAPES)

if TYPE_CHECKING:
    ProfileKind = str
else:  # the config engine validates a plan's `kind` against the registered names
    ProfileKind = Literal[SHAPE_NAMES]


def kinds_text() -> str:
    """The shapes for an operator: 'constant, step, ramp, sine or triangle'."""
    return ", ".join(SHAPE_NAMES[:-1]) + " or " + SHAPE_NAMES[-1]


def kinds_reading(param: str, sep: str = ", ") -> str:
    """The shapes that read ProfileSpec field `param` (help texts)."""
    return sep.join(s.name for s in SHAPES.values() if param in s.params)


def shape_of(kind: str) -> Shape:
    """The registered shape so named; CommandRefused naming the known ones."""
    shape = SHAPES.get(kind)
    if shape is None:
        raise CommandRefused(f"unknown profile kind {kind!r}; use {kinds_text()}")
    return shape


#: Longest profile (s): one cycle or all of them (30 days, as a time in the config,
#: `pamd.schema.domains`).
MAX_PROFILE_S = 30 * 86400.0


@dataclass(frozen=True)
class ProfileSpec:
    """What an operator asks for; validated by `check` before anything moves. An
    unknown `kind` is refused when the spec is made (CommandRefused)."""

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
    # multisine, multitriangle: (harmonic number, share of the half span); None: the
    # default (DEFAULT_HARMONICS)
    harmonics: tuple[tuple[int, float], ...] | None = None

    def __post_init__(self) -> None:
        shape_of(self.kind)

    def harmonic_list(self) -> tuple[tuple[int, float], ...]:
        """The harmonics a multisine or multitriangle sums (the default if none given)."""
        if self.harmonics is None:
            return DEFAULT_HARMONICS
        return tuple((n, float(a)) for n, a in self.harmonics)

    @property
    def shape(self) -> Shape:
        return SHAPES[self.kind]

    def start_value(self) -> float:
        return self.shape.start_value(self)

    def span(self) -> tuple[float, float]:
        """The lowest and highest value the profile's shape reaches."""
        return self.shape.span(self)

    def shape_max_rate(self, slew_limit: float) -> float:
        """Steepest slope of the shape itself (not the lead-in)."""
        return self.shape.max_rate(self, slew_limit)

    def edge_s(self, slew_limit: float) -> float:
        if self.rise_s is not None:
            return self.rise_s
        return (self.max_bar - self.min_bar) / slew_limit

    def check(self, low_bar: float, high_bar: float, slew_limit: float) -> None:
        """Refuse (CommandRefused) a profile outside [low, high] or faster than the slew
        limit, saying which parameter to change."""
        k = self.kind
        shape = self.shape
        shape.check_params(self)
        if isinstance(shape, Harmonic):
            shape.check_harmonics(self, low_bar, high_bar, slew_limit)
        lo, hi = self.span()
        if self.cycles is not None and self.cycles < 1:
            raise CommandRefused(f"{k} profile: cycles must be at least 1")
        self.check_duration()
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

    def check_duration(self) -> None:
        """Refuse a profile whose one cycle, or whole run, is longer than
        MAX_PROFILE_S (a frequency of 1e-300 Hz, a billion cycles): its times would not
        even be finite, and no rig runs unattended that long."""
        k = self.kind
        if self.shape.periodic:
            period = 1.0 / self.freq_hz if self.freq_hz > 0 else math.inf
            if not period <= MAX_PROFILE_S:
                raise CommandRefused(f"{k} profile: one cycle at freq_hz {self.freq_hz:g} "
                                     f"lasts longer than {MAX_PROFILE_S / 86400:g} days; "
                                     "raise freq_hz")
            if self.cycles is not None and not self.cycles * period <= MAX_PROFILE_S:
                raise CommandRefused(
                    f"{k} profile: {self.cycles} cycles at {self.freq_hz:g} Hz last "
                    f"{self.cycles * period / 86400:.3g} days, longer than "
                    f"{MAX_PROFILE_S / 86400:g} days; run fewer cycles (or several plans)")
        d = self.duration_s
        if d is not None and not d <= MAX_PROFILE_S:
            raise CommandRefused(f"{k} profile: duration_s {d:g} s is longer than "
                                 f"{MAX_PROFILE_S / 86400:g} days")

    def shape_period_s(self) -> float:
        return 1.0 / self.freq_hz if self.shape.periodic else 0.0


class ProfilePoint:
    """A profile's value, rate (per s) and acceleration (per s^2) at one time, with its
    cycle and whether it has ended: what `Profile.evaluate` writes (a preview of the
    profile's future, leaving the running profile untouched). Preallocate one and
    reuse it: evaluating allocates nothing."""

    __slots__ = ("value", "rate", "accel", "cycle", "done")

    def __init__(self) -> None:
        self.value = math.nan
        self.rate = self.accel = 0.0
        self.cycle = 0
        self.done = False


class Profile(ProfilePoint):
    """A running profile. Create with the spec, the present value and the start time.
    `sample(t)` moves its own point (value, rate, accel, cycle, done) to `t`;
    `evaluate(t, point)` writes another point and changes nothing here."""

    def __init__(self, spec: ProfileSpec, t0_s: float, present_bar: float,
                 slew_limit: float) -> None:
        self.spec = spec
        self.kind = spec.kind
        self.shape = spec.shape
        self.t0_s = t0_s
        self.from_bar = present_bar
        self.start_bar = spec.start_value()
        self.lo, self.hi = spec.min_bar, spec.max_bar
        self.span = spec.max_bar - spec.min_bar
        self.freq = spec.freq_hz
        self.period_s = spec.shape_period_s()
        self.edge_s = 0.0
        self.ramp_rate = self.ramp_s = 0.0
        self.harmonics: tuple[tuple[int, float], ...] = ()
        self.shape.begin(self, slew_limit)
        self.lead_in_s = abs(self.start_bar - present_bar) / spec.lead_in_bar_per_s
        self.lead_rate = math.copysign(spec.lead_in_bar_per_s, self.start_bar - present_bar)
        self.value = present_bar
        self.rate = self.accel = 0.0
        self.cycle = 0
        self.done = False

    def total_s(self) -> float | None:
        """Lead-in plus shape duration; None if it runs until stopped."""
        shape_s = self.shape.total_s(self)
        return None if shape_s is None else self.lead_in_s + shape_s

    def sample(self, t_s: float) -> None:
        """Move the profile to `t_s` (the tick's present)."""
        self.evaluate(t_s, self)

    def evaluate(self, t_s: float, out: ProfilePoint) -> None:
        """The profile at `t_s` into `out` (no allocation; `out` is not this profile:
        nothing of the running profile changes)."""
        tau = t_s - self.t0_s
        if tau < self.lead_in_s:
            out.value = self.from_bar + self.lead_rate * tau
            out.rate = self.lead_rate
            out.accel = 0.0
            out.cycle = 0
            out.done = False
            return
        if out is not self:
            out.done = False
        self.shape.sample(self, tau - self.lead_in_s, out)
