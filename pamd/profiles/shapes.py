"""`Shape`, what every profile shape is, and the plain shapes: constant, ramp, step
(a square wave whose edges are ramps), sine (the seeds' (p/2) sin + p/2: starts at
mid-range rising with maximum slope) and triangle. Each samples without allocating
(it runs in the tick).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, ClassVar

from pamd.wire.errors import CommandRefused
from pamd.wire.shape_names import SHAPE_PARAMS

if TYPE_CHECKING:
    from pamd.profiles.spec import Profile, ProfilePoint, ProfileSpec


class Shape:
    """A profile's shape after its lead-in: what it reads of a `ProfileSpec`, what it
    refuses, the values it spans and how fast, and its evaluator (`sample`, which
    allocates nothing: it runs in the tick)."""

    name: ClassVar[str]
    periodic: ClassVar[bool] = False
    """Spans min_bar..max_bar and repeats at freq_hz for `cycles` cycles."""

    @property
    def params(self) -> tuple[str, ...]:
        """The ProfileSpec fields the shape reads (beyond lead_in_bar_per_s), as
        declared in `pamd.wire.shape_names.SHAPE_PARAMS`."""
        return SHAPE_PARAMS[self.name]

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
        k = spec.shape_name
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


class Triangle(Periodic):
    name = "triangle"

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
