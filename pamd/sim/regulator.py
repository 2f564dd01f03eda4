"""The simulated proportional pressure regulator (Festo VPPM) and exhaust valve, as
a filter on its setpoint (the `lag` pneumatics; `pamd.sim.vppm` lets air flow).

Zero-point suppression, backlash and dead time are the `SetpointPilot`'s; then a
first-order lag, exact for any step length, toward the delayed setpoint clamped
to [0, min(supply, full scale)]. Without supply the pressure cannot rise: it
holds (or falls, if the setpoint asks for less). An open exhaust valve vents the
muscle toward 0 bar with its own time constant, whatever the regulator does.

Pure Python, nothing allocated per step: `step` runs inside the 1 kHz tick.
"""

from __future__ import annotations

import math

from pamd.sim.pilot import SetpointPilot


class Regulator:
    """One regulator feeding one muscle; `pressure_bar` is the muscle pressure."""

    def __init__(
        self,
        *,
        supply_bar: float,
        max_bar: float,
        dead_time_s: float,
        lag_s: float,
        backlash_bar: float,
        zero_bar: float,
        vent_time_constant_s: float,
        initial_bar: float,
    ) -> None:
        self.supply_bar = supply_bar
        self.max_bar = max_bar
        self.lag_s = lag_s
        self.vent_time_constant_s = vent_time_constant_s
        self.supply_ok = True
        self.stuck = False  # an injected fault: new setpoints are ignored
        self.exhaust_open = False
        p0 = min(max(initial_bar, 0.0), max_bar, supply_bar)
        self.pilot = SetpointPilot(max_bar=max_bar, dead_time_s=dead_time_s,
                                   backlash_bar=backlash_bar, zero_bar=zero_bar, initial_bar=p0)
        self.pressure_bar = p0
        self.t_s = 0.0
        self._dt_s = -1.0
        self._alpha_lag = 0.0
        self._alpha_vent = 0.0

    @property
    def setpoint_bar(self) -> float:
        return self.pilot.setpoint_bar

    def set_setpoint(self, value_bar: float) -> None:
        """The commanded pressure; clamped to the regulator's input range. Ignored while
        `stuck` (an injected fault)."""
        if self.stuck:
            return
        self.pilot.set_setpoint(value_bar)

    def _set_dt(self, dt_s: float) -> None:
        self._dt_s = dt_s
        self._alpha_lag = 1.0 - math.exp(-dt_s / self.lag_s)
        self._alpha_vent = 1.0 - math.exp(-dt_s / self.vent_time_constant_s)

    def step(self, dt_s: float, contraction: float = 0.0) -> float:
        """Advance by `dt_s` (a zero-order hold over the step); the new pressure.
        The muscle's `contraction` does not matter to this model (see `pamd.sim.vppm`
        for one where the air flow does)."""
        if dt_s != self._dt_s:
            self._set_dt(dt_s)
        target = self.pilot.step(self.t_s)
        top = self.max_bar if self.max_bar < self.supply_bar else self.supply_bar
        if target > top:
            target = top
        p = self.pressure_bar
        if self.exhaust_open:
            p -= p * self._alpha_vent
        else:
            if not self.supply_ok and target > p:
                target = p  # no air to fill with: hold
            p += (target - p) * self._alpha_lag
        self.pressure_bar = p
        self.t_s += dt_s
        return p
