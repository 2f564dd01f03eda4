"""The physics of one simulated muscle: hanging load, friction, regulator, sensors.

State, in the length coordinate L (m, positive = longer; contraction
x = 1 - L / L0): the load hangs from the muscle, so

    m dv/dt = W - T,   T = s F(p, x) + Ff + c v

with m the load plus a small moving mass, W the load's weight, F the static force
model of the muscle's type (`pamd.sim.specimen`: a DMSP-20's or DMSP-40's datasheet
map, or a custom muscle's measured one) times the force scale `s`, c a viscous damper
(larger while contracting) and Ff a Dahl friction state in the same coordinate,

    dFf = (Fc sign(dL) - Ff) |dL| / delta,   Fc = mu_p p + mu_T max(s F(p, x), 0).

Fc is Coulomb friction proportional to the braid's normal load (Chou and Hannaford,
as seed 004 cites them: the hysteresis is mostly Coulomb friction of the bladder on
the braid and of the braid's strands on each other). The bladder is pressed onto the
braid by the pressure (contact force ~ p times the contact area: mu_p p, with
`friction_n_per_bar`); the strands press on each other where they cross with a force
that follows the tension they carry, the muscle's static pull (mu_T s F, with
`friction_per_tension`; a slack braid, F < 0, adds none). With a hanging load the
static pull is about the weight, so the friction level, and the hysteresis loop,
grow with the load as seed 003 observes (`bench/hysteresis_width.py` measures the
width per load). `friction_per_tension: 0` gives friction from pressure alone (the
plant before issue 29: 10 N/bar, so 50 N at 5 bar, whatever the load).

The muscle is stiff (dF/dL ~ 125 N/mm against a 0.2 kg moving mass and a
1000 N s/m damper), so explicit Euler diverges. Each step is backward Euler with
F linearised around the present length (tangent stiffness by a one-sided
difference in the direction of motion) and the Dahl update taken implicitly too:
Ff_new = (Ff + sigma dL) / (1 + |dL| / delta) with sigma = Fc / delta. For a
known direction of motion that makes the step equation a quadratic in |dL| with
exactly one positive root, solved in closed form. The direction is the sign of
the force imbalance at dL = 0 (the step residual is monotone in dL), so the step
is unconditionally stable and its rest point is the exact static equilibrium.
Hard stops at both ends are perfectly inelastic (position clamped, velocity
zeroed); equal stops hold the muscle isometric.

`T` is what the in-line load cell measures: with the load hanging freely it is
the dead weight's m (g - a) (m the load and the moving mass, a its acceleration
upwards), so a noiseless load cell reads a constant while the load moves at a
steady speed. Sensors add gaussian noise (one `random.Random` per muscle, none at
a noise of 0), quantise the length like an encoder and, with `..._adc_bits`,
pressure and force like a converter (`pamd.sim.sensors`).
Pure Python and allocation-free per step: `advance` runs inside the 1 kHz tick.
"""

from __future__ import annotations

import math
import random
from collections.abc import Callable

from pamd.muscle_type import GRAVITY_M_S2, ForceModel, equilibrium_contraction
from pamd.sim.options import SimMuscleOptions
from pamd.sim.pneumatics import StiffSupply, SupplyLine
from pamd.sim.regulator import Regulator
from pamd.sim.sensors import SampledSensor
from pamd.sim.solenoid import OnOffValves
from pamd.sim.specimen import Specimen, specimen
from pamd.sim.vppm import FlowRegulator

MAX_STEP_S = 0.002
"""Longer `advance` calls (after skipped periods) are split into steps this long."""

_PROBE_CONTRACTION = 2e-4  # finite-difference step for the tangent stiffness (fraction)


class _ScaledModel:
    """A force model times a constant factor (for the start-up equilibrium)."""

    def __init__(self, model: ForceModel, scale: float) -> None:
        self.model = model
        self.scale = scale

    def force_n(self, pressure_bar: float, contraction: float) -> float:
        return self.scale * self.model.force_n(pressure_bar, contraction)


class MusclePlant:
    """One muscle with its hanging load, regulator and sensors.

    Call `advance(dt_s)`; then read `pressure_read_bar`, `force_read_n`,
    `length_read_mm` (sensor readings) or the true state (`pressure_bar`,
    `length_mm`, `contraction`, `velocity_mm_s`, `tension_n`, `friction_n`).
    """

    def __init__(
        self,
        options: SimMuscleOptions,
        rng: random.Random,
        muscle: Specimen | None = None,
        supply: SupplyLine | None = None,
    ) -> None:
        """`muscle`: what it simulates (default: its options' datasheet type)."""
        o = options
        self.options = o
        self.name = o.name
        self.muscle = muscle if muscle is not None else specimen(o)
        self.model: ForceModel = self.muscle.model
        self._force_fn = self.model.force_n
        self.force_scale = o.force_scale
        self._force_scale_0 = o.force_scale
        self._drift_per_s = o.force_drift_per_hour / 3600.0
        self._stiction_extra = o.stiction_ratio - 1.0
        self._inv_stribeck_m_s = 1.0 / (o.stribeck_velocity_mm_s * 1e-3)
        self.rng = rng
        self._gauss = rng.gauss
        self.nominal_length_m = o.nominal_length_mm * 1e-3
        self._inv_l0 = 1.0 / self.nominal_length_m
        self._probe_m = _PROBE_CONTRACTION * self.nominal_length_m
        self.stop_stretch_contraction = self.muscle.stop_stretch_contraction
        self.stop_contraction = self.muscle.stop_contraction
        self._length_max_m = self.nominal_length_m * (1.0 - self.stop_stretch_contraction)
        self._length_min_m = self.nominal_length_m * (1.0 - self.stop_contraction)
        self.moving_mass_kg = o.moving_mass_kg
        self.load_kg = 0.0
        self._mass_kg = 0.0
        self._weight_n = 0.0
        self.set_load_kg(o.load_kg)
        self._fric_per_bar = o.friction_n_per_bar
        self._fric_per_tension = o.friction_per_tension
        self._delta_m = o.friction_presliding_mm * 1e-3
        self._c_contract = o.damping_contracting_n_s_per_m
        self._c_relax = o.damping_relaxing_n_s_per_m
        self._p_noise = o.pressure_noise_bar
        self._f_noise = o.force_noise_n
        self._enc_res_mm = o.encoder_resolution_mm
        self._inv_enc_res = 1.0 / o.encoder_resolution_mm
        # The rig starts at rest, at the static equilibrium for its load and pressure.
        p0 = min(max(o.initial_pressure_bar, 0.0), o.regulator_max_bar, o.supply_bar)
        x0 = equilibrium_contraction(
            _ScaledModel(self.model, self.force_scale), p0, self.load_kg, -0.5, 0.9
        )
        x0 = min(max(x0, self.stop_stretch_contraction), self.stop_contraction)
        # A 'flow' muscle without a shared supply line has a stiff one of its own;
        # a shared one is stepped by its owner (the driver).
        self.regulator: Regulator | FlowRegulator | OnOffValves
        if o.pneumatics == "flow" or o.actuation == "onoff":
            own = StiffSupply(source_bar=o.supply_bar) if supply is None else supply
            self.regulator = (OnOffValves if o.actuation == "onoff" else FlowRegulator
                              ).from_options(o, own, x0, p0, self.muscle.inner_diameter_mm)
        else:
            self.regulator = Regulator(
                supply_bar=o.supply_bar,
                max_bar=o.regulator_max_bar,
                dead_time_s=o.regulator_dead_time_s,
                lag_s=o.regulator_lag_s,
                backlash_bar=o.regulator_backlash_bar,
                zero_bar=o.regulator_zero_bar,
                vent_time_constant_s=o.exhaust_vent_time_constant_s,
                initial_bar=p0,
            )
        self._length_m = self.nominal_length_m * (1.0 - x0)
        self._velocity_m_s = 0.0
        self._friction_n = 0.0
        self._tension_n = self.force_scale * self._force_fn(p0, x0)
        self.t_s = 0.0
        self.pressure_read_bar = 0.0
        self.force_read_n = 0.0
        self.length_read_mm = 0.0
        # How old each reading's stamp is (s): when it was sampled (or, on a bursty
        # link, when it arrived), before this plant time; and how much earlier than its
        # stamp it may have been taken (0 where the stamp is the sample's time).
        self.pressure_age_s = self.force_age_s = self.length_age_s = 0.0
        self.pressure_jitter_s = self.force_jitter_s = self.length_jitter_s = 0.0
        self._sensors = _sampled_sensors(o, rng.gauss)
        self._sensor_dt_s = 0.0
        self._sensors_every_step = False
        # The regulator's pressure as its last step returned it (what its `pressure_bar`
        # reads until the next step): the sensors read this, with no property call.
        self._pressure_bar = self.regulator.pressure_bar
        self._read_sensors()

    # --- inputs ---------------------------------------------------------------
    def set_load_kg(self, load_kg: float) -> None:
        """Change the hanging mass (takes effect at the next step)."""
        if not (load_kg >= 0.0 and math.isfinite(load_kg)):
            raise ValueError(f"load must be a finite mass >= 0 kg, got {load_kg!r}")
        self.load_kg = load_kg
        self._mass_kg = load_kg + self.moving_mass_kg
        self._weight_n = load_kg * GRAVITY_M_S2

    def set_setpoint(self, value_bar: float) -> None:
        """Regulator setpoint (bar), clamped to its input range (proportional
        actuation; an on/off muscle has no setpoint)."""
        reg = self.regulator
        if isinstance(reg, OnOffValves):
            raise TypeError(f"muscle {self.name!r} has on/off valves, not a regulator")
        reg.set_setpoint(value_bar)

    def set_supply(self, ok: bool) -> None:
        """Supply present (True) or lost: without it the pressure cannot rise."""
        self.regulator.supply_ok = ok

    # --- true state -----------------------------------------------------------
    @property
    def pressure_bar(self) -> float:
        return self.regulator.pressure_bar

    @property
    def length_mm(self) -> float:
        return self._length_m * 1e3

    @property
    def contraction(self) -> float:
        return 1.0 - self._length_m * self._inv_l0

    @property
    def velocity_mm_s(self) -> float:
        return self._velocity_m_s * 1e3

    @property
    def tension_n(self) -> float:
        """Force the muscle pulls (static + friction + damping): what the load cell sees."""
        return self._tension_n

    @property
    def friction_n(self) -> float:
        """Dahl friction state (positive while stretching)."""
        return self._friction_n

    def static_force_n(self, pressure_bar: float, contraction: float) -> float:
        """The static force this muscle's model gives (force scale included)."""
        return self.force_scale * self._force_fn(pressure_bar, contraction)

    # --- stepping -------------------------------------------------------------
    def advance(self, dt_s: float) -> None:
        """Advance physics and sensors by `dt_s` (split into steps <= MAX_STEP_S)."""
        if not dt_s > 0.0:
            return
        if dt_s <= MAX_STEP_S * 1.000001:
            self._step(dt_s)
        else:
            n = math.ceil(dt_s / MAX_STEP_S - 1e-9)
            h = dt_s / n
            for _ in range(n):
                self._step(h)
        if dt_s != self._sensor_dt_s:
            self._sensor_dt_s = dt_s
            self._sensors_every_step = _samples_every_step(self._sensors, dt_s)
        self._read_sensors()

    def _step(self, dt: float) -> None:
        length = self._length_m
        x = 1.0 - length * self._inv_l0
        p = self._pressure_bar = self.regulator.step(dt, x)
        force_fn = self._force_fn
        if self._drift_per_s != 0.0:
            drift = 1.0 + self._drift_per_s * self.t_s
            self.force_scale = self._force_scale_0 * (drift if drift > 0.05 else 0.05)
        scale = self.force_scale
        v = self._velocity_m_s
        ff = self._friction_n
        m = self._mass_kg
        fs = scale * force_fn(p, x)
        # Coulomb level from the braid's normal load: the bladder pressed onto it by
        # the pressure, its strands pressed together by the tension they carry.
        fc = self._fric_per_bar * p if p > 0.0 else 0.0
        if fs > 0.0:
            fc += self._fric_per_tension * fs
        # Stribeck: at rest the friction can reach the breakaway level, sliding less.
        if self._stiction_extra != 0.0:
            w = v * self._inv_stribeck_m_s
            fc *= 1.0 + self._stiction_extra * math.exp(-w * w)
        # Step residual R(dL) = a dL + b + Ff_new(dL) with b as below; R rises with dL.
        b = fs - self._weight_n - m * v / dt
        r0 = b + ff
        if r0 == 0.0:
            dl = 0.0
            stiff = 0.0
            c = 0.0
        else:
            delta = self._delta_m
            sigma = fc / delta
            probe = self._probe_m
            if r0 < 0.0:  # net pull down: the muscle lengthens
                s = 1.0
                c = self._c_relax
                stiff = (scale * force_fn(p, x - _PROBE_CONTRACTION) - fs) / probe
            else:
                s = -1.0
                c = self._c_contract
                stiff = (fs - scale * force_fn(p, x + _PROBE_CONTRACTION)) / probe
            if stiff < 0.0:
                stiff = 0.0
            a = m / (dt * dt) + c / dt + stiff
            # With u = s dL >= 0: (a/delta) u^2 + (a + sigma + s b/delta) u - |r0| = 0.
            qa = a / delta
            qb = a + sigma + s * b / delta
            qc = -abs(r0)
            root = math.sqrt(qb * qb - 4.0 * qa * qc)
            if qb >= 0.0:
                u = -2.0 * qc / (qb + root)
            else:
                u = (root - qb) / (2.0 * qa)
            dl = s * u
        new_length = length + dl
        if new_length > self._length_max_m:
            new_length = self._length_max_m
            dl = new_length - length
            v = 0.0
        elif new_length < self._length_min_m:
            new_length = self._length_min_m
            dl = new_length - length
            v = 0.0
        else:
            v = dl / dt
        if dl != 0.0:
            delta = self._delta_m
            ff = (ff + fc / delta * dl) / (1.0 + abs(dl) / delta)
        # Less contact force, less friction: the stored friction cannot exceed it.
        if ff > fc:
            ff = fc
        elif ff < -fc:
            ff = -fc
        self._length_m = new_length
        self._velocity_m_s = v
        self._friction_n = ff
        self._tension_n = fs + stiff * dl + ff + c * v
        self.t_s += dt

    def _read_sensors(self) -> None:
        if self._sensors is not None and not self._sensors_every_step:
            self._read_sampled(self._sensors)
            return
        # Every sensor takes a sample at each step and delivers it at once (no
        # sensors as devices, or a 1 kHz card at a 1 ms step): the same readings,
        # read directly.
        self.pressure_age_s = self.force_age_s = self.length_age_s = 0.0
        gauss = self._gauss
        self.pressure_read_bar = self._pressure_bar + gauss(0.0, self._p_noise)
        self.force_read_n = self._tension_n + gauss(0.0, self._f_noise)
        res = self._enc_res_mm
        self.length_read_mm = math.floor(self._length_m * 1e3 * self._inv_enc_res + 0.5) * res


    def _read_sampled(self, sensors: tuple[SampledSensor, SampledSensor, SampledSensor]) -> None:
        """Sensors with their own sample periods, latencies and filters."""
        t = self.t_s
        p_sensor, f_sensor, l_sensor = sensors
        p_sensor.update(t, self._pressure_bar)
        f_sensor.update(t, self._tension_n)
        l_sensor.update(t, self._length_m * 1e3)
        self.pressure_read_bar = p_sensor.value
        self.force_read_n = f_sensor.value
        self.length_read_mm = l_sensor.value
        self.pressure_age_s = t - p_sensor.stamp_s
        self.force_age_s = t - f_sensor.stamp_s
        self.length_age_s = t - l_sensor.stamp_s
        self.pressure_jitter_s = p_sensor.jitter_s
        self.force_jitter_s = f_sensor.jitter_s
        self.length_jitter_s = l_sensor.jitter_s


def _samples_every_step(sensors: tuple[SampledSensor, ...] | None, dt_s: float) -> bool:
    """True where each sensor samples at every plant step of `dt_s` and delivers at
    once, unfiltered: reading the plant directly then gives the same readings."""
    if sensors is None:
        return True
    p_sensor, f_sensor, _ = sensors
    if p_sensor.resolution or f_sensor.resolution:
        return False  # an ADC: only the sensor quantises pressure and force
    return all(s.period_s <= dt_s + 1e-12 and s.latency_s == 0.0 and s.filter_tau_s == 0.0
               and not s.bursty for s in sensors)


def _sampled_sensors(
    o: SimMuscleOptions, gauss: Callable[[float, float], float]
) -> tuple[SampledSensor, SampledSensor, SampledSensor] | None:
    """The three sensors as devices, or None where every one samples at each plant
    step without delay or filter (the plant then reads them directly: cheaper, and
    the same readings)."""
    if not (o.pressure_sample_period_s or o.pressure_latency_s or o.pressure_filter_s
            or o.force_sample_period_s or o.force_latency_s or o.force_filter_s
            or o.length_sample_period_s or o.length_latency_s or o.pressure_adc_bits
            or o.force_adc_bits or o.pressure_burst_s or o.force_burst_s or o.length_burst_s):
        return None
    return (
        SampledSensor(period_s=o.pressure_sample_period_s, latency_s=o.pressure_latency_s,
                      noise_sd=o.pressure_noise_bar, filter_tau_s=o.pressure_filter_s,
                      gauss=gauss, adc_bits=o.pressure_adc_bits,
                      range_min=o.pressure_adc_min_bar, range_max=o.pressure_adc_max_bar,
                      burst_s=o.pressure_burst_s, burst_every_s=o.burst_every_s),
        SampledSensor(period_s=o.force_sample_period_s, latency_s=o.force_latency_s,
                      noise_sd=o.force_noise_n, filter_tau_s=o.force_filter_s, gauss=gauss,
                      adc_bits=o.force_adc_bits, range_min=o.force_adc_min_n,
                      range_max=o.force_adc_max_n, burst_s=o.force_burst_s,
                      burst_every_s=o.burst_every_s),
        SampledSensor(period_s=o.length_sample_period_s, latency_s=o.length_latency_s,
                      resolution=o.encoder_resolution_mm, filter_tau_s=o.length_filter_s,
                      burst_s=o.length_burst_s, burst_every_s=o.burst_every_s),
    )
