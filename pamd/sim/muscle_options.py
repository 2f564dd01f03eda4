"""A simulated muscle's options by part, as frozen dataclasses: the muscle and its
load (`SimMechanics`), the air that drives it (`SimPneumatics`) and the sensors that
read it (`SimSensors`). `pamd.sim.options.SimMuscleOptions` is all three, one flat
`muscles[]` block of the config (the parts are how the code is read, not config keys).

Every field has a default, a one-sentence `doc`, and where it applies a `unit` and
`min`/`max` bounds (`pamd.wire.schema.engine.spec`). Like `pamd.sim.options`, this module
does not use `from __future__ import annotations`, so `dataclasses.fields(...)[i].type`
holds real types for the config engine.
"""

from dataclasses import dataclass
from typing import Any, Literal

from pamd.config.schema import Actuation
from pamd.wire.schema.engine import spec


def option(
    default: object, doc: str, unit: str = "", lo: float | None = None, hi: float | None = None
) -> Any:  # Any: a dataclass field() standing for the field's own type, as spec's
    """`pamd.wire.schema.engine.spec` with the bounds given positionally."""
    meta: dict[str, object] = {}
    if unit:
        meta["unit"] = unit
    if lo is not None:
        meta["min"] = lo
    if hi is not None:
        meta["max"] = hi
    return spec(default, doc, **meta)


@dataclass(frozen=True)
class SimMechanics:
    """The muscle (its type: a DMSP-20 by default, or the rig muscle's it stands for),
    its hanging load, its friction and its hard stops."""

    name: str = option(
        "m1",
        "Muscle name; its channels are NAME.pressure, NAME.force, "
        "NAME.length, NAME.valve and NAME.exhaust.",
    )
    nominal_length_mm: float = option(
        200.0, "Nominal (unpressurised, unloaded) muscle length.", "mm", 10.0, 5000.0
    )
    load_kg: float = option(
        30.0,
        "Mass hanging from the muscle at start-up (changeable while running).",
        "kg",
        0.0,
        500.0,
    )
    type: str | None = option(
        None,
        "The muscle simulated: dmsp20 or dmsp40 (Festo's datasheet map is the plant's "
        "static force), or custom (its measured map, map_file). null: the type of the "
        "rig's muscle whose signals are this muscle's channels (`muscles[].type`, a custom "
        "one with its map, diameter and stops), dmsp20 where no rig muscle is; give a type "
        "to keep the simulated muscle what it is while the rig's config changes (e.g. "
        "after `pamd commission --measure-map --save`).",
    )
    map_file: str | None = option(
        None,
        "type custom: the force map table (CSV or MAT, read as muscles[].custom.map_file), "
        "relative to the config file.",
    )
    inner_diameter_mm: float | None = option(
        None,
        "type custom: the inner diameter, for the air volume of 'flow' pneumatics (the "
        "DMSP-20-200's volume table scaled by the diameter squared and the length); null: "
        "the type's.",
        "mm",
        1.0,
        1000.0,
    )
    force_model: Literal["map", "fit"] = option(
        "map",
        "Static force model: 'map' interpolates the type's map, 'fit' is the DMSP-20's "
        "smooth closed-form fit.",
    )
    force_scale: float = option(
        1.0, "Factor on the datasheet force (real specimens are 0-40 % weaker).", "", 0.1, 2.0
    )
    friction_n_per_bar: float = option(
        6.0,
        "Coulomb friction of the bladder pressed against the braid: the sliding "
        "friction level's share that grows with pressure (contact force ~ p x area).",
        "N/bar",
        0.0,
        200.0,
    )
    friction_per_tension: float = option(
        0.06,
        "Coulomb friction where the braid's strands cross, pressed together by the "
        "tension they carry: the sliding friction level's share per newton of the "
        "muscle's static pull; 0 leaves friction to pressure alone.",
        "",
        0.0,
        1.0,
    )
    friction_presliding_mm: float = option(
        0.2,
        "Travel over which the friction builds up after a reversal (Dahl characteristic length).",
        "mm",
        0.001,
        10.0,
    )
    damping_contracting_n_s_per_m: float = option(
        1000.0, "Viscous damping while the muscle shortens.", "N s/m", 0.0, 100000.0
    )
    damping_relaxing_n_s_per_m: float = option(
        500.0,
        "Viscous damping while the muscle lengthens (smaller than when contracting).",
        "N s/m",
        0.0,
        100000.0,
    )
    moving_mass_kg: float = option(
        0.2,
        "Mass moving with the muscle end besides the load "
        "(fittings, load cell); inertia only, so 0 kg is well posed.",
        "kg",
        0.01,
        100.0,
    )
    stop_stretch_contraction: float | None = option(
        None,
        "Hard stop that catches the load when the "
        "muscle is stretched this far (contraction "
        "fraction, negative = longer than nominal); null: 1 % past the type's rated "
        "pretension (-0.05 on a DMSP-20, -0.06 on a DMSP-40).",
        "",
        -0.3,
        0.6,
    )
    stop_contraction: float | None = option(
        None,
        "Hard stop that limits shortening (contraction "
        "fraction); equal stops clamp the muscle isometric; null: the type's rated "
        "contraction (0.25 on a DMSP-20 or -40).",
        "",
        -0.3,
        0.6,
    )
    stiction_ratio: float = option(
        1.0,
        "Breakaway friction over sliding friction (Stribeck); 1 means no stiction.",
        "",
        1.0,
        5.0,
    )
    stribeck_velocity_mm_s: float = option(
        1.0,
        "Speed over which the friction falls from breakaway to sliding (Stribeck).",
        "mm/s",
        0.001,
        1000.0,
    )
    plant_model: str | None = option(
        None,
        "An identified model file (kind fn-qupi, pamd train's) that stands for this "
        "muscle's mechanics: the length is its forward model's, from the regulator's "
        "pressure history and the hanging load, once per sample period it was "
        "identified on (seed 003 runs its controllers against its FN-QUPI model); the "
        "regulator and the sensors stay as configured, the load cell reads the load's "
        "weight. Absolute, or relative to the directory pamd runs in. null: the "
        "muscle's own physics.",
    )


@dataclass(frozen=True)
class SimPneumatics:
    """The air: supply, proportional regulator or on/off valves, exhaust, and the
    'flow' model's orifices and gas."""

    initial_pressure_bar: float = option(
        0.0,
        "Pressure the regulator holds at power-up (a VPPM holds its pressure across a PC restart).",
        "bar",
        0.0,
        16.0,
    )
    supply_bar: float = option(7.0, "Supply pressure feeding the regulator.", "bar", 0.0, 16.0)
    regulator_max_bar: float = option(
        6.0, "Regulator full scale: the pressure at the largest setpoint.", "bar", 0.1, 16.0
    )
    regulator_dead_time_s: float = option(
        0.010,
        "Regulator dead time between a setpoint and the first pressure change.",
        "s",
        0.0,
        0.5,
    )
    regulator_lag_s: float = option(
        0.030,
        "'lag' pneumatics: first-order lag of the regulated pressure (dead time + lag "
        "= t63).",
        "s",
        0.0001,
        5.0,
    )
    regulator_backlash_bar: float = option(
        0.02,
        "Setpoint backlash (full width) standing in for the regulator's hysteresis.",
        "bar",
        0.0,
        1.0,
    )
    regulator_zero_bar: float = option(
        0.03, "Zero-point suppression: a setpoint below this vents to 0 bar.", "bar", 0.0, 1.0
    )
    exhaust_vent_time_constant_s: float = option(
        0.015,
        "'lag' pneumatics: time constant of the pressure decay while the exhaust "
        "valve is open ('flow' vents through exhaust_flow_l_min).",
        "s",
        0.0001,
        5.0,
    )
    actuation: Actuation = option(
        "proportional",
        "How air reaches the muscle: 'proportional', a pressure regulator (outputs "
        "NAME.valve in bar and NAME.exhaust, its exhaust valve); 'onoff', an inflate valve "
        "(3/2 NC) and an exhaust valve (2/2 NC), digital outputs NAME.inflate and "
        "NAME.exhaust, always with air that flows.",
    )
    onoff_inflate_flow_l_min: float = option(
        20.0,
        "'onoff' actuation: standard nominal flow of the inflate valve and its hose "
        "(fast switching valves are small: fine positioning needs small air portions).",
        "l/min",
        1.0,
        100000.0,
    )
    onoff_exhaust_flow_l_min: float = option(
        20.0,
        "'onoff' actuation: standard nominal flow of the exhaust valve.",
        "l/min",
        1.0,
        100000.0,
    )
    valve_on_delay_s: float = option(
        0.002,
        "'onoff' actuation: time from energising a valve to its opening.",
        "s",
        0.0,
        1.0,
    )
    valve_off_delay_s: float = option(
        0.004,
        "'onoff' actuation: time from releasing a valve to its closing.",
        "s",
        0.0,
        1.0,
    )
    pneumatics: Literal["lag", "flow"] = option(
        "flow",
        "How the muscle's pressure follows a proportional regulator: 'flow' (the "
        "default) lets air flow through the regulator (its own pressure loop, ISO 6358 "
        "orifices) into a chamber whose volume follows the contraction; 'lag' is the "
        "old simple plant, a dead time and a first-order lag on the setpoint (cheaper "
        "and kinder: for fast tests, not for figures).",
    )
    regulator_flow_l_min: float = option(
        140.0,
        "'flow' pneumatics: standard nominal flow (6 -> 5 bar, ANR) of the regulator's "
        "main stage and the hose to the muscle together, filling and venting (the default "
        "gives a t63 of about 40 ms for 0 -> 3 bar into a DMSP-20-200 at 30 kg).",
        "l/min",
        1.0,
        100000.0,
    )
    regulator_pilot_lag_s: float = option(
        0.005,
        "'flow' pneumatics: first-order response of the regulator's pilot stage.",
        "s",
        0.0,
        1.0,
    )
    regulator_full_open_error_bar: float = option(
        0.3,
        "'flow' pneumatics: pressure error at which the regulator's main stage is fully open.",
        "bar",
        0.001,
        10.0,
    )
    critical_pressure_ratio: float = option(
        0.3,
        "'flow' pneumatics: ISO 6358 critical pressure ratio b of the regulator, hose "
        "and exhaust valve.",
        "",
        0.01,
        0.99,
    )
    exhaust_flow_l_min: float = option(
        300.0,
        "'flow' pneumatics: standard nominal flow of the exhaust valve (the "
        "regulator vents through its own port, regulator_flow_l_min).",
        "l/min",
        1.0,
        100000.0,
    )
    dead_volume_cm3: float = option(
        10.0,
        "'flow' pneumatics: air volume of the hose and fittings beside the muscle's own.",
        "cm^3",
        0.0,
        10000.0,
    )
    polytropic_exponent: float = option(
        1.2,
        "'flow' pneumatics: polytropic exponent of the air in the muscle "
        "(1 isothermal, 1.4 adiabatic).",
        "",
        1.0,
        1.4,
    )


@dataclass(frozen=True)
class SimSensors:
    """The readings: noise, drift, resolution, sample times, latency, filters,
    converters, bursty links, and whether the length is absolute."""

    force_drift_per_hour: float = option(
        0.0,
        "Slow drift of the muscle's force (a warming muscle, a wearing braid): the "
        "force scale changes by this fraction per hour of rig time, linearly.",
        "1/h",
        -10.0,
        10.0,
    )
    pressure_noise_bar: float = option(
        0.003, "Standard deviation of the pressure sensor noise.", "bar", 0.0, 1.0
    )
    force_noise_n: float = option(
        0.5, "Standard deviation of the load cell noise.", "N", 0.0, 100.0
    )
    encoder_resolution_mm: float = option(
        0.01, "Length encoder resolution (readings are quantised to it).", "mm", 0.000001, 10.0
    )
    pressure_sample_period_s: float = option(
        0.001,
        "Pressure input: the device converts a sample this often (default: a DAQ card "
        "at 1 kHz; an ADAM-6024 about 0.1 s); 0 samples at every plant step.",
        "s",
        0.0,
        10.0,
    )
    pressure_latency_s: float = option(
        0.0, "Pressure input: time from taking a sample to its delivery.", "s", 0.0, 10.0
    )
    pressure_filter_s: float = option(
        0.0,
        "Pressure input: time constant of the device's own first-order filter (0: none).",
        "s",
        0.0,
        10.0,
    )
    force_sample_period_s: float = option(
        0.001,
        "Load cell: sample period of its amplifier (default: on the DAQ card at 1 kHz; "
        "0: every plant step).",
        "s",
        0.0,
        10.0,
    )
    force_latency_s: float = option(
        0.0, "Load cell: time from taking a sample to its delivery.", "s", 0.0, 10.0
    )
    force_filter_s: float = option(
        0.0, "Load cell: time constant of the amplifier's filter (0: none).", "s", 0.0, 10.0
    )
    length_sample_period_s: float = option(
        0.001,
        "Encoder: sample period of its interface (default: a CiA 406 encoder's TPDO "
        "every 1 ms; 0: every plant step).",
        "s",
        0.0,
        10.0,
    )
    length_latency_s: float = option(
        0.0, "Encoder: time from taking a sample to its delivery.", "s", 0.0, 10.0
    )
    length_filter_s: float = option(
        0.0, "Encoder: time constant of its interface's filter (0: none).", "s", 0.0, 10.0
    )
    pressure_adc_bits: int = option(
        0,
        "Pressure input: bits of its converter over pressure_adc_min_bar .. "
        "pressure_adc_max_bar (readings saturate there and move in steps of the range / "
        "(2^bits - 1); a 16-bit input over 0-10 bar reads in 0.15 mbar steps); 0: no "
        "converter (a continuous reading).",
        "",
        0,
        32,
    )
    pressure_adc_min_bar: float = option(
        0.0, "Pressure input: the converter's lowest reading.", "bar", -1.0, 100.0
    )
    pressure_adc_max_bar: float = option(
        10.0, "Pressure input: the converter's highest reading.", "bar", 0.01, 100.0
    )
    force_adc_bits: int = option(
        0,
        "Load cell: bits of its converter over force_adc_min_n .. force_adc_max_n (a "
        "16-bit input over +-2000 N reads in 0.061 N steps); 0: no converter.",
        "",
        0,
        32,
    )
    force_adc_min_n: float = option(
        -2000.0, "Load cell: the converter's lowest reading.", "N", -100000.0, 100000.0
    )
    force_adc_max_n: float = option(
        2000.0, "Load cell: the converter's highest reading.", "N", -100000.0, 100000.0
    )
    pressure_burst_s: float = option(
        0.0,
        "Pressure input: bursty delivery. Every burst_every_s the link holds its samples "
        "this long, then the backlog rushes in (oldest first, three samples per plant "
        "step, as a driver thread drains its socket); such a sensor is stamped on arrival "
        "with a declared jitter, as a protocol without a sample time is. 0: no bursts, "
        "stamped with the sample's time.",
        "s",
        0.0,
        10.0,
    )
    force_burst_s: float = option(
        0.0, "Load cell: bursty delivery (as pressure_burst_s).", "s", 0.0, 10.0
    )
    length_burst_s: float = option(
        0.0, "Encoder: bursty delivery (as pressure_burst_s).", "s", 0.0, 10.0
    )
    burst_every_s: float = option(
        1.0,
        "How often a bursty sensor's link holds (longer than its ..._burst_s).",
        "s",
        0.001,
        3600.0,
    )
    length_absolute: bool = option(
        True,
        "True: the length reads the true length (an absolute sensor; the muscle starts "
        "with its length datum). False: an incremental encoder that reads 0 mm at power-up "
        "and needs `home`.",
    )
