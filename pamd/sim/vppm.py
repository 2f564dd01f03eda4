"""The proportional pressure regulator (Festo VPPM) as a device, filling a muscle.

The regulator is not a filter on its setpoint: it has its own pressure loop.

    setpoint -> zero point, backlash, pilot dead time (`SetpointPilot`)
             -> pilot response (first-order lag)    = the pilot pressure p_pilot
    main stage opening u = clip((p_pilot - p_out) / full_open_error_bar, -1, 1)
             u > 0: supply -> muscle through C_in u        (ISO 6358 orifice)
             u < 0: muscle -> atmosphere through C_vent |u| (its own vent port)

so the muscle pressure is what the air flow allows: a large volume fills slower, a
contracting muscle loses pressure unless air flows in, and a sagging supply slows
the fill. Without power the main stage closes and the muscle holds its pressure
(a VPPM holds on power loss). A separate exhaust valve (`exhaust_open`) vents through
its own orifice whatever the regulator does. Without supply (`supply_ok` False) the
inlet is shut: the pressure can only fall.

Each step settles the chamber's implicit equation (as `settle_chamber_pa`, inlined)
and then lets in exactly the air q(p) dt that the supply gives up, so air is
conserved between the supply line and the muscle.
"""

from __future__ import annotations

import math

from pamd.sim.options import SimMuscleOptions
from pamd.sim.pilot import SetpointPilot
from pamd.sim.pneumatics import (
    BAR_PA,
    P_ATM_PA,
    FedChamber,
    MuscleVolume,
    Supply,
    conductance_from_nominal_flow,
    orifice_flow_kg_s,
)


class FlowRegulator(FedChamber):
    """One VPPM feeding one muscle chamber from a (possibly shared) supply line."""

    def __init__(
        self,
        *,
        supply: Supply,
        volume: MuscleVolume,
        contraction: float,
        max_bar: float,
        dead_time_s: float,
        pilot_lag_s: float,
        backlash_bar: float,
        zero_bar: float,
        nominal_flow_l_min: float,
        vent_flow_l_min: float,
        exhaust_valve_flow_l_min: float,
        critical_ratio: float,
        full_open_error_bar: float,
        polytropic: float,
        initial_bar: float,
    ) -> None:
        p0 = min(max(initial_bar, 0.0), max_bar)
        super().__init__(supply, volume, contraction, p0, polytropic)
        self.max_bar = max_bar
        self.pilot = SetpointPilot(max_bar=max_bar, dead_time_s=dead_time_s,
                                   backlash_bar=backlash_bar, zero_bar=zero_bar,
                                   initial_bar=initial_bar)
        self.pilot_lag_s = pilot_lag_s
        self.critical_ratio = critical_ratio
        self.c_in = conductance_from_nominal_flow(nominal_flow_l_min, critical_ratio)
        self.c_vent = conductance_from_nominal_flow(vent_flow_l_min, critical_ratio)  # its own
        self.c_exhaust_valve = conductance_from_nominal_flow(exhaust_valve_flow_l_min,
                                                             critical_ratio)
        self._inv_band_pa = 1.0 / (full_open_error_bar * BAR_PA)
        self.pilot_bar = p0  # the pilot stage's pressure, which the main stage tracks
        self._pilot_pa = p0 * BAR_PA + P_ATM_PA  # the same, absolute (each step's)
        self.supply_ok = True
        self.stuck = False  # an injected fault: new setpoints are ignored
        self.powered = True
        self.exhaust_open = False
        self.opening = 0.0
        self.t_s = 0.0
        self._dt_s = -1.0
        self._alpha_pilot = 0.0
        self._flow_fn = self._flow_in  # bound once: the tick allocates nothing
        # n R T of the chamber: its `pressure_per_kg(v)` is this / v (the same division)
        self._n_rt = self.chamber.pressure_per_kg(1.0)

    @classmethod
    def from_options(cls, o: SimMuscleOptions, supply: Supply, contraction: float,
                     initial_bar: float, inner_diameter_mm: float = 20.0) -> FlowRegulator:
        """The regulator of a simulated muscle with 'flow' pneumatics (its options)."""
        return cls(
            supply=supply,
            volume=MuscleVolume.of_muscle(o.nominal_length_mm, o.dead_volume_cm3,
                                          inner_diameter_mm),
            contraction=contraction,
            max_bar=o.regulator_max_bar,
            dead_time_s=o.regulator_dead_time_s,
            pilot_lag_s=o.regulator_pilot_lag_s,
            backlash_bar=o.regulator_backlash_bar,
            zero_bar=o.regulator_zero_bar,
            nominal_flow_l_min=o.regulator_flow_l_min,
            vent_flow_l_min=o.regulator_flow_l_min,
            exhaust_valve_flow_l_min=o.exhaust_flow_l_min,
            critical_ratio=o.critical_pressure_ratio,
            full_open_error_bar=o.regulator_full_open_error_bar,
            polytropic=o.polytropic_exponent,
            initial_bar=initial_bar,
        )

    # -- the same face as the lag regulator ------------------------------------------
    @property
    def setpoint_bar(self) -> float:
        return self.pilot.setpoint_bar

    def set_setpoint(self, value_bar: float) -> None:
        if not self.stuck:
            self.pilot.set_setpoint(value_bar)

    # -- physics ---------------------------------------------------------------------
    def _flow_in(self, p_pa: float) -> float:
        """Net mass flow into the muscle at chamber pressure `p_pa` (kg/s); the part
        drawn from the supply is left in `_q_supply`."""
        q_supply = 0.0
        q = 0.0
        if self.powered:
            u = (self._pilot_pa - p_pa) * self._inv_band_pa
            if u > 1.0:
                u = 1.0
            elif u < -1.0:
                u = -1.0
            self.opening = u
            if u > 0.0:
                if self.supply_ok:
                    q_supply = orifice_flow_kg_s(self.c_in * u, self.critical_ratio,
                                                 self.supply.pressure_pa, p_pa)
                    q = q_supply
            elif u < 0.0:
                q = -orifice_flow_kg_s(-self.c_vent * u, self.critical_ratio, p_pa, P_ATM_PA)
        else:
            self.opening = 0.0
        if self.exhaust_open:
            q -= orifice_flow_kg_s(self.c_exhaust_valve, self.critical_ratio, p_pa, P_ATM_PA)
        self._q_supply = q_supply
        return q

    def step(self, dt_s: float, contraction: float) -> float:
        """Advance by `dt_s` with the muscle at `contraction` at the step's end; the
        new muscle pressure (bar, gauge)."""
        if dt_s != self._dt_s:
            self._dt_s = dt_s
            lag = self.pilot_lag_s
            self._alpha_pilot = 1.0 - math.exp(-dt_s / lag) if lag > 0.0 else 1.0
        delayed = self.pilot.step(self.t_s)
        self.pilot_bar += (delayed - self.pilot_bar) * self._alpha_pilot
        self._pilot_pa = self.pilot_bar * BAR_PA + P_ATM_PA  # for the 3 flows below
        self.t_s += dt_s
        # `settle_chamber_pa`, then `FedChamber._admit`, inlined (this runs in the tick):
        # the chamber's implicit pressure by two chord-Newton steps from the no-flow
        # pressure, then exactly the air q(p) dt let in and booked.
        ch = self.chamber
        v1 = self.volume.volume_m3(contraction)
        v0 = ch.volume_m3
        p_nf = ch.pressure_pa if v0 == v1 else ch.pressure_pa * (v0 / v1) ** ch.polytropic
        k = self._n_rt / v1 * dt_s  # ch.pressure_per_kg(v1) * dt_s
        flow = self._flow_fn
        q0 = flow(p_nf)
        h = 1.0 + 1e-6 * p_nf
        inv = 1.0 / (1.0 - k * (flow(p_nf + h) - q0) / h)
        p = p_nf + k * q0 * inv
        if p < 0.0:
            p = 0.0
        q = flow(p)
        residual = p - p_nf - k * q
        if residual > 1.0 or residual < -1.0:  # Pa: not settled yet, one more chord step
            p -= residual * inv
            q = flow(p if p > 0.0 else 0.0)
        drawn = self._q_supply * dt_s
        self.supply.draw(drawn)
        self.supplied_kg += drawn
        self.vented_kg += drawn - q * dt_s
        p = p_nf + k * q
        ch.volume_m3 = v1
        ch.pressure_pa = p if p > 0.0 else 0.0
        return (ch.pressure_pa - P_ATM_PA) / BAR_PA
