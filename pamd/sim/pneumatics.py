"""Air that flows: ISO 6358 orifices, a muscle chamber whose volume follows its
contraction, a supply line several regulators draw from, and the proportional
regulator (Festo VPPM) as a device with its own pressure loop.

Pressures inside this module are absolute, in pascal (`_pa`); the plant and the
driver speak gauge bar. Mass flows are in kg/s, positive into the chamber.

Flow through a restriction (ISO 6358-1): with upstream p1, downstream p2 and
r = p2 / p1,

    q = C rho0 p1 sqrt(T0 / T1)                              r <= b (choked)
    q = C rho0 p1 sqrt(T0 / T1) sqrt(1 - ((r - b)/(1 - b))^2)    b < r <= 1

with C the sonic conductance (m^3 / (s Pa)), b the critical pressure ratio and
rho0 the density at ISO 8778 reference conditions. The subsonic branch has an
infinite slope at r = 1, which no fixed-step integrator survives; above
`LAMINAR_RATIO` the flow is taken linear in (1 - r), continuous at the joint
(ISO 6358-3's laminar region plays the same part).

Chamber (one lumped volume per muscle, hose included): with a polytropic
exponent n,

    dp/dt = n / V (R T qm - p dV/dt)

so a contracting muscle (dV/dt > 0) loses pressure unless air flows in, and a
large volume fills slower. With n = 1 (isothermal) p V / (R T) is the air mass
and `Chamber.step` conserves it to rounding. Each step is linearised implicit
Euler in p (the flow's slope taken by a one-sided difference), so stiff flows
into a small volume stay stable at the 1-2 ms plant step.

Pure Python floats, nothing allocated per step: this runs inside the tick.
"""

from __future__ import annotations

import math
from collections.abc import Callable

P_ATM_PA = 101325.0
"""Atmospheric pressure: gauge 0 bar."""
BAR_PA = 1.0e5
R_AIR_J_KG_K = 287.05
T_REF_K = 293.15
"""ISO 8778 reference temperature (also the supply's, here)."""
RHO_REF_KG_M3 = 1.185
"""Density of air at ISO 8778 reference conditions (20 C, 100 kPa, 65 % RH)."""
LAMINAR_RATIO = 0.995
"""Above this pressure ratio the orifice flow is linear in the pressure difference."""

_PHI_LAMINAR_CACHE: dict[float, float] = {}


def _phi_at_laminar(b: float) -> float:
    phi = _PHI_LAMINAR_CACHE.get(b)
    if phi is None:
        z = (LAMINAR_RATIO - b) / (1.0 - b)
        phi = math.sqrt(1.0 - z * z)
        _PHI_LAMINAR_CACHE[b] = phi
    return phi


def orifice_flow_kg_s(conductance_m3_s_pa: float, critical_ratio: float,
                      p_from_pa: float, p_to_pa: float) -> float:
    """Mass flow through an ISO 6358 restriction from `p_from_pa` to `p_to_pa`
    (negative when the air flows the other way); reference temperature upstream."""
    if p_from_pa >= p_to_pa:
        sign, p1, p2 = 1.0, p_from_pa, p_to_pa
    else:
        sign, p1, p2 = -1.0, p_to_pa, p_from_pa
    if p1 <= 0.0 or conductance_m3_s_pa <= 0.0:
        return 0.0
    b = critical_ratio
    r = p2 / p1
    full = conductance_m3_s_pa * RHO_REF_KG_M3 * p1
    if r <= b:
        return sign * full
    if r <= LAMINAR_RATIO:
        z = (r - b) / (1.0 - b)
        return sign * full * math.sqrt(1.0 - z * z)
    return sign * full * _phi_at_laminar(b) * (1.0 - r) / (1.0 - LAMINAR_RATIO)


def conductance_from_nominal_flow(nominal_flow_l_min: float, critical_ratio: float,
                                  p1_bar: float = 6.0, p2_bar: float = 5.0) -> float:
    """Sonic conductance (m^3/(s Pa)) of a valve whose datasheet gives its standard
    nominal flow (l/min, ANR) from `p1_bar` to `p2_bar` gauge (Festo: 6 -> 5 bar)."""
    p1 = p1_bar * BAR_PA + P_ATM_PA
    p2 = p2_bar * BAR_PA + P_ATM_PA
    z = (p2 / p1 - critical_ratio) / (1.0 - critical_ratio)
    phi = math.sqrt(1.0 - z * z) if z < 1.0 else 0.0
    q_m3_s = nominal_flow_l_min / 60000.0
    return q_m3_s / (p1 * phi)


class MuscleVolume:
    """Internal volume of a muscle against its contraction: piecewise linear through
    a table (contraction fraction -> cm^3), extended linearly past its ends and
    never below `min_fraction` of its first entry; plus a fixed dead volume (hose,
    fittings)."""

    # DMSP-20-200 from braid geometry (braid angle 28.6 deg), rig-physics.md.
    DMSP20_200 = ((0.0, 62.8), (0.05, 79.4), (0.10, 92.9), (0.15, 103.6), (0.20, 111.5),
                  (0.25, 116.9))

    def __init__(self, table: tuple[tuple[float, float], ...] = DMSP20_200,
                 length_scale: float = 1.0, dead_volume_cm3: float = 0.0,
                 min_fraction: float = 0.5) -> None:
        if len(table) < 2:
            raise ValueError("a volume table needs at least two points")
        self._x = tuple(x for x, _ in table)
        self._v = tuple(v * 1e-6 * length_scale for _, v in table)
        self._dead_m3 = dead_volume_cm3 * 1e-6
        self._floor_m3 = min_fraction * self._v[0]
        # An evenly spaced table (the DMSP-20's) finds its segment by division.
        steps = [b - a for a, b in zip(self._x, self._x[1:], strict=False)]
        self._inv_dx = (1.0 / steps[0] if steps[0] > 0.0 and all(
            abs(d - steps[0]) <= 1e-12 for d in steps) else 0.0)
        self._slopes = tuple((v1 - v0) / d for v0, v1, d in zip(self._v, self._v[1:], steps,
                                                                strict=False))

    @classmethod
    def of_muscle(cls, nominal_length_mm: float, dead_volume_cm3: float,
                  inner_diameter_mm: float = 20.0) -> MuscleVolume:
        """A muscle of this nominal length and inner diameter plus hose: the DMSP-20-200's
        table scaled by the length (from 200 mm) and the diameter squared (from 20 mm).
        The table's 62.8 cm^3 at 0 % is the 20 mm x 200 mm cylinder; a braid of the same
        angle on another diameter keeps its shape, so its volume scales with the
        diameter squared [derived; the braid angle of other sizes is not published]."""
        scale = nominal_length_mm / 200.0 * (inner_diameter_mm / 20.0) ** 2
        return cls(length_scale=scale, dead_volume_cm3=dead_volume_cm3)

    def volume_m3(self, contraction: float) -> float:
        xs = self._x
        last = len(xs) - 2
        if self._inv_dx > 0.0:
            i = int((contraction - xs[0]) * self._inv_dx)
            i = 0 if i < 0 else (last if i > last else i)
        else:
            i = 0
            while i < last and contraction > xs[i + 1]:
                i += 1
        v = self._v[i] + self._slopes[i] * (contraction - xs[i])
        if v < self._floor_m3:
            v = self._floor_m3
        return v + self._dead_m3


class Chamber:
    """A lumped air volume: its absolute pressure under mass flow and volume change."""

    def __init__(self, volume_m3: float, pressure_pa: float, polytropic: float = 1.2,
                 temperature_k: float = T_REF_K) -> None:
        if not volume_m3 > 0.0:
            raise ValueError(f"a chamber needs a positive volume, got {volume_m3!r} m^3")
        self.volume_m3 = volume_m3
        self.pressure_pa = pressure_pa
        self.polytropic = polytropic
        self._rt = R_AIR_J_KG_K * temperature_k

    @property
    def air_mass_kg(self) -> float:
        """p V / (R T): the air mass at the reference temperature."""
        return self.pressure_pa * self.volume_m3 / self._rt

    def no_flow_pressure_pa(self, new_volume_m3: float) -> float:
        """The pressure after a volume change with no air in or out (p V^n constant)."""
        ratio = self.volume_m3 / new_volume_m3
        if ratio == 1.0:
            return self.pressure_pa
        pressure_pa: float = self.pressure_pa * ratio ** self.polytropic
        return pressure_pa

    def pressure_per_kg(self, volume_m3: float) -> float:
        """Pressure rise (Pa) per kg of air let in at the reference temperature."""
        return self.polytropic * self._rt / volume_m3

    def step(self, dt_s: float, mass_flow_kg_s: float, new_volume_m3: float) -> float:
        """Step with a given mass flow and the volume at the step's end; the new
        pressure. Exact for n = 1 (p V / (R T) changes by the mass let in) and for no
        flow (p V^n constant)."""
        p = (self.no_flow_pressure_pa(new_volume_m3)
             + self.pressure_per_kg(new_volume_m3) * mass_flow_kg_s * dt_s)
        self.volume_m3 = new_volume_m3
        self.pressure_pa = p if p > 0.0 else 0.0
        return self.pressure_pa


def settle_chamber_pa(chamber: Chamber, new_volume_m3: float, dt_s: float,
                      flow_in: Callable[[float], float]) -> float:
    """The chamber pressure at the end of a step in which its volume becomes
    `new_volume_m3` and air flows in at `flow_in(p)` kg/s (a function of the chamber
    pressure, falling as it rises): p = p_nf + k q(p), solved by two chord-Newton
    steps from the no-flow pressure p_nf (the flow's slope taken once, there). The
    chamber is not changed; the caller lets the air in with `Chamber.step`, so what
    it books is what went in."""
    p_nf = chamber.no_flow_pressure_pa(new_volume_m3)
    k = chamber.pressure_per_kg(new_volume_m3) * dt_s
    q0 = flow_in(p_nf)
    h = 1.0 + 1e-6 * p_nf
    inv = 1.0 / (1.0 - k * (flow_in(p_nf + h) - q0) / h)
    p = p_nf + k * q0 * inv
    if p < 0.0:
        p = 0.0
    p -= (p - p_nf - k * flow_in(p)) * inv
    return p if p > 0.0 else 0.0


class SupplyLine:
    """Compressed air as it reaches the regulators: a line volume fed from the
    compressor's reservoir through a restriction. Regulators `draw` mass during a
    tick; `step` settles the line once per tick, so a shared supply sags when
    several muscles fill at once."""

    def __init__(self, source_bar: float = 7.0, conductance_m3_s_pa: float = 2.0e-7,
                 critical_ratio: float = 0.3, line_volume_l: float = 1.0) -> None:
        self.source_pa = source_bar * BAR_PA + P_ATM_PA
        self.conductance = conductance_m3_s_pa
        self.critical_ratio = critical_ratio
        self.chamber = Chamber(line_volume_l * 1e-3, self.source_pa, polytropic=1.0)
        self.ok = True
        self.delivered_kg = 0.0  # air that came in from the compressor so far
        self._drawn_kg = 0.0

    @property
    def pressure_pa(self) -> float:
        return self.chamber.pressure_pa

    @property
    def pressure_bar(self) -> float:
        return (self.chamber.pressure_pa - P_ATM_PA) / BAR_PA

    def draw(self, mass_kg: float) -> None:
        """Air taken by a regulator during this tick (returned air is negative)."""
        self._drawn_kg += mass_kg

    def step(self, dt_s: float) -> None:
        ch = self.chamber
        drawn, self._drawn_kg = self._drawn_kg, 0.0
        if not self.ok:  # compressor off or the line cut: the line only empties
            ch.step(dt_s, -drawn / dt_s, ch.volume_m3)
            return
        # Implicit in the line pressure: q(p) linearised at the step's start.
        c, b, src = self.conductance, self.critical_ratio, self.source_pa
        p0 = ch.pressure_pa
        q0 = orifice_flow_kg_s(c, b, src, p0)
        h = 1.0 + 1e-6 * p0
        dq = (orifice_flow_kg_s(c, b, src, p0 + h) - q0) / h
        k = ch.pressure_per_kg(ch.volume_m3)
        dp = (k * (q0 * dt_s - drawn)) / (1.0 - k * dq * dt_s)
        # Let in exactly the air the linearised flow gave, so the books balance.
        came_in = dp / k + drawn
        self.delivered_kg += came_in
        ch.step(dt_s, (came_in - drawn) / dt_s, ch.volume_m3)


class StiffSupply:
    """A supply no draw can sag (a muscle's own, when no shared line is configured):
    the source pressure at all times; it books what it delivered. The same face as
    `SupplyLine`, at no cost per step."""

    def __init__(self, source_bar: float = 7.0) -> None:
        self.source_pa = source_bar * BAR_PA + P_ATM_PA
        self.pressure_pa = self.source_pa
        self.ok = True
        self.delivered_kg = 0.0

    @property
    def pressure_bar(self) -> float:
        return (self.pressure_pa - P_ATM_PA) / BAR_PA

    def draw(self, mass_kg: float) -> None:
        self.delivered_kg += mass_kg

    def step(self, dt_s: float) -> None:
        """Nothing to settle: the source holds its pressure."""


Supply = SupplyLine | StiffSupply
"""What a regulator or valve draws its air from."""


class FedChamber:
    """One muscle's chamber fed from a supply line, and its air books: what came from
    the supply (`supplied_kg`) and what went out to the atmosphere (`vented_kg`).
    The regulator and the on/off valves build on it; their `_flow_in(p)` leaves the
    part drawn from the supply in `_q_supply`, and `_admit` books a step."""

    def __init__(self, supply: Supply, volume: MuscleVolume, contraction: float,
                 initial_bar: float, polytropic: float) -> None:
        self.supply = supply
        self.volume = volume
        self.chamber = Chamber(volume.volume_m3(contraction),
                               max(initial_bar, 0.0) * BAR_PA + P_ATM_PA, polytropic)
        self.supplied_kg = 0.0
        self.vented_kg = 0.0
        self._q_supply = 0.0

    @property
    def pressure_bar(self) -> float:
        return (self.chamber.pressure_pa - P_ATM_PA) / BAR_PA

    def _admit(self, dt_s: float, q_kg_s: float, new_volume_m3: float) -> float:
        """Let in the net flow `q_kg_s` (the supply's part drawn from it) over the step
        in which the volume becomes `new_volume_m3`; the new pressure (bar, gauge)."""
        drawn = self._q_supply * dt_s
        self.supply.draw(drawn)
        self.supplied_kg += drawn
        self.vented_kg += drawn - q_kg_s * dt_s
        ch = self.chamber
        ch.step(dt_s, q_kg_s, new_volume_m3)
        return (ch.pressure_pa - P_ATM_PA) / BAR_PA
