"""A muscle driven by fast on/off solenoid valves (seed 004's positioning rig):
an inflate valve (3/2 NC) from the supply and an exhaust valve (2/2 NC) to the
atmosphere, each a digital output with its own switching delays and orifice.

Plumbing, as on seed 004's rig: the inflate valve's outlet feeds the muscle; its
exhaust port leads through the exhaust valve. So

    inflate on                 supply -> muscle          (inflate)
    inflate off, exhaust off   the muscle is shut in     (hold)
    inflate off, exhaust on    muscle -> atmosphere       (exhaust)

A valve opens `on_delay_s` after it is energised and closes `off_delay_s` after it
is released (solenoid valves release slower than they pull in); a command that is
taken back within its delay never reaches the spool. Each valve counts the times
its spool really moved: valve wear is what users of on/off valves watch.

The same face as the regulators (`step(dt, contraction)`, `pressure_bar`,
`supply_ok`, `exhaust_open`), so the plant does not care which drives it.
"""

from __future__ import annotations

from pamd.sim.options import SimMuscleOptions
from pamd.sim.pneumatics import (
    P_ATM_PA,
    FedChamber,
    MuscleVolume,
    Supply,
    conductance_from_nominal_flow,
    orifice_flow_kg_s,
    settle_chamber_pa,
)


class SolenoidValve:
    """A digital output's valve: commanded on/off, open after its switching delay."""

    def __init__(self, on_delay_s: float, off_delay_s: float) -> None:
        self.on_delay_s = on_delay_s
        self.off_delay_s = off_delay_s
        self.commanded = False
        self.is_open = False
        self.switchings = 0
        self._commanded_at_s = 0.0
        self._pending_command = False

    def command(self, on: bool) -> None:
        """Energise (True) or release the coil; takes effect after the delay."""
        if on != self.commanded:
            self.commanded = on
            self._pending_command = True

    def step(self, t_s: float) -> bool:
        """The spool's position for the step starting at `t_s`."""
        if self._pending_command:
            self._commanded_at_s = t_s
            self._pending_command = False
        if self.commanded != self.is_open:
            delay = self.on_delay_s if self.commanded else self.off_delay_s
            if t_s - self._commanded_at_s >= delay - 1e-9:
                self.is_open = self.commanded
                self.switchings += 1
        return self.is_open


class OnOffValves(FedChamber):
    """The inflate and exhaust valves of one muscle, filling its chamber."""

    def __init__(self, *, supply: Supply, volume: MuscleVolume, contraction: float,
                 inflate_flow_l_min: float, exhaust_flow_l_min: float, critical_ratio: float,
                 on_delay_s: float, off_delay_s: float, polytropic: float,
                 initial_bar: float) -> None:
        super().__init__(supply, volume, contraction, initial_bar, polytropic)
        self.critical_ratio = critical_ratio
        self.c_inflate = conductance_from_nominal_flow(inflate_flow_l_min, critical_ratio)
        self.c_exhaust = conductance_from_nominal_flow(exhaust_flow_l_min, critical_ratio)
        self.inflate = SolenoidValve(on_delay_s, off_delay_s)
        self.exhaust = SolenoidValve(on_delay_s, off_delay_s)
        self.supply_ok = True
        self.stuck = False  # an injected fault: the spools stay where they are
        self.t_s = 0.0
        self._inflating = False
        self._venting = False
        self._flow_fn = self._flow_in  # bound once: the tick allocates nothing

    @classmethod
    def from_options(cls, o: SimMuscleOptions, supply: Supply, contraction: float,
                     initial_bar: float, inner_diameter_mm: float = 20.0) -> OnOffValves:
        return cls(
            supply=supply,
            volume=MuscleVolume.of_muscle(o.nominal_length_mm, o.dead_volume_cm3,
                                          inner_diameter_mm),
            contraction=contraction,
            inflate_flow_l_min=o.onoff_inflate_flow_l_min,
            exhaust_flow_l_min=o.onoff_exhaust_flow_l_min,
            critical_ratio=o.critical_pressure_ratio,
            on_delay_s=o.valve_on_delay_s,
            off_delay_s=o.valve_off_delay_s,
            polytropic=o.polytropic_exponent,
            initial_bar=initial_bar,
        )

    # -- the regulators' face ----------------------------------------------------------
    @property
    def exhaust_open(self) -> bool:
        return self.exhaust.commanded

    @exhaust_open.setter
    def exhaust_open(self, on: bool) -> None:
        if not self.stuck:
            self.exhaust.command(on)

    def set_inflate(self, on: bool) -> None:
        if not self.stuck:
            self.inflate.command(on)

    @property
    def switchings(self) -> int:
        return self.inflate.switchings + self.exhaust.switchings

    # -- physics -------------------------------------------------------------------------
    def _flow_in(self, p_pa: float) -> float:
        q_supply = 0.0
        q = 0.0
        if self._inflating:
            if self.supply_ok:
                q_supply = orifice_flow_kg_s(self.c_inflate, self.critical_ratio,
                                             self.supply.pressure_pa, p_pa)
                q = q_supply
        elif self._venting:
            q = -orifice_flow_kg_s(self.c_exhaust, self.critical_ratio, p_pa, P_ATM_PA)
        self._q_supply = q_supply
        return q

    def step(self, dt_s: float, contraction: float) -> float:
        """Advance by `dt_s`, the muscle at `contraction`; the new pressure (bar)."""
        t0 = self.t_s
        self._inflating = self.inflate.step(t0)
        self._venting = self.exhaust.step(t0) and not self._inflating
        v1 = self.volume.volume_m3(contraction)
        if self._inflating or self._venting:
            q = self._flow_in(settle_chamber_pa(self.chamber, v1, dt_s, self._flow_fn))
        else:
            q = self._q_supply = 0.0
        self.t_s = t0 + dt_s
        return self._admit(dt_s, q, v1)
