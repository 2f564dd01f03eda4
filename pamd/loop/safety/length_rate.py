"""The fastest length target a muscle can follow (`control.position.max_rate_per_s`
when the config leaves it `null`, its default): derived from what the regulator and
the muscle can do, not chosen.

A length target moving at r contraction/s asks the pressure to move at
r / (dcontraction/dpressure): the muscle's stiffness in pressure, at the configured
load, from its force model (`muscles[].force_model`). Two things bound it:

1. **The slew limit.** The pressure setpoint never moves faster than
   `control.slew_limit_bar_per_s` (the position loop's output is slew-limited too),
   so r may be at most slew x dcontraction/dpressure, at the stiffest place of the
   muscle's usable range (the least contraction per bar: with a load, near the top
   pressure). There the target is still followed; elsewhere it has room to spare.
2. **The pressure loop's bandwidth.** The loop follows its setpoint with dead time +
   lag = `control.rate_feedforward_s` (measured by `pamd tune`); its -3 dB frequency is
   about 1 / (2 pi (dead time + lag)). A sine over the whole usable contraction span at
   that frequency has a peak rate of span / (2 (dead time + lag)): nothing faster is
   followed. (`rate_feedforward_s: 0` says nothing about the loop: no bound.)

The usable range: pressures from 0 to the muscle's pressure limit whose equilibrium
contraction with the configured load lies in the muscle's contraction range, from
its nominal length (0) to the soft contraction limit. The stretch below the nominal
length is the load's margin, where the braid is stiff and a target only rests: it
would set the limit for the whole range (on the shipped DMSP-20 at 30 kg, 0.014
contraction/bar under 1 bar against 0.021 at the top).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pamd.muscle_type import ForceModel, equilibrium_contraction

#: pressure grid of the stiffness search (bar): fine against the force map's 0.5 bar
#: levels, cheap (config time only)
GRID_STEP_BAR = 0.05


@dataclass(frozen=True)
class LengthRate:
    """The derived rate limit and how it came about (for check-config and refusals)."""

    max_rate_per_s: float
    slew_limit_bar_per_s: float
    slew_bound_per_s: float
    bandwidth_bound_per_s: float  # inf: rate_feedforward_s = 0
    contraction_per_bar: float  # the least, in the usable range
    at_pressure_bar: float  # where that is
    span: float  # the usable contraction span

    def explain(self) -> str:
        bw = ("no bandwidth bound (rate_feedforward_s: 0)"
              if math.isinf(self.bandwidth_bound_per_s) else
              f"bandwidth bound {self.bandwidth_bound_per_s:.3g}/s")
        return (f"{self.max_rate_per_s:.3g}/s derived: slew limit "
                f"{self.slew_limit_bar_per_s:g} bar/s x "
                f"{self.contraction_per_bar:.3g} contraction/bar (the least, at "
                f"{self.at_pressure_bar:.2f} bar) = {self.slew_bound_per_s:.3g}/s; {bw}")


def derive_length_rate(model: ForceModel, load_kg: float, max_pressure_bar: float,
                       contraction_bounds: tuple[float, float], slew_limit_bar_per_s: float,
                       rate_feedforward_s: float) -> LengthRate:
    """The fastest length target's rate (contraction/s) the muscle follows at
    `load_kg` (see the module's docstring)."""
    lo, hi = max(contraction_bounds[0], 0.0), contraction_bounds[1]
    n = max(int(max_pressure_bar / GRID_STEP_BAR), 2)
    pressures = [max_pressure_bar * i / n for i in range(n + 1)]
    eq = [equilibrium_contraction(model, p, load_kg) for p in pressures]
    least, at = math.inf, max_pressure_bar
    inside: list[float] = []
    for i in range(n):
        a, b = eq[i], eq[i + 1]
        if not (lo <= a <= hi and lo <= b <= hi):
            continue
        inside += [a, b]
        slope = (b - a) / (pressures[i + 1] - pressures[i])
        if 0.0 < slope < least:
            least, at = slope, 0.5 * (pressures[i] + pressures[i + 1])
    if not inside or math.isinf(least):
        # the load holds the muscle outside its usable range at every pressure: nothing
        # moves a length target there; keep a small, still usable limit
        least = 0.0
    span = (max(inside) - min(inside)) if inside else 0.0
    slew_bound = slew_limit_bar_per_s * least
    bandwidth = (span / (2.0 * rate_feedforward_s) if rate_feedforward_s > 0.0 and span > 0.0
                 else math.inf)
    rate = min(slew_bound, bandwidth)
    return LengthRate(max_rate_per_s=rate if rate > 0.0 else FALLBACK_RATE_PER_S,
                      slew_limit_bar_per_s=slew_limit_bar_per_s,
                      slew_bound_per_s=slew_bound, bandwidth_bound_per_s=bandwidth,
                      contraction_per_bar=least, at_pressure_bar=at, span=span)


#: when the muscle cannot move in its range at all (a load beyond its force): the
#: limit of before, so length commands are still checked (the reachability check
#: refuses them with the reason)
FALLBACK_RATE_PER_S = 0.05
