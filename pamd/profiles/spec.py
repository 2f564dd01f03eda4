"""What an operator asks for (`ProfileSpec`, checked before anything moves), the
registry of the shapes (`SHAPES`) and a running profile (`Profile`: a lead-in ramp
from the present value to the shape's start, then the shape, sampled in the tick
without allocating).
"""

from __future__ import annotations

import dataclasses
import math
import sys
from collections.abc import Collection
from dataclasses import dataclass

from pamd.profiles.harmonic import DEFAULT_HARMONICS, Harmonic, Multisine, Multitriangle
from pamd.profiles.shapes import Constant, Ramp, Shape, Sine, Step, Triangle
from pamd.wire.errors import CommandRefused
from pamd.wire.shape_names import SHAPE_NAMES, ShapeName, shapes_text

_IMPLEMENTED: dict[str, Shape] = {s.name: s for s in (
    Constant(), Step(), Ramp(), Sine(), Triangle(), Multisine(), Multitriangle())}
if set(_IMPLEMENTED) != set(SHAPE_NAMES):  # a shape declared or implemented, not both
    raise ImportError(f"profile shapes implemented {sorted(_IMPLEMENTED)} but declared in "
                      f"pamd.wire.shape_names {sorted(SHAPE_NAMES)}")
SHAPES: dict[str, Shape] = {name: _IMPLEMENTED[name] for name in SHAPE_NAMES}
"""Every profile shape by name, in `pamd.wire.shape_names`' order: a new shape is its name
and fields in `pamd.wire.shape_names.SHAPE_PARAMS` and one `Shape` subclass added above (a
shape declared there and not here, or here and not there, fails at import)."""


def shape_of(name: str) -> Shape:
    """The registered shape so named; CommandRefused naming the known ones."""
    shape = SHAPES.get(name)
    if shape is None:
        raise CommandRefused(f"unknown profile shape {name!r}; use {shapes_text()}")
    return shape


#: Longest profile (s): one cycle or all of them (30 days, as a time in the config,
#: `pamd.wire.schema.domains`).
MAX_PROFILE_S = 30 * 86400.0


@dataclass(frozen=True)
class ProfileSpec:
    """What an operator asks for; validated by `check` before anything moves. An
    unknown `shape_name` is refused when the spec is made (CommandRefused)."""

    shape_name: ShapeName = "sine"
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
        shape_of(self.shape_name)

    def harmonic_list(self) -> tuple[tuple[int, float], ...]:
        """The harmonics a multisine or multitriangle sums (the default if none given)."""
        if self.harmonics is None:
            return DEFAULT_HARMONICS
        return tuple((n, float(a)) for n, a in self.harmonics)

    @property
    def shape(self) -> Shape:
        return SHAPES[self.shape_name]

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

    def check_reads(self, given: Collection[str] = ()) -> None:
        """Refuse (CommandRefused) a parameter given that the shape does not read: it
        would be ignored, and the run would not be the one asked for (a constant with
        cycles holds until stopped; a sine with to_bar never goes there). `given`: the
        parameters with a default that the caller knows were given (`pamd run
        --profile constant --freq-hz 2`)."""
        unread = [n for n in (*OPTIONAL_PARAMS, *(g for g in given if g not in OPTIONAL_PARAMS))
                  if (getattr(self, n) is not None or n in given)
                  and n not in self.shape.params and n != "lead_in_bar_per_s"]
        if unread:
            raise CommandRefused(
                f"a {self.shape_name} profile does not read {' or '.join(unread)} (it reads "
                f"{', '.join(self.shape.params)}); leave {'them' if len(unread) > 1 else 'it'}"
                " out" + ("; a constant holds until stopped, or for its duration_s (pamd run: "
                          "the run's --duration)" if self.shape_name == "constant" else ""))

    def check_values(self) -> None:
        """Refuse (CommandRefused) a parameter that is no physical number: not finite, or
        subnormal (nonzero below 2.2e-308, such as 1e-320: no quantity is that small,
        and arithmetic on it loses its precision silently), as the command and config
        schemas refuse them (`pamd.wire.schema.domains`), for whatever built this spec (the
        harmonics' shares: `Harmonic.check_params`)."""
        for name in _FLOAT_PARAMS:
            v = getattr(self, name)
            if v is not None and not _physical(v):
                raise CommandRefused(f"{self.shape_name} profile: {name} {v!r} is not a physical "
                                     "number (finite, 0 or at least 2.2e-308 in magnitude)")

    def check(self, low_bar: float, high_bar: float, slew_limit: float,
              period_s: float = 1e-3) -> None:
        """Refuse (CommandRefused) a profile outside [low, high] or faster than the slew
        limit, or costing a tick of the loop's `period_s` more than it affords (the
        harmonics), saying which parameter to change."""
        k = self.shape_name
        shape = self.shape
        self.check_values()
        self.check_reads()
        shape.check_params(self)
        if isinstance(shape, Harmonic):
            shape.check_cost(self, period_s)
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
        k = self.shape_name
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
        self.shape_name = spec.shape_name
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


#: ProfileSpec's parameters that default to None ("not given"): one given to a shape that
#: does not read it (`pamd.wire.shape_names.SHAPE_PARAMS`) is refused, not ignored.
OPTIONAL_PARAMS: tuple[str, ...] = tuple(
    f.name for f in dataclasses.fields(ProfileSpec) if f.default is None)
#: ProfileSpec's number parameters (`check_values`)
_FLOAT_PARAMS: tuple[str, ...] = tuple(
    f.name for f in dataclasses.fields(ProfileSpec) if f.type in ("float", "float | None"))


def _physical(v: float) -> bool:
    """Finite, and 0 or of a normal float's size."""
    return math.isfinite(v) and (v == 0.0 or abs(v) >= sys.float_info.min)
